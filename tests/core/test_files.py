"""Writes are atomic and never eat a command's own inputs; whatever a command writes, its reader accepts."""
import os
import resource
import signal
import subprocess
import sys

import pytest
from pdeface.animation.timeline import load_timeline
from pdeface.cli import main
from pdeface.errors import FileError
from pdeface.io.files import atomic_open


def test_a_failed_write_leaves_the_old_file_and_no_part(tmp_path):
    target = tmp_path / "old.txt"
    target.write_text("the user's file")
    with pytest.raises(RuntimeError):
        with atomic_open(target) as fh:
            fh.write("half of a new file")
            raise RuntimeError("disk gone")
    assert target.read_text() == "the user's file" and os.listdir(tmp_path) == ["old.txt"]
    with atomic_open(target) as fh:
        fh.write("new")
    assert target.read_text() == "new" and os.listdir(tmp_path) == ["old.txt"]
    with pytest.raises(FileError, match="no_such_folder"):
        with atomic_open(tmp_path / "no_such_folder" / "x.txt") as fh:
            fh.write("x")


def _limit_file_size():
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit then fails with EFBIG
    resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000))


@pytest.mark.skipif(not hasattr(resource, "RLIMIT_FSIZE"), reason="needs POSIX file-size limits")
def test_a_full_disk_names_the_file_and_keeps_the_old_one(tmp_path):
    target = tmp_path / "face.obj"
    target.write_text("# the user's previous mesh\n")
    res = subprocess.run([sys.executable, "-m", "pdeface.cli", "mesh", "default", "-o", str(target)],
                         capture_output=True, text=True, preexec_fn=_limit_file_size, timeout=120)
    assert res.returncode == 2 and f"{target}: cannot write (File too large)" in res.stderr
    assert target.read_text() == "# the user's previous mesh\n" and os.listdir(tmp_path) == ["face.obj"]


def test_an_output_that_is_an_input_is_refused(tmp_path, capsys):
    csv = tmp_path / "track.csv"
    csv.write_text("frame, timestamp, confidence, success, AU12_r\n1, 0.0, 0.98, 1, 5.0\n")
    before = csv.read_bytes()
    assert main(["import-au", str(csv), "-o", str(csv)]) == 2
    assert "is also an input" in capsys.readouterr().err and csv.read_bytes() == before
    lm = tmp_path / "lm.json"
    lm.write_text('{"indices": []}')
    assert main(["fit", str(csv), "--landmarks", str(lm), "-o", str(lm)]) == 2
    assert "is also an input" in capsys.readouterr().err and lm.read_text() == '{"indices": []}'


def test_import_au_writes_only_timelines_its_reader_accepts(tmp_path, capsys):
    fas = tmp_path / "fas.txt"
    fas.write_text("{1}\n{2}\n{4}\n{12}\n")
    # sets held far shorter than a frame: the later set wins its frame, the timeline stays valid
    assert main(["import-au", str(fas), "--hold", "0.01", "--fps", "30", "-o", str(tmp_path / "t.json")]) == 0
    frames = [k.frame for k in load_timeline(tmp_path / "t.json").keys]
    assert frames == sorted(set(frames))
    capsys.readouterr()
    assert main(["import-au", str(fas), "--fps", "5000", "-o", str(tmp_path / "u.json")]) == 2
    assert "fps must be in (0, 1000]" in capsys.readouterr().err and not (tmp_path / "u.json").exists()


def test_write_npz_writes_the_bytes_npz_bytes_gives_and_keeps_the_old_file_on_failure(tmp_path):
    """Written member by member (a head's keys without a whole copy in memory), the same bytes, deflated or
    stored; an array that cannot be written leaves the old file and no part."""
    import numpy as np
    from pdeface.io.files import npz_bytes, write_npz

    arrays = {"format": np.array("x"), "a": np.arange(1000, dtype=np.float32).reshape(10, 100), "b": np.eye(3)}
    for compress in (True, False):
        path = tmp_path / f"{compress}.npz"
        assert write_npz(path, arrays, compress) == len(npz_bytes(arrays, compress))
        assert path.read_bytes() == npz_bytes(arrays, compress)
        with np.load(path) as z:
            assert np.array_equal(z["a"], arrays["a"]) and str(z["format"]) == "x"
    before = (tmp_path / "True.npz").read_bytes()
    with pytest.raises(ValueError):
        write_npz(tmp_path / "True.npz", {"a": np.array([{}], dtype=object)})  # no pickles
    assert (tmp_path / "True.npz").read_bytes() == before
    assert [p.name for p in tmp_path.iterdir() if p.suffix == ".part"] == []
