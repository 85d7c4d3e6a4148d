"""The waveform fit's evaluations of the model and its Jacobian (mcfit.fit.waveform_laws'
AmplitudeWaveform and VelocityWaveform) against differences of the motion itself."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcfit.fit import waveform_laws
from mcfit.viscous_motion import viscous_motion

OMEGA = 2 * math.pi


@pytest.mark.parametrize(("terms", "values"), [
    ("b", [0.3]), ("c", [0.05]), ("bc", [0.4, 0.02]),
    ("b", [7.0]),  # beta held at 0.99*omega: b moves nothing, omega moves beta too
])
def test_the_velocity_forms_jacobian_is_the_derivative_of_the_residuals(terms, values):
    """Columns y0, theta0, omega, offset, drift and the terms against central differences
    of the residuals (in noise units), b held below omega included."""
    t = np.linspace(0.0, 8.0, 1601)
    form = waveform_laws.VelocityWaveform(t, np.zeros(t.size), 0.0, terms, 1e-3)
    p = np.array([1.2, 0.4, OMEGA, 0.01, 0.002] + values)
    jacobian = form.jacobian(p)
    for i in range(p.size):
        h = 1e-6 * max(abs(p[i]), 0.1)
        up, down = p.copy(), p.copy()
        up[i] += h
        down[i] -= h
        expected = (form.residual(up) - form.residual(down)) / (2 * h)
        scale = np.max(np.abs(expected)) + 1.0
        assert np.max(np.abs(jacobian[:, i] - expected)) < 1e-6 * scale, i


def test_the_velocity_forms_residuals_are_the_closed_form():
    t = np.linspace(0.5, 8.5, 801)
    x = np.sin(t)
    form = waveform_laws.VelocityWaveform(t, x, 0.5, "bc", 2e-3)
    p = np.array([1.2, 0.4, OMEGA, 0.01, 0.002, 0.4, 0.02])
    tau = t - 0.5
    expected = viscous_motion(tau, 1.2, 0.4, OMEGA, 0.4, 0.02) + 0.01 + 0.002 * tau
    np.testing.assert_allclose(form.residual(p), (expected - x) / 2e-3, rtol=1e-12,
                               atol=1e-9)
