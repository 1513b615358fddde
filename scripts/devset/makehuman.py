"""MakeHuman's base mesh and targets, read as plain arrays.

``base.obj`` (hm08, decimetres, +y up, +z forward) holds the skin (group ``body``) and helper geometry
(eyeballs, teeth, tongue, lashes, clothes, ``joint-*`` cubes); a target is a gzipped text file of
``index dx dy dz`` lines. See ``../shared/data/makehuman/README.md``.
"""
from __future__ import annotations

import gzip
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np



def _beside_checkout() -> Path:
    """``../shared/data/makehuman`` beside the checkout (or beside the folder of a git worktree of it)."""
    root = Path(__file__).resolve().parents[2]
    places = [up / "shared" / "data" / "makehuman" for up in (root.parent, root.parent.parent)]
    return next((p for p in places if (p / "base.obj").is_file()), places[0])


#: Where the data lies (``PDEFACE_MAKEHUMAN`` overrides): beside the checkout, as the issue names it.
DATA = Path(os.environ.get("PDEFACE_MAKEHUMAN") or _beside_checkout())
#: Millimetres per base-mesh unit (decimetres).
BASE_MM = 100.0


def available() -> bool:
    """Whether the MakeHuman data is there."""
    return (DATA / "base.obj").is_file()


@dataclass(frozen=True)
class Base:
    """The base mesh: vertices, quads and, per group name, the quads of that group."""

    vertices: np.ndarray
    quads: np.ndarray
    groups: dict

    def group_quads(self, *names) -> np.ndarray:
        """The quads of the named groups (a name ending in ``*`` matches its prefix)."""
        rows = [q for g, q in self.groups.items()
                if any(g == n or (n.endswith("*") and g.startswith(n[:-1])) for n in names)]
        return self.quads[np.concatenate(rows)] if rows else np.zeros((0, 4), np.int64)

    def joint(self, name, vertices=None) -> np.ndarray:
        """The centre of the ``joint-<name>`` cube (of the base, or of ``vertices``: a character's)."""
        V = self.vertices if vertices is None else vertices
        return V[np.unique(self.group_quads(f"joint-{name}"))].mean(0)


@lru_cache(maxsize=1)
def read_base(path=None) -> Base:
    """Read ``base.obj`` (cached)."""
    path = Path(path or DATA / "base.obj")
    V, F, group_of = [], [], []
    names, current = [], -1
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                V.append(line.split()[1:4])
            elif line.startswith("f "):
                corners = [int(c.split("/")[0]) - 1 for c in line.split()[1:]]
                if len(corners) == 3:
                    corners.append(corners[2])
                F.append(corners[:4])
                group_of.append(current)
            elif line.startswith("g "):
                name = line.split()[1]
                if name not in names:
                    names.append(name)
                current = names.index(name)
    group_of = np.array(group_of)
    groups = {n: np.flatnonzero(group_of == i) for i, n in enumerate(names)}
    return Base(np.array(V, np.float64), np.array(F, np.int64), groups)


@lru_cache(maxsize=256)
def read_target(name: str) -> tuple[np.ndarray, np.ndarray]:
    """A target by its path under ``targets/`` without ``.target.gz``: vertex indices and offsets (cached)."""
    with gzip.open(DATA / "targets" / f"{name}.target.gz", "rt") as f:
        rows = [line.split() for line in f if line.strip() and not line.startswith("#")]
    idx = np.array([int(r[0]) for r in rows], np.int64)
    d = np.array([[float(x) for x in r[1:4]] for r in rows], np.float64)
    return idx, d


def apply_targets(V, weights: dict) -> np.ndarray:
    """``V`` plus Σ weight · target (target names as :func:`read_target` takes them)."""
    V = np.array(V, np.float64)
    for name, w in weights.items():
        idx, d = read_target(name)
        np.add.at(V, idx, w * d)
    return V


def triangles(quads) -> np.ndarray:
    """Quads (a triangle's last corner repeated) split into triangles; degenerate ones dropped."""
    Q = np.asarray(quads)
    T = np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])
    ok = (T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 0] != T[:, 2])
    return T[ok]
