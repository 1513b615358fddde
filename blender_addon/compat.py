"""What differs between the Blender versions the add-on supports (4.2 LTS - 5.0)."""
import bpy

VERSION = bpy.app.version


def eevee_engine_id() -> str:
    """EEVEE's render engine id: 'BLENDER_EEVEE_NEXT' in 4.2-4.5, 'BLENDER_EEVEE' again from 5.0."""
    return "BLENDER_EEVEE" if VERSION >= (5, 0, 0) else "BLENDER_EEVEE_NEXT"


def render_engines() -> dict:
    """User-facing engine names → engine ids for this Blender."""
    return {"CYCLES": "CYCLES", "EEVEE": eevee_engine_id(), "WORKBENCH": "BLENDER_WORKBENCH"}


def set_status(context, text):
    """Status-bar text where there is a UI (no-op headless)."""
    workspace = getattr(context, "workspace", None)
    if workspace is not None and not bpy.app.background:
        workspace.status_text_set(text)


def use_nodes(material):
    """Give a material its node tree (always there from 5.0, where ``use_nodes`` is deprecated)."""
    if VERSION < (5, 0, 0) or material.node_tree is None:
        material.use_nodes = True


def set_video_output(scene, path):
    """FFmpeg MPEG-4/H.264 output (5.0 picks the media type first)."""
    im = scene.render.image_settings
    if hasattr(im, "media_type"):
        im.media_type = "VIDEO"
    im.file_format = "FFMPEG"
    scene.render.ffmpeg.format = "MPEG4"
    scene.render.ffmpeg.codec = "H264"
    scene.render.filepath = str(path)


def set_image_output(scene, path, file_format="PNG"):
    im = scene.render.image_settings
    if hasattr(im, "media_type"):
        im.media_type = "IMAGE"
    im.file_format = file_format
    im.color_mode = "RGB"
    scene.render.filepath = str(path)


def strips(sequence_editor):
    """The sequencer's strips ('sequences' before 4.4)."""
    return sequence_editor.strips if hasattr(sequence_editor, "strips") else sequence_editor.sequences


def fcurves_of(id_data):
    """The F-curves animating ``id_data`` (a collection with ``remove``), or None when it has none.

    Layered actions (4.4+) keep them in the channel bag of the ID's own slot;
    before, ``Action.fcurves`` (gone in 5.0).
    """
    ad = id_data.animation_data if id_data is not None else None
    if ad is None or ad.action is None:
        return None
    if VERSION >= (4, 4, 0):
        from bpy_extras.anim_utils import action_get_channelbag_for_slot
        bag = action_get_channelbag_for_slot(ad.action, ad.action_slot)
        return bag.fcurves if bag is not None else None
    return ad.action.fcurves
