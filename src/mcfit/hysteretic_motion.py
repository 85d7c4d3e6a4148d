"""Eq. 20.55 with the hysteretic term alone, in closed form: numpy only, no I/O.

With g(A) = b*A the equation of motion xddot + (pi*omega/2)*b*A*sgn(xdot) + omega**2*x = 0
(A the energy amplitude) has, in the phase plane of :mod:`mcfit.phase_plane`,
D = omega - k*cos(phi) with k = pi*b/2 in every half-cycle, independent of A. Then
dA/dphi = -k*A*sin(phi)/D integrates to A*D = const, and dt/dphi = 1/D to a half-cycle of
pi/nu, nu = sqrt(omega**2 - k**2). Counted from a turning point of amplitude A_j, the
half-cycle is a cosine about a centre that scales with it::

    x = +-A_j*(omega*cos(nu*t) + k)/(omega + k),    A_(j+1) = A_j*(omega - k)/(omega + k),

so the force (pi*omega/2)*b*A acts like a sliding friction whose size follows the
amplitude. :func:`hysteretic_motion` gives x(t) for several parameter sets at once, as
:func:`mcfit.phase_plane.phase_plane_motion` does; :func:`hysteretic_motion_jacobian` one
set and its derivatives, at a small share of the phase plane's cost.
"""

from __future__ import annotations

import math

import numpy as np

from mcfit.jets import Jet

__all__ = ["hysteretic_motion", "hysteretic_motion_jacobian"]

# k is held this far below omega (b near 2*omega/pi, Q near pi/4: no swing would cross 0).
_HELD = 1 - 1e-9


def hysteretic_motion(t, y0, theta0, omega, b):
    """x(t) of Eq. 20.55 with g(A) = b*A for ``m`` parameter sets at once.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Times (s) from the start, >= 0.
    y0, theta0, omega, b : ndarray, shape (m,) (or scalars)
        Energy amplitude (U) and phase (rad) at t = 0, with x = y0*cos(theta0) and
        xdot = -omega*y0*sin(theta0); angular frequency (rad/s); the averaged law's
        hysteretic rate (1/s), 0 <= b < 2*omega/pi (Q above pi/4; a larger b is held
        there).

    Returns
    -------
    ndarray, shape (m, n)
        The displacement (U).
    """
    sets = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, dtype=float))
                                 for v in (y0, theta0, omega, b)))
    return np.array([hysteretic_motion_jacobian(t, *p, derivatives=False)[0]
                     for p in zip(*sets)]).reshape(len(sets[0]), -1)


def hysteretic_motion_jacobian(t, y0, theta0, omega, b, derivatives=True):
    """x(t) as :func:`hysteretic_motion` gives it for one parameter set, and its
    derivatives with respect to (y0, theta0, omega, b), shape (4, n) (None unless
    ``derivatives``)."""
    t = np.asarray(t, dtype=float)
    y0, theta0, omega, b = Jet.variables((y0, theta0, omega, b))
    k = b * (0.5 * math.pi)
    if k.v > _HELD * omega.v:
        k = omega * _HELD
    less, more = omega - k, omega + k
    nu, log_ratio = (less * more).sqrt(), (less / more).log()
    turns = math.floor(theta0.v / math.pi)
    half = (theta0 - math.pi * turns) * 0.5  # half the phase into the half-cycle
    # The cosine's phase at t = 0, and the amplitude at the turning point its half-cycle
    # starts from.
    start = Jet.atan2(more.sqrt() * half.sin(), less.sqrt() * half.cos()) * 2
    first = y0 * (omega - k * (half * 2).cos()) / less
    phase = nu.v * t + start.v
    count = (phase * (1 / math.pi)).astype(np.intp)
    j = np.arange(int(count.max()) + 1 if count.size else 1)
    sign = -1.0 if turns % 2 else 1.0
    # Per half-cycle j: sign * ratio**j / (omega + k), and (-1)**j.
    scale = (sign / more.v) * np.exp(j * log_ratio.v)[count]
    parity = np.where(j % 2, -1.0, 1.0)[count]
    cos = np.cos(phase)
    shape = scale * (omega.v * cos + parity * k.v)  # x / first
    x = first.v * shape
    if not derivatives:
        return x, None
    sin_part = first.v * scale * omega.v * np.sin(phase)
    # x's partial derivatives in first, the log of the ratio, omega, nu, the start, k and
    # omega + k, by the chain rule with their gradients.
    basis = np.array([shape, x * count, first.v * scale * cos, sin_part * t, sin_part,
                      first.v * scale * parity, x])
    weights = np.array([first.g, log_ratio.g, omega.g, -nu.g, -start.g, k.g,
                        -more.g / more.v])
    return x, weights.T @ basis
