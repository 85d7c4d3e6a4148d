"""Runs side by side and the choice of the time and signal columns."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from mcfit.errors import InputError, UsageError
from mcfit.io.clocks import epoch_scale
from mcfit.io.layouts import LAYOUTS
from mcfit.io.lines import LINE_RATIO, line_strength
from mcfit.io.table import _describe
from mcfit.io.times import _timestamp_problem
from mcfit.io.tokens import _CYCLE_NAMES, _RUN_SUFFIX, _base_name, _is_time_name

_SECONDARY_SIGNAL_WORDS = ("vel", "speed", "acc", "resid", "error", "err", "fit", "model",
                           "derivative")

# Column suffixes numbering runs side by side ("Run #7"), from the export layouts.
_RUN_LABELS = tuple(layout.run_label for layout in LAYOUTS if layout.run_label is not None)


@dataclass(frozen=True)
class _Run:
    """One run of a file: its label ("Run 7", None for a file of one run), its number, the
    0-based columns it may use, and how many runs the file holds."""

    label: str | None
    number: int
    columns: tuple[int, ...]
    count: int = 1


def _plain_name(table, index):
    """A column's name without the " (N)" that tells repeated header names apart."""
    name = table.names[index]
    marker = f" ({index + 1})"
    if name.endswith(marker) and name[:-len(marker)] in table.names[:index]:
        return name[:-len(marker)]
    return name


def _labelled_runs(table):
    """Runs named by a "Run #N" suffix; unlabelled columns belong to every run."""
    numbers = [next(filter(None, (label.search(name) for label in _RUN_LABELS)), None)
               for name in table.names]
    found = list(dict.fromkeys(int(m.group(1)) for m in numbers if m))
    shared = tuple(i for i, m in enumerate(numbers) if m is None)
    return [(n, tuple(sorted(shared + tuple(i for i, m in enumerate(numbers)
                                            if m and int(m.group(1)) == n))))
            for n in found]


def _repeated_groups(table):
    """Runs as repeated groups of columns, each starting with a time column of one name."""
    starts = [i for i in range(len(table.names)) if _is_time_name(_plain_name(table, i))]
    if len(starts) < 2 or starts[0] != 0:
        return []
    bounds = starts + [len(table.names)]
    groups = [tuple(range(a, b)) for a, b in zip(bounds, bounds[1:])]
    shapes = {tuple(_plain_name(table, i) for i in group) for group in groups}
    if len(shapes) != 1 or len(groups[0]) < 2:
        return []
    return [(k + 1, group) for k, group in enumerate(groups)]


def _file_runs(table):
    """The file's runs side by side, in file order (one run of all columns if none)."""
    runs = _labelled_runs(table)
    if len(runs) < 2:
        runs = _repeated_groups(table)
    if len(runs) < 2:
        return [_Run(None, 1, tuple(range(len(table.names))))]
    return [_Run(f"Run {number}", number, columns, len(runs)) for number, columns in runs]


def _chosen_runs(table, wanted, column_specs):
    """The runs to read: the one numbered ``wanted``, those holding a column named in
    ``column_specs`` when it names one column of the file, else all."""
    runs = _file_runs(table)
    for spec in column_specs:
        if spec is None or len(runs) == 1:
            continue
        try:
            index = _resolve_column(table, spec, "signal")
        except UsageError:  # a name every run holds: chosen in each run
            continue
        runs = [r for r in runs if index in r.columns] or runs
    if wanted is None:
        return runs
    chosen = [r for r in runs if r.number == int(wanted)]
    if not chosen and runs[0].label is None and int(wanted) == 1:
        return runs
    if not chosen:
        held = ", ".join(str(r.number) for r in runs) if runs[0].label else "one run"
        raise UsageError(f"run {wanted} not found in {table.name}; it holds {held}. "
                         "Give one of those numbers to `run`.")
    return chosen


