"""The integrators section of ``mcfit bench``: work against precision of the four ways to
compute x(t) in :mod:`mcfit.motion` (Cromer-Euler over step sizes, the symplectic splitting
over step sizes, the accurate integrator over rtol, the averaged waveform), with the error
``max|x - x_ref| / y0`` on a grid of :data:`GRID_SAMPLES_PER_PERIOD` samples per period
against the accurate integrator at rtol :data:`REFERENCE_RTOL`."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from mcfit import motion
from mcfit.bench.config import (GRID_SAMPLES_PER_PERIOD, QUICK, REFERENCE_CHECK_RTOL,
                                REFERENCE_RTOL, BenchConfig, IntegratorScene)
from mcfit.bench.timing import fastest

__all__ = ["WorkPoint", "IntegratorResult", "run_integrators", "format_integrators"]


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
        seconds, x = fastest(function, *args, **kwargs)
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

