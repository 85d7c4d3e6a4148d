"""Fit the record x(t) itself by the equation of motion, where the averaged law is not
accurate enough (low Q), and the estimate that decides when that is.

The averaged law dy/dt = -c - b*y - a*y**2 is first order in 1/Q: fitted to the turning
points of a record that obeys Eq. 20.55, its coefficients are biased by about 0.1/Q**2 of
their value (b at Q = 3: -1.2 %); :mod:`mcfit.model_error` predicts that bias for a
record. :func:`fit_waveform` fits x(t) = e0 + e1*(t - t0) + u(t), u the
solution of Eq. 20.55 from amplitude y0 and phase theta0 at t0 with frequency omega, for
the eight candidate models, started from the turning-point fit, and chooses among them
with :func:`mcfit.fit.selection.select_model` as the turning-point fit does.
"""

from __future__ import annotations

import math
from dataclasses import replace

import lmfit
import numpy as np
from scipy import optimize

from mcfit import decay
from mcfit.fit import uncertainty
from mcfit.fit.candidates import Candidate, information_criteria, lmfit_least_squares
from mcfit.fit.models import MODELS, NONE, REGIME_NAMES, TERMS, terms_of
from mcfit.fit.selection import LRT_ALPHA, select_model
from mcfit.phase_plane import phase_plane_motion

__all__ = ["fit_waveform"]
# Nuisance parameters of the waveform besides y0: phase, frequency, offset, drift.
_NUISANCE = ("theta0", "omega", "e0", "e1")
_TOLERANCES = {"ftol": 1e-10, "xtol": 1e-10, "gtol": 1e-10}


class _Waveform:
    """The samples to fit and the model x(t) for a batch of parameter vectors
    (y0, theta0, omega, e0, e1, then the model's terms)."""

    def __init__(self, t, x, t0, terms, noise):
        self.t, self.x, self.t0, self.terms, self.noise = t, x, t0, terms, noise
        self.names = ("y0",) + _NUISANCE + tuple(terms)

    def batch(self, parameters):
        p = np.atleast_2d(parameters)
        coefficients = {k: np.zeros(p.shape[0]) for k in TERMS}
        for i, k in enumerate(self.terms):
            coefficients[k] = p[:, 5 + i]
        motion = phase_plane_motion(self.t - self.t0, p[:, 0], p[:, 1], p[:, 2],
                                    coefficients["a"], coefficients["b"], coefficients["c"])
        return motion + p[:, 3:4] + p[:, 4:5] * (self.t - self.t0)

    def residual(self, parameters):
        return (self.batch(parameters)[0] - self.x) / self.noise

    def jacobian(self, parameters):
        """Forward differences, all columns from one batched integration."""
        p = np.asarray(parameters, dtype=float)
        scale = np.maximum(np.abs(p), self.typical)
        steps = 1e-7 * scale
        trial = np.vstack([p, p + np.diag(steps)])
        x = self.batch(trial)
        return ((x[1:] - x[0]) / (steps[:, None] * self.noise)).T


def fit_waveform(t, x, turning, start_fit, *, criterion="aicc", alpha=LRT_ALPHA,
                 forced=None):
    """Fit the samples between the first and the last used turning point by Eq. 20.55.

    Parameters
    ----------
    t, x : ndarray, shape (n,)
        The record (s, U).
    turning : mcfit.turning.TurningPoints
        Its turning points (for the window, the first crest's sign and the equilibrium).
    start_fit : DecayFit
        The turning-point fit, whose candidates start the waveform candidates.
    criterion, alpha, forced
        As for :func:`mcfit.fit.fit_decay`.

    Returns
    -------
    DecayFit
        With ``method == "waveform"``; values, errors and Q from the waveform fit.
    """
    tw, xw, t0, nuisance = _window(t, x, turning, start_fit)
    noise = sample_noise(xw)
    starts = {c.model: c.values for c in start_fit.candidates}
    models = MODELS if forced is None else tuple(m for m in starts)
    candidates = {}
    for model in models:
        values = starts.get(model, starts.get(start_fit.model))
        start = np.array([values["y0"]] + nuisance + [values[k] for k in terms_of(model)])
        candidates[model] = _ranked(_Waveform(tw, xw, t0, terms_of(model), noise), start)
    selection = select_model(candidates, criterion, alpha, n_points=tw.size, forced=forced)
    return _reported(selection, candidates, tw, xw, t0, noise, start_fit)


