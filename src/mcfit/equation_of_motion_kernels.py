"""The compiled integrator of :mod:`mcfit.equation_of_motion`: the explicit Runge-Kutta
method of Dormand and Prince of order 8 with its error estimate of orders 5 and 3 and its
dense output of order 7 (Hairer, Norsett and Wanner, Solving ODEs I, section II.10), with
the coefficients and the step control of :class:`scipy.integrate.DOP853`, applied to the
state and its variational equations half-cycle by half-cycle.

numba loads with this module, so it is imported only inside the functions that integrate.
The compiled code is cached on disk where numba finds a writable folder for it (the
package's ``__pycache__``, else the user's cache folder) and compiled afresh in each process
where it finds none. numpy, scipy and numba only, no I/O.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate._ivp import dop853_coefficients as _dop853

from mcfit.compiled import compiled

__all__ = ["integrate_motion"]

_STAGES = _dop853.N_STAGES  # 12
# Row 12 of A is B: the 13th stage is the derivative at the step's end.
_A = np.ascontiguousarray(_dop853.A)
_E3 = np.ascontiguousarray(_dop853.E3)
_E5 = np.ascontiguousarray(_dop853.E5)
_D = np.ascontiguousarray(_dop853.D)
# scipy's step control (scipy/integrate/_ivp/rk.py).
_SAFETY, _MIN_FACTOR, _MAX_FACTOR = 0.9, 0.2, 10.0
_EXPONENT = -1.0 / 8.0  # the error estimate's order is 7
# The reversal is refined to this fraction of its step.
_ROOT_TOLERANCE = 1e-14
# The state: x, dx/dp for the six parameters, v, dv/dp; the output is its first 7 entries.
_OUT, _V = 7, 7
# Constant indices are passed as np.int64(...): numba would compile a function once more
# for each literal integer it is called with.


@compiled
def _restoring(x, omega, pendulum):
    """R(x) = omega**2*x, or omega**2*sin(x)."""
    return omega * omega * (math.sin(x) if pendulum else x)


@compiled
def _rates(y, K, row, parameters, sense):
    """The right-hand side at the state ``y`` of the motion and its variational equations
    into K[row]; ``sense`` is the sign of the velocity in the half-cycle, which stands for
    sgn(v) in the drag too, so that the step across a reversal sees no kink."""
    omega, beta, kappa, mu, pendulum = parameters
    x, v = y[0], y[_V]
    w2 = omega * omega
    if pendulum:
        g, slope = math.sin(x), math.cos(x)
    else:
        g, slope = x, 1.0
    speed = sense * v
    drag = v * speed
    k, d = -w2 * slope, -2.0 * beta - 2.0 * kappa * speed
    K[row, 0] = v
    K[row, _V] = -2.0 * beta * v - kappa * drag - mu * sense - w2 * g
    for j in range(1, _V):
        K[row, j] = y[_V + j]
        K[row, _V + j] = k * y[j] + d * y[_V + j]
    K[row, 10] -= 2.0 * omega * g  # the forcing by omega, beta, kappa and mu
    K[row, 11] -= 2.0 * v
    K[row, 12] -= drag
    K[row, 13] -= sense


@compiled
def _first_step(y, span, rtol, atol, K, work, parameters, sense):
    """scipy's initial step (Hairer, Solving ODEs I, section II.4) for an error of order 7,
    with K[0] = f(y); K[1] is overwritten."""
    n = y.size
    d0, d1 = 0.0, 0.0
    for i in range(n):
        scale = atol[i] + abs(y[i]) * rtol
        d0 += (y[i] / scale) ** 2
        d1 += (K[0, i] / scale) ** 2
    d0, d1 = math.sqrt(d0 / n), math.sqrt(d1 / n)
    h0 = min(1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1, span)
    for i in range(n):
        work[i] = y[i] + h0 * K[0, i]
    _rates(work, K, np.int64(1), parameters, sense)
    d2 = 0.0
    for i in range(n):
        d2 += ((K[1, i] - K[0, i]) / (atol[i] + abs(y[i]) * rtol)) ** 2
    d2 = math.sqrt(d2 / n) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100.0 * h0, h1, span)


@compiled
def _stage(y, K, A, s, h, out):
    """y + h*sum_j A[s, j]*K[j] over the stages j < s into ``out``."""
    for i in range(out.size):
        out[i] = 0.0
    for j in range(s):
        a = A[s, j]
        if a != 0.0:  # most of the tableau is zeros
            for i in range(out.size):
                out[i] += a * K[j, i]
    for i in range(out.size):
        out[i] = y[i] + h * out[i]


@compiled
def _step(y, h, K, A, y_new, work, parameters, sense):
    """One step of order 8 from y with K[0] = f(y): y_new, and K[12] = f(y_new)."""
    for s in range(1, _STAGES + 1):
        target = y_new if s == _STAGES else work
        _stage(y, K, A, s, h, target)
        _rates(target, K, s, parameters, sense)


@compiled
def _error_norm(y, y_new, K, h, E3, E5, rtol, atol):
    """scipy's DOP853 error norm: the fifth-order estimate, damped by the third's."""
    err5, err3 = 0.0, 0.0
    for i in range(y.size):
        scale = atol[i] + max(abs(y[i]), abs(y_new[i])) * rtol
        e5, e3 = 0.0, 0.0
        for j in range(E5.size):
            e5 += E5[j] * K[j, i]
            e3 += E3[j] * K[j, i]
        err5 += (e5 / scale) ** 2
        err3 += (e3 / scale) ** 2
    if err5 == 0.0 and err3 == 0.0:
        return 0.0
    return abs(h) * err5 / math.sqrt((err5 + 0.01 * err3) * y.size)


@compiled
def _accepted_step(y, t, h, K, A, E3, E5, y_new, work, rtol, atol, parameters, sense):
    """A step from (t, y) into ``y_new`` under scipy's control, tried first at ``h``: the
    step taken, the step proposed next and the attempts; the step is 0 where it failed
    (too small a step, an error that is not finite)."""
    attempts, rejected = 0, False
    while True:
        attempts += 1
        if h < 10.0 * (np.nextafter(t, np.inf) - t):
            return 0.0, 0.0, attempts
        _step(y, h, K, A, y_new, work, parameters, sense)
        error = _error_norm(y, y_new, K, h, E3, E5, rtol, atol)
        if not math.isfinite(error):
            return 0.0, 0.0, attempts
        if error < 1.0:
            break
        h *= max(_MIN_FACTOR, _SAFETY * error ** _EXPONENT)
        rejected = True
    growth = _MAX_FACTOR if error == 0.0 else min(_MAX_FACTOR, _SAFETY * error ** _EXPONENT)
    return h, h * (min(1.0, growth) if rejected else growth), attempts


@compiled
def _dense(y, y_new, h, K, A, D, F, work, parameters, sense):
    """The coefficients F (7, n) of the step's interpolant (three more stages)."""
    for s in range(_STAGES + 1, K.shape[0]):
        _stage(y, K, A, s, h, work)
        _rates(work, K, s, parameters, sense)
    for i in range(y.size):
        delta = y_new[i] - y[i]
        F[0, i] = delta
        F[1, i] = h * K[0, i] - delta
        F[2, i] = 2.0 * delta - h * (K[_STAGES, i] + K[0, i])
        for r in range(D.shape[0]):
            total = 0.0
            for j in range(K.shape[0]):
                total += D[r, j] * K[j, i]
            F[3 + r, i] = h * total


