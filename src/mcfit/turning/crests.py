"""Stage 5: the crest sequence (smoothed phase, crests filled in and continued) and the
amplitudes as projections onto it."""

from __future__ import annotations

import math

import numpy as np

from mcfit.turning.common import _CREST_BLOCK, _amplitude_sigma, _running_median
from mcfit.turning.windows import (_clipped, _decay_rates_at, _fit_windows,
                                   _local_half_periods)

# Crests either side of each one in the local fit of crest time against crest number.
_PHASE_HALF_WIDTH = 10
# Beyond this phase variance (rad**2) a crest's phase is mostly noise: its projection's
# bias is corrected no further.
_LARGEST_PHASE_VARIANCE = 1.0
# A faint tail, from the first crest where the running median of the smoothed phase's
# variance passes this (rad**2; 0.1 rad), is left out where it is longer than
# _LONG_FAINT_TAIL crests: over a long faint tail, numbered against the bright crests by
# a line continued past them, a noise crest slips the phase by a radian, and the
# projections come out low (a decay that seems to speed up: false Coulomb and fluid
# terms); it carries little on the decay. A short faint end (a decay of tens of
# cycles into the noise or to a Coulomb stop) keeps its crests: they are unbiased there
# and carry a Coulomb term.
_KEPT_PHASE_VARIANCE = 0.01
_LONG_FAINT_TAIL = 200
# Crests whose phase is known to 0.1 rad (inverse variance 100 rad**-2) are numbered
# reliably by their spacing; the others are numbered against them (_renumbered).
_RELIABLE_PHASE_WEIGHT = 100.0
# A smoothed crest phase this certain (rad**2) keeps the local quadratic, which follows an
# amplitude-dependent period without bias, whatever a line's variance.
_CERTAIN_PHASE_VARIANCE = 1e-3
# Crests above this many amplitude sigmas set the decay rates of the projection windows.
_RELIABLE_SNR = 5.0
# Crests in the running median that stands for the envelope in the phase scatter.
_ENVELOPE_CRESTS = 9


def _projected_crests(samples, m, period, line, decay, limit):
    """Crest times from the phase of the crests ``decay`` (a slice) of the measured crests
    ``m``, continued to ``limit``, and amplitudes as projections onto that phase
    (docs/theory.md section 8: near the noise a magnitude is biased, a projection is not).

    Returns the columns (t, sign, y, sigma, log_step, reason) and the time from which the
    crest phase is lost in the noise (None if it is not).
    """
    half = _local_half_periods(m.centres, period, m.valid)
    weights = np.where(m.measured, _phase_weights(m.magnitude, m.magnitude_sigma), 0.0)
    crests, crest_signs, phase_variance, phase_lost = _crest_sequence(
        m.crest_times[decay], m.signs[decay], half[decay], weights[decay], limit)
    del weights
    faint = _faint_from(phase_variance)
    if crests.size - faint > _LONG_FAINT_TAIL:  # a long tail whose phase is not known
        phase_lost = float(crests[faint])
        crests, crest_signs, phase_variance = (crests[:faint], crest_signs[:faint],
                                               phase_variance[:faint])
    in_decay = np.zeros(m.centres.size, dtype=bool)
    in_decay[decay] = True
    reliable = m.measured & in_decay & (m.magnitude > _RELIABLE_SNR * m.magnitude_sigma)
    crest_gamma = _decay_rates_at(crests, m.centres, m.magnitude, np.pi / half, reliable)
    del half, in_decay, reliable  # the measured crests' columns: not needed from here on
    crest_half = _local_half_periods(crests, period, np.ones(crests.size, dtype=bool))
    projected = _fit_windows(samples, crests, crest_signs, crest_half, crest_gamma, *line)
    keep = projected.count > 0  # crests filled in across a long gap have no samples
    if not keep.all():
        crests, crest_signs = crests[keep], crest_signs[keep]
        crest_half, crest_gamma = crest_half[keep], crest_gamma[:, keep]
        phase_variance = phase_variance[keep]
        projected = _fit_windows(samples, crests, crest_signs, crest_half, crest_gamma, *line)
    y, sigma_y = _phase_corrected(projected, phase_variance, m.noise_sigma)
    columns = (crests, crest_signs, y, sigma_y, crest_gamma[0] * crest_half,
               _window_reasons(projected, crest_signs))
    return columns, phase_lost


