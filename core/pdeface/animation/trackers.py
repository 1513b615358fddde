"""Import AU data that trackers write, as timelines.

Formats (``detect_format`` picks one from the file's first line):

``openface``
    OpenFace 2.x CSV: ``AUxx_r`` intensities 0-5 (divided by 5), ``AUxx_c``
    presence (an AU marked absent gets 0; an AU with only ``_c``, like AU28,
    gets its presence), rows with ``success`` 0 or ``confidence`` below the
    threshold are dropped, ``timestamp`` (s) gives the frame. Header names may
    carry leading spaces, as OpenFace writes them. One face (``face_id``).
``pyfeat``
    Py-Feat CSV: ``AU01`` … in 0-1; ``approx_time`` (s) or ``frame`` gives the
    time; rows with ``FaceScore`` below the threshold are dropped.
``livelink``
    Live Link Face CSV (ARKit's 52 blendshape names): mapped to AUs with the
    ICT-FaceKit table (:data:`pdeface.au.ict.ARKIT_TO_AU`); ``Timecode`` ``HH:MM:SS:FF[.ms]``,
    whose FF counts at the capture's rate, read off the file (:func:`timecode_rate`).
``fas``
    The FAS system's plain-text AU sets, one ``{1,2,5,15,16,20,26}`` per line
    (extended forms too, see :mod:`pdeface.stream.wire`), each held for
    ``hold`` seconds.

Channels a format carries but the FACS catalogue does not know are reported
once, not fatal; a malformed row raises an error naming its line.
"""
from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..au.ict import ARKIT_TO_AU
from ..errors import ModelFormatError, PdeFaceError
from ..facs import clamp_weight, clamp_weights, parse_au_key, split_au_key
from ..io.files import MAX_DIGITS, open_file, read_lines, whole_digits
from ..stream.wire import PacketError, parse_packet
from .timeline import MAX_FPS, MAX_SECONDS, Key, Timeline

FORMATS = ("openface", "pyfeat", "livelink", "fas")

_LLF_META = {"timecode", "blendshapecount"}


@dataclass
class ImportResult:
    timeline: Timeline
    format: str
    rows: int
    dropped: int = 0
    unknown: list = field(default_factory=list)
    capture_fps: float | None = None  # the rate the file's own time stamps count at, where they do (Live Link Face)
    notes: list = field(default_factory=list)  # what the reader had to guess


def detect_format(path) -> str:
    with open_file(path, encoding="utf-8-sig", errors="replace", kind="table") as fh:
        first = ""
        for line in fh:
            if line.strip() and not line.lstrip().startswith("#"):
                first = line
                break
    head = [h.strip().lower() for h in first.split(",")]
    if first.lstrip().startswith("{"):
        return "fas"
    if any(re.fullmatch(r"au\d+_[rc]", h) for h in head):
        return "openface"
    if "timecode" in head or "eyeblinkleft" in head:
        return "livelink"
    if any(re.fullmatch(r"au\d+", h) for h in head):
        return "pyfeat"
    raise ModelFormatError(f"{path}:1: unknown AU data format (expected an OpenFace, Py-Feat or Live Link Face "
                           "CSV header, or FAS {{...}} lines)")


def _number(text, path, lineno, column):
    digits = len(text) > MAX_DIGITS and whole_digits(text)
    if digits > MAX_DIGITS:  # the whole part's digits: as in JSON, no value in these files needs more
        raise ModelFormatError(f"{path}:{lineno}: column {column!r} has a number of {digits} digits "
                               f"(at most {MAX_DIGITS})")
    try:
        v = float(text)
    except ValueError:
        raise ModelFormatError(f"{path}:{lineno}: column {column!r} is not a number: {text.strip()[:20]!r}") from None
    if not math.isfinite(v):
        raise ModelFormatError(f"{path}:{lineno}: column {column!r} is not finite")
    return v


def _rows(path):
    with open_file(path, encoding="utf-8-sig", errors="replace", newline="", kind="table") as fh:
        reader = csv.reader(fh)
        header = None
        while True:
            try:
                row = next(reader)
            except StopIteration:
                break
            except csv.Error as exc:  # a field past the csv module's limit (128 KiB), a NUL byte, ...
                raise ModelFormatError(f"{path}:{reader.line_num}: {exc}") from None
            if not row or all(not c.strip() for c in row):
                continue
            if header is None:
                header = [h.strip() for h in row]
                continue
            if len(row) != len(header):
                raise ModelFormatError(f"{path}:{reader.line_num}: {len(row)} columns, the header has {len(header)}")
            yield reader.line_num, header, row
        if header is None:
            raise ModelFormatError(f"{path}: empty file")