@compiled
def _polynomial(F, y, fraction, i):
    """Component ``i`` of the step's interpolant at ``fraction`` of the step."""
    value = 0.0
    for r in range(F.shape[0] - 1, -1, -1):
        value += F[r, i]
        value *= fraction if (F.shape[0] - 1 - r) % 2 == 0 else 1.0 - fraction
    return value + y[i]


@compiled
def _fill(out, tau, filled, stop, F, y, t, h):
    """The output rows of the samples from ``filled`` up to ``stop`` by the step's
    interpolant; the index of the first row not filled."""
    while filled < tau.size and tau[filled] <= stop:
        fraction = (tau[filled] - t) / h
        for c in range(_OUT):
            out[filled, c] = _polynomial(F, y, fraction, c)
        filled += 1
    return filled


@compiled
def _reversal(F, y, sense):
    """The fraction of the step where the velocity of ``sense`` vanishes, positive at its
    start and negative at its end: the Illinois method on the interpolant."""
    low, high = 0.0, 1.0
    f_low, f_high = sense * y[_V], sense * (F[0, _V] + y[_V])
    side = 0
    for _ in range(200):
        if high - low <= _ROOT_TOLERANCE:
            break
        mid = (low * f_high - high * f_low) / (f_high - f_low)
        if not low < mid < high:
            mid = 0.5 * (low + high)
        value = sense * _polynomial(F, y, mid, np.int64(_V))
        if value == 0.0:
            return mid
        if value > 0.0:
            low, f_low = mid, value
            if side == 1:
                f_high *= 0.5
            side = 1
        else:
            high, f_high = mid, value
            if side == -1:
                f_low *= 0.5
            side = -1
    return 0.5 * (low + high)


