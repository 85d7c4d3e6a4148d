"""fit_decay: turning points in, the supported model with its uncertainties out."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from mcfit import decay
from mcfit.errors import FitError
from mcfit.fit import uncertainty
from mcfit.fit.candidates import fit_candidates, fit_reported, make_candidate
from mcfit.fit.diagnostics import fit_warnings, misfit_warning, no_decay_warning
from mcfit.fit.models import CRITERIA, MODELS, NONE, POWER, REGIME_NAMES, TERMS, \
    models_to_fit, parse_model
from mcfit.fit.power import PowerLawFit, fit_power_law
from mcfit.fit.problem import PARAMETERS, ScaledRecord
from mcfit.fit.reprs import fit_repr
from mcfit.fit.selection import LRT_ALPHA, Selection, select_model

__all__ = ["DecayFit", "fit_decay", "MIN_POINTS"]

MIN_POINTS = 4
# Amplitudes and times beyond these cannot be squared and multiplied in float64.
_LARGEST = 1e30
_SMALLEST = 1e-30


@dataclass(frozen=True)
class DecayFit:
    """Result of :func:`fit_decay`: plain data (:meth:`mcfit.Analysis.summary` is its JSON).

    Coefficients are in the units of ``t`` (seconds in the time domain, cycles in the cycle
    domain) and of ``y``; ``t0`` is the time of the first turning point used, where the
    amplitude is ``y0``. ``model`` is ``"none"`` when no damping is detected (then ``q``
    is None and ``q_lower_bound`` a one-sided 95 % bound); ``resolved`` is False when the
    record cannot tell the regimes apart (see :mod:`mcfit.fit.selection`).
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
    lrt_p_values: dict  # kept term -> p-value of the test against the model without it
    candidates: tuple
    n_points: int
    rms: float
    reduced_chi_square: float
    noise_from_residuals: bool
    selection: Selection
    t: np.ndarray = field(repr=False)
    y: np.ndarray = field(repr=False)
    y_fit: np.ndarray = field(repr=False)
    sigma: np.ndarray = field(repr=False)
    q: np.ndarray | None = field(repr=False)
    q_stderr: np.ndarray | None = field(repr=False)
    q_parts: dict | None = field(repr=False)
    q_summary: dict | None = None  # initial, final, min, max and each *_stderr
    q_lower_bound: float | None = None
    bootstrap: dict | None = None
    warnings: tuple = ()
    method: str = "turning-points"  # what the values come from (WaveformFit: "waveform")
    method_reason: str | None = None

    @property
    def resolved(self) -> bool:
        return self.selection.resolved

    @property
    def interval_factor(self) -> float:
        """Half-width of a 95 % interval in standard errors: Student's t with the fit's
        degrees of freedom (the noise scale is estimated from the residuals)."""
        return uncertainty.interval_factor(self.n_points - 1 - len(self.selection.terms))

    @property
    def forced(self) -> bool:
        return self.selection.forced

    def amplitude(self, t):
        """The fitted amplitude at times ``t`` (same units as the input)."""
        t = np.maximum(np.asarray(t, dtype=float) - self.t0, 0)
        return decay.amplitude(t, *(self.values[k] for k in PARAMETERS))

    def __repr__(self):
        return fit_repr(self, ("y0",) + tuple(self.selection.terms))

    def to_dict(self) -> dict:
        """The fit as plain data (JSON-ready; None where a number is missing or not
        finite): the model with its evidence, y0, a, b, c and Q with standard errors in
        the units of ``t`` and ``y``, the candidates' scores, and ``domain``, ``n_points``
        and ``correlation`` (``"a,b"`` -> rho)."""
        from mcfit import plain

        selection = self.selection
        out = {"model": self.model, "domain": self.domain, "method": self.method,
               "method_reason": self.method_reason, "resolved": bool(self.resolved),
               "regimes": {name: bool(present) for name, present in self.regimes.items()},
               "params": {k: {"value": plain.number(self.values[k]),
                              "stderr": plain.number(self.stderr[k])} for k in PARAMETERS},
               "t0": plain.number(self.t0),
               "q": plain.q_summary(self.q_summary, self.q_lower_bound),
               "fit": {"criterion": self.criterion, "forced": bool(self.forced),
                       "rms": plain.number(self.rms),
                       "reduced_chi_square": plain.number(self.reduced_chi_square),
                       "noise_from_residuals": bool(self.noise_from_residuals),
                       "lrt_p_values": _by_regime(self.lrt_p_values),
                       "alpha": plain.number(selection.alpha),
                       "preferred": selection.preferred, "ties": list(selection.ties),
                       "near_threshold": _by_regime(selection.near_threshold)},
               "candidates": plain.candidates(self.candidates),
               "n_points": int(self.n_points), "correlation": plain.numbers(self.correlation)}
        if self.bootstrap is not None:
            out["bootstrap"] = _plain_bootstrap(self.bootstrap)
        out["warnings"] = list(self.warnings)
        return out


