"""Every kind of file the add-on opens, broken, huge, NaN/inf or of the wrong types: each operator reports one
line (no "Python: Traceback", no internal error) and leaves the scene as it was (issue #38)."""
import io
import json
import zipfile

import numpy as np
import pytest

MODULE = "bl_ext.pdeface_test.pdeface"


def model_bytes(**replace):
    """The bundled face model's file with arrays replaced (``name=array``) or dropped (``name=None``)."""
    from pdeface.au.modelfile import load_face, model_to_bytes
    with zipfile.ZipFile(io.BytesIO(model_to_bytes(load_face("default")))) as zf:
        arrays = {n[:-4]: np.load(io.BytesIO(zf.read(n))) for n in zf.namelist()}
    if "every" in replace:
        every = replace.pop("every")
        arrays = {k: every(a) for k, a in arrays.items()}
    for k, v in replace.items():
        if v is None:
            arrays.pop(k)
        else:
            arrays[k] = v(arrays[k]) if callable(v) else v
    out = io.BytesIO()
    np.savez_compressed(out, **arrays)
    return out.getvalue()


def zip_bomb():
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("meta.npy", b"\0" * 128 * 2**20)
    return buf.getvalue()


def nan_everywhere(a):
    return np.full_like(a, np.nan) if a.dtype.kind == "f" else a


MODELS = {
    "broken": lambda: b"PK\x03\x04" + b"\x00garbage" * 100,
    "empty": lambda: b"",
    "huge": zip_bomb,
    "nan in every float": lambda: model_bytes(every=nan_everywhere),
    "inf frame": lambda: model_bytes(frame=lambda a: np.full_like(a, np.inf)),
    "huge frame": lambda: model_bytes(frame=lambda a: a * 1e300),
    "text layout": lambda: model_bytes(layout=np.array(["a", "b", "c"])),
    "no coefficients": lambda: model_bytes(coefficients=None),
}
TIMELINES = {
    "broken": b'{"fps": 24, "keys": [',
    "empty": b"",
    "wrong types": json.dumps({"fps": "fast", "keys": {"a": 1}}).encode(),
    "nan fps": b'{"fps": NaN, "keys": []}',
    "deep": b"[" * 100000,
    "5000 digits": b'{"fps": ' + b"9" * 5000 + b', "keys": []}',
}
PRESETS = {
    "broken": b'{"name": "x", "aus": {',
    "wrong types": json.dumps({"name": ["x"], "aus": "12"}).encode(),
    "nan weight": b'{"name": "x", "aus": {"12": NaN}}',
    "inf weight": b'{"name": "x", "aus": {"12": Infinity}}',
    "5000 digits": b'{"name": "x", "aus": {"12": ' + b"1" * 5000 + b"}}",
    "deep": b"{" * 100000,
}
FDTS = {
    "broken": b'{"name": "x", "regions": ',
    "wrong types": json.dumps({"name": 5, "model": [], "regions": "all"}).encode(),
    "nan table": b'{"format": "pdeface.fdt", "name": "x", "model": "3d", "regions": {"mouth": [NaN, NaN]}}',
    "list": b"[1, 2, 3]",
    "deep": b"[" * 100000,
}
TRACKERS = {
    "broken": b"frame, timestamp, AU12_r\n1, 0.0, lots\n",
    "empty": b"",
    "nan": b"frame, face_id, timestamp, confidence, success, AU12_r\n1, 0, nan, 0.98, 1, nan\n2, 0, inf, 0.98, 1, 1\n",
    "binary": bytes(range(256)) * 40,
    "no AU columns": b"frame, timestamp\n1, 0.0\n",
    "huge field": b"frame, timestamp, AU12_r\n1, 0.0, " + b"1" * 200_000 + b"\n",
}
LANDMARKS = {
    "broken": b'{"points": [[0, 0',
    "wrong types": json.dumps({"points": "here"}).encode(),
    "nan": json.dumps({"points": [[float("nan")] * 3] * 68}).encode(),
    "inf": b'{"points": [' + b",".join([b"[Infinity, 0, 0]"] * 68) + b"]}",
    "indices out of range": json.dumps({"indices": [10**12] * 68}).encode(),
    "too few": json.dumps({"indices": [1, 2, 3]}).encode(),
}


