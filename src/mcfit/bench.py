"""Speed against error: the benchmarks behind ``mcfit bench`` and BENCHMARKS.md (issue 6).

Three sections, each a function that returns plain data and a formatter that turns it into
the printed table:

- **integrators** (:func:`run_integrators`): work against precision of the four ways to
  compute x(t) in :mod:`mcfit.motion` (Cromer-Euler over step sizes, the symplectic
  splitting over step sizes, the accurate integrator over rtol, the averaged waveform),
  with the error ``max|x - x_ref| / y0`` on a grid of :data:`GRID_SAMPLES_PER_PERIOD`
  samples per period against the accurate integrator at rtol :data:`REFERENCE_RTOL`.
- **fitting** (:func:`run_fitting`): on the same noisy records, the RMSE and bias of a, b,
  c in units of the waveform Cramer-Rao bound (THEORY.md section 7,
  :func:`mcfit.bounds.waveform_crlb`)
  and the time per record, for mcfit (turning points then :func:`mcfit.fit.fit_decay`,
  forced to the true model and with the model it selects), the log decrement of
  single-sample peaks (:func:`log_decrement_rate`) and a Hilbert-envelope fit
  (:func:`hilbert_envelope_rate`).
- **verdicts** (:mod:`mcfit.bench_verdicts`): the rates of the true model, a spurious and
  a missed term, and the coverage of the 95 % intervals of a, b, c and Q, per scene.
- **methods** (:mod:`mcfit.bench_methods`): the turning-point fit against the waveform fit
  by Eq. 20.55 over Q from 2 to 50 (bias, RMSE and 95 % coverage of b in standard errors,
  time per record), and how often ``--method auto`` chose the waveform.
- **throughput** (:func:`run_throughput`): records per second through
  :func:`mcfit.analysis.analyse_record` in memory and through ``mcfit DIR --jobs 1`` and
  ``--jobs 2`` (:func:`mcfit.batch.run_jobs` over CSV files, run as a subprocess), peak
  memory and the start-up time of the command line.

Timings are wall-clock (``time.perf_counter``) on whatever machine runs them; nothing
here asserts a time. matplotlib is imported only by the plotting functions.
"""

from __future__ import annotations

import contextlib
import datetime
import math
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mcfit import decay, motion
from mcfit.bounds import waveform_crlb
from mcfit.options import BENCH_SECTIONS

__all__ = [
    "SECTIONS",
    "IntegratorScene",
    "FitScene",
    "INTEGRATOR_SCENES",
    "FIT_SCENES",
    "BenchConfig",
    "QUICK",
    "FULL",
    "WorkPoint",
    "IntegratorResult",
    "FitCell",
    "Throughput",
    "machine_summary",
    "log_decrement_rate",
    "hilbert_envelope_rate",
    "run_integrators",
    "run_fitting",
    "run_throughput",
    "format_integrators",
    "format_fitting",
    "format_throughput",
    "plot_integrators",
    "plot_fitting",
    "run",
]

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
# A cheap call is repeated until this much wall time has passed and its fastest run kept.
_TIMING_BUDGET = 0.05
_TIMING_MAX_RUNS = 20


# --------------------------------------------------------------------------- configuration


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

# The scene of Figure 20.19, also the records of the throughput section.
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


