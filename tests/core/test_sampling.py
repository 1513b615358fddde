"""The mesh's resolution: steps per interval, and the default's choice of them for each face (issue #16)."""
import numpy as np
import pytest
from pdeface.errors import MeshError, ModelFormatError
from pdeface.surface import sampling
from pdeface.surface.fit import face_mesh
from pdeface.surface.folds import fold_edges
from pdeface.surface.grid import surface_grid
from pdeface.surface.sampling import (
    known_resolution,
    mesh_resolution,
    parse_resolution,
    remember_resolution,
    resolution_text,
)

from scripts.devset import makehuman


@pytest.fixture(scope="module")
def model(default_face):
    return default_face


def test_steps_per_interval_sample_the_same_surface(model):
    """Uneven steps (the break blends included) put the same surface through the rows and columns they share
    with an even mesh: more steps add points on it, they do not change it."""
    K, J = len(model.knots), model.layout.n_points
    even = surface_grid(model, 4, 4)
    np.testing.assert_allclose(surface_grid(model, (4,) * (K - 1), (4,) * (J - 1)), even, atol=1e-9)
    rows = np.where(np.arange(K - 1) % 3 == 0, 8, 4)  # every third interval twice as fine
    cols = np.where(np.arange(J - 1) % 2 == 0, 8, 4)
    fine = surface_grid(model, rows, cols)
    assert fine.shape == (rows.sum() + 1, cols.sum() + 1, 3)

    def shared(steps):  # the finer mesh's rows (or columns) that the even 4-step mesh has too
        return np.concatenate([start + np.arange(0, s, s // 4) for start, s in zip(np.r_[0, np.cumsum(steps)[:-1]],
                                                                                      steps)] + [[steps.sum()]])
    np.testing.assert_allclose(fine[np.ix_(shared(rows), shared(cols))], even, atol=1e-9)


def test_the_default_adds_steps_where_the_face_creases(model):
    """On even 4 steps, AU18 (lip pucker) turns 12 edges beside the nose wings and lips by more than 30°: the
    surface is smooth there, its mesh is not fine enough (8 steps halve the turn). The default gives those
    intervals more steps and the flat forehead fewer: none over 30°, in fewer vertices than the even mesh."""
    from pdeface.posing import pose_curves
    from pdeface.surface.model import model_landmarks

    rows, cols = mesh_resolution(model)
    assert min(rows[:3]) == 2 and max(rows) >= 6 and max(cols) >= 6  # forehead top 2; nose, lips more
    C, R = pose_curves(model, {"18": 1.0})

    def folds(resolution):
        rest = face_mesh(model, resolution)
        return fold_edges(face_mesh(model, resolution, coefficients=C, residual=R), model.frame,
                          model_landmarks(model), rest=rest)  # a model file keeps some landmarks: the nostrils' are
        # its feature points

    even, finer, default = folds("4,4"), folds("8,8"), folds("default")
    assert even["count"] > 5 and finer["max_deg"] < 0.75 * even["max_deg"]  # measured 12 edges, 33° → 19°
    assert default["count"] == 0 and default["max_deg"] < 25
    assert len(face_mesh(model).vertices) < len(face_mesh(model, "4,4").vertices)  # 17,802 against 19,285


def test_a_model_file_keeps_its_steps(model, tmp_path, monkeypatch):
    """The bundled face carries its steps (build_assets.py); a model saved after they were chosen carries them
    too and reads back without choosing again; other descriptors are another model, chosen for afresh."""
    from pdeface.au.modelfile import load_model, save_model

    steps = known_resolution(model)
    assert steps is not None  # read from the file
    monkeypatch.setattr(sampling, "interval_turns", lambda *a, **k: pytest.fail("chose again"))
    save_model(tmp_path / "m.npz", model)
    assert known_resolution(load_model(tmp_path / "m.npz")) == steps
    monkeypatch.undo()
    fewer = load_model(tmp_path / "m.npz")
    fewer.descriptors = fewer.descriptors[:5]
    assert known_resolution(fewer) is None
    assert mesh_resolution(fewer) != steps  # fewer keys to keep smooth: another choice
    fewer.descriptors = []  # a face just fitted (pdeface demo meshes one): the rest shape alone
    rows, cols = mesh_resolution(fewer)
    assert len(rows) == len(model.knots) - 1 and min(rows) >= sampling.STEPS_RANGE[0]


