"""The velocity forms' closed form against an independent tight integration."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcfit.bench.reference_motion import integrate
from mcfit.viscous_motion import coulomb_force, viscous_motion

OMEGA = 2 * math.pi


@settings(max_examples=25, deadline=None)
@given(beta=st.floats(0.0, 2.0), mu=st.floats(0.0, 3.0), theta0=st.floats(-3.1, 3.1))
def test_viscous_motion_with_sliding_friction_matches_a_tight_integration(beta, mu, theta0):
    """Any viscous rate up to Q = 1.6, any friction (sticking within the record or not),
    any starting phase: within 1e-9 of the amplitude over 6 s."""
    x0, v0 = math.cos(theta0), -OMEGA * math.sin(theta0)
    t, expected = integrate(lambda x, v, _: 2 * beta * v, OMEGA, x0, 6.0, 50.0, mu=mu, v0=v0)
    c = 2 * mu / (math.pi * OMEGA)
    assert np.max(np.abs(viscous_motion(t, 1.0, theta0, OMEGA, beta, c) - expected)) < 1e-9


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
