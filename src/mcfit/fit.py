"""Fit the amplitude law to turning points, choose the damping regimes, estimate Q(t).

The fit works on turning-point amplitudes ``y_k`` at times ``t_k`` (THEORY.md section 5).
Internally time is measured from the first point in units of the record's span and
amplitudes in units of the largest one, so a record in volts or microvolts, seconds or hours
gives the same relative result after the same iterations. The seven candidate models are
ranked with scipy's least-squares solvers directly (:func:`_rank_subset`); the chosen one is
then fitted with lmfit, started there. numpy/scipy/lmfit only, no I/O.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import warnings
from dataclasses import asdict, dataclass, field

import lmfit
import numpy as np
from scipy import optimize

from mcfit import decay
from mcfit.errors import FitError

__all__ = ["MODELS", "TERMS", "REGIME_NAMES", "Candidate", "DecayFit", "fit_decay"]

TERMS = ("a", "b", "c")
# The seven non-empty subsets of {a, b, c}, as letters in the order a, b, c.
MODELS = tuple("".join(s) for n in (1, 2, 3) for s in itertools.combinations(TERMS, n))
REGIME_NAMES = {"a": "fluid", "b": "hysteretic", "c": "coulomb"}
CRITERIA = ("aicc", "bic")
# A kept term must also pass the boundary likelihood-ratio test at this level.
LRT_ALPHA = 0.01
# |correlation| above this between two kept parameters: the record hardly tells them apart.
DEGENERATE_CORRELATION = 0.98
MIN_POINTS = 4
# Column of each parameter in decay.amplitude_jacobian.
_COLUMN = {"y0": 0, "a": 1, "b": 2, "c": 3}
_NAMES = tuple(_COLUMN)
# Amplitudes and times beyond these cannot be squared and multiplied in float64.
_LARGEST = 1e30
_SMALLEST = 1e-30
# Stop when chi-square changes by < 1e-10 relative: 1e-5 of a standard error in the
# parameters, and far enough above chi-square's rounding floor (~1e-15) that the same
# record in other units stops after the same iterations.
_TOLERANCES = {"ftol": 1e-10, "xtol": 1e-10, "gtol": 1e-10}
# Ranking needs chi-square to far below 1 (AICc differences, likelihood ratios): 1e-8 of it
# is ample, and saves MINPACK one or two iterations per candidate. The model reported is
# fitted to _TOLERANCES.
_RANKING_TOLERANCES = {"ftol": 1e-8, "xtol": 1e-8, "gtol": 1e-8}
# Levenberg-Marquardt evaluations allowed for ranking a candidate before the bounded solver
# takes over (see _rank_subset): candidates whose optimum is inside the bounds need 4 to 13.
_RANKING_EVALUATIONS = 25


@dataclass(frozen=True)
class Candidate:
    """One model tried: its terms, fit quality and information criteria."""

    model: str
    n_params: int
    chi_square: float
    aicc: float
    bic: float
    success: bool
    values: dict
    # Evaluations of the law by the solvers (where the optimum is a smaller model's, a term
    # the record does not want at 0, those Levenberg-Marquardt spent finding that out; see
    # _rank_subset).
    evaluations: int

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class DecayFit:
    """Result of :func:`fit_decay`: plain data that serialises to JSON via ``to_dict()``.

    Coefficients are in the units of ``t`` (seconds in the time domain, cycles in the cycle
    domain) and of ``y``; ``t0`` is the time of the first turning point used, where the
    amplitude is ``y0``.
    """

    status: str
    message: str | None
    model: str
    domain: str
    criterion: str
    t0: float
    omega: float | None
    values: dict  # y0, a, b, c (absent regimes are 0)
    stderr: dict  # y0, a, b, c: float, or None for absent regimes / unknown
    correlation: dict  # "a,b" -> correlation of two free parameters
    regimes: dict  # fluid/hysteretic/coulomb -> bool
    lrt_p_values: dict  # kept term -> p-value of the boundary likelihood-ratio test
    candidates: tuple
    n_points: int
    rms: float
    reduced_chi_square: float
    noise_from_residuals: bool
    t: np.ndarray = field(repr=False)
    y: np.ndarray = field(repr=False)
    y_fit: np.ndarray = field(repr=False)
    sigma: np.ndarray = field(repr=False)
    q: np.ndarray | None = field(repr=False)
    q_stderr: np.ndarray | None = field(repr=False)
    q_parts: dict | None = field(repr=False)
    q_summary: dict | None = None
    bootstrap: dict | None = None  # {"n", "failed", "interval_95" (None if n == 0)}
    power_law: dict | None = None
    warnings: tuple = ()
    forced: bool = False  # the model was given (model=...), not chosen by the criterion

    def to_dict(self) -> dict:
        """JSON-ready summary (arrays as lists)."""
        out = {}
        for key, value in self.__dict__.items():
            if isinstance(value, np.ndarray):
                value = value.tolist()
            elif isinstance(value, tuple) and value and isinstance(value[0], Candidate):
                value = [c.to_dict() for c in value]
            elif isinstance(value, dict):
                value = {k: (v.tolist() if isinstance(v, np.ndarray) else v)
                         for k, v in value.items()}
            out[key] = value
        return out

    def amplitude(self, t):
        """The fitted amplitude at times ``t`` (same units as the input)."""
        t = np.asarray(t, dtype=float)
        if self.power_law is not None:
            p = self.power_law
            return decay.power_law_amplitude(np.maximum(t - self.t0, 0), p["y0"], p["k"], p["n"])
        v = self.values
        return decay.amplitude(np.maximum(t - self.t0, 0), v["y0"], v["a"], v["b"], v["c"])


class _Scaled:
    """The record in internal units: time from t0 over the span, amplitude over max|y|
    (a tail in the noise can reach below -max(y))."""

    def __init__(self, t, y, sigma):
        self.t0 = t[0]
        self.time_unit = t[-1] - t[0]
        self.amplitude_unit = float(np.max(np.abs(y)))
        self.t = (t - self.t0) / self.time_unit
        self.y = y / self.amplitude_unit
        self.weights = self.amplitude_unit / sigma
        # The solvers see the residuals over the largest weight. Chi-square's scale, unlike
        # its relative changes, depends on the units (sigma is 1 U when not given), and
        # scipy's gtol is an absolute threshold: a solver started close to its optimum would
        # otherwise stop after a different number of steps in microvolts than in volts.
        self.weight_scale = float(np.max(self.weights))
        self.solver_weights = self.weights / self.weight_scale
        self.design = None  # the reduced least-squares problem of _starting_values

    def with_amplitudes(self, y):
        """The same record in the same internal units, with amplitudes ``y`` (physical)."""
        other = object.__new__(_Scaled)
        other.__dict__.update(self.__dict__)
        other.y = y / self.amplitude_unit
        other.design = None
        return other

    def to_physical(self, values):
        """(y0, a, b, c) in internal units -> physical units."""
        y0, a, b, c = values
        return (y0 * self.amplitude_unit, a / (self.amplitude_unit * self.time_unit),
                b / self.time_unit, c * self.amplitude_unit / self.time_unit)

    def physical_factors(self):
        """Factors f with physical = f * internal for (y0, a, b, c)."""
        return np.array([self.amplitude_unit, 1.0 / (self.amplitude_unit * self.time_unit),
                         1.0 / self.time_unit, self.amplitude_unit / self.time_unit])


def _starting_values(scaled, terms):
    """Linear estimate from the integrated law: y_k = y0 - c*t_k - b*int(y) - a*int(y^2).

    Integrals by the trapezoid rule over the turning points; non-negative least squares
    keeps every coefficient >= 0. Integrating, unlike differencing neighbours, does not
    amplify the amplitude noise.
    """
    t, y, w = scaled.t, scaled.y, scaled.weights
    if scaled.design is None:  # the same for every model: reduced once per record
        int_y = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))])
        int_y2 = np.concatenate([[0.0],
                                 np.cumsum(0.5 * (y[1:] ** 2 + y[:-1] ** 2) * np.diff(t))])
        # With [A | y*w] = Q R, |A x - y*w| differs from |R[:4, :4] x - R[:4, 4]| by a
        # constant: the same solutions, from a 4-row problem (long records fit faster).
        scaled.design = np.linalg.qr(np.column_stack([np.ones_like(t), -int_y2, -int_y, -t,
                                                      y]) * w[:, None], mode="r")[:4]
    design = scaled.design[:, [_COLUMN[k] for k in ("y0",) + tuple(terms)]]
    solution, _ = optimize.nnls(design, scaled.design[:, 4])
    start = {"y0": solution[0], "a": 0.0, "b": 0.0, "c": 0.0}
    start.update(zip(terms, solution[1:]))
    # A zero start sits on the bound where the Jacobian may vanish; nudge it inside.
    rate_scale = max(1.0, -math.log(max(y[-1], 1e-3)))
    for k, floor in zip(TERMS, (1e-3, 1e-3, 1e-3)):
        if k in terms and start[k] <= 0:
            start[k] = floor * rate_scale
    if start["y0"] <= 0:
        start["y0"] = y[0] if y[0] > 0 else 1.0  # 1 is the largest |amplitude|
    return start


@contextlib.contextmanager
def _quiet_lmfit_errorbars():
    """Silence lmfit's square roots of a negative covariance diagonal after a fit.

    lmfit sets each ``Parameter.stderr`` from its own covariance, which rounding makes
    slightly negative when a parameter is nearly unconstrained (Q of 1e6: ``b`` barely
    moves the amplitudes); numpy then warns "invalid value encountered in sqrt". mcfit
    never reads those stderr values (it computes its own covariance), so only warnings
    raised inside lmfit are ignored; one from mcfit's own residuals still shows.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=RuntimeWarning, module=r"lmfit\.")
        yield


