"""A second round of characters nobody tuned on (the audit ``docs/measurements/audit_unseen2.md``), unlike both the
development set and the first round (:mod:`scripts.devset.unseen`).

Usage: python -m scripts.devset.unseen2 [-o FOLDER] [--only NAME,...]   (writes NAME.obj and NAME.truth.json)

Built at run time from MakeHuman's base mesh or ICT-FaceKit's head, the true 68 landmarks carried through:

- ``baby``: MakeHuman's baby (its age target: big eyes, a small jaw and nose), eyeballs in the mesh;
- ``anime``: eyes ×3, the mouth tiny and the nose almost flat (local targets at 2-3);
- ``glasses``: a frame of thin tubes round both eyes, over the nose and back to the ears, and a lens in each ring,
  in the same mesh;
- ``beard``: a shell over the jaw, chin and upper lip, off the skin, the lips left bare, in the same mesh;
- ``face-mask``: the back of the head cut away (an open boundary behind the ears), no eyeballs;
- ``dense-160k``: a bust (the body cut 10 eye distances under the chin) subdivided twice (butterfly): 160k vertices;
- ``quads-ngons``: MakeHuman's own quads, a third of them joined in pairs into hexagons (not triangulated);
- ``lying-zup-m``: metres, Blender's Z-up, the head lying on its back (face up, +z of the file);
- ``on-its-side``: the face towards +x of the file, the top of the head towards -z (no axis up);
- ``lashes-brows-cards``: eyelash ribbons on both lids and brow cards over the brows, in the same mesh;
- ``ict-mouth-open-parts``: ICT's identity 007 with its teeth, gums, tongue and lashes, jaw open 0.4 (the teeth and
  tongue seen in the mouth);
- ``two-heads``: two heads side by side in one mesh (the truth: the one at the file's -x);
- ``asymmetric``: one side's local targets alone (its eye larger and higher, its cheek bone out);
- ``long-neck-bust``: the body cut at the waist, the neck stretched to twice its length.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from pdeface.landmark_scheme import eye_centres, eye_distance
from pdeface.mesh import Mesh, butterfly_step, connected_components, vertex_normals
from pdeface.rigid import rotation_vector_matrix
from pdeface.surface.frame import BLENDER_FROM_ICT

from .characters import Spec, _annotation, _compact, _identity, read_base
from .makehuman import BASE_MM
from .unseen import LIKE, YOUNG, _append, _head, write_all


def baby():
    return _head(Spec("baby", {"caucasian-male-baby": 1.0}, eyeballs="merged"))


def anime():
    style = {"eyes/l-eye-scale-incr": 3.0, "eyes/r-eye-scale-incr": 3.0, "mouth/mouth-scale-horiz-decr": 2.5,
             "mouth/mouth-scale-vert-decr": 2.0, "nose/nose-scale-depth-decr": 1.5, "nose/nose-scale-horiz-decr": 1.5,
             "nose/nose-volume-decr": 1.0}  # the nose's depth at 3 folds it through the face
    return _head(Spec("anime", YOUNG, style=style, eyeballs="merged"))


def _tube(points, radius, closed=False, n=6):
    """A tube of ``n`` sides along the polyline ``points`` (open ends), facing outwards."""
    P = np.asarray(points, float)
    m = len(P)
    tangent = np.gradient(P, axis=0) if not closed else np.roll(P, -1, 0) - np.roll(P, 1, 0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    ref = np.where(np.abs(tangent[:, 1:2]) < 0.9, [[0, 1.0, 0]], [[1.0, 0, 0]])
    u = np.cross(tangent, ref)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(tangent, u)
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    V = (P[:, None] + radius * (np.cos(a)[None, :, None] * u[:, None] + np.sin(a)[None, :, None] * w[:, None]))
    i, j = np.meshgrid(np.arange(m if closed else m - 1), np.arange(n), indexing="ij")
    i2, j2 = (i + 1) % m, (j + 1) % n
    q = lambda r, c: r * n + c  # noqa: E731
    T = np.concatenate([np.stack([q(i, j), q(i2, j), q(i2, j2)], -1).reshape(-1, 3),
                        np.stack([q(i, j), q(i2, j2), q(i, j2)], -1).reshape(-1, 3)])
    return V.reshape(-1, 3), T


def _fan(ring, front):
    """A disc: the closed polyline ``ring`` fanned about its centre, wound to face ``front``."""
    c = ring.mean(0)
    n = len(ring)
    T = np.stack([np.full(n, n), np.arange(n), (np.arange(n) + 1) % n], 1)
    V = np.concatenate([ring, [c]])
    if np.cross(V[T[0, 1]] - V[T[0, 0]], V[T[0, 2]] - V[T[0, 0]]) @ front < 0:
        T = T[:, ::-1]
    return V, T


def glasses():
    V, T, L, mm = _head(Spec("glasses", YOUNG, eyeballs="merged"))
    ed = eye_distance(L)
    z = L[27, 2] + 0.05 * ed  # the frame's plane, just in front of the nose's bridge
    a = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    rings = []
    for c in eye_centres(L):
        ring = np.stack([c[0] + 0.3 * ed * np.cos(a), c[1] + 0.2 * ed * np.sin(a), np.full(len(a), z)], 1)
        rings.append(ring)
        V, T = _append(V, T, *_tube(ring, 0.015 * ed, closed=True))
        V, T = _append(V, T, *_fan(ring - [0, 0, 0.01 * ed], [0, 0, 1.0]))
    r, lft = rings  # the right eye's ring is at -x (ICT's axes)
    inner_r, inner_l = r[np.argmax(r[:, 0])], lft[np.argmin(lft[:, 0])]
    V, T = _append(V, T, *_tube(np.linspace(inner_r, inner_l, 8) + [0, 0.05 * ed, 0.02 * ed], 0.015 * ed))
    for ring, ear, s in ((r, L[0], -1), (lft, L[16], 1)):
        outer = ring[np.argmax(s * ring[:, 0])]
        back = np.array([ear[0] + s * 0.05 * ed, outer[1], ear[2] - 0.4 * ed])
        V, T = _append(V, T, *_tube(np.linspace(outer, back, 12), 0.015 * ed))
    return V, T, L, mm


def beard(offset=0.05):
    """A shell over the jaw, the chin and the upper lip, ``offset`` eye distances off the skin, the lips bare."""
    V, T, L, mm = _head(Spec("beard", YOUNG))
    ed = eye_distance(L)
    N = vertex_normals(V, T)
    mouth_c, half = L[48:60].mean(0), 0.5 * np.ptp(L[48:60, :2], axis=0) + 0.06 * ed
    lips = (((V[:, :2] - mouth_c[:2]) / half) ** 2).sum(1) < 1
    zone = ((V[:, 1] < L[33, 1] - 0.05 * ed) & (V[:, 1] > L[8, 1] - 0.6 * ed) & (V[:, 2] > L[0, 2] - 0.2 * ed)
            & ~lips & (N[:, 2] > -0.3))
    S = T[zone[T].all(1)]
    labels = connected_components(len(V), S)[S[:, 0]]
    S = S[np.isin(labels, np.nonzero(np.bincount(labels) > 50)[0])]  # the shell, not the mouth's inside
    Vs, Ts, _ = _compact(V + offset * ed * N, S)
    return (*_append(V, T, Vs, Ts), L, mm)


def face_mask():
    V, T, L, mm = _head(Spec("face-mask", YOUNG))
    ed = eye_distance(L)
    T = T[(V[T][:, :, 2] > min(L[0, 2], L[16, 2]) - 0.15 * ed).all(1)]
    lab = connected_components(len(V), T)[T[:, 0]]
    T = T[lab == np.bincount(lab).argmax()]
    V, T, _ = _compact(V, T)
    return V, T, L, mm


def dense_160k():
    """The body cut 10 eye distances under the chin (10k vertices), subdivided twice (butterfly): 160k."""
    V, T, L, mm = _head(Spec("dense-160k", YOUNG, eyeballs="merged", body=True))
    V, T, _ = _compact(V, T[(V[T][:, :, 1] > L[8, 1] - 10 * eye_distance(L)).all(1)])
    for _ in range(2):
        S, T = butterfly_step(len(V), T)
        V = S @ V  # the old vertices stay: the truth with them
    return V, T, L, mm


def quads_ngons():
    """``(vertices, polygons as a list of index lists, landmarks, mm)``: the head's quads, some joined into hexagons."""
    base = read_base()
    V = _identity(Spec("quads-ngons", YOUNG))
    L = V[np.array(_annotation()["characters"][LIKE])]
    Q = base.group_quads("body")
    Q = Q[(V[Q][:, :, 1] > base.joint("neck", V)[1] - 0.35).all(1)]
    polys = [list(dict.fromkeys(q)) for q in Q.tolist()]  # a triangle's repeated corner once
    edge_of = {}
    for k, p in enumerate(polys):
        for a, b in zip(p, p[1:] + p[:1]):
            edge_of[(a, b)] = k
    used, out = set(), []
    rng = np.random.default_rng(0)
    for k in rng.permutation(len(polys)):
        p = polys[k]
        if k in used:
            continue
        used.add(k)
        if len(p) == 4 and rng.random() < 0.5:
            for s in range(4):  # p = [a, b, c, d]; a neighbour [c, b, x, y] across b-c: a b x y c d
                a, b, c, d = p[s:] + p[:s]
                m = edge_of.get((c, b))
                if m is not None and m not in used and len(polys[m]) == 4:
                    q = polys[m]
                    t = q.index(c)
                    x, y = (q[t:] + q[:t])[2:]
                    used.add(m)
                    p = [a, b, x, y, c, d]
                    break
        out.append(p)
    keep = np.unique(np.concatenate([np.array(p) for p in out]))
    remap = np.full(len(V), -1)
    remap[keep] = np.arange(len(keep))
    k = BASE_MM / 10.0  # centimetres
    return V[keep] * k, [remap[p].tolist() for p in out], L * k, 10.0


