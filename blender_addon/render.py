"""Rendering a PDE face: framing, frames, video, contact sheet.

Used by scripts/figures/render_sequence.py (``blender -b -P`` or plain ``python`` with
bpy), which keyframes its timeline with ``animation.apply_timeline``. Camera and
lights depend only on the face at rest, and Cycles' seed is fixed, so frame
ranges rendered apart join seamlessly.
"""
import itertools
import math
import tempfile
from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix, Vector
from pdeface.au.expressions import ShapeBasis
from pdeface.facs import split_au_key
from pdeface.io.png import write_png
from pdeface.presets import resolve_preset
from pdeface.surface.fit import face_mesh

from . import bridge, compat
from .keys import all_presets, au_key_names, expression_key_names

RIG = "PDE Render"  # prefix of the camera and lights this module makes


#: A user's head is framed wider than its PDE face: the face's extent times this.
HEAD_FRAMING = 1.35


def face_axes(obj):
    """World-space centre, forward and up of a PDE face or the user's head it drives (the model's frame)."""
    pde = obj if obj.pdeface.is_face else obj.pdeface.rig_face
    model = bridge.face_model(pde)
    M = pde.matrix_world
    R = model.frame.rotation  # rows: face x, y, z axes in the object's space
    fwd = (M.to_3x3() @ Vector(R[2])).normalized()
    up = (M.to_3x3() @ Vector(R[1])).normalized()
    # The rest mesh, not bound_box: that follows the pose of the current frame.
    V = bridge.world_vertices(pde)
    lo, hi = V.min(axis=0), V.max(axis=0)
    extent = float(np.linalg.norm(hi - lo)) * (1.0 if pde is obj else HEAD_FRAMING)
    return Vector((lo + hi) / 2), fwd, up, extent


def _look_at(location, target, up):
    z = (location - target).normalized()  # cameras look down their -Z
    x = up.cross(z).normalized()
    y = z.cross(x)
    m = Matrix((x, y, z)).transposed().to_4x4()
    m.translation = location
    return m


def setup_render(scene, obj, engine="CYCLES", size=(256, 256), samples=16, seed=0, fps=24):
    """Camera and lights framing the face, and render settings (deterministic)."""
    centre, fwd, up, extent = face_axes(obj)
    for o in [o for o in scene.objects if o.name.startswith(RIG)]:
        bpy.data.objects.remove(o, do_unlink=True)
    cam_data = bpy.data.cameras.new(f"{RIG} camera")
    cam_data.lens = 85
    cam = bpy.data.objects.new(f"{RIG} camera", cam_data)
    scene.collection.objects.link(cam)
    fov = 2 * math.atan(cam_data.sensor_width / (2 * cam_data.lens))
    dist = 0.45 * extent / math.tan(fov / 2)
    cam.matrix_world = _look_at(centre + fwd * dist, centre, up)
    cam_data.clip_start, cam_data.clip_end = dist * 0.05, dist * 10
    scene.camera = cam
    side = up.cross(fwd).normalized()
    for name, direction, power in (("key", fwd + 0.7 * up - 0.8 * side, 2.2), ("fill", fwd + 0.1 * up + 0.9 * side, 0.5)):
        ld = bpy.data.lights.new(f"{RIG} {name}", "SUN")
        ld.energy = power
        lo = bpy.data.objects.new(f"{RIG} {name}", ld)
        scene.collection.objects.link(lo)
        lo.matrix_world = _look_at(centre + direction.normalized() * dist, centre, up)
    if scene.world is None:
        scene.world = bpy.data.worlds.new(f"{RIG} world")
    scene.world.color = (0.05, 0.05, 0.06)
    engines = compat.render_engines()
    if engine not in engines:
        raise ValueError(f"unknown engine {engine!r}; use one of {', '.join(engines)}")
    scene.render.engine = engines[engine]
    if engine == "CYCLES":
        scene.cycles.device = "CPU"
        scene.cycles.samples = samples
        scene.cycles.seed = seed
        scene.cycles.use_animated_seed = False
        scene.cycles.use_denoising = _has_denoiser()
        if hasattr(scene.cycles, "denoising_quality"):  # 4.1+: the high-quality filter costs minutes at this size
            scene.cycles.denoising_quality = "FAST"
        scene.cycles.denoising_prefilter = "FAST"  # OIDN is not everywhere; noise-free at these sizes anyway
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.fps = int(round(fps))
    scene.render.film_transparent = False
    scene.render.use_file_extension = True
    return cam