def _free_parameters(terms):
    """Names and Jacobian columns of the free parameters of a model."""
    free = ["y0"] + list(terms)
    return free, [_COLUMN[k] for k in free]


class _Problem:
    """One model's least-squares problem in internal units, in its free parameters.

    The solvers ask for the Jacobian where they just evaluated the residuals, so the law is
    evaluated once per parameter vector, and its Jacobian only where asked for (not at
    rejected trial steps). Residuals and Jacobian use the solver weights; chi-square and
    covariance, the weights of the record.
    """

    def __init__(self, scaled, terms):
        self.t, self.y = scaled.t, scaled.y
        self.weights, self.solver_weights = scaled.weights, scaled.solver_weights
        # Chi-square with the record's weights over that with the solver weights.
        self.chi_square_scale = scaled.weight_scale**2
        self.free, self.columns = _free_parameters(terms)
        self._key = self._law = self._jacobian = None

    def values(self, free_values):
        """(y0, a, b, c) with the absent terms 0."""
        values = np.zeros(4)
        values[self.columns] = free_values
        return values

    def law(self, free_values):
        values = [0.0, 0.0, 0.0, 0.0]
        for column, value in zip(self.columns, free_values):
            values[column] = float(value)
        key = tuple(values)
        if key != self._key:
            self._key, self._law = key, decay.amplitude_terms(self.t, *key)
            self._jacobian = None
        return self._law

    def law_jacobian(self, free_values):
        """dy/d(y0, a, b, c), unweighted (computed once per parameter vector)."""
        law = self.law(free_values)
        if self._jacobian is None:
            self._jacobian = law.jacobian()
        return self._jacobian

    def residual(self, free_values):
        return (self.law(free_values).amplitude() - self.y) * self.solver_weights

    def jacobian(self, free_values):
        return self.law_jacobian(free_values)[:, self.columns] * self.solver_weights[:, None]

    def chi_square(self, free_values):
        return float(np.sum(((self.law(free_values).amplitude() - self.y) * self.weights) ** 2))

    def covariance(self, free_values):
        """Unscaled covariance (J^T J)^-1 of the free parameters (times chi2/dof later)."""
        jacobian = self.law_jacobian(free_values)[:, self.columns] * self.weights[:, None]
        try:
            return np.linalg.pinv(jacobian.T @ jacobian)
        except np.linalg.LinAlgError:
            return None

    def gradient(self, free_values):
        """Cosines between the residuals and the Jacobian column of each of y0, a, b, c
        (free or not): the chi-square gradient, normalized as MINPACK's gtol test does."""
        w = self.solver_weights
        jacobian = self.law_jacobian(free_values) * w[:, None]
        residual = (self.law(free_values).amplitude() - self.y) * w
        norms = np.sqrt(np.sum(jacobian**2, axis=0)) * math.sqrt(float(residual @ residual))
        return (jacobian.T @ residual) / np.where(norms > 0, norms, 1.0)


