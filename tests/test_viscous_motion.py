"""The velocity forms' closed form against an independent tight integration."""

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from mcfit.bench.reference_motion import integrate
from mcfit.viscous_motion import coulomb_force, viscous_motion, viscous_motion_jacobian
from process_tools import python_words

OMEGA = 2 * math.pi
# x and the Jacobian from the numpy implementation that preceded the compiled kernel, on
# 241 samples from 0 to the duration (last item) of each set of (y0, theta0, omega, beta, c).
REFERENCE = Path(__file__).with_name("data") / "viscous_motion.npz"
REFERENCE_CASES = {
    "q1.5_from_crest": (1.0, 0.0, OMEGA, OMEGA / 3.0, 0.0, 4.0),
    "q3_sticks": (1.0, 0.0, OMEGA, OMEGA / 6.0, 0.04, 6.0),
    "q10_trough_friction": (1.3, math.pi, OMEGA, OMEGA / 20.0, 0.01, 12.0),
    "q5_trough": (0.8, -math.pi, OMEGA, OMEGA / 10.0, 0.0, 8.0),
    "q200_phase": (1.0, 0.7, OMEGA, OMEGA / 400.0, 0.0, 40.0),
    "q200_phase_friction": (1.0, 0.7, OMEGA, OMEGA / 400.0, 0.002, 40.0),
    "q8_sticks_negative_phase": (2.0, -2.3, OMEGA, OMEGA / 16.0, 0.05, 10.0),
    "q1.5_sticks_at_once": (1.0, 2.0, OMEGA, OMEGA / 3.0, 0.1, 3.0),
    "rest_in_dead_band": (0.001, 0.0, OMEGA, OMEGA / 40.0, 0.02, 5.0),
    "q50_trough_friction": (1.0, 3 * math.pi, 3.0, 0.03, 0.003, 30.0),
    "q2_sticks_early": (1.0, 0.3, OMEGA, OMEGA / 4.0, 0.08, 5.0),
    "q30_quadrature": (2.5, 1.5, 9.0, 0.15, 0.0, 15.0),
}


@settings(max_examples=25, deadline=None)
@given(beta=st.floats(0.0, 2.0), mu=st.floats(0.0, 3.0), theta0=st.floats(-3.1, 3.1))
@example(beta=0.0, mu=0.0, theta0=1e-9)  # a reversal 1.6e-10 s before the record's end
def test_viscous_motion_with_sliding_friction_matches_a_tight_integration(beta, mu, theta0):
    """Any viscous rate up to Q = 1.6, any friction (sticking within the record or not),
    any starting phase: within 1e-9 of the amplitude over 6 s."""
    x0, v0 = math.cos(theta0), -OMEGA * math.sin(theta0)
    t, expected = integrate(lambda x, v, _: 2 * beta * v, OMEGA, x0, 6.0, 50.0, mu=mu, v0=v0)
    c = 2 * mu / (math.pi * OMEGA)
    assert np.max(np.abs(viscous_motion(t, 1.0, theta0, OMEGA, beta, c) - expected)) < 1e-9


@pytest.mark.parametrize("theta0", [math.pi, -math.pi, 3 * math.pi])
def test_a_start_at_rest_on_the_negative_side_swings_back(theta0):
    """theta0 a multiple of pi: sin(theta0) is 1e-16, not 0; the mass starts from rest at
    -y0 (before, a velocity of -1e-16 ran a whole half-cycle with the friction's sign
    reversed, 4*mu/w**2 off for the rest of the record)."""
    mu = 0.3
    t, expected = integrate(lambda x, v, _: 0.4 * v, OMEGA, -1.0, 6.0, 50.0, mu=mu)
    x = viscous_motion(t, 1.0, theta0, OMEGA, 0.2, 2 * mu / (math.pi * OMEGA))
    assert np.max(np.abs(x - expected)) < 1e-9


