"""MediaPipe's face detector and 478-point face mesh, run offline on grey renders.

``mediapipe`` is an optional extra (``pip install "pdeface[landmarks]"``):
0.10.x carries both models inside its wheel (Apache-2.0); 1.x dropped the
``solutions`` API used here.
"""
from __future__ import annotations

import importlib.util
import os
import sys
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from ..errors import LandmarkError

#: The versions whose wheels carry ``mediapipe.solutions.face_mesh`` and its models.
MEDIAPIPE_REQUIREMENT = "mediapipe>=0.10.14,<0.10.22"
#: What ``mediapipe.solutions`` imports at run time, for an install beside another numpy (Blender's): each is
#: installed without its dependencies (numpy is the host's; jax, sounddevice and sentencepiece are unused here).
RUNTIME_PACKAGES = ("mediapipe==0.10.21", "absl-py", "attrs", "flatbuffers", "protobuf>=4.25.3,<5",
                    "opencv-python-headless", "matplotlib", "contourpy", "cycler", "fonttools", "kiwisolver",
                    "packaging", "pillow", "pyparsing", "python-dateutil", "six")
#: How to get them, said wherever they are missing.
INSTALL_HINT = (f'automatic landmarks need {MEDIAPIPE_REQUIREMENT}: pip install "pdeface[landmarks]" '
                "(or give the 68 landmarks by hand: --landmarks L.json)")
#: Face-mesh points that are the mesh proper (468); 468-477 are the irises, which sit on the eyeballs.
MESH_POINTS = 468


class MissingDependencyError(LandmarkError, ImportError):
    """The optional face-landmark model (mediapipe) is not installed."""


@dataclass
class Detection:
    """A face the detector found: score, box (x0, y0, x1, y1) in pixels."""

    score: float
    box: np.ndarray


#: fd 2's silencing is shared by the threads inside :func:`native_logs_silenced` at once: the first to enter turns
#: it to the null device, the last to leave turns it back (two readers' saves and restores would otherwise
#: interleave and leave it silenced for good).
_silence_lock = threading.Lock()
_silence = {"depth": 0, "saved": None, "null": None}


@contextmanager
def native_logs_silenced(show=False):
    """Send file descriptor 2 to the null device for the block, unless ``show`` (``--verbose``).

    MediaPipe's C++ side (TensorFlow Lite, absl/glog) writes its log lines (``INFO: Created TensorFlow Lite
    XNNPACK delegate``, ``W0000 ... inference_feedback_manager.cc``) straight to fd 2, past ``sys.stderr``,
    some of them from its own threads while a graph starts: only the descriptor itself silences them. It is
    restored on leaving, errors included, by the last thread inside (blocks on several threads overlap). While it
    is silenced, other threads' lines to fd 2 are lost too (the detector reads beside the renders: keep the
    renders' side quiet, or pass ``show``).
    """
    if show or not _silence_on():
        yield
        return
    try:
        yield
    finally:
        _silence_off()


def _silence_on() -> bool:
    """Enter the shared silencing (:func:`native_logs_silenced`); False where fd 2 cannot be turned (no fd 2)."""
    with _silence_lock:
        if _silence["depth"] == 0:
            try:
                sys.stderr.flush()  # Python's pending lines go out before the descriptor turns
            except (AttributeError, OSError, ValueError):
                pass
            try:
                saved = os.dup(2)
            except OSError:  # no descriptor 2 (a windowed process): nothing to silence
                return False
            try:
                null = os.open(os.devnull, os.O_WRONLY)
            except OSError:
                os.close(saved)
                return False
            os.dup2(null, 2)
            _silence.update(saved=saved, null=null)
        _silence["depth"] += 1
        return True


def _silence_off():
    """Leave the shared silencing; the last thread out turns fd 2 back."""
    with _silence_lock:
        _silence["depth"] -= 1
        if _silence["depth"] == 0:
            saved, null = _silence["saved"], _silence["null"]
            os.dup2(saved, 2)
            os.close(saved)
            os.close(null)
            _silence.update(saved=None, null=None)


#: The packages whose ``__init__`` imports far more than the two models: ``mediapipe`` (every solution, the tasks
#: API with its audio recorder) and ``mediapipe.python.solutions`` (the drawing utilities, hence matplotlib).
BARE_PACKAGES = ("mediapipe", "mediapipe.python.solutions")
#: Held while the bare packages are put in place and the models imported: the add-on warms them on a thread of
#: its own (:func:`pdeface.rig.warm_up`), and a half-made bare package seen from another thread would be taken as
#: the whole one.
_IMPORTING = threading.Lock()


def _mediapipe():
    try:
        with _IMPORTING:
            if "mediapipe" not in sys.modules:
                _bare_packages()
            from mediapipe.python.solutions import face_detection, face_mesh
    except ImportError:
        raise MissingDependencyError(INSTALL_HINT) from None
    return face_detection, face_mesh


