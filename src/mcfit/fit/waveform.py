"""Fit the record x(t) itself by the equation of motion, where the averaged law is not
accurate enough (low Q), and the estimate that decides when that is.

The averaged law dy/dt = -c - b*y - a*y**2 is first order in 1/Q: fitted to the turning
points of a record that obeys Eq. 20.55, its coefficients are biased by about 0.1/Q**2 of
their value (b at Q = 3: -1.2 %); :mod:`mcfit.model_error` predicts that bias for a
record. :func:`fit_waveform` fits x(t) = e0 + e1*(t - t0) + u(t), u the
solution of Eq. 20.55 from amplitude y0 and phase theta0 at t0 with frequency omega, for
the eight candidate models, started from the turning-point fit, and chooses among them
with :func:`mcfit.fit.selection.select_model` as the turning-point fit does.

Each term has two physical forms with the same averaged law (docs/theory.md section 5):
Eq. 20.55's amplitude forms (``form="amplitude"``) and the velocity forms, viscous
2*beta*x' for b, quadratic drag kappa*x'*|x'| for a and sliding friction mu*sgn(x') for c
(``form="velocity"``, in closed form by :func:`mcfit.viscous_motion.viscous_motion`
without drag, integrated by :mod:`mcfit.equation_of_motion` with it). At low Q they differ
at order 1/Q; :data:`FORMS` lists them, each form's model and Jacobian a law of
:mod:`mcfit.fit.waveform_laws`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import fft, linalg, optimize
from scipy.stats import median_abs_deviation  # lmfit imports scipy.stats anyway

from mcfit import decay
from mcfit.errors import FitError
from mcfit.fit import uncertainty
from mcfit.fit.candidates import Candidate, information_criteria
from mcfit.fit.decay_fit import DecayFit
from mcfit.fit.diagnostics import fit_warnings, misfit_warning
from mcfit.fit.models import MODELS, NONE, REGIME_NAMES, TERMS, terms_of
from mcfit.fit.reported import lmfit_parameters, solve_reported
from mcfit.fit.selection import LRT_ALPHA, select_model
from mcfit.fit.waveform_laws import NUISANCE, amplitude_waveform, velocity_waveform
from mcfit.turning.common import HALF_CYCLE_SPACING
from mcfit.viscous_motion import coulomb_force

__all__ = ["FORMS", "FORM_TIE", "WaveformFit", "WaveformStart", "RankedForm", "fit_waveform",
           "OpenedForm", "open_form", "rank_form", "rank_forms", "report_form", "fit_candidate",
           "within_noise"]
_TOLERANCES = {"ftol": 1e-10, "xtol": 1e-10, "gtol": 1e-10}
# The models fitted after the first are ranked, not reported (the one selected is
# refitted in full): fitted until chi-square falls by less than this share in a step,
# far finer than the selection's thresholds (chi-square differences of 2 to 18).
_RANKING = {**_TOLERANCES, "ftol": 1e-6}
# A candidate is estimated from the best fitted one (the quadratic model of chi-square
# about its solution) and fitted only where the estimate may change the choice: its AICc
# within _DECISIVE of the best's (the selection's ties lie within 7.15 and its "near the
# threshold" tests within 17.7, in the same units), unless it adds terms to the best that
# lower chi-square by less than _NEGLIGIBLE (half of the 1.97 below which a test is not
# "near the threshold"; the AICc penalty of a term is 2).
_DECISIVE = 60.0
_NEGLIGIBLE = 1.0
# Evaluations of the second form's first fit after which its candidates are estimated
# against the bar the first form sets (rank_form's rival; _glimpse).
_GLIMPSE = 3
# Selected models of two forms whose AICc differ by no more than this cannot be told
# apart (Burnham and Anderson: a difference above 10 leaves the worse model no support).
FORM_TIE = 10.0


@dataclass(frozen=True, eq=False, repr=False)  # DecayFit's short repr
class WaveformFit(DecayFit):
    """A :class:`DecayFit` whose values come from the waveform fit by the equation of
    motion: the averaged law's a, b, c (so Q(t) keeps its meaning), the form of the damping
    forces fitted (``damping_form``: "amplitude", "velocity" or "cannot tell", and why) and
    the forces' own coefficients (``physical``: name -> value, stderr, force, unit)."""

    method: str = "waveform"
    damping_form: str = "amplitude"
    damping_form_reason: str | None = None
    physical: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """:meth:`DecayFit.to_dict` with the damping form and the forces' coefficients."""
        from mcfit import plain

        return plain.before_warnings(super().to_dict(), {
            "damping_form": self.damping_form, "damping_form_reason": self.damping_form_reason,
            "physical": {name: {**entry, "value": plain.number(entry["value"]),
                                "stderr": plain.number(entry["stderr"])}
                         for name, entry in self.physical.items()}})


