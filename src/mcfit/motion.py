"""Equation of motion of the modified Coulomb oscillator, its integrators and synthetic records.

Handbook Eq. 20.55 per unit mass, with ``A = sqrt(x**2 + (xdot/omega)**2)`` the energy
amplitude (docs/theory.md section 4)::

    xddot + (pi*omega/2) * (c + b*A + a*A**2) * sgn(xdot) + omega**2 * x = 0

and its general power form (Eq. 20.51): the bracket is ``sum(k * A**n for k, n in terms)``,
a sequence of ``(coefficient, power)`` pairs; ``damping_terms(a, b, c)`` is
``((c, 0), (b, 1), (a, 2))``. Averaged over a cycle the bracket becomes the amplitude law
``dy/dt = -sum(k * y**n)`` (Eq. 20.59 for the three-term form).

Integrators, cheapest first:

- :func:`averaged_motion`: ``y(t)*cos(omega*t + phase)`` with ``y`` from the closed form
  (:mod:`mcfit.decay`); error about ``AVERAGED_ERROR_CONSTANT / Q0`` of the initial amplitude.
- :func:`integrate_cromer_euler`: the handbook's Table 20.1 scheme, first order.
- :func:`integrate_symplectic`: Strang splitting, second order between velocity reversals.
- :func:`integrate_accurate`: DOP853 with a step end at every velocity reversal and static
  friction at the turning points.

:func:`simulate_record` samples one of them on a uniform grid and adds noise, offset and drift.
Pure numpy/scipy: no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicHermiteSpline

from mcfit import decay
from mcfit.options import SIMULATE_METHODS

__all__ = [
    "METHODS",
    "AVERAGED_ERROR_CONSTANT",
    "AccurateMotion",
    "damping_terms",
    "friction_bracket",
    "acceleration",
    "integrate_cromer_euler",
    "integrate_symplectic",
    "integrate_accurate",
    "averaged_motion",
    "averaged_error_estimate",
    "choose_method",
    "default_step",
    "simulate_record",
]

METHODS = SIMULATE_METHODS

# max|x_averaged - x_true| / y0 = AVERAGED_ERROR_CONSTANT / Q(y0) at most, measured against
# the accurate integrator (tests/test_motion.py::test_averaged_error_constant) for Coulomb,
# hysteretic, fluid and mixed decays with Q(y0) from 2 to 1000: the ratio is pi/4 = 0.7854
# for Coulomb damping at every Q (the true motion swings about +-pi*c/(2*omega) instead of 0)
# and tends to pi/4 from below for the others (0.71 to 0.785); the largest error is in the
# first quarter cycle. 0.8 is pi/4 with a 2 % margin.
AVERAGED_ERROR_CONSTANT = 0.8

# Fixed-step default: the handbook's dt = 0.002 s for T = 0.5 s is T/250.
_STEPS_PER_PERIOD = 250
# Accurate integrator defaults (relative to the motion's scale max(|x0|, |v0|/omega)).
_ACCURATE_RTOL = 1e-10
_ACCURATE_ATOL = 1e-12


def damping_terms(a, b, c):
    """The three-term bracket of Eq. 20.55 as ``((c, 0), (b, 1), (a, 2))``.

    Parameters
    ----------
    a, b, c : float
        Fluid (1/(U*s)), hysteretic (1/s) and Coulomb (U/s) coefficients, all >= 0.

    Returns
    -------
    tuple of (float, float)
        ``(coefficient, power)`` pairs for the ``terms`` argument of the integrators.
    """
    return ((float(c), 0.0), (float(b), 1.0), (float(a), 2.0))


def _check_terms(terms):
    terms = tuple((float(k), float(n)) for k, n in terms)
    for k, n in terms:
        if not (k >= 0 and math.isfinite(k)):
            raise ValueError(f"damping coefficient {k} must be finite and >= 0")
        if not (n >= 0 and math.isfinite(n)):
            raise ValueError(f"damping power {n} must be finite and >= 0")
    return tuple((k, n) for k, n in terms if k > 0)


def _coulomb_part(terms):
    return sum(k for k, n in terms if n == 0)


def _bracket_function(terms):
    """A fast scalar F(A) = sum k*A**n for the integrator loops."""
    powers = {n for _, n in terms}
    if powers <= {0.0, 1.0, 2.0}:
        c = sum(k for k, n in terms if n == 0)
        b = sum(k for k, n in terms if n == 1)
        a = sum(k for k, n in terms if n == 2)
        return lambda amplitude: c + amplitude * (b + a * amplitude)
    return lambda amplitude: sum(k * amplitude**n for k, n in terms)


def friction_bracket(amplitude, terms):
    """The bracket of Eq. 20.51/20.55: ``sum(k * A**n)`` (U/s), i.e. the averaged -dy/dt.

    Parameters
    ----------
    amplitude : float or ndarray
        Energy amplitude A (U), >= 0.
    terms : sequence of (float, float)
        ``(coefficient, power)`` pairs, e.g. from :func:`damping_terms`.
    """
    amplitude = np.asarray(amplitude, dtype=float)
    total = np.zeros_like(amplitude)
    for k, n in terms:
        total = total + k * amplitude**n  # 0**0 = 1: the Coulomb term acts at A = 0 too
    return total[()] if total.ndim == 0 else total


def acceleration(x, v, omega, terms):
    """xddot of Eq. 20.55 (or 20.51 with general ``terms``), per unit mass.

    Parameters
    ----------
    x : float or ndarray
        Displacement (U).
    v : float or ndarray
        Velocity (U/s).
    omega : float
        Angular frequency 2*pi/T (rad/s).
    terms : sequence of (float, float)
        ``(coefficient, power)`` pairs of the friction bracket.

    Returns
    -------
    float or ndarray
        ``-omega**2*x - (pi*omega/2)*F(A)*sgn(v)`` (U/s**2), with ``sgn(0) = 0``.
    """
    x = np.asarray(x, dtype=float)
    v = np.asarray(v, dtype=float)
    amplitude = np.hypot(x, v / omega)
    result = -omega**2 * x - 0.5 * math.pi * omega * friction_bracket(amplitude, terms) * np.sign(v)
    return result[()] if result.ndim == 0 else result


def _check_steps(omega, dt, n_steps):
    if not (omega > 0 and math.isfinite(omega)):
        raise ValueError(f"omega = {omega} must be finite and > 0")
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f"dt = {dt} must be finite and > 0")
    if int(n_steps) != n_steps or n_steps < 0:
        raise ValueError(f"n_steps = {n_steps} must be a whole number >= 0")
    return int(n_steps)


def integrate_cromer_euler(x0, v0, omega, terms, dt, n_steps):
    """Cromer-Euler ("last point approximation") steps of Eq. 20.55, as Table 20.1.

    Each step is ``v += accel(x, v)*dt; x += v*dt`` (semi-implicit Euler, first order),
    with the handbook's sign rule: friction acts as for ``v > 0`` only when ``v > 0``,
    otherwise as for ``v < 0``. No static friction: a Coulomb decay ends in chatter
    about the origin of size about ``dt * pi*omega*c/2`` instead of sticking.

    Parameters
    ----------
    x0 : float
        Initial displacement (U).
    v0 : float
        Initial velocity (U/s).
    omega : float
        Angular frequency 2*pi/T (rad/s).
    terms : sequence of (float, float)
        ``(coefficient, power)`` pairs of the friction bracket (:func:`damping_terms`).
    dt : float
        Step (s).
    n_steps : int
        Number of steps.

    Returns
    -------
    t, x, v : ndarray, shape (n_steps + 1,)
        Times ``k*dt`` (s), displacements (U) and velocities (U/s) after each step
        (index 0 is the initial state). ``x[k+1] = x[k] + v[k+1]*dt`` exactly.
    """
    n_steps = _check_steps(omega, dt, n_steps)
    bracket = _bracket_function(_check_terms(terms))
    friction = 0.5 * math.pi * omega
    omega2 = omega * omega
    x_out = np.empty(n_steps + 1)
    v_out = np.empty(n_steps + 1)
    x, v = float(x0), float(v0)
    x_out[0], v_out[0] = x, v
    hypot = math.hypot
    for k in range(1, n_steps + 1):
        force = friction * bracket(hypot(x, v / omega))
        v += (-omega2 * x - (force if v > 0 else -force)) * dt
        x += v * dt
        x_out[k] = x
        v_out[k] = v
    return dt * np.arange(n_steps + 1), x_out, v_out


def integrate_symplectic(x0, v0, omega, terms, dt, n_steps):
    """Strang splitting of Eq. 20.55: half friction kick, exact harmonic rotation, half kick.

    Second order where the friction is smooth (between velocity reversals); at each
    reversal the jump of sgn(v) inside a step costs a local error O(dt), so over many
    cycles the phase/amplitude error falls only like dt. No static friction.

    Parameters
    ----------
    x0, v0, omega, terms, dt, n_steps
        As for :func:`integrate_cromer_euler`.

    Returns
    -------
    t, x, v : ndarray, shape (n_steps + 1,)
        Times (s), displacements (U), velocities (U/s) at the step ends; ``v`` is a
        second-order velocity (usable for cubic Hermite interpolation).

    Notes
    -----
    Why this scheme: the conservative part ``xddot = -omega**2*x`` is integrated exactly
    (a rotation in the (x, v/omega) plane), so the scheme has no phase drift of its own at
    any dt and is symplectic when the friction vanishes; the friction sub-flow
    ``vdot = -(pi*omega/2)*F(A)*sgn(v)`` at fixed x is one-dimensional and is advanced by
    the explicit midpoint rule (local error O(dt**3)), so the symmetric Strang composition
    is second order. A kick never reverses v: friction alone brings the mass to rest
    (clamped to v = 0), which is the exact behaviour of the friction sub-flow.
    A Stormer-Verlet step would need an implicit velocity update for a velocity-dependent
    force and would still carry the O((omega*dt)**2) phase error of the harmonic part.
    """
    n_steps = _check_steps(omega, dt, n_steps)
    bracket = _bracket_function(_check_terms(terms))
    friction = 0.5 * math.pi * omega
    cos_h, sin_h = math.cos(omega * dt), math.sin(omega * dt)
    half, quarter = 0.5 * dt, 0.25 * dt
    hypot = math.hypot

    def kick(x, v):
        if v == 0.0:
            return 0.0
        sign = 1.0 if v > 0 else -1.0
        v_mid = v - quarter * sign * friction * bracket(hypot(x, v / omega))
        if v_mid * sign <= 0.0:
            return 0.0
        v_new = v - half * sign * friction * bracket(hypot(x, v_mid / omega))
        return v_new if v_new * sign > 0.0 else 0.0

    x_out = np.empty(n_steps + 1)
    v_out = np.empty(n_steps + 1)
    x, v = float(x0), float(v0)
    x_out[0], v_out[0] = x, v
    for k in range(1, n_steps + 1):
        v = kick(x, v)
        x, v = x * cos_h + (v / omega) * sin_h, v * cos_h - x * omega * sin_h
        v = kick(x, v)
        x_out[k] = x
        v_out[k] = v
    return dt * np.arange(n_steps + 1), x_out, v_out


@dataclass(frozen=True)
class AccurateMotion:
    """Result of :func:`integrate_accurate`.

    Attributes
    ----------
    t, x, v : ndarray, shape (n,)
        The requested times (s), displacements (U) and velocities (U/s).
    turning_times, turning_x : ndarray, shape (m,)
        Times (s) and displacements (U) of every velocity reversal up to ``t[-1]``,
        including the start when ``v0 == 0`` and the stop.
    stop_time : float
        Time (s) at which static friction held the mass for good; ``inf`` if it did not
        stop before ``t[-1]``.
    n_evaluations : int
        Right-hand-side evaluations, a cost measure.
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    turning_times: np.ndarray
    turning_x: np.ndarray
    stop_time: float
    n_evaluations: int


