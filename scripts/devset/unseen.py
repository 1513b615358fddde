"""Characters nobody tuned on: heads unlike the development set's, as other artists make them (the audit
``docs/measurements/audit_unseen.md``).

Usage: python -m scripts.devset.unseen [-o FOLDER] [--only NAME,...]   (writes NAME.obj and NAME.truth.json)

Each is built at run time, from MakeHuman's base mesh (a development-set :class:`~scripts.devset.characters.Spec`
pushed past what the set holds, then changed as an artist's file would be) or from ICT-FaceKit's bundled head in an
expression, with its true 68 landmarks carried through every change (``None`` where no truth can be carried):

- ``cartoon``: big eyes, a tiny chin and a wide mouth (local targets at weight 2.5-3 at once);
- ``expression-at-rest``: eyes closed, mouth open 0.6 and a smile, as the "neutral";
- ``rolled-pitched``: the head rolled 30° and pitched 25° in its own file;
- ``lowpoly-flat``: decimated to about 1.5k vertices, written with a normal per face (flat shading);
- ``hat``: a closed cylinder over the skull, in the same mesh;
- ``hair-cards``: thin double-sided cards hanging in front of the right eye, in the same mesh;
- ``empty-sockets-bust``: cut just under the jaw, no eyeballs, the lids opened wide;
- ``scale-100x`` and ``scale-0.01x``: a millimetre head ×100 and a metre head ×0.01;
- ``mirrored``: x negated, the winding kept (a left-handed export: every normal points inwards);
- ``uv-seams``: vertices split along the midline (a UV seam, as a glTF export splits them);
- ``flipped-normals``: a third of the triangles turned the other way (mixed winding);
- ``non-manifold``: fins (a third triangle on an edge) and a tenth of the triangles doubled;
- ``triangle-soup``: every triangle its own three vertices (a flat-shaded export with its edges split);
- ``ict-expression``: ICT's identity 004 with its jaw open 0.5, both eyes blinked and a smile.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from pdeface.geometry import ClosestPoint
from pdeface.landmark_scheme import MIRROR, eye_centres, eye_distance
from pdeface.mesh import Mesh
from pdeface.rigid import rotation_vector_matrix

from .characters import SPECS, Spec, _annotation, build, decimate, shape

#: The identity of the characters built on the development set's ``LIKE``: its own annotation is their truth.
LIKE = "caucasian-female-young-cm"
YOUNG = SPECS[LIKE].identity


def _own(spec):
    """The true landmarks of ``spec``'s shape: the development set's annotation of :data:`LIKE`'s where the shape is
    its, else ICT's face registered onto the shape (``scripts/devset/annotate.py``, a few seconds)."""
    if spec.identity == YOUNG and not spec.style:
        a = _annotation()
        return a["characters"][LIKE], a["skin_points"][LIKE]["corners"], a["skin_points"][LIKE]["weights"]
    from .annotate import annotate_shape, ict_face, makehuman_head

    Vs, Ts, Ls, _ = ict_face()
    _, Tt, head = makehuman_head()
    return annotate_shape(shape(spec), Vs, Ts, Ls, Tt[head[Tt].all(1)])


def _head(spec):
    ch = build(spec, own=_own(spec))
    (V, T) = ch.joined()
    return V, T, ch.landmarks, ch.mm_per_unit


def _around(V, L, R):
    """``V`` and ``L`` turned by ``R`` about the eyes' midpoint."""
    c = np.mean(eye_centres(L), axis=0)
    return (V - c) @ R.T + c, (L - c) @ R.T + c


def _cylinder(centre, radius, y0, y1, n=32):
    """A closed cylinder along y (its caps fans about a centre vertex), facing outwards."""
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(a) * radius, np.zeros(n), np.sin(a) * radius], 1) + [centre[0], 0, centre[2]]
    lo, hi = ring + [0, y0, 0], ring + [0, y1, 0]
    V = np.concatenate([lo, hi, [[centre[0], y0, centre[2]], [centre[0], y1, centre[2]]]])
    i, j = np.arange(n), (np.arange(n) + 1) % n
    side = np.concatenate([np.stack([i, n + i, j], 1), np.stack([j, n + i, n + j], 1)])
    caps = np.concatenate([np.stack([np.full(n, 2 * n), i, j], 1), np.stack([np.full(n, 2 * n + 1), n + j, n + i], 1)])
    return V, np.concatenate([side, caps])


