"""From a read record to turning points and a fit: the whole job for one record, no I/O."""

from __future__ import annotations

import math
import re
from functools import partial
from dataclasses import dataclass, replace

import numpy as np

from mcfit import __version__
from mcfit.errors import FitError, McfitError, TooFewTurningPoints, UsageError
from mcfit.fit import DecayFit, PowerLawFit, fit_decay
from mcfit.fit.diagnostics import misfit_warning
from mcfit.fit.models import MODELS, NONE, TERMS, terms_of
from mcfit.fit.pendulum import (RADIANS_PER_DEGREE, fit_turning_points_of_pendulum,
                                large_swing_warning, names_degrees)
from mcfit.options import check_fit_options
from mcfit.turning import TurningPoints, turning_points_of
from mcfit.turning.placement import free_decay_runs, with_placed_release

__all__ = ["METHODS", "Analysis", "analyse_record", "auto_start", "crop_record",
           "failed_analysis", "free_decay_runs", "fit_turning_points", "fit_by_method",
           "fit_slow_record", "with_large_swing_warning"]

@dataclass(frozen=True)
class Analysis:
    """Everything known about one record; ``status`` is "ok" or "error" (with ``error``)."""

    source: str
    status: str
    error: str | None
    record: object | None = None  # mcfit.record.Record
    turning: TurningPoints | None = None
    fit: DecayFit | PowerLawFit | None = None

    @property
    def warnings(self) -> tuple[str, ...]:
        found = list(self.turning.warnings) if self.turning is not None else []
        if self.fit is not None:
            found += list(self.fit.warnings)
        return tuple(found)

    def to_dict(self, *, detail=False) -> dict:
        """The results as plain data (JSON-ready): exactly one JSON line of the command
        line, composed of the record's, the turning points' and the fit's ``to_dict``.
        Keys may be added, never renamed. With ``detail`` also ``detail``: the fit's
        ``domain``, ``n_points`` and ``correlation``, which the text report shows."""
        record = self.record.to_dict() if self.record is not None else None
        turning = self.turning.to_dict() if self.turning is not None else None
        out = {"source": self.source, "status": self.status, "error": self.error,
               "run": record["run"] if record else None,  # "Run 7" of a file of several
               "domain": record["domain"] if record else None,
               "turning_points": turning["count"] if turning else 0,
               "period": turning["period"] if turning else None}
        if self.fit is None:
            out.update({"model": None, "regimes": None, "params": None, "q": None,
                        "fit": None, "candidates": [], "warnings": []})
        else:
            out.update(self._fit_dict(record, turning, detail))
        if record is not None:
            out["columns"] = {"time": record["time_column"], "signal": record["signal_column"]}
            out["input"] = record["kind"]
            # What t = 0 is when the time column is a clock (None for elapsed time).
            out["time_origin"] = record["time_origin"]
        if turning is not None:
            out["turning_points_excluded"] = turning["excluded"]
            out["period_drift"] = turning["period_drift"]
            # Where the free decay starts, when the record begins held, driven or settling.
            out["release_time"] = turning["release_time"]
            out["notes"] = (record["notes"] if record else []) + turning["notes"]
            if "equilibrium_steps" in turning:  # only where one was found (issue 37)
                out["equilibrium_steps"] = turning["equilibrium_steps"]
        elif record is not None:
            out["notes"] = record["notes"]
        if record is not None:
            out["left_out"] = record["left_out"]
        out["mcfit_version"] = __version__  # which mcfit wrote the results
        if detail and "detail" in out:  # last, after the record's and turning points' keys
            out["detail"] = out.pop("detail")
        return out

    def summary(self) -> dict:
        """The results as plain Python objects: exactly one JSON line of the command line
        (:meth:`to_dict`)."""
        return self.to_dict()

    def report(self) -> str:
        """The text report, as ``mcfit FILE`` prints it."""
        from mcfit.report import to_text

        return to_text(self.to_dict(detail=True))

    def turning_point_table(self) -> list[dict]:
        """One row per turning point of the record, used or left out (with the reason),
        as plain data: source, t, amplitude, sigma, used, excluded_reason and the fitted
        envelope at the used ones, as the command line writes them."""
        from mcfit.plain import number

        if self.turning is None:
            return []
        rows = [{"source": self.source, **point, "envelope": None}
                for point in self.turning.to_dict(points=True)["points"]]
        used = [row for row in rows if row["used"]]
        # The fit's own amplitudes where it converted them (a pendulum's peak angles).
        for key, name in (("amplitude", "y"), ("sigma", "sigma"), ("envelope", "y_fit")):
            values = None if self.fit is None else getattr(self.fit, name)
            if values is not None and len(values) == len(used):
                for row, value in zip(used, values):
                    row[key] = number(value)
        return rows

    @property
    def turning_points(self):
        """The turning points as a pandas DataFrame: t, amplitude, sigma, used, why not
        (``excluded_reason``) and the fitted envelope, as the command line writes them."""
        from mcfit.frames import turning_points_frame

        return turning_points_frame(self.turning_point_table())

    def figure(self, title=None, *, panels=None, figsize=None, unit=None):
        """The report figure (a matplotlib Figure; nothing is shown or saved).

        ``title`` defaults to the file name (with the run); ``panels`` are names from
        :data:`mcfit.options.PANELS` (default :data:`mcfit.options.DEFAULT_PANELS`);
        ``figsize`` is (width, height) in inches; ``unit`` names the signal's unit where
        the record's header does not (``"mm"``)."""
        from mcfit.options import DEFAULT_PANELS
        from mcfit.plots import record_view, report_figure

        self._check_fitted()
        return report_figure(record_view(self, title, unit), self.fit,
                             DEFAULT_PANELS if panels is None else panels, figsize)

    def plot(self, ax=None, *, unit=None):
        """The record, its turning points and the fitted envelope on ``ax`` (a new figure's
        axes when None); returns the axes."""
        from mcfit.plots import plot_record

        self._check_fitted()
        return plot_record(self, ax, unit)

    def _check_fitted(self):
        if self.status != "ok" or self.fit is None:
            raise FitError(f"{self.source} was not fitted: {self.error}")

    def __repr__(self):
        if self.status != "ok" or self.fit is None:
            return f"Analysis(source={self.source!r}, status={self.status!r}, error={self.error!r})"
        values = self.fit.values
        terms = ", ".join(f"{k}={values.get(k, 0.0):.4g}" for k in ("a", "b", "c"))
        q = (self.fit.q_summary or {}).get("initial")
        q_text = f", Q={q:.4g}" if q is not None else ""
        return (f"Analysis(source={self.source!r}, model={self.fit.model!r}, {terms}"
                f"{q_text})")

    def _repr_html_(self):
        """The text report, for a notebook (Jupyter shows it as an Analysis's output)."""
        import html

        return f"<pre>{html.escape(self.report())}</pre>"

    def _repr_mimebundle_(self, include=None, exclude=None):
        """The report figure as PNG only when asked for by name, since drawing it takes
        seconds: ``IPython.display.display(analysis, include=["image/png"])``."""
        if (not include or "image/png" not in include or "image/png" in (exclude or ())
                or self.status != "ok" or self.fit is None):
            return {}
        import io

        from mcfit.plots import DPI, figure_metadata

        buffer = io.BytesIO()
        self.figure().savefig(buffer, format="png", dpi=DPI, metadata=figure_metadata("png"))
        return {"image/png": buffer.getvalue()}

    def _fit_dict(self, record, turning, detail):
        """The fit's part of :meth:`to_dict`, with the units from the record (time) or
        from a pendulum fit (angle), and the coefficients per cycle."""
        from mcfit.record import coefficient_units

        fit = self.fit.to_dict()
        found = {k: fit.pop(k) for k in _FIT_DETAIL if k in fit}
        time_unit = (record["time_unit"] if record else None) or "s"
        if found["domain"] == "cycle":
            per, unit = "cycle", "per cycle"
        else:  # an unknown unit as it is named
            per, unit = time_unit, "per second" if time_unit == "s" else f"per {time_unit}"
        signal_unit = ((record["signal_unit"] if record else None)
                       or (fit.get("pendulum") or {}).get("angle_unit"))
        out = {}
        for key, value in fit.items():
            out[key] = value
            if key == "params":
                out["params_units"] = unit
                out["signal_unit"] = signal_unit or None
                out["coefficient_units"] = coefficient_units(signal_unit, per)
                out["params_per_cycle"] = _per_cycle(value, found["domain"], turning)
        out["warnings"] = list(self.warnings)
        if detail:
            out["detail"] = found
        return out


