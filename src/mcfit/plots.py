"""Report figure: the record, the amplitudes and fits, Q(t), and damping rate against amplitude.

matplotlib is used through ``matplotlib.figure.Figure`` only (no pyplot, no display needed).
"""

from __future__ import annotations

import math

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from mcfit import decay
from mcfit.files import replace_atomically, temporary_beside
from mcfit.fit import NONE, POWER, REGIME_NAMES, DecayFit, PowerLawFit

__all__ = ["RecordView", "record_view", "report_figure", "draw_record", "plot_record",
           "save_figure"]

_SINGLE_STYLE = {"a": ("tab:orange", "fluid only (a)"), "b": ("tab:green", "hysteretic only (b)"),
                 "c": ("tab:purple", "Coulomb only (c)")}


@dataclass(frozen=True)
class RecordView:
    """What the figure shows of the record besides the fit.

    ``t``/``x`` are the waveform samples (None for a turning-point table);
    ``equilibrium`` the estimated equilibrium at each sample (same shape as ``t``) or None;
    ``turning_t``/``turning_x`` the signed extremum positions; ``used`` marks the turning
    points that entered the fit (their amplitudes are ``fit.y``). ``signal_unit`` names the
    signal's unit U in the coefficients' units (a in 1/(U*s), c in U/s).
    """

    title: str
    t: np.ndarray | None
    x: np.ndarray | None
    equilibrium: np.ndarray | None
    turning_t: np.ndarray
    turning_x: np.ndarray
    used: np.ndarray
    time_label: str = "time (s)"
    signal_label: str = "signal"
    signal_unit: str = "U"  # the signal's unit, for the coefficients' units


def record_view(analysis, title: str) -> RecordView:
    """What the figure shows of a fitted :class:`mcfit.analysis.Analysis`'s record."""
    record, turning = analysis.record, analysis.turning
    if record.kind == "waveform":
        t, x = record.t, record.x
        equilibrium = turning.equilibrium_at(t)
        turning_x = turning.equilibrium_at(turning.t) + turning.sign * turning.y
    else:
        t = x = equilibrium = None
        turning_x = turning.y
    time_label = ("cycle number n" if record.domain == "cycle"
                  else f"time ({record.time_unit or 's'})")
    return RecordView(title=title, t=t, x=x, equilibrium=equilibrium,
                      turning_t=np.asarray(turning.t), turning_x=np.asarray(turning_x),
                      used=np.asarray(turning.used), time_label=time_label,
                      signal_label=record.signal_unit or record.signal_column or "signal",
                      signal_unit=record.signal_unit or "U")


def plot_record(analysis, ax=None):
    """:func:`draw_record` of an analysis on ``ax`` (a new figure's axes when None)."""
    if ax is None:
        ax = Figure(figsize=(7, 4), layout="constrained").add_subplot()
    draw_record(ax, record_view(analysis, analysis.source), analysis.fit)
    return ax


def report_figure(view: RecordView, fit: DecayFit) -> Figure:
    """Four panels: record, amplitudes (+ residuals), Q(t) with parts, rate against amplitude."""
    figure = Figure(figsize=(12, 9.5), layout="constrained")
    grid = figure.add_gridspec(3, 2, height_ratios=[3, 1, 3])
    axes_record = figure.add_subplot(grid[0, 0])
    axes_amplitude = figure.add_subplot(grid[0, 1])
    axes_residual = figure.add_subplot(grid[1, 1], sharex=axes_amplitude)
    axes_q = figure.add_subplot(grid[2, 0])
    axes_rate = figure.add_subplot(grid[2, 1])
    draw_record(axes_record, view, fit)
    _draw_amplitudes(axes_amplitude, axes_residual, view, fit)
    _draw_q(axes_q, view, fit)
    _draw_rate(axes_rate, view, fit)
    figure.suptitle(f"{view.title}: {_verdict(fit)}", fontsize=13)
    # Free the blank cell under the record panel for a parameter summary.
    summary = figure.add_subplot(grid[1, 0])
    summary.axis("off")
    summary.text(0.0, 1.0, _summary_text(fit, view.signal_unit), va="top", ha="left",
                 family="monospace",
                 fontsize=9, transform=summary.transAxes)
    return figure


def _verdict(fit) -> str:
    if fit.model == POWER:
        return "power-law damping"
    if fit.model == NONE:
        return "no damping detected"
    kept = ", ".join(REGIME_NAMES[k] for k in fit.model).replace("coulomb", "Coulomb")
    return f"{kept} damping" if fit.resolved else "damping (regime not resolved: constant Q)"


