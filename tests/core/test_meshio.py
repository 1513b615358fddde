import numpy as np
import pytest
from pdeface.errors import MeshError
from pdeface.io.meshio import read_mesh, read_obj, read_ply, write_mesh, write_obj
from pdeface.mesh import Mesh

OBJ = """# a comment
mtllib skin.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0.5 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
usemtl Skin
f 1/1/1 2/2/1 3/3/1 4/4/1
usemtl Other
f -4/-3/-1 5/2/1 -3/-2/-1
"""


def write(tmp_path, text, name="m.obj"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_obj_reads_quads_tris_negative_indices_and_materials(tmp_path):
    m = read_obj(write(tmp_path, OBJ))
    assert m.vertices.shape == (5, 3)
    assert m.face_counts.tolist() == [4, 3]
    # -4 of 5 vertices is vertex 2 (1-based) → index 1; -3 → index 2
    assert m.face_indices.tolist() == [0, 1, 2, 3, 1, 4, 2]
    assert m.face_uv_indices.tolist() == [0, 1, 2, 3, 1, 1, 2]
    assert m.face_normal_indices.tolist() == [0] * 7
    assert m.material_names == ["Skin", "Other"] and m.face_materials.tolist() == [0, 1]
    assert m.mtllib == "skin.mtl"


def test_obj_ngon_and_forms_without_uv(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1 5//1\nf 1 2 3\n"
    m = read_obj(write(tmp_path, text))
    assert m.face_counts.tolist() == [5, 3]
    assert m.uvs is None
    T, poly = m.triangles()
    assert T.shape == (4, 3) and poly.tolist() == [0, 0, 0, 1]


def test_obj_roundtrip_keeps_uvs_normals_materials(tmp_path):
    m = read_obj(write(tmp_path, OBJ))
    out = tmp_path / "out.obj"
    write_obj(out, m)
    m2 = read_obj(out)
    np.testing.assert_allclose(m2.vertices, m.vertices)
    np.testing.assert_allclose(m2.uvs[m2.face_uv_indices], m.uvs[m.face_uv_indices])
    assert m2.face_indices.tolist() == m.face_indices.tolist()
    assert m2.material_names == m.material_names and m2.mtllib == "skin.mtl"


@pytest.mark.parametrize("text, message", [
    ("v 0 0 x\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "m.obj:1: bad number"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "m.obj:4: vertex index 4 out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", "m.obj:4: vertex index -4 out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no faces"),
    ("# empty\n", "no vertices"),
    ("v 0 nan 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "m.obj:1: vertex is not finite"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "m.obj:4: face needs at least 3 corners"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/2 2/1 3/1\n", "texture coordinate index 2 out of range"),
    ("v 0 0\n", "m.obj:1: vertex line needs 3 numbers"),
])
def test_obj_errors_name_file_and_line(tmp_path, text, message):
    with pytest.raises(MeshError, match=message.replace("(", r"\(")):
        read_obj(write(tmp_path, text))


def test_missing_file_and_unknown_format(tmp_path):
    with pytest.raises(MeshError, match="cannot open"):
        read_obj(tmp_path / "nope.obj")
    with pytest.raises(MeshError, match="unsupported mesh format"):
        read_mesh(tmp_path / "x.stl")


@pytest.mark.parametrize("name", ["m.ply", "m.obj"])
def test_write_read_roundtrip_any_format(tmp_path, name, rng):
    V = rng.normal(size=(6, 3))
    mesh = Mesh.from_faces(V, [[0, 1, 2, 3], [2, 3, 4, 5]], uvs=rng.random((6, 2)))
    write_mesh(tmp_path / name, mesh)
    back = read_mesh(tmp_path / name)
    np.testing.assert_allclose(back.vertices, V, atol=1e-5)
    assert back.face_indices.tolist() == mesh.face_indices.tolist()
    np.testing.assert_allclose(back.uvs[back.face_uv_indices], mesh.uvs[mesh.face_uv_indices], atol=1e-5)


def test_ascii_ply_and_bad_ply(tmp_path):
    text = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")
    m = read_ply(write(tmp_path, text, "a.ply"))
    assert m.face_counts.tolist() == [4] and m.vertices[2].tolist() == [1, 1, 0]
    with pytest.raises(MeshError, match="truncated or malformed"):
        read_ply(write(tmp_path, text.replace("4 0 1 2 3\n", "4 0 1\n"), "b.ply"))
    with pytest.raises(MeshError, match="not a PLY"):
        read_ply(write(tmp_path, "hello", "c.ply"))
    with pytest.raises(MeshError, match="out of range|outside"):
        read_ply(write(tmp_path, text.replace("4 0 1 2 3", "4 0 1 2 9"), "d.ply"))


def test_same_topology_is_the_same_polygons():
    quad = Mesh.from_faces(np.zeros((4, 3)), [[0, 1, 2, 3]])
    assert quad.same_topology(Mesh.from_faces(np.ones((4, 3)), [[0, 1, 2, 3]]))
    assert not quad.same_topology(Mesh.from_faces(np.zeros((4, 3)), [[0, 1, 3, 2]]))
    assert not quad.same_topology(Mesh.from_faces(np.zeros((5, 3)), [[0, 1, 2, 3]]))


def test_validate_rejects_nan_and_faceless():
    with pytest.raises(MeshError, match="not finite"):
        Mesh.from_faces([[0, 0, 0], [1, 0, np.nan], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(MeshError, match="no faces"):
        Mesh(np.zeros((3, 3)), np.zeros(0, int), np.zeros(0, int)).validate()


def _glb(path, gltf, blob):
    """Write a GLB container: the JSON chunk, then the binary one (both padded to 4 bytes)."""
    import json
    import struct

    text = json.dumps(gltf).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)
    return path


def _two_node_glb(path, material=True, external=False):
    """One triangle mesh (a unit quad, UVs with glTF's v down) used by two nodes: a parent translated by
    (10, 0, 0) and its child scaled by 2; the child's triangles come in with both transforms."""
    P = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], "<f4")
    UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], "<f4")  # glTF's v runs down the image
    idx = np.array([0, 1, 2, 0, 2, 3], "<u2")
    blob = P.tobytes() + UV.tobytes() + idx.tobytes()
    gltf = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": [10, 0, 0], "children": [1]}, {"mesh": 0, "scale": [2, 2, 2]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2,
                                    **({"material": 0} if material else {})}]}],
        "materials": [{"name": "skin"}] if material else [],
        "buffers": [{"byteLength": len(blob)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 32},
                        {"buffer": 0, "byteOffset": 80, "byteLength": 12}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0],
                       "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
                      {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    }
    if external:  # a .gltf beside its .bin
        gltf["buffers"][0]["uri"] = path.stem + ".bin"
        path.with_suffix(".bin").write_bytes(blob)
        path.write_text(__import__("json").dumps(gltf))
        return path, P
    return _glb(path, gltf, blob), P


