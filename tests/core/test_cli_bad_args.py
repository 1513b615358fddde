"""Bad arguments are refused at parse time (argparse's usage error: exit 2, one line naming the option),
and no command lets anything but its own one-line error out (issue #38)."""
import json

import pytest
from pdeface.cli import main

from tests.core.test_cli import _renderer_parser

FIVE_THOUSAND_DIGITS = "1" * 5000

#: (command line, the option its usage error names): each was taken, or escaped as a traceback, before #38.
BAD = [
    (["fit", "default", "--modes", "-1"], "--modes"),
    (["fit", "default", "--modes", "65"], "--modes"),
    (["fit", "default", "--curves", "99999"], "--curves"),
    (["fit", "default", "--points", "0"], "--points"),
    (["fit", "default", "--a", "nan"], "--a"),
    (["fit", "default", "--a", "-1"], "--a"),
    (["fit", "default", "--a", "0"], "--a"),
    (["fit", "default", "--a", "inf"], "--a"),
    (["pose", "default", "--au", f"{FIVE_THOUSAND_DIGITS}=1"], "--au"),
    (["pose", "default", "--au", f"12={FIVE_THOUSAND_DIGITS}"], "--au"),
    (["pose", "default", "--au", "12=1e308"], "--au"),
    (["pose", "default", "--au", "12=nan"], "--au"),
    (["pose", "default", "--au", "12=-0.5"], "--au"),
    (["pose", "default", "--au", "5000=1"], "--au"),
    (["pose", "default", "--au", "12"], "--au"),
    (["pose", "default", "--au", "12=1", "--resolution", "99999999,9"], "--resolution"),
    (["muscles", "default", "--au", "12=inf"], "--au"),
    (["descriptor", "default", "x.obj", "--au", "5000"], "--au"),
    (["descriptor", "default", "x.obj", "--au", FIVE_THOUSAND_DIGITS], "--au"),
    (["import-au", "x.csv", "--smooth", "0"], "--smooth"),
    (["import-au", "x.csv", "--smooth", "99999999999999999999999999999999999"], "--smooth"),
    (["import-au", "x.csv", "--reduce", "-1"], "--reduce"),
    (["import-au", "x.csv", "--capture-fps", "0"], "--capture-fps"),
    (["import-au", "x.csv", "--capture-fps", "nan"], "--capture-fps"),
    (["import-au", "x.csv", "--min-confidence", "nan"], "--min-confidence"),
    (["import-au", "x.csv", "--min-confidence", "2"], "--min-confidence"),
    (["import-au", "x.csv", "--fps", "-30"], "--fps"),
    (["import-au", "x.csv", "--hold", "inf"], "--hold"),
    (["fdt", "classify", "default", "x.obj", "--sigmas", "nan"], "--sigmas"),
    (["fdt", "classify", "default", "x.obj", "--top", "0"], "--top"),
    (["fdt", "apply", "default", "happy", "--weight", "1e308"], "--weight"),
    (["fdt", "fit", "default", "x.obj", "--blend", "nan"], "--blend"),
    (["pose", "default", "--all-keys", "--mesh", ""], "--mesh"),  # an empty name was taken as "no mesh"
    (["pose", "default", "--au", "12=1", "--mesh", "head", "--parts", " "], "--parts"),
    (["fdt", "apply", "default", "happy", "--landmarks", ""], "--landmarks"),
    (["demo", "--size", "0x5"], "--size"),
    (["demo", "--samples", "-1"], "--samples"),
    (["demo", "--fps", "nan"], "--fps"),
]


@pytest.mark.parametrize("argv, option", BAD, ids=[" ".join(a)[:60] for a, _ in BAD])
def test_a_bad_argument_is_a_one_line_usage_error(argv, option, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)  # the option is refused before -o is missed
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2
    assert err[-1].startswith("pdeface") and f"argument {option}" in err[-1], err[-1]
    assert len(err[-1]) < 200 and "Traceback" not in "\n".join(err)


