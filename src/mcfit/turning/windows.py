"""Stage 3: least-squares fits over the half-cycle windows, and the local period and decay
rate they need."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special

from mcfit.turning.common import (_BLOCK_SAMPLES, HALF_CYCLE_SPACING, _amplitude_sigma, _median,
                                  _running_median)


@dataclass
class MeasuredCrests:
    """The refined crests measured by one more pass of half-cycle fits."""

    centres: np.ndarray
    signs: np.ndarray
    valid: np.ndarray  # the half-cycle fit is valid
    shift: np.ndarray  # fitted crest time minus window centre
    gain: np.ndarray  # var(amplitude) / sigma**2 of the fit
    noise_sigma: float  # sample noise from the fit residuals (else the spectrum's)
    magnitude: np.ndarray  # |amplitude| of each two-parameter fit
    magnitude_sigma: np.ndarray
    measured: np.ndarray  # valid and not clipped

    @property
    def crest_times(self):
        """Window centres moved to the fitted crests where the fit is valid."""
        return self.centres + np.where(self.valid, self.shift, 0.0)


def _measure(samples, crests, noise):
    """Fit the half-cycles of the refined ``crests`` once more and measure the crests.

    Only the fits' columns the later stages read are kept: the others (nine arrays of
    the crests' size, 140 MB at 2x10^6 crests) are freed before the crest phase is
    smoothed and the amplitudes projected."""
    half = _local_half_periods(crests.centres, crests.period, crests.valid)
    fit = _fit_windows(samples, crests.centres, crests.signs, half, crests.gamma, *crests.line)
    noise_sigma = _pooled_noise(fit)
    if not np.isfinite(noise_sigma):
        noise_sigma = noise
    return MeasuredCrests(
        centres=crests.centres, signs=crests.signs, valid=fit.valid, shift=fit.shift,
        gain=fit.gain, noise_sigma=noise_sigma, magnitude=np.abs(fit.y),
        magnitude_sigma=_amplitude_sigma(noise_sigma, fit.gain),
        measured=fit.valid & ~_clipped(fit, crests.signs))


class _WindowFits:
    """Per-window results of the half-cycle fits."""

    def __init__(self, k):
        self.y = np.zeros(k)          # signed amplitude (sign * envelope at the crest)
        self.shift = np.zeros(k)      # crest time minus window centre
        self.gain = np.full(k, np.inf)  # var(y) / sigma**2
        self.offset_gain = np.zeros(k)  # dy / d(equilibrium error)
        self.rss = np.zeros(k)
        self.count = np.zeros(k, dtype=np.int64)
        self.valid = np.zeros(k, dtype=bool)
        self.complete = np.zeros(k, dtype=bool)  # the window covers its half-cycle, no gap
        self.edge = np.zeros(k, dtype=bool)
        self.projection = np.zeros(k)  # amplitude with the crest fixed at the centre
        self.projection_gain = np.full(k, np.inf)  # var(projection) / sigma**2
        self.phase_sensitivity = np.zeros(k)  # d(projection)/d(crest phase) / projection
        self.at_max = np.zeros(k, dtype=np.int64)  # samples at the record's max / min level
        self.at_min = np.zeros(k, dtype=np.int64)
        self.quantum = 0.0  # the grid of the record's values near its extremes (0: none)


@dataclass(frozen=True)
class Samples:
    """The finite samples of a record, with what every pass of half-cycle fits needs of
    them, found once: the samples at the record's largest and smallest level (within
    1e-9 of its range, for clipping) and, where several sit there, the quantum of the
    values near those levels (0 for values not on a grid)."""

    t: np.ndarray
    x: np.ndarray
    at_top: np.ndarray
    at_bottom: np.ndarray
    quantum: float = 0.0

    @classmethod
    def of(cls, t, x):
        """Samples ``t``, ``x``."""
        top = float(np.max(x))
        bottom = float(np.min(x))
        tolerance = 1e-9 * (top - bottom)
        at_top, at_bottom = (np.flatnonzero(x >= top - tolerance),
                             np.flatnonzero(x <= bottom + tolerance))
        quantum = (_quantum(x, top, bottom) if max(at_top.size, at_bottom.size) >= 2
                   else 0.0)
        return cls(t, x, at_top, at_bottom, quantum)

    def wide_steps(self, limit):
        """(index i, step t[i+1] - t[i]) of the time steps of at least ``limit``, taken
        _BLOCK_SAMPLES at a time: a record-sized array of steps (80 MB at 10^7 samples)
        is not kept for the few wide ones."""
        index, steps = [np.zeros(0, dtype=np.intp)], [np.zeros(0)]
        for lo in range(0, self.t.size - 1, _BLOCK_SAMPLES):
            block = np.diff(self.t[lo:lo + _BLOCK_SAMPLES + 1])
            wide = np.flatnonzero(block >= limit)
            index.append(wide + lo)
            steps.append(block[wide])
        return np.concatenate(index), np.concatenate(steps)


def _quantum(x, top, bottom):
    """The smallest step between the distinct values within a tenth of the range of
    either extreme (an ADC's count), or 0 where it is under 1e-6 of the range."""
    span = top - bottom
    near = x[(x >= top - 0.1 * span) | (x <= bottom + 0.1 * span)]
    steps = np.diff(np.unique(near))
    step = float(np.min(steps[steps > 0], initial=span))
    return step if step >= 1e-6 * span else 0.0


def _fit_windows(samples, centres, signs, half, gamma, e0, e1, t_ref):
    """Least-squares fit of exp(-g*s - h*s**2/2)*(A cos ws + B sin ws) over each half-cycle
    of ``samples`` (:class:`Samples`).

    ``gamma`` holds g (row 0) and h = dg/dt (row 1) at each crest. All windows at once:
    the samples of every window are gathered into one array (in blocks of
    _BLOCK_SAMPLES) and the sums of each window's run taken in one pass."""
    t, x = samples.t, samples.x
    k = centres.size
    out = _WindowFits(k)
    lo = np.searchsorted(t, centres - 0.5 * half, side="left")
    hi = np.searchsorted(t, centres + 0.5 * half, side="left")
    lo[1:] = np.maximum(lo[1:], hi[:-1])  # windows must not share samples
    hi = np.maximum(hi, lo)
    out.edge = (centres - 0.5 * half < t[0]) | (centres + 0.5 * half > t[-1])
    out.count = hi - lo
    out.quantum = samples.quantum
    out.at_max, out.at_min = (np.searchsorted(where, hi) - np.searchsorted(where, lo)
                              for where in (samples.at_top, samples.at_bottom))
    unbroken = _without_gaps(samples, lo, hi, half)
    first = 0
    cumulative = np.cumsum(hi - lo)
    while first < k:
        # Windows whose samples fit in one block.
        before = int(cumulative[first - 1]) if first else 0
        last = first + max(1, int(np.searchsorted(cumulative[first:], before + _BLOCK_SAMPLES,
                                                  side="right")))
        last = min(last, k)
        sel = slice(first, last)
        sums = _window_sums(t, x, lo[sel], hi[sel], centres[sel], np.pi / half[sel],
                            gamma[:, sel], (e0, e1, t_ref))
        _solve_windows(out, sel, sums, t, lo[sel], hi[sel], centres, signs, half, gamma,
                       unbroken[sel])
        first = last
    out.y = np.abs(out.y)  # envelope amplitude (already positive for valid windows)
    return out


def _without_gaps(samples, lo, hi, half):
    """Whether each window ``lo:hi`` of ``samples`` has no time step of half its
    half-period or more."""
    limit = 0.5 * half
    wide, steps = samples.wide_steps(np.min(limit, initial=np.inf))
    unbroken = np.ones(lo.size, dtype=bool)
    if wide.size == 0:  # the usual case: no step can break a window
        return unbroken
    # The widest step inside each window, from the few wide ones (steps lo..hi-2).
    begin = np.searchsorted(wide, lo)
    end = np.searchsorted(wide, np.maximum(hi - 1, lo))
    some = end > begin
    widest = np.maximum.reduceat(np.append(steps, 0.0),
                                 np.column_stack([begin[some], end[some]]).ravel())[::2]
    unbroken[some] = widest < limit[some]
    return unbroken


def _window_sums(t, x, lo, hi, centres, omega, gamma, line):
    """Rows (s11, s12, s22, b1, b2, s1, s2, rr) of sums over each window's samples of
    u1*u1, u1*u2, u2*u2, u1*r, u2*r, u1, u2, r*r, with u1, u2 the envelope times cos and
    sin and r the signal about the equilibrium line; zeros for empty windows."""
    e0, e1, t_ref = line
    lengths = hi - lo
    total = int(lengths.sum())
    sums = np.zeros((8, lengths.size))
    nonempty = lengths > 0
    if total == 0:
        return sums
    starts = np.cumsum(lengths) - lengths
    index = np.arange(total) + np.repeat(lo - starts, lengths)
    tt = t[index]
    s = tt - np.repeat(centres, lengths)
    columns = np.empty((8, total))
    u1, u2, r = columns[5], columns[6], columns[7]
    np.subtract(x[index], e0 + e1 * (tt - t_ref), out=r)
    del tt, index
    # u1 + i*u2 = exp(-g*s - h*s**2/2 + i*w*s): one complex exponential, not cos, sin,
    # exp and two products (the envelope is 1 before the decay rates are known).
    exponent = np.empty(total, dtype=complex)
    np.multiply(np.repeat(omega, lengths), s, out=exponent.imag)
    exponent.real = 0.0
    if np.any(gamma):
        exponent.real -= (np.repeat(gamma[0], lengths)
                          + 0.5 * np.repeat(gamma[1], lengths) * s) * s
    del s
    np.exp(exponent, out=exponent)
    u1[:], u2[:] = exponent.real, exponent.imag
    del exponent
    for row, (left, right) in enumerate(((u1, u1), (u1, u2), (u2, u2), (u1, r), (u2, r))):
        np.multiply(left, right, out=columns[row])
    r *= r
    sums[:, nonempty] = np.add.reduceat(columns, starts[nonempty], axis=1)
    return sums


def _solve_windows(out, sel, sums, t, lo, hi, centres, signs, half, gamma, unbroken):
    """Fill ``out[sel]`` from the window sums: the two-parameter fit, the crest phase,
    the projection with the crest fixed, and whether the window is complete."""
    s11, s12, s22, b1, b2, s1, s2, rr = sums
    lengths = hi - lo
    centres, sg, half, gamma = centres[sel], signs[sel], half[sel], gamma[:, sel]
    omega = np.pi / half
    det = s11 * s22 - s12 * s12
    good = (lengths >= 3) & (det > 1e-12 * np.maximum(s11 * s22, 1e-300))
    det = np.where(good, det, 1.0)
    # The fit (a, b) and its change with the equilibrium (c1, c2): the inverse of the
    # 2x2 normal matrix on the right-hand sides (b1, b2) and (s1, s2), all rows at once.
    a, b, c1, c2 = (sums[[2, 0, 2, 0]] * sums[[3, 4, 5, 6]] - s12 * sums[[4, 3, 6, 5]]) / det
    angle = np.arctan2(sg * b, sg * a)  # crest phase: cos(w*s - angle) = sign there
    shift = angle / omega
    decay = sg * np.exp(-(gamma[0] + 0.5 * gamma[1] * shift) * shift)
    g1 = decay * np.cos(angle)
    g2 = decay * np.sin(angle)
    y_signed = (a * g1 + b * g2) * sg
    gain = (g1 * g1 * s22 - 2 * g1 * g2 * s12 + g2 * g2 * s11) / det
    offset_gain = g1 * c1 + g2 * c2
    rss = _above_rounding(rr - a * b1 - b * b2, rr, lengths)
    # The first and last sample of each window, relative to its centre (windows of fewer
    # than 3 samples are incomplete whatever these are).
    s_min = t[np.minimum(lo, t.size - 1)] - centres
    s_max = t[np.maximum(hi - 1, 0)] - centres
    complete = ((lengths >= 3) & (s11 > 0) & (s_max - s_min >= 0.4 * half)
                & (s_min < 0.1 * half) & (s_max > -0.1 * half) & unbroken)
    valid = complete & good & (np.abs(angle) < 0.5 * np.pi)
    # With the phase known, one free parameter: linear in the data, so unbiased however
    # small the crest (the magnitude of the two-parameter fit is not).
    s11_safe = np.where(s11 > 0, s11, 1.0)
    out.projection[sel] = np.where(complete, sg * b1 / s11_safe, 0.0)
    out.projection_gain[sel] = np.where(complete, 1.0 / s11_safe, np.inf)
    # Moving the crest by a phase d changes the projection by -y*d*s12/s11 to first
    # order: nothing for a symmetric window, the most for a window cut at its crest.
    out.phase_sensitivity[sel] = np.where(complete, -s12 / s11_safe, 0.0)
    out.complete[sel] = complete
    y = y_signed * sg  # amplitude along the expected sign (< 0 if wrong)
    out.y[sel] = y
    out.shift[sel] = shift
    out.gain[sel] = np.where(good, gain, np.inf)
    out.offset_gain[sel] = np.where(good, offset_gain, 0.0)
    out.rss[sel] = rss
    out.valid[sel] = valid & (y > 0)


# A window's residual sum of squares, rr - a*b1 - b*b2, cancels terms of the size of rr:
# rounding leaves about sqrt(n)*eps*rr of it (n samples), whatever the record's noise.
# Below this many times that it is rounding, not noise: a noise-free record's windows give
# up to 0.6 of it, noise of 1e-7 of the amplitude about 100 (tests/test_package.py).
_ROUNDING_FLOOR = 16.0


def _above_rounding(rss, rr, lengths):
    """The windows' residual sums of squares ``rss``, 0 where they are within the
    rounding of the normal equations' sums (``rr``, the signal's sum of squares, over
    ``lengths`` samples): a noise-free record then has noise 0 on any machine, not the
    last bits of its floating point, which differ between processors."""
    floor = _ROUNDING_FLOOR * np.finfo(float).eps * np.sqrt(np.maximum(lengths, 1)) * rr
    return np.where(rss > floor, rss, 0.0)


def _pooled_noise(fit):
    """Sample noise sigma from the fit residuals: median of the per-window variances."""
    dof = fit.count - 2
    ok = fit.valid & (dof >= 2)
    if np.count_nonzero(ok) < 3:
        return float("nan")
    variance = fit.rss[ok] / dof[ok]
    # Each window's variance is sigma**2 * chi2(dof)/dof: rescale by its median (chdtri
    # gives the quantile of stats.chi2.median without the distribution's overhead).
    # Windows of a record have a few lengths only: the quantile once for each.
    lengths, which = np.unique(dof[ok], return_inverse=True)
    normalized = variance / (special.chdtri(lengths, 0.5)[which] / dof[ok])
    return float(np.sqrt(_median(normalized)))


def _clipped(fit, signs):
    """Crests flattened at the record's extreme level (saturation). On a grid of values
    (an ADC's counts) a crest of amplitude A stays within one count q of its top for about
    1 + (samples a cycle/pi)*sqrt(2q/A) samples: only a longer run at the level is a
    rail."""
    clipped = np.zeros(signs.size, dtype=bool)
    if fit.at_max.max(initial=0) < 2 and fit.at_min.max(initial=0) < 2:
        return clipped  # the usual case: no window has two samples at either level
    top_run = 1.0 + (2 * fit.count / np.pi) * np.sqrt(
        2 * fit.quantum / np.maximum(np.abs(fit.y), 1e-300))
    for count in (np.where(signs > 0, fit.at_max, 0), np.where(signs < 0, fit.at_min, 0)):
        if fit.quantum > 0:
            clipped |= count > 2 * top_run
            continue
        hits = count >= 2
        if np.count_nonzero(hits) >= 2 or np.any(count >= 3):
            clipped |= hits
    return clipped


def _local_half_periods(centres, period, valid):
    """Half-period at each crest from the spacing of valid neighbours, robust to misses."""
    nominal = 0.5 * period
    index = np.flatnonzero(valid)
    if index.size < 2:
        return np.full(centres.size, nominal)
    at = centres[index]
    spacing = (at[1:] - at[:-1]) / np.maximum(index[1:] - index[:-1], 1)
    low, high = (2 * fraction * nominal for fraction in HALF_CYCLE_SPACING)
    spacing = np.where((spacing > low) & (spacing < high), spacing, nominal)
    if spacing.size >= 5:  # the spacing of noisy crests scatters: smooth it over 5 crests
        spacing = _running_median(spacing, 5)
    middle = 0.5 * (at[1:] + at[:-1])
    if middle.size == 1:
        return np.full(centres.size, spacing[0])
    return np.interp(centres, middle, spacing)


def _local_decay_rates(centres, y, omega, valid):
    """Rows (g, dg/dt): -d ln(y)/dt at each crest from valid neighbours, smoothed, and its
    slope; 0 where unknown. The slope lets a window's envelope, exp(-g*s - dg/dt*s**2/2),
    follow a decay rate that changes within the half-cycle (low Q with fluid or Coulomb
    damping), which would otherwise bias the amplitudes."""
    index = np.flatnonzero(valid & (y > 0))
    rows = np.zeros((2, centres.size))
    if index.size < 3:
        return rows
    at = centres[index]
    log_y = np.log(y[index])
    rate = (log_y[:-1] - log_y[1:]) / (at[1:] - at[:-1])
    middle = 0.5 * (at[1:] + at[:-1])
    if rate.size >= 7:
        rate = _running_median(rate, 7)
    else:
        # Too few for the median: rates between crests of one sign, which an offset of
        # the equilibrium moves alike, not in turn (the median of seven damps that).
        rate = (log_y[:-2] - log_y[2:]) / (at[2:] - at[:-2])
        middle = at[1:-1]
    bound = 0.3 * omega
    gamma = np.minimum(np.maximum(_interpolate_extending_ends(centres, middle, rate), -bound),
                       bound)
    rows[0] = gamma
    if rate.size >= 7:
        slope = _interpolate_extending_ends(
            centres, middle[1:-1], (rate[2:] - rate[:-2]) / (middle[2:] - middle[:-2]))
        # Under the law |dg/dt| = |c/y**2 - a|*P(y) <= g**2 (|n - 1|*g**2 for dy/dt =
        # -k*y**n): twice that bounds a slope from noisy or gapped rates, which could
        # otherwise bend a window's envelope by 10 %.
        limit = np.minimum(2.0 * gamma**2, 0.1 * omega**2)
        rows[1] = np.minimum(np.maximum(_running_median(slope, 7), -limit), limit)
    return rows


def _interpolate_extending_ends(x, xp, fp):
    """np.interp, but continued past the first and last points by the parabola through the
    three outermost ones, not held flat: the first and last crests lie half an interval
    beyond the outermost rate midpoints, where the decay rate of a low-Q record still
    curves (a straight continuation leaves 1e-5 errors in the first amplitudes at Q 12)."""
    values = np.interp(x, xp, fp)
    if xp.size >= 3:
        for outside, ends in ((x < xp[0], slice(0, 3)), (x > xp[-1], slice(-3, None))):
            if outside.any():
                values[outside] = _parabola(x[outside], xp[ends], fp[ends])
    elif xp.size == 2:
        slope = (fp[1] - fp[0]) / (xp[1] - xp[0])
        values = np.where(x < xp[0], fp[0] + (x - xp[0]) * slope, values)
        values = np.where(x > xp[1], fp[1] + (x - xp[1]) * slope, values)
    return values


def _parabola(x, xp, fp):
    """The quadratic through three points (xp, fp), evaluated at x (Lagrange form)."""
    (x0, x1, x2), (f0, f1, f2) = xp.tolist(), fp.tolist()
    d0, d1, d2 = (x0 - x1) * (x0 - x2), (x1 - x0) * (x1 - x2), (x2 - x0) * (x2 - x1)
    if x.size > 8:
        return (f0 * (x - x1) * (x - x2) / d0 + f1 * (x - x0) * (x - x2) / d1
                + f2 * (x - x0) * (x - x1) / d2)
    # Usually one or two crests past the ends: plain floats, the same operations.
    return np.array([f0 * (v - x1) * (v - x2) / d0 + f1 * (v - x0) * (v - x2) / d1
                     + f2 * (v - x0) * (v - x1) / d2 for v in x.tolist()])


def _decay_rates_at(crests, centres, magnitude, omega, reliable):
    """Decay rate and its slope (rows) at ``crests``, from the reliable crests among
    ``centres``, held at the value of the nearest reliable crest beyond them."""
    gamma = _local_decay_rates(centres, magnitude, omega, reliable)
    index = np.flatnonzero(reliable)
    if index.size == 0:
        return np.zeros((2, crests.size))
    return np.vstack([np.interp(crests, centres[index], row[index]) for row in gamma])