def _resolve_column(table, spec, role, within=None):
    """The 0-based column named or numbered by ``spec``; a name is looked for among the
    columns ``within`` (default all), also without its unit and its run label."""
    option = {"time": "`time_col`", "signal": "`signal_col`"}.get(role, "`angle_from`")
    listing = ", ".join(table.names)
    if isinstance(spec, (int, np.integer)) or (isinstance(spec, str) and spec.strip().isdigit()
                                              and spec not in table.names):
        index = int(spec)
        if not 1 <= index <= len(table.names):
            raise UsageError(f"column {index} not found in {table.name}; it has "
                             f"{len(table.names)} columns: {listing}. Use {option} with a "
                             "1-based index or a name.")
        return index - 1
    spec = str(spec)
    candidates = range(len(table.names)) if within is None else within
    named = [i for i in candidates if _plain_name(table, i) == spec]
    if len(named) > 1:
        places = ", ".join(str(i + 1) for i in named[:-1]) + f" and {named[-1] + 1}"
        raise UsageError(f"column '{spec}' is ambiguous in {table.name}: columns {places} are "
                         f"named '{spec}'. Use {option} with a 1-based index.")
    if named:
        return named[0]
    if spec in table.names:
        return table.names.index(spec)
    wanted = _base_name(spec)[0]
    matches = [i for i in candidates if table.names[i].strip().lower() == spec.strip().lower()
               or _base_name(table.names[i])[0] == wanted
               or _RUN_SUFFIX.sub("", _base_name(_plain_name(table, i))[0]) == wanted]
    if len(matches) == 1:
        return matches[0]
    if len(matches) > 1:
        raise UsageError(f"column '{spec}' is ambiguous in {table.name}; columns are: "
                         f"{listing}. Use {option} with the full name or a 1-based index.")
    raise UsageError(f"column '{spec}' not found in {table.name}; columns are: {listing}. "
                     f"Use {option}.")


def _strictly_increasing(values):
    v = values[np.isfinite(values)]
    return v.size >= 3 and bool(np.all(np.diff(v) > 0))


# A column oscillates when it crosses its detrended middle at this fraction of its steps,
# or this many times (four cycles: a well sampled oscillation crosses it rarely per step).
_MIN_CROSSING_FRACTION = 0.02
_MIN_CROSSINGS = 8


def _oscillates(values):
    """Whether a column crosses its (detrended) middle often enough to be an oscillation."""
    v = values[np.isfinite(values)]
    if v.size < 8 or np.ptp(v) == 0:
        return False
    index = np.arange(v.size)
    trend = np.polyval(np.polyfit(index, v, 1), index)
    crossings = np.count_nonzero(np.diff(np.sign(v - trend)) != 0)
    return crossings > _MIN_CROSSING_FRACTION * v.size or crossings >= _MIN_CROSSINGS


def _choose_time(table, rate, columns):
    sample = table.sample
    named = [i for i in columns if _is_time_name(table.names[i])]
    cycle_named = [i for i in columns if _base_name(table.names[i])[0] in _CYCLE_NAMES]
    increasing = [i for i in columns if _strictly_increasing(sample[i].values)]
    # Elapsed seconds are the better time when the file also holds clock times, and a
    # logger's epoch clock, even without a telling name, better than its sample counter
    # and its clock-time text.
    clocks = [i for i in increasing if i not in named and i not in table.clock
              and epoch_scale(sample[i].values) is not None]
    named = ([i for i in named if i not in table.clock] + clocks
             + [i for i in named if i in table.clock])
    # Logger timestamps that repeat: a time column, but an unusable one.
    repeating = [i for i in columns if i not in increasing
                 and _timestamp_problem(sample[i].values) is not None
                 and np.all(np.diff(sample[i].values[np.isfinite(sample[i].values)]) >= 0)]
    if rate is not None:
        return None, named + [i for i in increasing + repeating if i not in named]
    for candidates in (named, cycle_named):
        if candidates:
            return candidates[0], []
    if increasing:
        return increasing[0], []
    if repeating:
        return repeating[0], []
    # No increasing column: a turning-point table may list its times unsorted.
    for i in columns:
        v = sample[i].values
        v = v[np.isfinite(v)]
        if v.size >= 4 and np.unique(v).size == v.size and v.size < 5000:
            return i, []
    return None, []


def _signal_candidates(table, time_index, ignored, columns):
    """The columns that may be the signal: not the time, a clock or an ignored time
    column, with two numbers at least and not constant in the sample."""
    sample = table.sample
    return [i for i in columns
            if i != time_index and i not in ignored and i not in table.clock
            and np.count_nonzero(np.isfinite(sample[i].values)) >= 2
            and np.ptp(sample[i].values[np.isfinite(sample[i].values)]) > 0]


def _line_strengths(table, candidates):
    """{column: :func:`line_strength` of its sample} for two candidates or more, else {}:
    one column needs no comparison."""
    if len(candidates) < 2:
        return {}
    return {i: line_strength(table.sample[i].to_numpy(dtype=np.float64))
            for i in candidates}


