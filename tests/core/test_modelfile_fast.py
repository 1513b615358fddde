"""A face model written ``fast`` (the add-on's copy in a .blend) reads back to the same model as its file does."""
import io
import zipfile

import numpy as np
import pytest
from pdeface.assets import DEFAULT
from pdeface.au.modelfile import load_face, model_from_bytes, model_to_bytes


@pytest.fixture(scope="module")
def face():
    return load_face(DEFAULT)


def test_fast_bytes_read_back_to_the_same_model(face):
    slow, fast = model_to_bytes(face), model_to_bytes(face, fast=True)
    assert fast != slow
    a, b = model_from_bytes(slow), model_from_bytes(fast, "fast")
    for name in ("coefficients", "residual", "knots", "features", "status", "landmarks"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    np.testing.assert_array_equal(a.frame.matrix(), b.frame.matrix())
    assert (a.n_modes, a.a, a.w, a.assembly, a.frame.unit) == (b.n_modes, b.a, b.w, b.assembly, b.frame.unit)
    assert [d.key for d in a.descriptors] == [d.key for d in b.descriptors] and len(a.descriptors) > 60
    for da, db in zip(a.descriptors, b.descriptors):
        np.testing.assert_array_equal(da.curves, db.curves)
        np.testing.assert_array_equal(da.points(), db.points(), err_msg=da.key)


def test_fast_bytes_are_a_stored_archive_a_little_larger(face):
    slow, fast = model_to_bytes(face), model_to_bytes(face, fast=True)
    members = zipfile.ZipFile(io.BytesIO(fast)).infolist()
    assert {m.compress_type for m in members} == {zipfile.ZIP_STORED}
    assert {m.compress_type for m in zipfile.ZipFile(io.BytesIO(slow)).infolist()} == {zipfile.ZIP_DEFLATED}
    assert len(slow) < len(fast) < 1.5 * len(slow)
