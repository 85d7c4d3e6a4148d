"""Writing output files whole or not at all (shared by the command line and the plots)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["temporary_beside", "replace_atomically"]


def temporary_beside(path) -> str:
    """An empty temporary file in the directory of ``path`` (same file system)."""
    path = Path(path)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                         suffix=".tmp")
    os.close(handle)
    return temporary


def replace_atomically(temporary, path) -> None:
    """Move a finished temporary file onto ``path``, keeping the mode of a file it replaces
    (a private results file stays private) or giving a new one the usual mode."""
    try:
        mode = os.stat(path).st_mode & 0o777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask
    os.chmod(temporary, mode)
    os.replace(temporary, path)
