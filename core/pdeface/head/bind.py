"""Bind a user's whole head to its PDE face: every AU key on every vertex.

The PDE face covers the front of the face. :class:`HeadBinding` carries its
motion to all of the user's mesh, once per fit:

- **covered skin** (within ``COVER_IOD`` of the PDE surface and facing the same
  way) reads the PDE displacement at its closest (u, v); skin whose closest point
  lies on the strip between an opening's two rims, or on a rim's line (skin beyond the rim), is not covered (the
  strip is no skin: it blends both lips' motion);
- **the rest of the skin** (cheeks to the ears, forehead to the hairline, under
  the chin, inner lips, lid margins, nostrils, the mouth's lining) is the
  harmonic extension of that motion over the mesh (cotangent Laplacian,
  Dirichlet values on the covered skin), falling to exactly zero in the
  **rest region**: skin farther than ``REST_IOD`` eye distances from the
  covered skin, more than ``BELOW_CHIN_IOD`` below the chin, or deeper in the
  mouth than ``MOUTH_DEPTH_IOD`` behind the lips (in jaw AUs only its upper half), or the upper lining's
  top deeper than ``UPPER_LINING_IOD``.
  The README lists what else was tried and measured;
- **the openings' corners** (inner lip corners, inner eye corners): where the covered skin's motion meets the
  lining's, the skin within ``SEAM_IOD`` of the lining is relaxed towards its neighbours' mean motion
  (``SEAM_STEPS`` times): the seam's step folded the lining there (issue #40);
- **lips joined in the mesh** (no opening between them: a voxel remesh, a decimated mouth) cannot part without a
  new topology: the binding notes it; where they are one row of vertices, the skin under the PDE face's strip
  between the lips' rims reads the strip (it stretches from the upper rim's motion to the lower's) and the folds'
  relaxation keeps the upper lip, so AU27 moves the lower lip and stretches the skin joining them; elsewhere (a
  decimation merged the rims at the middle) the jaw's keys hold each inner lip's uncovered rim with its own lip
  and, in the jaw keys that part the lips (``PARTED_IOD``), their folds' relaxation keeps the lower lip (no beak);
- **jaw AUs** (25, 26, 27, 29, 30) turn the jaw's parts (lower teeth, gums,
  tongue) about the hinge with the rotation recovered from the chin's own PDE
  motion (:mod:`pdeface.rigid`);
- **a mouth bag** (part kind ``mouth``, :mod:`pdeface.head.mouth`) hangs from the lips: below the mouth line it
  turns with the jaw, above it it moves with the upper lip's middle; a head with no mouth inside (and no bag) is
  noted, and so are lips joined in the mesh, in :attr:`HeadBinding.warnings` as well;
- **gaze AUs** (61-64) turn the eyeballs about their fitted centres;
- **attached parts** (lashes, brows, hair cards, lacrimal meshes) ride on their
  nearest skin vertex, turning with its normal;
- **keys that close the eyes** (AU43, AU45, AU46) turn the upper lid about the eye's centre onto the lower
  lid (:mod:`pdeface.head.lids`);
- lids never end inside an eyeball: skin outside the eyeball sphere at rest is
  kept outside it;
- **no new folds**: each key is relaxed where it would fold the mesh (:mod:`pdeface.head.folds`);
- **the back of the head and the neck keep (nearly) still**: every key's motion but the rigid parts' fades, from
  STILL_BEHIND[0] to STILL_BEHIND[1] head depths behind the nose tip and from STILL_BELOW_CHIN_IOD[0] to [1] eye
  distances below the chin, to at most STILL_MM (issue #40: the skin before the ears and a body's neck moved
  0.5-1.2 mm).

Each key is the binding of one descriptor's PDE displacement at weight 1: still
one linear shape key per AU or expression, as on the PDE face.
"""
from __future__ import annotations

from copy import copy
from functools import cached_property

import numpy as np

from .. import landmark_scheme
from ..au.descriptor import Descriptor
from ..errors import MeshError, PdeFaceError
from ..facs import au_number, normalise_weights
from ..geometry import (
    ClosestPoint,
    any_corner,
    closest_point_on_triangles,
    column_bounds,
    cross3,
    every_corner,
    in_box,
    median_edge,
    row_dots,
    row_norms,
    smoothstep,
    triangle_cross,
    unit_rows,
)
from ..landmark_scheme import (
    CHIN,
    EYE_INNER_LEFT,
    EYE_INNER_RIGHT,
    INNER_LIPS,
    JAW_LEFT_ANGLE,
    JAW_RIGHT_ANGLE,
    LIP_LOWER_BOTTOM,
    LIP_LOWER_INNER,
    LIP_MIDDLES,
    LIP_UPPER_INNER,
    LIP_UPPER_TOP,
    MOUTH_CORNERS,
    NOSE_BOTTOM,
)
from ..mesh import connected_components, cotan_laplacian, facing_forward, seam_welds, vertex_normals
from ..posing import pose_curves
from ..presets import every_pose
from ..rigid import JAW_BONE_GAIN, gaze_matrix, jaw_hinge, jaw_motion, rigid_displacement, rotation_vector_matrix
from ..surface.grid import grid_faces, surface_grid
from ..surface.layout import ANCHOR_NAMES
from ..surface.model import KEPT_LANDMARKS
from ..surface.scan import load_scan
from ..threads import bounded
from . import folds as fold_relax
from .folds import FoldRelax, Screen
from .lids import LidClosure, eyes_closed_by, eyes_or_sockets
from .mouth import has_mouth_inside, lower_share
from .parts import TOUCH_IOD, classify_parts, eye_films, mouth_line, read_overrides
from .prior import CARRIED_KINDS, load_head_prior

#: The PDE face as the binding reads it: between an opening's rims the runs carry their own motion into the
#: strip (the break piece at their full slope), so skin hidden behind a lip or lid follows its rim, while the
#: mesh :func:`~pdeface.surface.fit.face_mesh` shows links the rims flat (pdeface.surface.pde.BREAK_SLOPE).
READ_BREAK_SLOPE = 1.0
#: PDE grid the binding reads (rows per curve interval, columns per point interval).
RESOLUTION = (4, 4)
#: Skin within this many eye distances of the PDE surface, facing its way, is covered by it.
COVER_IOD = 0.05
COVER_COS = 0.3
#: A closest point this near a grid line (in grid steps, or barycentric weight) lies on it (see :func:`_read_pde`).
GRID_LINE_TOL = 1e-6
#: Skin this far (eye distances) from the covered skin does not move,
REST_IOD = 1.1
#: nor skin this far below the chin.
BELOW_CHIN_IOD = 0.75
#: Skin inside the mouth this far (eye distances) behind the lips does not move (but with the jaw),
MOUTH_DEPTH_IOD = 0.8
#: nor the upper lining this far behind them, above the mouth line by UPPER_LINING_RISE_IOD: the vestibule's
#: top, bound to the upper jaw (ICT's stays put; free, the lips' motion spread into it: spill 0.3-0.5 mm).
UPPER_LINING_IOD = 0.5
UPPER_LINING_RISE_IOD = 0.15
#: The openings' corners: skin within SEAM_IOD eye distances of the lining (skin the PDE face does not cover) is
#: relaxed SEAM_STEPS times towards its neighbours' mean motion after the binding (issue #40: skin folds in the
#: worst key on the MakeHuman development set and ICT's head: see docs/measurements/keys_devset.md).
SEAM_IOD = 0.05
SEAM_STEPS = 5
#: (landmark, radius in eye distances) of the corners relaxed: the inner lips' and the eyes' inner ones.
SEAM_CORNERS = ((INNER_LIPS[0], 0.3), (INNER_LIPS[4], 0.3), (EYE_INNER_RIGHT, 0.15), (EYE_INNER_LEFT, 0.15))
#: Rings of the jaw's parts next to the skull's (a piece split between them) that the folds' relaxation moves
#: (ICT's AU27: 110 folds at 1 ring, 96 at 2, 65 at 4, but its jaw's capture 0.94, 0.92, 0.90).
SPLIT_RINGS = 2
#: The head prior fades out over this share of the way from the covered skin to the rest region.
PRIOR_FADE = 0.3
#: Inner lips' middles nearer than this (eye distances) are one row of vertices (a voxel remesh's). (The folds'
#: relaxation once kept their skin as bound on joined lips: stylised-nose-mouth's AU27 folded 21 edges against it.)
LIP_LINE_IOD = 0.03
#: Lips joined in the mesh (a voxel remesh, a decimated mouth): the inner lips' middles (landmarks 62, 66) are joined
#: by skin no longer than FUSED_PATH times their distance apart plus FUSED_IOD eye distances (touching lips with a
#: mouth behind them: the shortest way runs round a corner or through the mouth).
FUSED_PATH = 3.0
FUSED_IOD = 0.05
#: Where both inner lips' middles fall on one vertex, the skin within this many eye distances of it shows whether
#: the mesh parts the lips there (:func:`_rims_near`).
RIMS_IOD = 0.15
#: One point for both inner lips' middles is split onto rims a decimation merged at a vertex this near it (eye
#: distances): the found points lay 0.01-0.04 from one on the decimated heads; 0.08 on the 1.4k-vertex game head
#: (lowpoly-flat), whose vertex there is a lip's side, not its rim: a point farther from every vertex is split onto
#: the edge across the mouth line nearest it (:func:`_rims_merged_at`, :func:`_rims_across`).
RIMS_NEAR_IOD = 0.06
#: On joined lips the skin under the strip between the rims within this share of the mouth's width reads it (lips in
#: one line), or the fold relaxation of the jaw keys that part the lips keeps the lower lip there (rims a decimation
#: merged; PARTED_IOD).
JOINED_WIDTH = 0.6
#: On joined lips the folds' relaxation keeps the upper lip's skin this far (eye distances) above the mouth's middle.
UPPER_LIP_IOD = 0.03
#: Where a decimation merged the lips' rims, a jaw key keeps the inner lips' middles and the lower lip in its folds'
#: relaxation only where it parts the lips' outer middles (landmarks 51, 57) by this many eye distances (AU25 0.14-0.15
#: on decimated heads, the sad preset 0.05-0.07; AU29 0.01, AU30 none): kept in AU29, they folded a decimated
#: caucasian-female-young's lips 10 edges (the issue's limit 9; 2 relaxed with the rest), asian-female-young's 13 (1).
#: Keys are made at full weight; a pose solved at its own weights (``pose_motion_args``) is tested the same way, so on
#: such a head a jaw pose whose weight takes its parting across this changes its relaxation there (a step in a
#: sweep of weights: shape keys mixed in Blender are linear and do not see it).
PARTED_IOD = 0.03
#: Every key's motion fades, from the first to the second share of the head's depth behind the nose tip (the
#: issue's still back of the head starts at 0.6), and from the first to the second eye distance below the chin (a
#: body's neck: the under-jaw the jaw keys move lies above it), to at most STILL_MM. A head depth is at least
#: MIN_HEAD_DEPTH_IOD eye distances (a face mask has no back: its cheeks keep their motion). ICT's own scanned AU12
#: and AU27 move the skin in front of its ears 1.8 and 2.3 mm past 0.6. Measured on ICT's ten unseen identities
#: (bench_head's prior way, medians of medians, face / head; warp smoothing 0.1, ridge 0.01): no fade 0.950 / 0.927;
#: to zero from 0.55 0.946 / 0.920; capped at 0.4 mm from 0.55 0.949 / 0.923, from 0.58 0.949 / 0.925, a step at
#: 0.6 0.949 / 0.926; capped at 0.25 mm from 0.55 0.946 / 0.922. The fade below the chin costs ICT nothing.
STILL_BEHIND = (0.58, 0.6)
STILL_BELOW_CHIN_IOD = (1.0, 1.4)
MIN_HEAD_DEPTH_IOD = 2.5
#: ... capped at this (mm, the key's motion's size, its direction kept: the issue's 0.5 less a margin; per key, so
#: keys mixed may add up).
STILL_MM = 0.4
#: Keys that do not open the jaw relax their folds in up to this many sweeps (the jaw's in folds.RELAX_STEPS, 60):
#: asian-female-old's and eyes-teeth-separate's AU17 folded 18 edges at the mouth's inner corners after 60 (the
#: issue's limit 13), 8 and 6 after 150; for the jaw's keys more sweeps smooth parted lips shut (african-male-old's
#: AU27 gap 0.37 -> 0.26 eye distances).
STEPS_NOT_JAW = 150
#: Vertices worked on at a time where every key's rows are read and written (the keys' last step: the turn to user
#: space; the back of the head kept still): the block's rows stay in cache.
USER_BLOCK = 1024
#: Columns of the harmonic extension's right-hand sides solved at a time: SuperLU's solve of ICT's 216 (72 keys) at
#: once ran 1.1-1.4x slower (its work array out of cache), and their transposed scatter into the keys' rows 2x.
SOLVE_COLUMNS = 72
#: Attached vertices turned at a time (:meth:`HeadBinding._follow`): the block's temporaries reused, not fresh pages.
FOLLOW_BLOCK = 256
#: AUs that move the jaw, and the gaze AUs.
JAW_AUS = frozenset({25, 26, 27, 29, 30})
GAZE_AUS = frozenset({61, 62, 63, 64})