def _phase_corrected(projected, phase_variance, noise_sigma):
    """(y, sigma) of the projections, corrected for the error of the crest phase.

    A phase error d scales a projection by cos(d), on average by exp(-var(d)/2) for a
    Gaussian error: undone here. It matters in the faint tail, where the crest times are
    least certain (there var(d) reaches about 0.1 at a few sigma).

    The phase error also scatters the projection, y*(cos(d) + k*sin(d)) with k the
    window's phase sensitivity (0 when symmetric, about 0.64 when cut at the crest):
    var = y**2*((1 - e**-v)**2 + k**2*(1 - e**-2v))/2, here with y from the running
    median of its neighbours: from the crest itself, a crest raised by noise would get a
    larger sigma and pull the fit down.
    """
    variance_d = np.minimum(np.nan_to_num(phase_variance, nan=0.0), _LARGEST_PHASE_VARIANCE)
    phase_gain = np.exp(0.5 * variance_d)
    y = projected.projection * phase_gain
    envelope = np.maximum(_running_median(y, _ENVELOPE_CRESTS), 0.0)
    sigma_y = _amplitude_sigma(noise_sigma, projected.projection_gain)
    for lo in range(0, y.size, _CREST_BLOCK):  # a block of crests at a time: temporaries
        part = slice(lo, lo + _CREST_BLOCK)
        v, gain = variance_d[part], phase_gain[part]
        sensitivity = projected.phase_sensitivity[part]
        sigma_y[part] = np.sqrt((sigma_y[part] * gain) ** 2 + (envelope[part] * gain) ** 2
                                / 2.0 * ((1.0 - np.exp(-v)) ** 2
                                         + sensitivity**2 * (1.0 - np.exp(-2.0 * v))))
    return y, sigma_y


def _window_reasons(projected, signs):
    """"edge", "gap" or "clipped" for the windows that cannot be used, else ""."""
    reasons = np.array([""] * signs.size, dtype=object)
    reasons[~projected.complete] = np.where(projected.edge[~projected.complete], "edge", "gap")
    reasons[(reasons == "") & _clipped(projected, signs)] = "clipped"
    return reasons


def _with_excluded(m, free, floor_start, columns):
    """The columns with the crests before the release (the first ``free``) and those from
    ``floor_start`` (in the floor) added, each with its half-cycle fit's magnitude."""
    parts = [_excluded_crests(slice(0, free), m.centres, m.signs, m.magnitude,
                              m.magnitude_sigma, "before release"), columns]
    if floor_start is not None:
        parts.append(_excluded_crests(slice(floor_start, None), m.centres, m.signs,
                                      m.magnitude, m.magnitude_sigma, "noise floor"))
    return tuple(np.concatenate(c) for c in zip(*parts))


def _crest_numbers(times, signs, half):
    """Whole half-periods from the first crest: each step is the nearest whole number of
    local half-periods whose parity agrees with the signs (odd when they alternate)."""
    if times.size < 2:
        return np.zeros(times.size, dtype=np.int64)
    ratio = np.diff(times) / (0.5 * (half[1:] + half[:-1]))
    step = np.maximum(np.rint(ratio), 1.0)
    wrong = (step % 2 == 1) != (signs[1:] != signs[:-1])
    nearer = np.where(ratio > step, step + 1, step - 1)
    step = np.where(wrong, np.where(nearer >= 1, nearer, step + 1), step)
    return np.concatenate([[0], np.cumsum(step)]).astype(np.int64)