@dataclass(frozen=True)
class WaveformStart:
    """Where a waveform fit starts: each model's start values (y0, a, b, c), the model
    fitted first (the turning-point fit's choice; its values start a model without its
    own; None: the model whose start lies nearest the record, among the models of
    ``among`` where given), the frequency, and the turning points (times, amplitudes,
    sigma) at which the result gives the law's amplitude."""

    values: dict
    model: str | None
    omega: float
    t: np.ndarray = field(repr=False)
    y: np.ndarray = field(repr=False)
    sigma: np.ndarray = field(repr=False)
    among: tuple | None = None

    @classmethod
    def of_fit(cls, fit):
        """The start a turning-point :class:`DecayFit` gives."""
        return cls({c.model: c.values for c in fit.candidates}, fit.model, fit.omega,
                   fit.t, fit.y, fit.sigma)


# The physical forms of the damping terms: the waveform model of each and the candidate
# models it offers.
FORMS = {"amplitude": (amplitude_waveform, MODELS), "velocity": (velocity_waveform, MODELS)}


def fit_waveform(t, x, turning, start, *, criterion="aicc", alpha=LRT_ALPHA,
                 forced=None, form="amplitude", kind=None):
    """Fit the samples between the first and the last used turning point by the equation
    of motion with the damping in ``form`` (a key of :data:`FORMS`).

    Parameters
    ----------
    t, x : ndarray, shape (n,)
        The record (s, U).
    turning : mcfit.turning.TurningPoints
        Its turning points (for the window, the first crest's sign and the equilibrium).
    start : WaveformStart
        Where the candidates start (:meth:`WaveformStart.of_fit` of the turning-point fit).
    criterion, alpha, forced
        As for :func:`mcfit.fit.fit_decay`; a ``forced`` model the form does not offer
        raises :class:`mcfit.errors.FitError`.
    kind : callable, optional
        The waveform model in place of the form's (a pendulum's equation of motion).

    Returns
    -------
    WaveformFit
        With ``damping_form == form``; values, errors and Q from the waveform fit,
        ``physical`` the coefficients of the forces.
    """
    ranked = rank_form(t, x, turning, start, criterion=criterion, alpha=alpha,
                       forced=forced, form=form, kind=kind)
    return report_form(ranked, start)


@dataclass(frozen=True)
class RankedForm:
    """One form's candidates (fitted or estimated) and the model they select, before the
    reported fit (:func:`report_form`); ``law`` is the selected model's waveform law, and
    ``solution`` its reported fit where the model fitted first was selected (None
    else)."""

    form: str
    selection: object
    candidates: dict
    law: object = field(repr=False)
    solution: object = field(default=None, repr=False)

    @property
    def aicc(self) -> float:
        """The selected model's AICc."""
        return self.candidates[self.selection.model].aicc


@dataclass(frozen=True)
class OpenedForm:
    """One form's laws on the record's window (``waveforms``: model -> law; ``law``:
    terms -> a new one), each model's start vector, the undamped frequency the crests
    imply and, once fitted, the first model's fit from its start (``first``, a
    Candidate, with lmfit's ``solution``)."""

    form: str
    law: object = field(repr=False)
    waveforms: dict = field(repr=False)
    vectors: dict = field(repr=False)
    undamped: float
    first: object = None
    solution: object = field(default=None, repr=False)

    @property
    def n_points(self) -> int:
        """The samples in the window."""
        return next(iter(self.waveforms.values())).t.size

    @property
    def noise(self) -> float:
        """The window's sample noise, in the record's units."""
        return next(iter(self.waveforms.values())).noise


def open_form(t, x, turning, start, *, form="amplitude", kind=None, forced=None, noise=None,
              fit=True):
    """``form``'s :class:`OpenedForm` on the record, with the sample ``noise`` given
    (another form's, on the same window) or estimated, and with ``fit`` its first model
    fitted from its start: ``forced``, else the start's model, else (None) the one whose
    start lies nearest the record (:func:`_first_model`). Without a start model or models
    to choose among (auto_start's distrust) the laws start at the undamped frequency, else
    at the crests' (from the undamped one, a + c at Q = 5.3 went to a false minimum)."""
    kind, offered = FORMS[form] if kind is None else (kind, FORMS[form][1])
    if forced is not None and forced not in offered:
        raise FitError(f"the {form} forms have no model {forced!r}", option="model")
    undamped = undamped_frequency(turning, start.omega)
    tw, xw, t0, nuisance = _window(t, x, turning,
                                   start.omega if start.model or start.among or forced
                                   else undamped)
    noise = sample_noise(xw) if noise is None else noise
    starts = start.values
    models = (offered if forced is None
              else tuple(m for m in starts if m in offered))
    waveforms = {model: kind(tw, xw, t0, terms_of(model), noise) for model in models}
    vectors = {model: _start_vector(starts.get(model, starts.get(start.model)), nuisance,
                                    model) for model in models}
    opened = OpenedForm(form, lambda terms: kind(tw, xw, t0, terms, noise), waveforms,
                        vectors, undamped)
    return _with_first_fit(opened, start, forced) if fit else opened


def _with_first_fit(opened, start, forced):
    """``opened`` with its first model fitted from its start (as it is, where fitted)."""
    if opened.first is not None:
        return opened
    first = forced or _first_model(start.model, opened.waveforms, opened.vectors,
                                   start.among)
    candidate, solution = _fitted_as_reported(opened.waveforms[first], opened.vectors[first])
    return replace(opened, first=candidate, solution=solution)


