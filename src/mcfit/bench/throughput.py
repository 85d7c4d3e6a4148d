"""The throughput section of ``mcfit bench``: every target of issue 17 against its measured
figure, then the measurements behind them.

- **Per record, in memory, one core:** the stages of a record of 10^4 samples
  (:mod:`mcfit.bench.stages`, in a child process with one BLAS thread), CPU time.
- **``mcfit DIR --format csv --jobs N``:** the real command on CSV files in a temporary
  directory, as a child process; its start-up is subtracted by timing the same command on
  one file: records/s = (files - 1) / (time(files) - time(one file)), in CPU seconds at
  ``--jobs 1`` and in wall seconds for the ``--jobs 2`` ratio. With the default
  ``--method auto`` and with ``--method turning-points``, since auto sends some records to
  the far slower waveform fit.
- **Start-up:** a one-record run against the import floor of its dependencies, and
  ``mcfit --help`` against ``import click``, the fastest of a few runs.
- **10^7 samples:** time and peak resident memory of ``mcfit FILE`` on a CSV of 10^7
  rows, against the file's size (only with ``config.big_samples``; the quick grid skips it).

The commands compared in a ratio run in turn (:func:`mcfit.bench.timing.fastest_in_turn`):
a shared machine's speed drifts by several per cent within minutes, which would otherwise
move a ratio by as much. Figures of one process are CPU time where the platform reports a
child's (wall time otherwise): on a shared machine wall time waits for other users. Every
child process finds mcfit compiled to bytecode, as an installed package has it
(:func:`mcfit.bench.timing.bytecode_environment`). Nothing here asserts a time; a target
not met is printed as NOT MET.
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
from dataclasses import dataclass

from mcfit.bench.config import QUICK, THROUGHPUT_SCENE, BenchConfig
from mcfit.bench.records import write_large_csv, write_throughput_files
from mcfit.bench.timing import (ONE_THREAD, ChildRun, bytecode_environment,
                                child_environment, fastest_child, fastest_in_turn,
                                mcfit_command, peak_memory_mib)

__all__ = ["Target", "load_lines", "CommandRate", "Throughput", "run_throughput", "format_throughput",
           "ISSUE_FILES"]

ISSUE_FILES = 200  # files of the batch target in issue 17
IMPORT_FLOOR = "import numpy, scipy, lmfit, pandas, click"
# About 29 bytes a row; room is checked before the large CSV is written.
_LARGE_ROW_BYTES = 30
METHODS = ("turning-points", "auto")


@dataclass(frozen=True)
class Target:
    """One target: what, the measured figure as printed, the target as printed, and
    whether it is met (None when not measured)."""

    label: str
    measured: str
    target: str
    met: bool | None

    def line(self) -> str:
        """The target as a line of a section's table of targets."""
        verdict = {True: "met", False: "NOT MET", None: "-"}[self.met]
        return f"  {self.label:<52}{self.measured:>12}   target {self.target:<12}{verdict}"


def load_lines(load) -> list[str]:
    """The line saying how busy the machine was at the start (none if unknown)."""
    if load is None:
        return []
    return [f"  (load average {load[0]:.1f} at the start on {os.cpu_count()} CPUs)"]


@dataclass(frozen=True)
class CommandRate:
    """``mcfit DIR --format csv --jobs N [--method M]`` on ``files`` files: the whole run
    and a one-file run (:class:`mcfit.bench.timing.ChildRun`), records fitted and how many
    by the waveform fit (None if the command failed)."""

    method: str
    jobs: int
    files: int
    whole: ChildRun
    one_file: ChildRun
    fitted: int | None
    waveform: int | None

    @property
    def rate(self) -> float:
        """Records per second of wall time after start-up: (files - 1) / (wall of the
        whole run - wall of the one-file run)."""
        return self._rate(self.whole.wall, self.one_file.wall)

    @property
    def cpu_rate(self) -> float:
        """Records per CPU second after start-up (every process of the run), or NaN
        where the platform does not report a child's CPU time."""
        if self.whole.cpu is None or self.one_file.cpu is None:
            return math.nan
        return self._rate(self.whole.cpu, self.one_file.cpu)

    def _rate(self, whole, one):
        spent = whole - one
        return (self.files - 1) / spent if spent > 0 and self.fitted is not None else math.nan


