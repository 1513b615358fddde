"""``pdeface batch`` render jobs: a timeline in frame chunks across 2 worker processes, each chunk rendered by
the add-on's headless renderer in each worker's own Blender (kept between its chunks); the frames are those of one
single-process render."""
import json
import subprocess
import sys

import numpy as np
import pytest
from pdeface.animation.timeline import save_timeline, sequence_timeline

pytest.importorskip("distributed")
ARGS = ["--engine", "WORKBENCH", "--size", "48x48", "--quiet"]


def _pixels(bpy, path):
    im = bpy.data.images.load(str(path))
    w, h = im.size
    a = np.array(im.pixels[:], dtype=np.float64).reshape(h, w, 4)[..., :3]
    bpy.data.images.remove(im)
    return a


def test_a_render_job_in_chunks_matches_one_render(bpy, tmp_path):
    timeline = tmp_path / "smile.json"
    save_timeline(timeline, sequence_timeline(["happy"], 4, 0.5, 0.5))
    (tmp_path / "job.toml").write_text('kind = "render"\nout = "out"\ntimeline = "smile.json"\nface = "default"\n'
                                       'chunk = 2\nengine = "WORKBENCH"\nsize = "48x48"\n')
    res = subprocess.run([sys.executable, "-m", "pdeface.cli", "batch", str(tmp_path / "job.toml"), "--workers", "2"],
                         capture_output=True, text=True, timeout=900, check=False)
    assert res.returncode == 0 and res.stdout.strip(), f"exit {res.returncode}, stderr:\n{res.stderr[-3000:]}"
    summary = json.loads(res.stdout)
    assert summary["failed"] == 0 and summary["done"] >= 3
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    chunks = [t["worker"] for t in manifest["tasks"]]
    assert max(chunks.count(w) for w in set(chunks)) >= 2  # a worker rendered chunks one after another in its Blender
    one = subprocess.run([sys.executable, "-m", "pdeface.cli", "render", "--timeline", str(timeline), *ARGS,
                          "--out", str(tmp_path / "one")], capture_output=True, text=True, timeout=900, check=False)
    assert one.returncode == 0, one.stderr[-2000:]
    expected = sorted(p.name for p in (tmp_path / "one" / "frames").iterdir())
    made = sorted(p.name for p in (tmp_path / "out" / "frames").iterdir())
    assert made == expected and len(made) >= 5
    for name in made:
        x, y = _pixels(bpy, tmp_path / "out" / "frames" / name), _pixels(bpy, tmp_path / "one" / "frames" / name)
        assert np.abs(x - y).max() < 1e-6, name
    assert not list((tmp_path / "out").glob(".pdeface-batch/chunks/*"))
    assert not np.allclose(_pixels(bpy, tmp_path / "out/frames" / made[0]), _pixels(bpy, tmp_path / "out/frames" / made[3]))