def rank_forms(t, x, turning, start, *, criterion="aicc", forced=None, noise=None):
    """{form: RankedForm} for each form of :data:`FORMS` that offers ``forced`` (every
    form without it): one ranked alone, then the others against it (:func:`rank_form`'s
    rival). The amplitude forms go first, unless their first fit does not describe the
    record within its noise and the velocity forms' first fit of the same model does,
    and better: then the velocity forms go first, and the amplitude forms close on
    estimates from their first fit, or are ranked from it as they would be first, down to
    the velocity forms' bar (on a viscous oscillator at Q = 3 the amplitude forms' b
    misfits; ranking them first cost a second b, a + b + c and a + b, about 30 ms).
    ``noise``: the sample noise in the record's units (default: :func:`sample_noise` of
    the window)."""
    forms = [form for form, (_, offered) in FORMS.items() if forced is None or forced in offered]
    if not forms:
        return {}
    lead = forms[0]
    opened = {lead: open_form(t, x, turning, start, form=lead, forced=forced, noise=noise)}
    if forced is None and len(forms) > 1 and _may_not_lead(opened[lead]):
        other = opened[forms[1]] = open_form(t, x, turning, start, form=forms[1],
                                             noise=opened[lead].noise)
        if _leads(other.first, opened[lead].first, other.n_points):
            lead = forms[1]
    ranked = {lead: rank_form(t, x, turning, start, criterion=criterion, forced=forced,
                              form=lead, opened=opened[lead])}
    for form in forms:
        if form == lead:
            continue
        if lead != forms[0]:  # the first form, opened, against the one that went first
            ranked[form] = _ranked_alone(opened[form], start, criterion, LRT_ALPHA, forced,
                                         rival=ranked[lead])
        else:
            ranked[form] = rank_form(t, x, turning, start, criterion=criterion,
                                     forced=forced, form=form, rival=ranked[lead],
                                     opened=opened.get(form))
    return ranked


def _leads(first, other, n_points):
    """Whether the form whose first fit is ``first`` goes before the one whose first fit
    is ``other``: the same model, ``first`` within its noise and lower (first fits of
    two models may only say which start lay nearer: at Q = 3 with b and c and a noise of
    3e-2 of y0, c and b + c)."""
    return (first.model == other.model and within_noise(first, n_points)
            and first.aicc < other.aicc)


def _may_not_lead(opened):
    """Whether another form may describe the record where ``opened``'s first fit does not
    (no damping has no form)."""
    first = opened.first
    return first.model != NONE and not within_noise(first, opened.n_points)


def rank_form(t, x, turning, start, *, criterion="aicc", alpha=LRT_ALPHA, forced=None,
              form="amplitude", kind=None, rival=None, opened=None):
    """The candidate step of :func:`fit_waveform` in ``form``, from ``opened``
    (:func:`open_form`; opened here without it).

    Alone: from the first fit; where it misfits, fitted again from the turning-point
    values at the undamped frequency the crests imply (:func:`_retuned`; at Q = 3 with a
    Coulomb stop, the crests' frequency is 11 % below omega).

    With ``rival`` (another form's :class:`RankedForm`): the first model is the one the
    rival selected where that describes the record within its noise, else the start's
    (:func:`_first_after`), started from the rival's values, and the step stops where no
    candidate can come within :data:`FORM_TIE` of the rival's AICc (the candidates are
    then those fitted so far and estimates). Where the rival describes the record within
    its noise, that can be after a few steps of the first fit (:func:`_glimpse`). Where it
    does not, or where the model is forced (nothing else is fitted then), the rival's
    values may sit in a false minimum: the first model is fitted from the turning-point
    values too (the fit ``opened`` holds, where it is of that model), the better kept.
    """
    if opened is None:
        opened = open_form(t, x, turning, start, form=form, kind=kind, forced=forced,
                           noise=None if rival is None else rival.law.noise,
                           fit=rival is None)
    if rival is None:
        return _ranked_alone(opened, start, criterion, alpha, forced)
    return _ranked_after(opened, start.model, rival, criterion, alpha, forced)


def _ranked_alone(opened, start, criterion, alpha, forced, rival=None):
    """:func:`rank_form` from this form's own first fit: without a rival, or against one
    (:func:`rank_forms`' second form where the other went first) closed on estimates
    from that fit where none can come within the rival's bar (:func:`_closed`), else
    ranked down to the bar."""
    opened = _with_first_fit(opened, start, forced)
    candidate, solution, vectors = opened.first, opened.solution, opened.vectors
    bar = bar_fits = None
    if rival is not None:
        bar = rival.aicc + FORM_TIE + _DECISIVE
        bar_fits = not _misfits(rival.candidates[rival.selection.model], opened.n_points)
        closed = _closed(opened.waveforms, candidate, bar)
        if closed is not None:
            candidates = {**closed, candidate.model: candidate}
            return _selected_form(opened, candidates, candidate, solution, criterion, alpha,
                                  forced)
    if _misfits(candidate, opened.n_points):
        candidate, solution, vectors = _retuned(
            opened.waveforms[candidate.model], candidate, solution, vectors,
            vectors[candidate.model], opened.undamped)
    candidates = _fitted_candidates(opened.waveforms, vectors, candidate, forced, bar,
                                    bool(bar_fits))
    return _selected_form(opened, candidates, candidate, solution, criterion, alpha, forced)


