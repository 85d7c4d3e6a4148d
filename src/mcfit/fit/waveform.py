"""Fit the record x(t) itself by the equation of motion, where the averaged law is not
accurate enough (low Q), and the estimate that decides when that is.

The averaged law dy/dt = -c - b*y - a*y**2 is first order in 1/Q: fitted to the turning
points of a record that obeys Eq. 20.55, its coefficients are biased by about 0.1/Q**2 of
their value (b at Q = 3: -1.2 %); :mod:`mcfit.model_error` predicts that bias for a
record. :func:`fit_waveform` fits x(t) = e0 + e1*(t - t0) + u(t), u the
solution of Eq. 20.55 from amplitude y0 and phase theta0 at t0 with frequency omega, for
the eight candidate models, started from the turning-point fit, and chooses among them
with :func:`mcfit.fit.selection.select_model` as the turning-point fit does.

Each term has two physical forms with the same averaged law (THEORY.md section 9):
Eq. 20.55's amplitude forms (``form="amplitude"``) and the velocity forms, viscous
2*beta*x' for b and sliding friction mu*sgn(x') for c (``form="velocity"``, exact in
closed form by :func:`mcfit.viscous_motion.viscous_motion`; quadratic drag for a has none
and is not offered). At low Q they differ at order 1/Q; :data:`FORMS` lists them.
"""

from __future__ import annotations

import math
from dataclasses import replace

import lmfit
import numpy as np
from scipy import fft, optimize
from scipy.stats import median_abs_deviation  # lmfit imports scipy.stats anyway

from mcfit import decay
from mcfit.errors import FitError
from mcfit.fit import uncertainty
from mcfit.fit.candidates import Candidate, information_criteria, lmfit_least_squares
from mcfit.fit.models import MODELS, NONE, REGIME_NAMES, TERMS, terms_of
from mcfit.fit.selection import LRT_ALPHA, select_model
from mcfit.phase_plane import phase_plane_differences
from mcfit.viscous_motion import coulomb_force, viscous_motion

__all__ = ["FORMS", "fit_waveform"]
# Nuisance parameters of the waveform besides y0: phase, frequency, offset, drift.
_NUISANCE = ("theta0", "omega", "e0", "e1")
_TOLERANCES = {"ftol": 1e-10, "xtol": 1e-10, "gtol": 1e-10}
# A candidate far from contention is fitted only until chi-square falls by less than this
# share in a step (within about 1e-5 of converged, in a third of the steps).
_SCREENING = {**_TOLERANCES, "ftol": 1e-6}
# Far from contention: AICc above the best by more than this. The selection's ties are
# within 2 and its tests reject a term for a chi-square drop of about 10.
_CONTENTION = 1000.0
# The turning-point fit's AICc within this of its best: likely in contention (fitted to
# full tolerance at once; the others are screened first).
_LIKELY = 20.0


class _Waveform:
    """The samples to fit, the residuals of the model x(t) and their Jacobian at a
    parameter vector (y0, theta0, omega, e0, e1, then the model's terms)."""

    def __init__(self, t, x, t0, terms, noise):
        self.t, self.x, self.t0, self.terms, self.noise = t, x, t0, terms, noise
        self.names = ("y0",) + _NUISANCE + tuple(terms)
        self.memory = {}  # the last solution of the motion starts the next

    def _motion(self, p):
        """(y0, theta0, omega, a, b, c) of each row of ``p``."""
        motion = np.zeros((p.shape[0], 6))
        motion[:, :3] = p[:, :3]
        for i, k in enumerate(self.terms):
            motion[:, 3 + TERMS.index(k)] = p[:, 5 + i]
        return motion

    def residual(self, parameters):
        """Residuals in noise units; the Jacobian at the same point comes with them (the
        solver asks for it next at every step it takes) and is kept for :meth:`jacobian`."""
        p = np.array(parameters, dtype=float)
        x, self._kept = self._with_jacobian(p)
        return (x - self.x) / self.noise

    def jacobian(self, parameters):
        p = np.asarray(parameters, dtype=float)
        kept = getattr(self, "_kept", None)
        if kept is not None and np.array_equal(kept[0], p):
            return kept[1]
        return self._with_jacobian(p)[1][1]

    def _with_jacobian(self, p):
        """x at ``p``, and (p, the Jacobian of the residuals) by forward differences of the
        motion (:meth:`_motion_changes`); offset and drift enter linearly."""
        tau = self.t - self.t0
        steps = 1e-7 * np.maximum(np.abs(p), self.typical)
        moved = [0, 1, 2] + list(range(5, p.size))
        motion, changes = self._motion_changes(tau, p, steps, moved)
        jacobian = np.empty((self.t.size, p.size))
        jacobian[:, moved] = changes.T / steps[moved]
        jacobian[:, 3] = 1.0
        jacobian[:, 4] = tau
        return motion + p[3] + p[4] * tau, (p.copy(), jacobian / self.noise)

    def _motion_changes(self, tau, p, steps, moved):
        """The motion at ``p`` and its changes when each parameter of ``moved`` moves by
        its step, from one solution (:func:`mcfit.phase_plane.phase_plane_differences`)."""
        return phase_plane_differences(tau, self._motion(p[None])[0],
                                       self._motion(np.diag(steps)[moved]), self.memory)


