import numpy as np
import pytest
from pdeface.errors import LayoutError
from pdeface.surface.curves import BEYOND, CAVITY, HIT, MISS, CurveSampler, place_samples
from pdeface.surface.frame import face_frame
from pdeface.surface.layout import DEFAULT_CURVES, CurveLayout, place_curves


@pytest.fixture(scope="module")
def face_space(scan):
    mesh, T, idx = scan
    frame = face_frame(mesh.vertices[idx], "cm")
    return frame.to_face(mesh.vertices), T, frame.to_face(mesh.vertices[idx])


def test_layout_from_landmarks(face_space):
    _, _, Lf = face_space
    lay = place_curves(Lf)
    assert lay.n_curves == DEFAULT_CURVES and lay.n_points == 37
    h = lay.heights
    assert (np.diff(h) < 0).all()  # forehead to chin
    assert h[0] > Lf[17:27, 1].max() and h[-1] < Lf[57, 1]
    gaps = -np.diff(h)
    # denser at eyes and lips than on the forehead
    at = lambda y: gaps[np.argmin(np.abs(h[:-1] - y))]  # noqa: E731
    assert at(Lf[36:48, 1].mean()) < 0.6 * gaps[0]
    assert at(Lf[[62, 66], 1].mean()) < 0.6 * gaps[0]
    assert (lay.half_angles > 0).all() and (lay.half_angles < np.pi / 2).all()
    back = CurveLayout.from_array(lay.as_array(), lay.n_curves)
    np.testing.assert_allclose(back.angles(), lay.angles())


def _opening(lay, name):
    """(a, k, line) of the opening whose top anchor line starts from landmark group ``name``."""
    from pdeface.surface.layout import FEATURE_LINES

    a = list(FEATURE_LINES).index(name)  # lines are made in FEATURE_LINES' order
    line = lay.lines[a]
    return next((aa, k) for aa, k in lay.opening_curves() if aa == line.anchor) + (line,)


def test_curves_follow_the_lips(face_space):
    """A curve on each side of the mouth line and of the eye line; every other curve keeps clear of
    the mouth line."""
    from pdeface.geometry import cylinder_coords
    from pdeface.surface.layout import OPENING_GAPS

    _, _, Lf = face_space
    lay = place_curves(Lf)
    mouth, eye = Lf[[62, 66], 1].mean(), Lf[36:48, 1].mean()
    g, ge = 0.5 * OPENING_GAPS["mouth_top"], 0.5 * OPENING_GAPS["lid_top"]
    assert [lay.anchors[ln.anchor] for ln in lay.lines] == [
        eye + ge, eye - ge, Lf[33, 1], Lf[51, 1], mouth + g, mouth - g, Lf[57, 1]]
    assert len(lay.openings) == 2 and len(lay.breaks()) == 2
    for a, k in lay.opening_curves():
        assert lay.heights[k] == lay.anchors[a] and lay.heights[k + 1] == lay.anchors[a + 1]
    a, k, line = _opening(lay, "mouth_top")
    th, H = lay.angles(), lay.ray_heights()
    corners = cylinder_coords(Lf[[60, 64]], lay.axis_z)[0]
    inner = (th > corners.min()) & (th < corners.max())
    gap = np.abs(H - line.pull(th.ravel(), 0.0).reshape(th.shape) + g)
    others = np.ones(lay.n_curves, bool)
    others[[k, k + 1]] = False
    assert gap[others][inner[others]].min() > 0.3
    assert gap[[k, k + 1]][inner[[k, k + 1]]].max() < 2 * g  # the pair sits on it
    # the level inverts the bend, and straight layouts have none
    np.testing.assert_allclose(lay.level(th, H).reshape(H.shape), np.broadcast_to(lay.heights[:, None], H.shape), atol=1e-9)
    flat = place_curves(Lf, follow_lips=False)
    np.testing.assert_array_equal(flat.ray_heights(), np.repeat(flat.heights[:, None], flat.n_points, 1))
    assert not flat.lines and not flat.breaks() and len(flat.as_array()) == 3 + 2 * flat.n_curves
    back = CurveLayout.from_array(lay.as_array(), lay.n_curves)
    np.testing.assert_allclose(back.ray_heights(), H, atol=1e-12)
    assert back.openings == lay.openings and back.breaks() == lay.breaks()
    with pytest.raises(LayoutError, match="cut short|malformed"):
        CurveLayout.from_array(lay.as_array()[:-4], lay.n_curves)
    with pytest.raises(LayoutError, match="openings are malformed"):
        CurveLayout.from_array(np.r_[lay.as_array()[:-1], 99], lay.n_curves)
    with pytest.raises(LayoutError, match="needs at least"):
        CurveLayout.from_array(lay.as_array()[:20], lay.n_curves)


