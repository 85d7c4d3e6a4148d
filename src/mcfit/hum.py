"""Steady lines (mains hum and the like) far from the oscillation's frequency.

A free decay's line fades; a hum's does not. The strongest line of the record's periodogram
is compared with the strongest one more than ``_APART`` times above or below it (the first
one's harmonics left out): if one keeps its amplitude from the first to the last third of
the record and the other decays, the steady one is a hum. Its frequency is refined by
Gauss-Newton and it is subtracted with its harmonics by a least-squares fit over the whole
record, Hann-weighted so that the decaying oscillation leaks little into it. A steady line
beside an oscillation that does not decay clearly is left in and only reported.
numpy only, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SteadyLine", "find_steady_line", "subtract_steady_line", "peak_frequency"]

_APART = 3.0          # a hum lies more than this factor from the oscillation's frequency
_HARMONICS = 10       # harmonics of a hum fitted at most
_STEADY = 0.05        # |ln(last/first third amplitude)| of a steady line, beyond 4 sigma
_DECAYS = 0.1         # ln(ratio) below -this (beyond 4 sigma): the line decays
_RELATIVE = 1e-4      # lines below this fraction of the strongest are ignored
_CLEAR_BINS = 3       # bins kept clear around the oscillation's harmonics ...
_ORDERS = 10          # ... up to this order
_BLOCK = 1 << 20      # samples per block in the whole-record fits
_LOWEST_BIN = 9       # 3 cycles in each third of the stretch at least: slower is drift


@dataclass(frozen=True)
class SteadyLine:
    """A steady line: frequency (1/time unit), the oscillation's, harmonics fitted and
    their amplitudes; ``removed`` False when it is only reported."""

    frequency: float
    oscillation_frequency: float
    harmonics: tuple[int, ...] = (1,)
    amplitudes: tuple[float, ...] = ()
    coefficients: tuple[float, ...] = ()  # cos, sin per harmonic, about the record's middle
    removed: bool = False
    oscillation_amplitude: float = float("nan")
    t_mid: float = 0.0  # the time the coefficients' phases refer to

    def note(self):
        ratio = self.frequency / self.oscillation_frequency
        where = (f"frequency {self.frequency:.6g} per time unit ({ratio:.3g} times the "
                 f"oscillation's; period {1 / self.frequency:.4g})")
        if not self.removed:
            return (f"two steady lines, neither decaying clearly: a possible hum at {where}, "
                    f"amplitude {self.amplitudes[0]:.3g}, is left in; the line at frequency "
                    f"{self.oscillation_frequency:.6g} (amplitude "
                    f"{self.oscillation_amplitude:.3g}) is taken as the oscillation")
        extra = f" and {len(self.harmonics) - 1} harmonic(s)" if len(self.harmonics) > 1 else ""
        return (f"steady line (hum) removed before the turning points: {where}, amplitude "
                f"{self.amplitudes[0]:.3g}{extra}")


def find_steady_line(t, x, periodogram, noise):
    """A :class:`SteadyLine` in the record, or None.

    ``periodogram``: (frequencies, power, window sum, window sum of squares, bin of the
    strongest line, and optionally the grid bins per bin of the stretch's length: more
    than 1 when zero-padded, 1 if left out) of the record's Hann periodogram over a
    stretch from ``t[0]``;
    ``noise``: the sample noise sigma.
    """
    frequencies, power, window_sum, energy, k1, *padding = periodogram
    oversampling = padding[0] if padding else 1.0
    f1 = peak_frequency(power, frequencies, k1)
    k2 = _strongest_apart(frequencies, power, f1, oversampling)
    if k2 is None:
        return None
    a1, a2 = (2.0 * np.sqrt(power[k]) / window_sum for k in (k1, k2))
    if not a2 > _RELATIVE * a1:
        return None
    if not a2 > noise:  # noise from differences can hold the hum: the periodogram's floor
        noise = min(noise, np.sqrt(np.median(power) / (np.log(2) * energy)))
        if not a2 > noise:
            return None
    f2 = peak_frequency(power, frequencies, k2)
    span = oversampling / frequencies[1]  # the stretch's duration
    steady1, decays1 = _steadiness(t, x, f1, span, noise)
    steady2, decays2 = _steadiness(t, x, f2, span, noise)
    if steady2 and decays1:
        hum, oscillation = f2, f1
    elif steady1 and decays2:
        hum, oscillation = f1, f2
    elif steady1 and steady2:  # which one is the oscillation cannot be told
        return SteadyLine(f2, f1, amplitudes=(float(a2),), oscillation_amplitude=float(a1))
    else:
        return None
    hum = _refined(t, x, hum, span)
    harmonics = _harmonics(frequencies, power, window_sum, hum, oscillation,
                           max(noise, _RELATIVE * max(a1, a2)), oversampling)
    coefficients = _fit(t, x, hum, harmonics)
    amplitudes = tuple(float(np.hypot(*pair)) for pair in coefficients.reshape(-1, 2))
    return SteadyLine(float(hum), float(oscillation), harmonics, amplitudes,
                      tuple(float(c) for c in coefficients), removed=True,
                      t_mid=0.5 * float(t[0] + t[-1]))


def subtract_steady_line(t, x, line):
    """x without the fitted line (a new array)."""
    coefficients = np.array(line.coefficients)
    out = np.array(x, dtype=np.float64)
    t_mid = line.t_mid
    for start in range(0, t.size, _BLOCK):
        block = slice(start, start + _BLOCK)
        out[block] -= _sinusoids(t[block] - t_mid, line.frequency, line.harmonics) @ coefficients
    return out


def peak_frequency(power, frequencies, k):
    """Frequency of the line at bin k of a periodogram, from the parabola through the log
    power at bins k - 1, k and k + 1, its vertex kept between bins k - 1 and k + 1. At a
    local maximum the vertex lies within half a bin of k; at the edge of a band searched
    it may lie up to a bin away (a line just outside the band), but where the log power
    is nearly straight the vertex of the parabola lies anywhere (it put a hum at -816)."""
    if not 0 < k < power.size - 1:
        return float(frequencies[k])
    a, b, c = np.log(power[k - 1:k + 2] + 1e-300)
    denominator = a - 2 * b + c
    offset = 0.5 * (a - c) / denominator if denominator < 0 else 0.0
    return float((k + min(max(offset, -1.0), 1.0)) * frequencies[1])


def _strongest_apart(frequencies, power, f1, oversampling=1.0):
    """Bin of the strongest line more than _APART times from f1, off f1's harmonics
    (``oversampling``: grid bins per bin of the stretch's length, in which the bins of
    _LOWEST_BIN and _CLEAR_BINS count)."""
    apart = (frequencies < f1 / _APART) | (frequencies > f1 * _APART)
    apart[:int(np.ceil(_LOWEST_BIN * oversampling))] = False
    step = frequencies[1] * oversampling
    order = np.rint(frequencies / f1)
    apart &= (order < 1) | (order > _ORDERS) | (np.abs(frequencies - order * f1)
                                                  > _CLEAR_BINS * step)
    if not apart.any():
        return None
    candidates = np.flatnonzero(apart)
    return int(candidates[np.argmax(power[candidates])])


def _third_amplitudes(t, x, f, span):
    """Amplitudes at frequency f in the first and last thirds of [t0, t0 + span] (Hann
    weighted), and the gain sqrt(2*sum(w**2))/sum(w) of each (sigma = noise*gain)."""
    out = []
    for lo, hi in ((0.0, 1.0 / 3.0), (2.0 / 3.0, 1.0)):
        a, b = np.searchsorted(t, t[0] + span * np.array([lo, hi]))
        tt, xx = t[a:b], x[a:b]
        if tt.size < 8:
            return None
        w = np.sin(np.pi * (tt - tt[0]) / (tt[-1] - tt[0])) ** 2
        sw = w.sum()
        # Products summed without BLAS dot: threaded, it can stall on a busy machine.
        wx = w * (xx - (w * xx).sum() / sw)
        phase = 2.0 * np.pi * f * (tt - tt[0])
        z = np.hypot((wx * np.cos(phase)).sum(), (wx * np.sin(phase)).sum())
        out.append((2.0 * z / sw, np.sqrt(2.0 * (w * w).sum()) / sw))
    return out


def _steadiness(t, x, f, span, noise):
    """(steady, decays) of the line at frequency f over the stretch."""
    thirds = _third_amplitudes(t, x, f, span)
    if thirds is None:
        return False, False
    (first, gain1), (last, gain3) = thirds
    sigma = noise
    first, last = max(first, sigma * gain1, 1e-300), max(last, sigma * gain3, 1e-300)
    with np.errstate(over="ignore"):
        log_ratio = np.log(last / first)
        spread = 4.0 * np.hypot(sigma * gain1 / first, sigma * gain3 / last)
    if not (np.isfinite(log_ratio) and np.isfinite(spread)):  # lost in the noise
        return False, False
    return bool(abs(log_ratio) < _STEADY + spread), bool(log_ratio < -(_DECAYS + spread))


def _harmonics(frequencies, power, window_sum, hum, oscillation, threshold, oversampling=1.0):
    """Harmonics of the hum standing above ``threshold``, off the oscillation's band and
    harmonics (bins of the stretch's length: ``oversampling`` grid bins each)."""
    kept = [1]
    step = frequencies[1] * oversampling
    reach = int(np.ceil(2 * oversampling))  # the peak within 2 bins
    for h in range(2, _HARMONICS + 1):
        f = h * hum
        k = int(round(f / frequencies[1]))
        if k + reach >= power.size:
            break
        order = round(f / oscillation)
        if oscillation / _APART < f < oscillation * _APART or (
                1 <= order <= _ORDERS and abs(f - order * oscillation) <= _CLEAR_BINS * step):
            continue
        if 2.0 * np.sqrt(power[k - reach:k + reach + 1].max()) / window_sum > threshold:
            kept.append(h)
    return tuple(kept)


def _sinusoids(tau, f, harmonics):
    phase = 2.0 * np.pi * f * tau
    return np.column_stack([g(h * phase) for h in harmonics for g in (np.cos, np.sin)])


def _normal_equations(t, x, columns_of):
    """Hann-weighted normal equations of x on [1, tau, *columns_of(tau)] over the record."""
    t_mid, length = 0.5 * (t[0] + t[-1]), t[-1] - t[0]
    matrix, vector = 0.0, 0.0
    for start in range(0, t.size, _BLOCK):
        tau = t[start:start + _BLOCK] - t_mid
        w = np.cos(np.pi * tau / length) ** 2
        design = np.column_stack([np.ones_like(tau), tau / length, columns_of(tau)])
        weighted = design * w[:, None]
        matrix = matrix + weighted.T @ design
        vector = vector + weighted.T @ x[start:start + _BLOCK]
    return matrix, vector


def _refined(t, x, f, span):
    """Frequency of a steady line by Gauss-Newton on A*cos + B*sin over the record."""
    length = t[-1] - t[0]
    for _ in range(4):
        def columns(tau):
            s = _sinusoids(tau, f, (1,))
            return np.column_stack([s, s * (tau / length)[:, None]])
        solution = np.linalg.lstsq(*_normal_equations(t, x, columns), rcond=None)[0]
        a, b, c, d = solution[2:]
        power = a * a + b * b
        if not power > 0:  # no line, or one so faint that its square underflows
            break
        # A*cos(w+dw)tau + B*sin(w+dw)tau ~ ... + tau*dw*(B*cos - A*sin)
        step = (c * b - d * a) / power / (2.0 * np.pi * length)
        if not np.isfinite(step) or abs(step) > 0.5 / span:
            break
        f += step
        if abs(step) * length < 1e-6:
            break
    return f


def _fit(t, x, f, harmonics):
    """Coefficients (cos, sin per harmonic) of the line in x."""
    matrix, vector = _normal_equations(t, x, lambda tau: _sinusoids(tau, f, harmonics))
    return np.linalg.lstsq(matrix, vector, rcond=None)[0][2:]
