"""Build the low-poly test face: MediaPipe's 468-point face mesh laid on the bundled ICT neutral scan.

Usage: python -m scripts.build.build_low_poly [-o assets/low_poly_face.npz]

MediaPipe's face mesh (found on the scan by ``pdeface.landmarks``, its 468 points cast onto the
skin) with MediaPipe's own tessellation: a game-density face of another topology on a surface whose
truth is known (the scan), for issue #16's "any mesh density". The triangles are the 3-cycles of
``FACEMESH_TESSELATION``'s edges, less those that enclose a vertex (each of their edges already has
two faces), oriented to face forward. Its 68 landmarks come from the 468 points through the shipped
landmark map. Needs the ``landmarks`` extra (MediaPipe) and the assets only.

Writes ``vertices`` (468, 3) cm and ``triangles`` in ICT's frame, ``landmarks`` (68, 3) and
``notice`` (ICT-FaceKit's MIT notice and MediaPipe's Apache-2.0 one).
"""
from __future__ import annotations

import argparse
from collections import Counter, defaultdict

import numpy as np
from pdeface.assets import ICT_NOTICE, assets_dir, load_neutral_scan
from pdeface.landmarks import detect
from pdeface.landmarks.facemap import read_map

MEDIAPIPE_NOTICE = ("Tessellation and 468-point layout: MediaPipe face mesh, Copyright 2020 The MediaPipe Authors, "
                    "Apache License 2.0 (https://github.com/google-ai-edge/mediapipe)")


def tessellation_triangles(edges):
    """Triangles of a mesh given only its edges: the 3-cycles, less any whose edges all have two other faces."""
    adj = defaultdict(set)
    for a, b in edges:
        adj[a].add(b)
        adj[b].add(a)
    tris = sorted({tuple(sorted((a, b, c))) for a, b in edges for c in adj[a] & adj[b]})
    uses = Counter((t[i], t[j]) for t in tris for i, j in ((0, 1), (1, 2), (0, 2)))
    tris = [t for t in tris if min(uses[(t[i], t[j])] for i, j in ((0, 1), (1, 2), (0, 2))) < 3]
    return np.array(tris, np.int64)


def orient(V, T, forward=(0, 0, 1.0)):
    """Triangles wound consistently (across shared edges), facing ``forward`` on the whole."""
    T = T.copy()
    edge_faces = defaultdict(list)
    for f, t in enumerate(T):
        for i in range(3):
            edge_faces[frozenset((t[i], t[(i + 1) % 3]))].append(f)
    done = np.zeros(len(T), bool)
    for seed in range(len(T)):
        if done[seed]:
            continue
        done[seed] = True
        stack = [seed]
        while stack:
            f = stack.pop()
            t = T[f]
            for i in range(3):
                a, b = t[i], t[(i + 1) % 3]
                for g in edge_faces[frozenset((a, b))]:
                    if done[g]:
                        continue
                    u = list(T[g])
                    # a neighbour wound the same way runs the shared edge the other way: b → a
                    if any(u[j] == a and u[(j + 1) % 3] == b for j in range(3)):
                        T[g] = T[g][::-1]
                    done[g] = True
                    stack.append(g)
    n = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    return T if (n @ np.asarray(forward)).sum() > 0 else T[:, ::-1].copy()


def main(argv=None):
    from mediapipe.python.solutions.face_mesh_connections import FACEMESH_TESSELATION

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--output", default=str(assets_dir() / "low_poly_face.npz"))
    args = ap.parse_args(argv)
    scan, _ = load_neutral_scan()
    found = detect(scan.vertices, scan.triangles()[0], unit="cm")
    V = found.mesh_points
    T = orient(V, tessellation_triangles(sorted(FACEMESH_TESSELATION)))
    L = read_map().apply(V)
    np.savez_compressed(args.output, vertices=V.astype(np.float32), triangles=T.astype(np.int16),
                        landmarks=L.astype(np.float32), notice=np.array(ICT_NOTICE + "\n" + MEDIAPIPE_NOTICE))
    print(f"wrote {args.output}: {len(V)} vertices, {len(T)} triangles")


if __name__ == "__main__":
    main()