@dataclass(frozen=True)
class BenchConfig:
    """What a bench run covers. :data:`QUICK` runs in about two minutes, :data:`FULL` in
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
        Number and length of the records of the throughput section.
    startup_runs : int
        Runs of each start-up command (the median is reported).
    verdict_records : int
        Noisy records per scene of the verdicts section.
    method_records : int
        Noisy records per Q of the methods section.
    method_qs : tuple
        The Q values of the methods section.
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
    startup_runs: int = 3
    verdict_records: int = 40
    method_records: int = 3
    method_qs: tuple = (3, 20)
    seed: int = 2026
    integrator_scenes: tuple = INTEGRATOR_SCENES
    fit_scenes: tuple = FIT_SCENES


QUICK = BenchConfig()
FULL = BenchConfig(name="full", steps_per_period=(50, 100, 250, 500, 1000, 2500, 5000),
                   rtols=(1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11),
                   snrs=(1e2, 1e3, 1e4), samples_per_cycle=(10, 20, 50, 200), repeats=100,
                   batch_records=200, startup_runs=7, verdict_records=400,
                   method_records=40, method_qs=(2, 3, 5, 10, 20, 50))


def machine_summary(config: BenchConfig) -> str:
    """Date, machine, CPU, Python and library versions, and the grid, as a few lines."""
    import lmfit
    import scipy

    cpu = platform.processor() or "unknown"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as handle:
            cpu = next((line.split(":", 1)[1].strip() for line in handle
                        if line.startswith("model name")), cpu)
    except OSError:
        pass
    return (f"mcfit bench ({config.name}), {datetime.date.today().isoformat()}\n"
            f"machine: {platform.machine()}, {os.cpu_count()} CPUs ({cpu}), "
            f"{platform.system()} {platform.release()}\n"
            f"python {platform.python_version()}, numpy {np.__version__}, scipy "
            f"{scipy.__version__}, lmfit {lmfit.__version__}; seed {config.seed}")


def _fastest(function, *args, **kwargs):
    """(smallest wall time in s, result) over repeated calls within a small time budget."""
    best, result, spent, runs = math.inf, None, 0.0, 0
    while runs == 0 or (spent < _TIMING_BUDGET and runs < _TIMING_MAX_RUNS):
        start = time.perf_counter()
        result = function(*args, **kwargs)
        elapsed = time.perf_counter() - start
        best, spent, runs = min(best, elapsed), spent + elapsed, runs + 1
    return best, result


# --------------------------------------------------------------------------- integrators


@dataclass(frozen=True)
class WorkPoint:
    """One integrator run: its cost (s, fastest of a few) and error (max|x - x_ref|/y0)."""

    scene: str
    method: str
    setting: str
    seconds: float
    error: float


@dataclass(frozen=True)
class IntegratorResult:
    """The work-precision points of every scene, with each reference's self-check."""

    points: tuple
    reference_seconds: dict  # scene name -> time of the reference solution (s)
    reference_spread: dict  # scene name -> max|x(rtol 1e-12) - x_ref| / y0
    scenes: tuple = field(default=())


def _grid(scene: IntegratorScene):
    """The common comparison grid: GRID_SAMPLES_PER_PERIOD samples per period, both ends."""
    n = round(scene.duration / scene.period * GRID_SAMPLES_PER_PERIOD) + 1
    return np.arange(n) * (scene.period / GRID_SAMPLES_PER_PERIOD)


def _accurate(scene: IntegratorScene, t, rtol, atol=None):
    omega = 2 * math.pi / scene.period
    terms = motion.damping_terms(scene.a, scene.b, scene.c)
    return motion.integrate_accurate(scene.y0, 0.0, omega, terms, t, rtol=rtol, atol=atol).x


def _fixed_step(scene: IntegratorScene, method, steps_per_period):
    rate = GRID_SAMPLES_PER_PERIOD / scene.period
    return motion.simulate_record(scene.a, scene.b, scene.c, scene.y0, scene.period,
                                  scene.duration, rate, method=method,
                                  dt=scene.period / steps_per_period).x


def _scene_work_points(scene: IntegratorScene, config: BenchConfig, reference):
    """Work-precision points of the four methods on one scene."""
    t = _grid(scene)

    def point(method, setting, function, *args, **kwargs):
        seconds, x = _fastest(function, *args, **kwargs)
        error = float(np.max(np.abs(x - reference)) / scene.y0)
        return WorkPoint(scene.name, method, setting, seconds, error)

    points = []
    for method in ("cromer-euler", "symplectic"):
        points += [point(method, f"dt = T/{n}", _fixed_step, scene, method, n)
                   for n in config.steps_per_period]
    points += [point("accurate", f"rtol {rtol:.0e}", _accurate, scene, t, rtol)
               for rtol in config.rtols]
    points.append(point("averaged", "closed form", motion.averaged_motion, t, scene.y0,
                        scene.a, scene.b, scene.c, scene.period))
    return points


