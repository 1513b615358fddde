"""How finely a PDE face is meshed: named and explicit resolutions, and the default's adaptive one.

The PDE surface is smooth, but a mesh of it turns at each edge by about the surface's curvature
times the edge's length. Where a face creases tightly (the base of the nose wings, the lip corners,
a puckered chin), 4 rows and columns per interval turn edges by 30–45°, and a render shows folds
there (issue #16); twice as many steps halve the turn, four times as many quarter it. So the
default resolution chooses the steps per curve interval and per point interval: enough that no
edge outside the openings (where lips and lids part) turns by more than :data:`MAX_TURN_DEG` at
rest, at weight 1 of each of the model's keys or in any preset, judged on a probe mesh of
:data:`PROBE` steps; fewer where the face is flat, so the mesh stays about as large as before.

The choice depends on the model's rest shape and its descriptors; it is made once per model (a model
file carries it). A face object keeps the steps it was built with (:func:`resolution_text`), so keys
added later land on the same vertices.
"""
from __future__ import annotations

import hashlib
import json

import numpy as np

from ..errors import MeshError
from ..geometry import degrees_from_cos
from ..presets import every_pose
from ..threads import bounded
from .folds import carried, nearest_vertices, opening_mask
from .grid import KEY_BATCH, break_weights, key_grids, key_stacks, surface_grid
from .model import model_landmarks

#: Named uniform resolutions: (rows per curve interval, columns per point interval). ``default`` is adaptive.
RESOLUTIONS = {"original": (10, 1), "fine": (8, 8)}
#: The adaptive resolution's name.
ADAPTIVE = "default"
#: Largest turn (degrees) the adaptive resolution aims for at an edge outside the openings, in each pose.
#: A third under the 30° at which a render shows a fold: the probe's estimate is not exact.
MAX_TURN_DEG = 20.0
#: Steps per interval of the probe mesh the turns are measured on (the old uniform default). A 3-step probe (10,900
#: vertices against 19,285) chose worse: its choice left bends that the one check saw, and raised, blind to what
#: the raise did to the intervals crossing them (the low-poly face's c11 turned 33° after r8 went 4 → 6 steps).
PROBE = 4
#: Fewest and most steps the adaptive resolution gives an interval.
STEPS_RANGE = (2, 16)
#: The probe's choice is measured once (the check): an interval whose edges turn by more than this many times the aim
#: on it gets more steps, aiming for :data:`RAISED_AIM` times the aim, in proportion to that turn. The raised mesh is
#: not measured again, and raising an interval can make the edges of the intervals crossing it turn more (their
#: quads grow narrower across them): hence 23° and 19°, not the 25° and 20° of the rule that checked twice (with one
#: check, those left the low-poly face at 35.1°; issue #35).
VERIFY_FACTOR = 1.15
RAISED_AIM = 0.95
#: An interval whose edges turn on the checked mesh by more than this many times the probe's turn scaled to its steps
#: (``PROBE * max(t, floor) / steps``, the probe's floor for a turn it did not look at) holds a bend narrower than the
#: probe's step, which more steps shrink by less than in proportion (a bend narrower than any step keeps its turn): it
#: gets the most steps.
NARROW = 1.5
#: Most vertices the adaptive mesh may have (the bundled face's has 17,802, the low-poly face's 28,545, a
#: MakeHuman head's 45,373): a descriptor that turns edges everywhere (a broken file, a huge residual) gets
#: its steps capped to fit, not the most steps everywhere (a 230,800-vertex mesh, its choice 6.3 s of CPU;
#: issue #35).
MAX_VERTICES = 60_000
#: Skin a pose moves less than this (mm) turns its edges as at rest (by under 0.3° on 1 mm edges).
MOVED_MM = 0.005
#: Poses whose edges are tested against the openings together (the test costs the same for a few edges or many;
#: an edge under the needs found so far is not tested).
SETTLE_POSES = 16
#: Largest explicit steps per interval.
MAX_STEPS = 64
#: Poses of one key whose turns are screened together (in float32, over the part of the grid their moved blocks
#: cover, in bands of at most :data:`SCREEN_CHUNK` of their quads).
SCREEN_POSES = 8
#: The float32 screen passes every edge within this many degrees of the turn it must pass; each it passes is
#: measured again in float64, as :func:`quad_turn_cosines` measures it. Float32 keeps 7 digits of the quads'
#: diagonals (the rest's and the key's apart), so its turns are within thousandths of a degree on quads larger than
#: :data:`SCREEN_TINY_MM2`; it passes 1.02-1.2x the edges float64 puts past a floor (tests/core/test_sampling.py).
SCREEN_MARGIN_DEG = 0.5
#: What one screen costs beyond its quads, as quads screened (its array operations' own time; measured on the probe).
SCREEN_CALL_QUADS = 4000
#: A quad whose normal (the cross product of its diagonals, mm²) is shorter than this, its float32 turns
#: unreliable: the screen passes its edges.
SCREEN_TINY_MM2 = 1e-3
#: The cosine an edge that is not looked at must fall under (none does): the screen's thresholds there.
NOT_LOOKED_COS = np.float32(-2.0)
#: Quads (of all its poses) the screen works on at once: what bounds its work arrays (7 MB). Larger were no faster,
#: 2**16 the same, 2**14 a third slower (more array operations).
SCREEN_CHUNK = 1 << 17