def viscous_aicc(t, x, turning, start_fit):
    """AICc of the linear viscous oscillator x = e0 + e1*tau + y0*exp(-beta*tau)*cos(w*tau +
    theta0) (tau = t - t0) fitted to the same samples as :func:`fit_waveform`, in the same
    noise units: comparable with its candidates' AICc. Its turning points follow the
    averaged law with b = beta exactly, at any Q."""
    tw, xw, t0, nuisance = _window(t, x, turning, start_fit)
    noise = sample_noise(xw)
    tau = tw - t0
    rate = start_fit.values["b"] + start_fit.values["a"] * start_fit.values["y0"]

    def residual(p):
        y0, theta0, omega, e0, e1, beta = p
        return (e0 + e1 * tau + y0 * np.exp(-beta * tau) * np.cos(omega * tau + theta0)
                - xw) / noise

    start = np.array([start_fit.values["y0"]] + nuisance + [rate])
    lower, upper = _bounds(start[:5], ("b",))
    result = optimize.least_squares(residual, np.clip(start, lower, upper),
                                    bounds=(lower, upper), method="trf", x_scale="jac",
                                    **_TOLERANCES)
    return information_criteria(float(2 * result.cost), tw.size, start.size)[0]


def _window(t, x, turning, start_fit):
    """The finite samples from the first to the last used turning point, the start time
    and the start of the nuisance parameters (phase, frequency, offset, drift)."""
    used = np.flatnonzero(turning.used)
    t0, t_end = float(turning.t[used[0]]), float(turning.t[used[-1]])
    window = (t >= t0) & (t <= t_end) & np.isfinite(x)
    theta0 = 0.0 if turning.sign[used[0]] >= 0 else math.pi
    e0 = turning.equilibrium_at(t0)
    return t[window], x[window], t0, [theta0, start_fit.omega, e0, turning.equilibrium_drift]


def sample_noise(x):
    """The standard deviation of white noise on a smooth signal, from the robust scale of
    its sixth differences (a sine sampled 20 times a cycle passes 1e-3 of its amplitude;
    the noise 924**0.5 times its own). Residuals in these units make chi-square about one
    per sample."""
    sixth = np.diff(x, 6)
    scale = 1.4826 * float(np.median(np.abs(sixth - np.median(sixth)))) / math.sqrt(924.0)
    return scale if scale > 0 else float(np.std(x)) or 1.0


def _bounds(start, terms):
    """Amplitude and terms >= 0; the phase within half a cycle and the frequency within
    20 % of the turning points' (a wider step would count other cycles)."""
    lower = np.array([0.0, start[1] - math.pi / 2, 0.8 * start[2], -np.inf, -np.inf]
                     + [0.0] * len(terms))
    upper = np.array([np.inf, start[1] + math.pi / 2, 1.25 * start[2], np.inf, np.inf]
                     + [np.inf] * len(terms))
    return lower, upper


def _ranked(waveform, start):
    waveform.typical = np.maximum(np.abs(start), 1e-3 * abs(start[0]))
    waveform.typical[1] = 1.0
    lower, upper = _bounds(start, waveform.terms)
    result = optimize.least_squares(waveform.residual, np.clip(start, lower, upper),
                                    jac=waveform.jacobian, bounds=(lower, upper),
                                    method="trf", x_scale="jac", max_nfev=200, **_TOLERANCES)
    return _candidate(waveform, result.x, float(2 * result.cost), bool(result.success),
                      int(result.nfev), result.jac)


def _candidate(waveform, p, chi_square, success, evaluations, jacobian):
    n_params = p.size
    aicc, bic = information_criteria(chi_square, waveform.t.size, n_params)
    values = {"y0": float(p[0]), "a": 0.0, "b": 0.0, "c": 0.0}
    values.update({k: float(p[5 + i]) for i, k in enumerate(waveform.terms)})
    covariance = np.linalg.pinv(jacobian.T @ jacobian)
    correlation = {}
    for i, first in enumerate(waveform.terms):
        for j, second in enumerate(waveform.terms[i + 1:], start=i + 1):
            product = covariance[5 + i, 5 + i] * covariance[5 + j, 5 + j]
            correlation[f"{first},{second}"] = (float(covariance[5 + i, 5 + j]
                                                      / math.sqrt(product)) if product > 0 else 0.0)
    model = "".join(waveform.terms) or NONE
    return Candidate(model, n_params, chi_square, aicc, bic, success, values, evaluations,
                     correlation, np.asarray(p), None)


