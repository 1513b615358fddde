"""Operators: each reads Blender data, calls pdeface, writes back, reports.

Errors pdeface raises on purpose (``PdeFaceError``) become ``self.report``
errors, never tracebacks. Shape keys this add-on made are listed on the face
(``obj.pdeface.keys``); the user's own keys, drivers and keyframes are never
deleted or renamed.
"""
import math

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from . import bridge, compat

MIX_KEY = "PDE Mix"


def _pd():
    """The pdeface modules the operators use (imported lazily: heavy, and only when needed)."""
    import pdeface.cli
    import pdeface.au.expressions
    import pdeface.au.facs
    import pdeface.surface.fit
    import pdeface.surface.frame
    import pdeface.surface.model
    import pdeface.au.retarget
    return pdeface


def active_face(context):
    obj = context.active_object
    return obj if obj is not None and obj.type == "MESH" and obj.pdeface.is_face else None


def au_key_name(d):
    return f"AU{d.key} {d.name}"


def expression_key_name(name):
    return f"Expr {name}"


def all_presets(context):
    """Built-in presets plus the user's preset file (if set and valid)."""
    pd = _pd()
    presets = dict(pd.expressions.PRESETS)
    path = bpy.path.abspath(context.scene.pdeface.presets_file) if context.scene else ""
    if path:
        presets.update({p.name: p for p in pd.expressions.load_presets(path)})
    return presets


_preset_items = []  # Blender needs the enum items kept alive


def preset_items(self, context):
    _preset_items.clear()
    try:
        names = list(all_presets(context))
    except Exception:  # a broken user file must not break the UI; the operator reports it
        names = list(_pd().expressions.PRESETS)
    _preset_items.extend((n, n.replace("_", " "), "") for n in names)
    return _preset_items


class _FaceOperator:
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if active_face(context) is None:
            cls.poll_message_set("Select a PDE face (Add default PDE face, or fit one to a mesh)")
            return False
        return True

    def execute(self, context):
        from pdeface.errors import PdeFaceError
        try:
            return self.run(context)
        except PdeFaceError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}


def managed(obj, kind=None):
    """(entry, key block) of our shape keys still present on the object."""
    blocks = obj.data.shape_keys.key_blocks if obj.data.shape_keys else {}
    return [(e, blocks[e.name]) for e in obj.pdeface.keys if e.name in blocks and (kind is None or e.kind == kind)]


def new_face_object(context, name, model, resolution, matrix=None, source=None, data=None):
    pd = _pd()
    mesh = bridge.new_mesh(name, pd.fit.face_mesh(model, resolution))
    obj = bpy.data.objects.new(name, mesh)
    context.collection.objects.link(obj)
    if matrix is not None:
        obj.matrix_world = matrix
    obj.pdeface.is_face = True
    obj.pdeface.resolution = resolution
    obj.pdeface.source = source
    bridge.store_model(obj, model, data)
    mesh.materials.append(bridge.skin_material())
    for o in context.view_layer.objects:
        o.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    return obj


class PDEFACE_OT_add_default_face(bpy.types.Operator):
    """Add the bundled PDE face (ICT-FaceKit neutral, 63 AU descriptors)"""

    bl_idname = "pdeface.add_default_face"
    bl_label = "Add Default PDE Face"
    bl_options = {"REGISTER", "UNDO"}

    resolution: StringProperty(name="Resolution", default="default",
                               description="default, original, fine, or ROWS,COLS subdivisions")
    shape_keys: BoolProperty(name="Build shape keys", default=True)
    model_path: StringProperty(name="Face model", subtype="FILE_PATH",
                               description="A face model file (.npz) to add instead of the bundled face")

    @classmethod
    def poll(cls, context):
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode")
            return False
        return True

    def execute(self, context):
        from pdeface.errors import PdeFaceError
        try:
            pd = _pd()
            pd.fit.parse_resolution(self.resolution)
            from pdeface.assets import DEFAULT_FACE, asset_path
            path = bpy.path.abspath(self.model_path) if self.model_path else asset_path(DEFAULT_FACE)
            try:
                data = open(path, "rb").read()
            except OSError as exc:
                raise pd.errors.ModelFormatError(f"{path}: cannot open ({exc.strerror})") from None
            model = pd.model.model_from_bytes(data, str(path))
            obj = new_face_object(context, "PDE Face", model, self.resolution, data=data)
            obj.rotation_euler = (math.pi / 2, 0.0, 0.0)  # the face frame's +y up becomes Blender's +Z up
        except PdeFaceError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        if self.shape_keys:
            return bpy.ops.pdeface.build_shape_keys()
        self.report({"INFO"}, f"Added {obj.name}")
        return {"FINISHED"}


