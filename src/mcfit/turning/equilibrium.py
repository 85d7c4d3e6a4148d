"""The equilibrium line: coarse, refined from the alternation of the crests, and for tables."""

from __future__ import annotations

import numpy as np

from mcfit.turning.common import _BLOCK_SAMPLES, _CREST_BLOCK, _median, _segment_groups
from mcfit.turning.windows import _pooled_noise

# Coefficients of the sixth, fourth and second differences, the highest first.
_DIFFERENCES = (np.array([1.0, -6.0, 15.0, -20.0, 15.0, -6.0, 1.0]),
                np.array([1.0, -4.0, 6.0, -4.0, 1.0]), np.array([1.0, -2.0, 1.0]))
# Windows of crests one half-period apart enough to leave out those across a gap.
_CLEAN_WINDOWS = 8
# Windows that a difference of an order needs before a lower one is taken instead.
_ORDER_WINDOWS = 3
# The envelope divided out of the crests decays only between crests this many standard
# errors clear of the noise.
_CLEAR_Z = 10.0


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


def _equilibrium_correction(centres, fit, half, t_ref, gamma=None, duration=np.inf):
    """(d0, d1): equilibrium error from the alternation of the amplitude sequence, in runs
    of consecutive crests (``half``: local half-periods; a gap breaks a run).

    ``gamma`` (rows: decay rate and its slope at each crest, as the window fits take them)
    divides each window of crests by the envelope that rate gives before differencing, so
    that a fast decay's own trend does not read as an offset. Where the valid crests span
    half the record's ``duration`` at least, the drift is fitted from two windows up, of
    lower difference orders where there are too few crests for sixth differences: the
    coarse line's drift is biased by a fast decay. Crests over less of the record would
    set a drift over the rest, where the coarse line follows the signal better: there
    the sixth differences of three windows give the offset, of _CLEAN_WINDOWS the drift.
    """
    index = np.flatnonzero(fit.valid)
    spans = index.size > 1 and centres[index[-1]] - centres[index[0]] >= 0.5 * duration
    orders = _DIFFERENCES if spans else _DIFFERENCES[:1]
    coefficients, index = _difference_windows(centres, fit.valid, half, orders)
    if index.size < (1 if spans else _ORDER_WINDOWS):
        return 0.0, 0.0
    width = coefficients.size
    kappa = fit.offset_gain  # y_observed = y_true + kappa*(equilibrium error)
    with np.errstate(invalid="ignore"):
        clear = fit.valid & (fit.y > _CLEAR_Z * _pooled_noise(fit) * np.sqrt(fit.gain))
    log_envelope = _log_envelope(centres, gamma, clear)
    rows, f0, f1 = np.empty((3, index.size))
    for lo in range(0, index.size, _CREST_BLOCK):  # windows of 7 crests: 170 bytes each
        part = index[lo:lo + _CREST_BLOCK, None] + np.arange(width)
        # The window's crests over the envelope, scaled to 1 at its middle crest.
        scaled = coefficients * np.exp(log_envelope[part[:, width // 2:width // 2 + 1]]
                                       - log_envelope[part])
        k_window = kappa[part] * scaled
        rows[lo:lo + part.shape[0]] = np.sum(fit.y[part] * scaled, axis=1)
        f0[lo:lo + part.shape[0]] = k_window.sum(axis=1)
        f1[lo:lo + part.shape[0]] = np.sum(k_window * (centres[part] - t_ref), axis=1)
    drift_windows = 2 if spans else _CLEAN_WINDOWS
    design = np.array([f0, f1]).T if index.size >= drift_windows else f0[:, None]
    solution, *_ = np.linalg.lstsq(design, rows, rcond=None)
    if not np.isfinite(solution).all():
        return 0.0, 0.0
    # y_obs = y_true + kappa*(e_true - e_used): the correction adds the error to e.
    d0 = float(solution[0])
    d1 = float(solution[1]) if solution.size > 1 else 0.0
    return d0, d1


def _difference_windows(centres, valid, half, orders=_DIFFERENCES):
    """(coefficients, first crest of each window): the highest difference order of
    ``orders`` with _ORDER_WINDOWS windows of valid crests (else the one with the most
    windows), and its windows.

    Sixth differences remove the decay's smooth trend up to fifth order (second
    differences leave its curvature, which biases the offset when Q is low) while the
    alternation, at the sequence's Nyquist frequency, gains 64 against white noise's
    sqrt(924), more than second differences' 4 against sqrt(6); a record of a few crests
    has too few windows of seven.
    """
    # Across a gap the decay is not smooth in the crest index: windows whose neighbouring
    # crests are all about one half-period apart are used when there are enough of them;
    # otherwise every window, as a sparse record needs.
    step_ok = centres[1:] - centres[:-1] < 0.75 * (half[1:] + half[:-1])
    best = (orders[-1], np.zeros(0, dtype=np.int64))
    for coefficients in orders:
        width = coefficients.size
        if valid.size < width:
            continue
        window_valid = _all_within(valid, width)
        clean = window_valid & _all_within(step_ok, width - 1)
        if np.count_nonzero(clean) >= _CLEAN_WINDOWS:
            window_valid = clean
        index = np.flatnonzero(window_valid)
        if index.size >= _ORDER_WINDOWS:
            return coefficients, index
        if index.size > best[1].size:
            best = (coefficients, index)
    return best


def _log_envelope(centres, gamma, clear):
    """Log of the envelope exp(-integral of the decay rate) at each crest (0 at the
    first), from the rates ``gamma[0]`` by the trapezoid rule; zeros without them. The
    rate counts only at crests ``clear`` of the noise: in the noise it is the noise's, and
    an envelope from it would weight the crests at random."""
    if gamma is None or not np.any(gamma[0]):
        return np.zeros(centres.size)
    rate = np.where(clear, gamma[0], 0.0)
    integral = 0.5 * (rate[1:] + rate[:-1]) * np.diff(centres)
    return -np.concatenate([[0.0], np.cumsum(integral)])


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
