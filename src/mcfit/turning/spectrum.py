"""Stage 1: the coarse period and the white-noise level from the spectrum, and the gaps."""

from __future__ import annotations

import functools

import numpy as np
from scipy.fft import next_fast_len

from mcfit.errors import RecordError
from mcfit.hum import peak_frequency
from mcfit.plain import period_resolution, time_text
from mcfit.turning.common import SAMPLES_PER_CYCLE, _median, _robust_sigma

# Longest stretch fed to the FFT for the coarse period and noise level.
_SPECTRUM_SAMPLES = 1 << 21
# A gap longer than this many median steps is left empty (zeros) in the spectrum.
_LONG_GAP_STEPS = 32
# A time step longer than this many median steps is a gap.
_GAP_STEPS = 2.5
# Stretches longer than this are zero-padded to a fast FFT length; a shorter one keeps
# its own (at most 10 ms for a prime length, and its results as they were).
_PADDED_SAMPLES = 1 << 16
# Hann windows of records up to this many samples are kept for the next record.
_CACHED_WINDOW = 1 << 16
# The white-noise floor is read from the spectrum above this multiple of the oscillation's
# frequency.
_NOISE_BAND = 2.5
# Fewest samples a cycle of a waveform whose crests can be placed (the waveform fit takes
# the record from 4; the half-cycle fits are biased below SAMPLES_PER_CYCLE).
MIN_SAMPLES_PER_CYCLE = 4
# The spectrum's period of a record at 4 samples a cycle, 30 cycles, reads 3.99 samples.
_SAMPLING_SLACK = 0.05


def _find_gaps(tf, steps, dt):
    """Stretches with missing samples or a time step over _GAP_STEPS median steps."""
    gaps = []
    long_steps = np.flatnonzero(steps > _GAP_STEPS * dt)
    for i in long_steps[:1000]:
        gaps.append((float(tf[i]), float(tf[i + 1])))
    return sorted(gaps)


def _checked_period(period, dt, source):
    """The period as a float, or RecordError when it is not over 2 samples."""
    period = float(period)
    if not np.isfinite(period) or period <= 2 * dt:
        raise RecordError(f"no oscillation found in {source}: the spectrum peaks at a period "
                          f"of {period:.3g}, under 2 samples. Check the signal column.")
    return period


def _checked_sampling(samples_per_cycle, source):
    """``samples_per_cycle``, or RecordError when it is under MIN_SAMPLES_PER_CYCLE (less
    the spectral period's error, _SAMPLING_SLACK): a crest between samples a third of a
    cycle apart has no sample near it."""
    if samples_per_cycle < (1 - _SAMPLING_SLACK) * MIN_SAMPLES_PER_CYCLE:
        raise RecordError(f"{source} is sampled at {samples_per_cycle:.2g} samples a cycle: "
                          "too few to place the crests; need at least "
                          f"{MIN_SAMPLES_PER_CYCLE}. Record at a higher sampling rate.")
    return samples_per_cycle


def _gap_note(gaps, period):
    """Where the gaps are: the fit spans them with the turning points on both sides."""
    start, end = max(gaps, key=lambda g: g[1] - g[0])
    cycles = f", about {(end - start) / period:.3g} periods" if np.isfinite(period) else ""
    resolution = period_resolution(period) if np.isfinite(period) else None
    where = (f"from t = {time_text(start, resolution)} to {time_text(end, resolution)} "
             f"({end - start:.4g} time units{cycles})")
    if len(gaps) == 1:
        head = f"a gap in the record {where}"
    else:
        total = sum(b - a for a, b in gaps)
        head = (f"{len(gaps)} gaps in the record, {total:.4g} time units in all, the longest "
                f"{where}")
    return head + ": bridged, the turning points on both sides are used"