def _reported(selection, candidates, tw, xw, t0, noise, start_fit):
    """The selected model refitted with lmfit; errors, Q and warnings as a DecayFit."""
    from mcfit.fit.decay_fit import diagnose, tie_warning  # noqa: PLC0415 (import cycle)

    terms = selection.terms
    waveform = _Waveform(tw, xw, t0, terms, noise)
    start = candidates[selection.model].internal
    waveform.typical = np.maximum(np.abs(start), 1e-3 * abs(start[0]))
    waveform.typical[1] = 1.0
    params = lmfit.Parameters()
    lower, upper = _bounds(start, terms)
    for name, value, low, high in zip(waveform.names, start, lower, upper):
        params.add(name, value=min(max(value, low), high), min=low, max=high)
    result = lmfit_least_squares(lambda p: waveform.residual(_vector(p, waveform.names)),
                                 lambda p: waveform.jacobian(_vector(p, waveform.names)),
                                 params)
    p = _vector(result.params, waveform.names)
    chi_square = float(result.chisqr)
    dof = tw.size - p.size
    covariance = getattr(result, "covar", None)
    if covariance is None or not np.all(np.isfinite(covariance)):
        jacobian = waveform.jacobian(p)
        covariance = np.linalg.pinv(jacobian.T @ jacobian) * chi_square / max(dof, 1)
    errors = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    index = {name: i for i, name in enumerate(waveform.names)}
    values = {"y0": float(p[0]), "a": 0.0, "b": 0.0, "c": 0.0}
    values.update({k: float(p[index[k]]) for k in terms})
    stderr = dict.fromkeys(("y0", "a", "b", "c"))
    stderr.update({k: float(errors[index[k]]) for k in ("y0",) + tuple(terms)})
    law_free = ("y0",) + tuple(terms)
    law_index = [index[k] for k in law_free]
    law_covariance = covariance[np.ix_(law_index, law_index)]
    correlation = {f"{a},{b}": float(law_covariance[i, j] / (errors[index[a]] * errors[index[b]]))
                   for i, a in enumerate(law_free) for j, b in enumerate(law_free)
                   if i < j and errors[index[a]] > 0 and errors[index[b]] > 0}
    omega, omega_sigma = float(p[2]), float(errors[2] / p[2])
    fit = start_fit
    t_points = fit.t
    y_fit = decay.amplitude(t_points - t0, *(values[k] for k in ("y0", "a", "b", "c")))
    q = q_stderr = q_parts = q_summary = q_bound = None
    if selection.model == NONE:
        q_bound = None
    else:
        q, q_stderr = uncertainty.q_with_stderr(t_points - t0, values, law_covariance, law_free,
                                                omega, omega_sigma)
        parts = decay.quality_parts(y_fit, omega, values["a"], values["b"], values["c"])
        q_parts = {"coulomb": parts[0], "hysteretic": parts[1], "fluid": parts[2]}
        q_summary = uncertainty.summarise_q(q, q_stderr)
    residual = waveform.residual(p)
    errors_view = uncertainty.ParameterErrors(stderr, correlation, law_covariance)
    warnings = (selection.warnings() + tie_warning(selection, y_fit)
                + diagnose(terms, values, errors_view, residual, bool(result.success),
                           autocorrelation=False))
    return replace(
        fit, status="ok" if result.success else "error",
        message=None if result.success else "the waveform fit did not converge",
        model=selection.model, t0=t0, omega=omega, values=values, stderr=stderr,
        correlation=correlation, regimes={REGIME_NAMES[k]: k in terms for k in TERMS},
        lrt_p_values=selection.p_values, candidates=tuple(candidates.values()),
        n_points=tw.size, rms=float(noise * np.sqrt(np.mean(residual**2))),
        reduced_chi_square=chi_square / dof if dof > 0 else math.nan, selection=selection,
        y_fit=y_fit, q=q, q_stderr=q_stderr, q_parts=q_parts, q_summary=q_summary,
        q_lower_bound=q_bound, bootstrap=None, warnings=tuple(warnings), method="waveform")


def _vector(params, names):
    return np.array([params[name].value for name in names])
