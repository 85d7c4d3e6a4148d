"""Fit every candidate model to a record's turning points, and the reported one with lmfit.

One solver path. Each candidate is ranked with MINPACK's Levenberg-Marquardt while its
parameters stay > 0 (it costs almost nothing per iteration); where the optimum lies on a
bound, scipy's bounded trust-region-reflective solver takes over (:func:`_rank`). The model
reported is refitted with lmfit, which drives the same trust-region-reflective solver on the
same residuals and Jacobian (:func:`fit_reported`, by :mod:`mcfit.fit.reported`). The empty model, constant amplitude, is
a weighted mean.
"""

from __future__ import annotations

import math
import threading
import warnings
from dataclasses import dataclass, field

import lmfit
import numpy as np
from scipy import optimize

from mcfit.fit.models import NONE, terms_of
from mcfit.fit.problem import Problem, ScaledRecord
from mcfit.fit.reported import TOLERANCES, solve_reported
from mcfit.fit.uncertainty import term_correlations

__all__ = ["Candidate", "ReportedFit", "fit_candidates", "nested_candidates", "fit_reported",
           "make_candidate",
           "information_criteria"]

# Ranking needs chi-square to far below 1 (AICc differences, likelihood ratios): 1e-8 of it
# is ample, and saves MINPACK one or two iterations per candidate.
_RANKING_TOLERANCES = {"ftol": 1e-8, "xtol": 1e-8, "gtol": 1e-8}
# Levenberg-Marquardt evaluations allowed for ranking a candidate before the bounded solver
# takes over: candidates whose optimum is inside the bounds need 4 to 13.
_RANKING_EVALUATIONS = 25


@dataclass(frozen=True)
class Candidate:
    """One model fitted to the record: its fit quality, criteria and parameters.

    ``values`` are physical (y0, a, b, c; absent terms 0); ``correlation`` holds the
    correlations of the estimates of its terms, ``{"a,b": rho}``, used by the joint
    likelihood-ratio tests.
    """

    model: str
    n_params: int
    chi_square: float
    aicc: float
    bic: float
    success: bool
    values: dict
    evaluations: int
    correlation: dict = field(default_factory=dict)
    internal: np.ndarray = field(default=None, repr=False, compare=False)
    # The chi-square gradient at ``internal`` where the ranking computed it (see _gradient).
    gradient: np.ndarray = field(default=None, repr=False, compare=False)
    # Its chi-square estimated from another model's fit, not fitted (it cannot change the
    # choice; mcfit.fit.waveform).
    estimated: bool = False

    @property
    def terms(self) -> str:
        return terms_of(self.model)

    def score(self, criterion: str) -> float:
        return getattr(self, criterion)


@dataclass(frozen=True)
class ReportedFit:
    """lmfit's fit of the reported model, in internal units: the values of y0, a, b, c,
    the free parameters' covariance (None if unknown), chi-square with the record's
    weights, and the :class:`Problem` fitted (its law at the values is at hand)."""

    values: np.ndarray
    free: tuple
    covariance: np.ndarray | None
    chi_square: float
    success: bool
    evaluations: int
    problem: Problem = field(default=None, repr=False, compare=False)


def information_criteria(chi_square, n_points, n_params):
    """AICc and BIC of a Gaussian likelihood whose overall noise scale is estimated."""
    log_likelihood_term = n_points * math.log(max(chi_square, 1e-300) / n_points)
    aic = log_likelihood_term + 2 * n_params
    denominator = n_points - n_params - 1
    aicc = aic + (2 * n_params * (n_params + 1) / denominator if denominator > 0 else math.inf)
    bic = log_likelihood_term + n_params * math.log(n_points)
    return aicc, bic


def nested_candidates(models, constant, fit_one) -> dict:
    """``{model: Candidate}`` for ``models`` (names from :data:`mcfit.fit.models.MODELS`,
    smaller ones first): ``constant()`` for the empty model, ``fit_one(model, smaller)``
    for the others, ``smaller`` the candidates fitted one term smaller (to start from, so a
    larger model never fits worse than a nested smaller one). Every law ranks so."""
    fitted = {}
    for model in models:
        if model == NONE:
            fitted[model] = constant()
            continue
        smaller = [fitted[m] for m in fitted if len(fitted[m].terms) == len(model) - 1
                   and set(fitted[m].terms) <= set(model)]
        fitted[model] = fit_one(model, smaller)
    return fitted


