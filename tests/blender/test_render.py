"""Headless animation and rendering through scripts/figures/render_sequence.py, and AU data import in Blender."""
import json
import os
import site
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "figures" / "render_sequence.py"
TINY = ["--sequence", "happy", "--fps", "4", "--hold", "0.5", "--blend-time", "0.5", "--size", "64x64",
        "--samples", "4", "--quiet"]


def run_script(argv, tmp_path):
    res = subprocess.run([sys.executable] + argv, capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    return json.loads(res.stdout)  # with --quiet, stdout holds the JSON summary alone


def pixels(bpy, path):
    im = bpy.data.images.load(str(path))
    w, h = im.size
    a = np.array(im.pixels[:], dtype=np.float64).reshape(h, w, 4)[..., :3]
    bpy.data.images.remove(im)
    return a


@pytest.fixture(scope="module")
def chunks(tmp_path_factory):
    """The same job rendered as two chunks, through both entry-point forms."""
    tmp = tmp_path_factory.mktemp("render")
    # plain python with the bpy module
    a = run_script([str(SCRIPT), *TINY, "--out", str(tmp / "a"), "--frame-start", "1", "--frame-end", "4",
                    "--video", "--save-blend", str(tmp / "a" / "scene.blend")], tmp)
    # Blender's convention: the script's arguments follow "--" (as with blender -b -P script -- ...)
    b = run_script([str(SCRIPT), "-b", "-P", str(SCRIPT), "--", *TINY, "--out", str(tmp / "b"),
                    "--frame-start", "3", "--frame-end", "7"], tmp)
    return tmp, a, b


def test_frames_video_and_blend(chunks):
    tmp, a, b = chunks
    assert a["frames"] == 4 and b["frames"] == 5  # counts, not 360 paths
    assert sorted(p.name for p in Path(a["frames_dir"]).iterdir()) == [f"frame_{i:04d}.png" for i in range(1, 5)]
    assert sorted(p.name for p in Path(b["frames_dir"]).iterdir()) == [f"frame_{i:04d}.png" for i in range(3, 8)]
    assert a["timeline"] == {"frame_start": 1, "frame_end": 7, "fps": 4.0}
    assert Path(a["video"]).stat().st_size > 1000
    assert (tmp / "a" / "scene.blend").read_bytes()[:4] in (b"BLEN", b"\x28\xb5\x2f\xfd")  # plain or zstd


def test_frame_matches_the_reference_image(bpy, chunks):
    tmp, a, _ = chunks
    got = pixels(bpy, tmp / "a" / "frames" / "frame_0003.png")
    ref = pixels(bpy, Path(__file__).parent / "data" / "reference_frame_0003.png")
    diff = np.abs(got - ref)
    assert diff.mean() < 0.02 and np.percentile(diff, 99) < 0.15
    # and it is not a blank image: the face is lighter than the background
    assert got[24:40, 24:40].mean() > got[:4, :4].mean() + 0.1


def test_chunks_join_seamlessly(bpy, chunks):
    tmp, _, _ = chunks
    for f in (3, 4):
        x = pixels(bpy, tmp / "a" / "frames" / f"frame_{f:04d}.png")
        y = pixels(bpy, tmp / "b" / "frames" / f"frame_{f:04d}.png")
        assert np.abs(x - y).max() < 1e-6  # same camera, same seed: identical frames
    # the animation moves between frames
    f1 = pixels(bpy, tmp / "a" / "frames" / "frame_0001.png")
    f3 = pixels(bpy, tmp / "a" / "frames" / "frame_0003.png")
    assert np.abs(f1 - f3).max() > 0.05


def test_loading_a_blend_renders_the_same(bpy, chunks, tmp_path):
    tmp, _, _ = chunks
    out = run_script([str(SCRIPT), "--blend", str(tmp / "a" / "scene.blend"), "--size", "64x64", "--samples", "4",
                      "--quiet", "--out", str(tmp_path / "c"), "--frame-start", "3", "--frame-end", "3"], tmp_path)
    x = pixels(bpy, Path(out["frames_dir"]) / "frame_0003.png")
    y = pixels(bpy, tmp / "a" / "frames" / "frame_0003.png")
    assert np.abs(x - y).mean() < 0.01


def test_a_new_sequence_on_a_posed_blend_starts_from_the_timeline_alone(bpy, chunks, tmp_path):
    """A .blend saved posed (surprise's AUs, unkeyed) renders a new sequence from neutral; the user's key stays."""
    tmp, _, _ = chunks
    addon = __import__("bl_ext.pdeface_test.pdeface", fromlist=["animation", "keys"])
    bpy.ops.wm.open_mainfile(filepath=str(tmp / "a" / "scene.blend"))
    face = next(o for o in bpy.context.scene.objects if o.type == "MESH" and o.pdeface.is_face)
    addon.animation.clear_keyframes(face)
    addon.keys.apply_preset(face, "surprise", addon.keys.all_presets(bpy.context.scene)["surprise"], mode="AUS")
    assert max(kb.value for _, kb in addon.keys.managed(face)) > 0.5
    mine = face.shape_key_add(name="Smirk", from_mix=False)  # the user's own key (the basis: moves nothing)
    mine.value = 0.7
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "posed.blend"))
    res = subprocess.run([sys.executable, "-m", "pdeface.cli", "render", "--blend", str(tmp_path / "posed.blend"),
                          *TINY[:-1], "--json", "--out", str(tmp_path / "out"), "--frame-start", "1",
                          "--frame-end", "1", "--save-blend", str(tmp_path / "out.blend")],
                         capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    summary = json.loads(res.stdout)  # stdout holds the JSON summary alone
    assert summary["frames"] == 1 and "Saved:" in res.stderr  # Blender's own lines go to stderr
    # frame 1 is neutral: as the same face rendered from a new file
    x = pixels(bpy, Path(summary["frames_dir"]) / "frame_0001.png")
    y = pixels(bpy, tmp / "a" / "frames" / "frame_0001.png")
    assert np.abs(x - y).max() < 0.02
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "out.blend"))
    face = next(o for o in bpy.context.scene.objects if o.type == "MESH" and o.pdeface.is_face)
    blocks = face.data.shape_keys.key_blocks
    for frame, expected in ((1, 0.0), (3, 1.0)):  # neutral, then happy held
        bpy.context.scene.frame_set(frame)
        values = {kb.name: kb.value for _, kb in addon.keys.managed(face)}
        assert values.pop("Expr happy") == pytest.approx(expected)
        assert max(values.values()) == 0.0, {k: v for k, v in values.items() if v}
        assert blocks["Smirk"].value == pytest.approx(0.7)


