"""Fuzz every pdeface reader, what consumes what it read, and every CLI command's arguments (seeded).

Usage: python -m scripts.bench.fuzz_readers [--inputs 100000] [--readers obj,model,...] [--seed 0]
       [--cli] [--commands all|fit,pose,...] [--time-limit 5] [--memory-mb 500] [--json OUT] [--markdown OUT]
       python -m scripts.bench.fuzz_readers --replay N (--readers NAME | --commands NAME | --cli) [--save FILE]
       python -m scripts.bench.fuzz_readers --gather JSON... --markdown OUT

Each reader gets a corpus of valid files made from the project's own data (the
default face, its descriptors, presets, a timeline, FDTs, tracker CSVs, packets;
small OBJ and PLY files beside the face's) and ``--inputs`` mutations of them, half
by bytes (bit flips, runs inserted, deleted or repeated, truncation, absurd numbers,
deep nesting) and half by structure: JSON is parsed and mutated as a tree (types
swapped, numbers at the limits: NaN, inf, 1e308, -0, 2**63, 5,000 digits; lists
emptied, nested or repeated; keys dropped), CSV, OBJ and PLY by their grammar (cells,
columns, rows, header counts, face indices), model archives member by member (a member
replaced by NaNs, the wrong type or shape, garbage bytes, dropped). What a
reader returns is fed to its consumers (mesh and landmarks → a small fit; model → surface,
pose, retarget; descriptor → pose; presets → resolve and pose; timeline →
channels and its first key posed; FDT → apply; tracker CSV → timeline).
``--cli`` fuzzes every command's arguments in-process (the ``pdeface`` entry point's ``main``):
each option given a value at the limits, a wrong type, a bad file or a good
one; the cheap commands run, the rest are parsed. ``--commands`` gives each named command (``all``: every
one) ``--inputs`` command lines of its own; without ``--readers`` it fuzzes only those commands.

An input passes when it is read or refused with ``PdeFaceError`` (the CLI:
exit 0 or 2, or argparse's ``SystemExit(2)``); anything else escaping is a
failure, and so is an input over ``--time-limit`` seconds of CPU time, or of wall
time twice (an input over it on the wall clock alone is run once more: a process
paused or starved by others is not the input's fault). The process's address space
is capped at its size after warm-up plus ``--memory-mb``, so an allocation past that
is a ``MemoryError`` failure. Prints per target: inputs, failures (the first few),
slowest input by wall and CPU time, peak RSS; ``--json`` is rewritten every 1,000
inputs, so a campaign stopped early says how far it got. Input N of a target is the
same for a seed on every run: ``--replay N`` makes inputs 0..N-1 (without running
them) and runs N, printing how it ended and its times (``--save``: the input itself).
``--gather`` writes the table of a campaign run one process per target. The test
suite runs a short, fixed slice (tests/core/test_fuzz.py).
"""
from __future__ import annotations

import argparse
import contextlib
import copy
import functools
import io
import json
import os
import random
import re
import resource
import struct
import sys
import tempfile
import time
import traceback
import zipfile
from pathlib import Path

import numpy as np

