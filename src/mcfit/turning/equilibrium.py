"""The equilibrium line: coarse, refined from the alternation of the crests, and for tables."""

from __future__ import annotations

import numpy as np

from mcfit.turning.common import _BLOCK_SAMPLES, _CREST_BLOCK, _median, _segment_groups

# Coefficients of a sixth difference.
_SIXTH_DIFFERENCE = np.array([1.0, -6.0, 15.0, -20.0, 15.0, -6.0, 1.0])
# Sixth-difference windows needed to fit the equilibrium's drift as well as its offset.
_DRIFT_WINDOWS = 8


def _line_fit(t, x):
    """Least-squares straight line x = e0 + e1*(t - t_ref), computed in chunks."""
    t_ref = float(t[0] + 0.5 * (t[-1] - t[0]))
    n = t.size
    st = sx = stt = stx = 0.0
    for start in range(0, n, _BLOCK_SAMPLES):
        tt = t[start:start + _BLOCK_SAMPLES] - t_ref
        xx = x[start:start + _BLOCK_SAMPLES]
        st += tt.sum()
        sx += xx.sum()
        stt += np.dot(tt, tt)
        stx += np.dot(tt, xx)
    denominator = n * stt - st * st
    e1 = (n * stx - st * sx) / denominator if denominator > 0 else 0.0
    e0 = (sx - e1 * st) / n
    return float(e0), float(e1), t_ref


def _equilibrium_line(t, x, period, noise):
    """Coarse equilibrium line (e0, e1, t_ref), each period weighted by 1/(its swing)**2.

    An unweighted line through a fast decay (Q of a few) is pulled towards the first
    half-cycle, which can leave every later, smaller swing on one side of it and hide its
    crests. Weighting each period by its swing about the line lets the small late swings,
    which show the equilibrium best, set it; for a slow decay the weights are nearly equal
    and the line is the plain fit. The weight is capped at 1e12 times the largest swing's.
    """
    e0, e1, t_ref = _line_fit(t, x)
    edges = np.searchsorted(t, t[0] + period * np.arange(1, int((t[-1] - t[0]) / period) + 1))
    starts = np.unique(np.concatenate([[0], edges[edges < t.size]]))
    if starts.size < 3:
        return e0, e1, t_ref
    counts = np.diff(np.append(starts, t.size))
    groups = _segment_groups(starts, t.size)  # whole periods, a block of samples at a time
    parts = []
    for first, stop, lo, hi in groups:
        tau, xx = t[lo:hi] - t_ref, x[lo:hi]
        local = starts[first:stop] - lo
        parts.append([np.add.reduceat(v, local) for v in (tau, xx, tau * tau, tau * xx)])
    sums = [np.concatenate(column) for column in zip(*parts)]
    for _ in range(3):
        swing = np.concatenate([
            np.maximum.reduceat(np.abs(x[lo:hi] - (e0 + e1 * (t[lo:hi] - t_ref))),
                                starts[first:stop] - lo)
            for first, stop, lo, hi in groups])
        largest = float(np.max(swing))
        floor = 1e-6 * largest
        if np.isfinite(noise):
            floor = max(floor, 3.0 * noise)
        if not floor > 0:
            break
        weight = (largest / np.maximum(swing, floor)) ** 2  # relative: no overflow for tiny x
        sw = float(np.dot(weight, counts))
        st, sx, stt, stx = (float(np.dot(weight, s)) for s in sums)
        denominator = sw * stt - st * st
        if not denominator > 0:
            break
        e1 = (sw * stx - st * sx) / denominator
        e0 = (sx - e1 * st) / sw
    return float(e0), float(e1), t_ref


def _equilibrium_correction(centres, fit, half, t_ref):
    """(d0, d1): equilibrium error from the alternation of the amplitude sequence, in runs
    of consecutive crests (``half``: local half-periods; a gap breaks a run)."""
    valid = fit.valid
    y = fit.y
    kappa = fit.offset_gain  # y_observed = y_true + kappa*(equilibrium error)
    # Sixth differences: they remove the decay's smooth trend up to fifth order (second
    # differences leave its curvature, which biases the offset when Q is low) while the
    # alternation, at the sequence's Nyquist frequency, gains 64 against white noise's
    # sqrt(924), more than second differences' 4 against sqrt(6).
    coefficients = _SIXTH_DIFFERENCE
    width = coefficients.size
    if valid.size < width:
        return 0.0, 0.0
    window_valid = _all_within(valid, width)
    # Across a gap the decay is not smooth in the crest index: windows whose neighbouring
    # crests are all about one half-period apart are used when there are enough of them
    # to fit offset and drift; otherwise every window, as a sparse record needs.
    step_ok = centres[1:] - centres[:-1] < 0.75 * (half[1:] + half[:-1])
    clean = window_valid & _all_within(step_ok, width - 1)
    if np.count_nonzero(clean) >= _DRIFT_WINDOWS:
        window_valid = clean
    index = np.flatnonzero(window_valid)  # first point of each full window
    if index.size < 3:
        return 0.0, 0.0
    rows, f0, f1 = np.empty((3, index.size))
    for lo in range(0, index.size, _CREST_BLOCK):  # windows of 7 crests: 170 bytes each
        part = index[lo:lo + _CREST_BLOCK, None] + np.arange(width)
        k_window = kappa[part]
        rows[lo:lo + part.shape[0]] = y[part] @ coefficients
        f0[lo:lo + part.shape[0]] = k_window @ coefficients
        f1[lo:lo + part.shape[0]] = (k_window * (centres[part] - t_ref)) @ coefficients
    if index.size >= _DRIFT_WINDOWS:
        design = np.array([f0, f1]).T
    else:
        design = f0[:, None]
    solution, *_ = np.linalg.lstsq(design, rows, rcond=None)
    if not np.isfinite(solution).all():
        return 0.0, 0.0
    # y_obs = y_true + kappa*(e_true - e_used): the correction adds the error to e.
    d0 = float(solution[0])
    d1 = float(solution[1]) if solution.size > 1 else 0.0
    return d0, d1


def _all_within(flags, width):
    """Whether ``flags[i:i + width]`` are all true, for each i (a count by cumulative sum)."""
    count = np.concatenate([[0], np.cumsum(flags)])
    return count[width:] - count[:-width] == width


def _table_equilibrium(values):
    """Level about which maxima and minima give one smooth amplitude sequence.

    An error in the level raises one kind of extremum and lowers the other, which shows in
    the second differences of the amplitude sequence; choose the level that removes it.
    """
    level = float(_median(values))
    for _ in range(5):
        signs = np.where(values >= level, 1.0, -1.0)
        rows = np.diff(signs * (values - level), 2)
        feature = -np.diff(signs, 2)  # d(amplitude)/d(level) is -sign
        denominator = np.dot(feature, feature)
        if denominator == 0:
            break
        level -= float(np.dot(feature, rows) / denominator)
    return level
