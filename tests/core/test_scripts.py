"""scripts/: three kinds run as modules, no sys.path edits, and benchmarks that write their own pages."""
import ast
from pathlib import Path

from scripts.bench import benchlib

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = ROOT / "scripts"


def test_scripts_are_sorted_by_kind_and_never_edit_sys_path():
    assert sorted(p.name for p in SCRIPTS.glob("*.py")) == ["__init__.py"]
    for kind, prefixes in {"bench": ("bench_", "benchlib", "fuzz_readers", "baseline_"), "build": ("build_",),
                           "figures": ("render_", "drawlib")}.items():
        names = [p.stem for p in (SCRIPTS / kind).glob("*.py") if p.stem != "__init__"]
        assert names and all(n.startswith(prefixes) for n in names), (kind, names)
    for path in SCRIPTS.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute) and node.attr == "path" and getattr(node.value, "id", "") == "sys":
                raise AssertionError(f"{path.relative_to(ROOT)}:{node.lineno} uses sys.path")


def test_every_benchmark_writes_its_page_through_benchlib():
    for path in (SCRIPTS / "bench").glob("bench_*.py"):
        text = path.read_text()
        assert f'run_bench(main, "{path.stem[6:]}")' in text and "bench_parser(__doc__)" in text, path.name


def test_a_page_holds_the_command_the_machine_and_what_was_printed(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(benchlib, "PAGES", tmp_path)

    def main(argv):
        args = benchlib.bench_parser(__doc__).parse_args(argv)
        print(f"captured 0.953 (target 0.95); no page: {args.no_page}")
        return 0

    main.__module__ = __name__
    assert benchlib.run_bench(main, "demo", []) == 0
    assert capsys.readouterr().out == "captured 0.953 (target 0.95); no page: False\n"
    page = (tmp_path / "demo.md").read_text()
    assert page.startswith("# Measured: demo\n\nscripts/: three kinds")
    assert f"`python -m {__name__}`" in page and "cores" in page and "Load average" in page
    assert "```text\ncaptured 0.953 (target 0.95); no page: False\n```" in page
    assert benchlib.run_bench(main, "quiet", ["--no-page"]) == 0
    assert not (tmp_path / "quiet.md").exists()


def test_a_page_links_what_its_benchmark_names_in_see_also(tmp_path, monkeypatch):
    import sys

    monkeypatch.setattr(benchlib, "PAGES", tmp_path)
    monkeypatch.setattr(sys.modules[__name__], "SEE_ALSO", (("close-ups", "../images/x.png"),), raising=False)

    def main(argv):
        print("measured")
        return 0

    main.__module__ = __name__
    benchlib.run_bench(main, "linked", [])
    assert (tmp_path / "linked.md").read_text().endswith("## See also\n\n- [close-ups](../images/x.png)\n")