#: Packets that once broke the player's reader (each is garbage or a packet; the next one must still play).
HOSTILE_PACKETS = [
    b'{"au_r": {"AU12": ' + b"9" * 400 + b'}, "timestamp": 1}\n',  # an AU value of 400 digits
    b'{"au_r": {"AU12": 0.5}, "timestamp": ' + b"9" * 400 + b"}\n",  # a timestamp of 400 digits
    b"-" + b"5" * 5000 + b" ",  # a control integer of 5,000 digits
    b'{"au_r": {"AU1": 1}, "x": "' + b"a" * 60000 + b'"}\n',  # a 60 KB JSON line in one read
    b"[" * 900 + b"\n",  # deep nesting
    b"7" * 200000,  # digits with no delimiter
    b" {12:" + b"9" * 900 + b"}",  # a weight of 900 digits
]
#: Small mesh files using what the readers' grammars allow (UVs, normals, n-gons, negative indices, groups,
#: materials; ASCII and big-endian PLY with extra properties): beside the bundled face's OBJ (100 KB) and
#: binary PLY (45 KB), which a fit can use, they reach the same parsing code at a fraction of the cost.
SMALL_OBJ = [(b"# a quad and a triangle\nmtllib m.mtl\no face\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 1.0\n"
             b"vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\ng a\nusemtl skin\ns 1\nf 1/1/1 2/2/1 3/3/1 4/3/1\n"
             b"usemtl lips\nf -4//1 -3//1 -1//1\nl 1 2\n"),
             b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\nv 2 0 1\nf 1 2 3\nf 2 4 3\nf 2 5 4 3\r\nf 3/ 4/ 5/\n"]
SMALL_PLY = [(b"ply\nformat ascii 1.0\ncomment small\nelement vertex 4\nproperty float x\nproperty float y\n"
             b"property float z\nproperty uchar red\nproperty float s\nproperty float t\nelement face 2\n"
             b"property list uchar int vertex_indices\nend_header\n0 0 0 255 0 0\n1 0 0 0 1 0\n1 1 0 9 1 1\n"
             b"0 1 0 1 0 1\n3 0 1 2\n4 0 1 2 3\n"),
             b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
             b"property double z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n"
             + struct.pack(">9dB3I", 0, 0, 0, 1, 0, 0, 0, 1, 0, 3, 0, 1, 2)]
NUMBERS = [b"1e308", b"-1e308", b"nan", b"NaN", b"inf", b"-inf", b"Infinity", b"9" * 400, b"-1", b"0",
           b"4294967296", b"1e-320", b"99999999999", b"-0"]


def _small_mesh():
    """A small PDE face (about 1,300 vertices): quick to parse thousands of times."""
    from pdeface.au.modelfile import load_face
    from pdeface.surface.fit import face_mesh

    return face_mesh(load_face("default"), (1, 1))


def _small_landmarks():
    """The bundled scan's 68 landmarks (cm), which lie on the small face: a small face can be fitted."""
    from pdeface.assets import DEFAULT
    from pdeface.surface.scan import load_scan

    return load_scan(DEFAULT)[1]


#: A small fit (a quarter of a second): what the fuzzer fits a read mesh or landmarks with.
SMALL_FIT = {"unit": "cm", "n_curves": 12, "n_points": 15, "n_modes": 3}


def corpus() -> dict:
    """Reader name → (file suffix, list of valid file bytes)."""
    from pdeface.animation.timeline import sequence_timeline, timeline_to_json
    from pdeface.au.descriptorfile import descriptor_to_bytes, descriptor_to_json
    from pdeface.au.modelfile import load_face, model_to_bytes
    from pdeface.fdt.table import load_fdt
    from pdeface.io.meshio import write_obj, write_ply
    from pdeface.presets import PRESETS, preset_to_json
    from pdeface.stream.rules import DEFAULT_RULES

    face = load_face("default")
    small = _small_mesh()
    L = _small_landmarks()
    nearest = np.linalg.norm(small.vertices[None] - L[:, None], axis=2).argmin(axis=1)
    with tempfile.TemporaryDirectory() as tmp:
        write_obj(Path(tmp) / "m.obj", small)
        write_ply(Path(tmp) / "m.ply", small)
        obj, ply = (Path(tmp) / "m.obj").read_bytes(), (Path(tmp) / "m.ply").read_bytes()
    descriptors = face.descriptors[:4]
    face_only = model_to_bytes(face, descriptors=False)
    return {
        "obj": (".obj", [obj, *SMALL_OBJ]),
        "ply": (".ply", [ply, *SMALL_PLY]),
        "model": (".npz", [face_only]),
        "descriptor_json": (".json", [json.dumps(descriptor_to_json(d)).encode() for d in descriptors]),
        "descriptor_pdd": (".pdd", [descriptor_to_bytes(d) for d in descriptors]),
        "presets": (".json", [json.dumps(preset_to_json(p)).encode() for p in list(PRESETS.values())[:3]]),
        "landmarks": (".json", [json.dumps({"indices": nearest.tolist()}).encode(),
                                json.dumps({"points": np.round(L, 4).tolist()}).encode()]),
        "timeline": (".json", [json.dumps(timeline_to_json(sequence_timeline(["happy", "sad"], 12))).encode()]),
        "rules": (".json", [Path(DEFAULT_RULES).read_bytes()]),
        "fdt": (".fdt.json", [json.dumps(load_fdt(n).to_json()).encode() for n in ("happy", "12L")]),
        "openface": (".csv", [b"frame, face_id, timestamp, confidence, success, AU01_r, AU12_r, AU12_c, AU28_c\n"
                              + b"".join(f"{i}, 0, {i / 30:.3f}, 0.98, 1, {i % 5}.0, 2.5, 1, 0\n".encode()
                                         for i in range(1, 30))]),
        "pyfeat": (".csv", [b"frame,FaceScore,AU01,AU12,AU43\n"
                            + b"".join(f"{i},0.99,0.{i % 9},0.5,0.1\n".encode() for i in range(30))]),
        "livelink": (".csv", [b"Timecode,BlendShapeCount,JawOpen,MouthSmileLeft,EyeBlinkRight\n"
                              + b"".join(f"10:00:0{i // 60}:{i % 60:02d}.000,61,0.{i % 9},0.5,0.1\n".encode()
                                         for i in range(90))]),
        "fas": (".txt", [b"# two sets\n{1,2,5,15,16,20,26}\n{12:0.8,6C}\n{12E}\n"]),
        "packets": ("", [b'{1,2,5}{12:0.8,6:0.5} 1 -1 {12E}\n{"au_r": {"AU12": 0.8}, "timestamp": 1.5}\n-3 -2 ']),
    }


def readers() -> dict:
    """Reader name → function(path) running it."""
    from pdeface.animation.timeline import load_timeline
    from pdeface.animation.trackers import import_au
    from pdeface.au.descriptorfile import load_descriptor
    from pdeface.au.modelfile import load_model
    from pdeface.fdt.table import read_fdt
    from pdeface.io.meshio import read_mesh
    from pdeface.presets import load_presets
    from pdeface.stream.rules import AUBlender
    from pdeface.stream.wire import StreamParser
    from pdeface.surface.frame import read_landmarks

    def packets(path):
        data = Path(path).read_bytes()
        parser = StreamParser()
        for i in range(0, len(data), 7):  # in pieces, as a socket delivers them
            parser.feed(data[i:i + 7])

    return {"obj": read_mesh, "ply": read_mesh, "model": load_model, "descriptor_json": load_descriptor,
            "descriptor_pdd": load_descriptor, "presets": load_presets, "landmarks": read_landmarks,
            "timeline": load_timeline, "rules": AUBlender.load, "fdt": read_fdt,
            "openface": lambda p: import_au(p, "openface", smooth_window=3),
            "pyfeat": lambda p: import_au(p, "pyfeat"), "livelink": lambda p: import_au(p, "livelink"),
            "fas": lambda p: import_au(p, "fas"), "packets": packets}


def mutate(data: bytes, rng: random.Random) -> bytes:
    """One to three random mutations of ``data``."""
    b = bytearray(data)
    for _ in range(rng.randint(1, 3)):
        kind = rng.randrange(8)
        pos = rng.randrange(len(b) + 1)
        if kind == 0 and b:  # bit flips
            for _ in range(rng.randint(1, 8)):
                i = rng.randrange(len(b))
                b[i] ^= 1 << rng.randrange(8)
        elif kind == 1:  # random bytes inserted
            b[pos:pos] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
        elif kind == 2 and b:  # a run deleted
            del b[pos:pos + rng.randint(1, 64)]
        elif kind == 3:  # truncated
            del b[pos:]
        elif kind == 4 and b:  # a run repeated
            run = b[pos:pos + rng.randint(1, 32)]
            b[pos:pos] = bytes(run) * rng.randint(2, 50)
        elif kind == 5:  # a number replaced by an absurd one
            digits = [m.start() for m in re.finditer(rb"[0-9]", b)]  # a Python loop took 90 ms on a 100 KB OBJ
            if digits:
                i = rng.choice(digits)
                j = i
                while j < len(b) and (48 <= b[j] <= 57 or b[j] in b".-e"):
                    j += 1
                b[i:j] = rng.choice(NUMBERS)
        elif kind == 6:  # deep nesting
            b[pos:pos] = rng.choice([b"[", b"{"]) * rng.randint(100, 3000)
        elif kind == 7 and b:  # a byte replaced by a structural one
            b[rng.randrange(len(b))] = rng.choice(b'{}[],:"\n\r\x00 -')
    return bytes(b)


# ------------------------------------------------------------------ mutations by structure

#: Numbers at the limits, as JSON text (a JSON tree is written with these spliced in).
LIMIT_NUMBERS = ["NaN", "Infinity", "-Infinity", "1e308", "-1e308", "-0", "-0.0", "0", "-1", "1e-320",
                 str(2**63), str(-2**63 - 1), "9" * 16, "1" * 5000, "0.1", "4294967296", "1e15"]
_SPLICE = "\u2063pdeface-number-{}\u2063"  # a placeholder string replaced by a number's text after json.dumps


def _random_value(rng, depth=0):
    kind = rng.randrange(9)
    if kind == 0:
        return _SPLICE.format(rng.randrange(len(LIMIT_NUMBERS)))
    if kind == 1:
        return rng.choice(["", "x" * rng.randint(1, 300), "12", "AU12", "happy", "sum", "3d", "\x00", "\u00e9", "NaN"])
    if kind == 2:
        return rng.choice([None, True, False])
    if kind == 3:
        return []
    if kind == 4:
        return {}
    if kind == 5 and depth < 3:
        return [_random_value(rng, depth + 1) for _ in range(rng.randint(1, 4))]
    if kind == 6 and depth < 3:
        return {rng.choice(["", "12", "x", "frame", "aus", "format"]): _random_value(rng, depth + 1)}
    return rng.choice([0, 1, -1, 0.5, 1.5, 68, 1000])


def _nodes(tree, path=()):
    """Every (path, value) of a JSON tree, the root included."""
    yield path, tree
    if isinstance(tree, dict):
        for k, v in tree.items():
            yield from _nodes(v, (*path, k))
    elif isinstance(tree, list):
        for i, v in enumerate(tree):
            yield from _nodes(v, (*path, i))


def _replace(tree, path, value):
    if not path:
        return value
    parent = tree
    for p in path[:-1]:
        parent = parent[p]
    parent[path[-1]] = value
    return tree


def mutate_json(data: bytes, rng: random.Random) -> bytes:
    """One to three mutations of a JSON document as a tree: a node's type swapped, a number at a limit,
    a list emptied, nested or repeated, a key dropped or added."""
    tree = copy.deepcopy(json.loads(data))
    for _ in range(rng.randint(1, 3)):
        path, node = rng.choice(list(_nodes(tree)))
        kind = rng.randrange(7)
        if kind == 0 or (kind == 1 and not isinstance(node, (int, float))):
            tree = _replace(tree, path, _random_value(rng))
        elif kind == 1:
            tree = _replace(tree, path, _SPLICE.format(rng.randrange(len(LIMIT_NUMBERS))))
        elif kind == 2 and isinstance(node, (list, dict)):
            node.clear()
        elif kind == 3:
            tree = _replace(tree, path, [node] if rng.random() < 0.5 else [[[[node]]]])
        elif kind == 4 and isinstance(node, list) and node:
            node.extend(copy.deepcopy(node) * rng.randint(1, 20))
        elif kind == 5 and isinstance(node, dict) and node:
            node.pop(rng.choice(list(node)))
        elif kind == 6 and isinstance(node, dict):
            node[rng.choice(["", "extra", "12", "fps", "frame", "aus", "presets", "mixer"])] = _random_value(rng)
    text = json.dumps(tree)
    for i, number in enumerate(LIMIT_NUMBERS):
        text = text.replace(json.dumps(_SPLICE.format(i)), number)
    return text.encode()


CELLS = [b"", b"nan", b"inf", b"-inf", b"1e308", b"-0", b"-1", b"1" * 5000, b"x", b'"', b'"a,b"', b"0x10", b" ",
         b"99999999999999999999", b"1e-320", b"\xff\xfe", b"10:00:00:99.999"]


def mutate_csv(data: bytes, rng: random.Random) -> bytes:
    """One to three mutations of a CSV by its grammar: a cell at a limit, a column dropped or repeated,
    a row dropped, repeated or made ragged, the header renamed, the separator changed."""
    rows = [r.split(b",") for r in data.split(b"\n")]
    for _ in range(rng.randint(1, 3)):
        r = rng.randrange(len(rows))
        kind = rng.randrange(6)
        if kind == 0 and rows[r]:
            rows[r][rng.randrange(len(rows[r]))] = rng.choice(CELLS)
        elif kind == 1:
            c = rng.randrange(max(len(rows[0]), 1))
            drop = rng.random() < 0.5
            for row in rows:
                if c < len(row):
                    row[c:c + 1] = [] if drop else [row[c]] * 2
        elif kind == 2:
            rows[r:r + 1] = [] if rng.random() < 0.5 else [rows[r]] * rng.randint(2, 200)
        elif kind == 3:
            rows[r] = rows[r][:rng.randrange(len(rows[r]) + 1)] + [rng.choice(CELLS)] * rng.randint(0, 3)
        elif kind == 4 and rows[0]:
            rows[0][rng.randrange(len(rows[0]))] = rng.choice([b"AU99_r", b"AU12_r", b"timestamp", b"frame",
                                                              b"", b"AU" + b"1" * 5000 + b"_r", b"Timecode"])
        elif kind == 5:
            return b"\n".join(b";".join(row) for row in rows)
    return b"\n".join(b",".join(row) for row in rows)


TOKENS = [b"nan", b"inf", b"-inf", b"1e308", b"-1e308", b"-0", b"0", b"-1", b"1" * 5000, b"x", b"",
          b"4294967296", b"-99999999", b"1e-320", b"3/3/3", b"1//", b"0.5"]


def mutate_lines(data: bytes, rng: random.Random) -> bytes:
    """One to three mutations of a line-based mesh file (OBJ, ASCII PLY) by its grammar: a token (a
    coordinate, a face index, a header count or type) at a limit or removed, a line dropped or repeated."""
    lines = data.split(b"\n")
    for _ in range(rng.randint(1, 3)):
        i = rng.randrange(len(lines))
        words = lines[i].split(b" ")
        kind = rng.randrange(5)
        if kind == 0 and len(words) > 1:
            words[rng.randrange(1, len(words))] = rng.choice(TOKENS)
        elif kind == 1 and len(words) > 1:
            del words[rng.randrange(1, len(words))]
        elif kind == 2:
            words.extend(rng.choice(TOKENS) for _ in range(rng.randint(1, 5)))
        elif kind == 3:
            lines[i:i + 1] = [] if rng.random() < 0.5 else [lines[i]] * rng.randint(2, 100)
            continue
        elif kind == 4:
            words = [rng.choice([b"f", b"v", b"vt", b"vn", b"element", b"property", b"format", b"end_header"])] \
                + [rng.choice(TOKENS) for _ in range(rng.randint(0, 4))]
        lines[i] = b" ".join(words)
    return b"\n".join(lines)


def _npz(arrays) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, value in arrays.items():
            if isinstance(value, bytes):
                zf.writestr(name + ".npy", value)
            else:
                buf = io.BytesIO()
                np.lib.format.write_array(buf, np.asarray(value), allow_pickle=False)
                zf.writestr(name + ".npy", buf.getvalue())
    return out.getvalue()


def mutate_zip(data: bytes, rng: random.Random) -> bytes:
    """One or two members of an ``.npz`` replaced: by NaNs or infs, values times 1e300, another dtype or
    shape, an empty array, text, garbage bytes, or dropped; or a junk member added."""
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        arrays = {n[:-4]: np.load(io.BytesIO(zf.read(n)), allow_pickle=False) for n in zf.namelist()}
    for _ in range(rng.randint(1, 2)):
        name = rng.choice(list(arrays))
        a = arrays[name]
        kind = rng.randrange(9)
        if isinstance(a, bytes) or a.dtype.kind not in "fiub":  # already garbage or text
            continue
        if kind == 0 and a.dtype.kind == "f":
            a = a.copy()
            a.flat[rng.randrange(max(a.size, 1)) if a.size else 0:] = rng.choice([np.nan, np.inf, -np.inf])
        elif kind == 1 and a.dtype.kind in "fiu":
            a = a.astype(np.float64) * rng.choice([1e300, -1e300, 0.0, -1.0, 1e-300])
        elif kind == 2:
            a = a.astype(rng.choice([np.float32, np.int64, np.uint8, np.bool_, "U4"]))
        elif kind == 3:
            a = a.reshape(-1)[:rng.randint(0, max(a.size, 1))]
        elif kind == 4:
            a = np.zeros((0,) * max(a.ndim, 1))
        elif kind == 5:
            a = np.array("garbage" if rng.random() < 0.5 else '{"format": ' + "[" * 5000)
        elif kind == 6:
            a = bytes(rng.randrange(256) for _ in range(rng.randint(0, 200)))
        elif kind == 7:
            arrays.pop(name)
            continue
        elif kind == 8:
            arrays["junk" + str(rng.randrange(9))] = np.zeros(rng.choice([1, 10**6]), np.uint8)
            continue
        arrays[name] = a
    return _npz(arrays)


#: Reader name → its structure-aware mutation (the others are mutated by bytes alone).
STRUCTURED = {"descriptor_json": mutate_json, "presets": mutate_json, "landmarks": mutate_json,
              "timeline": mutate_json, "rules": mutate_json, "fdt": mutate_json,
              "openface": mutate_csv, "pyfeat": mutate_csv, "livelink": mutate_csv,
              "obj": mutate_lines, "model": mutate_zip}


def mutate_any(name, data: bytes, rng: random.Random) -> bytes:
    """Half by structure (where the reader has a grammar), half by bytes."""
    structured = STRUCTURED.get(name)
    if name == "ply" and rng.random() < 0.5:
        return mutate_lines(data, rng)
    if structured is not None and rng.random() < 0.5:
        return structured(data, rng)
    return mutate(data, rng)


# ------------------------------------------------------------------ consumers of what was read

def consumers() -> dict:
    """Reader name → function(what it read) running the code that uses it on a small face."""
    from pdeface.au.descriptor import replace_descriptors
    from pdeface.au.modelfile import load_face
    from pdeface.au.retarget import retarget
    from pdeface.fdt.deform import fdt_curves
    from pdeface.posing import pose_curves
    from pdeface.presets import merged_presets, resolve_preset
    from pdeface.surface.fit import face_mesh, fit_face
    from pdeface.surface.frame import landmark_points

    face = load_face("default")

    def posed(model, weights, mixer="sum"):
        C, R = pose_curves(model, weights, mixer)
        face_mesh(model, (1, 1), coefficients=C, residual=R)

    small, L = _small_mesh(), _small_landmarks()

    def mesh(m):
        T, _ = m.triangles()
        fit_face(m.vertices, T, L, **SMALL_FIT)

    fit_face(small.vertices, small.triangles()[0], L, **SMALL_FIT)  # once before the clock: scipy's imports

    def landmarks(read):
        fit_face(small.vertices, small.triangles()[0], landmark_points(small.vertices, *read), **SMALL_FIT)

    def model(m):
        face_mesh(m, (1, 1))
        if m.descriptors:
            posed(m, {m.descriptors[0].key: 1.0})
        retarget(face, m, descriptors=face.descriptors[:2])

    def descriptor(d):
        m = copy.copy(face)
        m.descriptors = replace_descriptors(face.descriptors, [d])
        posed(m, {d.key: 1.0})

    def presets(items):
        have = {d.key for d in face.descriptors}
        for p in items[:3]:
            weights, _ = resolve_preset(p, have)
            if weights:
                posed(face, weights, p.mixer)

    def timeline(t):
        t.channels()
        t.frame_end  # noqa: B018 - the property is the consumer
        known = merged_presets()
        have = {d.key for d in face.descriptors}
        for k in t.keys[:2]:
            weights = {a: w for a, w in k.aus.items() if a in have}
            for name, w in k.presets.items():
                if name in known:
                    pw, _ = resolve_preset(known[name], have)
                    weights.update({a: x * w for a, x in pw.items()})
            if weights:
                posed(face, weights)

    def fdt(table):
        C, R = fdt_curves(face, table, 1.0)
        face_mesh(face, (1, 1), coefficients=face.coefficients + C, residual=face.residual + R)

    def tracker(result):
        result.timeline.channels()

    return {"obj": mesh, "ply": mesh, "landmarks": landmarks, "model": model, "descriptor_json": descriptor, "descriptor_pdd": descriptor,
            "presets": presets, "timeline": timeline, "fdt": fdt, "openface": tracker, "pyfeat": tracker,
            "livelink": tracker, "fas": tracker}


_CONSUMERS = {}


def reader_inputs(name, seed=0):
    """Reader ``name``'s mutated inputs, in order, endlessly: input ``k`` of a seed is always the same bytes."""
    seeds = corpus_cache()[name][1]
    rng = random.Random(f"{seed}:{name}")
    while True:
        yield mutate_any(name, rng.choice(seeds), rng)


def reader_call(name):
    """function(path) reading ``path`` with reader ``name`` and feeding what it read to its consumer; returns
    whether the consumer ran."""
    read = readers()[name]
    if not _CONSUMERS:
        _CONSUMERS.update(consumers())
    consume = _CONSUMERS.get(name)

    def call(path):
        result = read(path)
        if consume is not None:
            consume(result)
            return True
        return False

    return call


def _waited_s():
    """Seconds this thread has spent runnable but waiting for a CPU (Linux's schedstat; 0 elsewhere)."""
    try:
        with open("/proc/thread-self/schedstat") as f:
            return int(f.read().split()[1]) / 1e9
    except (OSError, IndexError, ValueError):
        return 0.0


def timed(call, *args):
    """``call(*args)`` → (its result or None, wall seconds, CPU seconds of this process, the exception escaping
    other than a ``PdeFaceError`` or None, the ``PdeFaceError`` refusing the input or None, seconds the call
    waited for a CPU that other processes held)."""
    from pdeface.errors import PdeFaceError

    result, error, refusal = None, None, None
    t, c, w = time.perf_counter(), time.process_time(), _waited_s()
    try:
        result = call(*args)
    except PdeFaceError as exc:
        refusal = exc
    except Exception as exc:  # noqa: BLE001 - what the fuzzer is for
        error = exc
    return result, time.perf_counter() - t, time.process_time() - c, error, refusal, _waited_s() - w


class Clock:
    """The time limit, robust to a paused or loaded machine. An input is over the limit when its CPU time is,
    or when the time it took is: its wall time less the time it waited for a CPU that other processes held
    (so time blocked, on a read that never ends say, counts; a machine's load does not). An input that took
    longer than the limit with less CPU time is run once more before it counts: a process stopped (SIGSTOP)
    while the input ran is not the input's fault. Keeps the slowest input by wall and by CPU time, and counts
    the inputs over the limit on the wall clock (most, on a loaded machine, its load)."""

    def __init__(self, limit_s):
        self.limit_s, self.over, self.reruns, self.wall_over = limit_s, [], [], 0
        self.slowest, self.slowest_cpu = (0.0, None), (0.0, None)

    def check(self, k, wall, cpu, waited, again):
        """Record input ``k``'s times; ``again()`` runs it again and returns (wall, CPU, waited)."""
        took = wall - waited
        self.wall_over += wall > self.limit_s
        if took > self.limit_s and cpu <= self.limit_s:
            wall2, cpu2, waited2 = again()
            self.reruns.append({"input": k, "wall_s": wall, "cpu_s": cpu, "waited_s": waited, "rerun_wall_s": wall2,
                                "rerun_cpu_s": cpu2, "rerun_waited_s": waited2})
            if wall2 - waited2 <= self.limit_s:
                took = min(took, wall2 - waited2)  # the first run's extra time was the machine's, not the input's
            cpu = max(cpu, cpu2)
        if cpu > self.limit_s or took > self.limit_s:
            self.over.append({"input": k, "wall_s": wall, "cpu_s": cpu, "took_s": took})
        self.slowest = max(self.slowest, (wall, k), key=lambda x: x[0])
        self.slowest_cpu = max(self.slowest_cpu, (cpu, k), key=lambda x: x[0])

    def summary(self):
        return {"slowest_s": self.slowest[0], "slowest_input": self.slowest[1], "slowest_cpu_s": self.slowest_cpu[0],
                "slowest_cpu_input": self.slowest_cpu[1], "over_limit": len(self.over),
                "over_limit_inputs": self.over[:20], "wall_reruns": self.reruns[:20], "wall_rerun_count": len(self.reruns),
                "over_limit_on_wall": self.wall_over, "time_limit_s": self.limit_s,
                "limit_on": "cpu, or wall less the wait for a CPU (rerun once)"}


def fuzz(name, n, seed=0, slow_s=5.0, keep=5, progress=None, first=0):
    """Run reader ``name`` (and its consumer) on ``n`` mutated inputs, from input ``first`` on (the ones
    before it are made, not run: a campaign split between processes); returns a summary dict. ``progress``:
    a function called with the summary so far every 1,000 inputs."""
    suffix, _ = corpus_cache()[name]
    call = reader_call(name)
    failures, consumed, clock = [], 0, Clock(slow_s)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"input{suffix}"
        inputs = reader_inputs(name, seed)
        for _ in range(first):
            next(inputs)
        t0 = time.perf_counter(), time.process_time()
        for k in range(first, first + n):
            path.write_bytes(next(inputs))
            ran, wall, cpu, error, _, waited = timed(call, path)
            consumed += bool(ran)
            if error is not None:
                _keep(failures, keep, k, error)
            clock.check(k, wall, cpu, waited, lambda: _times(timed(call, path)))
            if progress and (k + 1 - first) % 1000 == 0:
                progress(_summary(name, k + 1 - first, consumed, failures, clock, t0, first))
    return _summary(name, n, consumed, failures, clock, t0, first)


def _times(run):
    return run[1], run[2], run[5]


def _summary(name, n, consumed, failures, clock, t0, first=0):
    return {"reader": name, "inputs": n, **({"first": first} if first else {}), "consumed": consumed,
            "failures": len(failures),
            "examples": [f for f in failures if f], **clock.summary(), "peak_rss_mb": peak_rss_mb(),
            "wall_s": time.perf_counter() - t0[0], "cpu_s": time.process_time() - t0[1]}


def _keep(failures, keep, k, exc):
    if len(failures) < keep:
        failures.append({"input": k, "error": f"{type(exc).__name__}: {str(exc)[:120]}",
                         "where": traceback.extract_tb(exc.__traceback__)[-1][:2]})
    else:
        failures.append(None)


# ------------------------------------------------------------------ the command line's arguments

#: Values an option is given: numbers at the limits, wrong types, and (per kind of file) bad and good files.
ARG_VALUES = ["-1", "0", "1", "0.5", "nan", "inf", "-inf", "1e308", "-0", "1e-300", "1" * 5000, "", "x", "12=1",
              "12", "AU12L=C", "5000=1", "99999,99999", "2,2", "default", "head", "happy", ":99999", "-",
              "/dev/null", "/nonexistent/file.obj", "1x1", "0x0", "65536x2"]
#: Commands run to the end when their arguments parse (quick on the bundled face); the rest are only parsed.
RUN_COMMANDS = {"mesh", "pose", "aus", "muscles", "import-au", "fdt apply", "fdt mean", "retarget"}


@functools.cache
def cli_module():
    """The module of the ``pdeface`` console entry point: the command as installed (scripts import no CLI
    module by name; see tests/core/test_rooms.py). Looked up once: reading every installed package's entry
    points took 50 ms, most of a command line's cost."""
    from importlib.metadata import entry_points

    main = entry_points(group="console_scripts")["pdeface"].load()
    return sys.modules[main.__module__]


def cli_commands() -> dict:
    """The commands fuzzed: every (sub)command parser but the groups and ``render`` (which runs Blender)."""
    cli = cli_module()
    return {n: p for n, p in cli.subcommands(cli.build_parser()).items() if n not in ("fdt", "stream", "render")}


def cli_inputs(rng, files, name=None, commands=None):
    """One command line: a (sub)command (``name``, or one drawn), a few of its options with values from
    :data:`ARG_VALUES` or ``files`` (bad and good files of each kind), its positionals, and ``-o`` into a
    scratch folder."""
    commands = commands or cli_commands()
    name = name or rng.choice(sorted(commands))
    parser = commands[name]
    argv = name.split()
    values = ARG_VALUES + files
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        if not action.option_strings:  # positional
            argv += [rng.choice(["default"] * 3 + values)] * (2 if action.nargs == "+" and rng.random() < 0.3 else 1)
        elif action.dest == "output":
            argv += [action.option_strings[0], files[0]]
        elif rng.random() < 0.35:
            argv.append(action.option_strings[-1])
            if action.nargs != 0:
                argv.append(rng.choice(list(action.choices) + values if action.choices else values))
    return name, argv


@contextlib.contextmanager
def one_parser(cli):
    """The ``pdeface`` parser built once for a campaign (building it takes longer than most inputs do);
    parsing leaves an argparse parser as it was, so each input still meets a fresh one."""
    build = cli.build_parser
    parser = build()
    cli.build_parser = lambda command=None: parser  # the whole parser serves every command
    try:
        yield parser
    finally:
        cli.build_parser = build


def fuzz_cli(n, seed=0, slow_s=5.0, keep=5, command=None, progress=None, first=0):
    """``n`` command lines through the ``pdeface`` command's ``main`` (all of ``command``'s, or commands drawn
    at random), from line ``first`` on; returns a summary dict like :func:`fuzz`'s."""
    cli = cli_module()
    target = f"cli {command}" if command else "cli"
    with one_parser(cli), tempfile.TemporaryDirectory() as tmp:
        call = cli_call(cli)
        failures, ran, clock = [], 0, Clock(slow_s)
        lines = cli_lines(tmp, seed, command)
        for _ in range(first):
            next(lines)
        t0 = time.perf_counter(), time.process_time()
        for k in range(first, first + n):
            name, argv = next(lines)
            code, wall, cpu, error, _, waited = timed(call, name, argv)
            ran += code == "ran"
            if error is not None:
                error.args = (f"{error} for {' '.join(a[:40] for a in argv)}",)
                _keep(failures, keep, k, error)
            clock.check(k, wall, cpu, waited, lambda name=name, argv=argv: _times(timed(call, name, argv)))
            if progress and (k + 1 - first) % 1000 == 0:
                progress(_summary(target, k + 1 - first, ran, failures, clock, t0, first))
        return _summary(target, n, ran, failures, clock, t0, first)


def cli_lines(tmp, seed=0, command=None):
    """Command lines, in order, endlessly (all of ``command``'s, or commands drawn): line ``k`` of a seed is always
    the same; the files they name (good and mutated ones of each reader's kind) are written into ``tmp``."""
    rng = random.Random(f"{seed}:cli" + (f":{command}" if command else ""))
    files = [str(Path(tmp) / "out.obj")]
    for reader, (suffix, seeds) in corpus_cache().items():
        for i, data in enumerate(seeds[:1] + [mutate_any(reader, seeds[0], rng)]):
            path = Path(tmp) / f"{reader}{i}{suffix}"
            path.write_bytes(data)
            files.append(str(path))
    commands = cli_commands()
    while True:
        yield cli_inputs(rng, files, command, commands)


def cli_call(cli):
    """function(name, argv) running a command line as the campaign does: the quick commands through ``main`` to
    the end (returns "ran"), the rest parsed; an exit status other than 0 or 2 raises ``RuntimeError``."""
    from pdeface.errors import PdeFaceError

    build_parser, main = cli.build_parser, cli.main

    def call(name, argv):
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            try:
                if name in RUN_COMMANDS:
                    code, ran = main(argv), "ran"
                else:
                    build_parser().parse_known_args(argv)
                    code, ran = 0, "parsed"
            except SystemExit as exc:
                code, ran = exc.code, "parsed"
            except PdeFaceError:
                code, ran = 2, "refused"  # a command run outside main: its error
        if code not in (0, 2):
            raise RuntimeError(f"exit status {code}")
        return ran

    return call


_CORPUS = {}


def corpus_cache():
    if not _CORPUS:
        _CORPUS.update(corpus())
    return _CORPUS


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def cap_memory(extra_mb):
    """Cap the address space at its size now plus ``extra_mb``: a bigger allocation is a MemoryError."""
    with open("/proc/self/status") as f:
        size_kb = next(int(line.split()[1]) for line in f if line.startswith("VmSize:"))
    limit = (size_kb * 1024) + extra_mb * 2**20
    resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))
    return limit


