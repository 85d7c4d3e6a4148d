"""The period from the crest times, and its change with amplitude."""

from __future__ import annotations

import math

import numpy as np

from mcfit.turning.common import HALF_CYCLE_SPACING, _median


def _period_estimate(centres, signs, valid, period):
    """Twice the median spacing of neighbouring valid crests of opposite sign (``period``
    when fewer than two are one half-cycle apart)."""
    pairs = valid[:-1] & valid[1:] & (signs[:-1] != signs[1:])
    spacing = np.diff(centres)[pairs]
    low, high = (fraction * period for fraction in HALF_CYCLE_SPACING)
    spacing = spacing[(spacing > low) & (spacing < high)]
    return float(2 * _median(spacing)) if spacing.size >= 2 else period


def _period_and_drift(centres, signs, y, used, period, weights=None):
    """Period from the crest times and its relative change with amplitude."""
    pairs = used[:-1] & used[1:] & (signs[:-1] != signs[1:])
    spacing = np.diff(centres)
    low, high = (fraction * period for fraction in HALF_CYCLE_SPACING)
    ok = pairs & (spacing > low) & (spacing < high)
    halves = spacing[ok]
    if halves.size < 2:
        return period, float("nan"), float("nan"), float("nan")
    result = 2 * float(np.mean(halves))
    result_sigma = 2 * float(np.std(halves, ddof=1) / np.sqrt(halves.size))
    if weights is not None:
        result, result_sigma = _period_by_crest_times(centres, signs, used, result, weights,
                                                      result_sigma)
    # Full periods from same-sign neighbours cancel the max/min crest-time asymmetry.
    triple = used[:-2] & used[1:-1] & used[2:] & ok[:-1] & ok[1:]
    if np.count_nonzero(triple) < 4:
        return result, result_sigma, float("nan"), float("nan")
    middle = np.flatnonzero(triple) + 1
    full = centres[middle + 1] - centres[middle - 1]
    amplitude = y[middle]
    spread = np.ptp(amplitude)
    if spread <= 0:
        return result, result_sigma, float("nan"), float("nan")
    # Centred (better conditioned; the slope is the same), in units of the power of two
    # at the spread (an exact scaling): polyfit squares them, which underflows near 1e-160.
    unit = math.ldexp(1.0, math.frexp(spread)[1])
    centred = (amplitude - np.mean(amplitude)) / unit
    fit, covariance = np.polyfit(centred, full, 1, cov="unscaled")
    residual = full - np.polyval(fit, centred)
    dof = max(full.size - 2, 1)
    s2 = float(np.dot(residual, residual) / dof)
    variance = float(covariance[0, 0]) * s2
    if not (np.isfinite(variance) and variance >= 0):  # amplitudes too alike to tell
        return result, result_sigma, float("nan"), float("nan")
    slope_sigma = float(np.sqrt(variance))
    drift = float(fit[0] * (spread / unit) / result)
    drift_sigma = float(slope_sigma * (spread / unit) / result)
    return result, result_sigma, drift, drift_sigma


def _period_by_crest_times(times, signs, used, period, weights, fallback_sigma):
    """Period and its standard error from a weighted straight line through the crest times
    against half-cycle number, with an offset between maxima and minima.

    The mean of the half-cycle spacings depends on the first and last crest alone, which
    are often the faintest; the line weighs every crest by the inverse variance of its
    phase. The noise scale is estimated from the residuals, so a period that drifts with
    amplitude widens the error rather than hiding in it.
    """
    keep = used & (weights > 0) & np.isfinite(times)
    if np.count_nonzero(keep) < 5:
        return period, fallback_sigma
    t = times[keep]
    number = np.round((t - t[0]) / (0.5 * period))
    design = np.column_stack([np.ones_like(t), 0.5 * number, 0.5 * signs[keep]])
    root = np.sqrt(weights[keep] / np.max(weights[keep]))
    weighted = design * root[:, None]
    solution, _, rank, _ = np.linalg.lstsq(weighted, t * root, rcond=None)
    dof = t.size - 3
    if rank < 3 or dof <= 0 or np.unique(number).size != number.size:
        return period, fallback_sigma
    residual = (t - design @ solution) * root
    covariance = np.linalg.pinv(weighted.T @ weighted)
    variance = covariance[1, 1] * float(residual @ residual) / dof
    return float(solution[1]), float(np.sqrt(max(variance, 0.0)))
