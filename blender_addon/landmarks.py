"""Landmarks in Blender: found on the user's mesh, shown as empties to edit (guided), read back for the fit.

Found (or imported) landmarks become 68 empties parented to the mesh, one collection per group under
``PDE Landmarks``, each tagged with its Multi-PIE index; moving one moves that landmark for the next fit, and
being objects they are saved with the ``.blend``. The guided editor beside them: the scheme's picture
(:data:`SCHEME`, in the panel and as an image empty beside the head), :func:`snap` onto the surface,
:func:`gate` (the landmark gate of :mod:`pdeface.landmarks.gate`: its failing groups highlighted and kept on
the mesh for the panel), and the landmarks JSON out and in (:func:`export`, :func:`import_file`). Landmarks the user
gives (a file, a vertex group, selected vertices) skip the gate, but not its look at the mesh (:func:`at_rest`).

The face-landmark model (``mediapipe``) is optional: when it is missing, :func:`install` puts it in the
extension's own user folder on request.
"""
import hashlib
import json
import math
import os
import subprocess
import sys
import time

import bpy
import numpy as np
from mathutils import Matrix, Vector
from pdeface.errors import FileError, LandmarkError, MeshError, PdeFaceError
from pdeface.geometry import ClosestPoint
from pdeface.io.files import atomic_open
from pdeface.landmark_scheme import eye_distance
from pdeface.landmarks import MissingDependencyError, available
from pdeface.landmarks.detector import RUNTIME_PACKAGES
from pdeface.landmarks.facemap import GROUPS
from pdeface.landmarks.gate import LandmarkGateError, Verdict, check, check_mesh_at_rest, require
from pdeface.landmarks.headfind import detect_anywhere
from pdeface.landmarks.pipeline import onto_outer_surface, skin_triangles
from pdeface.landmarks.render import View, rasterise
from pdeface.surface.frame import face_frame, landmark_points
from pdeface.surface.frame import read_landmarks as read_landmark_file

from . import bridge

#: Custom property on each landmark empty: its Multi-PIE index (0-67).
INDEX_PROP = "pdeface_landmark"
COLLECTION = "PDE Landmarks"
#: Custom properties on the mesh (saved with the .blend): the gate's last one-line failure ("" when it passed), its
#: failing groups, comma-separated, and the landmarks it judged (:data:`EMPTIES` or the given source, in words), for
#: the panel: a verdict shows only under the source it was made on.
GATE_PROP, GATE_GROUPS_PROP, GATE_SOURCE_PROP = "pdeface_gate", "pdeface_gate_groups", "pdeface_gate_source"
#: The source the whole gate judges: the mesh's landmark empties (found, imported or edited).
EMPTIES = "the landmark empties"
#: Custom properties on the mesh: the gate's last verdict (JSON) and a digest of what it judged (the points, the
#: unit, the mesh's vertices and faces): Fit reuses the verdict of Find Landmarks when nothing of it changed.
GATE_VERDICT_PROP, GATE_OF_PROP = "pdeface_gate_verdict", "pdeface_gate_of"
#: What a refusal of the mesh (its landmarks given) tells the user to do: the CLI's ``FIX_MESH``, in the panel's words.
FIX_MESH = "give the head at rest (its eyes open), or Accept anyway"
#: Custom property on each landmark empty: its display size when its group passes (a failing one's is twice).
SIZE_PROP = "pdeface_size"
#: The picture of the 68-point scheme (drawn by scripts/figures/render_landmark_scheme.py).
SCHEME = os.path.join(os.path.dirname(os.path.realpath(__file__)), "images", "landmark_scheme.png")
#: Each group's collection colour, as in the scheme's picture (Blender's tags: 01 red, 02 orange, 04 green,
#: 05 blue, 06 violet); a failing group's collection turns yellow (03), its empties bigger cubes.
GROUP_TAGS = {"jaw": "COLOR_05", "brows": "COLOR_06", "nose": "COLOR_04", "eyes": "COLOR_02", "mouth": "COLOR_01"}
FAILING_TAG = "COLOR_03"
#: The share of the landmarks nearest to a connected part of the mesh that makes it skin for the gate (the four
#: upper-lid points may be nearest to lashes).
SKIN_SHARE = 0.1
GROUP_OF = {i: g for g, rows in GROUPS.items() for i in rows}