def test_contact_sheet(bpy, face, tmp_path):
    render = __import__("bl_ext.pdeface_test.pdeface.render", fromlist=["render"])
    path, cells = render.contact_sheet(face, tmp_path / "sheet.png", items=["neutral", "AU12", "AU27", "happy"],
                                       cell=48, columns=4, samples=2, motion=False)
    assert cells == ["neutral", "AU12", "AU27", "happy"]
    img = pixels(bpy, path)
    assert img.shape[1] == 192 and 48 < img.shape[0] < 96  # one row of 48 px wide cells, taller than wide
    cols = [img[:, i * 48:(i + 1) * 48] for i in range(4)]
    assert all(c.mean() > img[:2].mean() for c in cols)  # a face in every cell
    assert np.abs(cols[0] - cols[2]).mean() > 0.005  # jaw open differs from neutral
    # AUs in numeric order (12 before 27, sides after both), whatever order they are asked in
    _, cells = render.contact_sheet(face, tmp_path / "order.png", items=["AU27", "AU1R", "AU12", "neutral", "AU1"],
                                    cell=16, columns=5, samples=1, motion=False)
    assert cells == ["neutral", "AU1", "AU1R", "AU12", "AU27"]


def test_contact_sheet_motion_rows(bpy, face, tmp_path):
    """Below each face, the same pose coloured by how far it moved: grey at neutral, coloured where an AU moved."""
    render = __import__("bl_ext.pdeface_test.pdeface.render", fromlist=["render"])
    plain, _ = render.contact_sheet(face, tmp_path / "plain.png", items=["neutral", "AU1", "AU12"], cell=48,
                                    columns=3, samples=1, motion=False)
    path, _ = render.contact_sheet(face, tmp_path / "sheet.png", items=["neutral", "AU1", "AU12"], cell=48,
                                   columns=3, samples=1)
    img, top = pixels(bpy, path), pixels(bpy, plain)
    assert img.shape[1] == 144 and img.shape[0] > 1.8 * top.shape[0]  # a motion row and the legend below
    rows = img[::-1]  # Blender's pixels run bottom-up
    motion = rows[top.shape[0] + 2: 2 * top.shape[0] - 8]
    cols = [motion[:, i * 48:(i + 1) * 48] for i in range(3)]
    saturation = [float((c.max(axis=2) - c.min(axis=2)).max()) for c in cols]
    assert saturation[0] < 0.05 < saturation[1] and saturation[2] > 0.2  # neutral grey; AU1's brows, AU12 coloured


