"""Assembling a :class:`Record` from the chosen columns: trimming, checks, units and notes."""

from __future__ import annotations

import numpy as np

from mcfit.errors import InputError
from mcfit.io.columns import _Run, _axis_siblings, _chosen_columns, _resolve_column
from mcfit.io.table import _describe, _read_columns
from mcfit.io.times import _repair_times, _timestamp_problem
from mcfit.io.tokens import _CYCLE_NAMES, _SECONDS_PER_UNIT, _base_name
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
    run = run or _Run(None, 1, tuple(range(len(table.names))))
    name = table.name
    notes = list(table.notes)
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
    time_index, signal_index, others, ignored = _chosen_columns(
        table, time_col, signal_col, rate, run, angle_from)
    if run.label is not None:
        notes.append(f"{run.label}, one of {run.count} runs side by side in the file, fitted "
                     f"as a record of its own (`run={run.number}` picks it)")

    indices = [signal_index] if time_index is None else [time_index, signal_index]
    columns = _read_columns(table, indices)
    x = columns[-1]
    t = columns[0] if time_index is not None else None
    y_index = None
    if angle_from is not None:
        y_index = _resolve_column(table, angle_from[1], "angle", run.columns)
        x = _swing_angle(table, x, y_index, notes)

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

    time_unit = _base_name(table.names[time_index])[1] if time_index is not None else "s"
    signal_unit = _base_name(table.names[signal_index])[1]
    signal_label = table.names[signal_index]
    if angle_from is not None:
        signal_unit = "rad"
        signal_label = f"angle from {signal_label}, {table.names[y_index]}"
    time_label = table.names[time_index] if time_index is not None else None

    if rate is not None:
        if ignored:
            probe = table.sample[ignored[0]].values
            problem = _timestamp_problem(probe)
            text = f"; its timestamps are unusable: {problem}" if problem else ""
            notes.append(f"time built from the sample rate {rate:g} Hz; column "
                         f"{_describe(table, ignored[0])} ignored{text}")
        else:
            notes.append(f"time built from the sample rate {rate:g} Hz")
        t = np.arange(x.size, dtype=np.float64) / rate
        detected_kind = "waveform"
    else:
        detected_kind = detect_kind(t, x)
    chosen_kind = kind or detected_kind
    if kind is None and detected_kind == "turning-points":
        notes.append("read as a table of turning points (override with `kind=waveform`)")

    if chosen_kind == "turning-points":
        finite = np.isfinite(t) & np.isfinite(x)
        if np.count_nonzero(~finite):
            notes.append(f"{int(np.count_nonzero(~finite))} incomplete rows dropped")
        t, x = t[finite], x[finite]
        if np.unique(t).size != t.size:
            raise InputError(f"the time column {_describe(table, time_index)} of {name} repeats "
                             "values in a turning-point table. Remove the duplicate rows.")
        if not np.all(np.diff(t) > 0):
            order = np.argsort(t, kind="stable")
            t, x = t[order], x[order]
            notes.append("turning points sorted by time")
    else:
        t, x, event_driven = _repair_times(table, time_index, t, x, notes)
        if not np.all(np.diff(t) > 0):
            problem = _timestamp_problem(t)
            where = int(np.flatnonzero(~(np.diff(t) > 0))[0]) + 1
            if problem:
                raise InputError(f"the time column {_describe(table, time_index)} of {name} is "
                                 f"unusable: {problem}. Give the sample rate with `rate=HZ`.")
            raise InputError(f"the time column {_describe(table, time_index)} of {name} does "
                             f"not increase (data row {where + 1}: {t[where - 1]:g} then "
                             f"{t[where]:g}). Sort the file, choose another column with "
                             "`time_col`, or use `rate=HZ`.")
        problem = None if event_driven else _timestamp_problem(t)
        if problem:
            notes.append(f"irregular timestamps: {problem}; if the logger stamps samples in "
                         "bursts, use `rate=HZ`")
        gaps = np.count_nonzero(~np.isfinite(x))
        if gaps:
            notes.append(f"{gaps} samples without a signal value (gaps)")

    if domain is None:
        domain = "time"
        if time_index is not None and (_base_name(table.names[time_index])[0] in _CYCLE_NAMES):
            domain = "cycle"
        elif (chosen_kind == "turning-points" and t.size >= 2 and np.all(t == np.round(t))
              and np.all(np.diff(t) == np.diff(t)[0]) and time_unit is None):
            domain = "cycle"
        if domain == "cycle":
            notes.append("time column read as cycle number n (override with `domain=time`)")

    if time_index is not None and time_col is None:
        notes.append(f"time column: {_describe(table, time_index)} (chosen automatically; "
                     "use `time_col` to change)")
    if signal_col is None and angle_from is None:
        other = ""
        if others:
            other = "; other candidates: " + ", ".join(_describe(table, i) for i in others)
        most = (", the component that oscillates most"
                if _axis_siblings(table, signal_index, others) else "")
        notes.append(f"signal column: {_describe(table, signal_index)}{most} (chosen "
                     f"automatically; use `signal_col` to change{other})")

    if domain == "time" and time_unit is not None:
        seconds = _SECONDS_PER_UNIT.get(time_unit.strip().lower().replace("μ", "u").replace("µ", "u"))
        if seconds is None:
            notes.append(f"time unit '{time_unit}' not recognised: coefficients are per "
                         f"{time_unit}, not per second")
        elif seconds != 1.0:
            t = t * seconds
            notes.append(f"time converted from {time_unit} to seconds")
            time_unit = "s"
        else:  # "seconds", "sec": the report speaks of seconds as "s"
            time_unit = "s"

    t = np.ascontiguousarray(t, dtype=np.float64)
    x = np.ascontiguousarray(x, dtype=np.float64)
    t.setflags(write=False)
    x.setflags(write=False)
    return Record(source=name, t=t, x=x, kind=chosen_kind, domain=domain,
                  time_column=time_label, signal_column=signal_label,
                  time_unit=time_unit, signal_unit=signal_unit,
                  columns=tuple(table.names), notes=tuple(notes), run=run.label)
