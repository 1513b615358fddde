"""Benchmark the PDE face engine on the bundled ICT-FaceKit data (issue #2 targets).

Usage: python -m scripts.bench.bench_fit [--identities N] [--json OUT]

Prints, each measured in this run:
- accuracy on the ICT neutral (smooth and patches) and on identity000-019
  (median and worst), against the targets; the neutral again with the
  method's 31 curves, for comparison;
- the spectral solve against a finite-difference solve of the same PDE with
  the same curves (scipy.sparse), time ratio and error of each: the FD matrix
  factorised once and cached, as the spectral operators are (the fair figure),
  and, beside it, built and factorised on every solve;
- fit + solve time after curve extraction, and the model file size.

Everything runs with the BLAS pools bounded as the command line and the add-on run them
(:mod:`pdeface.threads`).
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from pdeface.assets import load_ict_shapes, load_neutral_scan
from pdeface.au.modelfile import model_nbytes, save_model
from pdeface.geometry import ClosestPoint
from pdeface.surface.fit import fit_face
from pdeface.surface.fourier import fit_fourier
from pdeface.surface.grid import grid_faces, surface_grid
from pdeface.surface.pde import output_grid, solve_surface
from pdeface.surface.report import accuracy_report, band_vertices
from pdeface.threads import bounded

from scripts.bench.benchlib import bench_parser, median_time, run_bench

TARGETS = {"mean_mm": 0.15, "p95_mm": 0.6, "max_mm": 3.0, "normal_p95_deg": 8.0, "seam_max_deg": 0.01}
KEYS = list(TARGETS)
METHOD_CURVES = 31


class FiniteDifferences:
    """Finite-difference solve of (D_uu + a² D_vv)² X = 0 between the curves, factorised once.

    The curve rows (Fourier series + remainder along v, as in the spectral
    solve) are fixed; every other grid node satisfies the discrete operator,
    with even reflection at the grid's edges. The sparse matrix is built with
    numpy and factorised once with SuperLU, as the spectral solve's operators
    are built once per layout and cached: :meth:`solve` is the fair figure;
    :func:`fd_uncached` builds and factorises on every solve.
    """

    def __init__(self, model, sub_u, sub_v):
        from scipy.sparse.linalg import splu

        self.X0 = surface_grid(model, sub_u, sub_v)  # only its curve rows are used
        nu, nv, _ = self.X0.shape
        fixed = np.zeros(nu, bool)
        fixed[::sub_u] = True
        u = output_grid(model.knots, model.layout.n_points, sub_u, sub_v).u
        v = np.linspace(0, np.pi, nv)
        L = sp.kron(second_diff(u), sp.identity(nv)) + model.a ** 2 * sp.kron(sp.identity(nu), second_diff(v))
        A = (L @ L).tocsr()
        self.free = np.repeat(~fixed, nv)
        self.lu = splu(A[self.free][:, self.free].tocsc())
        self.Afc = A[self.free][:, ~self.free].tocsr()
        self.curves = self.X0.reshape(-1, 3)[~self.free].copy()

    def solve(self):
        X = self.X0.reshape(-1, 3).copy()
        X[self.free] = self.lu.solve(-(self.Afc @ self.curves))
        return X.reshape(self.X0.shape)


def fd_uncached(model, sub_u, sub_v):
    """The finite-difference surface with its matrix built and factorised for this one solve."""
    return FiniteDifferences(model, sub_u, sub_v).solve()


def second_diff(x):
    """The non-uniform second difference on the nodes ``x`` (even reflection at both ends), sparse."""
    n = len(x)
    i = np.arange(n)
    im, ip = np.where(i > 0, i - 1, 1), np.where(i < n - 1, i + 1, n - 2)
    hm = np.where(i > 0, np.abs(x - x[im]), abs(x[1] - x[0]))
    hp = np.where(i < n - 1, np.abs(x[ip] - x), abs(x[-1] - x[-2]))
    vals = np.stack([2 / (hm * (hm + hp)), -2 / (hm * hp), 2 / (hp * (hm + hp))], 1)
    return sp.csr_matrix((vals.ravel(), (np.repeat(i, 3), np.stack([im, i, ip], 1).ravel())), shape=(n, n))


def surface_error(model, X, Vf, T, vis):
    nu, nv, _ = X.shape
    Q = grid_faces(nu, nv)
    Tp = np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])
    return float(ClosestPoint(X.reshape(-1, 3), Tp).query(Vf[vis])[0].mean())


@bounded  # BLAS threads bounded, as every pdeface command and operator runs (pdeface.threads)
def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--identities", type=int, default=20)
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    out = {}
    mesh, lm_idx = load_neutral_scan()
    T, _ = mesh.triangles()
    V = mesh.vertices
    model, sampler = fit_face(V, T, V[lm_idx], unit="cm")
    lay = model.layout
    print(f"== ICT generic neutral, default layout ({lay.n_curves} x {lay.n_points}, N={model.n_modes})")
    for asm in ("smooth", "patches"):
        r = accuracy_report(model, V, T, asm)
        out[f"neutral_{asm}"] = r
        print(f"  {asm:8s} " + "  ".join(f"{k}={r[k]:.4g} (target {TARGETS[k]}, ratio {r[k] / TARGETS[k]:.2f})" for k in KEYS))
        print(f"           normal p95 counted per vertex instead of by skin area: {r['normal_p95_vertex_deg']:.4g} deg")
    # The method's own count: 31 curves, its 10 patches of 4 (same densities, 3 curves fewer).
    m31, _ = fit_face(V, T, V[lm_idx], unit="cm", n_curves=METHOD_CURVES)
    print(f"== the same with the method's {METHOD_CURVES} curves (--curves {METHOD_CURVES}; patches = its 10 patches of 4)")
    for asm in ("smooth", "patches"):
        r = accuracy_report(m31, V, T, asm)
        out[f"neutral_{METHOD_CURVES}_{asm}"] = r
        print(f"  {asm:8s} " + "  ".join(f"{k}={r[k]:.4g}" for k in KEYS))
    shapes = load_ict_shapes()
    rows = []
    for i in range(args.identities):
        Vi = V + shapes[f"identity{i:03d}"]
        mi, _ = fit_face(Vi, T, Vi[lm_idx], unit="cm")
        rows.append(accuracy_report(mi, Vi, T))
    if rows:
        print(f"== identity000-{args.identities - 1:03d} (smooth): median / worst")
        agg = {}
        for k in KEYS:
            vals = np.array([r[k] for r in rows])
            agg[k] = {"median": float(np.median(vals)), "worst": float(vals.max())}
            print(f"  {k:15s} median {agg[k]['median']:.4g}  worst {agg[k]['worst']:.4g}  target {TARGETS[k]}  "
                  f"(worst/target {agg[k]['worst'] / TARGETS[k]:.2f})")
        vv = np.array([r["normal_p95_vertex_deg"] for r in rows])
        print(f"  normal p95 per vertex (not the target) median {np.median(vv):.4g}  worst {vv.max():.4g}")
        agg["normal_p95_vertex_deg"] = {"median": float(np.median(vv)), "worst": float(vv.max())}
        out["identities"] = agg
    print("== spectral vs finite-difference solve (same curves, same grid)")
    Vf = model.frame.to_face(V)
    vis = band_vertices(model, Vf, T)["visible"]
    su, sv = 4, 4
    br = model.layout.breaks()
    solve = lambda: solve_surface(model.coefficients, model.residual, model.knots, model.a, model.remainder_w,
                                  su, sv, breaks=br)
    solve()  # operators are built once per layout and cached
    t_spec = median_time(solve, 50)
    fd = FiniteDifferences(model, su, sv)
    t_fd = median_time(fd.solve, 50)
    t_fd_uncached = median_time(lambda: fd_uncached(model, su, sv), 5)
    e_spec = surface_error(model, solve(), Vf, T, vis)
    e_fd = surface_error(model, fd.solve(), Vf, T, vis)
    print(f"  spectral {t_spec * 1e3:.2f} ms, mean error {e_spec:.4f} mm")
    print(f"  finite differences, factorised once (SuperLU, cached as the spectral operators are): "
          f"{t_fd * 1e3:.2f} ms, mean error {e_fd:.4f} mm")
    print(f"  finite differences, matrix built and factorised on every solve: {t_fd_uncached * 1e3:.1f} ms")
    print(f"  speed-up {t_fd / t_spec:.0f}x against the cached factorisation (the fair figure), "
          f"{t_fd_uncached / t_spec:.0f}x against the uncached solve (target >= 100x, set against the uncached one); "
          f"error ratio spectral/FD {e_spec / e_fd:.3f} (target <= 1)")
    out["spectral_ms"], out["fd_ms"], out["fd_uncached_ms"] = t_spec * 1e3, t_fd * 1e3, t_fd_uncached * 1e3
    out["speedup"], out["speedup_uncached"] = t_fd / t_spec, t_fd_uncached / t_spec
    out["spectral_error_mm"], out["fd_error_mm"] = e_spec, e_fd
    print("== fit + solve after curve extraction, model size")
    points = sampler.sample(model.frame.to_face(V))
    fs = lambda: solve_surface(*fit_fourier(points, 5), model.knots, model.a, None, su, sv, breaks=br)
    fs()
    t_fs = median_time(fs, 50)
    path = Path("/tmp") / "pdeface_bench_face.npz"
    size = save_model(path, model)
    # The target is the PDE face's (its curves, layout and frame); the 68 landmarks it was fitted with, unrounded,
    # which a head's binding reads, come beside it (~2 KB).
    bare = model_nbytes(replace(model, landmarks=None))
    print(f"  fit + solve {t_fs * 1e3:.2f} ms (target <= 10 ms, ratio {t_fs * 1e3 / 10:.2f}); "
          f"model {bare} bytes without its landmarks (target <= 8192, ratio {bare / 8192:.2f}), {size} with them")
    out["fit_solve_ms"], out["model_bytes"], out["model_bytes_without_landmarks"] = t_fs * 1e3, size, bare
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    run_bench(main, "fit")