def _ranked_after(opened, model, rival, criterion, alpha, forced):
    """:func:`rank_form` against ``rival``, ``model`` the start's."""
    waveforms, n_points = opened.waveforms, opened.n_points
    first = forced or _first_after(rival, model, n_points)
    own, vectors = opened.vectors[first], dict(opened.vectors)
    vectors[first] = rival.candidates[first].internal
    bar = rival.aicc + FORM_TIE + _DECISIVE
    bar_fits = first == rival.selection.model and not _misfits(
        rival.candidates[rival.selection.model], n_points)
    opening = None  # the fit from the own start, where the form was opened by it
    if opened.first is not None and opened.first.model == first:
        opening = opened.first, opened.solution
    candidates = candidate = solution = None
    if bar_fits and forced is None:
        vectors[first], candidates = _glimpse(waveforms, first, vectors[first], bar)
    if candidates is None:
        fits = [_fitted_as_reported(waveforms[first], vectors[first])]
        if forced or not bar_fits:  # a false minimum, maybe
            fits.append(opening or _fitted_as_reported(waveforms[first], own))
        candidate, solution = min(fits, key=lambda fit: fit[0].chi_square)
        if _misfits(candidate, n_points):
            candidate, solution, vectors = _retuned(waveforms[first], candidate, solution,
                                                    vectors, own, opened.undamped)
        candidates = _fitted_candidates(waveforms, vectors, candidate, forced, bar, bar_fits)
    return _selected_form(opened, candidates, candidate, solution, criterion, alpha, forced)


def _selected_form(opened, candidates, candidate, solution, criterion, alpha, forced):
    """The :class:`RankedForm` of ``candidates``, with the first fit's ``solution`` where
    its ``candidate`` is selected."""
    selection = select_model(candidates, criterion, alpha, n_points=opened.n_points,
                             forced=forced)
    if solution is not None and candidates[selection.model] is candidate:
        return RankedForm(opened.form, selection, candidates,
                          opened.waveforms[candidate.model], solution)
    return RankedForm(opened.form, selection, candidates, opened.law(selection.terms))


def _first_after(rival, model, n_points):
    """The second form's first model: the one ``rival`` selected where that describes the
    record within its noise, else ``model`` (the start's, where it has a term; a choice
    from a misfit is no better than its estimates: on a viscous oscillator at Q = 3 the
    amplitude forms select a + b + c, whose drag is integrated, 15 and 10 evaluations
    from two starts, where b is the answer). From the start's model the second form is
    fitted from both starts, not glimpsed (rank_form)."""
    chosen = rival.selection.model
    if model in (None, NONE) or model not in rival.candidates or within_noise(
            rival.candidates[chosen], n_points):
        return chosen
    return model


def _retuned(waveform, candidate, solution, vectors, begin, omega):
    """Where the first fit misfits: (candidate, solution, vectors) of the fit from the
    turning-point start ``begin`` at the undamped frequency ``omega``
    (:func:`undamped_frequency`), with ``vectors`` at that frequency, where it ends lower
    by a likelihood-ratio statistic above _NEGLIGIBLE; else the fit as it was."""
    if abs(omega - begin[2]) <= 1e-3 * begin[2]:
        return candidate, solution, vectors
    again, solved = _fitted_as_reported(waveform, _at_frequency(begin, omega))
    if _statistic(candidate, again, waveform.t.size) <= _NEGLIGIBLE:
        return candidate, solution, vectors  # no better, or by rounding only
    return again, solved, {m: _at_frequency(v, omega) for m, v in vectors.items()}


def _at_frequency(vector, omega):
    moved = vector.copy()
    moved[2] = omega
    return moved


def _glimpse(waveforms, first, start, bar):
    """(where a few steps of ``first``'s fit from ``start`` end, :func:`_closed` from
    there)."""
    partial = _ranked(waveforms[first], start, _TOLERANCES, _GLIMPSE)[0]
    return partial.internal, _closed(waveforms, partial, bar)


def _closed(waveforms, reached, bar):
    """Every candidate estimated from ``reached`` (a fit, finished or a few steps in), or
    None unless the estimates show that no model of the form can come below ``bar``:
    every one above it by more than twice what ``reached`` is estimated to gain still (an
    estimate from a point short of a minimum can fall short of what a fit would reach)."""
    estimates = _estimates(waveforms[_largest(waveforms)], reached, set(waveforms))
    gain = max(reached.aicc - estimates[reached.model].aicc, 0.0)
    if min(e.aicc for e in estimates.values()) <= bar + 2 * gain:
        return None
    return estimates


def report_form(ranked, start):
    """The reported :class:`WaveformFit` of a :class:`RankedForm`."""
    return _reported(ranked.selection, ranked.candidates, ranked.law, start, ranked.form,
                     ranked.solution)


