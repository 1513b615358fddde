"""Replay a file of AU packets to a player, honouring its flow control."""
from __future__ import annotations

import json
import socket
import threading
import time

from ..errors import ModelFormatError
from ..io.files import read_lines
from .wire import ACK, END, PAUSE, RESUME, STOP, Control, PacketError, StreamParser, parse_json_line, parse_packet


def read_packets(path) -> tuple[list, list]:
    """Packets of a file: one ``{...}`` AU set or JSON line per line (``#`` comments, blanks skipped).

    Returns (packets, bad lines): a malformed line is skipped and reported as
    ``"FILE:LINE: reason"``, as the player skips a malformed packet. A file
    without one good packet is an error.
    """
    packets, bad = [], []
    for lineno, line in enumerate(read_lines(path), 1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        try:
            (parse_json_line if s.startswith('{"') else parse_packet)(s)
        except PacketError as exc:
            bad.append(f"{path}:{lineno}: {exc}")
            continue
        packets.append(s)
    if not packets:
        raise ModelFormatError(f"{path}: no packets" + (f" ({len(bad)} malformed lines; first: {bad[0]})" if bad else ""))
    return packets, bad


class Sender:
    """Sends packets at ``rate`` per second; pauses on -1, resumes on -3, stops on -4.

    ``token``: the player's shared token, presented first (``{"auth": TOKEN}``) when given.
    """

    def __init__(self, packets, rate=4.0, token=None):
        self.packets, self.rate, self.token = list(packets), float(rate), token or None
        self.acks = 0
        self.sent = 0
        self.pauses = 0
        self.stopped = False
        self._go = threading.Event()
        self._go.set()

    def _listen_controls(self, sock, done):
        parser = StreamParser()
        sock.settimeout(0.1)
        while not done.is_set():
            try:
                data = sock.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                break
            if not data:
                break
            for ev in parser.feed(data):
                if isinstance(ev, Control):
                    if ev.code == ACK:
                        self.acks += 1
                    elif ev.code == PAUSE:
                        self.pauses += 1
                        self._go.clear()
                    elif ev.code == RESUME:
                        self._go.set()
                    elif ev.code == STOP:
                        self.stopped = True
                        self._go.set()
        self._go.set()

    def run(self, sock, drain=2.0) -> dict:
        done = threading.Event()
        listener = threading.Thread(target=self._listen_controls, args=(sock, done), daemon=True)
        listener.start()
        interval = 1.0 / self.rate if self.rate > 0 else 0.0
        next_t = time.monotonic()
        try:
            if self.token is not None:
                sock.sendall((json.dumps({"auth": self.token}) + "\n").encode())
            for p in self.packets:
                self._go.wait()
                if self.stopped:
                    break
                if interval:
                    delay = next_t - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
                    next_t = max(next_t + interval, time.monotonic() - 1.0)
                sock.sendall((p + "\n").encode() if p.startswith('{"') else p.encode())
                self.sent += 1
            sock.sendall(f"\n{END}\n".encode())
            end = time.monotonic() + drain
            while self.acks < self.sent and time.monotonic() < end:
                time.sleep(0.01)
        finally:
            done.set()
            listener.join(timeout=1)
        return {"sent": self.sent, "acks": self.acks, "pauses": self.pauses, "stopped": self.stopped}


def send(packets, host="127.0.0.1", port=5000, rate=4.0, listen=False, timeout=30.0, token=None) -> dict:
    """Connect to a player (or, with ``listen``, wait for one) and replay ``packets``."""
    if listen:
        with socket.create_server((host, port)) as srv:
            srv.settimeout(timeout)
            sock, _ = srv.accept()
    else:
        sock = socket.create_connection((host, port), timeout=timeout)
    with sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return Sender(packets, rate, token).run(sock)
