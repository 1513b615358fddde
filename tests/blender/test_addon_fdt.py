"""Facial Deformation Tables in Blender: an FDT file or a bundled one as one more shape key."""
import json

import numpy as np
import pytest

MODULE = "bl_ext.pdeface_test.pdeface"


def addon(name="bridge"):
    return __import__(MODULE + "." + name, fromlist=[name])


def test_fdt_key_on_the_face_matches_the_core(bpy, face, tmp_path):
    from pdeface.fdt.deform import fdt_curves
    from pdeface.fdt.table import load_fdt, write_fdts
    from pdeface.surface.fit import face_mesh

    model = addon().face_model(face)
    happy = load_fdt("happy")
    write_fdts(tmp_path / "mine.fdt.json", [happy.__class__("my smile", happy.model, happy.mean)])
    assert bpy.ops.pdeface.load_fdt(filepath=str(tmp_path / "mine.fdt.json")) == {"FINISHED"}
    assert bpy.ops.pdeface.load_fdt(filepath="happy") == {"FINISHED"}  # a bundled one by name
    kb = face.data.shape_keys.key_blocks
    assert "FDT my smile (3d)" in kb and "FDT happy (3d)" in kb
    dC, dR = fdt_curves(model, happy)
    want = face_mesh(model, face.pdeface.resolution, coefficients=model.coefficients + dC,
                     residual=model.residual + dR).vertices
    np.testing.assert_allclose(addon().key_coords(kb["FDT happy (3d)"]), want, atol=1e-5)
    assert kb["FDT happy (3d)"].value == 0.0 and kb["FDT happy (3d)"].slider_max == 1.0
    # an expression key: presets and resets drive it like the others
    entry = next(e for e in face.pdeface.keys if e.name == "FDT happy (3d)")
    assert entry.kind == "EXPRESSION"
    kb["FDT happy (3d)"].value = 0.7
    assert bpy.ops.pdeface.reset_pose() == {"FINISHED"}
    assert kb["FDT happy (3d)"].value == 0.0


def test_bad_fdt_reports_and_keeps_the_users_key(bpy, face, tmp_path):
    (tmp_path / "bad.fdt.json").write_text(json.dumps({"format": "pdeface.fdt", "version": 1, "name": "x",
                                                       "model": "3d", "mean": [[0.0] * 3]}))
    n = len(face.data.shape_keys.key_blocks)
    with pytest.raises(RuntimeError, match="16 regions"):
        bpy.ops.pdeface.load_fdt(filepath=str(tmp_path / "bad.fdt.json"))
    with pytest.raises(RuntimeError, match="neither an FDT file"):
        bpy.ops.pdeface.load_fdt(filepath="no-such-expression")
    assert len(face.data.shape_keys.key_blocks) == n
    mine = face.shape_key_add(name="FDT happy (3d)", from_mix=False)  # the user's own key of that name
    co = addon().key_coords(mine) + 0.5
    addon().set_key_coords(mine, co)
    bpy.ops.pdeface.load_fdt(filepath="happy")
    np.testing.assert_allclose(addon().key_coords(face.data.shape_keys.key_blocks["FDT happy (3d)"]), co, atol=1e-6)
