"""Operators: each parses the context, calls the add-on's rooms (``face``, ``rigging``, ``keys``,
``muscles``, ``animation``, ``texturing``, ``live``), and says what it did.

Every operator runs through :class:`_Operator`: ``run`` returns its message
(reported as INFO), and errors pdeface raises on purpose (``PdeFaceError``)
become one ``self.report`` error and ``CANCELLED``, never a traceback, with
nothing written by then. Anything else is a bug: one line saying so in the
report, its traceback on the console.
"""
import traceback

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy.types import Operator
from pdeface.errors import PdeFaceError, one_line
from pdeface.fdt.quadratic import MODELS as FDT_MODELS
from pdeface.fdt.table import load_fdt
from pdeface.muscles.placement import MUSCLE_NAMES
from pdeface.threads import bounded_threads

from . import animation, compat, face, keys, landmarks, live, muscles, rigging, texturing, warm

#: How an unexpected exception's report starts (the tests look for it).
BUG = "pdeface internal error, please report it with the console's traceback"


class _Operator:
    """Runs ``self.run(context)``: its message becomes an INFO report, a PdeFaceError an ERROR report."""

    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        warm.wait()  # the core's warm-up (if still running) done first: nothing loaded from two threads
        try:
            with bounded_threads():  # BLAS threads that do not spin beside Blender's own (pdeface.threads)
                message = self.run(context)
        except PdeFaceError as exc:
            self.report({"ERROR"}, one_line(exc))
            return {"CANCELLED"}
        except Exception as exc:  # noqa: BLE001 - a bug: one line for the user, the traceback for its report
            if isinstance(exc, RuntimeError) and str(exc).startswith("Error: "):
                self.report({"ERROR"}, one_line(str(exc)[7:]))  # an operator it called reported this error
            else:
                traceback.print_exc()
                self.report({"ERROR"}, one_line(f"{BUG} ({type(exc).__name__}: {exc})"))
            return {"CANCELLED"}
        if isinstance(message, set):  # the result of an operator it handed over to
            return message
        if message:
            self.report({"INFO"}, message)
        return {"FINISHED"}


class _FaceOperator(_Operator):
    """An operator on the active PDE face."""

    @classmethod
    def poll(cls, context):
        if face.active_face(context) is None:
            cls.poll_message_set("Select a PDE face (Add default PDE face, or fit one to a mesh)")
            return False
        return True


class _ObjectModeOperator(_Operator):
    @classmethod
    def poll(cls, context):
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode")
            return False
        return True


class _UserMeshOperator(_ObjectModeOperator):
    """An operator on the user's active mesh (not a PDE face); ``select_message`` says what to select."""

    select_message = "Select a mesh (not a PDE face)"

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        if not super().poll(context):
            return False
        if obj is None or obj.type != "MESH" or obj.pdeface.is_face:
            cls.poll_message_set(cls.select_message)
            return False
        return True


class PDEFACE_OT_add_default_face(_ObjectModeOperator, Operator):
    """Add the bundled PDE face (ICT-FaceKit neutral, 63 AU descriptors from its shapes, 9 from muscles)"""

    bl_idname = "pdeface.add_default_face"
    bl_label = "Add Default PDE Face"

    resolution: StringProperty(name="Resolution", default="default",
                               description="default, original, fine, or ROWS,COLS subdivisions")
    shape_keys: BoolProperty(name="Build shape keys", default=True)
    model_path: StringProperty(name="Face model", subtype="FILE_PATH",
                               description="A face model file (.npz) to add instead of the bundled face")

    def run(self, context):
        obj = face.add_face(context, self.model_path, self.resolution)
        if self.shape_keys:
            return bpy.ops.pdeface.build_shape_keys()
        return f"Added {obj.name}"


class PDEFACE_OT_add_ict_head(_ObjectModeOperator, Operator):
    """Add ICT-FaceKit's whole head (eyes, teeth, lashes), rigged: every AU and expression key on it"""

    bl_idname = "pdeface.add_ict_head"
    bl_label = "Add ICT Head (rigged)"

    def run(self, context):
        obj = rigging.add_ict_head(context)
        return f"Added {obj.name}: {len(obj.data.shape_keys.key_blocks) - 1} keys on its {len(obj.data.vertices)} vertices"


