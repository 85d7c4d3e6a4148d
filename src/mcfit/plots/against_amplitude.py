"""The panels against amplitude: damping rate, Q and period (the backbone), each with the
measured points (faint), their medians in amplitude bins (with error bars) and the model."""

from __future__ import annotations

import math

import numpy as np

from mcfit import decay
from mcfit.fit import NONE, POWER
from mcfit.plots.binning import Binned, binned_medians, binned_rates, full_periods, \
    pair_rates
from mcfit.plots.legends import place_legend
from mcfit.plots.style import (BINNED, RAW, REGIME_OF_PART, REGIME_STYLE, SELECTED,
                               clipped, off_scale_note, padded, readable_log_axis, span_of,
                               visible)

__all__ = ["draw_rate", "draw_q_amplitude", "draw_backbone"]

# An amplitude axis spanning more than this ratio is logarithmic.
_LOG_RATIO = 10.0
# Outliers: the measured points decide the range only between these percentiles, widened
# by half their spread each way (a misread crest spoils the rates of several pairs).
_ROBUST_PERCENTILES = (10.0, 90.0)


def draw_rate(axes, view, fit):
    """-(dy/dt)/y against y: constant for hysteretic, rising for fluid, 1/y for Coulomb."""
    unit = "s" if fit.domain == "time" else "cycle"
    amplitude, rate, span = pair_rates(fit.t, fit.y, _finite_sigma(fit))
    bins = _rate_bins(fit)
    y_fine, log_x = _amplitude_grid(amplitude if amplitude.size else fit.y)
    model = _model_rate(fit, y_fine) if y_fine is not None else None
    _measured(axes, amplitude, rate, bins, model, f"rate over {span} crest step"
              + ("s" if span > 1 else ""))
    if model is not None:
        axes.plot(y_fine, model, label=_rate_label(fit), **SELECTED)
    if log_x:
        axes.set_xscale("log")
        readable_log_axis(axes.xaxis, y_fine[0], y_fine[-1])
    axes.set_xlabel(view.amplitude_label)
    axes.set_ylabel(f"damping rate -(dy/dt)/y (1/{unit})")
    axes.set_title("damping rate against amplitude")
    place_legend(axes)


def draw_q_amplitude(axes, view, fit):
    """Q against amplitude: measured omega/(2*rate) and the model's Q with its parts
    (Handbook Eq. 20.56; the pendulum's energy Q for a pendulum fit)."""
    axes.set_title("quality factor against amplitude")
    axes.set_xlabel(view.amplitude_label)
    axes.set_ylabel("Q")
    omega = fit.omega
    if omega is None or not omega > 0 or fit.model == NONE:
        text = ("no damping detected" if fit.model == NONE
                else "Q needs the period: not known for this record")
        axes.text(0.5, 0.5, text, ha="center", va="center", transform=axes.transAxes)
        return
    amplitude, rate, span = pair_rates(fit.t, fit.y, _finite_sigma(fit))
    positive = rate > 0
    amplitude, q = amplitude[positive], omega / (2.0 * rate[positive])
    rates = _rate_bins(fit)
    # Q = omega/(2 rate), with the rate's error carried over; a bin whose rate is not
    # clearly > 0 has no finite Q to show.
    clear = rates.y > rates.error
    bins = Binned(rates.x[clear], omega / (2.0 * rates.y[clear]),
                  omega / (2.0 * rates.y[clear]) * rates.error[clear] / rates.y[clear],
                  rates.count[clear])
    y_fine, log_x = _amplitude_grid(amplitude if amplitude.size else fit.y)
    model, parts = _model_q(fit, y_fine, omega)
    low, high = _measured(axes, amplitude, q, bins, model, "omega/(2 rate)")
    if model is not None:
        axes.plot(y_fine, model, label="model Q", **SELECTED)
    hidden = []
    for key, part in parts.items():
        color, dashes = REGIME_STYLE[REGIME_OF_PART[key]]
        label = f"Q {key}".replace("coulomb", "Coulomb")
        if visible(part, low, high):
            axes.plot(y_fine, clipped(part, low, high), color=color, ls=dashes, lw=1.3,
                      label=label)
        else:
            hidden.append((label, part))
    off_scale_note(axes, curves=hidden)
    if log_x:
        axes.set_xscale("log")
        readable_log_axis(axes.xaxis, y_fine[0], y_fine[-1])
    place_legend(axes)


def draw_backbone(axes, view, fit):
    """The period against amplitude (the backbone): periods measured crest to crest, their
    medians in bins, and the large-swing pendulum law T0*2K(sin(theta0/2))/pi for a
    pendulum fit, else the period from the crests' spacing."""
    axes.set_title("period against amplitude (backbone)")
    axes.set_xlabel(view.amplitude_label)
    axes.set_ylabel(f"period ({view.time_unit})")
    if view.time_unit == "cycle" or not math.isfinite(view.period):
        axes.text(0.5, 0.5, "no period: the record is indexed by cycle number"
                  if view.time_unit == "cycle" else "period not known for this record",
                  ha="center", va="center", transform=axes.transAxes)
        axes.set_xticks([])
        axes.set_yticks([])
        return
    used = view.used.astype(bool)
    amplitude, period = full_periods(view.turning_t[used], view.turning_y[used], view.period)
    bins = binned_medians(amplitude, period)
    y_fine, log_x = _amplitude_grid(amplitude if amplitude.size else fit.y)
    law, label = _period_law(fit, y_fine, view)
    _measured(axes, amplitude, period, bins, law, "crest to crest", log_y=False)
    axes.plot(y_fine, law, label=label, **SELECTED)
    if not _is_pendulum(fit) and math.isfinite(view.period_sigma):
        axes.axhspan(view.period - view.period_sigma, view.period + view.period_sigma,
                     color="0.85", zorder=0, label="± its standard error")
    if log_x:
        axes.set_xscale("log")
        readable_log_axis(axes.xaxis, y_fine[0], y_fine[-1])
    axes.ticklabel_format(axis="y", useOffset=False, style="plain")
    place_legend(axes)