def test_a_sheet_rendered_in_bands_is_the_sheet_in_one_render(bpy, face, tmp_path):
    """Bands of one row each (a few meshes per render) join into the same image as one render of the whole sheet."""
    render = __import__("bl_ext.pdeface_test.pdeface.render", fromlist=["render"])
    items = ["neutral", "AU1", "AU12", "AU27", "happy"]
    whole, cells = render.contact_sheet(face, tmp_path / "whole.png", items=items, cell=40, columns=2, samples=2,
                                        band_vertices=None)
    banded, banded_cells = render.contact_sheet(face, tmp_path / "banded.png", items=items, cell=40, columns=2,
                                                samples=2, band_vertices=1)
    assert banded_cells == cells
    a, b = pixels(bpy, whole), pixels(bpy, banded)
    assert a.shape == b.shape and a.shape[1] == 80 and a.shape[0] > 3 * 80  # three rows of faces, motion, legend
    assert np.abs(a - b).mean() < 0.01 and np.abs(a - b).max() < 0.5  # the same sheet, but for denoising at seams
    cols = [b[::-1][:60, i * 40:(i + 1) * 40] for i in range(2)]  # the first row: neutral and AU1, both drawn
    assert all(c.mean() > b[:2].mean() for c in cols)


def test_motion_attribute_is_the_keys_displacement_in_mm(bpy, face):
    addon = __import__("bl_ext.pdeface_test.pdeface", fromlist=["bridge", "keys", "render"])
    model = addon.bridge.face_model(face)
    blocks = face.data.shape_keys.key_blocks
    rest = addon.bridge.key_coords(face.data.shape_keys.reference_key).astype(np.float64)
    key = addon.bridge.key_coords(blocks[addon.keys.au_key_names(face)["12"]]).astype(np.float64)
    me = face.data.copy()
    d = addon.render.set_motion(me, model.frame.to_face(key) - model.frame.to_face(rest))
    stored = np.empty(len(me.vertices), np.float32)
    me.attributes[addon.render.MOTION_ATTRIBUTE].data.foreach_get("value", stored)
    expected = np.linalg.norm(key - rest, axis=1).max() * model.frame.scale  # object units to mm
    assert stored.max() == pytest.approx(expected, rel=1e-5) and np.array_equal(stored, d)
    assert 2.0 < expected < 30.0  # a smile moves the lip corners by millimetres


