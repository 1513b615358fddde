"""What a command's process does before its work: scipy's docstrings left as written (issue #35)."""
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
