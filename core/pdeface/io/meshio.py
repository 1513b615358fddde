"""Read and write meshes: Wavefront OBJ and PLY (ASCII and binary); read glTF 2.0 (``.glb``, ``.gltf``).

Broken files raise :class:`~pdeface.errors.MeshError` naming the file and line.
glTF is read with ``trimesh`` (the optional extra ``pdeface[gltf]``): it is
maintained, depends on numpy alone, and reads the whole container (binary
chunks, external and embedded buffers, triangle strips, the node hierarchy),
which leaves this module only flattening its scene into one mesh.
"""
from __future__ import annotations

import io
import json
import os
import struct
import warnings

import numpy as np

from ..errors import MeshError
from ..mesh import Mesh
from .files import MAX_DIGITS, atomic_open, open_file, read_bytes

#: Mesh file extensions :func:`read_mesh` reads, and those :func:`write_mesh` writes.
READ_FORMATS = (".obj", ".ply", ".glb", ".gltf")
WRITE_FORMATS = (".obj", ".ply")


def read_mesh(path) -> Mesh:
    """Read an ``.obj``, ``.ply``, ``.glb`` or ``.gltf`` file by its extension."""
    ext = os.path.splitext(str(path))[1].lower()
    if ext == ".obj":
        return read_obj(path)
    if ext == ".ply":
        return read_ply(path)
    if ext in (".glb", ".gltf"):
        return read_gltf(path)
    raise MeshError(f"{path}: unsupported mesh format {ext!r} (use {', '.join(READ_FORMATS)})")


def write_mesh(path, mesh: Mesh) -> None:
    """Write an ``.obj`` or ``.ply`` file by its extension."""
    ext = os.path.splitext(str(path))[1].lower()
    if ext == ".obj":
        write_obj(path, mesh)
    elif ext == ".ply":
        write_ply(path, mesh)
    else:
        raise MeshError(f"{path}: cannot write mesh format {ext!r} (use {' or '.join(WRITE_FORMATS)})")


def write_posed(path, source, mesh: Mesh, vertices) -> None:
    """Write ``mesh`` (read from ``source``) with new vertex positions, changing nothing else.

    An OBJ source is copied line by line with only its ``v`` lines' x y z
    replaced: groups, objects, smoothing, materials, UVs, normals, vertex
    colours and comments stay exactly as they were. Other sources are written
    with :func:`write_mesh`. :func:`write_posed_many` writes several poses of
    one source, reading it once.
    """
    write_posed_many([(path, vertices)], source, mesh)


def write_posed_many(outputs, source, mesh: Mesh) -> None:
    """:func:`write_posed` for each ``(path, vertices)`` of ``outputs`` (an iterable), reading ``source`` once."""
    template = None
    for path, vertices in outputs:
        V = np.asarray(vertices, dtype=np.float64)
        if V.shape != mesh.vertices.shape or not np.isfinite(V).all():
            raise MeshError(f"{path}: posed vertices must be finite and shaped {mesh.vertices.shape}, got {V.shape}")
        src_ext = os.path.splitext(str(source))[1].lower()
        out_ext = os.path.splitext(str(path))[1].lower()
        if src_ext != ".obj" or out_ext != ".obj":
            write_mesh(path, Mesh(**{**mesh.__dict__, "vertices": V}))
            continue
        if template is None:
            template = _posed_template(source, len(V))
        out, rows, tails = template
        for i, xyz, tail in zip(rows, V.tolist(), tails):
            out[i] = "v %.6f %.6f %.6f%s" % (*xyz, tail)
        with atomic_open(path, "w", encoding="utf-8", newline="") as fh:
            fh.write("".join(out))


def _posed_template(source, n):
    """The OBJ ``source``'s lines (a list to fill in), the index of each ``v`` line in it and what follows
    each one's x y z (its other values and its line ending)."""
    with open_file(source, "r", MeshError, encoding="utf-8", errors="replace", newline="") as fh:
        out = fh.readlines()
    rows, tails = [], []
    for i, line in enumerate(out):
        if line[:1] == "v" or line[:1].isspace():  # the only lines split: a v line, maybe indented
            parts = line.split()
            if parts and parts[0] == "v":
                rows.append(i)
                end = "\r\n" if line.endswith("\r\n") else "\n"
                tails.append("".join(" " + p for p in parts[4:]) + end)
    if len(rows) > n:
        raise MeshError(f"{source}: has more vertices than the mesh read from it ({n})")
    if len(rows) != n:
        raise MeshError(f"{source}: changed since it was read ({len(rows)} vertices, expected {n})")
    return out, rows, tails


def read_obj(path) -> Mesh:
    """Read a Wavefront OBJ file.

    Supports ``v``, ``vt``, ``vn``, ``f`` with triangles, quads and n-gons in
    ``v``, ``v/vt``, ``v//vn`` and ``v/vt/vn`` forms, negative (relative)
    indices, comments, ``mtllib``/``usemtl``. Other statements are ignored.
    A well-formed file is read a block at a time with numpy (a 27k-vertex head
    in milliseconds); any other is read line by line, which names the line at fault.

    Raises
    ------
    MeshError
        With file and line, for bad numbers, indices out of range, NaN/inf,
        missing file or a file without faces.
    """
    data = read_bytes(path, MeshError)
    if b"\r" in data:  # universal newlines, as text mode reads them
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    mesh = _obj_blocks(data)
    if mesh is None:
        mesh = _obj_lines(path, data.decode("utf-8", "replace").split("\n"))
    return mesh


