import argparse
import json
import shutil
import subprocess

import numpy as np
import pytest
from pdeface.cli import main
from pdeface.io.meshio import read_obj, write_obj
from pdeface.mesh import Mesh
from pdeface.surface.layout import DEFAULT_CURVES


@pytest.fixture(scope="module")
def scan_files(tmp_path_factory, scan):
    mesh, _, idx = scan
    d = tmp_path_factory.mktemp("scan")
    write_obj(d / "neutral.obj", mesh)
    (d / "lm_indices.json").write_text(json.dumps({"indices": idx.tolist()}))
    (d / "lm_points.json").write_text(json.dumps({"points": mesh.vertices[idx].tolist()}))
    return d


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_fit_mesh_report(tmp_path, capsys, scan_files):
    code, out, _ = run(capsys, "fit", scan_files / "neutral.obj", "--landmarks", scan_files / "lm_indices.json",
                       "--unit", "cm", "-o", tmp_path / "face.npz")
    assert code == 0 and json.loads(out)["model_bytes"] == (tmp_path / "face.npz").stat().st_size
    code, _, err = run(capsys, "mesh", tmp_path / "face.npz", "-o", tmp_path / "face.obj", "--resolution", "2,2")
    assert code == 0 and "vertices" in err
    pde = read_obj(tmp_path / "face.obj")
    assert pde.vertices.shape == (((DEFAULT_CURVES - 1) * 2 + 1) * 73, 3) and pde.uvs is not None
    code, out, _ = run(capsys, "report", tmp_path / "face.npz", scan_files / "neutral.obj", "--json")
    r = json.loads(out)
    assert code == 0
    for key in ("mean_mm", "p95_mm", "max_mm", "normal_p95_deg", "seam_max_deg", "model_bytes"):
        assert isinstance(r[key], (int, float))
    assert r["mean_mm"] < 0.15 and r["model_bytes"] <= 10240  # 8 KB of curves, 2 KB of landmarks (test_model)


def test_points_landmarks_and_unit_guess(tmp_path, capsys, scan_files):
    code, out, _ = run(capsys, "fit", scan_files / "neutral.obj", "--landmarks", scan_files / "lm_points.json",
                       "-o", tmp_path / "f.npz")
    assert code == 0 and json.loads(out)["unit"] == "cm"


def test_straight_curves_as_the_original_method(tmp_path, capsys, scan_files):
    from pdeface.au.modelfile import load_face, load_model

    code, _, _ = run(capsys, "fit", scan_files / "neutral.obj", "--landmarks", scan_files / "lm_indices.json",
                     "--straight", "-o", tmp_path / "s.npz")
    assert code == 0
    straight, bent = load_model(tmp_path / "s.npz"), load_face("default")
    assert not straight.layout.lines and len(bent.layout.lines) == 7
    assert not straight.layout.breaks() and len(bent.layout.breaks()) == 2
    # hit points lie on their curve's height: flat rows when straight
    P, hit = straight.curve_points(), straight.status == 0
    np.testing.assert_allclose(P[..., 1][hit], np.broadcast_to(straight.layout.heights[:, None], hit.shape)[hit],
                               atol=0.02)


def test_default_face_and_patches(tmp_path, capsys):
    code, _, _ = run(capsys, "mesh", "default", "--assembly", "patches", "--resolution", "original",
                     "-o", tmp_path / "d.obj")
    assert code == 0 and read_obj(tmp_path / "d.obj").vertices.shape == (((DEFAULT_CURVES - 1) * 10 + 1) * 37, 3)
    code, out, _ = run(capsys, "report", "default", "default", "--json", "--assembly", "patches")
    assert code == 0 and json.loads(out)["assembly"] == "patches"


def test_demo(tmp_path, capsys):
    code, out, err = run(capsys, "demo", "--out", tmp_path / "demo", "--no-render")
    assert code == 0 and "[3/3]" in err
    for f in ("face.npz", "face.obj", "report.json", "profiles.png", "profiles.csv"):
        assert (tmp_path / "demo" / f).stat().st_size > 0
    assert json.loads(out)["seam_max_deg"] < 0.01


def test_bad_input_is_a_clear_error(tmp_path, capsys, scan_files):
    broken = tmp_path / "broken.obj"
    broken.write_text("v 0 0 0\nv 1 0 zz\nf 1 2 3\n")
    code, _, err = run(capsys, "fit", broken, "--landmarks", scan_files / "lm_indices.json", "-o", tmp_path / "x.npz")
    assert code == 2 and "broken.obj:2: bad number" in err
    assert not (tmp_path / "x.npz").exists()
    faceless = tmp_path / "plane.obj"
    write_obj(faceless, Mesh.from_faces(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]) * 100.0, [[0, 1, 3, 2]]))
    # No --landmarks: they are looked for, and a plane has none (or the landmark model is missing: how to get it).
    code, _, err = run(capsys, "fit", faceless, "-o", tmp_path / "x.npz")
    from pdeface.landmarks import available
    assert code == 2 and ("no face found" if available() else 'pip install "pdeface[landmarks]"') in err
    assert not (tmp_path / "x.npz").exists()
    (tmp_path / "lm.json").write_text(json.dumps({"indices": [0, 1, 2, 3] * 17}))
    code, _, err = run(capsys, "fit", faceless, "--landmarks", tmp_path / "lm.json", "-o", tmp_path / "x.npz")
    assert code == 2 and "pdeface: error:" in err
    code, _, err = run(capsys, "mesh", tmp_path / "nope.npz", "-o", tmp_path / "y.obj")
    assert code == 2 and "no such file" in err.lower()