def test_the_fingerprint_is_every_number_the_choice_reads(model):
    """model_fingerprint (the arrays' bytes read in place) is the same for a copy of the model and differs when one
    number it reads moves by its last bit: a descriptor's residual or coefficient, the rest curves and their
    remainder, the curves' parameters, the feature points, a landmark, the smoothing parameters; or when bytes move
    from one array to the next (a feature point made a landmark)."""
    import copy

    base = sampling.model_fingerprint(model)
    assert sampling.model_fingerprint(copy.deepcopy(model)) == base
    for name in ("a", "w"):  # w: the remainder's own (remainder_w), where a model sets one
        other = copy.deepcopy(model)
        setattr(other, name, np.nextafter(other.a if name == "a" else other.remainder_w, np.inf))
        assert sampling.model_fingerprint(other) != base
    other = copy.deepcopy(model)  # the last feature point made the first landmark: the same bytes in the same order
    other.features, other.landmarks = other.features[:-1], np.concatenate([other.features[-1:], other.landmarks])
    assert sampling.model_fingerprint(other) != base
    for change in (lambda m: m.descriptors[-1].residual, lambda m: m.descriptors[0].coefficients,
                   lambda m: m.coefficients, lambda m: m.residual, lambda m: m.knots, lambda m: m.features,
                   lambda m: m.landmarks):
        other = copy.deepcopy(model)
        a = change(other)
        finite = np.flatnonzero(np.isfinite(a))  # (a landmark the model keeps)
        i = finite[len(finite) // 2]
        a.flat[i] = np.nextafter(a.flat[i], np.inf)
        assert sampling.model_fingerprint(other) != base


def test_the_bundled_steps_are_the_current_choice(model):
    """default_face.npz's steps are what the choice gives now (build_assets.py keeps them current)."""
    sampling._CHOSEN.clear()
    assert sampling.adaptive_resolution(model) == mesh_resolution(model)
    from pdeface.au.modelfile import load_face
    assert known_resolution(load_face("default")) == mesh_resolution(model)


def test_resolutions_as_text_and_their_errors(model, tmp_path):
    rows, cols = mesh_resolution(model)
    assert parse_resolution(resolution_text(rows, cols)) == (rows, cols)
    assert resolution_text(4, 4) == "4,4" and parse_resolution("4,4") == (4, 4)
    assert parse_resolution("default") == "default" and parse_resolution("fine") == (8, 8)
    for bad, match in (("[[1,2],[3", "resolution"), ("4", "rows and columns"), ("[[0],[4]]", "1..64")):
        with pytest.raises(MeshError, match=match):
            parse_resolution(bad)
    with pytest.raises(MeshError, match="curve intervals"):
        mesh_resolution(model, resolution_text(rows[:-1], cols))
    with pytest.raises(MeshError, match="point intervals"):
        remember_resolution(model, rows, cols + (4,))
    import io
    import json

    from pdeface.au.modelfile import model_from_bytes, model_to_bytes
    data = dict(np.load(io.BytesIO(model_to_bytes(model))))
    meta = json.loads(bytes(data["meta"]))
    meta["mesh_steps"] = [[4], [4]]
    data["meta"] = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **data)
    with pytest.raises(ModelFormatError, match="mesh_steps"):
        model_from_bytes(buf.getvalue(), "broken.npz")


def test_the_bundled_face_has_no_fold_in_any_pose(model):
    """What *Add Default Face* and ``pdeface pose default`` mesh: no edge over 30° outside the openings at rest, in
    any AU at weight 1 or any preset (83 poses; largest turn measured 22.7°, AU11)."""
    from pdeface.posing import pose_curves
    from pdeface.presets import every_pose
    from pdeface.surface.model import model_landmarks

    rest, L = face_mesh(model), model_landmarks(model)
    turns = {}
    for name, weights in every_pose(model).items():
        C, R = pose_curves(model, weights) if weights else (None, None)
        r = fold_edges(face_mesh(model, coefficients=C, residual=R), model.frame, L, rest=rest)
        turns[name] = (r["count"], r["max_deg"])
    assert len(turns) == 83 and {k: n for k, (n, _) in turns.items() if n} == {}
    assert max(t for _, t in turns.values()) < 25


