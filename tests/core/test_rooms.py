"""The package's rooms: who imports whom, the 0.1 module names, and facts with one home."""
import ast
import importlib
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
CORE = ROOT / "core" / "pdeface"
ADDON = ROOT / "blender_addon"


def imports(path):
    """(module names imported absolutely, relative imports as (level, module)) anywhere in a file."""
    absolute, relative = set(), set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            absolute |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                relative |= {(node.level, node.module or a.name) for a in node.names} if node.module is None \
                    else {(node.level, node.module)}
            else:
                absolute.add(node.module)
    return absolute, relative


def test_the_core_never_imports_bpy():
    for path in CORE.rglob("*.py"):
        absolute, _ = imports(path)
        assert not {m for m in absolute if m == "bpy" or m.startswith("bpy.")}, path


def test_only_the_entry_point_imports_the_cli():
    """The command line is one room, ``pdeface/cli/``: its modules import each other only from within it
    (relatively), nothing else imports them (the entry point names ``pdeface.cli:run``), and no concern
    keeps a ``cli`` module of its own."""
    room = CORE / "cli"
    assert (room / "__init__.py").is_file() and (room / "__main__.py").is_file()
    assert [p.relative_to(ROOT) for p in CORE.rglob("cli.py")] == []
    offenders = []
    for folder in (CORE, ADDON, ROOT / "scripts"):
        for path in folder.rglob("*.py"):
            absolute, relative = imports(path)  # the room's own modules import each other as ``from .x``
            if any(m == "pdeface.cli" or m.startswith("pdeface.cli.") for m in absolute) or any(
                    m == "cli" or m.startswith("cli.") or m.endswith(".cli") for _, m in relative):
                offenders.append(path.relative_to(ROOT))
    assert offenders == []


def test_the_addon_has_no_import_loop():
    graph = {p.stem: {m.split(".")[0] for level, m in imports(p)[1] if level == 1} for p in ADDON.glob("*.py")}
    done, stack = set(), []

    def visit(m):
        assert m not in stack, " -> ".join(stack + [m])
        if m in done:
            return
        stack.append(m)
        for n in graph.get(m, ()):
            visit(n)
        stack.pop()
        done.add(m)

    for m in graph:
        visit(m)
    # operators sit on top, over the face's rooms: only the add-on's register imports them
    assert graph["operators"] >= {"face", "keys", "muscles", "animation", "rigging"}
    assert [m for m, deps in graph.items() if "operators" in deps] == ["__init__"]


def test_the_01_module_names_still_import():
    import pdeface
    for old, homes in pdeface.MOVED.items():
        module = importlib.import_module(f"pdeface.{old}")
        for home in homes:
            new = importlib.import_module(f"pdeface.{home}")
            public = [n for n in vars(new) if not n.startswith("_") and getattr(new, n).__class__.__name__ in
                      ("function", "type")]
            for name in public[:5]:
                assert getattr(module, name) is getattr(new, name), (old, name)
    from pdeface.fit import face_mesh, fit_face
    from pdeface.model import load_model, save_model
    from pdeface.surface.fit import fit_face as fit_face_now
    assert fit_face is fit_face_now and pdeface.fit_face is fit_face and callable(face_mesh)
    assert pdeface.load_model is load_model and pdeface.save_model is save_model
    with pytest.raises(ImportError):
        from pdeface.fit import no_such_name  # noqa: F401
    from pdeface import (  # noqa: F401
        accuracy_report,
        face_mesh,
        fit_face,
        landmark_points,
        load_model,
        read_landmarks,  # the README's Python API
        read_mesh,
        save_model,
        write_mesh,
    )
    assert read_mesh is importlib.import_module("pdeface.io.meshio").read_mesh


def test_arkit_table_is_icts_read_backwards():
    from pdeface.au.ict import APPROXIMATIONS, ARKIT_TO_AU, AU_SHAPES
    assert ARKIT_TO_AU["browinnerup"] == [("1", 1.0)] and ARKIT_TO_AU["cheekpuff"] == [("33", 1.0)]
    assert ARKIT_TO_AU["mouthsmileleft"] == [("12L", 1.0)] and ARKIT_TO_AU["jawright"] == [("30R", 1.0)]
    assert ARKIT_TO_AU["mouthrolllower"] == [("28", 0.5)] and ARKIT_TO_AU["eyelookinright"] == [("61", 0.5)]
    assert ARKIT_TO_AU["jawopen"] == [("27", 1.0)]  # the approximations (25, 26) are not read backwards
    mapped = {k for pairs in ARKIT_TO_AU.values() for k, _ in pairs}
    assert not mapped & set(APPROXIMATIONS) and mapped <= set(AU_SHAPES)
    for key in ("12", "45", "61"):  # each AU's shares add up to one whole AU
        sided = [k for k in mapped if k.rstrip("LR") == key]
        total = sum(s for pairs in ARKIT_TO_AU.values() for k, s in pairs if k in sided)
        assert total == pytest.approx(1.0 if sided == [key] else 2.0), key


def test_au_keys_weights_and_mixers_have_one_rule():
    from pdeface.errors import PdeFaceError
    from pdeface.facs import au_number, clamp_weight, clamp_weights, split_au_key
    from pdeface.presets import MIXERS, PRESETS, Preset, choose_mixer
    assert sorted(["12R", "2", "12", "1", "12L", "30L"], key=split_au_key) == ["1", "2", "12", "12L", "12R", "30L"]
    assert au_number("45L") == 45 and split_au_key("7") == (7, "")
    assert (clamp_weight(-2), clamp_weight(0.25), clamp_weight(7)) == (0.0, 0.25, 1.0)
    np.testing.assert_array_equal(clamp_weights(np.array([-1.0, 0.5, 3.0])), [0.0, 0.5, 1.0])
    mine = Preset("mine", {"1": 1.0}, "average")
    assert choose_mixer(None, mine) == "average" and choose_mixer("max", mine) == "max"
    assert choose_mixer(None, PRESETS["happy"]) == "sum" and choose_mixer() == "sum"
    assert list(MIXERS) == ["sum", "average", "max", "muscle-average", "muscle-max"]
    with pytest.raises(PdeFaceError, match="unknown mixer"):
        choose_mixer("median")


