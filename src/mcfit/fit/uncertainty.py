"""Uncertainty of a fit: parameter covariance, Q(t) with its standard error (the period's
uncertainty included), a lower bound on Q when no damping is detected, and the bootstrap."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from mcfit import decay
from mcfit.fit.problem import PARAMETERS, Problem

__all__ = ["ParameterErrors", "parameter_errors", "physical_errors", "q_of_fit",
           "term_correlations", "q_with_stderr", "summarise_q",
           "q_lower_bound", "bootstrap_intervals", "interval_factor"]

_COLUMN = {name: i for i, name in enumerate(PARAMETERS)}


@dataclass(frozen=True)
class ParameterErrors:
    """Standard errors ({name: float or None}), correlations ({"a,b": rho}) and the
    covariance of the free parameters in physical units (None if unknown)."""

    stderr: dict
    correlation: dict
    covariance: np.ndarray | None


def parameter_errors(scaled, free, covariance) -> ParameterErrors:
    """Physical standard errors and correlations from the free parameters' covariance in
    internal units."""
    return physical_errors(free, covariance, scaled.physical_factors()[[_COLUMN[k] for k in free]])


def physical_errors(free, covariance, factors=1.0) -> ParameterErrors:
    """Standard errors and correlations of the parameters ``free`` (names of y0, a, b, c)
    from their covariance, each multiplied by its factor to physical units."""
    stderr = dict.fromkeys(PARAMETERS)
    if covariance is None:
        return ParameterErrors(stderr, {}, None)
    factors = np.broadcast_to(np.asarray(factors, dtype=float), (len(free),))
    physical = covariance * np.outer(factors, factors)
    errors = np.sqrt(np.maximum(np.diag(physical), 0.0))
    stderr.update({k: float(e) for k, e in zip(free, errors)})
    correlation = {f"{ki},{kj}": float(physical[i, j] / (errors[i] * errors[j]))
                   for (i, ki), (j, kj) in itertools.combinations(enumerate(free), 2)
                   if errors[i] > 0 and errors[j] > 0}
    return ParameterErrors(stderr, correlation, physical)


def term_correlations(free, covariance, terms) -> dict:
    """Correlations {"a,b": rho} of the estimates of each pair of ``terms`` (names in
    ``free``, the order of ``covariance``'s rows); 0 where a variance is 0."""
    pairs = {}
    for first, second in itertools.combinations(terms, 2):
        i, j = free.index(first), free.index(second)
        product = covariance[i, i] * covariance[j, j] if covariance is not None else 0.0
        pairs[f"{first},{second}"] = (float(covariance[i, j] / math.sqrt(product))
                                      if product > 0 else 0.0)
    return pairs


def interval_factor(dof, confidence=0.95):
    """Half-width of a two-sided interval in standard errors estimated with ``dof``
    degrees of freedom (Student's t; the normal quantile when dof is unknown)."""
    tail = 0.5 + 0.5 * confidence
    return float(special.stdtrit(dof, tail)) if dof > 0 else float(special.ndtri(tail))


# Points a block of q_with_stderr.
_BLOCK = 1 << 16


def q_with_stderr(t, values, covariance, free, omega, omega_relative_sigma=0.0):
    """Q at times ``t`` (from t0) and its standard error by the delta method.

    Q = omega*y/(2*(c + b*y + a*y^2)) (Handbook Eq. 20.56) depends on the coefficients
    directly and through y(t); the frequency's relative error adds (Q * sigma_w/w)^2 to the
    variance (it is estimated from the crest times, independently of the amplitudes).
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size <= _BLOCK:
        return _q_with_stderr(t, values, covariance, free, omega, omega_relative_sigma)
    # Block by block: the temporaries of a million turning points would be gigabytes.
    parts = [_q_with_stderr(t[i:i + _BLOCK], values, covariance, free, omega,
                            omega_relative_sigma) for i in range(0, t.size, _BLOCK)]
    q = np.concatenate([part[0] for part in parts])
    return q, None if covariance is None else np.concatenate([part[1] for part in parts])


def _q_with_stderr(t, values, covariance, free, omega, omega_relative_sigma):
    y0, a, b, c = (values[k] for k in PARAMETERS)
    law = decay.amplitude_terms(t, y0, a, b, c)
    y = law.amplitude()
    q = decay.quality_factor(y, omega, a, b, c)
    if covariance is None:
        return q, None
    rate = decay.decay_rate(y, a, b, c)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        denominator = 2.0 * rate**2
        dq_dy = omega * (c - a * y**2) / denominator
        direct = {"a": -omega * y**3 / denominator, "b": -omega * y**2 / denominator,
                  "c": -omega * y / denominator, "y0": np.zeros_like(y)}
        jac_y = law.jacobian()
        gradient = np.column_stack([dq_dy * jac_y[:, _COLUMN[k]] + direct[k] for k in free])
        variance = (np.einsum("ij,jk,ik->i", gradient, covariance, gradient)
                    + (q * omega_relative_sigma) ** 2)
        q_stderr = np.sqrt(np.maximum(variance, 0.0))
    return q, np.where(np.isfinite(q_stderr), q_stderr, np.nan)


def summarise_q(q, q_stderr):
    """Q at the first and last turning point and its extremes, each with its stderr."""
    finite = np.flatnonzero(np.isfinite(q))
    if finite.size == 0:
        return None
    where = {"initial": 0, "final": q.size - 1, "min": finite[np.argmin(q[finite])],
             "max": finite[np.argmax(q[finite])]}
    out = {}
    for key, i in where.items():
        out[key] = float(q[i])
        error = q_stderr[i] if q_stderr is not None else math.nan
        out[f"{key}_stderr"] = float(error) if math.isfinite(error) else None
    return out


def q_of_fit(t, y_fit, values, covariance, free, omega, omega_relative_sigma=0.0):
    """Q(t) at the turning points' times ``t`` (from t0) with its standard error, its
    parts by regime at the fitted amplitudes ``y_fit`` and its summary: (q, q_stderr,
    q_parts, q_summary)."""
    q, q_stderr = q_with_stderr(t, values, covariance, free, omega, omega_relative_sigma)
    parts = decay.quality_parts(y_fit, omega, values["a"], values["b"], values["c"])
    q_parts = {"coulomb": parts[0], "hysteretic": parts[1], "fluid": parts[2]}
    return q, q_stderr, q_parts, summarise_q(q, q_stderr)


def q_lower_bound(scaled, y0, omega, omega_relative_sigma=0.0, confidence=0.95):
    """One-sided lower confidence bound on Q when no damping is detected.

    Constant Q (model b) is linearised about b = 0 at the constant amplitude ``y0``
    (internal units): one Gauss-Newton step gives b's unconstrained estimate and its
    standard error s (noise scale from the residuals, Student's t with n - 2 degrees of
    freedom). The upper bound max(b, 0) + t*s covers any true b >= 0 at least as often as
    ``confidence``; Q > omega_low/(2*b_upper), with the frequency at its own lower bound.
    """
    problem = Problem(scaled, "b")
    x = np.array([y0, 0.0])
    jacobian, residual = problem.jacobian(x), problem.residual(x)
    step = np.linalg.lstsq(jacobian, -residual, rcond=None)[0]
    dof = scaled.t.size - 2
    if dof <= 0:
        return None
    chi_square = float(np.sum((residual + jacobian @ step) ** 2)) * problem.chi_square_scale
    variance = problem.covariance(x)[1, 1] * chi_square / dof
    quantile = float(special.stdtrit(dof, confidence))
    b_upper = (max(float(step[1]), 0.0) + quantile * math.sqrt(max(variance, 0.0)))
    b_upper /= scaled.time_unit
    if not b_upper > 0:
        return None
    omega_low = omega * max(1.0 - quantile * omega_relative_sigma, 0.0)
    return omega_low / (2.0 * b_upper)


def bootstrap_intervals(y_model, y, sigma, count, rng, refit, *, confidence=0.95):
    """Residual bootstrap: ``refit`` each of ``count`` draws y_model + sigma * resampled
    standardized residuals, and take percentile intervals.

    ``refit(draw)`` returns a dict of numbers (or None when the refit failed; counted as
    ``failed`` and left out) and, under the key ``"model"``, the model it reported. Returns
    ``{"n", "failed", "models": {model: fraction}, "interval_95": {name: [low, high]}}``.
    """
    standardized = (y - y_model) / sigma
    rows, models, failed = [], {}, 0
    for _ in range(count):
        result = refit(y_model + sigma * rng.choice(standardized, size=y.size, replace=True))
        if result is None:
            failed += 1
            continue
        model = result.pop("model")
        models[model] = models.get(model, 0) + 1
        rows.append(result)
    out = {"n": len(rows), "failed": failed,
           "models": {m: k / len(rows) for m, k in sorted(models.items(), key=lambda i: -i[1])}
           if rows else {}, "interval_95": None}
    if rows:
        tail = 100 * (1 - confidence) / 2
        out["interval_95"] = {}
        for name in rows[0]:
            column = np.array([row[name] for row in rows], dtype=float)
            low, high = np.percentile(column, [tail, 100 - tail], method="inverted_cdf")
            out["interval_95"][name] = [float(low), float(high)]
    return out