def run_integrators(config: BenchConfig = QUICK, progress=None) -> IntegratorResult:
    """Work against precision of the four integrators on each scene of ``config``.

    Returns
    -------
    IntegratorResult
        Each point's wall time (the fastest of up to 20 calls within 50 ms, or one call)
        and ``max|x - x_ref| / y0`` on the common grid, with ``x_ref`` from the accurate
        integrator at :data:`REFERENCE_RTOL` (atol 1e-15*y0).
    """
    points, seconds, spread = [], {}, {}
    for scene in config.integrator_scenes:
        if progress:
            progress(f"integrators: {scene.name}")
        t = _grid(scene)
        start = time.perf_counter()
        reference = _accurate(scene, t, REFERENCE_RTOL, atol=1e-15 * scene.y0)
        seconds[scene.name] = time.perf_counter() - start
        check = _accurate(scene, t, REFERENCE_CHECK_RTOL, atol=1e-14 * scene.y0)
        spread[scene.name] = float(np.max(np.abs(check - reference)) / scene.y0)
        points += _scene_work_points(scene, config, reference)
    return IntegratorResult(tuple(points), seconds, spread, tuple(config.integrator_scenes))


def format_integrators(result: IntegratorResult) -> str:
    """The work-precision table, one block per scene."""
    lines = [f"Integrators: error = max|x - x_ref| / y0 on {GRID_SAMPLES_PER_PERIOD} samples "
             f"per period; x_ref = accurate integrator at rtol {REFERENCE_RTOL:.0e}",
             "time = fastest of repeated calls (up to 20 within 50 ms), x(t) on the grid "
             "included"]
    for scene in result.scenes:
        lines += ["", f"{scene.name}: {scene.describe()}",
                  f"  reference: {1e3 * result.reference_seconds[scene.name]:.0f} ms; it differs "
                  f"from the rtol {REFERENCE_CHECK_RTOL:.0e} solution by "
                  f"{result.reference_spread[scene.name]:.1e}",
                  f"  {'method':<14}{'setting':<14}{'time (ms)':>11}{'error':>11}"]
        for p in result.points:
            if p.scene == scene.name:
                lines.append(f"  {p.method:<14}{p.setting:<14}{1e3 * p.seconds:>11.3g}"
                             f"{p.error:>11.2e}")
    return "\n".join(lines)


# --------------------------------------------------------------------------- fitting


def log_decrement_rate(t, x, period):
    """b (1/s) from single-sample peaks: what is often done today.

    ``x - mean(x)`` is cut into half-periods starting at its first zero crossing; the
    largest ``|x - mean|`` sample of each full half-period is its peak, and ``-slope`` of a
    least-squares line through ``log(peak)`` against the peak's time is b.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s), uniform.
    x : ndarray, shape (n,)
        Signal (U).
    period : float
        The true period (s); given, which favours this method.

    Returns
    -------
    float
        The decay rate b (1/s); NaN with fewer than 3 peaks.
    """
    centred = np.abs(x - np.mean(x))
    crossings = np.flatnonzero(np.diff(np.signbit(x - np.mean(x))))
    if crossings.size == 0:
        return math.nan
    start = t[crossings[0]]
    half_period = 0.5 * period
    window = np.floor((t - start) / half_period).astype(np.int64)
    full = (window >= 0) & (window < np.floor((t[-1] - start) / half_period))
    window, values, times = window[full], centred[full], t[full]
    # The last sample of each window after sorting by (window, value) is that window's peak.
    order = np.lexsort((values, window))
    last = np.flatnonzero(np.diff(window[order], append=np.iinfo(np.int64).max))
    peaks = order[last]
    if peaks.size < 3:
        return math.nan
    slope = np.polyfit(times[peaks], np.log(values[peaks]), 1)[0]
    return float(-slope)