@compiled
def _jump(y, sense, parameters):
    """At a reversal from the half-cycle of ``sense``: the velocity's sensitivities scaled
    by a+/a-, the accelerations after and before (the friction's sign flips at x' = 0)."""
    omega, _, _, mu, pendulum = parameters
    restoring = _restoring(y[0], omega, pendulum)
    before, after = -mu * sense - restoring, mu * sense - restoring
    if before != 0.0:
        for i in range(_V + 1, y.size):
            y[i] *= after / before


@compiled
def _hold(out, start, stop, y):
    """The rows from ``start`` to ``stop``: x and dx/dp of ``y``."""
    for row in range(start, stop):
        for c in range(_OUT):
            out[row, c] = y[c]


@compiled
def _integrate(tau, parameters, rtol, atol, max_steps, A, E3, E5, D, y, y_new, work, K, F,
               out):
    """Fill ``out`` from the state ``y`` at time 0; the number of rows filled."""
    omega, _, _, mu, pendulum = parameters
    n = tau.size
    if y[_V] != 0.0:
        sense = math.copysign(1.0, y[_V])
    else:
        sense = -math.copysign(1.0, _restoring(y[0], omega, pendulum))
    t, filled, steps = 0.0, np.int64(0), 0
    _rates(y, K, np.int64(0), parameters, sense)
    h = _first_step(y, max(tau[n - 1], 1e-300), rtol, atol, K, work, parameters, sense)
    while True:
        if y[_V] == 0.0 and abs(_restoring(y[0], omega, pendulum)) <= mu:
            _hold(out, filled, n, y)  # the mass has stuck
            return n
        while filled < n and tau[filled] <= t:
            _hold(out, filled, filled + 1, y)
            filled += 1
        if filled == n:
            return n
        h, proposed, attempts = _accepted_step(y, t, min(h, tau[n - 1] - t), K, A, E3, E5,
                                               y_new, work, rtol, atol, parameters, sense)
        steps += attempts
        if h == 0.0 or steps > max_steps:
            return filled
        _dense(y, y_new, h, K, A, D, F, work, parameters, sense)
        if sense * y_new[_V] < 0.0:  # the velocity changed sign in this step
            fraction = _reversal(F, y, sense)
            # x and dx/dp are continuous there: samples at the reversal may come from
            # either side.
            filled = _fill(out, tau, filled, t + fraction * h, F, y, t, h)
            for i in range(y.size):
                y_new[i] = _polynomial(F, y, fraction, i)
            y_new[_V] = 0.0
            _jump(y_new, sense, parameters)
            sense, t = -sense, t + fraction * h
        else:
            # The last step ends at the last sample exactly (t + h may round below it).
            end = tau[n - 1] if h == tau[n - 1] - t else t + h
            filled = _fill(out, tau, filled, end, F, y, t, h)
            t = end
        for i in range(y.size):
            y[i] = y_new[i]
        _rates(y, K, np.int64(0), parameters, sense)
        h = proposed


def integrate_motion(tau, state, parameters, rtol, atol, max_steps):
    """x and dx/dp at the times ``tau`` of the motion from ``state`` at time 0: half-cycle
    by half-cycle, each with its sense of motion, the reversals located on the steps'
    interpolants and the sensitivities of v jumping there.

    Parameters
    ----------
    tau : ndarray, shape (n,)
        Times (s) from the start, sorted, >= 0; n >= 1.
    state : ndarray, shape (14,)
        x, dx/dp, v and dv/dp at time 0, p = (y0, theta0, omega, beta, kappa, mu).
    parameters : tuple
        (omega, beta, kappa, mu, pendulum) as in
        :func:`mcfit.equation_of_motion.motion_with_sensitivities`.
    rtol : float
        Relative tolerance of each step's error (scipy's RMS norm).
    atol : ndarray, shape (14,)
        Absolute tolerance of each state component.
    max_steps : int
        The integration fails after this many steps (accepted or not).

    Returns
    -------
    rows : ndarray, shape (n, 7)
        x and dx/dp at ``tau``; NaN from where the integration failed (a state that is not
        finite, a step too small or too many steps).
    """
    size = state.size
    stages, interpolant = np.empty((_A.shape[0], size)), np.empty((_D.shape[0] + 3, size))
    out = np.empty((tau.size, _OUT))
    filled = _integrate(tau, parameters, rtol, atol, max_steps, _A, _E3, _E5, _D,
                        state.copy(), np.empty(size), np.empty(size), stages, interpolant,
                        out)
    out[filled:] = np.nan
    return out
