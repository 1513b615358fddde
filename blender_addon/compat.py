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
