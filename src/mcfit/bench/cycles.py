"""The cycles section of ``mcfit bench``: turning-point cost per cycle from 10^3 to 10^6
cycles (issue 28: linear in the record's length and cycle count).

- **Per cycle, in memory, one core:** :func:`mcfit.turning.find_turning_points` on a long
  ringdown, ``exp(-b*t)*cos(2*pi*t)`` plus white noise at 25 samples a cycle, decaying to
  exp(-2) of its start whatever its length (so Q grows with the cycles, as a MEMS
  resonator's), each length in its own child process with one BLAS thread: CPU time per
  cycle, the best of a few passes, and the peak of the memory allocated during one more
  call (``tracemalloc``, untimed). 10^3 to 10^5 cycles in the quick grid, 10^6 more with
  ``--full``.
- **10^7 samples of 10^6 cycles:** ``mcfit FILE --method turning-points`` on a CSV of
  ``config.big_samples`` rows at 10 samples a cycle, in the three-column form of the
  throughput section's large file: CPU time and peak resident memory against the file's
  size (only with ``config.big_samples``).

Nothing here asserts a time; a target not met is printed as NOT MET.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass

import numpy as np

from mcfit.bench.config import QUICK, BenchConfig
from mcfit.bench.throughput import Target, load_lines
from mcfit.bench.timing import ONE_THREAD, child_environment, mcfit_command, run_child

__all__ = ["CycleRow", "CycleCost", "QUICK_CYCLES", "FULL_CYCLES", "ringdown",
           "write_ringdown_csv", "run_cycles", "format_cycles", "main"]

QUICK_CYCLES = (1_000, 2_000, 10_000, 20_000, 100_000)
FULL_CYCLES = QUICK_CYCLES + (1_000_000,)
SAMPLES_PER_CYCLE = 25
# The large CSV: 10 samples a cycle (10^7 samples, 10^6 cycles).
FILE_SAMPLES_PER_CYCLE = 10
NOISE = 1e-3  # of the initial amplitude
OFFSET = 0.1
# Passes of the timed call, the best kept; one above this many cycles.
PASSES = 3
_MANY_CYCLES = 20_000
# About 31 bytes a row; room is checked before the large CSV is written.
_FILE_ROW_BYTES = 32
_CHUNK = 1_000_000


@dataclass(frozen=True)
class CycleRow:
    """One record length: cycles, samples, turning points found, CPU seconds of one call
    (best of ``passes``), and the peak MiB allocated during a call."""

    cycles: int
    samples: int
    crests: int
    seconds: float
    passes: int
    allocated: float

    @property
    def per_cycle(self) -> float:
        """CPU microseconds a cycle."""
        return 1e6 * self.seconds / self.cycles


@dataclass(frozen=True)
class CycleCost:
    """Everything the section measured: the rows, and the large file's run as (samples,
    cycles, file MiB, :class:`mcfit.bench.timing.ChildRun`, turning points used) or a
    string saying why it was not run."""

    config: BenchConfig
    rows: tuple
    large: tuple | str
    load: tuple | None = None


def ringdown(cycles, samples_per_cycle=SAMPLES_PER_CYCLE, seed=0):
    """(t, x): ``cycles`` periods of 1 s at ``samples_per_cycle``, amplitude 1 decaying as
    exp(-b*t) to exp(-2) at the end, offset :data:`OFFSET`, white noise :data:`NOISE`."""
    samples = int(round(cycles * samples_per_cycle))
    rng = np.random.default_rng(seed)
    t = np.arange(samples) / samples_per_cycle
    x = np.empty(samples)
    for lo in range(0, samples, _CHUNK):  # no record-sized temporaries
        part = t[lo:lo + _CHUNK]
        x[lo:lo + _CHUNK] = (OFFSET + np.exp(-2.0 * part / cycles) * np.cos(2 * np.pi * part)
                             + rng.normal(0.0, NOISE, part.size))
    return t, x


def write_ringdown_csv(path, cycles, samples_per_cycle=FILE_SAMPLES_PER_CYCLE, seed=0):
    """:func:`ringdown` as a three-column CSV (``time (s),position (m),velocity``, six
    decimals), the form of the throughput section's large file."""
    t, x = ringdown(cycles, samples_per_cycle, seed)
    with open(path, "w", encoding="utf-8") as handle:
        handle.write("time (s),position (m),velocity\n")
        for lo in range(0, t.size, _CHUNK):
            part = t[lo:lo + _CHUNK]
            v = -2 * np.pi * np.exp(-2.0 * part / cycles) * np.sin(2 * np.pi * part)
            np.savetxt(handle, np.column_stack([part, x[lo:lo + _CHUNK], v]), fmt="%.6f",
                       delimiter=",")