# What a fit's to_dict holds beyond the JSON line (the text report shows it).
_FIT_DETAIL = ("domain", "n_points", "correlation")


def _per_cycle(params, domain, turning):
    """The coefficients per cycle (a*T, b*T, c*T, as in Fig. 20.20) from a fit's plain
    ``params`` and the turning points' period, or None without a period."""
    from mcfit.plain import number

    if domain == "cycle":
        return {k: dict(params[k]) for k in TERMS}
    period = turning["period"] if turning else None
    if period is None:
        return None
    return {k: {part: None if params[k][part] is None else number(params[k][part] * period)
                for part in ("value", "stderr")} for k in TERMS}


def failed_analysis(source: str, message: str, record=None, turning=None) -> Analysis:
    """An analysis that ended in an expected failure, carrying the one-line message."""
    return Analysis(source=source, status="error", error=message, record=record, turning=turning)


def fit_turning_points(turning: TurningPoints, *, pendulum=False, degrees=False,
                       **options) -> DecayFit | PowerLawFit:
    """:func:`mcfit.fit.fit_decay` on the used turning points, with their uncertainties
    (only when every one is finite and > 0) and period (when known); ``options`` go to
    ``fit_decay``. Raises :class:`mcfit.errors.FitError` for unusable turning points.

    With ``pendulum`` the signal is a pendulum's swing angle (radians, or degrees with
    ``degrees``) and the pendulum's law is fitted (:func:`mcfit.fit.pendulum.fit_pendulum`;
    ``bootstrap`` and ``rng`` are not available there). Without it, a fluid term found in a
    record whose period grows with amplitude as a pendulum's does gets a warning."""
    check_fit_options(pendulum=pendulum, bootstrap=options.get("bootstrap", 0))
    used = turning.used
    sigma = turning.used_sigma()
    period = turning.period if math.isfinite(turning.period) and turning.period > 0 else None
    period_sigma = turning.period_sigma if math.isfinite(turning.period_sigma) else None
    if pendulum:
        return fit_turning_points_of_pendulum(turning, sigma, degrees, **options)
    fit = fit_decay(turning.t[used], turning.y[used], sigma, period=period,
                    period_sigma=period_sigma, domain=turning.domain, **options)
    return with_large_swing_warning(fit, turning, degrees)