def _table(path, columns):
    """A CSV's rows with what ``columns(header, index)`` reads off its header, once.

    Yields (line number, ``{column name: index}``, that reading, row).
    """
    idx = cols = None
    for lineno, header, row in _rows(path):
        if cols is None:
            idx = {h: i for i, h in enumerate(header)}
            cols = columns(header, idx)
        yield lineno, idx, cols, row


def _au_of(name):
    """'AU01_r' / 'AU01' → '1', or None when FACS has no such AU."""
    m = re.fullmatch(r"AU(\d+)(?:_[rc])?", name, re.IGNORECASE)
    try:
        return parse_au_key(m.group(1)) if m else None
    except PdeFaceError:
        return None


def _samples_openface(path, min_confidence, face_id):
    times, poses, dropped, unknown = [], [], 0, set()

    def columns(header, idx):
        if "timestamp" not in idx:
            raise ModelFormatError(f"{path}:1: OpenFace CSV without a 'timestamp' column")
        r_cols = [(h, _au_of(h)) for h in header if re.fullmatch(r"AU\d+_r", h)]
        c_cols = {_au_of(h): h for h in header if re.fullmatch(r"AU\d+_c", h)}
        unknown.update({h for h, a in r_cols if a is None} | {h for a, h in c_cols.items() if a is None})
        return [(h, a) for h, a in r_cols if a], {a: h for a, h in c_cols.items() if a}

    for lineno, idx, (r_cols, c_cols), row in _table(path, columns):
        if "face_id" in idx and int(_number(row[idx["face_id"]], path, lineno, "face_id")) != face_id:
            continue
        if "success" in idx and _number(row[idx["success"]], path, lineno, "success") == 0:
            dropped += 1
            continue
        if "confidence" in idx and _number(row[idx["confidence"]], path, lineno, "confidence") < min_confidence:
            dropped += 1
            continue
        pose = {}
        for h, a in r_cols:
            w = _number(row[idx[h]], path, lineno, h) / 5.0
            if a in c_cols and _number(row[idx[c_cols[a]]], path, lineno, c_cols[a]) == 0:
                w = 0.0
            pose[a] = clamp_weight(w)
        for a, h in c_cols.items():
            if a not in pose:
                pose[a] = 1.0 if _number(row[idx[h]], path, lineno, h) > 0 else 0.0
        times.append(_number(row[idx["timestamp"]], path, lineno, "timestamp"))
        poses.append(pose)
    return times, poses, dropped, sorted(unknown)


def _samples_pyfeat(path, fps, min_face_score):
    times, poses, dropped, unknown = [], [], 0, set()

    def columns(header, idx):
        au_cols = [(h, _au_of(h)) for h in header if re.fullmatch(r"AU\d+", h, re.IGNORECASE)]
        unknown.update(h for h, a in au_cols if a is None)
        tcol = "approx_time" if "approx_time" in idx else ("frame" if "frame" in idx else None)
        return [(h, a) for h, a in au_cols if a], tcol

    for lineno, idx, (au_cols, tcol), row in _table(path, columns):
        if "FaceScore" in idx:
            score = row[idx["FaceScore"]].strip()
            if not score or _number(score, path, lineno, "FaceScore") < min_face_score:
                dropped += 1
                continue
        values = [row[idx[h]].strip() for h, _ in au_cols]
        if any(not v for v in values):  # no face found in this frame
            dropped += 1
            continue
        pose = {a: clamp_weight(_number(v, path, lineno, h)) for (h, a), v in zip(au_cols, values)}
        if tcol == "approx_time":
            t = _number(row[idx[tcol]], path, lineno, tcol)
        elif tcol == "frame":
            t = _number(row[idx[tcol]], path, lineno, tcol) / fps
        else:
            t = len(times) / fps
        times.append(t)
        poses.append(pose)
    return times, poses, dropped, sorted(unknown)


#: Frame rates a timecode's frame field (FF) may count at.
TIMECODE_RATES = (24, 25, 30, 48, 50, 60, 72, 90, 100, 120, 240)


def _timecode(text, path, lineno):
    """``HH:MM:SS:FF[.sub]`` → (whole seconds, frames within the second incl. the sub-frame)."""
    m = re.fullmatch(r"\s*(\d{1,3}):(\d{1,2}):(\d{1,2})[:;](\d{1,3})(?:\.(\d{1,9}))?\s*", text)
    if not m:
        raise ModelFormatError(f"{path}:{lineno}: Timecode {text.strip()[:24]!r} is not HH:MM:SS:FF[.sub]")
    h, mi, s, f, sub = m.groups()
    return int(h) * 3600 + int(mi) * 60 + int(s), int(f) + (float("0." + sub) if sub else 0.0)


