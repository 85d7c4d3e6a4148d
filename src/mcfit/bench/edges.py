"""The edges section of ``mcfit bench``: scenes where real records live (low Q with
friction, viscous damping, quadratic drag, held releases, large swings, near ties,
beats, coarse quantisation), each record analysed with default options and counted as right, flagged
or silently wrong.

Every record comes from :mod:`mcfit.bench.reference_motion`, an integration that shares
no code with mcfit, plus seeded white noise. A record is

- right: the reported terms are the truth's and each true coefficient lies in its 95 %
  interval (value +- ``interval_factor`` standard errors), with no confident claim of the
  wrong damping form; a scene of another kind says what is right for it
  (:class:`EdgeScene`);
- flagged: not right, but the result says so (a warning, ``resolved`` False, damping form
  "cannot tell", or a refusal);
- silently wrong: neither.
"""

from __future__ import annotations

import math
import time
import zlib
from dataclasses import dataclass
from typing import Callable

import numpy as np

from mcfit.bench import reference_motion as motion

__all__ = ["EdgeScene", "EdgeRow", "EDGE_SCENES", "OUTCOMES", "classify", "run_edges",
           "format_edges"]

OUTCOMES = ("right", "flagged", "wrong")
W1 = 2 * math.pi  # T = 1 s
W_FIG = 4 * math.pi  # Fig. 20.19: T = 0.5 s
BEAT_WORDS = "beating of two modes"


@dataclass(frozen=True)
class EdgeScene:
    """A truth and how its records are made and judged.

    ``make()`` returns the clean record (t, x) from the reference integration; ``noise``
    is the standard deviation of the white noise added (in x's units); ``quantum``, when
    set, rounds the noisy record to multiples of it (an ADC's counts). ``truth`` holds
    the averaged law's coefficients ({"b": ..., "c": ...}); ``form`` the damping form
    ("amplitude" for Eq. 20.55, "velocity" for viscous) or None. ``kind`` says what is
    right: "coefficients" (the terms and their intervals), "tie" (not resolved, or b
    alone within its interval), "beat" (a warning names the beat), "clip" (no "clipped"
    note).
    """

    name: str
    make: Callable
    noise: float
    truth: dict
    form: str | None = None
    kind: str = "coefficients"
    pendulum: bool = False
    quantum: float | None = None


def _viscous_line():
    """x = exp(-0.8 t) cos(2 pi t): released at 1 with velocity -0.8."""
    beta = 0.8
    return motion.integrate(lambda x, v, _: 2 * beta * v, math.hypot(W1, beta), 1.0, 6.0,
                            400.0, v0=-beta)


def _held_start():
    """Held at 3.5 for 1.5 s at 100 Hz, then Fig. 20.19's decay from rest for 20 s."""
    t, x = motion.hysteretic(0.1, 0.1, 0.01, W_FIG, 3.5, 20.0, 100.0)
    held = np.arange(0.0, 1.5, 0.01)
    return np.concatenate([held, t + 1.5]), np.concatenate([np.full(held.size, 3.5), x])


def _two_modes():
    """Two viscous modes of equal size, 1 and 1.02 Hz, at Q = 200: 120 s at 50 Hz."""
    beta = math.pi / 200
    parts = [motion.viscous(beta, math.hypot(W1 * f, beta), 0.5, 120.0, 50.0)
             for f in (1.0, 1.02)]
    return parts[0][0], parts[0][1] + parts[1][1]


def _eight_bit():
    """A viscous decay at Q = 30 (T = 1 s, 30 s at 50 Hz) whose first swing spans 28-227
    counts."""
    beta = math.pi / 30
    y0 = 199.0 / (1.0 + math.exp(-beta / 2))
    t, x = motion.viscous(beta, W1, y0, 30.0, 50.0)
    return t, x + 227.0 - y0


# Ten cycles of T = 1 s falling 10 %.
TIE_BETA = -math.log(0.9) / 10.0