def _fitted_as_reported(waveform, start):
    """The model fitted first, by the reported fit's solver (lmfit), as the selection is
    most often its: (its Candidate, the :class:`mcfit.fit.reported.Solution`)."""
    solution = _solved(waveform, start)
    covariance = (np.full((start.size, start.size), np.nan) if solution.covariance is None
                  else solution.covariance)
    return _candidate(waveform.terms, waveform.t.size, solution.x, solution.chi_square,
                      solution.success, solution.evaluations, covariance), solution


def _solved(waveform, start):
    """lmfit's fit of ``waveform`` from ``start``, with the bounds and steps it sets."""
    waveform.typical = _typical(start, waveform.terms)
    waveform.bounds = _bounds(start, waveform.terms)
    return solve_reported(waveform, lmfit_parameters(waveform.free, start, *waveform.bounds))


def _start_vector(values, nuisance, model):
    return np.array([values["y0"]] + nuisance + [values[k] for k in terms_of(model)])


def _first_model(model, waveforms, vectors, among=None):
    """``model`` where the form offers it, the largest model where it does not, and where
    it is None the model (of ``among``, where given) whose waveform at its start vector
    in ``vectors`` lies nearest the record: least chi-square, each term counted 2 as in
    the AIC (a pendulum's b + c whose c started at 2e-10 beside b: 10 evaluations where b
    took 5); of equal starts, the fewest terms."""
    if model is not None:
        return model if model in waveforms else _largest(waveforms)
    found = {}  # chi-square by start vector (a model with a term at 0 starts as another)
    choices = [m for m in waveforms if among is None or m in among] or list(waveforms)
    for name in sorted(choices, key=lambda m: len(terms_of(m))):
        law, begin = waveforms[name], vectors[name]
        key = tuple(begin[:5]) + tuple((k, v) for k, v in zip(law.terms, begin[5:]) if v)
        if key not in found:
            law.typical = _typical(begin, law.terms)
            found[key] = (law.chi_square(begin) + 2 * len(law.terms), name)
    return min(found.values())[1]


def _largest(models):
    return max(models, key=lambda m: len(terms_of(m)))


def _fitted_candidates(waveforms, vectors, first, forced, bar=None, bar_fits=False):
    """{model: Candidate} for the models of ``waveforms``, ``first`` (a Candidate) fitted.

    The others are estimated from the best fitted one (:func:`_estimates`) and fitted
    where the estimate may change the choice (:func:`_may_matter`), again from each new
    best, until none may; each as :func:`_fit_estimated` does, from its estimate from the
    fitted model it extends where there is one (:func:`_parent`). Where every such model
    adds terms to a best that describes the record within its noise (a small step from
    a good fit: the estimates are close), one at a time, the lowest estimated AICc first,
    so that a model whose estimate only sets a term of the next best at 0 (a + b + c's
    from b + c at Q = 2 with b alone) is not fitted; else all at once (from a first fit
    in another minimum the estimates are far off: one at a time, b + c went unfitted at
    Q = 4 and 5 with a noise of 1e-2 of y0 from c, reduced chi-square 1.9, and from
    a + c, and a stuck a + b + c was reported 6-35 standard errors off). A fitted model
    that adds terms to a new best is refitted where it stopped above its estimate
    (:func:`_refit_stuck`). Where the best misfits, the largest model is fitted from its
    own start (an estimate far from a misfit may miss a better minimum).

    With ``bar``, the step stops where neither the best nor any estimate has an AICc below
    it: at once where the model that sets the bar describes the record within its noise
    (``bar_fits``), else only once the best here does or the largest model is fitted.
    """
    fitted = {first.model: first}
    top = _largest(waveforms)
    n_points = waveforms[top].t.size
    reference, earlier = None, {}  # earlier: id of a best -> (it, its estimates)
    while True:
        best = fitted[forced] if forced else min(fitted.values(), key=lambda c: c.aicc)
        if best is not reference:
            reference = best
            estimates = _estimates(waveforms[top], best, set(waveforms) - {best.model})
            earlier[id(best)] = best, estimates
            _refit_stuck(fitted, estimates, best, waveforms, n_points)
            unfitted = [e for m, e in estimates.items() if m not in fitted]
            if (bar is not None and min([best.aicc] + [e.aicc for e in unfitted]) > bar
                    and (bar_fits or top in fitted or not _misfits(best, n_points))):
                break
        pending = sorted((e for m, e in estimates.items()
                          if m not in fitted and _may_matter(e, best, n_points)),
                         key=lambda e: e.aicc)
        misfits = _misfits(best, n_points)
        close = within_noise(best, n_points) and all(
            set(best.terms) < set(e.terms) for e in pending)
        for estimate in pending[:1] if close else pending:
            parent, made = _parent(estimate.model, best, fitted, earlier)
            fitted[estimate.model] = _fit_estimated(waveforms, vectors,
                                                    made[estimate.model], parent, made)
        if pending:
            continue
        if top in fitted or not misfits:
            break
        fitted[top] = _ranked(waveforms[top], vectors[top], _RANKING)[0]
    return {m: fitted.get(m) or estimates[m] for m in waveforms}