def replay(kind, name, k, seed=0, limit_s=5.0, save=None):
    """Run input ``k`` of a target again (``kind`` "reader" or "cli"; ``name`` the reader or command, None for
    the commands drawn): the inputs before it are made (not run) to reach it. Returns a dict of what it did."""
    with tempfile.TemporaryDirectory() as tmp:
        if kind == "reader":
            inputs = reader_inputs(name, seed)
            for _ in range(k):
                next(inputs)
            data = next(inputs)
            path = Path(tmp) / f"input{corpus_cache()[name][0]}"
            path.write_bytes(data)
            if save:
                Path(save).write_bytes(data)
            call, args, what = reader_call(name), (path,), f"{len(data)} bytes"
        else:
            cli = cli_module()
            with one_parser(cli):
                lines = cli_lines(tmp, seed, name)
                for _ in range(k):
                    next(lines)
                command, argv = next(lines)
                if save:
                    Path(save).write_text(json.dumps(argv))
                return _replayed(f"cli {name}" if name else "cli", k, timed(cli_call(cli), command, argv), limit_s,
                                 " ".join(a[:40] for a in argv))
        return _replayed(name, k, timed(call, *args), limit_s, what)


def _replayed(name, k, run, limit_s, what):
    result, wall, cpu, error, refusal, waited = run
    if error is not None:
        outcome = f"FAILURE {type(error).__name__}: {str(error)[:200]}"
    elif refusal is not None:
        outcome = f"refused: {str(refusal)[:200]}"
    else:
        outcome = {True: "read and consumed", False: "read", "ran": "ran to the end"}.get(result, str(result))
    return {"target": name, "input": k, "what": what, "outcome": outcome, "failure": error is not None,
            "wall_s": wall, "cpu_s": cpu, "waited_s": waited,
            "over_limit": max(cpu, wall - waited) > limit_s, "peak_rss_mb": peak_rss_mb()}