def _bounded_least_squares(scaled, terms, start):
    """scipy's trust-region-reflective fit with the bounds [0, inf): the problem and settings
    of :func:`_fit_subset` (analytic Jacobian, x_scale="jac", the same tolerances and
    evaluation limit) without lmfit. Returns (values, chi_square, success, evaluations)."""
    problem = _Problem(scaled, terms)
    result = optimize.least_squares(problem.residual, start[problem.columns],
                                    jac=problem.jacobian, bounds=(0.0, np.inf), method="trf",
                                    x_scale="jac", max_nfev=4000 * (len(problem.free) + 1),
                                    **_TOLERANCES)
    return (problem.values(result.x), problem.chi_square(result.x), bool(result.success),
            int(result.nfev))


class _LeftTheBounds(Exception):
    """Levenberg-Marquardt tried a parameter < 0, where the law is not defined."""


def _levenberg_marquardt(problem, start):
    """MINPACK's Levenberg-Marquardt (through scipy) on ``problem`` from ``start``, in the
    same coordinates as the bounded solver, abandoned if it tries a parameter < 0.

    Returns (free values or None, lowest chi-square seen (record weights), evaluations,
    left the bounds). The free values are given only if a MINPACK convergence test passed
    inside the bounds.
    """
    seen = {"evaluations": 0, "lowest": math.inf}
    scale = problem.chi_square_scale

    def residual(x):
        seen["evaluations"] += 1
        if min(x) < 0:
            raise _LeftTheBounds
        r = problem.residual(x)
        seen["lowest"] = min(seen["lowest"], float(r @ r) * scale)
        return r

    def jacobian(x):
        if min(x) < 0:
            raise _LeftTheBounds
        return problem.jacobian(x)

    try:
        with warnings.catch_warnings():
            # leastsq's own covariance (unused here) may overflow far from a sensible optimum.
            warnings.filterwarnings("ignore", category=RuntimeWarning,
                                    module=r"scipy\.optimize\._minpack_py")
            x, _, _, _, status = optimize.leastsq(
                residual, start[problem.columns], Dfun=jacobian, full_output=True,
                maxfev=_RANKING_EVALUATIONS, **_RANKING_TOLERANCES)
    except _LeftTheBounds:
        return None, seen["lowest"], seen["evaluations"], True
    converged = status in (1, 2, 3, 4) and min(x) > 0
    return (x if converged else None), seen["lowest"], seen["evaluations"], False