def hilbert_envelope_rate(t, x, period, trim_periods=HILBERT_TRIM_PERIODS):
    """b (1/s) from a line through the logarithm of the Hilbert envelope.

    The envelope is ``|hilbert(x - mean(x))|``; ``trim_periods`` periods are dropped at
    each end, where it is distorted, and ``-slope`` of a least-squares line through its
    logarithm against time is b.

    Parameters
    ----------
    t, x : ndarray, shape (n,)
        Sample times (s, uniform) and signal (U).
    period : float
        Period (s), for the trimming only.
    trim_periods : float, optional
        Periods dropped at each end.

    Returns
    -------
    float
        The decay rate b (1/s); NaN if the trimmed record is too short.
    """
    from scipy.signal import hilbert

    envelope = np.abs(hilbert(x - np.mean(x)))
    keep = (t >= t[0] + trim_periods * period) & (t <= t[-1] - trim_periods * period)
    keep &= envelope > 0
    if np.count_nonzero(keep) < 3:
        return math.nan
    return float(-np.polyfit(t[keep], np.log(envelope[keep]), 1)[0])


def _mcfit_estimates(t, x, model):
    """mcfit on one record: turning points, then the forced and the selected fit.

    Returns a dict with, for "forced" and "selected", the coefficients (dict), standard
    errors (dict), chosen model and seconds (turning points included); None on failure.
    """
    from mcfit.analysis import fit_turning_points
    from mcfit.errors import McfitError
    from mcfit.turning import find_turning_points

    start = time.perf_counter()
    try:
        turning = find_turning_points(t, x)
    except McfitError:
        return {"forced": None, "selected": None}
    turning_seconds = time.perf_counter() - start
    out = {}
    for name, forced in (("forced", model), ("selected", None)):
        start = time.perf_counter()
        try:
            fit = fit_turning_points(turning, model=forced)
        except McfitError:
            out[name] = None
            continue
        seconds = turning_seconds + time.perf_counter() - start
        out[name] = None if fit.status != "ok" else {
            "values": dict(fit.values), "stderr": dict(fit.stderr), "model": fit.model,
            "seconds": seconds}
    return out


@dataclass(frozen=True)
class FitCell:
    """Statistics of one method on one (scene, SNR, samples per cycle) cell.

    ``rmse_ratio`` and ``bias_ratio`` map a coefficient letter to RMSE/CRLB and
    mean(error)/CRLB; ``stderr_ratio`` to mean(reported stderr)/RMSE (mcfit only);
    ``model_right`` is the number of records whose selected model is the true one.
    """

    scene: str
    snr: float
    samples_per_cycle: float
    method: str
    crlb: dict
    rmse_ratio: dict
    bias_ratio: dict
    stderr_ratio: dict
    milliseconds: float
    records: int
    failed: int
    model_right: int | None = None


def _fit_record_pair(scene: FitScene, snr, samples_per_cycle, rng):
    """Two noisy records of the averaged waveform, with the same noise of opposite signs:
    (t, x_plus, x_minus, phase, sigma_x).

    The errors of the pair cancel to first order in the noise, so the mean error over
    pairs shows a method's bias with far less scatter than over independent records.
    """
    rate = samples_per_cycle / scene.period
    t = np.arange(math.floor(scene.cycles * samples_per_cycle) + 1) / rate
    phase = float(rng.uniform(0.0, 2.0 * math.pi))
    sigma_x = scene.y0 / snr
    clean = motion.averaged_motion(t, scene.y0, scene.a, scene.b, scene.c, scene.period, phase)
    clean += scene.offset
    noise = rng.normal(0.0, sigma_x, t.size)
    return t, clean + noise, clean - noise, phase, sigma_x


def _fit_record(scene: FitScene, snr, samples_per_cycle, rng):
    """One noisy record of the averaged waveform: (t, x, phase, sigma_x)."""
    t, x, _, phase, sigma_x = _fit_record_pair(scene, snr, samples_per_cycle, rng)
    return t, x, phase, sigma_x


