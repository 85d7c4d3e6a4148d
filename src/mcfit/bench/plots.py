"""The bench's figures: work against precision of the integrators, and the fitting error
against the Cramer-Rao bound. matplotlib is imported only when a figure is drawn."""

from __future__ import annotations

import math

from mcfit.bench.config import SAMPLING_OFFSET, BenchConfig
from mcfit.bench.integrators import IntegratorResult

__all__ = ["plot_integrators", "plot_fitting"]


_METHOD_STYLE = {"cromer-euler": ("tab:red", "o"), "symplectic": ("tab:blue", "s"),
                 "accurate": ("tab:green", "^"), "averaged": ("black", "*")}


def plot_integrators(result: IntegratorResult, path) -> None:
    """Error against wall time (log-log), one panel per scene, written to ``path`` (PNG)."""
    from matplotlib.figure import Figure

    from mcfit.plots import save_figure

    scenes = result.scenes
    figure = Figure(figsize=(5.0 * len(scenes), 4.6), layout="constrained")
    axes_list = figure.subplots(1, len(scenes), squeeze=False)[0]
    for axes, scene in zip(axes_list, scenes):
        for method, (color, marker) in _METHOD_STYLE.items():
            points = [p for p in result.points if p.scene == scene.name and p.method == method]
            if not points:
                continue
            label = method if len(points) == 1 else (
                f"{method} ({points[0].setting} to {points[-1].setting.split()[-1]})")
            axes.loglog([1e3 * p.seconds for p in points], [max(p.error, 1e-16) for p in points],
                        color=color, marker=marker, markersize=9 if method == "averaged" else 5,
                        label=label)
        axes.set_title(scene.name, fontsize=10)
        axes.set_xlabel("wall time per record (ms)")
        axes.set_ylabel("max |x - x_ref| / y0")
        axes.grid(True, which="major", alpha=0.3)
    axes_list[0].legend(fontsize=8)
    figure.suptitle("Work against precision of the integrators of Eq. 20.55")
    save_figure(figure, path)


def plot_fitting(cells, config: BenchConfig, path) -> None:
    """RMSE/CRLB against SNR, one row per scene and one column per samples/cycle (PNG)."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import LogFormatter

    from mcfit.plots import save_figure

    class _PlainLogFormatter(LogFormatter):
        """Plain numbers (0.6, 2, 30) rather than 6x10^-1 on short log axes."""

        def __call__(self, value, pos=None):
            return f"{value:g}" if super().__call__(value, pos) else ""

    scenes = [s for s in config.fit_scenes if any(c.scene == s.name for c in cells)]
    columns = config.samples_per_cycle
    figure = Figure(figsize=(4.4 * len(columns), 3.8 * len(scenes)), layout="constrained")
    grid = figure.subplots(len(scenes), len(columns), squeeze=False, sharey="row")
    colors = {"a": "tab:orange", "b": "tab:green", "c": "tab:purple"}
    method_styles = {"log decrement": ("tab:red", "o"), "Hilbert envelope": ("tab:blue", "s")}
    for row, scene in zip(grid, scenes):
        for axes, spc in zip(row, columns):
            here = [c for c in cells if c.scene == scene.name
                    and math.isclose(c.samples_per_cycle, spc + SAMPLING_OFFSET)]
            for method in dict.fromkeys(c.method for c in here):
                mine = sorted((c for c in here if c.method == method), key=lambda c: c.snr)
                for k in scene.model:
                    if method.startswith("mcfit"):
                        color, marker = colors[k], "^" if "forced" in method else "v"
                        style = "-" if "forced" in method else "--"
                        label = f"{method}: {k}"
                    else:
                        (color, marker), style, label = method_styles[method], ":", method
                    values = [c.rmse_ratio.get(k, math.nan) for c in mine]
                    axes.loglog([c.snr for c in mine], values, style, color=color,
                                marker=marker, label=label)
            axes.axhline(1.0, color="grey", linewidth=0.8)
            axes.yaxis.set_major_formatter(_PlainLogFormatter())
            axes.yaxis.set_minor_formatter(_PlainLogFormatter(labelOnlyBase=False,
                                                              minor_thresholds=(1, 0.5)))
            axes.set_title(f"{scene.name}\n(true model {scene.model}), "
                           f"{spc + SAMPLING_OFFSET:g} samples/cycle", fontsize=8)
            axes.set_xlabel("SNR = y0 / sigma_x")
            axes.grid(True, which="major", alpha=0.3)
        row[0].set_ylabel("RMSE / Cramer-Rao bound")
        row[-1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    figure.suptitle(f"Fitting error in units of the Cramer-Rao bound ({config.repeats} records "
                    "per point)")
    save_figure(figure, path)