def render_frames(scene, out_dir, frame_start, frame_end, progress=None):
    """Render frames to ``out_dir/frame_####.png``; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, f in enumerate(range(frame_start, frame_end + 1)):
        scene.frame_set(f)
        path = out / f"frame_{f:04d}.png"
        compat.set_image_output(scene, path)
        bpy.ops.render.render(write_still=True)
        paths.append(path)
        if progress:
            progress(i + 1, frame_end - frame_start + 1)
    return paths


def make_video(frames, fps, path):
    """Join PNG frames into an MP4 with Blender's FFmpeg output (no 3D re-render)."""
    frames = [Path(p) for p in frames]
    scene = bpy.data.scenes.new("PDE video")
    try:
        sed = scene.sequence_editor_create()
        strip = compat.strips(sed).new_image("frames", str(frames[0]), 1, 1)
        for p in frames[1:]:
            strip.elements.append(p.name)
        first = bpy.data.images.load(str(frames[0]), check_existing=True)
        scene.render.resolution_x, scene.render.resolution_y = first.size
        scene.render.resolution_percentage = 100
        bpy.data.images.remove(first)
        scene.frame_start, scene.frame_end = 1, len(frames)
        scene.render.fps = int(round(fps))
        compat.set_video_output(scene, path)
        with bpy.context.temp_override(scene=scene):
            bpy.ops.render.render(animation=True, scene=scene.name)
    finally:
        bpy.data.scenes.remove(scene)
    out = Path(path)
    candidates = sorted(out.parent.glob(out.name + "*")) or sorted(out.parent.glob(out.stem + "*"))
    return candidates[0] if candidates else out


def _has_denoiser() -> bool:
    """Whether this Blender's Cycles has OpenImageDenoise (it runs on the CPU; builds without it exist)."""
    try:
        import _cycles
        return bool(getattr(_cycles, "with_openimagedenoise", False))
    except ImportError:
        return False


#: The contact sheet's motion rows: each vertex's distance from neutral (mm), a float point attribute of
#: each cell's mesh, coloured on this ramp of (mm, RGBA); beyond its last stop, the last colour.
MOTION_ATTRIBUTE = "pdeface_motion_mm"
MOTION_RAMP = ((0.0, (0.3, 0.3, 0.32, 1.0)), (0.5, (0.12, 0.22, 0.8, 1.0)), (2.0, (0.0, 0.65, 0.65, 1.0)),
               (5.0, (0.95, 0.85, 0.1, 1.0)), (10.0, (0.9, 0.12, 0.05, 1.0)))
#: The legend's ticks (mm).
MOTION_TICKS = (0, 2, 4, 6, 8, 10)


def set_motion(me, moved):
    """Store each vertex's distance moved, ``|moved|`` ((n, 3), mm), as ``me``'s :data:`MOTION_ATTRIBUTE`.

    Returns the distances (float32, as stored).
    """
    d = np.linalg.norm(np.asarray(moved, np.float64), axis=1).astype(np.float32)
    attr = me.attributes.get(MOTION_ATTRIBUTE) or me.attributes.new(MOTION_ATTRIBUTE, "FLOAT", "POINT")
    attr.data.foreach_set("value", d)
    return d