def _checked(steps, what):
    steps = tuple(int(s) for s in np.atleast_1d(steps))
    if not steps or min(steps) < 1 or max(steps) > MAX_STEPS:
        raise MeshError(f"resolution {what} subdivisions must be in 1..{MAX_STEPS}, got {steps}")
    return steps[0] if len(steps) == 1 else steps


def parse_resolution(value):
    """A resolution as given → ``(rows, cols)``, or :data:`ADAPTIVE` (decided per model: :func:`mesh_resolution`).

    ``value``: ``"default"``, ``"original"``, ``"fine"``, ``"ROWS,COLS"`` (steps per curve interval and per
    point interval), a pair of ints, or :func:`resolution_text`'s steps per interval (rows and cols are then
    tuples).
    """
    if isinstance(value, str):
        text = value.strip()
        if text == ADAPTIVE:
            return ADAPTIVE
        if text in RESOLUTIONS:
            return RESOLUTIONS[text]
        try:
            value = json.loads(text) if text.startswith("[") else tuple(int(p) for p in text.split(","))
        except ValueError:
            raise MeshError(f"resolution {value!r}: use {ADAPTIVE}, {', '.join(RESOLUTIONS)} or 'ROWS,COLS' "
                            "subdivisions") from None
    try:
        rows, cols = value
    except (TypeError, ValueError):
        raise MeshError(f"resolution {value!r}: give rows and columns") from None
    return _checked(rows, "row"), _checked(cols, "column")


def resolution_text(rows, cols) -> str:
    """Steps as text :func:`parse_resolution` reads back: ``"ROWS,COLS"``, or ``[[rows...],[cols...]]`` per
    interval."""
    if np.ndim(rows) == 0 and np.ndim(cols) == 0:
        return f"{int(rows)},{int(cols)}"
    return json.dumps([np.atleast_1d(rows).astype(int).tolist(), np.atleast_1d(cols).astype(int).tolist()],
                      separators=(",", ":"))


def mesh_resolution(model, resolution=ADAPTIVE):
    """``(rows, cols)`` steps the surface of ``model`` is meshed with: ints, or one per interval."""
    parsed = parse_resolution(resolution)
    if parsed == ADAPTIVE:
        return adaptive_resolution(model)
    rows, cols = parsed
    if np.ndim(rows) or np.ndim(cols):
        K, J = len(model.knots), model.layout.n_points
        _check_steps(model, np.broadcast_to(rows, K - 1) if np.ndim(rows) == 0 else rows,
                     np.broadcast_to(cols, J - 1) if np.ndim(cols) == 0 else cols)
    return rows, cols


def quad_turn_cosines(X):
    """Cosines of the turns across a grid mesh's inner edges: ``(across rows, across columns)`` (the turns'
    arccos costs more than the rest: callers compare cosines first).

    ``X`` (n_u, n_v, 3), or its three coordinate planes (n_u, n_v). Quad normals are their diagonals' cross
    product (Newell's for a quad); across rows: (n_u - 2, n_v - 1), the edge on row r + 1; across columns:
    (n_u - 1, n_v - 2). Worked on one coordinate plane at a time: reductions over an axis of 3 are slow in numpy.
    """
    x, y, z = (np.ascontiguousarray(p) for p in (X if isinstance(X, (list, tuple)) else np.moveaxis(X, 2, 0)))
    d1 = [p[1:, 1:] - p[:-1, :-1] for p in (x, y, z)]
    d2 = [p[:-1, 1:] - p[1:, :-1] for p in (x, y, z)]
    N = [d2[1] * d1[2] - d2[2] * d1[1], d2[2] * d1[0] - d2[0] * d1[2], d2[0] * d1[1] - d2[1] * d1[0]]
    length = np.sqrt(N[0] ** 2 + N[1] ** 2 + N[2] ** 2)
    length[length == 0] = 1.0
    N = [c / length for c in N]
    return sum(c[:-1] * c[1:] for c in N), sum(c[:, :-1] * c[:, 1:] for c in N)


#: The steps chosen for the models met so far, by :func:`model_fingerprint` (and aim): a model is meshed many
#: times (each pose, each key), chosen for once; a model file carries them (:func:`remember_resolution`).
_CHOSEN = {}
_CHOSEN_MAX = 32


def model_fingerprint(model) -> bytes:
    """A digest of everything the adaptive resolution reads: the curves, layout, landmarks and descriptors (the
    arrays' own bytes, read in place: no copies). SHA-256, which CPUs of the last years compute in hardware: 2.4 MB
    of a face's descriptors in 1.3 ms here, BLAKE2b's 2.7 ms."""
    h = hashlib.sha256()
    for a in (model.knots, model.coefficients, model.residual, model.layout.as_array(), model.features,
              model.landmarks if model.landmarks is not None else np.zeros(0), [model.a, model.remainder_w]):
        a = np.ascontiguousarray(a, np.float64)
        h.update(np.array(a.shape, np.int64).tobytes())  # bytes cannot move between arrays unnoticed
        h.update(a)
    h.update(model.assembly.encode())
    for d in model.descriptors:  # what its dense changes are made of (hashing those read 5x the bytes)
        h.update(d.key.encode())
        h.update(np.array(d.layout, np.int64).tobytes())
        h.update(np.ascontiguousarray(d.curves, np.int64).tobytes())
        for a in (d.coefficients, np.zeros(0) if d.residual is None else d.residual):
            h.update(np.array(a.shape, np.int64).tobytes())
            h.update(np.ascontiguousarray(a, np.float64))
    return h.digest()


