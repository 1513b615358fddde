"""``pdeface stream send`` and ``stream play``: the live AU stream's sender and headless player."""
from __future__ import annotations

import json
import os

from ..errors import PdeFaceError
from ..io.arguments import address, number_in, port
from ..stream.player import MODES, Player
from ..stream.rules import DEFAULT_RULES, AUBlender
from ..stream.sender import read_packets, send
from .common import log

#: Where ``--token`` is read from when not given (a token on the command line shows in the process list).
TOKEN_ENV = "PDEFACE_STREAM_TOKEN"

# The stream's ranges (argparse types: a bad value is a usage error at parse time, naming the option).
HZ = number_in(1.0, 1000.0, what="a rate of 1 to 1000 poses per second")
RATE = number_in(0.01, 1e6, zero=True, what="0 (as fast as allowed) or 0.01 to 1e6 packets per second")
SECONDS = number_in(0.0, 3600.0, what="a number of seconds from 0 to 3600")
DURATION = number_in(0.0, 1e7, what="a number of seconds from 0 (no limit) to 1e7")


def token_option(p, help):
    p.add_argument("--token", default=os.environ.get(TOKEN_ENV) or None,
                   help=f"{help} (default: ${TOKEN_ENV}, when set)")


def cmd_send(args):
    packets, bad = read_packets(args.file)
    for line in bad:
        log(f"skipped {line}")
    try:
        result = send(packets, args.host, args.port, args.rate, args.listen, token=args.token)
    except OSError as exc:
        raise PdeFaceError(f"{args.host}:{args.port}: {exc.strerror or exc}") from None
    print(json.dumps({**result, "skipped": len(bad)}))


def _print_pose(t, pose):
    print(json.dumps({"t": round(t, 4), "au": {k: round(w, 4) for k, w in pose.items()}}), flush=True)


def cmd_play(args):
    blender = AUBlender.load(args.rules or DEFAULT_RULES) if args.rules is not None else None
    player = Player(transition=args.transition, mode=args.mode, blender=blender, token=args.token)
    try:
        if args.connect:
            player.connect(*args.connect)
            log(f"connecting to {args.connect[0]}:{args.connect[1]}")
        else:
            host, bound = player.listen(*args.listen)
            log(f"listening on {host}:{bound}")
    except OSError as exc:
        raise PdeFaceError(f"cannot listen/connect: {exc.strerror or exc}") from None
    try:
        player.run(args.hz, args.duration, args.keep_running, _print_pose if args.print else None)
    except KeyboardInterrupt:
        pass
    finally:
        player.close()
    log(json.dumps(player.stats.as_dict()))


def register(sub):
    """The ``stream`` command and its subcommands."""
    p = sub.add_parser("stream", help="live AU stream: the remote player and a sender")
    ssub = p.add_subparsers(dest="stream_command", required=True)
    q = ssub.add_parser("send", help="replay a file of AU packets to a player")
    q.add_argument("file", help="one {1,2,5} / {12:0.8} / {12E} packet or JSON line per line")
    q.add_argument("--host", default="127.0.0.1", help="the player's address")
    q.add_argument("--port", type=port, default=5000, help="the player's port")
    q.add_argument("--rate", type=RATE, default=4.0, help="packets per second (0: as fast as allowed)")
    q.add_argument("--listen", action="store_true", help="wait for a player to connect instead")
    token_option(q, "the player's shared token: sent first, so this sender may end or stop it")
    q.set_defaults(func=cmd_send)

    q = ssub.add_parser("play", help="run the player headless")
    g = q.add_mutually_exclusive_group()
    g.add_argument("--listen", type=address, default=("127.0.0.1", 5000),
                   help="HOST:PORT to listen on (default 127.0.0.1:5000)")
    g.add_argument("--connect", type=address, help="HOST:PORT of a sender that listens")
    q.add_argument("--print", action="store_true", help="print each pose as a JSON line")
    q.add_argument("--mode", choices=MODES, default="queue",
                   help="queue: play every packet in turn (the FAS player); live: head for the newest")
    q.add_argument("--transition", type=SECONDS, default=0.25, help="seconds from one pose to the next")
    q.add_argument("--rules", nargs="?", const="", default=None,
                   help="apply the AU blender's co-occurrence rules (a rules JSON, or the bundled ones)")
    q.add_argument("--hz", type=HZ, default=60.0, help="poses per second")
    q.add_argument("--duration", type=DURATION, default=0.0, help="stop after this many seconds (0: never)")
    q.add_argument("--keep-running", action="store_true", help="do not exit when the sender ends")
    token_option(q, "a shared secret: only senders that present it may end or stop the player or send JSON lines")
    q.set_defaults(func=cmd_play)