def _choose_signal(table, time_index, ignored, columns, strengths):
    """(signal column, the other candidates in order): the column with the clearest
    spectral line (``strengths``), else the first that crosses its middle often, else the
    first that varies; names of derived quantities (velocity, fit) last; of a vector
    sensor's components, the one that swings most."""
    sample = table.sample
    candidates = _signal_candidates(table, time_index, ignored, columns)
    if not candidates:  # only constant columns: say so when they are read
        rest = [i for i in columns if i != time_index and i not in ignored
                and np.isfinite(sample[i].values).any()]
        return (rest[0], []) if rest else (None, [])
    secondary = [i for i in candidates
                 if any(w in _base_name(table.names[i])[0] for w in _SECONDARY_SIGNAL_WORDS)]
    primary = [i for i in candidates if i not in secondary]
    # Lines first, the clearest first (sorted stably: clean lines keep the file's order),
    # then columns that cross their middle often; one candidate needs no score.
    lines = sorted((i for i in primary if strengths.get(i, 0.0) >= LINE_RATIO),
                   key=lambda i: -strengths[i])
    oscillating = ([i for i in primary if _oscillates(sample[i].values)]
                   if len(primary) > 1 else primary)
    order = list(dict.fromkeys(lines + oscillating + primary + secondary))
    axes = [order[0]] + _axis_siblings(table, order[0], order[1:])
    if table.loudest in order:  # audio channels: the one that swings most
        order.remove(table.loudest)
        order.insert(0, table.loudest)
    elif len(axes) > 1:  # a vector sensor: the component that swings most
        strongest = max(axes, key=lambda i: _oscillation_size(sample[i].values))
        order.remove(strongest)
        order.insert(0, strongest)
    return order[0], order[1:]


# A vector sensor's components: "Rotation x (rad/s)", "acc_y", "Gyroscope z".
_AXIS_NAME = re.compile(r"^(.+?)[\s_\-]+([xyz])$")


def _axis_key(table, index):
    """(quantity, unit) of a column named as a component x, y or z, else None."""
    base, unit = _base_name(table.names[index])
    match = _AXIS_NAME.match(base)
    return (match.group(1), unit) if match else None


def _axis_siblings(table, index, others):
    """The columns of ``others`` that are components of the same quantity as ``index``."""
    key = _axis_key(table, index)
    return [i for i in others if key is not None and _axis_key(table, i) == key]


def _oscillation_size(values):
    """How much a column swings: the largest spectral amplitude of its detrended values."""
    v = values[np.isfinite(values)]
    if v.size < 8:
        return 0.0
    index = np.arange(v.size)
    centred = v - np.polyval(np.polyfit(index, v, 1), index)
    return float(np.abs(np.fft.rfft(centred)[1:]).max())


def _chosen_columns(table, time_col, signal_col, rate, run, angle_from):
    """(time index or None, signal index, other signal candidates, ignored time columns,
    line strengths) among the run's columns; for ``angle_from`` the signal is the bob's x
    column. The strengths ({column: :func:`line_strength`}) are those of the candidates
    for the signal, when there are two or more of them."""
    name, columns = table.name, run.columns
    ignored = []
    if time_col is not None:
        time_index = _resolve_column(table, time_col, "time", columns)
    else:
        time_index, ignored = _choose_time(table, rate, columns)
    strengths = _line_strengths(table, _signal_candidates(table, time_index, ignored,
                                                          columns))
    signal_col = angle_from[0] if angle_from is not None else signal_col
    if signal_col is not None:
        role = "signal" if angle_from is None else "angle"
        signal_index, others = _resolve_column(table, signal_col, role, columns), []
    else:
        signal_index, others = _choose_signal(table, time_index, ignored, columns, strengths)
        if signal_index is None:
            if table.sample.shape[1] == 1 or time_index is None:
                raise InputError(f"no signal column found in {name} (columns: "
                                 f"{', '.join(table.names)}). Use `signal_col`.")
            raise InputError(f"no varying signal column in {name} besides the time "
                             f"{_describe(table, time_index)}; columns are: "
                             f"{', '.join(table.names)}. Use `signal_col`.")
    if time_index is not None and time_index == signal_index:
        raise UsageError(f"the time and the signal are the same column "
                         f"{_describe(table, signal_index)} of {name}. Use `time_col` and "
                         "`signal_col` with different columns.")
    if time_index is None and rate is None:
        raise InputError(f"no time column found in {name} (no column increases steadily). "
                         "Name it with `time_col` or give the sample rate with `rate=HZ`.")
    return time_index, signal_index, others, ignored, strengths