# A sculpt exported without a material keeps its UVs too; a .gltf finds its .bin beside it.
@pytest.mark.parametrize("name, material", [("head.glb", True), ("head.glb", False), ("head.gltf", False)])
def test_glb_nodes_flatten_into_one_mesh_with_their_transforms(tmp_path, name, material):
    pytest.importorskip("trimesh")
    path, P = _two_node_glb(tmp_path / name, material, external=name.endswith(".gltf"))
    m = read_mesh(path)
    assert m.vertices.shape == (8, 3) and m.face_counts.tolist() == [3] * 4
    # Each node's copy of the quad, wherever trimesh puts it in the order: parent at +10 x, child scaled by 2 too.
    copies = sorted([m.vertices[:4], m.vertices[4:]], key=lambda c: c.max())
    np.testing.assert_allclose(copies[0], P + [10, 0, 0])
    np.testing.assert_allclose(copies[1], 2 * P + [10, 0, 0])
    assert set(m.face_indices[:6]) | set(m.face_indices[6:]) == set(range(8))
    # UVs in OBJ's convention (v up): the quad's corner at y=0 has v=0.
    uv = m.uvs[m.face_uv_indices]
    np.testing.assert_allclose(uv[m.face_indices == 0], [[0, 0]] * 2)


def test_glb_and_gltf_round_trip_a_scene_written_by_trimesh(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    head, eye = trimesh.creation.icosphere(2), trimesh.creation.icosphere(1, radius=0.1)
    scene = trimesh.Scene()
    placed = {"head": (head, trimesh.transformations.rotation_matrix(0.3, [0, 1, 0])),
              "eye": (eye, trimesh.transformations.translation_matrix([0.03, 0.02, 0.09]))}
    for name, (geom, matrix) in placed.items():
        scene.add_geometry(geom, node_name=name, geom_name=name, transform=matrix)
    for ext in ("glb", "gltf"):
        scene.export(tmp_path / f"s.{ext}")
        m = read_mesh(tmp_path / f"s.{ext}")
        assert len(m.vertices) == len(head.vertices) + len(eye.vertices)
        expected = {len(g.vertices): trimesh.transform_points(g.vertices, M) for g, M in placed.values()}
        start = 0
        for _ in placed:  # each node's vertices in their own order, whichever node comes first
            first = m.vertices[start]
            n = next(k for k, X in expected.items() if np.allclose(X[0], first, atol=1e-6))
            np.testing.assert_allclose(m.vertices[start:start + n], expected[n], atol=1e-6)
            start += n


def test_gltf_errors_name_the_file(tmp_path, monkeypatch):
    pytest.importorskip("trimesh")
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"glTF\x02\0\0\0 not really")
    with pytest.raises(MeshError, match="bad.glb: not a readable glTF file"):
        read_mesh(bad)
    with pytest.raises(MeshError, match="nope.gltf: cannot open"):
        read_mesh(tmp_path / "nope.gltf")
    empty = _glb(tmp_path / "empty.glb", {"asset": {"version": "2.0"}, "scenes": [{"nodes": []}]}, b"")
    with pytest.raises(MeshError, match="empty.glb: no triangle mesh"):
        read_mesh(empty)
    huge = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": 12}],
            "accessors": [{"componentType": 5126, "count": 10**12, "type": "VEC3"}]}
    with pytest.raises(MeshError, match="huge.glb: accessor 0 claims 1000000000000 elements in 12 bytes"):
        read_mesh(_glb(tmp_path / "huge.glb", huge, b"\0" * 12))
    monkeypatch.setitem(__import__("sys").modules, "trimesh", None)
    with pytest.raises(MeshError, match=r"bad.glb: reading glTF needs trimesh: .*pdeface\[gltf\]"):
        read_mesh(bad)


