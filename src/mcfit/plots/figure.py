"""The report figure: the chosen panels in two columns, the parameter box, the title."""

from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure

from mcfit import __version__
from mcfit.files import replace_atomically, temporary_beside
from mcfit.fit import NONE, POWER, TERMS, DecayFit, PowerLawFit
from mcfit.fit.models import regime_name
from mcfit.options import DEFAULT_PANELS, check_plot_name, parse_figsize, parse_panels
from mcfit.plots.against_amplitude import draw_backbone, draw_q_amplitude, draw_rate
from mcfit.plots.against_time import draw_amplitudes, draw_q, draw_record
from mcfit.plots.legends import place_legends
from mcfit.plots.view import record_view
from mcfit.report import coefficient_units

__all__ = ["DPI", "report_figure", "plot_record", "save_figure", "figure_metadata",
           "figure_size", "summary_text"]

_DRAW = {"record": draw_record, "q": draw_q, "rate": draw_rate, "qamp": draw_q_amplitude,
         "backbone": draw_backbone}
# Inches: the width of the two columns (legends inside or under them), the height of a row
# of panels and of the strip under the amplitudes (residuals beside the parameter box).
_WIDTH, _ROW, _STRIP = 13.0, 4.0, 1.6
# Dots per inch of a PNG figure unless told otherwise.
DPI = 110


def figure_size(panels) -> tuple[float, float]:
    """The default size of a figure of ``panels`` (inches)."""
    rows = _rows(panels)
    strip = "amplitude" in panels or len(rows[-1]) == 2
    return (_WIDTH if len(panels) > 1 else _WIDTH / 2 + 1.0,
            0.6 + _ROW * len(rows) + _STRIP * strip)


def _rows(panels):
    return [tuple(panels[i:i + 2]) for i in range(0, len(panels), 2)]


def report_figure(view, fit: DecayFit | PowerLawFit, panels=DEFAULT_PANELS,
                  figsize=None) -> Figure:
    """The record's panels, two a row in the order given, with the residuals under the
    amplitudes and the parameter box beside them (else in a free cell or a strip at the
    bottom); the title is ``view.title``.

    Parameters
    ----------
    view : RecordView
    fit : DecayFit or PowerLawFit
    panels : sequence of str or str
        Names from :data:`mcfit.options.PANELS`, or one comma-separated string.
    figsize : (float, float) or str, optional
        Width and height in inches [default: :func:`figure_size`].
    """
    panels = parse_panels(panels)
    rows = _rows(panels)
    size = figure_size(panels) if figsize is None else parse_figsize(figsize)
    figure = Figure(figsize=size, layout="constrained")
    strip = next((i for i, row in enumerate(rows) if "amplitude" in row), None)
    extra = strip is None and len(rows[-1]) == 2  # the box needs a strip of its own
    ratios = [r for i in range(len(rows)) for r in ([3, 1] if i == strip else [3])]
    grid = figure.add_gridspec(len(ratios) + extra, 2, height_ratios=ratios + [1] * extra)
    line, box = 0, None
    for i, row in enumerate(rows):
        tall = i == strip
        for column, name in enumerate(row):
            if name == "amplitude":
                axes = figure.add_subplot(grid[line, column])
                draw_amplitudes(axes, figure.add_subplot(grid[line + 1, column], sharex=axes),
                                view, fit)
            else:
                _DRAW[name](figure.add_subplot(grid[line, column]), view, fit)
                if tall:
                    box = grid[line + 1, column]
        if len(row) == 1 and box is None:  # the free cell beside the last panel
            box = grid[line:line + 1 + tall, 1]
        line += 1 + tall
    summary = figure.add_subplot(box if box is not None else grid[line, :])
    summary.axis("off")
    summary.text(0.0, 1.0, summary_text(fit, view), va="top", ha="left", family="monospace",
                 fontsize=9, transform=summary.transAxes)
    figure.suptitle(view.title, fontsize=13)
    place_legends(figure)
    return figure