def test_a_descriptor_turning_edges_everywhere_is_capped(model):
    """A huge residual in one descriptor (a broken or hostile file) turns edges everywhere: the steps are capped
    to MAX_VERTICES instead of the most everywhere (230,800 vertices), and the rest is chosen as before."""
    import copy

    hostile = copy.deepcopy(model)
    d = hostile.descriptors[0]
    d.residual = d.residual * 1e4 + 50 * np.random.default_rng(0).normal(size=d.residual.shape)
    rows, cols = sampling.adaptive_resolution(hostile)
    assert (sum(rows) + 1) * (sum(cols) + 1) <= sampling.MAX_VERTICES
    K, J = len(model.knots), model.layout.n_points
    lo, hi = sampling.STEPS_RANGE
    turns = sampling.interval_turns(hostile, (sampling.PROBE,) * (K - 1), (sampling.PROBE,) * (J - 1),
                                    sampling.pose_weights(hostile))
    wanted = [np.clip(np.ceil(sampling.PROBE * t / sampling.MAX_TURN_DEG), lo, hi) for t in turns]
    assert np.prod([w.sum() + 1 for w in wanted]) > 3 * sampling.MAX_VERTICES  # what the probe alone asks for
    steps, lowered = sampling.capped_steps([np.array(rows), np.array(cols)])
    assert not lowered and [tuple(s) for s in steps] == [rows, cols]
    many, lowered = sampling.capped_steps([np.full(33, 16), np.full(36, 16)])
    assert lowered and np.prod([s.sum() + 1 for s in many]) <= sampling.MAX_VERTICES and min(map(min, many)) >= 2


def test_one_check_raises_a_wide_bend_in_proportion_and_a_narrow_one_to_the_most(model, monkeypatch):
    """The choice measures two meshes, the probe and its choice. On the check, an interval over the bar whose turn
    shrank with its steps (a bend wider than the probe's step) gets steps in proportion to its turn; one whose turn
    did not (narrower) gets the most; the rest keep the probe's choice. Measured turns stood in here."""
    K, J = len(model.knots), model.layout.n_points
    lo, hi = sampling.STEPS_RANGE
    aim, probe = sampling.MAX_TURN_DEG, sampling.PROBE
    probed = [np.full(K - 1, 2.0 * aim), np.zeros(J - 1)]  # every curve interval 2x the aim on the probe
    wanted = int(np.ceil(probe * 2.0))
    shrunk = aim * 1.2  # past the bar (1.15x the aim), yet shrunk with the steps
    checked = [np.full(K - 1, aim * 0.9), np.zeros(J - 1)]
    checked[0][[3, 4]] = shrunk  # a wide bend, near the bar
    checked[0][7] = 2.0 * aim  # as on the probe at more steps: narrow
    calls = []

    def measured(m, rows, cols, W, floor=0.0, stacks=None, buffers=None):
        calls.append((tuple(rows), tuple(cols), floor))
        return [t.copy() for t in (probed if len(calls) == 1 else checked)]
    monkeypatch.setattr(sampling, "interval_turns", measured)
    monkeypatch.setattr(sampling, "_CHOSEN", {})
    rows, cols = sampling.adaptive_resolution(model)
    assert len(calls) == 2 and calls[0][0] == (probe,) * (K - 1)
    assert calls[1][:2] == ((wanted,) * (K - 1), (lo,) * (J - 1))
    assert calls[1][2] == pytest.approx(sampling.VERIFY_FACTOR * aim)
    raised = int(np.ceil(wanted * shrunk / (sampling.RAISED_AIM * aim)))
    assert wanted < raised < hi and rows[3] == rows[4] == raised and rows[7] == hi
    assert [r for i, r in enumerate(rows) if i not in (3, 4, 7)] == [wanted] * (K - 4) and cols == (lo,) * (J - 1)


@pytest.mark.skipif(not makehuman.available(), reason="needs ../shared/data/makehuman")
def test_a_narrow_bend_gets_the_most_steps_in_one_check():
    """On the face fitted on MakeHuman's african-male-old (a bend narrower than the probe's step in curve intervals 8
    and 9: 7 steps turned it by 35.5°, 4 by 33.4°), the choice measures two meshes and gives that bend the most
    steps; on the mesh chosen no interval under the most steps turns an edge by more than 25° in any pose (measured
    22.7°; with the second check before, 24.0°), and the mesh is at most 15 % larger than that rule's."""
    from pdeface.au.modelfile import load_face
    from pdeface.au.retarget import retarget
    from pdeface.surface.fit import fit_face

    from scripts.devset.characters import SPECS, build

    ch = build(SPECS["african-male-old-m"])
    face = retarget(load_face("default"), fit_face(*ch.joined(), ch.landmarks)[0])
    measure, calls = sampling.interval_turns, []

    def counted(*args, **kw):
        calls.append(args[1:3])
        return measure(*args, **kw)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sampling, "interval_turns", counted)
        rows, cols = sampling.adaptive_resolution(face)
    assert len(calls) == 2
    assert rows[8] == rows[9] == sampling.STEPS_RANGE[1]
    turns = sampling.interval_turns(face, rows, cols, sampling.pose_weights(face), 25.0)
    assert all(t[np.array(s) < sampling.STEPS_RANGE[1]].max() <= 25.0 for s, t in zip((rows, cols), turns))
    assert (sum(rows) + 1) * (sum(cols) + 1) <= 1.15 * 46_530  # main's rule (three meshes): 46,530 vertices