def timecode_rate(seconds, frames, path="timecode"):
    """The rate a timecode's frame field counts at, from its range: (rate, note or "").

    The frame field runs 0 … rate-1 within each second; a clip that crosses a
    second shows the whole range. A shorter one only bounds it from below: the
    smallest standard rate above its largest frame is taken, with a note.
    """
    top = int(max(frames))
    rate = next((r for r in TIMECODE_RATES if r > top), None)
    if rate is None:
        raise ModelFormatError(f"{path}: Timecode frame {top} is beyond {TIMECODE_RATES[-1]} fps")
    if len(set(seconds)) > 1:
        return rate, ""
    return rate, (f"{path}: the clip is shorter than a second, so its timecode's frame rate is a guess "
                  f"({rate} fps from its frames up to {top}); give the capture rate if it differs")


def _samples_livelink(path, fps, capture_fps=None):
    times, poses, unknown, stamps = [], [], set(), []

    def columns(header, idx):
        shape_cols = [h for h in header if h.lower() not in _LLF_META]
        unknown.update(h for h in shape_cols if h.lower() not in ARKIT_TO_AU)
        tc = next((h for h in header if h.lower() == "timecode"), None)
        return [h for h in shape_cols if h.lower() in ARKIT_TO_AU], tc

    for lineno, idx, (shape_cols, tc), row in _table(path, columns):
        pose = {}
        for h in shape_cols:
            w = clamp_weight(_number(row[idx[h]], path, lineno, h))
            for au, share in ARKIT_TO_AU[h.lower()]:
                pose[au] = pose.get(au, 0.0) + share * w
        if tc:
            stamps.append(_timecode(row[idx[tc]], path, lineno))
        poses.append(pose)
    note = ""
    if not stamps:  # no timecode: one row per timeline frame
        times = [i / fps for i in range(len(poses))]
    else:
        seconds, frames = (np.array(x, dtype=np.float64) for x in zip(*stamps))
        if capture_fps is None:
            capture_fps, note = timecode_rate(seconds, frames, str(path))
        elif frames.max() >= capture_fps:
            raise ModelFormatError(f"{path}: Timecode frame {int(frames.max())} does not fit {capture_fps} fps")
        times = list(seconds - seconds[0] + (frames - frames[0]) / capture_fps)
    return times, poses, 0, sorted(unknown), capture_fps, note


def _frame(seconds, fps):
    """Frame of a time (frame 1 at 0 s), rounding halves up."""
    return 1 + int(math.floor(seconds * fps + 0.5))