def test_good_arguments_still_parse():
    from pdeface.cli import build_parser
    args = build_parser().parse_args(["pose", "default", "--au", "12=1", "--au", "AU6L=C", "--au", "4=0",
                                      "--resolution", "2,2", "-o", "x.obj"])
    assert args.au == ["12=1", "AU6L=C", "4=0"] and args.resolution == "2,2"
    args = build_parser().parse_args(["import-au", "x.csv", "--smooth", "3", "--reduce", "0",
                                      "--min-confidence", "0", "--capture-fps", "59.94", "-o", "t.json"])
    assert (args.smooth, args.reduce, args.min_confidence, args.capture_fps) == (3, 0.0, 0.0, 59.94)
    assert build_parser().parse_args(["descriptor", "n.obj", "a.obj", "--au", "AU12", "-o", "d.json"]).au == 12


def test_fit_parts_naming_a_vertex_the_mesh_lacks_is_one_line(tmp_path, capsys):
    for bad, match in (([0, 10**9], "vertex index out of range"), ([-1], "vertex index out of range"),
                       ([0, 2**62], "integer of 19 digits"), ([0.5], "must be a list of vertex indices")):
        parts = tmp_path / "parts.json"
        parts.write_text(json.dumps({"skin": bad}))
        assert main(["fit", "default", "--parts", str(parts), "-o", str(tmp_path / "f.npz")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and match in err[0], err
        assert not (tmp_path / "f.npz").exists()


def test_render_blend_must_be_a_blend_file(tmp_path, capsys):
    parser = _renderer_parser()
    fake = tmp_path / "scene.blend"
    fake.write_bytes(b"not a blend file at all")
    for path in (fake, tmp_path / "missing.blend", tmp_path):
        with pytest.raises(SystemExit) as exc:
            parser.parse_args(["--blend", str(path)])
        assert exc.value.code == 2
        assert "argument --blend" in capsys.readouterr().err.strip().splitlines()[-1]
    real = tmp_path / "real.blend"
    real.write_bytes(b"BLENDER-v404RENDH")
    assert parser.parse_args(["--blend", str(real)]).blend == str(real)
    for argv, option in ((["--frame-start", "-5"], "--frame-start"), (["--size", "99999x2"], "--size"),
                         (["--fps", "0"], "--fps"), (["--samples", "0"], "--samples"),
                         (["--hold", "nan"], "--hold"), (["--blend-time", "-1"], "--blend-time")):
        with pytest.raises(SystemExit):
            parser.parse_args(argv)
        assert f"argument {option}" in capsys.readouterr().err


def test_a_pdeface_error_is_one_line_even_when_its_message_is_not(tmp_path, capsys, monkeypatch):
    from pdeface.cli import face
    from pdeface.errors import PdeFaceError

    def broken(args):
        raise PdeFaceError("first line\nsecond line\r\n  third")
    monkeypatch.setattr(face, "cmd_mesh", broken)
    assert main(["mesh", "default", "-o", str(tmp_path / "m.obj")]) == 2
    assert capsys.readouterr().err == "pdeface: error: first line second line third\n"


def test_fit_face_refuses_bad_options_with_its_own_error(scan):
    from pdeface.errors import LayoutError
    from pdeface.surface.fit import fit_face
    mesh, T, idx = scan
    L = mesh.vertices[idx]
    for kw, match in (({"n_modes": -1}, "modes"), ({"n_modes": 36, "n_points": 20}, "modes need more"),
                      ({"a": float("nan")}, "smoothing"), ({"a": 0}, "smoothing"), ({"n_curves": 1}, "curves")):
        with pytest.raises(LayoutError, match=match):
            fit_face(mesh.vertices, T, L, unit="cm", **kw)


def test_pdeface_render_refuses_a_file_that_is_not_a_blend(tmp_path, capfd):
    import importlib.util
    if importlib.util.find_spec("bpy") is None:
        pytest.skip("pdeface render needs the bpy module")
    fake = tmp_path / "scene.blend"
    fake.write_text("hello")
    with pytest.raises(SystemExit) as exc:
        main(["render", "--blend", str(fake), "--out", str(tmp_path / "out")])
    err = capfd.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and "argument --blend" in err[-1] and "Traceback" not in "\n".join(err)
    assert not (tmp_path / "out").exists()