def with_large_swing_warning(fit, turning: TurningPoints, degrees=False):
    """``fit`` with :func:`mcfit.fit.pendulum.large_swing_warning` added when it applies:
    the signal taken as radians, or as degrees where ``degrees`` or where its swing is too
    large for radians but not for degrees."""
    if not isinstance(fit, DecayFit) or turning.domain != "time":
        return fit
    used = turning.used
    largest = float(np.max(turning.y[used], initial=0.0))
    guessed = not degrees and math.pi < largest < 180.0
    scale = RADIANS_PER_DEGREE if degrees or guessed else 1.0
    values = {"a": fit.values["a"] / scale, "b": fit.values["b"], "c": fit.values["c"] * scale}
    sigma = np.where(np.isfinite(turning.sigma[used]) & (turning.sigma[used] > 0),
                     turning.sigma[used], 1.0) * scale
    warning = large_swing_warning(values, fit.model, turning.t[used], turning.y[used] * scale,
                                  sigma, turning.period_drift, turning.period_drift_sigma,
                                  fit.stderr.get("b"))
    if warning is None:
        return fit
    if guessed:
        warning = ("read as an angle in degrees (it swings beyond pi, too far for radians), "
                   + warning + " and `degrees`")
    return replace(fit, warnings=fit.warnings + (warning,))


def fit_by_method(record, turning, fit, method="auto", *, criterion="aicc", model=None):
    """``fit`` (of the turning points), or the waveform fit of ``record`` by the equation of
    motion, as ``method`` (a key of :data:`METHODS`) decides. The result says which it is
    and why (``method``, ``method_reason``); a misfit is never silent."""
    check_fit_options(method=method)
    if fit.model == "power":
        return fit
    if method != "turning-points":
        why = _why_no_waveform_fit(record, fit)
        if why:
            return replace(fit, method_reason=why)
    return METHODS[method](record, turning, fit, criterion=criterion, model=model)


def _why_no_waveform_fit(record, fit):
    if record.kind != "waveform":
        return "the record is a table of turning points"
    if fit.domain != "time" or fit.omega is None:
        return "no waveform fit for this model or domain"
    return None


def _turning_point_method(record, turning, fit, **_):
    return replace(fit, method_reason="asked for")


def _waveform_method(record, turning, fit, *, criterion, model):
    waveform = _waveform_fit(record, turning, fit, criterion, model)
    warned = () if describes_waveform(waveform) else (_misfit_warning(waveform),)
    return replace(waveform, method_reason="asked for", warnings=waveform.warnings + warned)


def _auto_method(record, turning, fit, *, criterion, model):
    """The turning-point fit where the averaged law's predicted bias is within
    :data:`mcfit.model_error.LIMIT` standard errors; else the waveform fit, unless it
    misfits where the turning-point fit does not."""
    from mcfit.model_error import LIMIT, averaged_law_bias

    slow = _slow_sampling(record.t, turning.period)
    if slow is not None:
        waveform = _waveform_fit(record, turning, fit, criterion, model, slow=True)
        dof = fit.n_points - 1 - len(fit.selection.terms)
        return _reported_of(fit, waveform, slow, _SLOW_MOTION,
                            bool(misfit_warning(fit.reduced_chi_square, dof)))
    error = averaged_law_bias(record.t, turning, fit)
    said = _predicted_bias(error, fit)
    if error.largest <= LIMIT:
        return replace(fit, method_reason=f"{said}: the turning-point fit suffices")
    waveform = _waveform_fit(record, turning, fit, criterion, model,
                             start=auto_start(fit, error))
    dof = fit.n_points - 1 - len(fit.selection.terms)
    return _reported_of(fit, waveform, said, "the equation of motion",
                        bool(misfit_warning(fit.reduced_chi_square, dof)))