def _write_json(path, results):
    tmp = Path(str(path) + ".tmp")
    tmp.write_text(json.dumps(results, indent=1))
    tmp.replace(path)


def join_parts(records) -> list:
    """Records of one target run in parts (``--first``) joined into one when they do not overlap: done when they
    follow each other from input 0 without a gap and the last is done; any other record as it is."""
    by_target = {}
    for r in records:
        by_target.setdefault(r["reader"], []).append(r)
    out = []
    for parts in by_target.values():
        parts.sort(key=lambda r: r.get("first", 0))
        starts = [r.get("first", 0) for r in parts]
        ends = [a + r["inputs"] for a, r in zip(starts, parts)]
        if len(parts) == 1 or any(e > a for e, a in zip(ends, starts[1:])):
            out += parts
            continue
        joined = {"reader": parts[0]["reader"], "parts": [[s, r["inputs"]] for s, r in zip(starts, parts)],
                  "done": starts == [0, *ends[:-1]] and parts[-1].get("done", True),
                  "slowest_s": 0.0, "slowest_input": None, "slowest_cpu_s": 0.0, "slowest_cpu_input": None,
                  "examples": [], "over_limit_inputs": [], "wall_reruns": []}
        for r in parts:
            for key in ("inputs", "consumed", "failures", "over_limit", "wall_rerun_count", "over_limit_on_wall",
                        "wall_s", "cpu_s"):
                joined[key] = joined.get(key, 0) + r.get(key, 0)
            for key in ("examples", "over_limit_inputs", "wall_reruns"):
                joined[key] += r[key]
            for key in ("slowest_s", "slowest_cpu_s"):
                if r[key] >= joined[key]:
                    joined[key], joined[key.replace("_s", "_input")] = r[key], r[key.replace("_s", "_input")]
            joined["peak_rss_mb"] = max(joined.get("peak_rss_mb", 0), r["peak_rss_mb"])
            joined["limit_on"] = sorted({*joined.get("limit_on", []), r.get("limit_on", "wall")})
        out.append(joined)
    return out


