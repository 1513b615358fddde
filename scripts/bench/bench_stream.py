"""Benchmark the live AU stream on loopback (issue #6 targets).

Usage: python -m scripts.bench.bench_stream [--duration 60] [--rate 1000] [--flood 600] [--hostile 600]

Prints, measured in this run:
- receive → pose applied latency (p50, p99) in live mode at RATE packets/s for DURATION s, and
  packets sent / received / played / lost, against the 16.7 ms (one frame at 60 Hz) target;
- the player's resident memory at the start and end of a FLOOD-second flood of malformed
  packets (garbage, oversized, NaN, unknown AUs, partial packets), which must stay flat;
- HOSTILE seconds of the packets that once broke the reader (huge numbers, 60 KB lines, endless
  digits, deep nesting: scripts/bench/fuzz_readers.HOSTILE_PACKETS) each followed by a good packet, in
  queue mode: every good packet must be acked and played, RSS flat.
"""
from __future__ import annotations

import socket
import threading
import time

from pdeface.stream.player import Player
from pdeface.stream.sender import Sender

from scripts.bench.benchlib import bench_parser, run_bench


def rss_mb():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def play(player, stop):
    while not stop.is_set():
        player.wait(0.002)
        player.pose()


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--flood", type=float, default=600.0)
    ap.add_argument("--hostile", type=float, default=600.0)
    args = ap.parse_args(argv)

    player = Player(mode="live", transition=0.05)
    address = player.listen()
    stop = threading.Event()
    controller = threading.Thread(target=play, args=(player, stop), daemon=True)
    controller.start()
    n = int(args.duration * args.rate)
    packets = [f"{{12:{(i % 100) / 100:.2f},6:{((i * 7) % 100) / 100:.2f},1}}" for i in range(n)]
    with socket.create_connection(address) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        t = time.perf_counter()
        result = Sender(packets, args.rate).run(sock, drain=5.0)
        elapsed = time.perf_counter() - t
    end = time.monotonic() + 5
    while player.stats.played < result["sent"] and time.monotonic() < end:
        time.sleep(0.01)
    st = player.stats.as_dict()
    lost = result["sent"] - st["played"]
    print(f"{result['sent']} packets in {elapsed:.1f} s ({result['sent'] / elapsed:.0f}/s): received {st['packets']}, "
          f"played {st['played']}, lost {lost}, dropped {st['dropped']}, pauses {result['pauses']}")
    print(f"receive -> pose applied: p50 {st['latency_ms_p50']:.3f} ms, p99 {st['latency_ms_p99']:.3f} ms "
          f"(target p99 <= 16.7 ms, ratio {st['latency_ms_p99'] / 16.7:.3f})")
    stop.set()
    controller.join()
    player.close()

    # Flood of malformed packets.
    player = Player(mode="live", transition=0.05)
    address = player.listen()
    stop = threading.Event()
    controller = threading.Thread(target=play, args=(player, stop), daemon=True)
    controller.start()
    junk = (b"{12:nan}{x,y}garbage \x00\xff {999,12}{" + b"1," * 700 + b"1}{12:0.5" + b"\n" * 3
            + b'{"au_r": 7}\n-9 {}{4}')
    start = rss_mb()
    sent = 0
    t_end = time.monotonic() + args.flood
    samples = []
    with socket.create_connection(address) as sock:
        while time.monotonic() < t_end:
            sock.sendall(junk * 50)
            sent += len(junk) * 50
            if len(samples) < int((args.flood - (t_end - time.monotonic())) / max(args.flood / 10, 1e-3)) + 1:
                samples.append(round(rss_mb(), 1))
    time.sleep(0.5)
    end_rss = rss_mb()
    st = player.stats.as_dict()
    print(f"malformed flood {args.flood:.0f} s, {sent / 1e6:.0f} MB: garbage events {st['garbage']}, valid packets "
          f"{st['packets']}; RSS start {start:.1f} MB, end {end_rss:.1f} MB (growth {end_rss - start:+.1f} MB); "
          f"samples {samples}")
    stop.set()
    controller.join()
    player.close()
    hostile_run(args.hostile)


def hostile_run(seconds):
    """Hostile packets, each followed by a good one: count the good ones acked and played."""
    from scripts.bench.fuzz_readers import HOSTILE_PACKETS  # here: the RSS figures before are the player's alone

    player = Player(mode="queue", transition=0.0, receive_capacity=10_000, playout_capacity=10_000)
    address = player.listen()
    stop = threading.Event()
    controller = threading.Thread(target=play, args=(player, stop), daemon=True)
    controller.start()
    acks, good, hostile, samples = [0], 0, 0, []
    start = rss_mb()
    with socket.create_connection(address) as sock:
        def count_acks():
            buf = b""
            while True:
                try:
                    data = sock.recv(65536)
                except OSError:
                    return
                if not data:
                    return
                buf += data
                *lines, buf = buf.split(b"\n")
                acks[0] += sum(1 for x in lines if x.strip() == b"1")
        reader = threading.Thread(target=count_acks, daemon=True)
        reader.start()
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            for h in HOSTILE_PACKETS:
                sock.sendall(h + b" {12:0.5}")
                hostile, good = hostile + 1, good + 1
            if len(samples) < 10 and time.monotonic() > t_end - seconds * (1 - len(samples) / 10):
                samples.append(round(rss_mb(), 1))
        deadline = time.monotonic() + 30
        while (acks[0] < good or player.stats.played < good) and time.monotonic() < deadline:
            time.sleep(0.05)
        sock.shutdown(socket.SHUT_WR)
    st = player.stats.as_dict()
    print(f"hostile packets {seconds:.0f} s: {hostile} hostile, {good} good; good acked {acks[0]}, played "
          f"{st['played']} (every one: {acks[0] == good == st['played']}); garbage {st['garbage']}; "
          f"RSS start {start:.1f} MB, end {rss_mb():.1f} MB; samples {samples}")
    stop.set()
    controller.join()
    player.close()


if __name__ == "__main__":
    run_bench(main, "stream")
