"""The remote player: AU sets over TCP → poses over time.

As in the FAS system: an AU reader on its own thread parses the socket into a
bounded receiver buffer (100) and acks every packet; when the buffer is full it
asks the sender to pause (``-1``) and stops reading (TCP then holds the sender
back, so nothing is lost), and once the buffer has drained below the threshold
(40 %) it asks the sender to resume (``-3``). The playback controller moves
packets into the playout FIFO (30), through the AU blender when one is chosen,
and interpolates from the current pose to each packet's pose over the player
speed (250 ms) at a constant rate.

Two playback modes: ``queue`` plays every packet in turn (the FAS player);
``live`` heads for the newest packet at once (trackers streaming at frame rate),
consuming every packet in order without waiting.

Nothing here evaluates input, buffers are bounded, and the listening socket
binds 127.0.0.1 unless told otherwise.
"""
from __future__ import annotations

import collections
import select
import socket
import threading
import time
from dataclasses import dataclass, field

from ..facs import split_au_key
from .wire import ACK, END, MAX_PACKET, PAUSE, RESUME, STOP, Control, Garbage, Packet, StreamParser

MODES = ("queue", "live")


@dataclass
class Stats:
    connected: bool = False
    connections: int = 0
    packets: int = 0
    played: int = 0
    dropped: int = 0
    garbage: int = 0
    unknown_aus: set = field(default_factory=set)
    pauses_sent: int = 0
    controls_dropped: int = 0
    resumes_sent: int = 0
    senders: int = 0  # connected now
    refused: int = 0  # connections turned away (too many senders)
    idle_drops: int = 0  # connections dropped for sitting on half a packet
    ended: bool = False
    stopped: bool = False
    latencies: collections.deque = field(default_factory=lambda: collections.deque(maxlen=100_000))
    last_error: str = ""

    def as_dict(self) -> dict:
        lat = sorted(self.latencies)
        p = (lambda q: lat[min(len(lat) - 1, int(q * len(lat)))] * 1e3) if lat else (lambda q: None)
        return {"connected": self.connected, "connections": self.connections, "packets": self.packets,
                "played": self.played, "dropped": self.dropped, "garbage": self.garbage,
                "unknown_aus": sorted(self.unknown_aus, key=str), "pauses_sent": self.pauses_sent,
                "controls_dropped": self.controls_dropped, "senders": self.senders, "refused": self.refused,
                "idle_drops": self.idle_drops, "resumes_sent": self.resumes_sent, "ended": self.ended, "latency_ms_p50": p(0.5),
                "latency_ms_p99": p(0.99), "last_error": self.last_error}


