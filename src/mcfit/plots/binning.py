"""Measured points for the panels against amplitude: damping rates, Q and periods from the
turning points, and their medians in amplitude bins (numpy and scipy)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import median_abs_deviation

from mcfit.turning.common import HALF_CYCLE_SPACING

__all__ = ["Binned", "binned_medians", "binned_rates", "pair_rates", "full_periods"]

# sqrt(pi/2): the standard error of a median over that of a mean, for Gaussian scatter.
_MEDIAN_EFFICIENCY = math.sqrt(math.pi / 2)
_FEWEST_FOR_BINS = 6


@dataclass(frozen=True)
class Binned:
    """Medians of ``y`` in bins of ``x`` holding (nearly) equal numbers of points.

    ``x`` is the median of ``x`` in each bin, ``y`` the median of ``y``, ``error`` the
    standard error of that median, ``count`` the points in the bin.
    """

    x: np.ndarray
    y: np.ndarray
    error: np.ndarray
    count: np.ndarray


def binned_medians(x, y, bins=None) -> Binned:
    """Medians of ``y`` in amplitude bins of equal counts, robust to outliers.

    Parameters
    ----------
    x, y : array_like, shape (n,)
        Amplitudes and the quantity measured at them (independent values); non-finite
        pairs are dropped.
    bins : int, optional
        Number of bins [default: n // 8, between 3 and 10]. Fewer than 6 points give none.
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    finite = np.isfinite(x) & np.isfinite(y)
    x, y = x[finite], y[finite]
    if x.size < _FEWEST_FOR_BINS:
        return _no_bins()
    mid, median, error, sizes = [], [], [], []
    for group in np.array_split(np.argsort(x, kind="stable"), bins or _bin_count(x.size)):
        values = y[group]
        centre = float(np.median(values))
        spread = float(median_abs_deviation(values, scale="normal"))
        if spread == 0 and values.size > 1:  # coarse steps (frame times): most values tie
            spread = float(np.std(values, ddof=1))
        mid.append(float(np.median(x[group])))
        median.append(centre)
        error.append(_MEDIAN_EFFICIENCY * spread / math.sqrt(values.size))
        sizes.append(values.size)
    return Binned(np.array(mid), np.array(median), np.array(error), np.array(sizes))


def binned_rates(t, y, sigma, bins=None, noise_scale=1.0) -> Binned:
    """The damping rate -d(ln y)/dt in bins of consecutive turning points (equal counts),
    robust to outliers, with its standard error from the amplitudes' ``sigma``.

    In a bin of n points the rate is the median of the n//2 slopes of ln y between points
    half the bin apart (k and k + ceil(n/2)); these pairs share no point, so the slopes
    are independent and the median's error is sqrt(pi/2) times that of their mean,
    sqrt(sum of var_k)/(n//2) with var_k = ((sigma/y)_k**2 + (sigma/y)_(k+h)**2)/dt_k**2,
    times ``noise_scale`` (the fit's sqrt of reduced chi-square, when above 1). Only crests
    clear of the noise (above 3 sigma) are taken. ``x`` is each bin's geometric-mean
    amplitude.
    """
    t, y, sigma = (np.asarray(v, dtype=float) for v in (t, y, sigma))
    keep = np.isfinite(t) & np.isfinite(y) & np.isfinite(sigma) & (y > 3 * sigma)
    t, y, sigma = t[keep], y[keep], sigma[keep]
    if t.size < _FEWEST_FOR_BINS:
        return _no_bins()
    mid, rate, error, sizes = [], [], [], []
    for group in np.array_split(np.arange(t.size), bins or _bin_count(t.size)):
        n = group.size
        h = (n + 1) // 2
        start, end = group[: n - h], group[h:]
        if start.size < 1:
            continue
        dt = t[end] - t[start]
        slopes = np.log(y[start] / y[end]) / dt
        variance = ((sigma[start] / y[start]) ** 2 + (sigma[end] / y[end]) ** 2) / dt**2
        mid.append(float(np.exp(np.mean(np.log(y[group])))))
        rate.append(float(np.median(slopes)))
        error.append(_MEDIAN_EFFICIENCY * noise_scale * math.sqrt(float(variance.sum()))
                     / start.size)
        sizes.append(n)
    return Binned(np.array(mid), np.array(rate), np.array(error), np.array(sizes))


def _bin_count(n):
    return int(np.clip(n // 8, 3, 10))


def _no_bins():
    empty = np.empty(0)
    return Binned(empty, empty, empty, np.empty(0, dtype=int))


def pair_rates(t, y, sigma):
    """-(dy/dt)/y between turning points ``span`` apart (long enough to beat the noise):
    (amplitude at the pair's geometric mean, rate, span). Only crests clear of the noise
    (above 3 sigma) are taken: the logarithm of a crest near the noise is mostly noise."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    span = max(1, t.size // 25)
    if t.size <= span:
        return np.empty(0), np.empty(0), span
    duration, start, end = t[span:] - t[:-span], y[:-span], y[span:]
    valid = (start > 3 * sigma[:-span]) & (end > 3 * sigma[span:]) & (duration > 0)
    rate = np.log(start[valid] / end[valid]) / duration[valid]
    return np.sqrt(start[valid] * end[valid]), rate, span


def full_periods(t, y, period):
    """Periods measured as the time from a crest to the next of the same side, two
    half-periods, so that an offset equilibrium (which lengthens one half and shortens the
    other) cancels: (amplitude of the middle crest, period). Only runs of consecutive
    crests about half a period apart are taken (a gap or a skipped crest breaks them)."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    if t.size < 3 or not (math.isfinite(period) and period > 0):
        return np.empty(0), np.empty(0)
    low, high = HALF_CYCLE_SPACING
    spacing = np.diff(t) / period
    regular = (spacing > low) & (spacing < high)
    keep = regular[:-1] & regular[1:]
    return y[1:-1][keep], (t[2:] - t[:-2])[keep]