def fit_decay(t, y, sigma=None, *, period=None, period_sigma=None, domain="time",
              criterion="aicc", model=None, alpha=LRT_ALPHA, bootstrap=0,
              rng=None) -> DecayFit | PowerLawFit:
    """Fit dy/dt = -c - b*y - a*y**2 to turning-point amplitudes and choose the regimes.

    Parameters
    ----------
    t : array_like, shape (n,)
        Turning-point times (s) or cycle numbers (``domain="cycle"``), increasing.
    y : array_like, shape (n,)
        Turning-point amplitudes about equilibrium (signal units U). The last ones may be
        <= 0 where noise dominates; the largest must be > 0. The model stays >= 0.
    sigma : array_like, shape (n,), optional
        Standard deviation of each amplitude. Only relative weights are taken from it: the
        overall noise scale is always estimated from the residuals as well.
    period, period_sigma : float, optional
        Oscillation period in s and its standard error; the period is needed for Q in the
        time domain, its error enters Q's. In the cycle domain omega is 2*pi per cycle.
    domain : {"time", "cycle"}
    criterion : {"aicc", "bic"}
        Information criterion that ranks the eight models (see :func:`select_model`).
    model : str, optional
        Force a model: letters from "abc" (e.g. "ab"), "none", or "power" for
        dy/dt = -k*y**n. Anything else raises :class:`FitError`.
    alpha : float
        Level of the likelihood-ratio tests that kept terms must pass.
    bootstrap : int
        Residual-bootstrap refits for 95 % intervals (0: none). Unless the model is forced,
        each resample is drawn from the three-term fit and the model is chosen anew, so the
        intervals include the uncertainty of the choice.
    rng : numpy.random.Generator, optional
        Random source for the bootstrap.

    Returns
    -------
    DecayFit, or PowerLawFit for ``model="power"``
        ``status == "ok"``, or ``"error"`` with ``message`` when the fit itself failed.
        Invalid input (too few points, no amplitude > 0, values beyond double precision)
        raises :class:`FitError`.
    """
    t, y, sigma, noise_from_residuals = _checked(t, y, sigma)
    if criterion not in CRITERIA:
        raise FitError(f"unknown criterion {criterion!r}; use one of {', '.join(CRITERIA)}",
                       option="criterion")
    if domain not in ("time", "cycle"):
        raise FitError(f"unknown domain {domain!r}; use time or cycle", option="domain")
    forced = parse_model(model) if model is not None else None
    omega, omega_sigma = _angular_frequency(domain, period, period_sigma)
    record = _Record(t, y, sigma, ScaledRecord(t, y, sigma), domain, omega, omega_sigma,
                     noise_from_residuals)
    if forced == POWER:
        return fit_power_law(record.scaled, t, y, sigma, omega, domain, criterion,
                             noise_from_residuals)
    candidates = fit_candidates(record.scaled, models_to_fit(forced))
    selection = select_model(candidates, criterion, alpha, n_points=t.size, forced=forced)
    fit = _reported(record, candidates, selection)
    if bootstrap:
        rng = rng if rng is not None else np.random.default_rng()
        fit = _with_bootstrap(fit, record, candidates, alpha, bootstrap, rng)
    return fit


def fit_model_values(t, y, sigma=None, *, model) -> dict:
    """The values (y0, a, b, c) of ``model`` (a set of terms) fitted alone to turning
    points, without the smaller models :func:`fit_decay` fits beside it, the errors or
    lmfit's report: for predictions that need the values only (within 1e-6 standard
    errors of the reported fit where no term sits at its bound). Raises
    :class:`FitError` as :func:`fit_decay` does."""
    t, y, sigma, _ = _checked(t, y, sigma)
    model = parse_model(model)
    if model == POWER:
        raise FitError("the power law has no values of a, b and c", option="model")
    return fit_candidates(ScaledRecord(t, y, sigma), (model,))[model].values


