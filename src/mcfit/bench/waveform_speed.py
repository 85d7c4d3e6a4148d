"""The waveform section of ``mcfit bench``: what the default method costs where it fits the
waveform (issue 28), in one child process with one BLAS thread, CPU time.

- **A mixed batch:** ``config.mixed_records`` records as ``mcfit simulate`` makes them
  (10^4 samples over 40 cycles of 1 s, y0 = 1), half with Q from 5 to 8 and half from 8
  to 200 (log-spaced; Q = omega/(2*rate) with the rate c/y0 + b + a*y0 at the start), the
  terms b, ab, bc, abc in turn (:data:`MIXES`), sample noise from 1e-4 to 1e-2 of y0
  (log-uniform). Each record is analysed by the default method (auto) and by
  ``method="turning-points"`` one after the other, so that a drift of the machine's speed
  slows both alike: records per CPU second of each and their ratio.
- **The waveform fit by Q:** :func:`mcfit.analysis.fit_both_forms` (both physical forms,
  as auto runs it) on records of 10^4 samples at Q = 2, 3, 5, 8, 10
  (b alone, and b with a Coulomb tenth of the first decay rate), long enough for the
  amplitude to fall to 1e-3 of y0 (at least 8 cycles), started where auto starts it
  (:func:`mcfit.analysis.auto_start`); and in the other forms the issue names, from an
  independent integration (:mod:`mcfit.bench.reference_motion`): a linear viscous
  oscillator (the velocity forms' b; ``fit_both_forms`` too) and a pendulum released at
  0.8 rad with viscous damping (its own equation of motion, as ``--pendulum`` fits it):
  CPU milliseconds, the best of ``config.waveform_runs`` runs.

Turning-point cost per cycle is the cycles section's. Nothing here asserts a time; a
target not met is printed as NOT MET.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from dataclasses import dataclass

import numpy as np

from mcfit.bench.config import QUICK, BenchConfig
from mcfit.bench.throughput import Target, load_lines
from mcfit.bench.timing import ONE_THREAD, child_environment

__all__ = ["MIXES", "WAVEFORM_QS", "WaveformSpeed", "mixed_record", "q_record",
           "run_waveform_speed", "format_waveform_speed", "targets", "main"]

# Share of the first decay rate c/y0 + b + a*y0 of each term (a, b, c).
MIXES = {"b": (0.0, 1.0, 0.0), "ab": (0.3, 0.7, 0.0), "bc": (0.0, 0.9, 0.1),
         "abc": (0.2, 0.7, 0.1)}
WAVEFORM_QS = (2, 3, 5, 8, 10)
# Eq. 20.55's mixes (MIXES), then the other forms' records (_other_form_record).
WAVEFORM_MIXES = ("b", "bc", "viscous", "pendulum")
PENDULUM_RELEASE = 0.8  # rad
SAMPLES = 10_000
CYCLES = 40
LOW_Q = (5.0, 8.0)
HIGH_Q = 200.0
NOISE = (1e-4, 1e-2)
# Issue 28's "Done when": auto at most 4 times turning points, 20 records per CPU second,
# the waveform fit at most 50 ms.
RATIO_TARGET, RATE_TARGET, WAVEFORM_TARGET = 4.0, 20.0, 0.050


@dataclass(frozen=True)
class WaveformSpeed:
    """What the section measured: per mixed record (q, mix, noise, auto's method, auto's
    and turning points' CPU seconds, or None where a method refused the record), and
    per (q, mix) the waveform fit's CPU seconds (None where the turning points were too
    few to start it)."""

    config: BenchConfig
    mixed: tuple
    waveform: dict
    load: tuple | None = None

    def rate(self, which) -> float:
        """Records per CPU second of ``which`` ("auto" or "turning-points") over the
        records both fitted."""
        column = 4 if which == "auto" else 5
        both = [row for row in self.mixed if row[4] is not None and row[5] is not None]
        spent = sum(row[column] for row in both)
        return len(both) / spent if spent > 0 else math.nan


def _law(q, mix, omega=2 * math.pi, y0=1.0):
    """(a, b, c) whose first decay rate c/y0 + b + a*y0 is omega/(2*q), shared as ``mix``."""
    rate = omega / (2 * q)
    share = MIXES[mix]
    return share[0] * rate / y0, share[1] * rate, share[2] * rate * y0


def mixed_record(index, count, seed):
    """Record ``index`` of the mixed batch of ``count``: (record, q, mix, noise)."""
    low = count // 2
    if index < low:
        q = float(np.geomspace(*LOW_Q, max(low, 2))[index] if low > 1 else LOW_Q[0])
    else:
        q = float(np.geomspace(LOW_Q[1], HIGH_Q, count - low + 1)[index - low + 1])
    mix = tuple(MIXES)[index % len(MIXES)]
    rng = np.random.default_rng([seed, 28, index])
    noise = float(math.exp(rng.uniform(*np.log(NOISE))))
    from mcfit.motion import simulate_record

    record = simulate_record(*_law(q, mix), 1.0, 1.0, CYCLES, (SAMPLES - 1) / CYCLES,
                             noise=noise, rng=rng)
    return record, q, mix, noise


def q_record(q, mix, seed):
    """A record of :data:`SAMPLES` samples at ``q`` for the waveform fit's timing,
    decaying to 1e-3 of y0 (at least 8 cycles, at most 40), noise 1e-3: Eq. 20.55 with
    the ``mix`` of :data:`MIXES`, or "viscous" or "pendulum"."""
    from mcfit.bench.methods import record_duration
    from mcfit.motion import simulate_record

    duration = record_duration(q)
    rng = np.random.default_rng([seed, 28, int(10 * q)])
    if mix not in MIXES:
        t, x = _other_form_record(q, mix, duration)
        return t, x + 1e-3 * rng.standard_normal(t.size)
    return simulate_record(*_law(q, mix), 1.0, 1.0, duration, (SAMPLES - 1) / duration,
                           method="accurate", noise=1e-3, rng=rng)


def _other_form_record(q, mix, duration, omega=2 * math.pi):
    """(t, x) of a linear viscous oscillator from rest at 1 ("viscous") or a viscous
    pendulum from rest at PENDULUM_RELEASE ("pendulum"), rate omega/(2*q), by the
    reference integration."""
    from mcfit.bench import reference_motion

    beta, rate = omega / (2 * q), SAMPLES / duration
    if mix == "viscous":
        return reference_motion.viscous(beta, omega, 1.0, duration, rate)
    return reference_motion.pendulum(beta, omega, PENDULUM_RELEASE, duration, rate)


def run_waveform_speed(config: BenchConfig = QUICK, progress=None) -> WaveformSpeed:
    """Measure in a child process with one BLAS thread (:func:`main`)."""
    say = progress or (lambda message: None)
    say(f"waveform: {config.mixed_records} mixed records by auto and turning points, and "
        f"the waveform fit at Q = {', '.join(map(str, WAVEFORM_QS))}")
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    spec = {"records": config.mixed_records, "runs": config.waveform_runs,
            "seed": config.seed}
    code = "from mcfit.bench.waveform_speed import main; main()"
    done = subprocess.run([sys.executable, "-c", code, json.dumps(spec)],
                          capture_output=True, text=True,
                          env=child_environment(ONE_THREAD), check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the waveform section failed:\n{done.stderr}")
    found = json.loads(done.stdout)
    waveform = {(q, mix): seconds for q, mix, seconds in found["waveform"]}
    return WaveformSpeed(config, tuple(map(tuple, found["mixed"])), waveform, load)


def _cpu(function, *args, **kwargs):
    """(CPU seconds, result) of one call; (None, None) where it refuses the record."""
    from mcfit.errors import McfitError

    start = time.process_time()
    try:
        result = function(*args, **kwargs)
    except McfitError:
        return None, None
    return time.process_time() - start, result


def main():
    """Child process: measure the spec in ``sys.argv[1]`` (JSON: records, runs, seed) and
    print the rows as JSON."""
    from mcfit.analysis import analyse_record
    from mcfit.turning import find_turning_points

    spec = json.loads(sys.argv[1])
    count, seed = spec["records"], spec["seed"]
    first = mixed_record(0, count, seed)[0]
    analyse_record(first)  # imports and caches warm
    analyse_record(first, method="turning-points")
    mixed = []
    for index in range(count):
        record, q, mix, noise = mixed_record(index, count, seed)
        auto_s, auto = _cpu(analyse_record, record)
        points_s, _ = _cpu(analyse_record, record, method="turning-points")
        method = None if auto is None or auto.fit is None else auto.fit.method
        mixed.append((q, mix, noise, method, auto_s, points_s))
    waveform, warm = [], set()
    for q in WAVEFORM_QS:
        for mix in WAVEFORM_MIXES:
            t, x = q_record(q, mix, seed)
            seconds, turning = _cpu(find_turning_points, t, x)
            prepared = turning and _cpu(_waveform_fit_as_auto, t, x, turning,
                                        mix == "pendulum")[1]
            if not prepared:  # too few turning points, or no law fitted to them
                waveform.append((q, mix, None))
                continue
            fit, args = prepared
            if mix not in warm:  # the first fit of a kind loads its compiled kernels
                warm.add(mix)
                _cpu(fit, *args)
            times = [_cpu(fit, *args)[0] for _ in range(spec["runs"])]
            waveform.append((q, mix, None if None in times else min(times)))
    print(json.dumps({"mixed": mixed, "waveform": waveform}))


def _waveform_fit_as_auto(t, x, turning, pendulum):
    """(the waveform fit, its arguments) as auto runs it on the record: both forms from
    auto's start, or a pendulum's equation of motion as ``pendulum=True`` runs it."""
    from mcfit.analysis import (_pendulum_law_error, _pendulum_waveform, auto_start,
                                fit_both_forms, fit_turning_points)
    from mcfit.io import Record
    from mcfit.model_error import averaged_law_bias

    fit = fit_turning_points(turning, pendulum=pendulum)
    if pendulum:
        error = _pendulum_law_error(t, turning, fit, False)
        return _pendulum_waveform, (Record(source="pendulum", t=t, x=x), turning, fit, error,
                                    False, "aicc", None)
    return fit_both_forms, (t, x, turning, auto_start(fit, averaged_law_bias(t, turning, fit)))


# --------------------------------------------------------------------------- report


def targets(result: WaveformSpeed) -> list:
    """Issue 28's targets on the default method and the waveform fit."""
    auto, points = result.rate("auto"), result.rate("turning-points")
    ratio = points / auto if auto > 0 else math.nan
    fits = [s for s in result.waveform.values() if s is not None]
    slowest = max(fits, default=math.nan)
    return [
        Target("auto / turning points, CPU per record (mixed batch)", f"{ratio:.1f}x",
               f"<= {RATIO_TARGET:g}x", ratio <= RATIO_TARGET),
        Target("auto: records per CPU second (mixed batch)", f"{auto:.1f}",
               f">= {RATE_TARGET:g}", auto >= RATE_TARGET),
        Target(f"waveform fit, Q {WAVEFORM_QS[0]}-{WAVEFORM_QS[-1]}: slowest",
               f"{1e3 * slowest:.0f} ms", f"<= {1e3 * WAVEFORM_TARGET:g} ms",
               slowest <= WAVEFORM_TARGET),
    ]