def _is_sep(x):
    """Whether each byte of the uint8 array ``x`` ends a token in a line (ASCII whitespace and the newline), as
    ``bytes.split`` splits; by arithmetic, a few passes 10× sooner than a table look-up."""
    return (x == 32) | (x - np.uint8(9) <= 4)  # 9-13 (uint8: below 9 wraps round past 4)


def _is_unsplit(x):
    """Whether each byte of ``x`` may begin whitespace ``str.split`` knows and ``bytes.split`` does not (non-ASCII,
    \\x1c-\\x1f)."""
    return (x - np.uint8(0x1c) <= 3) | (x >= 0x80)


_V, _VT, _VN, _F = 1, 2, 3, 4


def _obj_blocks(data: bytes) -> Mesh | None:
    """A well-formed OBJ file's mesh, parsed a block of like lines at a time; None for any other file.

    None means "read it line by line": a bad number or index, a short line, an
    empty face field or a line starting with whitespace. What is accepted here
    reads exactly as :func:`_obj_lines` reads it (tests/core/test_meshio.py checks).
    """
    buf = np.frombuffer(data + b"\n\n\n", np.uint8)
    newlines = np.flatnonzero(buf[:len(data)] == 10)
    starts = np.concatenate([[0], newlines + 1])
    lines = _Lines(data, starts, np.concatenate([newlines, [len(data)]]))
    b0, b1, b2 = buf[starts], buf[starts + 1], buf[starts + 2]
    sep1, sep2 = _is_sep(b1), _is_sep(b2)
    odd = (_is_sep(b0) & (b0 != 10)) | _is_unsplit(b0) | (((b0 == ord("v")) | (b0 == ord("f")))
                                                          & (_is_unsplit(b1) | _is_unsplit(b2)))
    for i in np.flatnonzero(odd).tolist():  # indented, or maybe split by Unicode whitespace: what is the tag?
        if lines[i].decode("utf-8", "replace").split()[:1] in (["v"], ["vt"], ["vn"], ["f"], ["usemtl"], ["mtllib"]):
            return None
    kind = np.zeros(len(starts), np.int8)
    is_v = b0 == ord("v")
    kind[is_v & sep1] = _V
    kind[is_v & (b1 == ord("t")) & sep2] = _VT
    kind[is_v & (b1 == ord("n")) & sep2] = _VN
    kind[(b0 == ord("f")) & sep1] = _F
    rows = {k: np.flatnonzero(kind == k) for k in (_V, _VT, _VN, _F)}
    blocks = {k: _numbers(lines, rows[k], tag, n)
              for k, tag, n in ((_V, b"v", 3), (_VT, b"vt", 2), (_VN, b"vn", 3))}
    if any(b is None for b in blocks.values()) or not len(rows[_V]) or not len(rows[_F]):
        return None
    faces = _faces(lines, rows)
    if faces is None:
        return None
    counts, corners = faces
    mesh = Mesh(blocks[_V], counts, corners[0])
    # Per-corner attributes are kept only when every corner has one.
    if len(rows[_VT]) and (corners[1] >= 0).all():
        mesh.uvs, mesh.face_uv_indices = blocks[_VT], corners[1]
    if len(rows[_VN]) and (corners[2] >= 0).all():
        mesh.normals, mesh.face_normal_indices = blocks[_VN], corners[2]
    materials, used_at, used = [], [], []
    for i in np.flatnonzero((b0 == ord("u")) | (b0 == ord("m"))).tolist():
        parts = lines[i].decode("utf-8", "replace").split()
        if parts[0] == "usemtl" and len(parts) > 1:
            name = " ".join(parts[1:])
            if name not in materials:
                materials.append(name)
            used_at.append(i)
            used.append(materials.index(name))
        elif parts[0] == "mtllib" and len(parts) > 1:
            mesh.mtllib = " ".join(parts[1:])
    if materials:
        current = np.searchsorted(used_at, rows[_F], side="right") - 1
        mesh.material_names = materials
        mesh.face_materials = np.where(current >= 0, np.array(used, np.int64)[current], -1)
    return mesh


class _Lines:
    """The lines of ``data`` without their newlines, by number (``starts``, ``ends``: where each begins and ends)."""

    def __init__(self, data: bytes, starts, ends):
        self.data, self.starts, self.ends = data, starts, ends

    def __getitem__(self, i):
        return self.data[self.starts[i]:self.ends[i]]

    def block(self, rows):
        """The lines ``rows`` (ascending) joined by newlines, with a newline before and after (``block``), and
        ``block``'s bytes as a uint8 array padded with 18 NULs (the parsers read a few bytes past a number); the
        data joined once, a run of consecutive lines at a time."""
        run = np.flatnonzero(np.diff(rows) != 1) + 1
        first, last = rows[np.concatenate([[0], run])], rows[np.concatenate([run - 1, [len(rows) - 1]])]
        view = memoryview(self.data)
        parts = [b"\n"]
        for a, b in zip(self.starts[first].tolist(), self.ends[last].tolist()):
            parts += [view[a:b], b"\n"]
        padded = b"".join([*parts, b"\0" * 18])
        return padded[:-18], np.frombuffer(padded, np.uint8)


def _tokens(b, sep):
    """Where each token of the bytes ``b`` starts and ends (``sep``: ``b``'s separator bytes, a bool array)."""
    edge = np.flatnonzero(sep[1:] != sep[:-1])  # b starts and ends with a separator (the callers pad it)
    edge += 1  # in place: a head's faces have 420k edges
    return edge[::2], edge[1::2]