@dataclass(frozen=True)
class Throughput:
    """Everything the section measured.

    ``stages`` maps a record length to CPU seconds per record of "read", "turning" and
    "fit"; ``auto`` lists (record index, method chosen, CPU seconds of the choice);
    ``commands`` the :class:`CommandRate` of each method and jobs; ``startup`` a command
    label to a :class:`mcfit.bench.timing.ChildRun`; ``large`` the 10^7-sample run as
    (samples, file MiB, ChildRun, method chosen), or a string saying why it was not run;
    ``crests`` the mean turning points of the fitted records; memory in MiB.
    """

    config: BenchConfig
    stages: dict
    records: int
    fitted: int
    crests: float
    auto: list
    commands: list
    startup: dict
    large: tuple | str
    peak_self: float | None
    load: tuple | None = None


def run_throughput(config: BenchConfig = QUICK, progress=None) -> Throughput:
    """Measure every figure of issue 17's targets (see the module's docstring)."""
    say = progress or (lambda message: None)
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    with tempfile.TemporaryDirectory(prefix="mcfit-bench-") as directory:
        files = os.path.join(directory, "records")
        one = os.path.join(directory, "one")
        write_throughput_files(config, files, config.batch_files)
        write_throughput_files(config, one, 1)
        env = bytecode_environment(os.path.join(directory, "bytecode"), warm_up=(
            _command(one, os.path.join(directory, "warm-up.csv"), "auto", 1),
            [sys.executable, "-c", IMPORT_FLOOR]))
        say(f"throughput: stages of {config.batch_records} records in memory, one core")
        stages = _stages(config, env)
        commands = []
        for method in config.batch_methods:
            say(f"throughput: mcfit on {config.batch_files} CSV files, --method {method}, "
                "--jobs 1 and 2")
            commands += _command_rates(config, directory, method, env)
        say("throughput: start-up times")
        startup = _startup(config, os.path.join(one, "record0000.csv"), env)
        large = ("not run in the quick grid (a CSV of about 290 MB, a minute or more): "
                 "run `mcfit bench --full --section throughput`")
        if config.big_samples:
            say(f"throughput: mcfit on a CSV of {config.big_samples:.0e} samples")
            large = _large_run(config.big_samples, directory, env)
    return Throughput(config, {int(k): v for k, v in stages["stages"].items()},
                      stages["records"], stages["fitted"], stages["crests"], stages["auto"],
                      commands, startup, large, peak_memory_mib(), load)


