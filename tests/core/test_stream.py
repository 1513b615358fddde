import json
import socket
import subprocess
import sys
import threading
import time

import pytest
from pdeface.errors import ModelFormatError
from pdeface.stream.player import Player
from pdeface.stream.rules import AUBlender
from pdeface.stream.sender import read_packets, send
from pdeface.stream.wire import (
    END,
    PAUSE,
    RESUME,
    Control,
    Garbage,
    Packet,
    PacketError,
    StreamParser,
    format_packet,
    parse_json_line,
    parse_packet,
)

from scripts.bench.fuzz_readers import HOSTILE_PACKETS

PUBLISHED = {"{1,2,5,15,16,20,26}": 19, "{1,2,4,5,15,20,26}": 18, "{2,4,9,15,17}": 13,
             "{2,4,7,9,10,20,26}": 18, "{1,6,12,14}": 11, "{1,4,15,23}": 11}


def test_wire_formats_match_the_published_table():
    for text, size in PUBLISHED.items():
        p = parse_packet(text)
        assert len(format_packet(p.weights, plain=True).encode()) == size == len(text.encode())
    assert parse_packet("{12:0.8,6:0.5}").weights == {"12": 0.8, "6": 0.5}
    assert parse_packet("{12E,6C,4L:2}").weights == {"12": 1.0, "6": 0.6, "4L": 1.0}
    assert parse_packet("{}").weights == {}
    assert parse_json_line('{"au_r": {"AU12": 0.8, "AU06": 0.5}, "timestamp": 3.5}').weights == {"12": 0.8, "6": 0.5}
    assert parse_json_line('{"au_r": {"AU12": 4.0, "AU01": 1.0}}').weights == {"12": 0.8, "1": 0.2}  # 0-5 scale
    for bad in ("{12:nan}", "{12:inf}", "{x}", "{12;3}", "12,3", "{" + "1," * 600 + "1}", "{12:-}"):
        with pytest.raises(PacketError):
            parse_packet(bad)
    for bad in ("{nope", '{"au": {}}', '{"au_r": {"AU12": "x"}}', '{"au_r": {"AU12": NaN}}'):
        with pytest.raises(PacketError):
            parse_json_line(bad)


def test_stream_parser_survives_anything():
    p = StreamParser(max_packet=64)
    assert p.feed(b"{1,6,") == []  # partial
    ev = p.feed(b"12}{2")
    assert [type(e) for e in ev] == [Packet] and ev[0].weights == {"1": 1.0, "6": 1.0, "12": 1.0}
    ev = p.feed(b",4}\n -1 -3\n{99,12}junk {12:nan} 7 -2\n")
    kinds = [(type(e).__name__, getattr(e, "code", None)) for e in ev]
    assert kinds == [("Packet", None), ("Control", PAUSE), ("Control", RESUME), ("Packet", None), ("Garbage", None),
                     ("Garbage", None), ("Garbage", None), ("Control", END)]
    assert ev[3].unknown == [99] and ev[3].weights == {"12": 1.0}
    ev = p.feed(b"{" + b"1," * 100)  # oversized: dropped up to the next packet
    assert isinstance(ev[0], Garbage) and p.buffered == 0
    assert [e.weights for e in p.feed(b"5,5}{5}") if isinstance(e, Packet)] == [{"5": 1.0}]
    ev = p.feed(b"\xff\xfe" * 50 + b" {1}")
    assert isinstance(ev[-1], Packet) and any(isinstance(e, Garbage) for e in ev)
    assert p.buffered < 64