# --- the OBJ reader: numpy blocks for well-formed files, line by line for the rest (same mesh, same errors) ---

_MESH_FIELDS = ("vertices", "face_counts", "face_indices", "uvs", "face_uv_indices", "normals",
                "face_normal_indices", "material_names", "face_materials", "mtllib")


def _same_mesh(a, b):
    for name in _MESH_FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            assert x is not None and y is not None and x.dtype == y.dtype, name
            np.testing.assert_array_equal(x, y, err_msg=name)
        else:
            assert x == y, name


def _both_ways(path):
    """(the mesh read_obj reads, the one the line-by-line reader reads, whether numpy's blocks read it)."""
    from pdeface.io import meshio

    data = path.read_bytes().replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    lines = meshio._obj_lines(path, data.decode("utf-8", "replace").split("\n"))
    return read_obj(path), lines, meshio._obj_blocks(data) is not None


WELL_FORMED = {
    "all forms": OBJ,
    "mixed polygons, forms, o/g/s, comments": (
        "# c\no head\ng skin\ns 1\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 .5 0\nvn 0 0 1\nvn 0 0 -1\n"
        "f 1//1 2//2 3//1 4//2\nf 2 5 3\ng other\nf -5//-1 -4//-2 -3//1 -2//2 -1//1\n"),
    "vertex colours, uv w, exponents, signs": (
        "v 1e-3 -2.5E+2 +3 0.5 0.25 1\nv -0 0.000001 123456.789012\nv 1. .5 -.25\nvt 0.5 0.25 0\nvt 1 1\n"
        "vt 0 1\nf 1/1 2/2 3/3\n"),
    "interleaved blocks and relative indices": (
        "v 0 0 0\nv 1 0 0\nvt 0 0\nv 1 1 0\nvt 1 0\nf -3/-2 -2/-1 -1/-1\nv 0 1 0\nvt 0 1\nf -4/1 -2/-2 -1/-1\n"),
    "tabs, CRLF, blank and indented blank lines, no final newline": (
        "v\t0 0 0\r\nv 1\t0 0 \r\n\r\n   \r\nv 0 1 0\r\nusemtl  two  words \r\nf 1 2 3"),
    "names in UTF-8, last mtllib wins": (
        "mtllib a.mtl\nmtllib b c.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl Haut\u00e9\nf 1 2 3\nusemtl x\nf 3 2 1\n"
        "usemtl Haut\u00e9\nf 1 3 2\n# \u00fcber\n"),
    "long decimals (read by float() one by one)": "v 0.12345678901234567 1 2\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "six decimals in every number, as exporters write them (one power of ten for all)": (
        "v 0.000000 -2.482510 11.838700\nv -0.503397 3.454130 10.638700\nv 1.000000 0.000001 -0.000001\n"
        "vt 0.480491 0.185494\nvt 0.000000 1.000000\nvt 1.000000 0.999999\nf 1/1 2/2 3/3\n"),
}


