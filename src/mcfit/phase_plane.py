"""Eq. 20.55 integrated in its phase plane: fast, batched, and smooth in the parameters.

With x = A*cos(theta) and xdot = -omega*A*sin(theta), A the energy amplitude, the equation
of motion ``xddot + (pi*omega/2)*g(A)*sgn(xdot) + omega**2*x = 0``, g(A) = c + b*A + a*A**2,
becomes in each half-cycle (theta = k*pi + phi, 0 <= phi <= pi, velocity of one sign)::

    dA/dphi = -(pi/2) * g(A) * sin(phi) / D,    dt/dphi = 1 / D,
    D = omega - (pi/2) * (g(A)/A) * cos(phi),

the same equation in every half-cycle: the sign of the friction never changes inside one,
and the half-cycle ends exactly at phi = pi, so no event has to be located. Inside a
half-cycle the solution is analytic in phi: it is found by Chebyshev collocation (Newton's
method on the integrated equations at ``NODES`` Chebyshev-Lobatto points), evaluated on
``FINE`` points of the half-cycle, and x(t) between those is a cubic Hermite interpolant of
phi(t) and A(t), whose derivatives the equations give. At a
turning point from which the swing may not reach the other side of 0 (:func:`_stuck`) the
last swings are integrated in x and xdot (:func:`_with_final_swing`).

Averaged over a half-cycle, dA/dt = -g(A): the amplitude law of THEORY.md section 1.
Every function takes arrays of parameter sets (shape (m,)) and integrates them together,
so that a finite-difference Jacobian costs one pass. numpy only.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["NODES", "FINE", "phase_plane_motion"]

# Collocation points and interpolation points per half-cycle: x is within 1e-9 of the
# amplitude for Q >= 2 (tests/test_phase_plane.py, against the accurate integrator).
NODES = 16
FINE = 64
_NEWTON_ITERATIONS = 8
_HALF_PI = 0.5 * math.pi


def _chebyshev_matrices(nodes, fine):
    """Chebyshev-Lobatto points s on [0, 1], the matrix that integrates the interpolant of
    values at them from 0 to each point, and the one that evaluates it at ``fine``
    uniform points."""
    from numpy.polynomial import chebyshev

    x = -np.cos(np.pi * np.arange(nodes) / (nodes - 1))
    coefficients = chebyshev.chebfit(x, np.eye(nodes), nodes - 1)  # one column per node
    integral = chebyshev.chebint(coefficients, lbnd=-1.0)
    x_fine = np.linspace(-1.0, 1.0, fine)
    return ((x + 1) / 2, 0.5 * chebyshev.chebval(x, integral).T,
            chebyshev.chebval(x_fine, coefficients).T)


_S, _INTEGRATE, _EVALUATE = _chebyshev_matrices(NODES, FINE)
_FINE_S = np.linspace(0.0, 1.0, FINE)


def _rates(amplitude, phi, omega, a, b, c):
    """dA/dphi and dt/dphi, with d(dA/dphi)/dA, for arrays of states and parameter sets."""
    safe = np.maximum(amplitude, 1e-100)
    friction = c + safe * (b + a * safe)
    cos, sin = np.cos(phi), np.sin(phi)
    denominator = np.maximum(omega - _HALF_PI * friction / safe * cos, 1e-9 * omega)
    slope = -_HALF_PI * friction * sin / denominator
    d_denominator = -_HALF_PI * (a - c / (safe * safe)) * cos
    d_slope = -_HALF_PI * sin * ((b + 2 * a * safe) - friction * d_denominator / denominator)
    return slope, 1.0 / denominator, d_slope / denominator


def phase_plane_motion(t, y0, theta0, omega, a, b, c):
    """x(t) of Eq. 20.55 for ``m`` parameter sets at once.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Times (s) from the start, sorted, >= 0.
    y0, theta0, omega, a, b, c : ndarray, shape (m,) (or scalars)
        Energy amplitude (U) and phase (rad) at t = 0, with x = y0*cos(theta0); angular
        frequency (rad/s); coefficients (1/(U*s), 1/s, U/s), >= 0.

    Returns
    -------
    ndarray, shape (m, n)
        The displacement (U).
    """
    t = np.asarray(t, dtype=float)
    y0, theta0, omega, a, b, c = (np.array(v, dtype=float)[:, None] for v in
                                  np.broadcast_arrays(*(np.atleast_1d(np.asarray(
                                      v, dtype=float)) for v in (y0, theta0, omega, a, b, c))))
    # A trial parameter set of a solver may bring a swing to a standstill inside a
    # half-cycle (D -> 0): its values are then huge but finite, and the solver steps back.
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        *nodes, final = _nodes(float(t[-1]), y0, theta0, omega, a, b, c)
        x = _with_final_swing(t, _sampled(t, *nodes), final, (a, b, c), omega[:, 0])
    return np.nan_to_num(x, nan=0.0, posinf=1e300, neginf=-1e300)


def _half_cycle(amplitude, now, phi, omega, a, b, c):
    """The solution from ``phi`` (shape (m, 1)) to pi: amplitude and time at the
    collocation points, by Newton's method on A = A0 + L*S*f(A)."""
    length = math.pi - phi
    phases = phi + length * _S
    guess = np.repeat(amplitude, _S.size, axis=1)
    identity = np.eye(_S.size)
    for _ in range(_NEWTON_ITERATIONS):
        slope, _, d_slope = _rates(guess, phases, omega, a, b, c)
        residual = guess - amplitude - length * (slope @ _INTEGRATE.T)
        jacobian = identity - length[:, :, None] * _INTEGRATE[None] * d_slope[:, None, :]
        step = np.linalg.solve(jacobian, residual[..., None])[..., 0]
        guess = guess - step
        if np.max(np.abs(step)) <= 1e-14 * np.max(np.abs(guess)):
            break
    _, time_rate, _ = _rates(guess, phases, omega, a, b, c)
    return guess, now + length * (time_rate @ _INTEGRATE.T), phases, length


