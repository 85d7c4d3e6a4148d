"""The panels against time: the record, the amplitudes with the fits, and Q(t)."""

from __future__ import annotations

import math

import numpy as np
from matplotlib import ticker

from mcfit import decay
from mcfit.fit import POWER
from mcfit.plots.legends import place_legend
from mcfit.plots.style import (DATA, LEFT_OUT, REGIME_OF_PART, REGIME_STYLE, SELECTED,
                               TOTAL, clipped, off_scale_note, padded, readable_log_axis,
                               span_of, visible)

__all__ = ["draw_record", "draw_amplitudes", "draw_q"]

_SINGLE_NAME = {"a": "fluid only (a)", "b": "hysteretic only (b)", "c": "Coulomb only (c)"}
# Parts of Q are drawn up to this many times the largest total Q; above, they say nothing
# the total does not.
_PART_REACH = 3.0
# A band is seen where it reaches this many points beyond each edge of the line it is about.
_BAND_SHOWS = 1.0


def draw_record(axes, view, fit):
    """The record, its turning points (used and left out) and the fitted envelope; the
    stretches that are not the free decay shaded, and where it starts and ends marked."""
    if view.whole_t is not None:
        _draw_left_out(axes, view)
    if view.t is not None:
        axes.plot(view.t, view.x, color="0.55", lw=0.5, label="record")
        if view.equilibrium is not None:
            axes.plot(view.t, view.equilibrium, color="k", lw=0.8, ls=":",
                      label="equilibrium")
    used = view.used.astype(bool)
    axes.plot(view.turning_t[used], view.turning_x[used], ls="none", marker="o", ms=3,
              color=DATA["color"], label="turning points used")
    if np.any(~used):
        axes.plot(view.turning_t[~used], view.turning_x[~used], label="left out", **LEFT_OUT)
    t_fine = np.linspace(fit.t[0], fit.t[-1], 800)
    envelope = fit.amplitude(t_fine)
    if view.t is not None and view.equilibrium is not None:
        centre = np.interp(t_fine, view.t, view.equilibrium)
        axes.plot(t_fine, centre + envelope, label="fitted envelope", **SELECTED)
        axes.plot(t_fine, centre - envelope, **SELECTED)
    else:
        axes.plot(t_fine, envelope, label="fitted envelope", **SELECTED)
    axes.set_xlabel(view.time_label)
    axes.set_ylabel(view.signal_label)
    axes.set_title("record and turning points")
    place_legend(axes)


def _draw_left_out(axes, view):
    """The record as read, lighter, with the stretches left out shaded and the free
    decay's start and end marked."""
    axes.plot(view.whole_t, view.whole_x, color="0.8", lw=0.5)
    for number, (start, end, _) in enumerate(view.left_out):
        axes.axvspan(start, end, color="0.85", alpha=0.6, lw=0,
                     label=None if number else "left out: not the free decay")
    for edge, inside in ((view.t[0], view.t[0] > view.whole_t[0]),
                         (view.t[-1], view.t[-1] < view.whole_t[-1])):
        if inside:
            axes.axvline(edge, color="0.3", lw=0.8, ls="--")


def draw_amplitudes(axes, axes_residual, view, fit):
    """Amplitudes with error bars, the selected fit and the single-regime fits (clipped
    to the range of the data and the selected fit), and the normalised residuals."""
    t_fine = np.linspace(fit.t[0], fit.t[-1], 600)
    selected = fit.amplitude(t_fine)
    sigma = np.where(np.isfinite(fit.sigma), fit.sigma, 0.0)
    axes.errorbar(fit.t, fit.y, yerr=sigma, label="amplitudes", **DATA)
    axes.plot(t_fine, selected, label=f"selected fit ({fit.model})", **SELECTED)
    log = bool(np.all(fit.y > 0))
    if log:
        low, high = padded(span_of(fit.y - sigma, fit.y + sigma, selected, positive=True),
                           log=True)
        axes.set_yscale("log")
    else:  # crests in the noise, kept as signed projections: linear about 0, log above
        low, high = padded(span_of(fit.y - sigma, fit.y + sigma, selected))
        positive = fit.y_fit[fit.y_fit > 0]
        floor = 2 * float(np.median(fit.sigma)) if np.all(np.isfinite(fit.sigma)) else 0.0
        if not floor > 0:
            floor = float(positive.min()) if positive.size else 1.0
        # A whole power of ten, so that the tick labels at 0 and +-floor stand apart.
        axes.set_yscale("symlog", linthresh=10.0 ** math.ceil(math.log10(floor)))
    hidden = []
    for candidate in fit.candidates:
        if candidate.model in _SINGLE_NAME and candidate.model != fit.model:
            v = candidate.values
            curve = decay.amplitude(t_fine - fit.t0, v["y0"], v["a"], v["b"], v["c"])
            color, dashes = REGIME_STYLE[candidate.model]
            if visible(curve, low, high):
                axes.plot(t_fine, clipped(curve, low, high), color=color, ls=dashes, lw=1.3,
                          label=_SINGLE_NAME[candidate.model])
            else:
                hidden.append((_SINGLE_NAME[candidate.model], curve))
    axes.set_ylim(low, high)
    if log:
        readable_log_axis(axes.yaxis, low, high)
    else:
        axes.yaxis.set_major_formatter(ticker.FuncFormatter(lambda value, _: f"{value:g}"))
    axes.set_ylabel(view.amplitude_label)
    axes.set_title("amplitudes: selected fit against single-regime fits")
    off_scale_note(axes, curves=hidden)
    axes.tick_params(labelbottom=False)
    place_legend(axes)
    _draw_residuals(axes_residual, view, fit)