class Player:
    """Receives AU packets and turns them into poses.

    Parameters
    ----------
    receive_capacity, playout_capacity : int
        Sizes of the receiver buffer and the playout FIFO.
    resume_below : float
        Fraction of the receiver buffer under which a paused sender may resume.
    transition : float
        Seconds to move from one pose to the next (player speed).
    mode : {'queue', 'live'}
    blender : AUBlender or None
        Co-occurrence rules applied to each packet (off when None).
    max_senders : int
        Senders served at once when listening; more are turned away.
    idle_timeout : float
        Seconds a sender may sit on half a packet before it is dropped (the others go on regardless).
    """

    def __init__(self, receive_capacity=100, playout_capacity=30, resume_below=0.4, transition=0.25,
                 mode="queue", blender=None, clock=time.monotonic, max_packet=MAX_PACKET, max_senders=8,
                 idle_timeout=10.0):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}")
        self.receive_capacity, self.playout_capacity = receive_capacity, playout_capacity
        self.resume_below, self.transition, self.mode = resume_below, transition, mode
        self.blender, self.clock, self.max_packet = blender, clock, max_packet
        self.max_senders, self.idle_timeout = max_senders, idle_timeout
        self.stats = Stats()
        self._buffer = collections.deque()  # (packet, receive time)
        self._playout = collections.deque()
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)
        self._room = threading.Condition(self._lock)
        self._paused_sender = False
        self._conns = set()
        self._threads = []
        self._closing = threading.Event()
        self._pose = {}
        self._from, self._to, self._t0 = {}, {}, None
        self._server = None

    # ------------------------------------------------------------ receiving

    def receive(self, packet: Packet, when=None, conn=None) -> bool:
        """Put a packet in the receiver buffer (False: buffer full, packet dropped); ack it to ``conn``.

        The socket reader never drops: it waits for room (see ``_read``).
        """
        with self._lock:
            self.stats.packets += 1
            self.stats.unknown_aus.update(packet.unknown)
            if len(self._buffer) >= self.receive_capacity:
                self.stats.dropped += 1
                return False
            self._buffer.append((packet, self.clock() if when is None else when))
            full = len(self._buffer) >= self.receive_capacity
            self._arrived.notify_all()
        self._send(ACK, conn)
        if full and not self._paused_sender:
            self._paused_sender = True
            self.stats.pauses_sent += 1
            self._send(PAUSE)
        return True

    def _send(self, code: int, conn=None):
        """Send a control integer to ``conn`` (None: every sender) without ever blocking.

        A peer that does not read its acks must not stall the reader (that
        deadlocks both ends): when the socket cannot take the bytes now, the
        control is dropped and counted. Backpressure still protects the buffer.
        """
        with self._lock:
            conns = [conn] if conn is not None else list(self._conns)
        for c in conns:
            try:
                _, writable, _ = select.select([], [c], [], 0)
                if not writable:
                    self.stats.controls_dropped += 1
                    continue
                c.send(f"{code}\n".encode())
            except (OSError, ValueError):
                pass  # a vanished peer: its reader notices and cleans up

    def _wait_room(self, timeout) -> bool:
        with self._lock:
            if len(self._buffer) < self.receive_capacity:
                return True
            self._room.wait(timeout)
            return len(self._buffer) < self.receive_capacity

    def _handle(self, ev, conn=None):
        if isinstance(ev, Packet):
            self.receive(ev, conn=conn)
        elif isinstance(ev, Control):
            if ev.code == END:
                self.stats.ended = True
            elif ev.code == STOP:
                self.stats.stopped = True
                with self._lock:
                    self._buffer.clear()
                    self._playout.clear()
                    self._arrived.notify_all()
        elif isinstance(ev, Garbage):
            with self._lock:
                self.stats.garbage += 1
                self.stats.last_error = ev.reason

    def _read(self, conn):
        parser = StreamParser(self.max_packet)
        with self._lock:
            self._conns.add(conn)
            self.stats.senders = len(self._conns)
        self.stats.connected, self.stats.ended = True, False
        self.stats.connections += 1
        conn.settimeout(0.2)
        last_data = time.monotonic()
        # Packets parsed but not yet in the buffer. While the buffer is full nothing more is read,
        # so TCP holds the sender back: no packet is lost, whatever the sender does with -1.
        pending = collections.deque()
        try:
            while not self._closing.is_set():
                if pending:
                    if isinstance(pending[0], Packet) and not self._wait_room(0.2):
                        continue
                    try:
                        self._handle(pending.popleft(), conn)
                    except Exception as exc:  # noqa: BLE001 - one bad event must not end the reader
                        self._handle(Garbage(f"could not handle: {exc}"[:200]))
                    continue
                try:
                    data = conn.recv(65536)
                except socket.timeout:
                    if parser.buffered and time.monotonic() - last_data > self.idle_timeout:
                        self.stats.idle_drops += 1
                        self.stats.last_error = f"dropped a sender idle on half a packet for {self.idle_timeout:g} s"
                        break
                    continue
                except OSError as exc:
                    self.stats.last_error = f"connection lost: {exc}"
                    break
                if not data:
                    break
                last_data = time.monotonic()
                try:
                    pending.extend(parser.feed(data))
                except Exception as exc:  # noqa: BLE001 - a parser fault drops this read, not the link
                    parser = StreamParser(self.max_packet)
                    self._handle(Garbage(f"could not parse: {exc}"[:200]))
        finally:
            with self._lock:
                self._conns.discard(conn)
                self.stats.senders = len(self._conns)
                self.stats.connected = bool(self._conns)
            try:
                conn.close()
            except OSError:
                pass

    def listen(self, host="127.0.0.1", port=0) -> tuple:
        """Accept senders on ``host:port`` (up to ``max_senders`` at once, each on its own reader thread;
        reconnects welcome); returns the bound address."""
        srv = socket.create_server((host, port), reuse_port=False)
        srv.settimeout(0.2)
        self._server = srv

        def serve():
            while not self._closing.is_set():
                try:
                    conn, _ = srv.accept()
                except socket.timeout:
                    continue
                except OSError:
                    break
                with self._lock:
                    full = len(self._conns) >= self.max_senders
                if full:
                    self.stats.refused += 1
                    conn.close()
                    continue
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self._threads = [t for t in self._threads if t.is_alive()]
                self._start(lambda c=conn: self._read(c))
        self._start(serve)
        return srv.getsockname()[:2]

    def connect(self, host, port, retry=0.5):
        """Connect to a sender that listens; reconnect while the player runs."""
        def run():
            while not self._closing.is_set():
                try:
                    conn = socket.create_connection((host, port), timeout=2)
                    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                except OSError as exc:
                    self.stats.last_error = f"connect {host}:{port}: {exc}"
                    self._closing.wait(retry)
                    continue
                self._read(conn)
                if self.stats.ended:
                    break
                self._closing.wait(retry)
        self._start(run)

    def _start(self, target):
        t = threading.Thread(target=target, daemon=True, name="pdeface-au-reader")
        t.start()
        self._threads.append(t)

    def close(self):
        self._closing.set()
        if self._server is not None:
            self._server.close()
        with self._lock:
            conns = list(self._conns)
        for conn in conns:
            try:
                conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        for t in list(self._threads):
            t.join(timeout=2)

    # ------------------------------------------------------------ playing

    def _refill(self):
        """Receiver buffer → playout FIFO (through the AU blender); resume a paused sender."""
        resume = False
        with self._lock:
            while self._buffer and len(self._playout) < self.playout_capacity:
                packet, t = self._buffer.popleft()
                weights = self.blender.apply(packet.weights) if self.blender else dict(packet.weights)
                self._playout.append((weights, t))
            self._room.notify_all()
            if self._paused_sender and len(self._buffer) < self.resume_below * self.receive_capacity:
                self._paused_sender = False
                resume = True
        if resume:
            self.stats.resumes_sent += 1
            self._send(RESUME)

    def _start_transition(self, target, now):
        self._from, self._to, self._t0 = dict(self._pose), target, now

    def pose(self, now=None) -> dict:
        """The pose now: AU key → weight (advances playback)."""
        now = self.clock() if now is None else now
        self._refill()
        if self.mode == "live":
            newest = None
            while self._playout:
                newest, t = self._playout.popleft()
                self.stats.played += 1
                self.stats.latencies.append(now - t)
            if newest is not None:
                self._start_transition(newest, now)
        elif self._t0 is None or now - self._t0 >= self.transition:
            if self._t0 is not None:
                self._pose = dict(self._to)
                self._t0 = None
            if self._playout:
                target, t = self._playout.popleft()
                self.stats.played += 1
                self.stats.latencies.append(now - t)
                self._start_transition(target, now)
        if self._t0 is not None:
            s = 1.0 if self.transition <= 0 else min(1.0, (now - self._t0) / self.transition)
            keys = set(self._from) | set(self._to)
            self._pose = {k: (1 - s) * self._from.get(k, 0.0) + s * self._to.get(k, 0.0) for k in keys}
            self._pose = {k: self._pose[k] for k in sorted(self._pose, key=split_au_key) if self._pose[k] > 1e-9}
            if s >= 1.0 and self.mode == "live":
                self._t0 = None
        return dict(self._pose)

    def wait(self, timeout: float) -> bool:
        """Block until a packet arrives (or ``timeout``); True if one is waiting."""
        with self._lock:
            if self._buffer:
                return True
            self._arrived.wait(timeout)
            return bool(self._buffer)

    @property
    def idle(self) -> bool:
        """Nothing buffered, queued or in transition."""
        with self._lock:
            return not self._buffer and not self._playout and self._t0 is None

    def run(self, hz=60.0, duration=0.0, keep_running=False, on_pose=None):
        """Play until the sender ends and everything is played (the headless player's loop).

        Parameters
        ----------
        hz : float
            Poses per second.
        duration : float
            Stop after this many seconds (0: no limit).
        keep_running : bool
            Go on after the sender ends (only a stop, ``duration`` or Ctrl-C end it).
        on_pose : callable, optional
            ``on_pose(seconds since start, pose)`` for each pose that differs from the last.
        """
        t0 = time.monotonic()
        last = None
        tick = 1.0 / hz
        while True:
            now = time.monotonic()
            pose = self.pose(now)
            if on_pose is not None and pose != last:
                on_pose(now - t0, pose)
            last = pose
            if self.stats.stopped or (duration and now - t0 > duration):
                return
            if self.stats.ended and not keep_running and self.idle:
                return
            self.wait(tick) if self.idle else time.sleep(tick)