def _cell_statistics(scene, snr, spc, method, crlb, estimates, seconds, stderr=None,
                     right=None):
    """Reduce the per-record estimates of one method to a :class:`FitCell`."""
    truth = scene.values
    letters = list(crlb)
    ok = [e for e in estimates if e is not None and all(math.isfinite(e[k]) for k in letters)]
    rmse, bias, se_ratio = {}, {}, {}
    for k in letters:
        errors = np.array([e[k] - truth[k] for e in ok])
        if errors.size:
            rmse[k] = float(np.sqrt(np.mean(errors**2)) / crlb[k])
            bias[k] = float(np.mean(errors) / crlb[k])
            if stderr is not None:
                reported = [s[k] for s in stderr if s is not None and s.get(k) is not None]
                if reported:
                    se_ratio[k] = float(np.mean(reported) / (rmse[k] * crlb[k]))
    milliseconds = 1e3 * float(np.mean(seconds)) if seconds else math.nan
    return FitCell(scene.name, snr, spc, method, dict(crlb), rmse, bias, se_ratio,
                   milliseconds, len(estimates), len(estimates) - len(ok), right)


def _run_cell(scene: FitScene, snr, nominal_spc, config: BenchConfig, cell_seed):
    """All methods on the same ``config.repeats`` records of one cell."""
    rng = np.random.default_rng(cell_seed)
    spc = nominal_spc + SAMPLING_OFFSET
    per_method = {name: ([], []) for name in ("forced", "selected", "log", "hilbert")}
    stderrs, right, variances = [], 0, []
    for repeat in range(config.repeats):
        if repeat % 2 == 0:  # antithetic pairs: the second record negates the noise
            t, x, mirrored, phase, sigma_x = _fit_record_pair(scene, snr, spc, rng)
            bound = waveform_crlb(t, scene.y0, scene.a, scene.b, scene.c, scene.period,
                                  sigma_x, scene.model, phase=phase)
        else:
            x = mirrored
        variances.append({k: v**2 for k, v in bound.items()})
        mcfit = _mcfit_estimates(t, x, scene.model)
        for name in ("forced", "selected"):
            result = mcfit[name]
            per_method[name][0].append(None if result is None else result["values"])
            if result is not None:
                per_method[name][1].append(result["seconds"])
        stderrs.append(None if mcfit["forced"] is None else mcfit["forced"]["stderr"])
        right += mcfit["selected"] is not None and mcfit["selected"]["model"] == scene.model
        if scene.model == "b":
            for name, function in (("log", log_decrement_rate), ("hilbert", hilbert_envelope_rate)):
                start = time.perf_counter()
                rate = function(t, x, scene.period)
                per_method[name][1].append(time.perf_counter() - start)
                per_method[name][0].append({"b": rate})
    # The RMSE over records of random phase is bounded by the root of the mean bound**2.
    crlb = {k: math.sqrt(statistics.fmean(v[k] for v in variances)) for k in scene.model}
    labels = {"forced": f"mcfit ({scene.model} forced)", "selected": "mcfit (selected)",
              "log": "log decrement", "hilbert": "Hilbert envelope"}
    cells = [
        _cell_statistics(scene, snr, spc, labels["forced"], crlb, *per_method["forced"],
                         stderr=stderrs),
        _cell_statistics(scene, snr, spc, labels["selected"], crlb, *per_method["selected"],
                         right=right),
    ]
    if scene.model == "b":
        cells += [_cell_statistics(scene, snr, spc, labels[name], crlb, *per_method[name])
                  for name in ("log", "hilbert")]
    return cells


def run_fitting(config: BenchConfig = QUICK, progress=None) -> list:
    """RMSE and bias against the Cramer-Rao bound, and time per record, for every cell.

    Every method sees the same records: ``config.repeats`` per cell, each the averaged
    waveform from a random phase plus ``x_eq`` plus white noise ``sigma_x = y0/SNR``,
    sampled at ``samples_per_cycle + SAMPLING_OFFSET`` per period. The records come in
    antithetic pairs (one noise draw with both signs), so that the bias is measured well
    below the scatter of the RMSE. The methods that give
    only b run on the hysteretic-only scene.

    Returns
    -------
    list of FitCell
    """
    # Imported here so that no record's time includes loading them.
    import scipy.signal  # noqa: F401

    import mcfit.analysis  # noqa: F401
    import mcfit.fit  # noqa: F401
    import mcfit.turning  # noqa: F401

    cells = []
    for i, scene in enumerate(config.fit_scenes):
        for j, snr in enumerate(config.snrs):
            for k, spc in enumerate(config.samples_per_cycle):
                if progress:
                    progress(f"fitting: {scene.name}, SNR {snr:g}, {spc} samples/cycle")
                cells += _run_cell(scene, snr, spc, config, [config.seed, i, j, k])
    return cells