def _slow_sampling(t, period):
    """Why the turning-point fit of a record sampled at times ``t`` with oscillation
    ``period`` is not trusted: under :data:`mcfit.turning.SAMPLES_PER_CYCLE` samples a
    cycle a half-cycle fit places each crest from two or three samples and the amplitudes
    are biased (b at 5 samples a cycle 5-17 standard errors off, where the waveform fit
    is within its errors); None at or above it, or without a period."""
    from mcfit.turning import SAMPLES_PER_CYCLE

    steps = np.diff(t)
    if steps.size == 0 or not (math.isfinite(period) and period > 0):
        return None
    samples = period / float(np.median(steps))
    if samples >= SAMPLES_PER_CYCLE:
        return None
    return (f"sampled at {samples:.2g} samples a cycle, under {SAMPLES_PER_CYCLE}: crests "
            "placed from so few samples are biased")


# How a record sampled too slowly for its crests is fitted (the method line says it).
_SLOW_MOTION = ("the equation of motion, its sample noise from the residuals of the "
                "best-fitting model (the samples alone cannot tell the noise from the "
                "oscillation)")


def fit_slow_record(t, x, turning, start, *, criterion="aicc", forced=None):
    """:func:`fit_both_forms` of a record of few samples a cycle, fitted twice: the
    second time with the sample noise the first one's residuals give, from the candidate
    of least chi-square per degree of freedom. Below 8 samples a cycle no difference
    filter takes out the oscillation and leaves the noise (at 4 samples a cycle the
    waveform fit's own estimate put the reduced chi-square anywhere from 0.4 to 6)."""
    first = fit_both_forms(t, x, turning, start, criterion=criterion, forced=forced)
    noise = _residual_noise(first)
    if noise is None:
        return first
    return fit_both_forms(t, x, turning, start, criterion=criterion, forced=forced,
                          noise=noise)


def _residual_noise(fit):
    """The sample noise (record units) the residuals of ``fit``'s candidates give: the
    least chi-square per degree of freedom, in units of the noise the fit had; None where
    none has a degree of freedom or a finite chi-square."""
    n = fit.n_points
    chosen = _selected(fit)
    dof = n - chosen.n_params
    if not (dof > 0 and fit.reduced_chi_square > 0 and math.isfinite(fit.rms)):
        return None
    had = fit.rms * math.sqrt(n / (fit.reduced_chi_square * dof))
    per_dof = [c.chi_square / (n - c.n_params) for c in fit.candidates
               if n > c.n_params and math.isfinite(c.chi_square) and c.chi_square > 0]
    if not per_dof or not (had > 0 and math.isfinite(had)):
        return None
    return had * math.sqrt(min(per_dof))


# A term whose value less the averaged law's predicted bias of it is at most this many
# standard errors: the bias explains it, or more than explains it.
_EXPLAINED = 2.0


def auto_start(fit, error):
    """Where auto starts the waveform fit: from the turning-point ``fit``, with its model
    less the terms whose value, less the bias the chain predicts for it (``error``), is
    at most _EXPLAINED standard errors: the averaged law cannot show such a term (at
    Q = 5 with b and c, a = 16 standard errors against 57 of bias). The terms left out
    are still estimated, and fitted where they may matter: a real term dropped costs a
    second fit, a spurious one kept costs a fit of a model not reported. Where the chain
    fails (an infinite predicted bias: the fitted law's own waveform gives too few
    turning points, or their fit fails), the fit's choice is not trusted: the waveform
    fit starts with the candidate whose start lies nearest the record (at Q = 3 with b
    and a Coulomb stop, b + c, not the fit's a + c)."""
    from mcfit.fit.waveform import WaveformStart
    from mcfit.model_error import noise_stderr

    start = WaveformStart.of_fit(fit)
    if error.how != "chain":
        return start
    if not all(map(math.isfinite, error.z.values())):
        return replace(start, model=None)
    stderr = noise_stderr(fit)
    kept = "".join(k for k in fit.selection.terms
                   if fit.values[k] / stderr[k] - error.z[k] > _EXPLAINED)
    return replace(start, model=kept) if kept else start