def fit_candidates(scaled: ScaledRecord, models) -> dict:
    """The averaged law's candidates (:func:`nested_candidates`, each by :func:`_rank`)."""
    return nested_candidates(models, lambda: _constant_amplitude(scaled),
                             lambda model, smaller: _rank(scaled, model, smaller))


def make_candidate(scaled, model, values, chi_square, success, evaluations, gradient=None,
                   problem=None):
    """A :class:`Candidate` from its internal values (y0, a, b, c) and chi-square
    (``problem``: the model's :class:`Problem`, whose law at ``values`` may be at hand)."""
    n_params = len(terms_of(model)) + 1
    aicc, bic = information_criteria(chi_square, scaled.t.size, n_params)
    return Candidate(model, n_params, chi_square, aicc, bic, success,
                     scaled.to_physical(values), evaluations,
                     _correlations(scaled, terms_of(model), values, problem), values, gradient)


def _constant_amplitude(scaled):
    """The empty model: the weighted mean amplitude (>= 0, as the law's)."""
    w2 = scaled.weights**2
    y0 = max(float(np.sum(w2 * scaled.y) / np.sum(w2)), 0.0)
    chi_square = float(np.sum(w2 * (scaled.y - y0) ** 2))
    return make_candidate(scaled, NONE, np.array([y0, 0.0, 0.0, 0.0]), chi_square, True, 1)


def _correlations(scaled, terms, values, problem=None):
    """Correlations of the estimates of two or more terms at ``values`` (internal units),
    from the pseudo-inverse of J'J."""
    if len(terms) < 2:
        return {}
    problem = problem or Problem(scaled, terms)
    return term_correlations(problem.free, problem.covariance(values[problem.columns]), terms)


def _rank(scaled, terms, smaller):
    """Fit one model well enough to rank it.

    Started where the bounded solver starts and in the same coordinates, MINPACK's
    Levenberg-Marquardt heads for the same optimum while the parameters stay > 0, and most
    candidates converge so. A candidate whose optimum lies on the bound 0 (a term the
    record does not want) makes it step below 0; that optimum is then a smaller model's,
    when every term at 0 there has a chi-square gradient pointing outward (the Kuhn-Tucker
    conditions) and nothing lower was met on the way. Otherwise the bounded solver runs
    from the linear estimate, and from the best smaller model if that was lower.
    """
    best_smaller = min(smaller, key=lambda c: c.chi_square, default=None)
    problem = Problem(scaled, terms)
    start = scaled.starting_values(terms)
    solution, lowest, evaluations, left = _levenberg_marquardt(problem, start)
    if solution is not None:
        chi_square = problem.chi_square(solution)
        if best_smaller is None or chi_square <= best_smaller.chi_square:
            return make_candidate(scaled, terms, problem.values(solution), chi_square, True,
                                  evaluations, problem=problem)
    elif left and best_smaller is not None and lowest >= best_smaller.chi_square:
        at_bound = [column for column in problem.columns[1:]
                    if best_smaller.internal[column] == 0]
        gradient = _gradient(scaled, best_smaller)
        if all(gradient[column] >= 0 for column in at_bound):
            return make_candidate(scaled, terms, best_smaller.internal.copy(),
                                  best_smaller.chi_square, best_smaller.success, evaluations,
                                  gradient)
    values, chi_square, success, more = _bounded(problem, start)
    evaluations += more
    if best_smaller is not None and best_smaller.chi_square < chi_square:
        values, chi_square, success, more = _bounded(problem, best_smaller.internal)
        evaluations += more
    return make_candidate(scaled, terms, values, chi_square, success, evaluations,
                          problem=problem)


def _gradient(scaled, candidate):
    """The chi-square gradient in (y0, a, b, c) at a candidate's values (Problem.gradient;
    it depends on the values only, not on which terms are free): computed where needed."""
    if candidate.gradient is not None:
        return candidate.gradient
    return Problem(scaled, "abc").gradient(candidate.internal)


