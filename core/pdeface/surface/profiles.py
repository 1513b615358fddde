"""Writing the accuracy report's cut profiles (the method's validation sections) as CSV and PNG.

A profile set is ``{cut name: (angle, height, scan radius, PDE radius)}``, arrays
of the points along each cut (radians, mm), as
:func:`pdeface.surface.report.accuracy_report` measures them.
"""
from __future__ import annotations

import csv

import numpy as np

from ..io.files import atomic_open
from ..io.png import plot_panels

SCAN, PDE, DIFFERENCE = (40, 40, 40), (220, 30, 30), (30, 60, 220)
ZERO, MARKS = (150, 150, 150), (210, 210, 210)


def write_profiles_csv(path, profiles: dict) -> None:
    """One row per point of each cut, with the scan's and the PDE face's radius and their difference."""
    with atomic_open(path, "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["cut", "i", "angle_deg", "height_mm", "scan_radius_mm", "pde_radius_mm", "difference_mm"])
        for name, (th, y, rs, rp) in profiles.items():
            for i in range(len(th)):
                wr.writerow([name, i, f"{np.degrees(th[i]):.4f}", f"{y[i]:.4f}", f"{rs[i]:.4f}",
                             f"{rp[i]:.4f}", f"{rp[i] - rs[i]:.4f}"])


def write_profiles_png(path, profiles: dict) -> None:
    """One panel per cut: the scan (thick, grey-black) under the PDE face (red), and below them their
    difference ×10 (blue) around a zero line with ±1 mm marks, so sub-millimetre errors show."""
    panels = []
    for th, y, rs, rp in profiles.values():
        along = np.concatenate([[0], np.cumsum(np.hypot(np.diff(th) * np.nanmean(rs), np.diff(y)))])
        base = np.nanmin(np.r_[rs, rp]) - 25.0
        diff = base + 10.0 * (rp - rs)
        ends = along[[0, -1]]
        panels.append([(along, rs, SCAN, 3), (along, rp, PDE),
                       (ends, np.full(2, base), ZERO),
                       (ends, np.full(2, base + 10.0), MARKS),
                       (ends, np.full(2, base - 10.0), MARKS), (along, diff, DIFFERENCE)])
    plot_panels(path, panels, titles=[f"{name} cut" for name in profiles], xlabel="along the cut (mm)",
                ylabel="radius from the axis (mm)",
                legend=[(SCAN, "scan"), (PDE, "PDE face"),
                        (DIFFERENCE, "PDE - scan, *10 (grey: 0 and +-1 mm)")])