def _append(V, T, Vp, Tp):
    return np.concatenate([V, Vp]), np.concatenate([T, Tp + len(V)])


def cartoon():
    style = {"eyes/l-eye-scale-incr": 3.0, "eyes/r-eye-scale-incr": 3.0, "chin/chin-width-decr": 2.5,
             "chin/chin-height-decr": 2.5, "chin/chin-prominent-decr": 2.0, "mouth/mouth-scale-horiz-incr": 2.5,
             "head/head-round": 1.0}
    return _head(Spec("cartoon", YOUNG, style=style, eyeballs="merged"))


def expression_at_rest():
    expr = {"eye-left-closure": 1.0, "eye-right-closure": 1.0, "mouth-corner-puller": 1.0}
    return _head(Spec("expression-at-rest", YOUNG, mouth_open=0.6, expression=expr))


def rolled_pitched():
    V, T, L, mm = _head(Spec("rolled-pitched", YOUNG))
    R = rotation_vector_matrix([np.radians(25), 0, 0]) @ rotation_vector_matrix([0, 0, np.radians(30)])
    V, L = _around(V, L, R)
    return V, T, L, mm


def lowpoly_flat():
    V, T, L, mm = _head(Spec("lowpoly-flat", YOUNG))
    W, F = decimate(V, T, 1500)
    return W, F, ClosestPoint(W, F).query(L)[3], mm  # the truth on the new surface, as the development set's


def hat():
    V, T, L, mm = _head(Spec("hat", YOUNG))
    ed = eye_distance(L)
    top = V[:, 1].max()
    skull = V[V[:, 1] > top - 1.5 * ed]
    centre = skull.mean(0)
    radius = 0.55 * np.ptp(skull[:, 0]) + 0.1 * ed
    Vc, Tc = _cylinder(centre, radius, np.mean(eye_centres(L), 0)[1] + 0.8 * ed, top + 0.6 * ed)
    return (*_append(V, T, Vc, Tc), L, mm)


def hair_cards():
    V, T, L, mm = _head(Spec("hair-cards", YOUNG))
    ed = eye_distance(L)
    right = eye_centres(L)[0]
    front = V[:, 2].max()
    Vs, Ts = [], []
    for k, x in enumerate(np.linspace(right[0] - 0.45 * ed, right[0] + 0.45 * ed, 9)):
        z = front - 0.25 * ed + 0.02 * ed * (k % 3)
        y0, y1 = right[1] - (0.35 + 0.1 * (k % 2)) * ed, right[1] + 1.6 * ed
        w = 0.06 * ed
        q = np.array([[x - w, y0, z], [x + w, y0, z], [x + w, y1, z - 0.3 * ed], [x - w, y1, z - 0.3 * ed]])
        n = sum(len(v) for v in Vs)
        Vs.append(q)
        Ts.append(np.array([[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]]) + n)  # both sides
    return (*_append(V, T, np.concatenate(Vs), np.concatenate(Ts)), L, mm)


def empty_sockets_bust():
    expr = {"eye-left-opened-up": 1.0, "eye-right-opened-up": 1.0}
    V, T, L, mm = _head(Spec("empty-sockets-bust", YOUNG, expression=expr))
    ed = eye_distance(L)
    T = T[(V[T][:, :, 1] > L[8, 1] - 0.5 * ed).all(1)]
    used = np.unique(T)
    remap = np.full(len(V), -1)
    remap[used] = np.arange(len(used))
    return V[used], remap[T], L, mm


def scale_100x():
    V, T, L, mm = _head(Spec("scale-100x", YOUNG, unit="mm"))
    return V * 100, T, L * 100, mm / 100


def scale_001x():
    V, T, L, mm = _head(Spec("scale-0.01x", YOUNG, unit="m"))
    return V * 0.01, T, L * 0.01, mm / 0.01


def mirrored():
    V, T, L, mm = _head(Spec("mirrored", YOUNG))
    flip = np.array([-1.0, 1, 1])
    return V * flip, T, (L * flip)[list(MIRROR)], mm