class PDEFACE_OT_fit_to_selected(_UserMeshOperator, Operator):
    """Fit a PDE face to the selected mesh, beside it, with the bundled AU descriptors retargeted to it"""

    bl_idname = "pdeface.fit_to_selected"
    bl_label = "Fit PDE Face to Selected"

    resolution: StringProperty(name="Resolution", default="default")
    retarget: BoolProperty(name="Retarget AU descriptors", default=True)
    accept: BoolProperty(name="Accept anyway", default=False,
                         description="Fit with landmarks that fail the landmark gate, or with given ones (a file, a "
                                     "vertex group, selected vertices) on a mesh whose eyes are closed (as the "
                                     "CLI's --accept)")
    keys_on_mesh: BoolProperty(name="Keys on my mesh", default=True,
                               description="Put the AU and expression keys on the selected mesh(es) themselves: "
                                           "the active one's skin and the other selected objects of the head "
                                           "(eyes, teeth; selected alone, the other meshes of its collection). "
                                           "The PDE face stays hidden as their reference")

    select_message = "Select the neutral face mesh to fit (not a PDE face)"

    def run(self, context):
        s = context.scene.pdeface
        wm = context.window_manager

        def progress(step, message):
            wm.progress_update(step)
            compat.set_status(context, f"PDE Face: {message}")

        wm.progress_begin(0, 4)
        try:
            compat.set_status(context, "PDE Face: reading landmarks")
            points, note = face.read_landmarks(s, context.active_object)
            if note:
                self.report({"INFO"}, note)
            src = context.active_object
            unit = face.chosen_unit(s)
            note = face.check_landmarks(s, src, points, unit, self.accept)
            if note:
                self.report({"WARNING"}, note)
            r = None
            if self.keys_on_mesh:
                parts = rigging.head_parts(context, src)
                obj, model, sampler, r = rigging.fit_and_rig(context, src, points, unit, self.resolution,
                                                             self.retarget, progress, parts)
            else:
                obj, model, sampler = face.fit_face_object(context, src, points, unit, self.resolution,
                                                           self.retarget, progress)
            wm.progress_update(4)
        finally:
            wm.progress_end()
            compat.set_status(context, None)
        for note in r["notes"] if r else []:  # the binding's, as build_keys made it (not bound again to ask)
            self.report({"INFO"}, note)
        filled = int((sampler.status != 0).sum())
        msg = (f"Fitted {obj.name}: {model.layout.n_curves} curves, unit {model.frame.unit}, "
               f"{filled} curve points filled over openings")
        if r:
            msg += f"; {r['aus']} AU and {r['expressions']} expression keys on {r['objects'] - 1} object(s) of yours"
        for warning in r["warnings"] if r else []:  # what the user should change: a warning too
            self.report({"WARNING"}, warning)
        return msg


class PDEFACE_OT_find_landmarks(_UserMeshOperator, Operator):
    """Find the 68 landmarks on the selected mesh (any pose and unit) and show them as empties you can nudge;
Fit then uses them"""

    bl_idname = "pdeface.find_landmarks"
    bl_label = "Find Landmarks"

    select_message = "Select the head or body mesh to find the face on"

    def run(self, context):
        s = context.scene.pdeface
        obj = context.active_object
        compat.set_status(context, "PDE Face: finding landmarks")
        unit = face.chosen_unit(s)
        arrays = landmarks.mesh_arrays(obj)  # read once for the find and its gate
        try:
            _, found, seconds = landmarks.find(context, obj, unit, arrays)
        finally:
            compat.set_status(context, None)
        # on the points as the empties hold them (float32 in Blender): what Fit reads back, reusing this verdict
        verdict = landmarks.gate(obj, landmarks.empty_points(obj), unit, found.skin, arrays)
        if verdict.passed:
            return landmarks.summary(obj, found, seconds)
        self.report({"WARNING"}, f"{landmarks.summary(obj, found, seconds)}; they fail the landmark gate: "
                                 f"{verdict.message()}: move the highlighted empties, or Accept anyway")