def _bare_packages():
    """Put :data:`BARE_PACKAGES` in ``sys.modules`` without running their ``__init__``, so that importing the two
    models loads only what they use (0.1 s instead of 0.7 s or more, mostly matplotlib's).

    Each package runs its own ``__init__`` on the first attribute it is asked for that it lacks (``mediapipe.
    solutions``, ``mediapipe.__version__``), so other code in the process sees the whole package as before.
    """
    for name in BARE_PACKAGES:
        spec = importlib.util.find_spec(name)
        if spec is None or spec.submodule_search_locations is None:
            return  # not installed (the plain import says so) or not laid out as expected (it imports it all)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        parent, _, child = name.rpartition(".")
        if parent:
            setattr(sys.modules[parent], child, module)
        module.__getattr__ = _completing(module, spec)


def _completing(module, spec):
    """A module ``__getattr__`` for a bare package: its submodules are imported as asked for (``from package
    import sub`` asks first); any other name runs the package's own ``__init__`` (its bare subpackages' first), once.
    """
    def __getattr__(name):
        sub = f"{module.__name__}.{name}"
        if sub in sys.modules or importlib.util.find_spec(sub) is not None:
            return importlib.import_module(sub)
        vars(module).pop("__getattr__", None)
        for sub in BARE_PACKAGES:
            bare = sys.modules.get(sub)
            if sub.startswith(module.__name__ + ".") and "__getattr__" in vars(bare):
                getattr(bare, "__version__", None)  # completes it
        spec.loader.exec_module(module)
        return getattr(module, name)
    return __getattr__


def available() -> bool:
    """Whether the face-landmark model can be loaded."""
    try:
        _mediapipe()
    except MissingDependencyError:
        return False
    return True


class Detector:
    """The two MediaPipe models, loaded once; use as a context manager or call :meth:`close`.

    Every image is read on one thread of the detector's own, in the order asked (the graphs read one image at a
    time): :meth:`mesh_points_later` lets the caller go on (render the next view, cast the last reading's points)
    while MediaPipe reads, which its graphs do without the GIL. MediaPipe's log lines are silenced there while it
    reads (:func:`native_logs_silenced`), so the caller's own lines to fd 2 in that time are silenced too.

    Parameters
    ----------
    min_score : float
        The face mesh's detection threshold.
    verbose : bool
        Let MediaPipe's own log lines through (silenced by default: see :func:`native_logs_silenced`).
    """

    def __init__(self, min_score: float = 0.5, verbose: bool = False):
        self.verbose, self.min_score = verbose, min_score
        with native_logs_silenced(verbose):
            face_detection, face_mesh = _mediapipe()
            # Full range (model 1): it also finds the small face of a whole body seen from afar.
            self._faces = face_detection.FaceDetection(model_selection=1, min_detection_confidence=0.2)
            self._mesh = face_mesh.FaceMesh(static_image_mode=True, max_num_faces=1, refine_landmarks=False,
                                            min_detection_confidence=min_score)
            # The graphs open their models on threads of their own after this and log as they do: one inference
            # on a blank image waits for them, with fd 2 still silenced.
            blank = self._rgb(np.zeros((8, 8)))
            self._faces.process(blank)
            self._mesh.process(blank)
        self._reader = ThreadPoolExecutor(1, thread_name_prefix="pdeface-mediapipe")

    def close(self, drop_queued=False):
        """Wait for the readings asked for (``drop_queued``: only the one under way), then close the graphs."""
        self._reader.shutdown(wait=True, cancel_futures=drop_queued)
        with native_logs_silenced(self.verbose):
            self._faces.close()
            self._mesh.close()

    def __enter__(self):
        return self

    def __exit__(self, kind, error, trace):
        self.close(drop_queued=kind is not None)  # an error, Ctrl-C: no reading left to wait for

    @staticmethod
    def _rgb(gray):
        gray = np.ascontiguousarray(gray, np.uint8)  # a rolled or mirrored render is a view
        return np.stack((gray, gray, gray), axis=-1)  # np.repeat's byte by byte: several times as long

    def faces(self, gray) -> list[Detection]:
        """Faces in a grey image, best first (any score; compare with ``min_score``)."""
        return self._reader.submit(self._read_faces, gray).result()

    def mesh_points(self, gray):
        """The 468 face-mesh points of the face in a grey image as pixel (x, y), or None when none is found."""
        return self.mesh_points_later(gray).result()

    def mesh_points_later(self, gray) -> Future:
        """:meth:`mesh_points` read on the detector's thread after the images asked for before: its future. The
        image must not change until it is read."""
        return self._reader.submit(self._read_mesh_points, gray)

    def _read_faces(self, gray):
        h, w = gray.shape
        with native_logs_silenced(self.verbose):  # MediaPipe warns on some inputs too
            res = self._faces.process(self._rgb(gray))
        out = []
        for d in res.detections or []:
            b = d.location_data.relative_bounding_box
            out.append(Detection(float(d.score[0]), np.array([b.xmin * w, b.ymin * h, (b.xmin + b.width) * w,
                                                              (b.ymin + b.height) * h])))
        return sorted(out, key=lambda d: -d.score)

    def _read_mesh_points(self, gray):
        h, w = gray.shape
        with native_logs_silenced(self.verbose):
            res = self._mesh.process(self._rgb(gray))
        if not res.multi_face_landmarks:
            return None
        lm = res.multi_face_landmarks[0].landmark[:MESH_POINTS]  # a list: each message read once, not indexed twice
        return np.array([[p.x * w - 0.5, p.y * h - 0.5] for p in lm])