def integrate_accurate(x0, v0, omega, terms, t, rtol=_ACCURATE_RTOL, atol=None):
    """Accurate solution of Eq. 20.55 with every velocity reversal a step end.

    Each half-cycle (constant sgn(v)) is one ``solve_ivp`` DOP853 run that ends at the
    event ``v = 0``; the run after it starts with the new sign, so the discontinuity of
    sgn(v) never falls inside a step. At a turning point the mass sticks for good when
    ``omega**2*|x| <= pi*omega*c/2`` (docs/theory.md section 4; ``c`` is the power-0
    coefficient), so a Coulomb decay ends at rest instead of chattering about 0.

    Parameters
    ----------
    x0 : float
        Displacement at t = 0 (U).
    v0 : float
        Velocity at t = 0 (U/s).
    omega : float
        Angular frequency 2*pi/T (rad/s).
    terms : sequence of (float, float)
        ``(coefficient, power)`` pairs of the friction bracket (:func:`damping_terms`).
    t : ndarray, shape (n,)
        Output times (s), non-decreasing, ``t[0] >= 0``; the integration runs to ``t[-1]``.
    rtol : float, optional
        DOP853 relative tolerance.
    atol : float, optional
        Absolute tolerance on x (U); default ``1e-12 * max(|x0|, |v0|/omega)``. The
        tolerance on v is ``omega * atol``.

    Returns
    -------
    AccurateMotion
        x(t), v(t) by the DOP853 dense output (7th order) of each half-cycle.

    Notes
    -----
    Only the Coulomb part sticks. If the whole bracket at a turning point exceeds the
    spring force while the Coulomb part alone does not (possible only for Q of order 1),
    Eq. 20.55 has no forward motion there and the mass is held as well.
    """
    if not (omega > 0 and math.isfinite(omega)):
        raise ValueError(f"omega = {omega} must be finite and > 0")
    terms = _check_terms(terms)
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size == 0 or t[0] < 0 or np.any(np.diff(t) < 0):
        raise ValueError("t must be a non-empty 1-D array of non-decreasing times >= 0")
    bracket = _bracket_function(terms)
    friction = 0.5 * math.pi * omega
    omega2 = omega * omega
    coulomb = _coulomb_part(terms)
    scale = max(abs(x0), abs(v0) / omega)
    if atol is None:
        atol = _ACCURATE_ATOL * scale if scale > 0 else _ACCURATE_ATOL
    tolerances = np.array([atol, atol * omega])

    x_out = np.empty_like(t)
    v_out = np.empty_like(t)
    turning_times, turning_x = [], []
    t_end = float(t[-1])
    now, x, v = 0.0, float(x0), float(v0)
    if abs(v) <= tolerances[1]:  # below the tolerance a start is a turning point
        v = 0.0
    stop_time = math.inf
    evaluations = 0
    filled = 0  # t[:filled] are done
    while True:
        if v == 0.0:
            turning_times.append(now)
            turning_x.append(x)
            spring = omega2 * abs(x)
            if spring <= friction * coulomb or spring <= friction * bracket(abs(x)):
                stop_time = now
                break
            sign = -1.0 if x > 0 else 1.0
        else:
            sign = 1.0 if v > 0 else -1.0
        if now >= t_end:
            break
        push = sign * friction

        def rhs(_, y, push=push):
            return [y[1], -omega2 * y[0] - push * bracket(math.hypot(y[0], y[1] / omega))]

        def reversal(_, y):
            return y[1]

        reversal.terminal = True
        reversal.direction = -sign
        solution = solve_ivp(rhs, (now, t_end), [x, v], method="DOP853", rtol=rtol,
                             atol=tolerances, events=reversal, dense_output=True)
        if not solution.success:  # pragma: no cover - DOP853 fails only on bad input
            raise RuntimeError(f"accurate integration failed at t = {now}: {solution.message}")
        evaluations += solution.nfev
        if solution.status == 1:
            t_next = float(solution.t_events[0][-1])
            x_next, v_next = float(solution.y_events[0][-1][0]), 0.0
        else:
            t_next = t_end
            x_next, v_next = float(solution.y[0, -1]), float(solution.y[1, -1])
        stop = int(np.searchsorted(t, t_next, side="right"))
        if stop > filled:
            state = solution.sol(t[filled:stop])
            x_out[filled:stop], v_out[filled:stop] = state
            filled = stop
        if t_next <= now and v_next == 0.0:  # pragma: no cover - a zero-length half-cycle
            raise RuntimeError(f"accurate integration stalled at t = {now}")
        now, x, v = t_next, x_next, v_next
        if solution.status != 1:
            break
    # Times at or after the stop (and t == 0 for a start at rest) keep the last state.
    x_out[filled:] = x
    v_out[filled:] = 0.0 if math.isfinite(stop_time) else v
    if math.isfinite(stop_time):
        held = t >= stop_time
        x_out[held], v_out[held] = x, 0.0
    return AccurateMotion(t=t, x=x_out, v=v_out, turning_times=np.array(turning_times),
                          turning_x=np.array(turning_x), stop_time=stop_time,
                          n_evaluations=evaluations)


