import numpy as np
import pytest
from pdeface.errors import LayoutError
from pdeface.surface.fourier import fit_fourier
from pdeface.surface.pde import (
    BREAK_SLOPE,
    _taylor_table,
    knot_slopes,
    merged_operator,
    mode_operator,
    mode_values,
    ode_bases,
    ode_basis,
    output_grid,
    solve_surface,
    subdivide,
)

T01 = np.linspace(0, 1, 11)


@pytest.mark.parametrize("kappa", [0.0, 1e-12, 0.4, 0.999, 1.0, 3.0, 40.0, 700.0, 1e5])
def test_basis_solves_the_ode_and_never_overflows(kappa):
    f = [ode_basis(kappa, T01, d) for d in range(4)]
    assert all(np.isfinite(x).all() for x in f)
    assert np.abs(f[0]).max() <= 1.6  # bounded for any kappa
    # (D² - κ²)² f = f'''' - 2κ² f'' + κ⁴ f = 0, with f'''' by central differences of f'''
    h = 1e-6
    t = np.linspace(0.1, 0.9, 5)
    d4 = (ode_basis(kappa, t + h, 3) - ode_basis(kappa, t - h, 3)) / (2 * h)
    res = d4 - 2 * kappa ** 2 * ode_basis(kappa, t, 2) + kappa ** 4 * ode_basis(kappa, t, 0)
    scale = max(1.0, np.abs(d4).max())
    assert np.abs(res).max() / scale < 1e-6
    # derivatives are consistent
    d1 = (ode_basis(kappa, t + h, 0) - ode_basis(kappa, t - h, 0)) / (2 * h)
    np.testing.assert_allclose(d1, ode_basis(kappa, t, 1), atol=1e-6 * max(1, np.abs(d1).max()))


def test_both_basis_forms_span_the_same_space():
    # interpolating the same 4 values with the Taylor form and the exponential form gives one function
    kappa, tk = 1.7, np.array([0.0, 0.3, 0.7, 1.0])
    y = np.array([1.0, -2.0, 0.5, 3.0])
    taylor = _taylor_table(kappa, 0)
    a = taylor(T01) @ np.linalg.solve(taylor(tk), y)
    b = ode_basis(kappa, T01) @ np.linalg.solve(ode_basis(kappa, tk), y)
    np.testing.assert_allclose(a, b, atol=1e-10)


def test_zero_wavenumber_is_the_cubic_spline():
    u = np.sort(np.r_[0, np.random.default_rng(0).random(9), 1])
    y = u ** 3 - 2 * u + 1
    M = mode_operator(tuple(u), 0.0, 5)
    g = output_grid(u, 5, 5, 1)
    np.testing.assert_allclose(M @ y, g.u ** 3 - 2 * g.u + 1, atol=1e-10)


@pytest.mark.parametrize("assembly", ["smooth", "patches"])
@pytest.mark.parametrize("k", [0.0, 2.0, 60.0, 5000.0])
def test_interpolates_every_curve(assembly, k):
    kn = tuple(np.linspace(0, 1, 13) ** 1.3)
    M = mode_operator(kn, k, 4, assembly)
    np.testing.assert_allclose(M[::4], np.eye(13), atol=1e-9)


