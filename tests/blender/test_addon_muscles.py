"""The muscle panel: contract muscles live on the face, record them as an AU, load an AU's muscles."""
import numpy as np
import pytest

MODULE = "bl_ext.pdeface_test.pdeface"


def addon(name="bridge"):
    return __import__(MODULE + "." + name, fromlist=[name])


def test_muscle_sliders_pose_the_face_live_and_record_an_au(bpy, face):
    from pdeface.muscles.aus import MuscleBasis
    from pdeface.muscles.placement import MUSCLE_NAMES
    from pdeface.surface.fit import face_mesh

    s = bpy.context.scene.pdeface
    model = addon().face_model(face)
    a = np.zeros(len(MUSCLE_NAMES))
    a[MUSCLE_NAMES.index("zygomatic_major_L")] = 0.8
    a[MUSCLE_NAMES.index("orbicularis_oris")] = 0.4
    s.muscles = a.tolist()
    addon("properties").muscles_tick()  # the timer's work, called directly (no event loop headless)
    kb = face.data.shape_keys.key_blocks
    assert kb["PDE Muscles"].value == 1.0 and s.muscle_note == ""
    dC, dR = MuscleBasis(model).curves(np.array(s.muscles))
    want = face_mesh(model, face.pdeface.resolution, coefficients=model.coefficients + dC,
                     residual=model.residual + dR).vertices
    np.testing.assert_allclose(addon().key_coords(kb["PDE Muscles"]), want, atol=1e-5)
    assert kb["AU12 Lip Corner Puller"].value == 0.0  # the muscle view is a pose of its own

    assert bpy.ops.pdeface.record_muscle_au(au="8") == {"FINISHED"}  # an AU the face lacks
    name = "AU8 Lips Toward Each Other"
    assert name in kb and kb[name].slider_max == 1.0
    d = next(d for d in addon().face_model(face).descriptors if d.key == "8")
    assert d.source == "muscle" and np.allclose(d.extra["activations"], s.muscles, atol=1e-4)
    # the key is that pose at weight 1, but for the curves moving under 0.5 mm (0.05 in this face's cm),
    # which a descriptor leaves out
    np.testing.assert_allclose(addon().key_coords(kb[name]), want, atol=0.05)
    with pytest.raises(RuntimeError, match="already"):
        bpy.ops.pdeface.record_muscle_au(au="12")  # the scan's AU12 is not overwritten unasked
    s.muscles = [0.0] * len(MUSCLE_NAMES)
    addon("properties").muscles_tick()
    assert kb["PDE Muscles"].value == 1.0 and np.abs(addon().key_coords(kb["PDE Muscles"])
                                                      - addon().key_coords(kb["Basis"])).max() < 1e-6  # relaxed
    assert bpy.ops.pdeface.load_muscle_au(au="8") == {"FINISHED"}  # its own recorded activations come back
    np.testing.assert_allclose(list(s.muscles), a, atol=1e-4)
    assert bpy.ops.pdeface.load_muscle_au(au="12") == {"FINISHED"}  # the bundled table's
    assert max(s.muscles) > 0
    assert bpy.ops.pdeface.reset_muscles() == {"FINISHED"}
    assert not any(s.muscles)
    with pytest.raises(RuntimeError, match="at rest"):
        bpy.ops.pdeface.record_muscle_au(au="8")