@pytest.mark.parametrize("name", WELL_FORMED)
def test_obj_well_formed_files_read_in_blocks_as_line_by_line(tmp_path, name):
    path = tmp_path / "m.obj"
    path.write_bytes(WELL_FORMED[name].encode())
    fast, lines, in_blocks = _both_ways(path)
    assert in_blocks
    _same_mesh(fast, lines)


def test_obj_blocks_read_random_meshes_exactly(tmp_path, rng):
    from pdeface.io import meshio

    for trial in range(20):
        nv, nt, nn = rng.integers(3, 40, size=3)
        V = np.round(rng.normal(scale=10.0 ** rng.integers(-3, 4), size=(nv, 3)), rng.integers(0, 9))
        out, seen = [], {"v": 0, "vt": 0, "vn": 0}
        pending = [("v", row) for row in V] + [("vt", row) for row in rng.random((nt, 2))] + \
            [("vn", row) for row in rng.normal(size=(nn, 3))]
        order = rng.permutation(len(pending))
        form = rng.integers(0, 4)  # v, v/vt, v//vn, v/vt/vn (the same for the whole file: attributes kept)
        for k in order:
            tag, row = pending[k]
            out.append(tag + " " + " ".join(repr(float(x)) for x in row))
            seen[tag] += 1
            if seen["v"] >= 3 and seen["vt"] and seen["vn"] and rng.random() < 0.3:
                n_corners = int(rng.integers(3, 7))
                corner = []
                for _ in range(n_corners):
                    idx = {t: int(rng.integers(0, seen[t])) for t in seen}
                    # a relative (negative) index now and then
                    txt = {t: str(idx[t] - seen[t] if rng.random() < 0.3 else idx[t] + 1) for t in seen}
                    corner.append([txt["v"], f"{txt['v']}/{txt['vt']}", f"{txt['v']}//{txt['vn']}",
                                   f"{txt['v']}/{txt['vt']}/{txt['vn']}"][form])
                if rng.random() < 0.2:
                    out.append(f"usemtl m{int(rng.integers(0, 3))}")
                out.append("f " + " ".join(corner))
        out.append("f 1 2 3")
        path = tmp_path / f"r{trial}.obj"
        path.write_text("\n".join(out) + "\n")
        data = path.read_bytes()
        assert meshio._obj_blocks(data) is not None
        _same_mesh(read_obj(path), meshio._obj_lines(path, data.decode().split("\n")))