def _turned(name, R, unit_scale=1.0, mm=None):
    V, T, L, mm0 = _head(Spec(name, YOUNG))
    return V @ R.T * unit_scale, T, L @ R.T * unit_scale, mm0 / unit_scale if mm is None else mm


def lying_zup_m():
    """Blender's axes (-y front, +z up) in metres, then laid on its back: the face up (+z), the top towards +y."""
    lay = rotation_vector_matrix([-np.pi / 2, 0, 0])  # about x: -y (the front) -> +z, +z (the top) -> +y
    return _turned("lying-zup-m", lay @ BLENDER_FROM_ICT, 0.01)


def on_its_side():
    """The face towards +x, the top of the head towards -z."""
    R = np.array([[0, 0, 1.0], [-1.0, 0, 0], [0, -1.0, 0]])  # ICT's x -> -y, y -> -z, z -> +x (det +1)
    return _turned("on-its-side", R)


def _ribbon(points, offset, front):
    """Quads between the polyline ``points`` and ``points + offset``, wound to face ``front`` (single-sided)."""
    P = np.asarray(points, float)
    m = len(P)
    V = np.concatenate([P, P + offset])
    i = np.arange(m - 1)
    T = np.concatenate([np.stack([i, i + 1, m + i + 1], 1), np.stack([i, m + i + 1, m + i], 1)])
    if np.cross(V[T[0, 1]] - V[T[0, 0]], V[T[0, 2]] - V[T[0, 0]]) @ front < 0:
        T = T[:, ::-1]
    return V, T


