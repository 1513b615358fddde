"""``pdeface rig`` and ``pdeface batch``: job files, task keys, and jobs on a local Dask cluster of 2 processes
(a worker killed mid-job, an interrupted job resumed, failures recorded)."""
import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from pdeface.assets import load_ict_shapes, load_neutral_scan
from pdeface.batch.job import JobError, plan_job
from pdeface.batch.run import labels_csv, local_workers
from pdeface.batch.work import RECORDS, one_line
from pdeface.errors import LandmarkError
from pdeface.io.meshio import write_mesh
from pdeface.rig import load_keys

distributed = pytest.importorskip("distributed")
psutil = pytest.importorskip("psutil")


def _pdeface(*args, **kwargs):
    return subprocess.Popen([sys.executable, "-m", "pdeface.cli", *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kwargs)


def _finish(proc, timeout=600):
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out, err


def _job(tmp_path, text, name="job.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _identity(folder, i):
    """An ICT identity's face region as an OBJ with its landmarks JSON beside it (``{stem}.json``)."""
    mesh, idx = load_neutral_scan()
    mesh.vertices = mesh.vertices + load_ict_shapes()[f"identity{i:03d}"]
    path = folder / f"ict{i:03d}.obj"
    write_mesh(path, mesh)
    (folder / f"ict{i:03d}.json").write_text(json.dumps({"indices": idx.tolist()}))
    return path


STIMULI = """kind = "stimuli"
out = "{out}"
faces = ["default"]
aus = [[12], [1, 2], [4]]
intensities = ["B", "E"]
views = ["front", "yaw20"]
size = 48
"""


def _outputs(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(Path(folder).rglob("*.png"))}


def _workers(proc):
    """The job's Dask worker processes (started by the nannies, which run in the job's process), once both are
    up."""
    for _ in range(1200):
        workers = local_workers(proc.pid)
        if len(workers) >= 2:
            return workers
        time.sleep(0.1)
    raise AssertionError("the local cluster's workers did not start")


def _records(out):
    """How many tasks of the job in ``out`` are done (their records written)."""
    return len(list((out / RECORDS).glob("*.json"))) if (out / RECORDS).exists() else 0


def _wait_for_records(out, n, proc, timeout=300):
    t0 = time.time()
    while time.time() - t0 < timeout:
        if _records(out) >= n:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise AssertionError("the job made no progress")


def _as_a_terminal_job():
    """In the child, before it runs: its own process group with SIGINT at its default, as a shell's foreground job
    has it. A job started in the background by a shell without job control (CI runs pytest so) inherits SIGINT
    ignored, and a Ctrl-C could not reach it."""
    os.setpgid(0, 0)
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_job_files_are_checked(tmp_path):
    for data, message in [({"kind": "paint", "out": "o"}, "'kind' must be one of"),
                          ({"kind": "rig", "out": "o", "meshes": ["m.obj"], "colour": 1}, "unknown key 'colour'"),
                          ({"kind": "rig", "meshes": ["m.obj"]}, "'out'"),
                          ({"kind": "rig", "out": "o", "meshes": ["nothing*.obj"]}, "matches no file"),
                          ({"kind": "stimuli", "out": "o", "faces": ["default"]}, "give 'aus'"),
                          ({"kind": "stimuli", "out": "o", "faces": ["default"], "aus": [[12]],
                            "intensities": ["F"]}, "FACS letter"),
                          ({"kind": "stimuli", "out": "o", "faces": ["default"], "aus": [[12]], "samples": 3},
                           "a square"),
                          ({"kind": "stimuli", "out": "o", "faces": ["default"], "aus": [[12]], "views": ["up"]},
                           "view 'up'"),
                          ({"kind": "stimuli", "out": "o", "faces": ["default"], "aus": [[12]], "lights": ["disco"]},
                           "light 'disco'"),
                          ({"kind": "stimuli", "out": "o", "faces": ["default"], "aus": [[12]],
                            "lights": [{"direction": [0, 0]}]}, "a custom light")]:
        with pytest.raises(JobError, match=message) as info:
            plan_job(data, tmp_path)
        assert "\n" not in str(info.value)


def test_stimulus_tasks_are_keyed_by_their_inputs_and_labelled(tmp_path):
    data = {"kind": "stimuli", "out": "o", "faces": ["default"], "aus": [[12], [1, 2]], "presets": ["happy"],
            "intensities": ["A", "E", 0.5], "views": ["front", "left"], "size": 32}
    job = plan_job(data, tmp_path)
    assert len(job.tasks) == 3 * 3 * 2
    assert len({t.key for t in job.tasks}) == len(job.tasks) == len({t.outputs[0] for t in job.tasks})
    assert [t.key for t in plan_job(data, tmp_path).tasks] == [t.key for t in job.tasks]
    bigger = plan_job({**data, "size": 64}, tmp_path)
    assert not {t.key for t in bigger.tasks} & {t.key for t in job.tasks}
    rows = list(csv.DictReader(labels_csv(job, {t.key: {"status": "done"} for t in job.tasks}).splitlines()))
    assert len(rows) == len(job.tasks)
    assert {"AU01_r", "AU02_r", "AU06_r", "AU12_r", "AU01_c", "AU12_c", "identity", "view", "intensity"} <= set(rows[0])
    one = next(r for r in rows if r["file"] == "default_AU01+02_E_left.png")
    assert (one["AU01_r"], one["AU02_r"], one["AU12_r"], one["AU01_c"], one["AU12_c"]) == \
        ("5.0", "5.0", "0.0", "1", "0")
    assert next(r for r in rows if r["file"] == "default_AU12_w0.5_front.png")["AU12_r"] == "2.5"
    sampled = plan_job({**data, "sampler": {"count": 7, "seed": 3}}, tmp_path)
    again = plan_job({**data, "sampler": {"count": 7, "seed": 3}}, tmp_path)
    assert [t.outputs for t in sampled.tasks] == [t.outputs for t in again.tasks] and len(sampled.tasks) == 7


def test_lights_are_crossed_with_views_keyed_labelled_and_seen(tmp_path):
    from pdeface.batch.stimuli import load_identity, render_identity

    data = {"kind": "stimuli", "out": "o", "faces": ["default"], "aus": [[12]], "intensities": ["E"],
            "views": ["front", "left"], "size": 48}
    plain = plan_job(data, tmp_path)
    lit = plan_job({**data, "lights": ["studio", "top", {"direction": [0, -1, 1], "strength": 0.8, "name": "low"},
                                       "front"]}, tmp_path)
    assert len(lit.tasks) == 2 * len(plain.tasks) * 2
    assert len({t.key for t in lit.tasks}) == len(lit.tasks) == len({t.outputs[0] for t in lit.tasks})
    assert not {t.key for t in lit.tasks} & {t.key for t in plain.tasks}
    assert "default_AU12_E_left_low.png" in {t.outputs[0] for t in lit.tasks}
    assert all("light" not in t.params for t in plain.tasks)  # a job without lights: its keys and names as before
    rows = list(csv.DictReader(labels_csv(lit, {t.key: {"status": "done"} for t in lit.tasks}).splitlines()))
    assert sorted({(r["view"], r["light"]) for r in rows}) == sorted(
        (v, x) for v in ("front", "left") for x in ("front", "low", "studio", "top"))
    assert {r["light"] for r in csv.DictReader(labels_csv(plain, {t.key: {"status": "done"} for t in plain.tasks})
                                                .splitlines())} == {"front"}
    face = load_identity("default", ("12",))
    by_light = {t.label["light"]: render_identity(face, t.params["weights"], "front", 48, 1, 0.0,
                                                  t.params.get("lights"))
                for t in lit.tasks if t.label["view"] == "front"}
    assert np.array_equal(by_light["front"], render_identity(face, {"12": 1.0}, "front", 48))
    grey = {name: img[..., 0].astype(float) for name, img in by_light.items()}
    seen = grey["front"] > 0
    for a in grey:
        for b in grey:
            if a < b:  # the same face, lit otherwise: clearly other shading on the face
                assert np.abs(grey[a] - grey[b])[seen].mean() > 5, (a, b)
    # lit from above: the brow (upper half) brighter than under the chin and nose in the lower half
    rows_seen = np.nonzero(seen.any(axis=1))[0]
    mid = (rows_seen[0] + rows_seen[-1]) // 2
    top, low = grey["top"], grey["low"]
    assert top[:mid][seen[:mid]].mean() - top[mid:][seen[mid:]].mean() > \
        low[:mid][seen[:mid]].mean() - low[mid:][seen[mid:]].mean()


def test_one_line_errors():
    assert one_line(LandmarkError("m.obj: no face found\nmore")) == "m.obj: no face found"
    assert one_line(ValueError("bad\nvalue")) == "ValueError: bad"


def test_a_local_worker_prints_on_stderr_and_leaves_ctrl_c_to_the_job():
    """What a local worker runs as it starts (:func:`~pdeface.batch.work.dask_setup`): what it prints, through
    Python or not, goes to stderr (the job's stdout is its JSON summary), and SIGINT is ignored."""
    code = ("import os, signal\nfrom pdeface.batch.work import dask_setup\ndask_setup(None)\n"
            "print('python', signal.getsignal(signal.SIGINT) is signal.SIG_IGN, flush=True)\nos.write(1, b'raw')\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False,
                         preexec_fn=_as_a_terminal_job)
    assert res.returncode == 0, res.stderr
    assert res.stdout == "" and res.stderr == "python True\nraw"


def test_a_killed_worker_loses_nothing(tmp_path):
    """Kill one of the 2 workers mid-job: the job completes, each image exists once, byte-identical to a serial
    run's (1 worker), and the labels too."""
    job = _job(tmp_path, STIMULI.format(out="par"))
    proc = _pdeface("batch", job, "--workers", 2)
    workers = _workers(proc)
    _wait_for_records(tmp_path / "par", 1, proc)
    workers[0].send_signal(signal.SIGKILL)
    code, out, err = _finish(proc)
    assert code == 0, err
    assert json.loads(out)["done"] == 12
    serial = _job(tmp_path, STIMULI.format(out="ser"), "serial.toml")
    code, _, err = _finish(_pdeface("batch", serial, "--workers", 1))
    assert code == 0, err
    made, expected = _outputs(tmp_path / "par"), _outputs(tmp_path / "ser")
    assert len(expected) == 12 and made == expected
    assert (tmp_path / "par" / "labels.csv").read_bytes() == (tmp_path / "ser" / "labels.csv").read_bytes()
    assert not [p for p in (tmp_path / "par").rglob("*.part")]


def test_an_interrupted_job_resumes_with_only_the_missing_outputs(tmp_path):
    """Ctrl-C (SIGINT to the job's process group, workers included) stops the job: no task starts after it (those
    running may finish), its worker processes are gone when it exits 130 saying how to resume, and ``--resume``
    makes only the missing outputs. However fast the machine, at most 2 tasks per worker finish after the
    interrupt, far fewer than the 60 images of the job."""
    n, workers = 60, 2
    job = _job(tmp_path, STIMULI.format(out="out").replace('aus = [[12], [1, 2], [4]]',
                                                           'aus = [[12], [1, 2], [4], [6], [15], [9, 10]]')
               .replace('intensities = ["B", "E"]', 'intensities = ["A", "B", "C", "D", "E"]')
               .replace("size = 48", "size = 192"))
    out = tmp_path / "out"
    proc = _pdeface("batch", job, "--workers", workers, preexec_fn=_as_a_terminal_job)
    job_workers = _workers(proc)
    _wait_for_records(out, 3, proc)
    os.killpg(proc.pid, signal.SIGINT)
    at_interrupt = _records(out)
    t0 = time.time()
    try:
        code, _, err = _finish(proc, timeout=120)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        raise AssertionError("the job did not stop within 120 s of the interrupt") from None
    stopped_in = time.time() - t0
    assert code == 130, err
    assert "--resume" in err and "Traceback" not in err, err
    _, alive = psutil.wait_procs(job_workers, timeout=5)
    assert not alive, "the job's workers outlived it"
    records = _records(out)  # final: nothing is left that could write one
    assert at_interrupt <= records <= at_interrupt + 2 * workers < n, (at_interrupt, records, stopped_in)
    before = {p: p.stat().st_mtime_ns for p in out.glob("*.png")}
    code, stdout, err = _finish(_pdeface("batch", job, "--workers", workers, "--resume"))
    assert code == 0, err
    summary = json.loads(stdout)
    assert summary["skipped"] == records and summary["done"] == n - records
    assert len(list(out.glob("*.png"))) == n
    kept = [p for p in before if p.stat().st_mtime_ns == before[p]]
    assert len(kept) >= records  # the done ones were not made again
    with open(out / "labels.csv") as f:
        assert len(list(csv.DictReader(f))) == n


def test_a_terminated_job_stops_as_an_interrupted_one(tmp_path):
    """SIGTERM (``kill``, a cluster's time limit; a job started in the background ignores Ctrl-C) stops a job as
    Ctrl-C does: no task starts after it, its workers are gone when it exits 143 saying how to resume, and its
    manifest lists every task."""
    n, workers = 12, 2
    job = _job(tmp_path, STIMULI.format(out="out").replace("size = 48", "size = 192"))
    out = tmp_path / "out"
    proc = _pdeface("batch", job, "--workers", workers)
    job_workers = _workers(proc)
    _wait_for_records(out, 1, proc)
    proc.terminate()
    at_signal = _records(out)
    code, _, err = _finish(proc, timeout=120)
    assert code == 143, err
    assert "--resume" in err and "Traceback" not in err, err
    _, alive = psutil.wait_procs(job_workers, timeout=5)
    assert not alive, "the job's workers outlived it"
    records = _records(out)
    assert at_signal <= records <= at_signal + 2 * workers < n, (at_signal, records)
    manifest = json.loads((out / "manifest.json").read_text())
    assert len(manifest["tasks"]) == n and [t["status"] for t in manifest["tasks"]].count("not run") >= n - records


def test_a_rig_job_rigs_each_head_and_records_a_broken_one(tmp_path):
    """2 ICT identities and a broken mesh: both heads get their keys, the broken one is failed in the manifest
    with its one-line error, and the job exits 2 naming the manifest."""
    for i in (1, 2):
        _identity(tmp_path, i)
    (tmp_path / "broken.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 3\n")
    job = _job(tmp_path, 'kind = "rig"\nout = "rigs"\nmeshes = ["ict*.obj", "broken.obj"]\n'
                         'landmarks = "{stem}.json"\npresets = false\n')
    code, _, err = _finish(_pdeface("batch", job, "--workers", 2))
    assert code == 2, err
    assert "manifest.json" in err
    manifest = json.loads((tmp_path / "rigs" / "manifest.json").read_text())
    status = {t["name"]: t for t in manifest["tasks"]}
    assert status["ict001"]["status"] == status["ict002"]["status"] == "done"
    assert status["broken"]["status"] == "failed" and "broken.obj" in status["broken"]["error"]
    assert "\n" not in status["broken"]["error"]
    k1, k2 = load_keys(tmp_path / "rigs/ict001/keys.npz"), load_keys(tmp_path / "rigs/ict002/keys.npz")
    assert k1["names"] == k2["names"] and len(k1["names"]) >= 60 and all(n.startswith("AU") for n in k1["names"])
    assert k1["deltas"].shape == (len(k1["names"]), 9409, 3)
    smile = k1["names"].index("AU12")
    assert np.linalg.norm(k1["deltas"][smile], axis=1).max() > 0.3  # cm: a smile moves the lips' corners
    assert not np.allclose(k1["deltas"], k2["deltas"])  # each head its own keys
    report = json.loads((tmp_path / "rigs/ict001/report.json").read_text())
    assert report["landmarks"]["source"] == "given" and set(report["timings"]) >= {"fit", "bind", "total"}


def test_pdeface_rig_writes_the_same_bytes_twice(tmp_path, capsys, monkeypatch):
    """``pdeface rig``: every file, and the same bytes for the same inputs (the batch jobs' idempotence rests on
    it), in the command's own process too (its heap kept and grown on a thread: pdeface.heap); the keys are those
    ``pose --mesh`` gives."""
    from pdeface.au.modelfile import load_face
    from pdeface.cli import main
    from pdeface.head.bind import bind_file
    from scipy._lib import _array_api, _util

    for module in (_array_api, _util):  # the command hands scipy's docstring decorators a stand-in: undone after
        if hasattr(module, "FunctionDoc"):
            monkeypatch.setattr(module, "FunctionDoc", module.FunctionDoc)
    mesh = _identity(tmp_path, 3)
    lm = tmp_path / "ict003.json"
    assert main(["rig", str(mesh), "--landmarks", str(lm), "--no-presets", "-o", str(tmp_path / "a")]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["keys"]["count"] == printed["keys"]["aus"] > 60 and "bind" in printed["timings"]
    # each step's CPU seconds (all threads) beside its wall seconds
    assert set(printed["cpu_timings"]) == set(printed["timings"]) and printed["cpu_timings"]["fit"] > 0
    report = json.loads((tmp_path / "a" / "report.json").read_text())
    assert report["cpu_timings"] == printed["cpu_timings"] and report["timings"] == printed["timings"]
    code, _, err = _finish(_pdeface("rig", mesh, "--landmarks", lm, "--no-presets", "-o", tmp_path / "b"))
    assert code == 0, err
    for name in ("landmarks.json", "face.npz", "rigged.npz", "keys.npz"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    keys = load_keys(tmp_path / "a" / "keys.npz")
    _, binding = bind_file(load_face(tmp_path / "a" / "rigged.npz"), str(mesh))
    smile = keys["names"].index("AU12")
    np.testing.assert_allclose(keys["deltas"][smile], binding.pose_displacement({"12": 1.0}), atol=1e-5)


def test_a_keys_file_of_an_estimated_unit_is_posed(tmp_path):
    """A head at no named scale: ``pdeface rig`` writes its unit as millimetres per unit (``0.1mm``), which the
    stimuli read; a keys file an older rig wrote with the unit ``estimated`` is read with the unit estimated again."""
    from pdeface.batch.stimuli import load_identity
    from pdeface.rig import save_keys

    mesh, idx = load_neutral_scan()
    V = mesh.vertices * 100.0  # cm → tenths of a millimetre
    smile = 100.0 * (load_ict_shapes()["mouthSmile_L"] + load_ict_shapes()["mouthSmile_R"])
    poses = []
    for unit in ("0.1mm", "estimated"):
        save_keys(tmp_path / f"{unit}.npz", V, mesh.triangles()[0], V[idx], ["AU12"], smile[None], unit)
        identity = load_identity(str(tmp_path / f"{unit}.npz"), ("12",))
        poses.append(identity.posed({"12": 1.0}))
    # the face frame's millimetres: the smile moves the mouth's corners by centimetres, whichever unit was written
    assert all(np.abs(p - identity.vertices).max() > 5.0 for p in poses)
    np.testing.assert_allclose(poses[0], poses[1], rtol=0.15)


def test_stimuli_of_a_rigged_head_and_a_broken_face(tmp_path):
    """A head's keys file (as ``pdeface rig`` writes it) is posed by its keys; a broken face fails its images
    alone, each with its one-line error in the manifest, and the labels list the images made."""
    from pdeface.batch.job import load_job
    from pdeface.batch.run import run_job
    from pdeface.rig import save_keys

    mesh, idx = load_neutral_scan()
    shapes = load_ict_shapes()
    smile = shapes["mouthSmile_L"] + shapes["mouthSmile_R"]
    (tmp_path / "bob").mkdir()
    save_keys(tmp_path / "bob" / "keys.npz", mesh.vertices, mesh.triangles()[0], mesh.vertices[idx], ["AU12", "happy"],
              np.stack([smile, smile]), "cm")
    (tmp_path / "broken.npz").write_bytes(b"not a face")
    job = load_job(_job(tmp_path, 'kind = "stimuli"\nout = "out"\nfaces = ["bob", "broken.npz"]\n'
                                  'aus = [[12]]\nintensities = ["A", "E"]\nsize = 64\nretries = 0\n'))
    with open(os.devnull, "w") as quiet:
        summary = run_job(job, workers=2, stream=quiet)
    assert summary.done == 2 and len(summary.failed) == 2
    assert all("broken.npz" in e and "\n" not in e for e in summary.failed.values())
    a, e = (np.asarray(bytearray((tmp_path / "out" / f"bob_AU12_{x}_front.png").read_bytes())) for x in "AE")
    assert len(a) != len(e) or (a != e).any()  # the smile shows
    rows = list(csv.DictReader((tmp_path / "out" / "labels.csv").read_text().splitlines()))
    assert [(r["identity"], r["intensity"], r["AU12_r"], r["AU12_c"]) for r in rows] == \
        [("bob", "A", "1.0", "1"), ("bob", "E", "5.0", "1")]
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert sorted(t["status"] for t in manifest["tasks"]) == ["done", "done", "failed", "failed"]
    assert {(t["identity"], t["light"]) for t in manifest["tasks"]} == {("bob", "front"), ("broken", "front")}


def test_the_head_is_bound_once_per_job_and_its_images_are_the_same(tmp_path):
    """The bundled head (seconds to bind) is made once for the job, by one worker, and loaded by every stimulus
    task: the images are those of the head bound in this process."""
    from pdeface.batch.job import load_job
    from pdeface.batch.run import run_job
    from pdeface.batch.stimuli import load_identity, render_identity
    from pdeface.io.png import write_png

    job = load_job(_job(tmp_path, 'kind = "stimuli"\nout = "out"\nfaces = ["head", "default"]\naus = [[12], [1, 2]]\n'
                                  'intensities = ["B", "E"]\nsize = 40\n'))
    with open(os.devnull, "w") as quiet:
        summary = run_job(job, workers=2, stream=quiet)
    assert summary.done == len(job.tasks) == 8 and not summary.failed
    assert len(list((tmp_path / "out" / RECORDS / "faces").glob("*.npz"))) == 1
    head = load_identity("head", tuple(job.tasks[0].params["keys"]))
    for t in job.tasks:
        if t.params["face"] == "head":
            write_png(tmp_path / "expected.png", render_identity(head, t.params["weights"], t.params["view"], 40))
            assert (tmp_path / "out" / t.outputs[0]).read_bytes() == (tmp_path / "expected.png").read_bytes(), t.name
