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

Several senders: each has its own receiver buffer and playout FIFO (a *lane*)
and the controller serves them in turn, least recently served first, so a flood
from one cannot hold another's newest pose up by more than a tick (see
:meth:`Player.pose`). Who may end or stop the player: see :meth:`Player.may_control`.

Nothing here evaluates input, buffers are bounded, and the listening socket
binds 127.0.0.1 unless told otherwise.
"""
from __future__ import annotations

import collections
import hmac
import ipaddress
import os
import select
import socket
import threading
import time
from dataclasses import dataclass, field

from ..facs import split_au_key
from .wire import ACK, END, MAX_PACKET, PAUSE, RESUME, STOP, Auth, Control, Garbage, Packet, StreamParser

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
    refused: int = 0  # connections turned away (every slot busy, none idle)
    evicted: int = 0  # idle connections dropped to make room for a new one
    idle_drops: int = 0  # connections dropped for sending bytes that completed no packet in idle_timeout
    controls_refused: int = 0  # end/stop from a sender not allowed to give them
    unauthenticated: int = 0  # JSON-line packets refused: a token is set and the sender did not present it
    auth_failures: int = 0  # wrong tokens (the connection is dropped)
    ended: bool = False
    stopped: bool = False
    latencies: collections.deque = field(default_factory=lambda: collections.deque(maxlen=100_000))
    last_error: str = ""

    def as_dict(self) -> dict:
        lat = sorted(self.latencies)
        p = (lambda q: lat[min(len(lat) - 1, int(q * len(lat)))] * 1e3) if lat else (lambda q: None)
        counts = ("connections", "packets", "played", "dropped", "garbage", "pauses_sent", "controls_dropped",
                  "senders", "refused", "evicted", "idle_drops", "controls_refused", "unauthenticated",
                  "auth_failures", "resumes_sent")
        return {"connected": self.connected, **{k: getattr(self, k) for k in counts},
                "unknown_aus": sorted(self.unknown_aus, key=str), "ended": self.ended, "stopped": self.stopped,
                "latency_ms_p50": p(0.5), "latency_ms_p99": p(0.99), "last_error": self.last_error}


@dataclass(eq=False)
class _Lane:
    """One sender's packets: its receiver buffer, its playout FIFO and its turn."""

    buffer: collections.deque = field(default_factory=collections.deque)  # (packet, receive time)
    playout: collections.deque = field(default_factory=collections.deque)  # (weights, receive time)
    paused: bool = False
    served: int = 0  # the play step it was last served at: the least recently served goes first
    newest: tuple | None = None  # live mode: its newest pose not headed for yet

    @property
    def waiting(self) -> bool:
        return bool(self.buffer or self.playout or self.newest is not None)


@dataclass(eq=False)
class _Peer:
    """A connected sender."""

    conn: socket.socket
    since: float  # connected at (monotonic)
    last_complete: float  # its last complete packet, control or JSON line (or the connection)
    outbound: bool = False  # the player connected to it (``connect``)
    owner: bool = False  # the user who started the player (see Player.may_control)
    authenticated: bool = False  # presented the token
    dirty: bool = False  # bytes since its last complete packet that completed nothing
    evicted: bool = False


def loopback_peer_uid(conn) -> int | None:
    """The user id owning the other end of a TCP connection on this machine (Linux), or None.

    Both ends of a loopback connection are in ``/proc/net/tcp`` (or ``tcp6``); the
    peer's is the entry whose local address is our peer's and remote address ours.
    """
    try:
        peer, me = conn.getpeername()[:2], conn.getsockname()[:2]
        if not ipaddress.ip_address(peer[0]).is_loopback:
            return None
    except (OSError, ValueError):
        return None
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            with open(table) as f:
                rows = f.read(1 << 24).splitlines()[1:]
        except OSError:
            continue
        for row in rows:
            cols = row.split()
            if len(cols) > 7 and _proc_address(cols[1]) == peer and _proc_address(cols[2]) == me:
                return int(cols[7])
    return None


def _proc_address(text: str):
    """``0100007F:1F90`` (``/proc/net/tcp``'s little-endian words) → ('127.0.0.1', 8080)."""
    host, _, port = text.partition(":")
    raw = bytes.fromhex(host)
    raw = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
    addr = ipaddress.ip_address(raw)
    if addr.version == 6 and addr.ipv4_mapped is not None:
        addr = addr.ipv4_mapped
    return str(addr), int(port, 16)