def _barycentric_matrix(tri_vertices, bary, n_columns):
    from scipy.sparse import csr_matrix

    rows = np.repeat(np.arange(len(bary)), 3)
    return csr_matrix((bary.ravel(), (rows, tri_vertices.ravel())), shape=(len(bary), n_columns))


class _Extension:
    """Harmonic extension over the skin of the PDE grid's motion: Dirichlet values read off the grid on the
    fixed vertices (covered skin; zero on the others), harmonic on the free ones (factorised once)."""

    _on_nodes = None  # :meth:`on_nodes`' extension, made on first use

    def __init__(self, L, fixed, read):
        from scipy.sparse.linalg import splu

        self.fixed, self.free = np.nonzero(fixed)[0], np.nonzero(~fixed)[0]
        free_rows = L[self.free]
        self.lu = splu(free_rows[:, self.free].tocsc()) if len(self.free) else None
        self.read = read[self.fixed].tocsr()  # grid → fixed values
        self.load = (-(free_rows[:, self.fixed] @ self.read)).tocsr()  # grid → the free rows' right-hand side

    def solve(self, G):
        """(fixed values, free values) for grid motions ``G`` (g, c)."""
        free = self.lu.solve(self.load @ G) if self.lu is not None else np.zeros((0, G.shape[1]))
        return self.read @ G, free

    def write(self, G, out, rows):
        """Write the extension of grid motions ``G`` (g, c) into ``out`` (n, c), at its rows ``rows[self.fixed]``
        and ``rows[self.free]``: :meth:`solve`'s values, the free ones solved :data:`SOLVE_COLUMNS` columns at a
        time and each block written while in cache."""
        fixed = rows[self.fixed]
        for start in range(0, len(fixed), USER_BLOCK):  # block by block: no fresh (fixed, c) array of every row
            block = slice(start, start + USER_BLOCK)
            out[fixed[block]] = self.read[block] @ G
        if self.lu is None:
            return
        # The right-hand sides are zero but on the few free rows next to a fixed one (ICT: 2,814 entries): those
        # rows' products alone, put in one zeroed block reused for every SOLVE_COLUMNS columns.
        loaded, free = self._loaded(), rows[self.free]
        part = self.load[loaded] @ G
        rhs = np.zeros((len(self.free), min(SOLVE_COLUMNS, G.shape[1])), order="F")
        for start in range(0, G.shape[1], SOLVE_COLUMNS):
            cols = slice(start, start + SOLVE_COLUMNS)
            width = part[:, cols].shape[1]
            rhs[loaded, :width] = part[:, cols]
            out[free, cols] = self.lu.solve(rhs[:, :width])

    def _loaded(self):
        """The free rows whose right-hand side has entries (:attr:`load`'s non-empty rows)."""
        return np.flatnonzero(np.diff(self.load.indptr))

    def on_nodes(self, slot):
        """This extension reading the grid's motion at the nodes read alone (``slot``: each grid node's row among
        them, :func:`_node_slots`); made once, the factorisation shared."""
        if self._on_nodes is None:
            self._on_nodes = copy(self)
            self._on_nodes.read, self._on_nodes.load = _on_nodes(self.read, slot), _on_nodes(self.load, slot)
        return self._on_nodes


def _node_slots(read_grid):
    """``(nodes, slot)``: the grid nodes ``read_grid`` reads (increasing) and each grid node's row among them (-1:
    not read)."""
    nodes = np.unique(read_grid.indices)
    slot = np.full(read_grid.shape[1], -1, np.int64)
    slot[nodes] = np.arange(len(nodes))
    return nodes, slot


def _on_nodes(read, slot):
    """A sparse map from grid nodes read as one from the nodes read alone (``slot``: :func:`_node_slots`): its
    entries as they were, in their order (the products sum the same terms in the same order)."""
    from scipy.sparse import csr_matrix

    read = read.tocsr()
    return csr_matrix((read.data, slot[read.indices], read.indptr), shape=(read.shape[0], slot.max() + 1))


def _check_on_skin(Lf, P, Ts, skin_tree, eye_distance):
    """Refuse landmarks off the skin ``(P, Ts)`` (a model fitted on another mesh, landmarks inside the head);
    ``skin_tree``: a ``cKDTree`` of ``P``.

    Measured to the nearest skin vertex: the median within 0.05 eye distances, or half the skin's median edge where
    that is longer (a point on a coarse head's surface lies up to about half an edge from every vertex: a game
    head's 1.4k vertices, its edges 0.2 eye distances, had its found landmarks a median 0.069 from one refused);
    the worst within 0.3. Not to the surface: ICT's landmarks pushed 3 cm into its head lie a median 0.038 eye
    distances from the mouth's and the eyes' sockets, 0.054 from their nearest vertex."""
    kept = np.nonzero(np.isfinite(Lf).all(axis=1))[0]
    off = skin_tree.query(Lf[kept])[0]
    limit = max(0.05 * eye_distance, 0.5 * median_edge(P, Ts))
    if np.median(off) > limit or off.max() > 0.3 * eye_distance:
        # (glasses in the same mesh: the eyes' landmarks found on the lenses, the worst 0.1 eye distances off)
        raise MeshError(f"the landmarks do not lie on skin (median {np.median(off):.3g} mm off it, the worst "
                        f"{off.max():.3g} mm, landmark {kept[np.argmax(off)]}): was the face fitted on this head, in "
                        "this unit, with landmarks on its face (not inside it, nor on something in front of it: "
                        "glasses, a visor, hair)?")


