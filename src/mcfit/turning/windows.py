"""Stage 3: least-squares fits over the half-cycle windows, and the local period and decay
rate they need."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special

from mcfit.turning.common import (_BLOCK_SAMPLES, HALF_CYCLE_SPACING, _amplitude_sigma,
                                  _running_median)


@dataclass
class MeasuredCrests:
    """The refined crests measured by one more pass of half-cycle fits."""

    centres: np.ndarray
    signs: np.ndarray
    fit: object  # _WindowFits
    noise_sigma: float  # sample noise from the fit residuals (else the spectrum's)
    magnitude: np.ndarray  # |amplitude| of each two-parameter fit
    magnitude_sigma: np.ndarray
    measured: np.ndarray  # valid and not clipped

    @property
    def crest_times(self):
        """Window centres moved to the fitted crests where the fit is valid."""
        return self.centres + np.where(self.fit.valid, self.fit.shift, 0.0)


def _measure(t, x, crests, noise):
    """Fit the half-cycles of the refined ``crests`` once more and measure the crests."""
    half = _local_half_periods(crests.centres, crests.period, crests.valid)
    fit = _fit_windows(t, x, crests.centres, crests.signs, half, crests.gamma, *crests.line)
    noise_sigma = _pooled_noise(fit)
    if not np.isfinite(noise_sigma):
        noise_sigma = noise
    return MeasuredCrests(
        centres=crests.centres, signs=crests.signs, fit=fit, noise_sigma=noise_sigma,
        magnitude=np.abs(fit.y), magnitude_sigma=_amplitude_sigma(noise_sigma, fit.gain),
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
        self.peak = np.zeros(k)       # fitted extreme value of x (equilibrium included)
        self.at_max = np.zeros(k, dtype=np.int64)  # samples at the record's max / min level
        self.at_min = np.zeros(k, dtype=np.int64)


def _fit_windows(t, x, centres, signs, half, gamma, e0, e1, t_ref):
    """Least-squares fit of exp(-g*s - h*s**2/2)*(A cos ws + B sin ws) over each half-cycle.

    ``gamma`` holds g (row 0) and h = dg/dt (row 1) at each crest."""
    k = centres.size
    out = _WindowFits(k)
    lo = np.searchsorted(t, centres - 0.5 * half, side="left")
    hi = np.searchsorted(t, centres + 0.5 * half, side="left")
    lo[1:] = np.maximum(lo[1:], hi[:-1])  # windows must not share samples
    hi = np.maximum(hi, lo)
    omega = np.pi / half
    top = float(np.max(x))
    bottom = float(np.min(x))
    tolerance = 1e-9 * (top - bottom)
    out.edge = (centres - 0.5 * half < t[0]) | (centres + 0.5 * half > t[-1])
    first = 0
    while first < k:
        # Windows whose samples fit in one block.
        cumulative = np.cumsum(hi[first:] - lo[first:])
        last = first + max(1, int(np.searchsorted(cumulative, _BLOCK_SAMPLES, side="right")))
        last = min(last, k)
        sel = slice(first, last)
        lengths = hi[sel] - lo[sel]
        total = int(lengths.sum())
        count = last - first
        starts = np.cumsum(lengths) - lengths
        nonempty = lengths > 0
        window = np.repeat(np.arange(count), lengths)
        index = np.arange(total) + np.repeat(lo[sel] - starts, lengths)
        tt = t[index]
        xx = x[index]
        s = tt - centres[sel][window]
        r = xx - (e0 + e1 * (tt - t_ref))
        ws = omega[sel][window] * s
        envelope = np.exp(-(gamma[0][sel][window] + 0.5 * gamma[1][sel][window] * s) * s)
        u1 = envelope * np.cos(ws)
        u2 = envelope * np.sin(ws)
        # Windows are contiguous runs of the gathered samples: sum each run at once.
        columns = np.empty((10, total))
        for row, (left, right) in enumerate(((u1, u1), (u1, u2), (u2, u2), (u1, r), (u2, r),
                                             (u1, 1.0), (u2, 1.0), (r, r))):
            np.multiply(left, right, out=columns[row])
        np.greater_equal(xx, top - tolerance, out=columns[8])
        np.less_equal(xx, bottom + tolerance, out=columns[9])
        sums = np.zeros((columns.shape[0], count))
        s_min = np.full(count, np.inf)
        s_max = np.full(count, -np.inf)
        max_step = np.zeros(count)
        if total:
            begin = starts[nonempty]
            sums[:, nonempty] = np.add.reduceat(columns, begin, axis=1)
            s_min[nonempty] = s[begin]
            s_max[nonempty] = s[begin + lengths[nonempty] - 1]
            # Largest step inside each window: a gap.
            step = np.diff(tt, prepend=tt[0])
            step[begin] = 0.0
            max_step[nonempty] = np.maximum.reduceat(step, begin)
        s11, s12, s22, b1, b2, s1, s2, rr, at_max, at_min = sums
        del tt, xx, s, r, ws, envelope, u1, u2, index, window, columns

        det = s11 * s22 - s12 * s12
        good = (lengths >= 3) & (det > 1e-12 * np.maximum(s11 * s22, 1e-300))
        det = np.where(good, det, 1.0)
        a = (s22 * b1 - s12 * b2) / det
        b = (s11 * b2 - s12 * b1) / det
        sg = signs[sel]
        angle = np.arctan2(sg * b, sg * a)  # crest phase: cos(w*s - angle) = sign there
        shift = angle / omega[sel]
        decay = np.exp(-(gamma[0][sel] + 0.5 * gamma[1][sel] * shift) * shift)
        g1 = sg * decay * np.cos(angle)
        g2 = sg * decay * np.sin(angle)
        y_signed = (a * g1 + b * g2) * sg
        gain = (g1 * g1 * s22 - 2 * g1 * g2 * s12 + g2 * g2 * s11) / det
        c1 = (s22 * s1 - s12 * s2) / det
        c2 = (s11 * s2 - s12 * s1) / det
        offset_gain = g1 * c1 + g2 * c2
        rss = np.maximum(rr - a * b1 - b * b2, 0.0)
        span = s_max - s_min
        hs = half[sel]
        complete = ((lengths >= 3) & (s11 > 0) & (span >= 0.4 * hs) & (s_min < 0.1 * hs)
                    & (s_max > -0.1 * hs) & (max_step < 0.5 * hs))
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
        out.y[sel] = y_signed * sg  # amplitude along the expected sign (< 0 if wrong)
        out.shift[sel] = shift
        out.gain[sel] = np.where(good, gain, np.inf)
        out.offset_gain[sel] = np.where(good, offset_gain, 0.0)
        out.rss[sel] = rss
        out.count[sel] = lengths
        out.valid[sel] = valid & (out.y[sel] > 0)
        out.peak[sel] = (e0 + e1 * (centres[sel] + shift - t_ref)) + sg * out.y[sel]
        out.at_max[sel] = at_max.astype(np.int64)
        out.at_min[sel] = at_min.astype(np.int64)
        first = last
    out.y = np.abs(out.y)  # envelope amplitude (already positive for valid windows)
    return out


def _pooled_noise(fit):
    """Sample noise sigma from the fit residuals: median of the per-window variances."""
    dof = fit.count - 2
    ok = fit.valid & (dof >= 2)
    if np.count_nonzero(ok) < 3:
        return float("nan")
    variance = fit.rss[ok] / dof[ok]
    # Each window's variance is sigma**2 * chi2(dof)/dof: rescale by its median (chdtri
    # gives the quantile of stats.chi2.median without the distribution's overhead).
    normalized = variance / (special.chdtri(dof[ok], 0.5) / dof[ok])
    return float(np.sqrt(np.median(normalized)))


def _clipped(fit, signs):
    """Crests flattened at the record's extreme level (saturation)."""
    clipped = np.zeros(signs.size, dtype=bool)
    for count in (np.where(signs > 0, fit.at_max, 0), np.where(signs < 0, fit.at_min, 0)):
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
    spacing = np.diff(centres[index]) / np.maximum(np.diff(index), 1)
    low, high = (2 * fraction * nominal for fraction in HALF_CYCLE_SPACING)
    spacing = np.where((spacing > low) & (spacing < high), spacing, nominal)
    if spacing.size >= 5:  # the spacing of noisy crests scatters: smooth it over 5 crests
        spacing = _running_median(spacing, 5)
    middle = 0.5 * (centres[index][1:] + centres[index][:-1])
    if middle.size == 1:
        return np.full(centres.size, spacing[0])
    return np.interp(centres, middle, spacing)