def test_descriptors_solved_in_batches_are_those_solved_at_once(model):
    """key_grids (a few descriptors per solve, to bound memory) gives each descriptor's grid as one stacked solve
    of them all does, in order."""
    from pdeface.surface.grid import key_grids

    rows, cols = mesh_resolution(model)
    dense = [d.dense() for d in model.descriptors]
    C, R = (np.concatenate(parts, axis=2) for parts in zip(*dense))
    at_once = surface_grid(model, rows, cols, coefficients=C, residual=R)
    seen = 0
    for first, grids in key_grids(model, rows, cols, batch=7):
        assert first == seen and grids.shape[2] <= 7
        np.testing.assert_allclose(grids, at_once[..., 3 * first:3 * (first + grids.shape[2])].reshape(grids.shape),
                                   atol=1e-10)
        seen += grids.shape[2]
    assert seen == len(model.descriptors)



def test_key_batches_kept_and_written_over_are_the_fresh_ones(model):
    """key_stacks are the descriptors' dense changes side by side, and key_grids solving from them, each batch
    written over the last one's (reuse), yields each batch's grids to the bit as fresh solves do."""
    from pdeface.surface.grid import key_grids, key_stacks

    rows, cols = mesh_resolution(model)
    stacks = key_stacks(model, batch=7)
    for first, C, R in stacks:
        dense = [d.dense() for d in model.descriptors[first:first + 7]]
        want_C, want_R = (np.concatenate(parts, axis=2) for parts in zip(*dense))
        np.testing.assert_array_equal(C, want_C)
        np.testing.assert_array_equal(R, want_R)
    fresh = [g.copy() for _, g in key_grids(model, rows, cols, batch=7, planes=True)]
    kept, last = [], None
    for (first, grids), want in zip(key_grids(model, rows, cols, batch=7, planes=True, reuse=True, stacks=stacks),
                                    fresh, strict=True):
        np.testing.assert_array_equal(grids, want)
        assert last is None or np.shares_memory(grids, last)
        kept.append(first)
        last = grids
    assert kept == [first for first, _, _ in stacks]
    # one list of buffers kept across two grids (the probe's and the chosen mesh's), made larger where too small
    buffers = []
    for steps in ((4, 4), (rows, cols), (2, 2)):
        fresh = [g.copy() for _, g in key_grids(model, *steps, batch=7, planes=True, dtype=np.float32)]
        for (_, grids), want in zip(key_grids(model, *steps, batch=7, planes=True, reuse=buffers, dtype=np.float32),
                                    fresh, strict=True):
            np.testing.assert_array_equal(grids, want)
            assert np.shares_memory(grids, buffers[0])
    # buffers a caller made, of unequal sizes (or another type), in either type: made again where they will not do
    for dtype in (np.float64, np.float32):
        fresh = [g.copy() for _, g in key_grids(model, 4, 4, batch=7, planes=True, dtype=dtype)]
        for given in ([np.empty(10 ** 7, dtype), np.empty(10, dtype)], [np.empty(10 ** 7, dtype)],
                      [np.empty(10 ** 7, dtype), np.empty(10 ** 7, np.float16)]):
            for (_, grids), want in zip(key_grids(model, 4, 4, batch=7, planes=True, reuse=given, dtype=dtype),
                                        fresh, strict=True):
                np.testing.assert_array_equal(grids, want)
                assert grids.dtype == dtype
    # stacks of another type than the solve's are made again: float32 stacks never round a float64 solve's keys
    float64 = [g.copy() for _, g in key_grids(model, 4, 4, batch=7, planes=True)]
    for (_, grids), want in zip(key_grids(model, 4, 4, batch=7, planes=True,
                                          stacks=key_stacks(model, 7, dtype=np.float32)), float64, strict=True):
        np.testing.assert_array_equal(grids, want)
    with pytest.raises(ValueError, match="float32 or float64"):
        next(key_grids(model, 4, 4, planes=True, dtype=np.float16))