def test_console_script_is_installed(tmp_path):
    exe = shutil.which("pdeface")
    assert exe, "pip install -e . should put the pdeface console script on PATH"
    res = subprocess.run([exe, "mesh", "default", "-o", str(tmp_path / "c.obj"), "--resolution", "1,1"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert read_obj(tmp_path / "c.obj").vertices.shape == (DEFAULT_CURVES * 37, 3)


def _renderer_parser():
    """The parser of the renderer ``pdeface render`` runs (read from its file: importing the add-on needs bpy)."""
    import importlib.util
    from pathlib import Path

    folder = Path(next(iter(importlib.util.find_spec("pdeface_blender").submodule_search_locations)))
    spec = importlib.util.spec_from_file_location("pdeface_headless", folder / "headless.py")
    headless = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(headless)
    return headless.build_parser("pdeface render")


def test_version_and_help_for_every_option(capsys):
    import pdeface
    from pdeface.cli import build_parser, subcommands
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"pdeface {pdeface.__version__}"
    commands = subcommands(build_parser())
    assert {"fit", "render", "demo", "aus", "fdt fit", "stream play", "stream send"} <= set(commands)
    # pdeface render passes its arguments on to the add-on's renderer: its options are render's
    commands.update({"": build_parser(), "render": _renderer_parser()})
    for name, parser in commands.items():
        for action in parser._actions:
            if not isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                assert action.help, f"pdeface {name} {action.option_strings or action.dest}: no help text"
    # defaults are shown; without --landmarks a mesh file's are found automatically
    fit_help = commands["fit"].format_help()
    assert "(default: 37)" in fit_help and "found automatically" in fit_help
    assert "(default: 192x192)" in commands["demo"].format_help()


def test_render_passes_its_arguments_on(capsys):
    from pdeface.cli import build_parser
    args, extra = build_parser().parse_known_args(["render", "--sequence", "happy", "--size", "64x64"])
    assert args.command == "render" and extra == ["--sequence", "happy", "--size", "64x64"]
    with pytest.raises(SystemExit):  # other commands still refuse unknown options
        main(["mesh", "default", "-o", "x.obj", "--no-such-option"])
    assert "unrecognized arguments: --no-such-option" in capsys.readouterr().err


def test_each_command_imports_only_its_group(capsys):
    import sys

    from pdeface import cli
    registered = {}
    for group in cli.GROUPS:
        sub = argparse.ArgumentParser().add_subparsers()
        __import__(f"pdeface.cli.{group}", fromlist=["register"]).register(sub)
        registered.update(dict.fromkeys(sub.choices, group))
    assert list(registered.items()) == list(cli.COMMANDS.items())  # the table is the groups' own, in their order
    probe = ("import sys\nfrom pdeface.cli import main\ntry:\n    main(['rig', '--help'])\nexcept SystemExit:\n"
             "    print(sorted(m for m in sys.modules if m.startswith('pdeface.cli.')))")
    res = subprocess.run([sys.executable, "-c", probe], check=False, capture_output=True, text=True)
    assert "keys.npz" in res.stdout and "'pdeface.cli.rig'" in res.stdout, res.stderr
    assert "pdeface.cli.au'" not in res.stdout and "pdeface.cli.batch'" not in res.stdout
    with pytest.raises(SystemExit):  # an unknown command still lists every command
        main(["no-such-command"])
    assert "'fit'" in capsys.readouterr().err


def test_the_command_ends_with_everything_written(tmp_path):
    """``pdeface`` (``cli.run``) ends the process without the interpreter's teardown: its output is whole, the
    exit handlers ran, and the exit status is ``main``'s, on success and on an error."""
    import os
    import sys

    probe = ("import atexit, os\nfrom pathlib import Path\nfrom pdeface import cli\n"
             "atexit.register(lambda: Path(os.environ['MARKER']).write_text('ran'))\ncli.run()\n")
    whole = subprocess.run([sys.executable, "-c", "from pdeface.cli import main; main(['aus', 'default'])"],
                           check=True, capture_output=True, text=True).stdout
    for face, code in (("default", 0), (str(tmp_path / "missing.npz"), 2)):
        marker = tmp_path / f"handler{code}.txt"
        res = subprocess.run([sys.executable, "-c", probe, "aus", face], check=False, capture_output=True,
                             text=True, env={**os.environ, "MARKER": str(marker)})
        assert res.returncode == code, res.stderr
        assert marker.read_text() == "ran"
        assert res.stdout == (whole if code == 0 else "")
        assert code == 0 or "missing.npz: cannot open" in res.stderr


def test_accept_help_names_given_landmarks_only_where_the_command_takes_them():
    """``--accept`` is shared: its help speaks of given landmarks (--landmarks) only on commands that take them."""
    from pdeface.cli import build_parser, subcommands

    accepting = {}
    for name, parser in subcommands(build_parser()).items():
        options = {o: a for a in parser._actions for o in a.option_strings}
        if "--accept" in options:
            accepting[name] = ("--landmarks" in options, options["--accept"].help)
    assert {"landmarks", "fit", "rig"} <= set(accepting)
    for name, (takes_given, text) in accepting.items():
        assert ("--landmarks" in text) == takes_given, name
        assert "eyes closed" in text, name  # found landmarks on a head with its eyes closed fail the gate too