class _LandmarksOperator(_ObjectModeOperator):
    """An operator on the landmarks of the active mesh (or of the mesh the active landmark empty belongs to)."""

    @classmethod
    def poll(cls, context):
        if not super().poll(context):
            return False
        if landmarks.mesh_of(context.active_object) is None:
            cls.poll_message_set("Select the mesh (not a PDE face) or one of its landmark empties")
            return False
        return True


class PDEFACE_OT_snap_landmarks(_LandmarksOperator, Operator):
    """Move every landmark empty onto the closest point of its mesh's surface (after dragging them)"""

    bl_idname = "pdeface.snap_landmarks"
    bl_label = "Snap Landmarks to Surface"

    def run(self, context):
        obj = landmarks.mesh_of(context.active_object)
        moved = landmarks.snap(context, obj)
        return f"Snapped the landmarks of {obj.name} onto its surface (the farthest moved {moved:.4g})"


class PDEFACE_OT_export_landmarks(_LandmarksOperator, Operator):
    """Write the landmark empties as the landmarks JSON the command line reads (--landmarks)"""

    bl_idname = "pdeface.export_landmarks"
    bl_label = "Export Landmarks"
    bl_options = {"REGISTER"}

    filepath: StringProperty(name="File", subtype="FILE_PATH")
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})
    check_existing: BoolProperty(default=True, options={"HIDDEN"})
    overwrite: BoolProperty(name="Overwrite", default=False, description="Replace an existing file")
    indices: BoolProperty(name="Vertex indices", default=False,
                          description="Write the nearest vertices' indices (hold whatever the exported file's "
                                      "axes and scale) instead of the points in the mesh's own coordinates")

    def invoke(self, context, event):
        if not self.filepath:
            self.filepath = f"{landmarks.mesh_of(context.active_object).name}_landmarks.json"
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def run(self, context):
        obj = landmarks.mesh_of(context.active_object)
        path = landmarks.export(obj, bpy.path.abspath(self.filepath), self.overwrite, self.indices)
        return f"Wrote the 68 landmarks of {obj.name} to {path}"


class PDEFACE_OT_import_landmarks(_LandmarksOperator, Operator):
    """Read a landmarks JSON ('indices' or 'points' in the mesh's own coordinates) as the mesh's landmark empties"""

    bl_idname = "pdeface.import_landmarks"
    bl_label = "Import Landmarks"

    filepath: StringProperty(name="File", subtype="FILE_PATH")
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def run(self, context):
        obj = landmarks.mesh_of(context.active_object)
        landmarks.import_file(context, obj, bpy.path.abspath(self.filepath))
        return f"Read 68 landmarks onto {obj.name}: edit the empties, then Fit"


class PDEFACE_OT_show_landmark_scheme(_LandmarksOperator, Operator):
    """Show the 68-point scheme's picture (numbers, groups) beside the mesh, as an image empty"""

    bl_idname = "pdeface.show_landmark_scheme"
    bl_label = "Show Landmark Scheme"

    def run(self, context):
        ref = landmarks.show_scheme(context, landmarks.mesh_of(context.active_object))
        return f"{ref.name}: the scheme beside the mesh"


class PDEFACE_OT_install_landmark_model(_Operator, Operator):
    """Download and install the face-landmark model (MediaPipe 0.10, Apache-2.0, about 100 MB) into this
extension's user folder, for Find Landmarks"""

    bl_idname = "pdeface.install_landmark_model"
    bl_label = "Install Landmark Model"
    bl_options = {"REGISTER"}

    def run(self, context):
        if not bpy.app.online_access:
            raise PdeFaceError("Blender is offline: allow online access (Preferences > System) to install the "
                               "landmark model, or install mediapipe 0.10.21 yourself")
        landmarks.install()
        return "Installed the landmark model: Find Landmarks is ready"


class PDEFACE_OT_build_shape_keys(_FaceOperator, Operator):
    """Basis = neutral PDE face; one shape key per AU and per expression preset (range 0-1).
Rebuilding updates these keys in place; your own keys are left alone"""

    bl_idname = "pdeface.build_shape_keys"
    bl_label = "Build Shape Keys"

    expressions: BoolProperty(name="Expression keys", default=True)

    def run(self, context):
        obj = face.active_face(context)
        presets = keys.all_presets(context.scene) if self.expressions else {}
        r = keys.build_keys(obj, presets)
        msg = (f"{obj.name}: {r['made']} shape keys made, {r['updated']} updated "
               f"({r['aus']} AUs, {r['expressions']} expressions)")
        if not r["skipped"]:
            return msg
        self.report({"WARNING"}, msg + f"; {r['skipped']} left alone (your own keys share those names)")