def scene_state(bpy):
    """What an operator could change: objects, their shape keys and values, animation, frame range, settings."""
    state = {"frames": (bpy.context.scene.frame_start, bpy.context.scene.frame_end),
             "actions": sorted((a.name, tuple(a.frame_range)) for a in bpy.data.actions)}
    for o in bpy.data.objects:
        keys = o.data.shape_keys if o.type == "MESH" else None
        ad = keys.animation_data if keys else None
        state[o.name] = (len(o.data.vertices) if o.type == "MESH" else 0,
                         [(k.name, round(k.value, 6)) for k in keys.key_blocks] if keys else None,
                         ad.action.name if ad and ad.action else None)
    return state


def refused(bpy, call):
    """Run the operator ``call``; its one-line error report, checked to be no internal error or traceback."""
    before = scene_state(bpy)
    with pytest.raises(RuntimeError) as exc:
        call()
    message = str(exc.value).strip()
    addon = __import__(MODULE + ".operators", fromlist=["operators"])
    assert len(message.splitlines()) == 1 and "Traceback" not in message, message
    assert addon.BUG not in message, message
    assert scene_state(bpy) == before
    return message


def write(tmp_path, name, data):
    path = tmp_path / name
    path.write_bytes(data() if callable(data) else data)
    return str(path)


@pytest.mark.parametrize("case", MODELS)
def test_bad_model_files(bpy, tmp_path, case):
    path = write(tmp_path, "face.npz", MODELS[case])
    message = refused(bpy, lambda: bpy.ops.pdeface.add_default_face(model_path=path))
    assert "face.npz" in message


@pytest.mark.parametrize("case", TIMELINES)
def test_bad_timelines(bpy, face, tmp_path, case):
    path = write(tmp_path, "t.json", TIMELINES[case])
    assert "t.json" in refused(bpy, lambda: bpy.ops.pdeface.import_au(filepath=path, format="timeline"))


@pytest.mark.parametrize("case", PRESETS)
def test_bad_preset_files(bpy, face, tmp_path, case):
    bpy.context.scene.pdeface.presets_file = write(tmp_path, "p.json", PRESETS[case])
    assert "p.json" in refused(bpy, lambda: bpy.ops.pdeface.build_shape_keys())
    refused(bpy, lambda: bpy.ops.pdeface.animate_sequence(presets="happy"))


@pytest.mark.parametrize("case", FDTS)
def test_bad_fdt_files(bpy, face, tmp_path, case):
    path = write(tmp_path, "x.fdt.json", FDTS[case])
    assert "x.fdt.json" in refused(bpy, lambda: bpy.ops.pdeface.load_fdt(filepath=path))


@pytest.mark.parametrize("case", TRACKERS)
def test_bad_tracker_files(bpy, face, tmp_path, case):
    path = write(tmp_path, "au.csv", TRACKERS[case])
    assert "au.csv" in refused(bpy, lambda: bpy.ops.pdeface.import_au(filepath=path))


@pytest.mark.parametrize("case", LANDMARKS)
def test_bad_landmark_files(bpy, scan_object, tmp_path, case):
    s = bpy.context.scene.pdeface
    s.landmark_source = "FILE"
    s.landmark_file = write(tmp_path, "lm.json", LANDMARKS[case])
    refused(bpy, lambda: bpy.ops.pdeface.fit_to_selected())


def test_an_unexpected_exception_is_one_line_saying_it_is_a_bug(bpy, face, monkeypatch):
    addon = __import__(MODULE + ".operators", fromlist=["operators"])

    def broken(*args, **kwargs):
        raise KeyError("multi\nline")
    monkeypatch.setattr(addon.keys, "set_pose", broken)
    with pytest.raises(RuntimeError) as exc:
        bpy.ops.pdeface.reset_pose()
    message = str(exc.value).strip()
    assert len(message.splitlines()) == 1 and addon.BUG in message and "KeyError" in message
