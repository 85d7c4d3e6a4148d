"""The per-sample work of :func:`mcfit.viscous_motion.viscous_motion_jacobian` compiled
(numba): the half-cycle of each time, the damped cosine about its centre and its
derivatives, in one pass over the samples.

Only the waveform fit and the few-swings fit import this module (inside
:mod:`mcfit.viscous_motion`'s functions): numba's import costs more than a one-record run
of the turning-point fit. The compiled code is cached as :mod:`mcfit.compiled` says.
"""

from __future__ import annotations

import math

import numpy as np

from mcfit.compiled import compiled

__all__ = ["damped_swings"]


@compiled
def damped_swings(tau, scalars, gradients, points, point_gradients, x, jacobian):
    """x at each time of ``tau``, and its derivatives where ``jacobian`` has columns.

    Parameters
    ----------
    tau : ndarray, shape (n,)
        Times (s) from the start.
    scalars : ndarray, shape (9,)
        The end of the first half-cycle (s), the length of a later one (s), beta (1/s),
        w_d and omega (rad/s), m = mu/omega**2, and the first half-cycle's centre,
        start and slope (U): x = centre + exp(-beta*t)*(start*cos(w_d*t) +
        slope*sin(w_d*t)) until its end.
    gradients : ndarray, shape (5, 8)
        The gradients of centre, start, slope, beta, w_d, the first end, the length and
        m in the five parameters, as columns.
    points, point_gradients : ndarray, shape (count,) and (5, count)
        The signed turning points that start the later half-cycles, and their gradients.
    x : ndarray, shape (n,)
        Filled with the displacement (U).
    jacobian : ndarray, shape (5, n) or (5, 0)
        Filled with the derivatives of x, if it has n columns.
    """
    first_end, half, beta, damped, omega, offset, centre, start, slope = scalars
    derivatives = jacobian.shape[1] > 0
    rate = omega * omega / damped
    ratio, curve = beta / damped, beta / damped**2
    last = points.size - 1
    partials = np.empty(5)
    for i in range(tau.size):
        t = tau[i]
        if not t > first_end:  # the first half-cycle
            decay = math.exp(-beta * t)
            cos, sin = math.cos(damped * t), math.sin(damped * t)
            moved = decay * (start * cos + slope * sin)
            x[i] = centre + moved
            if derivatives:
                # x's partial derivatives in centre, start, slope, beta and w_d.
                partials[0], partials[1], partials[2] = 1.0, decay * cos, decay * sin
                partials[3] = -t * moved
                partials[4] = t * decay * (slope * cos - start * sin)
                for r in range(5):
                    total = 0.0
                    for j in range(5):
                        total += gradients[r, j] * partials[j]
                    jacobian[r, i] = total
            continue
        quotient = (t - first_end) / half
        if last < 0 or not quotient < last:  # the last turning point's half-cycle on
            k = last
            if k < 0:  # no turning point to start from: t is not finite
                x[i] = math.nan
                if derivatives:
                    for r in range(5):
                        jacobian[r, i] = math.nan
                continue
        else:
            k = math.floor(quotient)
            if quotient - k < 1e-9:  # maybe rounded up to a whole number: numpy's floor
                k = int((t - first_end) // half)  # division, exact (slower)
        since = t - first_end - k * half
        at = points[k]
        sign = 1.0 if at > 0 else (-1.0 if at < 0 else 0.0)
        centre_k = sign * offset
        size = at - centre_k
        if not abs(at) > offset:  # stuck: x stays at the turning point
            x[i] = centre_k + size
            if derivatives:
                for r in range(5):
                    jacobian[r, i] = point_gradients[r, k]
            continue
        decay = math.exp(-beta * since)
        cos, sin = math.cos(damped * since), math.sin(damped * since)
        swing = decay * (cos + ratio * sin)
        x[i] = centre_k + size * swing
        if derivatives:
            # The swing's partial derivatives in its time, beta and w_d, times its size;
            # its time is t less the first end less k lengths.
            by_time = -decay * sin * rate
            by_end, by_half = size * -by_time, size * (-k * by_time)
            by_beta = size * (decay * sin / damped - since * swing)
            by_damped = size * (decay * (since * (ratio * cos - sin) - curve * sin))
            held = sign * (1 - swing)
            for r in range(5):
                jacobian[r, i] = (point_gradients[r, k] * swing + gradients[r, 7] * held
                                  + gradients[r, 5] * by_end + gradients[r, 6] * by_half
                                  + gradients[r, 3] * by_beta + gradients[r, 4] * by_damped)
    return x, jacobian
