"""The amplitude law of a gravity pendulum at large swings, and its fit (docs/theory.md section 6).

For theta'' + D(theta') + w0**2 sin(theta) = 0 the energy at a turning point is
E = w0**2 (1 - cos theta0), so dE/dtheta0 = w0**2 sin(theta0), and averaged over one exact
(undamped) swing of period T(theta0) = T0 * 2K(k)/pi, k = sin(theta0/2),

    dtheta0/dt = -(loop integral of theta' D(theta') dt) / (w0**2 sin(theta0) T(theta0)).

With the small-angle meanings of the coefficients, c = 2*tau/(pi*w0) for a Coulomb torque
tau*sgn(theta'), b = beta for viscous damping 2*beta*theta' and a = 4*kappa*w0/(3*pi) for
quadratic drag kappa*theta'*|theta'|, this is

    dtheta0/dt = -(c*G0 + b*theta0*G1 + a*theta0**2*G2)

with factors of the amplitude alone that tend to 1 as theta0 -> 0 (K, E complete elliptic
integrals of modulus k, k' = cos(theta0/2)):

    G0 = pi*theta0 / (2 K sin(theta0))                    Coulomb: loss 4*tau*theta0 per cycle
    G1 = 8 (E - k'**2 K) / (K theta0 sin(theta0))          viscous: loop of theta'**2 dt
                                                            = 16 w0 (E - k'**2 K)
    G2 = 3 pi (sin(theta0) - theta0 cos(theta0))           drag: loop of |theta'|**3 dt
         / (2 K theta0**2 sin(theta0))                        = 8 w0**2 (sin - theta0 cos)

w0 drops out: the law depends on the amplitude in radians only. It has no closed form; being
autonomous, it is solved as the time to fall from y0 to theta0 (a quadrature, inverted by
Newton's method), with its sensitivities to (y0, a, b, c) in closed form.
The candidate models and the verdict are those of the ordinary fit
(:mod:`mcfit.fit.selection`); Q is the energy's, 2*pi*E over the energy lost per cycle.

numpy/scipy/lmfit only, no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import integrate, optimize, special

from mcfit.errors import FitError
from mcfit.fit.candidates import Candidate, information_criteria, nested_candidates
from mcfit.fit.decay_fit import MIN_POINTS, DecayFit
from mcfit.fit.diagnostics import fit_warnings, misfit_warning, no_decay_warning
from mcfit.fit.models import CRITERIA, NONE, POWER, REGIME_NAMES, TERMS, models_to_fit, \
    parse_model, terms_of
from mcfit.fit.problem import PARAMETERS
from mcfit.fit.reported import TOLERANCES, lmfit_parameters, solve_reported
from mcfit.fit.selection import LRT_ALPHA, select_model
from mcfit.fit.uncertainty import physical_errors, summarise_q, term_correlations

__all__ = ["PendulumFit", "fit_pendulum", "fit_turning_points_of_pendulum", "geometric_factors", "period_ratio",
           "fundamental_amplitude",
           "names_degrees", "RADIANS_PER_DEGREE", "large_swing_warning"]

RADIANS_PER_DEGREE = math.pi / 180.0
# Amplitudes beyond this (178 degrees) are too close to going over the top to fit.
_LARGEST_ANGLE = 3.1
# Below this amplitude the elliptic forms lose digits to cancellation: series instead.
_SERIES_BELOW = 0.02
_RTOL, _ATOL = 1e-11, 1e-14
_COLUMN = {name: i for i, name in enumerate(PARAMETERS)}


def names_degrees(column_name) -> bool:
    """Whether a signal column's header names degrees ("angle (deg)", "theta [°]")."""
    name = str(column_name or "").lower()
    return "deg" in name or "°" in name


def period_ratio(theta0):
    """T(theta0)/T0 = 2K(k)/pi, k = sin(theta0/2): the exact period of the undamped swing
    over the small-angle one (theta0 in radians, |theta0| < pi)."""
    k = np.sin(0.5 * np.abs(np.asarray(theta0, dtype=float)))
    return 2.0 * special.ellipk(k * k) / math.pi


def fundamental_amplitude(theta0):
    """The amplitude of the fundamental in the Fourier series of the undamped swing of
    amplitude ``theta0`` (radians): 8*sqrt(q)/(1 + q), q = exp(-pi*K(k')/K(k)) the nome.

    A pendulum's swing is flatter at its turning points than a sine of the same amplitude,
    so this exceeds theta0 (by 0.53 % at 1 rad). It is what a least-squares fit of
    A*cos(w*s) over a half cycle centred on a crest measures (the odd harmonics are
    orthogonal to cos(w*s) there), as :func:`mcfit.turning.find_turning_points` does.
    """
    theta = np.abs(np.asarray(theta0, dtype=float))
    m = np.sin(0.5 * theta) ** 2
    with np.errstate(divide="ignore"):
        nome = np.exp(-math.pi * special.ellipkm1(m) / special.ellipk(m))
    return 8.0 * np.sqrt(nome) / (1.0 + nome)


