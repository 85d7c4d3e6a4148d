"""The velocity forms of the damping that have a closed form: viscous damping with Coulomb
friction, x'' + 2*beta*x' + mu*sgn(x') + w**2*x = 0 (docs/theory.md section 5).

Between two reversals of the velocity the equation is linear, with the centre moved to
-sgn(x')*mu/w**2, so each half-cycle is a damped cosine about its own centre. From rest
every half-cycle lasts pi/w_d (w_d = sqrt(w**2 - beta**2)) and the turning points' distances
from 0 follow r' = (r - m)*q - m, m = mu/w**2, q = exp(-beta*pi/w_d); the mass sticks at the
first turning point with r <= m (static friction equal to the sliding friction). With
mu = 0 this is x = A*exp(-beta*t)*cos(w_d*t + phi), exact at any Q; its turning points follow
the averaged law dy/dt = -beta*y, and the Coulomb term that of dy/dt = -c with
c = 2*mu/(pi*w).

:func:`viscous_motion_jacobian` gives the derivatives of x with respect to the five
parameters in closed form too (piecewise where the mass sticks): every scalar of the
solution carries its gradient (:class:`mcfit.jets.Jet`), and x's partial derivatives with respect to
those scalars are combined with them once per sample. The per-sample work is compiled
(:mod:`mcfit.viscous_kernels`, numba), imported at the first motion only: the
turning-point path imports this module without numba.
"""

from __future__ import annotations

import math

import numpy as np

from mcfit.jets import Jet

__all__ = ["AT_REST", "coulomb_force", "viscous_motion", "viscous_motion_jacobian"]

# The parameters of the derivatives, in the order of viscous_motion's arguments.
_PARAMETERS = ("y0", "theta0", "omega", "beta", "c")
AT_REST = 1e-14  # a starting speed below this share of omega*|x0| is none


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
    return _motion(tau, y0, theta0, omega, beta, c, False)[0]


def viscous_motion_jacobian(tau, y0, theta0, omega, beta, c=0.0):
    """x(tau) as :func:`viscous_motion` gives it, and its derivatives with respect to
    (y0, theta0, omega, beta, c) in closed form.

    Returns
    -------
    x : ndarray, shape (n,)
        The displacement (U).
    jacobian : ndarray, shape (5, n)
        dx/dy0, dx/dtheta0, dx/domega, dx/dbeta, dx/dc. Where the mass sticks (or a
        half-cycle ends) the derivative is that of the side the times fall on.
    """
    return _motion(tau, y0, theta0, omega, beta, c, True)


def _motion(tau, y0, theta0, omega, beta, c, derivatives):
    tau = np.ascontiguousarray(tau, dtype=float)
    y0, theta0, omega, beta, c = Jet.variables((y0, theta0, omega, beta, c))
    squared = omega * omega - beta * beta
    damped = (squared.sqrt() if squared.v > 1e-12 * omega.v * omega.v
              else omega * 1e-6)
    offset = (0.5 * math.pi) * c / omega  # mu / omega**2
    x0, v0 = y0 * theta0.cos(), -(omega * y0 * theta0.sin())
    if abs(v0.v) <= AT_REST * omega.v * abs(x0.v):
        # At rest (theta0 a multiple of pi, where sin is 1e-16, not 0): a velocity of
        # either sign would start a half-cycle that ends at once or the wrong way.
        v0 = Jet(0.0, v0.g)
    if v0.v == 0.0 and abs(x0.v) <= offset.v:
        return np.full(tau.shape, x0.v), _constant(x0, tau, derivatives)
    sense = math.copysign(1.0, v0.v) if v0.v != 0.0 else -math.copysign(1.0, x0.v)
    centre = offset * -sense
    start = x0 - centre
    slope = (v0 + beta * start) / damped
    first = Jet.atan2(v0, start * damped + beta * slope)
    first = Jet(first.v % math.pi or math.pi, first.g)
    first_end = first / damped
    half = math.pi / damped
    end = float(np.max(tau[np.isfinite(tau)], initial=0.0))  # times in any order
    if end > first_end.v:
        x1 = centre + (beta * first_end * -1.0).exp() * (start * first.cos()
                                                         + slope * first.sin())
        count = int(math.ceil((end - first_end.v) / half.v)) + 1
        points, point_gradients = _turning_points(x1, offset, (beta * half * -1.0).exp(),
                                                  count)
    else:
        points, point_gradients = np.empty(0), np.empty((len(_PARAMETERS), 0))
    # numba's import is the waveform fit's: the turning-point path imports this module.
    from mcfit.viscous_kernels import damped_swings

    scalars = np.array([first_end.v, half.v, beta.v, damped.v, omega.v, offset.v,
                        centre.v, start.v, slope.v])
    gradients = _gradients(centre, start, slope, beta, damped, first_end, half, offset)
    jacobian = np.empty((len(_PARAMETERS), tau.size if derivatives else 0))
    x, jacobian = damped_swings(tau, scalars, gradients, points, point_gradients,
                                np.empty(tau.size), jacobian)
    return x, jacobian if derivatives else None


def _gradients(*jets):
    """The gradients of ``jets`` as columns, shape (5, len(jets))."""
    columns = np.empty((len(_PARAMETERS), len(jets)))
    for i, jet in enumerate(jets):
        columns[:, i] = jet.g
    return columns


def _constant(value, tau, derivatives):
    return np.outer(value.g, np.ones(tau.size)) if derivatives else None


def _turning_points(x1, offset, ratio, count):
    """The signed turning points from ``x1`` on, each from rest: r' = (r - m)*q - m with
    alternating signs, held at the first with r <= m (stuck); and their gradients, shape
    (5, count)."""
    k = np.arange(count)
    q, m = ratio.v, offset.v
    powers = q ** k
    # (1 - q**k)/(1 - q) without cancellation, k where q == 1; its derivative in q is
    # the sum of j*q**(j - 1) for j < k.
    sums = k.astype(float) if q == 1.0 else -np.expm1(k * math.log(q)) / (1 - q)
    sums_by_q = np.concatenate([[0.0], np.cumsum(k[:-1] * q ** np.maximum(k[:-1] - 1, 0))])
    distance = powers * abs(x1.v) - m * (1 + q) * sums
    by_q = (k * q ** np.maximum(k - 1, 0) * abs(x1.v) - m * sums - m * (1 + q) * sums_by_q)
    gradient = (np.outer(math.copysign(1.0, x1.v) * x1.g, powers)
                - np.outer(offset.g, (1 + q) * sums) + np.outer(ratio.g, by_q))
    signs = math.copysign(1.0, x1.v) * (-1.0) ** k
    points = signs * distance
    gradients = signs * gradient
    stuck = np.flatnonzero(distance <= m)
    if stuck.size:
        first = stuck[0]
        # A last half-swing that does not cross 0 ends on the side it started.
        points[first:] = points[first]
        gradients[:, first:] = gradients[:, first:first + 1]
    return points, gradients