@pytest.mark.parametrize("k", [0.0, 3.0, 60.0])
def test_a_break_keeps_its_tangents_and_parts_the_two_sides(k):
    """Across a break the surface keeps its tangent direction (no crease; the break piece's u-slope is
    BREAK_SLOPE of the runs', so it cannot loop where the rims nearly meet), but the curves below it no
    longer pull the pieces above it."""
    kn = tuple(np.cumsum(np.r_[0, 1, 1, 1, 1, 1, 0.05, 1, 1, 1, 1]) / 9.05)
    b = 6  # the short interval between curves 6 and 7 (two rims of a slit)
    M = mode_operator(kn, k, 4, "smooth", 0, (b,))
    np.testing.assert_allclose(M[::4], np.eye(11), atol=1e-9)  # still through every curve
    above, below = knot_slopes(kn, k, "smooth", (b,))
    rest = np.r_[:b, b + 2:11]
    np.testing.assert_allclose(above[rest], below[rest], atol=1e-9)  # no crease elsewhere
    np.testing.assert_allclose(below[b], BREAK_SLOPE * above[b], atol=1e-9)  # into the break piece
    np.testing.assert_allclose(above[b + 1], BREAK_SLOPE * below[b + 1], atol=1e-9)  # and out of it
    assert np.abs(M[:4 * b, b + 1:]).max() < 1e-12  # above the break: only curves 0..b
    assert np.abs(M[4 * (b + 1):, :b]).max() < 1e-12  # below it: only curves b+1..
    # one side still; the other moves along u: without the break the motion leaks across the slit
    u = output_grid(np.array(kn), 5, 4, 1).u
    moved = np.where(np.arange(11) > b, np.array(kn), 0.0)
    if k < 10:  # (high modes damp it within an interval anyway)
        assert np.abs((mode_operator(kn, k, 4, "smooth") @ moved)[:4 * b + 1]).max() > 1e-3
    assert np.abs((M @ moved)[:4 * b + 1]).max() < 1e-12
    if k == 0.0:  # each side is its own not-a-knot spline, which reproduces the line exactly
        np.testing.assert_allclose((M @ moved)[4 * (b + 1):], u[4 * (b + 1):], atol=1e-12)
    with pytest.raises(LayoutError, match="at least 3 curve intervals"):
        mode_operator(kn, k, 4, "smooth", 0, (1,))


@pytest.mark.parametrize("deriv", [0, 1])
def test_mode_values_anywhere_match_the_output_rows(deriv):
    kn = tuple(np.cumsum(np.r_[0, 1, 1, 1, 1, 1, 0.05, 1, 1, 1, 1]) / 9.05)
    u = output_grid(np.array(kn), 5, 4, 1).u
    for breaks in ((), (6,)):
        np.testing.assert_allclose(mode_values(kn, 2.0, u, deriv, breaks), mode_operator(kn, 2.0, 4, "smooth", deriv,
                                                                                        breaks), atol=1e-9)


def test_a_confined_break_applies_only_where_its_weight_is_one():
    """Where the weight is 0 the surface is the one with the rim pair merged into their mean curve: C2 across,
    no break piece (beyond an opening's corners); where it is 1, the break's; linear in the curves either way."""
    kn = tuple(np.cumsum(np.r_[0, 1, 1, 1, 1, 1, 0.05, 1, 1, 1, 1]) / 9.05)
    rng = np.random.default_rng(3)
    K, J, N = 11, 9, 3
    C, R = rng.normal(size=(K, N + 1, 3)), np.zeros((K, J, 3))
    n_v = (J - 1) * 2 + 1
    weight = np.r_[np.ones(8), np.zeros(n_v - 8)]
    confine = ((6, weight, np.zeros(n_v)),)
    X = solve_surface(C, R, kn, 1.0, None, 4, 2, "smooth", (0, 0), (6,))
    Y = solve_surface(C, R, kn, 1.0, None, 4, 2, "smooth", (0, 0), (6,), BREAK_SLOPE, confine)
    M = merged_operator(kn, J, N, 1.0, 4.0, 4, 2, (0, 0), (6,), 6).apply(C, R)
    np.testing.assert_allclose(Y[:, :8], X[:, :8], atol=1e-12)
    np.testing.assert_allclose(Y[:, 8:], M[:, 8:], atol=1e-12)
    merged_knot = 0.5 * (kn[6] + kn[7])
    mean_curve = mode_values((*kn[:6], merged_knot, *kn[8:]), 0.0, np.array([merged_knot]))  # passes the mean
    assert mean_curve.shape == (1, 10) and abs(mean_curve[0, 6] - 1) < 1e-9
    Y2 = solve_surface(2 * C, R, kn, 1.0, None, 4, 2, "smooth", (0, 0), (6,), BREAK_SLOPE, confine)
    np.testing.assert_allclose(Y2, 2 * Y, atol=1e-9)


