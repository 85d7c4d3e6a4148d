"""From a read record to turning points and a fit: the whole job for one record, no I/O."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mcfit.errors import McfitError, UsageError
from mcfit.fit import DecayFit, PowerLawFit, fit_decay
from mcfit.turning import TurningPoints, turning_points_of

__all__ = ["METHODS", "Analysis", "analyse_record", "failed_analysis", "fit_turning_points",
           "fit_by_method"]

# How the coefficients are fitted: "auto" takes the waveform fit only where the averaged
# law's bias would be a noticeable part of the statistical error.
METHODS = ("auto", "turning-points", "waveform")


@dataclass(frozen=True)
class Analysis:
    """Everything known about one record; ``status`` is "ok" or "error" (with ``error``)."""

    source: str
    status: str
    error: str | None
    record: object | None = None  # mcfit.records.Record
    turning: TurningPoints | None = None
    fit: DecayFit | PowerLawFit | None = None

    @property
    def warnings(self) -> tuple[str, ...]:
        found = []
        if self.fit is not None:
            found += list(self.fit.warnings)
        return tuple(found)


def failed_analysis(source: str, message: str, record=None, turning=None) -> Analysis:
    """An analysis that ended in an expected failure, carrying the one-line message."""
    return Analysis(source=source, status="error", error=message, record=record, turning=turning)


def fit_turning_points(turning: TurningPoints, **options) -> DecayFit | PowerLawFit:
    """:func:`mcfit.fit.fit_decay` on the used turning points, with their uncertainties
    (only when every one is finite and > 0) and period (when known); ``options`` go to
    ``fit_decay``. Raises :class:`mcfit.errors.FitError` for unusable turning points."""
    used = turning.used
    sigma = turning.sigma[used]
    if not np.all(np.isfinite(sigma)) or np.any(sigma <= 0):
        sigma = None
    period = turning.period if math.isfinite(turning.period) and turning.period > 0 else None
    period_sigma = turning.period_sigma if math.isfinite(turning.period_sigma) else None
    return fit_decay(turning.t[used], turning.y[used], sigma, period=period,
                     period_sigma=period_sigma, domain=turning.domain, **options)


def fit_by_method(record, turning, fit, method="auto", *, criterion="aicc", model=None):
    """``fit`` (of the turning points), or the waveform fit of ``record`` by the equation of
    motion when ``method`` asks for it or, for "auto", when the averaged law's predicted
    bias exceeds :data:`mcfit.model_error.LIMIT` standard errors. The result
    says which it is and why (``method``, ``method_reason``)."""
    from dataclasses import replace

    from mcfit.fit.waveform import fit_waveform
    from mcfit.model_error import LIMIT, averaged_law_bias

    if method not in METHODS:
        raise UsageError(f"unknown method {method!r}; use one of {', '.join(METHODS)}",
                         option="method")
    usable = (record.kind == "waveform" and fit.domain == "time" and fit.model != "power"
              and fit.omega is not None)
    if method == "turning-points" or not usable:
        why = "asked for" if method == "turning-points" else (
            "the record is a table of turning points" if record.kind != "waveform"
            else "no waveform fit for this model or domain")
        return replace(fit, method_reason=why) if fit.model != "power" else fit
    error = averaged_law_bias(record.t, turning, fit)
    said = (f"the averaged law's bias is predicted at {error.largest:.2g} standard errors"
            + (f" at Q down to {error.q_min:.3g}" if error.q_min else ""))
    if method == "auto" and error.largest <= LIMIT:
        return replace(fit, method_reason=f"{said}: the turning-point fit suffices")
    waveform = fit_waveform(record.t, record.x, turning, fit, criterion=criterion,
                            forced=model)
    why = "asked for" if method == "waveform" else f"{said}: fitted by the equation of motion"
    return replace(waveform, method_reason=why)


def analyse_record(record, *, criterion="aicc", model=None, bootstrap=0, rng=None,
                   method="auto") -> Analysis:
    """Turning points of ``record`` and the fit of the amplitude law to the used ones.

    Expected failures (no usable decay, too few turning points) come back as an
    :class:`Analysis` with ``status == "error"``; they are not raised.
    """
    source = record.source
    try:
        turning = turning_points_of(record)
    except McfitError as error:
        return failed_analysis(source, str(error), record=record)
    try:
        fit = fit_turning_points(turning, criterion=criterion, model=model,
                                 bootstrap=bootstrap, rng=rng)
        fit = fit_by_method(record, turning, fit, method, criterion=criterion, model=model)
    except McfitError as error:
        return failed_analysis(source, f"{source}: {error}", record=record, turning=turning)
    error = None if fit.message is None else f"{source}: {fit.message}"
    return Analysis(source=source, status=fit.status, error=error, record=record,
                    turning=turning, fit=fit)
