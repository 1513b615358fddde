"""The core warmed while Blender idles: a new head's first Find Landmarks and Fit run as later ones do.

A first Find Landmarks or Fit in a session pays for scipy's imports, MediaPipe's models and the bundled head
prior (:func:`pdeface.rig.warm_up`, about 0.7 s of CPU). A few seconds after the add-on is enabled (at
Blender's start, as a rule) a thread of its own loads them, while the artist opens or imports a mesh; every
operator waits for it first (:func:`wait`, at most :data:`WAIT_AT_MOST_S`: a warm-up stuck in a slow disk must
not freeze Blender; the operator then goes on and loads what it needs itself). What else reaches the core
meanwhile (the panel's draw asking whether MediaPipe is installed, timers) is safe because MediaPipe's import,
the one step two threads must not run together, holds a lock of its own (``pdeface.landmarks.detector``). The
thread touches no Blender data (bpy is not thread-safe): it only imports and reads pdeface's own files. Not in
background mode (a headless render or a script): no one is idling there, and a thread must not outlive the
script it is in.
"""
import sys
import threading

import bpy
from pdeface.errors import PdeFaceError
from pdeface.rig import warm_up

#: Seconds after the add-on is enabled before the warm-up starts (Blender's own start first).
WARM_AFTER_S = 2.0
#: Seconds an operator (or quitting) waits for an unfinished warm-up before it goes on without it.
WAIT_AT_MOST_S = 10.0

_started = []  # the warm-up's thread, once started


def start():
    """Start the warm-up on a thread of its own (once a session); a timer callback (no return value: it runs
    once)."""
    if not _started:
        thread = threading.Thread(target=_warm, name="pdeface warm-up", daemon=True)
        _started.append(thread)
        thread.start()


def _warm():
    try:
        warm_up()
    except (ImportError, PdeFaceError):
        pass  # a missing extra or asset: the operator that needs it says so when it runs
    except Exception as exc:  # noqa: BLE001 (a thread's error reaches no one: said once on the console)
        print(f"pdeface: the core's warm-up stopped ({type(exc).__name__}: {exc}); the first operator loads it",
              file=sys.stderr)


def wait():
    """Return once the warm-up (if started) is done, or after :data:`WAIT_AT_MOST_S`."""
    if _started:
        _started[0].join(timeout=WAIT_AT_MOST_S)


def register():
    if not bpy.app.background:
        # persistent: a file opened at start-up (a .blend double-clicked) must not cancel it
        bpy.app.timers.register(start, first_interval=WARM_AFTER_S, persistent=True)


def unregister():
    if bpy.app.timers.is_registered(start):
        bpy.app.timers.unregister(start)
    wait()