def _local_decay_rates(centres, y, omega, valid):
    """Rows (g, dg/dt): -d ln(y)/dt at each crest from valid neighbours, smoothed, and its
    slope; 0 where unknown. The slope lets a window's envelope, exp(-g*s - dg/dt*s**2/2),
    follow a decay rate that changes within the half-cycle (low Q with fluid or Coulomb
    damping), which would otherwise bias the amplitudes."""
    index = np.flatnonzero(valid & (y > 0))
    if index.size < 3:
        return np.zeros((2, centres.size))
    log_y = np.log(y[index])
    rate = -np.diff(log_y) / np.diff(centres[index])
    if rate.size >= 7:
        rate = _running_median(rate, 7)
    middle = 0.5 * (centres[index][1:] + centres[index][:-1])
    gamma = np.clip(_interpolate_extending_ends(centres, middle, rate), -0.3 * omega,
                    0.3 * omega)
    slope = np.zeros(centres.size)
    if rate.size >= 7:
        slope = _interpolate_extending_ends(
            centres, middle[1:-1], (rate[2:] - rate[:-2]) / (middle[2:] - middle[:-2]))
        # Under the law |dg/dt| = |c/y**2 - a|*P(y) <= g**2 (|n - 1|*g**2 for dy/dt =
        # -k*y**n): twice that bounds a slope from noisy or gapped rates, which could
        # otherwise bend a window's envelope by 10 %.
        limit = np.minimum(2.0 * gamma**2, 0.1 * omega**2)
        slope = np.clip(_running_median(slope, 7), -limit, limit)
    return np.vstack([gamma, slope])


