"""Helpers for the tests that run mcfit in other processes: its workers, and fresh
interpreters that show what an import or a call loads."""

import os
import signal
import subprocess
import sys
from pathlib import Path


def children(pid):
    """The process ids of ``pid``'s children (Linux /proc; none where it cannot be read)."""
    try:
        return [int(p) for task in Path(f"/proc/{pid}/task").iterdir()
                for p in (task / "children").read_text().split()]
    except OSError:
        return []


def with_stop_signals(disposition=signal.SIG_DFL):
    """A ``preexec_fn`` that starts a child with SIGINT, SIGTERM and SIGHUP at
    ``disposition``: a test run from a background job (a shell starts those with SIGINT
    ignored; ``nohup`` ignores SIGHUP) sends its signals to a child that would otherwise
    inherit them ignored."""
    def preexec():
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            signal.signal(signum, disposition)
    return preexec


def python_words(code, **environment):
    """What ``code`` prints in a fresh interpreter (with ``environment`` added), split
    into words; its exit status must be 0."""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            env={**os.environ, "PYTHONWARNINGS": "ignore", **environment},
                            timeout=600)
    assert result.returncode == 0, result.stderr
    return result.stdout.split()
