"""Bad input of issue 38: a stray vertex far away, broken files of every kind, endless and inflating files.
Each is refused with one PdeFaceError line naming the file (or fitted, for the stray vertex), in bounded work."""
import contextlib
import gzip
import io
import json
import os
import resource
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pdeface
import pytest
from pdeface.errors import PdeFaceError
from pdeface.io.meshio import write_mesh
from pdeface.mesh import Mesh
from pdeface.surface.fit import fit_face


def _moved(scan, far):
    """The scan with one skin vertex (no landmark) moved to (far, far, far)."""
    mesh, T, idx = scan
    V = mesh.vertices.copy()
    others = np.setdiff1d(np.arange(len(V)), idx)
    V[others[len(others) // 2]] = far
    return V, T, idx


@pytest.mark.parametrize("far", [1e25, 1e12, 1e6])
def test_the_ray_grid_is_bounded_whatever_a_vertex_coordinates(scan, fitted, far):
    from pdeface.geometry import MAX_GRID_CELLS, cast_cylinder_rays, cylinder_ray_candidates

    model, _ = fitted
    V, T, _ = _moved(scan, far)
    Vf = model.frame.to_face(V)
    th = np.linspace(-1.5, 1.5, 300)
    y = np.linspace(-80, 60, 300)
    rays, _ = cylinder_ray_candidates(Vf, T, model.layout.axis_z, th, y)
    assert len(rays) < 50 * len(th) + MAX_GRID_CELLS ** 2
    clean = cast_cylinder_rays(model.frame.to_face(scan[0].vertices), T, model.layout.axis_z, th, y)[0]
    moved = cast_cylinder_rays(Vf, T, model.layout.axis_z, th, y)[0]
    both = np.isfinite(clean) & np.isfinite(moved)
    assert both.sum() > 0.9 * np.isfinite(clean).sum() and np.allclose(clean[both], moved[both])


@pytest.mark.parametrize("far", [1e25, 1e6])
def test_a_fit_ignores_a_vertex_far_away(scan, fitted, far):
    V, T, idx = _moved(scan, far)
    model, _ = fit_face(V, T, scan[0].vertices[idx], unit="cm")
    assert np.abs(model.coefficients - fitted[0].coefficients).max() < 1.0  # mm


def _limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))


