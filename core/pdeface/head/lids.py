"""Keys that close the eyes close them on any head: the upper lid taken down onto the lower one (issue #40).

On ICT's head the PDE face's blink closes the lids 0.87; on older, narrow or remeshed heads the retargeted
motion stops short (0.44-0.8 of the gap on the MakeHuman development set): the upper margin lags the lid.
:class:`LidClosure` measures, per key and eye, how far the key closes the gap between the upper and lower
lid middles (the vertices at the landmarks); a key that closes it more than ``CLOSING`` is taken the rest of
the way, to ``LEFT_OPEN`` of the rest gap, by moving the upper lid (its margin fully, fading out above it
over ``LID_IOD`` eye distances and along the margin as the opening's height does) towards the lower lid's
keyed middle. Keys that narrow the eye less (AU6, AU7, a smile) are left as bound.
"""
from __future__ import annotations

import numpy as np

from ..geometry import smoothstep

#: Upper and lower lid landmarks (iBUG-68, 0-based) per eye, each from one corner to the other.
LIDS = {"R": ((36, 37, 38, 39), (36, 41, 40, 39)), "L": ((42, 43, 44, 45), (42, 47, 46, 45))}
#: The lid middles (the issue's closure measure): upper pair, lower pair.
MIDDLES = {"R": ((37, 38), (40, 41)), "L": ((43, 44), (46, 47))}
#: A key closing an eye's gap by CLOSING[0] starts to be taken further; by CLOSING[1], all the way.
CLOSING = (0.35, 0.6)
#: The gap left (share of the rest gap): lids meeting exactly would cross on the next frame's blend.
LEFT_OPEN = 0.03
#: How far above the margin (eye distances) the upper lid moves with it, and how deep behind it.
LID_IOD = 0.2
DEPTH_IOD = 0.25


class LidClosure:
    """The upper lids of one head and how each follows its margin.

    Parameters
    ----------
    Vf : (n, 3) array
        The head's vertices, face frame (+y up, +z front).
    Lf : (68, 3) array
        Its landmarks, face frame.
    lid : (n,) bool array
        Vertices that may move with the upper lid (skin that moves at all, lashes and other attached parts).
    eye_distance : float
    """

    def __init__(self, Vf, Lf, lid, eye_distance):
        self.Vf = Vf
        self.eyes = []
        for side, (upper, lower) in LIDS.items():
            (mu, ml) = MIDDLES[side]
            on_lid = np.nonzero(lid)[0]
            at = [int(on_lid[np.argmin(np.linalg.norm(Vf[on_lid] - Lf[i], axis=1))]) for i in mu + ml]
            xu, yu = Lf[list(upper), 0], Lf[list(upper), 1]
            xl, yl = Lf[list(lower), 0], Lf[list(lower), 1]
            ou, ol = np.argsort(xu), np.argsort(xl)
            x = Vf[:, 0]
            inside = (x > xu.min()) & (x < xu.max())
            y_up = np.interp(x, xu[ou], yu[ou])
            height = np.maximum(y_up - np.interp(x, xl[ol], yl[ol]), 0)
            mid_x = Lf[list(mu), 0].mean()
            h_mid = max(float(np.interp(mid_x, xu[ou], yu[ou]) - np.interp(mid_x, xl[ol], yl[ol])), 1e-9)
            along = np.clip(height / h_mid, 0, 1)  # how much of the middle's closing this place needs
            dy = Vf[:, 1] - y_up
            # Above the margin the lid moves with it, fading out; in the opening (a lid's lining, an occlusion
            # mesh across it) the closing is shared out from the upper margin (all) to the lower one (none).
            above = 1 - smoothstep(dy / (LID_IOD * eye_distance))
            share = np.where(dy >= 0, above, np.clip(1 + dy / np.maximum(height, 1e-12), 0, 1))
            z_margin = Lf[list(upper), 2].max()
            w = along * share * inside * lid * (Vf[:, 2] > z_margin - DEPTH_IOD * eye_distance)
            idx = np.nonzero(w > 0)[0]
            self.eyes.append((np.array(at[:2]), np.array(at[2:]), idx, w[idx]))

    def apply(self, out):
        """Close the eyes further in the keys that close them (``out`` (n, k, 3), face frame, in place);
        whether any key was changed."""
        changed = False
        for j, (up, lo, idx, w) in enumerate(self.eyes):
            U0, L0 = self.Vf[up].mean(0), self.Vf[lo].mean(0)
            U1 = U0 + out[up].mean(0)  # (k, 3)
            L1 = L0 + out[lo].mean(0)
            gap0 = np.linalg.norm(U0 - L0)
            gap1 = np.linalg.norm(U1 - L1, axis=1)
            closed = 1 - gap1 / max(gap0, 1e-12)
            gain = smoothstep((closed - CLOSING[0]) / (CLOSING[1] - CLOSING[0]))
            rest_of_way = np.clip(1 - LEFT_OPEN * gap0 / np.maximum(gap1, 1e-12), 0, 1)
            step = (L1 - U1) * (gain * rest_of_way)[:, None]  # (k, 3)
            out[idx] += w[:, None, None] * step[None]
            changed |= bool((gain > 0).any())
        return changed
