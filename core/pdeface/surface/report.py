"""How well a PDE face matches the scan it was fitted to.

Measured on the scan's *visible* face vertices inside the curve band: a vertex
is visible when the layout's ray through it meets the scan there first (not
hidden in a nostril, a lid fold or the mouth corner). Hidden ones are reported
separately. Normals are compared over the visible skin's area, triangle by
triangle. All figures are in millimetres and degrees.
"""
from __future__ import annotations

import numpy as np

from ..geometry import ClosestPoint, cast_cylinder_rays, cylinder_coords, degrees_from_cos, triangle_cross, unit_rows
from ..mesh import vertex_normals
from .fit import skin_triangles
from .grid import grid_faces, surface_grid
from .model import FaceModel
from .pde import SurfaceOperator, knot_slopes, surface_operator
from .profiles import write_profiles_csv, write_profiles_png
from .rims import FACING_MIN_COS

#: Resolution the report measures the surface at (rows, columns per interval).
REPORT_RESOLUTION = (6, 6)
#: A vertex more than this (mm) behind the first surface its ray meets is hidden.
VISIBILITY_TOLERANCE_MM = 0.5
#: A vertex lower than the skin on both sides of it, this far (mm) off in angle or
#: height, by more than ``PIT_DEPTH_MM`` is seen down a hole (a flared nostril).
PIT_REACH_MM = (1.0, 2.0, 4.0)
PIT_DEPTH_MM = 4.0


def band_vertices(model: FaceModel, V_face: np.ndarray, T: np.ndarray, occluders=None) -> dict:
    """Classify the vertices of triangles ``T`` inside the curve band.

    ``occluders`` (default ``T``) are the triangles rays may hit first: the whole
    mesh when ``T`` is its skin, so skin behind an eyeball or teeth is hidden.

    ``visible``: the layout's ray through the vertex meets the scan there
    first, the skin faces the ray within ~72°, and the vertex is not sunk in
    an opening (a grid cell with a filled corner, over 2 mm below that cell's
    ray hits, as nostril and mouth-corner interiors seen straight through their
    openings are), nor at the bottom of a pit (see :data:`PIT_DEPTH_MM`: a
    nostril flared so wide that no curve's ray went in). ``occluded``: hidden
    behind other skin or sunk in an opening. ``oblique``: otherwise visible
    but seen at a grazing angle.

    Returns
    -------
    dict of (n,) bool masks: ``inside``, ``visible``, ``occluded``, ``oblique``
    """
    lay = model.layout
    th, y, r = cylinder_coords(V_face, lay.axis_z)
    half = np.interp(y, lay.heights[::-1], lay.half_angles[::-1])
    inside = (y <= lay.heights[0]) & (y >= lay.heights[-1]) & (np.abs(th) <= half)
    inside &= np.bincount(T.ravel(), minlength=len(V_face)) > 0  # vertices of these triangles only
    first = np.zeros(len(V_face), bool)
    idx = np.nonzero(inside)[0]
    blockers = T if occluders is None else occluders
    rad, _, _, _ = cast_cylinder_rays(V_face, blockers, lay.axis_z, th[idx], y[idx])
    first[idx] = np.isfinite(rad) & (rad - r[idx] <= VISIBILITY_TOLERANCE_MM)
    idx = np.nonzero(first)[0]
    first[idx] = ~_in_pit(V_face, blockers, lay.axis_z, th[idx], y[idx], r[idx])
    if model.status is not None and (model.status != 0).any():
        first &= ~_in_opening(model, th, y, r)
    n = vertex_normals(V_face, T)
    facing = n[:, 0] * np.sin(th) + n[:, 2] * np.cos(th) >= FACING_MIN_COS
    return {"inside": inside, "visible": inside & first & facing,
            "occluded": inside & ~first, "oblique": inside & first & ~facing}


def _in_pit(V_face, T, axis_z, th, y, r):
    """Which points (angle, height, radius) lie ``PIT_DEPTH_MM`` below the skin
    on both sides of them, across or along the curves."""
    n = len(th)
    # Every probe in one cast: (reach, side) blocks of n rays each.
    dth = np.concatenate([[-d / r, d / r, 0 * r, 0 * r] for d in PIT_REACH_MM]).ravel()
    dy = np.concatenate([[0 * r, 0 * r, np.full(n, -d), np.full(n, d)] for d in PIT_REACH_MM]).ravel()
    k = len(dth) // n
    rad = cast_cylinder_rays(V_face, T, axis_z, np.tile(th, k) + dth, np.tile(y, k) + dy)[0]
    R = np.nan_to_num(rad, nan=-np.inf).reshape(len(PIT_REACH_MM), 4, n)
    floor = np.maximum(np.minimum(R[:, 0], R[:, 1]), np.minimum(R[:, 2], R[:, 3])).max(axis=0)
    return r + PIT_DEPTH_MM < floor