def _parent(model, best, fitted, earlier):
    """(the fitted model ``model`` adds terms to with the least chi-square of those
    estimated from, its estimates), or (``best``, its estimates) where there is none:
    from there the estimate is a small step (a + b at Q = 2 with b alone from b, one
    evaluation, where from the best b + c, which it does not contain, it took three)."""
    parents = [earlier[id(c)] for c in fitted.values()
               if id(c) in earlier and set(c.terms) < set(terms_of(model))]
    if not parents:
        return earlier[id(best)]
    return min(parents, key=lambda pair: pair[0].chi_square)


def _fit_estimated(waveforms, vectors, estimate, source, estimates):
    """The ranking fit of the model of ``estimate`` (made from the fitted ``source``, as
    the rest of ``estimates``): from the estimate where the model adds terms to the
    source, has no sliding friction (a smooth motion) or drops only terms the source can
    do without (:func:`_dispensable`: a small step), else from its start in ``vectors``
    (from an estimate that drops terms, a fit with sliding friction stopped at a kink of
    the motion, where the swing that stops changes)."""
    model = estimate.model
    if ("c" not in estimate.terms or set(source.terms) <= set(estimate.terms)
            or _dispensable(source, estimate, estimates, waveforms[model].t.size)):
        return _from_estimate(waveforms[model], estimate)
    return _ranked(waveforms[model], vectors[model], _RANKING)[0]


def _dispensable(source, estimate, estimates, n_points):
    """Whether the terms of ``source`` that ``estimate`` drops lower chi-square by less
    than _NEGLIGIBLE (``estimates`` has source without them): within about a standard
    error of 0 (a pendulum at Q = 3 whose a + b fit ends at a = 2e-5, against b + c)."""
    kept = "".join(k for k in source.terms if k in estimate.terms) or NONE
    without = estimates.get(kept)
    return (without is not None and without.chi_square >= source.chi_square
            and _statistic(without, source, n_points) < _NEGLIGIBLE)


def _refit_stuck(fitted, estimates, best, waveforms, n_points):
    """Refit, from its estimate, each fitted model that adds terms to ``best`` but whose
    fit ended above what the estimate from ``best`` reaches (a fit from an earlier, worse
    start stuck at a kink of the motion), keeping the lower of the two."""
    for model in [m for m in fitted if set(best.terms) < set(terms_of(m))]:
        if _statistic(fitted[model], estimates[model], n_points) > _NEGLIGIBLE:
            again = _from_estimate(waveforms[model], estimates[model])
            if again.chi_square < fitted[model].chi_square:
                fitted[model] = again


def _from_estimate(waveform, estimate):
    """The candidate ``estimate`` fitted by the ranking fit: the estimate itself,
    evaluated, where the Gauss-Newton step from it (within the bounds) would lower
    chi-square by less than the ranking's tolerance (the ranking fit from there takes
    that step and stops: two evaluations; the estimate's chi-square is within the
    tolerance of it, its values within about 0.1 standard errors, 0.02 on the records
    tried); else fitted from there."""
    begin = estimate.internal
    waveform.typical = _typical(begin, waveform.terms)
    lower, upper = waveform.bounds = _bounds(begin, waveform.terms)
    p = np.clip(begin, lower, upper)
    residual = waveform.residual(p)
    orthogonal, triangle = linalg.qr(waveform.jacobian(p), mode="economic")
    projected = orthogonal.T @ residual
    step = _bounded_least_squares(triangle, -projected, lower - p, upper - p)
    gain = projected @ projected - np.sum((triangle @ step + projected) ** 2)
    chi_square = float(residual @ residual)
    if gain > _RANKING["ftol"] * chi_square:
        return _ranked(waveform, begin, _RANKING)[0]
    return _candidate(waveform.terms, waveform.t.size, p, chi_square, True, 1,
                      np.linalg.pinv(triangle.T @ triangle))


def within_noise(candidate, n_points):
    """Whether ``candidate`` describes the record within its noise: reduced chi-square
    within 5 of its standard deviations sqrt(2/dof) of 1 (a misfit is far above that)."""
    dof = n_points - candidate.n_params
    return dof > 0 and candidate.chi_square / dof <= 1.0 + 5.0 * math.sqrt(2.0 / dof)


def _misfits(candidate, n_points):
    return bool(misfit_warning(candidate.chi_square / (n_points - candidate.n_params),
                               n_points - candidate.n_params))


def _may_matter(estimate, best, n_points):
    """Whether ``estimate`` may change the choice among candidates (the selection's ties,
    tests and thresholds; see ``_DECISIVE``), ``best`` fitted to ``n_points``."""
    if estimate.aicc - best.aicc > _DECISIVE:
        return False
    adds = set(best.terms) < set(estimate.terms)
    return not (adds and _statistic(best, estimate, n_points) < _NEGLIGIBLE)


def _statistic(higher, lower, n_points):
    """The likelihood-ratio statistic of ``lower``'s chi-square against ``higher``'s, in
    the units of AICc."""
    return n_points * math.log(higher.chi_square / max(lower.chi_square, 1e-300))