def read_landmarks(context, obj):
    """68 landmark positions (object space) from the chosen source."""
    pd = _pd()
    from pdeface.errors import LandmarkError
    s = context.scene.pdeface
    V = bridge.vertices(obj.data)
    if s.landmark_source == "FILE":
        path = bpy.path.abspath(s.landmark_file)
        if not path:
            raise LandmarkError("choose a landmarks JSON file")
        idx, pts = pd.frame.read_landmarks(path)
        return pd.frame.landmark_points(V, idx, pts)
    if s.landmark_source == "GROUP":
        group = obj.vertex_groups.get(s.landmark_group)
        if group is None:
            raise LandmarkError(f"{obj.name} has no vertex group {s.landmark_group!r}")
        members = [(g.weight, v.index) for v in obj.data.vertices for g in v.groups if g.group == group.index]
        if len(members) != 68:
            raise LandmarkError(f"vertex group {group.name!r} has {len(members)} vertices; it needs the 68 landmarks")
        order = [i for _, i in sorted(members)]
        return V[order]
    import bmesh
    bm = bmesh.new()
    try:
        bm.from_mesh(obj.data)
        hist = [e.index for e in bm.select_history if isinstance(e, bmesh.types.BMVert)]
    finally:
        bm.free()
    if len(hist) != 68:
        raise LandmarkError(f"{len(hist)} vertices selected in order; select the 68 landmarks one by one in Edit Mode")
    return V[hist]


class PDEFACE_OT_fit_to_selected(bpy.types.Operator):
    """Fit a PDE face to the selected mesh, beside it, with the bundled AU descriptors retargeted to it"""

    bl_idname = "pdeface.fit_to_selected"
    bl_label = "Fit PDE Face to Selected"
    bl_options = {"REGISTER", "UNDO"}

    resolution: StringProperty(name="Resolution", default="default")
    retarget: BoolProperty(name="Retarget AU descriptors", default=True)

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode")
            return False
        if obj is None or obj.type != "MESH" or obj.pdeface.is_face:
            cls.poll_message_set("Select the neutral face mesh to fit (not a PDE face)")
            return False
        return True

    def execute(self, context):
        from pdeface.errors import PdeFaceError
        pd = _pd()
        src = context.active_object
        wm = context.window_manager
        wm.progress_begin(0, 4)
        try:
            compat.set_status(context, "PDE Face: reading landmarks")
            landmarks = read_landmarks(context, src)
            wm.progress_update(1)
            V = bridge.vertices(src.data)
            T, _ = bridge.triangles(src.data)
            if len(T) == 0:
                raise PdeFaceError(f"{src.name} has no faces")
            unit = None if context.scene.pdeface.unit == "AUTO" else context.scene.pdeface.unit
            compat.set_status(context, "PDE Face: fitting curves")
            model, sampler = pd.fit.fit_face(V, T, landmarks, unit=unit, source=src.name)
            wm.progress_update(2)
            if self.retarget:
                model = pd.retarget.retarget(pd.cli.load_face("default"), model)
            wm.progress_update(3)
            obj = new_face_object(context, f"PDE {src.name}", model, self.resolution, src.matrix_world.copy(), src)
            wm.progress_update(4)
        except PdeFaceError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
            compat.set_status(context, None)
        filled = int((sampler.status != 0).sum())
        self.report({"INFO"}, f"Fitted {obj.name}: {model.layout.n_curves} curves, unit {model.frame.unit}, "
                              f"{filled} curve points filled over openings")
        return {"FINISHED"}