def _spectrum(t, x, dt, steps):
    """(period, noise sigma, periodogram) from a Hann-windowed periodogram of the first
    stretch; the periodogram is (frequencies, power, window sum, window sum of squares,
    bin of the peak, grid bins per bin of the stretch's length), or None when too
    short."""
    n = min(t.size, _SPECTRUM_SAMPLES)
    irregular = steps[: n - 1].size and (steps[: n - 1].max() > 1.05 * steps[: n - 1].min())
    outside = None
    if irregular:
        grid = t[0] + dt * np.arange(int((t[n - 1] - t[0]) / dt) + 1)
        grid = grid[:_SPECTRUM_SAMPLES]
        v = np.interp(grid, t[:n], x[:n])
        outside = _in_long_gaps(grid, t[:n], steps[: n - 1], dt)
    else:
        v = x[:n].astype(np.float64, copy=True)
    m = v.size
    index = np.arange(m, dtype=np.float64) - 0.5 * (m - 1)  # centred: the line's terms decouple
    if outside is None:
        slope = float(np.dot(index, v) / np.dot(index, index)) if m > 1 else 0.0
        v -= v.mean() + slope * index
    else:  # a straight line across a long gap would be a spectral line of its own: zeros
        inside = ~outside
        slope, mean = np.polyfit(index[inside], v[inside], 1)
        v -= mean + slope * index
        v[outside] = 0.0
    window, window_sum, energy = _hann(m)
    v *= window
    # A long stretch is zero-padded to a fast length (the same periodogram, on a grid
    # finer by ``oversampling``): a length with a large prime factor, such as 1,000,001,
    # takes the FFT 27 times as long.
    size = next_fast_len(m, real=True) if m > _PADDED_SAMPLES else m
    oversampling = size / m
    power = np.abs(np.fft.rfft(v, size)) ** 2
    del v
    frequencies = np.fft.rfftfreq(size, d=dt)
    # Periods longer than half the stretch (bin 2 of its own length) are drift.
    lowest = int(np.ceil(2 * oversampling))
    if power.size <= lowest + 2:
        return float("nan"), float("nan"), None
    k = lowest + int(np.argmax(power[lowest:]))
    f0 = peak_frequency(power, frequencies, k)
    noise = _spectral_noise(power, frequencies, f0, energy, x[:n])
    return ((1.0 / f0 if f0 > 0 else float("nan")), noise,
            (frequencies, power, window_sum, energy, k, oversampling))


def _hann(m):
    """(Hann window of ``m`` points, its sum, its sum of squares); those of the short
    records, where computing it costs most against the rest, are kept for the next one."""
    if m <= _CACHED_WINDOW:
        return _cached_hann(m)
    window = np.hanning(m)
    return window, float(window.sum()), np.dot(window, window)


@functools.lru_cache(maxsize=4)
def _cached_hann(m):
    window = np.hanning(m)
    window.setflags(write=False)
    return window, float(window.sum()), np.dot(window, window)


def _spectral_noise(power, frequencies, f0, energy, x):
    """White-noise sigma from the periodogram's floor above _NOISE_BAND*f0 (``energy``: the
    window's sum of squares); where that band is too narrow, from differences: the first
    ones, or under SAMPLES_PER_CYCLE samples a cycle (the first differences of a sine at 4
    to 6 samples a cycle are as large as the sine: "no oscillation above the noise")
    those of :func:`_notch_noise`."""
    band = power[frequencies > _NOISE_BAND * f0]
    if band.size >= 16:
        return float(np.sqrt(_median(band) / (np.log(2) * energy)))
    if 0 < f0 and frequencies[-1] < 0.5 * SAMPLES_PER_CYCLE * f0:
        return _notch_noise(x, f0 / (2 * frequencies[-1]))
    # Too few samples per cycle for a clean band: differences overestimate, safely.
    d = np.diff(x)
    return float(_robust_sigma(d) / np.sqrt(2))


# Notch filters at the oscillation's frequency applied one after another: a damped sine
# at Q = 40 and 4 samples a cycle passes about (2*pi/(8*Q))**3, 6e-6 of its amplitude.
_NOTCHES = 3


def _notch_noise(x, cycles_per_sample):
    """White-noise sigma of ``x``, an oscillation of ``cycles_per_sample`` (up to 0.5)
    sampled few times a cycle, from the robust scale of ``x`` filtered by a first
    difference (the offset) and _NOTCHES notches ``x[i-1] - 2*cos(w)*x[i] + x[i+1]`` at the
    oscillation's frequency, divided by the filter's gain for white noise. An overestimate
    where damping is strong or the frequency drifts: the crest search needs the noise's
    order only, the waveform fit of such a record takes it from its residuals."""
    notch = np.array([1.0, -2.0 * np.cos(2.0 * np.pi * cycles_per_sample), 1.0])
    kernel = np.array([1.0, -1.0])
    for _ in range(_NOTCHES):
        kernel = np.convolve(kernel, notch)
    if x.size <= kernel.size:
        return float(_robust_sigma(np.diff(x)) / np.sqrt(2))
    filtered = np.convolve(x, kernel, mode="valid")
    return float(_robust_sigma(filtered) / np.linalg.norm(kernel))


def _in_long_gaps(grid, t, steps, dt):
    """Grid points inside gaps longer than _LONG_GAP_STEPS median steps (None if none)."""
    long_steps = np.flatnonzero(steps > _LONG_GAP_STEPS * dt)
    if long_steps.size == 0:
        return None
    edges = np.zeros(grid.size + 1)
    np.add.at(edges, np.searchsorted(grid, t[long_steps], side="right"), 1.0)
    np.add.at(edges, np.searchsorted(grid, t[long_steps + 1]), -1.0)
    return np.cumsum(edges[:-1]) > 0
