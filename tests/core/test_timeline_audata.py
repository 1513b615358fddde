import json

import numpy as np
import pytest
from pdeface.animation.timeline import load_timeline, save_timeline, sequence_timeline, timeline_from_json
from pdeface.animation.trackers import ARKIT_TO_AU, detect_format, import_au, reduce_keys, smooth
from pdeface.cli import main
from pdeface.errors import ModelFormatError

GOOD = {"format": "pdeface.timeline", "version": 1, "fps": 10, "frame_start": 1,
        "keys": [{"time": 0, "aus": {}}, {"time": 0.5, "aus": {"AU12": 0.8, "6": "C"}, "interpolation": "linear"},
                 {"frame": 20, "presets": ["happy"]}, {"time": 3.0, "presets": {"sad": 0.5}, "interpolation": "constant"}]}


def test_timeline_format(tmp_path):
    t = timeline_from_json(GOOD)
    assert [k.frame for k in t.keys] == [1, 6, 20, 31]
    assert t.keys[1].aus == {"12": 0.8, "6": 0.6} and t.keys[1].interpolation == "linear"
    assert t.keys[2].presets == {"happy": 1.0} and t.keys[3].interpolation == "constant"
    assert t.channels() == (["6", "12"], ["happy", "sad"])
    save_timeline(tmp_path / "t.json", t)
    back = load_timeline(tmp_path / "t.json")
    assert [(k.frame, k.aus, k.presets, k.interpolation) for k in back.keys] == \
        [(k.frame, k.aus, k.presets, k.interpolation) for k in t.keys]


@pytest.mark.parametrize("change, message", [
    ({"format": "x"}, "'format'"),
    ({"fps": 0}, "'fps'"),
    ({"keys": []}, "'keys'"),
    ({"keys": [{"aus": {}}]}, r"keys\[0\] needs exactly one of 'time'"),
    ({"keys": [{"time": 1, "frame": 3}]}, "exactly one"),
    ({"keys": [{"time": -1}]}, r"keys\[0\]: field 'time'"),
    ({"keys": [{"time": 0, "aus": {"3": 1}}]}, r"keys\[0\]: field 'aus'"),
    ({"keys": [{"time": 0, "aus": {"12": "Q"}}]}, r"keys\[0\]: field 'aus'"),
    ({"keys": [{"time": 0, "presets": 5}]}, "'presets'"),
    ({"keys": [{"time": 0, "interpolation": "cubic"}]}, "'interpolation'"),
    ({"keys": [{"frame": 5}, {"frame": 5}]}, r"keys\[1\]: frame 5 is not after"),
])
def test_timeline_errors_name_the_field(change, message):
    with pytest.raises(ModelFormatError, match=message):
        timeline_from_json({**GOOD, **change})


def test_sequence_timeline():
    t = sequence_timeline(["happy", "sad"], fps=10, hold=0.5, blend=0.5)
    assert [k.frame for k in t.keys] == [1, 6, 11, 16, 21, 26, 31, 36]
    assert t.keys[1].presets == {"happy": 1.0} and t.keys[3].presets == {}


def openface(path, rows, extra_cols=""):
    head = "frame, face_id, timestamp, confidence, success, AU01_r, AU12_r, AU99_r, AU01_c, AU12_c, AU28_c" + extra_cols
    path.write_text(head + "\n" + "\n".join(rows) + "\n")
    return path


def test_openface(tmp_path):
    p = openface(tmp_path / "of.csv", [
        "1, 0, 0.000, 0.98, 1, 0.0, 5.0, 1.0, 0, 1, 0",
        "2, 0, 0.100, 0.98, 1, 2.5, 2.5, 1.0, 1, 1, 1",
        "3, 0, 0.200, 0.10, 1, 5.0, 5.0, 1.0, 1, 1, 1",  # low confidence: dropped
        "4, 0, 0.300, 0.98, 0, 5.0, 5.0, 1.0, 1, 1, 1",  # tracking failed: dropped
        "5, 1, 0.300, 0.98, 1, 5.0, 5.0, 1.0, 1, 1, 1",  # another face
        "6, 0, 0.400, 0.98, 1, 5.0, 1.0, 1.0, 1, 0, 0",  # AU12 marked absent
    ])
    assert detect_format(p) == "openface"
    r = import_au(p, fps=10)
    assert r.format == "openface" and r.dropped == 2 and r.unknown == ["AU99_r"]
    k = {key.frame: key.aus for key in r.timeline.keys}
    assert sorted(k) == [1, 2, 5]
    assert k[1] == {"1": 0.0, "12": 1.0, "28": 0.0}
    assert k[2] == {"1": 0.5, "12": 0.5, "28": 1.0}
    assert k[5] == {"1": 1.0, "12": 0.0, "28": 0.0}
    bad = openface(tmp_path / "bad.csv", ["1, 0, 0.0, 0.98, 1, 0.0, oops, 1.0, 0, 1, 0"])
    with pytest.raises(ModelFormatError, match=r"bad.csv:2: column 'AU12_r' is not a number"):
        import_au(bad)
    short = openface(tmp_path / "short.csv", ["1, 0, 0.0, 0.98, 1, 0.0"])
    with pytest.raises(ModelFormatError, match="short.csv:2: 6 columns"):
        import_au(short)


