"""Assembling a :class:`Record` from the chosen columns: trimming, checks, units and notes."""

from __future__ import annotations

import numpy as np

from mcfit.errors import InputError
from mcfit.io.clocks import rebased_epoch
from mcfit.io.columns import _Run, _axis_siblings, _chosen_columns, _resolve_column
from mcfit.io.lines import LINE_RATIO
from mcfit.io.table import _describe, _read_columns
from mcfit.io.times import _repair_times, _timestamp_problem
from mcfit.io.tokens import _CYCLE_NAMES, _SECONDS_PER_UNIT, _base_name, _time_unit
from mcfit.record import Record, detect_kind


def _swing_angle(table, x, y_index, notes):
    """The swing angle atan2(x, -y) of a bob tracked at (x, y), pivot at the origin; with
    y growing downwards (image coordinates: the bob hangs at y > 0), atan2(x, y)."""
    y = _read_columns(table, [y_index])[0][:x.size]
    finite = np.isfinite(y)
    downwards = finite.any() and np.median(y[finite]) > 0
    angle = np.arctan2(x, y if downwards else -y)
    formula = "atan2(x, y), y growing downwards" if downwards else "atan2(x, -y)"
    notes.append(f"signal: the swing angle {formula}, in radians, y from "
                 f"{_describe(table, y_index)} (pivot at the origin)")
    return angle


def _end_of(present):
    """One past the last True of ``present`` (which holds one), without an index array."""
    return present.size - int(np.argmax(present[::-1]))


def _build_record(table, time_col, signal_col, rate, kind, domain, run=None,
                  angle_from=None):
    """The :class:`Record` of one run of ``table``; the options as :func:`read_record`'s."""
    run = run or _Run(None, 1, tuple(range(len(table.names))))
    notes = list(table.notes)
    _check_rows(table, time_col, signal_col, rate)
    time_index, signal_index, others, ignored, strengths = _chosen_columns(
        table, time_col, signal_col, rate, run, angle_from)
    if run.label is not None:
        notes.append(f"{run.label}, one of {run.count} runs side by side in the file, fitted "
                     f"as a record of its own (`run={run.number}` picks it)")
    indices = [signal_index] if time_index is None else [time_index, signal_index]
    columns = _read_columns(table, indices)
    t, x = (columns[0] if time_index is not None else None), columns[-1]
    signal_unit, signal_label = _base_name(table.names[signal_index])[1], table.names[signal_index]
    if angle_from is not None:
        y_index = _resolve_column(table, angle_from[1], "angle", run.columns)
        x = _swing_angle(table, x, y_index, notes)
        signal_unit = "rad"
        signal_label = f"angle from {signal_label}, {table.names[y_index]}"
    t, x = _trimmed(table, t, x, time_index, signal_index, notes)
    time_unit = _time_unit(table.names[time_index]) if time_index is not None else "s"

    if rate is not None:
        t = _time_from_rate(table, x.size, rate, ignored, notes)
        detected_kind = "waveform"
    else:
        detected_kind = detect_kind(t, x)
    chosen_kind = kind or detected_kind
    if kind is None and detected_kind == "turning-points":
        notes.append("read as a table of turning points (override with `kind=waveform`)")
    if chosen_kind == "turning-points":
        t, x = _sorted_turning_points(table, time_index, t, x, notes)
    else:
        t, x = _checked_waveform(table, time_index, t, x, notes)
    if domain is None:
        domain = _detected_domain(table, time_index, chosen_kind, t, time_unit, notes)
    _choice_notes(table, time_index, (signal_index, others, strengths), time_col is None,
                  signal_col is None and angle_from is None, notes)
    if domain == "time" and time_unit is not None:
        t, time_unit = _in_seconds(t, time_unit, notes)
    origin = None
    if domain == "time" and rate is None and time_index is not None:
        origin = table.origins.get(time_index)
        if origin is None:
            t, time_unit, origin = rebased_epoch(t, time_unit, table.names[time_index], notes)

    t = np.ascontiguousarray(t, dtype=np.float64)
    x = np.ascontiguousarray(x, dtype=np.float64)
    t.setflags(write=False)
    x.setflags(write=False)
    return Record(source=table.name, t=t, x=x, kind=chosen_kind, domain=domain,
                  time_column=table.names[time_index] if time_index is not None else None,
                  signal_column=signal_label, time_unit=time_unit, signal_unit=signal_unit,
                  columns=tuple(table.names), notes=tuple(notes), run=run.label,
                  time_origin=origin,
                  oscillating_columns=_oscillating_instead(table, signal_index, strengths))