def _reported_of(fit, waveform, said, motion, averaged_misfits):
    """The ``waveform`` fit (by ``motion``) where it describes the record; else the
    turning-point ``fit`` unless it misfits too, with a warning either way."""
    if describes_waveform(waveform):
        return replace(waveform, method_reason=f"{said}: fitted by {motion}")
    warning = _misfit_warning(waveform)
    if not averaged_misfits:
        return replace(fit, method_reason=f"{said}, but {motion} does not fit the waveform: "
                       "the turning-point fit is kept", warnings=fit.warnings + (
                           warning + "; the turning-point fit is reported, biased by the "
                           "amount predicted",))
    return _unresolved(replace(
        waveform, method_reason=f"{said}: fitted by {motion}, which misfits as the "
        "turning-point fit does", warnings=waveform.warnings + (
            warning + f"; the turning-point fit misfits too (reduced chi-square "
            f"{fit.reduced_chi_square:.3g}): the regimes are not resolved",)))


def _pendulum_method(record, turning, fit, degrees, *, criterion, model):
    """``fit`` (the pendulum's averaged law on the turning points), or the waveform fit
    by the pendulum's equation of motion where the averaged law would be biased by more
    than a (reported) standard error (:func:`mcfit.model_error.pendulum_law_bias`) or
    misfits, started from :func:`_pendulum_start`."""
    from mcfit.fit.pendulum_waveform import PendulumWaveformFit
    from mcfit.model_error import misfit_scale

    if (record.kind != "waveform" or fit.domain != "time" or fit.omega is None
            or not fit.selection.terms):
        return fit
    error = _pendulum_law_error(record.t, turning, fit, degrees)
    misfits = error is None
    bias = math.nan if misfits else error.largest / misfit_scale(fit)
    said = (f"the averaged large-swing law misfits (reduced chi-square "
            f"{fit.reduced_chi_square:.3g})" if misfits else
            f"the averaged large-swing law's bias is predicted at {bias:.2g} standard errors")
    if not misfits and bias <= 1.0:
        return replace(fit, method_reason=f"{said}: the turning-point fit suffices")
    waveform = PendulumWaveformFit.of(replace(
        _pendulum_waveform(record, turning, fit, error, degrees, criterion, model),
        damping_form_reason=("the pendulum's equation of motion, with the velocity forms of "
                             "the damping (viscous, quadratic drag, sliding friction)")), fit)
    return _reported_of(fit, waveform, said, "the pendulum's equation of motion", misfits)


def _pendulum_waveform(record, turning, fit, error, degrees, criterion, model):
    """The waveform fit by the pendulum's equation of motion from :func:`_pendulum_start`.

    From the nearest of the law's models (where the law misfits), where that is not the
    law's own, it is fitted from the law's model too and the better by ``criterion``
    kept, unless the model fitted first is selected and fits within the noise: a model
    reached from another's estimate can stop short (drag and Coulomb friction at Q = 10,
    a + b + c from b + c: reduced chi-square 1.82, and at Q = 15 1.0004 with a 4.5
    standard errors off; from the law's a + b + c 0.99 and 0.98)."""
    from mcfit.fit.waveform import (WaveformStart, fit_waveform, open_form, rank_form,
                                    report_form, within_noise)
    from mcfit.fit.waveform_laws import PendulumWaveform

    kind = partial(PendulumWaveform, radians_per_unit=RADIANS_PER_DEGREE if degrees else 1.0)
    x = _without_steady_line(record.t, record.x, turning.steady_line,
                             turning.equilibrium_steps)
    fitted = partial(fit_waveform, record.t, x, turning, criterion=criterion, forced=model,
                     form="velocity", kind=kind)
    start = _pendulum_start(fit, error)
    if start.model is not None or model is not None:
        return fitted(start)
    opened = open_form(record.t, x, turning, start, form="velocity", kind=kind)
    nearest = opened.first.model
    waveform = report_form(rank_form(record.t, x, turning, start, criterion=criterion,
                                     form="velocity", kind=kind, opened=opened), start)
    if nearest == fit.model or (waveform.model == nearest and within_noise(
            _selected(waveform), waveform.n_points)):
        return waveform
    return min(waveform, fitted(WaveformStart.of_fit(fit)),
               key=lambda found: getattr(_selected(found), criterion))


def _pendulum_law_error(t, turning, fit, degrees):
    """The pendulum's averaged-law ``fit``'s predicted bias
    (:func:`mcfit.model_error.pendulum_law_bias`), or None where that law misfits: the
    waveform fit is then asked for whatever the bias, and the chain is not run."""
    from mcfit.model_error import pendulum_law_bias

    dof = fit.n_points - 1 - len(fit.selection.terms)
    if not fit.noise_from_residuals and misfit_warning(fit.reduced_chi_square, dof):
        return None
    return pendulum_law_bias(t, turning, fit, degrees)


