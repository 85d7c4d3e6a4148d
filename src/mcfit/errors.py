"""Expected failures a person can fix, each with its exit code.

The command line catches only :class:`McfitError` and prints its message on one line;
anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import re
import unicodedata

__all__ = ["McfitError", "InputError", "RecordError", "TooFewTurningPoints", "FitError",
           "UsageError", "OutputError", "ClosedOutputError", "escape_controls", "printable"]

# Longest message shown on a terminal; the middle of a longer one is cut, so that both the
# cause (at the start) and the fix (at the end) stay.
MESSAGE_LIMIT = 1000


class McfitError(Exception):
    """Base of every expected failure: the message says what, where and how to fix.

    ``option`` names the parameter at fault (``"model"``, ``"signal_col"``), so that an
    interface can point at its own spelling of it.
    """

    exit_code = 1

    def __init__(self, message: str = "", *, option: str | None = None):
        super().__init__(message)
        self.option = option


class InputError(McfitError):
    """A file cannot be read: missing, unreadable, wrong format, bad columns."""


class RecordError(McfitError):
    """A record was read but holds no usable decay (too few turning points, beating...)."""


class TooFewTurningPoints(RecordError):
    """Fewer turning points than a fit of the averaged law needs."""


class FitError(McfitError):
    """A fit could not be made from usable turning points."""


class UsageError(McfitError):
    """Options that contradict each other or name something that does not exist."""

    exit_code = 2


class OutputError(McfitError):
    """Results cannot be written: a full disk, a file-size limit, a read-only target."""


class ClosedOutputError(OutputError):
    """The reader of the output went away (``mcfit ... | head -1``); not worth a message."""


# Controls (C0, DEL, C1) and the bidirectional overrides that reorder what a terminal shows.
_BIDI_CONTROLS = frozenset("\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")
_RUN = re.compile(r"(\\x[0-9a-f]{2}|\\u[0-9a-f]{4})\1{3,}")


def _escape(character: str) -> str:
    if unicodedata.category(character) == "Cc" or character in _BIDI_CONTROLS:
        code = ord(character)
        return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"
    return character


def escape_controls(text: str) -> str:
    """``text`` with its control characters escaped and runs of one counted (see
    :func:`printable`); spacing and length are kept."""
    text = "".join(_escape(character) for character in text)
    return _RUN.sub(lambda run: f"{run.group(1)}*{len(run.group(0)) // len(run.group(1))}",
                    text)


def printable(message: str, limit: int = MESSAGE_LIMIT) -> str:
    """``message`` safe to show on a terminal, on one line of at most about ``limit`` characters.

    Runs of whitespace become one space; control characters (which could move the cursor,
    change colours or ring the bell) are shown escaped, ``\\x1b``, and a run of one of them
    is shown once with its count, ``\\x00*3000``. A message still longer than ``limit`` loses
    its middle.
    """
    text = escape_controls(" ".join(str(message).split()))
    if len(text) > limit:
        head = (2 * limit) // 3
        text = text[:head] + " ... " + text[-(limit - head - 5):]
    return text