class PDEFACE_OT_build_shape_keys(_FaceOperator, bpy.types.Operator):
    """Basis = neutral PDE face; one shape key per AU and per expression preset (range 0-1).
Rebuilding updates these keys in place; your own keys are left alone"""

    bl_idname = "pdeface.build_shape_keys"
    bl_label = "Build Shape Keys"

    expressions: BoolProperty(name="Expression keys", default=True)

    def run(self, context):
        pd = _pd()
        obj = active_face(context)
        model = bridge.face_model(obj)
        presets = all_presets(context) if self.expressions else {}  # read every input before writing anything
        if not model.descriptors:
            raise pd.errors.PdeFaceError(f"{obj.name}'s model carries no AU descriptors")
        basis = pd.expressions.ShapeBasis(model, obj.pdeface.resolution, dtype=np.float64)
        if len(basis.neutral) != len(obj.data.vertices):
            raise pd.errors.PdeFaceError(
                f"{obj.name} has {len(obj.data.vertices)} vertices, its model meshes to {len(basis.neutral)}: "
                "the mesh was edited; add the face again")
        if obj.data.shape_keys is None:
            obj.shape_key_add(name="Basis", from_mix=False)
        ref = obj.data.shape_keys.reference_key
        bridge.set_key_coords(ref, basis.neutral)
        obj.data.vertices.foreach_set("co", basis.neutral.astype(np.float32).ravel())
        regions = {au: a.region for au, a in pd.facs.catalogue().items()}
        made = updated = skipped = 0
        entries = {e.name: e for e in obj.pdeface.keys}
        blocks = obj.data.shape_keys.key_blocks

        def put(name, coords, kind, au_key="", label=""):
            nonlocal made, updated, skipped
            if name in blocks and name not in entries:
                skipped += 1  # the user's own key of that name: not ours to touch
                return
            kb = blocks.get(name)
            if kb is None:
                kb = obj.shape_key_add(name=name, from_mix=False)
                kb.value = 0.0  # new keys start at 1 in Blender 5.0
                made += 1
            else:
                updated += 1
            kb.slider_min, kb.slider_max = 0.0, 1.0
            bridge.set_key_coords(kb, coords)
            e = entries.get(name)
            if e is None:
                e = obj.pdeface.keys.add()
                e.name = name
                entries[name] = e
            e.kind, e.au_key, e.label = kind, au_key, label or name
            e.region = regions.get(int(au_key.rstrip("LR")), "lower") if au_key else ""

        for i, d in enumerate(model.descriptors):
            put(au_key_name(d), basis.neutral + basis.deltas[i].reshape(-1, 3), "AU", d.key, d.label)
        n_expr = 0
        if self.expressions:
            available = set(basis.keys)
            for name, preset in presets.items():
                weights, _ = pd.expressions.resolve_preset(preset, available)
                if not weights:
                    continue
                if preset.mixer == "sum":
                    coords = basis.vertices(basis.weights_matrix(weights))[0]
                else:
                    C, R = pd.expressions.pose_curves(model, weights, preset.mixer)
                    coords = pd.fit.face_mesh(model, obj.pdeface.resolution, coefficients=C, residual=R).vertices
                put(expression_key_name(name), coords, "EXPRESSION", label=f"{name} ({preset.description})")
                n_expr += 1
        obj.data.update()
        msg = f"{obj.name}: {made} shape keys made, {updated} updated ({len(model.descriptors)} AUs, {n_expr} expressions)"
        if skipped:
            msg += f"; {skipped} left alone (your own keys share those names)"
            self.report({"WARNING"}, msg)
        else:
            self.report({"INFO"}, msg)
        return {"FINISHED"}


def set_pose(obj, values, kinds=("AU", "EXPRESSION", "MIX")):
    """Set our keys of ``kinds``: listed ones to their value, the others to 0."""
    for e, kb in managed(obj):
        if e.kind in kinds:
            kb.value = values.get(e.name, 0.0)