def test_float32_keys_leave_the_float64_ones_as_they_were(model):
    """key_grids in float32 (the resolution choice's) are the float64 keys to float32's rounding of its products;
    the float64 keys (the rig's, ShapeBasis', the binding's) stay float64 and the same to the bit before and after
    a float32 solve on the same operator (its float32 factors are kept apart)."""
    from pdeface.surface.grid import key_grids, key_stacks

    rows, cols = mesh_resolution(model)
    before = [g.copy() for _, g in key_grids(model, rows, cols, planes=True)]
    stacks = key_stacks(model, dtype=np.float32)
    assert all(C.dtype == R.dtype == np.float32 for _, C, R in stacks)
    single = [g.copy() for _, g in key_grids(model, rows, cols, planes=True, reuse=True, stacks=stacks,
                                             dtype=np.float32)]
    after = [g for _, g in key_grids(model, rows, cols, planes=True)]
    for b, s, a in zip(before, single, after, strict=True):
        assert b.dtype == a.dtype == np.float64 and s.dtype == np.float32
        np.testing.assert_array_equal(a, b)
        # each key's largest displacement sets the scale of its rounding (float32 keeps about 7 digits)
        scale = np.abs(b).max(axis=(1, 2, 3))[:, None, None, None]
        assert (np.abs(s - b) <= 2e-6 * scale + 1e-12).all()  # measured under 4e-7 on 3 faces
    np.testing.assert_array_equal(surface_grid(model, rows, cols, dtype=np.float32), surface_grid(model, rows, cols))


def reference_interval_turns(model, rows, cols, W, floor=0.0, stacks=None, buffers=None, dtype=np.float64):
    """interval_turns written straightforwardly: every key's grid kept, each pose posed on the whole grid and
    its turns and openings measured alone; an edge counts where both its quads lie in the pose's moved block
    (``stacks`` and ``buffers``, what the choice keeps for both meshes, unread). ``dtype``: the keys solved in
    float64 (the surface's keys), or in float32 as the choice solves them, then measured in float64."""
    from pdeface.geometry import degrees_from_cos
    from pdeface.surface.folds import carried, opening_mask
    from pdeface.surface.grid import key_grids
    from pdeface.surface.model import model_landmarks

    X0 = surface_grid(model, rows, cols)
    n_u, n_v, _ = X0.shape
    D = np.concatenate([np.transpose(g, (2, 3, 0, 1)) for _, g in key_grids(model, rows, cols, planes=True,
                                                                             dtype=dtype)], axis=2).astype(np.float64)
    # (n_u, n_v, keys, 3)
    L, rest = model_landmarks(model), X0.reshape(-1, 3)
    interval = [np.repeat(np.arange(len(model.knots) - 1), rows), np.repeat(np.arange(model.layout.n_points - 1), cols)]
    need = [np.zeros(len(rows)), np.zeros(len(cols))]
    for w in W:
        keys = np.nonzero(w)[0]
        X = X0 + np.tensordot(D[:, :, keys], w[keys], axes=([2], [0]))
        moved = (np.abs(D[:, :, keys]) > sampling.MOVED_MM).any(axis=(2, 3)) if len(keys) else np.ones((n_u, n_v), bool)
        if not moved.any():
            continue
        r, c = np.nonzero(moved.any(axis=1))[0], np.nonzero(moved.any(axis=0))[0]
        r0, r1, c0, c1 = max(r[0] - 2, 0), min(r[-1] + 3, n_u), max(c[0] - 2, 0), min(c[-1] + 3, n_v)
        posed_L = carried(rest, X.reshape(-1, 3), L)
        for axis, cos in enumerate(sampling.quad_turn_cosines(X)):
            R, C = np.meshgrid(np.arange(cos.shape[0]), np.arange(cos.shape[1]), indexing="ij")
            # the edge's quads (and the edge) in the block: across rows R, R + 1 and the edge on row R + 1
            inside = (R >= r0) & (C >= c0) & (R + 2 + (axis == 0) <= r1) & (C + 2 + (axis == 1) <= c1)
            if axis == 0:
                a, b = (R + 1) * n_v + C, (R + 1) * n_v + C + 1
            else:
                a, b = R * n_v + C + 1, (R + 1) * n_v + C + 1
            opened = (opening_mask(0.5 * (rest[a.ravel()] + rest[b.ravel()]), L)
                      | opening_mask(0.5 * (X.reshape(-1, 3)[a.ravel()] + X.reshape(-1, 3)[b.ravel()]), L)
                      | opening_mask(0.5 * (X.reshape(-1, 3)[a.ravel()] + X.reshape(-1, 3)[b.ravel()]), posed_L))
            t = degrees_from_cos(cos).ravel()
            counted = inside.ravel() & ~opened & (t > floor)
            first = (R, C)[axis].ravel()[counted]
            for side in (first, first + 1):
                np.maximum.at(need[axis], interval[axis][side], t[counted])
    return need


