"""Wire formats of AU streams.

The FAS system's own: one packet per expression, the AU set as plain text
``{1,6,12,14}`` (no spaces), packets delimited by their braces (newlines and
spaces between packets are ignored). Extended: intensities ``{12:0.8,6:0.5}``
and FACS letters ``{12E,6C}``; side suffixes ``{12L:0.5}``. Control integers
between packets: 1 packet received (ack), -1 pause, -2 end of transmission,
-3 resume, -4 stop. FACSvatar-style JSON lines: ``{"au_r": {"AU12": 0.8}, "timestamp": 1.5}``, and
``{"auth": "TOKEN"}``: a sender presenting the player's shared token (see :mod:`.player`).

:class:`StreamParser` takes bytes as they arrive (partial packets, garbage,
floods) and yields events; it never evaluates anything and bounds its buffer.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from ..errors import PdeFaceError
from ..facs import INTENSITY, clamp_weight, parse_au_key
from ..io.files import parse_json

ACK, PAUSE, END, RESUME, STOP = 1, -1, -2, -3, -4
CONTROLS = {ACK: "ack", PAUSE: "pause", END: "end", RESUME: "resume", STOP: "stop"}
#: Longest packet accepted (bytes); longer input is dropped up to the next packet.
MAX_PACKET = 1024
#: Digits a control integer may have (they are -4 … 1); a longer run is garbage, however it arrives.
MAX_CONTROL_DIGITS = 8
#: What may follow a control integer: whitespace or the next packet (``-4x`` is garbage, not a stop).
CONTROL_DELIMITERS = " \t\r\n{"

_ITEM = re.compile(r"^(\d{1,3})([LR]?)(?:([A-E])|:([0-9]*\.?[0-9]+(?:[eE][-+]?\d+)?))?$")


class PacketError(PdeFaceError, ValueError):
    """A malformed packet."""


@dataclass
class Packet:
    """One expression: AU key → weight in [0, 1]; ``unknown``: AU numbers not in FACS; ``json``: sent as a JSON line."""

    weights: dict
    raw: str = ""
    unknown: list = field(default_factory=list)
    timestamp: float | None = None
    json: bool = False


@dataclass
class Control:
    code: int

    @property
    def name(self) -> str:
        return CONTROLS[self.code]


@dataclass
class Auth:
    """``{"auth": "TOKEN"}``: a sender presenting a shared token (never shown in a repr)."""

    token: str = field(repr=False)


@dataclass
class Garbage:
    """Input that was dropped, and why."""

    reason: str
    text: str = ""


def parse_packet(text: str) -> Packet:
    """Parse ``{1,2,5}``, ``{12:0.8,6:0.5}`` or ``{12E,6C}`` (braces included)."""
    if len(text) > MAX_PACKET:
        raise PacketError(f"packet longer than {MAX_PACKET} bytes")
    if not (text.startswith("{") and text.endswith("}")):
        raise PacketError(f"a packet is enclosed in braces: {text[:40]!r}")
    body = text[1:-1].strip()
    weights, unknown = {}, []
    if not body:
        return Packet({}, text)
    for item in body.split(","):
        item = item.strip()
        m = _ITEM.match(item)
        if not m:
            raise PacketError(f"bad item {item[:20]!r} in {text[:60]!r}")
        num, side, letter, value = m.groups()
        if letter:
            w = INTENSITY[letter]
        elif value is not None:
            w = float(value)
            if not math.isfinite(w):
                raise PacketError(f"weight of AU{num} is not finite")
            w = clamp_weight(w)
        else:
            w = 1.0
        try:
            key = parse_au_key(num + side)
        except PdeFaceError:
            unknown.append(int(num))
            continue
        weights[key] = w
    return Packet(weights, text, unknown)


def format_packet(weights: dict, plain: bool = False) -> str:
    """``{1,6,12}`` (plain: AUs at weight > 0) or ``{12:0.8,6:0.5}``."""
    if plain:
        return "{" + ",".join(k for k, w in weights.items() if w > 0) + "}"
    return "{" + ",".join(f"{k}:{w:.3g}" for k, w in weights.items()) + "}"


def parse_json_line(line: str) -> Packet:
    """A FACSvatar-style JSON line: ``{"au_r": {"AU12": 0.8, ...}, "timestamp": ...}``.

    Intensities above 1 are taken as OpenFace's 0-5 scale.
    """
    if len(line) > MAX_PACKET:
        raise PacketError(f"JSON line longer than {MAX_PACKET} bytes")
    return _json_packet(parse_json(line, "JSON line", PacketError), line)  # (depth and huge integers refused there)


def parse_json_event(line: str) -> Packet | Auth:
    """A JSON line: an AU packet (see :func:`parse_json_line`) or ``{"auth": "TOKEN"}``."""
    if len(line) > MAX_PACKET:
        raise PacketError(f"JSON line longer than {MAX_PACKET} bytes")
    obj = parse_json(line, "JSON line", PacketError)
    if isinstance(obj, dict) and "auth" in obj and "au_r" not in obj:
        if not isinstance(obj["auth"], str):
            raise PacketError("JSON line's 'auth' must be a string")
        return Auth(obj["auth"])
    return _json_packet(obj, line)


def _json_packet(obj, line: str) -> Packet:
    if not isinstance(obj, dict) or not isinstance(obj.get("au_r"), dict):
        raise PacketError("JSON line needs an 'au_r' object")
    weights, unknown = {}, []
    values = obj["au_r"]
    for k, v in values.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise PacketError(f"au_r[{str(k)[:20]!r}] is not a finite number")
    scale = 5.0 if any(v > 1.0 for v in values.values()) else 1.0
    for k, v in values.items():
        try:
            key = parse_au_key(k)
        except PdeFaceError:
            unknown.append(k)
            continue
        weights[key] = clamp_weight(v / scale)
    ts = obj.get("timestamp")
    ts = float(ts) if isinstance(ts, (int, float)) and not isinstance(ts, bool) and math.isfinite(ts) else None
    return Packet(weights, line[:200], unknown, ts, json=True)


class StreamParser:
    """Incremental parser of a byte stream of packets, controls and JSON lines."""

    def __init__(self, max_packet: int = MAX_PACKET):
        self.max_packet = max_packet
        self._buf = ""
        self._skipping = False

    def feed(self, data: bytes) -> list:
        """Events (:class:`Packet`, :class:`Control`, :class:`Garbage`) completed by ``data``."""
        self._buf += data.decode("utf-8", "replace")
        events = []
        while self._buf:
            s = self._buf.lstrip(" \t\r\n")
            self._buf = s
            if not s:
                break
            if self._skipping:  # dropping an oversized packet: resume at the next line or packet
                cut = min([i for i in (s.find("\n"), s.find("{")) if i >= 0], default=-1)
                if cut < 0:
                    self._buf = ""
                    break
                self._buf, self._skipping = s[cut:], False
                continue
            if s[0] == "{":
                if s.startswith('{"'):  # a JSON line ends at its newline
                    end = s.find("\n")
                    if end < 0:
                        if len(s) > self.max_packet:
                            events.append(Garbage("JSON line too long", s[:40]))
                            self._buf, self._skipping = "", True
                        break
                    line, self._buf = s[:end], s[end + 1:]
                    if len(line) > self.max_packet:  # however it arrived: whole in one read, or in pieces
                        events.append(Garbage("JSON line too long", line[:40]))
                        continue
                    try:
                        events.append(parse_json_event(line))
                    except PacketError as exc:
                        events.append(Garbage(str(exc), line[:40]))
                    continue
                end = s.find("}")
                if end < 0:
                    if len(s) > self.max_packet:
                        events.append(Garbage(f"packet longer than {self.max_packet} bytes", s[:40]))
                        self._buf, self._skipping = "", True
                    break
                nxt = s.find("{", 1)
                if 0 < nxt < end:  # an unclosed packet followed by another
                    events.append(Garbage("unclosed packet", s[:nxt][:40]))
                    self._buf = s[nxt:]
                    continue
                text, self._buf = s[:end + 1], s[end + 1:]
                try:
                    events.append(parse_packet(text))
                except PacketError as exc:
                    events.append(Garbage(str(exc), text[:40]))
                continue
            m = re.match(r"-?\d+", s)
            if m and len(m.group()) > MAX_CONTROL_DIGITS:  # no control is this long: drop the run of digits
                events.append(Garbage("control integer too long", m.group()[:40]))
                self._buf = s[m.end():]
                continue
            if m and m.end() < len(s) and s[m.end()] not in CONTROL_DELIMITERS:
                m = None  # digits glued to something else: garbage up to the next delimiter
            if m and (m.end() < len(s)):  # a control integer needs a delimiter after it
                code = int(m.group())
                events.append(Control(code) if code in CONTROLS else Garbage(f"unknown control {code}", m.group()))
                self._buf = s[m.end():]
                continue
            if m:
                break  # maybe more digits to come
            # Garbage up to the next packet or whitespace.
            cut = min([i for i in (s.find("{"), s.find(" "), s.find("\n")) if i > 0], default=len(s))
            if cut > self.max_packet or (cut == len(s) and len(s) > self.max_packet):
                events.append(Garbage("garbage", s[:40]))
                self._buf = s[cut:]
                continue
            if cut == len(s):
                if len(s) > 64:
                    events.append(Garbage("garbage", s[:40]))
                    self._buf = ""
                break
            events.append(Garbage("garbage", s[:cut][:40]))
            self._buf = s[cut:]
        return events

    @property
    def buffered(self) -> int:
        return len(self._buf)
