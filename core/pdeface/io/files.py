"""Opening a user's files with errors that name the file, and writing them atomically (the one way
pdeface does it)."""
from __future__ import annotations

import contextlib
import io
import json
import os
import re
import stat
import tempfile
import zipfile

from ..errors import FileError, ModelFormatError

#: The largest file of each kind pdeface reads (bytes), checked before reading: a mesh (OBJ, PLY, glTF), a
#: table (tracker CSVs, FAS and stream text: hours of frames), an archive (models, ``.pdd``, ``.npz``,
#: ``.gz``; and what one inflates to, see :func:`inflate`) and JSON (presets, timelines, landmarks, maps, rules).
MAX_BYTES = {"mesh": 1 << 30, "table": 256 << 20, "archive": 64 << 20, "json": 64 << 20}
# A keys file (``pdeface rig``'s) has the mesh's limit, not the archive's: 82 keys of a 160k-vertex head are 160 MiB
# (float32), which the archive limit refused. Not every mesh under that limit fits: 82 keys are 984 bytes a vertex
# and the rest mesh about 48 more (float64 vertices, int32 triangles), so a head of more than about 1.04M vertices is
# over it, and ``save_keys`` refuses it before writing.
MAX_BYTES["keys"] = MAX_BYTES["mesh"]
_KIND_OF_EXT = {".obj": "mesh", ".ply": "mesh", ".glb": "mesh", ".gltf": "mesh", ".csv": "table", ".txt": "table",
                ".npz": "archive", ".pdd": "archive", ".gz": "archive"}
#: The most digits an integer in any of pdeface's text formats (JSON, CSV, PLY) may have: no count, index or
#: frame in them needs more, and Python's int() of thousands of digits is slow or refused.
MAX_DIGITS = 15


def file_kind(path) -> str:
    """The kind of file (a key of :data:`MAX_BYTES`) a path's extension says; JSON for any other."""
    return _KIND_OF_EXT.get(os.path.splitext(str(path))[1].lower(), "json")


def open_file(path, mode="r", error=ModelFormatError, kind=None, **kwargs):
    """``open(path, mode, **kwargs)``; a failure raises ``error`` (a PdeFaceError subclass) naming the file.

    Opened for reading, the file must be a regular file (a device, FIFO or folder is refused before it is
    opened: it may never end) no larger than ``MAX_BYTES[kind]`` (``kind`` by default from the extension,
    see :func:`file_kind`).
    """
    if not any(c in mode for c in "wax+"):
        check_readable(path, error, kind)
    try:
        return open(path, mode, **kwargs)
    except OSError as exc:
        raise error(f"{path}: cannot open ({exc.strerror})") from None