def _estimates(largest, best, models):
    """{model: Candidate} for ``models``, each estimated from the fitted ``best``: the
    chi-square of the quadratic model of the residuals about ``best``'s solution, the
    Jacobian that of the ``largest`` waveform (every term, absent ones at 0), minimised
    with the terms each model drops at 0 and the others >= 0 (scipy's bounded linear least
    squares). A model whose terms change little from ``best`` is estimated closely (the
    model is quadratic in the change); the others are only ranked."""
    index = {k: 5 + i for i, k in enumerate(largest.terms)}
    at = np.zeros(5 + len(largest.terms))
    at[:5] = best.internal[:5]
    for i, k in enumerate(best.terms):
        at[index[k]] = best.internal[5 + i]
    largest.typical = _typical(at, largest.terms)
    residual = largest.residual(at)
    orthogonal, triangle = linalg.qr(largest.jacobian(at), mode="economic")
    projected = orthogonal.T @ residual
    n = residual.size
    found = {}
    for model in models:
        free = list(range(5)) + [index[k] for k in terms_of(model)]
        fixed = [i for i in range(at.size) if i not in free]
        lower = np.full(len(free), -np.inf)
        lower[5:] = -at[free[5:]]  # terms >= 0
        target = -(projected - triangle[:, fixed] @ at[fixed])
        step = _bounded_least_squares(triangle[:, free], target, lower, np.inf)
        rise = float(np.sum((triangle[:, free] @ step - target) ** 2)
                     - projected @ projected)
        covariance = np.linalg.pinv(triangle[:, free].T @ triangle[:, free])
        found[model] = _candidate(terms_of(model), n, at[free] + step,
                                  best.chi_square + rise, True, 0, covariance, estimated=True)
    return found


def _bounded_least_squares(matrix, target, lower, upper):
    """The s within [lower, upper] that minimises |matrix @ s - target|: the unbounded
    solution where it lies within, else scipy's bounded-variable least squares (a tenth
    of its cost where no bound binds)."""
    step = np.linalg.lstsq(matrix, target, rcond=None)[0]
    if np.all((step >= lower) & (step <= upper)):
        return step
    return optimize.lsq_linear(matrix, target, bounds=(lower, upper), method="bvls").x


def _window(t, x, turning, omega):
    """The finite samples from the first to the last used turning point, the start time
    and the start of the nuisance parameters (phase, frequency, offset, drift)."""
    used = np.flatnonzero(turning.used)
    t0, t_end = float(turning.t[used[0]]), float(turning.t[used[-1]])
    window = (t >= t0) & (t <= t_end) & np.isfinite(x)
    theta0 = 0.0 if turning.sign[used[0]] >= 0 else math.pi
    e0 = turning.equilibrium_at(t0)
    return t[window], x[window], t0, [theta0, omega, e0, turning.equilibrium_drift]


# Crests this many standard errors above 0 count in the start frequency.
_CLEAR = 10.0


def undamped_frequency(turning, omega):
    """The undamped angular frequency the crests imply, ``omega`` (the crests' own) where
    no half-cycle tells it.

    The crests' spacing gives the damped frequency nu = pi/spacing of each half-cycle,
    below omega at low Q; Eq. 20.55 with b alone has nu = sqrt(omega**2 - k**2) and the
    amplitude ratio r = (omega - k)/(omega + k) per half-cycle (mcfit.hysteretic_motion),
    so omega = nu/sqrt(1 - rho**2), rho = (1 - r)/(1 + r). The median over the
    half-cycles between used crests of opposite sign, both clear of the noise, weighted by
    their amplitude (where a Coulomb term, which drops the amplitude but not the
    frequency, counts least). At Q = 3 the crests' frequency is 3 % below omega, and with
    a Coulomb stop 11 %: a start that far off led the fit into another minimum.
    """
    keep = turning.used & (turning.y > _CLEAR * turning.sigma)
    pairs = keep[:-1] & keep[1:] & (turning.sign[:-1] != turning.sign[1:])
    spacing = np.diff(turning.t)[pairs]
    low, high = (fraction * 2 * math.pi / omega for fraction in HALF_CYCLE_SPACING)
    pairs = np.flatnonzero(pairs)[(spacing > low) & (spacing < high)]
    if pairs.size == 0:
        return omega
    before, after = turning.y[pairs], turning.y[pairs + 1]
    rho = np.abs(before - after) / (before + after)
    estimates = math.pi / (turning.t[pairs + 1] - turning.t[pairs]) / np.sqrt(1 - rho**2)
    order = np.argsort(estimates)
    weights = np.cumsum((before + after)[order])
    return float(estimates[order][np.searchsorted(weights, 0.5 * weights[-1])])


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


# The waveform's amplitude stays below this many times its start (the turning points').
_REACH = 3.0


def _bounds(start, terms):
    """Amplitude and terms >= 0; the phase within half a cycle and the frequency within
    20 % of the turning points' (a wider step would count other cycles); the amplitude
    below _REACH times its start and the offset within that start of its own (an
    amplitude of 12 on a record of 1, its swing held by friction and its offset at 11,
    had mimicked a viscous decay)."""
    y0 = abs(start[0]) if start[0] else np.inf
    lower = np.array([0.0, start[1] - math.pi / 2, 0.8 * start[2], start[3] - y0, -np.inf]
                     + [0.0] * len(terms))
    upper = np.array([_REACH * y0, start[1] + math.pi / 2, 1.25 * start[2], start[3] + y0,
                      np.inf] + [np.inf] * len(terms))
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