class PDEFACE_OT_apply_preset(_FaceOperator, bpy.types.Operator):
    """Pose the face with an expression preset"""

    bl_idname = "pdeface.apply_preset"
    bl_label = "Apply Expression"

    preset: EnumProperty(name="Preset", items=preset_items)
    mode: EnumProperty(name="Apply as", items=[("SCENE", "Panel setting", ""), ("AUS", "AU weights", ""),
                                               ("KEY", "Expression key", "")], default="SCENE")
    weight: FloatProperty(name="Weight", default=1.0, min=0.0, max=1.0)

    def run(self, context):
        pd = _pd()
        obj = active_face(context)
        s = context.scene.pdeface
        mode = s.preset_mode if self.mode == "SCENE" else self.mode
        presets = all_presets(context)
        if self.preset not in presets:
            raise pd.errors.PdeFaceError(f"unknown preset {self.preset!r}")
        preset = presets[self.preset]
        ours = {e.name: e for e, _ in managed(obj)}
        if mode == "KEY":
            name = expression_key_name(self.preset)
            if name not in ours:
                raise pd.errors.PdeFaceError(f"no {name!r} shape key: build shape keys first")
            set_pose(obj, {name: self.weight})  # AU keys to 0: the expression key already holds them
            self.report({"INFO"}, f"{self.preset} as its own key at {self.weight:g}")
            return {"FINISHED"}
        model = bridge.face_model(obj)
        weights, missing = pd.expressions.resolve_preset(preset, {d.key for d in model.descriptors})
        weights = {k: w * self.weight for k, w in weights.items()}
        mixer = s.mixer if s.mixer != "sum" else preset.mixer
        by_key = {e.au_key: name for name, e in ours.items() if e.kind == "AU"}
        if mixer == "sum":
            set_pose(obj, {by_key[k]: w for k, w in weights.items() if k in by_key})
        else:
            write_mix_key(obj, model, weights, mixer)
        note = f" (no descriptor for AU {', '.join(missing)})" if missing else ""
        self.report({"INFO"}, f"{self.preset} as AU weights, {mixer} mixer{note}")
        return {"FINISHED"}


def write_mix_key(obj, model, weights, mixer):
    """Average and max are not linear: the mixed pose goes into one key of its own, at 1."""
    pd = _pd()
    C, R = pd.expressions.pose_curves(model, weights, mixer)
    coords = pd.fit.face_mesh(model, obj.pdeface.resolution, coefficients=C, residual=R).vertices
    if obj.data.shape_keys is None:
        raise pd.errors.PdeFaceError("build shape keys first")
    blocks = obj.data.shape_keys.key_blocks
    kb = blocks.get(MIX_KEY)
    if kb is not None and MIX_KEY not in {e.name for e in obj.pdeface.keys}:
        raise pd.errors.PdeFaceError(f"a shape key named {MIX_KEY!r} is yours; rename it to use the {mixer} mixer")
    if kb is None:
        kb = obj.shape_key_add(name=MIX_KEY, from_mix=False)
        kb.value = 0.0
        e = obj.pdeface.keys.add()
        e.name, e.kind, e.label = MIX_KEY, "MIX", "mixed pose"
    kb.slider_min, kb.slider_max = 0.0, 1.0
    bridge.set_key_coords(kb, coords)
    set_pose(obj, {MIX_KEY: 1.0})


class PDEFACE_OT_reset_pose(_FaceOperator, bpy.types.Operator):
    """Set every PDE Face shape key to 0 (neutral)"""

    bl_idname = "pdeface.reset_pose"
    bl_label = "Reset to Neutral"

    def run(self, context):
        set_pose(active_face(context), {})
        return {"FINISHED"}


class PDEFACE_OT_keyframe_pose(_FaceOperator, bpy.types.Operator):
    """Keyframe the current AU and expression weights at the current frame"""

    bl_idname = "pdeface.keyframe_pose"
    bl_label = "Keyframe Pose"

    def run(self, context):
        obj = active_face(context)
        frame = context.scene.frame_current
        keys = managed(obj)
        for _, kb in keys:
            kb.keyframe_insert("value", frame=frame)
        self.report({"INFO"}, f"Keyframed {len(keys)} shape keys at frame {frame}")
        return {"FINISHED"}