@pytest.mark.parametrize("opening", ["mouth_top", "lid_top"])
def test_opening_curves_lie_on_the_rims(face_space, opening):
    """Fitted to the mesh, each pair runs along the rims of its lips or lids: each ray still meets its
    own lip or lid facing the viewer, and a step past it towards the opening leaves that skin."""
    from pdeface.geometry import cast_cylinder_rays, cylinder_coords
    from pdeface.surface.rims import FACING_MIN_COS, RIM_JUMP_MM, RIM_STEP_MM, follow_rims

    V, T, Lf = face_space
    seed = place_curves(Lf)
    lay = follow_rims(seed, V, T)
    _, k, _ = _opening(lay, opening)
    th, H = lay.angles()[k], lay.ray_heights()
    # well inside the corners: the middle half of the mouth, or of each eye
    corners = cylinder_coords(Lf[[48, 54] if opening == "mouth_top" else [36, 39, 42, 45]], lay.axis_z)[0]
    middle = np.zeros(len(th), bool)
    for lo, hi in zip(corners[0::2], corners[1::2]):
        middle |= np.abs(th - 0.5 * (lo + hi)) < 0.25 * abs(hi - lo)
    assert middle.sum() >= 2
    for row, step in ((k, -RIM_STEP_MM), (k + 1, RIM_STEP_MM)):
        ys = H[row, middle]
        r0, _, _, f0 = cast_cylinder_rays(V, T, lay.axis_z, th[middle], ys)
        r1, _, _, f1 = cast_cylinder_rays(V, T, lay.axis_z, th[middle], ys + step)
        assert (f0 >= FACING_MIN_COS).all()
        past = ~np.isfinite(r1) | (f1 < FACING_MIN_COS) | (np.abs(r1 - r0) > RIM_JUMP_MM)
        assert past.all()
    assert (H[k, middle] - H[k + 1, middle]).min() > 0.3  # the opening between the rims is open
    np.testing.assert_array_equal(lay.heights, seed.heights)  # only the pairs' lines moved


def test_crowded_anchors_are_kept_apart():
    """Where lines converge, heights move the least (least squares) that keeps every gap; others stay."""
    from pdeface.surface.layout import _keep_apart

    gaps = np.array([1.0, 0.1, 1.0])
    Y = np.array([[10.0, 5.0], [5.0, 5.2], [4.0, 5.1], [0.0, 5.0]])  # column 1: all four crowd
    out = _keep_apart(Y, gaps)
    np.testing.assert_array_equal(out[:, 0], Y[:, 0])
    assert (-np.diff(out[:, 1]) >= gaps - 1e-12).all()
    assert out[:, 1].mean() == pytest.approx(Y[:, 1].mean())  # pooled around the middle
    # no other order-keeping heights lie closer
    from itertools import product
    best = min(np.sum((np.array(z) - Y[:, 1]) ** 2) for z in product(*[np.linspace(v - 1.2, v + 1.2, 25) for v in Y[:, 1]])
               if (-np.diff(z) >= gaps - 1e-9).all())
    assert np.sum((out[:, 1] - Y[:, 1]) ** 2) <= best + 1e-9


def test_rims_need_a_layout_from_place_curves(face_space):
    from pdeface.surface.rims import follow_rims

    V, T, Lf = face_space
    lay = place_curves(Lf)
    lay.openings = lay.openings[:1]
    with pytest.raises(LayoutError, match="openings"):
        follow_rims(lay, V, T)


def test_layout_count_is_configurable_and_checked(face_space):
    _, _, Lf = face_space
    assert place_curves(Lf, 19, 21).angles().shape == (19, 21)
    with pytest.raises(LayoutError, match="3 curves; a face has 4 to"):
        place_curves(Lf, 3)
    with pytest.raises(LayoutError, match="2000 points per curve; a face has 7 to"):
        place_curves(Lf, 34, 2000)  # a face needs nothing like it: refused before anything is allocated
    with pytest.raises(LayoutError, match="not in face order"):
        place_curves(Lf * np.array([1, -1, 1]))  # upside down
    collapsed = Lf.copy()
    collapsed[49:54] = Lf[51]  # the upper lip's edge squashed into one point
    with pytest.raises(LayoutError, match="lip_upper landmarks do not run across the face"):
        place_curves(collapsed)
    assert not place_curves(collapsed, follow_lips=False).lines  # straight curves do not need them


def test_samples_are_material_points_exact_on_same_topology(face_space, rng):
    V, T, Lf = face_space
    s = place_samples(V, T, place_curves(Lf))
    P = s.sample(V)
    hit = s.status == HIT
    # hits lie on their rays: same height as their curve, on the mesh surface
    lay = place_curves(Lf)
    np.testing.assert_allclose(P[..., 1][hit], lay.ray_heights()[hit], atol=1e-9)
    # any deformation of the same mesh is read exactly and linearly
    D = rng.normal(size=V.shape)
    np.testing.assert_allclose(s.sample(V + 0.3 * D), P + 0.3 * s.sample(D), atol=1e-9)
    with pytest.raises(LayoutError, match="vertices"):
        s.sample(V[:-1])


