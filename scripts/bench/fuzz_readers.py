"""Fuzz every pdeface reader with mutated copies of valid files (seeded, deterministic).

Usage: python -m scripts.bench.fuzz_readers [--inputs 100000] [--readers obj,model,...] [--seed 0] [--json OUT]

Each reader gets a corpus of valid files made from the project's own data (the
default face, its descriptors, presets, a timeline, tracker CSVs, packets), and
``--inputs`` mutations of them: bit flips, byte runs inserted, deleted or
repeated, truncation, numbers replaced by huge, negative, NaN or inf ones, and
deep nesting. A reader passes an input when it returns or raises
``PdeFaceError``; anything else, or an input slower than 2 s, is a failure.
Prints per reader: inputs tried, failures (with the first few), slowest input,
peak RSS. The test suite runs a short, fixed slice of the same (tests/core/test_fuzz.py).
"""
from __future__ import annotations

import argparse
import json
import random
import resource
import sys
import tempfile
import time
import traceback
from pathlib import Path

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
NUMBERS = [b"1e308", b"-1e308", b"nan", b"NaN", b"inf", b"-inf", b"Infinity", b"9" * 400, b"-1", b"0",
           b"4294967296", b"1e-320", b"99999999999", b"-0"]


def _small_mesh():
    """A small PDE face (a few hundred vertices): quick to parse thousands of times."""
    from pdeface.au.modelfile import load_face
    from pdeface.surface.fit import face_mesh

    return face_mesh(load_face("default"), (1, 1))


def corpus() -> dict:
    """Reader name → (file suffix, list of valid file bytes)."""
    from pdeface.animation.timeline import sequence_timeline, timeline_to_json
    from pdeface.au.descriptorfile import descriptor_to_bytes, descriptor_to_json
    from pdeface.au.modelfile import load_face, model_to_bytes
    from pdeface.io.meshio import write_obj, write_ply
    from pdeface.presets import PRESETS, preset_to_json
    from pdeface.stream.rules import DEFAULT_RULES

    face = load_face("default")
    small = _small_mesh()
    with tempfile.TemporaryDirectory() as tmp:
        write_obj(Path(tmp) / "m.obj", small)
        write_ply(Path(tmp) / "m.ply", small)
        obj, ply = (Path(tmp) / "m.obj").read_bytes(), (Path(tmp) / "m.ply").read_bytes()
    descriptors = face.descriptors[:4]
    face_only = model_to_bytes(face, descriptors=False)
    return {
        "obj": (".obj", [obj]),
        "ply": (".ply", [ply]),
        "model": (".npz", [face_only]),
        "descriptor_json": (".json", [json.dumps(descriptor_to_json(d)).encode() for d in descriptors]),
        "descriptor_pdd": (".pdd", [descriptor_to_bytes(d) for d in descriptors]),
        "presets": (".json", [json.dumps(preset_to_json(p)).encode() for p in list(PRESETS.values())[:3]]),
        "landmarks": (".json", [json.dumps({"indices": list(range(0, 680, 10))}).encode(),
                                json.dumps({"points": [[i * 0.1, -i * 0.2, 1.5] for i in range(68)]}).encode()]),
        "timeline": (".json", [json.dumps(timeline_to_json(sequence_timeline(["happy", "sad"], 12))).encode()]),
        "rules": (".json", [Path(DEFAULT_RULES).read_bytes()]),
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
            "timeline": load_timeline, "rules": AUBlender.load,
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
            digits = [i for i in range(len(b)) if 48 <= b[i] <= 57]
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


def fuzz(name, n, seed=0, slow_s=2.0, keep=5):
    """Run reader ``name`` on ``n`` mutated inputs; returns a summary dict."""
    from pdeface.errors import PdeFaceError

    suffix, seeds = corpus_cache()[name]
    read = readers()[name]
    rng = random.Random(f"{seed}:{name}")
    failures, slowest = [], (0.0, None)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"input{suffix}"
        for k in range(n):
            data = mutate(rng.choice(seeds), rng)
            path.write_bytes(data)
            t = time.perf_counter()
            try:
                read(path)
            except PdeFaceError:
                pass
            except Exception as exc:  # noqa: BLE001 - what the fuzzer is for
                if len(failures) < keep:
                    failures.append({"input": k, "error": f"{type(exc).__name__}: {str(exc)[:120]}",
                                     "where": traceback.extract_tb(exc.__traceback__)[-1][:2]})
                else:
                    failures.append(None)
            dt = time.perf_counter() - t
            if dt > slowest[0]:
                slowest = (dt, k)
    return {"reader": name, "inputs": n, "failures": len(failures),
            "examples": [f for f in failures if f], "slowest_s": slowest[0],
            "over_2s": int(slowest[0] > slow_s), "peak_rss_mb": peak_rss_mb()}


_CORPUS = {}


def corpus_cache():
    if not _CORPUS:
        _CORPUS.update(corpus())
    return _CORPUS


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--inputs", type=int, default=100_000, help="mutated inputs per reader")
    ap.add_argument("--readers", default="", help="comma-separated reader names (default: all)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", help="write the summaries here")
    args = ap.parse_args(argv)
    names = [r for r in args.readers.split(",") if r] or list(readers())
    out = []
    for name in names:
        r = fuzz(name, args.inputs, args.seed)
        out.append(r)
        print(f"{name:16s} {r['inputs']:>7d} inputs  {r['failures']} failures  slowest {r['slowest_s']:.3f} s  "
              f"peak RSS {r['peak_rss_mb']:.0f} MB", flush=True)
        for f in r["examples"]:
            print(f"    input {f['input']}: {f['error']} at {f['where']}")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 1 if any(r["failures"] or r["over_2s"] for r in out) else 0


if __name__ == "__main__":
    sys.exit(main())