class PDEFACE_OT_animate_sequence(_FaceOperator, bpy.types.Operator):
    """Keyframe a sequence of expressions: neutral → expression → neutral → next (or expression → expression)"""

    bl_idname = "pdeface.animate_sequence"
    bl_label = "Animate Sequence"

    presets: StringProperty(name="Presets", default="", description="Comma-separated; empty: the panel's sequence")
    start: IntProperty(name="Start frame", default=-1, description="-1: the current frame")
    hold: IntProperty(name="Hold", default=-1, min=-1)
    blend: IntProperty(name="Blend", default=-1, min=-1)
    mode: StringProperty(name="Path", default="", description="via_neutral or direct; empty: the panel's")
    channels: StringProperty(name="Animate", default="", description="KEY or AUS; empty: the panel's")

    def run(self, context):
        pd = _pd()
        from pdeface.au.sequence import sequence_keys
        obj = active_face(context)
        s = context.scene.pdeface
        names = [n.strip() for n in (self.presets or s.sequence).split(",") if n.strip()]
        presets = all_presets(context)
        unknown = [n for n in names if n not in presets]
        if unknown:
            raise pd.errors.PdeFaceError(f"unknown preset(s): {', '.join(unknown)}")
        channels = self.channels or s.sequence_channels
        ours = {e.name: e for e, _ in managed(obj)}
        poses = []
        if channels == "KEY":
            for n in names:
                if expression_key_name(n) not in ours:
                    raise pd.errors.PdeFaceError(f"no {expression_key_name(n)!r} shape key: build shape keys first")
                poses.append({expression_key_name(n): 1.0})
        else:
            by_key = {e.au_key: name for name, e in ours.items() if e.kind == "AU"}
            for n in names:
                w, _ = pd.expressions.resolve_preset(presets[n], set(by_key))
                poses.append({by_key[k]: v for k, v in w.items()})
        start = context.scene.frame_current if self.start < 0 else self.start
        keys = sequence_keys(poses, start, s.sequence_hold if self.hold < 0 else self.hold,
                             s.sequence_blend if self.blend < 0 else self.blend, self.mode or s.sequence_mode)
        blocks = obj.data.shape_keys.key_blocks
        for frame, pose in keys:
            for name, value in pose.items():
                kb = blocks[name]
                kb.value = value
                kb.keyframe_insert("value", frame=frame)
        last = keys[-1][0]
        if context.scene.frame_end < last:
            context.scene.frame_end = last
        set_pose(obj, {})
        context.scene.frame_set(context.scene.frame_current)
        self.report({"INFO"}, f"Animated {len(names)} expressions over frames {start}-{last}")
        return {"FINISHED"}


def apply_timeline(obj, timeline):
    """Keyframe the face's shape keys from a pdeface Timeline.

    Returns (first frame, last frame, channels the face lacks).
    """
    ours = {e.name: e for e, _ in managed(obj)}
    by_au = {e.au_key: name for name, e in ours.items() if e.kind == "AU"}
    aus, presets = timeline.channels()
    missing = [f"AU{a}" for a in aus if a not in by_au] + [p for p in presets if expression_key_name(p) not in ours]
    names = [by_au[a] for a in aus if a in by_au] + [expression_key_name(p) for p in presets
                                                        if expression_key_name(p) in ours]
    blocks = obj.data.shape_keys.key_blocks
    prefs = bpy.context.preferences.edit
    saved = prefs.keyframe_new_interpolation_type
    try:
        for key in timeline.keys:
            # New keys take the user-preference interpolation: the one way that works on 4.2-5.0.
            prefs.keyframe_new_interpolation_type = key.interpolation.upper()
            values = {by_au[a]: w for a, w in key.aus.items() if a in by_au}
            values.update({expression_key_name(p): w for p, w in key.presets.items() if expression_key_name(p) in ours})
            for name in names:
                kb = blocks[name]
                kb.value = values.get(name, 0.0)
                kb.keyframe_insert("value", frame=key.frame)
    finally:
        prefs.keyframe_new_interpolation_type = saved
    return timeline.keys[0].frame, timeline.frame_end, missing