def averaged_motion(t, y0, a, b, c, period, phase=0.0):
    """The averaged (envelope) waveform ``x = y(t) * cos(omega*t + phase)``.

    ``y(t)`` is the closed-form amplitude of :func:`mcfit.decay.amplitude` (Eq. 20.59),
    0 after the stop. First order in 1/Q: it omits the odd harmonics of the friction
    square wave (Eq. 20.64), the frequency shift and the Coulomb rest offset; the error is
    at most about ``AVERAGED_ERROR_CONSTANT / Q(y0)`` of ``y0``.

    Parameters
    ----------
    t : ndarray
        Times (s).
    y0 : float
        Amplitude at t = 0 (U).
    a, b, c : float
        Coefficients (1/(U*s), 1/s, U/s).
    period : float
        Period T (s); ``omega = 2*pi/T``.
    phase : float, optional
        Phase at t = 0 (rad); 0 starts at a turning point ``x = y0``.

    Returns
    -------
    ndarray
        x(t) (U), same shape as ``t``.
    """
    t = np.asarray(t, dtype=float)
    omega = 2.0 * math.pi / period
    return decay.amplitude(t, y0, a, b, c) * np.cos(omega * t + phase)


def averaged_error_estimate(y0, a, b, c, period):
    """Expected ``max|x_averaged - x_true| / y0`` of :func:`averaged_motion`.

    The neglected parts of the motion (harmonics of the friction square wave, Coulomb rest
    offset, second-order amplitude and phase drift) scale with the friction force, i.e.
    with ``P(y)/omega`` in absolute terms, where ``P(y) = c + b*y + a*y**2``. Relative to
    the initial amplitude that is ``(y/y0)/Q(y)`` (Eq. 20.56), largest at the start because
    P grows with y. So the estimate is ``AVERAGED_ERROR_CONSTANT / Q(y0)``. (Q itself can
    fall to 0 at the stop of a Coulomb decay, but by then the amplitude is small too: the
    smallest Q over the record, unweighted, would forbid the averaged model for every
    record that reaches its stop.)

    Parameters
    ----------
    y0 : float
        Initial amplitude (U), > 0.
    a, b, c : float
        Coefficients (1/(U*s), 1/s, U/s).
    period : float
        Period (s).

    Returns
    -------
    float
        The estimated relative error (dimensionless); 0 without damping.
    """
    omega = 2.0 * math.pi / period
    q0 = float(decay.quality_factor(y0, omega, a, b, c))
    return AVERAGED_ERROR_CONSTANT / q0