def motion_material():
    """Emission coloured by :data:`MOTION_ATTRIBUTE` on :data:`MOTION_RAMP`, darker where the surface turns
    away (the face's shape still reads); lights do not change its colours, so the legend holds."""
    mat = bpy.data.materials.new("PDE motion")
    compat.use_nodes(mat)
    tree = mat.node_tree
    tree.nodes.clear()
    attr = tree.nodes.new("ShaderNodeAttribute")
    attr.attribute_type, attr.attribute_name = "GEOMETRY", MOTION_ATTRIBUTE
    full = MOTION_RAMP[-1][0]
    scaled = tree.nodes.new("ShaderNodeMath")
    scaled.operation, scaled.use_clamp = "DIVIDE", True
    scaled.inputs[1].default_value = full
    tree.links.new(attr.outputs["Fac"], scaled.inputs[0])
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    elements = ramp.color_ramp.elements
    while len(elements) < len(MOTION_RAMP):
        elements.new(0.5)
    for e, (mm, colour) in zip(elements, MOTION_RAMP):
        e.position, e.color = mm / full, colour
    tree.links.new(scaled.outputs[0], ramp.inputs["Fac"])
    facing = tree.nodes.new("ShaderNodeLayerWeight")
    facing.inputs["Blend"].default_value = 0.5
    shade = tree.nodes.new("ShaderNodeMath")  # 1 facing the camera, 0.45 at the silhouette
    shade.operation = "MULTIPLY_ADD"
    shade.inputs[1].default_value, shade.inputs[2].default_value = -0.55, 1.0
    tree.links.new(facing.outputs["Facing"], shade.inputs[0])
    emit = tree.nodes.new("ShaderNodeEmission")
    tree.links.new(ramp.outputs["Color"], emit.inputs["Color"])
    tree.links.new(shade.outputs[0], emit.inputs["Strength"])
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(emit.outputs[0], out.inputs["Surface"])
    if hasattr(mat, "cycles") and hasattr(mat.cycles, "emission_sampling"):
        mat.cycles.emission_sampling = "NONE"  # a colour map, not a lamp: sampling it as light triples the sheet's time
    return mat


def _camera_only(o):
    """Seen by the camera alone: no shadows, bounces or light on the faces beside it."""
    for ray in ("visible_diffuse", "visible_glossy", "visible_transmission", "visible_volume_scatter",
                "visible_shadow"):
        setattr(o, ray, False)


def _text(scene, name, body, size, location, material, align="CENTER"):
    curve = bpy.data.curves.new(name, "FONT")
    curve.body = body
    curve.align_x = align
    curve.size = size
    curve.materials.append(material)
    t = bpy.data.objects.new(name, curve)
    t.visible_shadow = False  # the sun would print it on the forehead below
    t.location = location
    scene.collection.objects.link(t)
    return t


def _legend(scene, left, top, length, size, z, motion_mat, text_mat):
    """The motion rows' colour bar, ``length`` long from (``left``, ``top``), with its ticks in mm."""
    full = MOTION_RAMP[-1][0]
    n = 64
    x = np.linspace(0.0, length, n + 1)
    V = np.concatenate([np.stack([x, np.zeros_like(x), np.zeros_like(x)], 1),
                        np.stack([x, np.full_like(x, -size), np.zeros_like(x)], 1)])
    me = bpy.data.meshes.new("legend bar")
    me.from_pydata(V.tolist(), [], [(i, i + 1, n + 2 + i, n + 1 + i) for i in range(n)])
    set_motion(me, np.stack([np.tile(x / length * full, 2), np.zeros(len(V)), np.zeros(len(V))], 1))
    me.materials.append(motion_mat)
    bar = bpy.data.objects.new("legend bar", me)
    _camera_only(bar)
    bar.location = (left, top, z)
    scene.collection.objects.link(bar)
    for mm in MOTION_TICKS:
        _text(scene, f"legend {mm}", f"{mm}", 0.8 * size, (left + length * mm / full, top - 2.0 * size, z), text_mat)
    _text(scene, "legend title", "mm moved from neutral", 0.8 * size, (left + length + 1.5 * size, top - 0.8 * size, z),
          text_mat, align="LEFT")