def _summary_text(fit: DecayFit | PowerLawFit, signal_unit: str) -> str:
    unit = "s" if fit.domain == "time" else "cycle"
    u = signal_unit
    lines = []
    if fit.model == POWER:
        v, e = fit.values, fit.stderr
        lines.append(f"dy/d{unit} = -k*y^n: n = {v['n']:.3f} +- {e['n']:.2g}, k = {v['k']:.4g}")
    else:
        for key, label in (("a", f"a (1/({u}*{unit}))"), ("b", f"b (1/{unit})"),
                           ("c", f"c ({u}/{unit})")):
            value, error = fit.values[key], fit.stderr[key]
            if key in fit.selection.terms:
                lines.append(f"{label:16s} {value:.4g} +- {error:.2g}" if error else
                             f"{label:16s} {value:.4g}")
    q = fit.q_summary
    if q and q.get("initial_stderr") is not None:
        lines.append(f"Q initial {q['initial']:.4g} +- {q['initial_stderr']:.2g}, "
                     f"final {q['final']:.4g} +- {q['final_stderr']:.2g}")
    elif q:
        lines.append(f"Q initial {q['initial']:.4g}, final {q['final']:.4g}, "
                     f"min {q['min']:.4g}, max {q['max']:.4g}")
    elif getattr(fit, "q_lower_bound", None) is not None:
        lines.append(f"Q > {fit.q_lower_bound:.2g} (95 %)")
    lines.append(f"{fit.n_points} turning points, reduced chi-square {fit.reduced_chi_square:.3g}")
    return "\n".join(lines)


def draw_record(axes, view, fit):
    """The record, its turning points (used and left out) and the fitted envelope."""
    unit_label = view.time_label
    if view.t is not None:
        axes.plot(view.t, view.x, color="0.55", lw=0.6, label="record")
        if view.equilibrium is not None:
            axes.plot(view.t, view.equilibrium, color="k", lw=0.8, ls=":", label="equilibrium")
    used = view.used.astype(bool)
    axes.plot(view.turning_t[used], view.turning_x[used], "o", ms=3, color="tab:blue",
              label="turning points used")
    if np.any(~used):
        axes.plot(view.turning_t[~used], view.turning_x[~used], "x", ms=4, color="tab:red",
                  label="left out")
    t_fine = np.linspace(fit.t[0], fit.t[-1], 800)
    envelope = fit.amplitude(t_fine)
    if view.t is not None and view.equilibrium is not None:
        centre = np.interp(t_fine, view.t, view.equilibrium)
        axes.plot(t_fine, centre + envelope, color="tab:red", lw=1.2, label="fitted envelope")
        axes.plot(t_fine, centre - envelope, color="tab:red", lw=1.2)
    else:
        axes.plot(t_fine, envelope, color="tab:red", lw=1.2, label="fitted envelope")
    axes.set_xlabel(unit_label)
    axes.set_ylabel(view.signal_label)
    axes.set_title("record and turning points")
    axes.legend(loc="upper right", fontsize=8)


def _draw_amplitudes(axes, axes_residual, view, fit):
    t_fine = np.linspace(fit.t[0], fit.t[-1], 600)
    axes.errorbar(fit.t, fit.y, yerr=fit.sigma, fmt="o", ms=3, color="tab:blue", elinewidth=0.8,
                  label="amplitudes")
    label = f"selected fit ({fit.model})"
    axes.plot(t_fine, fit.amplitude(t_fine), color="tab:red", lw=1.6, label=label)
    for candidate in fit.candidates:
        if candidate.model in _SINGLE_STYLE and candidate.model != fit.model:
            color, name = _SINGLE_STYLE[candidate.model]
            v = candidate.values
            axes.plot(t_fine, decay.amplitude(t_fine - fit.t0, v["y0"], v["a"], v["b"], v["c"]),
                      color=color, lw=1.0, ls="--", label=name)
    if np.all(fit.y > 0):
        axes.set_yscale("log")
    else:  # crests in the noise, kept as signed projections: linear about 0, log above
        positive = fit.y_fit[fit.y_fit > 0]
        floor = 2 * float(np.median(fit.sigma)) if np.all(np.isfinite(fit.sigma)) else 0.0
        if not floor > 0:
            floor = float(positive.min()) if positive.size else 1.0
        # A whole power of ten, so that the tick labels at 0 and +-floor stand apart.
        axes.set_yscale("symlog", linthresh=10.0 ** math.ceil(math.log10(floor)))
    axes.set_ylabel(f"amplitude ({view.signal_label})")
    axes.set_title("amplitudes: selected fit against single-regime fits")
    axes.legend(loc="upper right", fontsize=8)
    axes.tick_params(labelbottom=False)
    residuals = (fit.y - fit.y_fit) / fit.sigma
    axes_residual.axhline(0.0, color="k", lw=0.6)
    axes_residual.plot(fit.t, residuals, "o", ms=2.5, color="tab:blue")
    axes_residual.set_xlabel(view.time_label)
    axes_residual.set_ylabel("residual / sigma")