@pytest.mark.parametrize("far", ["1e25", "1e9", "1e6"])
def test_fit_on_a_mesh_with_one_stray_vertex_neither_crashes_nor_bombs(tmp_path, scan, far):
    mesh, _, idx = scan
    V = mesh.vertices.copy()
    others = np.setdiff1d(np.arange(len(V)), idx)
    V[others[len(others) // 2]] = float(far)
    write_mesh(tmp_path / "stray.obj", Mesh(V, mesh.face_counts, mesh.face_indices))
    (tmp_path / "lm.json").write_text(json.dumps({"indices": [int(i) for i in idx]}))
    res = subprocess.run([sys.executable, "-m", "pdeface.cli", "fit", str(tmp_path / "stray.obj"), "--landmarks",
                          str(tmp_path / "lm.json"), "--unit", "cm", "-o", str(tmp_path / "face.npz")],
                         check=False, capture_output=True, text=True, timeout=300,
                         preexec_fn=_limit_memory)
    assert res.returncode == 0, res.stderr[-2000:]
    assert (tmp_path / "face.npz").stat().st_size > 1000


# ---------------------------------------------------------------- readers: one PdeFaceError line naming the file


def refused(call, match, seconds=2.0):
    """``call`` raises a PdeFaceError (one line, matching ``match``) within ``seconds``."""
    from pdeface.errors import PdeFaceError

    t = time.perf_counter()
    with pytest.raises(PdeFaceError, match=match) as info:
        call()
    assert time.perf_counter() - t < seconds
    assert "\n" not in str(info.value) and len(str(info.value)) < 400
    return str(info.value)


PLY_HEAD = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
PLY_FACE = "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n"


@pytest.mark.parametrize("text, match", [
    ("ply\nformat\nelement vertex 0\nend_header\n", "unknown PLY format"),
    (PLY_HEAD + PLY_FACE.replace("uchar int", "uchar float") + "3 0 1 nan\n", "whole numbers"),
    (PLY_HEAD + PLY_FACE.replace("uchar int", "uchar float") + "3 0 1 inf\n", "whole numbers"),
    (PLY_HEAD + PLY_FACE.replace("uchar int", "uchar float") + "3 0 1 1e400\n", "whole numbers"),
    (PLY_HEAD.replace("property float x", "property list uchar float x") + PLY_FACE.replace("0 0 0\n1 0 0\n0 1 0\n",
     "1 0 0 0\n1 1 0 0\n1 0 1 0\n") + "3 0 1 2\n", "not lists"),
    ("ply\nformat ascii 1.0\nelement vertex " + "9" * 5000 + "\nend_header\n", "elements claimed|expected"),
    (PLY_HEAD + PLY_FACE + "-3 0 1 2\n", "malformed"),
])
def test_broken_ply_files_name_the_file(tmp_path, text, match):
    from pdeface.io.meshio import read_mesh

    path = tmp_path / "bad.ply"
    path.write_text(text)
    assert "bad.ply" in refused(lambda: read_mesh(path), match)


def test_a_preset_whose_mixer_is_an_object(tmp_path):
    from pdeface.presets import load_presets

    path = tmp_path / "p.json"
    path.write_text(json.dumps({"format": "pdeface.preset", "version": 1, "name": "x", "weights": {"12": 1},
                                "mixer": {}}))
    assert "p.json" in refused(lambda: load_presets(path), "mixer")


@pytest.mark.parametrize("key, match", [({"frame": 1, "presets": [[]]}, "presets"),
                                         ({"time": 1e308}, "time"), ({"frame": 10 ** 14}, "frame"),
                                         ({"frame": 1, "aus": {"9" * 5000: 1}}, "AU key"),
                                         ({"frame": 1, "interpolation": {}}, "interpolation")])
def test_broken_timelines_name_the_file(tmp_path, key, match):
    from pdeface.animation.timeline import load_timeline

    path = tmp_path / "t.json"
    path.write_text(json.dumps({"format": "pdeface.timeline", "version": 1, "fps": 24, "keys": [key]}))
    assert "t.json" in refused(lambda: load_timeline(path), match)


def test_tracker_files_and_options(tmp_path):
    from pdeface.animation.trackers import import_au

    openface = tmp_path / "of.csv"
    openface.write_text("frame,timestamp,AU" + "1" * 5000 + "_r,AU12_r\n1,0.0,1,2\n2,0.1,1,3\n")
    r = import_au(openface)  # an AU the catalogue lacks: reported, not fatal
    assert r.unknown and len(r.timeline.keys) == 2
    long_number = tmp_path / "n.csv"
    long_number.write_text("frame,timestamp,AU12_r\n1,0.0," + "1" * 5000 + "\n")
    assert "n.csv:2" in refused(lambda: import_au(long_number), "digits")
    live = tmp_path / "ll.csv"
    live.write_text("Timecode,BlendShapeCount,NoSuchShape\n" + "".join(
        f"00:00:0{i // 30}:{i % 30:02d}.000,1,0.5\n" for i in range(40)))
    r = import_au(live, reduce_tolerance=0.01)
    assert len(r.timeline.keys) == 2 and r.unknown == ["NoSuchShape"]
    assert len(import_au(live, smooth_window=3).timeline.keys) > 2
    fas = tmp_path / "fas.txt"
    fas.write_text("{1,2}\n{12}\n")
    refused(lambda: import_au(fas, hold=float("inf")), "hold")
    refused(lambda: import_au(fas, hold=float("nan")), "hold")
    t = time.perf_counter()
    r = import_au(openface, smooth_window=1e11)  # as wide as the take: every key is the mean
    assert time.perf_counter() - t < 2.0
    assert r.timeline.keys[0].aus["12"] == pytest.approx(0.5)
    refused(lambda: import_au(openface, smooth_window=float("nan")), "smoothing")
    refused(lambda: import_au(openface, reduce_tolerance=float("nan")), "tolerance")


def _corrupt_members(src, dst, rng):
    """``src`` (a zip) with a few bytes of each member's compressed data flipped."""
    data = bytearray(src.read_bytes())
    with zipfile.ZipFile(src) as zf:
        for info in zf.infolist():
            start = info.header_offset + 30 + len(info.filename) + len(info.extra)
            for k in rng.integers(start, start + max(1, info.compress_size), 4):
                data[k] ^= 0x55
    dst.write_bytes(bytes(data))


def test_broken_muscle_fields_name_the_file(tmp_path, rng):
    from pdeface.muscles.fields import load_fields

    good = Path(pdeface.__file__).parent / "data" / "muscle_fields.npz"
    for i in range(20):
        bad = tmp_path / f"f{i}.npz"
        _corrupt_members(good, bad, rng)
        with contextlib.suppress(PdeFaceError):
            load_fields(bad)
    truncated = tmp_path / "cut.npz"
    truncated.write_bytes(good.read_bytes()[:5000])
    assert "cut.npz" in refused(lambda: load_fields(truncated), "muscle fields")


def test_fdt_bundles_corrupt_or_inflating_are_refused(tmp_path):
    from pdeface.fdt.table import read_fdts

    good = gzip.compress((Path(pdeface.__file__).parent / "data" / "paper_smile.fdt.json").read_bytes())
    corrupt = tmp_path / "c.fdt.json.gz"
    corrupt.write_bytes(good[:10] + bytes(b ^ 0x5A for b in good[10:40]) + good[40:])
    assert "c.fdt.json.gz" in refused(lambda: read_fdts(corrupt), "corrupt|truncated|gzip|JSON")
    cut = tmp_path / "t.fdt.json.gz"
    cut.write_bytes(good[:len(good) // 2])
    refused(lambda: read_fdts(cut), "truncated")
    bomb = tmp_path / "b.fdt.json.gz"
    bomb.write_bytes(gzip.compress(b" " * (200 << 20), 9))  # 200 MiB of blanks in 200 KB
    assert bomb.stat().st_size < 1 << 20
    refused(lambda: read_fdts(bomb), "inflates past")


@pytest.mark.parametrize("change, match", [
    ({"mirror": [1e400] * 468}, "mirror"), ({"mirror": [10 ** 14] * 468}, "mirror"),
    ({"trained_on": 5}, "trained_on"), ({"landmarks": [[]] * 68}, "malformed"),
    ({"landmarks": [{"indices": [1e400], "weights": [1]}] * 68}, "malformed"),
    ({"template": "x"}, "template")])
def test_broken_landmark_maps_name_the_file(tmp_path, change, match):
    from pdeface.landmarks.facemap import DEFAULT_MAP, read_map

    obj = json.loads(Path(DEFAULT_MAP).read_text())
    obj.update(change)
    path = tmp_path / "map.json"
    path.write_text(json.dumps(obj).replace("Infinity", "1e400"))
    assert "map.json" in refused(lambda: read_map(path), match)


def _rewrite_meta(src, dst, **change):
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "meta.npy":
                meta = json.loads(bytes(np.load(io.BytesIO(data))))
                meta.update(change)
                buf = io.BytesIO()
                np.save(buf, np.frombuffer(json.dumps(meta).encode(), np.uint8))
                data = buf.getvalue()
            zout.writestr(item, data)


@pytest.mark.parametrize("change", [{"w": "seven"}, {"w": -1}, {"a": "x"}, {"a": 0}])
def test_a_model_whose_meta_numbers_are_not_numbers(tmp_path, change):
    from pdeface.assets import DEFAULT_FACE, asset_path
    from pdeface.au.modelfile import load_model
    from pdeface.surface.fit import face_mesh

    path = tmp_path / "m.npz"
    _rewrite_meta(asset_path(DEFAULT_FACE), path, **change)

    def load_and_mesh():
        face_mesh(load_model(path))
    assert "m.npz" in refused(load_and_mesh, f"meta '{next(iter(change))}'")


def test_values_far_beyond_a_face_are_refused(tmp_path, default_face):
    from pdeface.au.descriptorfile import descriptor_to_json, load_descriptor, save_descriptor
    from pdeface.au.modelfile import load_model, save_model

    d = next(iter(default_face.descriptors))
    obj = descriptor_to_json(d)
    obj["residual"][0][0][0] = -6.5e11
    path = tmp_path / "d.json"
    path.write_text(json.dumps(obj))
    assert "d.json" in refused(lambda: load_descriptor(path), "residual")
    huge = d.scaled(1e6)
    save_descriptor(tmp_path / "d.pdd", huge)
    refused(lambda: load_descriptor(tmp_path / "d.pdd"), "mm")
    model = load_model_copy(default_face)
    model.residual[0, 0, 0] = -6.5e11
    save_model(tmp_path / "m.npz", model)
    refused(lambda: load_model(tmp_path / "m.npz"), "residual")


@pytest.mark.parametrize("scale", [1e300, -1.0, 0.0])
def test_a_model_whose_frame_is_no_rotation_and_scale(tmp_path, scale):
    from pdeface.assets import DEFAULT_FACE, asset_path
    from pdeface.au.modelfile import load_model

    with zipfile.ZipFile(asset_path(DEFAULT_FACE)) as zf:
        arrays = {n[:-4]: np.load(io.BytesIO(zf.read(n))) for n in zf.namelist()}
    arrays["frame"] = arrays["frame"] * scale  # x1e300: its scale overflows to inf (was accepted, issue 38)
    np.savez_compressed(tmp_path / "m.npz", **arrays)
    assert "m.npz" in refused(lambda: load_model(tmp_path / "m.npz"), "field 'frame'")


def load_model_copy(model):
    import copy

    return copy.deepcopy(model)


# ---------------------------------------------------------------- bounded reads


@pytest.mark.parametrize("reader", ["json", "csv", "timeline", "mesh", "model"])
def test_endless_and_special_files_are_refused_at_once(tmp_path, reader):
    from pdeface.animation.timeline import load_timeline
    from pdeface.animation.trackers import import_au
    from pdeface.au.modelfile import load_model
    from pdeface.io.files import load_json
    from pdeface.io.meshio import read_mesh

    call = {"json": load_json, "csv": import_au, "timeline": load_timeline, "mesh": read_mesh,
            "model": load_model}[reader]
    if os.path.exists("/dev/zero"):
        refused(lambda: call("/dev/zero"), "not a regular file|unsupported")
    fifo = tmp_path / ("pipe.obj" if reader == "mesh" else "pipe.csv")
    os.mkfifo(fifo)  # nothing ever writes it: opening it to read would wait for ever
    refused(lambda: call(fifo), "not a regular file")


def test_files_past_their_kind_limit_are_refused_before_reading(tmp_path, monkeypatch):
    from pdeface.animation.trackers import import_au
    from pdeface.io import files
    from pdeface.presets import load_presets

    path = tmp_path / "big.json"
    with open(path, "wb") as fh:
        fh.truncate(files.MAX_BYTES["json"] + 1)  # sparse: nothing is written, or read
    assert "big.json" in refused(lambda: load_presets(path), "too large for a json file")
    csv_path = tmp_path / "big.csv"
    with open(csv_path, "wb") as fh:
        fh.truncate(files.MAX_BYTES["table"] + 1)
    refused(lambda: import_au(csv_path), "too large for a table file")
    monkeypatch.setitem(files.MAX_BYTES, "json", 10)
    (tmp_path / "small.json").write_text('{"format": "x"}')
    refused(lambda: load_presets(tmp_path / "small.json"), "too large")


def test_a_small_file_is_read_without_reserving_its_kind_limit(tmp_path, monkeypatch):
    """read(n) allocates n bytes first: asking for a mesh's 1 GiB limit made every OBJ read a MemoryError
    under a 500 MB address-space cap (the fuzz campaign's)."""
    from pdeface.io import files

    asked = []
    real_open = files.open_file

    class Recording:  # the opened file, noting what each read asks for
        def __init__(self, fh):
            self.fh = fh

        def read(self, n=-1):
            asked.append(n)
            return self.fh.read(n)

        def fileno(self):
            return self.fh.fileno()

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.fh.close()

    def recording_open(*args, **kwargs):
        return Recording(real_open(*args, **kwargs))

    monkeypatch.setattr(files, "open_file", recording_open)
    (tmp_path / "m.obj").write_bytes(b"v 0 0 0\n" * 100)
    assert files.read_bytes(tmp_path / "m.obj") == b"v 0 0 0\n" * 100
    assert max(asked) <= 801
    monkeypatch.setattr(files, "open_file", real_open)
    if os.path.exists("/proc/self/status"):  # a regular file of size 0 that reads as text: read to its end
        assert b"VmSize" in files.read_bytes("/proc/self/status", kind="json")