class _VelocityWaveform(_Waveform):
    """As :class:`_Waveform` for the velocity forms: viscous b and sliding friction c, the
    motion in closed form, each change a solution of its own."""

    def _motion_changes(self, tau, p, steps, moved):
        motion = self._x(tau, p)
        changes = np.array([self._x(tau, p + steps[i] * np.eye(p.size)[i]) - motion
                            for i in moved])
        return motion, changes

    def _x(self, tau, p):
        terms = dict(zip(self.terms, p[5:]))
        beta = min(terms.get("b", 0.0), 0.99 * p[2])
        return viscous_motion(tau, p[0], p[1], p[2], beta, terms.get("c", 0.0))


# The physical forms of the damping terms: the waveform model of each and the candidate
# models it offers (the velocity forms have no fluid term).
FORMS = {"amplitude": (_Waveform, MODELS),
         "velocity": (_VelocityWaveform, tuple(m for m in MODELS if "a" not in m))}


def fit_waveform(t, x, turning, start_fit, *, criterion="aicc", alpha=LRT_ALPHA,
                 forced=None, form="amplitude"):
    """Fit the samples between the first and the last used turning point by the equation
    of motion with the damping in ``form`` (a key of :data:`FORMS`).

    Parameters
    ----------
    t, x : ndarray, shape (n,)
        The record (s, U).
    turning : mcfit.turning.TurningPoints
        Its turning points (for the window, the first crest's sign and the equilibrium).
    start_fit : DecayFit
        The turning-point fit, whose candidates start the waveform candidates.
    criterion, alpha, forced
        As for :func:`mcfit.fit.fit_decay`; a ``forced`` model the form does not offer
        raises :class:`mcfit.errors.FitError`.

    Returns
    -------
    DecayFit
        With ``method == "waveform"`` and ``damping_form == form``; values, errors and Q
        from the waveform fit, ``physical`` the coefficients of the forces.
    """
    kind, offered = FORMS[form]
    if forced is not None and forced not in offered:
        raise FitError(f"the {form} forms have no model {forced!r}", option="model")
    tw, xw, t0, nuisance = _window(t, x, turning, start_fit)
    noise = sample_noise(xw)
    starts = {c.model: c.values for c in start_fit.candidates}
    models = (offered if forced is None
              else tuple(m for m in starts if m in offered))
    candidates, solutions = {}, {}
    waveforms = {model: kind(tw, xw, t0, terms_of(model), noise) for model in models}
    likely = _likely(start_fit, models)
    for model in models:
        values = starts.get(model, starts.get(start_fit.model))
        start = np.array([values["y0"]] + nuisance + [values[k] for k in terms_of(model)])
        candidates[model], solutions[model] = _ranked(
            waveforms[model], start, _TOLERANCES if model in likely else _SCREENING)
    best = min(c.aicc for c in candidates.values())
    for model in models:
        if model not in likely and (candidates[model].aicc - best <= _CONTENTION
                                    or model == forced):
            candidates[model], solutions[model] = _ranked(
                waveforms[model], solutions[model].x, _TOLERANCES, solutions[model].nfev)
    selection = select_model(candidates, criterion, alpha, n_points=tw.size, forced=forced)
    return _reported(selection, candidates, kind(tw, xw, t0, selection.terms, noise),
                     start_fit, form)


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
    """The standard deviation of white noise on a smooth oscillation, from the robust scale
    of its k-th differences, k chosen by :func:`_noise_difference_order` (6 from 20 samples
    a cycle: a sine passes 1e-3 of its amplitude, the noise 924**0.5 times its own; sixth
    differences at 8 samples a cycle passed 0.2 of a sine and read a noise of 1e-3 as
    3e-3). Residuals in these units make chi-square about one per sample."""
    order = _noise_difference_order(x)
    differences = np.diff(x, order)
    gain = math.sqrt(math.comb(2 * order, order))  # white noise's, sum of C(k, j)**2
    scale = (float(median_abs_deviation(differences, scale="normal")) / gain
             if differences.size else 0.0)
    return scale if scale > 0 else float(np.std(x)) or 1.0