class PDEFACE_OT_import_au(_FaceOperator, bpy.types.Operator):
    """Keyframe the face from AU data a tracker wrote (OpenFace, Py-Feat, Live Link Face CSV, FAS text) or a timeline"""

    bl_idname = "pdeface.import_au"
    bl_label = "Import AU Data"

    filepath: StringProperty(name="File", subtype="FILE_PATH")
    format: EnumProperty(name="Format", default="auto",
                         items=[(f, f, "") for f in ("auto", "openface", "pyfeat", "livelink", "fas", "timeline")])
    fps: FloatProperty(name="FPS", default=0.0, min=0.0, description="0: the scene's frame rate")
    smooth: IntProperty(name="Smooth", default=1, min=1, description="Moving-average window (samples)")
    reduce: FloatProperty(name="Reduce", default=0.0, min=0.0, max=0.5, description="Keyframe reduction tolerance")
    hold: FloatProperty(name="Hold", default=0.5, min=0.01, description="Seconds per FAS AU set")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def run(self, context):
        from pdeface.io.trackers import import_au
        from pdeface.io.timeline import load_timeline
        obj = active_face(context)
        if not self.filepath:
            raise _pd().errors.PdeFaceError("choose an AU data file")
        path = bpy.path.abspath(self.filepath)
        fps = self.fps or context.scene.render.fps / context.scene.render.fps_base
        if self.format == "timeline" or (self.format == "auto" and path.lower().endswith(".json")):
            timeline, note = load_timeline(path), ""
        else:
            r = import_au(path, self.format, fps, self.hold, self.smooth, self.reduce)
            timeline = r.timeline
            note = f"; {r.dropped} rows dropped" if r.dropped else ""
            if r.unknown:
                self.report({"WARNING"}, f"not FACS AUs / not mapped, ignored: {', '.join(map(str, r.unknown))}")
        first, last, missing = apply_timeline(obj, timeline)
        if context.scene.frame_end < last:
            context.scene.frame_end = last
        if missing:
            self.report({"WARNING"}, f"this face has no shape key for {', '.join(missing)}")
        self.report({"INFO"}, f"Keyframed {len(timeline.keys)} keys, frames {first}-{last}{note}")
        return {"FINISHED"}