def site_dir(create=False):
    """The extension's own folder for the optional packages (outside Blender's, so nothing of it is changed)."""
    return bpy.utils.extension_path_user(__package__, path="site-packages", create=create)


def add_site():
    """Make packages installed by :func:`install` importable (after Blender's own: its numpy wins)."""
    try:
        path = site_dir()
    except ValueError:  # not running as an extension (a source checkout on sys.path)
        return
    if os.path.isdir(path) and path not in sys.path:
        sys.path.append(path)


_AVAILABLE = []


def model_available():
    """Whether the face-landmark model imports (checked once per session, and again after an install)."""
    if not _AVAILABLE:
        _AVAILABLE.append(available())
    return _AVAILABLE[0]


def install_command(target):
    """The pip command that installs the face-landmark model into ``target``."""
    return [sys.executable, "-m", "pip", "install", "--no-deps", "--upgrade", "--target", target, *RUNTIME_PACKAGES]


def install():
    """Install the face-landmark model for this extension; returns pip's last lines. Raises PdeFaceError."""
    target = site_dir(create=True)
    subprocess.run([sys.executable, "-m", "ensurepip"], capture_output=True)
    done = subprocess.run(install_command(target), capture_output=True, text=True)
    if done.returncode != 0:
        raise PdeFaceError(f"installing the landmark model failed: {done.stderr.strip().splitlines()[-1:]}")
    add_site()
    _AVAILABLE.clear()
    return done.stdout.strip().splitlines()[-1:]


def empties(obj):
    """The mesh's 68 landmark empties ordered by index, or None when it has not all of them."""
    found = {e[INDEX_PROP]: e for e in obj.children if e.type == "EMPTY" and INDEX_PROP in e}
    if sorted(found) != list(range(68)):
        return None
    return [found[i] for i in range(68)]


def empty_points(obj):
    """The landmarks where the empties are now (the mesh's object space), or None."""
    lms = empties(obj)
    if lms is None:
        return None
    inv = obj.matrix_world.inverted()
    return np.array([tuple(inv @ e.matrix_world.translation) for e in lms])


def mesh_of(obj):
    """The user's mesh a landmark empty belongs to (or ``obj`` itself when it is a mesh); else None."""
    if obj is not None and obj.type == "EMPTY" and INDEX_PROP in obj:
        obj = obj.parent
    return obj if obj is not None and obj.type == "MESH" and not obj.pdeface.is_face else None


def _collection(context, name, parent, tag):
    coll = bpy.data.collections.get(name)
    if coll is None:
        coll = bpy.data.collections.new(name)
        parent.children.link(coll)
    coll.color_tag = tag
    return coll


def show(context, obj, points, confidence=None):
    """Put (or move) the 68 landmark empties of ``obj`` at ``points`` (object space), a collection per group."""
    top = bpy.data.collections.get(COLLECTION) or _collection(context, COLLECTION, context.scene.collection, "NONE")
    lms = empties(obj) or []
    size = 0.024 * eye_distance(points)  # 1.5 mm spheres on an adult face (object space, as the empties)
    for i, p in enumerate(points):
        group = GROUP_OF[i]
        e = lms[i] if lms else bpy.data.objects.new(f"{obj.name} LM{i:02d} {group}", None)
        if not lms:
            _collection(context, f"{COLLECTION} {group}", top, GROUP_TAGS[group]).objects.link(e)
            e[INDEX_PROP] = i
            e.parent = obj
            e.empty_display_type = "SPHERE"
        e.matrix_parent_inverse.identity()
        e.location = tuple(p)
        e.empty_display_size = e[SIZE_PROP] = size
        if confidence is not None:
            e["pdeface_confidence"] = round(confidence[group], 3)
    context.view_layer.update()


#: How far (share of the eye distance) a landmark may be from where the face's forward ray meets the surface
#: for that hit to count; farther (the jaw's contour seen edge on), the closest point of the surface counts.
SNAP_REACH = 0.15
#: A landmark this close to the surface (share of the eye distance) is on it: only brought onto it exactly
#: (the ray would find lashes in front of a lid point).
ON_SURFACE = 0.005
#: Pixels of the straight-on view the snap casts its rays in (about 0.3 mm on an adult face).
SNAP_SIZE = 512