def peak_from_fundamental(amplitude):
    """The swing amplitude theta0 whose fundamental is ``amplitude`` (radians): the inverse
    of :func:`fundamental_amplitude` by Newton's method, odd in ``amplitude``."""
    target = np.asarray(amplitude, dtype=float)
    size = np.abs(target)
    theta = np.minimum(size, _LARGEST_ANGLE)
    for _ in range(6):
        step = 1e-6 * np.maximum(theta, 1e-3)
        slope = (fundamental_amplitude(theta + step)
                 - fundamental_amplitude(np.maximum(theta - step, 0.0))) / (
                     theta + step - np.maximum(theta - step, 0.0))
        theta = np.clip(theta - (fundamental_amplitude(theta) - size) / slope, 0.0,
                        _LARGEST_ANGLE)
    return np.sign(target) * theta


def geometric_factors(theta0):
    """(G0, G1, G2): the Coulomb, viscous and quadratic-drag decay rates of the amplitude
    of a pendulum at amplitude ``theta0`` (radians, |theta0| < pi) over their small-angle
    values c, b*theta0 and a*theta0**2. Each is 1 at theta0 = 0 and even in theta0."""
    theta = np.abs(np.asarray(theta0, dtype=float))
    small = theta < _SERIES_BELOW
    with np.errstate(divide="ignore", invalid="ignore"):
        mean, difference = _arithmetic_geometric_mean(theta)
        s = np.sin(theta)
        g0 = theta * mean / s  # pi/(2K) = the mean
        g1 = 8.0 * difference / (theta * s)
        g2 = 3.0 * mean * (s - theta * np.cos(theta)) / (theta**2 * s)
    t2 = theta * theta
    # Taylor series about 0 (checked against the closed forms in the tests).
    g0 = np.where(small, 1.0 + 5.0 * t2 / 48.0 + 431.0 * t2 * t2 / 46080.0, g0)
    g1 = np.where(small, 1.0 + 5.0 * t2 / 96.0 + 17.0 * t2 * t2 / 3840.0, g1)
    g2 = np.where(small, 1.0 + t2 / 240.0 + 809.0 * t2 * t2 / 322560.0, g2)
    return g0, g1, g2


def _arithmetic_geometric_mean(theta):
    """The arithmetic-geometric mean M of 1 and k' = |cos(theta/2)|, so that K(k) = pi/(2M),
    and (E - k'**2 K)/K = k**2/2 - sum over n >= 1 of 2**(n-1) c_n**2, with
    c_(n+1) = c_n**2/(4 a_(n+1)), c_0 = k = sin(theta/2) (Abramowitz and Stegun 17.6):
    no cancellation as k -> 0, and several times faster than scipy's R_D."""
    mean, geometric = np.ones_like(theta), np.abs(np.cos(0.5 * theta))
    c_squared = np.sin(0.5 * theta) ** 2
    difference, power = 0.5 * c_squared, 1.0
    for _ in range(30):  # quadratic convergence: 6 steps at 3.1 rad
        mean, geometric = 0.5 * (mean + geometric), np.sqrt(mean * geometric)
        c_squared = c_squared * c_squared / (16.0 * mean * mean)
        difference = difference - power * c_squared
        power *= 2.0
        if not np.any(c_squared > 1e-36):
            break
    return mean, difference


def _rate_terms(theta):
    """(h0, h1, h2) = (G0, theta*G1, theta**2*G2): the law is -(c*h0 + b*h1 + a*h2)."""
    g0, g1, g2 = geometric_factors(theta)
    return np.array([g0, theta * g1, theta * theta * g2])


def _rate_terms_slope(theta):
    """d(h0, h1, h2)/dtheta by central differences (only the Jacobian uses it)."""
    step = 1e-5 * max(abs(theta), 1e-2)
    return (_rate_terms(theta + step) - _rate_terms(theta - step)) / (2.0 * step)


# The law is autonomous, dtheta/dt = -F(theta) with F = c*h0 + b*h1 + a*h2 > 0, so the time
# to fall from y0 to theta is the integral of 1/F from theta to y0, taken by Gauss-Legendre
# panels, each at least 2.4 times as far from 0 and from pi (where F vanishes or its terms
# are singular) as it is wide: 8 points integrate such a panel to about 1e-16.
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(8)
_RATIO = 2.0**-0.5  # of a panel's lower edge to its upper one, below y0
_FIRST_PANELS = 12  # panels made at first below y0 (to y0/64); then twice as many each time
_DEEPEST = 200  # below _RATIO**200 = 2**-100 of y0 the amplitude counts as 0
# Where the Coulomb term is this many times the others at theta <= pi/3, [0, theta] is one
# panel: the nearest zero of F lies beyond 4*theta.
_COULOMB_PANEL = 16.0
_NEWTON_STEPS = 8


def _rate(coefficients, theta):
    """The law's rate F at ``theta`` and its terms h, shape (3,) + theta's shape."""
    h = _rate_terms(theta)
    return np.tensordot(coefficients, h, axes=1), h


def _integrals(coefficients, lower, upper, sensitivities, at=None):
    """Integrals from ``lower`` to ``upper`` (arrays) of 1/F and, with ``sensitivities``,
    of h/F**2 (shape (3, ...), else None) by the Gauss rule; and F and h at ``at``
    (default ``lower``), in the same evaluation."""
    at = lower if at is None else at
    half = 0.5 * (upper - lower)
    nodes = ((0.5 * (upper + lower))[..., None] + half[..., None] * _NODES).ravel()
    rate, h = _rate(coefficients, np.concatenate([nodes, at]))
    shape = half.shape + _NODES.shape
    weights = half[..., None] / rate[:nodes.size].reshape(shape) * _WEIGHTS
    terms = None
    if sensitivities:
        h_nodes = h[:, :nodes.size].reshape((3,) + shape)
        terms = np.sum(weights * h_nodes / rate[:nodes.size].reshape(shape), axis=-1)
    return np.sum(weights, axis=-1), terms, rate[nodes.size:], h[:, nodes.size:]