def test_without_friction_it_is_the_damped_cosine():
    t = np.linspace(0.0, 5.0, 501)
    damped = math.sqrt(OMEGA**2 - 0.64)
    np.testing.assert_allclose(viscous_motion(t, 2.0, 0.0, OMEGA, 0.8, 0.0),
                               2.0 * np.exp(-0.8 * t) * (np.cos(damped * t)
                                                         + 0.8 / damped * np.sin(damped * t)),
                               atol=1e-13)


def test_friction_stops_the_mass_off_centre_and_keeps_it_there():
    t = np.linspace(0.0, 30.0, 3001)
    c = 0.02
    x = viscous_motion(t, 1.0, 0.0, OMEGA, 0.05, c)
    offset = coulomb_force(c, OMEGA) / OMEGA**2
    assert 0 < abs(x[-1]) <= offset and np.all(x[-200:] == x[-1])


def test_the_coulomb_force_gives_the_averaged_term():
    # Coulomb friction mu removes 4*mu*A per cycle of energy w**2*A**2/2: dA/dt = -2*mu/(pi*w).
    assert 2 * coulomb_force(0.3, OMEGA) / (math.pi * OMEGA) == pytest.approx(0.3, rel=1e-15)


def _central(tau, p, i, h):
    up, down = np.array(p, dtype=float), np.array(p, dtype=float)
    up[i] += h
    down[i] -= h
    return (viscous_motion(tau, *up) - viscous_motion(tau, *down)) / (2 * h)


@settings(max_examples=25, deadline=None)
@given(beta=st.floats(0.0, 2.0), mu=st.floats(0.05, 3.0),
       theta0=st.floats(-3.1, 3.1).filter(lambda v: abs(math.sin(v)) > 1e-3),
       y0=st.floats(0.5, 2.0))
def test_the_jacobian_is_the_derivative_of_the_motion(beta, mu, theta0, y0):
    """The closed-form derivatives in (y0, theta0, omega, beta, c) against central
    differences of the motion, sticking within the record or not: within 1e-6 of the
    largest derivative (the differences' own error is about 1e-8). A start at rest
    (theta0 a multiple of pi) is a kink in theta0, where the friction's sign is chosen."""
    tau = np.linspace(0.0, 6.0, 1201)
    p = [y0, theta0, OMEGA, beta, 2 * mu / (math.pi * OMEGA)]
    x, jacobian = viscous_motion_jacobian(tau, *p)
    np.testing.assert_array_equal(x, viscous_motion(tau, *p))
    for i in range(5):
        expected = _central(tau, p, i, 1e-6 * max(abs(p[i]), 0.1))
        scale = np.max(np.abs(expected)) + 1.0
        assert np.max(np.abs(jacobian[i] - expected)) < 1e-6 * scale, i


def test_the_jacobian_without_friction_is_the_damped_cosines():
    """mu = 0: d/dbeta of exp(-beta*t)*(cos(wd*t) + beta/wd*sin(wd*t)), wd**2 = w**2 -
    beta**2, differentiated by hand; and d/dc as the one-sided limit c -> 0+."""
    tau = np.linspace(0.0, 5.0, 501)
    beta = 0.8
    damped = math.sqrt(OMEGA**2 - beta**2)
    d_damped = -beta / damped
    decay, cos, sin = np.exp(-beta * tau), np.cos(damped * tau), np.sin(damped * tau)
    by_beta = (-tau * decay * (cos + beta / damped * sin)
               + decay * (-tau * d_damped * sin + sin / damped - beta * d_damped / damped**2 * sin
                          + beta / damped * tau * d_damped * cos))
    _, jacobian = viscous_motion_jacobian(tau, 1.0, 0.0, OMEGA, beta, 0.0)
    np.testing.assert_allclose(jacobian[3], by_beta, atol=1e-12)
    h = 1e-9
    one_sided = (viscous_motion(tau, 1.0, 0.0, OMEGA, beta, h)
                 - viscous_motion(tau, 1.0, 0.0, OMEGA, beta, 0.0)) / h
    np.testing.assert_allclose(jacobian[4], one_sided, atol=1e-5)