def test_a_confined_surface_is_one_operator_with_the_blend_and_its_v_derivative():
    """The blend X + (1 - w)(M - X) is built into one operator; its v-derivative carries the product rule,
    so it matches a finite difference of the blended surface along v (residual included)."""
    kn = tuple(np.cumsum(np.r_[0, 1, 1, 1, 1, 1, 0.05, 1, 1, 1, 1]) / 9.05)
    rng = np.random.default_rng(5)
    K, J, N = 11, 9, 3
    C, R = rng.normal(size=(K, N + 1, 3)), 0.1 * rng.normal(size=(K, J, 3))
    n_v = (J - 1) * 8 + 1
    v = np.linspace(0, np.pi, n_v)
    weight = 0.5 + 0.5 * np.tanh(3 * (v - 1.5))
    confine = ((6, weight, np.gradient(weight, v)),)
    args = (C, R, kn, 1.0, None, 4, 8, "smooth")
    X = solve_surface(*args, (0, 0), (6,))
    M = merged_operator(kn, J, N, 1.0, 4.0, 4, 8, (0, 0), (6,), 6).apply(C, R)
    Y = solve_surface(*args, (0, 0), (6,), BREAK_SLOPE, confine)
    np.testing.assert_allclose(Y, X + (1 - weight)[None, :, None] * (M - X), atol=1e-12)
    Yv = solve_surface(*args, (0, 1), (6,), BREAK_SLOPE, confine)
    fd = np.gradient(Y, v, axis=1)
    inner = slice(2, -2)  # one-sided differences at the ends
    assert np.abs(Yv[:, inner] - fd[:, inner]).max() < 2e-2 * np.abs(Yv).max()
    assert np.abs((1 - weight)[None, inner, None] * (M - X)[:, inner]).max() > 0.1  # the blend matters


def test_smooth_has_no_creases_and_patches_do():
    kn = tuple(np.linspace(0, 1, 10))
    above, below = knot_slopes(kn, 3.0, "smooth")
    np.testing.assert_allclose(above, below, atol=1e-9)
    above, below = knot_slopes(kn, 3.0, "patches")
    jump = np.abs(above - below).max(axis=1)
    assert jump[[3, 6]].min() > 1e-3  # shared curves of the 4-curve patches
    assert jump[[1, 2, 4, 5, 7, 8]].max() < 1e-9  # inside a patch the solution is analytic


def exact_solution(u, v, a):
    """A closed-form solution of (∂u² + a²∂v²)² X = 0 with modes 0, 1, 3."""
    X = np.zeros((len(u), len(v), 3))
    cu = np.cos(np.outer(np.ones_like(u), v))
    X[..., 0] = (1 + 0.5 * u[:, None]) * np.exp(-a * u[:, None]) * cu
    X[..., 1] = (2 - u[:, None] + u[:, None] ** 3)[:, :] * np.ones_like(v)
    X[..., 2] = (0.3 + 2 * u[:, None]) * np.exp(3 * a * (u[:, None] - 1)) * np.cos(3 * v)
    return X


@pytest.mark.parametrize("assembly", ["smooth", "patches"])
@pytest.mark.parametrize("a", [0.5, 1.0, 30.0])
def test_reproduces_an_exact_pde_solution_between_curves(assembly, a):
    knots = np.linspace(0, 1, 10) ** 1.2
    J = 21
    curves = exact_solution(knots, np.linspace(0, np.pi, J), a)
    coef, res = fit_fourier(curves, 5)
    X = solve_surface(coef, res, knots, a=a, sub_u=6, sub_v=2, assembly=assembly)
    g = output_grid(knots, J, 6, 2)
    np.testing.assert_allclose(X, exact_solution(g.u, g.v, a), atol=1e-8)


def test_surface_passes_through_curve_points_with_remainder(rng):
    knots = np.linspace(0, 1, 7)
    P = rng.normal(size=(7, 15, 3))
    coef, res = fit_fourier(P, 5)
    for assembly in ("smooth", "patches"):
        X = solve_surface(coef, res, knots, sub_u=3, sub_v=3, assembly=assembly)
        np.testing.assert_allclose(X[::3, ::3], P, atol=1e-10)