def _panels(y0, coefficients, end, sensitivities):
    """Panel edges from y0 down (y0 times powers of _RATIO, and edges closing in on pi
    above _RATIO**2 * y0), until the time to reach them passes ``end``, or 0 where Coulomb
    friction stops the swing, or 2**-100 of y0. Returns the edges, F at each, the time to
    reach each and the integrals of h/F**2 from each to y0 (shape (3, edges))."""
    near_pi = math.pi - (math.pi - y0) * _RATIO ** -np.arange(1.0, 120.0)
    upper = near_pi[near_pi > _RATIO**2 * y0]
    edges, rates, times = np.array([y0]), np.zeros(0), np.zeros(1)
    terms = np.zeros((3, 1))
    depth, count = 0, _FIRST_PANELS
    while depth < _DEEPEST and edges[-1] > 0 and times[-1] <= end:
        count = min(count, _DEEPEST - depth)
        lower = y0 * _RATIO ** np.arange(depth + 1.0, depth + count + 1)
        if depth == 0:
            lower = np.unique(np.concatenate([upper, lower]))[::-1]
        chunk = np.concatenate([edges[-1:], lower])
        depth, count = depth + count, 2 * count
        time, term, rate, h = _integrals(coefficients, chunk[1:], chunk[:-1], sensitivities,
                                         at=chunk)
        coulomb = coefficients[0] * h[0]
        stops = (chunk <= math.pi / 3) & (coulomb >= _COULOMB_PANEL * (rate - coulomb))
        if coefficients[0] > 0 and np.any(stops):
            last = int(np.argmax(stops))  # [0, chunk[last]] is the last panel: it stops
            final = _integrals(coefficients, np.zeros(1), chunk[last:last + 1],
                               sensitivities, at=np.zeros(0))
            chunk = np.append(chunk[:last + 1], 0.0)
            rate = np.append(rate[:last + 1], coefficients[0])  # F(0) = c
            time = np.append(time[:last], final[0])
            if sensitivities:
                term = np.concatenate([term[:, :last], final[1]], axis=1)
        edges, rates = np.concatenate([edges, chunk[1:]]), np.concatenate([rates, rate[:-1]])
        times = np.concatenate([times, times[-1] + np.cumsum(time)])
        if sensitivities:
            terms = np.concatenate([terms, terms[:, -1:] + np.cumsum(term, axis=1)], axis=1)
    return edges, np.append(rates, rate[-1]), times, terms


def _amplitude_solution(t, y0, a, b, c, sensitivities=True):
    """theta0 at times ``t`` (>= 0, from the first turning point) from y0, and, with
    ``sensitivities``, d theta0/d(y0, a, b, c), shape (n, 4). The amplitude stays at 0 once
    it reaches it (Coulomb friction stops the swing in finite time).

    The law dtheta/dt = -F(theta) is autonomous: t(theta) is the integral of 1/F from
    theta to y0, inverted by Newton's method; d theta/d y0 = F(theta)/F(y0) and
    d theta/dp = -F(theta) * (integral of (dF/dp)/F**2 from theta to y0).
    """
    t = np.asarray(t, dtype=float)
    coefficients = np.array([c, b, a], dtype=float)
    theta = np.zeros(t.size)
    jacobian = np.zeros((t.size, 4))
    if y0 <= 0 or t.size == 0:
        jacobian[:, 0] = t == 0
        return theta, jacobian
    end = float(np.max(t))
    if end <= 0:
        theta[:], jacobian[:, 0] = y0, 1.0
        return theta, jacobian
    if np.any(coefficients < 0) or not y0 < math.pi:
        return _amplitude_solution_by_ode(t, y0, coefficients, sensitivities)
    rate, h = _rate(coefficients, np.array(y0))
    if rate * end <= 1e-12 * y0:  # next to no damping: first order in it, to 1e-12
        theta[:], jacobian[:, 0] = y0 - rate * t, 1.0
        jacobian[:, 1:] = -t[:, None] * h[::-1]
        return theta, jacobian
    edges, rates, times, terms = _panels(y0, coefficients, end, sensitivities)
    panel = np.maximum(np.searchsorted(times, t, side="right") - 1, 0)
    moving = panel < edges.size - 1  # else stopped, or below 2**-100 of y0
    panel = panel[moving]
    theta[moving], rate, tail = _newton_inverse(
        coefficients, t[moving], times[panel], times[panel + 1], edges[panel],
        edges[panel + 1], rates[panel], rates[panel + 1], sensitivities)
    if sensitivities:
        jacobian[moving, 0] = rate / rates[0]
        jacobian[moving, 1:] = -rate[:, None] * (terms[:, panel] + tail)[::-1].T
    return theta, jacobian


