"""Running the fit over many files: one job per file, results in input order as they finish.

Each job reads, analyses and (optionally) plots one record and returns its results as
plain data (:meth:`mcfit.analysis.Analysis.to_dict`), small to send back from a worker
process; the command line alone formats them as text, CSV or JSON.
"""

from __future__ import annotations

import dataclasses
import importlib
import multiprocessing
import os
import signal
import stat
import sys
import time
from collections import deque
from dataclasses import dataclass
from multiprocessing.connection import wait
from pathlib import Path

from mcfit.errors import InputError, McfitError, UsageError
from mcfit.files import describe_os_error, display_name, record_extensions, supported_types

__all__ = ["FitOptions", "FileResult", "Inputs", "find_inputs", "expand_inputs",
           "run_jobs",
           "plot_path_for", "available_cpus"]

# What a directory's records are called (any file named on the command line is read by
# its content): text, gzip-compressed text, LabVIEW and logger files, spreadsheets, audio
# (mcfit.files.RECORD_TYPES).
RECORD_EXTENSIONS = record_extensions()

# Signals that stop a whole run. Workers ignore them: the parent keeps the finished records
# and then ends the workers itself (a terminal's Ctrl-C reaches every process of the group).
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


@dataclass(frozen=True)
class FitOptions:
    """Everything a job needs besides the file name (picklable for worker processes)."""

    time_col: str | int | None = None
    signal_col: str | int | None = None
    sheet: str | int | None = None
    rate: float | None = None
    kind: str | None = None
    domain: str | None = None
    criterion: str = "aicc"
    model: str | None = None
    bootstrap: int = 0
    seed: int | None = None
    method: str = "auto"
    output_format: str = "text"  # how the command line writes the results (not the jobs)
    pendulum: bool = False
    degrees: bool | None = None  # None: from the signal column's name
    turning_points_out: bool = False  # also give each record's turning points
    start: float | None = None  # window of the record to fit (time or cycle)
    end: float | None = None
    run: int | None = None  # of a file's runs side by side, the one to fit (None: all)
    angle_from: tuple | None = None  # (x, y) columns of a tracked pendulum bob
    unit: str | None = None  # the signal's unit for every output, in place of the header's
    title: str | None = None  # the figure's title (default: the file name)
    panels: tuple | None = None  # the figure's panels (default: mcfit.options.DEFAULT_PANELS)
    figsize: tuple | None = None  # the figure's (width, height) in inches
    dpi: int | None = None  # a PNG figure's dots per inch (default: mcfit.plots.DPI)


@dataclass(frozen=True)
class FileResult:
    """What one file produced: a result per record (one per run side by side, in file
    order), each a dict: ``analysis``, the record's :meth:`Analysis.to_dict` with its
    ``detail``; ``plot_error``, why its figure could not be written, or None;
    ``turning_points``, its :meth:`Analysis.turning_point_table` where asked for, else
    empty. ``source`` is the file's name as the results give it."""

    source: str
    records: tuple[dict, ...]

    @classmethod
    def failed(cls, source, message):
        from mcfit.analysis import failed_analysis

        analysis = failed_analysis(_display_name(source), message)
        return cls(_display_name(source), (_record_result(analysis),))


def _record_result(analysis, plot_error=None, turning_points=()) -> dict:
    return {"analysis": analysis.to_dict(detail=True), "plot_error": plot_error,
            "turning_points": list(turning_points)}


# The first line of each file mcfit writes: results as CSV, turning points as CSV, a text
# report, JSON Lines. A directory's file that starts so is mcfit's output, not a record
# (tests/test_folders.py holds these to mcfit.report's headers).
OUTPUT_SIGNATURES = ("source,status,model,", "source,t,amplitude,sigma,used,",
                     "mcfit report: ", '{"source": ')
_SIGNATURE_BYTES = 64
_LISTED = 5  # names given in a note before "and N more"


@dataclass(frozen=True)
class Inputs:
    """The files a batch fits, from the files and directories it was given.

    ``notes`` say what was left out and why (a subfolder, a broken link, mcfit's own
    output, a file named twice); ``problems`` are directories that could not be listed:
    the others are fitted and the batch counts each problem as a failure.
    """

    files: tuple[str, ...]
    notes: tuple[str, ...] = ()
    problems: tuple[str, ...] = ()