def _check_steps(model, rows, cols):
    for steps, n, what in ((rows, len(model.knots) - 1, "curve"), (cols, model.layout.n_points - 1, "point")):
        if len(steps) != n or not all(1 <= int(s) <= MAX_STEPS for s in steps):
            raise MeshError(f"this face has {n} {what} intervals: give {n} steps, each 1..{MAX_STEPS}; got "
                            f"{len(steps)}: {list(steps)}")


def remember_resolution(model, rows, cols, max_turn=MAX_TURN_DEG, fingerprint=None):
    """Record ``rows``, ``cols`` (steps per interval) as ``model``'s adaptive resolution: what a model file
    read back carries (:mod:`pdeface.au.modelfile`), so it is not chosen again. ``fingerprint``: the model's
    :func:`model_fingerprint`, when known."""
    _check_steps(model, rows, cols)
    while len(_CHOSEN) >= _CHOSEN_MAX:
        del _CHOSEN[next(iter(_CHOSEN))]
    steps = (tuple(int(s) for s in rows), tuple(int(s) for s in cols))
    _CHOSEN[fingerprint or model_fingerprint(model), max_turn] = steps
    return steps


def forget_resolution(model, max_turn=MAX_TURN_DEG):
    """Drop ``model``'s remembered adaptive steps (those its file carried), so they are chosen again."""
    _CHOSEN.pop((model_fingerprint(model), max_turn), None)


def known_resolution(model, max_turn=MAX_TURN_DEG, fingerprint=None):
    """``model``'s adaptive steps if they were chosen or read already, else None."""
    return _CHOSEN.get((fingerprint or model_fingerprint(model), max_turn))


def pose_weights(model) -> np.ndarray:
    """(poses, descriptors) weights of :func:`pdeface.presets.every_pose`, in the descriptors' order."""

    keys = [d.key for d in model.descriptors]
    W = [[weights.get(k, 0.0) for k in keys] for weights in every_pose(model).values()]
    return np.array(W, dtype=np.float64).reshape(len(W), len(keys))


def _moved_block(rows_moved, cols_moved):
    """The grid block a pose is measured on: the rows and columns its keys move, and two more around them (the
    quads beside a moved vertex turn); None where it moves nothing."""
    r, c = np.nonzero(rows_moved)[0], np.nonzero(cols_moved)[0]
    if not len(r):
        return None
    return np.s_[max(r[0] - 2, 0):r[-1] + 3, max(c[0] - 2, 0):c[-1] + 3]


def _edges_over(X, block, shut_at_rest, interval, need, floor):
    """(interval before, interval after, turn, midpoint) per axis, of the edges of ``X`` (the grid's ``block``,
    posed: its three coordinate planes) that turn past ``floor`` and past a need of their intervals found so
    far, outside the openings at rest (the openings where the pose carries them are tested later, for many
    poses at once)."""
    r0, c0 = block[0].start, block[1].start
    floor_cos = np.cos(np.radians(floor)) + 1e-9
    edges = []
    for axis, cos in enumerate(quad_turn_cosines(X)):
        looked = cos < floor_cos  # a few more than turn past the floor (rounding)
        looked &= shut_at_rest[axis][r0:r0 + cos.shape[0], c0:c0 + cos.shape[1]]
        r, c = np.nonzero(looked)
        t = degrees_from_cos(cos[r, c])
        over = t > floor
        r, c, t = r[over], c[over], t[over]
        first = (r + r0, c + c0)[axis]  # the quad before the edge; the one after is first + 1
        before, after = interval[axis][first], interval[axis][first + 1]
        keep = (t > need[axis][before]) | (t > need[axis][after])
        r, c = r[keep], c[keep]
        # the edge's ends in the block: across rows (r + 1, c) and (r + 1, c + 1), across columns (r, c + 1)
        # and (r + 1, c + 1)
        mid = np.stack([0.5 * (p[r + 1, c] + p[r + 1, c + 1]) if axis == 0 else 0.5 * (p[r, c + 1] + p[r + 1, c + 1])
                        for p in X], axis=1)
        edges.append((before[keep], after[keep], t[keep], mid))
    return edges


def _rest_diagonals(planes):
    """The rest grid's quad diagonals ``(d1, d2)`` in float32, each three coordinate planes (n_u - 1, n_v): the
    screen's rows, a column wider than the quads' (the last a copy of the one before, so its quad is no tinier
    than a real one). :func:`quad_turn_cosines`' own differences."""
    out = []
    for d in ([p[1:, 1:] - p[:-1, :-1] for p in planes], [p[:-1, 1:] - p[1:, :-1] for p in planes]):
        padded = np.empty((3, len(planes[0]) - 1, len(planes[0][0])), np.float32)
        padded[:, :, :-1] = d
        padded[:, :, -1] = padded[:, :, -2]
        out.append(padded)
    return out