def test_bad_parameters():
    with pytest.raises(LayoutError, match="3m\\+1"):
        mode_operator(tuple(np.linspace(0, 1, 6)), 1.0, 2, "patches")
    with pytest.raises(LayoutError, match="unknown assembly"):
        mode_operator(tuple(np.linspace(0, 1, 7)), 1.0, 2, "spline")
    with pytest.raises(LayoutError, match="increase"):
        mode_operator((0.0, 0.5, 0.5, 1.0), 1.0, 2)
    with pytest.raises(LayoutError, match="a must be > 0"):
        solve_surface(np.zeros((4, 3, 3)), np.zeros((4, 5, 3)), np.linspace(0, 1, 4), a=0)


@pytest.mark.parametrize("deriv", [0, 1])
def test_own_cubic_spline_matches_scipy(deriv):
    from pdeface.surface.pde import cubic_spline_operator
    from scipy.interpolate import CubicSpline
    x = np.sort(np.random.default_rng(3).random(11))
    xe = np.linspace(x[0], x[-1], 40)
    expect = CubicSpline(x, np.eye(11), bc_type="not-a-knot")(xe, deriv)
    np.testing.assert_allclose(cubic_spline_operator(x, xe, deriv), expect, atol=1e-10)


@pytest.mark.parametrize("deriv", [0, 1, 2, 3])
def test_bases_of_many_wavenumbers_are_each_ones(deriv):
    """ode_bases (one batched Taylor sum) is ode_basis per wavenumber, at shared and at per-wavenumber t."""
    kappas = np.array([0.0, 1e-9, 0.2, 0.7, 0.999, 1.0, 4.0, 90.0])
    T = np.random.default_rng(1).random((len(kappas), 6))
    for t, rows in ((T01, [T01] * len(kappas)), (T, T)):
        got = ode_bases(kappas, t, deriv)
        for k, r, g in zip(kappas, rows, got):
            want = ode_basis(k, r, deriv)
            np.testing.assert_allclose(g, want, rtol=1e-12, atol=1e-12 * max(1.0, np.abs(want).max()))


def straightforward_mode_operator(knots, k, steps, deriv, breaks):
    """mode_operator's smooth rows written out: each interval's own basis at its own steps, the last curve
    from the piece above."""
    from pdeface.surface.pde import _smooth_coefficients

    h = np.diff(knots)
    C = _smooth_coefficients(tuple(knots), k, breaks)
    rows = [ode_basis(k * h[i], subdivide([0.0, 1.0], s)[:-1], deriv) / h[i] ** deriv @ C[4 * i:4 * i + 4]
            for i, s in enumerate(steps)]
    rows.append(ode_basis(k * h[-1], np.array([1.0]), deriv) / h[-1] ** deriv @ C[-4:])
    return np.vstack(rows)


@pytest.mark.parametrize("deriv", [0, 1])
def test_smooth_rows_evaluated_together_are_the_straightforward_ones(deriv):
    """The smooth assembly's rows, evaluated for all intervals of a step count at once, equal each interval's
    own evaluation: even and uneven steps, with and without a break, wavenumbers on both sides of 1."""
    kn = tuple(np.cumsum(np.r_[0, 1, 1, 1, 1, 1, 0.05, 1, 1, 1, 1]) / 9.05)
    for k in (0.0, 2.0, 60.0):
        for steps in ((4,) * 10, (2, 3, 5, 4, 4, 7, 1, 2, 6, 3)):
            for breaks in ((), (5,)):
                want = straightforward_mode_operator(np.array(kn), k, steps, deriv, breaks)
                got = mode_operator(kn, k, steps, "smooth", deriv, breaks)
                np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10 * np.abs(want).max())


def straightforward_surface(op, coefficients, residual):
    """A SurfaceOperator's surface (n_u, n_v, c) written out: each block's modes times cos(n v) (its weights
    folded in) plus its remainder's rows times its v spline, summed over the blocks."""
    modes = op.modes if op.modes.ndim == 4 else op.modes[None]
    rem_u = op.remainder_u if op.remainder_u.ndim == 3 else op.remainder_u[None]
    b, n1 = modes.shape[:2]
    J = residual.shape[1]
    X = 0.0
    for k in range(b):
        A = np.einsum("nuk,knc->unc", modes[k], coefficients)  # (n_u, N+1, c): each mode's values on the rows
        X = X + np.einsum("unc,vn->uvc", A, op.cos_nv[:, k * n1:(k + 1) * n1])
        Ru = np.einsum("uk,kjc->ujc", rem_u[k], residual)
        X = X + np.einsum("ujc,vj->uvc", Ru, op.remainder_v[:, k * J:(k + 1) * J])
    return X


