"""Writing output files whole or not at all (shared by the command line and the plots).

A regular file (or a new name) is written through a temporary file beside it that replaces
it at the end, so a reader never sees half a file and a failed run keeps the old one.
Anything else, a device (``/dev/null``, a terminal) or a FIFO, is written in place: renaming
a file over it would replace the device node or the pipe the reader waits on.
"""

from __future__ import annotations

import errno
import os
import stat
import sys
import tempfile
from pathlib import Path

from mcfit.errors import ClosedOutputError, OutputError, escape_controls

__all__ = ["temporary_beside", "replace_atomically", "is_regular_or_new", "Output",
           "display_name", "describe_os_error", "RECORD_TYPES", "record_type",
           "record_extensions", "supported_types"]

# The records mcfit reads, by extension: the reader (mcfit.io.opening dispatches on it)
# and its extensions. Text is also read gzip-compressed (.csv.gz); a file named on the
# command line is read by its content whatever its extension, a directory yields the files
# with these extensions. Every list of supported types in a message comes from here.
RECORD_TYPES = (
    ("text", (".csv", ".tsv", ".txt", ".dat", ".lvm", ".log")),
    ("workbook", (".xlsx", ".xlsm", ".xls", ".ods")),
    ("audio", (".wav",)),
)
COMPRESSED_SUFFIX = ".gz"


def record_type(suffix):
    """The reader of a file extension (``".wav"`` -> ``"audio"``), or None."""
    suffix = suffix.lower()
    return next((kind for kind, suffixes in RECORD_TYPES if suffix in suffixes), None)


def record_extensions() -> tuple:
    """Every extension of a record file, the gzip-compressed text ones included."""
    plain = tuple(s for _, suffixes in RECORD_TYPES for s in suffixes)
    text = dict(RECORD_TYPES)["text"]
    return plain + tuple(s + COMPRESSED_SUFFIX for s in text)


def supported_types() -> str:
    """The supported types in words, for messages and help: ``.csv .tsv ... .wav, and
    .gz of the text ones``."""
    listed = " ".join(s for _, suffixes in RECORD_TYPES for s in suffixes)
    return f"{listed}, and {COMPRESSED_SUFFIX} of the text ones"

# The escapes a reader knows from Python's own strings; other controls are shown \xNN.
_NAMED_ESCAPES = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def display_name(path) -> str:
    """A file name as it can be shown and written in any output: the bytes of a name that
    is not UTF-8 as ``\\xe9``, a newline as ``\\n``, other control characters escaped.

    A name given on the command line keeps its undecodable bytes as lone surrogates
    (``os.fsdecode``); no text encoding can write those, so a result names such a file
    escaped. ``"-"`` stays as it is.
    """
    text = os.fsencode(os.fspath(path)).decode("utf-8", "backslashreplace")
    for character, escape in _NAMED_ESCAPES.items():
        text = text.replace(character, escape)
    return escape_controls(text)


def is_regular_or_new(path) -> bool:
    """Whether ``path`` (after symbolic links) is a regular file or does not exist yet.

    A path that cannot be looked at (below a file, in a closed folder) counts as new: the
    write that follows then fails with the reason.
    """
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return True


def temporary_beside(path) -> str:
    """An empty temporary file in the directory of ``path`` (same file system).

    A symbolic link is followed, so that the link is kept and its target replaced.
    """
    path = Path(os.path.realpath(path))
    prefix = f".{path.name}."
    if len(os.fsencode(prefix)) + _RANDOM_PART + len(".tmp") > _name_max(path.parent):
        prefix = ".mcfit-"  # a long legal name must not become too long a temporary one
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=prefix, suffix=".tmp")
    os.close(handle)
    return temporary


_RANDOM_PART = 8  # characters tempfile puts between the prefix and the suffix


def _name_max(directory) -> int:
    """The longest file name, in bytes, that ``directory``'s file system takes."""
    try:
        return os.pathconf(directory, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):
        return 255  # the usual limit; a missing directory fails in mkstemp with the reason


def describe_os_error(error: OSError) -> str:
    """The cause of a failed write and what to do about it, without the file's name:
    ``No such file or directory; check that the directory exists and is writable``."""
    return f"{error.strerror or error}; {_ADVICE.get(error.errno, 'write elsewhere')}"


def replace_atomically(temporary, path) -> None:
    """Move a finished temporary file onto ``path``, keeping the mode of a file it replaces
    (a private results file stays private) or giving a new one the usual mode.

    A ``path`` that is not a regular file (a device, a FIFO) receives the temporary file's
    bytes in place instead, and the temporary file is removed.
    """
    if not is_regular_or_new(path):
        try:
            with open(temporary, "rb") as source, open(path, "wb") as target:
                while block := source.read(1 << 20):
                    target.write(block)
        finally:
            os.unlink(temporary)
        return
    path = os.path.realpath(path)
    try:
        mode = os.stat(path).st_mode & 0o777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask
    os.chmod(temporary, mode)
    os.replace(temporary, path)