def _verdict(fit) -> str:
    if fit.model == POWER:
        return "power-law damping"
    if fit.model == NONE:
        return "no damping detected"
    form = getattr(fit, "damping_form", None)  # a waveform fit's
    kept = ", ".join(regime_name(k, form) for k in fit.model).replace("coulomb", "Coulomb")
    return f"{kept} damping" if fit.resolved else "damping (regime not resolved: constant Q)"


def summary_text(fit: DecayFit | PowerLawFit, view) -> str:
    """The parameter box: the verdict, the coefficients in the record's units, Q."""
    per = "s" if fit.domain == "time" else "cycle"
    lines = [_verdict(fit) + (" (pendulum law)" if hasattr(fit, "small_angle_period")
                              else "")]
    if fit.model == POWER:
        v, e = fit.values, fit.stderr
        lines.append(f"dy/d{per} = -k*y^n: n = {v['n']:.3f} +- {e['n']:.2g}, "
                     f"k = {v['k']:.4g}")
    else:
        units = coefficient_units(view.unit, view.time_unit)
        for key in TERMS:
            label = f"{key} ({units[key]})"
            value, error = fit.values[key], fit.stderr[key]
            if key in fit.selection.terms:
                lines.append(f"{label:18s} {value:.4g} +- {error:.2g}" if error else
                             f"{label:18s} {value:.4g}")
    q = fit.q_summary
    if q and q.get("initial_stderr") is not None:
        lines.append(f"Q initial {q['initial']:.4g} +- {q['initial_stderr']:.2g}, "
                     f"final {q['final']:.4g} +- {q['final_stderr']:.2g}")
    elif q:
        lines.append(f"Q initial {q['initial']:.4g}, final {q['final']:.4g}, "
                     f"min {q['min']:.4g}, max {q['max']:.4g}")
    elif getattr(fit, "q_lower_bound", None) is not None:
        lines.append(f"Q > {fit.q_lower_bound:.2g} (95 %)")
    # A waveform fit's points are the record's samples, not its turning points.
    points = "samples" if getattr(fit, "method", None) == "waveform" else "turning points"
    lines.append(f"{fit.n_points} {points}, reduced chi-square {fit.reduced_chi_square:.3g}")
    if view.unit is None and fit.model not in (POWER, NONE):
        lines.append("U: the signal's unit (not named in the record)")
    return "\n".join(lines)


def plot_record(analysis, ax=None, unit=None):
    """:func:`draw_record` of an analysis on ``ax`` (a new figure's axes when None)."""
    if ax is None:
        ax = Figure(figsize=(8, 4), layout="constrained").add_subplot()
    draw_record(ax, record_view(analysis, unit=unit), analysis.fit)
    return ax


def figure_metadata(file_format: str) -> dict:
    """What a figure file says made it, as matplotlib's ``savefig(metadata=...)`` takes it
    for ``file_format`` ("png", "pdf", "svg"): mcfit and its version, in PNG's
    "Software", PDF's "Creator" and "Producer", SVG's "Creator"."""
    import matplotlib

    made_by = f"mcfit {__version__}"
    with_matplotlib = f"{made_by} (matplotlib {matplotlib.__version__})"
    if file_format == "png":
        return {"Software": with_matplotlib}
    if file_format == "pdf":
        return {"Creator": made_by, "Producer": with_matplotlib}
    if file_format == "svg":
        return {"Creator": with_matplotlib}
    return {}


def save_figure(figure: Figure, path, dpi=None) -> None:
    """Write the figure whole or not at all (temporary file, then rename); format from
    suffix, with mcfit's version in its metadata (:func:`figure_metadata`). ``dpi`` is a
    PNG's dots per inch [default: :data:`DPI`]."""
    check_plot_name(path)
    path = Path(path)
    file_format = path.suffix.lower().lstrip(".")
    temporary = temporary_beside(path)
    try:
        figure.savefig(temporary, format=file_format, dpi=dpi or DPI,
                       metadata=figure_metadata(file_format))
        replace_atomically(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