def _stages(config, env):
    """:func:`mcfit.bench.stages.measure_stages` in a child process with one BLAS thread
    (and ``env``)."""
    spec = {"config": {"seed": config.seed, "batch_records": config.batch_records,
                       "batch_samples": config.batch_samples},
            "lengths": [config.batch_samples // 10, config.batch_samples]}
    code = "from mcfit.bench.stages import main; main()"
    done = subprocess.run([sys.executable, "-c", code, json.dumps(spec)], capture_output=True,
                          text=True, env=child_environment({**env, **ONE_THREAD}),
                          check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the stage measurement failed:\n{done.stderr}")
    return json.loads(done.stdout)


def _command(files_dir, output, method, jobs):
    command = [*mcfit_command(), files_dir, "--format", "csv", "-o", output, "--jobs",
               str(jobs)]
    return command if method == "auto" else [*command, "--method", method]


def _command_rates(config, directory, method, env) -> list:
    """The :class:`CommandRate` of ``method`` at ``--jobs`` 1 and 2: the four commands
    (every file and one file, at each) run in turn, so that the machine's drift slows
    them alike."""
    records, one = (os.path.join(directory, name) for name in ("records", "one"))
    outputs = {jobs: os.path.join(directory, f"results-{jobs}.csv") for jobs in (1, 2)}
    single_output = os.path.join(directory, "one-result.csv")
    commands = [(_command(folder, output, method, jobs), env) for jobs in (1, 2)
                for folder, output in ((records, outputs[jobs]), (one, single_output))]
    runs = fastest_in_turn(commands, config.batch_runs, by="wall")
    rates = []
    for jobs, whole, single in ((1, *runs[:2]), (2, *runs[2:])):
        fitted, waveform = _outcome(outputs[jobs]) if whole.returncode == 0 else (None, None)
        rates.append(CommandRate(method, jobs, config.batch_files, whole, single, fitted,
                                 waveform))
    return rates


def _outcome(path):
    """(records fitted, of which by the waveform fit) from a results CSV."""
    with open(path, encoding="utf-8", newline="") as handle:
        rows = list(csv.DictReader(handle))
    ok = [row for row in rows if row["status"] == "ok"]
    return len(ok), sum(row.get("method") == "waveform" for row in ok)


def _startup(config, record_path, env):
    """The start-up commands, each the fastest of ``config.startup_runs``, run in turn so
    that each ratio compares runs made at the same time."""
    python, mcfit = sys.executable, mcfit_command()
    commands = {
        f'python -c "{IMPORT_FLOOR}"': ([python, "-c", IMPORT_FLOOR], {**env, **ONE_THREAD}),
        f"mcfit {os.path.basename(record_path)} (one record of {config.batch_samples} samples)":
            ([*mcfit, record_path], env),
        'python -c "import click"': ([python, "-c", "import click"], env),
        "mcfit --help": ([*mcfit, "--help"], env),
    }
    return dict(zip(commands, fastest_in_turn(list(commands.values()), config.startup_runs)))


def _large_run(samples, directory, env):
    """``mcfit FILE --format csv`` on a CSV of ``samples`` rows: (samples, file MiB,
    ChildRun, method chosen); a string when the disk has no room for the file."""
    needed = 2 * _LARGE_ROW_BYTES * samples
    if shutil.disk_usage(directory).free < needed:
        return f"not run: {needed / 1e6:.0f} MB of free disk needed in {directory}"
    path = os.path.join(directory, "large.csv")
    write_large_csv(path, samples)
    size = os.path.getsize(path) / 2**20
    output = os.path.join(directory, "large-result.csv")
    run = fastest_child([*mcfit_command(), path, "--format", "csv", "-o", output], 1, env=env)
    method = None
    if run.returncode == 0:
        with open(output, encoding="utf-8", newline="") as handle:
            method = next(csv.DictReader(handle)).get("method")
    os.remove(path)
    return samples, size, run, method


# --------------------------------------------------------------------------- report


def targets(result: Throughput) -> list:
    """Issue 17's targets, each with its measured figure."""
    turning, fitting = (result.stages[result.config.batch_samples][k] for k in ("turning", "fit"))
    both, choice = turning + fitting, _mean_choice(result.auto)
    rows = [Target("turning points + fit per record", f"{1e3 * both:.1f} ms", "<= 20 ms",
                   both <= 0.020),
            Target("  the same with --method auto's choice (mean)",
                   f"{1e3 * (both + choice):.1f} ms", "<= 20 ms", both + choice <= 0.020)]
    commands = {(c.method, c.jobs): c for c in result.commands}
    for method in METHODS:
        label = f"mcfit DIR --jobs 1, {_method_label(method)}"
        if (method, 1) not in commands:
            rows.append(Target(label, "not run", ">= 50 rec/s", None))
            continue
        one = commands[(method, 1)]
        rate = one.cpu_rate if not math.isnan(one.cpu_rate) else one.rate
        rows.append(Target(label, _figure(rate, ".1f", " rec/s"), ">= 50 rec/s",
                           _at_least(rate, 50)))
    for method in METHODS:
        label = f"--jobs 2 / --jobs 1 (wall), {_method_label(method)}"
        if (method, 1) not in commands:
            rows.append(Target(label, "not run", ">= 1.8x", None))
            continue
        ratio = commands[(method, 2)].rate / commands[(method, 1)].rate
        rows.append(Target(label, _figure(ratio, ".2f", "x"), ">= 1.8x", _at_least(ratio, 1.8)))
    floor, one_record, click_only, help_run = (_seconds(r) for r in result.startup.values())
    rows.append(Target("one-record run / import floor", f"{one_record / floor:.2f}x",
                       "<= 1.15x", one_record / floor <= 1.15))
    rows.append(Target("mcfit --help / import click", f"{help_run / click_only:.2f}x",
                       "<= 2x", help_run / click_only <= 2.0))
    return rows + _large_targets(result)


def _method_label(method):
    return "--method auto (default)" if method == "auto" else f"--method {method}"


def _large_targets(result):
    wall, memory = "10^7 samples: time", "10^7 samples: peak memory / file size"
    if isinstance(result.large, str):
        return [Target(wall, "not run", "< 10 s", None), Target(memory, "not run", "< 3x", None)]
    _, size, run, _ = result.large
    seconds = _seconds(run)
    rows = [Target(wall, f"{seconds:.1f} s", "< 10 s", seconds < 10)]
    if run.peak_mib is None:
        return rows + [Target(memory, "unavailable", "< 3x", None)]
    return rows + [Target(memory, f"{run.peak_mib / size:.3f}x", "< 3x", run.peak_mib / size < 3)]


def _figure(value, spec, unit):
    """A measured figure as printed; n/a where start-up noise exceeded the work timed."""
    return "n/a" if math.isnan(value) else f"{format(value, spec)}{unit}"


def _at_least(value, bound):
    return None if math.isnan(value) else value >= bound


def _seconds(run):
    """CPU seconds of a child run where reported, else its wall seconds."""
    return run.cpu if run.cpu is not None else run.wall


def _mean_choice(auto):
    return sum(seconds for _, _, seconds in auto) / len(auto) if auto else math.nan


def format_throughput(result: Throughput) -> str:
    """The targets, one line each, then the measurements behind them."""
    config = result.config
    lines = [f"Throughput: issue 17's targets on records of {config.batch_samples} samples, "
             f"{result.crests:.0f} crests on average",
             f"  ({THROUGHPUT_SCENE.name}: {THROUGHPUT_SCENE.describe()}; SNR 1e3)"]
    lines += [row.line() for row in targets(result)]
    lines += _notes(result)
    lines.append("  (one process: CPU time where the platform reports it, as wall time on a "
                 "shared machine waits")
    lines.append("  for other users; --jobs 2 ratios: wall time; the wall times are in the "
                 "tables below)")
    lines += load_lines(result.load)
    lines += ["", *_stage_lines(result), "", *_auto_lines(result), "",
              *_command_lines(result), "", *_startup_lines(result), "", *_large_lines(result),
              "", _memory_line(result)]
    return "\n".join(lines)


def _notes(result):
    notes = []
    if result.config.batch_files < ISSUE_FILES:
        notes.append(f"  (quick run: mcfit DIR on {result.config.batch_files} files, not the "
                     f"{ISSUE_FILES} of the target; --full runs {ISSUE_FILES})")
    if isinstance(result.large, str):
        notes.append(f"  (10^7 samples {result.large})")
    return notes


def _stage_lines(result):
    lines = [f"  per record in memory, one core (one BLAS thread), CPU time, best of 3 passes "
             f"over {result.records} records read from CSV:",
             f"  {'samples':>10}{'read CSV (ms)':>15}{'turning points (ms)':>21}{'fit (ms)':>10}"
             f"{'TP + fit (ms)':>15}{'records/s':>11}"]
    for samples, stage in result.stages.items():
        both = stage["turning"] + stage["fit"]
        lines.append(f"  {samples:>10d}{1e3 * stage['read']:>15.1f}"
                     f"{1e3 * stage['turning']:>21.1f}{1e3 * stage['fit']:>10.1f}"
                     f"{1e3 * both:>15.1f}{1.0 / both:>11.1f}")
    return lines


def _auto_lines(result):
    """Where --method auto sent the in-memory records of 10^4 samples."""
    kept = [choice for choice in result.auto if choice[1] == "turning-points"]
    waveform = [choice for choice in result.auto if choice[1] == "waveform"]
    samples = result.config.batch_samples
    lines = [f"  --method auto on the {result.fitted} fitted records of {samples} samples (of "
             f"{result.records}): {len(kept)} kept the turning-point fit"]
    if kept:
        lines[-1] += f" (the choice costs {1e3 * _mean_choice(kept):.1f} ms a record)"
    if waveform:
        which = ", ".join(str(i) for i, _, _ in waveform)
        lines.append(f"  {len(waveform)} went to the waveform fit (records {which}; "
                     f"{_mean_choice(waveform):.1f} s CPU each)")
    else:
        lines.append("  none went to the waveform fit")
    others = [m for _, m, _ in result.auto if m not in ("turning-points", "waveform")]
    if others:
        lines.append(f"  {len(others)} ended otherwise ({', '.join(sorted(set(others)))})")
    return lines


def _command_lines(result):
    runs = result.config.batch_runs
    lines = [f"  mcfit DIR --format csv -o FILE as a child process (fastest of {runs} "
             f"run{'s' * (runs > 1)}); records/s after start-up, removed by a one-file run:",
             f"  {'method':<16}{'jobs':>5}{'files':>7}{'wall (s)':>10}{'one file':>10}"
             f"{'rec/s':>8}{'CPU (s)':>9}{'one file':>10}{'rec/CPU s':>11}{'fitted':>9}"
             f"{'waveform':>10}"]
    for c in result.commands:
        fitted = "failed" if c.fitted is None else f"{c.fitted}/{c.files}"
        waveform = "-" if c.waveform is None else str(c.waveform)
        cpu = [_number(run.cpu, ".2f") for run in (c.whole, c.one_file)]
        lines.append(f"  {c.method:<16}{c.jobs:>5d}{c.files:>7d}{c.whole.wall:>10.2f}"
                     f"{c.one_file.wall:>10.2f}{_figure(c.rate, '.1f', ''):>8}{cpu[0]:>9}"
                     f"{cpu[1]:>10}{_figure(c.cpu_rate, '.1f', ''):>11}{fitted:>9}"
                     f"{waveform:>10}")
    lines.append("  (CPU time counts every process of the run, so at --jobs 2 it is not the "
                 "rate; n/a: the whole run")
    lines.append("  took no longer than the one-file run, the work drowned in start-up noise)")
    return lines


def _number(value, spec):
    return "-" if value is None else format(value, spec)


def _startup_lines(result):
    lines = [f"  start-up, fastest of {result.config.startup_runs} runs as child processes "
             "(the import floor with one BLAS thread):",
             f"  {'command':<66}{'CPU (ms)':>10}{'wall (ms)':>11}"]
    for label, run in result.startup.items():
        cpu = "-" if run.cpu is None else f"{1e3 * run.cpu:.0f}"
        lines.append(f"  {label:<66}{cpu:>10}{1e3 * run.wall:>11.0f}")
    lines.append("  ratios of CPU time where the platform reports it, of wall time otherwise")
    return lines


def _large_lines(result):
    if isinstance(result.large, str):
        return [f"  10^7 samples: {result.large}"]
    samples, size, run, method = result.large
    memory = "unavailable" if run.peak_mib is None else f"{run.peak_mib:.0f} MiB"
    status = "" if run.returncode == 0 else f", exit code {run.returncode}"
    return [f"  mcfit FILE --format csv on {samples} samples ({size:.0f} MiB CSV): wall "
            f"{run.wall:.1f} s, CPU {_seconds(run):.1f} s, peak resident memory {memory}, "
            f"method {method}{status}"]


def _memory_line(result):
    if result.peak_self is None:
        return "  peak resident memory: unavailable on this platform"
    return (f"  peak resident memory (ru_maxrss): this process {result.peak_self:.0f} MiB; "
            "child processes above")
