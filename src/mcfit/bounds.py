"""Cramer-Rao bounds of the damping coefficients: the smallest standard errors any unbiased
fit can reach from a record with white Gaussian noise (docs/theory.md section 8). numpy only.

The bound is ``sqrt(diag(inv(J.T @ J))) * sigma`` with J the model's derivatives with respect
to every free parameter at the truth. From turning-point amplitudes the parameters are y0
and the free coefficients; from the samples of a waveform
``x = y(t) * cos(omega*t + phase) + x_eq`` also omega, the phase and x_eq.

>>> import numpy as np
>>> t = np.arange(0.0, 50.0, 0.5)
>>> bound = amplitude_crlb(t, 1.0, 0.0, 0.02, 0.0, sigma=1e-3, model="b")
>>> round(bound["b"] * 1e5, 2)  # 1/s
1.15
"""

from __future__ import annotations

import math

import numpy as np

from mcfit import decay

__all__ = ["amplitude_crlb", "waveform_crlb"]


def amplitude_crlb(t, y0, a, b, c, sigma, model="abc") -> dict:
    """Bounds of the coefficients in ``model`` from amplitudes at times ``t`` (from the
    time where the amplitude is ``y0``), each with noise ``sigma`` (scalar or per point).
    Returns {letter: bound} in the coefficients' units."""
    jacobian = decay.amplitude_jacobian(np.asarray(t, dtype=float), y0, a, b, c)
    columns = jacobian[:, _columns(model)] / np.broadcast_to(sigma, np.shape(t))[:, None]
    return _bounds(columns, model)


def waveform_crlb(t, y0, a, b, c, period, sigma_x, model="abc", phase=0.0) -> dict:
    """Bounds of the coefficients in ``model`` from a waveform sampled at ``t`` (s, from
    the time where the amplitude is ``y0``) with noise ``sigma_x`` per sample, the period,
    phase and equilibrium fitted too. Returns {letter: bound} in the coefficients' units."""
    t = np.asarray(t, dtype=float)
    omega = 2 * math.pi / period
    y, jacobian = decay.amplitude_and_jacobian(t, y0, a, b, c)
    carrier, quadrature = np.cos(omega * t + phase), np.sin(omega * t + phase)
    design = np.column_stack([jacobian[:, _columns(model)] * carrier[:, None],
                              -y * t * quadrature, -y * quadrature, np.ones_like(t)])
    return _bounds(design / sigma_x, model)


def _columns(model):
    """y0's column and those of the coefficients in ``model``."""
    return [0] + ["abc".index(k) + 1 for k in model]


def _bounds(design, model):
    """sqrt(diag(inv(D.T @ D))) of the coefficients (columns 1 to len(model)); the columns
    are scaled to unit norm first, so the inverse is well conditioned."""
    norms = np.linalg.norm(design, axis=0)
    scaled = design / norms
    covariance = np.linalg.inv(scaled.T @ scaled) / np.outer(norms, norms)
    bounds = np.sqrt(np.diag(covariance))
    return {k: float(bounds[i + 1]) for i, k in enumerate(model)}
