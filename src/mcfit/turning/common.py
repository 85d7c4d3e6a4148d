"""Thresholds and small helpers shared by the turning-point stages."""

from __future__ import annotations

import numpy as np

# Samples processed at once in the local fits (bounds the memory of a 1e7-sample record:
# their temporaries take about a hundred bytes a sample).
_BLOCK_SAMPLES = 1 << 18
# Crests processed at once where each takes a few hundred bytes (a million cycles).
_CREST_BLOCK = 1 << 16
# Samples per cycle below which the amplitudes are less accurate; a waveform needs two
# cycles of them at least.
SAMPLES_PER_CYCLE = 8
# Neighbouring crests of opposite sign count as one half-cycle apart when their spacing is
# within this fraction of a period (a wider or narrower one is a missed or false crest).
HALF_CYCLE_SPACING = (0.3, 0.7)


# ndtri(3/4): the median absolute deviation of Gaussian values in units of their sigma.
_NORMAL_MAD = 0.6744897501960817


# Running medians over more neighbours than this are not taken by one partition of all
# the windows (memory n*width: 1.96 GB for 80,000 crests in windows of 2,667).
_WIDE_MEDIAN = 64


def _time_at(value, crests):
    """A time of a note, with the digits that resolve a hundredth of the period at its
    magnitude: the period is taken as twice the median spacing of the ``crests`` times
    (turning points alternate), which errs towards more digits."""
    from mcfit.plain import time_text
    crests = np.asarray(crests, dtype=np.float64)
    steps = np.diff(crests[np.isfinite(crests)])
    spacing = _median(np.abs(steps)) if steps.size else float("nan")
    return time_text(value, spacing / 50.0 if np.isfinite(spacing) and spacing > 0 else None)


def _median(values):
    """np.median of a 1-D array (NaN if it holds a NaN or is empty), without its overhead:
    the middle order statistics by one partition."""
    n = values.size
    if n == 0:
        return float("nan")
    middle = n // 2
    if n % 2:
        part = np.partition(values, middle)
        value = part[middle]
    else:
        part = np.partition(values, (middle - 1, middle))
        value = (part[middle - 1] + part[middle]) / 2
    return float("nan") if np.isnan(part[-1]) else float(value)


def _robust_sigma(values):
    """Standard deviation of Gaussian values from their median absolute deviation (as
    ``scipy.stats.median_abs_deviation(values, scale="normal")``, a tenth of its cost)."""
    values = np.asarray(values, dtype=np.float64)
    return _median(np.abs(values - _median(values))) / _NORMAL_MAD


def _running_median(values, width):
    """Median of each ``width`` (made odd) neighbours, the ends repeating the end values as
    if the sequence went on level (``scipy.ndimage.median_filter(mode="nearest")``).

    Narrow windows take one partition of the windows of a block of values at once (time
    ``n*width``); windows wider than _WIDE_MEDIAN, on finite values, take
    ``median_filter`` itself (time ``n*log(width)``, memory ``n``). Both return the same
    order statistic, so the same values."""
    if values.size < width or width < 3:
        return values.copy()
    half = width // 2
    if width > _WIDE_MEDIAN and np.isfinite(values).all():
        from scipy.ndimage import median_filter  # loaded only for long records

        return median_filter(values, size=2 * half + 1, mode="nearest")
    padded = np.empty(values.size + 2 * half)
    padded[:half] = values[0]
    padded[half:-half] = values
    padded[-half:] = values[-1]
    # Row i is padded[i:i + width], a view; partitioned a block of rows at a time.
    windows = np.ndarray((values.size, 2 * half + 1), buffer=padded,
                         strides=(padded.itemsize, padded.itemsize))
    out = np.empty(values.size, dtype=padded.dtype)
    for lo in range(0, values.size, _CREST_BLOCK):
        out[lo:lo + _CREST_BLOCK] = np.partition(windows[lo:lo + _CREST_BLOCK], half,
                                                 axis=1)[:, half]
    return out


def _amplitude_sigma(noise_sigma, gain):
    """Standard deviation of window amplitudes from the sample noise and each window's
    gain; infinite for windows without a fit, even on a noise-free record (0 * inf is NaN)."""
    sigma = np.full(gain.shape, np.inf)
    finite = np.isfinite(gain)
    sigma[finite] = noise_sigma * np.sqrt(gain[finite])
    return sigma


def _segment_groups(starts, n):
    """Whole segments in groups of about _BLOCK_SAMPLES samples: (first, stop) ranges of
    segments and the (lo, hi) samples they span, for segments starting at ``starts``
    (increasing, the last ending at ``n``). A segment longer than a block is a group of
    its own; a record of up to a block of samples is one group."""
    cuts = np.searchsorted(starts, np.arange(_BLOCK_SAMPLES, n, _BLOCK_SAMPLES))
    bounds = np.unique(np.concatenate([[0], cuts, [starts.size]]))
    ends = np.append(starts, n)
    return [(int(a), int(b), int(ends[a]), int(ends[b])) for a, b in zip(bounds[:-1], bounds[1:])
            if b > a]