def find_inputs(arguments) -> Inputs:
    """The record files of ``arguments`` (files, ``-`` and directories), each once.

    A directory gives its record files (by extension), sorted, leaving out subfolders,
    anything that is not a regular file, and the files mcfit wrote (by their first line:
    :data:`OUTPUT_SIGNATURES`), each named in a note. Raises :class:`UsageError` for a
    directory with no record files, naming what it holds instead.
    """
    files, notes, problems = [], [], []
    for argument in arguments:
        if argument != "-" and os.path.isdir(argument):
            try:
                found, skipped = _directory_records(argument)
            except OSError as error:
                problems.append(f"cannot list directory {display_name(argument)}: "
                                f"{error.strerror or error}. Check its permissions, or name "
                                "the files instead.")
                continue
            if not found:
                held = f"; it holds {'; '.join(skipped)}" if skipped else ""
                raise UsageError(f"directory {display_name(argument)} holds no record files "
                                 f"({supported_types()}){held}; name the files "
                                 "instead.")
            notes.extend(f"{display_name(argument)}: left out {what}." for what in skipped)
            files.extend(found)
        else:
            files.append(argument)
    files, repeated = _once_each(files)
    return Inputs(tuple(files), tuple(notes + repeated), tuple(problems))


def expand_inputs(arguments) -> list[str]:
    """The record files of ``arguments`` (see :func:`find_inputs`), each once; raises
    :class:`InputError` for a directory that cannot be listed."""
    inputs = find_inputs(arguments)
    if inputs.problems:
        raise InputError(inputs.problems[0])
    return list(inputs.files)


def _directory_records(directory):
    """(record files, what was left out in words) of one directory; OSError if unlistable."""
    found, subfolders, special, own = [], [], [], []
    with os.scandir(directory) as entries:
        for entry in entries:
            path = str(Path(directory) / entry.name)
            if entry.is_dir():
                if not entry.name.startswith("."):
                    subfolders.append(path)
            elif not entry.is_file():
                if not entry.name.startswith("."):
                    special.append(f"{display_name(path)} ({_kind_of(path)})")
            elif entry.name.lower().endswith(RECORD_EXTENSIONS):
                (own if _written_by_mcfit(path) else found).append(path)
    skipped = []
    if subfolders:
        skipped.append(f"its subfolders {_listed(sorted(subfolders))} (name them to fit "
                       "their records)")
    if special:
        skipped.append(f"{_listed(sorted(special))}: not regular files")
    if own:
        skipped.append(f"{_listed(sorted(own))}: output of mcfit, not records")
    return sorted(found), skipped


def _kind_of(path) -> str:
    """What a directory entry that is neither a regular file nor a directory is."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "a broken symbolic link"
    except OSError as error:
        return f"not readable: {error.strerror or error}"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file"


def _written_by_mcfit(path) -> bool:
    """Whether the file starts as mcfit's outputs do (an unreadable one is left to the
    reader, which says why)."""
    try:
        with open(path, "rb") as file:
            head = file.read(_SIGNATURE_BYTES)
    except OSError:
        return False
    return head.decode("latin-1").startswith(OUTPUT_SIGNATURES)


def _listed(names) -> str:
    names = [display_name(name) for name in names]
    more = len(names) - _LISTED
    return ", ".join(names[:_LISTED]) + (f" and {more} more" if more > 0 else "")


def _once_each(files):
    """``files`` without the second naming of a file (``a.csv`` and ``./a.csv``, or a.csv
    and its directory), with a note for each left out."""
    kept, seen, notes = [], {}, []
    for file in files:
        key = _identity(file)
        if key in seen:
            again = ("named twice" if file == seen[key]
                     else f"{display_name(seen[key])}, named before")
            notes.append(f"{display_name(file)} is {again}; fitted once.")
            continue
        seen[key] = file
        kept.append(file)
    return kept, notes


def _identity(file):
    """What tells two names of one file apart from two files: device and inode, or the
    resolved path of a file that does not exist (its error is then given once)."""
    if file == "-":
        return "-"
    try:
        status = os.stat(file)
        return (status.st_dev, status.st_ino)
    except (OSError, ValueError):
        return os.path.realpath(file)


def plot_path_for(source: str, plot_dir: str, taken: set) -> str:
    """A PNG name in ``plot_dir`` from the record's file name, unique within the batch."""
    stem = "stdin" if source == "-" else Path(source).stem
    candidate = Path(plot_dir) / f"{stem}.png"
    if str(candidate) in taken:  # e.g. run.csv and run.xlsx: keep the extension in the name
        candidate = Path(plot_dir) / f"{Path(source).name}.png"
    number = 2
    while str(candidate) in taken:
        candidate = Path(plot_dir) / f"{stem}-{number}.png"
        number += 1
    taken.add(str(candidate))
    return str(candidate)