def _newton_inverse(coefficients, target, start, finish, top, bottom, top_rate, bottom_rate,
                    sensitivities):
    """theta in [bottom, top] reached at times ``target`` (between ``start`` and
    ``finish``, the times of top and bottom, where F is ``top_rate`` and ``bottom_rate``):
    a cubic Hermite guess, then Newton's method on t(theta) = start + integral of 1/F from
    theta to top. Returns theta, F(theta) and the integrals of h/F**2 from theta to top."""
    span = finish - start
    s = (target - start) / span
    theta = ((1 + 2 * s) * (1 - s) ** 2 * top - s * (1 - s) ** 2 * span * top_rate
             + s * s * (3 - 2 * s) * bottom + s * s * (1 - s) * span * bottom_rate)
    theta = np.clip(theta, bottom, top)
    for _ in range(_NEWTON_STEPS):
        time, tail, rate, h = _integrals(coefficients, theta, top, sensitivities)
        last, theta = theta, np.clip(theta + (start + time - target) * rate, bottom, top)
        # Newton's error after a step of 1e-5 of a panel's width is below 1e-10 of it.
        if np.all(np.abs(theta - last) <= 1e-5 * (top - bottom)):
            break
    # F and the integrals moved from the last point to theta (trapezoid: O(step**3))
    new_rate, new_h = _rate(coefficients, theta)
    if sensitivities:
        tail = tail + 0.5 * (last - theta) * (h / rate**2 + new_h / new_rate**2)
    return theta, new_rate, tail


def _amplitude_solution_by_ode(t, y0, coefficients, sensitivities):
    """:func:`_amplitude_solution` by integrating the law and its sensitivities
    (DOP853), for coefficients < 0 or y0 >= pi, which the fits never ask for."""
    def rhs(_, state):
        theta = max(state[0], 0.0)
        h = _rate_terms(theta)
        out = np.empty_like(state)
        out[0] = -float(coefficients @ h)
        if sensitivities:
            slope = -float(coefficients @ _rate_terms_slope(theta))
            out[1:] = slope * state[1:]
            out[2:] -= h[::-1]
        return out

    def stopped(_, state):
        return state[0]
    stopped.terminal, stopped.direction = True, -1

    start = np.array([y0, 1.0, 0.0, 0.0, 0.0]) if sensitivities else np.array([y0])
    theta = np.zeros(t.size)
    jacobian = np.zeros((t.size, 4))
    solution = integrate.solve_ivp(rhs, (0.0, float(t[-1])), start, method="DOP853",
                                   t_eval=t, events=stopped, rtol=_RTOL,
                                   atol=_ATOL * max(abs(y0), 1e-300))
    reached = solution.t.size
    theta[:reached] = solution.y[0]
    if sensitivities:
        jacobian[:reached] = solution.y[1:].T
    return np.maximum(theta, 0.0), jacobian


class _Problem:
    """One model's least-squares problem: time from the first turning point over the span,
    angles in radians, coefficients per span (a per radian per span, c radians per span).
    The law is integrated once per parameter vector, with its sensitivities."""

    def __init__(self, t, theta, weights, terms):
        self.t, self.theta, self.weights = t, theta, weights
        self.weight_scale = float(np.max(weights))
        self.chi_square_scale = self.weight_scale**2
        self.free = ("y0",) + tuple(terms)
        self.columns = [_COLUMN[k] for k in self.free]
        self._key = self._solution = None
        self.evaluations = 0

    def values(self, free_values):
        values = np.zeros(4)
        values[self.columns] = free_values
        return values

    def solve(self, free_values):
        key = tuple(self.values(free_values))
        if key != self._key:
            self.evaluations += 1
            self._key, self._solution = key, _amplitude_solution(self.t, *key)
        return self._solution

    def residual(self, free_values):
        return (self.solve(free_values)[0] - self.theta) * self.weights / self.weight_scale

    def jacobian(self, free_values):
        return (self.solve(free_values)[1][:, self.columns]
                * (self.weights / self.weight_scale)[:, None])

    def chi_square(self, free_values):
        return float(np.sum(((self.solve(free_values)[0] - self.theta) * self.weights) ** 2))

    def covariance(self, free_values):
        """Unscaled (J^T J)^-1 with the record's weights (pseudo-inverse)."""
        jacobian = self.solve(free_values)[1][:, self.columns] * self.weights[:, None]
        return np.linalg.pinv(jacobian.T @ jacobian)


@dataclass(frozen=True, eq=False, repr=False)  # DecayFit's short repr
class PendulumFit(DecayFit):
    """A :class:`DecayFit` of the pendulum's amplitude law. Coefficients keep their
    small-angle meaning and the units of the signal (radians, or degrees when the record is
    in degrees); ``small_angle_period`` is T0 in s, ``angle_unit`` "rad" or "deg"."""

    small_angle_period: float | None = None
    small_angle_period_stderr: float | None = None
    angle_unit: str = "rad"

    @property
    def radians_per_unit(self) -> float:
        return RADIANS_PER_DEGREE if self.angle_unit == "deg" else 1.0

    def amplitude(self, t):
        """The fitted amplitude at times ``t`` (signal units), by the pendulum's law."""
        t = np.maximum(np.asarray(t, dtype=float) - self.t0, 0)
        order = np.argsort(t, kind="stable")
        scale = self.radians_per_unit
        v = self.values
        theta, _ = _amplitude_solution(t[order], v["y0"] * scale, v["a"] / scale, v["b"],
                                       v["c"] * scale, sensitivities=False)
        out = np.empty_like(t)
        out[order] = theta / scale
        return out

    def to_dict(self) -> dict:
        """:meth:`DecayFit.to_dict` with the pendulum's angle unit and small-angle period
        T0 in s (``pendulum``)."""
        return with_pendulum_entry(super().to_dict(), self)


