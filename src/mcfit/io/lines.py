"""How clearly a column oscillates: the strongest spectral line of its values over the
noise floor around it (numpy only; a bounded sample of the column, so the cost stays small).

A line is a peak of the periodogram of the detrended column that stands above the median
power on both sides of it (from half its frequency to twice it): white noise, a counter,
a clock and a slow drift have none (a drift's power falls with frequency, so the side
below the peak is the higher), an oscillation at a steady period has one.
"""

from __future__ import annotations

import numpy as np

# At most this many values of a column are looked at (every k-th, over the whole sample).
_MAX_POINTS = 1 << 15
# A line needs at least this many cycles in the values looked at, and this many values.
_MIN_CYCLES = 8
_MIN_POINTS = 64
# Bins either side of a peak left out of its floor (a Hann window's main lobe and a
# decaying oscillation's width), and the local maxima tried as peaks.
_GUARD = 3
_PEAKS_TRIED = 8
# A column oscillates when its line stands this many times above its floor: white noise
# of 16384 bins reaches about 15 (the largest of them over their median).
LINE_RATIO = 40.0
# Lines this strong are all clean: beyond it the order of the file decides.
_CLEAN_RATIO = 1e6
# A column whose steps are this often one and the same non-zero step counts or clocks.
_STEADY_STEPS = 0.9


def line_strength(values):
    """The power of the strongest spectral line of ``values`` over the noise floor beside
    it, at most :data:`_CLEAN_RATIO`; 0 for too few values, a constant, a counter or a
    clock. A column oscillates when this is at least :data:`LINE_RATIO`.

    Parameters
    ----------
    values : ndarray, shape (n,)
        A column as read (NaN where empty); only every k-th finite value is looked at, at
        most :data:`_MAX_POINTS` of them.
    """
    v = values[np.isfinite(values)]
    if v.size > _MAX_POINTS:
        v = v[::-(-v.size // _MAX_POINTS)]
    if v.size < _MIN_POINTS or _counts(v):
        return 0.0
    index = np.arange(v.size, dtype=np.float64)
    v = v - v.mean()
    centred = v - np.polyval(np.polyfit(index, v, 1), index)
    if not np.any(np.abs(centred) > 1e-9 * max(np.abs(v).max(), 1e-300)):
        return 0.0  # a straight line: its residual is rounding
    power = np.abs(np.fft.rfft(centred * np.hanning(v.size))) ** 2
    return min(_best_ratio(power), _CLEAN_RATIO)


def _counts(v):
    """Whether most steps of ``v`` are one and the same non-zero step (a counter, a clock,
    a sawtooth of either)."""
    steps, counts = np.unique(np.diff(v), return_counts=True)
    top = int(np.argmax(counts))
    return steps[top] != 0 and counts[top] >= _STEADY_STEPS * (v.size - 1)


def _best_ratio(power):
    """The largest ratio of a local maximum of ``power`` (among the strongest ones) to the
    floor beside it: the larger of the medians below and above it."""
    top = power.size - 1
    lo = _MIN_CYCLES
    if top - lo < 2 * _GUARD:
        return 0.0
    inner = power[lo:top]
    maxima = np.flatnonzero((inner >= power[lo - 1:top - 1]) & (inner >= power[lo + 1:top + 1]))
    if maxima.size == 0:
        return 0.0
    peaks = maxima[np.argsort(inner[maxima])[::-1][:_PEAKS_TRIED]] + lo
    best = 0.0
    for k in peaks:
        below = power[max(1, k // 2):k - _GUARD]
        above = power[k + _GUARD + 1:min(top, 2 * k) + 1]
        sides = [np.median(side) for side in (below, above) if side.size]
        floor = max(sides) if sides else 0.0
        ratio = power[k] / floor if floor > 0 else _CLEAN_RATIO
        best = max(best, ratio)
    return float(best)