def _pendulum_start(fit, error):
    """Where the pendulum's waveform fit starts: :func:`auto_start`'s start (the fit's
    model less the terms the predicted bias ``error`` explains) where the chain gave every
    term a finite bias. Where the law misfits (``error`` None), its choice of terms is
    not trusted: the model nearest the record among those it contains (at 0.8 rad with
    viscous damping alone, b, where the law said a + b or a + b + c, reduced chi-square
    3-14; :func:`_pendulum_waveform` fits from the law's model too where the fit from
    there selects another model or ends outside the noise). Where the chain failed, the
    fit's own model (the candidate nearest the record among all would start a large
    swing from b + c, further from its answer)."""
    from mcfit.fit.waveform import WaveformStart

    start = WaveformStart.of_fit(fit)
    if error is None:
        kept = set(fit.selection.terms)
        return replace(start, model=None, among=tuple(
            m for m in MODELS if m != NONE and set(terms_of(m)) <= kept))
    z = error.z
    if set(z) != set(fit.selection.terms) or not all(map(math.isfinite, z.values())):
        return start
    return auto_start(fit, error)


# How each value of ``method`` (mcfit.options.FIT_METHODS) chooses the reported fit: "auto"
# takes the waveform fit only where the averaged law's bias would be a noticeable part of
# the statistical error.
METHODS = {"auto": _auto_method, "turning-points": _turning_point_method,
           "waveform": _waveform_method}


def _waveform_fit(record, turning, fit, criterion, model, start=None, slow=False):
    """The waveform fit in the form the record supports, started from ``start`` (the
    turning-point ``fit``'s by default), of the signal without the hum the turning-point
    search took out; ``slow``: with the noise from its residuals (:func:`fit_slow_record`)."""
    from mcfit.fit.waveform import WaveformStart

    x = _without_steady_line(record.t, record.x, turning.steady_line,
                             turning.equilibrium_steps)
    start = start or WaveformStart.of_fit(fit)
    waveform = (fit_slow_record if slow else fit_both_forms)(
        record.t, x, turning, start, criterion=criterion, forced=model)
    if fit.bootstrap is None:
        return waveform
    return replace(waveform, warnings=waveform.warnings + (
        f"the {fit.bootstrap['n'] + fit.bootstrap['failed']} bootstrap refits asked for are "
        "of the turning-point fit, "
        "which is not reported: the waveform fit's intervals are from its covariance",))


def fit_both_forms(t, x, turning, start, *, criterion="aicc", forced=None, noise=None):
    """The waveform fit in the form of the damping forces the record supports: Eq. 20.55's
    amplitude forms or the velocity forms (:data:`mcfit.fit.waveform.FORMS`), by the AICc
    of the model each selects; ``damping_form`` is "cannot tell" within
    :data:`mcfit.fit.waveform.FORM_TIE`, and the lower one is reported. One form is
    ranked first (the velocity forms where they alone describe the record at their first
    fit, else the amplitude forms: :func:`mcfit.fit.waveform.rank_forms`); the other
    starts from its choice and stops where it cannot come within the tie. ``noise``: the
    sample noise (default: the window's, :func:`mcfit.fit.waveform.sample_noise`)."""
    from mcfit.fit.waveform import FORM_TIE, rank_forms, report_form

    ranked = rank_forms(t, x, turning, start, criterion=criterion, forced=forced,
                        noise=noise)
    if not ranked:
        raise FitError(f"no form of the waveform fit has the model {forced!r}",
                       option="model")
    names = {"amplitude": "Eq. 20.55's amplitude forms", "velocity": "the velocity forms "
             "(viscous, quadratic drag, sliding friction)"}
    if len(ranked) == 1:
        (only, alone), = ranked.items()
        return replace(report_form(alone, start), damping_form_reason=(
            f"only {names[only]} have the model {forced!r}"))
    scores = {form: r.aicc for form, r in ranked.items()}
    best, other = sorted(scores, key=scores.get)
    gap = scores[other] - scores[best]
    fit = report_form(ranked[best], start)
    if set(terms_of(fit.model)) <= {"c"}:
        return replace(fit, damping_form="cannot tell", damping_form_reason=(
            f"{names[best]} fit the waveform best, but sliding friction has one form only: "
            f"the coefficients are those of {names[best]}"))
    if gap <= FORM_TIE:
        return replace(fit, damping_form="cannot tell", damping_form_reason=(
            f"{names[best]} and {names[other]} fit the waveform equally well (AICc "
            f"{gap:.3g} apart): the coefficients of the averaged law are those of "
            f"{names[best]}"))
    about = "about " if ranked[other].candidates[ranked[other].selection.model].estimated else ""
    return replace(fit, damping_form_reason=(
        f"{names[best]} fit the waveform better than {names[other]} (AICc lower by "
        f"{about}{gap:.3g})"))


def _selected(fit):
    """The candidate of the model ``fit`` reports."""
    return next(c for c in fit.candidates if c.model == fit.model)


def _unresolved(fit):
    """``fit`` with its regimes marked as not resolved."""
    return replace(fit, selection=replace(fit.selection, resolved=False))