def snap(context, obj):
    """Move each landmark empty of ``obj`` onto its surface: one off it straight back along the face's forward
    direction (where a drag in a front view meant it: core's
    :func:`~pdeface.landmarks.pipeline.onto_outer_surface`, which takes the lid margin or the lip's edge over an
    opening), else onto the closest point. Returns the farthest move (object space)."""
    lms = empties(obj)
    if lms is None:
        raise LandmarkError(f"{obj.name} has no landmark empties: Find Landmarks or Import Landmarks first")
    points = empty_points(obj)
    V = bridge.vertices(obj.data)
    T, _ = bridge.triangles(obj.data, loops=False)
    eyes = eye_distance(points)
    frame = face_frame(points)
    R = frame.rotation
    view = View.looking(R[2], R[1], points.mean(0), 1.6 * eyes, SNAP_SIZE)
    cast, _ = onto_outer_surface(V, T, rasterise(V, T, view), points, frame.scale)
    closest = ClosestPoint(V, T).query(points)[3]
    to_closest = np.linalg.norm(closest - points, axis=1)
    to_cast = np.linalg.norm(cast - points, axis=1)  # NaN where the ray found no outer surface
    use_cast = (to_closest >= ON_SURFACE * eyes) & (to_cast < SNAP_REACH * eyes)
    target = np.where(use_cast[:, None], cast, closest)
    for e, p in zip(lms, target, strict=True):
        m = e.matrix_world.copy()
        m.translation = obj.matrix_world @ Vector(p)
        e.matrix_world = m
    context.view_layer.update()
    return float(np.linalg.norm(target - points, axis=1).max())


def mesh_arrays(obj):
    """Vertices (object space) and triangles of mesh object ``obj``, read from Blender once for a find and its
    gate."""
    return bridge.vertices(obj.data), bridge.triangles(obj.data, loops=False)[0]


def gate(obj, points, unit=None, skin=None, arrays=None):
    """The landmark gate on ``points`` (object space) over ``obj``'s skin: the verdict, kept on the mesh
    (:data:`GATE_PROP`) and shown on the empties (:func:`highlight`).

    ``skin``: the triangles the landmarks were found on; else the connected parts of the mesh nearest to at
    least :data:`SKIN_SHARE` of the points (lashes and eyeballs in front of the skin are no face).
    ``arrays``: :func:`mesh_arrays` of ``obj``, when already read.
    """
    V, T = mesh_arrays(obj) if arrays is None else arrays
    if skin is None:
        skin = skin_triangles(V, T, ClosestPoint(V, T).query(points)[1], share=SKIN_SHARE)
    verdict = check(points, V, T[skin], unit)
    obj[GATE_VERDICT_PROP] = json.dumps(verdict.to_json())
    obj[GATE_OF_PROP] = gate_digest(obj, points, unit)
    _show(obj, verdict, EMPTIES)
    return verdict


def _show(obj, verdict, source):
    """Keep ``verdict``'s one line, failing groups and ``source`` (the landmarks judged) on the mesh for the panel,
    and highlight the failing groups' empties when it judged them (else none: the verdict is not theirs)."""
    obj[GATE_PROP] = verdict.message()
    obj[GATE_GROUPS_PROP] = ",".join(verdict.failures)
    obj[GATE_SOURCE_PROP] = source
    highlight(obj, list(verdict.failures) if source == EMPTIES else [])


def gate_digest(obj, points, unit=None):
    """A digest of what the gate judges on ``obj``: the points (object space), the unit, the mesh's vertices and
    its faces' corners (read from Blender: a few milliseconds)."""
    mesh = obj.data
    corners = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", corners)
    starts = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("loop_start", starts)
    h = hashlib.blake2b(digest_size=16)
    for a in (np.asarray(points, np.float64), bridge.vertices(mesh), corners, starts):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(str(unit).encode())
    return h.hexdigest()


def last_verdict(obj, points, unit=None):
    """The verdict the gate gave on ``points`` over ``obj`` as it is now, if it judged them already; else None."""
    if GATE_VERDICT_PROP not in obj or obj.get(GATE_OF_PROP) != gate_digest(obj, points, unit):
        return None
    return Verdict.from_json(json.loads(obj[GATE_VERDICT_PROP]))