def _stuck(amplitude, omega, a, b, c):
    """At a turning point: the swing may not reach the other side of 0. Under a friction
    force held at its start value (pi*omega/2)*g(A) the mass swings about
    x_c = (pi/(2*omega))*g(A) and ends at 2*x_c - A, beyond 0 only if A > 2*x_c. From
    there on the motion is :func:`_with_final_swing`."""
    return omega * amplitude <= math.pi * (c + amplitude * (b + a * amplitude))


def _nodes(t_end, amplitude, theta0, omega, a, b, c):
    """Times, total phases, amplitudes and their time derivatives on FINE points of each
    half-cycle, until every set has passed ``t_end`` or is held; arrays of shape
    (m, nodes). A half-cycle boundary is a node twice, once with the rates of either side
    (the friction changes sign there)."""
    base = np.floor(theta0 / math.pi) * math.pi
    phi = theta0 - base
    now = np.zeros_like(amplitude)
    held = np.zeros(amplitude.shape, dtype=bool)
    final = np.full((amplitude.shape[0], 3), np.inf)  # start, amplitude, sign
    pieces = []
    # Friction at Q >= 1 speeds the phase by less than a factor 2: a bound on the loop.
    for _ in range(int(2 * np.max(omega) * t_end / math.pi) + 4):
        stuck = ~held & (phi == 0.0) & _stuck(amplitude, omega, a, b, c)
        if np.any(stuck):
            rows = stuck[:, 0]
            final[rows] = np.column_stack([now, amplitude, np.cos(base)])[rows]
        held = held | stuck
        free = [np.where(held, 0.0, k) for k in (a, b, c)]  # a held set needs no solution
        amplitudes, times, phases, length = _half_cycle(amplitude, now, phi, omega, *free)
        fine_a, fine_t = amplitudes @ _EVALUATE.T, times @ _EVALUATE.T
        fine_phi = phi + length * _FINE_S
        slope, time_rate, _ = _rates(fine_a, fine_phi, omega, *free)
        moving = ~held
        pieces.append((np.where(moving, fine_t, now), np.where(moving, base + fine_phi, base + phi),
                       np.where(moving, fine_a, amplitude), np.where(moving, 1.0 / time_rate, 0.0),
                       np.where(moving, slope / time_rate, 0.0)))
        amplitude = np.where(held, amplitude, fine_a[:, -1:])
        now = np.where(held, now, fine_t[:, -1:])
        base = np.where(held, base, base + math.pi)
        phi = np.where(held, phi, 0.0)
        if np.all(held | (now >= t_end)):
            break
    return tuple(np.concatenate(v, axis=1) for v in zip(*pieces)) + (final,)


def _with_final_swing(t, x, final, coefficients, omega):
    """The end of a decay that stops, from the turning point where :func:`_stuck` holds:
    the last swings are short of crossing 0 and the friction changes much within them, so
    they are integrated in x and xdot by :func:`mcfit.motion.integrate_accurate` (which
    holds the mass where static friction wins)."""
    from mcfit.motion import damping_terms, integrate_accurate  # noqa: PLC0415

    for i, (start, amplitude, sign) in enumerate(final):
        after = t >= start
        if np.isfinite(start) and np.any(after):
            terms = damping_terms(*(k[i, 0] for k in coefficients))
            x[i, after] = integrate_accurate(sign * amplitude, 0.0, omega[i], terms,
                                             t[after] - start).x
    return x


def _sampled(t, times, phases, amplitudes, phase_rates, amplitude_rates):
    """x at times ``t`` from the nodes, by cubic Hermite interpolation of the total phase
    and the amplitude in time; past the last node the state stays where it was held."""
    x = np.empty((times.shape[0], t.size))
    for i in range(times.shape[0]):
        node_t = times[i]
        j = np.clip(np.searchsorted(node_t, t, side="right") - 1, 0, node_t.size - 2)
        span = node_t[j + 1] - node_t[j]
        width = np.where(span > 0, span, 1.0)
        s = np.where(span > 0, np.clip((t - node_t[j]) / width, 0.0, 1.0), 0.0)
        phase = _hermite(s, width, phases[i, j], phases[i, j + 1], phase_rates[i, j],
                         phase_rates[i, j + 1])
        amplitude = _hermite(s, width, amplitudes[i, j], amplitudes[i, j + 1],
                             amplitude_rates[i, j], amplitude_rates[i, j + 1])
        after = t >= node_t[-1]
        phase = np.where(after, phases[i, -1], phase)
        amplitude = np.where(after, amplitudes[i, -1], amplitude)
        x[i] = amplitude * np.cos(phase)
    return x


def _hermite(s, width, p0, p1, m0, m1):
    s2, s3 = s * s, s * s * s
    return ((2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * width * m0
            + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * width * m1)