def run_cycles(config: BenchConfig = QUICK, progress=None) -> CycleCost:
    """Measure each record length in a child process, then the large file."""
    say = progress or (lambda message: None)
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    rows = []
    for cycles in (FULL_CYCLES if config.big_samples else QUICK_CYCLES):
        say(f"cycles: turning points of {cycles} cycles")
        rows.append(_measure_in_child(cycles, config.seed))
    large = ("not run in the quick grid (a CSV of about 320 MB, a minute or more): run "
             "`mcfit bench --full --section cycles`")
    if config.big_samples:
        say(f"cycles: mcfit on a CSV of {config.big_samples:.0e} samples")
        large = _large_run(config.big_samples, config.seed)
    return CycleCost(config, tuple(rows), large, load)


def _measure_in_child(cycles, seed):
    spec = {"cycles": cycles, "seed": seed}
    code = "from mcfit.bench.cycles import main; main()"
    done = subprocess.run([sys.executable, "-c", code, json.dumps(spec)], capture_output=True,
                          text=True, env=child_environment(ONE_THREAD), check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the turning points of {cycles} cycles failed:\n{done.stderr}")
    return CycleRow(**json.loads(done.stdout))


def main():
    """Child process: time the turning points of the record in ``sys.argv[1]`` (JSON:
    cycles, seed) and print a :class:`CycleRow` as JSON."""
    import tracemalloc

    from mcfit.turning import find_turning_points

    spec = json.loads(sys.argv[1])
    t, x = ringdown(spec["cycles"], seed=spec["seed"])
    find_turning_points(t[:10_000], x[:10_000])  # imports and caches warm
    passes = PASSES if spec["cycles"] <= _MANY_CYCLES else 1
    best = math.inf
    for _ in range(passes):
        clock = time.process_time()
        points = find_turning_points(t, x)
        best = min(best, time.process_time() - clock)
    del points
    tracemalloc.start()  # numpy reports its arrays to it
    points = find_turning_points(t, x)
    allocated = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    print(json.dumps({"cycles": spec["cycles"], "samples": int(t.size),
                      "crests": int(points.t.size), "seconds": best, "passes": passes,
                      "allocated": allocated}))


def _large_run(samples, seed):
    """``mcfit FILE --method turning-points --format csv`` on a CSV of ``samples`` rows at
    :data:`FILE_SAMPLES_PER_CYCLE`: (samples, cycles, file MiB, ChildRun, turning points),
    or a string when the disk has no room for the file."""
    cycles = samples // FILE_SAMPLES_PER_CYCLE
    with tempfile.TemporaryDirectory(prefix="mcfit-bench-cycles-") as directory:
        needed = 2 * _FILE_ROW_BYTES * samples
        if shutil.disk_usage(directory).free < needed:
            return f"not run: {needed / 1e6:.0f} MB of free disk needed in {directory}"
        path = os.path.join(directory, "ringdown.csv")
        write_ringdown_csv(path, cycles, seed=seed)
        output = os.path.join(directory, "ringdown-result.csv")
        run = run_child([*mcfit_command(), path, "--method", "turning-points", "--format",
                         "csv", "-o", output], env=ONE_THREAD)
        used = None
        if run.returncode == 0:
            with open(output, encoding="utf-8", newline="") as handle:
                used = int(next(csv.DictReader(handle))["turning_points"])
        return samples, cycles, os.path.getsize(path) / 2**20, run, used


# --------------------------------------------------------------------------- report


def _row(result, cycles):
    return next((row for row in result.rows if row.cycles == cycles), None)


def _growth(result, low, high):
    """Cost per cycle at ``high`` cycles over that at ``low`` (NaN if either is not run)."""
    a, b = _row(result, low), _row(result, high)
    return b.per_cycle / a.per_cycle if a and b else math.nan


def targets(result: CycleCost) -> list:
    """Issue 28's targets on the cycle count, each with its measured figure."""
    rows = []
    for low, high in ((2_000, 20_000), (20_000, 1_000_000)):
        label = f"turning points per cycle, {high:,} / {low:,} cycles"
        growth = _growth(result, low, high)
        if math.isnan(growth):
            rows.append(Target(label, "not run", "<= 2x", None))
        else:
            rows.append(Target(label, f"{growth:.2f}x", "<= 2x", growth <= 2.0))
    size = _power(result.config.big_samples or 10**7)
    cycle_count = _power((result.config.big_samples or 10**7) // FILE_SAMPLES_PER_CYCLE)
    time_label, memory_label = (f"{size} samples, {cycle_count} cycles: CPU time",
                                f"{size} samples, {cycle_count} cycles: peak memory / file size")
    if isinstance(result.large, str):
        return rows + [Target(time_label, "not run", "< 60 s", None),
                       Target(memory_label, "not run", "< 3x", None)]
    _, _, size, run, _ = result.large
    seconds = run.cpu if run.cpu is not None else run.wall
    ok = run.returncode == 0
    rows.append(Target(time_label, f"{seconds:.1f} s", "< 60 s", ok and seconds < 60))
    if run.peak_mib is None:
        return rows + [Target(memory_label, "unavailable", "< 3x", None)]
    ratio = run.peak_mib / size
    return rows + [Target(memory_label, f"{ratio:.2f}x", "< 3x", ok and ratio < 3)]


def _power(n):
    """``n`` as 10^k when it is a power of ten, else with thousands separators."""
    k = round(math.log10(n))
    return f"10^{k}" if 10**k == n else f"{n:,}"


def format_cycles(result: CycleCost) -> str:
    """The targets, one line each, then the table of cost per cycle and the large run."""
    lines = [f"Cycles: issue 28's targets on the cycle count (ringdown exp(-b*t)*cos(2*pi*t) "
             f"to exp(-2), {SAMPLES_PER_CYCLE} samples a cycle, noise {NOISE:g})"]
    lines += [row.line() for row in targets(result)]
    lines += load_lines(result.load)
    return "\n".join(lines + ["", *_table_lines(result), "", *_large_lines(result)])


def _table_lines(result):
    lines = ["  find_turning_points in a child process with one BLAS thread, CPU time (best of "
             f"{PASSES} passes up to",
             f"  {_MANY_CYCLES:,} cycles, one above); the peak allocated during one more call:",
             f"  {'cycles':>10}{'samples':>12}{'crests':>10}{'time (ms)':>12}"
             f"{'us/cycle':>10}{'x 2,000':>9}{'allocated (MiB)':>17}{'B/sample':>10}"]
    base = _row(result, 2_000)
    for row in result.rows:
        ratio = f"{row.per_cycle / base.per_cycle:.2f}" if base else "-"
        lines.append(f"  {row.cycles:>10,}{row.samples:>12,}{row.crests:>10,}"
                     f"{1e3 * row.seconds:>12.1f}{row.per_cycle:>10.2f}{ratio:>9}"
                     f"{row.allocated:>17.1f}{row.allocated * 2**20 / row.samples:>10.0f}")
    return lines


def _large_lines(result):
    if isinstance(result.large, str):
        return [f"  the large file: {result.large}"]
    samples, cycles, size, run, used = result.large
    memory = "unavailable" if run.peak_mib is None else f"{run.peak_mib:.0f} MiB"
    cpu = "-" if run.cpu is None else f"{run.cpu:.1f} s"
    status = (f"{used:,} turning points" if run.returncode == 0
              else f"exit code {run.returncode}")
    return [f"  mcfit FILE --method turning-points --format csv on {samples:,} samples, "
            f"{cycles:,} cycles ({size:.0f} MiB CSV):",
            f"  wall {run.wall:.1f} s, CPU {cpu}, peak resident memory {memory}; {status}"]