class PDEFACE_OT_add_mouth_bag(_FaceOperator, Operator):
    """Add a dark mouth bag behind the lips of your head (an object of its own, parented to it) that opens with the
    jaw keys: for a head with no mouth inside. Your mesh is not changed; every key is built again"""

    bl_idname = "pdeface.add_mouth_bag"
    bl_label = "Add Mouth Bag"

    def run(self, context):
        bag, r = rigging.add_mouth_bag(context, face.active_face(context))
        return (f"Added {bag.name} ({len(bag.data.vertices)} vertices) behind the lips; keys built again on "
                f"{r['objects'] - 1} object(s) of yours")


class PDEFACE_OT_cut_lips_open(_FaceOperator, Operator):
    """Cut your mesh's fused lips (one surface, as a voxel remesh leaves them) open along the line between them, then
    fit and rig it again so the lips part: this changes your mesh's topology (a few vertices added); your keys, UVs
    and materials carry over. Add a mouth bag after it"""

    bl_idname = "pdeface.cut_lips_open"
    bl_label = "Cut Lips Open"

    def run(self, context):
        new, added = rigging.cut_lips_open(context, face.active_face(context))
        for note in face.binding_notes(new):
            self.report({"WARNING"} if note in face.binding_warnings(new) else {"INFO"}, note)
        return f"Cut the lips of {new.pdeface.source.name} open ({added} vertices added) and fitted {new.name} again"


class PDEFACE_OT_apply_preset(_FaceOperator, Operator):
    """Pose the face with an expression preset"""

    bl_idname = "pdeface.apply_preset"
    bl_label = "Apply Expression"

    preset: EnumProperty(name="Preset", items=keys.preset_items)
    mode: EnumProperty(name="Apply as", items=[("SCENE", "Panel setting", ""), ("AUS", "AU weights", ""),
                                               ("KEY", "Expression key", "")], default="SCENE")
    weight: FloatProperty(name="Weight", default=1.0, min=0.0, max=1.0)

    def run(self, context):
        s = context.scene.pdeface
        mode = s.preset_mode if self.mode == "SCENE" else self.mode
        presets = keys.all_presets(context.scene)
        if self.preset not in presets:
            raise PdeFaceError(f"unknown preset {self.preset!r}")
        mixer, missing = keys.apply_preset(face.active_face(context), self.preset, presets[self.preset], mode,
                                           self.weight, keys.scene_mixer(s))
        if mixer is None:
            return f"{self.preset} as its own key at {self.weight:g}"
        note = f" (no descriptor for AU {', '.join(missing)})" if missing else ""
        return f"{self.preset} as AU weights, {mixer} mixer{note}"


class PDEFACE_OT_load_fdt(_FaceOperator, Operator):
    """Load a Facial Deformation Table (a .fdt.json file, or a bundled generic one by name) as one more shape
key on the face and the objects it drives"""

    bl_idname = "pdeface.load_fdt"
    bl_label = "Load FDT as Shape Key"

    filepath: StringProperty(name="FDT", subtype="FILE_PATH",
                             description="An .fdt.json file, or a bundled FDT: an AU key (12, 12L), a basic "
                                         "expression (happy, sad, ...) or paper-smile")
    model: EnumProperty(name="Model", items=[(m, m, "") for m in FDT_MODELS], default="3d",
                        description="Model of a bundled FDT: 3d (x', y', z' quadratic in x, y, z), 3d-surface, "
                                    "or the paper's 2d (no depth)")

    def invoke(self, context, event):
        if not self.filepath:
            context.window_manager.fileselect_add(self)
            return {"RUNNING_MODAL"}
        return self.execute(context)

    def run(self, context):
        if not self.filepath.strip():
            raise PdeFaceError("give an FDT file or a bundled FDT's name")
        path = self.filepath.strip()
        fdt = load_fdt(bpy.path.abspath(path) if path.startswith("//") else path, self.model)
        obj = face.active_face(context)
        if obj.data.shape_keys is None:
            raise PdeFaceError(f"{obj.name} has no shape keys yet: Build Shape Keys first")
        r = keys.add_fdt_key(obj, fdt)
        msg = f"{r['name']}: shape key on {r['objects']} object(s) ({r['made']} made, {r['updated']} updated)"
        if not r["skipped"]:
            return msg
        self.report({"WARNING"}, msg + f"; {r['skipped']} left alone (your own keys share that name)")


