"""Opening a user's files with errors that name the file, and writing them atomically (the one way
pdeface does it)."""
from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
import zipfile

from ..errors import FileError, ModelFormatError


def open_file(path, mode="r", error=ModelFormatError, **kwargs):
    """``open(path, mode, **kwargs)``; a failure raises ``error`` (a PdeFaceError subclass) naming the file."""
    try:
        return open(path, mode, **kwargs)
    except OSError as exc:
        raise error(f"{path}: cannot open ({exc.strerror})") from None


def read_bytes(path, error=ModelFormatError) -> bytes:
    """A whole file's bytes (see :func:`open_file`)."""
    with open_file(path, "rb", error) as fh:
        return fh.read()


def read_lines(path, error=ModelFormatError) -> list:
    """A UTF-8 text file's lines (undecodable bytes replaced; see :func:`open_file`)."""
    with open_file(path, "r", error, encoding="utf-8", errors="replace") as fh:
        return fh.read().splitlines()


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
    """A JSON integer; one of more than 15 digits (no count, index or frame in pdeface's files) is refused."""
    if len(text.lstrip("-")) > 15:
        raise ValueError(f"integer of {len(text.lstrip('-'))} digits")
    return int(text)


def load_json(path, error=ModelFormatError):
    """Parse a JSON file; ``error`` names the file and line of a problem."""
    return parse_json(read_bytes(path, error), str(path), error)


def load_npz(path, fmt: str, what: str) -> dict:
    """The arrays of a pdeface ``.npz`` file whose ``format`` member is ``fmt`` (``what`` names the kind
    of file in the errors), read without pickles."""
    import numpy as np

    try:
        with np.load(path, allow_pickle=False) as f:
            data = {k: f[k] for k in f.files}
    except FileNotFoundError:
        raise ModelFormatError(f"{path}: {what} file not found") from None
    except (OSError, ValueError) as exc:
        raise ModelFormatError(f"{path}: not a {what} file ({exc})") from None
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
    import numpy as np

    buf = io.BytesIO()
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(buf, "w", compression=method) as zf:
        for name, value in arrays.items():
            info = zipfile.ZipInfo(name + ".npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = method
            with zf.open(info, "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, np.asanyarray(value), allow_pickle=False)
    return buf.getvalue()


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
