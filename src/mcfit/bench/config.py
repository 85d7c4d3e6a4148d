"""What a bench run covers: the scenes of each section and the quick and full grids.

No heavy imports beyond numpy and :mod:`mcfit.decay`, so that the command line's ``--help``
and the tests can read the configuration cheaply.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mcfit import decay
from mcfit.options import BENCH_SECTIONS

__all__ = ["SECTIONS", "IntegratorScene", "FitScene", "INTEGRATOR_SCENES", "FIT_SCENES",
           "FIG_20_19_SCENE", "THROUGHPUT_SCENE", "BenchConfig", "QUICK", "FULL",
           "GRID_SAMPLES_PER_PERIOD", "REFERENCE_RTOL", "REFERENCE_CHECK_RTOL",
           "SAMPLING_OFFSET", "HILBERT_TRIM_PERIODS"]

SECTIONS = BENCH_SECTIONS

# The common grid on which every integrator is compared with the reference (a divisor of
# every fixed step's steps per period, so simulate_record samples the steps without
# interpolation).
GRID_SAMPLES_PER_PERIOD = 50
REFERENCE_RTOL = 1e-13
# The reference's own error is judged by its distance from a solution this much looser.
REFERENCE_CHECK_RTOL = 1e-12
# Added to the nominal samples per cycle of the fitting records so that the crests drift
# across the sample grid from one half-cycle to the next, as with a clock independent of the
# oscillator; with a whole number every crest would sit at the same place between samples.
SAMPLING_OFFSET = 0.29
# The Hilbert envelope is distorted near the record's ends; this many periods are dropped
# at each end before the line fit.
HILBERT_TRIM_PERIODS = 2.0


@dataclass(frozen=True)
class IntegratorScene:
    """A decay for the work-precision comparison; the motion starts at x = y0, v = 0.

    Coefficients a (1/(U*s)), b (1/s), c (U/s); y0 (U); period and duration (s).
    """

    name: str
    a: float
    b: float
    c: float
    y0: float
    period: float
    duration: float

    def describe(self) -> str:
        omega = 2 * math.pi / self.period
        q0 = float(decay.quality_factor(self.y0, omega, self.a, self.b, self.c))
        stop = float(decay.stop_time(self.y0, self.a, self.b, self.c))
        text = (f"y0 = {self.y0:g}, T = {self.period:g} s, a = {self.a:.4g}, b = {self.b:.4g}, "
                f"c = {self.c:.4g}, {self.duration:g} s ({self.duration / self.period:g} "
                f"periods), Q(y0) = {q0:.4g}")
        if stop < self.duration:
            text += f", amplitude law stops at {stop:.4g} s"
        return text


@dataclass(frozen=True)
class FitScene:
    """A decay whose averaged waveform plus white noise makes the fitting records.

    ``model`` names the true regimes (letters of "abc"); ``offset`` is the equilibrium x_eq
    (U). The record runs for ``cycles`` periods from a random phase.
    """

    name: str
    model: str
    y0: float
    a: float
    b: float
    c: float
    period: float
    cycles: int
    offset: float = 0.1

    @property
    def values(self) -> dict:
        return {"a": self.a, "b": self.b, "c": self.c}

    def describe(self) -> str:
        omega = 2 * math.pi / self.period
        q0 = float(decay.quality_factor(self.y0, omega, self.a, self.b, self.c))
        end = float(decay.amplitude(self.cycles * self.period, self.y0, self.a, self.b, self.c))
        coefficients = ", ".join(f"{k} = {self.values[k]:g}" for k in self.model)
        return (f"y0 = {self.y0:g}, T = {self.period:g} s, {coefficients}, {self.cycles} "
                f"cycles, x_eq = {self.offset:g}, Q(y0) = {q0:.3g}, y_end/y0 = "
                f"{end / self.y0:.3g}")


INTEGRATOR_SCENES = (
    IntegratorScene("Q 12.5, all three regimes (Fig. 20.19)", 0.1, 0.1, 0.01, 4.0, 0.5, 20.0),
    IntegratorScene("Q 1000, hysteretic only", 0.0, math.pi / 1000, 0.0, 1.0, 1.0, 100.0),
    IntegratorScene("Coulomb-dominated stop", 0.0, 0.002, 0.05, 1.0, 1.0, 25.0),
)

# The scene of Figure 20.19.
FIG_20_19_SCENE = FitScene("all three regimes (Fig. 20.19)", "abc", 4.0, 0.1, 0.1, 0.01, 0.5,
                           40)
# From 20 to 500 cycles: the range of the accuracy bar (BENCHMARKS.md).
FIT_SCENES = (
    FitScene("hysteretic only", "b", 1.0, 0.0, 0.02, 0.0, 1.0, 100),
    FitScene("all three regimes, slow (500 cycles)", "abc", 4.0, 0.005, 0.005, 0.0005, 0.5,
             500),
    FIG_20_19_SCENE,
    FitScene("fluid and hysteretic, short (20 cycles)", "ab", 1.0, 0.05, 0.03, 0.0, 1.0, 20),
)
# The records of issue 17's throughput targets: 10^4 samples over 80 cycles, about 159
# crests (Fig. 20.19's law at half its coefficients, so that it lasts the 80 cycles).
THROUGHPUT_SCENE = FitScene("all three regimes, 80 cycles", "abc", 4.0, 0.05, 0.05, 0.005,
                            0.5, 80)


@dataclass(frozen=True)
class BenchConfig:
    """What a bench run covers. :data:`QUICK` runs in about five minutes, :data:`FULL` in
    about an hour on two cores (most of it the methods section's waveform fits).

    Attributes
    ----------
    steps_per_period : tuple of int
        Fixed steps ``dt = T/N`` for Cromer-Euler and the symplectic scheme; each N a
        multiple of :data:`GRID_SAMPLES_PER_PERIOD`.
    rtols : tuple of float
        Relative tolerances of the accurate integrator.
    snrs : tuple of float
        Signal-to-noise ratios ``y0 / sigma_x`` of the fitting records.
    samples_per_cycle : tuple of int
        Nominal samples per period of the fitting records (plus :data:`SAMPLING_OFFSET`).
    repeats : int
        Noisy records per fitting cell (scene, SNR, samples per cycle).
    batch_records, batch_samples : int
        Number and length of the in-memory records of the throughput section.
    batch_files : int
        Files of ``batch_samples`` samples given to ``mcfit DIR`` (issue 17 names 200).
    batch_runs : int
        Runs of each ``mcfit DIR`` command (the fastest is kept).
    batch_methods : tuple of str
        The ``--method`` of each ``mcfit DIR`` command timed.
    startup_runs : int
        Runs of each start-up command (the fastest is kept).
    big_samples : int or None
        Samples of the large CSV fitted by ``mcfit FILE``; None skips it.
    verdict_records : int
        Noisy records per scene of the verdicts section.
    method_records : int
        Noisy records per Q of the methods section.
    method_qs : tuple
        The Q values of the methods section.
    edge_records : int
        Noisy records per scene of the edges section.
    edge_scenes : tuple or None
        The edges section's scenes; None for all of :data:`mcfit.bench.edges.EDGE_SCENES`.
    mixed_records : int
        Records of the waveform section's mixed batch (issue 28 names 100).
    waveform_runs : int
        Runs of each waveform fit timed in the waveform section (the fastest is kept).
    seed : int
        Seed of every random record.
    integrator_scenes, fit_scenes : tuple
        The scenes (:data:`INTEGRATOR_SCENES`, :data:`FIT_SCENES`).
    """

    name: str = "quick"
    steps_per_period: tuple = (50, 250, 1000)
    rtols: tuple = (1e-4, 1e-7, 1e-10)
    snrs: tuple = (1e3,)
    samples_per_cycle: tuple = (20,)
    repeats: int = 8
    batch_records: int = 20
    batch_samples: int = 10_000
    batch_files: int = 40
    batch_runs: int = 1
    batch_methods: tuple = ("turning-points", "auto")
    startup_runs: int = 3
    big_samples: int | None = None
    verdict_records: int = 40
    method_records: int = 3
    method_qs: tuple = (3, 20)
    edge_records: int = 5
    edge_scenes: tuple | None = None
    mixed_records: int = 20
    waveform_runs: int = 1
    seed: int = 2026
    integrator_scenes: tuple = INTEGRATOR_SCENES
    fit_scenes: tuple = FIT_SCENES


QUICK = BenchConfig()
FULL = BenchConfig(name="full", steps_per_period=(50, 100, 250, 500, 1000, 2500, 5000),
                   rtols=(1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11),
                   snrs=(1e2, 1e3, 1e4), samples_per_cycle=(10, 20, 50, 200), repeats=100,
                   batch_records=200, batch_files=200, batch_runs=3, startup_runs=7,
                   big_samples=10_000_000, verdict_records=400,
                   method_records=40, method_qs=(2, 3, 5, 10, 20, 50),
                   edge_records=60, mixed_records=100, waveform_runs=3)

