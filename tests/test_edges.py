"""The edges where real records live, on records from an integration that shares no code
with mcfit (mcfit.bench.reference_motion), with fixed seeds: right, or flagged."""

import math

import numpy as np
import pytest

from mcfit.bench.reference_motion import hysteretic, viscous
from mcfit.analysis import analyse_record
from mcfit.record import Record

W_FIG = 4 * math.pi  # Fig. 20.19: T = 0.5 s


def _noisy(t, x, noise, seed):
    return Record(source=f"seed{seed}", t=t, x=x + np.random.default_rng(seed).normal(
        0.0, noise, t.size))


@pytest.fixture(scope="module")
def fig20_19_for_30_s():
    """a = b = 0.1, c = 0.01, y0 = 4, T = 0.5 s for 30 s: the motion stops at 24.4 s."""
    return hysteretic(0.1, 0.1, 0.01, W_FIG, 4.0, 30.0, 100.0)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_handbook_scene_past_its_coulomb_stop_is_fitted_up_to_the_stop(
        fig20_19_for_30_s, seed):
    analysis = analyse_record(_noisy(*fig20_19_for_30_s, 1e-4, seed))
    fit = analysis.fit
    assert analysis.status == "ok", analysis.error
    assert fit.model == "abc" and not analysis.warnings
    for term, truth in {"a": 0.1, "b": 0.1, "c": 0.01}.items():
        assert abs(fit.values[term] - truth) < 3 * fit.stderr[term], term
    assert any(note.startswith("the decay ends in the noise or stops")
               for note in analysis.turning.notes)
    assert analysis.turning.t[analysis.turning.used].max() < 25.5


def test_the_textbook_linear_oscillator_is_viscous_and_exact():
    """x = exp(-0.8 t) cos(w t) (w the damped frequency), T = 1 s, 6 s at 400 Hz, noise
    1e-4: b was 0.788 +- 0.032 from the turning points (reduced chi-square 2,350) or abc
    from Eq. 20.55's waveform. Over 8 seeds b covers within 3 standard errors, the form is
    viscous, and the fit is within its noise."""
    t = np.arange(0.0, 6.0, 1 / 400)
    for seed in range(8):
        x = np.exp(-0.8 * t) * np.cos(2 * math.pi * t)
        fit = analyse_record(_noisy(t, x, 1e-4, seed)).fit
        assert fit.model == "b" and fit.damping_form == "velocity" and fit.resolved
        assert abs(fit.values["b"] - 0.8) < 3 * fit.stderr["b"]
        assert fit.reduced_chi_square < 1.2
        # The natural frequency: w0**2 = w_d**2 + beta**2.
        assert fit.omega == pytest.approx(math.hypot(2 * math.pi, 0.8), rel=1e-4)


@pytest.mark.parametrize("form", ["velocity", "amplitude"])
def test_the_form_of_the_damping_is_told_apart_at_low_q_and_never_confused(form):
    """Q = 3, noise 1e-3 of the amplitude (8 s at 100 Hz), 8 seeds each: viscous
    2*beta*x' against Eq. 20.55's hysteretic (pi*w/2)*b*A*sgn(x'), the same averaged b.
    Each record names its own form, or says it cannot tell; none names the other."""
    omega, b = 2 * math.pi, math.pi / 3
    if form == "velocity":
        t, x = viscous(b, omega, 1.0, 8.0, 100.0)
    else:
        t, x = hysteretic(0.0, b, 0.0, omega, 1.0, 8.0, 100.0)
    named = [analyse_record(_noisy(t, x, 1e-3, seed)).fit.damping_form for seed in range(8)]
    assert set(named) <= {form, "cannot tell"} and named.count(form) >= 6, named


def test_a_beat_of_two_close_modes_is_named_not_absorbed():
    """Two viscous modes 2 % apart at Q = 200, equal in size: the envelope falls to a
    node and rises again. The decay before the node is fitted and the beat named in a
    warning, not read as a Coulomb term without a word."""
    t = np.arange(0.0, 120.0, 0.02)
    rate = math.pi / 200
    x = sum(np.exp(-rate * t) * np.cos(2 * math.pi * f * t) for f in (1.0, 1.02))
    analysis = analyse_record(_noisy(t, x, 1e-3, 1))
    assert any("beating of two modes" in w for w in analysis.warnings), analysis.warnings