def test_au_blender_rules(tmp_path):
    b = AUBlender.load()
    assert b.apply({"25": 0.5, "26": 0.7}) == {"26": 0.7}  # 26 includes parting the lips
    assert b.apply({"25": 1, "26": 1, "27": 0.3}) == {"27": 0.3}
    assert b.apply({"5": 0.3, "45L": 0.8, "12": 1}) == {"45L": 0.8, "12": 1}  # exclusive: the stronger stays
    assert b.apply({"18": 1.0, "20": 0.5}) == {"18": 1.0}
    assert b.apply({"1": 1, "2": 1}) == {"1": 1, "2": 1}
    (tmp_path / "r.json").write_text(json.dumps({"format": "pdeface.au_rules", "exclusive": [[1]]}))
    with pytest.raises(ModelFormatError, match="'exclusive'"):
        AUBlender.load(tmp_path / "r.json")
    (tmp_path / "r.json").write_text("{")
    with pytest.raises(ModelFormatError, match="not valid JSON"):
        AUBlender.load(tmp_path / "r.json")


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def connect(address):
    s = socket.create_connection(address, timeout=5)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return s


def until(cond, timeout=5.0):
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError("timed out")
        time.sleep(0.005)


def read_controls(sock, n, timeout=5.0):
    parser, out = StreamParser(), []
    sock.settimeout(timeout)
    while len(out) < n:
        data = sock.recv(4096)
        if not data:
            break
        out += [e.code for e in parser.feed(data) if isinstance(e, Control)]
    return out


def test_packets_in_poses_out_in_order_with_interpolation():
    clock = Clock()
    player = Player(transition=0.25, clock=clock)
    host, port = player.listen()
    assert host == "127.0.0.1"  # nothing binds beyond localhost unless asked
    try:
        s = connect((host, port))
        s.sendall(b"{12}{6:0.5}\n{1,2}")
        until(lambda: player.stats.packets == 3)
        assert read_controls(s, 3) == [1, 1, 1]  # every packet acked
        poses = [player.pose(t) for t in (0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 1.0)]
        assert poses[0] == {}
        assert poses[1] == pytest.approx({"12": 0.5})
        assert poses[2] == {"12": 1.0}
        assert poses[3] == pytest.approx({"6": 0.25, "12": 0.5})
        assert poses[4] == {"6": 0.5}
        assert poses[5] == pytest.approx({"1": 0.5, "2": 0.5, "6": 0.25})
        assert poses[6] == {"1": 1.0, "2": 1.0} == poses[7]
        assert player.stats.played == 3 and player.idle
        s.close()
    finally:
        player.close()


def test_flow_control_pause_and_resume():
    player = Player(receive_capacity=10, playout_capacity=3, resume_below=0.4, transition=0.0)
    address = player.listen()
    try:
        s = connect(address)
        s.sendall(b"".join(b"{%d}" % a for a in [1, 2, 4, 5, 6, 7, 9, 10, 12, 14]))
        codes = read_controls(s, 11)
        assert codes == [1] * 10 + [PAUSE]  # buffer full: the sender is asked to pause
        for _ in range(3):  # each pose() takes one packet, refilling the 3-packet FIFO from the buffer
            player.pose()
        # buffer 10 → 7 → 6 → 5: still at or above 40 %, no resume yet
        assert player.stats.resumes_sent == 0
        for _ in range(3):
            player.pose()
        assert player.stats.resumes_sent == 1
        assert read_controls(s, 1) == [RESUME]
        s.sendall(b"{15}{17}")
        until(lambda: player.stats.packets == 12)
        assert player.stats.dropped == 0
        s.close()
    finally:
        player.close()


def test_live_mode_heads_for_the_newest_packet():
    clock = Clock()
    player = Player(mode="live", transition=0.1, clock=clock)
    for w in (0.2, 0.4, 0.6):
        player.receive(Packet({"12": w}))
    assert player.pose(0.0) == {}  # moving towards the newest at once
    assert player.pose(0.05) == pytest.approx({"12": 0.3})
    assert player.pose(0.1) == {"12": 0.6}
    assert player.stats.played == 3 and len(player.stats.latencies) == 3