class Player:
    """Receives AU packets and turns them into poses.

    Parameters
    ----------
    receive_capacity, playout_capacity : int
        Sizes of each sender's receiver buffer and playout FIFO.
    resume_below : float
        Fraction of the receiver buffer under which a paused sender may resume.
    transition : float
        Seconds to move from one pose to the next (player speed).
    mode : {'queue', 'live'}
    blender : AUBlender or None
        Co-occurrence rules applied to each packet (off when None).
    max_senders : int
        Senders served at once when listening. When all are busy a newcomer takes the slot of the sender idle
        longest (no complete packet for ``evict_after`` s, none of its packets waiting); if none is, it is
        turned away.
    idle_timeout : float
        Seconds a sender may go without completing a packet, a control or a JSON line while it sends bytes
        (half a packet, garbage, a trickle) before it is dropped; counted from its last complete one, not reset
        per byte. A silent sender is never timed out, only evicted when its slot is needed.
    evict_after : float
        Seconds without a complete packet after which a sender may be evicted for a newcomer.
    token : str or None
        A shared secret: when set, only senders that present it (``{"auth": "TOKEN"}``) may end or stop the
        player or send JSON-line packets (FAS packets are taken from anyone, as the FAS wire has no token).
    """

    def __init__(self, receive_capacity=100, playout_capacity=30, resume_below=0.4, transition=0.25,
                 mode="queue", blender=None, clock=time.monotonic, max_packet=MAX_PACKET, max_senders=8,
                 idle_timeout=10.0, evict_after=1.0, token=None):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}")
        self.receive_capacity, self.playout_capacity = receive_capacity, playout_capacity
        self.resume_below, self.transition, self.mode = resume_below, transition, mode
        self.blender, self.clock, self.max_packet = blender, clock, max_packet
        self.max_senders, self.idle_timeout, self.evict_after = max_senders, idle_timeout, evict_after
        self.token = token or None
        #: The user allowed to end or stop the player without a token (its own user).
        self.owner_uid = os.getuid() if hasattr(os, "getuid") else None
        self.stats = Stats()
        self._lanes = {}  # sender (its socket; None: packets given to receive() directly) → _Lane
        self._step = 0
        self._playing = None  # the lane whose packet the face is heading for (queue mode)
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)
        self._room = threading.Condition(self._lock)
        self._conns = {}  # socket → _Peer
        self._threads = []
        self._closing = threading.Event()
        self._pose = {}
        self._from, self._to, self._t0 = {}, {}, None
        self._server = None

    # ------------------------------------------------------------ who may do what

    def may_control(self, peer) -> bool:
        """May ``peer`` end (``-2``) or stop (``-4``) the player?

        With a token: only a sender that presented it. Without: the user who started the player (a
        loopback peer owned by the same user id; where the system cannot tell, as off Linux, any loopback
        peer) and a sender the player connected to itself. Packets given to :meth:`receive` directly: yes.
        """
        if peer is None:
            return True
        if self.token is not None:
            return peer.authenticated
        return peer.outbound or peer.owner

    def _is_owner(self, conn) -> bool:
        if not os.path.exists("/proc/net/tcp"):  # no way to tell who is at the other end: loopback is local
            try:
                return ipaddress.ip_address(conn.getpeername()[0]).is_loopback
            except (OSError, ValueError):
                return False
        uid = loopback_peer_uid(conn)
        return uid is not None and uid == self.owner_uid

    # ------------------------------------------------------------ receiving

    def _lane(self, key) -> _Lane:
        lane = self._lanes.get(key)
        if lane is None:
            lane = self._lanes[key] = _Lane()
        return lane

    def receive(self, packet: Packet, when=None, conn=None) -> bool:
        """Put a packet in its sender's receiver buffer (False: buffer full, dropped); ack it to ``conn``.

        The socket reader never drops: it waits for room (see ``_read``).
        """
        with self._lock:
            self.stats.packets += 1
            self.stats.unknown_aus.update(packet.unknown)
            lane = self._lane(conn)
            if len(lane.buffer) >= self.receive_capacity:
                self.stats.dropped += 1
                return False
            lane.buffer.append((packet, self.clock() if when is None else when))
            pause = len(lane.buffer) >= self.receive_capacity and not lane.paused
            lane.paused = lane.paused or pause
            self._arrived.notify_all()
        if conn is not None:
            self._send(ACK, conn)
            if pause:
                self.stats.pauses_sent += 1
                self._send(PAUSE, conn)
        return True

    def _send(self, code: int, conn):
        """Send a control integer to ``conn`` without ever blocking.

        A peer that does not read its acks must not stall the reader (that
        deadlocks both ends): when the socket cannot take the bytes now, the
        control is dropped and counted. Backpressure still protects the buffer.
        """
        try:
            _, writable, _ = select.select([], [conn], [], 0)
            if not writable:
                self.stats.controls_dropped += 1
                return
            conn.send(f"{code}\n".encode())
        except (OSError, ValueError):
            pass  # a vanished peer: its reader notices and cleans up

    def _wait_room(self, key, timeout) -> bool:
        with self._lock:
            lane = self._lane(key)
            if len(lane.buffer) < self.receive_capacity:
                return True
            self._room.wait(timeout)
            return len(lane.buffer) < self.receive_capacity

    def _handle(self, ev, peer=None) -> bool:
        """Act on one event from ``peer``; False: drop the connection (a wrong token)."""
        conn = peer.conn if peer is not None else None
        if isinstance(ev, Packet):
            if ev.json and self.token is not None and peer is not None and not peer.authenticated:
                self.stats.unauthenticated += 1
                self.stats.last_error = "refused a JSON-line packet from a sender without the token"
            else:
                self.receive(ev, conn=conn)
        elif isinstance(ev, Control) and ev.code in (END, STOP):
            if not self.may_control(peer):
                self.stats.controls_refused += 1
                self.stats.last_error = f"refused '{ev.code}' ({ev.name}) from a sender not allowed to give it"
            elif ev.code == END:
                self.stats.ended = True
            else:
                self.stats.stopped = True
                with self._lock:
                    for lane in self._lanes.values():
                        lane.buffer.clear()
                        lane.playout.clear()
                        lane.newest = None
                    self._arrived.notify_all()
        elif isinstance(ev, Auth):
            if self.token is not None and peer is not None:
                if not hmac.compare_digest(ev.token.encode(), self.token.encode()):
                    self.stats.auth_failures += 1
                    self.stats.last_error = "dropped a sender that presented a wrong token"
                    return False
                peer.authenticated = True
        elif isinstance(ev, Garbage):
            with self._lock:
                self.stats.garbage += 1
                self.stats.last_error = ev.reason
        return True

    def _read(self, peer):
        conn = peer.conn
        parser = StreamParser(self.max_packet)
        peer.owner = self._is_owner(conn)
        with self._lock:
            self._conns[conn] = peer
            self.stats.senders = len(self._conns)
        self.stats.connected = True
        if self.may_control(peer):  # a sender that may end the player starts a new transmission
            self.stats.ended = False
        self.stats.connections += 1
        conn.settimeout(0.2)
        # Packets parsed but not yet in the buffer. While the buffer is full nothing more is read,
        # so TCP holds the sender back: no packet is lost, whatever the sender does with -1.
        pending = collections.deque()
        try:
            while not self._closing.is_set() and not peer.evicted:
                if pending:
                    if isinstance(pending[0], Packet) and not self._wait_room(conn, 0.2):
                        continue
                    try:
                        if not self._handle(pending.popleft(), peer):
                            break
                    except Exception as exc:  # noqa: BLE001 - one bad event must not end the reader
                        self._handle(Garbage(f"could not handle: {exc}"[:200]))
                    continue
                if peer.dirty and time.monotonic() - peer.last_complete > self.idle_timeout:
                    self.stats.idle_drops += 1
                    self.stats.last_error = (f"dropped a sender that completed no packet in {self.idle_timeout:g} s "
                                             "while sending")
                    break
                try:
                    data = conn.recv(65536)
                except TimeoutError:
                    continue
                except OSError as exc:
                    self.stats.last_error = f"connection lost: {exc}"
                    break
                if not data:
                    break
                try:
                    events = parser.feed(data)
                except Exception as exc:  # noqa: BLE001 - a parser fault drops this read, not the link
                    parser = StreamParser(self.max_packet)
                    events = [Garbage(f"could not parse: {exc}"[:200])]
                if any(not isinstance(e, Garbage) for e in events):
                    peer.last_complete = time.monotonic()
                # Bytes that completed nothing (half a packet, garbage) start the idle clock; whitespace does not.
                peer.dirty = parser.buffered > 0 or (isinstance(events[-1], Garbage) if events else peer.dirty)
                pending.extend(events)
        finally:
            with self._lock:
                if self._conns.get(conn) is peer:
                    del self._conns[conn]
                self.stats.senders = len(self._conns)
                self.stats.connected = bool(self._conns)
            try:
                conn.close()
            except OSError:
                pass

    def _evictable(self, now):
        """The sender idle longest that may give its slot to a newcomer, or None (under the lock)."""
        idle = [p for p in self._conns.values() if not p.authenticated and not p.outbound
                and not (self._lanes.get(p.conn) and self._lanes[p.conn].waiting)
                and (p.dirty or now - p.last_complete >= self.evict_after)]
        return min(idle, key=lambda p: p.last_complete, default=None)

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
                except TimeoutError:
                    continue
                except OSError:
                    break
                now = time.monotonic()
                peer, victim = _Peer(conn, now, now), None
                with self._lock:
                    if len(self._conns) >= self.max_senders:
                        victim = self._evictable(now)
                        if victim is None:
                            self.stats.refused += 1
                            conn.close()
                            continue
                        victim.evicted = True
                        del self._conns[victim.conn]
                        self.stats.evicted += 1
                    self._conns[conn] = peer  # the slot is taken now, before the reader starts
                if victim is not None:
                    try:
                        victim.conn.shutdown(socket.SHUT_RDWR)
                    except OSError:
                        pass
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self._threads = [t for t in self._threads if t.is_alive()]
                self._start(lambda p=peer: self._read(p))
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
                now = time.monotonic()
                self._read(_Peer(conn, now, now, outbound=True))
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

    def _refill(self) -> list:
        """Receiver buffers → playout FIFOs (through the AU blender); the senders to resume (under the lock)."""
        resume = []
        for key, lane in list(self._lanes.items()):
            while lane.buffer and len(lane.playout) < self.playout_capacity:
                packet, t = lane.buffer.popleft()
                weights = self.blender.apply(packet.weights) if self.blender else dict(packet.weights)
                lane.playout.append((weights, t))
            if lane.paused and len(lane.buffer) < self.resume_below * self.receive_capacity:
                lane.paused = False
                resume.append(key)
            if key is not None and key not in self._conns and not lane.waiting and lane is not self._playing:
                del self._lanes[key]  # a sender gone, everything of it played
        self._room.notify_all()
        return resume

    def _next_lane(self, but=None):
        """The lane to serve next: of those with a packet to play, the least recently served."""
        ready = [lane for lane in self._lanes.values() if lane.playout and lane is not but]
        return min(ready, key=lambda lane: lane.served, default=None)  # min keeps arrival order on ties

    def _serve(self, lane, target, now):
        self._step += 1
        lane.served, self._playing = self._step, lane
        self._from, self._to, self._t0 = dict(self._pose), target, now

    def _interpolate(self, now):
        s = 1.0 if self.transition <= 0 else min(1.0, (now - self._t0) / self.transition)
        keys = set(self._from) | set(self._to)
        pose = {k: (1 - s) * self._from.get(k, 0.0) + s * self._to.get(k, 0.0) for k in keys}
        self._pose = {k: pose[k] for k in sorted(pose, key=split_au_key) if pose[k] > 1e-9}
        return s

    def pose(self, now=None) -> dict:
        """The pose now: AU key → weight (advances playback).

        Senders are served in turn. Queue mode plays each sender's packets in order; while a sender that
        is behind (more of its packets waiting) is being played and another sender has a packet, the
        transition hands over at once, from the pose reached. Live mode heads for the newest packet of the
        least recently served sender that has a new one.
        """
        now = self.clock() if now is None else now
        with self._lock:
            resume = self._refill()
            if self.mode == "live":
                for lane in self._lanes.values():
                    while lane.playout:
                        lane.newest, t = lane.playout.popleft()
                        self.stats.played += 1
                        self.stats.latencies.append(now - t)
                ready = [lane for lane in self._lanes.values() if lane.newest is not None]
                lane = min(ready, key=lambda lane: lane.served, default=None)
                if lane is not None:
                    self._serve(lane, lane.newest, now)
                    lane.newest = None
            else:
                lane = None
                if self._t0 is None or now - self._t0 >= self.transition:
                    if self._t0 is not None:
                        self._pose, self._t0, self._playing = dict(self._to), None, None
                    lane = self._next_lane()
                elif self._playing is not None and self._playing.waiting:
                    lane = self._next_lane(but=self._playing)
                    if lane is not None:
                        self._interpolate(now)  # hand over from the pose reached
                if lane is not None:
                    target, t = lane.playout.popleft()
                    self.stats.played += 1
                    self.stats.latencies.append(now - t)
                    self._serve(lane, target, now)
            if self._t0 is not None and self._interpolate(now) >= 1.0 and self.mode == "live":
                self._t0 = None
            pose = dict(self._pose)
        for conn in resume:
            self.stats.resumes_sent += 1
            self._send(RESUME, conn)
        return pose

    @property
    def target(self) -> dict:
        """The pose the face is heading for (the last one reached when none)."""
        with self._lock:
            return dict(self._to if self._t0 is not None else self._pose)

    @property
    def buffered(self) -> int:
        """Packets in the receiver buffers."""
        with self._lock:
            return sum(len(lane.buffer) for lane in self._lanes.values())

    def wait(self, timeout: float) -> bool:
        """Block until a packet arrives (or ``timeout``); True if one is waiting."""
        with self._lock:
            if any(lane.buffer for lane in self._lanes.values()):
                return True
            self._arrived.wait(timeout)
            return any(lane.buffer for lane in self._lanes.values())

    @property
    def idle(self) -> bool:
        """Nothing buffered, queued or in transition."""
        with self._lock:
            return not any(lane.waiting for lane in self._lanes.values()) and self._t0 is None

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
