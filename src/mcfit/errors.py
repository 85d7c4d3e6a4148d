"""Expected failures a person can fix, each with its exit code.

The command line catches only :class:`McfitError` and prints its message on one line;
anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

__all__ = ["McfitError", "InputError", "RecordError", "FitError", "UsageError"]


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


class FitError(McfitError):
    """A fit could not be made from usable turning points."""


class UsageError(McfitError):
    """Options that contradict each other or name something that does not exist."""

    exit_code = 2