def test_import_au_operator(bpy, face, tmp_path):
    csv = tmp_path / "of.csv"
    csv.write_text("frame, face_id, timestamp, confidence, success, AU12_r, AU01_r, AU12_c\n"
                   "1, 0, 0.0, 0.98, 1, 0.0, 0.0, 0\n"
                   "2, 0, 0.5, 0.98, 1, 5.0, 2.5, 1\n"
                   "3, 0, 1.0, 0.98, 1, 0.0, 0.0, 0\n")
    bpy.context.scene.render.fps = 10
    assert bpy.ops.pdeface.import_au(filepath=str(csv)) == {"FINISHED"}
    kb = face.data.shape_keys.key_blocks
    bpy.context.scene.frame_set(6)
    assert kb["AU12 Lip Corner Puller"].value == pytest.approx(1.0)
    assert kb["AU1 Inner Brow Raiser"].value == pytest.approx(0.5)
    bpy.context.scene.frame_set(11)
    assert kb["AU12 Lip Corner Puller"].value == pytest.approx(0.0)
    bad = tmp_path / "bad.csv"
    bad.write_text("frame, timestamp, AU12_r\n1, 0.0, lots\n")
    with pytest.raises(RuntimeError, match="bad.csv:2"):
        bpy.ops.pdeface.import_au(filepath=str(bad))


def test_importing_again_replaces_our_animation_and_keeps_the_users(bpy, face, tmp_path):
    kb = face.data.shape_keys.key_blocks
    scene = bpy.context.scene
    scene.render.fps = 10
    mine = face.shape_key_add(name="Smirk", from_mix=False)  # the user's own animated key
    for frame, value in ((1, 0.0), (40, 0.9)):
        mine.value = value
        mine.keyframe_insert("value", frame=frame)
    long = tmp_path / "long.txt"
    long.write_text("{12}\n{1}\n{12}\n{1}\n")  # FAS: 4 sets of 0.5 s, 0.25 s between
    assert bpy.ops.pdeface.import_au(filepath=str(long)) == {"FINISHED"}
    first_end = scene.frame_end
    short = tmp_path / "short.csv"
    short.write_text("frame, timestamp, confidence, success, AU06_r\n1, 0.0, 0.98, 1, 5.0\n2, 0.4, 0.98, 1, 0.0\n")
    assert bpy.ops.pdeface.import_au(filepath=str(short)) == {"FINISHED"}
    assert (scene.frame_start, scene.frame_end) == (1, 5) and first_end > 5  # the new import's range
    scene.frame_set(3)  # AU12 was keyed here by the first import: gone, not merged
    assert kb["AU12 Lip Corner Puller"].value == 0.0 and kb["AU6 Cheek Raiser"].value > 0
    scene.frame_set(40)
    assert kb["Smirk"].value == pytest.approx(0.9)  # the user's own keyframes are untouched
    # merging, when asked, keeps the first import's keys and only grows the range
    assert bpy.ops.pdeface.import_au(filepath=str(long), merge=True) == {"FINISHED"}
    assert scene.frame_end == first_end
    scene.frame_set(6)
    assert kb["AU12 Lip Corner Puller"].value == pytest.approx(1.0)


def test_live_link_face_rate_guess_is_reported(bpy, face, tmp_path):
    clip = tmp_path / "llf.csv"
    clip.write_text("Timecode,BlendShapeCount,JawOpen\n10:00:00:00.000,61,0.0\n10:00:00:20.000,61,1.0\n")
    bpy.context.scene.render.fps = 24
    assert bpy.ops.pdeface.import_au(filepath=str(clip), capture_fps=60) == {"FINISHED"}
    assert bpy.context.scene.frame_end == 9  # 20 frames at 60 fps = 1/3 s
    assert bpy.ops.pdeface.import_au(filepath=str(clip)) == {"FINISHED"}  # guessed from frames up to 20: 24 fps
    assert bpy.context.scene.frame_end == 21