def format_fitting(cells, config: BenchConfig) -> str:
    """The fitting tables: one per scene."""
    lines = [f"Fitting: RMSE and bias over {config.repeats} records per row, in units of the "
             "waveform Cramer-Rao bound",
             "  (y0, the model's coefficients, omega, phase, x_eq free; RMS over the records' "
             "random phases);",
             f"  SNR = y0/sigma_x; samples/cycle = nominal + {SAMPLING_OFFSET} (crests drift "
             "across the sample grid);",
             "  se/RMSE = mean stderr reported by mcfit over the observed RMSE; ms = wall time "
             "per record",
             f"  (mcfit: turning points + fit); statistical scatter of RMSE/CRLB about "
             f"{100 / math.sqrt(config.repeats):.0f} %; records in antithetic pairs (the same "
             "noise with both signs),",
             "  so the bias, a mean, cancels the noise to first order and is known to a few "
             "hundredths."]
    for scene in config.fit_scenes:
        rows = [c for c in cells if c.scene == scene.name]
        if not rows:
            continue
        letters = scene.model
        lines += ["", f"{scene.name}: {scene.describe()}"]
        head = f"  {'SNR':>6}{'spc':>7}  {'method':<20}"
        head += "".join(f"{'CRLB ' + k:>10}" for k in letters)
        head += "".join(f"{'RMSE/CRLB ' + k:>13}" for k in letters)
        head += "".join(f"{'bias ' + k:>8}" for k in letters)
        head += "".join(f"{'se/RMSE ' + k:>10}" for k in letters)
        head += f"{'ms':>7}{'failed':>8}{'model ok':>10}"
        lines.append(head)
        for c in rows:
            row = f"  {c.snr:>6.0e}{c.samples_per_cycle:>7.4g}  {c.method:<20}"
            row += "".join(f"{c.crlb[k]:>10.2e}" for k in letters)
            row += "".join(_number(c.rmse_ratio.get(k), 13, ".3g") for k in letters)
            row += "".join(_number(c.bias_ratio.get(k), 8, "+.2g") for k in letters)
            row += "".join(_number(c.stderr_ratio.get(k), 10, ".2f") for k in letters)
            row += f"{c.milliseconds:>7.3g}{c.failed:>8d}"
            row += f"{c.model_right:>6d}/{c.records:<3d}" if c.model_right is not None else ""
            lines.append(row.rstrip())
    return "\n".join(lines)


def _number(value, width, spec):
    return ("-" if value is None else format(value, spec)).rjust(width)


# --------------------------------------------------------------------------- throughput


@dataclass(frozen=True)
class Throughput:
    """Batch rate, peak memory and start-up times.

    ``rates`` maps a path label to ``(wall seconds, records per second, records fitted)``;
    ``stages`` a record length (samples) to the mean CPU seconds per record of its turning
    points and of its fit; ``startup`` a command label to the median wall time (s); memory
    in MiB.
    """

    records: int
    samples: int
    rates: dict
    stages: dict
    max_rss_self: float
    max_rss_children: float
    startup: dict
    startup_runs: int


def _throughput_record(config: BenchConfig, seed, samples=None):
    """A record of the Fig. 20.19 scene with ``samples`` (default ``config.batch_samples``)
    samples."""
    scene = FIG_20_19_SCENE
    rng = np.random.default_rng([config.seed, 99, seed])
    spc = ((samples or config.batch_samples) - 1) / scene.cycles
    t, x, _, _ = _fit_record(scene, 1e3, spc, rng)
    return t, x


