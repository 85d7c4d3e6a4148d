"""Repairing time columns: rounded in print, event-driven logs, glitched or bursty stamps."""

from __future__ import annotations

import re

import numpy as np

from mcfit.io.table import _describe
from mcfit.io.tokens import _split


def _timestamp_problem(t):
    """Describe unusable logger timestamps (repeats or bursts), or None."""
    # Copies of a long record's times are avoided: they set the reader's peak memory.
    finite = t if np.isfinite(t).all() else t[np.isfinite(t)]
    if finite.size < 4:
        return None
    steps = np.diff(finite)
    if not np.all(steps > 0):
        repeats = np.count_nonzero(steps == 0)
        if repeats > 0 and np.all(steps >= 0):
            return (f"{repeats} of {steps.size} time steps repeat the previous timestamp "
                    "(the logger stamps samples in bursts)")
        return None
    if steps.size >= 4:
        median = np.median(steps)
        long_steps = np.count_nonzero(steps > 4 * median)
        if long_steps >= 3 and long_steps >= 0.05 * steps.size:
            return (f"time steps come in bursts ({long_steps} of {steps.size} steps are more "
                    "than 4 times the median step)")
    return None


# Glitched timestamps (repeated or stepping back) repaired when at most this fraction of the
# steps is wrong; more means the column is not a clean clock, and a person must decide.
_MAX_GLITCH_FRACTION = 0.01


def _repair_times(table, time_index, t, x, notes):
    """(t, x, event_driven) with rounded, event-driven or glitched timestamps dealt with.

    A time column rounded in print (Tracker's 3 significant figures) is rebuilt as the
    evenly spaced times it rounds; an event-driven log (a row each time the signal moves
    by one step) keeps its uneven times; a few repeated or backward timestamps are set to
    the middle of their neighbours, or dropped. Each repair adds a note.
    """
    if t.size < 4 or (np.all(np.diff(t) > 0) and _timestamp_problem(t) is None):
        return t, x, False
    label = _describe(table, time_index)
    rebuilt = _unrounded_times(table, time_index, t)
    if rebuilt is not None:
        t, model = rebuilt
        step = float(np.median(np.diff(t)))
        notes.append(f"time column {label} is rounded ({model}); times rebuilt as evenly "
                     f"spaced, step {step:.6g} s ({1 / step:.6g} Hz)")
        return t, x, False
    event_step = _event_step(x)
    if event_step is not None:
        same = np.flatnonzero(np.diff(t) == 0)
        if same.size and np.all(np.diff(t) >= 0):
            keep = np.ones(t.size, dtype=bool)
            keep[same] = False  # of rows sharing a timestamp, the last is the state then
            t, x = t[keep], x[keep]
            notes.append(f"{same.size} rows sharing their timestamp with the next row "
                         "dropped (the last row of each time kept)")
        notes.append(f"an event-driven log (a row each time the signal moves by "
                     f"{event_step:g}): its uneven time steps are real and kept")
        return t, x, True
    steps = np.diff(t)
    if np.all(steps > 0):
        return t, x, False
    repaired = _mend_glitches(t)
    if repaired is None:
        return t, x, False
    t_new, keep, fixed, first = repaired
    bad = fixed + int(np.count_nonzero(~keep))
    what = []
    if fixed:
        what.append(f"{fixed} set to the middle of their neighbours")
    if not keep.all():
        what.append(f"{int(np.count_nonzero(~keep))} rows dropped")
    notes.append(f"{bad} glitched timestamps (repeated or stepping back) in {label}, the "
                 f"first at data row {first + 1}: " + ", ".join(what))
    return t_new[keep], x[keep], False


def _mend_glitches(t):
    """(times, rows kept, number set right, first glitch) for a few glitched timestamps,
    or None when there are too many or they cannot be told from the rest.

    A glitch is a time off the local run of the clock: t_i - i*step against its running
    median over five rows differs by more than half a step. A glitch between two good
    rows is set to their middle; other glitches, and rows that still do not increase
    (kept by the longest increasing run), are dropped.
    """
    steps = np.diff(t)
    step = float(np.median(steps))
    if not step > 0:
        return None
    limit = _MAX_GLITCH_FRACTION * steps.size
    drift = t - step * np.arange(t.size)
    window = np.lib.stride_tricks.sliding_window_view(np.pad(drift, 2, mode="edge"), 5)
    glitch = np.abs(drift - np.median(window, axis=1)) > 0.5 * step
    if not glitch.any() or np.count_nonzero(glitch) > limit:
        glitch = np.zeros(t.size, dtype=bool)
    t = t.copy()
    keep = ~glitch
    fixed = 0
    for i in np.flatnonzero(glitch):
        if 0 < i < t.size - 1 and not glitch[i - 1] and not glitch[i + 1] and (
                t[i - 1] < t[i + 1]):
            t[i] = 0.5 * (t[i - 1] + t[i + 1])
            keep[i] = True
            fixed += 1
    order = np.flatnonzero(keep)
    increasing = order[_longest_increasing(t[order])]
    if fixed + t.size - increasing.size > limit:
        return None
    keep = np.zeros(t.size, dtype=bool)
    keep[increasing] = True
    bad = glitch | ~keep
    return t, keep, fixed, int(np.flatnonzero(bad)[0])