EDGE_SCENES = (
    EdgeScene("Eq. 20.55 b + c, Q = 3",
              lambda: motion.hysteretic(0.0, math.pi / 3, math.pi / 27, W1, 1.0, 8.0, 100.0),
              1e-3, {"b": math.pi / 3, "c": math.pi / 27}, "amplitude"),
    EdgeScene("Eq. 20.55 b + c, Q = 2",
              lambda: motion.hysteretic(0.0, math.pi / 2, math.pi / 18, W1, 1.0, 8.0, 100.0),
              1e-3, {"b": math.pi / 2, "c": math.pi / 18}, "amplitude"),
    EdgeScene("Eq. 20.55 b alone, Q = 2",
              lambda: motion.hysteretic(0.0, math.pi / 2, 0.0, W1, 1.0, 8.0, 100.0),
              1e-3, {"b": math.pi / 2}, "amplitude"),
    EdgeScene("Fig. 20.19 for 30 s (stops 24.4 s)",
              lambda: motion.hysteretic(0.1, 0.1, 0.01, W_FIG, 4.0, 30.0, 100.0),
              1e-4, {"a": 0.1, "b": 0.1, "c": 0.01}, "amplitude"),
    EdgeScene("linear viscous, Q = 3.9", _viscous_line, 1e-4, {"b": 0.8}, "velocity"),
    EdgeScene("held 1.5 s, then Fig. 20.19", _held_start, 1e-3,
              {"a": 0.1, "b": 0.1, "c": 0.01}, "amplitude"),
    EdgeScene("pendulum Q = 50, 0.3 rad, no --pendulum",
              lambda: motion.pendulum(math.pi / 50, W1, 0.3, 60.0, 50.0),
              1e-3, {"b": math.pi / 50}),
    EdgeScene("pendulum Q = 50, 0.8 rad, --pendulum",
              lambda: motion.pendulum(math.pi / 50, W1, 0.8, 60.0, 50.0),
              1e-5, {"b": math.pi / 50}, pendulum=True),
    EdgeScene("pendulum Q = 50, 1.4 rad, --pendulum",
              lambda: motion.pendulum(math.pi / 50, W1, 1.4, 60.0, 50.0),
              1e-5, {"b": math.pi / 50}, pendulum=True),
    EdgeScene("quadratic drag alone, Q = 5",
              lambda: motion.quadratic_drag(3 * math.pi / 40, W1, 1.0, 8.0, 100.0),
              1e-3, {"a": W1 / 10}, "velocity"),
    EdgeScene("viscous, 10 % over 10 cycles (tie)",
              lambda: motion.viscous(TIE_BETA, W1, 1.0, 10.0, 100.0),
              5e-3, {"b": TIE_BETA}, "velocity", kind="tie"),
    EdgeScene("two viscous modes 2 % apart (beat)", _two_modes, 1e-3,
              {"b": math.pi / 200}, "velocity", kind="beat"),
    EdgeScene("8-bit record, 28-227 counts", _eight_bit, 0.3, {"b": math.pi / 30},
              "velocity", kind="clip", quantum=1.0),
)


@dataclass(frozen=True)
class EdgeRow:
    """The outcomes of ``records`` analyses of one scene: counts by :data:`OUTCOMES`,
    and the median time of an analysis (s)."""

    scene: EdgeScene
    records: int
    counts: dict
    median_seconds: float


def _covered(fit, truth):
    return all(fit.stderr.get(k) is not None
               and abs(fit.values[k] - value) <= fit.interval_factor * fit.stderr[k]
               for k, value in truth.items())


def _right_coefficients(fit, scene):
    form = getattr(fit, "damping_form", None)
    wrong_form = scene.form is not None and form in ("amplitude", "velocity") \
        and form != scene.form
    return fit.model == "".join(sorted(scene.truth)) and _covered(fit, scene.truth) \
        and not wrong_form


def _notes(analysis):
    turning = analysis.turning
    return tuple(turning.notes) if turning is not None else ()


