"""The PDE Face tab of the 3D View sidebar."""
import bpy
from pdeface.facs import REGIONS
from pdeface.muscles.placement import MUSCLE_NAMES

from . import landmarks, live
from .face import active_face, chosen_unit, key_owner, landmark_origin
from .keys import managed, preset_items


class _Panel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "PDE Face"


class _FacePanel(_Panel):
    """A sub-panel shown while a PDE face is active: draws with ``draw_face(layout, settings, face)``."""

    bl_parent_id = "PDEFACE_PT_face"

    @classmethod
    def poll(cls, context):
        return active_face(context) is not None

    def draw(self, context):
        self.draw_face(self.layout, context.scene.pdeface, active_face(context))


def _sliders(layout, rows, text):
    """One slider per (entry, key block), labelled ``text(entry)``."""
    col = layout.column(align=True)
    for e, kb in rows:
        col.prop(kb, "value", text=text(e), slider=True)


class PDEFACE_PT_face(_Panel, bpy.types.Panel):
    bl_label = "PDE Face"

    def draw(self, context):
        layout = self.layout
        s = context.scene.pdeface
        obj = active_face(context)
        col = layout.column(align=True)
        col.operator("pdeface.add_default_face", icon="USER")
        col.operator("pdeface.add_ict_head", icon="MONKEY")
        box = layout.box()
        box.label(text="Fit to selected mesh")
        box.prop(s, "landmark_source")
        if s.landmark_source == "AUTO":
            if landmarks.model_available():
                box.operator("pdeface.find_landmarks", icon="EMPTY_DATA")
            else:
                box.label(text="Finding landmarks needs MediaPipe", icon="INFO")
                box.operator("pdeface.install_landmark_model", icon="IMPORT")
        if s.landmark_source in ("GROUP", "AUTO"):
            box.prop(s, "landmark_group")
        elif s.landmark_source == "FILE":
            box.prop(s, "landmark_file")
        box.prop(s, "unit")
        if s.unit == "CUSTOM":
            box.prop(s, "unit_mm")
        box.operator("pdeface.fit_to_selected", icon="MOD_MESHDEFORM")
        mesh = landmarks.mesh_of(context.active_object)
        if mesh is not None:  # the gate's, or its look at the mesh (landmarks given)
            _gate_verdict(box, s, mesh)
        if obj is not None:
            layout.label(text=f"Face: {obj.name}", icon="OBJECT_DATA")
            layout.operator("pdeface.build_shape_keys", icon="SHAPEKEY_DATA")
            if obj.pdeface.head_keys:
                row = layout.row(align=True)
                row.operator("pdeface.add_mouth_bag", icon="MESH_UVSPHERE")
                row.operator("pdeface.cut_lips_open", icon="SCULPTMODE_HLT")


def _gate_verdict(layout, settings, mesh):
    """The gate's last failure on ``mesh`` where it judged the landmarks the next Fit reads (:func:`_gate_failure`);
    one on other landmarks (the source switched since) only said to be stale. Returns the failing groups shown."""
    source, unit = landmark_origin(settings, mesh), chosen_unit(settings)
    failing = landmarks.failing_groups(mesh, source, unit)
    if failing:
        _gate_failure(layout, mesh, failing)
    elif landmarks.failing_groups(mesh):
        col = layout.column(align=True)
        col.label(text="The landmark gate's last failure is stale", icon="INFO")
        col.label(text=f"it judged {landmarks.verdict_source(mesh, unit) or 'other landmarks'}; Fit checks {source}")
    return failing


def _gate_failure(layout, mesh, failing):
    """The gate's ``failing`` groups, its one line, and Fit with them anyway (as the CLI's --accept)."""
    col = layout.column()
    col.alert = True
    col.label(text=f"Landmark gate: {', '.join(failing)} failed", icon="ERROR")
    for part in mesh.get(landmarks.GATE_PROP, "").split("; "):
        col.label(text=part)
    layout.operator("pdeface.fit_to_selected", text="Accept anyway and Fit", icon="CHECKMARK").accept = True


class PDEFACE_PT_landmarks(_Panel, bpy.types.Panel):
    """The guided landmark editor: the scheme's picture, the groups, the gate's verdict, snap, export, import."""

    bl_label = "Landmarks"
    bl_parent_id = "PDEFACE_PT_face"

    @classmethod
    def poll(cls, context):
        return landmarks.mesh_of(context.active_object) is not None

    def draw(self, context):
        layout = self.layout
        mesh = landmarks.mesh_of(context.active_object)
        failing = _gate_verdict(layout, context.scene.pdeface, mesh)
        layout.template_icon(icon_value=landmarks.scheme_icon(), scale=9.0)
        col = layout.column(align=True)
        for group, rows in landmarks.GROUPS.items():
            col.label(text=f"{group} {rows.start}-{rows.stop - 1}", icon="ERROR" if group in failing else "DOT")
        if landmarks.empties(mesh) is None:
            layout.label(text="No landmark empties yet: Find or Import Landmarks", icon="INFO")
        else:
            layout.label(text="Drag the empties to the scheme's places, then Snap and Fit", icon="INFO")
            layout.operator("pdeface.snap_landmarks", icon="SNAP_ON")
        row = layout.row(align=True)
        row.operator("pdeface.import_landmarks", icon="IMPORT")
        row.operator("pdeface.export_landmarks", icon="EXPORT")
        layout.operator("pdeface.show_landmark_scheme", icon="IMAGE_REFERENCE")


