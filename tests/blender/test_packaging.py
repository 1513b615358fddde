"""The extension as users get it: built by scripts/build/build_extension.py, installed from its zip."""
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_build_install_and_use_the_linux_zip(tmp_path):
    out = tmp_path / "dist"
    res = subprocess.run([sys.executable, str(ROOT / "scripts" / "build" / "build_extension.py"), "--platforms", "linux-x64",
                          "--out", str(out), "--wheel-cache", str(ROOT / "build" / "wheels")],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr
    (zip_path,) = out.glob("pdeface-*.zip")
    assert zip_path.name == "pdeface-0.1.0-linux_x64.zip"  # the same naming as a build for every platform
    names = zipfile.ZipFile(zip_path).namelist()
    wheels = [n for n in names if n.startswith("wheels/")]
    assert any("pdeface-" in w for w in wheels) and any("scipy-" in w for w in wheels) and any("xatlas-" in w for w in wheels)
    assert any("threadpoolctl-" in w for w in wheels)  # the operators' bounded BLAS threads (pdeface.threads)
    assert not any("numpy" in w for w in wheels)  # Blender ships numpy
    manifest = zipfile.ZipFile(zip_path).read("blender_manifest.toml").decode()
    assert 'platforms = ["linux-x64"]' in manifest and "wheels = [" in manifest
    # A fresh Blender (bpy) with nothing of ours on its path installs the zip and uses it.
    script = textwrap.dedent(f"""
        import os, sys, tempfile
        os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp()
        sys.path = [p for p in sys.path if p not in ("", {str(ROOT / "core")!r})]
        import bpy
        bpy.context.preferences.extensions.repos.new(name="zipped", module="zipped",
                                                     custom_directory=tempfile.mkdtemp(), source="USER")
        assert bpy.ops.extensions.package_install_files(filepath={str(zip_path)!r}, repo="zipped",
                                                        enable_on_install=True) == {{"FINISHED"}}
        import pdeface
        assert "extensions" in pdeface.__file__, pdeface.__file__
        bpy.ops.wm.read_homefile(use_empty=True)
        assert bpy.ops.pdeface.add_default_face() == {{"FINISHED"}}
        print("KEYS", len(bpy.context.active_object.data.shape_keys.key_blocks))
        import addon_utils
        addon_utils.disable("bl_ext.zipped.pdeface", default_set=True)
    """)
    env = {k: v for k, v in __import__("os").environ.items() if k != "PYTHONPATH"}
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path, env=env,
                         timeout=600)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    assert "KEYS 83" in res.stdout  # Basis, 72 AUs (63 from ICT, 9 from muscles), 10 expressions