#: The contact sheet is rendered in bands of whole rows (of faces, or of motion), each holding at most about this
#: many vertices of posed meshes (at least one row): 83 poses of a 27k-vertex head in one scene took 3.2 GB
#: (issue #35).
SHEET_BAND_VERTICES = 250_000


def contact_sheet(obj, path, items=None, cell=256, columns=8, samples=16, resolution="2,2", motion=True,
                  band_vertices=SHEET_BAND_VERTICES):
    """One PNG grid of the neutral, every AU (in numeric order) and every preset at weight 1, labelled.

    All cells are posed copies of the face laid out in one orthographic view
    (Cycles, denoised where Blender has OpenImageDenoise), each labelled by a
    text object in a strip below the lowest chin of any cell. With ``motion``,
    each row of faces has a row below it of the same poses coloured by how far
    each vertex moved from neutral (:func:`set_motion`, :data:`MOTION_RAMP`),
    where AUs too subtle to see in the shading show, and a colour bar in mm
    closes the sheet.

    The sheet is rendered in horizontal bands of whole rows (of faces with their
    labels, or of motion) through the same camera (a render border each), with
    only the meshes a band shows in the scene, at most about ``band_vertices``
    vertices of them but a row at least (``None``: the whole sheet in one
    render); the bands are joined into one PNG.
    """
    pde = obj if obj.pdeface.is_face else obj.pdeface.rig_face
    model = bridge.face_model(pde)
    keys = sorted((d.key for d in model.descriptors), key=split_au_key)
    cells = [("neutral", {})] + [(f"AU{k}", {k: 1.0}) for k in keys]
    for name, preset in all_presets(bpy.context.scene).items():
        w, _ = resolve_preset(preset, set(keys))
        cells.append((name, w))
    if items is not None:
        cells = [c for c in cells if c[0] in items]
    scene = bpy.data.scenes.new("PDE contact sheet")
    materials = []
    try:
        if pde is obj:  # the PDE face, meshed at the sheet's resolution
            basis = ShapeBasis(model, resolution, dtype=np.float64)
            cell_mesh = face_mesh(model, resolution)
            user_space = [basis.vertices(basis.weights_matrix(w))[0] if w else basis.neutral for _, w in cells]
        else:  # the user's head: its own keys at weight 1
            cell_mesh = bridge.as_pdeface_mesh(obj.data)
            blocks = obj.data.shape_keys.key_blocks
            names = {**{f"AU{k}": n for k, n in au_key_names(obj).items()},
                     **expression_key_names(obj, [c[0] for c in cells])}
            rest = bridge.key_coords(obj.data.shape_keys.reference_key).astype(np.float64)
            user_space = [bridge.key_coords(blocks[names[label]]).astype(np.float64) if w else rest
                          for label, w in cells]
        rows = math.ceil(len(cells) / columns)
        # Faces in the face frame (mm), looking +z, each centred on its cell by the neutral's
        # bounding box; the labels go in a strip below the lowest point any pose reaches (an open jaw).
        posed = [model.frame.to_face(V) for V in user_space]
        del user_space
        neutral = posed[0]
        lo, hi = neutral.min(axis=0), neutral.max(axis=0)
        centre = (lo + hi) / 2
        width, height = hi[0] - lo[0], hi[1] - lo[1]
        lowest = min(float(V[:, 1].min()) for V in posed) - centre[1]
        label_size = 0.09 * width
        label_y = lowest - 0.04 * height - label_size  # the text's baseline, its top clear of every chin
        top = hi[1] - centre[1]
        pitch_x, pitch_y = 1.08 * width, (top - label_y) + 0.08 * height
        motion_pitch = (top - lowest) + 0.06 * height if motion else 0.0  # a motion row has no labels
        block = pitch_y + motion_pitch
        legend_h = 4.5 * label_size if motion else 0.0
        motion_mat = motion_material() if motion else None
        text_mat = bpy.data.materials.new("PDE label")
        materials += [m for m in (motion_mat, text_mat) if m is not None]
        text_mat.diffuse_color = (0.9, 0.9, 0.9, 1)
        compat.use_nodes(text_mat)
        bsdf = text_mat.node_tree.nodes.get("Principled BSDF")
        if bsdf is not None:
            bsdf.inputs["Base Color"].default_value = (0.9, 0.9, 0.9, 1)
        skin = bridge.skin_material() if pde is obj else None
        places = [divmod(i, columns) for i in range(len(cells))]
        for (label, _), (r, c) in zip(cells, places):  # labels are light: all of them, in every band
            _text(scene, f"label {label}", label.replace("_", " "), label_size,
                  (c * pitch_x, -r * block + label_y, hi[2] - centre[2]), text_mat)
        if motion:
            _legend(scene, -width / 2, top + 0.04 * height - rows * block - 0.5 * label_size,
                    max(1.0, min(3.0, columns - 1.5)) * pitch_x, label_size, hi[2] - centre[2], motion_mat, text_mat)
        cam_data = bpy.data.cameras.new("sheet camera")
        cam_data.type = "ORTHO"
        sheet_w, sheet_h = columns * pitch_x, rows * block + legend_h
        cam_data.ortho_scale = max(sheet_w, sheet_h)
        cam = bpy.data.objects.new("sheet camera", cam_data)
        sheet_top = top + 0.04 * height
        cam.location = ((columns - 1) * pitch_x / 2, sheet_top - sheet_h / 2, 500)
        cam_data.clip_end = 2000
        scene.collection.objects.link(cam)
        scene.camera = cam
        light = bpy.data.objects.new("sheet light", bpy.data.lights.new("sheet light", "SUN"))
        light.data.energy = 3.0
        light.rotation_euler = (math.radians(-25), math.radians(20), 0)
        scene.collection.objects.link(light)
        scene.world = bpy.data.worlds.new("sheet world")
        scene.world.color = (0.05, 0.05, 0.06)
        scene.render.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = samples
        scene.cycles.use_denoising = _has_denoiser()
        if hasattr(scene.cycles, "denoising_quality"):  # 4.1+: the high-quality filter costs minutes at this size
            scene.cycles.denoising_quality = "FAST"
        scene.cycles.denoising_prefilter = "FAST"
        scene.render.resolution_x = columns * cell
        scene.render.resolution_y = int(round(columns * cell * sheet_h / sheet_w))
        scene.render.resolution_percentage = 100
        cam_data.sensor_fit = "HORIZONTAL" if sheet_w >= sheet_h else "VERTICAL"
        # A mesh's world y extent: its cell's place plus the pose's own extent.
        extents = [(float(V[:, 1].min()) - centre[1], float(V[:, 1].max()) - centre[1]) for V in posed]
        meshes = []  # (label, vertices, x, y, y extent, motion)
        for i, ((label, _), V, (r, c)) in enumerate(zip(cells, posed, places)):
            cy, (y0, y1) = -r * block, extents[i]
            meshes.append((label, V, c * pitch_x, cy, (cy + y0, cy + y1), False))
            if motion:
                meshes.append((label, V, c * pitch_x, cy - pitch_y, (cy - pitch_y + y0, cy - pitch_y + y1), True))

        def add_mesh(label, V, x, y, moved):
            cell_mesh.vertices = V - centre
            me = bridge.new_mesh(f"{'motion' if moved else 'sheet'} {label}", cell_mesh)
            if moved:
                set_motion(me, V - neutral)
                me.materials.append(motion_mat)
            elif pde is obj:
                me.materials.append(skin)
            else:  # the user's own materials, per polygon
                for m in obj.data.materials:
                    me.materials.append(m)
                me.polygons.foreach_set("material_index", bridge.polygon_materials(obj.data))
                me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), bool))
            o = bpy.data.objects.new(me.name, me)
            o.location = (x, y, 0)
            if moved:
                _camera_only(o)
            scene.collection.objects.link(o)
            return o

        view_h = cam_data.ortho_scale * (1.0 if cam_data.sensor_fit == "VERTICAL" else
                                         scene.render.resolution_y / scene.render.resolution_x)
        image_top = cam.location.y + view_h / 2
        height_px = scene.render.resolution_y
        # Strips: each row of faces with its labels, and each motion row; a band is a few whole strips.
        strip_tops = [sheet_top - r * block - m for r in range(rows) for m in ((0.0, pitch_y) if motion else (0.0,))]
        per_band = len(strip_tops) if not band_vertices else max(1, band_vertices // (columns * len(cell_mesh.vertices)))
        cuts = [0] + [min(height_px, max(0, round((image_top - y) / view_h * height_px)))
                      for y in strip_tops[per_band::per_band]] + [height_px]
        bands = []
        with tempfile.TemporaryDirectory(prefix="pdeface_sheet_") as tmp:
            for b, (p0, p1) in enumerate(itertools.pairwise(cuts)):
                if p1 <= p0:
                    continue
                band_top, band_bottom = (image_top - p * view_h / height_px for p in (p0, p1))
                shown = [add_mesh(label, V, x, y, moved) for label, V, x, y, (y0, y1), moved in meshes
                         if y1 >= band_bottom and y0 <= band_top]
                bands.append(_render_band(scene, Path(tmp) / f"band_{b:03d}.png", p0, p1, len(cuts) > 2))
                for o in shown:
                    data = o.data
                    bpy.data.objects.remove(o, do_unlink=True)
                    bpy.data.meshes.remove(data)
        write_png(path, np.concatenate(bands))
    finally:
        for o in list(scene.collection.objects):
            data = o.data
            bpy.data.objects.remove(o, do_unlink=True)
            if isinstance(data, bpy.types.Mesh):
                bpy.data.meshes.remove(data)
            elif isinstance(data, bpy.types.Curve):
                bpy.data.curves.remove(data)
        bpy.data.scenes.remove(scene)
        for m in materials:
            bpy.data.materials.remove(m)
    return Path(path), [c[0] for c in cells]


def _render_band(scene, path, top, bottom, border):
    """Render pixel rows ``top`` to ``bottom`` (from the top) of ``scene``'s image to ``path`` (a render border
    cropped to them, with ``border``); returns them as (rows, width, 3) uint8, top row first."""
    height = scene.render.resolution_y
    scene.render.use_border = scene.render.use_crop_to_border = border
    # Blender truncates border × height to whole pixels: a quarter pixel up keeps a float's error off the edge.
    scene.render.border_min_x, scene.render.border_max_x = 0.0, 1.0
    scene.render.border_min_y = min(1.0, (height - bottom + 0.25) / height)
    scene.render.border_max_y = min(1.0, (height - top + 0.25) / height)
    compat.set_image_output(scene, path)
    with bpy.context.temp_override(scene=scene):
        bpy.ops.render.render(write_still=True, scene=scene.name)
    im = bpy.data.images.load(str(path))
    try:
        w, h = im.size
        px = np.empty(w * h * im.channels, np.float32)
        im.pixels.foreach_get(px)
        rgb = px.reshape(h, w, im.channels)[::-1, :, :3]  # Blender's rows run bottom-up
    finally:
        bpy.data.images.remove(im)
    if h != bottom - top or w != scene.render.resolution_x:
        raise RuntimeError(f"contact sheet band rendered {w}x{h} pixels, not {scene.render.resolution_x}x"
                           f"{bottom - top}")
    return np.round(rgb * 255).astype(np.uint8)