def test_malformed_input_and_floods_are_survived():
    player = Player(receive_capacity=50, max_packet=256, transition=0.0)
    address = player.listen()
    try:
        s = connect(address)
        s.sendall(b"{12:na" + b"n}")  # NaN, split across sends
        s.sendall(b"hello world \x00\x01\x02 {99} {12:0.5} {" + b"7" * 5000 + b"}\n")
        s.sendall(b'{"au_r": {"AU06": 0.5}}\n{"au_r": 5}\n')
        s.sendall(b"\x00garbage" * 20000)  # a garbage flood
        s.sendall(b"{4}" * 200 + b" {1,2}")  # a packet flood: more than the buffer holds
        until(lambda: player.stats.packets >= 50)
        time.sleep(0.2)
        st = player.stats
        assert st.garbage >= 4 and 99 in st.unknown_aus
        assert player.buffered == 50 and st.packets == 50  # bounded: reading waits for room
        deadline = time.monotonic() + 10
        while player.stats.packets < 204:  # playing drains the buffer; the rest arrives, nothing lost
            assert time.monotonic() < deadline, player.stats
            player.pose()
            time.sleep(0.001)
        assert player.stats.dropped == 0
        s.close()
        until(lambda: not player.stats.connected)
        # a vanished peer does not stop the player: a new sender is served
        s2 = connect(address)
        s2.sendall(b"{20:0.5}")
        until(lambda: player.pose() is not None and player.stats.connections == 2 and player.stats.packets >= 205)
        s2.close()
    finally:
        player.close()


def test_sender_honours_flow_control_and_connect_role(tmp_path):
    player = Player(receive_capacity=8, playout_capacity=2, transition=0.0)
    address = player.listen()
    packets = [f"{{{a}}}" for a in (1, 2, 4, 5, 6, 7, 9, 10, 12, 14, 15, 16, 17, 20, 23, 24)] * 2
    result = {}
    t = threading.Thread(target=lambda: result.update(send(packets, *address, rate=0)))
    t.start()
    until(lambda: player.stats.pauses_sent >= 1)
    time.sleep(0.1)
    assert player.stats.packets <= 8  # the sender stopped at pause
    deadline = time.monotonic() + 20
    while t.is_alive():
        assert time.monotonic() < deadline, player.stats
        player.pose()
        time.sleep(0.001)
    t.join()
    assert result["sent"] == 32 and result["pauses"] >= 1 and player.stats.dropped == 0
    assert player.stats.packets == 32 and player.stats.ended
    player.close()
    # the player can also connect to a sender that listens
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    out = {}
    t = threading.Thread(target=lambda: out.update(send(["{12}", "{6}"], "127.0.0.1", port, rate=50, listen=True)))
    t.start()
    time.sleep(0.2)
    p2 = Player(transition=0.0)
    p2.connect("127.0.0.1", port)
    until(lambda: p2.stats.packets == 2 and p2.stats.ended)
    t.join()
    p2.close()
    assert out["sent"] == 2


def test_read_packets(tmp_path):
    (tmp_path / "p.txt").write_text("# demo\n{1,2}\n\n{12:0.5}\n" + '{"au_r": {"AU12": 1}}\n')
    assert read_packets(tmp_path / "p.txt") == (["{1,2}", "{12:0.5}", '{"au_r": {"AU12": 1}}'], [])
    # a malformed line is skipped and reported, the rest is sent
    (tmp_path / "bad.txt").write_text("{1,2}\n{1,zz}\n{12}\n")
    packets, bad = read_packets(tmp_path / "bad.txt")
    assert packets == ["{1,2}", "{12}"] and len(bad) == 1 and "bad.txt:2:" in bad[0]
    (tmp_path / "worse.txt").write_text("{1,zz}\nnonsense\n")
    with pytest.raises(ModelFormatError, match="no packets .2 malformed lines; first: .*worse.txt:1"):
        read_packets(tmp_path / "worse.txt")