def markdown(results, args, seconds, replays=()) -> str:
    """The campaign's table for docs/measurements. With ``--gather``: a line for every reader and command, those
    without a finished run of ``--inputs`` inputs saying how far they got. A ``--replay --json`` record of an
    input over the limit is noted beside it, and settles it when under the limit (the rerun the clock makes)."""
    replayed = {(r["target"], r["input"]): r for r in replays}
    if args.gather:  # targets run one process each (--readers NAME --json FILE), their summaries gathered
        how = (f"Each target run in a process of its own, `python -m scripts.bench.fuzz_readers --inputs N --readers "
               f"NAME --json FILE` (or `--commands NAME`; `--first K` for a part), seed {args.seed}, each input "
               f"limited to {args.time_limit:g} s of CPU time and of wall time less the wait for a CPU that other "
               "processes held (an input over it with less CPU time is run once more), the process to "
               f"{args.memory_mb} MB past its warm-up size; gathered with `--gather FILE...`.")
        names = list(readers()) + [f"cli {c}" for c in sorted(cli_commands())]
        results = [r for n in names for r in ([r for r in results if r["reader"] == n] or [{"reader": n}])] + \
            [r for r in results if r["reader"] not in names]
    else:
        how = (f"`python -m scripts.bench.fuzz_readers --inputs {args.inputs} --cli --seed {args.seed}` "
               f"({seconds / 60:.0f} min, load {os.getloadavg()[0]:.1f}; each input limited to {args.time_limit:g} s "
               f"of CPU time and of wall time less the wait for a CPU, the process to {args.memory_mb} MB past its "
               "warm-up size).")
    ran = [r for r in results if "inputs" in r]
    full = [r for r in ran if r["inputs"] >= args.inputs and r.get("done", True)]
    lines = [f"# The fuzzer: {len(full)} of {len(results)} targets at {args.inputs:,} inputs", "", how, "",
             ("| target | inputs | read and consumed | failures | over the time limit | wall outliers re-run | "
             "slowest wall (s) | slowest CPU (s) |"), "|---|---:|---:|---:|---:|---:|---:|---:|"]
    notes = []
    for r in results:
        if "inputs" not in r:
            lines.append(f"| {r['reader']} | not yet run | | | | | | |")
            continue
        inputs = f"{r['inputs']:,}" + ("" if r.get("done", True) else f" (not yet {args.inputs:,})")
        over, reruns = r["over_limit"], r.get("wall_rerun_count", "—")
        over_inputs = r.get("over_limit_inputs") or (  # a run before the CPU clock kept its slowest input alone
            [{"input": r["slowest_input"], "wall_s": r["slowest_s"], "cpu_s": None}] if over == 1 else [])
        for o in over_inputs:
            again = replayed.get((r["reader"], o["input"]))
            how = "`--replay {} --{} {}`".format(o["input"], "commands" if r["reader"].startswith("cli ") else "readers",
                                                 r["reader"].removeprefix("cli "))
            first = f"{o['wall_s']:.2f} s wall" + ("" if o["cpu_s"] is None else f", {o['cpu_s']:.2f} s CPU")
            if again and not again["over_limit"] and not again["failure"]:
                over, reruns = over - 1, 1 if reruns == "—" else reruns  # the rerun the clock makes, made by --replay
                notes.append(f"- {r['reader']} input {o['input']}: over the limit on the wall clock alone ({first}); "
                             f"replayed ({how}): {again['outcome']} in {again['wall_s']:.2f} s wall, "
                             f"{again['cpu_s']:.2f} s CPU: not counted.")
            elif again:
                notes.append(f"- {r['reader']} input {o['input']} over the limit: {first}; replayed ({how}): "
                             f"{again['outcome']} in {again['wall_s']:.2f} s wall, {again['cpu_s']:.2f} s CPU "
                             f"(`{again['what']}`).")
            else:
                notes.append(f"- {r['reader']} input {o['input']} over the limit: {first} ({how} replays it)")
        cpu = f"{r['slowest_cpu_s']:.2f}" if "slowest_cpu_s" in r else "—"
        lines.append(f"| {r['reader']} | {inputs} | {r['consumed']:,} | {r['failures']} | {over} | {reruns} | "
                     f"{r['slowest_s']:.2f} | {cpu} |")
        for f in r["examples"]:
            notes.append(f"- {r['reader']} input {f['input']}: `{f['error']}` at {f['where']}")
        if "parts" in r:
            notes.append(f"- {r['reader']}: run in {len(r['parts'])} processes, " + ", ".join(
                f"inputs {a:,} to {a + n - 1:,}" for a, n in r["parts"]) + " (`--first`).")
    older = [r["reader"] for r in ran if "cpu, or wall twice" in str(r.get("limit_on"))]
    if older:
        notes.append(f"- {', '.join(older)}: (some) inputs run before the clock subtracted the wait for a CPU: "
                     "over the limit meant CPU time over it, or wall time over it twice (the first run's wall time "
                     "alone sends an input to the rerun).")
    lines += ["", (f"{sum(r['inputs'] for r in ran):,} inputs in all. Peak RSS {max(r['peak_rss_mb'] for r in ran):.0f}"
              " MB. *Read and consumed*: inputs the reader accepted whose consumer then ran (the rules and packets "
              "have none; a command's: command lines run to the end). *Slowest CPU*: \u2014 where the run predates "
              "the CPU clock (its limit was on wall time alone)."), "", *notes]
    return "\n".join(lines).rstrip() + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--inputs", type=int, default=100_000, help="mutated inputs per target")
    ap.add_argument("--readers", default="", help="comma-separated reader names (default: all)")
    ap.add_argument("--cli", action="store_true", help="also fuzz the command line's arguments (commands drawn)")
    ap.add_argument("--commands", default="",
                    help="comma-separated commands ('all': every one) each given --inputs command lines of its own")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--first", type=int, default=0, metavar="K",
                    help="start at input K (a target split between processes; --gather joins them)")
    ap.add_argument("--time-limit", type=float, default=5.0,
                    help="CPU seconds an input may take (or wall seconds, twice running)")
    ap.add_argument("--memory-mb", type=int, default=500, help="address space past the warm-up size")
    ap.add_argument("--json", help="write the summaries here (every 1,000 inputs, and at the end); with --replay: its record")
    ap.add_argument("--markdown", help="write the table here (docs/measurements/fuzz_readers.md)")
    ap.add_argument("--replay", type=int, metavar="N",
                    help="run input N of one target again (--readers NAME, --commands NAME or --cli) and print it")
    ap.add_argument("--save", metavar="FILE", help="with --replay: write the input (a command line: as JSON) here")
    ap.add_argument("--gather", nargs="+", metavar="JSON", help="write --markdown from these runs' --json summaries")
    args = ap.parse_args(argv)
    if args.gather:
        records = [json.loads(Path(f).read_text()) for f in args.gather]
        replays = [r for r in records if isinstance(r, dict)]  # --replay N --json FILE
        out = join_parts([r for rs in records if isinstance(rs, list) for r in rs])
        if args.markdown:
            Path(args.markdown).write_text(markdown(out, args, None, replays))
        return 1 if any(r["failures"] or r["over_limit"] for r in out) else 0
    names = [r for r in args.readers.split(",") if r] or ([] if args.commands or args.replay is not None
                                                         else list(readers()))
    commands = sorted(cli_commands()) if args.commands == "all" else [c for c in args.commands.split(",") if c]
    if args.replay is not None:
        if len(names) + len(commands) + args.cli != 1:
            ap.error("--replay N needs one target: --readers NAME, --commands NAME or --cli")
        kind, name = ("reader", names[0]) if names else ("cli", commands[0] if commands else None)
        r = replay(kind, name, args.replay, args.seed, args.time_limit, args.save)
        print(json.dumps(r, indent=1))
        if args.json:
            _write_json(args.json, r)
        return 1 if r["failure"] or r["over_limit"] else 0
    # argparse looks each message up through gettext, which searches the locale folders every time: a third of
    # a command line's parse; the fuzzer checks exit statuses, not the messages' language.
    os.environ.setdefault("LANGUAGE", "C")
    corpus_cache()
    _CONSUMERS.update(consumers())
    cap_memory(args.memory_mb)
    t0 = time.perf_counter()
    out = []
    targets = [("reader", n) for n in names] + ([("cli", None)] if args.cli else []) + [("cli", c) for c in commands]
    for kind, name in targets:
        def progress(r):  # the summary so far, so a campaign stopped early still says how far it got
            if args.json:
                _write_json(args.json, [*out, {**r, "done": False}])

        r = fuzz_cli(args.inputs, args.seed, args.time_limit, command=name, progress=progress, first=args.first) \
            if kind == "cli" else \
            fuzz(name, args.inputs, args.seed, args.time_limit, progress=progress, first=args.first)
        out.append({**r, "done": True})
        print(f"{r['reader']:16s} {r['inputs']:>7d} inputs  {r['consumed']:>7d} consumed  {r['failures']} failures  "
              f"{r['over_limit']} over {args.time_limit:g} s  slowest {r['slowest_s']:.3f} s "
              f"(CPU {r['slowest_cpu_s']:.3f} s)  {r['wall_rerun_count']} rerun  peak RSS {r['peak_rss_mb']:.0f} MB",
              flush=True)
        for f in r["examples"]:
            print(f"    input {f['input']}: {f['error']} at {f['where']}")
        if args.json:
            _write_json(args.json, out)
    if args.markdown:
        Path(args.markdown).write_text(markdown(out, args, time.perf_counter() - t0))
    return 1 if any(r["failures"] or r["over_limit"] for r in out) else 0


if __name__ == "__main__":
    sys.exit(main())