def test_the_main_job(bpy, tmp_path):
    """`pdeface demo`, the README's first command, at a tiny size."""
    res = subprocess.run([sys.executable, "-m", "pdeface.cli", "demo", "--out", str(tmp_path / "out"),
                          "--size", "48x48", "--samples", "2", "--fps", "4"],
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    summary = json.loads(res.stdout.strip().splitlines()[-1])
    out = tmp_path / "out"
    for name in ("face.npz", "face.obj", "report.json", "profiles.png", "contact_sheet.png", "demo.blend"):
        assert (out / name).stat().st_size > 0, name
    frames = sorted((out / "frames").glob("frame_*.png"))
    assert len(frames) == summary["render"]["frame_end"] - summary["render"]["frame_start"] + 1 > 20
    assert "[4/4]" in res.stderr
    # progress is shown for every stage; stderr is no terminal here, so a line as it starts and one as it ends
    for stage in ("Blender start-up", "rig", "frames", "contact sheet"):
        assert f"\n{stage}: started (" in res.stderr and f"\n{stage}: done (" in res.stderr, stage
    assert "\r" not in res.stderr and res.stderr.count("\nframes: ") == 2
    sheet = pixels(bpy, out / "contact_sheet.png")
    assert sheet.shape[0] > 1000 and sheet.std() > 0.05  # 74 labelled cells


def installed_venv(tmp_path):
    """A venv holding pdeface from its wheel and seeing this interpreter's packages (bpy, numpy), not the checkout.

    ``venv --system-site-packages`` would see the *base* Python's packages, which lack bpy when the tests run in
    a venv (the README's way); a ``.pth`` file listing this interpreter's site directories works in and out of
    one. Those directories come after the venv's own, so its pdeface is the one imported, and their ``.pth``
    files are not read, so an editable install of the checkout stays out.
    """
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # no checkout on the path
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q",
                    "-w", str(tmp_path / "wheel"), str(ROOT)], check=True, timeout=300)
    subprocess.run([sys.executable, "-m", "venv", str(tmp_path / "venv")], check=True, env=env)
    python = tmp_path / "venv" / ("Scripts" if sys.platform == "win32" else "bin") / "python"
    # --ignore-installed: pip must not take a pdeface it finds elsewhere (an egg-info left in core/) for this one.
    subprocess.run([str(python), "-m", "pip", "install", "-q", "--no-deps", "--no-index", "--ignore-installed",
                    *map(str, (tmp_path / "wheel").glob("pdeface-*.whl"))], check=True, timeout=300, cwd=tmp_path,
                   env=env)
    purelib = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True, env=env).stdout.strip()
    ours = [*site.getsitepackages(), *([site.getusersitepackages()] if site.ENABLE_USER_SITE else [])]
    Path(purelib, "running_interpreter.pth").write_text("".join(f"{d}\n" for d in ours if Path(d).is_dir()))
    return python, env


def test_pdeface_render_from_an_installed_package(tmp_path):
    """`pdeface render` with pdeface installed from its wheel: no checkout, no scripts/ folder."""
    python, env = installed_venv(tmp_path)
    bin_dir = python.parent
    where = subprocess.run([str(python), "-c", "import importlib.util as u, pdeface.assets as a; "
                            "print(u.find_spec('pdeface_blender').origin); print(a.assets_dir())"],
                           capture_output=True, text=True, cwd=tmp_path, check=True, env=env).stdout.split()
    assert all(str(tmp_path / "venv") in w for w in where), where  # the installed copy, with its own assets
    res = subprocess.run([str(bin_dir / "pdeface"), "render", *TINY, "--out", str(tmp_path / "out")],
                         capture_output=True, text=True, cwd=tmp_path, timeout=600, env=env)
    assert res.returncode == 0, res.stderr[-3000:]
    summary = json.loads(res.stdout.strip().splitlines()[-1])
    assert summary["frames"] == 7 and len(list((tmp_path / "out" / "frames").glob("frame_*.png"))) == 7
    bad = subprocess.run([str(bin_dir / "pdeface"), "render", "--face", str(tmp_path / "missing.npz"), *TINY,
                          "--out", str(tmp_path / "out2")], capture_output=True, text=True, cwd=tmp_path, timeout=600,
                         env=env)
    assert bad.returncode == 2 and "pdeface render: error:" in bad.stderr and "missing.npz" in bad.stderr
