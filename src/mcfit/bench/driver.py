"""The driver of ``mcfit bench``: run the chosen sections and yield each printed block."""

from __future__ import annotations

import os

from mcfit.bench.config import QUICK, SECTIONS, BenchConfig
from mcfit.bench.timing import machine_summary

__all__ = ["run"]


def run(config: BenchConfig = QUICK, sections=SECTIONS, plot_dir=None, progress=None):
    """Run the chosen sections; yield each printed block (text) as soon as it is ready.

    Parameters
    ----------
    config : BenchConfig
    sections : sequence of str
        Names from :data:`SECTIONS`.
    plot_dir : str or os.PathLike, optional
        Directory for ``integrators.png`` and ``fitting.png`` (created if needed).
    progress : callable, optional
        Called with a short message before each step.
    """
    unknown = set(sections) - set(SECTIONS)
    if unknown:
        raise ValueError(f"unknown bench sections {sorted(unknown)}; use {', '.join(SECTIONS)}")
    if plot_dir is not None:
        os.makedirs(plot_dir, exist_ok=True)
    yield machine_summary(config)
    if "integrators" in sections:
        from mcfit.bench.integrators import format_integrators, run_integrators
        from mcfit.bench.plots import plot_integrators

        result = run_integrators(config, progress)
        yield format_integrators(result)
        if plot_dir is not None:
            plot_integrators(result, os.path.join(plot_dir, "integrators.png"))
    if "fitting" in sections:
        from mcfit.bench.accuracy import format_fitting, run_fitting
        from mcfit.bench.plots import plot_fitting

        cells = run_fitting(config, progress)
        yield format_fitting(cells, config)
        if plot_dir is not None:
            plot_fitting(cells, config, os.path.join(plot_dir, "fitting.png"))
    if "verdicts" in sections:
        from mcfit.bench.verdicts import format_verdicts, run_verdicts

        yield format_verdicts(run_verdicts(config.verdict_records, config.seed,
                                           progress=progress))
    if "methods" in sections:
        from mcfit.bench.methods import format_methods, run_methods

        yield format_methods(run_methods(config.method_records, config.seed,
                                         qs=config.method_qs, progress=progress))
    if "cycles" in sections:
        from mcfit.bench.cycles import format_cycles, run_cycles

        yield format_cycles(run_cycles(config, progress))
    if "edges" in sections:
        from mcfit.bench.edges import EDGE_SCENES, format_edges, run_edges

        yield format_edges(run_edges(config.edge_records, config.seed,
                                     config.edge_scenes or EDGE_SCENES, progress))
    if "waveform" in sections:
        from mcfit.bench.waveform_speed import format_waveform_speed, run_waveform_speed

        yield format_waveform_speed(run_waveform_speed(config, progress))
    if "throughput" in sections:
        from mcfit.bench.throughput import format_throughput, run_throughput

        yield format_throughput(run_throughput(config, progress))