def _predicted_bias(error, fit):
    if not math.isfinite(error.largest):  # the chain found no turning points to fit
        return ("no turning points were found on the noise-free waveform of the fitted "
                "coefficients, so the averaged law's bias cannot be predicted")
    q_min = error.q_min if error.q_min and math.isfinite(error.q_min) else None
    coulomb = " without the Coulomb term" if fit.values.get("c") else ""
    return (f"the averaged law's bias is predicted at {error.largest:.2g} standard errors"
            + (f" at Q down to {q_min:.3g}{coulomb}" if q_min else ""))


def _without_steady_line(t, x, line, steps=()):
    """The signal with the hum ``line`` and the ``steps`` of the equilibrium the
    turning-point search subtracted (if any) taken out."""
    if line is None and not steps:
        return x
    from mcfit.hum import subtract_steady_line
    from mcfit.turning.step import subtract_equilibrium_steps

    finite = np.isfinite(x)
    out = np.array(x, dtype=float)
    kept = subtract_equilibrium_steps(t[finite], x[finite], steps)
    out[finite] = kept if line is None else subtract_steady_line(t[finite], kept, line)
    return out


def describes_waveform(waveform) -> bool:
    """Whether the equation of motion fits the waveform within its noise: converged, with
    a reduced chi-square not far above 1 (:func:`mcfit.fit.diagnostics.misfit_warning`)."""
    reduced = waveform.reduced_chi_square
    if not math.isfinite(reduced) or waveform.status != "ok":
        return False
    return not misfit_warning(reduced, waveform.n_points - _selected(waveform).n_params)


def _misfit_warning(waveform):
    return (f"the equation of motion fits the waveform with reduced chi-square "
            f"{waveform.reduced_chi_square:.3g}: the record holds something it does not "
            "model (a damping force of another form, a disturbance, a second mode)")


def crop_record(record, start=None, end=None):
    """``record`` kept to ``start <= t <= end`` (either may be None), with a note.

    Raises :class:`mcfit.errors.UsageError` when the window is empty."""
    if start is None and end is None:
        return record
    keep = np.ones(record.t.size, dtype=bool)
    if start is not None:
        keep &= record.t >= start
    if end is not None:
        keep &= record.t <= end
    unit = "cycles" if record.domain == "cycle" else "s"
    low = f"{start:g} {unit}" if start is not None else "the start"
    high = f"{end:g} {unit}" if end is not None else "the end"
    if not np.any(keep):
        raise UsageError(f"{record.source}: no samples in the window from {low} to {high}; "
                         f"the record spans {np.nanmin(record.t):g} to "
                         f"{np.nanmax(record.t):g} {unit}",
                         option="start" if start is not None else "end")
    note = (f"window: {low} to {high} as asked ({np.count_nonzero(keep)} of "
            f"{keep.size} rows kept)")
    return replace(record, t=record.t[keep], x=record.x[keep], notes=record.notes + (note,))


def _bound(value, default, record):
    unit = "cycles" if record.domain == "cycle" else "s"
    return default if value is None else f"{value:g} {unit}"


