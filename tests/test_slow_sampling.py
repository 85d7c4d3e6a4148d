"""Records sampled slowly, down to 4 samples a cycle (a slow logger, a video at a low frame
rate): fitted by the equation of motion with honest intervals, or refused for the true
reason; a well-sampled record keeps its method."""

import math
from dataclasses import replace

import numpy as np
import pytest

from mcfit import decay
from mcfit.analysis import analyse_record
from mcfit.motion import simulate_record
from mcfit.turning import find_turning_points

PERIOD = 1.0
# Samples of the simulated motion between two samples of the record: the record starts
# at a random phase of its sampling.
FINE = 60
VISCOUS = (0.0, 0.04, 0.0)  # Q = 78.5
ALL_THREE = (0.05, 0.02, 0.01)  # Q = 40 at the start


def slow_record(samples_per_cycle, law, seed, noise=3e-3, cycles=30):
    """A record of ``law`` (a, b, c per second) from y0 = 1 at ``samples_per_cycle``, its
    first sample at a random phase, with white noise of ``noise``."""
    rng = np.random.default_rng(seed)
    rate = samples_per_cycle / PERIOD
    motion = simulate_record(*law, 1.0, PERIOD, cycles * PERIOD + 1 / rate, rate * FINE)
    first = int(rng.integers(FINE))
    t, x = motion.t[first::FINE], motion.x[first::FINE]
    return replace(motion, t=t, x=x + rng.normal(0.0, noise, x.size),
                   source=f"slow{samples_per_cycle}-{seed}.csv")


def z_scores(fit, law):
    """(z of b, z of Q at the first turning point) against the truth."""
    a, b, c = law
    q_true = float(decay.quality_factor(decay.amplitude(fit.t[0], 1.0, a, b, c),
                                        2 * math.pi / PERIOD, a, b, c))
    q = fit.q_summary
    return ((fit.values["b"] - b) / fit.stderr["b"],
            (q["initial"] - q_true) / q["initial_stderr"])


@pytest.mark.parametrize("samples_per_cycle, law, seed", [
    (4, VISCOUS, 1), (4, VISCOUS, 2), (4, VISCOUS, 3), (4, ALL_THREE, 12),
    (5, VISCOUS, 5), (5, ALL_THREE, 6), (6, VISCOUS, 7)])
def test_a_record_of_few_samples_a_cycle_is_fitted_within_its_intervals(
        samples_per_cycle, law, seed):
    analysis = analyse_record(slow_record(samples_per_cycle, law, seed))
    assert analysis.status == "ok", analysis.error
    fit = analysis.fit
    assert fit.method == "waveform"
    assert f"sampled at {samples_per_cycle:.2g} samples a cycle" in fit.method_reason
    assert fit.model == "".join(k for k, v in zip("abc", law) if v)
    z_b, z_q = z_scores(fit, law)
    assert abs(z_b) < 1.96 and abs(z_q) < 1.96, (z_b, z_q)


def test_the_noise_of_a_slow_record_comes_from_the_residuals():
    # The samples alone cannot tell the noise at 4 samples a cycle (the waveform fit's
    # own estimate put the reduced chi-square between 0.4 and 6): the residuals can.
    noise = 5e-3
    fit = analyse_record(slow_record(4, ALL_THREE, 11, noise=noise)).fit
    assert fit.rms == pytest.approx(noise, rel=0.15)
    assert fit.reduced_chi_square == pytest.approx(1.0, abs=0.05)
    assert "residuals" in fit.method_reason


@pytest.mark.parametrize("samples_per_cycle", [5, 6])
def test_the_noise_is_not_the_oscillation_at_few_samples_a_cycle(samples_per_cycle):
    # The first differences of a sine at 5 or 6 samples a cycle are as large as the
    # sine: the noise read 0.44 and the record was refused as "no oscillation".
    record = slow_record(samples_per_cycle, VISCOUS, 21, noise=3e-3)
    turning = find_turning_points(record.t, record.x, source=record.source)
    assert 1e-3 < turning.noise_sigma < 1e-2


@pytest.mark.parametrize("samples_per_cycle", [3.0, 3.2])
def test_a_record_of_under_four_samples_a_cycle_gets_the_true_reason(samples_per_cycle):
    analysis = analyse_record(slow_record(samples_per_cycle, VISCOUS, 31))
    assert analysis.status == "error"
    assert (f"sampled at {samples_per_cycle:.2g} samples a cycle: too few to place the "
            "crests; need at least 4") in analysis.error
    assert "no oscillation" not in analysis.error


@pytest.mark.parametrize("samples_per_cycle", [8, 20])
def test_a_well_sampled_record_keeps_the_turning_point_fit(samples_per_cycle):
    analysis = analyse_record(slow_record(samples_per_cycle, VISCOUS, 41))
    fit = analysis.fit
    assert fit.method == "turning-points"
    assert fit.method_reason.endswith("the turning-point fit suffices")
    z_b, z_q = z_scores(fit, VISCOUS)
    assert abs(z_b) < 1.96 and abs(z_q) < 1.96, (z_b, z_q)
