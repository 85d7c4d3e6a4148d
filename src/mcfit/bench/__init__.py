"""Speed against error: the benchmarks behind ``mcfit bench`` and BENCHMARKS.md (issues 6
and 17). One module a section, each with a function that returns plain data and a
formatter that turns it into the printed table:

- :mod:`~mcfit.bench.integrators`: work against precision of the four ways to compute
  x(t) in :mod:`mcfit.motion`.
- :mod:`~mcfit.bench.accuracy` (section "fitting"): RMSE and bias of a, b, c in units of
  the waveform Cramer-Rao bound (:func:`mcfit.bounds.waveform_crlb`) and time per record,
  for mcfit, the log decrement and a Hilbert envelope.
- :mod:`~mcfit.bench.verdicts`: the rates of the true model, a spurious and a missed term,
  and the coverage of the 95 % intervals, per scene.
- :mod:`~mcfit.bench.methods`: the turning-point fit against the waveform fit over Q.
- :mod:`~mcfit.bench.cycles`: turning-point cost per cycle from 10^3 to 10^6 cycles, and
  a CSV of 10^7 samples and 10^6 cycles (issue 28).
- :mod:`~mcfit.bench.throughput`: every target of issue 17 (per record, batch, start-up,
  10^7 samples) against its measured figure.
- :mod:`~mcfit.bench.waveform_speed` (section "waveform"): the default method on a mixed
  batch against the turning-point method, and the waveform fit's time by Q (issue 28).

The scenes and grids are in :mod:`~mcfit.bench.config`, the records (all generated, none
read from the source tree) in :mod:`~mcfit.bench.records`, the clocks in
:mod:`~mcfit.bench.timing`, the figures in :mod:`~mcfit.bench.plots` (matplotlib only when
drawing) and :func:`run` in :mod:`~mcfit.bench.driver`. Nothing here asserts a time.
"""

from __future__ import annotations

from mcfit.bench.accuracy import (FitCell, format_fitting, hilbert_envelope_rate,
                                  log_decrement_rate, run_fitting)
from mcfit.bench.config import (FIG_20_19_SCENE, FIT_SCENES, FULL, INTEGRATOR_SCENES, QUICK,
                                SECTIONS, THROUGHPUT_SCENE, BenchConfig, FitScene,
                                IntegratorScene)
from mcfit.bench.driver import run
from mcfit.bench.integrators import (IntegratorResult, WorkPoint, format_integrators,
                                     run_integrators)
from mcfit.bench.plots import plot_fitting, plot_integrators
from mcfit.bench.throughput import Throughput, format_throughput, run_throughput
from mcfit.bench.timing import machine_summary

__all__ = [
    "SECTIONS", "IntegratorScene", "FitScene", "INTEGRATOR_SCENES", "FIT_SCENES",
    "FIG_20_19_SCENE", "THROUGHPUT_SCENE", "BenchConfig", "QUICK", "FULL", "WorkPoint",
    "IntegratorResult", "FitCell", "Throughput", "machine_summary", "log_decrement_rate",
    "hilbert_envelope_rate", "run_integrators", "run_fitting", "run_throughput",
    "format_integrators", "format_fitting", "format_throughput", "plot_integrators",
    "plot_fitting", "run",
]
