"""Memory of the turning points on long records (issue 28: 10^7 samples with 10^6 cycles
within 3 times the file's size): record-sized arrays taken a block at a time, and the
columns of a pass of half-cycle fits freed when no longer needed."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from mcfit.turning import crests, windows
from mcfit.turning.common import _amplitude_sigma, _running_median
from mcfit.turning.windows import Samples


@pytest.fixture
def rng():
    return np.random.default_rng(2028)


def test_wide_steps_block_by_block_are_those_of_the_whole_record(monkeypatch, rng):
    t = np.cumsum(rng.uniform(0.5, 1.5, 1000))
    t[[1, 63, 64, 65, 500, 998]] += 10.0  # steps either side of block edges, and the last
    samples = Samples.of(t, np.cos(t))
    steps = np.diff(t)
    monkeypatch.setattr(windows, "_BLOCK_SAMPLES", 64)
    for limit in (1.4, 5.0, 10.5, np.inf):
        index, wide = samples.wide_steps(limit)
        np.testing.assert_array_equal(index, np.flatnonzero(steps >= limit))
        np.testing.assert_array_equal(wide, steps[steps >= limit])


def test_a_record_of_one_sample_has_no_steps_and_two_have_one():
    index, wide = Samples.of(np.array([0.0]), np.array([1.0])).wide_steps(0.0)
    assert index.size == wide.size == 0 and index.dtype == np.intp
    index, wide = Samples.of(np.array([0.0, 2.0]), np.array([1.0, -1.0])).wide_steps(0.0)
    np.testing.assert_array_equal(index, [0])
    np.testing.assert_array_equal(wide, [2.0])


def test_phase_corrected_amplitudes_block_by_block_are_the_whole_array_formula(
        monkeypatch, rng):
    n = 1000
    projected = SimpleNamespace(
        projection=rng.normal(1.0, 0.3, n),
        projection_gain=np.where(rng.random(n) < 0.05, np.inf, rng.uniform(0.01, 0.1, n)),
        phase_sensitivity=rng.uniform(-0.7, 0.7, n))
    phase_variance = rng.uniform(0.0, 1.5, n)
    phase_variance[::37] = np.nan
    monkeypatch.setattr(crests, "_CREST_BLOCK", 64)
    y, sigma = crests._phase_corrected(projected, phase_variance, 0.02)
    # docs/theory.md section 8, written out on whole arrays.
    v = np.minimum(np.nan_to_num(phase_variance, nan=0.0), 1.0)
    gain = np.exp(0.5 * v)
    expected_y = projected.projection * gain
    envelope = np.maximum(_running_median(expected_y, 9), 0.0)
    expected_sigma = np.sqrt(
        (_amplitude_sigma(0.02, projected.projection_gain) * gain) ** 2
        + (envelope * gain) ** 2 / 2.0 * ((1.0 - np.exp(-v)) ** 2 + projected.phase_sensitivity**2
                                          * (1.0 - np.exp(-2.0 * v))))
    np.testing.assert_array_equal(y, expected_y)
    np.testing.assert_array_equal(sigma, expected_sigma)
    assert np.isinf(sigma[~np.isfinite(projected.projection_gain)]).all()