class PDEFACE_OT_record_muscle_au(_FaceOperator, Operator):
    """Store the muscle sliders as an AU: a descriptor (source muscle) in the face's model and its AU key,
as the FAS let users calibrate their own AUs"""

    bl_idname = "pdeface.record_muscle_au"
    bl_label = "Record as AU"

    au: StringProperty(name="AU", description="AU key: 13, 13L, 46R (default: the panel's)")
    replace: BoolProperty(name="Replace", default=False, description="Record over an AU the face has already")

    def run(self, context):
        s = context.scene.pdeface
        activations = list(s.muscles)
        if not any(activations):
            raise PdeFaceError("every muscle is at rest: contract some first")
        d = muscles.record_muscle_au(face.active_face(context), activations, self.au or s.muscle_au,
                                     self.replace or s.muscle_replace)
        return f"{d.label} recorded from {sum(1 for a in activations if a)} muscles ({len(d.curves)} curves)"


class PDEFACE_OT_load_muscle_au(_FaceOperator, Operator):
    """Set the muscle sliders to an AU's activations: one the face recorded, else the bundled muscle table's"""

    bl_idname = "pdeface.load_muscle_au"
    bl_label = "Load AU's Muscles"

    au: StringProperty(name="AU", description="AU key (default: the panel's)")

    def run(self, context):
        s = context.scene.pdeface
        key = self.au or s.muscle_au
        s.muscles, where = muscles.muscle_activations(face.active_face(context), key)
        return f"AU{key}: muscles from {where}"


class PDEFACE_OT_reset_muscles(_FaceOperator, Operator):
    """Relax every muscle (the muscle key goes to 0)"""

    bl_idname = "pdeface.reset_muscles"
    bl_label = "Relax All"

    def run(self, context):
        context.scene.pdeface.muscles = [0.0] * len(MUSCLE_NAMES)


class PDEFACE_OT_reset_pose(_FaceOperator, Operator):
    """Set every PDE Face shape key to 0 (neutral)"""

    bl_idname = "pdeface.reset_pose"
    bl_label = "Reset to Neutral"

    def run(self, context):
        keys.set_pose(face.active_face(context), {})


class PDEFACE_OT_keyframe_pose(_FaceOperator, Operator):
    """Keyframe the current AU and expression weights at the current frame"""

    bl_idname = "pdeface.keyframe_pose"
    bl_label = "Keyframe Pose"

    def run(self, context):
        frame = context.scene.frame_current
        n = animation.keyframe_pose(face.active_face(context), frame)
        return f"Keyframed {n} shape keys at frame {frame}"


class PDEFACE_OT_animate_sequence(_FaceOperator, Operator):
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
        scene, s = context.scene, context.scene.pdeface
        names = [n.strip() for n in (self.presets or s.sequence).split(",") if n.strip()]
        start = scene.frame_current if self.start < 0 else self.start
        last = animation.animate_sequence(scene, face.active_face(context), names, keys.all_presets(scene), start,
                                          s.sequence_hold if self.hold < 0 else self.hold,
                                          s.sequence_blend if self.blend < 0 else self.blend,
                                          self.mode or s.sequence_mode, self.channels or s.sequence_channels)
        return f"Animated {len(names)} expressions over frames {start}-{last}"