def test_cli_send_and_play(tmp_path):
    (tmp_path / "p.txt").write_text("{12}\n{6:zz}\n{6:0.5}\n")  # one malformed line, skipped and reported
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    play = subprocess.Popen([sys.executable, "-m", "pdeface.cli", "stream", "play", "--listen", f"127.0.0.1:{port}",
                             "--print", "--transition", "0.1", "--hz", "100"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        for _ in range(100):
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
                break
            except OSError:
                time.sleep(0.05)
        time.sleep(0.1)
        sent = subprocess.run([sys.executable, "-m", "pdeface.cli", "stream", "send", str(tmp_path / "p.txt"),
                               "--port", str(port), "--rate", "20"], capture_output=True, text=True, timeout=30)
        assert sent.returncode == 0 and json.loads(sent.stdout)["acks"] == 2
        assert json.loads(sent.stdout)["skipped"] == 1 and "p.txt:2:" in sent.stderr
        out, err = play.communicate(timeout=30)
    finally:
        play.kill()
    poses = [json.loads(line) for line in out.splitlines()]
    ts = [p["t"] for p in poses]
    assert ts == sorted(ts)
    w12 = [p["au"].get("12", 0) for p in poses]
    peak = w12.index(max(w12))
    assert max(w12) == 1.0 and any(0 < w < 1 for w in w12[:peak])  # interpolated towards {12}
    assert poses[-1]["au"] == {"6": 0.5}
    stats = json.loads(err.strip().splitlines()[-1])
    assert stats["packets"] == 2 and stats["played"] == 2 and stats["ended"]


def test_a_peer_that_never_reads_acks_cannot_stall_the_player():
    """Flooding without reading the acks fills the player's send buffer: it must drop acks, not block."""
    player = Player(mode="live", transition=0.0)
    address = player.listen()
    stop = threading.Event()

    def play():
        while not stop.is_set():
            player.wait(0.002)
            player.pose()
    t = threading.Thread(target=play, daemon=True)
    t.start()
    try:
        s = socket.socket()
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # small buffers: acks back up quickly
        s.connect(address)
        until(lambda: len(player._conns) == 1)
        next(iter(player._conns)).setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
        s.settimeout(20)
        n = 300_000  # ~1 MB of packets, ~600 KB of acks the sender never reads
        s.sendall(b"{4}" * n)  # would hang forever if the player blocked on its acks
        until(lambda: player.stats.packets == n, timeout=20)
        assert player.stats.controls_dropped > 0 and player.stats.dropped == 0
        s.close()
    finally:
        stop.set()
        t.join()
        player.close()


@pytest.mark.parametrize("hostile", HOSTILE_PACKETS, ids=range(len(HOSTILE_PACKETS)))
def test_one_bad_packet_never_stops_the_stream(hostile):
    # Every packet above, then a good one: it is acked and played; the reader thread lives on.
    player = Player(transition=0.0)
    address = player.listen()
    try:
        s = connect(address)
        s.sendall(hostile)
        s.sendall(b" {6:0.5}")
        acks = b""
        deadline = time.monotonic() + 5
        while b"1\n" not in acks:
            assert time.monotonic() < deadline, player.stats
            s.settimeout(0.1)
            try:
                acks += s.recv(4096)
            except socket.timeout:
                pass
        until(lambda: player.pose().get("6") == 0.5)
        assert player.stats.garbage + player.stats.packets >= 2 and player.stats.connected
        s.close()
    finally:
        player.close()


def test_senders_are_served_at_once_and_an_idle_half_packet_is_dropped():
    player = Player(transition=0.0, idle_timeout=0.5, max_senders=2, evict_after=60.0)
    address = player.listen()
    try:
        quiet = connect(address)
        until(lambda: player.stats.senders == 1)
        other = connect(address)
        other.sendall(b"{12}")
        until(lambda: player.pose().get("12") == 1.0)  # served while the first one sits there
        third = connect(address)  # over max_senders, nobody idle long enough to evict: turned away
        until(lambda: player.stats.refused == 1)
        quiet.sendall(b"{1,2")  # half a packet, then silence: dropped, the others go on
        until(lambda: player.stats.idle_drops == 1 and player.stats.senders == 1, timeout=5)
        other.sendall(b"{6}")
        until(lambda: player.pose().get("6") == 1.0)
        for s in (quiet, other, third):
            s.close()
    finally:
        player.close()