def _longest_increasing(t):
    """Indices of a longest strictly increasing subsequence of ``t`` (patience sorting)."""
    import bisect
    tails, tail_index = [], []
    previous = np.full(t.size, -1, dtype=np.intp)
    for i, value in enumerate(t.tolist()):
        k = bisect.bisect_left(tails, value)
        if k == len(tails):
            tails.append(value)
            tail_index.append(i)
        else:
            tails[k] = value
            tail_index[k] = i
        previous[i] = tail_index[k - 1] if k else -1
    out = []
    i = tail_index[-1] if tail_index else -1
    while i >= 0:
        out.append(i)
        i = previous[i]
    return np.array(out[::-1], dtype=np.intp)


def _event_step(x):
    """The step of an event-driven log (nearly every row moves the signal by one step),
    else None."""
    finite = x[np.isfinite(x)]
    if finite.size < 20:
        return None
    moves = np.abs(np.diff(finite))
    moving = moves[moves > 0]
    if moving.size < 0.9 * moves.size:
        return None
    step = moving.min()
    if np.count_nonzero(np.abs(moving - step) <= 1e-9 * max(step, 1e-300)) < 0.9 * moves.size:
        return None
    return float(step)


_DECIMAL_TOKEN = re.compile(r"^[+-]?(\d*)(?:\.(\d*))?(?:[eE]([+-]?\d+))?$")


def _print_resolutions(tokens):
    """Ways the times may have been printed, as (description, value -> resolution): to a
    fixed number of decimals, or of significant figures (Tracker's default). Tokens with
    fewer digits (trailing zeros left out) are exact at the finer resolution too."""
    decimals, figures = 0, 0
    for token in tokens:
        match = _DECIMAL_TOKEN.match(token.strip())
        if not match or not (match.group(1) or match.group(2)) or match.group(3) is not None:
            return []
        whole, fraction = match.group(1), match.group(2) or ""
        decimals = max(decimals, len(fraction))
        figures = max(figures, len((whole + fraction).lstrip("0")))
    if figures == 0 or decimals > 12:
        return []

    def fixed(v):
        return np.full(v.shape, 10.0 ** -decimals)

    def significant(v):
        magnitude = np.floor(np.log10(np.maximum(np.abs(v), 1e-300)))
        return 10.0 ** (magnitude - figures + 1)
    return [(f"to {decimals} decimals", fixed), (f"to {figures} significant figures",
                                                 significant)]


def _unrounded_times(table, time_index, t):
    """(evenly spaced times, how they were rounded) when ``t`` is an evenly sampled time
    rounded in print, else None. The line a + b*i is the one that stays closest to every
    time in units of its rounding (a linear programme); rounding explains the times when
    no time is further from it than half its last printed digit."""
    tokens = []
    for line in table.token_lines[:2000]:
        fields = _split(line.strip(), table.sep) if line.strip() else []
        if len(fields) > time_index and fields[time_index]:
            tokens.append(fields[time_index])
    if len(tokens) < 20 or t.size < 20 or not np.all(np.isfinite(t)):
        return None
    # Samples in equal groups per timestamp (2, 2, 2...) fit a rounded clock as well as
    # bursts; with a fixed number of decimals they are taken for bursts, as the logger's
    # own stamps. Rounding to significant figures changes the group size with the time.
    _, groups = np.unique(t, return_counts=True)
    regular = bool(np.all(groups[1:-1] == groups[1])) if groups.size > 2 else True
    for how, resolution in _print_resolutions(tokens):
        if regular and "decimals" in how:
            continue
        line = _line_within(t, 0.5 * resolution(t))
        if line is not None:
            return line, how
    return None


def _line_within(t, half):
    """a + b*i, shape (n,), within ``half`` of every ``t`` with b > 0, or None."""
    from scipy.optimize import linprog
    i = np.arange(t.size, dtype=np.float64)
    # minimise s subject to |a + b*i - t| <= s*half  (variables a, b, s)
    ones = np.ones(t.size)
    a_ub = np.block([[ones[:, None], i[:, None], -half[:, None]],
                     [-ones[:, None], -i[:, None], -half[:, None]]])
    b_ub = np.concatenate([t, -t])
    result = linprog([0.0, 0.0, 1.0], A_ub=a_ub, b_ub=b_ub,
                     bounds=[(None, None), (None, None), (0, None)], method="highs")
    if not result.success or result.x[2] > 1.0 + 1e-6 or result.x[1] <= 0:
        return None
    a, b = result.x[0], result.x[1]
    return a + b * i
