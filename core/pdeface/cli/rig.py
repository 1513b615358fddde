"""``pdeface rig``: a head rigged in one go (landmarks → fit → retarget → every key on the mesh)."""
from __future__ import annotations

import json

from ..assets import DEFAULT
from ..heap import grow_heap
from ..io.files import check_output
from ..rig import rig_head
from .common import log, plain_scipy_docs, unit_option
from .landmarks import accept_option

#: The memory ``pdeface rig`` has the kernel give on a thread beside the chain's start (:func:`pdeface.heap.grow_heap`),
#: with its landmarks found (the renders take ~100 MB of it): no more than the rig faults on ICT's 27k-vertex head,
#: more being memory held for nothing on a small head (sizes tried and what it gains: docs/design/rig.md).
RIG_HEAP = 224 << 20
#: ... and with its landmarks given (no renders).
RIG_HEAP_GIVEN_LANDMARKS = 128 << 20


def cmd_rig(args):
    for name in ("keys.npz", "face.npz", "rigged.npz", "landmarks.json", "report.json"):
        check_output(f"{args.output}/{name}", args.mesh, args.landmarks, args.parts)
    # the pages of the chain's arrays faulted on another core while it starts (the command's process keeps its
    # heap: cli.run; elsewhere nothing is done)
    grow_heap(RIG_HEAP if args.landmarks is None else RIG_HEAP_GIVEN_LANDMARKS)
    plain_scipy_docs()  # before the chain loads scipy's subpackages
    report = rig_head(args.mesh, args.output, landmarks=args.landmarks, unit=args.unit, parts=args.parts,
                      descriptors=args.descriptors, presets=not args.no_presets, blend=args.blend,
                      accept=args.accept, log=log)
    for note in report["binding_notes"]:
        log(note)
    print(json.dumps({"output": str(args.output), "keys": report["keys"], "timings": report["timings"],
                      "cpu_timings": report["cpu_timings"], "files": report["outputs"]}))


def register(sub):
    """The ``rig`` command."""
    p = sub.add_parser("rig", help="rig a head in one go: landmarks, face model, retargeted AUs and every key on "
                                   "the mesh (keys.npz for other tools)")
    p.add_argument("mesh", help="head or body mesh (.obj/.ply/.glb/.gltf), or 'head' (the bundled ICT head)")
    p.add_argument("--landmarks", help="the mesh's 68 landmarks (JSON; default: found, needs pdeface[landmarks])")
    p.add_argument("--parts", help="JSON of part kind → vertex indices overriding the automatic parts "
                                   "(see 'pdeface parts')")
    unit_option(p)
    p.add_argument("--descriptors", default=DEFAULT, help="face model whose AU descriptors are retargeted "
                                                          "(default: the bundled ones)")
    p.add_argument("--no-presets", action="store_true", help="AU keys only (default: also a key per expression "
                                                             "preset, as the add-on makes)")
    p.add_argument("--blend", action="store_true", help="also head.blend, rigged by the add-on (needs Blender's "
                                                        "bpy module: pdeface[blender])")
    accept_option(p)
    p.add_argument("-o", "--output", required=True,
                   help="folder to write: landmarks.json, face.npz, rigged.npz, keys.npz (the rest mesh and each "
                        "key's vertex deltas), report.json (what each step found and took)")
    p.set_defaults(func=cmd_rig)
