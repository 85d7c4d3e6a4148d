"""Records of damped oscillators from a tight integration that shares no code with mcfit:
scipy's DOP853 between the reversals of the velocity (located as events), so the
discontinuous friction never sits inside a step; the mass sticks at a reversal where the
spring cannot overcome static friction (equal to the sliding friction mu) and the
amplitude-form forces there.

The records of the edges section of ``mcfit bench`` and of the tests of the edge scenes.
This module imports nothing from mcfit, so that it stays independent of the code it
checks."""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp


def integrate(force, omega, x0, t_end, rate, *, mu=0.0, v0=0.0, restoring=None):
    """Samples (t, x) at ``rate`` Hz of x'' + force(x, v) + mu*sgn(v) + restoring(x) = 0.

    ``force(x, v, sense)`` is the damping other than Coulomb friction, ``sense`` the sign
    of the velocity in the half-cycle;
    ``restoring`` defaults to omega**2 * x (a pendulum passes omega**2 * sin(x))."""
    restoring = restoring or (lambda x: omega * omega * x)
    t = np.arange(0.0, t_end, 1.0 / rate)
    x = np.empty(t.size)
    state, now = np.array([x0, v0], float), 0.0
    sense = math.copysign(1.0, v0) if v0 else -math.copysign(1.0, restoring(x0))
    while now < t_end:
        # At rest the spring must beat the friction and any force at zero velocity
        # (Eq. 20.55's amplitude forms: a swing with D <= 0 cannot start).
        held = mu + abs(force(state[0], 0.0, sense))
        if abs(restoring(state[0])) <= held and state[1] == 0.0:
            x[t >= now] = state[0]  # stuck
            break

        def rhs(_, y, sense=sense):
            return [y[1], -force(y[0], y[1], sense) - mu * sense - restoring(y[0])]

        def reversal(_, y):
            return y[1]

        reversal.terminal, reversal.direction = True, -sense
        # A step off rest: the velocity's zero at the start is not a reversal (no longer
        # than what is left of the record: a reversal may come just before its end).
        solution = solve_ivp(rhs, (now, t_end), state, method="DOP853", rtol=1e-12,
                             atol=1e-14 * max(1.0, abs(x0)), events=reversal,
                             dense_output=True, first_step=min(1e-9, t_end - now))
        end = solution.t[-1]
        inside = (t >= now) & (t <= end)
        if np.any(inside):
            x[inside] = solution.sol(t[inside])[0]
        if solution.status != 1:
            break
        now, state = end, np.array([solution.y[0, -1], 0.0])
        sense = -sense
    return t, x


def viscous(beta, omega, y0, t_end, rate, *, mu=0.0):
    """Linear viscous damping 2*beta*x' (and Coulomb mu), released from rest at y0."""
    return integrate(lambda x, v, _: 2 * beta * v, omega, y0, t_end, rate, mu=mu)


def hysteretic(a, b, c, omega, y0, t_end, rate):
    """Eq. 20.55: (pi*w/2)*(c + b*A + a*A**2)*sgn(x'), A the energy amplitude, released
    from rest at y0 (the Coulomb part as mu = pi*w*c/2, which also sticks)."""
    def force(x, v, sense):
        amplitude = math.hypot(x, v / omega)
        return 0.5 * math.pi * omega * (b * amplitude + a * amplitude**2) * sense
    return integrate(force, omega, y0, t_end, rate, mu=0.5 * math.pi * omega * c)


def quadratic_drag(kappa, omega, y0, t_end, rate, *, beta=0.0, mu=0.0):
    """Quadratic drag kappa*x'*|x'| (with viscous 2*beta*x' and Coulomb mu), released from
    rest at y0."""
    return integrate(lambda x, v, _: 2 * beta * v + kappa * v * abs(v), omega, y0, t_end,
                     rate, mu=mu)


def pendulum(beta, omega, theta0, t_end, rate, *, kappa=0.0):
    """theta'' + 2*beta*theta' + kappa*theta'*|theta'| + omega**2*sin(theta) = 0, released
    from rest at theta0."""
    return integrate(lambda x, v, _: 2 * beta * v + kappa * v * abs(v), omega, theta0, t_end,
                     rate, restoring=lambda x: omega * omega * math.sin(x))
