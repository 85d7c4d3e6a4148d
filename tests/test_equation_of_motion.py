"""The velocity forms with any restoring force, and their sensitivities, against
independent integrations, the closed form and finite differences."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from mcfit.bench.reference_motion import integrate
from mcfit.equation_of_motion import PARAMETERS, motion_with_sensitivities
from mcfit.viscous_motion import viscous_motion

OMEGA = 2 * math.pi


def _dop853(t, y0, theta0, beta, kappa, pendulum):
    """x(t) without sliding friction (a smooth right-hand side) by DOP853 at rtol 1e-12."""
    def rates(_, y):
        restoring = OMEGA**2 * (math.sin(y[0]) if pendulum else y[0])
        return [y[1], -2 * beta * y[1] - kappa * y[1] * abs(y[1]) - restoring]
    start = [y0 * math.cos(theta0), -OMEGA * y0 * math.sin(theta0)]
    return solve_ivp(rates, (0.0, t[-1]), start, method="DOP853", t_eval=t, rtol=1e-12,
                     atol=1e-14).y[0]


@settings(max_examples=20, deadline=None)
@given(beta=st.floats(0.0, 2.0), mu=st.floats(0.0, 3.0), theta0=st.floats(-3.1, 3.1),
       y0=st.floats(0.1, 10.0))
def test_linear_restoring_with_viscous_and_sliding_friction_is_the_closed_form(
        beta, mu, theta0, y0):
    """Any viscous rate up to Q = 1.6, any friction (sticking or not), any phase: within
    1e-8 of the amplitude over 6 s."""
    t = np.arange(0.0, 6.0, 0.02)
    x, _ = motion_with_sensitivities(t, y0, theta0, OMEGA, beta, 0.0, mu * y0, rtol=1e-11)
    c = 2 * mu * y0 / (math.pi * OMEGA)
    expected = viscous_motion(t, y0, theta0, OMEGA, beta, c)
    assert np.max(np.abs(x - expected)) < 1e-8 * y0


@pytest.mark.parametrize("pendulum", [False, True])
@pytest.mark.parametrize("theta0", [0.0, 2.0])
def test_quadratic_drag_and_the_pendulum_match_an_independent_dop853_solve(pendulum, theta0):
    t = np.arange(0.0, 20.0, 0.01)
    x, _ = motion_with_sensitivities(t, 1.4, theta0, OMEGA, 0.05, 0.3, 0.0,
                                     restoring="pendulum" if pendulum else "linear",
                                     rtol=1e-11)
    assert np.max(np.abs(x - _dop853(t, 1.4, theta0, 0.05, 0.3, pendulum))) < 1e-8


@pytest.mark.parametrize("pendulum", [False, True])
def test_with_sliding_friction_it_matches_the_reference_integration_to_the_stop(pendulum):
    """All three forces, friction stopping the swing inside the record; the reference
    integrates between reversals located as events (mcfit.bench.reference_motion)."""
    restoring = (lambda x: OMEGA**2 * math.sin(x)) if pendulum else None
    t, expected = integrate(lambda x, v, _: 0.2 * v + 0.4 * v * abs(v), OMEGA, 1.2, 10.0,
                            100.0, mu=1.5, restoring=restoring)
    x, sensitivities = motion_with_sensitivities(
        t, 1.2, 0.0, OMEGA, 0.1, 0.4, 1.5, restoring="pendulum" if pendulum else "linear",
        rtol=1e-11)
    assert np.all(expected[-50:] == expected[-1])  # the reference stopped
    assert np.max(np.abs(x - expected)) < 1e-8
    assert np.all(x[-50:] == x[-1]) and np.all(sensitivities[-50:] == sensitivities[-1])


def _central_differences(t, p, restoring):
    columns = []
    for j in range(p.size):
        step = 1e-6 * max(abs(p[j]), 1.0)
        up, down = p.copy(), p.copy()
        up[j] += step
        down[j] -= step if p[j] > 0 else 0.0  # one-sided where a force would turn negative
        columns.append((motion_with_sensitivities(t, *up, restoring=restoring, rtol=1e-12)[0]
                        - motion_with_sensitivities(t, *down, restoring=restoring,
                                                    rtol=1e-12)[0]) / (up[j] - down[j]))
    return np.column_stack(columns)


@pytest.mark.parametrize("restoring", ["linear", "pendulum"])
@pytest.mark.parametrize("mu", [0.0, 0.8])
def test_the_sensitivities_are_the_derivatives_of_the_motion(restoring, mu):
    """Against central differences, each column within 1e-4 of its size, with and without
    the reversals' jumps (sliding friction)."""
    t = np.arange(0.0, 6.0, 0.01)
    p = np.array([1.2, 0.3, OMEGA, 0.1, 0.4, mu])
    _, sensitivities = motion_with_sensitivities(t, *p, restoring=restoring, rtol=1e-12)
    expected = _central_differences(t, p, restoring)
    assert sensitivities.shape == (t.size, len(PARAMETERS))
    for j in range(p.size):
        size = np.max(np.abs(expected[:, j]))
        assert np.max(np.abs(sensitivities[:, j] - expected[:, j])) < 1e-4 * size, \
            PARAMETERS[j]


def test_a_start_at_rest_inside_the_friction_band_stays_there():
    t = np.linspace(0.0, 2.0, 11)
    x, sensitivities = motion_with_sensitivities(t, 0.01, 0.0, OMEGA, 0.1, 0.0, 1.0)
    assert np.all(x == 0.01)
    np.testing.assert_array_equal(sensitivities[:, 0], 1.0)


def test_times_after_the_start_and_unknown_restoring_forces():
    t = np.array([0.5, 1.0, 1.7])
    x, _ = motion_with_sensitivities(t, 1.0, 0.0, OMEGA, 0.2)
    np.testing.assert_allclose(x, viscous_motion(t, 1.0, 0.0, OMEGA, 0.2), atol=1e-8)
    with pytest.raises(ValueError, match="restoring"):
        motion_with_sensitivities(t, 1.0, 0.0, OMEGA, restoring="cubic")


def test_without_friction_the_sensitivity_to_it_is_skipped_only_when_not_wanted():
    t = np.arange(0.0, 10.0, 0.02)
    every = motion_with_sensitivities(t, 1.0, 0.2, OMEGA, 0.1, 0.3, restoring="pendulum",
                                      rtol=1e-11)
    some = motion_with_sensitivities(t, 1.0, 0.2, OMEGA, 0.1, 0.3, restoring="pendulum",
                                     rtol=1e-11, wanted=PARAMETERS[:5])
    np.testing.assert_allclose(some[0], every[0], atol=1e-8)
    np.testing.assert_allclose(some[1][:, :5], every[1][:, :5], atol=1e-6)
    assert np.all(np.isnan(some[1][:, 5])) and np.all(np.isfinite(every[1]))


def test_a_motion_the_integrator_cannot_follow_is_nan_not_a_warning():
    """A solver's trial step may make the motion run away (here negative damping): NaN from
    where the integration fails, which the fit steps back from, and no ODEintWarning."""
    t = np.linspace(0.0, 10.0, 101)
    x, sensitivities = motion_with_sensitivities(t, 1.0, 0.0, OMEGA, -50.0)
    assert x[0] == 1.0 and np.isnan(x[-1]) and np.isnan(sensitivities[-1]).all()