def _random_surfaces(rng, m, n):
    """``n`` random surfaces of face ``m``'s layout at random uneven steps: ``(C, R, rows, cols, args, key)``, the
    operators' arguments (less assembly, derivative and breaks) and the confined operator's break key."""
    from pdeface.surface.grid import break_weights

    K, J = len(m.knots), m.layout.n_points
    rows, cols = tuple(rng.integers(1, 6, K - 1)), tuple(rng.integers(1, 6, J - 1))
    C = rng.normal(size=m.coefficients.shape[:2] + (n,))
    R = rng.normal(size=m.residual.shape[:2] + (n,))
    key = tuple((int(b), tuple(w), tuple(s)) for b, w, s in break_weights(m, cols))
    args = (tuple(m.knots), J, C.shape[1] - 1, float(m.a), float(m.remainder_w), rows, cols)
    return C, R, rows, cols, args, key


def test_surface_planes_are_the_straightforward_sums(rng, default_face):
    """SurfaceOperator.planes (and apply, the same as a grid) are the sums written out, for a face with breaks
    confined to its openings and for several surfaces solved together, at uneven steps and for a v-derivative."""
    from pdeface.surface import pde

    m = default_face
    C, R, rows, cols, args, key = _random_surfaces(rng, m, 6)
    for deriv in ((0, 0), (0, 1)):
        for op in (pde.surface_operator(*args, "smooth", deriv, m.layout.breaks()),
                   pde.confined_operator(*args, deriv, m.layout.breaks(), BREAK_SLOPE, key)):
            want = straightforward_surface(op, C, R)
            planes = op.planes(C, R)
            assert planes.shape == (6,) + want.shape[:2]
            np.testing.assert_allclose(planes, np.moveaxis(want, 2, 0), atol=1e-9 * np.abs(want).max())
            np.testing.assert_array_equal(op.apply(C, R), np.moveaxis(planes, 0, 2))



def test_planes_into_kept_buffers_are_the_planes(rng, default_face):
    """planes(..., reuse): the same numbers as fresh planes, written over the last call's buffers (a smaller solve
    after a larger one uses their first rows; a larger one makes new ones)."""
    from pdeface.surface import pde

    m = default_face
    C, R, rows, cols, args, key = _random_surfaces(rng, m, 6)
    op = pde.confined_operator(*args, (0, 0), m.layout.breaks(), BREAK_SLOPE, key)
    reuse = []
    first = op.planes(C, R, reuse)
    np.testing.assert_array_equal(first, op.planes(C, R))
    fewer = op.planes(C[..., :3], R[..., :3], reuse)
    np.testing.assert_array_equal(fewer, op.planes(C[..., :3], R[..., :3]))
    assert np.shares_memory(first, fewer)  # written over the first
    C2, R2 = np.concatenate([C, C], axis=2), np.concatenate([R, R], axis=2)
    more = op.planes(C2, R2, reuse)
    np.testing.assert_array_equal(more, op.planes(C2, R2))
    assert not np.shares_memory(more, first)



