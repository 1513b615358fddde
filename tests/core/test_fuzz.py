"""Every reader, fed mutated copies of valid files, says what is wrong with a PdeFaceError or reads them.

A fixed slice of scripts/bench/fuzz_readers.py (the long run's harness): the same seed, a few hundred
inputs per reader, so a failure here replays exactly.
"""
import io
import time
import zipfile
import zlib

import numpy as np
import pytest
from pdeface.errors import LandmarkError, ModelFormatError

from scripts.bench import fuzz_readers


@pytest.mark.parametrize("reader", sorted(fuzz_readers.readers()))
def test_mutated_files_raise_only_pdeface_errors(reader):
    r = fuzz_readers.fuzz(reader, 250, seed=0)
    assert r["failures"] == 0, r["examples"]
    assert r["slowest_s"] < 5.0  # the campaign's limit per input (a small fit takes a quarter of a second)
    if reader in fuzz_readers.consumers() and reader not in ("descriptor_pdd", "fas"):
        assert r["consumed"] > 0  # some inputs get past the reader into the code that uses them


def test_structured_mutations_keep_their_grammar_and_reach_the_limits():
    import json
    import random
    rng = random.Random(0)
    doc = json.dumps({"a": [1, 2.5, {"b": "x"}], "c": 3}).encode()
    texts = [fuzz_readers.mutate_json(doc, rng).decode() for _ in range(300)]
    for t in texts:  # each still JSON (with NaN, Infinity and huge integers)
        json.loads(t, parse_int=len)
    assert any("NaN" in t for t in texts) and any("1" * 5000 in t for t in texts) and any("[]" in t for t in texts)
    csv = b"frame,timestamp,AU12_r\n1,0.0,0.5\n2,0.1,0.7"
    rows = [fuzz_readers.mutate_csv(csv, rng) for _ in range(200)]
    assert any(b"nan" in r for r in rows) and any(r.count(b",") != csv.count(b",") for r in rows)
    seed = fuzz_readers.corpus_cache()["model"][1][0]
    with zipfile.ZipFile(io.BytesIO(seed)) as zf:
        names = set(zf.namelist())
    changed = 0
    for _ in range(20):
        with zipfile.ZipFile(io.BytesIO(fuzz_readers.mutate_zip(seed, rng))) as zf:  # still an archive
            changed += set(zf.namelist()) != names or any(zf.read(n) != zipfile.ZipFile(io.BytesIO(seed)).read(n)
                                                          for n in names & set(zf.namelist()))
    assert changed == 20


def test_command_line_arguments_fuzzed_in_process():
    r = fuzz_readers.fuzz_cli(150, seed=0)
    assert r["failures"] == 0, r["examples"]
    assert r["consumed"] > 0  # some commands ran to the end


def refused_fast(call, error, match):
    t = time.process_time()  # CPU time: a loaded machine's wall clock says nothing of what was allocated
    with pytest.raises(error, match=match):
        call()
    assert time.process_time() - t < 1.0


def test_bombs_and_absurd_sizes_are_refused_before_allocating(tmp_path, fitted, scan):
    from pdeface.au.descriptorfile import MAGIC, load_descriptor
    from pdeface.au.modelfile import load_model, model_to_bytes
    from pdeface.surface.fit import fit_face
    # a .pdd whose body inflates to 64 MiB of zeros
    (tmp_path / "bomb.pdd").write_bytes(MAGIC + zlib.compress(b"\0" * 64 * 2**20, 9))
    refused_fast(lambda: load_descriptor(tmp_path / "bomb.pdd"), ModelFormatError, "inflates past")
    # a model archive whose member inflates to 128 MiB
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("meta.npy", b"\0" * 128 * 2**20)
    (tmp_path / "bomb.npz").write_bytes(buf.getvalue())
    refused_fast(lambda: load_model(tmp_path / "bomb.npz"), ModelFormatError, "claim 128 MiB")
    # a model claiming 2,000 points per curve
    model, _ = fitted
    data = bytearray(model_to_bytes(model, descriptors=False))
    with zipfile.ZipFile(io.BytesIO(bytes(data))) as zf:
        arrays = {n[:-4]: np.load(io.BytesIO(zf.read(n))) for n in zf.namelist()}
    arrays["layout"][1] = 2000.0  # points per curve
    out = io.BytesIO()
    np.savez_compressed(out, **arrays)
    (tmp_path / "wide.npz").write_bytes(out.getvalue())
    refused_fast(lambda: load_model(tmp_path / "wide.npz"), ModelFormatError, "2000 points per curve")
    # landmarks with one moved a kilometre, or all scaled by a million
    mesh, T, idx = scan
    L = mesh.vertices[idx].copy()
    far = L.copy()
    far[30] += [0, 0, 1e5]  # cm
    refused_fast(lambda: fit_face(mesh.vertices, T, far, unit="cm"), LandmarkError, "landmark 30 lies .* from the mesh")
    refused_fast(lambda: fit_face(mesh.vertices, T, L * 1e6), LandmarkError, "eyes are|from the mesh")


def test_a_field_past_the_csv_limit_is_named(tmp_path):
    from pdeface.animation.trackers import import_au
    big = tmp_path / "big.csv"
    big.write_text("frame, timestamp, AU12_r\n1, 0.0, " + "1" * 200_000 + "\n")
    with pytest.raises(ModelFormatError, match="big.csv:2: field larger than field limit"):
        import_au(big)


