import numpy as np
import pytest
from pdeface.surface.grid import grid_faces
from pdeface.surface.report import PIT_DEPTH_MM, _in_pit, weighted_percentile

AXIS_Z = -100.0


def cylinder_sheet(radius):
    """A sheet r = radius(theta, y) round the vertical axis at z = AXIS_Z, 0.25 mm cells."""
    th = np.linspace(-0.3, 0.3, int(0.6 * 100 / 0.25) + 1)
    y = np.linspace(-15, 15, 121)
    TH, Y = np.meshgrid(th, y, indexing="ij")
    R = radius(TH, Y)
    V = np.stack([R * np.sin(TH), Y, AXIS_Z + R * np.cos(TH)], axis=-1).reshape(-1, 3)
    Q = grid_faces(len(th), len(y))
    return V, np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])


def test_a_narrow_deep_hole_is_a_pit_and_a_broad_hollow_is_not():
    # A 3 mm wide hole 8 mm deep (a flared nostril seen head on) beside a 12 mm wide, 3 mm deep hollow.
    def radius(th, y):
        hole = (np.abs(100 * (th + 0.1)) < 1.5) & (np.abs(y) < 1.5)
        hollow = 3.0 * np.exp(-((100 * (th - 0.1)) ** 2 + y ** 2) / 18.0)
        return 100.0 - np.where(hole, 8.0, 0.0) - hollow
    V, T = cylinder_sheet(radius)
    th = np.array([-0.1, 0.1, 0.0, -0.1])
    y = np.array([0.0, 0.0, 0.0, 8.0])
    r = radius(th, y)
    assert r[0] < 100 - PIT_DEPTH_MM and r[1] < 98
    assert _in_pit(V, T, AXIS_Z, th, y, r).tolist() == [True, False, False, False]


def test_weighted_percentile_counts_each_value_by_its_weight():
    x = np.arange(100.0)
    assert weighted_percentile(x, np.ones(100), 95) == 94.0
    w = np.ones(100)
    w[:10] = 100.0  # the ten smallest values hold 1000 of 1090 units of weight
    assert weighted_percentile(x, w, 50) < 10 and weighted_percentile(x, w, 95) > 40
    assert weighted_percentile(x[::-1], w[::-1], 50) == weighted_percentile(x, w, 50)


def test_api_and_cli_measure_the_same_skin_on_a_head_with_separate_parts(tmp_path, capsys, scan, fitted):
    # A strip of "lashes" 2 mm in front of the right eye, not joined to the skin: the README's Python
    # API (all triangles) and `pdeface report` measure the skin alone (the strip only hides the lid
    # skin behind it, as it would from a camera), and agree.
    import json

    from pdeface.au.modelfile import load_model, save_model
    from pdeface.cli import main
    from pdeface.io.meshio import read_mesh, write_obj
    from pdeface.mesh import Mesh
    from pdeface.surface.report import accuracy_report
    mesh, T, idx = scan
    model, _ = fitted
    eye = mesh.vertices[idx[36:42]].mean(axis=0) + np.array([0, 0, 0.2])  # cm
    strip = eye + np.array([[-1.5, -0.1, 0], [1.5, -0.1, 0], [1.5, 0.1, 0], [-1.5, 0.1, 0]])
    V = np.vstack([mesh.vertices, strip])
    n = len(mesh.vertices)
    T_head = np.vstack([T, [[n, n + 1, n + 2], [n, n + 2, n + 3]]])
    face_only = accuracy_report(model, mesh.vertices, T)
    head = accuracy_report(model, V, T_head)
    counted = ("n_visible", "n_occluded", "n_oblique")
    assert sum(head[k] for k in counted) == sum(face_only[k] for k in counted)  # no strip vertex is skin
    assert head["n_visible"] < face_only["n_visible"] and head["max_mm"] <= face_only["max_mm"]
    write_obj(tmp_path / "head.obj", Mesh.from_faces(V, T_head))
    save_model(tmp_path / "face.npz", model)
    assert main(["report", str(tmp_path / "face.npz"), str(tmp_path / "head.obj"), "--json"]) == 0
    cli = json.loads(capsys.readouterr().out)
    # the same files through the README's Python API (the model file holds µm codes, the OBJ 6 digits)
    read = read_mesh(tmp_path / "head.obj")
    api = accuracy_report(load_model(tmp_path / "face.npz"), read.vertices, read.triangles()[0])
    # the same figures; the CLI sums under one BLAS thread (pdeface.threads), so the last bit may differ
    api = {**api, "model_bytes": cli["model_bytes"]}
    assert cli.keys() == api.keys()
    for k, v in api.items():
        assert cli[k] == (pytest.approx(v, rel=1e-12) if isinstance(v, float) else v), k
    assert abs(api["p95_mm"] - head["p95_mm"]) < 0.01


def read_png(path):
    """(h, w, 3) uint8 of a PNG written by pdeface.io.png (8-bit RGB, filter 0)."""
    import struct
    import zlib
    data = path.read_bytes()
    w, h = struct.unpack(">II", data[16:24])
    idat, pos = b"", 8
    while pos < len(data):
        n, tag = struct.unpack(">I4s", data[pos:pos + 8])
        idat += data[pos + 8:pos + 8 + n] if tag == b"IDAT" else b""
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + 3 * w)
    return raw[:, 1:].reshape(h, w, 3)


def test_profiles_png_has_titles_ticks_and_a_legend(tmp_path, scan, fitted):
    from pdeface.io.png import draw_text, text_width
    from pdeface.surface.report import accuracy_report
    img = np.full((10, 40, 3), 255, np.uint8)
    draw_text(img, 1, 1, "AU12")
    assert (img == 0).all(axis=2).sum() > 20 and text_width("AU12") == 23
    mesh, T, _ = scan
    accuracy_report(fitted[0], mesh.vertices, T, profiles_png=tmp_path / "p.png")
    img = read_png(tmp_path / "p.png")
    h, w, _ = img.shape
    dark = (img < 100).all(axis=2)
    assert dark[:16].sum() > 3 * 60  # three panel titles above the axes
    legend = img[h - 44:]
    for colour in ((40, 40, 40), (220, 30, 30), (30, 60, 220)):  # scan, PDE, difference swatches
        assert (legend == colour).all(axis=2).sum() >= 18, colour
    # the scan's thick line shows beside the PDE's red one: both colours inside the first panel
    panel = img[22:h - 80, 46:410]
    assert (panel == (40, 40, 40)).all(axis=2).sum() > 100 and (panel == (220, 30, 30)).all(axis=2).sum() > 100