class PDEFACE_OT_transfer_texture(_FaceOperator, bpy.types.Operator):
    """UVs for the PDE face: from the scan by closest point (the method's texturing) or a fresh xatlas atlas"""

    bl_idname = "pdeface.transfer_texture"
    bl_label = "Transfer Texture"

    method: EnumProperty(name="UVs", items=[("SCENE", "Panel setting", ""), ("CLOSEST", "From scan", ""),
                                            ("ATLAS", "Fresh atlas", "")], default="SCENE")

    def run(self, context):
        pd = _pd()
        from pdeface.surface.texture import atlas_uvs, transfer_uvs
        obj = active_face(context)
        s = context.scene.pdeface
        method = s.texture_method if self.method == "SCENE" else self.method
        me = obj.data
        if method == "ATLAS":
            F = np.array([list(p.vertices) for p in me.polygons])
            uv = atlas_uvs(bridge.vertices(me), F)
            bridge.set_loop_uvs(me, "Atlas UV", uv.reshape(-1, 2))
            self.report({"INFO"}, f"{obj.name}: fresh UV atlas 'Atlas UV'")
            return {"FINISHED"}
        src = s.texture_source or obj.pdeface.source
        if src is None or src.type != "MESH":
            raise pd.errors.PdeFaceError("choose the scan to take UVs from (Scan field)")
        if src.pdeface.is_face:
            raise pd.errors.PdeFaceError(f"{src.name} is a PDE face: choose the scan to take UVs from")
        if not src.data.uv_layers:
            raise pd.errors.PdeFaceError(f"{src.name} has no UV map")
        T, L = bridge.triangles(src.data)
        corner_uv = bridge.loop_uvs(src.data)[L]
        loop_v = np.empty(len(me.loops), dtype=np.int32)
        me.loops.foreach_get("vertex_index", loop_v)
        uv, dist = transfer_uvs(bridge.world_vertices(obj), bridge.world_vertices(src), T, corner_uv)
        bridge.set_loop_uvs(me, "Scan UV", uv[loop_v])
        image = next((n.image for m in src.data.materials if m and m.node_tree for n in m.node_tree.nodes
                      if n.type == "TEX_IMAGE" and n.image), None)
        if image is not None:
            mat = bpy.data.materials.new(f"PDE {src.name} texture")
            compat.use_nodes(mat)
            nodes, links = mat.node_tree.nodes, mat.node_tree.links
            tex = nodes.new("ShaderNodeTexImage")
            tex.image = image
            uvn = nodes.new("ShaderNodeUVMap")
            uvn.uv_map = "Scan UV"
            links.new(uvn.outputs["UV"], tex.inputs["Vector"])
            links.new(tex.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
            if me.materials and me.materials[0] and me.materials[0].name.startswith("PDE Skin"):
                me.materials[0] = mat
            else:
                me.materials.append(mat)
        self.report({"INFO"}, f"{obj.name}: UVs from {src.name} (median distance {np.median(dist):.3g})"
                              + (f", textured with {image.name}" if image else ""))
        return {"FINISHED"}


class PDEFACE_OT_live_start(_FaceOperator, bpy.types.Operator):
    """Start the live link: AU packets over TCP drive the face's AU keys"""

    bl_idname = "pdeface.live_start"
    bl_label = "Start Live Link"

    def run(self, context):
        from . import live
        s = context.scene.pdeface
        if s.live_role == "LISTEN" and s.live_host not in ("127.0.0.1", "localhost", "::1") and not s.live_allow_remote:
            raise _pd().errors.PdeFaceError(f"listening on {s.live_host} opens the player to the network: "
                                            "tick 'Allow remote' to do that")
        obj = active_face(context)
        if not managed(obj, "AU"):
            raise _pd().errors.PdeFaceError("build shape keys first")
        try:
            host, port = live.start(obj, s.live_role, s.live_host, s.live_port, s.live_mode, s.live_rules,
                                    s.live_record, s.live_hz, s.mixer)
        except OSError as exc:
            raise _pd().errors.PdeFaceError(f"cannot {s.live_role.lower()} on {s.live_host}:{s.live_port}: "
                                            f"{exc.strerror or exc}") from None
        self.report({"INFO"}, f"Live link {'listening on' if s.live_role == 'LISTEN' else 'connecting to'} {host}:{port}")
        return {"FINISHED"}


class PDEFACE_OT_live_stop(bpy.types.Operator):
    """Stop the live link"""

    bl_idname = "pdeface.live_stop"
    bl_label = "Stop Live Link"

    @classmethod
    def poll(cls, context):
        from . import live
        if not live.running():
            cls.poll_message_set("The live link is not running")
            return False
        return True

    def execute(self, context):
        from . import live
        st = live.status()
        live.stop()
        self.report({"INFO"}, f"Live link stopped after {st.get('packets', 0)} packets")
        return {"FINISHED"}


_classes = (PDEFACE_OT_add_default_face, PDEFACE_OT_fit_to_selected, PDEFACE_OT_build_shape_keys,
            PDEFACE_OT_apply_preset, PDEFACE_OT_reset_pose, PDEFACE_OT_keyframe_pose, PDEFACE_OT_animate_sequence,
            PDEFACE_OT_import_au, PDEFACE_OT_transfer_texture, PDEFACE_OT_live_start, PDEFACE_OT_live_stop)


def register():
    for c in _classes:
        bpy.utils.register_class(c)


def unregister():
    from . import live
    live.stop()  # sockets and timers must not outlive the add-on
    for c in reversed(_classes):
        bpy.utils.unregister_class(c)
