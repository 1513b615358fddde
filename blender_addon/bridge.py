"""Blender data ↔ numpy, and the face model stored in a PDE face object.

A PDE face keeps its model file's bytes (base64) on the object, so a .blend
is self-contained; decoded models are cached per object.
"""
import base64
import hashlib

import bpy
import numpy as np
from pdeface.au.modelfile import model_from_bytes, model_to_bytes
from pdeface.errors import PdeFaceError
from pdeface.mesh import Mesh

from . import compat

_models = {}


def vertices(mesh) -> np.ndarray:
    """(n, 3) vertex coordinates of a Blender mesh (object space)."""
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def world_vertices(obj) -> np.ndarray:
    M = np.array(obj.matrix_world)
    V = vertices(obj.data)
    return V @ M[:3, :3].T + M[:3, 3]


def triangles(mesh, loops=True):
    """Loop triangles: (t, 3) vertex indices and (t, 3) loop indices (None unless ``loops``: not read)."""
    mesh.calc_loop_triangles()
    n = len(mesh.loop_triangles)
    tv = np.empty(n * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", tv)
    if not loops:
        return tv.reshape(-1, 3).astype(np.int64), None
    tl = np.empty(n * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("loops", tl)
    return tv.reshape(-1, 3).astype(np.int64), tl.reshape(-1, 3).astype(np.int64)


def as_pdeface_mesh(mesh, V=None):
    """A Blender mesh's polygons as a pdeface Mesh (object space), corners in polygon order, with the active UV
    layer's coordinates where it has one; ``V (n, 3)``: at these vertices instead of the mesh's own (no UVs)."""
    counts = np.empty(len(mesh.polygons), dtype=np.int32)
    starts = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.polygons.foreach_get("loop_total", counts)
    mesh.polygons.foreach_get("loop_start", starts)
    corners = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", corners)
    first = np.repeat(np.cumsum(counts) - counts, counts)
    loops = np.repeat(starts, counts) + np.arange(counts.sum()) - first  # each polygon's loops, in polygon order
    own = V is None
    out = Mesh(vertices(mesh) if own else np.asarray(V, np.float64), counts.astype(np.int64),
               corners[loops].astype(np.int64))
    if own and mesh.uv_layers.active is not None:
        out.uvs, out.face_uv_indices = loop_uvs(mesh), loops.astype(np.int64)
    return out


def polygon_materials(mesh) -> np.ndarray:
    index = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.polygons.foreach_get("material_index", index)
    return index


def polygon_triangles(mesh, V) -> np.ndarray:
    """Triangles of each polygon as pdeface fans an OBJ's faces (:meth:`pdeface.mesh.Mesh.triangles`): triangles
    and quads from their first corner, an n-gon from its best corner at coordinates ``V (n, 3)`` (the rest shape).

    Blender's own loop triangles may split a quad along its other diagonal;
    binding a head on the same triangles as ``pdeface pose --mesh`` makes the
    keys equal to its poses.
    """
    return as_pdeface_mesh(mesh, V).triangles()[0]


def loop_uvs(mesh, layer=None) -> np.ndarray:
    layer = layer or mesh.uv_layers.active
    uv = np.empty(len(mesh.loops) * 2, dtype=np.float32)
    layer.data.foreach_get("uv", uv)
    return uv.reshape(-1, 2).astype(np.float64)


def set_loop_uvs(mesh, name, uv):
    """Write per-loop UVs into layer ``name`` (created if missing) and make it active."""
    layer = mesh.uv_layers.get(name) or mesh.uv_layers.new(name=name)
    layer.data.foreach_set("uv", np.asarray(uv, np.float32).ravel())
    mesh.uv_layers.active = layer
    return layer


def new_mesh(name, pde_mesh):
    """A Blender mesh from a pdeface Mesh (quads, parametric UVs, smooth shading)."""
    me = bpy.data.meshes.new(name)
    V = pde_mesh.vertices.astype(np.float32)
    counts = pde_mesh.face_counts
    me.vertices.add(len(V))
    me.vertices.foreach_set("co", V.ravel())
    me.loops.add(len(pde_mesh.face_indices))
    me.loops.foreach_set("vertex_index", pde_mesh.face_indices.astype(np.int32))
    me.polygons.add(len(counts))
    me.polygons.foreach_set("loop_start", pde_mesh.face_starts.astype(np.int32))
    me.update(calc_edges=True)
    me.polygons.foreach_set("use_smooth", np.ones(len(counts), dtype=bool))
    if pde_mesh.uvs is not None:
        set_loop_uvs(me, "UVMap", pde_mesh.uvs[pde_mesh.face_uv_indices])
    return me


def store_model(obj, model, data=None):
    """Keep the model on the object; ``data``: the file's bytes ``model`` was read from, when at hand (saves
    re-encoding, and reading them back: ``model`` is cached as what they read to).

    Encoded anew, the model is read back once it is asked for (:func:`face_model`): keys are made from what the
    .blend keeps, so a reopened file makes the same. Written ``fast`` (the same format, deflated less): a third of
    the time, as a fitted head is made.
    """
    text = base64.b64encode(data or model_to_bytes(model, fast=True)).decode("ascii")
    obj.pdeface.model_data = text
    if data is None:
        _models.pop(obj.as_pointer(), None)
    else:
        _models[obj.as_pointer()] = (hash(text), model)


def face_model(obj):
    """The FaceModel stored on a PDE face object (cached)."""
    data = obj.pdeface.model_data
    if not data:
        raise PdeFaceError(f"{obj.name} carries no PDE face model")
    key = obj.as_pointer()
    cached = _models.get(key)
    if cached is None or cached[0] != hash(data):
        cached = (hash(data), model_from_bytes(base64.b64decode(data), obj.name))
        _models[key] = cached
    return cached[1]


def fingerprint(*parts) -> str:
    """A short hash of arrays (as float32 / int32 where they are numbers) and strings."""
    h = hashlib.blake2b(digest_size=8)
    for p in parts:
        if isinstance(p, str):
            h.update(p.encode())
        else:
            a = np.asarray(p)
            a = a.astype(np.int32 if np.issubdtype(a.dtype, np.integer) else np.float32, copy=False)
            h.update(memoryview(np.ascontiguousarray(a)))  # no copy: keys are hashed on every write
    return h.hexdigest()


def set_key_coords(key_block, V):
    # ``points`` (Blender 4.1+, meshes' keys) copies the whole array at once; ``data`` goes point by point,
    # 80 times slower (0.16 s for 82 keys of a 27k-vertex head).
    key_block.points.foreach_set("co", np.asarray(V, np.float32).ravel())


def key_coords(key_block) -> np.ndarray:
    """A shape key's coordinates, float32 (n, 3), as Blender stores them."""
    co = np.empty(len(key_block.points) * 3, dtype=np.float32)
    key_block.points.foreach_get("co", co)
    return co.reshape(-1, 3)


def skin_material():
    mat = bpy.data.materials.get("PDE Skin")
    if mat is None:
        mat = bpy.data.materials.new("PDE Skin")
        compat.use_nodes(mat)
        bsdf = mat.node_tree.nodes.get("Principled BSDF")
        if bsdf is not None:
            bsdf.inputs["Base Color"].default_value = (0.8, 0.6, 0.5, 1.0)
            bsdf.inputs["Roughness"].default_value = 0.55
        mat.diffuse_color = (0.8, 0.6, 0.5, 1.0)
    return mat
