"""The chain's warm-up (issue #35): what a first landmarks/fit/bind call loads, loaded ahead, in a fresh process."""
import json
import subprocess
import sys

import pytest


def _fresh(code):
    """What ``code`` prints last (JSON), run in a fresh process (the modules it loads are its own)."""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_warm_up_loads_the_chains_libraries_and_the_prior_without_mediapipe_when_asked():
    out = _fresh("import json, sys\n"
                 "from pdeface.rig import CHAIN_MODULES, warm_up\n"
                 "from pdeface.head.prior import load_head_prior\n"
                 "before = [m for m in CHAIN_MODULES if m in sys.modules]\n"
                 "warm_up(landmarks=False)\n"
                 "print(json.dumps({'before': before, 'after': [m for m in CHAIN_MODULES if m in sys.modules],\n"
                 "                  'all': list(CHAIN_MODULES), 'prior': load_head_prior.cache_info().currsize,\n"
                 "                  'solver': '_solver' in vars(load_head_prior()),\n"
                 "                  'mediapipe': 'mediapipe' in sys.modules}))")
    assert out["before"] == [] and out["after"] == out["all"]
    assert out["prior"] == 1  # read once, kept for the binding
    assert out["solver"]  # its kernel-ridge solver made once, kept for every binding
    assert not out["mediapipe"]  # landmarks given: MediaPipe is not loaded


def test_the_prior_and_the_landmark_steps_read_icts_head_file_once():
    # The prior's head is the landmark steps' copy (issue #35: the file was read twice a process, 10-14 ms each).
    out = _fresh("import json, os\n"
                 "import numpy as np\n"
                 "from pdeface.assets import ICT_HEAD, generic_head_geometry\n"
                 "from pdeface.head.prior import load_head_prior\n"
                 "reads, load = [], np.load\n"
                 "def counted(path, *args, **kw):\n"
                 "    reads.append(os.path.basename(str(path)) == os.path.basename(str(ICT_HEAD)))\n"
                 "    return load(path, *args, **kw)\n"
                 "np.load = counted\n"
                 "load_head_prior()\n"
                 "generic_head_geometry()\n"
                 "print(json.dumps({'reads': sum(reads)}))")
    assert out["reads"] == 1


def test_mediapipe_models_imported_from_two_threads_at_once_stay_bare():
    """The add-on warms MediaPipe on a thread while an operator may ask for it: both get the two models, and
    neither sees a half-made bare package (which would import every solution, matplotlib with them)."""
    pytest.importorskip("mediapipe")
    out = _fresh("import json, sys, threading\n"
                 "from pdeface.landmarks.detector import _mediapipe\n"
                 "got = []\n"
                 "threads = [threading.Thread(target=lambda: got.append(_mediapipe())) for _ in range(4)]\n"
                 "[t.start() for t in threads]; [t.join() for t in threads]\n"
                 "print(json.dumps({'got': len(got), 'same': len({id(g[1]) for g in got}),\n"
                 "                  'matplotlib': 'matplotlib' in sys.modules}))")
    assert out == {"got": 4, "same": 1, "matplotlib": False}