#: Largest difference (degrees) allowed between the choice's needs (keys solved in float32) and the float64 keys'
#: (measured: under 6e-5° on the face below; on 47 faces' 92 meshes under 0.002° for needs under 25°, 0.14° in all,
#: at turns past 90°).
NEED_ROUNDING_DEG = 0.01


def test_the_choice_is_the_straightforward_ones(model, monkeypatch):
    """The choice's turns (poses of one key measured as their batch is solved, the openings tested for many
    poses at once) are those of a pose-at-a-time measurement on the whole grid of the same float32 keys, at the
    probe's steps and at the chosen ones; within NEED_ROUNDING_DEG of the float64 keys' turns, and the choice is
    the float64 reference's; on a smaller face (a quarter of the bundled descriptors)."""
    import copy

    small = copy.deepcopy(model)
    small.descriptors = small.descriptors[::4]
    W = sampling.pose_weights(small)
    assert (np.count_nonzero(W, axis=1) > 1).any() and (np.count_nonzero(W, axis=1) == 1).any()
    chosen = sampling.adaptive_resolution(small)
    K, J = len(small.knots), small.layout.n_points
    for steps, floor in ((((sampling.PROBE,) * (K - 1), (sampling.PROBE,) * (J - 1)), 10.0), (chosen, 10.0)):
        fast = sampling.interval_turns(small, *steps, W, floor)
        same_keys = reference_interval_turns(small, *steps, W, floor, dtype=np.float32)
        slow = reference_interval_turns(small, *steps, W, floor)
        assert max(s.max() for s in slow) > floor
        for f, s, s64 in zip(fast, same_keys, slow):
            np.testing.assert_allclose(f, s, atol=1e-9)
            np.testing.assert_allclose(f, s64, atol=NEED_ROUNDING_DEG)
    monkeypatch.setattr(sampling, "interval_turns", reference_interval_turns)
    small.descriptors = small.descriptors[:]  # the same model: its choice is made again, the reference's way
    sampling._CHOSEN.pop((sampling.model_fingerprint(small), sampling.MAX_TURN_DEG))
    assert sampling.adaptive_resolution(small) == chosen


def screened(rest, G, w, looked):
    """sampling._screened's masks as quad_turn_cosines shapes them (its rows are a column wider), copied."""
    across_rows, across_columns = sampling._screened(rest, G, w, looked)
    assert not across_rows[:, :, -1:].any() and not across_columns[:, :, -2:].any()
    return across_rows[:, :, :-1].copy(), across_columns[:, :, :-2].copy()


@pytest.mark.parametrize("floor", [10.0, 25.0])
def test_the_float32_screen_passes_every_edge_past_its_floor(model, floor):
    """The choice looks at an edge in float64 only where its float32 screen passes it: every edge whose float64
    turn (quad_turn_cosines, as the choice measures it) is past the floor passes, in each pose of one key at
    weight 1 and 0.5 on the probe mesh and on the chosen one; and it passes few others."""
    from pdeface.surface.grid import key_grids

    K, J = len(model.knots), model.layout.n_points
    for steps in (((sampling.PROBE,) * (K - 1), (sampling.PROBE,) * (J - 1)), mesh_resolution(model)):
        rest = surface_grid(model, *steps, planes=True)
        rest_diagonals = sampling._rest_diagonals(rest)
        looked = np.float32(np.cos(np.radians(floor - sampling.SCREEN_MARGIN_DEG)))
        passed = over = 0
        for _, grids in key_grids(model, *steps, planes=True, dtype=np.float32):  # the keys as the choice solves them
            w = np.where(np.arange(len(grids)) % 2, 0.5, 1.0)
            screens = screened(rest_diagonals, grids, w, [looked, looked])
            for g, wi, *masks in zip(grids.astype(np.float64), w, *screens):
                for cos, mask in zip(sampling.quad_turn_cosines(list(rest + wi * g)), masks):
                    past = np.degrees(np.arccos(np.clip(cos, -1, 1))) > floor
                    assert mask[past].all()
                    over, passed = over + past.sum(), passed + mask.sum()
        assert over > 0 and passed < 1.5 * over  # measured 1.02-1.18x