def _stage_seconds(config: BenchConfig, samples):
    """Mean CPU seconds per record of the turning points and of the fit, in memory.

    CPU time, not wall time, and the best of three passes: on a shared machine the
    smallest figure is the least disturbed one.
    """
    from mcfit.analysis import fit_turning_points
    from mcfit.errors import McfitError
    from mcfit.records import Record
    from mcfit.turning import turning_points_of

    records = [Record(f"record{i}", *_throughput_record(config, i, samples))
               for i in range(config.batch_records)]
    best = [math.inf, math.inf]
    for _ in range(3):
        turning = []
        start = time.process_time()
        for record in records:
            with contextlib.suppress(McfitError):  # timed all the same
                turning.append(turning_points_of(record))
        middle = time.process_time()
        for points in turning:
            with contextlib.suppress(McfitError):
                fit_turning_points(points)
        end = time.process_time()
        best = [min(best[0], middle - start), min(best[1], end - middle)]
    return best[0] / len(records), best[1] / len(records)


def _rate_in_memory(config: BenchConfig):
    """(s, records/s, fitted) of analyse_record over in-memory records: no I/O, no start-up."""
    from mcfit.analysis import analyse_record
    from mcfit.records import Record

    records = [Record(f"record{i}", *_throughput_record(config, i))
               for i in range(config.batch_records)]
    start = time.perf_counter()
    fitted = sum(analyse_record(record).status == "ok" for record in records)
    seconds = time.perf_counter() - start
    return seconds, len(records) / seconds, fitted


def _write_records(config: BenchConfig, directory):
    for i in range(config.batch_records):
        t, x = _throughput_record(config, i)
        np.savetxt(os.path.join(directory, f"record{i:04d}.csv"), np.column_stack([t, x]),
                   fmt="%.10g", delimiter=",", header="t,x", comments="")


def _rate_of_command(config: BenchConfig, directory, jobs):
    """(s, records/s, fitted) of ``mcfit DIR --format csv -o FILE --jobs N`` as a subprocess.

    This is the batch path a user runs (:func:`mcfit.batch.run_jobs`: read, analyse,
    format), start-up included; worker processes start from a fresh interpreter, as they do
    for a user, not from this process with its libraries loaded.
    """
    output = os.path.join(directory, f"results-{jobs}.csv")
    start = time.perf_counter()
    subprocess.run([*_mcfit_command(), os.path.join(directory, "records"), "--format", "csv",
                    "-o", output, "--jobs", str(jobs)], stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, check=False)
    seconds = time.perf_counter() - start
    try:
        with open(output, encoding="utf-8") as handle:
            fitted = sum(line.split(",")[1] == "ok" for line in handle.readlines()[1:])
    except OSError:
        fitted = 0
    return seconds, config.batch_records / seconds, fitted


def _median_wall_time(command, runs):
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                       check=False)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _mcfit_command():
    """The installed ``mcfit`` script beside this Python, else ``python -m mcfit``."""
    script = Path(sys.executable).parent / "mcfit"
    return [str(script)] if script.exists() else [sys.executable, "-m", "mcfit"]


def _sample_file(directory):
    """sample_data/fig20_21_soup_can.csv (cwd or the source tree), else a simulated one."""
    name = os.path.join("sample_data", "fig20_21_soup_can.csv")
    for base in (Path.cwd(), Path(__file__).resolve().parents[2]):
        if (base / name).is_file():
            return str(base / name)
    t, x = motion.simulate_record(0.22, 0.0, 0.0, 1.0, 0.5, 20.0, 100.0, method="averaged",
                                  noise=1e-3, rng=np.random.default_rng(0))
    path = os.path.join(directory, "soup_can.csv")
    np.savetxt(path, np.column_stack([t, x]), fmt="%.10g", delimiter=",", header="t,x",
               comments="")
    return path


def _startup_times(config: BenchConfig, directory):
    mcfit = _mcfit_command()
    sample = _sample_file(directory)
    shown = os.path.relpath(sample) if not os.path.relpath(sample).startswith("..") else sample
    fit_imports = "import mcfit.batch, mcfit.analysis, mcfit.records, mcfit.report"
    commands = {
        "mcfit --help": [*mcfit, "--help"],
        f'python -c "{fit_imports}"': [sys.executable, "-c", fit_imports],
        f"mcfit {shown}": [*mcfit, sample],
    }
    return {label: _median_wall_time(command, config.startup_runs)
            for label, command in commands.items()}


def _max_rss_mib(who):
    return resource.getrusage(who).ru_maxrss / 1024  # Linux reports kB