def failing_groups(obj, source=None, unit=None):
    """The groups that failed the gate when last checked (from the .blend), or []; with ``source``, only when that
    check judged the landmarks of ``source`` (:data:`EMPTIES` or a given source, as :func:`at_rest` was told;
    ``unit``: the unit the fit is told, see :func:`verdict_source`)."""
    groups = [] if obj is None else [g for g in obj.get(GATE_GROUPS_PROP, "").split(",") if g]
    if not groups or (source is not None and verdict_source(obj, unit) != source):
        return []  # (nothing failed: the source is not asked, which reads the empties on an older .blend)
    return groups


def verdict_source(obj, unit=None):
    """The landmarks the gate's last verdict on ``obj`` judged (:data:`GATE_SOURCE_PROP`), or None (none kept).

    A verdict kept before verdicts named their source (an older .blend) is the empties' where the gate's last
    verdict on them (:func:`last_verdict`, at ``unit``) is still theirs as they are now, and is the one shown: else
    it would read as stale, and hide Accept anyway, until the next Find or Fit."""
    source = obj.get(GATE_SOURCE_PROP)
    if source is None and GATE_PROP in obj:
        points = empty_points(obj)
        verdict = None if points is None else last_verdict(obj, points, unit)
        if verdict is not None and verdict.message() == obj[GATE_PROP]:
            return EMPTIES
    return source


def highlight(obj, groups):
    """Show the failing ``groups``: their collections yellow, their empties bigger cubes and selected."""
    lms = empties(obj)
    if lms is None:
        return
    for g in GROUPS:
        coll = bpy.data.collections.get(f"{COLLECTION} {g}")
        if coll is not None:
            coll.color_tag = FAILING_TAG if g in groups else GROUP_TAGS[g]
    for i, e in enumerate(lms):
        failing = GROUP_OF[i] in groups
        e.empty_display_type = "CUBE" if failing else "SPHERE"
        e.empty_display_size = e.get(SIZE_PROP, e.empty_display_size) * (2 if failing else 1)
        if groups and e.name in bpy.context.view_layer.objects:
            e.select_set(failing)


def gated(obj, points, unit=None, accept=False):
    """Gate the landmarks the fit is about to use; raise :class:`LandmarkGateError` (one line, the empties left
    as they are for editing) when a group fails, unless ``accept``. Returns a note on an accepted failure.
    The verdict of Find Landmarks is reused when neither the points nor the mesh changed since (issue #35: the
    gate ran twice, the second time on a skin chosen otherwise)."""
    verdict = last_verdict(obj, points, unit)
    if verdict is None:
        verdict = gate(obj, points, unit)
    else:
        _show(obj, verdict, EMPTIES)  # the panel's line may be another check's since (:func:`at_rest`)
    if verdict.passed:
        return None
    if not accept:
        raise LandmarkGateError(
            f"the landmarks of {obj.name} fail the landmark gate: {verdict.message()}; move the highlighted "
            f"empties ({', '.join(verdict.failures)}), Snap Landmarks to Surface and Fit again, or Accept anyway",
            verdict)
    return f"going on with landmarks that fail the gate (accepted): {verdict.message()}"


def at_rest(obj, points, source, unit=None, accept=False):
    """The gate's look at mesh ``obj`` alone, for landmarks the user gave (``points``, object space, taken at
    their word as the CLI takes ``--landmarks``; ``source``: where from, in words): its eyes open, as a head at rest
    has them (:func:`~pdeface.landmarks.gate.check_mesh_at_rest`). The verdict is kept as :func:`gate`'s is, under
    ``source``; raise :class:`LandmarkGateError` with the CLI's message when an eye is closed, unless ``accept``.
    Returns a note on an accepted failure."""
    V, T = mesh_arrays(obj)
    verdict = check_mesh_at_rest(points, V, T, unit)
    _show(obj, verdict, source)
    if verdict.passed:
        return None
    if not accept:
        require(verdict, f"{obj.name} and its given landmarks", FIX_MESH)
    return f"going on with a mesh that fails the gate (accepted): {verdict.message()}"