def format_waveform_speed(result: WaveformSpeed) -> str:
    """The targets, then the mixed batch by Q band and the waveform fit by Q."""
    lines = [f"Waveform: issue 28's targets on the default method ({len(result.mixed)} "
             f"mixed records of {SAMPLES:,} samples, {CYCLES} cycles; one core, CPU time)"]
    lines += [row.line() for row in targets(result)]
    lines += load_lines(result.load)
    lines += ["", f"  {'records':<24}{'n':>4}{'by waveform':>13}{'auto ms':>10}"
                  f"{'TP ms':>8}{'auto/TP':>9}"]
    bands = (("Q <= 8", lambda q: q <= LOW_Q[1] * (1 + 1e-9)),
             ("Q > 8", lambda q: q > LOW_Q[1] * (1 + 1e-9)), ("all", lambda q: True))
    for name, inside in bands:
        rows = [r for r in result.mixed if inside(r[0]) and r[4] is not None
                and r[5] is not None]
        if not rows:
            continue
        auto, points = (1e3 * np.mean([r[k] for r in rows]) for k in (4, 5))
        waveform = sum(r[3] == "waveform" for r in rows)
        lines.append(f"  {name:<24}{len(rows):>4}{waveform:>13}{auto:>10.1f}{points:>8.1f}"
                     f"{auto / points:>9.1f}")
    refused = sum(r[4] is None or r[5] is None for r in result.mixed)
    if refused:
        lines.append(f"  ({refused} records refused by a method, left out)")
    lines += ["", "  the waveform fit as auto runs it (Eq. 20.55's b and b + c and a viscous "
              "oscillator: both forms from auto's start; a pendulum released at "
              f"{PENDULUM_RELEASE:g} rad: its equation of motion), CPU ms, best of "
              f"{result.config.waveform_runs}:",
              f"  {'Q':>4}" + "".join(f"{mix:>10}" for mix in WAVEFORM_MIXES)]
    for q in WAVEFORM_QS:
        cells = [result.waveform.get((q, mix)) for mix in WAVEFORM_MIXES]
        lines.append(f"  {q:>4}" + "".join("         -" if s is None else f"{1e3 * s:>10.0f}"
                                           for s in cells))
    lines.append("  (turning-point cost per cycle: the cycles section)")
    return "\n".join(lines)