#: The bytes of number lines and of face lines but their tags (``bytes.translate`` deletes them in one C pass).
_NUMBER_BYTES = b"0123456789+-.eE \t\n\x0b\x0c"
_CORNER_BYTES = b"0123456789-/ \t\n\x0b\x0c"
_POW10 = 10.0 ** np.arange(16)
_IPOW10 = 10 ** np.arange(16, dtype=np.int64)


def _decimals(text: bytes, b, at, end):
    """The numbers at ``b[at:end]`` (``b``: ``text``'s bytes, padded), exactly as ``float()`` parses them;
    None if one is not a number.

    ``-?digits[.digits]`` of at most 15 bytes (sign and dot included), nearly all of them, are read as integers
    (several times faster than floats): the integer and fraction digits, then ``mantissa / 10**k``, both exact,
    one correctly rounded division, as float() rounds. The few others (exponents, a sign +, many
    digits) are read by float() itself.
    """
    t = b[:len(text)]
    long = end - at > 15
    if b"+" in text or b"e" in text or b"E" in text:  # + e E: the only other letters allowed
        other = np.flatnonzero((t == ord("+")) | ((t | 32) == ord("e")))
    elif not long.any():  # the usual file
        return _plain_decimals(text, b, at, end)
    else:
        other = np.zeros(0, np.int64)
    other = np.union1d(np.searchsorted(at, other, side="right") - 1, np.flatnonzero(long))
    if len(other) > 1000:
        return None
    # some are other (a letter in a number, or a long one): blanked for the integer reading, read one by one
    spans = list(zip(at[other].tolist(), end[other].tolist()))
    try:
        exotic = [float(text[i:j]) for i, j in spans]
    except ValueError:
        return None
    blanked = bytearray(text)
    for i, j in spans:
        blanked[i:j] = b" " * (j - i)
    text = bytes(blanked)
    b = np.frombuffer(text + b"\0" * 18, np.uint8)
    plain = np.ones(len(at), bool)
    plain[other] = False
    values = np.empty(len(at))
    values[other] = exotic
    values[plain] = _plain_decimals(text, b, at[plain], end[plain])
    return None if np.isnan(values[plain]).any() else values


def _plain_decimals(text: bytes, b, at, end):
    """:func:`_decimals` of numbers ``-?digits[.digits]`` written in at most 15 bytes; NaN everywhere if any is
    not."""
    dot = np.flatnonzero(b == ord("."))
    every = len(dot) == len(at) and (at < dot).all() and (dot < end).all()  # a dot in each number (the usual file)
    if every:
        has_dot, frac_digits = True, end - dot - 1
    else:
        has_dot = np.zeros(len(at), bool)
        of = np.searchsorted(at, dot, side="right") - 1
        has_dot[of] = True
        frac_digits = np.zeros(len(at), np.int64)
        frac_digits[of] = end[of] - dot - 1
    minus = b[at] == ord("-")
    if ((not every and len(dot) != np.count_nonzero(has_dot)) or (b[dot - 1] - 48 > 9).any()
            or (b[dot + 1] - 48 > 9).any()):  # (uint8: a byte below '0' wraps round past 9 too)
        return np.full(len(at), np.nan)
    # as many decimals in each number (the usual file)
    if every and len(at) and (frac_digits == frac_digits[0]).all():
        frac_digits = frac_digits[0]  # one power of ten for all: no table look-up per number
    if every and np.count_nonzero(b[:len(text)] == ord("-")) == np.count_nonzero(minus):
        # -digits.digits each (a sign only in front): the two runs of digits read as integers.
        mantissa = _digit_values(b, at + minus, dot) * _IPOW10[frac_digits] + _digit_values(b, dot + 1, end)
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # fromstring stops early on a bad token: counted
            ints = np.fromstring(text.translate(_DOT_TO_SPACE), np.int64, sep=" ")
        if len(ints) != len(at) + len(dot):
            return np.full(len(at), np.nan)
        has_dot = np.broadcast_to(has_dot, at.shape)
        first = np.arange(len(at)) + np.cumsum(has_dot) - has_dot
        mantissa = np.abs(ints[first]) * _IPOW10[frac_digits]
        mantissa[has_dot] += ints[first[has_dot] + 1]
    values = mantissa / _POW10[frac_digits]
    return np.negative(values, out=values, where=minus)


def _digit_values(b, at, end):
    """The integers written at ``b[at:end]`` (``b``: bytes as uint8), each 1 to 15 decimal digits and nothing else;
    ``end`` ascending (the numbers in the order they are written).

    All numbers at once, a few passes over the numbers where parsing the text (``np.fromstring``) is a pass over its
    bytes: digit by digit from the right where they are short or all as long (fractions written with a fixed count
    of decimals), else (indices) each from the 8 bytes ending it (:func:`_eight_digits`: a head's faces 5-10 % sooner).
    """
    length = end - at
    width = int(length.max(initial=1))
    alike = bool((length == width).all())
    if alike or width <= 3 or width > 8:
        return _digit_by_digit(b, end, length, width, alike)
    head = int(np.searchsorted(end, 8))  # the few ending in the text's first 8 bytes: no 8 bytes before their end
    values = _eight_digits(b, end, length, head)
    values[:head] = _digit_by_digit(b, end[:head], length[:head], width, alike)
    return values


#: Masks keeping the last ``k`` bytes (k = 0 to 8) of 8 read as a little-endian word (the first in its lowest byte).
_LAST_BYTES = np.array([0] + [(1 << 64) - (1 << 8 * (8 - k)) for k in range(1, 9)], np.uint64)
_U64 = {k: np.uint64(v) for k, v in (("nibbles", 0x0F0F0F0F0F0F0F0F), ("pairs", 0x000000FF000000FF),
                                     ("by100", 0x000F424000000064), ("by1", 0x0000271000000001),
                                     (10, 10), (8, 8), (16, 16), (32, 32))}