def _keys_fas(path, fps, hold):

    if not 0 < hold <= MAX_SECONDS:
        raise ModelFormatError(f"hold must be in (0, {MAX_SECONDS}] seconds, got {hold}")
    keys, unknown = [Key(1, {}, {}, "linear")], set()
    blend = min(0.25, hold / 2)  # the FAS player's 250 ms between expressions
    t = 0.0
    lines = read_lines(path)
    n = 0
    for lineno, line in enumerate(lines, 1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        try:
            p = parse_packet(s)
        except PacketError as exc:
            raise ModelFormatError(f"{path}:{lineno}: {exc}") from None
        unknown |= {f"AU{u}" for u in p.unknown}
        f_in, f_out = _frame(t + blend, fps), _frame(t + hold, fps)
        if f_in <= keys[-1].frame:  # sets held shorter than a frame: the later one wins its frame
            keys.pop()
        keys.append(Key(max(f_in, keys[-1].frame + 1 if keys else 1), dict(p.weights), {}, "linear"))
        if f_out > keys[-1].frame:
            keys.append(Key(f_out, dict(p.weights), {}, "linear"))
        t += hold
        n += 1
        if t > MAX_SECONDS:
            raise ModelFormatError(f"{path}:{lineno}: the AU sets held {hold} s each last past "
                                   f"{MAX_SECONDS // 3600} hours")
    if n == 0:
        raise ModelFormatError(f"{path}: no AU sets in the file")
    keys.append(Key(keys[-1].frame + max(1, _frame(blend, fps) - 1), {}, {}, "linear"))
    return keys, n, sorted(unknown)


def smooth(values: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average over ``window`` samples along axis 0 (edges use what is there)."""
    if window <= 1 or values.size == 0:
        return values
    window = min(window, 2 * len(values) + 1)  # any wider window averages everything, as this one does
    kernel = np.ones(window)
    pad = window // 2
    num = np.apply_along_axis(lambda c: np.convolve(c, kernel, mode="full")[pad:pad + len(c)], 0, values)
    den = np.convolve(np.ones(len(values)), kernel, mode="full")[pad:pad + len(values)]
    return num / den[:, None]


def reduce_keys(frames: np.ndarray, values: np.ndarray, tolerance: float) -> np.ndarray:
    """Indices of keys to keep so linear interpolation stays within ``tolerance`` on every channel.

    Ramer-Douglas-Peucker on the weight curves: first and last keys always stay.
    """
    n = len(frames)
    if n <= 2 or tolerance <= 0:
        return np.arange(n)
    if values.shape[1] == 0:  # no channel: the first and last keys say everything
        return np.array([0, n - 1])
    keep = np.zeros(n, bool)
    keep[[0, n - 1]] = True
    stack = [(0, n - 1)]
    x = frames.astype(np.float64)
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        t = (x[a + 1:b] - x[a]) / (x[b] - x[a])
        interp = values[a] + t[:, None] * (values[b] - values[a])
        err = np.abs(values[a + 1:b] - interp).max(axis=1)
        i = int(np.argmax(err))
        if err[i] > tolerance:
            m = a + 1 + i
            keep[m] = True
            stack += [(a, m), (m, b)]
    return np.nonzero(keep)[0]


def import_au(path, fmt="auto", fps=30.0, hold=0.5, smooth_window=1, reduce_tolerance=0.0,
              min_confidence=0.75, face_id=0, capture_fps=None) -> ImportResult:
    """Read an AU data file into a timeline.

    Parameters
    ----------
    fmt : {'auto', 'openface', 'pyfeat', 'livelink', 'fas'}
    fps : float
        Frame rate of the timeline (and of Py-Feat's frame counter).
    capture_fps : float, optional
        The rate Live Link Face's timecode frames count at; None: read off the
        file (the frame field's range, see :func:`timecode_rate`).
    hold : float
        Seconds each FAS AU set is held.
    smooth_window : int
        Moving-average window in samples (1: none).
    reduce_tolerance : float
        Drop keys while linear interpolation stays within this weight (0: keep all).
    min_confidence : float
        OpenFace confidence / Py-Feat FaceScore below which a row is dropped.
    """
    if not 0 < fps <= MAX_FPS:
        raise ModelFormatError(f"fps must be in (0, {MAX_FPS}], got {fps}")
    if not 1 <= smooth_window < math.inf:
        raise ModelFormatError(f"the smoothing window must be a whole number of samples >= 1, got {smooth_window}")
    if not 0 <= reduce_tolerance < math.inf:
        raise ModelFormatError(f"the reduction tolerance must be a weight >= 0, got {reduce_tolerance}")
    if not -math.inf < min_confidence < math.inf:
        raise ModelFormatError(f"the minimum confidence must be a number, got {min_confidence}")
    if capture_fps is not None and not 0 < capture_fps <= MAX_FPS:
        raise ModelFormatError(f"the capture rate must be in (0, {MAX_FPS}] fps, got {capture_fps}")
    fmt = detect_format(path) if fmt == "auto" else fmt
    if fmt not in FORMATS:
        raise ModelFormatError(f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
    if fmt == "fas":
        keys, n, unknown = _keys_fas(path, fps, hold)
        return ImportResult(Timeline(float(fps), keys, 1), fmt, n, 0, unknown)
    notes = []
    if fmt == "openface":
        times, poses, dropped, unknown = _samples_openface(path, min_confidence, face_id)
    elif fmt == "pyfeat":
        times, poses, dropped, unknown = _samples_pyfeat(path, fps, min_confidence)
    else:
        times, poses, dropped, unknown, capture_fps, note = _samples_livelink(path, fps, capture_fps)
        notes += [note] if note else []
    if not poses:
        raise ModelFormatError(f"{path}: no usable rows ({dropped} dropped for tracking failure or low confidence)")
    channels = sorted({a for p in poses for a in p}, key=split_au_key)
    times = np.asarray(times, dtype=np.float64)
    if not (np.abs(times) <= MAX_SECONDS).all():
        raise ModelFormatError(f"{path}: time stamps span more than {MAX_SECONDS // 3600} hours")
    frames = 1 + np.floor(times * fps + 0.5).astype(np.int64)
    values = np.array([[p.get(c, 0.0) for c in channels] for p in poses])
    # One key per frame (trackers may sample faster than the timeline): the last sample wins.
    order = np.argsort(frames, kind="stable")
    frames, values = frames[order], values[order]
    last = np.r_[frames[1:] != frames[:-1], True]
    frames, values = frames[last], values[last]
    values = clamp_weights(smooth(values, int(smooth_window)))
    keep = reduce_keys(frames, values, reduce_tolerance)
    keys = [Key(int(frames[i]), {c: float(v) for c, v in zip(channels, values[i])}, {}, "linear") for i in keep]
    return ImportResult(Timeline(float(fps), keys, 1), fmt, len(poses) + dropped, dropped, unknown,
                        capture_fps if fmt == "livelink" else None, notes)