# A sine leaks through the noise's differences, against white noise, as much as through
# sixth differences at 20 samples a cycle, or less.
_NOISE_LEAK = (2 * math.sin(math.pi / 20)) ** 6 / math.sqrt(924.0)


def _noise_difference_order(x):
    """The least difference order k >= 6 (40 and a quarter of the samples at most) at
    which a sine at the spectrum's peak, N samples a cycle, passes (2*sin(pi/N))**k of
    its amplitude, within _NOISE_LEAK of white noise's sqrt(C(2k, k))."""
    size = fft.next_fast_len(x.size, real=True)
    power = np.abs(fft.rfft(x - np.mean(x), size))
    peak = 1 + int(np.argmax(power[1:])) if power.size > 1 else 0
    step = 2 * math.sin(math.pi * min(peak / size, 0.5))
    most = max(6, min(40, x.size // 4))
    return next((k for k in range(6, most)
                 if step**k <= _NOISE_LEAK * math.sqrt(math.comb(2 * k, k))), most)


def _bounds(start, terms):
    """Amplitude and terms >= 0; the phase within half a cycle and the frequency within
    20 % of the turning points' (a wider step would count other cycles)."""
    lower = np.array([0.0, start[1] - math.pi / 2, 0.8 * start[2], -np.inf, -np.inf]
                     + [0.0] * len(terms))
    upper = np.array([np.inf, start[1] + math.pi / 2, 1.25 * start[2], np.inf, np.inf]
                     + [np.inf] * len(terms))
    return lower, upper


def _typical(start, terms):
    """The size below which a parameter's difference step stops shrinking: its start
    value, or a thousandth of its unit's natural scale (the amplitude U for y0, offset,
    drift and c; 1 for the phase and b; 1/U for a). A scale in the wrong unit (1e9 for b
    of a record in picometres) made the steps stop the motion at once."""
    y0 = abs(start[0])
    natural = np.array([y0, 1.0, 0.0, y0, y0] + [{"a": 1.0 / y0, "b": 1.0, "c": y0}[k]
                                                for k in terms])
    typical = np.maximum(np.abs(start), 1e-3 * natural)
    typical[1] = 1.0
    return typical


def _likely(start_fit, models):
    """The models the turning-point fit puts in contention (its AICc within ``_LIKELY``
    of its best): fitted to full tolerance at once. Only the cost depends on this."""
    scores = {c.model: c.aicc for c in start_fit.candidates
              if c.model in models and math.isfinite(c.aicc)}
    best = min(scores.values(), default=math.inf)
    return {m for m, score in scores.items() if score - best <= _LIKELY} | (
        set(models) - set(scores))


def _ranked(waveform, start, tolerances, evaluations=0):
    """The candidate fitted from ``start`` (a screening fit's end, which has already
    taken ``evaluations``, keeps the bounds and steps of the first start)."""
    if not evaluations:
        waveform.typical = _typical(start, waveform.terms)
        waveform.bounds = _bounds(start, waveform.terms)
    lower, upper = waveform.bounds
    result = optimize.least_squares(waveform.residual, np.clip(start, lower, upper),
                                    jac=waveform.jacobian, bounds=(lower, upper),
                                    method="trf", x_scale="jac",
                                    max_nfev=max(200 - evaluations, 10), **tolerances)
    result.nfev += evaluations
    return _candidate(waveform, result.x, float(2 * result.cost), bool(result.success),
                      int(result.nfev), result.jac), result


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


def _reported(selection, candidates, waveform, start_fit, form):
    """The selected model refitted with lmfit; errors, Q and warnings as a DecayFit."""
    from mcfit.fit.decay_fit import diagnose, tie_warning  # noqa: PLC0415 (import cycle)

    terms, tw, t0, noise = selection.terms, waveform.t, waveform.t0, waveform.noise
    start = candidates[selection.model].internal
    waveform.typical = _typical(start, terms)
    dof = tw.size - start.size
    # lmfit reports the fit (it restarts at the ranking fit's solution and stops there).
    params = lmfit.Parameters()
    lower, upper = _bounds(start, terms)
    for name, value, low, high in zip(waveform.names, start, lower, upper):
        params.add(name, value=min(max(value, low), high), min=low, max=high)
    result = lmfit_least_squares(lambda p: waveform.residual(_vector(p, waveform.names)),
                                 lambda p: waveform.jacobian(_vector(p, waveform.names)),
                                 params)
    p, success = _vector(result.params, waveform.names), bool(result.success)
    chi_square = float(result.chisqr)
    covariance = getattr(result, "covar", None)
    residual = waveform.residual(p)
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
    errors_view = uncertainty.ParameterErrors(stderr, correlation, law_covariance)
    warnings = (selection.warnings() + tie_warning(selection, y_fit)
                + diagnose(terms, values, errors_view, residual, success))
    return replace(
        fit, status="ok" if success else "error",
        message=None if success else "the waveform fit did not converge",
        model=selection.model, t0=t0, omega=omega, values=values, stderr=stderr,
        correlation=correlation, regimes={REGIME_NAMES[k]: k in terms for k in TERMS},
        lrt_p_values=selection.p_values, candidates=tuple(candidates.values()),
        n_points=tw.size, rms=float(noise * np.sqrt(np.mean(residual**2))),
        reduced_chi_square=chi_square / dof if dof > 0 else math.nan, selection=selection,
        y_fit=y_fit, q=q, q_stderr=q_stderr, q_parts=q_parts, q_summary=q_summary,
        q_lower_bound=q_bound, bootstrap=None, warnings=tuple(warnings), method="waveform",
        damping_form=form, physical=physical_coefficients(form, terms, values, stderr, omega))


# Each form's force per unit mass for each term: (name, force, coefficient from the
# averaged law's (value, omega), unit; U the signal's unit). THEORY.md section 9.
_FORCES = {
    "amplitude": {"a": ("a", "(pi*w/2)*a*A**2*sgn(x')", lambda v, w: v, "1/(U*s)"),
                  "b": ("b", "(pi*w/2)*b*A*sgn(x')", lambda v, w: v, "1/s"),
                  "c": ("mu", "mu*sgn(x')", coulomb_force, "U/s**2")},
    "velocity": {"b": ("beta", "2*beta*x'", lambda v, w: v, "1/s"),
                 "c": ("mu", "mu*sgn(x')", coulomb_force, "U/s**2")},
}


def physical_coefficients(form, terms, values, stderr, omega):
    """The coefficients of the forces of ``terms`` in ``form`` (per unit mass): name ->
    {"term", "value", "stderr", "force", "unit"}, U the signal's unit."""
    found = {}
    for term in terms:
        name, force, coefficient, unit = _FORCES[form][term]
        error = stderr.get(term)
        found[name] = {"term": term, "value": coefficient(values[term], omega),
                       "stderr": None if error is None else coefficient(error, omega),
                       "force": force, "unit": unit}
    return found


def _vector(params, names):
    return np.array([params[name].value for name in names])