# What each write error means for the person running mcfit, and what to do about it.
_ADVICE = {
    errno.ENOSPC: "the disk is full; free some space or write elsewhere",
    errno.EDQUOT: "the disk quota is used up; free some space or write elsewhere",
    errno.EFBIG: "the file-size limit (ulimit -f) was reached; raise it or write elsewhere",
    errno.EROFS: "the file system is read-only; write elsewhere",
    errno.EACCES: "check its permissions, or write elsewhere",
    errno.EPERM: "check its permissions, or write elsewhere",
    errno.EIO: "the device reported an error; check it, or write elsewhere",
    errno.ENOENT: "check that the directory exists and is writable",
    errno.ENOTDIR: "check that the directory exists and is writable",
    errno.EBADF: "open it, or write to a file instead",
}


class Output:
    """A text output that is whole or absent: stdout (``-``), a file, a device or a FIFO.

    Write with :meth:`write`; end with :meth:`commit` (the file then holds everything
    written) or :meth:`discard` (a regular file is left as it was). Every ``OSError`` is
    raised as :class:`mcfit.errors.OutputError` naming the output, the cause and the fix,
    or as :class:`mcfit.errors.ClosedOutputError` when the reader has gone away.

    Parameters
    ----------
    path : str
        ``-`` for stdout, else the file to write.
    """

    def __init__(self, path: str):
        self.path = path
        self.name = "stdout" if path == "-" else path
        self.temporary = None
        self._existed = path != "-" and os.path.exists(path)
        try:
            if path == "-":
                if sys.stdout is None:  # started with stdout closed (>&-)
                    raise OSError(errno.EBADF, "it is closed")
                self.stream = sys.stdout
            elif not is_regular_or_new(path):
                self.stream = open(path, "w", newline="")
            else:
                # The directory's permissions would let the file be renamed over; its own
                # say that it is not to be changed (cp would refuse it too).
                if self._existed and not _may_write(path):
                    raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), path)
                self.temporary = temporary_beside(path)
                self.stream = open(self.temporary, "w", newline="")
        except OSError as error:
            self.discard()
            raise self._error(error) from None

    def write(self, text: str) -> None:
        """Write ``text`` and pass it on at once (a reader sees whole records as they come)."""
        try:
            self.stream.write(text)
            self.stream.flush()
        except OSError as error:
            raise self._error(error) from None

    def write_with(self, write) -> None:
        """Call ``write(stream)`` for output written in many small pieces (no flush each)."""
        try:
            write(self.stream)
        except OSError as error:
            raise self._error(error) from None

    def commit(self) -> None:
        """Make the output whole: flush stdout or the device, or move the file into place."""
        try:
            self.stream.flush()
            if self.temporary is not None:
                os.fsync(self.stream.fileno())
                self.stream.close()
                replace_atomically(self.temporary, self.path)
                self.temporary = None
            elif self.stream is not sys.stdout:
                self.stream.close()
        except OSError as error:
            failure = self._error(error)
            self.discard()
            raise failure from None

    def discard(self) -> None:
        """Close without completing: remove the temporary file, keep a file it would replace.

        After an error on stdout, stdout is pointed at /dev/null, so that the interpreter's
        last flush at exit does not fail again with a traceback.
        """
        stream = getattr(self, "stream", None)
        if stream is sys.stdout:
            _silence_stdout()
        elif stream is not None:
            try:
                stream.close()
            except OSError:
                pass  # what could not be written is thrown away
        if self.temporary is not None:
            Path(self.temporary).unlink(missing_ok=True)
            self.temporary = None

    def _error(self, error: OSError) -> OutputError:
        if error.errno == errno.EPIPE:
            return ClosedOutputError(f"the reader of {self.name} has gone away")
        kept = (f"; {self.path} was left as it was"
                if self._existed and self.temporary is not None else "")
        return OutputError(f"cannot write {self.name}: {describe_os_error(error)}{kept}.")


def _may_write(path) -> bool:
    effective = os.access in os.supports_effective_ids  # as the checks of open() are made
    return os.access(path, os.W_OK, effective_ids=effective)


def _silence_stdout() -> None:
    try:
        descriptor = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):
        return  # not a real file (a test's capture): nothing flushes it at exit
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, descriptor)
    finally:
        os.close(devnull)