def _job(argument):
    """Read, analyse and plot one record (:class:`FileResult`); never raises, not even for
    a bug.

    A bad file is an expected failure with its own message. Any other exception is a bug
    in mcfit, but losing the rest of a batch to it would be worse: the record is reported
    with status "error" and a message that says so, and the command line exits 1.
    """
    source, options, plot_path = argument
    try:
        return _job_for(source, options, plot_path)
    except MemoryError:
        message = (f"not enough memory to fit {_display_name(source)}; fit a shorter part of "
                   "the record, or run with `jobs=1`.")
    except Exception as error:  # noqa: BLE001 - a bug must not end the batch
        detail = " ".join(str(error).split())
        detail = detail if len(detail) <= 300 else detail[:297] + "..."
        message = (f"internal error while fitting {_display_name(source)}: "
                   f"{type(error).__name__}: {detail} (a bug in mcfit; please report it)")
    return FileResult.failed(source, message)


def _job_for(source, options, plot_path):
    from mcfit.io import read_records

    try:
        records = _free_decays(source, options)
    except McfitError as error:
        return FileResult.failed(source, _message(error, source))
    several = len(records) > 1
    return FileResult(_display_name(source), tuple(
        _record_job(source, record, options,
                    run_plot_path(plot_path, record.run) if several else plot_path)
        for record in records))


def _free_decays(source, options):
    """The records of ``source`` to fit: every run side by side, each kept to its free
    decay or split into one record per free decay (:func:`mcfit.analysis.free_decay_runs`)
    unless ``start``/``end`` set the window; ``run=N`` picks a run side by side or,
    in a file of one run, a free decay."""
    from mcfit.analysis import free_decay_runs
    from mcfit.io import read_records

    def read(run):
        return read_records(source, time_col=options.time_col,
                            signal_col=options.signal_col, sheet=options.sheet,
                            rate=options.rate, kind=options.kind, domain=options.domain,
                            run=run, angle_from=options.angle_from)

    if options.start is not None or options.end is not None:
        return read(options.run)
    try:
        records = read(options.run)
    except UsageError as error:
        if options.run is None:
            raise
        records = read(None)
        if len(records) != 1 or records[0].run is not None:
            raise
        return _free_decay_numbered(records[0], options.run, error)
    if options.run is not None and len(records) == 1 and records[0].run is None:
        return _free_decay_numbered(records[0], options.run, None)
    return [run for record in records for run in free_decay_runs(record)]


def _free_decay_numbered(record, number, error):
    """[the free decay ``Run {number}`` of a record of one run] (the record itself for
    number 1 where it has one free decay); UsageError where there is no such one."""
    from mcfit.analysis import free_decay_runs

    runs = free_decay_runs(record)
    if len(runs) == 1 and runs[0].run is None and int(number) == 1:
        return runs
    chosen = [r for r in runs if r.run == f"Run {number}"]
    if not chosen:
        said = error or f"run {number} not found in {record.source}; it holds one run."
        raise UsageError(f"{said} (its free decays: {len(runs)})", option="run")
    return chosen


def run_plot_path(plot_path, run):
    """The figure of one run of several: ``fig.png`` -> ``fig-run7.png``."""
    if plot_path is None:
        return None
    path = Path(plot_path)
    number = run.split()[-1]
    return str(path.with_name(f"{path.stem}-run{number}{path.suffix}"))