def _draw_q(axes, view, fit):
    axes.set_title("quality factor Q and its parts")
    axes.set_xlabel(view.time_label)
    axes.set_ylabel("Q")
    if fit.q is None:
        bound = getattr(fit, "q_lower_bound", None)
        text = (f"no damping detected:\nQ > {bound:.2g} (95 %)" if bound is not None else
                "Q needs the period: not known for this record")
        axes.text(0.5, 0.5, text, ha="center", transform=axes.transAxes)
        return
    axes.plot(fit.t, fit.q, color="k", lw=1.6, label="Q total")
    if getattr(fit, "q_stderr", None) is not None:
        half = fit.interval_factor * fit.q_stderr
        axes.fill_between(fit.t, fit.q - half, fit.q + half,
                          color="0.6", alpha=0.4, label="95 % band")
    if getattr(fit, "q_parts", None) is not None:
        for key, color in (("fluid", "tab:orange"), ("hysteretic", "tab:green"),
                           ("coulomb", "tab:purple")):
            part = fit.q_parts[key]
            # An absent regime is infinite throughout; a present one may be infinite only
            # past a Coulomb stop (y = 0), where the line simply ends.
            if np.any(np.isfinite(part)):
                axes.plot(fit.t, np.where(np.isfinite(part), part, np.nan), color=color,
                          lw=1.0, ls="--",
                          label=f"Q {key}".replace("coulomb", "Coulomb"))
    finite = fit.q[np.isfinite(fit.q)]
    if finite.size:
        axes.set_ylim(0.0, 2.5 * finite.max())
    axes.legend(loc="upper left", fontsize=8)


def _draw_rate(axes, view, fit):
    """-(dy/dt)/y against y: constant for hysteretic, rising for fluid, 1/y for Coulomb."""
    unit = "s" if fit.domain == "time" else "cycle"
    t, y = fit.t, fit.y
    # Rate between neighbouring amplitudes, over spans long enough to beat the noise.
    span = max(1, t.size // 25)
    t_pair, y_start, y_end = t[span:] - t[:-span], y[:-span], y[span:]
    sigma = fit.sigma
    # Only crests clear of the noise: the logarithm of a crest near it is mostly noise.
    valid = (y_start > 3 * sigma[:-span]) & (y_end > 3 * sigma[span:])
    rate = np.log(y_start[valid] / y_end[valid]) / t_pair[valid]
    y_mid = np.sqrt(y_start[valid] * y_end[valid])
    axes.plot(y_mid, rate, "o", ms=3, color="tab:blue", label="from amplitudes")
    shown = y_mid if y_mid.size else y[y > 0]
    y_fine = np.linspace(max(shown.min(initial=y.max()), 1e-12 * y.max()), y.max(), 300)
    v = fit.values
    if fit.model == POWER:
        model_rate = v["k"] * y_fine ** (v["n"] - 1)
        label = "model k*y^(n-1)"
    else:
        model_rate = decay.decay_rate(y_fine, v["a"], v["b"], v["c"]) / y_fine
        label = "model c/y + b + a*y"
    axes.plot(y_fine, model_rate, color="tab:red", lw=1.6, label=label)
    axes.set_xlabel(f"amplitude y ({view.signal_label})")
    axes.set_ylabel(f"-(dy/dt)/y (1/{unit})")
    axes.set_title("damping rate against amplitude")
    axes.legend(loc="best", fontsize=8)


def save_figure(figure: Figure, path) -> None:
    """Write the figure whole or not at all (temporary file, then rename); format from suffix."""
    path = Path(path)
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in {"png", "pdf", "svg"}:
        raise ValueError(f"plot file {path} must end in .png, .pdf or .svg")
    temporary = temporary_beside(path)
    try:
        figure.savefig(temporary, format=suffix, dpi=110)
        replace_atomically(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