def _interpolate_extending_ends(x, xp, fp):
    """np.interp, but continued past the first and last points by the parabola through the
    three outermost ones, not held flat: the first and last crests lie half an interval
    beyond the outermost rate midpoints, where the decay rate of a low-Q record still
    curves (a straight continuation leaves 1e-5 errors in the first amplitudes at Q 12)."""
    values = np.interp(x, xp, fp)
    if xp.size >= 3:
        for outside, ends in ((x < xp[0], slice(0, 3)), (x > xp[-1], slice(-3, None))):
            if np.any(outside):
                values[outside] = _parabola(x[outside], xp[ends], fp[ends])
    elif xp.size == 2:
        slope = (fp[1] - fp[0]) / (xp[1] - xp[0])
        values = np.where(x < xp[0], fp[0] + (x - xp[0]) * slope, values)
        values = np.where(x > xp[1], fp[1] + (x - xp[1]) * slope, values)
    return values


def _parabola(x, xp, fp):
    """The quadratic through three points (xp, fp), evaluated at x (Lagrange form)."""
    (x0, x1, x2), (f0, f1, f2) = xp, fp
    return (f0 * (x - x1) * (x - x2) / ((x0 - x1) * (x0 - x2))
            + f1 * (x - x0) * (x - x2) / ((x1 - x0) * (x1 - x2))
            + f2 * (x - x0) * (x - x1) / ((x2 - x0) * (x2 - x1)))


def _decay_rates_at(crests, centres, magnitude, omega, reliable):
    """Decay rate and its slope (rows) at ``crests``, from the reliable crests among
    ``centres``, held at the value of the nearest reliable crest beyond them."""
    gamma = _local_decay_rates(centres, magnitude, omega, reliable)
    index = np.flatnonzero(reliable)
    if index.size == 0:
        return np.zeros((2, crests.size))
    return np.vstack([np.interp(crests, centres[index], row[index]) for row in gamma])