class _ScreenScratch:
    """The screen's work arrays, kept from one screen to the next (fresh pages cost: issue #35), grown as needed."""

    def __init__(self):
        self.planes = np.empty((0,), np.float32)
        self.masks = np.empty((0,), bool)

    def arrays(self, floats, bools):
        """A float32 array of ``floats`` elements and a boolean one of ``bools``: views of the kept arrays."""
        if len(self.planes) < floats:
            self.planes = np.empty(floats, np.float32)
        if len(self.masks) < bools:
            self.masks = np.empty(bools, bool)
        return self.planes[:floats], self.masks[:bools]


def _screened(rest, G, w, looked_cos, scratch=None):
    """Which inner edges of each pose ``rest + w[p] G[p]`` may turn past ``looked_cos`` (the cosine each edge must
    fall under to be looked at; -2 where none is): ``(across rows, across columns)`` masks (poses, ...), a few more
    edges than do, as :func:`quad_turn_cosines` shapes them but a column wider (False there, and in the column before
    it across columns); views of ``scratch``'s arrays (a :class:`_ScreenScratch`), good until its next screen.

    ``G`` (poses, 3, rows, columns) float32 key grids; ``rest``: :func:`_rest_diagonals` of the rest grid where
    ``G`` lies ((rows - 1, columns) of each), ``looked_cos`` (rows - 2, columns) and (rows - 1, columns), or
    numbers. Each pose's diagonals are the rest's plus its keys': float32 then keeps their own digits, not the
    coordinates'. An edge beside a quad under :data:`SCREEN_TINY_MM2` passes wherever an edge is looked at. Worked
    on rows a column wider than the quads' (then every array is read in order, each operation on the three planes at
    once: a quad's right neighbour is the next element, the one below it the next row's; the extra column's numbers
    are the next row's), in bands of :data:`SCREEN_CHUNK` quads of the poses (each band's last quad row the next
    one's first): each element the same sums and products as one pass over the part.
    """
    G = np.asarray(G, np.float32)  # (the float32 keys as they are; another type would round otherwise by path)
    P, _, n_u, n_v = G.shape
    H = n_u - 1  # quad rows; a row of quads is n_v long, its last the wrap to the next row
    band = max(2, min(H, SCREEN_CHUNK // (P * n_v)))
    size = P * 3 * (band + 1) * n_v  # a band's vertex rows
    planes, masks = (scratch or _ScreenScratch()).arrays(size + 10 * P * band * n_v, P * (2 * H - 1) * n_v)
    copied = planes[:size].reshape(P, 3, -1)
    work = planes[size:size + 9 * P * band * n_v].reshape(3, P, 3, -1)  # d1, d2, the normals: (poses, planes, quads)
    products = planes[size + 9 * P * band * n_v:].reshape(P, -1)
    # rows read in place where they are whole rows of G's array (in order) and the poses' weights 1
    whole_rows = G.strides[2:] == (n_v * G.itemsize, G.itemsize) and (w == 1).all()
    masks = masks[:P * (H - 1) * n_v].reshape(P, H - 1, n_v), masks[P * (H - 1) * n_v:].reshape(P, H, n_v)
    tiny_square = np.float32(SCREEN_TINY_MM2 ** 2)
    a = 0
    while True:
        b = min(a + band, H)
        n = (b - a) * n_v  # the band's quads, flat
        if whole_rows:
            X = G[:, :, a:b + 1].reshape(P, 3, n + n_v)  # a view: its rows follow each other
        else:
            X = copied[:, :, :n + n_v]
            np.copyto(X.reshape(P, 3, b - a + 1, n_v), G[:, :, a:b + 1])
            if not (w == 1).all():
                X *= np.asarray(w, np.float32)[:, None, None]
        d1, d2, N = (p[:, :, :n] for p in work)
        np.subtract(X[:, :, n_v + 1:], X[:, :, :n - 1], out=d1[:, :, :-1])  # (r + 1, c + 1) - (r, c)
        d1[:, :, -1] = 0.0  # the extra column's last quad: past the band's last vertex
        np.subtract(X[:, :, 1:1 + n], X[:, :, n_v:], out=d2)  # (r, c + 1) - (r + 1, c)
        for d, r in ((d1, rest[0]), (d2, rest[1])):
            d.reshape(P, 3, b - a, n_v)[...] += r[:, a:b]  # rest + w k: float32 keeps the diagonals' own digits
        for i, (x, y) in enumerate(((1, 2), (2, 0), (0, 1))):  # the cross product d2 × d1, a component at a time
            np.multiply(d2[:, x], d1[:, y], out=N[:, i])
            N[:, i] -= np.multiply(d2[:, y], d1[:, x], out=products[:, :n])
        square = np.einsum("pik,pik->pk", N, N, out=d1[:, 0])  # d1, d2 are free now; einsum: one pass, not five
        # (a NaN's quad is no tiny one: its cosines are NaN, under no threshold, as in float64)
        tiny = np.less(square, tiny_square) if not square.min() >= tiny_square else None
        if tiny is not None:
            square[tiny] = 1.0
        inverse = np.divide(1.0, np.sqrt(square, out=square), out=square)
        N *= inverse[:, None]
        for axis, step in ((0, n_v), (1, 1)):  # the neighbour across rows is a row on, across columns the next
            cos = d2[:, 0]
            cos[:, n - step:] = 1.0  # no neighbour in the band (the extra column's last edge: cleared below)
            np.einsum("pik,pik->pk", N[:, :, :n - step], N[:, :, step:], out=cos[:, :n - step])
            rows = b - a - 1 + axis
            looked = np.float32(looked_cos[axis]) if np.ndim(looked_cos[axis]) == 0 else looked_cos[axis][a:a + rows]
            mask = np.less(cos[:, :rows * n_v].reshape(P, rows, n_v), looked, out=masks[axis][:, a:a + rows])
            if tiny is not None:  # its float32 normal may point anywhere
                beside = np.zeros((P, n), bool)
                beside[:, :n - step] = tiny[:, :n - step] | tiny[:, step:]
                mask |= beside[:, :rows * n_v].reshape(P, rows, n_v) & (np.asarray(looked) > NOT_LOOKED_COS)
        if b == H:
            break
        a = b - 1
    masks[0][:, :, -1] = False  # the extra column's edges
    masks[1][:, :, -2:] = False
    return masks


def _screen_groups(R0, R1, C0, C1):
    """Consecutive runs (slices) of poses whose blocks (rows ``R0[p]`` .. ``R1[p]``, columns ``C0[p]`` .. ``C1[p]``) are
    screened over one part of the grid, the smallest holding them all: a pose joins the run before it while the run's
    part costs no more screened quads (and :data:`SCREEN_CALL_QUADS` a screen) than screening the two apart."""
    runs, start = [], 0
    R0, R1, C0, C1 = (np.asarray(a).tolist() for a in (R0, R1, C0, C1))  # Python's ints: small arrays' min is slow
    for p in range(1, len(R0) + 1):
        if p < len(R0):
            part = min(R0[start:p]), max(R1[start:p]), min(C0[start:p]), max(C1[start:p])
            alone = (part[1] - part[0]) * (part[3] - part[2])
            joined = (max(part[1], R1[p]) - min(part[0], R0[p])) * (max(part[3], C1[p]) - min(part[2], C0[p]))
            if joined * (p + 1 - start) <= alone * (p - start) + (R1[p] - R0[p]) * (C1[p] - C0[p]) + SCREEN_CALL_QUADS:
                continue
        runs.append(slice(start, p))
        start = p
    return runs


def _edge_cosines(vertex, axis):
    """:func:`quad_turn_cosines` of some edges (r, c) across rows (``axis`` 0) or columns (1), the same products
    in the same order (so the same numbers): ``vertex(dr, dc)`` gives the posed grid's three coordinates at
    (r + dr, c + dc) of each."""
    def normal(dr, dc):  # the quad (r + dr, c + dc)'s unit normal
        a, b = vertex(dr + 1, dc + 1), vertex(dr, dc)
        e, f = vertex(dr, dc + 1), vertex(dr + 1, dc)
        d1, d2 = [p - q for p, q in zip(a, b)], [p - q for p, q in zip(e, f)]
        N = [d2[1] * d1[2] - d2[2] * d1[1], d2[2] * d1[0] - d2[0] * d1[2], d2[0] * d1[1] - d2[1] * d1[0]]
        length = np.sqrt(N[0] ** 2 + N[1] ** 2 + N[2] ** 2)
        length[length == 0] = 1.0
        return [x / length for x in N]
    before, after = normal(0, 0), normal(1, 0) if axis == 0 else normal(0, 1)
    return sum(x * y for x, y in zip(before, after))


def interval_turns(model, rows, cols, W, floor=0.0, stacks=None, buffers=None):
    """Largest turn (degrees) of the edges in each curve interval and each point interval, outside the
    openings, over the poses ``W`` (:func:`pose_weights`), on the mesh of ``rows``, ``cols`` steps.

    An edge across rows belongs to the curve intervals of the quads on both its sides, one across columns to their point
    intervals. Turns under ``floor`` are not looked at. The openings are those :func:`pdeface.surface.folds.fold_edges`
    allows: the landmark polygons at rest, where the pose carries them, and the edges that lie in them at rest. A pose
    turns edges as the rest does where it does not move the skin: only its moved block is measured. A pose of one key is
    measured as its key's batch is solved; only the keys of poses of several are kept. The keys are solved in float32
    (:func:`pdeface.surface.grid.key_grids`' ``dtype``): their moved rows and columns are read from them, and the poses'
    edges are screened on them as they are, a few poses in one array operation over the part of the grid their moved
    blocks cover, for those that could raise a need (:data:`SCREEN_MARGIN_DEG`); only those are measured in float64,
    with :func:`quad_turn_cosines`' products, on the rest (float64) plus the weight times the key (float32, upcast):
    the turns of the float64 keys to their float32 rounding (the steps the same on 47 faces, the needs within 0.002°
    under 25°; docs/design/folds.md). ``stacks``: :func:`pdeface.surface.grid.key_stacks` in float32, when made already
    (they do not depend on the steps; float64 ones are made again). ``buffers``: the key solves' buffers, a list
    (:meth:`pdeface.surface.pde.SurfaceOperator.planes`' ``reuse``), kept across meshes.
    """
    weights = break_weights(model, cols)  # the rest's and the keys' (the same columns)
    planes0 = surface_grid(model, rows, cols, planes=True, weights=weights)
    X0 = np.ascontiguousarray(np.moveaxis(planes0, 0, 2))
    n_u, n_v, _ = X0.shape
    K, J = len(model.knots), model.layout.n_points
    interval = [np.repeat(np.arange(K - 1), rows), np.repeat(np.arange(J - 1), cols)]  # of each quad row, column
    L = model_landmarks(model)
    nearest = nearest_vertices(X0.reshape(-1, 3), L, grid=(n_u, n_v))
    # each inner edge's midpoint at rest in the frontal view (the openings' x and y): across rows (on row r + 1),
    # across columns (on column c + 1)
    mids = (0.5 * (X0[1:-1, :-1, :2] + X0[1:-1, 1:, :2]), 0.5 * (X0[:-1, 1:-1, :2] + X0[1:, 1:-1, :2]))
    shut_at_rest = [~opening_mask(m.reshape(-1, 2), L).reshape(m.shape[:2]) for m in mids]
    flat0 = X0.reshape(-1, 3)
    need = [np.zeros(K - 1), np.zeros(J - 1)]
    known = nearest >= 0
    at_landmarks = np.where(known, nearest, 0)  # the posed grid is read only here and in the moved block
    rest_at_landmarks = flat0[at_landmarks]
    at_nearest = np.where(known, np.arange(len(nearest)), -1)
    found = []  # per pose with edges that may raise a need: (its landmarks' displacement, its edges)

    def settle():  # the edges found outside the openings raise their intervals' needs: one test for many poses
        if not found:
            return
        posed_L = carried(rest_at_landmarks, rest_at_landmarks + np.stack([moved for moved, _ in found]), L,
                          nearest=at_nearest)
        parts = [e for _, edges in found for e in edges]
        mid = np.concatenate([e[3] for e in parts])
        which = np.repeat(np.arange(len(found)), [sum(len(e[2]) for e in edges) for _, edges in found])
        # in the openings at rest or where the pose carries them: one test, the rest's landmarks a set of their own
        inside = opening_mask(np.concatenate([mid, mid]), np.concatenate([posed_L, L[None]]),
                              which=np.concatenate([which, np.full(len(mid), len(found))]))
        shut = ~(inside[:len(mid)] | inside[len(mid):])
        # each axis' edges of all the poses at once (a maximum is the same in any order)
        axis_of = np.repeat(np.tile([0, 1], len(found)), [len(e[2]) for e in parts])
        before, after, t = (np.concatenate([e[i] for e in parts]) for i in range(3))
        for axis in (0, 1):
            s = shut & (axis_of == axis)
            np.maximum.at(need[axis], np.concatenate([before[s], after[s]]), np.concatenate([t[s], t[s]]))
        found.clear()

    def measure(X, block, moved_landmarks):
        edges = _edges_over(X, block, shut_at_rest, interval, need, floor)
        if sum(len(e[2]) for e in edges):
            found.append((moved_landmarks, edges))
        if len(found) == SETTLE_POSES:
            settle()

    counts = np.count_nonzero(W, axis=1)
    if (counts == 0).any():  # the rest first: its needs spare most poses' edges the openings' test
        measure(list(planes0), np.s_[0:n_u, 0:n_v], np.zeros_like(rest_at_landmarks))
        settle()
    single = {}  # key → the poses of it alone
    for p in np.nonzero(counts == 1)[0]:
        single.setdefault(int(np.nonzero(W[p])[0][0]), []).append(p)
    several = np.nonzero(counts > 1)[0]
    kept = {int(k): None for k in np.nonzero(W[several].any(axis=0))[0]}  # key → its grid, for poses of several
    n = W.shape[1]
    rows_moved, cols_moved = np.zeros((n, n_u), bool), np.zeros((n, n_v), bool)
    rest_screened = _rest_diagonals(planes0)
    floor_cos = np.cos(np.radians(floor)) + 1e-9
    looked_at = {}  # the cosines each edge must fall under to be looked at, for the needs found so far
    scratch = _ScreenScratch()

    def measure_screened(G, w, blocks, vertex, moved_landmarks, origin=(0, 0)):
        """Poses ``rest + w[p] G[p]`` (``G`` float32 (poses, 3, n_u, n_v), or the grid's part from row and column
        ``origin`` on), each on its block: screened together, their candidates measured as :func:`_edges_over`
        measures a block, from ``vertex(pose, rows, cols)``: the posed grid's three coordinates in float64, as its
        block is posed (the same numbers). Runs of poses with like blocks are screened over the part of the grid
        their blocks cover (:func:`_screen_groups`; element by element, the whole grid's numbers there)."""
        R0, R1, C0, C1 = (np.array(a) for a in zip(*[(b[0].start, min(b[0].stop, n_u), b[1].start, min(b[1].stop, n_v))
                                                    for b in blocks]))
        edges = [[] for _ in blocks]
        # an edge is looked at past the floor and past the need of one of its intervals (the others cannot raise
        # one), shut at rest; the screen passes those a margin under that
        needs = need[0].tobytes() + need[1].tobytes()
        if needs not in looked_at:  # the needs changed (a settle raised one)
            looked_at.clear()
            looked_at[needs] = []
            for axis in (0, 1):
                lower = np.maximum(floor, np.minimum(need[axis][interval[axis][:-1]], need[axis][interval[axis][1:]]))
                cos = np.cos(np.radians(np.maximum(lower - SCREEN_MARGIN_DEG, 0.0))).astype(np.float32)
                looked = np.full((n_u - 2 + axis, n_v), NOT_LOOKED_COS)  # a column wider, as the screen's rows
                looked[:, :n_v - 1 - axis] = np.where(shut_at_rest[axis], cos[:, None] if axis == 0 else cos[None, :],
                                                      NOT_LOOKED_COS)
                looked_at[needs].append(looked)
        looked_cos = looked_at[needs]
        passed = ([], [])  # per axis: (pose, row, column) of the edges the screen passes
        for g in _screen_groups(R0, R1, C0, C1):
            r0, r1, c0, c1 = R0[g].min(), R1[g].max(), C0[g].min(), C1[g].max()  # the grid's part they cover
            # the edges with both quads in the part: across rows r0 .. r1 - 3, across columns c0 .. c1 - 3
            masks = _screened([d[:, r0:r1 - 1, c0:c1] for d in rest_screened],
                              G[g, :, r0 - origin[0]:r1 - origin[0], c0 - origin[1]:c1 - origin[1]],
                              w[g], [cos[r0:r1 - 2 + axis, c0:c1] for axis, cos in enumerate(looked_cos)], scratch)
            for axis, mask in enumerate(masks):
                if np.count_nonzero(mask):  # the indices read slower
                    q, r, c = np.unravel_index(np.flatnonzero(mask), mask.shape)  # 10x nonzero's speed in 3-d
                    passed[axis].append((q + g.start, r + r0, c + c0))
        if not (passed[0] or passed[1]):
            return  # no edge can raise a need (most screens of a finer mesh)
        for axis in (0, 1):
            if not passed[axis]:
                for e in edges:
                    e.append((np.zeros(0, int), np.zeros(0, int), np.zeros(0), np.zeros((0, 3))))
                continue
            q, r, c = (np.concatenate(a) for a in zip(*passed[axis]))
            # the edge and both its quads in the pose's block (as _edges_over's block slices give them)
            inside = (r >= R0[q]) & (r <= R1[q] - 3 + axis) & (c >= C0[q]) & (c <= C1[q] - 2 - axis)
            q, r, c = q[inside], r[inside], c[inside]
            # the posed corners of both quads, read at once: rows r .. r + 2 (across rows) or columns c .. c + 2
            corners = [(dr, dc) for dr in range(3 - axis) for dc in range(2 + axis)]
            posed = vertex(np.tile(q, len(corners)), np.concatenate([r + dr for dr, _ in corners]),
                           np.concatenate([c + dc for _, dc in corners]))
            corner = dict(zip(corners, zip(*(p.reshape(len(corners), -1) for p in posed))))
            cos = _edge_cosines(lambda dr, dc, corner=corner: corner[dr, dc], axis)
            looked = cos < floor_cos
            t = degrees_from_cos(cos[looked])
            over = t > floor
            chosen, t = np.nonzero(looked)[0][over], t[over]
            q, r, c = q[chosen], r[chosen], c[chosen]
            first = (r, c)[axis]
            before, after = interval[axis][first], interval[axis][first + 1]
            keep = (t > need[axis][before]) | (t > need[axis][after])
            q, before, after, t, chosen = q[keep], before[keep], after[keep], t[keep], chosen[keep]
            # the edge's ends: across rows (r + 1, c) and (r + 1, c + 1), across columns (r, c + 1) and (r + 1, c + 1)
            a, b = (corner[e] for e in (((1, 0), (1, 1)) if axis == 0 else ((0, 1), (1, 1))))
            mid = np.stack([0.5 * (x[chosen] + y[chosen]) for x, y in zip(a, b)], axis=1)
            bounds = np.searchsorted(q, np.arange(len(blocks) + 1))  # q increases: each pose's run
            for i, (s, e) in enumerate(zip(bounds[:-1], bounds[1:])):
                edges[i].append((before[s:e], after[s:e], t[s:e], mid[s:e]))
        for moved, e in zip(moved_landmarks, edges):
            if sum(len(x[2]) for x in e):
                found.append((moved, e))
            if len(found) == SETTLE_POSES:
                settle()

    buffers = [] if buffers is None else buffers
    # (m, 3, n_u, n_v) float32: each key's planes, each batch written over the last one's (fresh pages cost; issue
    # #35). They are the keys the turns are measured on: screened as they are, read in float64 at the candidates
    for first, grids in key_grids(model, rows, cols, planes=True, reuse=buffers, stacks=stacks, dtype=np.float32,
                                  weights=weights):
        m = len(grids)
        # a row or column moves where its largest displacement (of the three planes) is past MOVED_MM: the planes'
        # largest first (reductions over two axes at once read slower), their magnitudes in the solve's scratch
        largest = np.abs(grids, out=buffers[1][:grids.size].reshape(grids.shape)).max(axis=1)
        for axis, moved_lines in ((0, rows_moved), (1, cols_moved)):
            moved_lines[first:first + m] = largest.max(axis=2 - axis).astype(np.float64) > MOVED_MM
        at_landmarks_moved = grids.reshape(m, 3, n_u * n_v)[:, :, at_landmarks].astype(np.float64)
        poses = []  # (its key's grid, key, pose, block)
        for j, k in enumerate(range(first, first + m)):
            if k in kept:
                kept[k] = grids[j].copy()
            block = _moved_block(rows_moved[k], cols_moved[k])
            poses += [(j, k, p, block) for p in single.get(k, ())] if block is not None else []
        for part in (poses[i:i + SCREEN_POSES] for i in range(0, len(poses), SCREEN_POSES)):
            j = np.array([g for g, _, _, _ in part])
            w = W[[p for _, _, p, _ in part], [k for _, k, _, _ in part]]

            def vertex(q, r, c, grids=grids, j=j, w=w):
                return [w[q] * grids[j[q], i, r, c] + planes0[i, r, c] for i in range(3)]
            measure_screened(grids[j[0]:j[-1] + 1] if (np.diff(j) == 1).all() else grids[j], w,
                             [b for _, _, _, b in part], vertex, [wi * at_landmarks_moved[g].T for (g, _, _, _), wi
                                                                  in zip(part, w)])
    for p in several:
        keys = np.nonzero(W[p])[0]
        block = _moved_block(rows_moved[keys].any(axis=0), cols_moved[keys].any(axis=0))
        if block is None:
            continue
        G = sum(np.float32(W[p, k]) * kept[k][:, block[0], block[1]] for k in keys)[None]  # its block alone

        def vertex(q, r, c, keys=keys, p=p):
            return list(planes0[:, r, c] + np.tensordot(W[p, keys], np.stack([kept[k][:, r, c] for k in keys]), axes=1))
        moved = np.tensordot(W[p, keys], np.stack([kept[k].reshape(3, -1)[:, at_landmarks].T for k in keys]), axes=1)
        measure_screened(G, np.ones(1), [block], vertex, [moved], origin=(block[0].start, block[1].start))
    settle()
    return need


def capped_steps(steps):
    """``steps`` (rows, cols per interval) with the largest lowered to a common cap until the mesh has at most
    :data:`MAX_VERTICES` vertices (never under :data:`STEPS_RANGE`'s fewest), and whether any was lowered."""
    cap = max(int(max(s.max() for s in steps)), STEPS_RANGE[0])
    while cap > STEPS_RANGE[0] and np.prod([np.minimum(s, cap).sum() + 1 for s in steps]) > MAX_VERTICES:
        cap -= 1
    out = [np.minimum(s, cap) for s in steps]
    return out, any((o != s).any() for o, s in zip(out, steps))


@bounded  # its solves are small: more BLAS threads only spin, the more so on a busy machine (issue #35)
def adaptive_resolution(model, max_turn=MAX_TURN_DEG):
    """Steps per curve interval and per point interval (two tuples) keeping each edge's turn outside the
    openings under about ``max_turn`` at rest, at weight 1 of each descriptor and in each built-in preset.

    Each interval's largest turn ``t`` on the probe mesh (:data:`PROBE` steps; :func:`interval_turns`)
    gives it ``ceil(PROBE * t / max_turn)`` steps within :data:`STEPS_RANGE`. Then the mesh so chosen is
    measured the same way, once: an interval still over :data:`VERIFY_FACTOR` × ``max_turn`` gets steps in
    proportion to its measured turn, aiming for :data:`RAISED_AIM` × ``max_turn``, or the most steps where its
    turn shrank much less than its steps grew (:data:`NARROW`: a bend narrower than the probe's step). The mesh
    is kept under :data:`MAX_VERTICES` (:func:`capped_steps`); a capped choice is not checked (more steps are
    what it would ask for).
    """
    fingerprint = model_fingerprint(model)  # a digest of the descriptors: taken once
    known = known_resolution(model, max_turn, fingerprint)
    if known is not None:
        return known
    K, J = len(model.knots), model.layout.n_points
    W = pose_weights(model)
    lo, hi = STEPS_RANGE
    floor = max_turn * lo / PROBE  # turns below this leave an interval at the fewest steps
    stacks = key_stacks(model, dtype=np.float32)  # the keys' coefficients, for both meshes (solved in float32)
    # the solves' buffers, for both meshes: as large as the largest mesh the choice can measure (its pages are
    # touched as used), so the check faults in only the pages the probe did not touch (2.7 us a page here)
    probe_vertices, finest = (((K - 1) * s + 1) * ((J - 1) * s + 1) for s in (PROBE, hi))
    vertices = max(probe_vertices, min(MAX_VERTICES, finest))
    buffers = [np.empty(3 * KEY_BATCH * vertices, np.float32) for _ in range(2)]
    probed = interval_turns(model, (PROBE,) * (K - 1), (PROBE,) * (J - 1), W, floor, stacks=stacks, buffers=buffers)
    steps, capped = capped_steps([np.clip(np.ceil(PROBE * t / max_turn), lo, hi).astype(int) for t in probed])
    if not capped:
        bar = VERIFY_FACTOR * max_turn
        raised = []
        for s, t, p in zip(steps, interval_turns(model, *steps, W, bar, stacks=stacks, buffers=buffers), probed):
            expected = PROBE * np.maximum(p, floor) / s  # its turn if it shrank in proportion to the steps
            wanted = np.where(t > NARROW * expected, hi, np.ceil(s * t / (RAISED_AIM * max_turn)))
            raised.append(np.where((t > bar) & (s < hi), np.clip(wanted, s, hi), s).astype(int))
        steps, _ = capped_steps(raised)
    return remember_resolution(model, *steps, max_turn=max_turn, fingerprint=fingerprint)