def hostile_grid(rng, n_u=14, n_v=17):
    """A wavy rest grid (mm) with a tiny quad (its corners within 0.01 mm), a flipped one (two corners swapped) and
    a needle (a quad 2 mm long and 1e-4 mm wide, its normal under SCREEN_TINY_MM2)."""
    r, c = np.meshgrid(np.arange(n_u, dtype=float), np.arange(n_v, dtype=float), indexing="ij")
    X = np.stack([c + 0.1 * rng.normal(size=c.shape), r, 0.5 * np.sin(0.7 * c) * np.cos(0.4 * r)]) * 1.3 + 40.0
    X[:, 3:5, 3:5] = X[:, 3:4, 3:4] + 0.005 * rng.normal(size=(3, 2, 2))  # tiny
    X[:, 8, 9], X[:, 8, 10] = X[:, 8, 10].copy(), X[:, 8, 9].copy()  # flipped
    X[:, 11, 5] = X[:, 10, 5] + [0, 2.0, 0]
    X[:, 11, 6] = X[:, 11, 5] + [1e-4, 0, 0]  # a needle, with (10, 6) where it was
    X[:, 10, 6] = X[:, 10, 5] + [1e-4, 0, 0]
    return X


def test_the_screen_passes_every_edge_the_float64_measurement_counts_on_hostile_quads():
    """Tiny, flipped and needle quads, weights other than 1 (negative too), thresholds over 90° and edges not looked
    at (-2): every edge looked at whose float64 turn is past its threshold passes the float32 screen, as does
    every edge looked at beside a quad whose float32 normal is under SCREEN_TINY_MM2; none not looked at passes."""
    rng = np.random.default_rng(35)
    counted = beside_tiny = 0
    for trial in range(6):
        X = hostile_grid(rng)
        n_u, n_v = X.shape[1:]
        G = (rng.normal(size=(5, 3, n_u, n_v)) * 0.3 + rng.normal(size=(5, 3, 1, 1)) * 5).astype(np.float32)
        G[1, :, 3:6, 3:6] *= 40  # a key that tears the tiny quad open, and two that move it and the needle whole
        G[[0, 2], :, 3:5, 3:5] = G[[0, 2], :, 3:4, 3:4]
        G[[0, 2], :, 10:12, 5:7] = G[[0, 2], :, 10:11, 5:6]
        w = np.array([1.0, 0.5, -1.0, 2.0, 0.25])
        turn = [rng.uniform(0, 180, size=(n_u - 2, n_v - 1)), rng.uniform(0, 180, size=(n_u - 1, n_v - 2))]
        shut = [rng.random(t.shape) > 0.1 for t in turn]
        looked = [np.full((t.shape[0], n_v), -2.0, np.float32) for t in turn]  # a column wider, as the screen's
        for lc, t, s in zip(looked, turn, shut):
            lc[:, :t.shape[1]] = np.where(s, np.cos(np.radians(np.maximum(t - sampling.SCREEN_MARGIN_DEG, 0))), -2)
        masks = screened(sampling._rest_diagonals(X), G, w, looked)
        for p in range(len(G)):
            posed = X + w[p] * G[p].astype(np.float64)
            d1, d2 = posed[:, 1:, 1:] - posed[:, :-1, :-1], posed[:, :-1, 1:] - posed[:, 1:, :-1]
            tiny = np.linalg.norm(np.cross(d2, d1, axis=0), axis=0) < 1.01 * sampling.SCREEN_TINY_MM2
            beside = [tiny[:-1] | tiny[1:], tiny[:, :-1] | tiny[:, 1:]]
            for cos, t, s, b, mask in zip(sampling.quad_turn_cosines(list(posed)), turn, shut, beside, masks):
                past = (np.degrees(np.arccos(np.clip(cos, -1, 1))) > t) & s
                assert mask[p][past].all() and mask[p][b & s].all() and not mask[p][~s].any()
                counted, beside_tiny = counted + past.sum(), beside_tiny + (b & s).sum()
    assert counted > 0 and beside_tiny > 0