def _read_pde(model, P, N, eye_distance, resolution, skin_strips=(), on_strip=None):
    """Which skin points the PDE face covers, and the sparse map reading its grid at their closest points.

    ``skin_strips``: the breaks (:meth:`~pdeface.surface.layout.CurveLayout.breaks`) whose strip is skin (lips
    joined in the mesh): what lies under it (and where ``on_strip``, an (n,) bool array) reads the strip, which
    stretches from one rim's motion to the other's.
    """
    X0 = surface_grid(model, *resolution, break_slope=READ_BREAK_SLOPE, confine=False)
    nu, nv, _ = X0.shape
    # The grid's edges (Tp's): along u, along v, the quads' diagonals.
    along_u, along_v, diagonal = (row_norms(X0[1:] - X0[:-1]), row_norms(X0[:, 1:] - X0[:, :-1]),
                                  row_norms(X0[1:, 1:] - X0[:-1, :-1]))
    X0 = X0.reshape(-1, 3)
    Q = grid_faces(nu, nv)
    Tp = np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])
    # Only skin near the grid can be under it (the back of a head, a body: skip the exact query): within the cover
    # and Tp's first edges (along u, diagonals) of a grid vertex, and within the cover and 2/3 of the longest edge (a
    # point of a triangle lies that near a corner: skin farther is not covered; ICT's head: 6.5k queries, not 7k).
    edge = max(along_u[:, :-1].max(), diagonal.max())
    corner_reach = 2 / 3 * max(along_u.max(), along_v.max(), diagonal.max())
    reach = COVER_IOD * eye_distance + min(edge, corner_reach * (1 + 1e-6))
    closest = ClosestPoint(X0, Tp, balanced=False)  # a grid: no point repeated
    gap, nearest = np.full(len(P), np.inf), np.zeros(len(P), np.int64)
    lo, hi = column_bounds(X0)
    boxed = np.flatnonzero(in_box(P, lo - reach, hi + reach))  # the rest: farther from it
    gap[boxed], nearest[boxed] = closest.vtree.query(P[boxed], distance_upper_bound=reach)  # its grid's tree
    near = gap < np.inf
    dist, tri, bary = np.full(len(P), np.inf), np.zeros(len(P), np.int64), np.zeros((len(P), 3))
    if near.any():
        dist[near], tri[near], bary[near], _ = closest.query(P[near], nearest[near])
    # Each closest point's place on the grid (rows, columns), not its triangle's: skin beyond a convex grid line
    # (an opening's rim, where the strip turns in) is closest to a point on the line, as near the triangles on
    # either side of it, and which one the query returns is rounding's choice (issue #35: 4e-11 in the operators
    # moved a lid vertex of asian-male-young-blender-m from its rim onto the strip, and the folds' relaxation after
    # the blink then took 16 sweeps, not 10: closed 0.77 of the gap, not 0.86). A point on a line (within
    # GRID_LINE_TOL of a step) counts as on its side that is not covered: skin beyond a rim follows the lid's or
    # lip's extension, as it did in most draws (ICT's head covered then 5,749 vertices, now 5,715; the head prior
    # relearned with it).
    u, v = ((bary * (Tp[tri] // nv)).sum(1), (bary * (Tp[tri] % nv)).sum(1))
    inside = ((u > 1 + GRID_LINE_TOL) & (u < nu - 2 - GRID_LINE_TOL)
              & (v > 1 + GRID_LINE_TOL) & (v < nv - 2 - GRID_LINE_TOL))
    sub_u = resolution[0]  # curve k is grid row k * sub_u
    facing_free = np.zeros(len(P), bool)
    for k in model.layout.breaks():  # the strip between the rims is no skin: what lies under it follows its rim
        strip = (u > k * sub_u - GRID_LINE_TOL) & (u < (k + 1) * sub_u + GRID_LINE_TOL)
        if k in skin_strips:  # a joined mouth's skin, its rims (a row either side) facing otherwise than the strip
            reads = (u > k * sub_u - 1 + GRID_LINE_TOL) & (u < (k + 1) * sub_u + 1 - GRID_LINE_TOL)
            facing_free |= reads & (True if on_strip is None else on_strip)
            strip &= ~facing_free
        inside &= ~strip
    n_pde = unit_rows(triangle_cross(X0, Tp[tri]))
    # On a triangle's edge (a grid line or a quad's diagonal) the same normal whichever triangle the query returned:
    # the grid's, interpolated there (points not near the grid were not queried and read nothing)
    on_line = near & (bary.min(1) < GRID_LINE_TOL)
    if on_line.any():
        corners = Tp[tri[on_line]]  # the normals at their corners alone (from the grid's triangles around them)
        at, where = np.unique(corners, return_inverse=True)
        n_pde[on_line] = unit_rows(np.einsum("pc,pcx->px", bary[on_line],
                                             vertex_normals(X0, Tp, only=at)[where.reshape(corners.shape)]))
    covered = inside & (dist < COVER_IOD * eye_distance) & (facing_free | ((N * n_pde).sum(1) > COVER_COS))
    if covered.sum() < 100:
        raise MeshError(f"only {int(covered.sum())} skin vertices lie under the PDE face: "
                        "was the model fitted on this mesh, in this unit?")
    return covered, _barycentric_matrix(Tp[tri[covered]], bary[covered], len(X0))


def _lips_joined(P, Ts, Lf, eye_distance, skin_tree, normals) -> tuple:
    """``(joined, one_line, beside, middles)``: whether skin joins the inner lips' middles (landmarks 62 and 66), with
    no opening between the lips (a voxel remesh, a decimated mouth, a clustered one); whether they are one row of
    vertices there (nearest the same vertex, or within LIP_LINE_IOD: a voxel remesh's); and whether they are joined
    beside their middles alone; and the inner lips' middles it read (landmarks 62 and 66: given, or, nearest one
    vertex, split onto rims a decimation merged, :func:`_rims_merged_at`); ``skin_tree``: a ``cKDTree`` of the skin
    ``P``, ``normals`` its vertex normals.

    Joined: by a way about as short as the gap between them (FUSED_PATH, FUSED_IOD), or else, beside them, by any
    way; either way across the middle of the mouth's width (:func:`_mouth_middle`) and no deeper than FUSED_IOD
    behind them (ICT's generic head and its identity008 clustered on a 0.42 cm grid join them 0.07 eye distances
    aside, ways of 0.16 and 0.13 eye distances, FUSED_PATH's 0.12 and 0.10; touching lips with a mouth behind them
    part across the middle, and the way through the mouth runs deeper; a mouth open at rest has a way round its
    corner about as short as the short way's limit). Lips joined beside their middles are never one line."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    ends = Lf[[LIP_UPPER_INNER, LIP_LOWER_INNER]]
    if not np.isfinite(ends).all():
        return False, False, False, ends
    a, b = skin_tree.query(ends)[1]
    a, b = _rims_near(P, Ts, ends, a, b, eye_distance, skin_tree)  # on one lip (a detector's on closed lips)
    d = np.abs(P[a] - P[b])
    if d[0] > d[1] and np.linalg.norm(ends[0] - ends[1]) < LIP_LINE_IOD * eye_distance:
        # One point for both on two vertices side by side (more aside than one above the other): one row of a mouth
        # coarser than the lips, not each lip's rim. Read as the two lips' rims, caucasian-female-young decimated to
        # 1,815 vertices took its upper lip with the jaw in AU27 (its middle -0.55 eye distances; true landmarks -0.04).
        a = b = int(skin_tree.query(ends.mean(0))[1])
    apart = np.linalg.norm(P[a] - P[b])
    if a == b:  # one vertex for both: one found point, or two closer than the mesh's vertices
        a, b = _rims_merged_at(P, Ts, normals, a, b, ends.mean(0), eye_distance)
        if a != b:  # on rims a decimation merged: each lip's own
            ends = P[[a, b]]
            apart = np.linalg.norm(P[a] - P[b])
    reach = FUSED_PATH * apart + FUSED_IOD * eye_distance
    corners = Lf[MOUTH_CORNERS, 0]
    half_middle = 0.5 * JOINED_WIDTH * np.ptp(corners) if np.isfinite(corners).all() else 0.0
    # Either way stays within its reach of a: the short one within its length, the one across the middle within
    # the middle's half-width (a way round the corners leaves the middle). The edges inside that ball alone (the
    # same answer; the whole skin's edges' lengths cost ICT's binding 6 ms).
    near = np.asarray(skin_tree.query_ball_point(P[a], max(reach, half_middle) * (1 + 1e-9)), np.int64)
    ball = np.zeros(len(P), bool)
    ball[near] = True
    i, j = Ts.ravel(), np.roll(Ts, -1, axis=1).ravel()
    i, j = i[ball[i] & ball[j]], j[ball[i] & ball[j]]
    length = row_norms(P[i] - P[j])

    def way(keep, limit=np.inf):
        """Whether a way over the skin ``keep`` (an (n,) bool array) joins a and b, no longer than ``limit``."""
        e = keep[i] & keep[j]
        graph = coo_matrix((length[e], (i[e], j[e])), shape=(len(P), len(P))).tocsr()
        return bool(np.isfinite(dijkstra(graph, directed=False, indices=a, limit=limit)[b]))

    # The lips' front within the mouth's middle: a way round a corner or through the mouth joins no lips (ICT's jaw
    # open 0.4 at rest, its inner lips 0.25 eye distances apart: the way round a corner is about 3 times the gap, at
    # the short way's limit, and the detector's middles 0.024 eye distances aside fell within it)
    front = np.zeros(len(P), bool)
    front[near] = ((_mouth_middle(P[near], Lf) if half_middle else True)
                   & (P[near, 2] > min(P[a, 2], P[b, 2]) - FUSED_IOD * eye_distance))
    short = np.zeros(len(P), bool)
    short[near[row_norms(P[near] - P[a]) <= reach * (1 + 1e-9)]] = True
    short &= front
    if a == b or way(short, reach):
        return True, bool(apart < LIP_LINE_IOD * eye_distance), False, ends  # touching lips (ICT's): near, not joined
    if not half_middle:
        return False, False, False, ends
    front[near] &= row_norms(P[near] - P[a]) <= half_middle * (1 + 1e-9)
    beside = bool(front[a] and front[b] and way(front))
    return beside, False, beside, ends


def _rims_merged_at(P, Ts, normals, a, b, point, eye_distance) -> tuple:
    """``(upper, lower)``: where one point stands for both inner lips' middles (a detector's, where the lips touch)
    and ``a`` is their vertex (``b`` too), within RIMS_NEAR_IOD of it, and a mouth's lining (skin facing into the head:
    ``normals``' depth below 0) is joined to ``a`` by an edge, the rims a decimation merged there: ``a`` one lip's
    (the lower's where it faces up more than forward or back, else the upper's) and, of its neighbours more above it
    (below it) than aside, the one nearest ``point`` the other's. On a mouth coarser than that (no vertex near the
    point) the edge across the mouth line nearest it (:func:`_rims_across`). Otherwise ``(a, b)`` as they are: lips
    one row of vertices (a voxel remesh's) have no lining behind them.

    Read as one row, a decimated head's AU27 pulled the lips into a beak (decimated-cm with found landmarks: the lower
    lip's middle dropped 0.14 eye distances, a third of the way to each corner 0.09 and 0.06; true landmarks 0.55,
    0.07 and 0.12); the merged rims' holding (:func:`_merged_rims`) needs each lip's own middle. Split by the
    vertices' facing alone (down: the upper lip's, up: the lower's), decimated-cm's upper rim vertex, facing up into
    the mouth, read as the lower lip's and its upper lip sank 0.54 eye distances; ``a`` always the upper lip's, a
    point 0.01 eye distances lower fell on the lower rim and opened a beak on a decimated asian-female-young."""
    if np.linalg.norm(P[a] - point) > RIMS_NEAR_IOD * eye_distance:
        return _rims_across(P, Ts, normals, point, eye_distance) or (a, b)
    ring = np.unique(Ts[(Ts == a).any(axis=1)])
    if not (normals[ring, 2] < 0).any():
        return a, b
    on_lower = normals[a, 1] > abs(normals[a, 2])  # a faces the upper lip: the lower lip's rim
    rise = (P[ring, 1] - P[a, 1]) * (1 if on_lower else -1)
    other = ring[rise > np.abs(P[ring, 0] - P[a, 0])]  # across the mouth line, not along it
    if not len(other):
        return a, b
    other = int(other[np.argmin(row_norms(P[other] - point))])
    return (other, a) if on_lower else (a, other)


def _rims_across(P, Ts, normals, point, eye_distance):
    """``(upper, lower)`` on a mouth coarser than its lips (no vertex within RIMS_NEAR_IOD of ``point``, one point for
    both inner lips' middles): the ends of the edge across the mouth line (one end more above the other than aside)
    nearest the point, of the skin triangle the point lies on (within RIMS_NEAR_IOD of it), where a mouth's lining
    (skin facing into the head) is joined to either end by an edge; None otherwise (a point off the skin, lips one
    row of vertices with no lining behind them).

    A 1.4k-vertex game head (lowpoly-flat, edges 0.2 eye distances) has its lips' merged rims in a groove facing into
    the head and, in front of it, triangles joining the upper lip's front to the lower's, where the detector's point
    lies, its nearest vertex 0.08 eye distances aside on the upper lip: read as lips in one line, AU27 dropped the
    lower lip's middle 0.23 eye distances (true landmarks 0.52)."""
    reach = RIMS_NEAR_IOD * eye_distance + 2 * median_edge(P, Ts)  # the triangles that may lie that near
    near = row_norms(P - point) < reach
    tris = Ts[near[Ts].any(axis=1)]
    if not len(tris):
        return None
    q, _ = closest_point_on_triangles(np.broadcast_to(point, (len(tris), 3)), *(P[tris[:, k]] for k in range(3)))
    k = int(np.argmin(row_norms(q - point)))
    if np.linalg.norm(q[k] - point) > RIMS_NEAR_IOD * eye_distance:
        return None
    ends = np.stack([tris[k], np.roll(tris[k], -1)], 1)  # the triangle's three edges
    d = P[ends[:, 0]] - P[ends[:, 1]]
    ends = ends[np.abs(d[:, 1]) > np.abs(d[:, 0])]  # across the mouth line, not along it
    if not len(ends):
        return None
    A, B = P[ends[:, 0]], P[ends[:, 1]]
    t = np.clip(row_dots(q[k] - A, B - A) / np.maximum(row_dots(B - A, B - A), 1e-300), 0, 1)
    i, j = (int(e) for e in ends[np.argmin(row_norms(A + t[:, None] * (B - A) - q[k]))])
    joined = np.unique(Ts[(Ts == i).any(axis=1) | (Ts == j).any(axis=1)])
    if not (normals[joined, 2] < 0).any():
        return None
    return (i, j) if P[i, 1] > P[j, 1] else (j, i)


def _rims_near(P, Ts, ends, a, b, eye_distance, skin_tree) -> tuple:
    """``(a, b)``: the skin vertices nearest the inner lips' middles ``ends`` (landmarks 62, 66), ``a`` and ``b``,
    each moved onto its own lip where both lie on one piece of the skin within RIMS_IOD of their midpoint (joined
    by its edges there) and another piece of 3 vertices or more comes as near as RIMS_IOD / 2: the mesh parts the
    lips there, the upper one the piece whose skin lies higher on average. Otherwise as they are.

    A detector puts both points on one place where the lips touch: on MakeHuman's heads (their lips apart in the
    mesh, touching, the lower rim 0.04 eye distances in front of the upper) both fell on one lip, read as lips
    joined in one row, and AU27 scalloped the lips' edge (caucasian-female-young: 41 new folds; 4 with the true
    landmarks, 6 now)."""
    middle = (P[a] + P[b]) / 2
    near = np.asarray(skin_tree.query_ball_point(middle, RIMS_IOD * eye_distance), np.int64)
    local = np.full(len(P), -1)  # each skin vertex's place in near (-1: outside the ball)
    local[near] = np.arange(len(near))
    if local[a] < 0 or local[b] < 0:
        return a, b
    inside = local >= 0
    around = Ts[inside[Ts[:, 0]] | inside[Ts[:, 1]] | inside[Ts[:, 2]]]  # touching the ball (by column: ICT 0.2 ms)
    i, j = local[around.ravel()], local[np.roll(around, -1, axis=1).ravel()]
    kept = (i >= 0) & (j >= 0)  # the edges within the ball (a triangle half in it still joins its corners in it)
    pieces = connected_components(len(near), np.column_stack([i[kept], j[kept], j[kept]]))
    own, sizes = pieces[local[a]], np.bincount(pieces)
    other = (pieces != own) & (sizes[pieces] > 2) & (row_norms(P[near] - middle) < 0.5 * RIMS_IOD * eye_distance)
    if pieces[local[b]] != own or not other.any():
        return a, b
    nearest = np.flatnonzero(other)[np.argmin(row_norms(P[near[other]] - middle))]
    lips = [near[pieces == own], near[pieces == pieces[nearest]]]
    if P[lips[0], 1].mean() < P[lips[1], 1].mean():
        lips.reverse()
    return tuple(int(lip[np.argmin(row_norms(P[lip] - end))]) for lip, end in zip(lips, ends))


def _rest_region(P, Ts, covered, from_covered, Lf, eye_distance, pieces=None):
    """Skin that never moves: far from the covered skin (``from_covered``: distances to it), well below the
    chin, or in a piece it misses (``pieces``: each skin vertex's piece label, where known)."""

    far = from_covered > REST_IOD * eye_distance
    lab = connected_components(len(P), Ts) if pieces is None else pieces
    return ((far | _below_chin(P, Lf, eye_distance)) & ~covered) | ~np.isin(lab, np.unique(lab[covered]))


def _below_chin(X, Lf, eye_distance):
    return X[:, 1] < Lf[CHIN, 1] - BELOW_CHIN_IOD * eye_distance


def _prior_reach(Vf, from_covered, skin_rest, Lf, eye_distance, eyeballs=None):
    """How much of the head prior each vertex takes: none in the rest region (``skin_rest``: its vertex
    indices) nor below the chin's rest line, fading in over the last PRIOR_FADE of the way to the rest
    region (no step where it starts); none in an empty socket's cup behind where its eyeball would sit (an eye
    not in ``eyeballs``: ICT's orbit residuals moved MakeHuman's base's cup 2-6 mm in a blink)."""
    reach = np.clip((REST_IOD * eye_distance - from_covered) / (PRIOR_FADE * REST_IOD * eye_distance), 0, 1)
    reach = reach * reach * (3 - 2 * reach)
    reach[skin_rest] = 0.0
    reach[_below_chin(Vf, Lf, eye_distance)] = 0.0
    for name, (centre, radius) in eyes_or_sockets(Lf, eye_distance, eyeballs).items():
        if name not in (eyeballs or {}):
            reach[(from_covered > 0) & (row_norms(Vf - centre) < radius + 0.1 * eye_distance)
                  & (Vf[:, 2] < centre[2])] = 0.0
    return reach


def still_weight(X, P, Lf, eye_distance) -> np.ndarray:
    """How much of every key's motion each point ``X`` (face frame) keeps: 1 on the face, fading to 0 at the back of
    the head (STILL_BEHIND head depths behind the nose tip) and down a body's neck (STILL_BELOW_CHIN_IOD), where
    the motion left is at most STILL_MM (:meth:`HeadBinding._keep_still`).

    The nose tip is the skin's foremost point within half an eye distance of the nose's base (landmark 33: a model
    file keeps no tip); the head's depth its distance in front of the farthest skin ``P`` above the chin and within
    1.5 eye distances of the nose sideways (a body's arms and a hair card's tips left out).
    """
    nose, chin_y = Lf[NOSE_BOTTOM], Lf[CHIN, 1]
    near_nose = row_norms(P - nose) < 0.5 * eye_distance
    tip_z = P[near_nose, 2].max() if near_nose.any() else nose[2]
    head = (P[:, 1] > chin_y) & (np.abs(P[:, 0] - nose[0]) < 1.5 * eye_distance)
    depth = max(tip_z - P[head, 2].min() if head.any() else 0.0, MIN_HEAD_DEPTH_IOD * eye_distance)
    (a, b), (c, d) = STILL_BEHIND, STILL_BELOW_CHIN_IOD
    behind = smoothstep((b - (tip_z - X[:, 2]) / depth) / (b - a))
    below = smoothstep((d - (chin_y - X[:, 1]) / eye_distance) / (d - c))
    return behind * below


def _mouth_middle(P, Lf):
    """Skin within the middle of the mouth's width (JOINED_WIDTH of it): on lips in one line it reads the stretching
    strip between the rims (towards the corners it folded a decimated head's lips); on rims a decimation merged the
    fold relaxation of the jaw keys that part the lips keeps the lower lip there (:func:`_lower_lip`,
    ``PARTED_IOD``)."""
    corners = Lf[MOUTH_CORNERS, 0]
    return np.abs(P[:, 0] - corners.mean()) < 0.5 * JOINED_WIDTH * np.ptp(corners)


def _inner_lip_middles(P, Lf, eye_distance, lines=((61, 62), (62, 63), (65, 66), (66, 67))):
    """Skin on the inner lips' middle thirds (landmarks 61-63, 65-67): kept by the jaw keys' fold relaxation on lips
    joined in the mesh, which it would otherwise smooth shut in AU27 where they meet in one row of vertices (a
    decimated head). Lips apart are not kept: the step between a kept middle and its relaxed neighbours folded parted
    lips' AU27 (36 edges on parted-lips-cm, 4 without). ``lines``: the landmark pairs whose segments are the middles
    (the default: both inner lips' middle thirds; ``_merged_rims`` passes one lip's)."""
    from scipy.spatial import cKDTree

    t = np.linspace(0, 1, 8, endpoint=False)[:, None]
    along = np.concatenate([Lf[a] + t * (Lf[b] - Lf[a]) for a, b in lines] + [Lf[[b for _, b in lines[1::2]]]])
    along = along[np.isfinite(along).all(axis=1)]  # a landmark may be missing
    if not len(along):
        return np.zeros(len(P), bool)
    near = cKDTree(along).query(P, distance_upper_bound=LIP_LINE_IOD * eye_distance)[0]
    return np.isfinite(near)


def _merged_rims(P, covered, fixed, Lf, eye_distance, skin_tree, beside=False):
    """``(held, anchors)`` on lips joined in the mesh: the skin the PDE face does not cover (nor ``fixed``: rest,
    depths) on each inner lip's middle third (at its landmarks, 61-63 or 65-67, or on their line on its side of the
    mouth line), not at the other lip's landmarks, and each one's nearest covered skin of its own lip. A decimation
    merges the lips' rims there: free, such a vertex took both lips' motion (decimated-cm's upper lip sank 0.24 eye
    distances in AU27, following the jaw); held, each rim follows its lip and the skin joining them stretches.
    ``beside``: lips joined beside their middles alone (:func:`_lips_joined`): each middle its own lip's, the sides
    split half-way between the inner lips (:func:`_inner_lips_between`), not at the mouth line.

    The anchors, the PDE face's lips, are told apart half-way between the inner lips whatever splits the rims: where
    the corners turn down the mouth line passes under the lower lip's rim, and the upper rim anchored on the lower
    lip sank with the jaw (ICT's head clustered on a 0.5 cm grid: AU27's upper lip -0.60 eye distances, gap -0.04;
    anchored on its own lip -0.08 and 0.48; caucasian-female-old decimated to 4,000 vertices -0.56 and 0.00, -0.04 and
    0.52). The rims themselves stay split at the mouth line where they merged at the middle (split half-way,
    decimated-cm's AU27 folded 9 edges, not 1)."""
    empty = np.zeros(0, np.int64)
    if not np.isfinite(Lf[list(INNER_LIPS)]).all():
        return empty, empty
    from scipy.spatial import cKDTree

    at = skin_tree.query(Lf[list(INNER_LIPS)])[1]  # 60-67: the corners 60 and 64 are both lips'
    free = ~covered & ~fixed
    above_half_way = P[:, 1] > _inner_lips_between(P, Lf)
    side = above_half_way if beside else P[:, 1] > mouth_line(Lf)
    held, anchors = [empty], [empty]
    for own, other, lines, upper in ((at[1:4], at[5:8], ((61, 62), (62, 63)), True),
                                     (at[5:8], at[1:4], ((65, 66), (66, 67)), False)):
        on_side = side if upper else ~side
        rim = np.union1d(own, np.nonzero(_inner_lip_middles(P, Lf, eye_distance, lines) & on_side)[0])
        rim = np.setdiff1d(rim[free[rim]], other)
        lip = np.nonzero(covered & (above_half_way if upper else ~above_half_way))[0]
        if len(rim) and len(lip):
            held.append(rim)
            anchors.append(lip[cKDTree(P[lip]).query(P[rim])[1]])
    # The two rims share no vertex: each drops the other lip's landmark vertices, and their middles lie on opposite
    # sides of the mouth line.
    return np.concatenate(held), np.concatenate(anchors)


def _inner_lips_between(P, Lf):
    """The height (face frame) half-way between the inner lips under each point ``P``: the middles of their facing
    landmarks (61-67, 62-66, 63-65), linearly across the middle third, level beyond it. The mouth line (the corners'
    too) lay 0.005 eye distances below the lower inner lip's middle on ICT's head clustered on a 0.42 cm grid (its
    corners turn down): the lower lip's rim, above it, was held with the upper lip (AU27 folded 25 edges, 19 split
    here). Where the rims merged at the middle the mouth line still splits them (split here, decimated-cm's AU27
    folded 9 edges, not 1), but not their anchors (:func:`_merged_rims`)."""
    facing = Lf[[61, 62, 63]] + Lf[[67, 66, 65]]
    order = np.argsort(facing[:, 0])
    return np.interp(P[:, 0], facing[order, 0] / 2, facing[order, 1] / 2)


def _lower_lip(P, covered, Lf):
    """The lower lip's skin the PDE face covers (below the mouth line, above the lower lip's bottom, landmark 57) within
    the middle of the mouth's width (:func:`_mouth_middle`): kept by the fold relaxation of the jaw keys that part
    the lips (``PARTED_IOD``) where a decimation merged the lips' rims. Relaxed, it followed the rims held with the
    upper lip up: decimated-cm's AU27 opened a beak (its lower lip a third of the way to each corner sank 0.34 and
    0.30 eye distances, its middle 0.48); kept, 0.53, 0.47 and 0.55, and 1 edge folded, not 5. Towards the corners
    it moves with the relaxation (kept to the corners, decimated-cm's folded 3 edges there)."""
    return covered & _mouth_middle(P, Lf) & (P[:, 1] <= mouth_line(Lf)) & (P[:, 1] > Lf[LIP_LOWER_BOTTOM, 1])


def _upper_lip(P, Lf, eye_distance):
    """Skin between the nose's base and the mouth's middle line, no wider than the mouth (half an eye distance
    beyond each corner): kept by the folds' relaxation on joined lips, which would otherwise spread the stretch of
    the skin joining them up into the upper lip."""
    corners = Lf[MOUTH_CORNERS, 0]
    middle = Lf[[LIP_UPPER_INNER, LIP_LOWER_INNER], 1].mean()
    return ((P[:, 1] > middle + UPPER_LIP_IOD * eye_distance) & (P[:, 1] < Lf[NOSE_BOTTOM, 1])
            & (P[:, 0] > corners.min() - 0.05 * eye_distance) & (P[:, 0] < corners.max() + 0.05 * eye_distance)
            & (P[:, 2] > Lf[LIP_MIDDLES, 2].min() - 0.1 * eye_distance))


def _depths(P, covered, Lf, eye_distance, eyes):
    """The mouth's depths (lining, throat) and the orbits behind the eyeballs (or where they would sit: an empty
    socket's cup): left at rest.

    The lips' motion would otherwise spread through the whole mouth (ICT-FaceKit's truth fades), the lids' through an
    empty socket (MakeHuman's base: its blink moved the cup behind the lids 6 mm, 17 mm deep; its own eye closure
    keeps it still).
    """
    lips_z = Lf[LIP_MIDDLES, 2].max()
    inside = ~covered & (np.abs(P[:, 0]) < 0.6 * eye_distance) & (P[:, 1] < Lf[NOSE_BOTTOM, 1])
    depths = inside & (P[:, 2] < lips_z - MOUTH_DEPTH_IOD * eye_distance) & (P[:, 1] > Lf[CHIN, 1])
    depths |= (inside & (P[:, 2] < lips_z - UPPER_LINING_IOD * eye_distance)
               & (P[:, 1] > mouth_line(Lf) + UPPER_LINING_RISE_IOD * eye_distance))
    for centre, radius in eyes_or_sockets(Lf, eye_distance, eyes).values():
        depths |= ~covered & (row_norms(P - centre) < radius + 0.1 * eye_distance) & (P[:, 2] < centre[2])
    return depths


def _seam_smoother(P, L, covered, rest, Lf, eye_distance):
    """``(band, reads, S, weight, steps)``: the skin at the openings' corners near their lining (skin the PDE
    face does not cover), the skin those steps read (the band first, then its other neighbours), the map from the
    read skin to each band vertex's neighbours' mean motion (cotangent weights: a harmonic lining is left as it is),
    and how far each relaxes per step (fading to 0 at the band's edges: no new step there); None when SEAM_STEPS is
    0 or there is no band."""
    from scipy.sparse import csr_matrix, diags
    from scipy.spatial import cKDTree

    lining = ~covered & ~rest
    if not SEAM_STEPS or not lining.any():
        return None
    at_corner = np.zeros(len(P))
    reach = np.zeros(len(P), bool)  # the lining within SEAM_IOD of a corner's skin lies this near its landmark
    for i, r in SEAM_CORNERS:
        apart = row_norms(P - Lf[i])
        at_corner = np.maximum(at_corner, smoothstep(1 - apart / (r * eye_distance)))
        reach |= apart < (r + SEAM_IOD) * eye_distance * (1 + 1e-9)
    near = np.zeros(len(P))  # read at the corners alone: elsewhere the weight is 0 whatever it is
    corner = np.flatnonzero(at_corner > 0)
    if len(corner) and (lining & reach).any():  # the distances to the lining near the corners: all within the band
        near[corner] = smoothstep(1 - cKDTree(P[lining & reach]).query(
            P[corner], distance_upper_bound=SEAM_IOD * eye_distance)[0] / (SEAM_IOD * eye_distance))  # inf (0) beyond
    weight = at_corner * near * ~rest
    band = np.nonzero(weight > 0)[0]
    if not len(band):
        return None
    W = (diags(L.diagonal()) - L).tocsr()  # the Laplacian's (clamped, positive) neighbour weights
    S = (diags(1.0 / np.maximum(L.diagonal(), 1e-300)[band]) @ W[band]).tocsr()  # the band's rows, as scipy makes them
    reads = np.union1d(band, S.indices)  # a few hundred rows of the skin's, not all of it for every key
    S = S[:, reads].tocsr()
    # The band's rows first: each step reads and writes them as one slice. The columns renamed in place, each row's
    # terms kept in their order: the same sums.
    at = np.searchsorted(reads, band)
    order = np.concatenate([at, np.setdiff1d(np.arange(len(reads)), at)])
    renamed = np.empty(len(reads), S.indices.dtype)
    renamed[order] = np.arange(len(reads))
    S = csr_matrix((S.data, renamed[S.indices], S.indptr), shape=S.shape)
    return band, reads[order], S, weight[band, None], SEAM_STEPS


class HeadBinding:
    """The linear map from a PDE face's motion to every vertex of the user's head mesh.

    Parameters
    ----------
    model : FaceModel
        Fitted on this mesh (retargeted descriptors or its own).
    vertices : (n, 3) array
        The head in the user's space and unit (the one the model was fitted in).
    triangles : (t, 3) int array
    landmarks : (68, 3) array, optional
        The landmarks (user space) for a model file that does not carry them (pdeface 0.1).
    overrides : dict, optional
        Part kind → vertex indices (see :func:`pdeface.head.parts.classify_parts`).
    prior : HeadPrior, ``"bundled"`` or None
        Motion learned from scans beyond the harmonic extension (:mod:`pdeface.head.prior`):
        ICT-FaceKit's by default; None for the PDE face and its extension alone.
    """

    @bounded
    def __init__(self, model, vertices, triangles, landmarks=None, overrides=None, resolution=RESOLUTION,
                 prior="bundled"):
        from scipy.sparse import csr_matrix
        from scipy.spatial import cKDTree


        V = np.asarray(vertices, np.float64)
        T = np.asarray(triangles, np.int64)
        if V.ndim != 2 or V.shape[1] != 3 or not np.isfinite(V).all():
            raise MeshError("head vertices must be a finite (n, 3) array")
        if len(T) == 0 or T.min() < 0 or T.max() >= len(V):
            raise MeshError("head triangles are empty or index missing vertices")
        # Copies split along UV or normal seams: one vertex for the skin's topology; the copies ride on it.
        pieces = connected_components(len(V), T)  # the welding's, and the parts' where it joins nothing
        rep = seam_welds(V, T, pieces=pieces)
        seams = int((rep != np.arange(len(V))).sum())
        if seams:
            T = rep[T]
            T = T[(T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 2] != T[:, 0])]
            pieces = None
        self.model, self.resolution = model, resolution
        self.frame = frame = model.frame
        self.V = V
        self.Vf = Vf = frame.to_face(V)
        if landmarks is not None:
            Lf = frame.to_face(np.asarray(landmarks, np.float64))
        elif model.landmarks is not None and np.isfinite(model.landmarks[list(KEPT_LANDMARKS)]).all():
            Lf = model.landmarks
        else:
            raise MeshError("this face model carries no landmarks (made by pdeface 0.1): give the head's landmarks "
                            "or refit the face")
        # Normals all pointing inwards (a mirrored export), turned outwards: the skin's normals read the PDE face.
        T = facing_forward(Vf, T, Lf)
        self.eye_distance = eye_distance = landmark_scheme.eye_distance(Lf)
        self.hinge = jaw_hinge(Lf, eye_distance)
        self.parts = parts = classify_parts(Vf, T, Lf, self.hinge, overrides, welded=True, pieces=pieces)
        # Seam copies take their vertex's kind and, in the end, its motion; nothing else counts them.
        self._copies = np.nonzero(rep != np.arange(len(V)))[0]
        self._copy_of = rep[self._copies]
        parts.kind[self._copies] = parts.kind[self._copy_of]
        original = np.ones(len(V), bool)
        original[self._copies] = False
        self.notes = list(parts.notes) + ([f"{seams} vertices split along seams joined"] if seams else [])

        # Skin: its own index space.
        skin = parts.mask("skin") & original
        self.skin = si = np.nonzero(skin)[0]
        if len(si) == 0:
            raise MeshError("no skin: the landmarks lie on no part of this mesh")
        P = Vf[si]
        skin_tree = cKDTree(P)  # the landmarks' check, the lips' ends, the attached parts' anchors
        local = np.full(len(V), -1)
        local[si] = np.arange(len(si))
        Ts = local[T[every_corner(skin, T)]]
        if len(Ts) == 0:
            raise MeshError("the skin has no triangles")
        _check_on_skin(Lf, P, Ts, skin_tree, eye_distance)
        self.skin_normals = vertex_normals(P, Ts)
        mouth_strip = [k for a, k in model.layout.opening_curves() if ANCHOR_NAMES[a] == "mouth_top"]
        lips_joined, self.lips_one_line, joined_beside, middles = (
            _lips_joined(P, Ts, Lf, eye_distance, skin_tree, self.skin_normals) if mouth_strip
            else (False, False, False, Lf[[LIP_UPPER_INNER, LIP_LOWER_INNER]]))
        if not np.array_equal(middles, Lf[[LIP_UPPER_INNER, LIP_LOWER_INNER]], equal_nan=True):
            Lf = Lf.copy()  # one found point split onto merged rims: the binding reads the lips' own middles
            Lf[[LIP_UPPER_INNER, LIP_LOWER_INNER]] = middles
        #: The landmarks (face frame) the keys and the mouth bag read: the given ones, but for one found point for both
        #: inner lips' middles split onto rims a decimation merged. The parts (:attr:`parts`) were classified before
        #: that, on the given ones.
        self.face_landmarks = Lf
        if lips_joined:
            self.notes.append("the lips are joined in the mesh (no opening between them): keys that open the mouth "
                              "move the lower lip and stretch the skin joining it to the upper one; cut the mouth "
                              "open (the add-on's Cut Lips Open, or in your modeller), fit again and add a mouth "
                              "bag for lips that part")
        if not parts.mask("mouth").any() and not has_mouth_inside(P, Ts, Lf, eye_distance):
            self.notes.append("no mouth inside the lips: keys that open the mouth show the inside of the head; add a "
                              "mouth bag (the add-on's Add Mouth Bag, or a part of kind 'mouth')")
        #: The notes that ask the user to change something (the add-on reports them as warnings).
        self.warnings = [n for n in self.notes if n.startswith(("the lips are joined", "no mouth inside"))]
        # Lips one row of vertices have no rims of their own: the strip between the PDE face's rims is their skin.
        covered, self.read_grid = _read_pde(model, P, self.skin_normals, eye_distance, resolution,
                                            mouth_strip if self.lips_one_line else (), _mouth_middle(P, Lf))
        self.covered = covered
        # every vertex's distance to the covered skin, as far as the rest region and the prior's fade read it (inf
        # beyond, and on the parts the prior does not carry: their fade is never read; ICT's eyeballs, teeth and gums
        # were half the queries). The covered skin is a sheet, most queries far from it: a tree without shrunk boxes
        # answers 2× faster. The covered vertices themselves are at 0 (a sixth of ICT's head's queries).
        from_covered = np.full(len(Vf), np.inf)
        from_covered[si[covered]] = 0.0
        measured = parts.mask(*CARRIED_KINDS)
        measured[si[covered]] = False
        from_covered[measured] = cKDTree(P[covered], balanced_tree=False, compact_nodes=False).query(
            Vf[measured], distance_upper_bound=REST_IOD * eye_distance * (1 + 1e-9))[0]  # exact up to the edge
        # The skin's pieces are the parts' where it is whole ones (no override split one): the same partition.
        size = np.bincount(parts.pieces)
        whole = (np.bincount(parts.pieces[si], minlength=len(size)) == size)[parts.pieces[si]].all()
        self.rest = rest = _rest_region(P, Ts, covered, from_covered[si], Lf, eye_distance,
                                        parts.pieces[si] if whole else None)
        depths = _depths(P, covered, Lf, eye_distance, parts.eyes)
        # The folds' relaxation's Laplacian (the head but a mouth bag) holds the skin's, where no triangle joins the
        # skin to another part (an override may): the same sums in the same order, built once.
        # The films on the eyes (ICT's occlusion and tear-line meshes) are left out of it with the mouth bag: hidden
        # under the lids, they crumple in ICT's own scanned blink (AU45: 253 folded edges, three times the issue's
        # limit) and relaxing them took 0.2 s CPU of ICT's rig (issue #35); see docs/design/head.md.
        self.films = eye_films(parts, Vf)
        relaxed_T = ~every_corner(parts.mask("mouth") | self.films, T)
        fold_T = T[relaxed_T]
        fold_L = cotan_laplacian(Vf, fold_T)
        self._L = L = fold_L[si][:, si] if len(Ts) == any_corner(skin, fold_T).sum() else cotan_laplacian(P, Ts)
        cov = np.nonzero(covered)[0]  # the grid read at every skin vertex (rows of the covered ones)
        self._read_skin = csr_matrix((np.ones(len(cov)), (cov, np.arange(len(cov)))),
                                     shape=(len(P), len(cov))) @ self.read_grid
        self._ext = _Extension(L, covered | rest | depths, self._read_skin)
        self._jaw_fixed = covered | rest | (depths & (P[:, 1] > mouth_line(Lf)))  # the jaw moves the lower depths
        self._read_jaw = self._read_skin
        if lips_joined and not self.lips_one_line:  # rims merged by a decimation held with their lips
            held, anchor = _merged_rims(P, covered, rest | depths, Lf, eye_distance, skin_tree, joined_beside)
            self._jaw_fixed[held] = True
            pick = np.arange(len(P))
            pick[held] = anchor
            self._read_jaw = csr_matrix((np.ones(len(P)), (np.arange(len(P)), pick)), shape=(len(P),) * 2) @ \
                self._read_skin
        self._ext_jaw = None  # factorised on first use
        self._seam = _seam_smoother(P, L, covered, rest, Lf, eye_distance)
        # The back of the head and the neck keep still; the rigid parts turn whole.
        still = still_weight(Vf, P, Lf, eye_distance)
        still[parts.mask("eye_L", "eye_R", "jaw", "mouth")] = 1.0
        self._fading = np.nonzero(still < 1)[0]
        self._still = still[self._fading, None, None]
        # Each key relaxed where it would fold the mesh; rigid eyeballs, the jaw's and the skull's parts and the skin
        # that never moves kept (the mouth's lower depths move with the jaw).
        pinned = parts.mask("eye_L", "eye_R", "skull", "rest", "mouth") | ~original
        pinned[si[rest | (depths & (P[:, 1] > mouth_line(Lf)))]] = True
        near_skull = parts.mask("skull")  # the jaw turned whole, but near a split with the skull (ICT's gums)
        for _ in range(SPLIT_RINGS):
            near_skull[T[any_corner(near_skull, T)]] = True
        pinned |= parts.mask("jaw") & ~near_skull
        # On lips joined in the mesh the inner lips' middles (their AU27 opening) and, on lips in one line, the upper
        # lip are kept in the jaw's keys alone: the other keys' relaxation moves them (stylised-nose-mouth's AU22 and
        # AU18 folded 26 and 15 edges against them, 39 and 25 over 35° after 150 sweeps; without the middles kept,
        # decimated-cm's AU27 inner gap closed to 0.16 eye distances).
        kept = np.zeros(len(P), bool)
        if lips_joined:
            kept |= _inner_lip_middles(P, Lf, eye_distance)
        if self.lips_one_line:  # the skin joining the lips stretches; the upper lip keeps its (still) motion
            kept |= _upper_lip(P, Lf, eye_distance)
        elif lips_joined:  # rims merged by a decimation: the lower lip keeps the jaw's motion
            kept |= _lower_lip(P, covered, Lf)
        self._jaw_pins = si[kept & ~pinned[si]]
        pinned[self._jaw_pins] = True
        #: Rims a decimation merged: the lips' outer middles, whose parting says a jaw key keeps the pins.
        self._lip_middles = None
        if lips_joined and not self.lips_one_line:
            self._lip_middles = si[skin_tree.query(Lf[[LIP_UPPER_TOP, LIP_LOWER_BOTTOM]])[1]]
        # (a mouth bag left out: pinned, and not counted in the head's share of folds: the head's keys as without it)
        whole = not np.isin(parts.pieces[T[~relaxed_T, 0]], parts.pieces[fold_T[:, 0]]).any()  # pieces left out whole
        self._folds = FoldRelax(Vf, fold_T, pinned, fold_L, parts.pieces if whole else None)

        # Jaw: the chin that drives it, and the parts it turns.
        chin = covered & (P[:, 1] < Lf[LIP_LOWER_BOTTOM, 1] - 0.08 * eye_distance) \
            & (np.abs(P[:, 0]) < abs(Lf[JAW_RIGHT_ANGLE, 0] - Lf[JAW_LEFT_ANGLE, 0]) / 2) \
            & (P[:, 2] > min(Lf[JAW_RIGHT_ANGLE, 2], Lf[JAW_LEFT_ANGLE, 2]))
        self.chin = chin if chin.sum() >= 10 else None
        if self.chin is None:
            self.notes.append("too little chin under the PDE face: jaw AUs move the skin only")
        self.jaw_parts = np.nonzero(parts.mask("jaw", "mouth") & original)[0]  # a mouth bag: its lower share
        # A mouth bag: each vertex's share of the jaw's turn, the rest the upper lip's middle (its nearest skin).
        self.mouth = np.nonzero(parts.mask("mouth") & original)[0]
        self._mouth_lower = lower_share(Vf[self.mouth], Lf, eye_distance)[:, None, None]
        self._upper_lip_vertex = si[np.argmin(row_norms(P - Lf[LIP_UPPER_INNER]))]

        # Attached parts ride on their nearest skin vertex.
        self.follow = follow = np.nonzero(parts.mask("follow") & original)[0]
        if len(follow):
            self.anchor = self._anchors(Vf[follow], parts.pieces[follow], skin_tree)
            self.follow_offset = Vf[follow] - P[self.anchor]
            # The anchors' normals, read off the skin triangles around them alone (each key turns them).
            anchors, self._anchor_of = np.unique(self.anchor, return_inverse=True)
            slot = np.full(len(si), -1)
            slot[anchors] = np.arange(len(anchors))
            ring = Ts[any_corner(slot >= 0, Ts)]
            r, c = np.nonzero(slot[ring] >= 0)
            self._ring_vertices, ring_local = np.unique(si[ring], return_inverse=True)  # head indices
            self._ring = ring_local.reshape(ring.shape)
            self._ring_sum = csr_matrix((np.ones(len(r)), (slot[ring[r, c]], r)), shape=(len(anchors), len(ring)))

        # Keys that close the eyes close them (the lashes along).
        moving = parts.mask("follow") & original
        moving[si[~(rest | depths)]] = True
        self._lids = LidClosure(Vf, Lf, moving, eye_distance, parts.eyes, T, parts.mask("skin"))

        # Lids stay outside the eyeballs.
        self.eyes = {}
        for name, (centre, radius) in parts.eyes.items():
            idx = np.nonzero(parts.mask(name) & original)[0]
            rho = row_norms(P - centre)
            guard = (rho >= radius) & (rho < radius + 0.15 * eye_distance) & (P[:, 2] > centre[2])
            self.eyes[name] = (centre, radius, idx, np.nonzero(guard)[0])
            self._folds.keep_outside(si[guard], centre, radius)

        # What the PDE face and its extension miss, learned from scans; nothing in the rest region.
        self.prior = None
        if prior is not None:
            if isinstance(prior, str):

                try:
                    prior = load_head_prior()
                except PdeFaceError as exc:  # an install without it: the binding still works, and says so
                    prior = None
                    self.notes.append(f"no head prior ({exc}): the skin beyond the PDE face follows its harmonic "
                                      "extension alone")
            reach = _prior_reach(Vf, from_covered, si[rest], Lf, eye_distance, parts.eyes) * original
            self.prior = (prior.on(model, Vf, parts.kind, reach, eye_distance=eye_distance)
                          if prior is not None else None)
            if prior is not None and self.prior is None:
                self.notes.append("the face's curve layout is not the head prior's: the skin beyond the PDE face "
                                  "follows its harmonic extension alone")

    def _anchors(self, X, labels, skin_tree):
        """Skin anchor of each attached vertex: the skin vertex nearest its part's root.

        A part's roots are its vertices touching the skin (a lash strip's base;
        all of a part that floats). Each vertex takes its nearest root in the
        same part, so a lash tip curling towards the brow still rides on the lid. ``skin_tree``: a ``cKDTree`` of
        the skin.
        """
        from scipy.spatial import cKDTree


        gap, nearest_skin = skin_tree.query(X)
        roots = gap < TOUCH_IOD * self.eye_distance
        floating = ~np.isin(labels, np.unique(labels[roots]))
        roots |= floating
        # Parts far apart along a fourth axis: the nearest root is one of the same part.
        lifted = np.c_[X, labels * (10.0 * np.ptp(X, axis=0).max() + 1.0)]
        ri = np.nonzero(roots)[0]
        root_of = ri[cKDTree(lifted[ri]).query(lifted)[1]]
        return nearest_skin[root_of]

    # ---------------------------------------------------------------- motion

    def _extension(self, jaw):
        if not jaw:
            return self._ext
        if self._ext_jaw is None:  # factorised on first use
            self._ext_jaw = _Extension(self._L, self._jaw_fixed, self._read_jaw)
        return self._ext_jaw

    def face_motion(self, delta_coefficients, delta_residual, jaw=False, gaze=None, with_prior=True) -> np.ndarray:
        """Displacement of every vertex in the face frame (mm), before the lids' guard and the seam copies.

        ``with_prior=False``: the PDE face, its harmonic extension and the rigid parts alone (what a
        :class:`~pdeface.head.prior.HeadPrior` learns the residual of).
        """
        return self.face_motions([(delta_coefficients, delta_residual, jaw, gaze)], with_prior)[0]

    @cached_property
    def _read_nodes(self):
        """:func:`_node_slots` of the covered skin's reads: the PDE grid's nodes every extension reads."""
        return _node_slots(self.read_grid)

    @cached_property
    def _prior_runs(self) -> list:
        """The head prior's vertices (distinct) as runs of consecutive ones, ``(first vertex, its place among them,
        count)`` each: ICT's 14,457 in 90."""
        rows = self.prior.vertices
        cut = np.flatnonzero(np.diff(rows) != 1) + 1
        first, end = np.r_[0, cut], np.r_[cut, len(rows)]
        return [(int(rows[a]), int(a), int(b - a)) for a, b in zip(first, end)]

    @bounded
    def face_motions(self, motions, with_prior=True) -> np.ndarray:
        """:meth:`face_motion` of several ``(delta_coefficients, delta_residual, jaw, gaze)`` at once, (k, n, 3)
        (one PDE solve, one harmonic solve per kind and one prior product for them all)."""
        m, k = self.model, len(motions)
        # The solve is linear: all motions side by side along the last axis, as ShapeBasis does.
        C = np.concatenate([np.asarray(c, np.float64) for c, _, _, _ in motions], axis=2)
        R = np.concatenate([np.asarray(r, np.float64) for _, r, _, _ in motions], axis=2)
        # The grid at the nodes the skin reads alone (half ICT's face's grid), their rows in their order.
        nodes, slot = self._read_nodes
        G = surface_grid(m, *self.resolution, coefficients=C, residual=R, break_slope=READ_BREAK_SLOPE,
                         confine=False, nodes=nodes)
        jaws = np.array([bool(jaw) and self.chin is not None for _, _, jaw, _ in motions])
        out = np.zeros((len(self.V), k, 3))  # vertex-major: the parts below are row blocks
        flat = out.reshape(len(self.V), 3 * k)
        # Every key through the skin's extension, whole rows (a column gather and scatter of most keys cost more
        # than solving the few jaw keys twice); the jaw keys then again through the jaw's, every skin row.
        ext = self._extension(jaws.all()).on_nodes(slot)
        ext.write(G, flat, self.skin)
        members = np.nonzero(jaws)[0]
        if 0 < len(members) < k:
            cols = (3 * members[:, None] + np.arange(3)).ravel()
            ext = self._extension(True).on_nodes(slot)
            fixed, free = ext.solve(G.take(cols, axis=1))  # C-ordered (G[:, cols] is not: sparse @ copies it)
            entries = flat.reshape(-1)  # written at flat indices: 1.5-5x faster than numpy.ix_'s
            entries[(self.skin[ext.fixed][:, None] * flat.shape[1] + cols).ravel()] = fixed.ravel()
            entries[(self.skin[ext.free][:, None] * flat.shape[1] + cols).ravel()] = free.ravel()
        if len(self.follow):
            self._follow(out)
        jaw_keys = np.nonzero(jaws)[0] if len(self.jaw_parts) else ()
        if len(jaw_keys):  # the chin's PDE motion in every jaw key at once
            chin = _on_nodes(self.read_grid[np.nonzero(self.chin[self.covered])[0]], slot)
            cols = (3 * jaw_keys[:, None] + np.arange(3)).ravel()
            d_chins = (chin @ G.take(cols, axis=1)).reshape(chin.shape[0], -1, 3)
        for j, i in enumerate(jaw_keys):
            rv, t = jaw_motion(self.Vf[self.skin[self.chin]], d_chins[:, j], self.hinge)
            bone = rotation_vector_matrix(JAW_BONE_GAIN * rv)  # the bone turns further than the chin's skin
            out[self.jaw_parts, i] = rigid_displacement(self.Vf[self.jaw_parts], self.hinge, bone, t)
        for i, (_, _, _, gaze) in enumerate(motions):
            for _, (centre, _, idx, _) in self.eyes.items() if gaze else ():
                out[idx, i] = rigid_displacement(self.Vf[idx], centre, gaze_matrix(gaze))
        if with_prior and self.prior is not None:
            # the curve points' motion of every key in one evaluation (a linear one: 72 calls cost ICT's rig 25 ms)
            prior = self.prior.many(np.moveaxis(m.curve_points(C, R).reshape(*R.shape[:2], k, 3), 2, 0))
            for row, at, count in self._prior_runs:  # added in place, no copy of every key's rows
                out[row:row + count] += prior[at:at + count]
        return out.transpose(1, 0, 2)

    def displacement(self, delta_coefficients, delta_residual, jaw=False, gaze=None, lids=None) -> np.ndarray:
        """Displacement of every vertex (user space and unit) for a change of the PDE curves.

        Parameters
        ----------
        delta_coefficients, delta_residual : arrays
            Change of the model's coefficients and residual (a descriptor's, or a pose's).
        jaw : bool
            Move the jaw's parts with the rotation the chin's motion shows (jaw AUs).
        gaze : dict, optional
            Gaze AU weights ``{61: w, ...}``: turn the eyeballs.
        lids : dict, optional
            How far the motion closes each eye (:func:`pdeface.head.lids.eyes_closed_by`): the lids meet.
        """
        return self.displacements([(delta_coefficients, delta_residual, jaw, gaze, lids)])[0]

    def displacements(self, motions) -> np.ndarray:
        """:meth:`displacement` of several ``(delta_coefficients, delta_residual, jaw, gaze[, lids])`` at once,
        (k, n, 3): a view of a vertex-major (n, k, 3) array (each key's rows 3k apart, not contiguous)."""
        closing = [m[4] if len(m) > 4 else None for m in motions]
        out = self.face_motions([tuple(m[:4]) for m in motions]).transpose(1, 0, 2)  # (n, k, 3)
        if self._seam is not None:
            band, reads, S, w, steps = self._seam
            flat = out[self.skin[reads]].reshape(len(reads), -1)
            moving = flat[:len(band)]  # the band's rows (a view: 2x faster than gathering and scattering them)
            for _ in range(steps):
                step = S @ flat
                step -= moving
                step *= w
                moving += step
            out[self.skin[band]] = moving.reshape(len(band), -1, 3)
        # The jaw's keys in RELAX_STEPS sweeps, the others in up to STEPS_NOT_JAW and free to move a joined upper lip
        # (one relaxation: one screen kept).
        steps = np.array([fold_relax.RELAX_STEPS if m[2] else STEPS_NOT_JAW for m in motions])
        pins = np.array([bool(m[2]) for m in motions])
        if self._lip_middles is not None:  # rims a decimation merged: pinned in the keys that part the lips alone
            up, lo = self._lip_middles
            pins &= out[up, :, 1] - out[lo, :, 1] > PARTED_IOD * self.eye_distance
        screen = Screen()
        self._folds.relax(out, steps=steps, screen=screen, unpinned=self._jaw_pins,
                          unpinned_keys=np.flatnonzero(~pins).tolist(), look=fold_relax.SWEEPS_PER_LOOK)
        moved, closed = self._lids.apply(out, closing)
        screen.moved(*moved)
        pushed = self._keep_out_of_eyeballs(out, screen)
        # Relaxed again where the lids' closing or the eyeballs' surface folded them (a blink, a glance down), past
        # the limit alone (each sweep opens a closed lid a little), the lids kept out of the eyeballs; only
        # what moved since the first relaxation's screen is screened again.
        self._folds.relax(out, keys=[i for i, c in enumerate(closing) if c or pushed[i]], budget=self._folds.limit,
                          screen=screen, held=self._lids.held_in(closed))
        if len(self.mouth):  # the bag: the jaw's turn below the mouth line, the upper lip's motion above it
            lip = out[self._upper_lip_vertex][None]
            out[self.mouth] = self._mouth_lower * out[self.mouth] + (1 - self._mouth_lower) * lip
        self._keep_still(out)
        out[self._copies] = out[self._copy_of]
        # To user space in place, a block of USER_BLOCK vertices at a time (the frame's map as a matrix; the block's
        # rows of every key stay in cache), returned as a (k, n, 3) view: a fresh key-major array to write the keys
        # into cost ICT's 72 keys ~0.15-0.2 s CPU of the kernel's page faults on this VM (46 MB), more than the product.
        to_user = self.frame.to_user_vectors(np.eye(3))
        for start in range(0, len(out), USER_BLOCK):
            block = out[start:start + USER_BLOCK]
            block[...] = block @ to_user
        return out.transpose(1, 0, 2)

    def _keep_still(self, out):
        """The back of the head and a body's neck (``out`` (n, k, 3), face frame mm, in place): each key's motion
        faded towards at most STILL_MM as :func:`still_weight` falls to 0 (its direction kept)."""
        for start in range(0, len(self._fading), USER_BLOCK):  # by blocks of vertices: no copy of every key's rows
            rows, s = self._fading[start:start + USER_BLOCK], self._still[start:start + USER_BLOCK]
            moved = out[rows]
            size = row_norms(moved)[..., None]
            out[rows] = moved * (s + (1 - s) * np.minimum(1.0, STILL_MM / np.maximum(size, 1e-12)))

    def _keep_out_of_eyeballs(self, out, screen=None):
        """Lids that a key takes into an eyeball put back on its surface (``out`` (n, k, 3), in place); which keys
        it changed, (k,) bool; the (vertex, key) pairs it moved told to ``screen`` (a :class:`~.folds.Screen`)."""
        changed = np.zeros(out.shape[1], bool)
        for centre, radius, _, guard in self.eyes.values():
            if len(guard):
                g = self.skin[guard]
                p = self.Vf[g, None] + out[g]  # (guard, motions, 3)
                p -= centre
                rho = row_norms(p)
                inside = rho < radius
                rows, keys = np.nonzero(inside)  # only those inside are put back
                out[g[rows], keys] = centre + p[rows, keys] * (radius / np.maximum(rho[rows, keys], 1e-12))[:, None] \
                    - self.Vf[g[rows]]
                changed |= inside.any(axis=0)
                if screen is not None:
                    screen.moved(g[rows], keys)
        return changed

    def _follow(self, out):
        """Attached vertices: their anchor's motion, their offset turned as the anchor's normal turns.

        ``out`` (n, k, 3): k motions of the head, the skin's set; the attached vertices' rows written in place.
        """

        k = out.shape[1]
        ring = self._ring_vertices
        moved = triangle_cross(self.Vf[ring][:, None] + out[ring], self._ring)  # (ring triangles, k, 3)
        n1 = unit_rows((self._ring_sum @ moved.reshape(len(moved), -1)).reshape(-1, k, 3))  # each anchor's
        n0 = self.skin_normals[np.unique(self.anchor)][:, None]
        # The turn of each anchor's normal (axis v, 1 + cos), then gathered for its attached vertices (ICT: 318
        # anchors, 2,080 vertices). 1 + cos: the products summed in numpy.sum's order, without its slow reduction
        # over an axis of 3.
        v = cross3(n0, n1)
        c = n0[..., 0] * n1[..., 0] + n0[..., 1] * n1[..., 1]
        c += n0[..., 2] * n1[..., 2]
        c += 1
        c = np.maximum(c, 1e-6)
        # Written into ``out`` block by block of attached vertices: no fresh (attached, k, 3) arrays (ICT: 3.6 MB each).
        for start in range(0, len(self.follow), FOLLOW_BLOCK):
            block = slice(start, start + FOLLOW_BLOCK)
            at = self._anchor_of[block]
            vb, o = v[at], self.follow_offset[block, None]
            vo = cross3(vb, o)
            bend = cross3(vb, vo)
            bend /= c[at][..., None]
            turned = o + vo
            turned += bend
            turned += out[self.skin[self.anchor[block]]]
            turned -= o
            out[self.follow[block]] = turned

    # ---------------------------------------------------------------- keys and poses

    def bindable(self, descriptors) -> list:
        """The descriptors this head has keys for: the gaze AUs (61-64) left out where it has no eyeballs (an
        empty socket or a painted eye has nothing to turn; the parts' notes say so)."""
        if self.eyes:
            return list(descriptors)
        return [d for d in descriptors if au_number(d.key) not in GAZE_AUS]

    def descriptor_displacement(self, descriptor) -> np.ndarray:
        """One descriptor's shape key on the head (user space): its displacement at weight 1."""
        return self.displacement(*descriptor_motion_args(descriptor))

    def descriptor_displacements(self, descriptors) -> np.ndarray:
        """:meth:`descriptor_displacement` of several descriptors at once, (k, n, 3) (faster than one by one)."""
        return self.displacements([descriptor_motion_args(d) for d in descriptors])

    def pose_displacement(self, weights: dict, mixer: str = "sum") -> np.ndarray:
        """The head's displacement for AU ``weights`` mixed by ``mixer`` (user space)."""
        return self.displacements([self.pose_motion_args(weights, mixer)])[0]

    def pose_displacements(self, poses) -> np.ndarray:
        """:meth:`pose_displacement` of several ``(weights, mixer)`` at once, (k, n, 3)."""
        return self.displacements([self.pose_motion_args(w, m) for w, m in poses])

    def motion_args(self, keys) -> list:
        """Each key's motion, as :meth:`displacements` takes it: the one rule of how a key moves.

        Parameters
        ----------
        keys : iterable of Descriptor or (dict, str)
            A :class:`~pdeface.au.descriptor.Descriptor` moves as its own change at weight 1
            (:func:`descriptor_motion_args`: not its weight-1 mix, which rounds differently); an
            ``(AU weights, mixer)`` pair as those weights mixed (:meth:`pose_motion_args`).

        Returns
        -------
        list of tuple
            ``(delta_coefficients, delta_residual, jaw, gaze, lids)`` per key, in the order of ``keys``.
        """
        return [descriptor_motion_args(k) if isinstance(k, Descriptor) else self.pose_motion_args(*k) for k in keys]

    def every_pose_motion_args(self, names) -> list:
        """:meth:`motion_args` of the poses :func:`pdeface.presets.every_pose` names (the poses folds are measured
        in): ``AU<key>`` the model's descriptor, a preset its AU weights summed.

        Parameters
        ----------
        names : iterable of str
            Names of ``every_pose(self.model)``, ``neutral`` left out (it does not move).

        Returns
        -------
        list of tuple
            One motion per name, in the order of ``names``.

        Raises
        ------
        KeyError
            A name that is not one of the model's poses.
        """
        poses = every_pose(self.model)
        descriptors = {f"AU{d.key}": d for d in self.model.descriptors}
        return self.motion_args(descriptors[n] if n in descriptors else (poses[n], "sum") for n in names)

    def pose_motion_args(self, weights, mixer) -> tuple:
        """``(delta_coefficients, delta_residual, jaw, gaze, lids)`` of AU ``weights`` mixed by ``mixer``."""

        weights = normalise_weights(weights)
        C, R = pose_curves(self.model, weights, mixer)
        numbers = {k: au_number(k) for k, w in weights.items() if w}
        gaze = {}
        for k, a in numbers.items():
            if a in GAZE_AUS:
                gaze[a] = gaze.get(a, 0.0) + weights[k]
        jaw = any(a in JAW_AUS for a in numbers.values())
        return C - self.model.coefficients, R - self.model.residual, jaw, gaze or None, eyes_closed_by(weights)


def descriptor_motion_args(descriptor) -> tuple:
    """``(delta_coefficients, delta_residual, jaw, gaze, lids)`` of one descriptor at weight 1."""

    au = au_number(descriptor.key)
    return (*descriptor.dense(), au in JAW_AUS, {au: 1.0} if au in GAZE_AUS else None,
            eyes_closed_by({descriptor.key: 1.0}))


def bind_file(model, mesh_arg, landmarks=None, parts=None):
    """``(mesh, binding)`` of the head ``mesh_arg`` (a file, ``head`` or ``default``) that ``model`` was
    fitted on; ``landmarks`` and ``parts`` are JSON files (the CLI's ``--landmarks``, ``--parts``)."""

    mesh, lm = load_scan(mesh_arg, landmarks)
    overrides = read_overrides(parts) if parts else None
    given = lm if (landmarks or model.landmarks is None) else None
    return mesh, HeadBinding(model, mesh.vertices, mesh.triangles()[0], landmarks=given, overrides=overrides)