def _in_opening(model, th, y, r, depth=2.0):
    lay = model.layout
    K, J = lay.n_curves, lay.n_points
    P = model.curve_points()
    pth, _, pr = cylinder_coords(P.reshape(-1, 3), lay.axis_z)
    pth, pr = pth.reshape(K, J), pr.reshape(K, J)
    # Cell of each vertex: curve row from its level, point column from its angle on that row.
    i = np.clip(np.searchsorted(-lay.heights, -lay.level(th, y)) - 1, 0, K - 2)
    rows = np.stack([i, i + 1])
    hit = model.status == 0
    # Openings reach a grid step past their filled points (nostrils are wider than one ray).
    near_fill = ~hit
    near_fill[1:] |= ~hit[:-1]
    near_fill[:-1] |= ~hit[1:]
    near_fill[:, 1:] |= near_fill[:, :-1].copy()
    near_fill[:, :-1] |= near_fill[:, 1:].copy()
    j = np.empty((2, len(th)), np.int64)
    for a in range(2):
        pt = pth[rows[a]]
        j[a] = np.clip((pt < th[:, None]).sum(axis=1) - 1, 0, J - 2)
    corners = [(rows[a], j[a] + b) for a in range(2) for b in range(2)]
    filled = np.zeros(len(th), bool)
    rmin = np.full(len(th), np.inf)
    for ci, cj in corners:
        filled |= near_fill[ci, cj]
        rmin = np.where(hit[ci, cj], np.minimum(rmin, pr[ci, cj]), rmin)
    return filled & (r < rmin - depth)


def seam_jump_deg(model: FaceModel, assembly=None, sub_v=4) -> float:
    """Largest angle (deg) between the surface normals above and below a curve."""
    assembly = assembly or model.assembly
    kn = tuple(float(x) for x in model.knots)
    J = model.layout.n_points
    N1 = model.coefficients.shape[1]
    Xv = surface_grid(model, 1, sub_v, assembly, deriv=(0, 1))  # rows are the curves
    # d/du at the curves from each side: the surface operator with one-sided slope matrices.
    br = model.layout.breaks()
    plain = surface_operator(kn, J, N1 - 1, float(model.a), float(model.remainder_w), 1, sub_v, assembly)
    sides = []
    for side in (0, 1):
        op = SurfaceOperator(np.stack([knot_slopes(kn, model.a * m, assembly, br)[side] for m in range(N1)]),
                             plain.cos_nv, knot_slopes(kn, model.remainder_w, assembly, br)[side], plain.remainder_v)
        n = np.cross(op.apply(model.coefficients, model.residual), Xv)
        sides.append(n / np.maximum(np.linalg.norm(n, axis=2, keepdims=True), 1e-300))
    cosang = np.einsum("kvc,kvc->kv", sides[0], sides[1])[1:-1]
    return float(degrees_from_cos(cosang).max()) if cosang.size else 0.0


def _normal_deviation(nearest, normals, npde, Tp):
    """Angles (deg) between ``normals`` and the PDE normal at the nearest surface points
    (a :meth:`ClosestPoint.query` result)."""
    _, tri, bary, _ = nearest
    n_at = np.einsum("pk,pkc->pc", bary, npde[Tp[tri]])
    n_at /= np.maximum(np.linalg.norm(n_at, axis=1, keepdims=True), 1e-300)
    cos = np.einsum("pc,pc->p", n_at, normals)
    # The grid's orientation is fixed by the layout, so align it with the scan's once.
    if np.median(cos) < 0:
        cos = -cos
    return degrees_from_cos(cos)


def weighted_percentile(x, weights, q) -> float:
    """The ``q``-th percentile of ``x`` where each value counts with its weight (e.g. skin area)."""
    if len(x) == 0:
        return float("nan")
    o = np.argsort(x)
    cw = np.cumsum(np.asarray(weights, np.float64)[o])
    return float(np.asarray(x)[o][min(np.searchsorted(cw, q / 100.0 * cw[-1]), len(o) - 1)])