def test_obj_blocks_read_numbers_of_every_length_exactly(tmp_path, rng):
    """Numbers of 1 to 15 digits (integer and fraction parts of any split, signs; indices padded with zeros) in
    files whose longest has 1 to 15 (8 digits at a time up to 8, digit by digit above), the first ending in a
    block's first 8 bytes; every number with a dot, or some without: read as float() and int() read them."""
    from pdeface.io import meshio

    def number(total, whole):
        digits = "".join(str(d) for d in rng.integers(0, 10, total))
        return ("-" if rng.random() < 0.5 else "") + digits[:whole] + ("." + digits[whole:] if whole < total else "")

    for longest in range(1, 16):
        for dotted in (True, False):
            splits = [(t, w) for t in range(1, longest + 1) for w in range(t + 1)
                      if not dotted or 0 < w < t] or [(1, 1)]
            out = [f"v {number(*s)} {number(*splits[-1])} {number(*splits[0])}" for s in splits]
            out += [f"vt {number(*s)} {number(*splits[-1])}" for s in splits] + ["v 1 2 3", "vt 0 1"] * 3
            out += [f"f {'1'.zfill(k)}/{'3'.zfill(longest)} {'2'.zfill(longest)}/{'1'.zfill(k)} "
                    f"{str(1 + k % 3).zfill(1 + (longest - k) % longest)}/{'2'.zfill(1 + k % longest)}"
                    for k in range(1, longest + 1)]
            path = tmp_path / f"{longest}{dotted}.obj"
            path.write_text("\n".join(out) + "\n")
            data = path.read_bytes()
            assert meshio._obj_blocks(data) is not None
            _same_mesh(read_obj(path), meshio._obj_lines(path, data.decode().split("\n")))


@pytest.mark.parametrize("text", [
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 # a comment\n",       # a comment after a face: a bad index
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n",               # four fields
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/ 2 3\n",                    # an empty texture field: kept line by line
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf /1 2 3\n",                    # no vertex index
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\nv 0 0 1\n",            # a vertex defined after its face
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n",  # an index too long for int64
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3x\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf +1 2 3\n",                    # int() reads +1: line by line
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1-2 2 3\n",
    "v 0 0 0\nv 1 0 0 inf\nv 0 1 0\nf 1 2 3\n",                # a fourth value is ignored, even inf
    "v 0 0 0\nv 1 0 inf\nv 0 1 0\nf 1 2 3\n",
    "v 0 0 0\nv 1 0 1e999\nv 0 1 0\nf 1 2 3\n",
    "v 0 0 0\nv 1 0 1.5.3\nv 0 1 0\nf 1 2 3\n",
    "v 0 0 0\nv 1 0 1-2\nv 0 1 0\nf 1 2 3\n",
    "v 0 0 0\nv 1 0 1_0\nv 0 1 0\nf 1 2 3\n",                  # float() reads 1_0 as 10
    "v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0\nf 1/1 2/1 3/1\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 x\nf 1//1 2//1 3//1\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\n  f 1 2 3\n",                  # an indented face
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf\u00a01 2 3\n",               # a no-break space str.split splits on
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1\x1c2 3\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/2\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 2 3\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -0 2 3\n",
    "v 0 \xff 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",                  # undecodable: replaced, then a bad number
    # Numbers of one dot each and indices without a sign, read digit by digit: what else they meet.
    "v 0.5 0.25 -0.125\nv 1.5 0.0 1-2.5\nv 0.0 1.0 0.0\nf 1 2 3\n",    # a sign inside a number
    "v 0.5 0.25 -0.125\nv 1.5 -.5 0.0\nv 0.0 1.0 0.0\nf 1 2 3\n",      # no digit before the dot
    "v 0.5 0.25 -0.125\nv 1.5 0.0 1.\nv 0.0 1.0 0.0\nf 1 2 3\n",       # none after it
    "v 0.5 0.25 -0.125\nv 1.5 0.0 -0.0\nv 0.0 1.0 0.0\nf 1 2 0000000003\n",  # ten digits: 3
    "v 0.0 0.0 0.0\nv 1.0 0.0 0.0\nv 0.0 1.0 0.0\nvt 0.5 0.5\nf 1/1 2 3/1\n",  # corners unlike
    "v 0.0 0.0 0.0\nv 1.0 0.0 0.0\nv 0.0 1.0 0.0\nvt 0.5 0.5\nf 1/1 2/1 3/1234567890123456\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -\n",                      # a sign alone
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 --1\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf -3/-1 -2/1 -1/-1\n",      # relative and absolute, read as columns
    # Slashes the usual corners' count of them lets through only where each joins two fields of one corner.
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1 /1 2/1 3/1\n",        # a slash after a space: as many in all
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1/ 2/1/ 3/1/\n",      # trailing
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1 /\n",       # alone
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3\nf 1 2 3/1\n",  # corners of two forms
    "v 0 0 0\n",
    "f 1 2 3\n",
    "",
])
def test_obj_irregular_files_read_or_fail_as_line_by_line(tmp_path, text):
    from pdeface.io import meshio

    path = tmp_path / "m.obj"
    path.write_bytes(text.encode("utf-8", "surrogateescape") if "\xff" not in text else text.encode("latin-1"))
    data = path.read_bytes()
    try:
        expected = meshio._obj_lines(path, data.decode("utf-8", "replace").split("\n"))
    except MeshError as exc:
        with pytest.raises(MeshError) as got:
            read_obj(path)
        assert str(got.value) == str(exc)
    else:
        _same_mesh(read_obj(path), expected)