def _record_job(source, record, options, plot_path):
    """The result (a dict, as :class:`FileResult` holds them) of one record read from
    ``source``, its signal in ``options.unit`` where given."""
    from mcfit.analysis import analyse_record, failed_analysis
    from mcfit.record import with_signal_unit

    record = with_signal_unit(record, options.unit)

    try:
        analysis = analyse_record(record, criterion=options.criterion, model=options.model,
                                  bootstrap=options.bootstrap, seed=options.seed,
                                  pendulum=options.pendulum, degrees=options.degrees,
                                  method=options.method, start=options.start,
                                  end=options.end)
    except McfitError as error:
        analysis = failed_analysis(record.name, _message(error, source), record=record)
    # Every row names its record as the user gave it, so scripts can match rows to files.
    name = _display_name(source) + (f"#{record.run}" if record.run else "")
    analysis = dataclasses.replace(analysis, source=name)
    plot_error = None
    if plot_path is not None and analysis.status == "ok":
        try:
            _plot(analysis, plot_path, options)
        except OSError as error:  # its message would name the temporary file
            plot_error = f"cannot write plot {display_name(plot_path)}: " \
                         f"{describe_os_error(error)}."
        except (ValueError, McfitError) as error:
            plot_error = f"cannot write plot {display_name(plot_path)}: {error}"
    points = analysis.turning_point_table() if options.turning_points_out else ()
    return _record_result(analysis, plot_error, points)


def _display_name(source) -> str:
    return "<stdin>" if source == "-" else display_name(source)


def _message(error, source) -> str:
    """The error on one line, naming the file as results name it (a newline in the name
    is shown as \\n, not lost with the other line breaks)."""
    text = str(error)
    if source != "-":
        text = text.replace(str(source), _display_name(source))
    return " ".join(text.split())


def _plot(analysis, path, options):
    from mcfit.plots import save_figure

    from mcfit.plots import figure_title

    title = options.title
    run = getattr(analysis.record, "run", None)
    if title is not None and run:
        title = f"{title}, {run}"
    elif title is None:  # the file name as results show it (matplotlib draws no stray bytes)
        title = figure_title(_display_name(analysis.record.source), run)
    figure = analysis.figure(title, panels=options.panels, figsize=options.figsize,
                             unit=options.unit)
    save_figure(figure, path, dpi=options.dpi)