def _profiles(model, Vf, T, Vp, Tp, n=60):
    """Three cut sections through scan and PDE surface (the method's validation)."""
    lay = model.layout
    eye_y = model.features[[4, 5, 6, 7], 1].mean()
    mid_y = 0.5 * (eye_y + model.features[12, 1])
    h_mid = np.interp(mid_y, lay.heights[::-1], lay.half_angles[::-1])
    th_off = 0.5 * np.interp(eye_y, lay.heights[::-1], lay.half_angles[::-1])
    s = np.linspace(0, 1, n)
    cuts = {
        "horizontal": (-0.85 * h_mid + 1.7 * h_mid * s, np.full(n, mid_y)),
        "vertical": (np.full(n, th_off), lay.heights[1] + (lay.heights[-2] - lay.heights[1]) * s),
        "diagonal": (-0.7 * h_mid + 1.4 * h_mid * s, lay.heights[2] + (lay.heights[-3] - lay.heights[2]) * s),
    }
    out = {}
    for name, (th, y) in cuts.items():
        r_scan = cast_cylinder_rays(Vf, T, lay.axis_z, th, y)[0]
        r_pde = cast_cylinder_rays(Vp, Tp, lay.axis_z, th, y)[0]
        out[name] = (th, y, r_scan, r_pde)
    return out


def accuracy_report(model: FaceModel, scan_vertices, scan_triangles, assembly=None,
                    profiles_png=None, profiles_csv=None) -> dict:
    """Compare the PDE surface of ``model`` with the scan it came from.

    Parameters
    ----------
    model : FaceModel
    scan_vertices : (n, 3) array
        The scan in its own space (the model's frame maps it).
    scan_triangles : (t, 3) int array
        The scan's triangles. Only its skin counts: the connected pieces at the
        model's feature points (eyeballs, lashes, teeth and other separate parts
        of a full head are left out), so every caller measures the same thing.
    assembly : str, optional
    profiles_png, profiles_csv : path, optional
        Where to write the three cut profiles (scan black, PDE red; below them
        the difference ×10 in blue around a grey zero line, ±1 mm marks).

    Returns
    -------
    dict
        ``mean_mm``, ``p95_mm``, ``max_mm`` over the visible band vertices
        (``n_visible``); ``normal_p95_deg``, the 95th percentile by skin area
        of the angle between each visible scan triangle's normal and the PDE
        normal nearest its centre, and ``normal_p95_vertex_deg``, the same
        from vertex normals counted per vertex; ``n_occluded``,
        ``occluded_mean_mm``, ``occluded_max_mm`` and the same for
        ``oblique`` (see :func:`band_vertices`); ``seam_max_deg``;
        ``assembly``.
    """
    assembly = assembly or model.assembly
    Vf = model.frame.to_face(scan_vertices)
    T_all = np.asarray(scan_triangles, dtype=np.int64)
    T = skin_triangles(Vf, T_all, model.features)
    su, sv = REPORT_RESOLUTION
    X = surface_grid(model, su, sv, assembly)
    nu, nv, _ = X.shape
    Vp = X.reshape(-1, 3)
    Q = grid_faces(nu, nv)
    Tp = np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])
    cls = band_vertices(model, Vf, T, T_all)  # eyeballs and teeth hide what is behind them
    visible = cls["visible"]
    cp = ClosestPoint(Vp, Tp)
    nearest = cp.query(Vf[visible])
    d = nearest[0]
    others = {k: cp.query(Vf[cls[k]])[0] if cls[k].any() else np.zeros(0) for k in ("occluded", "oblique")}
    # Normal deviation over the skin's area: each visible scan triangle's own normal (a
    # vertex normal averages across creases) against the PDE normal nearest its centre.
    Xu = surface_grid(model, su, sv, assembly, deriv=(1, 0)).reshape(-1, 3)
    Xv = surface_grid(model, su, sv, assembly, deriv=(0, 1)).reshape(-1, 3)
    npde = unit_rows(np.cross(Xu, Xv))
    Ts = T[visible[T].all(axis=1)]
    nscan = triangle_cross(Vf, Ts)
    area = 0.5 * np.linalg.norm(nscan, axis=1)
    nscan = unit_rows(nscan)
    ang = _normal_deviation(cp.query(Vf[Ts].mean(axis=1)), nscan, npde, Tp)
    ang_vertex = _normal_deviation(nearest, vertex_normals(Vf, T)[visible], npde, Tp)
    result = {
        "assembly": assembly,
        "mean_mm": float(d.mean()), "p95_mm": float(np.percentile(d, 95)), "max_mm": float(d.max()),
        "n_visible": int(visible.sum()),
        "normal_p95_deg": weighted_percentile(ang, area, 95),
        "normal_p95_vertex_deg": float(np.percentile(ang_vertex, 95)),
        "seam_max_deg": seam_jump_deg(model, assembly),
    }
    for k, dk in others.items():
        result[f"n_{k}"] = int(len(dk))
        result[f"{k}_mean_mm"] = float(dk.mean()) if len(dk) else 0.0
        result[f"{k}_max_mm"] = float(dk.max()) if len(dk) else 0.0
    if profiles_png or profiles_csv:

        prof = _profiles(model, Vf, T, Vp, Tp)
        if profiles_csv:
            write_profiles_csv(profiles_csv, prof)
        if profiles_png:
            write_profiles_png(profiles_png, prof)
    return result