def _seam(V, T, L):
    """The right side's triangles take copies of the midline's vertices (a UV seam down the face, as glTF splits)."""
    mid = np.mean(eye_centres(L), 0)[0]
    on_mid = np.abs(V[:, 0] - mid) < 1e-6 * eye_distance(L)
    copy = np.full(len(V), -1)
    copy[on_mid] = len(V) + np.arange(on_mid.sum())
    right = V[T].mean(1)[:, 0] < mid
    T = T.copy()
    sub = T[right]
    sub[on_mid[sub]] = copy[sub[on_mid[sub]]]
    T[right] = sub
    return np.concatenate([V, V[on_mid]]), T


def uv_seams():
    V, T, L, mm = _head(Spec("uv-seams", YOUNG))
    return (*_seam(V, T, L), L, mm)


def flipped_normals():
    V, T, L, mm = _head(Spec("flipped-normals", YOUNG))
    flip = np.random.default_rng(0).random(len(T)) < 1 / 3
    T = T.copy()
    T[flip] = T[flip][:, ::-1]
    return V, T, L, mm


def non_manifold():
    """Fins (a third triangle on an edge) on the cheeks and forehead, and a tenth of the triangles doubled."""
    V, T, L, mm = _head(Spec("non-manifold", YOUNG))
    ed = eye_distance(L)
    centres = V[T].mean(1)
    fins = []
    for at in (L[2], L[14], L[27] + [0, 0.8 * ed, 0]):
        a, b = T[np.argmin(np.linalg.norm(centres - at, axis=1))][:2]
        fins.append([a, b, len(V) + len(fins)])
    tip = [(V[a] + V[b]) / 2 + [0, 0, 0.3 * ed] for a, b, _ in fins]
    doubled = T[np.random.default_rng(0).random(len(T)) < 0.1]
    return np.concatenate([V, tip]), np.concatenate([T, fins, doubled]), L, mm


def triangle_soup():
    V, T, L, mm = _head(Spec("triangle-soup", YOUNG))
    return V[T.ravel()], np.arange(3 * len(T)).reshape(-1, 3), L, mm


def ict_expression():
    from pdeface.assets import load_head, load_head_shapes

    mesh, lm = load_head()
    shapes = load_head_shapes()
    V = mesh.vertices + shapes["identity004"]
    for name, w in (("jawOpen", 0.5), ("eyeBlink_L", 1.0), ("eyeBlink_R", 1.0), ("mouthSmile_L", 0.8),
                    ("mouthSmile_R", 0.8)):
        V = V + w * shapes[name]
    return V, mesh.triangles()[0], V[lm], 10.0


#: name → builder: ``(vertices, triangles, true landmarks (68, 3), mm per unit)``.
BUILDERS = {"cartoon": cartoon, "expression-at-rest": expression_at_rest, "rolled-pitched": rolled_pitched,
            "lowpoly-flat": lowpoly_flat, "hat": hat, "hair-cards": hair_cards,
            "empty-sockets-bust": empty_sockets_bust, "scale-100x": scale_100x, "scale-0.01x": scale_001x,
            "mirrored": mirrored, "uv-seams": uv_seams,
            "flipped-normals": flipped_normals, "non-manifold": non_manifold, "triangle-soup": triangle_soup,
            "ict-expression": ict_expression}


def write(name, folder) -> Path:
    """Write ``NAME.obj`` (``lowpoly-flat`` with a normal per face) and ``NAME.truth.json`` into ``folder``."""
    from pdeface.io.meshio import write_obj

    V, T, L, mm = BUILDERS[name]()
    mesh = Mesh.from_faces(V, T)
    if name == "lowpoly-flat":
        n = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
        mesh.normals = n / np.linalg.norm(n, axis=1, keepdims=True)
        mesh.face_normal_indices = np.repeat(np.arange(len(T)), 3)
    path = Path(folder) / f"{name}.obj"
    write_obj(path, mesh, header=f"pdeface unseen character {name}")
    truth = {"points": np.asarray(L).tolist(), "mm_per_unit": mm}  # a landmarks file: --landmarks
    (Path(folder) / f"{name}.truth.json").write_text(json.dumps(truth))
    return path


def write_all(argv, description, builders, write_one, out):
    """The builders' command line: write each head (``--only`` some) with ``write_one`` into ``-o`` (``out``)."""
    ap = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", default=out)
    ap.add_argument("--only")
    args = ap.parse_args(argv)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    for name in args.only.split(",") if args.only else builders:
        print(write_one(name, args.out), flush=True)


def main(argv=None):
    write_all(argv, __doc__, BUILDERS, write, "unseen")


if __name__ == "__main__":
    main()
