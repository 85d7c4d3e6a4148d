"""The velocity forms of the damping with any restoring force, integrated with their
sensitivities: x'' + 2*beta*x' + kappa*x'*|x'| + mu*sgn(x') + R(x) = 0, R(x) = w**2*x
("linear") or w**2*sin(x) (a pendulum, x in radians). THEORY.md sections 8 and 9.

The motion and its derivatives with respect to the parameters (y0, theta0, omega, beta,
kappa, mu) come from one integration (LSODA, :func:`scipy.integrate.odeint`) of the state
and the variational equations S' = (df/dy) S + df/dp. Sliding friction is smooth inside a
half-cycle (the velocity keeps its sign), so with mu > 0 each half-cycle is integrated on
its own, its end (the reversal, x' = 0) found by Newton's method, and the sensitivities
of the velocity jump there by a+/a-, the accelerations after and before (the saltation
of the switching surface x' = 0). The mass sticks at a reversal where |R(x)| <= mu
(static friction equal to the sliding friction). numpy and scipy only, no I/O.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy.integrate import ODEintWarning, odeint

__all__ = ["PARAMETERS", "RESTORING", "motion_with_sensitivities"]

PARAMETERS = ("y0", "theta0", "omega", "beta", "kappa", "mu")
RESTORING = ("linear", "pendulum")
_COUNT = len(PARAMETERS)
_STATE = 2 + 2 * _COUNT  # x, v, then dx/dp and dv/dp
# A half-cycle is integrated this far past its expected end before the reversal is sought
# (a longer one is continued).
_REACH = 1.3
_NEWTON_STEPS = 30


def motion_with_sensitivities(tau, y0, theta0, omega, beta=0.0, kappa=0.0, mu=0.0, *,
                              restoring="linear", rtol=1e-9, wanted=PARAMETERS):
    """x(tau) and dx/d(y0, theta0, omega, beta, kappa, mu) of
    x'' + 2*beta*x' + kappa*x'*|x'| + mu*sgn(x') + R(x) = 0.

    Parameters
    ----------
    tau : ndarray, shape (n,)
        Times (s) from the start, sorted, >= 0.
    y0, theta0 : float
        Amplitude (U) and phase (rad) at the start: x = y0*cos(theta0),
        x' = -omega*y0*sin(theta0) (for theta0 = 0, a turning point at y0).
    omega : float
        Small-amplitude angular frequency (rad/s), > 0.
    beta, kappa, mu : float
        Viscous rate (1/s), quadratic drag (1/U) and sliding friction (U/s**2) per unit
        mass, >= 0.
    restoring : {"linear", "pendulum"}
        R(x) = omega**2*x, or omega**2*sin(x) with x in radians.
    rtol : float
        Relative tolerance of the integration (the error at the end of a long record is a
        few times this, relative to y0).
    wanted : sequence of str
        The parameters whose sensitivities are needed. Without friction (mu = 0) and
        without "mu" here, the motion is integrated in one piece (twice as fast: the
        sensitivity to mu is forced by sgn(x'), which jumps at every reversal) and that
        column is NaN.

    Returns
    -------
    x : ndarray, shape (n,)
        The displacement (U); constant from where the mass sticks.
    sensitivities : ndarray, shape (n, 6)
        dx/dp for p in :data:`PARAMETERS`, in the order there.
    """
    if restoring not in RESTORING:
        raise ValueError(f"restoring must be one of {RESTORING}, not {restoring!r}")
    tau = np.asarray(tau, dtype=float)
    pendulum = restoring == "pendulum"
    parameters = (float(omega), float(beta), float(kappa), float(mu), pendulum)
    state = _initial_state(float(y0), float(theta0), float(omega))
    scale = _error_scale(float(y0), float(omega))
    tolerances = {"rtol": rtol, "atol": rtol * scale, "mxstep": 100000}
    if tau.size == 0:
        return np.empty(0), np.empty((0, _COUNT))
    if mu == 0.0 and "mu" not in wanted:
        rows = _smooth(tau, state, parameters, tolerances)
        rows[:, 2 + PARAMETERS.index("mu")] = np.nan
    else:
        rows = _by_half_cycles(tau, state, parameters, tolerances)
    return rows[:, 0], rows[:, 2:2 + _COUNT]


def _initial_state(y0, theta0, omega):
    """x, v and their derivatives by the parameters at the start."""
    cos, sin = math.cos(theta0), math.sin(theta0)
    state = np.zeros(_STATE)
    state[0], state[1] = y0 * cos, -omega * y0 * sin
    state[2], state[3] = cos, -y0 * sin  # dx/dy0, dx/dtheta0
    state[2 + _COUNT:5 + _COUNT] = -omega * sin, -omega * y0 * cos, -y0 * sin
    return state


def _error_scale(y0, omega):
    """The size of each state component that the absolute tolerance is relative to: y0 for
    x and y0*omega for v; y0 over each parameter's natural size for the sensitivities."""
    size = max(abs(y0), 1e-300)
    natural = np.array([size, 1.0, omega, omega, omega / size, omega * omega * size])
    sensitivity = size / natural
    return np.concatenate([[size, size * omega], sensitivity, sensitivity * omega])


def _rates(parameters, sense):
    """The right-hand side of the state and its variational equations; ``sense`` is the
    sign of the velocity in the half-cycle."""
    omega, beta, kappa, mu, pendulum = parameters
    w2, two_beta, two_omega = omega * omega, 2.0 * beta, 2.0 * omega
    friction = mu * sense
    sin, cos = math.sin, math.cos

    def rates(y, _):
        # Unrolled: the integrator calls this tens of thousands of times a solve.
        x, v, a0, a1, a2, a3, a4, a5, b0, b1, b2, b3, b4, b5 = y.tolist()
        g, slope = (sin(x), cos(x)) if pendulum else (x, 1.0)
        speed = abs(v)
        drag = v * speed
        k, d = -w2 * slope, -two_beta - 2.0 * kappa * speed
        return (v, -two_beta * v - kappa * drag - friction - w2 * g, b0, b1, b2, b3, b4, b5,
                k * a0 + d * b0, k * a1 + d * b1, k * a2 + d * b2 - two_omega * g,
                k * a3 + d * b3 - 2.0 * v, k * a4 + d * b4 - drag, k * a5 + d * b5 - sense)
    return rates


def _restoring(x, parameters):
    omega, *_, pendulum = parameters
    return omega * omega * (math.sin(x) if pendulum else x)


def _smooth(tau, state, parameters, tolerances):
    """Without sliding friction the right-hand side is smooth: one integration (the
    sensitivity to mu, forced by the sense of motion, is not found)."""
    start = tau[0] > 0
    times = np.concatenate([[0.0], tau]) if start else tau
    rows = _integrated(_rates(parameters, 1.0), state, times, tolerances)
    return rows[1:] if start else rows


def _by_half_cycles(tau, state, parameters, tolerances):
    """With sliding friction: half-cycle by half-cycle, each with its sense of motion, the
    sensitivities carried across each reversal; at rest for good once the mass sticks."""
    omega, *_, mu, _ = parameters
    rows = np.empty((tau.size, _STATE))
    now, filled, last, half = 0.0, 0, None, math.pi / omega
    sense = (math.copysign(1.0, state[1]) if state[1]
             else -math.copysign(1.0, _restoring(state[0], parameters)))
    while filled < tau.size:
        if state[1] == 0.0 and abs(_restoring(state[0], parameters)) <= mu:
            rows[filled:] = _stuck(state)
            break
        rates = _rates(parameters, sense)
        end = max(now + _REACH * half, tau[filled])
        inside = filled + int(np.searchsorted(tau[filled:], end, side="right"))
        # The samples not yet filled (tau[filled] >= now) follow ``now`` in ``times``.
        offset = int(tau[filled] > now)
        times = np.concatenate([[now][:offset], tau[filled:inside], [end][:int(end > tau[
            inside - 1])]])
        path = _integrated(rates, state, times, tolerances)
        crossed = np.flatnonzero(sense * path[1:, 1] < 0)
        if crossed.size == 0:  # no reversal yet: go on from the end
            rows[filled:inside] = path[offset:offset + inside - filled]
            filled, now, state = inside, float(times[-1]), path[-1]
            continue
        k = int(crossed[0]) + 1
        reversal, state = _reversal(rates, times[k - 1], path[k - 1], times[k], path[k],
                                    sense, tolerances)
        before = filled + int(np.searchsorted(tau[filled:], reversal, side="left"))
        rows[filled:before] = path[offset:offset + before - filled]
        if last is not None:
            half = reversal - last
        filled, now, last = before, reversal, reversal
        state = _jump(state, sense, mu, parameters)
        sense = -sense
    return rows


def _integrated(rates, state, times, tolerances):
    """odeint's rows at ``times``; NaN from where it failed (a solver's trial parameters
    may make the motion run away: the caller's solver steps back from NaN)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ODEintWarning)
        rows, info = odeint(rates, state, times, full_output=True, **tolerances)
    if info["message"] != "Integration successful.":
        failed = np.flatnonzero(info["tcur"] < np.asarray(times)[1:] * (1 - 1e-12)) + 1
        rows[failed[0] if failed.size else 0:] = np.nan
    return rows


def _reversal(rates, t_a, y_a, t_b, y_b, sense, tolerances):
    """The time and state where the velocity of ``sense`` vanishes in (t_a, t_b], the
    states there ``y_a`` and ``y_b``: Newton's method on v(t) integrated from t_a (v' is
    the acceleration), from t_b, kept inside the bracket by bisection."""
    low, high, when = t_a, t_b, t_b

    def state_at(time):
        return (_integrated(rates, y_a, [t_a, time], tolerances)[-1] if time > t_a
                else y_a.copy())

    state = y_b
    for step in range(_NEWTON_STEPS):
        state = state_at(when) if step else y_b
        v = sense * state[1]
        if v > 0:
            low = when
        elif v < 0:
            high = when
        else:
            break
        acceleration = sense * rates(state, when)[1]
        guess = when - v / acceleration if acceleration < 0 else math.nan
        if abs(guess - when) <= 1e-14 * (t_b - t_a) or high - low <= 1e-14 * (t_b - t_a):
            break
        when = guess if low <= guess <= high else 0.5 * (low + high)
    state = state_at(when)
    state[1] = 0.0
    return when, state


def _jump(state, sense, mu, parameters):
    """The state after a reversal in the half-cycle of ``sense``: the velocity's
    sensitivities scaled by a+/a- (the friction's sign flips at x' = 0)."""
    restoring = _restoring(state[0], parameters)
    before, after = -mu * sense - restoring, mu * sense - restoring
    out = state.copy()
    if before != 0.0:
        out[2 + _COUNT:] *= after / before
    return out


def _stuck(state):
    """The state at rest from where the mass sticks: x and dx/dp held, v and dv/dp 0."""
    out = state.copy()
    out[1] = 0.0
    out[2 + _COUNT:] = 0.0
    return out
