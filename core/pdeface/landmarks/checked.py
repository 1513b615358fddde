"""The landmarks as every command takes them: found anywhere on the mesh (the head first on a body), then gated.

One home for the chain ``pdeface landmarks``, ``fit``, ``rig`` and batch rig jobs share: the detector's word is
not enough, so the points go through :mod:`~pdeface.landmarks.gate` before anything is fitted to them. Landmarks
given by hand are taken at their word, but the mesh they come with is still looked at (:func:`check_given`).
"""
from __future__ import annotations

import time

from .gate import FIX_MESH, LandmarkGateError, Verdict, check, check_mesh_at_rest, require
from .headfind import detect_anywhere
from .pipeline import FoundLandmarks


def find_checked(mesh, unit=None, keep_images=False, verbose=False, accept=False,
                 log=None) -> tuple[FoundLandmarks, Verdict]:
    """:func:`~pdeface.landmarks.headfind.detect_anywhere` on ``mesh``, then the landmark gate.

    Parameters
    ----------
    mesh : Mesh
        The head or body (:class:`~pdeface.mesh.Mesh`).
    unit : str or float, optional
        The mesh unit (a name or millimetres per unit); estimated from the face's size when None.
    keep_images, verbose : bool
        Passed to the detector (the renders kept for a picture; its own progress lines).
    accept : bool
        Go on when a group fails the gate (the verdict is returned and logged) instead of raising.
    log : callable, optional
        Called with a line saying what was found, and with the gate's note when ``accept`` lets a failure by.

    Returns
    -------
    found : FoundLandmarks
    verdict : Verdict

    Raises
    ------
    LandmarkGateError
        A group fails the gate and ``accept`` is False; the error carries ``found`` (for a picture of it).
    LandmarkError
        No face found anywhere tried.
    """
    say = log or (lambda msg: None)
    t = time.perf_counter()
    T = mesh.triangles()[0]
    found = detect_anywhere(mesh.vertices, T, unit, keep_images=keep_images, verbose=verbose)
    low = found.least_sure()
    say(f"found the 68 landmarks in {time.perf_counter() - t:.1f} s (view {found.view}, detector score "
        f"{found.score:.2f}, {found.residual_mm:.1f} mm from the template; least sure: {low} "
        f"{found.confidence[low]:.2f}; {found.mm_per_unit:.4g} mm per unit)")
    # On the skin the points were cast onto: lashes and helper geometry in front of it are no face.
    verdict = check(found.points, mesh.vertices, T if found.skin is None else T[found.skin], unit)
    if not verdict.passed:
        if not accept:
            try:
                require(verdict)
            except LandmarkGateError as exc:
                exc.found = found  # for the picture of what failed
                raise
        say(f"note: the landmarks fail the gate ({verdict.message()}); going on (--accept)")
    return found, verdict


def check_given(mesh, points, unit=None, accept=False, log=None) -> Verdict:
    """The gate's look at a mesh whose landmarks were given by hand (``--landmarks``): its eyes open, as a head at
    rest has them (:func:`~pdeface.landmarks.gate.check_mesh_at_rest`: a small render of each eye's middle).

    Raises
    ------
    LandmarkGateError
        An eye is closed and ``accept`` is False (with ``accept``, the verdict is returned and ``log`` told).
    """
    verdict = check_mesh_at_rest(points, mesh.vertices, mesh.triangles()[0], unit)
    if not verdict.passed:
        if not accept:
            require(verdict, "the mesh and its given landmarks", FIX_MESH)
        (log or (lambda msg: None))(f"note: the mesh fails the gate ({verdict.message()}); going on (--accept)")
    return verdict
