"""``pdeface batch`` stimuli of a TD's ``.blend``: a head rigged by the add-on's operator, saved, then posed by its
shape keys (named by AU) in a job on 2 worker processes, each reading the file in its own Blender."""
import csv
import json
import os
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("distributed")


def test_a_stimulus_job_poses_the_shape_keys_of_an_addon_blend(bpy, tmp_path):
    from pdeface.batch.job import load_job
    from pdeface.batch.stimuli import load_identity, render_identity
    from pdeface.batch.work import RECORDS
    from pdeface.io.png import write_png

    assert bpy.ops.pdeface.add_ict_head() == {"FINISHED"}
    head = bpy.context.active_object
    smile = np.array([p.co for p in head.data.shape_keys.key_blocks["AU12 Lip Corner Puller"].data])
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "td_head.blend"), copy=True)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "no_face.blend"), copy=True)
    (tmp_path / "job.toml").write_text('kind = "stimuli"\nout = "out"\nfaces = ["td_head.blend", "no_face.blend"]\n'
                                       'aus = [[12], [1, 2]]\nintensities = ["A", "E"]\nsize = 48\nretries = 0\n')
    # Blender's settings shared with another Blender, which was writing its extension cache: the workers' Blenders
    # print a line about it, which must not reach the job's stdout (its JSON summary)
    config = tmp_path / "blender_config"
    (config / "extensions" / ".cache").mkdir(parents=True)
    (config / "extensions" / ".cache" / "compat.dat").write_bytes(b"\x1f\x8b\x08")  # a gzip cut short
    # as a TD runs it (a process of its own: this one's Blender put its script folders on sys.path)
    res = subprocess.run([sys.executable, "-m", "pdeface.cli", "batch", str(tmp_path / "job.toml"), "--workers", "2"],
                         capture_output=True, text=True, timeout=900, check=False,
                         env={**os.environ, "BLENDER_USER_RESOURCES": str(config)})
    # exit 2: the file without a face failed its images; the summary on stdout says so
    assert res.returncode == 2 and res.stdout.strip(), f"exit {res.returncode}, stderr:\n{res.stderr[-3000:]}"
    summary = json.loads(res.stdout)
    assert "reading cache failed" in res.stderr  # a worker's Blender printed it
    assert summary["done"] == 4 and summary["failed"] == 4, summary
    assert all("no_face.blend: no PDE face" in e and "\n" not in e for e in summary["errors"].values())
    job = load_job(tmp_path / "job.toml")
    assert len(list((tmp_path / "out" / RECORDS / "faces").glob("*.npz"))) == 1  # read once for the job
    rows = list(csv.DictReader((tmp_path / "out" / "labels.csv").read_text().splitlines()))
    assert sorted((r["identity"], r["intensity"], r["AU12_r"], r["AU01_r"]) for r in rows) == \
        [("td_head", "A", "0.0", "1.0"), ("td_head", "A", "1.0", "0.0"), ("td_head", "E", "0.0", "5.0"),
         ("td_head", "E", "5.0", "0.0")]
    # the images are the .blend's head posed by its own keys, as read here
    identity = load_identity(str(tmp_path / "td_head.blend"), tuple(job.tasks[0].params["keys"]))
    frame_delta = identity.keys["12"]
    assert np.linalg.norm(frame_delta, axis=1).max() > 3  # mm: the lip corners pull
    assert len(identity.vertices) == len(smile)
    images = {}
    for t in job.tasks:
        if t.params["face"].endswith("td_head.blend"):
            write_png(tmp_path / "expected.png", render_identity(identity, t.params["weights"], "front", 48))
            made = (tmp_path / "out" / t.outputs[0]).read_bytes()
            assert made == (tmp_path / "expected.png").read_bytes(), t.name
            images[t.name] = made
    assert images["td_head_AU12_A_front.png"] != images["td_head_AU12_E_front.png"]
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert sorted(t["status"] for t in manifest["tasks"]) == ["done"] * 4 + ["failed"] * 4