def analyse_record(record, *, criterion="aicc", model=None, bootstrap=0, rng=None,
                   seed=None, pendulum=False, degrees=None, method="auto", start=None,
                   end=None) -> Analysis:
    """Turning points of ``record`` and the fit of the amplitude law to the used ones.

    ``bootstrap`` resamples are drawn by ``rng`` where given, else by a generator seeded
    with ``seed``, or with a seed drawn from the system's entropy where there is none:
    the seed is reported (the fit's ``bootstrap["seed"]``; None for a given ``rng``), so
    that ``seed=`` repeats the run.

    ``start``, ``end``: fit only the part of the record between these times (or cycles).
    ``pendulum``: the signal is a pendulum's swing angle, in degrees when ``degrees`` or,
    if ``degrees`` is None, when the signal column's name says so ("deg", "°"), else in
    radians (see :func:`fit_turning_points`). Otherwise ``method`` chooses between the
    turning-point fit and the waveform fit (:func:`fit_by_method`).

    Expected failures (no usable decay, too few turning points) come back as an
    :class:`Analysis` with ``status == "error"``; they are not raised. Options that are
    unknown or contradict each other raise :class:`mcfit.errors.UsageError`.
    """
    model = check_fit_options(criterion=criterion, model=model, bootstrap=bootstrap,
                              method=method, pendulum=pendulum, start=start, end=end)
    rng, seed = _bootstrap_generator(bootstrap, rng, seed)
    source = record.source
    try:
        if start is None and end is None:
            record = free_decay_runs(record)[0]
        record = crop_record(record, start, end)
        turning = with_placed_release(turning_points_of(record), record)
    except McfitError as error:
        few = (isinstance(error, TooFewTurningPoints) and bootstrap == 0
               and _waveform_fit_possible(record, pendulum, method))
        analysis = _few_swings_analysis(record, criterion=criterion, model=model) if few \
            else None
        if analysis is not None:
            return analysis
        message = _oscillating_hint(str(error), record, error)
        if (start, end) != (None, None) and not isinstance(error, UsageError):
            message += (f" This is in the window from {_bound(start, 'the start', record)} to "
                        f"{_bound(end, 'the end', record)} asked for: widen it.")
        return failed_analysis(source, message, record=record)
    try:
        if degrees is None:
            degrees = names_degrees(getattr(record, "signal_column", None))
        fit = fit_turning_points(turning, criterion=criterion, model=model,
                                 bootstrap=bootstrap, rng=rng, pendulum=pendulum,
                                 degrees=degrees)
        if not pendulum:
            chosen = fit_by_method(record, turning, fit, method, criterion=criterion,
                                   model=model)
            if getattr(chosen, "method", None) != getattr(fit, "method", None):
                chosen = with_large_swing_warning(chosen, turning, degrees)
            fit = chosen
        else:
            fit = _pendulum_method(record, turning, fit, degrees, criterion=criterion,
                                   model=model)
        if turning.warnings and fit.model != "power":
            fit = _unresolved(fit)  # a beat or disturbance was left out: no confident verdict
    except McfitError as error:
        return failed_analysis(source, f"{source}: {_oscillating_hint(str(error), record, error)}",
                               record=record, turning=turning)
    error = None if fit.message is None else f"{source}: {fit.message}"
    if getattr(fit, "bootstrap", None) is not None:
        fit = replace(fit, bootstrap={**fit.bootstrap, "seed": seed})
    return Analysis(source=source, status=fit.status, error=error, record=record,
                    turning=turning, fit=fit)


def _bootstrap_generator(bootstrap, rng, seed):
    """(generator, seed) for ``bootstrap`` resamples: ``rng`` as given (its seed is not
    known: None), else a generator seeded with ``seed``, drawn by numpy's SeedSequence
    from the system's entropy where none is given."""
    if rng is not None:
        return rng, None
    if not bootstrap:
        return None, seed
    if seed is None:
        seed = int(np.random.SeedSequence().generate_state(1)[0])
    return np.random.default_rng(seed), seed


def _oscillating_hint(message, record, error):
    """``message`` of a record that shows no oscillation, naming the file's column that
    does (:attr:`Record.oscillating_columns`) in place of "Check the signal column."."""
    columns = getattr(record, "oscillating_columns", ())
    # A noise column's spectrum peaks anywhere: "no oscillation" or "too few samples a
    # cycle" are both about the column, which the other column's line answers.
    about_column = "signal column" in message or "samples a cycle" in message
    if not columns or isinstance(error, UsageError) or not about_column:
        return message
    name = columns[0]
    index = list(record.columns).index(name) + 1 if name in record.columns else None
    given = name if re.fullmatch(r"[^`\s]+", name) else index
    others = f" (also {', '.join(repr(c) for c in columns[1:3])})" if len(columns) > 1 else ""
    where = f" (column {index})" if index is not None else ""
    hint = (f"The signal column {record.signal_column!r} shows no oscillation above its "
            f"noise, but {name!r}{where} does{others}: use `signal_col={given}`.")
    cut = message.rfind("Check the ")
    return (message[:cut] if cut >= 0 else message + " ") + hint


def _waveform_fit_possible(record, pendulum, method):
    return (record.kind == "waveform" and record.domain == "time" and not pendulum
            and method != "turning-points")


def _few_swings_analysis(record, *, criterion, model):
    """The waveform fit of a record with too few turning points for the averaged law,
    started from a damped cosine (:mod:`mcfit.fit.few_swings`), or None where even that
    cannot be fitted."""
    from mcfit.fit.few_swings import few_swings_start, with_fitted_amplitudes

    try:
        turning, start = few_swings_start(record.t, record.x, record.source)
        slow = _slow_sampling(record.t, turning.period)
        waveform = (fit_slow_record if slow else fit_both_forms)(
            record.t, record.x, turning, start, criterion=criterion, forced=model)
    except McfitError:
        return None
    why = (f"{slow}, too few for the averaged law: fitted by {_SLOW_MOTION}" if slow else
           "too few turning points for the averaged law were found: fitted by the equation "
           "of motion")
    fit = replace(waveform, method_reason=f"{why}, from a damped cosine's start")
    if not describes_waveform(fit):
        fit = _unresolved(replace(fit, warnings=fit.warnings + (_misfit_warning(fit),)))
    turning, fit = with_fitted_amplitudes(turning, fit)
    error = None if fit.message is None else f"{record.source}: {fit.message}"
    return Analysis(source=record.source, status=fit.status, error=error, record=record,
                    turning=turning, fit=fit)
