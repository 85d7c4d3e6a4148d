"""Thresholds and small helpers shared by the turning-point stages."""

from __future__ import annotations

import numpy as np
from scipy import ndimage, stats

# Samples processed at once in the local fits (bounds the memory of a 1e7-sample record).
_BLOCK_SAMPLES = 1 << 20
# Samples per cycle below which the amplitudes are less accurate; a waveform needs two
# cycles of them at least.
SAMPLES_PER_CYCLE = 8
# Neighbouring crests of opposite sign count as one half-cycle apart when their spacing is
# within this fraction of a period (a wider or narrower one is a missed or false crest).
HALF_CYCLE_SPACING = (0.3, 0.7)


def _robust_sigma(values):
    """Standard deviation of Gaussian values from their median absolute deviation."""
    return float(stats.median_abs_deviation(values, scale="normal"))


def _running_median(values, width):
    if values.size < width or width < 3:
        return values.copy()
    # The ends repeat the end values, as if the sequence went on level.
    return ndimage.median_filter(values, size=2 * (width // 2) + 1, mode="nearest")


def _amplitude_sigma(noise_sigma, gain):
    """Standard deviation of window amplitudes from the sample noise and each window's
    gain; infinite for windows without a fit, even on a noise-free record (0 * inf is NaN)."""
    sigma = np.full(gain.shape, np.inf)
    finite = np.isfinite(gain)
    sigma[finite] = noise_sigma * np.sqrt(gain[finite])
    return sigma