def _rank_subset(scaled, terms, ranked):
    """Fit one candidate well enough to rank and report it.

    Returns (values, chi_square, success, evaluations, gradient) in internal units, with
    ``gradient`` that of chi-square in y0, a, b, c at the solution (up to a factor > 0).
    ``ranked`` holds these for the models fitted so far, smaller ones first.

    The bounded trust-region solver spends about 0.1 ms of its own per iteration, far more
    than the law costs; MINPACK's Levenberg-Marquardt almost nothing. Started where the
    bounded solver starts and in the same coordinates, it heads for the same optimum while
    the parameters stay > 0, and most candidates converge so. A candidate whose optimum
    lies on the bound 0 (a term the record does not want) makes it step below 0; that
    optimum is then a smaller model's, when every term at 0 there has a chi-square gradient
    pointing outward (the Kuhn-Tucker conditions) and nothing lower was met on the way.
    Otherwise the bounded solver runs as it always did, from the linear estimate.
    """
    smaller = [ranked[m] for m in ranked if len(m) == len(terms) - 1 and set(m) <= set(terms)]
    best_smaller = min(smaller, key=lambda fit: fit[1], default=None)
    problem = _Problem(scaled, terms)
    start = _starting_values(scaled, terms)
    start = np.array([start[k] for k in _NAMES])
    free_values, lowest, evaluations, left = _levenberg_marquardt(problem, start)
    if free_values is not None:
        chi_square = problem.chi_square(free_values)
        if best_smaller is None or chi_square <= best_smaller[1]:
            return (problem.values(free_values), chi_square, True, evaluations,
                    problem.gradient(free_values))
    elif left and best_smaller is not None and lowest >= best_smaller[1]:
        values, chi_square, ok, _, gradient = best_smaller
        at_bound = [_COLUMN[k] for k in terms if values[_COLUMN[k]] == 0]
        if all(gradient[column] >= 0 for column in at_bound):
            return values.copy(), chi_square, ok, evaluations, gradient
    values, chi_square, ok, more = _bounded_least_squares(scaled, terms, start)
    evaluations += more
    if best_smaller is not None and best_smaller[1] < chi_square:  # a lower point to go on from
        values, chi_square, ok, more = _bounded_least_squares(scaled, terms, best_smaller[0])
        evaluations += more
    return values, chi_square, ok, evaluations, problem.gradient(values[problem.columns])


def _gauss_newton_refined(scaled, terms, values):
    """``values`` (a ranking solution) after up to two Gauss-Newton steps, and the number of
    evaluations of the law they took.

    Along a direction the record hardly determines (correlated parameters, e.g. a, b and c
    together), chi-square changes by less than its rounding error over a range of about
    1e-9 of the values: a solver that compares chi-square values stops anywhere in it,
    where its path (the record's units, say) leads. A Gauss-Newton step solves for the
    optimum instead, to about eps times the condition number. A step is kept only inside
    the bounds and if chi-square does not rise beyond rounding.
    """
    problem = _Problem(scaled, terms)
    x = values[problem.columns]
    chi_square = problem.chi_square(x)
    evaluations = 0
    for _ in range(2):
        step = np.linalg.lstsq(problem.jacobian(x), -problem.residual(x), rcond=None)[0]
        trial = x + step
        if not np.all(trial > 0):
            break
        trial_chi_square = problem.chi_square(trial)
        evaluations += 1
        if not trial_chi_square <= chi_square * (1.0 + 1e-12):
            break
        x, chi_square = trial, trial_chi_square
    return problem.values(x), evaluations


def _fit_subset(scaled, terms, start):
    """lmfit fit of one model in internal units from ``start`` (values of y0, a, b, c);
    returns (values, covar, free, chi2, ok, evaluations)."""
    start = dict(zip(_NAMES, start))
    problem = _Problem(scaled, terms)
    free = problem.free
    params = lmfit.Parameters()
    for k in free:  # absent terms are 0: no need for lmfit to carry them
        params.add(k, value=start[k], min=0.0)

    def residual(p):
        return problem.residual([p[k].value for k in free])

    def jacobian(p):
        return problem.jacobian([p[k].value for k in free])

    minimizer = lmfit.Minimizer(residual, params)
    with _quiet_lmfit_errorbars():
        result = minimizer.minimize(method="least_squares", jac=jacobian, x_scale="jac",
                                    **_TOLERANCES)
    free_values = [result.params[k].value for k in free]
    return (problem.values(free_values), problem.covariance(free_values), free,
            problem.chi_square(free_values), bool(result.success), int(result.nfev))


def _candidate(scaled, name, values, chi_square, ok, evaluations, n_points):
    aicc, bic = _information_criteria(chi_square, n_points, len(name) + 1)
    physical = dict(zip(_NAMES, map(float, scaled.to_physical(values))))
    return Candidate(name, len(name) + 1, chi_square, aicc, bic, ok, physical, evaluations)


def _information_criteria(chi_square, n_points, n_params):
    """AICc and BIC of a Gaussian likelihood whose overall noise scale is estimated."""
    log_likelihood_term = n_points * math.log(max(chi_square, 1e-300) / n_points)
    aic = log_likelihood_term + 2 * n_params
    denominator = n_points - n_params - 1
    aicc = aic + (2 * n_params * (n_params + 1) / denominator if denominator > 0 else math.inf)
    bic = log_likelihood_term + n_params * math.log(n_points)
    return aicc, bic