def _along(P, n):
    t = np.linspace(0, 1, len(P))
    s = np.linspace(0, 1, n)
    return np.stack([np.interp(s, t, P[:, k]) for k in range(3)], 1)


def lashes_brows_cards():
    V, T, L, mm = _head(Spec("lashes-brows-cards", YOUNG, eyeballs="merged"))
    ed = eye_distance(L)
    fwd = np.array([0, 0, 1.0])
    for upper, lower in (([36, 37, 38, 39], [39, 40, 41, 36]), ([42, 43, 44, 45], [45, 46, 47, 42])):
        V, T = _append(V, T, *_ribbon(_along(L[upper], 12) + 0.01 * ed * fwd, [0, 0.05 * ed, 0.06 * ed], fwd))
        V, T = _append(V, T, *_ribbon(_along(L[lower], 10) + 0.01 * ed * fwd, [0, -0.025 * ed, 0.03 * ed], fwd))
    for brow in (L[17:22], L[22:27]):
        P = _along(brow, 14) + 0.025 * ed * fwd
        V, T = _append(V, T, *_ribbon(P - [0, 0.05 * ed, 0], [0, 0.1 * ed, 0.01 * ed], fwd))
    return V, T, L, mm


#: How far ``ict-mouth-open-parts`` has its jaw open (0: the control, ICT's identity 007 at rest).
JAW_OPEN = 0.4


