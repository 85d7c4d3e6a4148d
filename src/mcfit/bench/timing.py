"""Clocks of the bench: the fastest of repeated calls in this process, and the time and
peak memory of a command run as a child process. Portable: where the platform cannot
report a figure (memory on Windows), it is None and printed as unavailable."""

from __future__ import annotations

import datetime
import math
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["machine_summary", "fastest", "ChildRun", "run_child", "fastest_child",
           "fastest_in_turn", "mcfit_command", "peak_memory_mib", "bytecode_environment",
           "child_environment", "ONE_THREAD"]

# A cheap call is repeated until this much wall time has passed and its fastest run kept.
_TIMING_BUDGET = 0.05
_TIMING_MAX_RUNS = 20
# The environment of a process held to one core: BLAS threads would only spin beside it.
ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def machine_summary(config) -> str:
    """Date, machine, CPU, Python and library versions, and the grid, as a few lines."""
    import lmfit
    import scipy

    cpu = platform.processor() or "unknown"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as handle:
            cpu = next((line.split(":", 1)[1].strip() for line in handle
                        if line.startswith("model name")), cpu)
    except OSError:
        pass
    return (f"mcfit bench ({config.name}), {datetime.date.today().isoformat()}\n"
            f"machine: {platform.machine()}, {os.cpu_count()} CPUs ({cpu}), "
            f"{platform.system()} {platform.release()}\n"
            f"python {platform.python_version()}, numpy {np.__version__}, scipy "
            f"{scipy.__version__}, lmfit {lmfit.__version__}; seed {config.seed}")


def fastest(function, *args, **kwargs):
    """(smallest wall time in s, result) over repeated calls within a small time budget."""
    best, result, spent, runs = math.inf, None, 0.0, 0
    while runs == 0 or (spent < _TIMING_BUDGET and runs < _TIMING_MAX_RUNS):
        start = time.perf_counter()
        result = function(*args, **kwargs)
        elapsed = time.perf_counter() - start
        best, spent, runs = min(best, elapsed), spent + elapsed, runs + 1
    return best, result


@dataclass(frozen=True)
class ChildRun:
    """One child process: wall and CPU seconds (user + system, None where the platform
    does not report a child's CPU time), peak resident MiB (None likewise), exit code."""

    wall: float
    cpu: float | None
    peak_mib: float | None
    returncode: int


def run_child(command, env=None, stdout=subprocess.DEVNULL) -> ChildRun:
    """Run ``command`` to its end and measure it (``os.wait4`` where there is one, so that
    the figures are this child's alone). ``env`` is added to this process's environment;
    a variable set to None there is left out."""
    environment = None if env is None else child_environment(env)
    start = time.perf_counter()
    child = subprocess.Popen(command, stdout=stdout, stderr=subprocess.DEVNULL,
                             env=environment)
    if hasattr(os, "wait4"):
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - start
        child.returncode = os.waitstatus_to_exitcode(status)
        return ChildRun(wall, usage.ru_utime + usage.ru_stime, _rss_mib(usage.ru_maxrss),
                        child.returncode)
    before = os.times()
    child.wait()
    wall, after = time.perf_counter() - start, os.times()
    cpu = (after.children_user + after.children_system
           - before.children_user - before.children_system)
    return ChildRun(wall, cpu if cpu > 0 else None, None, child.returncode)


def fastest_child(command, runs, env=None, by="cpu") -> ChildRun:
    """The run of ``command`` (``runs`` times) with the smallest CPU time (``by="cpu"``,
    wall time where CPU time is not reported) or wall time (``by="wall"``): on a shared
    machine the least disturbed one. A failed run is returned at once."""
    return fastest_in_turn([(command, env)], runs, by)[0]


def fastest_in_turn(commands, runs, by="cpu") -> list:
    """:func:`fastest_child` of each (command, env) in ``commands``, the commands run one
    after the other ``runs`` times, so that a machine whose speed drifts (a shared one
    does, by several per cent within minutes) slows all of them alike and their ratios
    hold. A failed run is kept as its command's result."""
    best = [None] * len(commands)
    for _ in range(max(runs, 1)):
        for i, (command, env) in enumerate(commands):
            if best[i] is not None and best[i].returncode != 0:
                continue
            run = run_child(command, env)
            if best[i] is None or run.returncode != 0 or _key(run, by) < _key(best[i], by):
                best[i] = run
    return best


def _key(run, by):
    return run.cpu if by == "cpu" and run.cpu is not None else run.wall


def _rss_mib(maxrss):
    """ru_maxrss in MiB: kB on Linux, bytes on macOS."""
    return maxrss / 2**20 if sys.platform == "darwin" else maxrss / 1024


def peak_memory_mib():
    """Peak resident MiB of this process, or None where ``resource`` does not exist."""
    try:
        import resource  # POSIX only
    except ImportError:
        return None
    return _rss_mib(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)


def bytecode_environment(directory, warm_up=()) -> dict:
    """The environment of child processes that keep compiled bytecode in ``directory``
    (PYTHONPYCACHEPREFIX, PYTHONDONTWRITEBYTECODE left out), with mcfit's modules compiled
    there now, as an installed package has them from its install: a start-up time must not
    count compiling mcfit's source, which an editable install under PYTHONDONTWRITEBYTECODE
    does in every process. The prefix hides the libraries' own bytecode too: the commands
    ``warm_up`` are run once, untimed, to compile what they import."""
    import mcfit

    env = {"PYTHONPYCACHEPREFIX": str(directory), "PYTHONDONTWRITEBYTECODE": None}
    package = str(Path(mcfit.__file__).parent)
    for command in ([sys.executable, "-m", "compileall", "-q", package], *warm_up):
        subprocess.run(command, check=False, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, env=child_environment(env))
    return env


def child_environment(env):
    """This process's environment with ``env`` added, less its variables set to None."""
    return {name: value for name, value in {**os.environ, **env}.items() if value is not None}


def mcfit_command():
    """The installed ``mcfit`` script beside this Python, else ``python -m mcfit``."""
    folder = Path(sys.executable).parent
    for name in ("mcfit", "mcfit.exe"):
        if (folder / name).exists():
            return [str(folder / name)]
    return [sys.executable, "-m", "mcfit"]