def test_the_jacobian_of_a_stuck_mass_is_that_of_its_stop():
    """From the stop on x is the turning point where the mass stuck: its derivatives are
    the same at every later time, and the start at rest inside the dead band is x0."""
    tau = np.linspace(0.0, 30.0, 3001)
    x, jacobian = viscous_motion_jacobian(tau, 1.0, 0.0, OMEGA, 0.05, 0.02)
    assert np.all(jacobian[:, -200:] == jacobian[:, -1:])
    held, still = viscous_motion_jacobian(tau, 0.001, 0.0, OMEGA, 0.05, 0.02)
    assert np.all(held == 0.001)
    np.testing.assert_array_equal(still, np.outer([1.0, 0.0, 0.0, 0.0, 0.0],
                                                  np.ones(tau.size)))


@pytest.mark.parametrize("name", sorted(REFERENCE_CASES))
def test_the_motion_and_jacobian_are_those_of_the_reference(name):
    """Starts at a crest, a trough (theta0 = +-pi, 3*pi) or between, with and without
    friction, the mass sticking inside the record or not, Q from 1.5 to 200: x within
    1e-13 of y0 and each derivative within 1e-13 of its largest stored value."""
    *p, duration = REFERENCE_CASES[name]
    tau = np.linspace(0.0, duration, 241)
    x, jacobian = viscous_motion_jacobian(tau, *p)
    with np.load(REFERENCE) as stored:
        expected = stored[name]
    assert np.max(np.abs(x - expected[0])) <= 1e-13 * p[0]
    for i in range(5):
        scale = np.max(np.abs(expected[1 + i]))
        assert np.max(np.abs(jacobian[i] - expected[1 + i])) <= 1e-13 * scale, i


def test_numba_loads_with_the_motion_not_with_the_module():
    """The turning-point path imports this module (for AT_REST), not numba; the motion
    loads the compiled kernel."""
    code = (
        "import sys\n"
        "import numpy as np\n"
        "from mcfit import viscous_motion\n"
        "print('numba' in sys.modules, 'mcfit.viscous_kernels' in sys.modules)\n"
        "viscous_motion.viscous_motion(np.linspace(0.0, 3.0, 31), 1.0, 0.2, 6.0, 0.3)\n"
        "print('mcfit.viscous_kernels' in sys.modules)\n")
    assert python_words(code) == ["False", "False", "True"]


def test_the_kernel_compiles_once():
    """One type per argument (a first compilation, about 0.6 s, not one per call's kind):
    the motion alone, a record within the first half-cycle, an empty one, a strided one."""
    viscous_motion(np.arange(10.0)[::2], 1.0, 0.3, OMEGA, 0.1, 0.01)
    viscous_motion_jacobian(np.linspace(0.0, 5.0, 101), 1.0, 0.3, OMEGA, 0.1, 0.01)
    viscous_motion_jacobian(np.linspace(0.0, 0.01, 5), 1.0, 0.3, OMEGA, 0.1, 0.0)
    viscous_motion_jacobian(np.empty(0), 1.0, 0.0, OMEGA, 0.1, 0.0)
    from mcfit.viscous_kernels import damped_swings

    assert len(damped_swings.signatures) == 1


@pytest.mark.parametrize("c", [0.0, 0.05])
def test_times_in_any_order_give_each_time_its_own_motion(c):
    """The half-cycles are counted to the latest time, not the last one given: the
    samples of a permutation are the permuted samples, and times before the first given
    one (as [5, 0]) are no reads past the turning points."""
    tau = np.linspace(0.0, 5.0, 501)
    order = np.random.default_rng(3).permutation(tau.size)
    x, jacobian = viscous_motion_jacobian(tau, 1.0, 0.0, 2 * math.pi, 0.3, c)
    x_moved, jacobian_moved = viscous_motion_jacobian(tau[order], 1.0, 0.0, 2 * math.pi,
                                                      0.3, c)
    assert np.array_equal(x_moved, x[order])
    assert np.array_equal(jacobian_moved, jacobian[:, order])
    pair = viscous_motion_jacobian(np.array([5.0, 0.0]), 1.0, 0.0, 2 * math.pi, 0.3, c)
    assert np.array_equal(pair[0], x[[-1, 0]]) and np.array_equal(pair[1], jacobian[:, [-1, 0]])