def _smooth_crest_times(numbers, times, weights, count):
    """Crest times at numbers 0..count-1: a weighted local quadratic in the crest number
    over 2*_PHASE_HALF_WIDTH + 1 crests (tricube kernel), local linear where too few crests
    are measured, and past the last measured crest the straight line continuing it.

    ``weights`` are the inverse variances of the measured crest phases (rad**-2).

    Returns (times, half-period at the last measured crest, phase variance, growth). The
    variance (rad**2) of each smoothed crest phase is that of a linear smoother,
    ``e1' M^-1 N M^-1 e1`` with ``M`` the kernel-weighted and ``N`` the squared-kernel-
    weighted moments. ``growth`` = (covariance of the last measured crest's phase with the
    continuing slope, variance of that slope) per crest: the variance ``k`` crests further
    on is ``variance[last] + 2*k*growth[0] + k**2*growth[1]``.
    """
    have = weights > 0
    first, last = numbers[have][0], numbers[have][-1]
    slope = (times[have][-1] - times[have][0]) / max(last - first, 1)
    origin = times[have][0] - first * slope
    w = np.zeros(count)
    r = np.zeros(count)
    n_measured = min(last + 1, count)
    inside = numbers < count
    w[numbers[inside]] = weights[inside]
    r[numbers[inside]] = (times - (origin + numbers * slope))[inside]
    smooth = np.full(count, np.nan)
    variance = np.full(count, np.nan)
    local_slope = np.full(count, np.nan)
    at_last = None
    # In blocks of crests: each crest's fit is its own, and the moment matrices of all
    # would take 0.6 kB a crest.
    for lo in range(0, count, _CREST_BLOCK):
        hi = min(lo + _CREST_BLOCK, count)
        fits = _local_fits(w, r, lo, hi)
        smooth[lo:hi], variance[lo:hi], local_slope[lo:hi] = fits[:3]
        if lo <= last < hi:
            at_last = [part[last - lo] for part in fits[3:]]
    linear_last, row3_last, spread3_last, inverse2_last = at_last
    grid = np.arange(count)
    known = np.isfinite(smooth[:n_measured])
    if not known.any():
        return origin + grid * slope, slope, np.full(count, np.nan), (np.nan, np.nan)
    # Across a stretch with no measured crest in reach, both are interpolated (the variance
    # a little low there).
    for values in (smooth, variance):
        values[:n_measured] = np.interp(grid[:n_measured], grid[:n_measured][known],
                                        values[:n_measured][known])
    tail_slope = local_slope[last] if linear_last else 0.0
    growth = (np.nan, np.nan)
    if linear_last and np.isfinite(smooth[last]):
        slope_row = inverse2_last[1]
        growth = (float(row3_last @ spread3_last[:, :2] @ slope_row),
                  float(slope_row @ spread3_last[:2, :2] @ slope_row))
    beyond = grid > last
    steps = grid[beyond] - last
    smooth[beyond] = smooth[last] + tail_slope * steps
    variance[beyond] = _continued_variance(variance[last], growth, steps)
    return origin + grid * slope + smooth, slope + tail_slope, variance, growth


def _local_fits(w, r, lo, hi):
    """The local fits of _smooth_crest_times at crests ``lo:hi``: (smoothed offset,
    phase variance, local slope, whether the line is determined, the weights of the fit
    on the moments, the squared-kernel moment matrix, the inverse 2x2 moment matrix), one
    row per crest."""
    moment, spread, target, points = _kernel_sums(w, r, lo, hi)
    count = hi - lo
    # Per crest: the 3x3 and 2x2 moment matrices (quadratic, linear), and the cross
    # moments of the two fits (3x2), all Hankel in the moments.
    hankel3 = np.array([[i + j for j in range(3)] for i in range(3)])
    matrix3 = np.moveaxis(moment[hankel3], -1, 0)
    matrix2 = matrix3[:, :2, :2]
    spread3 = np.moveaxis(spread[hankel3], -1, 0)
    row3 = np.full((count, 3), np.nan)  # the quadratic fit's weights on the moments
    with np.errstate(divide="ignore", invalid="ignore"):
        det3 = np.linalg.det(matrix3)
        quadratic = (points >= 4) & (np.abs(det3) > 1e-12 * moment[0] ** 3)
        if np.any(quadratic):
            row3[quadratic] = np.linalg.inv(matrix3[quadratic])[:, 0]
        det2 = moment[0] * moment[2] - moment[1] ** 2
        linear = (points >= 2) & (det2 > 1e-12 * moment[0] ** 2)
        inverse2 = np.zeros((count, 2, 2))
        inverse2[linear] = np.linalg.inv(matrix2[linear])
        row2 = np.column_stack([inverse2[:, 0], np.zeros(count)])
        variance2 = np.einsum("ij,ijk,ik->i", row2, spread3, row2)
        variance3 = np.einsum("ij,ijk,ik->i", row3, spread3, row3)
        # The line gives the crest time where the quadratic is not determined, or is far
        # less certain than the line and not certain in itself (few crests measured on
        # one side: an edge, or crests lost in the noise), where its curvature is noise.
        fill = linear & ~(quadratic & ((variance3 <= 2.0 * variance2)
                                       | (variance3 <= _CERTAIN_PHASE_VARIANCE)))
        row3[fill] = row2[fill]
        smooth = np.einsum("ij,ji->i", row3, target)
        variance = np.where(fill, variance2, variance3)
        local_slope = np.einsum("ij,ji->i", inverse2[:, 1], target[:2])
    return smooth, variance, local_slope, linear, row3, spread3, inverse2