def _check_rows(table, time_col, signal_col, rate):
    """Refuse a table without two rows of numbers, or of one column and no way to time it."""
    name = table.name
    present = ~np.isnan(table.sample.to_numpy(dtype=np.float64))
    if table.sample.shape[0] == 0 or not present.any():
        raise InputError(f"{name} has no numeric data rows. Give a file with a time and a "
                         "signal column of numbers.")
    numeric_rows = int(np.count_nonzero(present.any(axis=1)))
    if numeric_rows < 2:
        raise InputError(f"{name} has only {numeric_rows} data row. A decay record needs "
                         "many samples over several cycles.")
    if len(table.names) == 1 and time_col is None and rate is None and signal_col is None:
        rows = " (its values written in one row)" if table.transposed else ""
        raise InputError(f"{name} has one column{rows}, {_describe(table, 0)}, and no time "
                         "column. Give the sample rate with `rate=HZ`, or add a time column.")


def _trimmed(table, t, x, time_index, signal_index, notes):
    """(t, x) without padding rows, rows without a time and trailing rows without a signal;
    refuses a time or signal column without numbers and a constant signal."""
    name = table.name
    # Side-by-side runs: shorter runs are padded with empty cells at the end.
    present = np.isfinite(x) if t is None else np.isfinite(t)
    if not present.any():
        what = "signal" if t is None else "time"
        column = signal_index if t is None else time_index
        raise InputError(f"the {what} column {_describe(table, column)} of {name} holds no "
                         "numbers. Choose another column with `time_col` or `signal_col`.")
    end = _end_of(present)
    if end < x.size:
        notes.append(f"{x.size - end} empty trailing rows dropped (padding)")
        x = x[:end]
        t = None if t is None else t[:end]
    if t is not None:
        missing_t = ~np.isfinite(t)
        if missing_t.any():
            notes.append(f"{int(missing_t.sum())} rows without a time value dropped")
            t, x = t[~missing_t], x[~missing_t]
    finite = np.isfinite(x)
    if not finite.any():
        raise InputError(f"the signal column {_describe(table, signal_index)} of {name} holds "
                         "no numbers (all empty or NaN). Choose the signal with `signal_col`.")
    values = x if finite.all() else x[finite]  # copied only where there are gaps
    if values.min() == values.max():
        raise InputError(f"the signal column {_describe(table, signal_index)} of {name} is "
                         f"constant ({values[0]:g}). Choose the signal with `signal_col`.")
    del values
    # Trailing NaN in the signal alone (a shorter run sharing the time column).
    last_x = _end_of(finite)
    del finite
    if last_x < x.size:
        notes.append(f"{x.size - last_x} trailing rows without a signal value dropped")
        x = x[:last_x]
        t = None if t is None else t[:last_x]
    return t, x


def _time_from_rate(table, size, rate, ignored, notes):
    """Times index/rate, shape (size,), with a note naming a time column left unused."""
    if ignored:
        problem = _timestamp_problem(table.sample[ignored[0]].values)
        text = f"; its timestamps are unusable: {problem}" if problem else ""
        notes.append(f"time built from the sample rate {rate:g} Hz; column "
                     f"{_describe(table, ignored[0])} ignored{text}")
    else:
        notes.append(f"time built from the sample rate {rate:g} Hz")
    return np.arange(size, dtype=np.float64) / rate


def _sorted_turning_points(table, time_index, t, x, notes):
    """A turning-point table's complete rows, sorted by time; repeated times refused."""
    finite = np.isfinite(t) & np.isfinite(x)
    if np.count_nonzero(~finite):
        notes.append(f"{int(np.count_nonzero(~finite))} incomplete rows dropped")
    t, x = t[finite], x[finite]
    if np.unique(t).size != t.size:
        raise InputError(f"the time column {_describe(table, time_index)} of {table.name} "
                         "repeats values in a turning-point table. Remove the duplicate rows.")
    if not np.all(np.diff(t) > 0):
        order = np.argsort(t, kind="stable")
        t, x = t[order], x[order]
        notes.append("turning points sorted by time")
    return t, x