def _right(analysis, scene) -> bool:
    if scene.kind == "beat":
        return any(BEAT_WORDS in w for w in analysis.warnings)
    fit = analysis.fit
    if analysis.status != "ok" or fit is None:
        return False
    if scene.kind == "clip":
        return not any("clipped" in note for note in _notes(analysis))
    if scene.kind == "tie":
        return not fit.resolved or (fit.model == "b" and _covered(fit, scene.truth))
    return _right_coefficients(fit, scene)


def _flagged(analysis) -> bool:
    fit = analysis.fit
    if analysis.status != "ok" or fit is None:
        return bool(analysis.error)
    return bool(analysis.warnings) or not fit.resolved \
        or getattr(fit, "damping_form", None) == "cannot tell"


def classify(analysis, scene) -> str:
    """"right", "flagged" or "wrong" (silently) for one analysis of ``scene``.

    ``analysis`` needs ``status``, ``error``, ``warnings``, ``fit`` (``model``,
    ``values``, ``stderr``, ``interval_factor``, ``resolved``, ``damping_form``) and
    ``turning`` (``notes``), as :class:`mcfit.analysis.Analysis` has.
    """
    if _right(analysis, scene):
        return "right"
    return "flagged" if _flagged(analysis) else "wrong"


def scene_key(scene):
    """A number that names ``scene`` in its seeds."""
    return zlib.crc32(scene.name.encode())


def noisy_record(scene, clean, seed):
    """The clean record ``(t, x)`` of ``scene`` with seeded noise (and quantisation)."""
    from mcfit.record import Record

    t, x = clean
    x = x + np.random.default_rng(seed).normal(0.0, scene.noise, x.size)
    if scene.quantum is not None:
        x = scene.quantum * np.round(x / scene.quantum)
    return Record(source=f"seed{seed}", t=t, x=x)


def run_edges(records=8, seed=2026, scenes=EDGE_SCENES, progress=None) -> list:
    """Analyse ``records`` noisy records of each scene and count outcomes. The seeds are
    ``[seed, crc32 of the scene's name, index]``: a scene has the same records in any
    selection of scenes."""
    from mcfit.analysis import analyse_record

    rows = []
    for scene in scenes:
        if progress is not None:
            progress(f"edges: {scene.name}")
        clean = scene.make()
        counts = dict.fromkeys(OUTCOMES, 0)
        seconds = []
        for index in range(records):
            record = noisy_record(scene, clean, [seed, scene_key(scene), index])
            start = time.perf_counter()
            analysis = analyse_record(record, pendulum=scene.pendulum)
            seconds.append(time.perf_counter() - start)
            counts[classify(analysis, scene)] += 1
        rows.append(EdgeRow(scene, records, counts, float(np.median(seconds))))
    return rows


def wilson_interval(count, total):
    """The 95 % Wilson score interval of the rate ``count / total``."""
    from scipy.stats import binomtest

    interval = binomtest(count, total).proportion_ci(confidence_level=0.95, method="wilson")
    return interval.low, interval.high


def _cell(count, total):
    low, high = wilson_interval(count, total)
    return f"{count:3d} ({low:4.2f}-{high:4.2f})"


def format_edges(rows) -> str:
    """The edges table: one line per scene, each outcome as a count and the 95 % Wilson
    interval of its rate."""
    width = max(len(row.scene.name) for row in rows) if rows else 10
    lines = ["Edges: records from an independent integration, default options; right, "
             "flagged, silently wrong (count and 95 % Wilson interval of the rate)",
             f"{'scene':{width}s} {'N':>4s} {'right':>15s} {'flagged':>15s} "
             f"{'silently wrong':>15s} {'ms':>7s}"]
    for row in rows:
        cells = " ".join(f"{_cell(row.counts[k], row.records):>15s}" for k in OUTCOMES)
        lines.append(f"{row.scene.name:{width}s} {row.records:4d} {cells} "
                     f"{1e3 * row.median_seconds:7.0f}")
    return "\n".join(lines)