def export(obj, path, overwrite=False, indices=False):
    """Write the empties as the landmarks JSON the CLI reads (``{"points"}`` in the mesh's own coordinates, or
    ``{"indices"}`` of the nearest vertices); an existing file only with ``overwrite``. Returns the path."""
    points = empty_points(obj)
    if points is None:
        raise LandmarkError(f"{obj.name} has no landmark empties to export: Find Landmarks or Import Landmarks")
    if not path:
        raise FileError("choose a file to export the landmarks to")
    if os.path.exists(path) and not overwrite:
        raise FileError(f"{path}: exists; tick Overwrite to replace it")
    if indices:
        V = bridge.vertices(obj.data)
        data = {"indices": [int(np.argmin(((V - p) ** 2).sum(1))) for p in points]}
    else:
        data = {"points": points.tolist()}
    with atomic_open(path) as f:
        json.dump(data, f, allow_nan=False)
    return path


def import_file(context, obj, path):
    """Read a landmarks JSON (``indices`` or ``points``, the mesh's own coordinates) and show it as the empties."""
    idx, pts = read_landmark_file(path)
    points = landmark_points(bridge.vertices(obj.data), idx, pts)
    show(context, obj, points)
    return points


def show_scheme(context, obj):
    """The scheme's picture as an image empty beside ``obj`` (in the landmarks' collection), facing the front
    (-Y), as tall as the landmarks; made once, then moved. Returns the empty."""
    name = f"{obj.name} landmark scheme"
    ref = bpy.data.objects.get(name)
    if ref is None:
        ref = bpy.data.objects.new(name, None)
        ref.empty_display_type = "IMAGE"
        ref.data = bpy.data.images.load(SCHEME, check_existing=True)
        top = bpy.data.collections.get(COLLECTION) or _collection(context, COLLECTION, context.scene.collection,
                                                                   "NONE")
        top.objects.link(ref)
    points = empty_points(obj)
    world = [obj.matrix_world @ Vector(p) for p in points] if points is not None else \
        [obj.matrix_world @ Vector(c) for c in obj.bound_box]
    lo = Vector([min(p[k] for p in world) for k in range(3)])
    hi = Vector([max(p[k] for p in world) for k in range(3)])
    height = max(hi.z - lo.z, 1e-6) * 1.2
    ref.empty_display_size = height
    ref.matrix_world = Matrix.Translation((hi.x + 0.6 * height, (lo.y + hi.y) / 2, (lo.z + hi.z) / 2)) @ \
        Matrix.Rotation(math.pi / 2, 4, "X")
    return ref


_previews = []


def scheme_icon():
    """The scheme's picture as an icon for the panel (loaded once per session)."""
    if not _previews:
        import bpy.utils.previews

        pcoll = bpy.utils.previews.new()
        pcoll.load("scheme", SCHEME, "IMAGE")
        _previews.append(pcoll)
    return _previews[0]["scheme"].icon_id


def unregister():
    for pcoll in _previews:
        bpy.utils.previews.remove(pcoll)
    _previews.clear()


def find(context, obj, unit=None, arrays=None):
    """Find the landmarks of mesh object ``obj`` and show them as empties; returns (points, found, seconds).
    ``arrays``: :func:`mesh_arrays` of ``obj``, when already read."""
    V, T = mesh_arrays(obj) if arrays is None else arrays
    if len(T) == 0:
        raise MeshError(f"{obj.name} has no faces")
    t = time.perf_counter()
    try:
        found = detect_anywhere(V, T, unit)  # on a body, the head first (as the CLI does)
    except MissingDependencyError:
        raise LandmarkError("finding landmarks needs the face-landmark model: press Install Landmark Model in the "
                            "PDE Face panel, or choose Vertex group, Selected vertices or JSON file") from None
    seconds = time.perf_counter() - t
    show(context, obj, found.points, found.confidence)
    return found.points, found, seconds


def summary(obj, found, seconds):
    low = min(found.confidence, key=found.confidence.get)
    return (f"Found 68 landmarks on {obj.name} in {seconds:.1f} s (view {found.view}; least sure: {low} "
            f"{found.confidence[low]:.2f}): nudge the empties in '{COLLECTION}' if needed, then Fit")
