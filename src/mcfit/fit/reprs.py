"""Short reprs of the fit results: the model, the kept coefficients with their standard
errors, Q and the goodness of fit on one line, instead of every field and array."""

from __future__ import annotations

import math

__all__ = ["fit_repr"]


def fit_repr(fit, names) -> str:
    """``<DecayFit abc by turning points: y0 = 3.545 +- 0.001, a = ..., Q initial 13.74;
    79 turning points, reduced chi-square 0.88>`` for the parameters ``names`` of ``fit``
    (a DecayFit, PendulumFit or PowerLawFit)."""
    method = getattr(fit, "method", "turning-points").replace("-", " ")
    points = "samples" if method == "waveform" else "turning points"
    head = f"<{type(fit).__name__} {fit.model} by {method}"
    if fit.status != "ok":
        head += f" ({fit.status}: {fit.message})"
    parts = [_value(name, fit.values.get(name), fit.stderr.get(name)) for name in names]
    q = (fit.q_summary or {}).get("initial")
    if q is not None:
        parts.append(f"Q initial {q:.4g}")
    elif getattr(fit, "q_lower_bound", None) is not None:
        parts.append(f"Q > {fit.q_lower_bound:.2g} (95 %)")
    return (f"{head}: {', '.join(parts)}; {fit.n_points} {points}, reduced chi-square "
            f"{fit.reduced_chi_square:.3g}>")


def _value(name, value, error) -> str:
    if value is None:
        return f"{name} = -"
    if error is None or not math.isfinite(error):
        return f"{name} = {value:.4g}"
    return f"{name} = {value:.4g} +- {error:.2g}"