def with_pendulum_entry(out, fit) -> dict:
    """A fit's dict with the ``pendulum`` entry (angle unit, small-angle period T0 in s)
    before its warnings."""
    from mcfit import plain

    return plain.before_warnings(out, {"pendulum": {
        "angle_unit": fit.angle_unit,
        "small_angle_period": plain.number(fit.small_angle_period),
        "small_angle_period_stderr": plain.number(fit.small_angle_period_stderr)}})


def fit_pendulum(t, y, sigma=None, *, period=None, period_sigma=None, signs=None,
                 degrees=False, amplitudes="peak", criterion="aicc", model=None,
                 alpha=LRT_ALPHA) -> PendulumFit:
    """Fit the pendulum's amplitude law dtheta0/dt = -(c*G0 + b*theta0*G1 + a*theta0**2*G2)
    to turning points of a swing angle, and choose the regimes as :func:`fit_decay` does.

    Parameters
    ----------
    t : array_like, shape (n,)
        Turning-point times in s, increasing.
    y : array_like, shape (n,)
        Turning-point amplitudes of the swing angle about the vertical, in radians (degrees
        with ``degrees=True``); all below 178 degrees.
    sigma : array_like, shape (n,), optional
        Relative weights, as for :func:`fit_decay` (the noise scale comes from the residuals).
    period, period_sigma : float, optional
        The measured period (s) and its error; with ``signs`` (+1/-1 per turning point) the
        small-angle period T0 is fitted to the crest times, else taken from the period.
    degrees : bool
    amplitudes : {"peak", "fundamental"}
        What ``y`` measures: the peak angle of each swing (a table of extrema), or the
        amplitude of the fundamental (a half-cycle fit of a waveform, as
        :func:`mcfit.turning.find_turning_points` gives); the latter are converted to peak
        angles (:func:`peak_from_fundamental`) before fitting.
    criterion, model, alpha
        As for :func:`fit_decay`; ``model="power"`` is not available here.

    Returns
    -------
    PendulumFit
        Coefficients with their small-angle meaning (b is the small-swing decay rate), in
        the signal's units; Q = 2*pi*E/(energy lost per cycle) at each amplitude.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.shape != y.shape or t.ndim != 1 or t.size < MIN_POINTS:
        raise FitError(f"the pendulum fit needs at least {MIN_POINTS} turning points as 1-D "
                       "arrays of equal length")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))) or np.any(np.diff(t) <= 0):
        raise FitError("turning-point times must be finite and strictly increasing, and "
                       "amplitudes finite")
    if criterion not in CRITERIA:
        raise FitError(f"unknown criterion {criterion!r}; use one of {', '.join(CRITERIA)}",
                       option="criterion")
    forced = parse_model(model) if model is not None else None
    if forced == POWER:
        raise FitError("the power law is not available with the pendulum correction",
                       option="model")
    scale = RADIANS_PER_DEGREE if degrees else 1.0
    theta = y * scale
    largest = float(np.max(theta))
    if not largest > 0:
        raise FitError("no turning-point amplitude is > 0: there is no decay to fit")
    if largest >= _LARGEST_ANGLE:
        unit = "degrees" if degrees else "radians"
        raise FitError(f"the swing reaches {largest / scale:.4g} {unit}, beyond 178 degrees: "
                       "the pendulum correction needs a swinging pendulum (is the angle in "
                       "degrees?)", option="degrees")
    noise_from_residuals = sigma is None
    sigma = np.ones_like(y) if sigma is None else np.asarray(sigma, dtype=float)
    if sigma.shape != y.shape or not np.all(np.isfinite(sigma)) or np.any(sigma <= 0):
        raise FitError("amplitude uncertainties must be finite and > 0, one per turning point")
    if amplitudes == "fundamental":
        peak = peak_from_fundamental(theta)
        slope = np.where(np.abs(theta) > 0, peak / np.where(theta != 0, theta, 1.0), 1.0)
        theta, y, sigma = peak, peak / scale, sigma * slope
    elif amplitudes != "peak":
        raise ValueError("amplitudes must be 'peak' or 'fundamental'")
    span = float(t[-1] - t[0])
    tau = (t - t[0]) / span
    weights = 1.0 / (sigma * scale)
    models = models_to_fit(forced)
    candidates = _fit_candidates(tau, theta, weights, models, span, scale)
    selection = select_model(candidates, criterion, alpha, n_points=t.size, forced=forced)
    return _reported(t, y, sigma, tau, theta, weights, span, scale, candidates, selection,
                     period, period_sigma, signs, noise_from_residuals,
                     "deg" if degrees else "rad")


def fit_turning_points_of_pendulum(turning, sigma=None, degrees=False, *, criterion="aicc",
                                   model=None, bootstrap=0, rng=None, alpha=LRT_ALPHA):
    """:func:`fit_pendulum` on the used points of ``turning`` (a
    :class:`mcfit.turning.TurningPoints`) with their ``sigma``: peak angles from a table
    of extrema, fundamentals from a waveform's half-cycle fits. ``bootstrap`` and ``rng``
    are not available here."""
    if turning.domain != "time":
        raise FitError("the pendulum correction needs turning points against time, not "
                       "cycle number", option="pendulum")
    used = turning.used
    period = turning.period if math.isfinite(turning.period) and turning.period > 0 else None
    period_sigma = turning.period_sigma if math.isfinite(turning.period_sigma) else None
    table = not math.isfinite(turning.noise_sigma)
    return fit_pendulum(turning.t[used], turning.y[used], sigma, period=period,
                        period_sigma=period_sigma, signs=turning.sign[used], degrees=degrees,
                        amplitudes="peak" if table else "fundamental", criterion=criterion,
                        model=model, alpha=alpha)


def _physical(values, span, scale):
    """Internal (y0, a, b, c) (radians, per span) -> {name: value} in signal units per s."""
    y0, a, b, c = (float(v) for v in values)
    return {"y0": y0 / scale, "a": a * scale / span, "b": b / span, "c": c / (scale * span)}


def _physical_factors(span, scale):
    return np.array([1.0 / scale, scale / span, 1.0 / span, 1.0 / (scale * span)])


def _candidate(model, values, chi_square, success, evaluations, n_points, span, scale,
               problem=None):
    n_params = len(terms_of(model)) + 1
    aicc, bic = information_criteria(chi_square, n_points, n_params)
    correlation = {}
    if problem is not None and len(problem.free) > 2:
        correlation = term_correlations(problem.free, problem.covariance(values[problem.columns]),
                                        problem.free[1:])
    return Candidate(model, n_params, chi_square, aicc, bic, success,
                     _physical(values, span, scale), evaluations, correlation, values)


def _fit_candidates(tau, theta, weights, models, span, scale):
    """Every model fitted with scipy's bounded trust-region-reflective solver, started from
    the best of: a linear estimate of the small-angle law and the best fit one term smaller
    (:func:`mcfit.fit.candidates.nested_candidates`)."""
    def constant():
        w2 = weights**2
        y0 = max(float(np.sum(w2 * theta) / np.sum(w2)), 0.0)
        chi_square = float(np.sum(w2 * (theta - y0) ** 2))
        return _candidate(NONE, np.array([y0, 0.0, 0.0, 0.0]), chi_square, True, 1, tau.size,
                          span, scale)

    def fit_one(model, smaller):
        problem = _Problem(tau, theta, weights, model)
        starts = [_linear_start(tau, theta, weights, model)]
        if smaller:
            best = min(smaller, key=lambda c: c.chi_square).internal.copy()
            rate = max(float(np.sum(best[1:])), 1e-3)
            for k in model:  # off the bound, where the Jacobian of a term may vanish
                best[_COLUMN[k]] = max(best[_COLUMN[k]], 1e-3 * rate)
            starts.append(best)
        values, chi_square, success = min((_bounded(problem, start) for start in starts),
                                          key=lambda r: r[1])
        return _candidate(model, values, chi_square, success, problem.evaluations, tau.size,
                          span, scale, problem)

    return nested_candidates(models, constant, fit_one)


def _upper_bounds(problem):
    return np.array([_LARGEST_ANGLE] + [np.inf] * (len(problem.free) - 1))


def _bounded(problem, start):
    x0 = np.minimum(np.maximum(start[problem.columns], 0.0), 0.999 * _LARGEST_ANGLE)
    try:
        result = optimize.least_squares(problem.residual, x0, jac=problem.jacobian,
                                        bounds=(0.0, _upper_bounds(problem)), method="trf",
                                        x_scale="jac", max_nfev=200 * len(problem.free),
                                        **TOLERANCES)
    except (ValueError, FloatingPointError):
        return problem.values(x0), math.inf, False
    return problem.values(result.x), problem.chi_square(result.x), bool(result.success)


def _linear_start(tau, theta, weights, terms):
    """(y0, a, b, c) from the integrated small-angle law by non-negative least squares."""
    steps = np.diff(tau)
    int_y = np.concatenate([[0.0], np.cumsum(0.5 * (theta[1:] + theta[:-1]) * steps)])
    int_y2 = np.concatenate([[0.0], np.cumsum(0.5 * (theta[1:] ** 2 + theta[:-1] ** 2)
                                               * steps)])
    design = np.column_stack([np.ones_like(tau), -int_y2, -int_y, -tau]) * weights[:, None]
    columns = [0] + [_COLUMN[k] for k in terms]
    solution, _ = optimize.nnls(design[:, columns], theta * weights)
    start = np.zeros(4)
    start[columns] = solution
    rate = max(1.0, -math.log(max(theta[-1] / np.max(theta), 1e-3)))
    for k in terms:
        start[_COLUMN[k]] = max(start[_COLUMN[k]], 1e-3 * rate)
    if start[0] <= 0:
        start[0] = theta[0] if theta[0] > 0 else float(np.max(theta))
    return start


def _reported(t, y, sigma, tau, theta, weights, span, scale, candidates, selection, period,
              period_sigma, signs, noise_from_residuals, angle_unit):
    """The selected model refitted with lmfit, with its errors, Q(t) and warnings."""
    chosen = candidates[selection.model]
    if selection.model == NONE:
        free, internal, covariance = ("y0",), chosen.internal, None
        chi_square, success = chosen.chi_square, True
        if t.size > 1:
            covariance = np.array([[chi_square / (t.size - 1) / float(np.sum(weights**2))]])
    else:
        problem = _Problem(tau, theta, weights, selection.model)
        upper = _upper_bounds(problem)
        solution = solve_reported(problem, lmfit_parameters(
            problem.free, np.maximum(chosen.internal[problem.columns], 0.0),
            np.zeros(upper.size), upper))
        free, internal = problem.free, problem.values(solution.x)
        chi_square, success, covariance = (solution.chi_square, solution.success,
                                           solution.covariance)
        candidates = {**candidates, selection.model: _candidate(
            selection.model, internal, chi_square, success,
            chosen.evaluations + problem.evaluations, t.size, span, scale, problem)}
    dof = t.size - len(free)
    reduced = chi_square / dof if dof > 0 else math.nan
    factors = _physical_factors(span, scale)[[_COLUMN[k] for k in free]]
    errors = physical_errors(free, covariance, factors)
    stderr, correlation = errors.stderr, errors.correlation
    values = _physical(internal, span, scale)
    theta_fit, sensitivity = _amplitude_solution(tau, *internal)
    y_fit = theta_fit / scale
    sigma_out = (sigma * math.sqrt(reduced) if noise_from_residuals and math.isfinite(reduced)
                 else sigma)
    period0, period0_sigma = _small_angle_period(t, theta_fit, signs, period, period_sigma)
    q = q_stderr = q_parts = q_summary = None
    if period0 is not None and selection.model != NONE:
        q, q_stderr, q_parts = _quality(theta_fit, sensitivity, internal, free, covariance,
                                        span, period0, period0_sigma)
        q_summary = summarise_q(q, q_stderr)
    warnings = (fit_warnings(selection, y_fit, values, errors, (y_fit - y) / sigma, success)
                + ([] if noise_from_residuals else misfit_warning(reduced, dof))
                + ([no_decay_warning(float(t[-1] - t[0]), "s", None)]
                   if selection.model == NONE else []))
    omega = 2 * math.pi / period0 if period0 else None
    return PendulumFit(
        status="ok" if success else "error",
        message=None if success else "the fit did not converge",
        model=selection.model, domain="time", criterion=selection.criterion,
        t0=float(t[0]), omega=omega, values=values, stderr=stderr, correlation=correlation,
        regimes={REGIME_NAMES[k]: k in selection.terms for k in TERMS},
        lrt_p_values=selection.p_values, candidates=tuple(candidates.values()),
        n_points=t.size, rms=float(np.sqrt(np.mean((y_fit - y) ** 2))),
        reduced_chi_square=float(reduced), noise_from_residuals=noise_from_residuals,
        selection=selection, t=t, y=y, y_fit=y_fit, sigma=sigma_out, q=q, q_stderr=q_stderr,
        q_parts=q_parts, q_summary=q_summary, warnings=tuple(warnings),
        small_angle_period=period0, small_angle_period_stderr=period0_sigma,
        angle_unit=angle_unit)


def _small_angle_period(t, theta, signs, period, period_sigma):
    """T0 (s) and its standard error: a straight line through the crest times against the
    swing's phase, each half-cycle counting T(theta0)/(2*T0) = K(k)/pi at its mean
    amplitude, with an offset between maxima and minima. Without usable signs, the measured
    period over the mean period ratio."""
    if period is None or not period > 0:
        return None, None
    ratio = period_ratio(theta)
    fallback = (period / float(np.mean(ratio)),
                None if period_sigma is None else period_sigma / float(np.mean(ratio)))
    if signs is None or len(signs) != t.size or np.any(np.asarray(signs) == 0):
        return fallback
    signs = np.asarray(signs, dtype=float)
    steps = np.maximum(np.round(np.diff(t) / (0.5 * period)), 1.0)
    phase = np.concatenate([[0.0], np.cumsum(steps * 0.25 * (ratio[1:] + ratio[:-1]))])
    design = np.column_stack([np.ones_like(t), phase, 0.5 * signs])
    weights = theta / np.max(theta)  # the crest time's error falls as the amplitude grows
    solution, _, rank, _ = np.linalg.lstsq(design * weights[:, None], t * weights, rcond=None)
    dof = t.size - 3
    if rank < 3 or dof <= 0 or not solution[1] > 0:
        return fallback
    residual = (t - design @ solution) * weights
    covariance = np.linalg.pinv((design * weights[:, None]).T @ (design * weights[:, None]))
    error = math.sqrt(max(float(covariance[1, 1] * (residual @ residual) / dof), 0.0))
    return float(solution[1]), error


def _q_of(theta, coefficients, period0):
    """Q = 2*pi*E/(energy lost per cycle) = 2*pi*(1 - cos)/(sin * T(theta0) * rate), and its
    parts (Coulomb, viscous, drag), for physical (c, b, a) in radians per s."""
    h = _rate_terms(theta)
    with np.errstate(divide="ignore", invalid="ignore"):
        stored = 2 * math.pi * (1.0 - np.cos(theta)) / (np.sin(theta) * period_ratio(theta)
                                                         * period0)
        parts = [stored / (coefficient * term) for coefficient, term in zip(coefficients, h)]
        q = stored / np.sum(np.asarray(coefficients)[:, None] * h, axis=0)
    return q, parts


def _quality(theta, sensitivity, internal, free, covariance, span, period0, period0_sigma):
    """Q(t), its standard error by the delta method (the period's error included) and its
    parts, in the keys of :attr:`DecayFit.q_parts`."""
    coefficients = np.array([internal[3], internal[2], internal[1]]) / span  # c, b, a per s
    q, parts = _q_of(theta, coefficients, period0)
    q_parts = {"coulomb": parts[0], "hysteretic": parts[1], "fluid": parts[2]}
    if covariance is None:
        return q, None, q_parts
    step = 1e-6 * np.maximum(theta, 1e-3)
    dq_dtheta = (_q_of(theta + step, coefficients, period0)[0]
                 - _q_of(theta - step, coefficients, period0)[0]) / (2 * step)
    h = _rate_terms(theta)
    rate = coefficients @ h
    direct = {"y0": np.zeros_like(theta), "a": -q * h[2] / rate / span,
              "b": -q * h[1] / rate / span, "c": -q * h[0] / rate / span}
    with np.errstate(invalid="ignore", over="ignore"):
        gradient = np.column_stack([dq_dtheta * sensitivity[:, _COLUMN[k]] + direct[k]
                                    for k in free])
        relative = (period0_sigma or 0.0) / period0
        variance = (np.einsum("ij,jk,ik->i", gradient, covariance, gradient)
                    + (q * relative) ** 2)
        q_stderr = np.sqrt(np.maximum(variance, 0.0))
    return q, np.where(np.isfinite(q_stderr), q_stderr, np.nan), q_parts


def large_swing_warning(values, model, times, amplitudes, sigma, period_drift,
                        period_drift_sigma, b_stderr=None):
    """A warning when the small-angle law was fitted to a record whose period grows with
    amplitude as a pendulum's does, and the geometry of sin(theta) then biases what was
    found: a fluid term reported, or b biased by more than its standard error; else None.

    ``values`` are the fitted (small-angle law) y0, a, b, c and ``amplitudes`` the used
    turning-point amplitudes at ``times`` with standard deviations ``sigma``, in radians;
    ``b_stderr`` is b's standard error; ``period_drift`` is the relative change of
    the period from the smallest to the largest amplitude, with its standard error. The
    pendulum's drift is T(theta_max)/T(theta_min) - 1; when the measured one matches it
    (within 3 standard errors and a third of itself) and is clearly > 0, viscous damping
    decays the swing G1(theta) times as fast as the small-angle law says (1.06 at 1 rad;
    docs/theory.md section 6), which biases the small-angle b by :func:`_viscous_bias`.
    """
    amplitudes = np.asarray(amplitudes, dtype=float)
    kept = np.isfinite(amplitudes) & (amplitudes > 0)
    times, amplitudes = np.asarray(times, dtype=float)[kept], amplitudes[kept]
    sigma = np.broadcast_to(np.asarray(sigma, dtype=float), kept.shape)[kept]
    if amplitudes.size < 2 or not all(map(math.isfinite, (period_drift, period_drift_sigma))):
        return None
    low, high = float(np.min(amplitudes)), float(np.max(amplitudes))
    if not high < _LARGEST_ANGLE:
        return None
    # The record's drift is the slope of a straight line through the periods against the
    # amplitude, times the amplitude range: the pendulum's, measured the same way.
    ratio = period_ratio(amplitudes)
    expected = float(np.polyfit(amplitudes, ratio, 1)[0] * (high - low) / np.mean(ratio))
    if not (expected > 3 * period_drift_sigma
            and abs(period_drift - expected) <= 3 * period_drift_sigma + expected / 3):
        return None
    # With a fluid term kept, that term takes up the geometry instead.
    viscous = "b" in model and "a" not in model
    bias = _viscous_bias(values["b"], times, amplitudes, sigma) if viscous else 0.0
    b_biased = b_stderr is not None and abs(bias) > b_stderr > 0
    if "a" not in model and not b_biased:
        return None
    effects = []
    if b_biased:
        effects.append(f"b about {bias / b_stderr:.2g} standard errors above the viscous "
                       "rate")
    if "a" in model:
        effects.append("a fluid term that may be this geometry alone")
    return (f"the period grows with amplitude as a pendulum's does ({100 * period_drift:+.2g} "
            f"%, {100 * expected:+.2g} % expected for a swing of {high:.3g} rad): the geometry "
            f"of sin(theta) makes viscous damping {geometric_factors(high)[1]:.4g} times as "
            f"fast at the largest swing as the small-angle law says, which gives "
            f"{' and '.join(effects)}. If the signal is a pendulum's angle, fit it with "
            "`pendulum`")


def _viscous_bias(b, times, amplitudes, sigma):
    """How far the small-angle law's b, fitted to these amplitudes, lies above the viscous
    rate b of a pendulum: its decay d(theta0)/dt = -b*theta0*G1(theta0) integrated from the
    first amplitude, then the weighted straight line through its logarithm."""
    from scipy.integrate import solve_ivp

    span = (float(times[0]), float(times[-1]))
    decay = solve_ivp(lambda _, y: -b * y * geometric_factors(y)[1], span, [amplitudes[0]],
                      t_eval=times, rtol=1e-10, atol=1e-14)
    swing = decay.y[0]
    weights = swing / sigma  # polyfit squares them: the weights of ln(y) are (y/sigma)**2
    slope = np.polyfit(times, np.log(swing), 1, w=weights)[0]
    return float(-slope - b)