def ict_mouth_open_parts():
    from pdeface.assets import load_head, load_head_shapes

    mesh, lm = load_head()
    shapes = load_head_shapes()
    V = mesh.vertices + shapes["identity007"] + JAW_OPEN * shapes["jawOpen"]
    return V, mesh.triangles()[0], V[lm], 10.0


def two_heads():
    V, T, L, mm = _head(Spec("two-heads", YOUNG))
    shift = [1.3 * np.ptp(V[:, 0]), 0, 0]
    return (*_append(V, T, V + shift, T), L, mm)


def asymmetric():
    style = {"eyes/l-eye-scale-incr": 1.5, "eyes/l-eye-trans-up": 1.5, "eyes/l-eye-corner2-up": 1.5,
             "cheek/l-cheek-bones-incr": 2.0, "cheek/l-cheek-volume-incr": 2.0}
    return _head(Spec("asymmetric", YOUNG, style=style))


def long_neck_bust():
    """The body from the waist up, its neck stretched to twice its length (the skin between the shoulders and the
    jaw's underside)."""
    base = read_base()
    from .characters import build
    from .unseen import _own

    spec = Spec("long-neck-bust", YOUNG, body=True)
    ch = build(spec, own=_own(spec))
    V, T, L = ch.vertices, ch.triangles, ch.landmarks
    k = BASE_MM / 10.0
    B = _identity(spec) * k
    y_waist = base.joint("spine-3", B)[1]
    y0, y1 = base.joint("neck", B)[1] - 0.5 * k * 0.35, L[8, 1] - 0.2 * eye_distance(L)
    stretch = y1 - y0
    t = np.clip((V[:, 1] - y0) / (y1 - y0), 0, 1)
    V = V + np.outer(t * stretch, [0, 1.0, 0])
    T = T[(V[T][:, :, 1] > y_waist).all(1)]
    V, T, _ = _compact(V, T)
    return V, T, L + [0, stretch, 0], ch.mm_per_unit


#: name → builder: ``(vertices, triangles (or polygons), true landmarks (68, 3), mm per unit)``.
BUILDERS = {"baby": baby, "anime": anime, "glasses": glasses, "beard": beard, "face-mask": face_mask,
            "dense-160k": dense_160k, "quads-ngons": quads_ngons, "lying-zup-m": lying_zup_m,
            "on-its-side": on_its_side, "lashes-brows-cards": lashes_brows_cards,
            "ict-mouth-open-parts": ict_mouth_open_parts, "two-heads": two_heads, "asymmetric": asymmetric,
            "long-neck-bust": long_neck_bust}


def mesh_of(V, F) -> Mesh:
    """A :class:`Mesh` of triangles ``F`` ((t, 3) array) or polygons (a list of index lists)."""
    if isinstance(F, list):
        return Mesh(np.asarray(V, float), np.array([len(p) for p in F]), np.concatenate([np.array(p) for p in F]))
    return Mesh.from_faces(V, F)


def write(name, folder) -> Path:
    """Write ``NAME.obj`` and ``NAME.truth.json`` (a landmarks file: ``--landmarks``) into ``folder``."""
    from pdeface.io.meshio import write_obj

    V, F, L, mm = BUILDERS[name]()
    path = Path(folder) / f"{name}.obj"
    write_obj(path, mesh_of(V, F), header=f"pdeface unseen character {name}")
    (Path(folder) / f"{name}.truth.json").write_text(json.dumps({"points": np.asarray(L).tolist(), "mm_per_unit": mm}))
    return path


def main(argv=None):
    write_all(argv, __doc__, BUILDERS, write, "unseen2")


if __name__ == "__main__":
    main()
