"""UVs for a PDE face: from its scan by closest point (the method's texturing) or a fresh atlas."""
import bpy
import numpy as np
from pdeface.errors import PdeFaceError
from pdeface.surface.texture import atlas_uvs, transfer_uvs

from . import bridge, compat

CLOSEST_LAYER = "Scan UV"
ATLAS_LAYER = "Atlas UV"


def atlas(obj):
    """A fresh xatlas atlas in the ``Atlas UV`` layer (made active)."""
    me = obj.data
    F = np.array([list(p.vertices) for p in me.polygons])
    uv = atlas_uvs(bridge.vertices(me), F)
    bridge.set_loop_uvs(me, ATLAS_LAYER, uv.reshape(-1, 2))


def from_scan(obj, src):
    """The scan's UVs at each face vertex's closest point, in ``Scan UV``; the scan's image as material.

    Returns (median distance to the scan in scene units, the image or None).
    """
    if src is None or src.type != "MESH":
        raise PdeFaceError("choose the scan to take UVs from (Scan field)")
    if src.pdeface.is_face:
        raise PdeFaceError(f"{src.name} is a PDE face: choose the scan to take UVs from")
    if not src.data.uv_layers:
        raise PdeFaceError(f"{src.name} has no UV map")
    me = obj.data
    T, L = bridge.triangles(src.data)
    corner_uv = bridge.loop_uvs(src.data)[L]
    loop_v = np.empty(len(me.loops), dtype=np.int32)
    me.loops.foreach_get("vertex_index", loop_v)
    uv, dist = transfer_uvs(bridge.world_vertices(obj), bridge.world_vertices(src), T, corner_uv)
    bridge.set_loop_uvs(me, CLOSEST_LAYER, uv[loop_v])
    image = next((n.image for m in src.data.materials if m and m.node_tree for n in m.node_tree.nodes
                  if n.type == "TEX_IMAGE" and n.image), None)
    if image is not None:
        _texture_material(obj, src, image)
    return float(np.median(dist)), image


def _texture_material(obj, src, image):
    """A material showing ``image`` through ``Scan UV``, replacing our skin material (never the user's)."""
    me = obj.data
    mat = bpy.data.materials.new(f"PDE {src.name} texture")
    compat.use_nodes(mat)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    uvn = nodes.new("ShaderNodeUVMap")
    uvn.uv_map = CLOSEST_LAYER
    links.new(uvn.outputs["UV"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    if me.materials and me.materials[0] and me.materials[0].name.startswith("PDE Skin"):
        me.materials[0] = mat
    else:
        me.materials.append(mat)