POSED_SOURCE = ("# head\r\nmtllib h.mtl\r\no head\r\nv 0 0 0 0.5 0.5 0.5\r\n  v 1 0 0\r\nvt 0 0\r\ng skin\r\n"
                "v 0 1 0\r\nvn 0 0 1\r\nusemtl Skin\r\ns 1\r\nf 1/1/1 2/1/1 3/1/1\r\n# end")


def test_write_posed_changes_only_the_vertex_positions(tmp_path):
    from pdeface.io.meshio import write_posed

    src = tmp_path / "src.obj"
    src.write_bytes(POSED_SOURCE.encode())
    mesh = read_obj(src)
    V = mesh.vertices + [[0.25, 0, 0], [0, 0.5, 0], [0, 0, -1.5]]
    write_posed(tmp_path / "out.obj", src, mesh, V)
    got = (tmp_path / "out.obj").read_bytes().decode().split("\r\n")
    want = POSED_SOURCE.split("\r\n")
    # the v lines: new x y z, their colours kept; every other line (and its CRLF) exactly as it was
    want[3], want[4], want[7] = "v 0.250000 0.000000 0.000000 0.5 0.5 0.5", "v 1.000000 0.500000 0.000000", \
        "v 0.000000 1.000000 -1.500000"
    assert got == want
    np.testing.assert_allclose(read_obj(tmp_path / "out.obj").vertices, V)


def test_write_posed_many_reads_the_source_once(tmp_path, monkeypatch):
    from pdeface.io import meshio

    src = tmp_path / "src.obj"
    src.write_bytes(POSED_SOURCE.encode())
    mesh = read_obj(src)
    opened = []
    real_open = meshio.open_file
    monkeypatch.setattr(meshio, "open_file", lambda path, *a, **k: opened.append(path) or real_open(path, *a, **k))
    poses = [(tmp_path / f"p{i}.obj", mesh.vertices + i) for i in range(5)] + [(tmp_path / "p.ply", mesh.vertices)]
    meshio.write_posed_many(poses, src, mesh)
    assert opened == [src]
    for path, V in poses:
        np.testing.assert_allclose(read_mesh(path).vertices, V, atol=1e-5)
    other = Mesh.from_faces(np.zeros((4, 3)), [[0, 1, 2, 3]])  # not the mesh read from src
    with pytest.raises(MeshError, match=r"src.obj: changed since it was read \(3 vertices, expected 4\)"):
        meshio.write_posed_many([(tmp_path / "q.obj", other.vertices)], src, other)
    assert not (tmp_path / "q.obj").exists()
