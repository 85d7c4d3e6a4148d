"""Fit the amplitude law to turning points, choose the damping regimes, estimate Q(t).

The fit works on turning-point amplitudes ``y_k`` at times ``t_k`` (THEORY.md section 5).
Internally time is measured from the first point in units of the record's span and
amplitudes in units of the largest one, so a record in volts or microvolts, seconds or hours
gives the same relative result after the same iterations. numpy/scipy/lmfit only, no I/O.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import warnings
from dataclasses import asdict, dataclass, field

import lmfit
import numpy as np
from scipy import optimize, stats

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
# Amplitudes and times beyond these cannot be squared and multiplied in float64.
_LARGEST = 1e30
_SMALLEST = 1e-30
# Stop when chi-square changes by < 1e-10 relative: 1e-5 of a standard error in the
# parameters, and far enough above chi-square's rounding floor (~1e-15) that the same
# record in other units stops after the same iterations.
_TOLERANCES = {"ftol": 1e-10, "xtol": 1e-10, "gtol": 1e-10}


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
    bootstrap: dict | None = None
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
    """The record in internal units: time from t0 over the span, amplitude over max(y)."""

    def __init__(self, t, y, sigma):
        self.t0 = t[0]
        self.time_unit = t[-1] - t[0]
        self.amplitude_unit = float(np.max(y))
        self.t = (t - self.t0) / self.time_unit
        self.y = y / self.amplitude_unit
        self.weights = self.amplitude_unit / sigma

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
    int_y = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))])
    int_y2 = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] ** 2 + y[:-1] ** 2) * np.diff(t))])
    columns = {"a": -int_y2, "b": -int_y, "c": -t}
    design = np.column_stack([np.ones_like(t)] + [columns[k] for k in terms])
    solution, _ = optimize.nnls(design * w[:, None], y * w)
    start = {"y0": solution[0], "a": 0.0, "b": 0.0, "c": 0.0}
    start.update(zip(terms, solution[1:]))
    # A zero start sits on the bound where the Jacobian may vanish; nudge it inside.
    rate_scale = max(1.0, -math.log(max(y[-1], 1e-3)))
    for k, floor in zip(TERMS, (1e-3, 1e-3, 1e-3)):
        if k in terms and start[k] <= 0:
            start[k] = floor * rate_scale
    if start["y0"] <= 0:
        start["y0"] = y[0]
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


def _fit_subset(scaled, terms):
    """Least-squares fit of one model in internal units; returns (values, covar, chi2, ok)."""
    start = _starting_values(scaled, terms)
    params = lmfit.Parameters()
    params.add("y0", value=start["y0"], min=0.0)
    for k in TERMS:
        params.add(k, value=start[k], min=0.0, vary=k in terms)
    free = ["y0"] + list(terms)
    t, y, w = scaled.t, scaled.y, scaled.weights
    free_columns = [_COLUMN[k] for k in free]
    last = {}  # the law at the last parameters: scipy asks for the Jacobian where it just
    # evaluated the residuals, so one evaluation serves both

    def evaluate(p):
        key = tuple(p[k].value for k in ("y0", "a", "b", "c"))
        if last.get("key") != key:
            last["key"] = key
            last["value"] = decay.amplitude_and_jacobian(t, *key)
        return last["value"]

    def residual(p):
        return (evaluate(p)[0] - y) * w

    def jacobian(p):
        return evaluate(p)[1][:, free_columns] * w[:, None]

    minimizer = lmfit.Minimizer(residual, params)
    with _quiet_lmfit_errorbars():
        result = minimizer.minimize(method="least_squares", jac=jacobian, x_scale="jac",
                                    **_TOLERANCES)
    values = np.array([result.params[k].value for k in ("y0", "a", "b", "c")])
    chi_square = float(np.sum(residual(result.params) ** 2))
    # Unscaled covariance from the Jacobian at the solution (scaled by chi2/dof later).
    jac = jacobian(result.params)
    try:
        covar = np.linalg.pinv(jac.T @ jac)
    except np.linalg.LinAlgError:
        covar = None
    return values, covar, free, chi_square, bool(result.success), int(result.nfev)


def _information_criteria(chi_square, n_points, n_params):
    """AICc and BIC of a Gaussian likelihood whose overall noise scale is estimated."""
    log_likelihood_term = n_points * math.log(max(chi_square, 1e-300) / n_points)
    aic = log_likelihood_term + 2 * n_params
    denominator = n_points - n_params - 1
    aicc = aic + (2 * n_params * (n_params + 1) / denominator if denominator > 0 else math.inf)
    bic = log_likelihood_term + n_params * math.log(n_points)
    return aicc, bic


def _boundary_lrt_p_value(chi_square_without, chi_square_with, n_points):
    """p-value of adding one term >= 0: the statistic follows 0.5*chi2(0) + 0.5*chi2(1)."""
    statistic = n_points * math.log(max(chi_square_without, 1e-300) / max(chi_square_with, 1e-300))
    if statistic <= 0:
        return 1.0
    return 0.5 * float(stats.chi2.sf(statistic, 1))


def _lag_one_autocorrelation(residuals):
    r = residuals - residuals.mean()
    denominator = float(np.dot(r, r))
    return float(np.dot(r[1:], r[:-1]) / denominator) if denominator > 0 else 0.0


def _q_with_stderr(t_scaled, values, covar_physical, free, scaled, omega):
    """Q at each turning point and its standard error by the delta method."""
    y0, a, b, c = values
    t_phys = t_scaled * scaled.time_unit
    y = decay.amplitude(t_phys, y0, a, b, c)
    q = decay.quality_factor(y, omega, a, b, c)
    if covar_physical is None:
        return q, None
    rate = decay.decay_rate(y, a, b, c)
    with np.errstate(divide="ignore", invalid="ignore"):
        denominator = 2.0 * rate**2
        dq_dy = omega * (c - a * y**2) / denominator
        direct = {"a": -omega * y**3 / denominator, "b": -omega * y**2 / denominator,
                  "c": -omega * y / denominator, "y0": np.zeros_like(y)}
        jac_y = decay.amplitude_jacobian(t_phys, y0, a, b, c)
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
        Turning-point amplitudes about equilibrium, > 0 (signal units U).
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
        Invalid input (too few points, non-positive amplitudes) raises :class:`FitError`.
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
    if np.any(y <= 0):
        raise FitError("turning-point amplitudes must be > 0 (measured about the equilibrium)")
    # Squares and products of the coefficients must stay inside double precision.
    for what, values, unit in (("amplitudes", y, "the signal"),
                               ("times", np.abs(t[[0, -1]]), "the time")):
        largest = float(np.max(values))
        smallest = float(np.min(y)) if what == "amplitudes" else float(t[-1] - t[0])
        if largest > _LARGEST or smallest < _SMALLEST:
            raise FitError(f"turning-point {what} span {smallest:.3g} to {largest:.3g}, beyond "
                           f"what mcfit fits in double precision (1e-30 to 1e30); rescale {unit}.")
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
    candidates = []
    # A forced model needs only itself and the models one term smaller (for the LRT).
    tried = MODELS if model is None else tuple(
        m for m in MODELS if m == model or (len(m) == len(model) - 1 and set(m) <= set(model)))
    for name in tried:
        values, covar, free, chi_square, ok, evaluations = _fit_subset(scaled, name)
        fits[name] = (values, covar, free, chi_square, ok)
        aicc, bic = _information_criteria(chi_square, n, len(free))
        physical = dict(zip(("y0", "a", "b", "c"), map(float, scaled.to_physical(values))))
        candidates.append(Candidate(name, len(free), chi_square, aicc, bic, ok, physical,
                                    evaluations))

    warnings = []
    by_score = {c.model: getattr(c, criterion) for c in candidates}
    if model is None:
        chosen = min(by_score, key=by_score.get)
        # Each kept term must also survive the boundary likelihood-ratio test.
        while len(chosen) > 1:
            p_values = {k: _boundary_lrt_p_value(fits[chosen.replace(k, "")][3], fits[chosen][3], n)
                        for k in chosen}
            weakest = max(p_values, key=p_values.get)
            if p_values[weakest] < LRT_ALPHA:
                break
            warnings.append(f"{REGIME_NAMES[weakest]} term dropped: {criterion} kept it but the "
                            f"likelihood-ratio test does not support it (p = {p_values[weakest]:.3g})")
            chosen = chosen.replace(weakest, "")
    else:
        chosen = model
    values, covar, free, chi_square, ok = fits[chosen]
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

    boot = (_bootstrap(scaled, chosen, physical_values, y_fit, y, sigma, omega, bootstrap, rng)
            if bootstrap else None)
    return DecayFit(
        status="ok" if ok else "error", message=None if ok else "the fit did not converge",
        model=chosen, domain=domain, criterion=criterion, t0=float(t[0]), omega=omega,
        values=values_dict, stderr=stderr, correlation=correlation,
        regimes={REGIME_NAMES[k]: k in chosen for k in TERMS}, lrt_p_values=p_values,
        candidates=tuple(candidates), n_points=n, rms=rms, reduced_chi_square=float(reduced),
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


def _bootstrap(scaled, chosen, physical_values, y_fit, y, sigma, omega, count, rng):
    """Residual bootstrap: refit the chosen model to y_fit + resampled weighted residuals."""
    standardized = (y - y_fit) / sigma
    samples = []
    for _ in range(count):
        draw = y_fit + sigma * rng.choice(standardized, size=y.size, replace=True)
        if np.any(draw <= 0):
            continue
        resampled = _Scaled(scaled.t * scaled.time_unit + scaled.t0, draw, sigma)
        values = resampled.to_physical(_fit_subset(resampled, chosen)[0])
        row = list(values)
        if omega is not None:
            t_end = (scaled.t[-1]) * scaled.time_unit
            y_ends = decay.amplitude(np.array([0.0, t_end]), *values)
            row += list(decay.quality_factor(y_ends, omega, *values[1:]))
        samples.append(row)
    if not samples:
        return None
    samples = np.array(samples)
    names = ["y0", "a", "b", "c"] + (["q_initial", "q_final"] if omega is not None else [])
    low, high = np.percentile(samples, [2.5, 97.5], axis=0)
    return {"n": int(samples.shape[0]),
            "interval_95": {k: [float(lo), float(hi)] for k, lo, hi in zip(names, low, high)}}


def _fit_power_law(scaled, t, y, sigma, omega, domain, criterion, noise_from_residuals):
    """Fit dy/dt = -k*y**n (Handbook Eq. 20.51) in internal units."""
    ts, ys, w = scaled.t, scaled.y, scaled.weights
    start_b = -math.log(max(ys[-1] / ys[0], 1e-6)) / max(ts[-1], 1e-12)
    params = lmfit.Parameters()
    params.add("y0", value=ys[0], min=0.0)
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