def _kernel_sums(w, r, lo=0, hi=None):
    """(moment, spread, target, points) about each crest m of ``lo:hi`` (default all):
    rows p of sum_d K(d) d**p w(m+d) (p < 5), of sum_d K(d)**2 d**p w(m+d) (p < 5, for
    the variances), of sum_d K(d) d**p w(m+d) r(m+d) (p < 3), and the crests measured
    within reach; w and r are 0 beyond the ends. One product of the windows about every
    crest with the kernels."""
    hi = w.size if hi is None else hi
    reach = _PHASE_HALF_WIDTH
    padded = np.zeros((3, hi - lo + 2 * reach))
    # padded[:, j] holds crest lo - reach + j, where there is one.
    first, stop = max(lo - reach, 0), min(hi + reach, w.size)
    part = slice(first - (lo - reach), stop - (lo - reach))
    padded[0, part] = w[first:stop]
    padded[1, part] = w[first:stop] * r[first:stop]
    padded[2, part] = w[first:stop] > 0
    # windows[i, m] is padded[i, m:m + 2*reach + 1], a view.
    windows = np.ndarray((3, hi - lo, 2 * reach + 1), buffer=padded,
                         strides=(padded.strides[0], padded.itemsize, padded.itemsize))
    sums = windows @ _KERNEL_COLUMNS
    return sums[0, :, :5].T, sums[0, :, 5:10].T, sums[1, :, :3].T, sums[2, :, 10]


def _kernel_columns():
    """Columns K(d)*d**p (p < 5), K(d)**2*d**p (p < 5) and 1 over the smoother's reach
    d = -_PHASE_HALF_WIDTH.._PHASE_HALF_WIDTH, K the tricube kernel."""
    d = np.arange(-_PHASE_HALF_WIDTH, _PHASE_HALF_WIDTH + 1, dtype=np.float64)
    kernel = (1.0 - (np.abs(d) / (_PHASE_HALF_WIDTH + 1)) ** 3) ** 3
    return np.column_stack([kernel * d**p for p in range(5)]
                           + [kernel**2 * d**p for p in range(5)] + [np.ones(d.size)])


_KERNEL_COLUMNS = _kernel_columns()


def _continued_variance(variance, growth, steps):
    """Phase variance ``steps`` crests past the last measured one (see
    _smooth_crest_times)."""
    return variance + 2.0 * steps * growth[0] + steps**2 * growth[1]


def _phase_weights(magnitude, sigma):
    """Inverse variances (rad**-2) of crest phases measured with amplitude ``magnitude``
    and standard deviation ``sigma`` in each of the window's two components.

    The phase error is about B/A with A ~ N(y, sigma**2), B ~ N(0, sigma**2): its variance
    is sigma**2/y**2 * (1 + 3*sigma**2/y**2) to second order, and y**2 is estimated without
    the Rician bias as magnitude**2 - 2*sigma**2 (the weight is 0 where that is <= 0).
    """
    # In units of the power of two at the largest magnitude (an exact scaling): the squares
    # of amplitudes near 1e-300 would underflow, and the weights be 0/0.
    largest = float(np.max(magnitude, initial=0.0))
    if largest > 0 and np.isfinite(largest):
        unit = math.ldexp(1.0, math.frexp(largest)[1])
        magnitude, sigma, largest = magnitude / unit, sigma / unit, largest / unit
    floor = (1e-9 * largest) ** 2 + 1e-300  # a noise-free record
    variance = np.maximum(sigma**2, floor)
    square = np.maximum(magnitude**2 - 2.0 * variance, 0.0)
    return square**2 / (variance * (square + 3.0 * variance))


