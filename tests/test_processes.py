"""Worker processes of a batch (issue 27): they die with their parent, there are no more of
them than CPUs, and a stop signal that arrives while one starts still ends it.

Waits are bounded (``TIMEOUT``); nothing is timed.
"""

from __future__ import annotations

import multiprocessing
import os
import select
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit import batch, decay
from mcfit.cli import cli
from process_tools import children

TIMEOUT = 120  # seconds any one wait may take, however loaded the machine


def _record(path, *, b=0.02, duration=60.0, rate=50.0, seed=1):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    x = decay.amplitude(t, 1.0, 0.0, b, 0.0) * np.cos(2 * np.pi * t)
    x = x + rng.normal(0.0, 1e-3, t.size)
    path.write_text("t,x\n" + "".join(f"{ti!r},{xi!r}\n"
                                      for ti, xi in zip(t.tolist(), x.tolist())))
    return path


def _gone(pid):
    """Whether ``pid`` has ended (a zombie has: only its exit status is left)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] in "ZX"
    except OSError:
        return True


def _wait_until(condition, what):
    deadline = time.monotonic() + TIMEOUT
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


needs_proc = pytest.mark.skipif(
    not Path(f"/proc/{os.getpid()}/task/{os.getpid()}/children").exists(),
    reason="needs /proc/PID/task/TID/children to find the worker processes")


@needs_proc
@pytest.mark.slow
def test_workers_die_with_a_parent_killed_outright(tmp_path):
    """SIGKILL of mcfit while both workers are in the middle of a long bootstrap (seconds
    of work each): they end before finishing it, so no figure is ever drawn."""
    files = [_record(tmp_path / f"run{i}.csv", seed=i) for i in range(4)]
    plots = tmp_path / "plots"
    process = subprocess.Popen([sys.executable, "-m", "mcfit", *map(str, files), "--jobs", "2",
                                "--bootstrap", "4000", "--format", "csv", "--plot-dir",
                                str(plots)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _wait_until(lambda: len(children(process.pid)) == 2 or process.poll() is not None,
                    "two workers")
        workers = children(process.pid)
        assert len(workers) == 2
        process.kill()
        process.wait(timeout=TIMEOUT)
        _wait_until(lambda: all(_gone(pid) for pid in workers), "the workers to end")
        assert list(plots.iterdir()) == []
    finally:
        process.kill()
        for pid in children(process.pid):
            os.kill(pid, signal.SIGKILL)


_WATCHED_CHILD = textwrap.dedent("""
    import os, sys, time
    from mcfit import batch

    batch._kill_with_parent = lambda: False  # as on a system without prctl
    pid = os.fork()
    if pid == 0:
        batch._end_with_parent(None)
        print("watching", flush=True)
        time.sleep(600)
        os._exit(0)
    print(pid, flush=True)
    time.sleep(600)
""")


def test_without_prctl_a_thread_ends_the_worker_with_its_parent():
    parent = subprocess.Popen([sys.executable, "-c", _WATCHED_CHILD], stdout=subprocess.PIPE,
                              text=True)
    try:
        child = int(parent.stdout.readline())
        assert select.select([parent.stdout], [], [], TIMEOUT)[0], "the child never started"
        assert parent.stdout.readline() == "watching\n"
        parent.kill()
        parent.wait(timeout=TIMEOUT)
        _wait_until(lambda: _gone(child), "the child to end")
    finally:
        parent.kill()
        parent.stdout.close()


def test_a_worker_asks_the_kernel_to_end_it_with_its_parent():
    if not sys.platform.startswith("linux"):
        pytest.skip("PR_SET_PDEATHSIG is Linux's")
    script = ("import ctypes, signal; from mcfit import batch; assert batch._kill_with_parent()"
              "; libc = ctypes.CDLL(None); n = ctypes.c_int(); "
              "libc.prctl(2, ctypes.byref(n), 0, 0, 0); print(n.value)")  # PR_GET_PDEATHSIG
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=TIMEOUT)
    assert result.stdout.strip() == str(int(signal.SIGKILL)), result.stderr


def test_workers_are_capped_at_the_cpus_available(tmp_path, monkeypatch):
    files = [_record(tmp_path / f"run{i}.csv", duration=10.0, seed=i) for i in range(4)]
    started = []
    real = batch._run_in_workers

    def counting(arguments, jobs):
        started.append(jobs)
        return real(arguments, jobs)

    monkeypatch.setattr(batch, "available_cpus", lambda: 2)
    monkeypatch.setattr(batch, "_run_in_workers", counting)
    result = CliRunner().invoke(cli, [*map(str, files), "--jobs", "1000", "--format", "csv"])
    assert result.exit_code == 0, result.output
    assert started == [2]
    assert result.stderr == ("Note: --jobs 1000 is more than the 2 CPUs available; running 2 "
                             "worker processes.\n")
    assert result.stdout.count("\n") == 5
    result = CliRunner().invoke(cli, [*map(str, files[:2]), "--jobs", "1000", "--format", "csv"])
    assert result.exit_code == 0 and result.stderr == ""  # two records: two workers at most
    assert started == [2, 2]


def test_available_cpus_follows_the_affinity_mask():
    if not hasattr(os, "sched_getaffinity"):
        pytest.skip("no affinity masks here")
    assert batch.available_cpus() == len(os.sched_getaffinity(0))


class _Stop(BaseException):
    pass


def test_a_stop_signal_while_a_worker_starts_ends_it(tmp_path, monkeypatch):
    """The signal, held back while the process starts, is delivered the moment it is let
    through; the new worker (which ignores SIGTERM) must be ended with the others, not
    waited for forever at exit."""
    files = [str(_record(tmp_path / f"run{i}.csv", duration=10.0, seed=i)) for i in range(3)]
    real_start = multiprocessing.Process.start
    started = []  # this test's workers only: another test's may share the process

    def start_then_stop(process):
        real_start(process)
        started.append(process)
        os.kill(os.getpid(), signal.SIGTERM)  # pending: blocked until the start is over

    def stop(signum, frame):
        raise _Stop

    monkeypatch.setattr(batch, "available_cpus", lambda: 2)
    monkeypatch.setattr(multiprocessing.Process, "start", start_then_stop)
    previous = signal.signal(signal.SIGTERM, stop)
    try:
        with pytest.raises(_Stop):
            list(batch.run_jobs(files, batch.FitOptions(), [None] * 3, jobs=2))
        left = [process for process in started if process.is_alive()]
    finally:
        signal.signal(signal.SIGTERM, previous)
        for process in started:
            process.kill()
            process.join(TIMEOUT)
    assert started and left == []
