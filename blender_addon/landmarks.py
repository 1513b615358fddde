"""Landmarks in Blender: found on the user's mesh, shown as empties to nudge, read back for the fit.

Found landmarks become 68 empties parented to the mesh (in the collection
``PDE Landmarks``), each tagged with its Multi-PIE index; moving one moves
that landmark for the next fit. The face-landmark model (``mediapipe``) is
optional: when it is missing, :func:`install` puts it in the extension's own
user folder on request.
"""
import os
import subprocess
import sys
import time

import bpy
import numpy as np
from pdeface.errors import LandmarkError, MeshError, PdeFaceError
from pdeface.landmarks import MissingDependencyError, available, detect
from pdeface.landmarks.detector import RUNTIME_PACKAGES
from pdeface.landmarks.facemap import GROUPS

from . import bridge

#: Custom property on each landmark empty: its Multi-PIE index (0-67).
INDEX_PROP = "pdeface_landmark"
COLLECTION = "PDE Landmarks"


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


def show(context, obj, points, found):
    """Put (or move) the 68 landmark empties of ``obj`` at ``points`` (object space)."""
    group_of = {i: g for g, rows in GROUPS.items() for i in rows}
    coll = bpy.data.collections.get(COLLECTION)
    if coll is None:
        coll = bpy.data.collections.new(COLLECTION)
        context.scene.collection.children.link(coll)
    lms = empties(obj) or []
    size = 1.5 / found.mm_per_unit  # 1.5 mm spheres
    for i, p in enumerate(points):
        e = lms[i] if lms else bpy.data.objects.new(f"{obj.name} LM{i:02d} {group_of[i]}", None)
        if not lms:
            coll.objects.link(e)
            e[INDEX_PROP] = i
            e.parent = obj
            e.empty_display_type = "SPHERE"
        e.matrix_parent_inverse.identity()
        e.location = tuple(p)
        e.empty_display_size = size
        e["pdeface_confidence"] = round(found.confidence[group_of[i]], 3)


def find(context, obj, unit=None):
    """Find the landmarks of mesh object ``obj`` and show them as empties; returns (points, found, seconds)."""
    V = bridge.vertices(obj.data)
    T, _ = bridge.triangles(obj.data)
    if len(T) == 0:
        raise MeshError(f"{obj.name} has no faces")
    t = time.perf_counter()
    try:
        found = detect(V, T, unit)
    except MissingDependencyError:
        raise LandmarkError("finding landmarks needs the face-landmark model: press Install Landmark Model in the "
                            "PDE Face panel, or choose Vertex group, Selected vertices or JSON file") from None
    seconds = time.perf_counter() - t
    show(context, obj, found.points, found)
    return found.points, found, seconds


def summary(obj, found, seconds):
    low = min(found.confidence, key=found.confidence.get)
    return (f"Found 68 landmarks on {obj.name} in {seconds:.1f} s (view {found.view}; least sure: {low} "
            f"{found.confidence[low]:.2f}): nudge the empties in '{COLLECTION}' if needed, then Fit")
