"""The waveform fit by the integrated equation of motion: the pendulum's own (sin
restoring) with `pendulum`, and quadratic drag as the velocity form of the fluid term.
Records from an integration that shares no code with mcfit
(mcfit.bench.reference_motion), fixed seeds."""

import math

import numpy as np
import pytest

from mcfit.analysis import analyse_record
from mcfit.bench import reference_motion as motion
from mcfit.fit.waveform_laws import EquationOfMotionWaveform, PendulumWaveform
from mcfit.record import Record

OMEGA = 2 * math.pi
BETA = math.pi / 50  # Q = 50


def _noisy(t, x, noise, seed):
    return Record(source=f"seed{seed}", t=t, x=x + np.random.default_rng(seed).normal(
        0.0, noise, t.size))


def _waveform(kind, terms, **options):
    t = np.arange(0.0, 4.0, 0.01)
    waveform = kind(t, np.zeros_like(t), 0.0, terms, 1e-9, **options)  # integrated tightly
    waveform.typical = np.ones(5 + len(terms))
    return waveform


@pytest.mark.parametrize("kind, options", [(EquationOfMotionWaveform, {}),
                                           (PendulumWaveform, {}),
                                           (PendulumWaveform, {"radians_per_unit": 0.1})])
def test_the_jacobian_is_that_of_the_residuals(kind, options):
    """Every column (the averaged law's a, b, c through kappa and mu, omega through both,
    the units of a pendulum's angle) against central differences of the residuals."""
    waveform = _waveform(kind, ("a", "b", "c"), **options)
    scale = options.get("radians_per_unit", 1.0)
    p = np.array([0.9 / scale, 0.3, OMEGA, 0.01, 0.002, 0.2 * scale, 0.1, 0.02 / scale])
    jacobian = waveform.jacobian(p)
    for j in range(p.size):
        step = 1e-6 * max(abs(p[j]), 1e-2)
        up, down = p.copy(), p.copy()
        up[j] += step
        down[j] -= step
        expected = (waveform.residual(up) - waveform.residual(down)) / (2 * step)
        size = np.max(np.abs(expected))
        assert np.max(np.abs(jacobian[:, j] - expected)) < 1e-4 * size, waveform.names[j]


def test_a_pendulum_in_other_units_is_the_same_swing():
    t = np.arange(0.0, 4.0, 0.01)
    p = np.array([1.2, 0.0, OMEGA, 0.0, 0.0, 0.05])
    radians = PendulumWaveform(t, np.zeros_like(t), 0.0, ("b",), 1.0)
    degrees = PendulumWaveform(t, np.zeros_like(t), 0.0, ("b",), 1.0, math.pi / 180)
    for waveform in (radians, degrees):
        waveform.typical = np.ones(6)
    scale = 180 / math.pi
    in_degrees = degrees.residual(p * [scale, 1, 1, 1, 1, 1])
    np.testing.assert_allclose(in_degrees, scale * radians.residual(p), atol=1e-6)
    # A linear restoring force would not be the same swing.
    linear = EquationOfMotionWaveform(t, np.zeros_like(t), 0.0, ("b",), 1.0)
    linear.typical = np.ones(6)
    assert np.max(np.abs(linear.residual(p) - radians.residual(p))) > 0.05


@pytest.fixture(scope="module", params=[0.8, 1.4])
def large_swing(request):
    """A viscous pendulum, Q = 50, released from rest: 20 s at 50 Hz."""
    return request.param, motion.pendulum(BETA, OMEGA, request.param, 20.0, 50.0)


