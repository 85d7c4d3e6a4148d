"""The velocity forms of the damping with any restoring force, integrated with their
sensitivities: x'' + 2*beta*x' + kappa*x'*|x'| + mu*sgn(x') + R(x) = 0, R(x) = w**2*x
("linear") or w**2*sin(x) (a pendulum, x in radians). docs/theory.md sections 5 and 6.

The motion and its derivatives with respect to the parameters (y0, theta0, omega, beta,
kappa, mu) come from one integration of the state and the variational equations
S' = (df/dy) S + df/dp, by a compiled Dormand-Prince 8(5,3) method with dense output
(:mod:`mcfit.equation_of_motion_kernels`, imported only when a motion is integrated).
Sliding friction and quadratic drag are smooth inside a half-cycle (the velocity keeps
its sign), so each half-cycle is integrated on its own with sgn(x') its sense of motion,
its end (the reversal, x' = 0) found as the root of the step's interpolant, and the
sensitivities of the velocity jump there by a+/a-, the accelerations after and before
(the saltation of the switching surface x' = 0). The mass sticks at a reversal where
|R(x)| <= mu (static friction equal to the sliding friction). No I/O.
"""

from __future__ import annotations

import math

import numpy as np

from mcfit.viscous_motion import AT_REST

__all__ = ["PARAMETERS", "RESTORING", "motion_with_sensitivities"]

PARAMETERS = ("y0", "theta0", "omega", "beta", "kappa", "mu")
RESTORING = ("linear", "pendulum")
_COUNT = len(PARAMETERS)
_STATE = 2 + 2 * _COUNT  # x, dx/dp, then v, dv/dp
# Steps (accepted or not) before an integration is given up as a runaway: far more than
# an oscillation needs at rtol 1e-13.
_STEPS, _STEPS_PER_CYCLE = 100_000, 1_000


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
        without "mu" here, the sensitivity to mu is NaN.

    Returns
    -------
    x : ndarray, shape (n,)
        The displacement (U); constant from where the mass sticks.
    sensitivities : ndarray, shape (n, 6)
        dx/dp for p in :data:`PARAMETERS`, in the order there.
    """
    if restoring not in RESTORING:
        raise ValueError(f"restoring must be one of {RESTORING}, not {restoring!r}")
    tau = np.ascontiguousarray(tau, dtype=float)
    if tau.size == 0:
        return np.empty(0), np.empty((0, _COUNT))
    from mcfit.equation_of_motion_kernels import integrate_motion

    parameters = (float(omega), float(beta), float(kappa), float(mu), restoring == "pendulum")
    cycles = float(omega) * float(tau[-1]) / (2.0 * math.pi)
    cycles = min(cycles, 1e9) if cycles >= 0.0 else 0.0  # NaN too
    rows = integrate_motion(tau, _initial_state(float(y0), float(theta0), float(omega)),
                            parameters, float(rtol),
                            rtol * _error_scale(float(y0), float(omega)),
                            int(_STEPS + _STEPS_PER_CYCLE * cycles))
    if mu == 0.0 and "mu" not in wanted:
        rows[:, 1 + PARAMETERS.index("mu")] = np.nan
    return rows[:, 0], rows[:, 1:]


def _initial_state(y0, theta0, omega):
    """x, v and their derivatives by the parameters at the start."""
    cos, sin = math.cos(theta0), math.sin(theta0)
    if abs(sin) <= AT_REST * abs(cos):
        sin = 0.0  # theta0 a multiple of pi (sin is 1e-16 there): at rest, as it is
    state = np.zeros(_STATE)
    state[:3] = y0 * cos, cos, -y0 * sin  # x, dx/dy0, dx/dtheta0
    # v, dv/dy0, dv/dtheta0, dv/domega
    state[1 + _COUNT:5 + _COUNT] = (-omega * y0 * sin, -omega * sin, -omega * y0 * cos,
                                    -y0 * sin)
    return state


def _error_scale(y0, omega):
    """The size of each state component that the absolute tolerance is relative to: y0 for
    x and y0*omega for v; y0 over each parameter's natural size for the sensitivities."""
    size = max(abs(y0), 1e-300)
    natural = np.array([size, 1.0, omega, omega, omega / size, omega * omega * size])
    sensitivity = size / natural
    return np.concatenate([[size], sensitivity, [size * omega], sensitivity * omega])
