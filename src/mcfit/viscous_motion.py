"""The velocity forms of the damping that have a closed form: viscous damping with Coulomb
friction, x'' + 2*beta*x' + mu*sgn(x') + w**2*x = 0 (THEORY.md section 9), numpy only.

Between two reversals of the velocity the equation is linear, with the centre moved to
-sgn(x')*mu/w**2, so each half-cycle is a damped cosine about its own centre. From rest
every half-cycle lasts pi/w_d (w_d = sqrt(w**2 - beta**2)) and the turning points' distances
from 0 follow r' = (r - m)*q - m, m = mu/w**2, q = exp(-beta*pi/w_d); the mass sticks at the
first turning point with r <= m (static friction equal to the sliding friction). With
mu = 0 this is x = A*exp(-beta*t)*cos(w_d*t + phi), exact at any Q; its turning points follow
the averaged law dy/dt = -beta*y, and the Coulomb term that of dy/dt = -c with
c = 2*mu/(pi*w).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["coulomb_force", "viscous_motion"]


def coulomb_force(c, omega):
    """mu (U/s**2), the sliding friction per unit mass whose averaged law's term is ``c``
    (U/s): c = 2*mu/(pi*omega)."""
    return 0.5 * math.pi * omega * c


def viscous_motion(tau, y0, theta0, omega, beta, c=0.0):
    """x(tau) of x'' + 2*beta*x' + mu*sgn(x') + omega**2*x = 0, mu = pi*omega*c/2.

    Parameters
    ----------
    tau : ndarray, shape (n,)
        Times (s) from the start, >= 0.
    y0, theta0 : float
        Energy amplitude (U) and phase (rad) at the start: x = y0*cos(theta0),
        x' = -omega*y0*sin(theta0).
    omega : float
        Undamped angular frequency (rad/s).
    beta : float
        Viscous rate (1/s), 0 <= beta < omega: the averaged law's b.
    c : float
        The averaged law's Coulomb term (U/s), >= 0.

    Returns
    -------
    ndarray, shape (n,)
        The displacement (U); constant from where the mass sticks.
    """
    tau = np.asarray(tau, dtype=float)
    damped = math.sqrt(max(omega * omega - beta * beta, 1e-12 * omega * omega))
    offset = 0.5 * math.pi * c / omega  # mu / omega**2
    x0, v0 = y0 * math.cos(theta0), -omega * y0 * math.sin(theta0)
    if v0 == 0.0 and abs(x0) <= offset:
        return np.full(tau.shape, x0)
    sense = math.copysign(1.0, v0) if v0 != 0.0 else -math.copysign(1.0, x0)
    centre = -sense * offset
    start, slope = x0 - centre, (v0 + beta * (x0 - centre)) / damped
    first = (math.atan2(v0, start * damped + beta * slope) % math.pi) or math.pi
    first_end = first / damped
    x = centre + np.exp(-beta * tau) * (start * np.cos(damped * tau)
                                        + slope * np.sin(damped * tau))
    later = tau > first_end
    if not np.any(later):
        return x
    x1 = centre + math.exp(-beta * first_end) * (start * math.cos(first)
                                                 + slope * math.sin(first))
    half = math.pi / damped
    count = int(math.ceil((tau[-1] - first_end) / half)) + 1
    turning = _turning_points(x1, offset, math.exp(-beta * half), count)
    k = np.minimum(((tau[later] - first_end) // half).astype(np.int64), turning.size - 1)
    since = tau[later] - first_end - k * half
    at = turning[k]
    centre_k = np.sign(at) * offset
    moving = np.abs(at) > offset
    swing = np.exp(-beta * since) * (np.cos(damped * since)
                                     + beta / damped * np.sin(damped * since))
    x[later] = np.where(moving, centre_k + (at - centre_k) * swing, at)
    return x


def _turning_points(x1, offset, ratio, count):
    """The signed turning points from ``x1`` on, each from rest: r' = (r - m)*q - m with
    alternating signs, held at the first with r <= m (stuck)."""
    k = np.arange(count)
    powers = ratio ** k
    # (1 - q**k)/(1 - q) without cancellation, k where q == 1.
    sums = k.astype(float) if ratio == 1.0 else -np.expm1(k * math.log(ratio)) / (1 - ratio)
    distance = powers * abs(x1) - offset * (1 + ratio) * sums
    signs = math.copysign(1.0, x1) * (-1.0) ** k
    points = signs * distance
    stuck = np.flatnonzero(distance <= offset)
    if stuck.size:
        first = stuck[0]
        # A last half-swing that does not cross 0 ends on the side it started.
        points[first:] = points[first]
    return points