def test_pyfeat(tmp_path):
    p = tmp_path / "feat.csv"
    p.write_text("frame,FaceScore,AU01,AU12,AU43\n0,0.99,0.1,0.9,0.2\n1,0.2,0.5,0.5,0.5\n2,0.95,,,\n3,0.97,0.3,0.4,0.5\n")
    assert detect_format(p) == "pyfeat"
    r = import_au(p, fps=30)
    assert r.dropped == 2
    assert [(k.frame, k.aus) for k in r.timeline.keys] == [(1, {"1": 0.1, "12": 0.9, "43": 0.2}),
                                                          (4, {"1": 0.3, "12": 0.4, "43": 0.5})]


def test_live_link_face(tmp_path):
    names = ["EyeBlinkLeft", "MouthSmileLeft", "MouthSmileRight", "BrowInnerUp", "MouthRollLower",
             "MouthRollUpper", "TongueOut", "HeadYaw"]
    p = tmp_path / "llf.csv"
    p.write_text("Timecode,BlendShapeCount," + ",".join(names) + "\n"
                 "10:00:00:00.000,61,1.0,0.5,0.25,0.0,0.4,0.6,0.9,0.1\n"
                 "10:00:00:30.000,61,0.0,0.0,0.0,1.0,0.0,0.0,0.0,0.0\n")
    assert detect_format(p) == "livelink"
    guessed = import_au(p, fps=60)  # under a second: frames up to 30 only bound the timecode's rate
    assert guessed.capture_fps == 48 and "shorter than a second" in guessed.notes[0]
    r = import_au(p, fps=60, capture_fps=60)
    assert r.notes == [] and r.capture_fps == 60
    assert r.unknown == ["HeadYaw", "TongueOut"]
    first, second = r.timeline.keys
    assert (first.frame, second.frame) == (1, 31)  # 30 frames at 60 fps = 0.5 s
    assert first.aus["45L"] == 1.0 and first.aus["12L"] == 0.5 and first.aus["12R"] == 0.25
    assert first.aus["28"] == pytest.approx(0.5)  # mean of the two rolls, as ICT builds AU28
    assert second.aus["1"] == 1.0
    assert ARKIT_TO_AU["jawopen"] == [("27", 1.0)]


def live_link_clip(path, capture_fps, seconds=5.0):
    """A Live Link Face CSV captured at ``capture_fps``: jawOpen ramps 0 → 1 over the clip."""
    n = int(seconds * capture_fps)
    lines = ["Timecode,BlendShapeCount,JawOpen"]
    start = 9 * 3600 + 59 * 60 + 58  # 09:59:58, so the clip crosses an hour
    for i in range(n):
        s, f = divmod(i, capture_fps)
        h, rest = divmod(start + s, 3600)
        lines.append(f"{h:02d}:{rest // 60:02d}:{rest % 60:02d}:{f:02d}.000,61,{i / n:.6f}")
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("capture_fps", [30, 60])
def test_live_link_face_timecode_counts_at_the_capture_rate(tmp_path, capture_fps):
    # A 5 s clip comes out 5 s long at the timeline's 30 fps, the ramp rising with no jitter.
    r = import_au(live_link_clip(tmp_path / "clip.csv", capture_fps), fps=30)
    assert r.capture_fps == capture_fps and r.notes == []
    frames = np.array([k.frame for k in r.timeline.keys])
    jaw = np.array([k.aus["27"] for k in r.timeline.keys])
    last_t = (5 * capture_fps - 1) / capture_fps  # the last sample, 4.97-4.98 s after the first
    assert frames[0] == 1 and frames[-1] == 1 + int(np.floor(last_t * 30 + 0.5))
    assert np.all(np.diff(frames) == 1) and np.all(np.diff(jaw) > 0)
    expected = (frames - 1) / 30 / 5.0  # jawOpen at the frame's time
    assert np.abs(jaw - expected).max() < 1.5 / capture_fps / 5.0