def _boundary_lrt_p_value(chi_square_without, chi_square_with, n_points, terms=1,
                          correlation=0.0):
    """p-value of adding ``terms`` (1 or 2) coefficients >= 0.

    Each sits on its bound under the null, so the statistic follows a chi-bar-square
    mixture: 0.5*chi2(0) + 0.5*chi2(1) for one term; for two whose estimates have
    ``correlation`` rho, w*chi2(0) + 0.5*chi2(1) + (0.5 - w)*chi2(2) with
    0.5 - w = 1/4 + asin(rho)/(2*pi), the chance that both estimates are > 0 (Kudo 1963).
    """
    statistic = n_points * math.log(max(chi_square_without, 1e-300) / max(chi_square_with, 1e-300))
    if statistic <= 0:
        return 1.0
    # chi2(1).sf(x) = erfc(sqrt(x/2)) and chi2(2).sf(x) = exp(-x/2), without scipy.stats'
    # per-call cost.
    one = math.erfc(math.sqrt(0.5 * statistic))
    if terms == 1:
        return 0.5 * one
    if terms == 2:
        rho = min(1.0, max(-1.0, correlation)) if math.isfinite(correlation) else 0.0
        both = 0.25 + math.asin(rho) / (2.0 * math.pi)
        return 0.5 * one + both * math.exp(-0.5 * statistic)
    raise ValueError("terms must be 1 or 2")


def _correlations(scaled, model, values):
    """Correlations of the estimates of ``model``'s terms at ``values`` (y0, a, b, c;
    internal units), from the pseudo-inverse of J'J, as {(first, second): rho}; 0 where a
    variance is 0 or the inversion fails."""
    problem = _Problem(scaled, model)
    covariance = problem.covariance(values[problem.columns])
    pairs = {}
    for first, second in itertools.combinations(model, 2):
        i, j = problem.free.index(first), problem.free.index(second)
        denominator = (math.sqrt(max(covariance[i, i] * covariance[j, j], 0.0))
                       if covariance is not None else 0.0)
        pairs[first, second] = (float(covariance[i, j] / denominator) if denominator > 0
                                else 0.0)
    return pairs


def _lag_one_autocorrelation(residuals):
    r = residuals - residuals.mean()
    denominator = float(np.dot(r, r))
    return float(np.dot(r[1:], r[:-1]) / denominator) if denominator > 0 else 0.0


def _q_with_stderr(t_scaled, values, covar_physical, free, scaled, omega):
    """Q at each turning point and its standard error by the delta method."""
    y0, a, b, c = values
    t_phys = t_scaled * scaled.time_unit
    law = decay.amplitude_terms(t_phys, y0, a, b, c)
    y = law.amplitude()
    q = decay.quality_factor(y, omega, a, b, c)
    if covar_physical is None:
        return q, None
    rate = decay.decay_rate(y, a, b, c)
    with np.errstate(divide="ignore", invalid="ignore"):
        denominator = 2.0 * rate**2
        dq_dy = omega * (c - a * y**2) / denominator
        direct = {"a": -omega * y**3 / denominator, "b": -omega * y**2 / denominator,
                  "c": -omega * y / denominator, "y0": np.zeros_like(y)}
        jac_y = law.jacobian()
        gradient = np.column_stack([dq_dy * jac_y[:, _COLUMN[k]] + direct[k] for k in free])
        variance = np.einsum("ij,jk,ik->i", gradient, covar_physical, gradient)
        q_stderr = np.sqrt(np.maximum(variance, 0.0))
    return q, np.where(np.isfinite(q_stderr), q_stderr, np.nan)


