"""Plain data for JSON: the conversions every result's ``to_dict`` shares (no numpy types,
None for what is missing or not finite, since JSON has no NaN). Standard library only."""

from __future__ import annotations

import math

__all__ = ["number", "numbers", "q_summary", "candidates", "before_warnings", "time_text",
           "period_resolution"]

_Q_KEYS = ("initial", "final", "min", "max")


def number(value):
    """``value`` as a float, or None where it is missing, NaN or infinite."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def numbers(values) -> dict:
    """Each value of the mapping ``values`` through :func:`number`."""
    return {k: number(v) for k, v in values.items()}


def q_summary(summary, lower_bound=None) -> dict:
    """Q initial, final, min and max with their standard errors (None where unknown) from a
    fit's ``q_summary``, and the one-sided bound of a fit that found no damping."""
    summary = summary or {}
    out = {k: number(summary.get(k)) for k in _Q_KEYS}
    out.update({f"{k}_stderr": number(summary.get(f"{k}_stderr")) for k in _Q_KEYS})
    out["lower_bound"] = number(lower_bound)
    return out


def candidates(fitted) -> list[dict]:
    """The candidate models' scores (:class:`mcfit.fit.Candidate` each); a candidate
    whose chi-square was estimated, not fitted (it cannot change the choice), says so."""
    return [{"model": c.model, "n_params": int(c.n_params),
             "chi_square": number(c.chi_square), "aicc": number(c.aicc),
             "bic": number(c.bic), "converged": bool(c.success),
             **({"estimated": True} if c.estimated else {})} for c in fitted]


def before_warnings(out: dict, entries: dict) -> dict:
    """A result's dict ``out`` with ``entries`` added before its warnings, which stay last
    (a subclass's ``to_dict`` adds its own keys so)."""
    warnings = out.pop("warnings")
    out.update(entries)
    out["warnings"] = warnings
    return out


def period_resolution(period):
    """The time a printed time must resolve: a hundredth of ``period`` (None: unknown)."""
    period = number(period)
    return period / 100.0 if period is not None and period > 0 else None


def time_text(value, resolution=None, digits=6) -> str:
    """A time for a note or report: ``digits`` significant digits, more where they are
    needed to resolve ``resolution`` (a hundredth of the period, say) at the time's
    magnitude, so that a late time of a fast oscillation stays readable; "-" for none."""
    value = number(value)
    if value is None:
        return "-"
    resolution = number(resolution)
    if resolution is not None and resolution > 0 and value != 0:
        needed = math.floor(math.log10(abs(value))) - math.floor(math.log10(resolution)) + 1
        digits = min(max(digits, needed), 17)
    return f"{value:.{digits}g}"