def _checked_waveform(table, time_index, t, x, notes):
    """A waveform's times repaired (:func:`_repair_times`) and refused unless increasing."""
    t, x, event_driven = _repair_times(table, time_index, t, x, notes)
    if not np.all(np.diff(t) > 0):
        label = f"the time column {_describe(table, time_index)} of {table.name}"
        problem = _timestamp_problem(t)
        where = int(np.flatnonzero(~(np.diff(t) > 0))[0]) + 1
        if problem:
            raise InputError(f"{label} is unusable: {problem}. Give the sample rate with "
                             "`rate=HZ`.")
        raise InputError(f"{label} does not increase (data row {where + 1}: {t[where - 1]:g} "
                         f"then {t[where]:g}). Sort the file, choose another column with "
                         "`time_col`, or use `rate=HZ`.")
    problem = None if event_driven else _timestamp_problem(t)
    if problem:
        notes.append(f"irregular timestamps: {problem}; if the logger stamps samples in "
                     "bursts, use `rate=HZ`")
    gaps = np.count_nonzero(~np.isfinite(x))
    if gaps:
        notes.append(f"{gaps} samples without a signal value (gaps)")
    return t, x


def _detected_domain(table, time_index, kind, t, time_unit, notes):
    """'cycle' for a time column named like a cycle count, or a turning-point table whose
    times are the integers 0, 1, 2... without a unit; else 'time'."""
    domain = "time"
    if time_index is not None and (_base_name(table.names[time_index])[0] in _CYCLE_NAMES):
        domain = "cycle"
    elif (kind == "turning-points" and t.size >= 2 and np.all(t == np.round(t))
          and np.all(np.diff(t) == np.diff(t)[0]) and time_unit is None):
        domain = "cycle"
    if domain == "cycle":
        notes.append("time column read as cycle number n (override with `domain=time`)")
    return domain


def _choice_notes(table, time_index, signal, time_chosen, signal_chosen, notes):
    """Notes naming the time and signal columns chosen automatically, the other columns
    that oscillate and the other candidates; ``signal`` is (signal column, the other
    candidates, their line strengths)."""
    signal_index, others, strengths = signal
    if time_index is not None and time_chosen:
        notes.append(f"time column: {_describe(table, time_index)} (chosen automatically; "
                     "use `time_col` to change)")
    if signal_chosen:
        other = ""
        also = [i for i in others if strengths.get(i, 0.0) >= LINE_RATIO]
        if also:
            own = strengths.get(signal_index, 0.0)
            other = "; also oscillating: " + ", ".join(
                _describe(table, i) + (" (weaker)" if strengths[i] < own else "")
                for i in also)
        rest = [i for i in others if i not in also]
        if rest:
            other += "; other candidates: " + ", ".join(_describe(table, i) for i in rest)
        most = (", the component that oscillates most"
                if _axis_siblings(table, signal_index, others) else "")
        if table.loudest == signal_index:
            most = ", the channel that swings most"
        notes.append(f"signal column: {_describe(table, signal_index)}{most} (chosen "
                     f"automatically; use `signal_col` to change{other})")


def _oscillating_instead(table, signal_index, strengths):
    """The names of the other columns with a spectral line, clearest first, when the
    signal column has none; else ()."""
    if not strengths or strengths.get(signal_index, 0.0) >= LINE_RATIO:
        return ()
    lines = sorted((i for i, s in strengths.items() if s >= LINE_RATIO and i != signal_index),
                   key=lambda i: -strengths[i])
    return tuple(table.names[i] for i in lines)


def _in_seconds(t, time_unit, notes):
    """(t, unit): times in a unit the header names, converted to seconds where known."""
    seconds = _SECONDS_PER_UNIT.get(time_unit.strip().lower().replace("μ", "u")
                                    .replace("µ", "u"))
    if seconds is None:
        notes.append(f"time unit '{time_unit}' not recognised: coefficients are per "
                     f"{time_unit}, not per second")
        return t, time_unit
    if seconds != 1.0:
        t = t * seconds
        notes.append(f"time converted from {time_unit} to seconds")
    return t, "s"  # "seconds", "sec": the report speaks of seconds as "s"