def fit_decay(t, y, sigma=None, *, period=None, domain="time", criterion="aicc", model=None,
              bootstrap=0, rng=None) -> DecayFit:
    """Fit dy/dt = -c - b*y - a*y**2 to turning-point amplitudes and choose the regimes.

    Parameters
    ----------
    t : array_like, shape (n,)
        Turning-point times (s) or cycle numbers (``domain="cycle"``), increasing.
    y : array_like, shape (n,)
        Turning-point amplitudes about equilibrium (signal units U). The last ones may be
        <= 0 where noise dominates (signed projections onto the crest phase scatter about
        a small envelope); the largest must be > 0. The model itself stays >= 0.
    sigma : array_like, shape (n,), optional
        Standard deviation of each amplitude. Only relative weights are taken from it: the
        overall noise scale is always estimated from the residuals as well.
    period : float, optional
        Oscillation period in s; needed for Q in the time domain. In the cycle domain the
        angular frequency is 2*pi per cycle.
    domain : {"time", "cycle"}
    criterion : {"aicc", "bic"}
        Information criterion that picks the model among the seven subsets of {a, b, c}.
    model : str, optional
        Force a model: letters from "abc" (e.g. "ab"), or "power" for dy/dt = -k*y**n.
    bootstrap : int
        Number of residual-bootstrap refits for resampled 95 % intervals (0: none).
    rng : numpy.random.Generator, optional
        Random source for the bootstrap.

    Returns
    -------
    DecayFit
        ``status == "ok"``, or ``"error"`` with ``message`` when the fit itself failed.
        Invalid input (too few points, no amplitude > 0, values beyond double precision)
        raises :class:`FitError`.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.shape != y.shape or t.ndim != 1:
        raise FitError("turning-point times and amplitudes must be 1-D arrays of equal length")
    if t.size < MIN_POINTS:
        raise FitError(f"only {t.size} turning points; at least {MIN_POINTS} are needed to fit "
                       "the decay. Use a longer record.")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise FitError("turning points contain NaN or inf; remove them before fitting")
    if np.any(np.diff(t) <= 0):
        raise FitError("turning-point times must be strictly increasing")
    if not np.max(y) > 0:
        raise FitError("no turning-point amplitude is > 0 (amplitudes are measured about the "
                       "equilibrium): there is no decay to fit")
    # Squares and products of the coefficients must stay inside double precision. Amplitudes
    # near 0 (or below: noise in the tail) are fine; the largest sets the scale.
    largest = float(np.max(np.abs(y)))
    if not _SMALLEST <= largest <= _LARGEST:
        raise FitError(f"turning-point amplitudes reach {largest:.3g}, beyond what mcfit fits "
                       "in double precision (1e-30 to 1e30); rescale the signal.")
    largest, span = float(np.max(np.abs(t[[0, -1]]))), float(t[-1] - t[0])
    if largest > _LARGEST or span < _SMALLEST:
        raise FitError(f"turning-point times span {span:.3g} to {largest:.3g}, beyond what "
                       "mcfit fits in double precision (1e-30 to 1e30); rescale the time.")
    if criterion not in CRITERIA:
        raise FitError(f"unknown criterion {criterion!r}; use one of {', '.join(CRITERIA)}")
    if domain not in ("time", "cycle"):
        raise FitError(f"unknown domain {domain!r}; use time or cycle")
    noise_from_residuals = sigma is None
    sigma = np.ones_like(y) if sigma is None else np.asarray(sigma, dtype=float)
    if sigma.shape != y.shape or not np.all(np.isfinite(sigma)) or np.any(sigma <= 0):
        raise FitError("amplitude uncertainties must be finite and > 0, one per turning point")
    omega = 2 * math.pi if domain == "cycle" else (2 * math.pi / period if period else None)
    rng = rng if rng is not None else np.random.default_rng()

    scaled = _Scaled(t, y, sigma)
    if model == "power":
        return _fit_power_law(scaled, t, y, sigma, omega, domain, criterion, noise_from_residuals)
    if model is not None:
        model = "".join(k for k in TERMS if k in model.lower())
        if not model:
            raise FitError("--model takes letters from 'abc' (e.g. 'ab') or 'power'")

    n = t.size
    fits = {}
    candidates = {}
    # A forced model needs only itself and the models one term smaller (for the LRT).
    tried = MODELS if model is None else tuple(
        m for m in MODELS if m == model or (len(m) == len(model) - 1 and set(m) <= set(model)))
    ranked = {}
    for name in tried:  # smaller models first: _rank_subset starts from them
        ranked[name] = _rank_subset(scaled, name, ranked)
        values, chi_square, ok, evaluations, _ = ranked[name]
        fits[name] = (values, None, _free_parameters(name)[0], chi_square, ok)
        candidates[name] = _candidate(scaled, name, values, chi_square, ok, evaluations, n)

    warnings = []
    by_score = {c.model: getattr(c, criterion) for c in candidates.values()}
    if model is None:
        chosen = min(by_score, key=by_score.get)
        # The kept terms must also survive the boundary likelihood-ratio test against every
        # smaller model, alone and together: two terms that mimic a third between them
        # (a*y**2 + c against b*y) each pass a test of one term, but not the joint test.
        while len(chosen) > 1:
            p_values = {}
            rhos = (_correlations(scaled, chosen, fits[chosen][0]) if len(chosen) == 3
                    else {})
            for smaller in MODELS:
                if len(smaller) < len(chosen) and set(smaller) <= set(chosen):
                    dropped = [k for k in chosen if k not in smaller]
                    rho = rhos[tuple(dropped)] if len(dropped) == 2 else 0.0
                    p_values[smaller] = _boundary_lrt_p_value(
                        fits[smaller][3], fits[chosen][3], n, len(dropped), rho)
            weakest = max(p_values, key=lambda m: (p_values[m], -by_score[m]))
            if p_values[weakest] < LRT_ALPHA:
                break
            dropped = [k for k in chosen if k not in weakest]
            names = " and ".join(REGIME_NAMES[k] for k in dropped)
            warnings.append(f"{names} term{'s' if len(dropped) > 1 else ''} dropped: "
                            f"{criterion} kept {'them' if len(dropped) > 1 else 'it'} but the "
                            f"likelihood-ratio test does not support "
                            f"{'them' if len(dropped) > 1 else 'it'} "
                            f"(p = {p_values[weakest]:.3g})")
            chosen = weakest
    else:
        chosen = model
    # The reported fit is lmfit's, started where the ranking stopped (refined): it
    # converges at once.
    start, refining = _gauss_newton_refined(scaled, chosen, fits[chosen][0])
    values, covar, free, chi_square, ok, evaluations = _fit_subset(scaled, chosen, start)
    fits[chosen] = (values, covar, free, chi_square, ok)
    candidates[chosen] = _candidate(scaled, chosen, values, chi_square, ok,
                                    candidates[chosen].evaluations + refining + evaluations, n)
    # A single term has no smaller model in the family to be tested against.
    p_values = ({k: _boundary_lrt_p_value(fits[chosen.replace(k, "")][3], chi_square, n)
                 for k in chosen} if len(chosen) > 1 else {})

    dof = n - len(free)
    reduced = chi_square / dof if dof > 0 else math.nan
    factors = scaled.physical_factors()
    index = [("y0", "a", "b", "c").index(k) for k in free]
    covar_physical = None
    stderr = {"y0": None, "a": None, "b": None, "c": None}
    correlation = {}
    if covar is not None and dof > 0:
        covar_physical = covar * reduced * np.outer(factors[index], factors[index])
        errors = np.sqrt(np.maximum(np.diag(covar_physical), 0.0))
        stderr.update({k: float(e) for k, e in zip(free, errors)})
        for (i, ki), (j, kj) in itertools.combinations(enumerate(free), 2):
            if errors[i] > 0 and errors[j] > 0:
                correlation[f"{ki},{kj}"] = float(covar_physical[i, j] / (errors[i] * errors[j]))
    physical_values = scaled.to_physical(values)
    values_dict = dict(zip(("y0", "a", "b", "c"), map(float, physical_values)))

    y_fit = decay.amplitude(t - t[0], *physical_values)
    weighted_residuals = (y_fit - y) / sigma
    if noise_from_residuals and math.isfinite(reduced):
        sigma = sigma * math.sqrt(reduced)  # the amplitude noise the residuals show
    rms = float(np.sqrt(np.mean((y_fit - y) ** 2)))
    warnings += _diagnose(chosen, values_dict, stderr, correlation, weighted_residuals, ok)

    q = q_stderr = q_parts = q_summary = None
    if omega is not None:
        q, q_stderr = _q_with_stderr(scaled.t, physical_values, covar_physical, free, scaled, omega)
        parts = decay.quality_parts(y_fit, omega, *physical_values[1:])
        q_parts = {"coulomb": parts[0], "hysteretic": parts[1], "fluid": parts[2]}
        q_summary = _summarise_q(q)

    boot = (_bootstrap(scaled, chosen, values, y_fit, y, sigma, omega, bootstrap, rng)
            if bootstrap else None)
    if boot is not None and boot["failed"]:
        warnings.append(f"{boot['failed']} of {bootstrap} bootstrap refits did not converge "
                        "and are left out: the intervals may be too narrow"
                        if boot["n"] else
                        f"no bootstrap refit of {bootstrap} converged: no intervals")
    return DecayFit(
        status="ok" if ok else "error", message=None if ok else "the fit did not converge",
        model=chosen, domain=domain, criterion=criterion, t0=float(t[0]), omega=omega,
        values=values_dict, stderr=stderr, correlation=correlation,
        regimes={REGIME_NAMES[k]: k in chosen for k in TERMS}, lrt_p_values=p_values,
        candidates=tuple(candidates.values()), n_points=n, rms=rms,
        reduced_chi_square=float(reduced),
        noise_from_residuals=noise_from_residuals, t=t, y=y, y_fit=y_fit, sigma=sigma,
        q=q, q_stderr=q_stderr, q_parts=q_parts, q_summary=q_summary, bootstrap=boot,
        warnings=tuple(warnings), forced=model is not None)


def _diagnose(chosen, values, stderr, correlation, weighted_residuals, converged):
    """Warnings a careful reader needs next to the numbers."""
    warnings = []
    if not converged:
        warnings.append("the least-squares fit did not report convergence")
    n = weighted_residuals.size
    r1 = _lag_one_autocorrelation(weighted_residuals)
    if r1 * math.sqrt(n) > 3.0:
        warnings.append(f"residuals are correlated (lag-1 autocorrelation {r1:.2f}): the "
                        "standard errors understate the uncertainty, or the model misses a "
                        "systematic effect")
    for k in chosen:
        error = stderr.get(k)
        if values[k] == 0.0 or (error is not None and values[k] < 1e-8 * max(error, 1e-300)):
            warnings.append(f"{REGIME_NAMES[k]} coefficient {k} sits on its bound 0")
    for pair, r in correlation.items():
        if abs(r) > DEGENERATE_CORRELATION and "y0" not in pair:
            warnings.append(f"parameters {pair.replace(',', ' and ')} are nearly degenerate "
                            f"(correlation {r:+.3f}): the record hardly separates them")
    return warnings


def _summarise_q(q):
    finite = q[np.isfinite(q)]
    if finite.size == 0:
        return None
    return {"initial": float(q[0]), "final": float(q[-1]), "min": float(finite.min()),
            "max": float(finite.max())}


def _bootstrap(scaled, chosen, fitted, y_fit, y, sigma, omega, count, rng):
    """Residual bootstrap: refit the chosen model to y_fit + resampled weighted residuals.

    Each refit starts from the fit (``fitted``: y0, a, b, c in internal units), in the same
    internal units. A draw may hold amplitudes <= 0 as the data may; the model stays >= 0.
    A refit that does not converge is left out and counted (``failed``).
    """
    standardized = (y - y_fit) / sigma
    samples = []
    failed = 0
    for _ in range(count):
        draw = y_fit + sigma * rng.choice(standardized, size=y.size, replace=True)
        refit = _fit_subset(scaled.with_amplitudes(draw), chosen, fitted)
        if not refit[4]:
            failed += 1
            continue
        values = scaled.to_physical(refit[0])
        row = list(values)
        if omega is not None:
            t_end = (scaled.t[-1]) * scaled.time_unit
            y_ends = decay.amplitude(np.array([0.0, t_end]), *values)
            row += list(decay.quality_factor(y_ends, omega, *values[1:]))
        samples.append(row)
    if not samples:
        return {"n": 0, "failed": failed, "interval_95": None}
    samples = np.array(samples)
    names = ["y0", "a", "b", "c"] + (["q_initial", "q_final"] if omega is not None else [])
    low, high = np.percentile(samples, [2.5, 97.5], axis=0)
    return {"n": int(samples.shape[0]), "failed": failed,
            "interval_95": {k: [float(lo), float(hi)] for k, lo, hi in zip(names, low, high)}}


def _fit_power_law(scaled, t, y, sigma, omega, domain, criterion, noise_from_residuals):
    """Fit dy/dt = -k*y**n (Handbook Eq. 20.51) in internal units."""
    ts, ys, w = scaled.t, scaled.y, scaled.weights
    first = ys[0] if ys[0] > 0 else 1.0  # 1 is the largest |amplitude|
    # The tail may be <= 0 (noise): then start from a decay to 1e-6 of the first amplitude.
    start_b = -math.log(max(ys[-1] / first, 1e-6)) / max(ts[-1], 1e-12)
    params = lmfit.Parameters()
    params.add("y0", value=first, min=0.0)
    params.add("k", value=max(start_b, 1e-3), min=0.0)
    params.add("n", value=1.0, min=-2.0, max=6.0)

    def residual(p):
        v = p.valuesdict()
        return (decay.power_law_amplitude(ts, v["y0"], v["k"], v["n"]) - ys) * w

    def jacobian(p):
        v = p.valuesdict()
        return decay.power_law_jacobian(ts, v["y0"], v["k"], v["n"]) * w[:, None]

    with _quiet_lmfit_errorbars():
        result = lmfit.Minimizer(residual, params).minimize(
            method="least_squares", jac=jacobian, x_scale="jac", **_TOLERANCES)
    v = result.params.valuesdict()
    n_exp = v["n"]
    # Back to physical units: y = A*y', t = T*t'  =>  k = k' * A**(1-n) / T.
    y0 = v["y0"] * scaled.amplitude_unit
    k = v["k"] * scaled.amplitude_unit ** (1 - n_exp) / scaled.time_unit
    chi_square = float(np.sum(residual(result.params) ** 2))
    n_points = t.size
    dof = n_points - 3
    reduced = chi_square / dof if dof > 0 else math.nan
    jac = jacobian(result.params)
    stderr_internal = np.sqrt(np.maximum(np.diag(np.linalg.pinv(jac.T @ jac)) * reduced, 0))
    y_fit = decay.power_law_amplitude(t - t[0], y0, k, n_exp)
    q = q_summary = None
    if omega is not None:
        with np.errstate(divide="ignore"):
            q = omega / (2 * k * y_fit ** (n_exp - 1))
        q_summary = _summarise_q(q)
    aicc, bic = _information_criteria(chi_square, n_points, 3)
    # Standard errors: y0 scales with A, n is dimensionless; k's unit depends on n, so its
    # relative error carries over.
    power = {"y0": y0, "k": k, "n": n_exp,
             "y0_stderr": float(stderr_internal[0] * scaled.amplitude_unit),
             "k_stderr": float(stderr_internal[1] / v["k"] * k) if v["k"] > 0 else None,
             "n_stderr": float(stderr_internal[2])}
    candidate = Candidate("power", 3, chi_square, aicc, bic, bool(result.success),
                          {"y0": y0, "k": k, "n": n_exp}, int(result.nfev))
    return DecayFit(
        status="ok" if result.success else "error",
        message=None if result.success else "the fit did not converge", model="power",
        domain=domain, criterion=criterion, t0=float(t[0]), omega=omega,
        values={"y0": y0, "a": 0.0, "b": 0.0, "c": 0.0},
        stderr={"y0": power["y0_stderr"], "a": None, "b": None, "c": None}, correlation={},
        regimes={"fluid": False, "hysteretic": False, "coulomb": False}, lrt_p_values={},
        candidates=(candidate,), n_points=n_points,
        rms=float(np.sqrt(np.mean((y_fit - y) ** 2))), reduced_chi_square=float(reduced),
        noise_from_residuals=noise_from_residuals, t=t, y=y, y_fit=y_fit, sigma=sigma, q=q,
        q_stderr=None, q_parts=None, q_summary=q_summary, power_law=power, forced=True)
