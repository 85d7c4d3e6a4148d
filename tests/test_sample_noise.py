"""The white-noise level the waveform fit weighs its residuals by (mcfit.fit.waveform)."""

from __future__ import annotations

import numpy as np
import pytest

from mcfit.fit.waveform import sample_noise


@pytest.mark.parametrize("samples_per_cycle", [8, 12, 20, 100])
def test_the_noise_of_a_sampled_oscillation_is_its_own_at_any_sampling(samples_per_cycle):
    """200 cycles of a slow decay (Q = 200, unit amplitude) with white noise 1e-3: sixth
    differences read it as 1.75e-3 at 8 samples a cycle (a sine passes them); the
    estimate is the noise's within its scatter at every sampling."""
    estimates = []
    for seed in range(6):
        rng = np.random.default_rng([7, samples_per_cycle, seed])
        t = np.arange(200 * samples_per_cycle) / samples_per_cycle
        signal = np.exp(-np.pi / 200 * t) * np.cos(2 * np.pi * t + rng.uniform(0, 2 * np.pi))
        estimates.append(sample_noise(signal + rng.normal(0.0, 1e-3, t.size)))
    assert np.all(np.abs(np.array(estimates) / 1e-3 - 1) < 0.15)
    assert np.mean(estimates) == pytest.approx(1e-3, rel=0.05)


def test_a_waveform_fit_at_eight_samples_a_cycle_weighs_its_residuals_by_the_noise():
    """Eq. 20.55 with b alone sampled 8 times a cycle, noise 1e-3: the noise read three
    times too high made the reduced chi-square 0.07 to 0.08, which would hide a misfit
    under the warning's limit; it is near 1 now."""
    from mcfit import analyse
    from mcfit.motion import simulate_record

    for seed in range(3):
        t, x = simulate_record(y0=1.0, period=1.0, duration=60.0, rate=8.0, noise=1e-3,
                               rng=np.random.default_rng(seed), a=0.0, b=0.02, c=0.0)
        fit = analyse(t, x, method="waveform").fit
        assert fit.model == "b" and abs(fit.values["b"] - 0.02) < 3 * fit.stderr["b"]
        assert 0.6 < fit.reduced_chi_square < 1.5


@pytest.mark.parametrize("size", [2, 5, 7])
def test_a_record_too_short_for_differences_falls_back_to_its_spread(size):
    x = np.arange(float(size))
    assert sample_noise(x) == pytest.approx(np.std(x))
