"""What a command's process does before its work: scipy's docstrings left as written (issue #35), and left to scipy
where its internals differ."""
import subprocess
import sys

import pytest

NOTE = "Array API Standard Support"
BATCH = 'The documentation is written assuming array arguments are of specified\n"core" shapes.'
CHECK = f"""
import numpy as np
{{setup}}
import scipy.ndimage, scipy.special, scipy.linalg
labels, count = scipy.ndimage.label(np.array([[1, 0, 1], [1, 0, 0]]))
assert count == 2 and labels.tolist() == [[1, 0, 2], [1, 0, 0]]
assert np.isclose(scipy.special.gamma(5.0), 24.0) and np.isclose(scipy.linalg.det(np.eye(3) * 2), 8.0)
print({NOTE!r} in scipy.ndimage.label.__doc__, {BATCH!r} in scipy.linalg.lu_factor.__doc__,
      "Label features in an array." in scipy.ndimage.label.__doc__)
"""


def run(setup):
    done = subprocess.run([sys.executable, "-c", CHECK.format(setup=setup)], capture_output=True, text=True,
                          check=False, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout.split()


def test_a_command_leaves_scipys_docstrings_as_written_and_scipy_works_alike():
    """``plain_scipy_docs`` (``pdeface rig`` calls it first): scipy's functions compute as ever and keep their
    own docstrings, without the notes scipy rewrites 300 of them with at import (0.15 s of CPU): on the
    Array API backends (``xp_capabilities``) and on batches (``_apply_over_batch``)."""
    if "True" not in run("")[:2]:
        pytest.skip("this scipy writes no notes into its docstrings")
    assert run("from pdeface.cli.common import plain_scipy_docs; plain_scipy_docs()") == ["False", "False", "True"]


def test_the_library_alone_leaves_scipy_as_it_is():
    """Importing pdeface's chain (as a script or Blender does) changes nothing of scipy's."""
    out = run("import pdeface.rig; pdeface.rig.warm_up(landmarks=False)")
    assert out[2] == "True"
    assert out[:2] == run("")[:2]  # the notes as scipy alone writes them (none before 1.15-1.16)


def _scipy_doc_users(monkeypatch):
    """scipy's modules whose ``FunctionDoc`` ``plain_scipy_docs`` hands over, each put back after the test."""
    _lib = pytest.importorskip("scipy._lib")
    from scipy._lib import _array_api, _util

    users = [m for m in (_array_api, _util) if isinstance(getattr(m, "FunctionDoc", None), type)]
    if not users:
        pytest.skip("this scipy has no FunctionDoc to hand over")
    for m in users:
        monkeypatch.setattr(m, "FunctionDoc", m.FunctionDoc)  # undone at the end, whatever the call left
    return _lib, _array_api, {m: m.FunctionDoc for m in users}


def test_where_scipys_decorator_fails_its_docstring_rewriting_is_put_back(monkeypatch):
    """The fallback: scipy's decorator breaking on the stand-in (its internals changed) leaves every
    ``FunctionDoc`` as scipy had it."""
    from pdeface.cli.common import plain_scipy_docs

    _, _array_api, before = _scipy_doc_users(monkeypatch)
    seen = []

    def broken(*args, **kwargs):
        seen.append({m: m.FunctionDoc for m in before})  # the stand-in was in place when it broke
        raise TypeError("a decorator that takes other arguments")

    monkeypatch.setattr(_array_api, "xp_capabilities", broken)
    plain_scipy_docs()
    assert seen and all(cls is not before[m] for m, cls in seen[0].items())
    assert {m: m.FunctionDoc for m in before} == before


def test_without_scipys_internals_nothing_is_handed_over(monkeypatch):
    """The other fallback: a scipy without ``scipy._lib._array_api`` (another layout) is left as it is."""
    import sys

    from pdeface.cli.common import plain_scipy_docs

    _lib, _array_api, before = _scipy_doc_users(monkeypatch)
    monkeypatch.delattr(_lib, "_array_api")
    monkeypatch.setitem(sys.modules, "scipy._lib._array_api", None)  # its import fails
    plain_scipy_docs()
    assert {m: m.FunctionDoc for m in before} == before