def _eight_digits(b, end, length, head=0):
    """:func:`_digit_values` of numbers of 1 to 8 digits ending at ``end`` (``end >= 8`` but for the first ``head``,
    left to the caller): the 8 bytes before each end as one integer, the bytes before the number masked off (leading
    zeros), its digits combined pairwise in 3 multiplications (the "eight digits at once" of Lemire's fast_float):
    some 15 passes over the numbers, not 5 per digit, most in place."""
    words = np.ndarray((len(b) - 7,), "<u8", b, 0, (1,))  # the 8 bytes at each offset (unaligned)
    at = end - 8
    at[:head] = 0
    v = words[at]
    v &= _LAST_BYTES[length]
    v &= _U64["nibbles"]  # '0'-'9' to 0-9 (the masked bytes are 0)
    low = v >> _U64[8]
    v *= _U64[10]
    v += low  # each even byte: two digits
    np.bitwise_and(v, _U64["pairs"], out=low)
    low *= _U64["by100"]
    v >>= _U64[16]
    v &= _U64["pairs"]
    v *= _U64["by1"]
    v += low
    v >>= _U64[32]
    return v.view(np.int64)  # (under 10**8: the same bits)


def _digit_by_digit(b, end, length, width, alike):
    """:func:`_digit_values` of numbers ending at ``end``, ``length`` digits each (at most ``width``; ``alike``: all
    ``width``)."""
    kind = np.int32 if width <= 9 else np.int64  # half the memory to go through, where the numbers fit
    values = b[end - 1].astype(kind) - 48
    at_digit = end - 1
    for j in range(1, width):
        at_digit = at_digit - 1
        digit = b[at_digit].astype(kind) - 48
        if not alike:
            digit *= length > j
        values += digit * kind(10 ** j)
    return values.astype(np.int64)


_DOT_TO_SPACE = bytes.maketrans(b".vtnf", b"     ")


def _numbers(lines: _Lines, rows, tag: bytes, n: int):
    """The first ``n`` numbers of each of the lines ``rows`` (all tagged ``tag``) as a ``(len(rows), n)``
    array; None if a line is short or has anything but numbers, or a number is not finite."""
    if not len(rows):
        return np.zeros((0, n))
    block, b = lines.block(rows)
    if len(block.translate(None, _NUMBER_BYTES)) != len(rows) * len(tag):  # letters other than the tags'
        return None
    at, end = _tokens(b[:len(block)], b[:len(block)] <= 32)  # only whitespace is below '+' now
    if len(at) == len(rows) * (n + 1) and (b[at[::n + 1]] == tag[0]).all():
        # n numbers on every line (the usual file): the tags are every (n+1)th token, as the tag letters are
        # only at the lines' starts.
        per_line = np.full(len(rows), n)
        at, end = at.reshape(-1, n + 1)[:, 1:].ravel(), end.reshape(-1, n + 1)[:, 1:].ravel()
    else:
        first = np.searchsorted(at, np.flatnonzero(b == 10))  # each line's first token: its tag
        is_tag = np.zeros(len(at), bool)
        is_tag[first[:-1]] = True
        per_line = np.diff(first) - 1
        if (per_line < n).any():
            return None
        at, end = at[~is_tag], end[~is_tag]
    values = _decimals(block, b, at, end)
    if values is None or np.isnan(values).any():  # not numbers, or many digits: numpy's float parser
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # fromstring stops early on a bad token: counted
            values = np.fromstring(block.translate(bytes.maketrans(tag, b" " * len(tag))), np.float64, sep=" ")
        if len(values) != per_line.sum():
            return None
    if (per_line == n).all():
        out = values.reshape(len(rows), n)
    else:  # more values on some lines (vertex colours): the first n of each
        out = values[(np.cumsum(per_line) - per_line)[:, None] + np.arange(n)]
    return out if np.isfinite(out).all() else None


def _usual_corners(text, space):
    """The face lines' fields (where each starts and ends), corners per line and fields per corner ``f``, where
    every corner is ``f`` fields (1 to 3) joined by single slashes, as in nearly every file; None for any other.

    A corner's first field follows whitespace (the tag ``f`` is followed by it), each other field the slash
    just after the field before it; with no other slash in the lines, none is doubled, leading or trailing.
    """
    slash = text == ord("/")
    field_at, field_end = _tokens(text, space | slash | (text == ord("f")))
    first = np.flatnonzero(space[field_at - 1])
    f = len(field_at) // max(len(first), 1)
    if (not len(first) or not 1 <= f <= 3 or len(field_at) != f * len(first)
            or np.count_nonzero(slash) != (f - 1) * len(first)):
        return None
    if f > 1 and not ((first == np.arange(0, len(field_at), f)).all()
                      and (field_at.reshape(-1, f)[:, 1:] == field_end.reshape(-1, f)[:, :-1] + 1).all()):
        return None
    return field_at, field_end, np.diff(np.searchsorted(field_at[first], np.flatnonzero(text == 10))), f