def test_ply_headers_that_once_escaped(tmp_path):
    from pdeface.errors import MeshError
    from pdeface.io.meshio import read_mesh
    cases = {b"ply\nformat binary_little_endian 1.0\nelement vertex 19999999999999999999\nproperty float x\n"
             b"property float y\nproperty float z\nend_header\n\0\0": "elements claimed in",
             b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header": "nothing after 'end_header'"}
    for i, (data, match) in enumerate(cases.items()):
        (tmp_path / f"{i}.ply").write_bytes(data)
        with pytest.raises(MeshError, match=match):
            read_mesh(tmp_path / f"{i}.ply")


def test_a_landmark_whose_coordinates_overflow_is_off_the_mesh(scan):
    from pdeface.surface.fit import fit_face
    mesh, T, idx = scan
    L = mesh.vertices[idx].copy()
    L[17, 1] = 1e308  # a brow landmark: the frame is made of others, so it overflows only in the frame's space
    with pytest.raises(LandmarkError, match="landmark 17 lies inf mm"):
        fit_face(mesh.vertices, T, L, unit="cm")


def test_a_model_whose_curve_parameters_coincide_is_refused(tmp_path):
    from pdeface.au.modelfile import load_face, load_model, model_to_bytes
    with zipfile.ZipFile(io.BytesIO(model_to_bytes(load_face("default"), descriptors=False))) as zf:
        arrays = {n[:-4]: np.load(io.BytesIO(zf.read(n))) for n in zf.namelist()}
    for name, knots in (("squashed", arrays["knots"].astype(np.float64) * 1e-300),
                        ("backwards", arrays["knots"][::-1]), ("short", arrays["knots"][:1])):
        out = io.BytesIO()
        np.savez_compressed(out, **{**arrays, "knots": knots})
        (tmp_path / f"{name}.npz").write_bytes(out.getvalue())
        with pytest.raises(ModelFormatError):  # the surface's equations would be singular
            load_model(tmp_path / f"{name}.npz")


def test_an_input_replays_by_seed_and_index(tmp_path):
    inputs = fuzz_readers.reader_inputs("fas", seed=3)
    made = [next(inputs) for _ in range(40)]
    r = fuzz_readers.replay("reader", "fas", 37, seed=3, save=tmp_path / "in.txt")
    assert (tmp_path / "in.txt").read_bytes() == made[37]  # the same bytes the campaign fed the reader
    assert not r["failure"] and r["outcome"] and r["cpu_s"] < 5.0
    r = fuzz_readers.replay("cli", "pose", 12, seed=3, save=tmp_path / "argv.json")
    assert not r["failure"] and (tmp_path / "argv.json").read_text().startswith('["pose"')


def test_the_time_limit_counts_cpu_time_and_reruns_wall_time_outliers():
    clock = fuzz_readers.Clock(5.0)
    clock.check(0, 1559.0, 0.1, 0.0, lambda: (0.2, 0.1, 0.0))  # stopped while it ran: run again, fast
    clock.check(1, 6.0, 5.5, 0.0, lambda: (0.0, 0.0, 0.0))  # over on CPU: counted, not run again
    clock.check(2, 9.0, 0.1, 0.0, lambda: (9.0, 0.1, 0.0))  # blocked (a read that never ends): counted
    clock.check(3, 8.2, 0.4, 7.7, lambda: 1 / 0)  # waiting for a CPU on a loaded machine: not counted, not rerun
    s = clock.summary()
    assert [o["input"] for o in clock.over] == [1, 2] and s["over_limit"] == 2
    assert [r["input"] for r in s["wall_reruns"]] == [0, 2] and s["slowest_s"] == 1559.0
    assert s["over_limit_on_wall"] == 4
    assert s["slowest_cpu_s"] == 5.5 and s["slowest_cpu_input"] == 1


def test_a_blocked_input_is_timed_on_the_wall_and_a_busy_one_on_the_cpu():
    _, wall, cpu, error, refusal, waited = fuzz_readers.timed(time.sleep, 0.2)
    assert wall >= 0.2 and cpu < 0.1 and wall - waited >= 0.2 and error is None and refusal is None
    _, wall, cpu, *_ = fuzz_readers.timed(lambda: sum(range(3_000_000)))
    assert cpu > 0.01 and cpu <= wall + 0.01


def test_a_target_split_between_processes_joins_into_one_record():
    whole = fuzz_readers.fuzz("fas", 40, seed=5)
    parts = [fuzz_readers.fuzz("fas", 25, seed=5), fuzz_readers.fuzz("fas", 15, seed=5, first=25)]
    [joined] = fuzz_readers.join_parts(parts)
    assert joined["inputs"] == 40 and joined["parts"] == [[0, 25], [25, 15]]
    assert joined["consumed"] == whole["consumed"] and joined["failures"] == whole["failures"] == 0
    [gap] = fuzz_readers.join_parts([parts[0], {**parts[1], "first": 30}])  # inputs 25 to 29 not run: not done
    assert gap["inputs"] == 40 and not gap["done"]
    assert len(fuzz_readers.join_parts([parts[0], {**parts[1], "first": 20}])) == 2  # an overlap: not joined