def check_readable(path, error=ModelFormatError, kind=None) -> int:
    """Refuse a path that is not a regular file, or is larger than ``MAX_BYTES[kind]``; returns its size."""
    try:
        st = os.stat(path)
    except (OSError, ValueError) as exc:
        raise error(f"{path}: cannot open ({getattr(exc, 'strerror', None) or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise error(f"{path}: cannot open (a folder, not a file)")
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{path}: not a regular file (a device, pipe or socket has no end to read to)")
    kind = kind or file_kind(path)
    if st.st_size > MAX_BYTES[kind]:
        raise error(f"{path}: {st.st_size / 2**20:.0f} MiB is too large for a {kind} file "
                    f"(limit {MAX_BYTES[kind] >> 20} MiB)")
    return st.st_size


def read_bytes(path, error=ModelFormatError, kind=None) -> bytes:
    """A whole file's bytes, at most ``MAX_BYTES[kind]`` (see :func:`open_file`)."""
    kind = kind or file_kind(path)
    limit = MAX_BYTES[kind]
    with open_file(path, "rb", error, kind) as fh:
        # read(n) allocates n bytes first: ask for the file's size (and one more), not the limit
        size = os.fstat(fh.fileno()).st_size
        data = fh.read(min(size, limit) + 1)
        if size < len(data) <= limit:  # it grew while read: on to the limit (and one more)
            data += fh.read(limit + 1 - len(data))
    if len(data) > limit:
        raise error(f"{path}: larger than a {kind} file may be (limit {limit >> 20} MiB)")
    return data


def read_lines(path, error=ModelFormatError, kind="table") -> list:
    """A UTF-8 text file's lines (undecodable bytes replaced; see :func:`read_bytes`)."""
    return read_bytes(path, error, kind).decode("utf-8", "replace").splitlines()


def inflate(data: bytes, where, error=ModelFormatError, wbits=15, limit=MAX_BYTES["archive"]) -> bytes:
    """Inflate zlib (``wbits`` 15) or gzip (31) ``data``, refusing output past ``limit`` bytes (a small file
    must not claim gigabytes) and a corrupt stream, naming ``where``."""
    import zlib

    stream = zlib.decompressobj(wbits)
    try:
        raw = stream.decompress(data, limit)
    except zlib.error:
        raise error(f"{where}: compressed data is corrupt") from None
    if stream.unconsumed_tail:
        raise error(f"{where}: inflates past {limit >> 20} MiB; no pdeface file is that large")
    if not stream.eof:
        raise error(f"{where}: compressed data is truncated")
    return raw


def whole_digits(text) -> int:
    """The digits of a number's whole part as written (``"-1234.5e6"`` → 4): what :data:`MAX_DIGITS` limits in
    every text format, floats included (a fraction may be long; no value pdeface reads is 10**15 or more)."""
    return sum(c.isdigit() for c in re.split("[.eE]", str(text), maxsplit=1)[0])


def parse_int(text, where, error=ModelFormatError) -> int:
    """An integer written in text, of at most :data:`MAX_DIGITS` digits."""
    s = str(text).strip()
    if len(s.lstrip("+-")) > MAX_DIGITS:
        raise error(f"{where}: integer of {len(s.lstrip('+-'))} digits (at most {MAX_DIGITS})")
    try:
        return int(s)
    except ValueError:
        raise error(f"{where}: not an integer: {s[:20]!r}") from None


def parse_json(text, where="JSON", error=ModelFormatError):
    """Parse JSON text or bytes; ``error`` (a PdeFaceError subclass) says what is wrong, where."""
    try:
        return json.loads(text, parse_int=_json_int)
    except json.JSONDecodeError as exc:
        raise error(f"{where}: not valid JSON ({exc.msg}, line {exc.lineno})") from None
    except UnicodeDecodeError:
        raise error(f"{where}: not UTF-8 text") from None
    except RecursionError:
        raise error(f"{where}: JSON nested too deeply") from None
    except ValueError as exc:  # an integer of thousands of digits
        raise error(f"{where}: {str(exc)[:80]}") from None


def _json_int(text: str) -> int:
    """A JSON integer; one of more than :data:`MAX_DIGITS` digits is refused."""
    if len(text.lstrip("-")) > MAX_DIGITS:
        raise ValueError(f"integer of {len(text.lstrip('-'))} digits")
    return int(text)


def load_json(path, error=ModelFormatError):
    """Parse a JSON file (at most ``MAX_BYTES["json"]``); ``error`` names the file and line of a problem."""
    return parse_json(read_bytes(path, error, "json"), str(path), error)


def check_archive(data: bytes, where, what="pdeface", error=ModelFormatError, kind="archive") -> None:
    """Refuse a zip archive (``.npz``, ``what`` names its kind) whose members claim more than
    ``MAX_BYTES[kind]`` inflated (before inflating any), or that is no zip archive."""
    import io
    import zipfile

    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            total = sum(info.file_size for info in zf.infolist())
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
        raise error(f"{where}: not a {what} file ({str(exc)[:80]})") from None
    if total > MAX_BYTES[kind]:
        raise error(f"{where}: its arrays claim {total / 2**20:.0f} MiB; a {what} file is far smaller "
                    f"(limit {MAX_BYTES[kind] >> 20} MiB)")


def load_npz(path, fmt: str, what: str, kind="archive") -> dict:
    """The arrays of a pdeface ``.npz`` file whose ``format`` member is ``fmt`` (``what`` names the kind
    of file in the errors), read without pickles, its size and what it inflates to capped by ``MAX_BYTES[kind]``
    (:func:`check_archive`)."""
    import io

    import numpy as np

    if not os.path.exists(path):
        raise ModelFormatError(f"{path}: {what} file not found")
    data = read_bytes(path, ModelFormatError, kind)
    check_archive(data, path, what, kind=kind)
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as f:
            data = {k: f[k] for k in f.files}
    except Exception as exc:  # noqa: BLE001 - a damaged member raises zlib, zip, value or OS errors: all mean one thing
        raise ModelFormatError(f"{path}: not a {what} file ({type(exc).__name__}: {str(exc)[:80]})") from None
    if str(data.get("format", "")) != fmt:
        raise ModelFormatError(f"{path}: not a pdeface {what} file (format {fmt!r})")
    return data


@contextlib.contextmanager
def atomic_open(path, mode="w", **kwargs):
    """Write ``path`` through a temporary file beside it, renamed over it on success.

    On any failure (a full disk, an exception in the ``with`` block) the
    temporary file is removed and an existing ``path`` is left as it was. OS
    failures raise :class:`FileError` naming ``path``.
    """
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.", suffix=".part", dir=folder)
    except OSError as exc:
        raise FileError(f"{path}: cannot write ({exc.strerror})") from None
    try:
        with os.fdopen(fd, mode, **kwargs) as fh:
            yield fh
        os.chmod(tmp, _new_file_mode(path))  # mkstemp makes it private; a written file is not
        os.replace(tmp, path)
    except OSError as exc:
        _remove(tmp)
        raise FileError(f"{path}: cannot write ({exc.strerror or exc})") from None
    except BaseException:
        _remove(tmp)
        raise


def write_bytes(path, data: bytes) -> int:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_open`); returns its length."""
    with atomic_open(path, "wb") as fh:
        fh.write(data)
    return len(data)


def npz_bytes(arrays: dict, compress: bool = True) -> bytes:
    """The bytes of a NumPy ``.npz`` archive of ``arrays`` (``numpy.load`` reads it), the same bytes for the same
    arrays: unlike ``numpy.savez``, no member carries the time it was written (batch jobs compare outputs)."""
    buf = io.BytesIO()
    _write_npz(buf, arrays, compress)
    return buf.getvalue()


def write_npz(path, arrays: dict, compress: bool = True) -> int:
    """Write the bytes :func:`npz_bytes` gives to ``path`` atomically (see :func:`atomic_open`), member by member
    (no copy of the whole archive in memory: a head's keys are tens of MB).

    Parameters
    ----------
    path : str or Path
        The archive to write; an existing file there is replaced only once the new one is whole.
    arrays : dict
        Member name (without ``.npy``) to array.
    compress : bool
        Deflate the members (as ``numpy.savez_compressed``) or store them.

    Returns
    -------
    int
        The file's length in bytes.
    """
    with atomic_open(path, "wb") as fh:
        _write_npz(fh, arrays, compress)
        return fh.tell()


def stored_npz_bytes(arrays: dict) -> int:
    """At least the length of the file ``write_npz(path, arrays, compress=False)`` writes: the arrays' bytes and a
    KiB a member for its headers (zip and ``.npy``: about 270 bytes), known before writing it."""
    import numpy as np

    return sum(np.asanyarray(value).nbytes + 1024 for value in arrays.values())


def _write_npz(fh, arrays, compress):
    import numpy as np

    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(fh, "w", compression=method) as zf:
        for name, value in arrays.items():
            info = zipfile.ZipInfo(name + ".npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = method
            with zf.open(info, "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)


def check_output(output, *inputs) -> None:
    """Refuse an output path that is one of the command's input files (it would be lost)."""
    for source in inputs:
        if source and os.path.exists(source) and os.path.exists(output) and os.path.samefile(source, output):
            raise FileError(f"{output}: is also an input of this command ({source}); write to another file")


def _new_file_mode(path) -> int:
    try:
        return os.stat(path).st_mode & 0o777  # replacing a file keeps its permissions
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def _remove(path):
    with contextlib.suppress(OSError):
        os.remove(path)