def test_eye_openings_are_detected_and_filled(face_space):
    V, T, Lf = face_space
    lay = place_curves(Lf)
    s = place_samples(V, T, lay)
    assert (s.status == MISS).sum() >= 4  # the face region has holes at the eyes
    P = s.sample(V)
    bad = np.argwhere(s.status != HIT)
    # filled points lie within their neighbours' range: no garbage spikes
    for i, j in bad:
        nb = P[max(i - 1, 0):i + 2, max(j - 1, 0):j + 2].reshape(-1, 3)
        assert np.all(P[i, j] >= nb.min(0) - 1e-9) and np.all(P[i, j] <= nb.max(0) + 1e-9)
    eye_rows = np.unique(bad[:, 0])
    assert np.any(np.abs(lay.heights[eye_rows] - Lf[36:48, 1].mean()) < 6)


def test_pocket_behind_an_opening_is_a_cavity(face_space):
    V, T, Lf = face_space
    lay = place_curves(Lf)
    # close the eye openings from behind with a plate 25 mm deep: rays now hit it
    eye = Lf[36:42].mean(0)
    x, y = np.meshgrid(np.linspace(-20, 20, 9) + eye[0], np.linspace(-12, 12, 7) + eye[1])
    plate = np.stack([x.ravel(), y.ravel(), np.full(x.size, eye[2] - 25)], 1)
    n0 = len(V)
    quads = [[n0 + r * 9 + c, n0 + r * 9 + c + 1, n0 + (r + 1) * 9 + c + 1, n0 + (r + 1) * 9 + c]
             for r in range(6) for c in range(8)]
    Tp = np.array([[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads])
    s = place_samples(np.vstack([V, plate]), np.vstack([T, Tp]), lay)
    assert (s.status == CAVITY).sum() >= 2
    plain = place_samples(V, T, lay)
    assert ((s.status != HIT) == (plain.status != HIT)).mean() > 0.99


def test_missing_face_is_a_clear_error(face_space):
    V, T, Lf = face_space
    with pytest.raises(LayoutError, match="landed on the face"):
        place_samples(V + np.array([0, 0, -500.0]), T, place_curves(Lf))


def test_deep_set_eye_corners_are_skin_not_pockets(scan):
    # An ICT face with deep-set eyes (identity modes mixed; mode 3 at +2.2 sigma): its inner eye
    # corners lie 12-16 mm below their neighbours, shallower than any opening's pocket.
    from pdeface.assets import load_ict_shapes
    from pdeface.surface.fit import fit_face, skin_triangles
    from pdeface.surface.report import accuracy_report
    mesh, T, idx = scan
    shapes = load_ict_shapes()
    z = [-0.3, -0.9, 0.16, 2.24, -0.83, -0.62, 0.21, 0.49, -0.18, -0.21,
         0.7, 0.52, -1.03, -0.08, 0.04, -1.05, 0.26, -0.86, 0.97, 0.19]
    V = mesh.vertices + sum(w * shapes[f"identity{i:03d}"] for i, w in enumerate(z))
    model, _ = fit_face(V, T, V[idx], unit="cm")
    Vf = model.frame.to_face(V)
    eyes = place_samples(Vf, skin_triangles(V, T, V[idx]), model.layout, cavity_depth=12.0)
    rims = [k + d for k in model.layout.breaks()[:1] for d in (0, 1)]
    assert (eyes.status[rims] == CAVITY).sum() >= 4  # the old 12 mm rule filled the corners over
    assert (model.status[rims] == CAVITY).sum() == 0
    assert accuracy_report(model, V, T)["max_mm"] < 3.0  # 3.9 mm when they were filled


def test_points_beyond_the_mesh_edge_carry_on_its_slope():
    """A ramp (value = row) known on rows 3-9 and at all but one point: the hole inside is filled
    harmonically (exact for a ramp); the rows beyond the edge carry on falling, evenly, instead of staying
    flat (the harmonic fill) or bunching up at the border (the graph Laplacian squared)."""
    from pdeface.surface.curves import _fill_weights, beyond_edge

    K, J = 10, 8
    valid = np.ones((K, J), bool)
    valid[:3] = False
    valid[6, 3] = False
    ramp = np.repeat(np.arange(K, dtype=float)[:, None], J, 1)
    beyond = beyond_edge(~valid)
    assert beyond[:3].all() and not beyond[3:].any()  # the hole inside is not beyond the edge
    flat = (_fill_weights(valid) @ np.where(valid, ramp, 0).ravel()).reshape(K, J)
    out = (_fill_weights(valid, beyond) @ np.where(valid, ramp, 0).ravel()).reshape(K, J)
    np.testing.assert_allclose(flat[:3], 3.0)  # harmonic: a ledge
    np.testing.assert_allclose(out[:3], ramp[:3], atol=1e-9)  # extrapolated: the ramp itself, step for step
    np.testing.assert_allclose(out[6, 3], 6.0)
    np.testing.assert_allclose(out[3:], np.where(valid, ramp, out)[3:])  # known points stay


def test_curves_mostly_beyond_the_edge_are_named():
    status = np.full((4, 6), HIT)
    status[0, :4] = BEYOND  # 4 of 6
    status[2, :3] = BEYOND  # half: not more than half
    status[3, 0] = MISS
    sampler = CurveSampler(None, status, status.shape)
    assert sampler.beyond_curves().tolist() == [0] and sampler.beyond_curves(0.4).tolist() == [0, 2]
    assert sampler.summary()["beyond the edge"] == 7


def test_twin_triangles_give_the_outward_hit():
    """A wall in front of the axis, each triangle doubled on the same vertices wound the other way (as vertex
    clustering leaves them): the ray takes the outward-facing twin, whichever comes first in the list."""
    from pdeface.geometry import cast_cylinder_rays

    V = np.array([[-5.0, -5, 10], [5, -5, 10], [5, 5, 10], [-5, 5, 10]])
    out = np.array([[0, 1, 2], [0, 2, 3]])  # facing +z, away from the axis at z = 0
    for T in (np.concatenate([out, out[:, ::-1]]), np.concatenate([out[:, ::-1], out])):
        r, tri, _, facing = cast_cylinder_rays(V, T, 0.0, np.zeros(3), np.array([-2.0, 0.5, 3.0]))
        np.testing.assert_allclose(r, 10.0)
        assert np.all(facing > 0)  # the reversed twin would face the axis (facing < 0)


def test_a_corner_beyond_the_edge_carries_on_a_tilted_plane():
    """Known on a ragged region (a corner and a side missing, as the MediaPipe face's temples): the points
    beyond the edge continue any plane exactly, in both grid directions, with their spacing."""
    from pdeface.surface.curves import _fill_weights, beyond_edge

    K, J = 9, 11
    rows, cols = np.mgrid[0:K, 0:J].astype(float)
    plane = 2.0 * rows - 0.7 * cols + 3.0
    valid = np.ones((K, J), bool)
    valid[:2, :4] = False  # a corner
    valid[:, -1] = False  # the last column, as beyond the cheek
    valid[0] = False  # the top row
    beyond = beyond_edge(~valid)
    assert beyond.sum() == (~valid).sum()
    out = (_fill_weights(valid, beyond) @ np.where(valid, plane, 0).ravel()).reshape(K, J)
    np.testing.assert_allclose(out, plane, atol=1e-9)


def test_a_groove_narrower_than_the_points_is_drawn_to_its_neighbours_chord(face_space, rng):
    """The nose band's alar grooves: a hit 4-5 mm below the chord of its neighbours on the curve made a V the
    surface turned through by 30-40°. With ``groove_depth`` such a hit (between two hits) is drawn to that depth
    below the chord, as a fixed mix of the three points (still read exactly and linearly off any pose), and
    only there."""
    from pdeface.geometry import cylinder_coords
    from pdeface.surface.curves import NOSE_GROOVE_MM, groove_depths, nose_band

    V, T, Lf = face_space
    lay = place_curves(Lf)
    free = place_samples(V, T, lay)
    limited = place_samples(V, T, lay, groove_depth=groove_depths(lay, Lf))
    radius = lambda P: cylinder_coords(P.reshape(-1, 3), lay.axis_z)[2].reshape(P.shape[:2])  # noqa: E731
    r0, r1 = radius(free.sample(V)), radius(limited.sample(V))
    below = lambda r: 0.5 * (r[:, :-2] + r[:, 2:]) - r[:, 1:-1]  # noqa: E731
    band = nose_band(lay, Lf)[:, 1:-1]
    hits = free.status == HIT
    deep = band & (below(r0) > NOSE_GROOVE_MM) & hits[:, 1:-1] & hits[:, :-2] & hits[:, 2:]
    assert deep.sum() >= 4  # measured 6: the alar grooves, both sides (beside a nostril's pocket it is left)
    assert below(r1)[deep].max() < NOSE_GROOVE_MM + 0.3  # now at the limit (the neighbours may move too)
    moved = np.linalg.norm(limited.sample(V) - free.sample(V), axis=-1) > 1e-9
    assert moved.sum() == deep.sum() and nose_band(lay, Lf)[moved].all()
    D = rng.normal(size=V.shape)
    np.testing.assert_allclose(limited.sample(V + 0.3 * D), limited.sample(V) + 0.3 * limited.sample(D), atol=1e-9)