def _faces(lines: _Lines, rows: dict):
    """The faces' corner counts and their vertex, texture and normal indices, 0-based (-1: none given);
    None if a face has fewer than 3 corners or a corner is not 1 to 3 fields of valid indices."""
    block, b = lines.block(rows[_F])
    text = b[:len(block)]
    if len(block.translate(None, _CORNER_BYTES)) != len(rows[_F]):  # anything but the tags, indices and slashes
        return None
    space = text <= 32  # only whitespace is below '-' now
    usual = _usual_corners(text, space)
    if usual is not None:  # no slash to check: the fields are as the usual file has them
        field_at, field_end, counts, f = usual
        corner_at, slash, double = field_at[::f], None, ()
        if (counts < 3).any():
            return None
    else:
        at, _ = _tokens(text, space)
        corner_at = at[b[at] != ord("f")]
        counts = np.diff(np.searchsorted(at, np.flatnonzero(text == 10))) - 1  # tokens per line but the tag
        slash = np.flatnonzero(text == ord("/"))
        # A slash stands between two fields, or is the first of "//" (no texture index).
        double = slash[b[slash + 1] == ord("/")]
        if ((counts < 3).any() or _is_sep(b[slash - 1]).any() or _is_sep(b[slash + 1]).any()
                or (b[double + 2] == ord("/")).any()):
            return None
        field_at, field_end = _tokens(text, space | (text == ord("/")) | (text == ord("f")))
    signs = np.count_nonzero(text == ord("-"))
    minus = b[field_at] == ord("-") if signs else None  # a relative index (none in the usual file)
    digits_at = field_at + minus if signs else field_at
    length = field_end - digits_at
    if (signs and signs != np.count_nonzero(minus)) or length.min() < 1 or length.max() > 15:
        return None  # a sign inside an index, a sign alone, or more digits than an index has
    values = _digit_values(b, digits_at, field_end)
    if signs:
        values[minus] *= -1
    f = len(field_at) // len(corner_at)
    if 1 <= f <= 3 and len(field_at) == f * len(corner_at) and not len(double) and (field_at[::f] == corner_at).all():
        # Every corner f fields, v, v/vt or v/vt/vn (the usual file): the values as columns.
        columns = [*values.reshape(-1, f).T, *[None] * (3 - f)]
        given = [np.ones(len(corner_at), bool)] * f + [np.zeros(len(corner_at), bool)] * (3 - f)
    else:
        slashes = np.bincount(np.searchsorted(corner_at, slash, side="right") - 1, minlength=len(corner_at))
        no_uv = np.zeros(len(corner_at), bool)
        no_uv[np.searchsorted(corner_at, double, side="right") - 1] = True
        fields = slashes + 1 - no_uv
        if (slashes > 2).any() or len(values) != fields.sum():
            return None
        first = np.cumsum(fields) - fields
        has_uv = (slashes >= 1) & ~no_uv
        given = [slashes >= 0, has_uv, slashes == 2]
        columns = [values[col[has]] for col, has in zip((first, first + 1, first + 1 + has_uv), given)]
    out = []
    for k, has, i in zip((_V, _VT, _VN), given, columns):
        if not has.any():
            out.append(np.full(len(corner_at), -1, np.int64))
            continue
        # OBJ indices are 1-based; negative ones count back from the last element read before the face.
        if not len(rows[k]) or rows[k][-1] < rows[_F][0]:
            count = len(rows[k])  # all read before the first face (the usual layout)
            if i.min() > 0:  # no relative index (the usual file)
                if i.max() > count:
                    return None
                j = i - 1
            else:
                j = np.where(i > 0, i - 1, count + i)
                if ((i == 0) | (j < 0) | (j >= count)).any():
                    return None
        else:
            corner_line = np.repeat(np.arange(len(counts)), counts)
            count = np.searchsorted(rows[k], rows[_F])[corner_line[has]]
            j = np.where(i > 0, i - 1, count + i)
            if ((i == 0) | (j < 0) | (j >= count)).any():
                return None
        if has.all():
            out.append(np.ascontiguousarray(j))
        else:
            idx = np.full(len(corner_at), -1, np.int64)
            idx[has] = j
            out.append(idx)
    return counts, out


def _obj_lines(path, lines: list) -> Mesh:
    """Read an OBJ file's text lines one by one (see :func:`read_obj`): the errors name the line."""
    V, VT, VN = [], [], []
    counts, fv, ft, fn, fmat = [], [], [], [], []
    materials, current_mat, mtllib = [], -1, None
    any_vt = any_vn = False
    for lineno, line in enumerate(lines, 1):
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        tag = parts[0]
        if tag == "v":
            V.append(_floats(parts[1:], 3, path, lineno, "vertex"))
        elif tag == "vt":
            VT.append(_floats(parts[1:], 2, path, lineno, "texture coordinate"))
        elif tag == "vn":
            VN.append(_floats(parts[1:], 3, path, lineno, "normal"))
        elif tag == "f":
            corners = parts[1:]
            if len(corners) < 3:
                raise MeshError(f"{path}:{lineno}: face needs at least 3 corners, got {len(corners)}")
            for c in corners:
                sub = c.split("/")
                if len(sub) > 3:
                    raise MeshError(f"{path}:{lineno}: bad face corner {c!r}")
                fv.append(_index(sub[0], len(V), path, lineno, "vertex"))
                if len(sub) > 1 and sub[1]:
                    ft.append(_index(sub[1], len(VT), path, lineno, "texture coordinate"))
                    any_vt = True
                else:
                    ft.append(-1)
                if len(sub) > 2 and sub[2]:
                    fn.append(_index(sub[2], len(VN), path, lineno, "normal"))
                    any_vn = True
                else:
                    fn.append(-1)
            counts.append(len(corners))
            fmat.append(current_mat)
        elif tag == "usemtl" and len(parts) > 1:
            name = " ".join(parts[1:])
            if name not in materials:
                materials.append(name)
            current_mat = materials.index(name)
        elif tag == "mtllib" and len(parts) > 1:
            mtllib = " ".join(parts[1:])
    if not V:
        raise MeshError(f"{path}: no vertices")
    if not counts:
        raise MeshError(f"{path}: no faces")
    mesh = Mesh(np.array(V, dtype=np.float64), np.array(counts, dtype=np.int64), np.array(fv, dtype=np.int64))
    ft, fn = np.array(ft, dtype=np.int64), np.array(fn, dtype=np.int64)
    # Per-corner attributes are kept only when every corner has one.
    if any_vt and (ft >= 0).all():
        mesh.uvs, mesh.face_uv_indices = np.array(VT, dtype=np.float64), ft
    if any_vn and (fn >= 0).all():
        mesh.normals, mesh.face_normal_indices = np.array(VN, dtype=np.float64), fn
    if materials:
        mesh.material_names, mesh.face_materials = materials, np.array(fmat, dtype=np.int64)
    mesh.mtllib = mtllib
    return mesh