def test_wavenumbers_together_are_each_alone(default_face):
    """A surface's modes and remainder evaluated together (one batch of bases, one stacked solve) are, to the bit,
    each wavenumber's alone: the coefficients, the output rows at even and uneven steps (a step count of a single
    interval among them) and the merged surface's values anywhere, on one interval too."""
    from pdeface.surface import pde

    m = default_face
    knots, breaks = tuple(float(x) for x in m.knots), tuple(m.layout.breaks())
    ks = tuple(m.a * n for n in range(m.coefficients.shape[1])) + (m.remainder_w,)
    K = len(knots)
    uneven = tuple(int(s) for s in np.resize([2, 3, 4, 4, 7, 16], K - 1))  # 7 and 16: one interval each
    stack = pde._smooth_coefficient_stack(knots, ks, breaks, BREAK_SLOPE)
    for j, k in enumerate(ks):
        np.testing.assert_array_equal(stack[j], pde._smooth_coefficients(knots, k, breaks, BREAK_SLOPE))
    for sub in (4, uneven):
        for deriv in (0, 1):
            rows = pde.mode_operators(knots, ks, sub, "smooth", deriv, breaks, BREAK_SLOPE)
            for j, k in enumerate(ks):
                np.testing.assert_array_equal(rows[j], mode_operator(knots, k, sub, "smooth", deriv, breaks))
    for u in (np.linspace(0.0, 1.0, 57), np.array([0.37])):
        values = pde.mode_value_stack(knots, ks, u, 1, breaks)
        for j, k in enumerate(ks):
            np.testing.assert_array_equal(values[j], mode_values(knots, k, u, 1, breaks))

def test_subdivide_is_each_interval_cut_alone(rng):
    """subdivide (all intervals at once) gives each interval's start + length * j / steps, the same numbers as
    cutting the intervals one at a time, with one count or one per interval."""
    for _ in range(50):
        params = np.unique(rng.random(rng.integers(2, 30)) * rng.choice([1.0, np.pi, 80.0]))
        if len(params) < 2:
            continue
        steps = rng.integers(1, 17, len(params) - 1)
        for sub in (steps, int(steps[0])):
            each = np.broadcast_to(sub, len(params) - 1)
            alone = [params[i] + (params[i + 1] - params[i]) * np.arange(s) / s for i, s in enumerate(each)]
            np.testing.assert_array_equal(subdivide(params, sub), np.append(np.concatenate(alone), params[-1]))
    with pytest.raises(LayoutError):
        subdivide([0.0, 0.5, 1.0], (2, 0))

def test_surface_at_nodes_is_the_grid_there(rng, default_face):
    """SurfaceOperator.at_nodes (solve_surface's ``nodes``): a scattered subset of the grid's nodes, a grid row
    with one node read, the first and last nodes, every node: the whole grid's values there (to rounding: a node's
    two sums are one), for a confined face and several surfaces at once; bad nodes refused."""
    from pdeface.surface import pde

    m = default_face
    C, R, rows, cols, args, key = _random_surfaces(rng, m, 9)
    for op in (pde.surface_operator(*args, "smooth", (0, 0), m.layout.breaks()),
               pde.confined_operator(*args, (0, 1), m.layout.breaks(), BREAK_SLOPE, key)):
        grid = op.apply(C, R)
        n_u, n_v = grid.shape[:2]
        flat = grid.reshape(n_u * n_v, -1)
        some = np.sort(rng.choice(n_u * n_v, n_u * n_v // 3, replace=False))
        lone = 2 * n_v + 3  # row 2 read at this node alone
        some = np.union1d(np.setdiff1d(some, np.arange(2 * n_v, 3 * n_v)), [0, lone, n_u * n_v - 1])
        for nodes in (some, np.arange(n_u * n_v), np.array([lone])):
            got = op.at_nodes(C, R, nodes)
            assert got.shape == (len(nodes), 9)
            np.testing.assert_allclose(got, flat[nodes], rtol=0, atol=1e-12 * np.abs(flat).max())
        assert op.at_nodes(C, R, np.zeros(0, int)).shape == (0, 9)
        for bad in ([3, 2], [2, 2], [-1, 4], [n_u * n_v]):
            with pytest.raises(LayoutError, match="grid nodes"):
                op.at_nodes(C, R, np.array(bad))
    X = solve_surface(C[..., :3], R[..., :3], m.knots, m.a, m.remainder_w, rows, cols, breaks=m.layout.breaks(),
                      nodes=some)
    full = solve_surface(C[..., :3], R[..., :3], m.knots, m.a, m.remainder_w, rows, cols, breaks=m.layout.breaks())
    np.testing.assert_allclose(X, full.reshape(-1, 3)[some], rtol=0, atol=1e-12 * np.abs(full).max())