class PDEFACE_PT_action_units(_FacePanel, bpy.types.Panel):
    bl_label = "Action Units"

    def draw_face(self, layout, s, obj):
        layout.prop(s, "au_filter", icon="VIEWZOOM", text="")
        keys = managed(key_owner(bpy.context), "AU")
        if not keys:
            layout.label(text="No AU shape keys yet: Build Shape Keys", icon="INFO")
            return
        needle = s.au_filter.strip().lower()
        for region, title in REGIONS.items():
            rows = [(e, kb) for e, kb in keys if e.region == region and needle in e.label.lower()]
            if not rows:
                continue
            box = layout.box()
            box.label(text=title)
            _sliders(box, rows, lambda e: e.label)


class PDEFACE_PT_expressions(_FacePanel, bpy.types.Panel):
    bl_label = "Expressions"

    def draw_face(self, layout, s, obj):
        layout.row().prop(s, "mixer", expand=True)
        layout.prop(s, "preset_mode")
        layout.prop(s, "presets_file")
        grid = layout.grid_flow(columns=2, align=True)
        for name, label, _ in preset_items(None, bpy.context):
            op = grid.operator("pdeface.apply_preset", text=label)
            op.preset = name
        layout.operator("pdeface.reset_pose", icon="LOOP_BACK")
        layout.operator("pdeface.load_fdt", icon="FILE")
        _sliders(layout, managed(key_owner(bpy.context), "EXPRESSION"), lambda e: e.name)


class PDEFACE_PT_animation(_FacePanel, bpy.types.Panel):
    bl_label = "Animation"

    def draw_face(self, layout, s, obj):
        layout.operator("pdeface.keyframe_pose", icon="KEY_HLT")
        box = layout.box()
        box.prop(s, "sequence")
        row = box.row(align=True)
        row.prop(s, "sequence_hold")
        row.prop(s, "sequence_blend")
        box.prop(s, "sequence_mode")
        box.prop(s, "sequence_channels")
        box.operator("pdeface.animate_sequence", icon="ANIM")
        layout.operator("pdeface.import_au", icon="IMPORT")


class PDEFACE_PT_muscles(_FacePanel, bpy.types.Panel):
    bl_label = "Muscles"
    bl_options = {"DEFAULT_CLOSED"}

    def draw_face(self, layout, s, obj):
        col = layout.column(align=True)
        for i, name in enumerate(MUSCLE_NAMES):
            col.prop(s, "muscles", index=i, text=name.replace("_", " "), slider=True)
        if s.muscle_note:
            layout.label(text=s.muscle_note, icon="ERROR")
        layout.operator("pdeface.reset_muscles", icon="LOOP_BACK")
        row = layout.row(align=True)
        row.prop(s, "muscle_au")
        row.prop(s, "muscle_replace")
        row = layout.row(align=True)
        row.operator("pdeface.load_muscle_au", icon="IMPORT")
        row.operator("pdeface.record_muscle_au", icon="REC")


class PDEFACE_PT_live(_FacePanel, bpy.types.Panel):
    bl_label = "Live Link"
    bl_options = {"DEFAULT_CLOSED"}

    def draw_face(self, layout, s, obj):
        st = live.status()
        col = layout.column()
        col.enabled = not st["running"]
        col.prop(s, "live_role", expand=True)
        row = col.row(align=True)
        row.prop(s, "live_host")
        row.prop(s, "live_port")
        col.prop(s, "live_allow_remote")
        col.prop(s, "live_token")
        col.prop(s, "live_mode")
        col.prop(s, "live_rules")
        col.prop(s, "live_record")
        col.prop(s, "live_hz")
        if st["running"]:
            layout.operator("pdeface.live_stop", icon="PAUSE")
            box = layout.box()
            box.label(text=("Connected" if st["connected"] else "Waiting for a sender"),
                      icon="LINKED" if st["connected"] else "UNLINKED")
            box.label(text=f"Packets {st['packets']}, played {st['played']}, dropped {st['dropped']}, "
                           f"garbage {st['garbage']}")
            if st["controls_refused"] or st["refused"] or st["unauthenticated"] or st["auth_failures"]:
                box.label(text=f"Refused: {st['controls_refused']} stops, {st['refused']} connections, "
                               f"{st['unauthenticated'] + st['auth_failures']} without the token", icon="LOCKED")
            if st["latency_ms_p99"] is not None:
                box.label(text=f"Latency p50 {st['latency_ms_p50']:.1f} ms, p99 {st['latency_ms_p99']:.1f} ms")
        else:
            layout.operator("pdeface.live_start", icon="PLAY")


class PDEFACE_PT_texture(_FacePanel, bpy.types.Panel):
    bl_label = "Texture"
    bl_options = {"DEFAULT_CLOSED"}

    def draw_face(self, layout, s, obj):
        layout.prop(s, "texture_method")
        if s.texture_method == "CLOSEST":
            layout.prop(s, "texture_source")
        layout.operator("pdeface.transfer_texture", icon="TEXTURE")


_classes = (PDEFACE_PT_face, PDEFACE_PT_landmarks, PDEFACE_PT_action_units, PDEFACE_PT_expressions,
            PDEFACE_PT_animation, PDEFACE_PT_muscles, PDEFACE_PT_live, PDEFACE_PT_texture)


def register():
    for c in _classes:
        bpy.utils.register_class(c)


def unregister():
    for c in reversed(_classes):
        bpy.utils.unregister_class(c)