def test_fas_text(tmp_path):
    p = tmp_path / "fas.txt"
    p.write_text("# surprise, then happiness\n{1,2,5,15,16,20,26}\n\n{1,6,12,14}\n{12:0.5,6C,99}\n")
    assert detect_format(p) == "fas"
    r = import_au(p, fps=10, hold=1.0)
    assert r.rows == 3 and r.unknown == ["AU99"]
    frames = [k.frame for k in r.timeline.keys]
    assert frames == sorted(frames) and frames[0] == 1
    k = {key.frame: key.aus for key in r.timeline.keys}
    assert k[4] == {a: 1.0 for a in ("1", "2", "5", "15", "16", "20", "26")}  # in after 250 ms, held to 1 s
    assert k[11] == k[4]
    assert k[24] == {"12": 0.5, "6": 0.6}
    (tmp_path / "bad.txt").write_text("{1,2}\n{1,x}\n")
    with pytest.raises(ModelFormatError, match=r"bad.txt:2: bad item 'x'"):
        import_au(tmp_path / "bad.txt")


def test_smoothing_and_reduction():
    x = np.arange(100)
    v = np.c_[np.clip((x - 20) / 30, 0, 1), np.zeros(100)]
    keep = reduce_keys(x, v, 0.01)
    assert list(keep) == [0, 20, 50, 99]  # a ramp: its corners only
    noisy = v + np.random.default_rng(0).normal(0, 0.05, v.shape)
    assert np.abs(smooth(noisy, 9) - v)[10:-10].std() < np.abs(noisy - v).std() / 2


def test_unknown_and_broken_files(tmp_path):
    (tmp_path / "x.csv").write_text("a,b,c\n1,2,3\n")
    with pytest.raises(ModelFormatError, match="x.csv:1: unknown AU data format"):
        import_au(tmp_path / "x.csv")
    with pytest.raises(ModelFormatError, match="cannot open"):
        import_au(tmp_path / "missing.csv")
    openface(tmp_path / "none.csv", ["1, 0, 0.0, 0.1, 1, 0.0, 0.0, 0.0, 0, 0, 0"])
    with pytest.raises(ModelFormatError, match="no usable rows"):
        import_au(tmp_path / "none.csv")


def test_import_au_cli(tmp_path, capsys):
    p = openface(tmp_path / "of.csv", [f"{i}, 0, {i / 30:.4f}, 0.98, 1, {i % 5}.0, 1.0, 0.0, 1, 1, 0" for i in range(60)])
    code = main(["import-au", str(p), "--fps", "30", "--smooth", "3", "--reduce", "0.01", "-o", str(tmp_path / "t.json")])
    out = capsys.readouterr()
    assert code == 0 and "AU99_r" in out.err
    summary = json.loads(out.out)
    assert summary["format"] == "openface" and summary["aus"] == ["1", "12", "28"] and summary["keys"] < 60
    t = load_timeline(tmp_path / "t.json")
    assert t.fps == 30 and len(t.keys) == summary["keys"]
    code = main(["import-au", str(tmp_path / "nope.csv"), "-o", str(tmp_path / "u.json")])
    assert code == 2 and "cannot open" in capsys.readouterr().err


def test_cli_reads_the_capture_rate_or_takes_it(tmp_path, capsys):
    clip = live_link_clip(tmp_path / "clip.csv", 60, seconds=2.0)
    assert main(["import-au", str(clip), "--fps", "30", "-o", str(tmp_path / "t.json")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["capture_fps"] == 60 and out["frames"] == [1, 61]
    # told a wrong rate (the clip's frames reach 59), it says so
    assert main(["import-au", str(clip), "--capture-fps", "30", "-o", str(tmp_path / "u.json")]) == 2
    assert "does not fit 30" in capsys.readouterr().err


def test_neutral_in_a_sequence_is_the_rest_pose():
    from pdeface.animation.timeline import sequence_timeline
    t = sequence_timeline(["neutral", "happy"], fps=4, hold=0.5, blend=0.5)
    assert t.channels() == ([], ["happy"])  # no channel a face would lack: nothing reported missing
    assert [k.presets for k in t.keys][:3] == [{}, {}, {}] and any(k.presets == {"happy": 1.0} for k in t.keys)
