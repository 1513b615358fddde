"""Waters-style pseudo-muscles as displacement fields over points (face frame, mm).

Each muscle gives the displacement of points ``P`` (n, 3) at activation 1; the
displacement is linear in the activation (Waters' one-step contraction), so an
AU made of muscle activations is a linear shape key, and activations can be
calibrated by linear least squares.

- :class:`LinearMuscle` (Waters 1987, "A muscle model for animating three-dimensional
  facial expression"): a vector from its bony head h to its skin insertion i, an
  angular zone Ω about that vector and a radial fall-off from Rs to Rf (distances
  from h). A point p at distance D = |p − h| and angle α from h→i moves towards h::

      Δp = a · k · A(α) · R(D) · (h − p) / D
      A = cos(α / Ω · π/2) for α ≤ Ω, else 0     (Waters: cos α; this one reaches 0 at the zone's edge)
      R = cos((1 − D/Rs) · π/2) for D < Rs;  cos((D − Rs)/(Rf − Rs) · π/2) for Rs ≤ D ≤ Rf;  else 0

  plus, where the FAS's flat face has none, the skin's bulge over a shortening muscle:
  ``Δz = a · b · A · R`` (b mm, out of the face).

- :class:`Sphincter` (Tanguy 2001; Edge and Maddock 2001): an ellipse of centre c and
  semi-axes (ax, ay) in the face's plane; with ρ² = ((x − cx)/ax)² + ((y − cy)/ay)²,
  F = cos(ρ · π/2) for ρ ≤ 1. The mouth's converges on its centre, Δp = a · k · F · (c − p)
  in x, y; the eyes' on the ellipse's semi-major axis (FAS), Δp = a · k · F · (0, cy − y, 0):
  lids close and the eye squints. The mouth's also pushes the lips out, Δz = a · b · F (pucker).
- :class:`Sheet` (parallel fibres): an attachment edge through o, fibres along d (in the
  face's plane) of length L, half-width W. With s = (p − o)·d and w = |(p − o)·e|, e ⟂ d,
  Δp = −a · k · sin(min(s/L, 1) · π/2) · T(s) · cos(w/W · π/2) · d for 0 ≤ s ≤ (1 + f) L, w ≤ W, T
  fading smoothly from 1 at L to 0 at (1 + f) L (``fade`` f, 0.3 by default). ``mirrored`` fibres run
  outwards on both sides of o (d → sign(x − ox) d), as the nasalis across the nose.
- :class:`Jaw`: a turn about the left-right axis through the hinge, linearised
  (Δp = a · θ · w(p) · x̂ × (p − hinge)), w = 1 below the lower lip, 0 above the
  mouth line, smooth between.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import smoothstep


@dataclass(frozen=True)
class LinearMuscle:
    name: str
    head: np.ndarray
    insertion: np.ndarray
    zone_deg: float
    fall_start: float  # Rs (mm from the head)
    fall_end: float  # Rf
    pull_mm: float
    bulge_mm: float = 0.0

    kind = "linear"

    def displacement(self, P) -> np.ndarray:
        P = np.asarray(P, np.float64)
        v = P - self.head
        D = np.linalg.norm(v, axis=1)
        axis = self.insertion - self.head
        axis = axis / np.linalg.norm(axis)
        cos_a = np.clip((v @ axis) / np.maximum(D, 1e-12), -1, 1)
        alpha = np.arccos(cos_a)
        omega = np.radians(self.zone_deg)
        A = np.where(alpha <= omega, np.cos(alpha / omega * np.pi / 2), 0.0)
        Rs, Rf = self.fall_start, self.fall_end
        R = np.where(D < Rs, np.cos((1 - D / Rs) * np.pi / 2),
                     np.where(D <= Rf, np.cos(np.clip((D - Rs) / (Rf - Rs), 0, 1) * np.pi / 2), 0.0))
        out = (self.pull_mm * A * R / np.maximum(D, 1e-12))[:, None] * -v
        out[:, 2] += self.bulge_mm * A * R
        return out


@dataclass(frozen=True)
class Sphincter:
    name: str
    centre: np.ndarray
    semi_axes: tuple  # (ax, ay) mm
    pull: float  # fraction of the distance to the centre (or axis) closed at activation 1
    to_axis: bool = False  # the eyes': converge on the semi-major (horizontal) axis
    push_mm: float = 0.0  # out of the face at the centre (the lips' pucker)

    kind = "sphincter"

    def displacement(self, P) -> np.ndarray:
        P = np.asarray(P, np.float64)
        d = P - self.centre
        rho = np.hypot(d[:, 0] / self.semi_axes[0], d[:, 1] / self.semi_axes[1])
        F = np.where(rho <= 1, np.cos(np.clip(rho, 0, 1) * np.pi / 2), 0.0) * self.pull
        out = np.zeros_like(P)
        out[:, 1] = -F * d[:, 1]
        if not self.to_axis:
            out[:, 0] = -F * d[:, 0]
        out[:, 2] = self.push_mm * F / max(self.pull, 1e-12)
        return out


@dataclass(frozen=True)
class Sheet:
    name: str
    origin: np.ndarray
    direction: np.ndarray  # unit, in the face's plane: from the attachment edge along the fibres
    length: float
    half_width: float
    pull_mm: float
    mirrored: bool = False
    fade: float = 0.3  # share of the length beyond it over which the pull fades

    kind = "sheet"

    def displacement(self, P) -> np.ndarray:
        P = np.asarray(P, np.float64)
        v = P - self.origin
        d = np.broadcast_to(self.direction, P.shape).copy()
        if self.mirrored:
            d[:, 0] *= np.where(v[:, 0] < 0, -1.0, 1.0)
        e = np.stack([-d[:, 1], d[:, 0], np.zeros(len(P))], axis=1)
        s = (v * d).sum(1)
        w = np.abs((v * e).sum(1))
        along = np.sin(np.clip(s / self.length, 0, 1) * np.pi / 2) * (1 - smoothstep((s - self.length) / (self.fade * self.length)))
        across = np.where(w <= self.half_width, np.cos(np.clip(w / self.half_width, 0, 1) * np.pi / 2), 0.0)
        mag = np.where(s >= 0, self.pull_mm * along * across, 0.0)
        return -mag[:, None] * d


@dataclass(frozen=True)
class Jaw:
    name: str
    hinge: np.ndarray
    degrees: float  # the skin's turn at activation 1
    lip_lower_y: float  # full weight below
    mouth_y: float  # none above

    kind = "jaw"

    def displacement(self, P) -> np.ndarray:
        P = np.asarray(P, np.float64)
        w = smoothstep((self.mouth_y - P[:, 1]) / (self.mouth_y - self.lip_lower_y))
        r = P - self.hinge
        turn = np.stack([np.zeros(len(P)), -r[:, 2], r[:, 1]], axis=1)  # x̂ × r
        return np.radians(self.degrees) * w[:, None] * turn