def _floats(parts, n, path, lineno, what):
    try:
        vals = [float(p) for p in parts[:n]]
    except ValueError:
        raise MeshError(f"{path}:{lineno}: bad number in {what} line: {' '.join(parts)!r}") from None
    if len(vals) < n:
        raise MeshError(f"{path}:{lineno}: {what} line needs {n} numbers, got {len(vals)}")
    if not all(np.isfinite(vals)):
        raise MeshError(f"{path}:{lineno}: {what} is not finite (NaN or inf)")
    return vals


def _index(token, count, path, lineno, what):
    try:
        i = int(token)
    except ValueError:
        raise MeshError(f"{path}:{lineno}: bad {what} index {token!r}") from None
    # OBJ indices are 1-based; negative ones count back from the last element read so far.
    j = i - 1 if i > 0 else count + i
    if i == 0 or not 0 <= j < count:
        raise MeshError(f"{path}:{lineno}: {what} index {i} out of range (have {count})")
    return j


def write_obj(path, mesh: Mesh, header: str | None = None) -> None:
    """Write a mesh as OBJ, keeping UVs, normals and material groups."""
    mesh.validate(str(path))
    lines = []
    if header:
        lines += ["# " + h for h in header.splitlines()]
    if mesh.mtllib:
        lines.append(f"mtllib {mesh.mtllib}")
    out = ["\n".join(lines) + "\n" if lines else ""]
    out.append("".join("v %.6f %.6f %.6f\n" % tuple(v) for v in mesh.vertices))
    has_uv = mesh.uvs is not None and mesh.face_uv_indices is not None
    has_n = mesh.normals is not None and mesh.face_normal_indices is not None
    if has_uv:
        out.append("".join("vt %.6f %.6f\n" % tuple(t) for t in mesh.uvs))
    if has_n:
        out.append("".join("vn %.6f %.6f %.6f\n" % tuple(n) for n in mesh.normals))
    fv = (mesh.face_indices + 1).astype(str)
    if has_uv and has_n:
        corners = np.char.add(np.char.add(np.char.add(np.char.add(fv, "/"), (mesh.face_uv_indices + 1).astype(str)), "/"),
                              (mesh.face_normal_indices + 1).astype(str))
    elif has_uv:
        corners = np.char.add(np.char.add(fv, "/"), (mesh.face_uv_indices + 1).astype(str))
    elif has_n:
        corners = np.char.add(np.char.add(fv, "//"), (mesh.face_normal_indices + 1).astype(str))
    else:
        corners = fv
    corners = corners.tolist()
    starts = mesh.face_starts.tolist()
    last_mat = None
    faces = []
    for f, (s, c) in enumerate(zip(starts, mesh.face_counts.tolist())):
        if mesh.face_materials is not None:
            m = int(mesh.face_materials[f])
            if m != last_mat and m >= 0:
                faces.append(f"usemtl {mesh.material_names[m]}\n")
            last_mat = m
        faces.append("f " + " ".join(corners[s:s + c]) + "\n")
    out.append("".join(faces))
    with atomic_open(path, "w", encoding="utf-8") as fh:
        fh.write("".join(out))


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def read_ply(path) -> Mesh:
    """Read a PLY file (ascii, binary_little_endian or binary_big_endian).

    Reads ``vertex`` x, y, z (and s/t or u/v texture coordinates) and the
    ``face`` vertex index lists.
    """
    data = read_bytes(path, MeshError)
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise MeshError(f"{path}:1: not a PLY file (missing 'ply' magic or 'end_header')")
    header = data[:end].decode("ascii", "replace").splitlines()
    newline = data.find(b"\n", end)
    if newline < 0:
        raise MeshError(f"{path}:{len(header) + 1}: nothing after 'end_header'")
    body = data[newline + 1:]
    fmt, elements = None, []
    for lineno, line in enumerate(header, 1):
        p = line.split()
        if not p:
            continue
        if p[0] == "format":
            fmt = p[1] if len(p) > 1 else None
        elif p[0] == "element":
            if len(p) != 3 or not (p[2].isascii() and p[2].isdigit()):
                raise MeshError(f"{path}:{lineno}: 'element NAME COUNT' expected, got {line[:60]!r}")
            if len(p[2]) > MAX_DIGITS or int(p[2]) > len(data):  # every element takes at least a byte: checked before any allocation
                raise MeshError(f"{path}:{lineno}: {p[2][:20]} {p[1][:20]} elements claimed in {len(data)} bytes")
            elements.append([p[1], int(p[2]), []])
        elif p[0] == "property":
            if not elements:
                raise MeshError(f"{path}:{lineno}: property before any element")
            if len(p) < 3 or (p[1] == "list" and len(p) < 5):
                raise MeshError(f"{path}:{lineno}: incomplete property {line[:60]!r}")
            if p[1] == "list":
                if p[2] not in _PLY_TYPES or p[3] not in _PLY_TYPES:
                    raise MeshError(f"{path}:{lineno}: unknown PLY type in {line[:60]!r}")
                elements[-1][2].append((p[4], "list", _PLY_TYPES[p[2]], _PLY_TYPES[p[3]]))
            else:
                if p[1] not in _PLY_TYPES:
                    raise MeshError(f"{path}:{lineno}: unknown PLY type {p[1][:20]!r}")
                elements[-1][2].append((p[2], _PLY_TYPES[p[1]]))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise MeshError(f"{path}: unknown PLY format {fmt and fmt[:20]!r}")
    values = {}
    if fmt == "ascii":
        tokens = body.decode("ascii", "replace").split()
        pos = 0
        try:
            for name, count, props in elements:
                rows = []
                for _ in range(count):
                    row = []
                    for prop in props:
                        if prop[1] == "list":
                            n = int(tokens[pos]); pos += 1
                            if not 0 <= n <= len(tokens) - pos:
                                raise IndexError
                            row.append([float(t) for t in tokens[pos:pos + n]]); pos += n
                        else:
                            row.append(float(tokens[pos])); pos += 1
                    rows.append(row)
                values[name] = (props, rows)
        except (ValueError, IndexError):
            raise MeshError(f"{path}: truncated or malformed ASCII PLY body") from None
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        off = 0
        try:
            for name, count, props in elements:
                rows = []
                if all(p[1] != "list" for p in props):
                    dt = np.dtype([(p[0], order + p[1]) for p in props])
                    arr = np.frombuffer(body, dtype=dt, count=count, offset=off)
                    off += dt.itemsize * count
                    rows = [[arr[p[0]][i] for p in props] for i in range(count)] if name != "vertex" else arr
                else:
                    for _ in range(count):
                        row = []
                        for prop in props:
                            if prop[1] == "list":
                                ct, it = np.dtype(order + prop[2]), np.dtype(order + prop[3])
                                n = int(np.frombuffer(body, ct, 1, off)[0]); off += ct.itemsize
                                if not 0 <= n <= len(body) - off:
                                    raise ValueError
                                row.append(np.frombuffer(body, it, n, off).tolist()); off += it.itemsize * n
                            else:
                                t = np.dtype(order + prop[1])
                                row.append(np.frombuffer(body, t, 1, off)[0]); off += t.itemsize
                        rows.append(row)
                values[name] = (props, rows)
        except (ValueError, struct.error):
            raise MeshError(f"{path}: truncated binary PLY body") from None
    if "vertex" not in values:
        raise MeshError(f"{path}: no vertex element")
    props, rows = values["vertex"]
    names = [p[0] for p in props]
    if not {"x", "y", "z"} <= set(names):
        raise MeshError(f"{path}: vertex element lacks x, y, z")
    if any(p[1] == "list" for p in props):  # x, y, z and the UVs are numbers; a list of them is no vertex
        raise MeshError(f"{path}: vertex properties must be numbers, not lists")
    if isinstance(rows, np.ndarray):
        with np.errstate(invalid="ignore"):  # NaN/inf coordinates are refused below, naming the file
            V = np.stack([rows["x"], rows["y"], rows["z"]], 1).astype(np.float64)
            uv_names = next((n for n in (("s", "t"), ("u", "v"), ("texture_u", "texture_v"))
                             if set(n) <= set(names)), None)
            UV = np.stack([rows[uv_names[0]], rows[uv_names[1]]], 1).astype(np.float64) if uv_names else None
    else:
        arr = np.array(rows, dtype=np.float64).reshape(len(rows), len(names))
        V = arr[:, [names.index(c) for c in "xyz"]]
        uv_names = next((n for n in (("s", "t"), ("u", "v"), ("texture_u", "texture_v")) if set(n) <= set(names)), None)
        UV = arr[:, [names.index(uv_names[0]), names.index(uv_names[1])]] if uv_names else None
    if "face" not in values:
        raise MeshError(f"{path}: no faces")
    fprops, frows = values["face"]
    li = next((i for i, p in enumerate(fprops) if p[1] == "list" and p[0] in ("vertex_indices", "vertex_index")), None)
    if li is None:
        raise MeshError(f"{path}: face element lacks vertex_indices")
    polys = [r[li] for r in frows]
    if not polys:
        raise MeshError(f"{path}: no faces")
    counts = np.array([len(p) for p in polys], dtype=np.int64)
    flat = np.array([i for p in polys for i in p], dtype=np.float64)
    if not (np.isfinite(flat).all() and (flat == np.round(flat)).all() and np.abs(flat).max(initial=0) < 2**62):
        raise MeshError(f"{path}: face vertex indices must be whole numbers (NaN, inf or fractions found)")
    idx = flat.astype(np.int64)
    mesh = Mesh(V, counts, idx)
    if UV is not None:
        mesh.uvs, mesh.face_uv_indices = UV, idx.copy()
    return mesh.validate(str(path))