@pytest.mark.parametrize("noise", [1e-5, 1e-3])
def test_a_large_swing_with_pendulum_is_fitted_by_its_equation_of_motion(large_swing,
                                                                         noise):
    """Where the averaged large-swing law misfits or is biased (noise 1e-5: reduced
    chi-square 14.6 and 35 before), the waveform by the pendulum's own equation of motion:
    model b, b within 3 standard errors, reduced chi-square near 1, beta reported."""
    _, (t, x) = large_swing
    for seed in range(2):
        analysis = analyse_record(_noisy(t, x, noise, seed), pendulum=True)
        fit = analysis.fit
        assert fit.model == "b" and fit.resolved, (fit.model, analysis.warnings)
        assert abs(fit.values["b"] - BETA) < 3 * fit.stderr["b"]
        if fit.method == "waveform":
            assert 0.8 < fit.reduced_chi_square < 1.25
            assert fit.physical["beta"]["value"] == fit.values["b"]
            assert "pendulum's equation of motion" in fit.method_reason
            # Q is the energy's: below w0/(2*beta) = 50 at large swings, tending to it.
            q = fit.q_summary
            assert q["initial"] < 49.5 and q["initial"] < q["final"] < 50.01
        else:
            assert "turning-point fit suffices" in fit.method_reason
    if noise == 1e-5:
        assert fit.method == "waveform" and fit.angle_unit == "rad"


@pytest.mark.slow
def test_b_covers_over_seeds_at_a_large_swing(large_swing):
    """Noise 1e-5 rad, 10 seeds: b's 95 % interval covers the viscous rate in at least 8
    (the averaged law covered none)."""
    _, (t, x) = large_swing
    covered = 0
    for seed in range(100, 110):
        fit = analyse_record(_noisy(t, x, 1e-5, seed), pendulum=True).fit
        covered += fit.model == "b" and abs(fit.values["b"] - BETA) < (
            fit.interval_factor * fit.stderr["b"])
    assert covered >= 8


def test_a_swing_in_degrees_is_fitted_in_degrees():
    t, x = motion.pendulum(BETA, OMEGA, 1.0, 12.0, 50.0)
    fit = analyse_record(_noisy(t, np.degrees(x), 1e-3, 0), pendulum=True, degrees=True).fit
    assert fit.method == "waveform" and fit.model == "b" and fit.angle_unit == "deg"
    assert abs(fit.values["b"] - BETA) < 3 * fit.stderr["b"]
    crest = np.degrees(x[np.argmin(np.abs(t - fit.t0))])  # the sample nearest the crest
    assert abs(fit.values["y0"]) == pytest.approx(abs(crest), rel=5e-3)


def test_quadratic_drag_is_the_velocity_form_of_the_fluid_term():
    """An oscillator with quadratic drag alone at Q about 5 (a*y0 = w/10), noise 1e-3, 4
    seeds: the velocity form, model a, kappa within 3 standard errors of its value."""
    kappa = 3 * math.pi / 40  # a = 4*kappa*w/(3*pi) = w/10
    t, x = motion.quadratic_drag(kappa, OMEGA, 1.0, 8.0, 100.0)
    for seed in range(4):
        fit = analyse_record(_noisy(t, x, 1e-3, seed)).fit
        assert fit.model == "a" and fit.damping_form == "velocity", fit.damping_form_reason
        drag = fit.physical["kappa"]
        assert abs(drag["value"] - kappa) < 3 * drag["stderr"] and drag["unit"] == "1/U"
        assert fit.reduced_chi_square < 1.25


def test_a_trial_step_the_integrator_cannot_follow_is_a_huge_finite_misfit():
    """lmfit refuses NaN residuals; a run-away motion (negative damping) must be a misfit
    the solver steps back from."""
    t = np.linspace(0.0, 10.0, 101)
    waveform = EquationOfMotionWaveform(t, np.zeros_like(t), 0.0, ("b",), 1e-3)
    waveform.typical = np.ones(6)
    p = np.array([1.0, 0.0, OMEGA, 0.0, 0.0, -50.0])
    residual, jacobian = waveform.residual(p), waveform.jacobian(p)
    assert np.all(np.isfinite(residual)) and np.all(np.isfinite(jacobian))
    assert np.max(np.abs(residual)) > 1e50