def _bounded(problem, start):
    """scipy's trust-region-reflective fit with the bounds [0, inf), analytic Jacobian,
    x_scale="jac": the solver and settings lmfit uses for the reported fit.
    Returns (values, chi_square, success, evaluations)."""
    result = optimize.least_squares(problem.residual, np.maximum(start[problem.columns], 0.0),
                                    jac=problem.jacobian, bounds=(0.0, np.inf), method="trf",
                                    x_scale="jac", max_nfev=4000 * (len(problem.free) + 1),
                                    **TOLERANCES)
    return (problem.values(result.x), problem.chi_square(result.x), bool(result.success),
            int(result.nfev))


class _LeftTheBounds(Exception):
    """Levenberg-Marquardt tried a parameter < 0, where the law is not defined."""


def _levenberg_marquardt(problem, start):
    """MINPACK's Levenberg-Marquardt on ``problem`` from ``start`` (y0, a, b, c), abandoned
    if it tries a parameter < 0.

    Returns (free values or None, lowest chi-square seen (record weights), evaluations,
    left the bounds). The free values are given only if a MINPACK convergence test passed
    inside the bounds.
    """
    seen = {"evaluations": 0, "lowest": math.inf}

    def residual(x):
        seen["evaluations"] += 1
        if min(x.tolist()) < 0:
            raise _LeftTheBounds
        r = problem.residual(x)
        seen["lowest"] = min(seen["lowest"], float(r @ r) * problem.chi_square_scale)
        return r

    def jacobian(x):
        if min(x.tolist()) < 0:
            raise _LeftTheBounds
        return problem.jacobian_rows(x)

    try:
        with warnings.catch_warnings():
            # Without full_output, leastsq warns where it stops unconverged (the status
            # says so), and it computes neither its covariance (unused) nor copies of the
            # Jacobian: a LAPACK call that gave scipy's BLAS its own 32 MiB buffer.
            warnings.filterwarnings("ignore", category=RuntimeWarning,
                                    message=r"(Number of calls to function|[fxg]tol=)")
            x, status = optimize.leastsq(
                residual, start[problem.columns], Dfun=jacobian, col_deriv=True,
                maxfev=_RANKING_EVALUATIONS, **_RANKING_TOLERANCES)
    except _LeftTheBounds:
        return None, seen["lowest"], seen["evaluations"], True
    converged = status in (1, 2, 3, 4) and min(x) > 0
    return (x if converged else None), seen["lowest"], seen["evaluations"], False


def fit_reported(scaled: ScaledRecord, candidate: Candidate) -> ReportedFit:
    """The reported model fitted with lmfit (:func:`mcfit.fit.reported.solve_reported`),
    started at its ranking solution refined by Gauss-Newton (so lmfit converges at once)."""
    problem = Problem(scaled, candidate.terms)
    start, refining = _gauss_newton_refined(problem, candidate.internal)
    solution = solve_reported(problem, _parameters(problem.free, start[problem.columns]))
    return ReportedFit(problem.values(solution.x), problem.free, solution.covariance,
                       solution.chi_square, solution.success,
                       candidate.evaluations + refining + solution.evaluations, problem)


# lmfit Parameters by tuple of free names, one dictionary per thread (Dask workers may run
# fits in threads): building them costs more than lmfit's whole fit from a converged start.
_PARAMETERS = threading.local()


def _parameters(free, values):
    """lmfit Parameters named ``free``, each >= 0, set to ``values`` (reused, see above;
    lmfit fits a copy and leaves them as they are)."""
    cache = _PARAMETERS.__dict__.setdefault("by_free", {})
    params = cache.get(free)
    if params is None:
        params = cache[free] = lmfit.Parameters()
        for name in free:
            params.add(name, value=1.0, min=0.0)
    for name, value in zip(free, values):
        params[name].value = float(value)
    return params


def _gauss_newton_refined(problem, values):
    """``values`` (a ranking solution) after up to two Gauss-Newton steps, and the number of
    evaluations of the law they took.

    Along a direction the record hardly determines (correlated parameters), chi-square
    changes by less than its rounding error over a range of about 1e-9 of the values: a
    solver that compares chi-square values stops anywhere in it, where its path (the
    record's units, say) leads. A Gauss-Newton step solves for the optimum instead. A step
    is kept only inside the bounds and if chi-square does not rise beyond rounding.
    """
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
