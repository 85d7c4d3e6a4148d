"""The amplitude form's Jacobian (mcfit.fit.waveform_laws.AmplitudeWaveform, from
mcfit.phase_plane.phase_plane_differences) against central differences of the motion
itself (mcfit.phase_plane.phase_plane_motion), with and without a Coulomb stop."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcfit.fit.waveform_laws import AmplitudeWaveform
from mcfit.phase_plane import phase_plane_motion

OMEGA = 2 * math.pi
TERMS = ("a", "b", "c")


def _central(t, p, terms, i):
    """d x / d p_i by central differences of :func:`phase_plane_motion` (step 1e-5
    relative: truncation and the solve's rounding both near 1e-10 of the amplitude)."""
    h = 1e-5 * max(abs(p[i]), 1e-3)
    sets = np.repeat(p[None], 2, axis=0)
    sets[0, i] += h
    sets[1, i] -= h
    motion = np.zeros((2, 6))
    motion[:, :3] = sets[:, :3]
    for k, name in enumerate(terms):
        motion[:, 3 + TERMS.index(name)] = sets[:, 5 + k]
    x = phase_plane_motion(t, *motion.T)
    x = x + sets[:, 3:4] + sets[:, 4:5] * t
    return (x[0] - x[1]) / (2 * h)


@pytest.mark.parametrize(("q", "shares", "theta0", "stops"), [
    (2.0, {"b": 1.0}, 0.3, False),              # Q = 2: every half-cycle strongly damped
    (10.0, {"b": 1.0}, -0.4, False),
    (2.0, {"b": 0.9, "c": 0.1}, 0.2, True),     # a Coulomb stop early in the record
    (5.0, {"a": 0.2, "b": 0.7, "c": 0.1}, 1.0, True),
    (3.0, {"c": 1.0}, 0.5, True),               # Coulomb alone
])
def test_the_jacobian_is_the_derivative_of_the_motion(q, shares, theta0, stops):
    rate = OMEGA / (2 * q)  # the first decay rate c/y0 + b + a*y0 at y0 = 1
    terms = "".join(k for k in TERMS if k in shares)
    t = np.linspace(0.0, 4.0 * q, 2001)
    p = np.array([1.0, theta0, OMEGA, 0.01, 0.002] + [rate * shares[k] for k in terms])
    form = AmplitudeWaveform(t, np.zeros(t.size), 0.0, terms, 1.0)
    form.typical = np.maximum(np.abs(p), 1e-3)
    jacobian = form.jacobian(p)
    stop = form.memory["solution"][3].any() if "solution" in form.memory else None
    assert stop == stops
    for i in range(p.size):
        expected = _central(t, p, terms, i)
        scale = np.max(np.abs(expected))
        assert np.max(np.abs(jacobian[:, i] - expected)) < 1e-5 * scale, (i, scale)
