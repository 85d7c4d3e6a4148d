"""Helpers for the tests that watch mcfit's worker processes."""

from pathlib import Path


def children(pid):
    """The process ids of ``pid``'s children (Linux /proc; none where it cannot be read)."""
    try:
        return [int(p) for task in Path(f"/proc/{pid}/task").iterdir()
                for p in (task / "children").read_text().split()]
    except OSError:
        return []