def run_throughput(config: BenchConfig = QUICK, progress=None) -> Throughput:
    """Batch rate (in memory, and ``mcfit DIR --jobs 1`` and ``2``), memory and start-up."""
    rates = {}
    with tempfile.TemporaryDirectory(prefix="mcfit-bench-") as directory:
        if progress:
            progress(f"throughput: {config.batch_records} records in memory")
        rates["analyse_record, in memory, 1 process"] = _rate_in_memory(config)
        os.mkdir(os.path.join(directory, "records"))
        _write_records(config, os.path.join(directory, "records"))
        for jobs in (1, 2):
            if progress:
                progress(f"throughput: mcfit on {config.batch_records} CSV files, --jobs {jobs}")
            rates[f"mcfit DIR --format csv --jobs {jobs}"] = _rate_of_command(config, directory,
                                                                              jobs)
        stages = {}
        for samples in (config.batch_samples // 10, config.batch_samples):
            if progress:
                progress(f"throughput: stages of records of {samples} samples")
            stages[samples] = _stage_seconds(config, samples)
        if progress:
            progress("throughput: start-up times")
        startup = _startup_times(config, directory)
    return Throughput(config.batch_records, config.batch_samples, rates, stages,
                      _max_rss_mib(resource.RUSAGE_SELF), _max_rss_mib(resource.RUSAGE_CHILDREN),
                      startup, config.startup_runs)


def format_throughput(result: Throughput) -> str:
    """The throughput table."""
    lines = [f"Throughput: {result.records} records of {result.samples} samples (Fig. 20.19 "
             "scene, SNR 1e3; every record: turning points, 7 models, selection)",
             "  mcfit DIR: the command line as a subprocess (batch.run_jobs: read CSV, analyse, "
             "format), start-up included",
             f"  {'path':<40}{'wall (s)':>10}{'records/s':>11}{'per process':>13}{'fitted':>10}"]
    for label, (seconds, rate, fitted) in result.rates.items():
        jobs = 2 if label.endswith("--jobs 2") else 1
        lines.append(f"  {label:<40}{seconds:>10.2f}{rate:>11.1f}{rate / jobs:>13.1f}"
                     f"{fitted:>6d}/{result.records}")
    lines += ["", "  per record in memory, CPU time (best of 3 passes), by record length:",
              f"  {'samples':>10}{'turning points (ms)':>22}{'fit (ms)':>11}{'total (ms)':>13}"
              f"{'records/s':>11}"]
    for samples, (turning, fitting) in result.stages.items():
        total = turning + fitting
        lines.append(f"  {samples:>10d}{1e3 * turning:>22.1f}{1e3 * fitting:>11.1f}"
                     f"{1e3 * total:>13.1f}{1.0 / total:>11.1f}")
    lines += ["", f"  peak resident memory (ru_maxrss): this process {result.max_rss_self:.0f} "
              f"MiB, largest child process {result.max_rss_children:.0f} MiB",
              "", f"  start-up, median wall time of {result.startup_runs} runs as subprocesses:"]
    lines += [f"  {label:<72}{1e3 * seconds:>7.0f} ms"
              for label, seconds in result.startup.items()]
    return "\n".join(lines)


# --------------------------------------------------------------------------- plots


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


# --------------------------------------------------------------------------- driver


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
        result = run_integrators(config, progress)
        yield format_integrators(result)
        if plot_dir is not None:
            plot_integrators(result, os.path.join(plot_dir, "integrators.png"))
    if "fitting" in sections:
        cells = run_fitting(config, progress)
        yield format_fitting(cells, config)
        if plot_dir is not None:
            plot_fitting(cells, config, os.path.join(plot_dir, "fitting.png"))
    if "verdicts" in sections:
        from mcfit.bench_verdicts import format_verdicts, run_verdicts

        yield format_verdicts(run_verdicts(config.verdict_records, config.seed,
                                           progress=progress))
    if "methods" in sections:
        from mcfit.bench_methods import format_methods, run_methods

        yield format_methods(run_methods(config.method_records, config.seed,
                                         qs=config.method_qs, progress=progress))
    if "throughput" in sections:
        yield format_throughput(run_throughput(config, progress))