def _draw_residuals(axes, view, fit):
    """The turning points' residuals in their sigmas; for a waveform fit, which fitted the
    samples and not these points, their difference from its law in percent, and a word
    on the samples' fit (a crest of a fast decay is not its envelope: in sigmas of the
    turning points that gap reads as a misfit)."""
    waveform = getattr(fit, "method", None) == "waveform"
    with np.errstate(divide="ignore", invalid="ignore"):
        residuals = (100.0 * (fit.y - fit.y_fit) / fit.y_fit if waveform
                     else (fit.y - fit.y_fit) / fit.sigma)
    axes.axhline(0.0, color="k", lw=0.6)
    axes.plot(fit.t, residuals, ls="none", marker="o", ms=2.5, color=DATA["color"])
    axes.set_xlabel(view.time_label)
    axes.set_ylabel("point - law (%)" if waveform else "residual / sigma")
    if waveform:
        axes.text(0.99, 0.04, f"not fitted: the waveform was ({fit.n_points} samples, "
                  f"reduced chi-square {fit.reduced_chi_square:.3g})", ha="right",
                  va="bottom", fontsize=7, color="0.35", transform=axes.transAxes)


def draw_q(axes, view, fit):
    """Q(t) with its 95 % band and its parts (Handbook Eq. 20.56), the parts clipped to a
    range set by the total."""
    axes.set_title("quality factor Q and its parts")
    axes.set_xlabel(view.time_label)
    axes.set_ylabel("Q")
    if fit.q is None or not np.any(np.isfinite(fit.q)):
        axes.text(0.5, 0.5, _no_q_text(fit), ha="center", va="center",
                  transform=axes.transAxes)
        return
    half = None
    if getattr(fit, "q_stderr", None) is not None:
        half = np.nan_to_num(fit.interval_factor * fit.q_stderr)
    top = span_of(fit.q + (0.0 if half is None else half))[1]
    parts = _q_parts_shown(fit)
    reach = [part[part <= _PART_REACH * top] for part in parts.values()]
    top = max([top] + [float(r.max()) for r in reach if r.size])
    high = 1.08 * top
    axes.set_ylim(0.0, high)
    band_seen = half is not None and _band_seen(axes, half, high)
    label = "Q total"
    if half is not None and not band_seen:
        label += " (95 % band narrower than the line)"
    axes.plot(fit.t, fit.q, label=label, **TOTAL)
    if band_seen:
        axes.fill_between(fit.t, fit.q - half, fit.q + half, color="0.6", alpha=0.4,
                          hatch="///", edgecolor="0.45", lw=0, label="95 % band")
    hidden = []
    for key, part in parts.items():
        color, dashes = REGIME_STYLE[REGIME_OF_PART[key]]
        label = f"Q {key}".replace("coulomb", "Coulomb")
        if visible(part, 0.0, high):
            axes.plot(fit.t, part, color=color, ls=dashes, lw=1.3, label=label)
        else:
            hidden.append((label, part))
    off_scale_note(axes, curves=hidden)
    place_legend(axes)


def _band_seen(axes, half, high) -> bool:
    """Whether a band of half-width ``half`` (Q units) about the total, on axes from 0 to
    ``high``, shows beyond the total's line somewhere (by a point each side)."""
    points_per_q = axes.get_window_extent().height * 72 / axes.figure.dpi / high
    return bool(np.max(half) * points_per_q > TOTAL["lw"] / 2 + _BAND_SHOWS)


def _q_parts_shown(fit) -> dict:
    """The finite parts of Q; an absent regime is infinite throughout, a present one may be
    infinite only past a Coulomb stop (y = 0), where the line simply ends."""
    if getattr(fit, "q_parts", None) is None or fit.model == POWER:
        return {}
    shown = {}
    for key in ("fluid", "hysteretic", "coulomb"):
        part = np.asarray(fit.q_parts[key], dtype=float)
        if np.any(np.isfinite(part)):
            shown[key] = np.where(np.isfinite(part), part, np.nan)
    return shown if len(shown) > 1 else {}  # one regime: its part is the total


def _no_q_text(fit) -> str:
    bound = getattr(fit, "q_lower_bound", None)
    if bound is not None:
        return f"no damping detected:\nQ > {bound:.2g} (95 %)"
    return "Q needs the period: not known for this record"