def test_a_tiny_quad_folded_back_passes_past_90_degrees():
    """A quad under SCREEN_TINY_MM2 folded back on a flat grid turns its edges by about 180° in float64: they pass a
    screen whose thresholds are 120° (a normal taken as 0 would give them a cosine of 0, a turn of 90°: not past)."""
    r, c = np.meshgrid(np.arange(8.0), np.arange(9.0), indexing="ij")
    X = np.stack([c, r, np.zeros_like(c)])
    X[:, 3:5, 3:5] = X[:, 3:4, 3:4] + 0.006 * np.array([[[0, 1], [0, 1]], [[0, 0], [1, 1]], [[0, 0], [0, 0]]])
    X[:, 3, 3], X[:, 4, 4] = X[:, 4, 4].copy(), X[:, 3, 3].copy()  # a diagonal's ends swapped: its normal down
    cos = sampling.quad_turn_cosines(list(X))
    folded = [np.degrees(np.arccos(np.clip(x, -1, 1))) > 120 for x in cos]
    assert folded[0][2:4, 3].all() and folded[1][3, 2:4].all()
    looked = [np.full((n, 9), np.cos(np.radians(120 - sampling.SCREEN_MARGIN_DEG)), np.float32) for n in (6, 7)]
    masks = screened(sampling._rest_diagonals(X), np.zeros((1, 3, 8, 9), np.float32), np.ones(1), looked)
    for f, mask in zip(folded, masks):
        assert mask[0][f].all()


def test_a_screen_in_bands_is_one_pass(model, monkeypatch):
    """The screen works SCREEN_CHUNK quads at a time, in bands of rows: the same masks as one band, with bands of 2
    rows, of 5 and one band, on a grid whose rows do not divide evenly."""
    steps = ((sampling.PROBE,) * (len(model.knots) - 1), (sampling.PROBE,) * (model.layout.n_points - 1))
    rest = surface_grid(model, *steps, planes=True)[:, :47]
    from pdeface.surface.grid import key_grids

    _, grids = next(key_grids(model, *steps, planes=True))
    G = grids[:3, :, :47].astype(np.float32)
    rng = np.random.default_rng(2)
    looked = [np.float32(np.cos(np.radians(rng.uniform(0, 25, size=(n, G.shape[3]))))) for n in (45, 46)]
    monkeypatch.setattr(sampling, "SCREEN_CHUNK", 1 << 30)
    whole = screened(sampling._rest_diagonals(rest), G, np.ones(3), looked)
    assert all(m.any() and not m.all() for m in whole)
    for rows in (2, 5):
        monkeypatch.setattr(sampling, "SCREEN_CHUNK", rows * 3 * G.shape[3])
        banded = screened(sampling._rest_diagonals(rest), G, np.ones(3), looked)
        assert all(np.array_equal(a, b) for a, b in zip(banded, whole))


def test_a_screen_of_the_blocks_part_is_the_whole_grids_there(model):
    """interval_turns screens a run of poses over the grid's part their blocks cover (_screen_groups): element by
    element the numbers of the whole grid's screen, so the same edges pass there; every pose is in one run, in
    order, and a run's part is no larger than the poses' blocks screened apart ask for."""
    from pdeface.surface.grid import key_grids

    K, J = len(model.knots), model.layout.n_points
    steps = ((sampling.PROBE,) * (K - 1), (sampling.PROBE,) * (J - 1))
    rest = sampling._rest_diagonals(surface_grid(model, *steps, planes=True))
    _, grids = next(key_grids(model, *steps, planes=True))
    G = grids[:8].astype(np.float32)
    w = np.linspace(0.5, 1.0, len(G))
    rng = np.random.default_rng(5)
    looked = [np.float32(np.cos(np.radians(rng.uniform(0, 30, size=(G.shape[2] - 2 + axis, G.shape[3])))))
              for axis in (0, 1)]
    whole = screened(rest, G, w, looked)
    assert all(m.any() for m in whole)
    r0, r1, c0, c1 = 7, 60, 11, 90
    part = screened([d[:, r0:r1 - 1, c0:c1] for d in rest], G[:, :, r0:r1, c0:c1], w,
                    [looked[0][r0:r1 - 2, c0:c1], looked[1][r0:r1 - 1, c0:c1]])
    assert np.array_equal(part[0], whole[0][:, r0:r1 - 2, c0:c1 - 1])
    assert np.array_equal(part[1], whole[1][:, r0:r1 - 1, c0:c1 - 2])
    # blocks: two alike, one far off, two alike again
    R0, R1 = np.array([0, 2, 60, 61, 0]), np.array([40, 42, 100, 100, 40])
    C0, C1 = np.array([0, 0, 100, 100, 5]), np.array([50, 50, 140, 140, 45])
    runs = sampling._screen_groups(R0, R1, C0, C1)
    assert [(g.start, g.stop) for g in runs] == [(0, 2), (2, 4), (4, 5)]
    assert sampling._screen_groups(R0[:1], R1[:1], C0[:1], C1[:1]) == [slice(0, 1)]
