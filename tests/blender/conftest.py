"""Blender tests: the add-on enabled as a real extension, with the bpy module, headless.

BLENDER_USER_RESOURCES points at a temporary folder before bpy is imported, the
add-on folder is linked into a local extension repository (as the headless
renderer does it) and enabled as ``bl_ext.pdeface_test.pdeface``; every test
starts from an empty file, and the add-on is disabled at the end of the session.
"""
import importlib.util
import os
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MODULE = "bl_ext.pdeface_test.pdeface"


@pytest.fixture(scope="session")
def bpy():
    os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="pdeface_blender_user_")
    bpy = pytest.importorskip("bpy", reason="the Blender tests need the bpy module (pip install bpy==5.0.1)")
    import addon_utils

    spec = importlib.util.spec_from_file_location("pdeface_headless", ROOT / "blender_addon" / "headless.py")
    headless = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(headless)
    assert headless.enable_addon(bpy, "pdeface_test") == MODULE
    yield bpy
    addon_utils.disable(MODULE, default_set=True)


@pytest.fixture(autouse=True)
def empty_file(bpy):
    bpy.ops.wm.read_homefile(use_empty=True)
    yield


@pytest.fixture
def face(bpy):
    """The default PDE face with its shape keys."""
    assert bpy.ops.pdeface.add_default_face() == {"FINISHED"}
    return bpy.context.active_object


@pytest.fixture
def scan_object(bpy):
    """The bundled ICT neutral scan as a mesh object (with UVs)."""
    from pdeface.assets import load_neutral_scan

    addon = __import__(MODULE, fromlist=["bridge"])
    mesh, idx = load_neutral_scan()
    me = addon.bridge.new_mesh("ICT neutral", mesh)
    obj = bpy.data.objects.new("ICT neutral", me)
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    return obj, idx