@dataclass(frozen=True)
class _Record:
    """The turning points as given and in internal units, with the frequency."""

    t: np.ndarray
    y: np.ndarray
    sigma: np.ndarray
    scaled: ScaledRecord
    domain: str
    omega: float | None
    omega_sigma: float  # relative
    noise_from_residuals: bool


def _checked(t, y, sigma):
    """The turning points as float arrays, or a FitError saying what is wrong."""
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
    if _looks_like_a_waveform(y, sigma):
        raise FitError("these values swing up and down smoothly like samples of the "
                       "oscillation itself, not turning-point amplitudes: fit the waveform "
                       "with mcfit.analyse(t, x), which finds its turning points first")
    if not np.max(y) > 0:
        raise FitError("no turning-point amplitude is > 0 (amplitudes are measured about the "
                       "equilibrium): there is no decay to fit")
    # Squares and products of the coefficients must stay inside double precision.
    largest = float(np.max(np.abs(y)))
    if not _SMALLEST <= largest <= _LARGEST:
        raise FitError(f"turning-point amplitudes reach {largest:.3g}, beyond what mcfit fits "
                       "in double precision (1e-30 to 1e30); rescale the signal.")
    largest, span = float(np.max(np.abs(t[[0, -1]]))), float(t[-1] - t[0])
    if largest > _LARGEST or span < _SMALLEST:
        raise FitError(f"turning-point times span {span:.3g} to {largest:.3g}, beyond what "
                       "mcfit fits in double precision (1e-30 to 1e30); rescale the time.")
    noise_from_residuals = sigma is None
    sigma = np.ones_like(y) if sigma is None else np.asarray(sigma, dtype=float)
    if sigma.shape != y.shape or not np.all(np.isfinite(sigma)) or np.any(sigma <= 0):
        raise FitError("amplitude uncertainties must be finite and > 0, one per turning point")
    return t, y, sigma, noise_from_residuals


def _looks_like_a_waveform(y, sigma=None):
    """Samples of an oscillation, not amplitudes: many below zero (by more than two
    ``sigma`` where given: amplitudes within the noise can be), or rising as often as
    falling in five or more swings of four or more steps each (amplitudes fall, or
    scatter step by step in the noise)."""
    if y.size < 20:
        return False
    below = y < (0.0 if sigma is None else -2.0 * np.asarray(sigma, dtype=float))
    if np.count_nonzero(below) > 0.3 * y.size:
        return True
    rising = np.diff(y) > 0
    runs = 1 + np.count_nonzero(rising[1:] != rising[:-1])
    return bool(0.35 <= rising.mean() <= 0.65 and runs >= 10 and rising.size / runs >= 4.0)


def _angular_frequency(domain, period, period_sigma):
    """omega (None without a period) and its relative standard error."""
    if domain == "cycle":
        return 2 * math.pi, 0.0
    if not period:
        return None, 0.0
    relative = period_sigma / period if period_sigma and math.isfinite(period_sigma) else 0.0
    return 2 * math.pi / period, relative


