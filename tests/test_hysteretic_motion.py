"""Eq. 20.55 with the hysteretic term alone in closed form (mcfit.hysteretic_motion),
against the accurate integrator (DOP853 at 1e-12, every reversal a step end) and its own
derivatives against differences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcfit.hysteretic_motion import hysteretic_motion, hysteretic_motion_jacobian
from mcfit.motion import damping_terms, integrate_accurate

OMEGA = 2 * math.pi


def _accurate(t, y0, theta0, omega, b):
    motion = integrate_accurate(y0 * math.cos(theta0), -omega * y0 * math.sin(theta0), omega,
                                damping_terms(0.0, b, 0.0), t, rtol=1e-12,
                                atol=1e-14 * y0)
    return motion.x


@settings(max_examples=30, deadline=None)
@given(q=st.floats(1.0, 300.0), theta0=st.floats(-7.0, 7.0), y0=st.floats(1e-3, 1e3))
def test_the_closed_form_follows_the_accurate_integrator(q, theta0, y0):
    """Q from 1 to 300 (b = omega/(2*Q)), any start phase and size: within 1e-9 of y0
    over ten periods."""
    t = np.linspace(0.0, 10.0, 2001)
    b = OMEGA / (2 * q)
    x = hysteretic_motion(t, y0, theta0, OMEGA, b)[0]
    assert np.max(np.abs(x - _accurate(t, y0, theta0, OMEGA, b))) < 1e-9 * y0


def test_several_sets_at_once_are_each_sets_motion():
    t = np.linspace(0.0, 5.0, 501)
    sets = np.array([[1.0, 0.0, OMEGA, 0.3], [2.0, 2.0, 5.0, 0.05], [0.5, -1.0, 7.0, 1.5]])
    together = hysteretic_motion(t, *sets.T)
    for row, p in zip(together, sets):
        np.testing.assert_allclose(row, _accurate(t, *p), rtol=0, atol=1e-9 * p[0])


@pytest.mark.parametrize("q", [1.0, 2.0, 5.0, 40.0])
@pytest.mark.parametrize("theta0", [0.4, 2.5, -1.0, 7.0])
def test_the_derivatives_match_central_differences(q, theta0):
    t = np.linspace(0.0, 8.0, 4001)
    p = np.array([1.3, theta0, OMEGA, OMEGA / (2 * q)])
    _, jacobian = hysteretic_motion_jacobian(t, *p)
    for i in range(4):
        step = 1e-6 * max(abs(p[i]), 1.0)
        up, down = p.copy(), p.copy()
        up[i] += step
        down[i] -= step
        difference = (hysteretic_motion_jacobian(t, *up, derivatives=False)[0]
                      - hysteretic_motion_jacobian(t, *down, derivatives=False)[0]) / (2 * step)
        assert np.max(np.abs(difference - jacobian[i])) < 1e-7 * np.max(np.abs(jacobian[i]))


def test_at_a_turning_point_the_phase_derivative_is_the_one_forward():
    """At theta0 = 0 the motion has a kink in theta0 (a start just before the turning
    point meets the friction of the other sense first); the waveform fit starts there and
    steps forward, as the phase plane's forward differences do."""
    t = np.linspace(0.0, 8.0, 4001)
    _, jacobian = hysteretic_motion_jacobian(t, 1.0, 0.0, OMEGA, 0.2)
    step = 1e-7
    forward = (hysteretic_motion(t, 1.0, step, OMEGA, 0.2)[0]
               - hysteretic_motion(t, 1.0, 0.0, OMEGA, 0.2)[0]) / step
    assert np.max(np.abs(forward - jacobian[1])) < 1e-5 * np.max(np.abs(jacobian[1]))


def test_each_half_cycle_ends_at_the_ratio_of_the_closed_form():
    """Turning points of the accurate motion fall by (omega - k)/(omega + k), k = pi*b/2,
    every half-cycle, and the closed form is at them then."""
    b, y0 = 0.4, 1.0
    k = 0.5 * math.pi * b
    nu = math.sqrt(OMEGA**2 - k**2)
    ends = math.pi / nu * np.arange(1, 9)
    x = hysteretic_motion(ends, y0, 0.0, OMEGA, b)[0]
    ratio = (OMEGA - k) / (OMEGA + k)
    np.testing.assert_allclose(np.abs(x), y0 * ratio ** np.arange(1, 9), rtol=1e-12)
    np.testing.assert_allclose(x, _accurate(ends, y0, 0.0, OMEGA, b), atol=1e-10)


def test_the_waveform_law_of_b_alone_is_the_phase_planes():
    """The amplitude form's law for b alone (closed form) gives the residuals and the
    Jacobian of the phase-plane law for the same model, to the phase plane's accuracy."""
    from mcfit.fit.waveform_laws import AmplitudeWaveform, amplitude_waveform

    rng = np.random.default_rng(5)
    t = np.linspace(0.3, 12.0, 6000)
    x = 0.01 * rng.standard_normal(t.size)
    p = np.array([1.2, 0.3, OMEGA, 0.01, 0.002, OMEGA / (2 * 4.0)])
    closed, plane = (law(t, x, 0.3, ("b",), 0.01) for law in (amplitude_waveform,
                                                               AmplitudeWaveform))
    assert type(closed).__name__ == "HystereticWaveform"
    for law in (closed, plane):
        law.typical = np.maximum(np.abs(p), 1e-3)
    np.testing.assert_allclose(closed.residual(p), plane.residual(p), rtol=0, atol=1e-5)
    by_closed, by_plane = closed.jacobian(p), plane.jacobian(p)
    scale = np.max(np.abs(by_plane), axis=0)
    assert np.all(np.max(np.abs(by_closed - by_plane), axis=0) < 1e-5 * scale)