def fit_candidate(waveform, start):
    """One model's waveform fitted from ``start`` to full tolerance: (its
    :class:`mcfit.fit.candidates.Candidate`, scipy's result)."""
    return _ranked(waveform, start, _TOLERANCES)


def _ranked(waveform, start, tolerances, evaluations=200):
    """The candidate fitted from ``start`` (in at most ``evaluations``), with the bounds
    and steps it sets."""
    waveform.typical = _typical(start, waveform.terms)
    waveform.bounds = _bounds(start, waveform.terms)
    lower, upper = waveform.bounds
    result = optimize.least_squares(waveform.residual, np.clip(start, lower, upper),
                                    jac=waveform.jacobian, bounds=(lower, upper),
                                    method="trf", x_scale="jac", max_nfev=evaluations,
                                    **tolerances)
    return _candidate(waveform.terms, waveform.t.size, result.x, float(2 * result.cost),
                      bool(result.success), int(result.nfev),
                      np.linalg.pinv(result.jac.T @ result.jac)), result


def _candidate(terms, n_points, p, chi_square, success, evaluations, covariance,
               estimated=False):
    """The :class:`Candidate` of the model with ``terms`` at the vector ``p`` (y0, the
    nuisance parameters, the terms), fitted or ``estimated``."""
    n_params = p.size
    aicc, bic = information_criteria(chi_square, n_points, n_params)
    values = {"y0": float(p[0]), "a": 0.0, "b": 0.0, "c": 0.0}
    values.update({k: float(p[5 + i]) for i, k in enumerate(terms)})
    correlation = uncertainty.term_correlations(("y0",) + NUISANCE + tuple(terms),
                                                covariance, terms)
    return Candidate("".join(terms) or NONE, n_params, chi_square, aicc, bic, success,
                     values, evaluations, correlation, np.asarray(p), None, estimated)


def _reported(selection, candidates, waveform, start, form, solution=None):
    """The selected model's reported fit (``solution``, else refitted with lmfit from its
    candidate); errors, Q and warnings."""
    terms, t0, names = selection.terms, waveform.t0, waveform.free
    if solution is None:
        solution = _solved(waveform, candidates[selection.model].internal)
    p = solution.x
    residual = waveform.residual(p)
    covariance = solution.covariance
    if covariance is None:  # as many parameters as samples
        covariance = np.full((p.size, p.size), np.nan)
    law_free = ("y0",) + tuple(terms)
    law_index = [names.index(k) for k in law_free]
    errors = uncertainty.physical_errors(law_free, covariance[np.ix_(law_index, law_index)])
    values = {"y0": float(p[0]), "a": 0.0, "b": 0.0, "c": 0.0}
    values.update({k: float(p[names.index(k)]) for k in terms})
    omega = float(p[2])
    omega_sigma = float(math.sqrt(max(covariance[2, 2], 0.0)) / omega)
    y_fit = decay.amplitude(start.t - t0, *(values[k] for k in ("y0", "a", "b", "c")))
    q = q_stderr = q_parts = q_summary = None
    if selection.model != NONE:
        q, q_stderr, q_parts, q_summary = uncertainty.q_of_fit(
            start.t - t0, y_fit, values, errors.covariance, law_free, omega, omega_sigma)
    dof = waveform.t.size - p.size
    return WaveformFit(
        status="ok" if solution.success else "error",
        message=None if solution.success else "the waveform fit did not converge",
        model=selection.model, domain="time", criterion=selection.criterion, t0=t0,
        omega=omega, values=values, stderr=errors.stderr, correlation=errors.correlation,
        regimes={REGIME_NAMES[k]: k in terms for k in TERMS},
        lrt_p_values=selection.p_values, candidates=tuple(candidates.values()),
        n_points=waveform.t.size,
        rms=float(waveform.noise * np.sqrt(np.mean(residual**2))),
        reduced_chi_square=solution.chi_square / dof if dof > 0 else math.nan,
        noise_from_residuals=False, selection=selection, t=start.t, y=start.y, y_fit=y_fit,
        sigma=start.sigma, q=q, q_stderr=q_stderr, q_parts=q_parts, q_summary=q_summary,
        warnings=tuple(fit_warnings(selection, y_fit, values, errors, residual,
                                    solution.success)),
        damping_form=form,
        physical=physical_coefficients(form, terms, values, errors.stderr, omega))


# Each form's force per unit mass for each term: (name, force, coefficient from the
# averaged law's (value, omega), unit; U the signal's unit). docs/theory.md section 5.
_FORCES = {
    "amplitude": {"a": ("a", "(pi*w/2)*a*A**2*sgn(x')", lambda v, w: v, "1/(U*s)"),
                  "b": ("b", "(pi*w/2)*b*A*sgn(x')", lambda v, w: v, "1/s"),
                  "c": ("mu", "mu*sgn(x')", coulomb_force, "U/s**2")},
    "velocity": {"a": ("kappa", "kappa*x'*abs(x')", lambda v, w: 0.75 * math.pi * v / w,
                       "1/U"),
                 "b": ("beta", "2*beta*x'", lambda v, w: v, "1/s"),
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
