"""Build the PDE Face Blender extension zips, with their wheels.

Usage: python scripts/build/build_extension.py [--platforms linux-x64,macos-arm64,macos-x64,windows-x64]
                                         [--out dist] [--wheel-cache DIR]

Stages blender_addon/, builds a pdeface wheel carrying the default face assets
(default_face.npz, the ICT neutral scan and whole head with its head prior, ICT-FaceKit's licence), downloads
CPython 3.11 wheels of scipy and xatlas for each platform (Blender 4.2-5.0 run
Python 3.11 and ship numpy), lists them in the manifest, then builds one zip
per platform with Blender's own extension tool and validates them. The tool
comes from the ``bpy`` module or a ``blender`` on PATH.
"""
from __future__ import annotations

import argparse
import importlib.util
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PLATFORMS = {
    "linux-x64": ["manylinux_2_17_x86_64", "manylinux2014_x86_64", "manylinux_2_28_x86_64"],
    "macos-arm64": ["macosx_12_0_arm64", "macosx_14_0_arm64", "macosx_11_0_arm64"],
    "macos-x64": ["macosx_10_9_x86_64", "macosx_10_14_x86_64", "macosx_10_15_x86_64"],
    "windows-x64": ["win_amd64"],
}
DEPENDENCIES = ["scipy==1.14.1", "xatlas==0.0.11", "threadpoolctl==3.8.0"]
BUNDLED_ASSETS = ["default_face.npz", "ict_neutral_face.npz", "ict_head.npz", "ict_head_prior.npz",
                  "ict_generic_fdts.json.gz", "ICT-FaceKit-LICENSE.txt"]


def blender_ext_command():
    """How to run Blender's extension tool: via bpy's copy of blender_ext.py, or blender itself."""
    spec = importlib.util.find_spec("bpy")
    if spec and spec.origin:
        found = sorted(Path(spec.origin).parent.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if found:
            return [sys.executable, str(found[-1])]
    blender = shutil.which("blender")
    if blender:
        return [blender, "--factory-startup", "--command", "extension"]
    raise SystemExit("needs Blender's extension tool: pip install bpy==5.0.1, or put blender on PATH")


def build_core_wheel(dest: Path) -> Path:
    """A pdeface wheel with the default assets inside the package."""
    with tempfile.TemporaryDirectory() as tmp:
        stage = Path(tmp)
        skip = shutil.ignore_patterns("__pycache__", "*.egg-info")
        for folder in ("core", "blender_addon"):
            shutil.copytree(ROOT / folder, stage / folder, ignore=skip)
        (stage / "assets").mkdir()
        for name in BUNDLED_ASSETS:  # the ICT shapes (tests and benchmarks only) stay out
            shutil.copy(ROOT / "assets" / name, stage / "assets" / name)
        for name in ("pyproject.toml", "README.md", "LICENSE"):
            shutil.copy(ROOT / name, stage / name)
        subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q",
                        "-w", str(dest), str(stage)], check=True)
    return next(dest.glob("pdeface-*.whl"))


def download_wheels(platform: str, cache: Path) -> list:
    target = cache / platform
    target.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--only-binary=:all:",
           "--python-version", "3.11", "--implementation", "cp", "-d", str(target)]
    for tag in PLATFORMS[platform]:
        cmd += ["--platform", tag]
    subprocess.run(cmd + DEPENDENCIES, check=True)
    return sorted(target.glob("*.whl"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--platforms", default=",".join(PLATFORMS))
    ap.add_argument("--out", type=Path, default=ROOT / "dist")
    ap.add_argument("--wheel-cache", type=Path, default=ROOT / "build" / "wheels")
    args = ap.parse_args(argv)
    platforms = [p.strip() for p in args.platforms.split(",") if p.strip()]
    unknown = set(platforms) - set(PLATFORMS)
    if unknown:
        raise SystemExit(f"unknown platform(s) {', '.join(sorted(unknown))}; use {', '.join(PLATFORMS)}")
    ext = blender_ext_command()
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        stage = Path(tmp) / "pdeface"
        shutil.copytree(ROOT / "blender_addon", stage, ignore=shutil.ignore_patterns("__pycache__"))
        wheels_dir = stage / "wheels"
        wheels_dir.mkdir()
        core = build_core_wheel(wheels_dir)
        wheels = [core]
        for p in platforms:
            for w in download_wheels(p, args.wheel_cache):
                shutil.copy(w, wheels_dir / w.name)
                wheels.append(wheels_dir / w.name)
        manifest = (stage / "blender_manifest.toml").read_text()
        listing = "".join(f'  "./wheels/{w.name}",\n' for w in sorted(set(wheels)))
        manifest = re.sub(r"\n# scripts/build/build_extension.py adds.*\n", "\n", manifest)
        quoted = ", ".join(f'"{p}"' for p in platforms)
        # Top-level keys must come before the first [table].
        manifest = manifest.replace("[permissions]", f"platforms = [{quoted}]\nwheels = [\n{listing}]\n\n[permissions]", 1)
        (stage / "blender_manifest.toml").write_text(manifest)
        # One zip per platform, always named pdeface-VERSION-PLATFORM.zip (linux_x64, windows_x64, ...).
        subprocess.run(ext + ["build", "--source-dir", str(stage), "--output-dir", str(args.out),
                              "--split-platforms"], check=True)
    built = sorted(args.out.glob("pdeface-*.zip"))
    for z in built:
        subprocess.run(ext + ["validate", str(z)], check=True)
        print(f"{z} ({z.stat().st_size // 1024} KiB)")
    return built


if __name__ == "__main__":
    main()