class PDEFACE_OT_import_au(_FaceOperator, Operator):
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
    capture_fps: FloatProperty(name="Capture FPS", default=0.0, min=0.0,
                               description="Rate of a Live Link Face timecode's frames; 0: read off the file")
    merge: BoolProperty(name="Merge", default=False,
                        description="Add to the face's animation instead of replacing it (your own keys are "
                                    "never touched)")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def run(self, context):
        if not self.filepath:
            raise PdeFaceError("choose an AU data file")
        fps = self.fps or animation.scene_fps(context.scene)
        timeline, dropped, unknown, notes = animation.read_au_file(bpy.path.abspath(self.filepath), self.format, fps,
                                                                   self.hold, self.smooth, self.reduce,
                                                                   self.capture_fps or None)
        for note in notes:
            self.report({"WARNING"}, note)
        if unknown:
            self.report({"WARNING"}, f"not FACS AUs / not mapped, ignored: {', '.join(map(str, unknown))}")
        first, last, missing = animation.apply_timeline(face.active_face(context), timeline, context.scene,
                                                        self.merge)
        if missing:
            self.report({"WARNING"}, f"this face has no shape key for {', '.join(missing)}")
        note = f"; {dropped} rows dropped" if dropped else ""
        return f"Keyframed {len(timeline.keys)} keys, frames {first}-{last}{note}"


class PDEFACE_OT_transfer_texture(_FaceOperator, Operator):
    """UVs for the PDE face: from the scan by closest point (the method's texturing) or a fresh xatlas atlas"""

    bl_idname = "pdeface.transfer_texture"
    bl_label = "Transfer Texture"

    method: EnumProperty(name="UVs", items=[("SCENE", "Panel setting", ""), ("CLOSEST", "From scan", ""),
                                            ("ATLAS", "Fresh atlas", "")], default="SCENE")

    def run(self, context):
        s = context.scene.pdeface
        obj = face.active_face(context)
        if (s.texture_method if self.method == "SCENE" else self.method) == "ATLAS":
            texturing.atlas(obj)
            return f"{obj.name}: fresh UV atlas {texturing.ATLAS_LAYER!r}"
        src = s.texture_source or obj.pdeface.source
        dist, image = texturing.from_scan(obj, src)
        return (f"{obj.name}: UVs from {src.name} (median distance {dist:.3g})"
                + (f", textured with {image.name}" if image else ""))


class PDEFACE_OT_live_start(_FaceOperator, Operator):
    """Start the live link: AU packets over TCP drive the face's AU keys"""

    bl_idname = "pdeface.live_start"
    bl_label = "Start Live Link"

    def run(self, context):
        s = context.scene.pdeface
        obj = face.active_face(context)
        host, port = live.start(obj, s.live_role, s.live_host, s.live_port, s.live_mode, s.live_rules,
                                s.live_record, s.live_hz, keys.scene_mixer(s), s.live_allow_remote,
                                token=s.live_token)
        return f"Live link {'listening on' if s.live_role == 'LISTEN' else 'connecting to'} {host}:{port}"


class PDEFACE_OT_live_stop(_Operator, Operator):
    """Stop the live link"""

    bl_idname = "pdeface.live_stop"
    bl_label = "Stop Live Link"

    @classmethod
    def poll(cls, context):
        if not live.running():
            cls.poll_message_set("The live link is not running")
            return False
        return True

    def run(self, context):
        packets = live.stop()
        return f"Live link stopped after {packets} packets"


_classes = (PDEFACE_OT_add_default_face, PDEFACE_OT_add_ict_head, PDEFACE_OT_fit_to_selected,
            PDEFACE_OT_find_landmarks, PDEFACE_OT_snap_landmarks, PDEFACE_OT_export_landmarks,
            PDEFACE_OT_import_landmarks, PDEFACE_OT_show_landmark_scheme, PDEFACE_OT_install_landmark_model,
            PDEFACE_OT_build_shape_keys, PDEFACE_OT_add_mouth_bag, PDEFACE_OT_cut_lips_open, PDEFACE_OT_apply_preset,
            PDEFACE_OT_load_fdt, PDEFACE_OT_record_muscle_au,
            PDEFACE_OT_load_muscle_au, PDEFACE_OT_reset_muscles, PDEFACE_OT_reset_pose, PDEFACE_OT_keyframe_pose, PDEFACE_OT_animate_sequence,
            PDEFACE_OT_import_au, PDEFACE_OT_transfer_texture, PDEFACE_OT_live_start, PDEFACE_OT_live_stop)


def register():
    for c in _classes:
        bpy.utils.register_class(c)


def unregister():
    live.stop()  # sockets and timers must not outlive the add-on
    landmarks.unregister()
    for c in reversed(_classes):
        bpy.utils.unregister_class(c)