def write_ply(path, mesh: Mesh) -> None:
    """Write a binary little-endian PLY with per-vertex UVs when they map one-to-one."""
    mesh.validate(str(path))
    V = mesh.vertices.astype("<f4")
    uv = None
    if mesh.uvs is not None and mesh.face_uv_indices is not None:
        uv = np.zeros((len(V), 2), "<f4")
        uv[mesh.face_indices] = mesh.uvs[mesh.face_uv_indices]
    head = ["ply", "format binary_little_endian 1.0", f"element vertex {len(V)}",
            "property float x", "property float y", "property float z"]
    if uv is not None:
        head += ["property float s", "property float t"]
    head += [f"element face {len(mesh.face_counts)}", "property list uchar int vertex_indices", "end_header"]
    with atomic_open(path, "wb") as fh:
        fh.write(("\n".join(head) + "\n").encode("ascii"))
        fh.write((np.hstack([V, uv]) if uv is not None else V).astype("<f4").tobytes())
        for s, c in zip(mesh.face_starts, mesh.face_counts):
            fh.write(struct.pack("<B", c) + mesh.face_indices[s:s + c].astype("<i4").tobytes())


def read_gltf(path) -> Mesh:
    """Read a glTF 2.0 file (``.glb`` or ``.gltf``) as one triangle mesh.

    Every triangle primitive of every node in the default scene comes in with
    its node's world transform applied (a head with separate eyes and teeth
    becomes one mesh), in trimesh's order of the scene's nodes and each
    primitive's own vertex order; positions stay in the file's units (glTF's
    are metres, +Y up). Texture coordinates come along when every primitive
    has them (flipped to OBJ's convention, v up). Points and lines are skipped.

    Raises
    ------
    MeshError
        Naming the file: missing, not glTF 2.0, broken, or without triangles;
        or trimesh not installed (with how to install it).
    """
    data = read_bytes(path, MeshError)  # a missing or unreadable file says so as every other format does
    try:
        import trimesh
        from trimesh.resolvers import FilePathResolver
    except ImportError:
        raise MeshError(f"{path}: reading glTF needs trimesh: python -m pip install 'pdeface[gltf]'") from None
    ext = os.path.splitext(str(path))[1].lower()[1:]
    data = _prepared(path, data, ext == "glb")
    try:
        scene = trimesh.load(io.BytesIO(data), file_type=ext, force="scene",
                             process=False, resolver=FilePathResolver(os.path.abspath(path)))
    except Exception as exc:  # noqa: BLE001 - trimesh raises whatever its parsing met (KeyError, struct.error ...)
        raise MeshError(f"{path}: not a readable glTF file ({type(exc).__name__}: {str(exc)[:120]})") from None
    V, F, UV = [], [], []
    offset = 0
    for node in scene.graph.nodes_geometry:
        matrix, name = scene.graph[node]
        geom = scene.geometry.get(name)
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        P = np.asarray(geom.vertices, dtype=np.float64)
        V.append(P @ matrix[:3, :3].T + matrix[:3, 3])
        faces = np.asarray(geom.faces, dtype=np.int64)
        if np.linalg.det(matrix[:3, :3]) < 0:  # a mirroring node turns its triangles inside out: keep them facing out
            faces = faces[:, ::-1]
        F.append(faces + offset)
        uv = getattr(geom.visual, "uv", None)
        UV.append(None if uv is None or len(uv) != len(P) else np.asarray(uv, dtype=np.float64)[:, :2])
        offset += len(P)
    if not V:
        raise MeshError(f"{path}: no triangle mesh in the file's scene")
    F = np.concatenate(F).reshape(-1)
    mesh = Mesh(np.concatenate(V), np.full(len(F) // 3, 3, dtype=np.int64), F)
    if all(uv is not None for uv in UV):
        mesh.uvs, mesh.face_uv_indices = np.concatenate(UV), mesh.face_indices.copy()
    return mesh.validate(str(path))


def _prepared(path, data: bytes, binary: bool) -> bytes:
    """A glTF file's bytes with an empty material on every primitive that has none, its claims checked.

    trimesh reads a primitive's texture coordinates only along with its material;
    a head exported without one (a sculpt) keeps its UVs this way. An accessor
    claiming more elements than the buffers have bytes is refused before trimesh
    allocates it. Bytes that are not glTF are returned as they are, for trimesh
    to refuse.
    """
    try:
        if binary:
            magic, version, _, n, kind = struct.unpack_from("<4sIIII", data)
            if magic != b"glTF" or kind != 0x4E4F534A:
                return data
            gltf, rest = json.loads(data[20:20 + n]), data[20 + n:]
        else:
            gltf = json.loads(data)
    except (struct.error, ValueError, RecursionError):
        return data
    if not isinstance(gltf, dict):
        return data

    def listed(key):  # the objects of a top-level array (anything else is trimesh's to refuse)
        items = gltf.get(key)
        return [x for x in items if isinstance(x, dict)] if isinstance(items, list) else []

    total = sum(b["byteLength"] for b in listed("buffers") if isinstance(b.get("byteLength"), int))
    for i, a in enumerate(listed("accessors")):
        if isinstance(a.get("count"), int) and a["count"] > total:
            raise MeshError(f"{path}: accessor {i} claims {a['count']} elements in {total} bytes of buffers")
    primitives = [p for m in listed("meshes") if isinstance(m.get("primitives"), list) for p in m["primitives"]
                  if isinstance(p, dict) and "material" not in p]
    if not primitives or not isinstance(gltf.get("materials", []), list):
        return data
    gltf.setdefault("materials", []).append({"name": "pdeface_default"})
    for p in primitives:
        p["material"] = len(gltf["materials"]) - 1
    text = json.dumps(gltf).encode()
    if not binary:
        return text
    text += b" " * (-len(text) % 4)  # chunks are 4-byte aligned
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + rest
    return struct.pack("<4sII", b"glTF", version, 12 + len(body)) + body