def available_cpus() -> int:
    """The CPUs this process may run on (its affinity mask where the system has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def run_jobs(sources, options: FitOptions, plot_paths, jobs: int = 1):
    """Yield a :class:`FileResult` per source, in input order, each as soon as it is ready.

    With ``jobs`` > 1 the records are fitted by worker processes, at most one per available
    CPU (:func:`available_cpus`: more would only share the CPUs and the memory). A worker
    that dies (the out-of-memory killer, a crash in a library) costs only its record,
    reported as an error that names the cause; a new worker takes its place. Closing the
    generator ends the workers at once; a worker whose parent dies ends too.
    """
    arguments = [(source, options, plot) for source, plot in zip(sources, plot_paths)]
    jobs = min(jobs, len(arguments), available_cpus())
    if jobs <= 1:
        for argument in arguments:
            yield _job(argument)
        return
    if multiprocessing.get_start_method() == "fork":
        # Forked workers inherit what is imported here: the numerical stack is then imported
        # once (about 1.4 s of CPU) instead of once in every worker.
        for module in ("mcfit.analysis", "mcfit.io"):
            importlib.import_module(module)
    yield from _run_in_workers(arguments, jobs)


# How long a worker asked to stop, or killed, may take to be gone before it is left behind.
_STOP_SECONDS = 5.0


class _Worker:
    """One worker process and the pipe that carries its jobs and results.

    The worker joins ``pool`` before its process starts, so that whoever ends the pool
    ends it too, whenever a stop signal comes.
    """

    def __init__(self, pool: list):
        self.connection, child = multiprocessing.Pipe()
        # A forked or spawned worker's parent is this process; a forkserver's is not.
        parent = os.getpid() if multiprocessing.get_start_method() in ("fork", "spawn") \
            else None
        self.process = multiprocessing.Process(target=_work, args=(child, parent),
                                               daemon=True)
        self.task = None  # (index, argument) of the record being fitted
        # In the pool before it starts: a stop signal that another thread takes (a BLAS
        # pool's, say; the mask below holds it back from this one only) runs its handler
        # here between any two steps, and a worker started outside the pool, which
        # ignores SIGTERM, would be waited for forever at exit. Blocked while the process
        # starts, so that the signal cannot reach the new process before it ignores it
        # (it would print a KeyboardInterrupt traceback).
        pool.append(self)
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        try:
            self.process.start()
        finally:
            child.close()
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)

    def give(self, task):
        """Send a record; a worker that died meanwhile is found by its sentinel."""
        self.task = task
        try:
            self.connection.send(task)
        except OSError:
            pass

    def stop(self):
        """End the process: at once if it is fitting a record that is not wanted any more.

        An idle worker is told to stop; closing the pipe would not do, as forked siblings
        hold copies of its end. Bounded: a worker still there after :data:`_STOP_SECONDS`
        is killed, and one that outlives that too (stuck in the kernel) is left.
        """
        if self.process.pid is None:  # stopped before its process started
            self.connection.close()
            return
        if self.task is None:
            try:
                self.connection.send(None)
            except OSError:
                pass  # already gone
        else:
            self.process.kill()
            self.task = None
        self.connection.close()
        self.process.join(timeout=_STOP_SECONDS)
        if self.process.exitcode is None:
            self.process.kill()
            self.process.join(timeout=_STOP_SECONDS)


def _work(connection, parent=None):
    """Worker process: fit the records sent through ``connection`` until it is closed, or
    until its parent process (``parent``, where known) is gone."""
    for stop in STOP_SIGNALS:
        signal.signal(stop, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
    _end_with_parent(parent)
    while True:
        try:
            task = connection.recv()
        except EOFError:
            return
        if task is None:
            return
        index, argument = task
        connection.send((index, _job(argument)))


def _end_with_parent(parent):
    """End this process when its parent dies, even killed outright in the middle of a fit.

    On Linux the kernel sends SIGKILL (``prctl(PR_SET_PDEATHSIG)``); elsewhere a daemon
    thread polls the parent's process id, which changes when the parent is gone.
    ``parent``, the process id the parent had when it started this one (None: the current
    parent), also catches a parent that died before this process could ask.
    """
    parent = os.getppid() if parent is None else parent
    if not _kill_with_parent():
        import threading

        threading.Thread(target=_watch_parent, args=(parent,), daemon=True,
                         name="mcfit-parent-watch").start()
    if os.getppid() != parent:  # died before the request above was in place
        os._exit(1)


def _kill_with_parent() -> bool:
    """Ask the kernel to SIGKILL this process when its parent dies; whether it could."""
    if not sys.platform.startswith("linux"):
        return False
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


_PR_SET_PDEATHSIG = 1  # from <linux/prctl.h>


def _watch_parent(parent, interval=0.5):
    while os.getppid() == parent:
        time.sleep(interval)
    os._exit(1)


def _run_in_workers(arguments, jobs):
    waiting = deque(enumerate(arguments))
    finished = {}
    workers = []
    next_index = 0
    try:
        while next_index < len(arguments):
            for worker in [w for w in workers if w.task is None and not w.process.is_alive()]:
                workers.remove(worker)  # died between two records: nothing lost
                worker.stop()
            while waiting and len(workers) < jobs:
                _Worker(workers)
            for worker in workers:
                if worker.task is None and waiting:
                    worker.give(waiting.popleft())
            busy = [worker for worker in workers if worker.task is not None]
            ready = wait([w.connection for w in busy] + [w.process.sentinel for w in busy])
            for worker in busy:
                if worker.connection in ready or worker.process.sentinel in ready:
                    index, result = _collect(worker)
                    if result is None:
                        result = _lost(worker)
                        workers.remove(worker)
                        worker.stop()
                    finished[index] = result
            while next_index in finished:
                yield finished.pop(next_index)
                next_index += 1
    finally:
        for worker in workers:
            worker.stop()


def _collect(worker):
    """The index and result of the worker's record; result None when the worker died."""
    index = worker.task[0]
    try:
        if worker.connection.poll():
            received_index, result = worker.connection.recv()
            worker.task = None
            return received_index, result
    except (EOFError, OSError):
        pass
    worker.process.join()
    return index, None


def _lost(worker):
    """The error result of a record whose worker died while fitting it."""
    (_, (source, _, _)) = worker.task
    code = worker.process.exitcode
    if code is not None and code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = "an unknown signal"
        cause = f"was killed by signal {-code} ({name})"
        if -code == signal.SIGKILL:
            cause += ", likely by the out-of-memory killer"
    else:
        cause = f"ended with exit code {code}"
    message = (f"the worker process fitting {_display_name(source)} {cause}; fit it again "
               "alone, with `jobs=1`, or free some memory.")
    return FileResult.failed(source, message)