def _crest_sequence(times, signs, half, weights, limit):
    """Every crest from the first measured one to ``limit``: smoothed times, signs, the
    variance of each smoothed phase (rad**2; NaN where unknown), and the time of the first
    crest left out because its phase is lost (None if none is).

    ``times`` are measured crest times, ``weights`` the inverse variances of their phases
    (rad**-2; 0: not measured). Crests missed in between (noise) are filled in, and the
    sequence goes on past the last crest found, at the local half-period, to ``limit`` or
    until its phase variance passes _LARGEST_PHASE_VARIANCE (the phase is lost there).
    A measured crest with no other within the smoother's reach is left out: alone, it
    sets neither time nor slope.
    """
    if np.count_nonzero(weights > 0) < 3:
        return times, signs, np.full(times.size, np.nan), None
    numbers = _crest_numbers(times, signs, half)
    first_sign = signs[0]
    measured = weights > 0
    numbers, times, weights = numbers[measured], times[measured], weights[measured]
    signs = signs[measured]
    reliable = weights >= min(_RELIABLE_PHASE_WEIGHT, 0.1 * float(np.max(weights)))
    if np.count_nonzero(reliable) >= 3 and not reliable.all():
        numbers, times, weights = _renumbered(numbers, times, signs, weights, reliable,
                                              first_sign)
    gaps = np.diff(numbers)
    accompanied = np.minimum(np.concatenate([[np.inf], gaps]),
                             np.concatenate([gaps, [np.inf]])) <= _PHASE_HALF_WIDTH
    if np.count_nonzero(accompanied) >= 3:
        numbers, times, weights = numbers[accompanied], times[accompanied], weights[accompanied]
    count = int(numbers[-1]) + 1
    smooth, step, variance, growth = _smooth_crest_times(numbers, times, weights, count)
    phase_lost = None
    if step > 0 and smooth[-1] < limit:
        extra = int(np.floor((limit - smooth[-1]) / step))
        if extra > 0:
            last = int(numbers[-1])
            more = _continued_variance(variance[last], growth,
                                       np.arange(count, count + extra) - last)
            lost = np.flatnonzero(more > _LARGEST_PHASE_VARIANCE)
            if lost.size:  # not past the crest where the phase is lost
                extra = int(lost[0])
                phase_lost = float(smooth[-1] + step * (extra + 1))
            smooth = np.concatenate([smooth, smooth[-1] + step * np.arange(1, extra + 1)])
            variance = np.concatenate([variance, more[:extra]])
    grid = np.arange(smooth.size)
    crest_signs = np.where(grid % 2 == 0, first_sign, -first_sign).astype(signs.dtype)
    ordered = np.concatenate([[True], np.diff(smooth) > 0])
    return smooth[ordered], crest_signs[ordered], variance[ordered], phase_lost


def _faint_from(variance):
    """The start of the faint tail: the first crest where the running median of the
    smoothed phase variance passes _KEPT_PHASE_VARIANCE after the last where it is
    clearly known (within a quarter of that); the crests' size where there is none. A
    beat's node, where the phase is lost for a while and found again clearly, is no
    faint tail; a faint tail hovers about the limit, then leaves it."""
    typical = _running_median(np.nan_to_num(variance, nan=0.0), _ENVELOPE_CRESTS)
    clear = np.flatnonzero(typical <= 0.25 * _KEPT_PHASE_VARIANCE)
    if clear.size == 0:
        return variance.size
    lost = np.flatnonzero(typical[clear[-1]:] > _KEPT_PHASE_VARIANCE)
    return int(clear[-1] + lost[0]) if lost.size else variance.size


def _renumbered(numbers, times, signs, weights, reliable, first_sign):
    """(numbers, times, weights) of the measured crests, numbered by the smoothed times of
    the reliable ones instead of by their spacing.

    Numbering by spacing counts the half-periods between neighbours; in the faint tail one
    crest displaced by noise can make it count one period too many, and every later crest
    is then a period off. Here each crest takes the number of the nearest crest of its
    sign on the curve through the reliable crests (continued straight past its ends); a
    crest more than half a half-period from it, numbered < 0, or the weaker of two with
    one number is dropped.
    """
    count = int(numbers[reliable][-1]) + 1
    curve, end_step, _, _ = _smooth_crest_times(numbers[reliable], times[reliable],
                                                weights[reliable], count)
    grid = np.arange(count, dtype=np.float64)
    position = np.interp(times, curve, grid)
    start_step = curve[1] - curve[0]
    before, after = times < curve[0], times > curve[-1]
    position[before] = (times[before] - curve[0]) / start_step
    position[after] = count - 1 + (times[after] - curve[-1]) / end_step
    number = np.rint(position)
    # A crest of the wrong sign for its nearest number is more than half a half-period
    # from any crest of its own sign.
    expected_sign = np.where(number % 2 == 0, first_sign, -first_sign)
    keep = (number >= 0) & (expected_sign == signs)
    # One crest per number: the best measured.
    order = np.flatnonzero(keep)[np.lexsort((-weights[keep], number[keep]))]
    order = order[np.concatenate([[True], np.diff(number[order]) > 0])]
    return number[order].astype(np.int64), times[order], weights[order]



def _excluded_crests(select, centres, signs, magnitude, magnitude_sigma, reason):
    """Columns (t, sign, y, sigma, log_step, reason) of the crests ``select``, excluded for
    ``reason``, with the magnitudes of their half-cycle fits."""
    t = centres[select]
    return (t, signs[select], magnitude[select], magnitude_sigma[select],
            np.full(t.size, np.nan), np.full(t.size, reason, dtype=object))
