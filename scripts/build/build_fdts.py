"""Build the bundled generic Facial Deformation Tables from the bundled ICT-FaceKit data.

Usage: python -m scripts.build.build_fdts [--out assets/ict_generic_fdts.json.gz]

For every AU key ICT-FaceKit maps and the six basic expressions, the mean and σ
over identity000-019 of each identity's own FDT (models 3d and 2d), as one
FDT bundle (:mod:`pdeface.fdt.table`). Needs only the assets (no ../shared).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from pdeface.assets import load_ict_shapes, load_neutral_scan
from pdeface.fdt.generic import generic_fdts, ict_targets, identity_fits
from pdeface.fdt.table import write_fdts

IDENTITIES = [f"identity{i:03d}" for i in range(20)]
MODELS = ("3d", "2d")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[2] / "assets" / "ict_generic_fdts.json.gz")
    args = ap.parse_args(argv)
    mesh, idx = load_neutral_scan()
    T, _ = mesh.triangles()
    shapes = load_ict_shapes()
    targets = ict_targets(shapes)
    fits = [identity_fits(mesh.vertices, T, idx, shapes, name, targets, MODELS) for name in IDENTITIES]
    tables = []
    for m in MODELS:
        tables += generic_fdts([f[m] for f in fits], m, source=f"ICT-FaceKit identity000-019, generic FDT ({m})")
    size = write_fdts(args.out, tables)
    print(f"{args.out}: {len(tables)} FDTs ({len(targets)} expressions x {len(MODELS)} models), {size} bytes")


if __name__ == "__main__":
    main()
