"""Exceptions raised by pdeface.

Every error the package raises on purpose is a :class:`PdeFaceError`, so callers
(the CLI, the Blender add-on) can turn them into one clean message.
"""


class PdeFaceError(Exception):
    """Base class of every error pdeface raises on purpose."""


class MeshError(PdeFaceError, ValueError):
    """A mesh (or mesh file) is malformed or unusable."""


class LandmarkError(PdeFaceError, ValueError):
    """Landmarks are missing, malformed or inconsistent with the mesh."""


class LayoutError(PdeFaceError, ValueError):
    """A curve layout cannot be placed on the mesh."""


class ModelFormatError(PdeFaceError, ValueError):
    """A face model or descriptor file is malformed or of an unknown version."""


class FileError(PdeFaceError, OSError):
    """A file cannot be written (or would overwrite one of the command's own inputs)."""


def one_line(exc) -> str:
    """An error's message as the one line the CLI prints and the add-on reports (whatever text it quotes)."""
    return " ".join(str(exc).split())[:500]