def _reported(record, candidates, selection):
    """The selected model refitted with lmfit, with its errors, Q and warnings."""
    t, y, scaled, omega = record.t, record.y, record.scaled, record.omega
    reported = fit_reported(scaled, candidates[selection.model])
    candidates = {**candidates, selection.model: make_candidate(
        scaled, selection.model, reported.values, reported.chi_square, reported.success,
        reported.evaluations, problem=reported.problem)}
    dof = t.size - len(reported.free)
    reduced = reported.chi_square / dof if dof > 0 else math.nan
    errors = uncertainty.parameter_errors(scaled, reported.free, reported.covariance)
    values = scaled.to_physical(reported.values)
    y_fit = decay.amplitude(t - t[0], *(values[k] for k in PARAMETERS))
    sigma = record.sigma
    if record.noise_from_residuals and math.isfinite(reduced):
        sigma = sigma * math.sqrt(reduced)  # the amplitude noise the residuals show
    warnings = (fit_warnings(selection, y_fit, values, errors, (y_fit - y) / record.sigma,
                             reported.success)
                + ([] if record.noise_from_residuals else misfit_warning(reduced, dof)))
    q = q_stderr = q_parts = q_summary = q_bound = None
    if omega is not None and selection.model == NONE:
        q_bound = uncertainty.q_lower_bound(scaled, reported.values[0], omega,
                                            record.omega_sigma)
    if selection.model == NONE:
        warnings.append(no_decay_warning(float(t[-1] - t[0]),
                                          "s" if record.domain == "time" else "cycles", q_bound))
    if omega is not None and selection.model != NONE:
        q, q_stderr, q_parts, q_summary = uncertainty.q_of_fit(
            t - t[0], y_fit, values, errors.covariance, reported.free, omega,
            record.omega_sigma)
    return DecayFit(
        status="ok" if reported.success else "error",
        message=None if reported.success else "the fit did not converge",
        model=selection.model, domain=record.domain, criterion=selection.criterion,
        t0=float(t[0]), omega=omega, values=values, stderr=errors.stderr,
        correlation=errors.correlation,
        regimes={REGIME_NAMES[k]: k in selection.terms for k in TERMS},
        lrt_p_values=selection.p_values, candidates=tuple(candidates.values()),
        n_points=t.size, rms=float(np.sqrt(np.mean((y_fit - y) ** 2))),
        reduced_chi_square=float(reduced), noise_from_residuals=record.noise_from_residuals,
        selection=selection, t=t, y=y, y_fit=y_fit, sigma=sigma, q=q, q_stderr=q_stderr,
        q_parts=q_parts, q_summary=q_summary, q_lower_bound=q_bound,
        warnings=tuple(warnings))


def _with_bootstrap(fit, record, candidates, alpha, count, rng):
    """``fit`` with residual-bootstrap 95 % intervals of y0, a, b, c and Q.

    A forced model is refitted to draws about its own fit. Otherwise the draws are made
    about the three-term fit (so a term the selection missed is in them) and each is
    fitted and selected anew: the intervals include the uncertainty of the model choice.
    """
    scaled, selection = record.scaled, fit.selection
    if selection.forced:
        source, models = candidates[selection.model], models_to_fit(selection.model)
    else:
        source, models = candidates["abc"], MODELS
    y_model = decay.amplitude(record.t - record.t[0], *(source.values[k] for k in PARAMETERS))
    t_ends = np.array([0.0, record.t[-1] - record.t[0]])

    def refit(draw):
        drawn = scaled.with_amplitudes(draw)
        fitted = fit_candidates(drawn, models)
        chosen = select_model(fitted, selection.criterion, alpha, n_points=draw.size,
                              forced=selection.model if selection.forced else None).model
        if not fitted[chosen].success:
            return None
        row = {"model": chosen, **fitted[chosen].values}
        if record.omega is not None:
            ends = decay.amplitude(t_ends, *(row[k] for k in PARAMETERS))
            with np.errstate(divide="ignore"):
                q = decay.quality_factor(ends, record.omega, row["a"], row["b"], row["c"])
            row["q_initial"], row["q_final"] = (float(v) for v in q)
        return row

    result = uncertainty.bootstrap_intervals(y_model, record.y, record.sigma, count, rng, refit)
    result["selection"] = "fixed" if selection.forced else "redone"
    warnings = list(fit.warnings)
    if result["failed"]:
        warnings.append(f"{result['failed']} of {count} bootstrap refits did not converge "
                        "and are left out: the intervals may be too narrow"
                        if result["n"] else
                        f"no bootstrap refit of {count} converged: no intervals")
    return replace(fit, bootstrap=result, warnings=tuple(warnings))


def _by_regime(p_values):
    """``{term: p}`` as ``{regime name: p}`` (plain numbers)."""
    from mcfit import plain

    return {REGIME_NAMES[k]: plain.number(p) for k, p in p_values.items()}


def _plain_bootstrap(boot):
    """A bootstrap summary (:func:`mcfit.fit.uncertainty.bootstrap`) as plain data."""
    from mcfit import plain

    intervals = boot["interval_95"]
    return {**boot, "models": plain.numbers(boot["models"]),
            "interval_95": None if intervals is None else
            {k: [plain.number(low), plain.number(high)] for k, (low, high) in intervals.items()}}