def choose_method(y0, a, b, c, period, rtol):
    """The cheapest method meeting ``rtol`` (relative to y0): "averaged" or "accurate".

    The averaged model costs one closed-form evaluation and is picked when
    :func:`averaged_error_estimate` ``<= rtol``. Otherwise the accurate integrator is used:
    the fixed-step schemes lose their order at every velocity reversal, so reaching a small
    rtol with them takes far more steps than DOP853 with event location needs.
    """
    if averaged_error_estimate(y0, a, b, c, period) <= rtol:
        return "averaged"
    return "accurate"


def default_step(period, rate):
    """Default fixed step (s): the largest ``(1/rate)/k`` (k whole) not above ``period/250``.

    The handbook uses dt = 0.002 s for T = 0.5 s (T/250); a divisor of the sample interval
    lets :func:`simulate_record` take every k-th step without interpolation.
    """
    interval = 1.0 / rate
    k = max(1, math.ceil(interval / (period / _STEPS_PER_PERIOD) - 1e-9))
    return interval / k


def _resample_fixed_step(t_steps, x_steps, v_steps, t, dt, rate, method):
    k = round(1.0 / (rate * dt))
    if k >= 1 and abs(k * dt * rate - 1.0) < 1e-9:
        return x_steps[::k][: t.size]
    if method == "cromer-euler":
        # The scheme's own continuous path: x moves at v[k+1] over step k (first order).
        return np.interp(t, t_steps, x_steps)
    return CubicHermiteSpline(t_steps, x_steps, v_steps)(t)