def _measured(axes, x, y, bins, model, what, log_y=None):
    """Draw the measured points (faint, only those in range) and their binned medians;
    set the y range from the bins, the model and the points' bulk; return it."""
    robust = _robust_span(y)
    span = span_of(bins.y - bins.error, bins.y + bins.error, model,
                   *([robust] if robust is not None else []))
    if span is None:
        axes.text(0.5, 0.5, "too few turning points", ha="center", va="center",
                  transform=axes.transAxes)
        return 0.0, 1.0
    positive = span[0] > 0
    if log_y is None:
        log_y = positive and span[1] / span[0] > 20.0
    low, high = padded(span, log=log_y)
    inside = (y >= low) & (y <= high)
    axes.plot(x[inside], y[inside], label=f"measured ({what})", **RAW)
    if bins.x.size:
        axes.errorbar(bins.x, bins.y, yerr=bins.error, label="median in amplitude bin",
                      **BINNED)
    if log_y:
        axes.set_yscale("log")
        readable_log_axis(axes.yaxis, low, high)
    axes.set_ylim(low, high)
    off_scale_note(axes, int(np.count_nonzero(~inside & np.isfinite(y))))
    return low, high


def _robust_span(values):
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    if values.size < 4:
        return values if values.size else None
    low, high = np.percentile(values, _ROBUST_PERCENTILES)
    spread = 0.5 * (high - low)
    return np.array([max(low - spread, values.min()), min(high + spread, values.max())])


def _amplitude_grid(amplitudes):
    """A fine grid over the positive measured amplitudes, logarithmic when they span more
    than a factor 10: (grid, log), or (None, False) with no positive amplitude."""
    span = span_of(amplitudes, positive=True)
    if span is None:
        return None, False
    log = span[1] / span[0] > _LOG_RATIO
    grid = np.geomspace(*span, 300) if log else np.linspace(*span, 300)
    return grid, log


def _rate_bins(fit):
    """Binned rates of the fitted turning points, their errors scaled by the fit's
    reduced chi-square when it exceeds 1 (the amplitudes scatter more than their sigma)."""
    chi_square = fit.reduced_chi_square
    scale = math.sqrt(chi_square) if math.isfinite(chi_square) and chi_square > 1 else 1.0
    return binned_rates(fit.t, fit.y, _finite_sigma(fit), noise_scale=scale)


def _finite_sigma(fit):
    return np.where(np.isfinite(fit.sigma), fit.sigma, 0.0)


def _is_pendulum(fit) -> bool:
    return getattr(fit, "small_angle_period", None) is not None


def _model_rate(fit, y):
    """The fitted -(dy/dt)/y at amplitudes ``y``."""
    v = fit.values
    if fit.model == POWER:
        return v["k"] * y ** (v["n"] - 1)
    if hasattr(fit, "radians_per_unit"):
        from mcfit.fit.pendulum import geometric_factors

        scale = fit.radians_per_unit
        theta = y * scale
        g0, g1, g2 = geometric_factors(theta)
        return (v["c"] * scale * g0 + v["b"] * theta * g1 + v["a"] / scale * theta**2 * g2) \
            / theta
    return decay.decay_rate(y, v["a"], v["b"], v["c"]) / y


def _rate_label(fit) -> str:
    if fit.model == POWER:
        return "model k*y^(n-1)"
    if hasattr(fit, "radians_per_unit"):
        return "model (pendulum law)"
    return "model c/y + b + a*y"


def _model_q(fit, y, omega):
    """(Q, {part: Q_part}) of the fit at amplitudes ``y``."""
    if y is None:
        return None, {}
    v = fit.values
    if fit.model == POWER:
        return omega / (2.0 * v["k"] * y ** (v["n"] - 1)), {}
    if hasattr(fit, "radians_per_unit"):
        # The pendulum's energy Q along the fit, as a function of the fitted amplitude.
        order = np.argsort(fit.y_fit)
        q = np.interp(y, fit.y_fit[order], fit.q[order], left=np.nan, right=np.nan)
        return q, {}
    coulomb, hysteretic, fluid = decay.quality_parts(y, omega, v["a"], v["b"], v["c"])
    parts = {key: part for key, part in (("fluid", fluid), ("hysteretic", hysteretic),
                                         ("coulomb", coulomb)) if np.all(np.isfinite(part))}
    if len(parts) < 2:
        parts = {}  # one regime: its part is the total
    return decay.quality_factor(y, omega, v["a"], v["b"], v["c"]), parts


def _period_law(fit, y, view):
    """(period at amplitudes ``y``, label): the pendulum's law with its fitted T0, or the
    period from the crests' spacing."""
    if _is_pendulum(fit):
        from mcfit.fit.pendulum import period_ratio

        period0 = fit.small_angle_period
        return (period0 * period_ratio(y * fit.radians_per_unit),
                f"pendulum law, T0 = {period0:.4g} {view.time_unit}")
    return (np.full(y.shape, view.period),
            f"period from the crests' spacing, {view.period:.4g} {view.time_unit}")