def test_files_open_one_way_and_name_the_file(tmp_path):
    from pdeface.animation.trackers import import_au
    from pdeface.au.descriptorfile import load_descriptor
    from pdeface.errors import MeshError, ModelFormatError
    from pdeface.io.files import read_bytes, read_lines
    from pdeface.io.meshio import read_mesh
    from pdeface.stream.sender import read_packets
    missing = tmp_path / "missing.txt"
    for reader, error in ((read_bytes, ModelFormatError), (read_lines, ModelFormatError),
                          (load_descriptor, ModelFormatError), (read_packets, ModelFormatError),
                          (import_au, ModelFormatError)):
        with pytest.raises(error, match=f"{missing.name}: cannot open"):
            reader(missing)
    for name in ("missing.obj", "missing.ply"):
        with pytest.raises(MeshError, match=f"{name}: cannot open"):
            read_mesh(tmp_path / name)
    with pytest.raises(ModelFormatError, match="cannot open"):
        read_bytes(tmp_path)  # a folder
    (tmp_path / "t.txt").write_bytes(b"a\nb\xff\n")
    assert read_lines(tmp_path / "t.txt") == ["a", "b\ufffd"]


def test_skin_is_the_pieces_at_the_landmarks():
    from pdeface.surface.fit import skin_triangles
    # two separate triangles; points near the second pick only it
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 0, 0], [6, 0, 0], [5, 1, 0]], float)
    T = np.array([[0, 1, 2], [3, 4, 5]])
    np.testing.assert_array_equal(skin_triangles(V, T, V[[3, 4]] + 0.01), T[1:])
    np.testing.assert_array_equal(skin_triangles(V, T, V[[0, 5]]), T)


def test_every_package_is_in_the_distribution():
    import tomllib
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT / "core").parts) for p in CORE.rglob("__init__.py")}
    assert found <= listed, f"add {sorted(found - listed)} to pyproject.toml's packages"
    assert {"pdeface.bundled", "pdeface_blender"} <= listed  # the assets and the add-on travel too


#: The core's rooms (packages and top-level modules), stacked: a room may import only rooms on floors
#: below its own. The package docstring (``pdeface/__init__.py``) describes the same order.
FLOORS = [
    ["errors"],
    ["geometry", "landmark_scheme", "units", "facs", "threads", "heap"],
    ["mesh", "rigid"],
    ["assets", "io", "headless"],
    ["presets"],
    ["surface"],
    ["au"],
    ["muscles"],
    ["posing"],
    ["stream"],
    ["animation"],
    ["head"],
    ["fdt"],
    ["landmarks"],
    ["rig"],
    ["batch"],
    ["cli"],
]


def room_imports():
    """``{room: {imported room: [file:line, ...]}}`` over every import in the core, inside functions too."""
    rooms = {}
    for path in sorted(CORE.rglob("*.py")):
        rel = path.relative_to(CORE)
        if rel == Path("__init__.py"):
            continue  # the package's face: it imports its rooms lazily, by name
        room = rel.parts[0].removesuffix(".py")
        package = ["pdeface", *rel.parts[:-1]]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = package[:len(package) - node.level + 1] if node.level else []
                module = ".".join(base + ([node.module] if node.module else []))
                targets = [module] if node.module else [f"{module}.{a.name}" for a in node.names]
            else:
                continue
            for target in targets:
                parts = target.split(".")
                if parts[0] != "pdeface" or len(parts) < 2 or parts[1] == "__version__":
                    continue
                if parts[1] != room:
                    rooms.setdefault(room, {}).setdefault(parts[1], []).append(f"{rel}:{node.lineno}")
    return rooms


def test_the_rooms_stack_with_no_arrow_back_up_and_no_circle():
    floor = {room: i for i, names in enumerate(FLOORS) for room in names}
    found = {p.name.removesuffix(".py") for p in CORE.iterdir() if p.name != "__init__.py" and
             (p.suffix == ".py" or (p / "__init__.py").exists())}
    assert found == set(floor), f"place every room on a floor: {sorted(found ^ set(floor))}"
    back_up = [f"{room} -> {target} ({', '.join(where)})" for room, targets in room_imports().items()
               for target, where in targets.items() if floor[target] >= floor[room]]
    # an arrow to the same floor or up would be the start of a circle: none
    assert back_up == []


def test_heavy_modules_load_only_when_needed():
    """Importing the core (the add-on does at start-up) loads neither scipy nor mediapipe: fitting, reports
    and landmarks load them when called. The stream player (a lightweight process) needs no numpy."""
    import subprocess
    import sys
    probe = ("import sys, pdeface.cli, pdeface.posing, pdeface.head.bind, pdeface.fdt.deform, "
             "pdeface.landmarks.pipeline; "
             "print(sorted(m for m in ('scipy', 'mediapipe', 'trimesh') if m in sys.modules))")
    assert subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          check=True).stdout.strip() == "[]"
    probe = "import sys, pdeface.stream.player, pdeface.stream.sender; print('numpy' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          check=True).stdout.strip() == "False"