def _check_positive(name, value):
    if not (value > 0 and math.isfinite(value)):
        raise ValueError(f"{name} = {value} must be finite and > 0")


def simulate_record(a, b, c, y0, period, duration, rate, method="auto", dt=None, rtol=1e-6,
                    noise=0.0, offset=0.0, drift=0.0, rng=None):
    """A synthetic free-decay record of Eq. 20.55, sampled uniformly.

    The oscillator starts at a turning point, ``x = y0``, ``xdot = 0``, at t = 0.

    Parameters
    ----------
    a, b, c : float
        Fluid (1/(U*s)), hysteretic (1/s) and Coulomb (U/s) coefficients, >= 0.
    y0 : float
        Initial amplitude (U), > 0.
    period : float
        Undamped period T (s), > 0.
    duration : float
        Record length (s), >= 0; samples run from 0 to ``duration`` inclusive.
    rate : float
        Sampling rate (Hz), > 0.
    method : {"auto", "averaged", "cromer-euler", "symplectic", "accurate"}, optional
        ``auto`` takes the averaged model when its error estimate meets ``rtol`` and the
        accurate integrator otherwise (:func:`choose_method`).
    dt : float, optional
        Step (s) of the fixed-step methods; default :func:`default_step`. Not used by the
        other methods.
    rtol : float, optional
        Tolerance relative to ``y0`` for ``auto``; the accurate integrator runs at
        ``0.1*rtol/cycles`` (between 1e-13 and 1e-10), because its phase error grows with
        the number of cycles.
    noise : float, optional
        Standard deviation (U) of independent Gaussian noise added to each sample.
    offset : float, optional
        Constant added to x (U).
    drift : float, optional
        Linear drift added to x (U/s).
    rng : numpy.random.Generator or int, optional
        Source of the noise, or its seed; a fresh unseeded one when omitted.

    Returns
    -------
    mcfit.record.Record
        ``t = arange(n)/rate`` (s), ``n = floor(duration*rate) + 1``, and ``x`` the
        displacement (U); it unpacks as ``t, x = simulate_record(...)`` and
        :func:`mcfit.analyse` takes it as it is.
    """
    for name, value in (("y0", y0), ("period", period), ("rate", rate)):
        _check_positive(name, value)
    for name, value in (("a", a), ("b", b), ("c", c), ("duration", duration), ("noise", noise)):
        if not (value >= 0 and math.isfinite(value)):
            raise ValueError(f"{name} = {value} must be finite and >= 0")
    if not (rtol > 0):
        raise ValueError(f"rtol = {rtol} must be > 0")
    if method not in METHODS:
        raise ValueError(f"method {method!r} is not one of {', '.join(METHODS)}")
    if dt is not None:
        _check_positive("dt", dt)
    n = math.floor(duration * rate * (1 + 1e-12)) + 1
    t = np.arange(n) / rate
    omega = 2.0 * math.pi / period
    terms = damping_terms(a, b, c)
    if method == "auto":
        method = choose_method(y0, a, b, c, period, rtol)
    if method == "averaged":
        x = averaged_motion(t, y0, a, b, c, period)
    elif method == "accurate":
        # The phase error of DOP853 grows about linearly with the number of cycles (measured
        # 0.2-0.3 * cycles * solver rtol, relative to y0, over 1400 cycles).
        cycles = max(1.0, duration / period)
        solver_rtol = min(_ACCURATE_RTOL, max(0.1 * rtol / cycles, 1e-13))
        x = integrate_accurate(y0, 0.0, omega, terms, t, rtol=solver_rtol).x
    else:
        step = default_step(period, rate) if dt is None else float(dt)
        n_steps = math.ceil(t[-1] / step * (1 - 1e-12))
        integrate = integrate_cromer_euler if method == "cromer-euler" else integrate_symplectic
        t_steps, x_steps, v_steps = integrate(y0, 0.0, omega, terms, step, n_steps)
        x = _resample_fixed_step(t_steps, x_steps, v_steps, t, step, rate, method)
    x = x + offset + drift * t
    if noise > 0:
        x = x + np.random.default_rng(rng).normal(0.0, noise, size=n)
    from mcfit.record import Record  # noqa: PLC0415 - numpy only, kept off the import path

    note = (f"simulated by the {method} method: a = {a:g}, b = {b:g}, c = {c:g}, "
            f"y0 = {y0:g}, period {period:g} s, noise {noise:g}")
    return Record(source="<simulated>", t=t, x=x, time_column="t", signal_column="x",
                  time_unit="s", notes=(note,))
