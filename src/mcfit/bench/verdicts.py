"""The verdicts section of ``mcfit bench``: how often the reported model is the true one,
and how often the 95 % intervals of a, b, c and Q (value +- ``DecayFit.interval_factor``
standard errors, the band of the report figure) cover the truth, by Monte Carlo.

Two kinds of scene. Amplitude scenes draw turning points from the law itself with Gaussian
noise, so the selection is measured alone. Waveform scenes simulate the averaged waveform
and run the whole chain (turning points, period, fit), so Q's interval is measured with
the period's uncertainty in it. A missed term counts as an interval that does not cover.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mcfit import decay
from mcfit.bounds import amplitude_crlb

__all__ = ["VerdictScene", "VerdictRow", "VERDICT_SCENES", "run_verdicts", "format_verdicts"]


@dataclass(frozen=True)
class VerdictScene:
    """A known truth: coefficients, period (s), duration (s) and amplitude noise (or, for
    ``waveform``, sample noise at 100 samples per period), amplitude y0 = 1."""

    name: str
    a: float
    b: float
    c: float
    period: float
    duration: float
    noise: float
    waveform: bool = False

    @property
    def model(self) -> str:
        return "".join(k for k, v in zip("abc", (self.a, self.b, self.c)) if v) or "none"


def _fluid_at(standard_errors, b, duration, noise):
    """The fluid coefficient that is ``standard_errors`` of its Cramer-Rao bound beside b
    (amplitudes every half period of 1 s, y0 and a and b free)."""
    t = np.arange(0.0, duration, 0.5)
    return standard_errors * amplitude_crlb(t, 1.0, 0.0, b, 0.0, noise, "ab")["a"]


VERDICT_SCENES = (
    VerdictScene("undamped sine, SNR 100", 0.0, 0.0, 0.0, 1.0, 100.0, 0.01),
    VerdictScene("0.6 % decay (b = 6e-5)", 0.0, 6e-5, 0.0, 1.0, 100.0, 2e-3),
    VerdictScene("pure b, 16 turning points", 0.0, 0.1, 0.0, 1.0, 8.0, 2e-3),
    VerdictScene("pure b, 200 turning points", 0.0, 0.05, 0.0, 1.0, 100.0, 2e-3),
    VerdictScene("fluid at 3 sigma beside b", _fluid_at(3, 0.05, 100.0, 2e-3), 0.05, 0.0, 1.0,
                 100.0, 2e-3),
    VerdictScene("fluid at 1.5 sigma beside b", _fluid_at(1.5, 0.05, 100.0, 2e-3), 0.05, 0.0,
                 1.0, 100.0, 2e-3),
    VerdictScene("all three (Fig. 20.19)", 0.1, 0.1, 0.01, 0.5, 20.0, 1e-3),
    VerdictScene("Q = 5, 8 cycles, waveform", 0.0, math.pi / 5, 0.0, 1.0, 8.0, 1e-3, True),
    VerdictScene("Q = 100, 100 cycles, waveform", 0.0, math.pi / 100, 0.0, 1.0, 100.0, 1e-3,
                 True),
)


@dataclass(frozen=True)
class VerdictRow:
    """Rates over ``records`` fits of one scene; coverages are None where not defined."""

    scene: VerdictScene
    records: int
    true_model: float
    spurious: float
    missed: float
    unresolved: float
    coverage: dict  # "a", "b", "c", "Q" -> fraction covered, or None
    seconds: float


def _fit(scene, rng):
    from mcfit.analysis import fit_turning_points
    from mcfit.fit import fit_decay
    from mcfit.motion import simulate_record
    from mcfit.turning import find_turning_points

    if scene.waveform:
        t, x = simulate_record(scene.a, scene.b, scene.c, 1.0, scene.period, scene.duration,
                               100.0 / scene.period, method="averaged", noise=scene.noise,
                               rng=rng)
        return fit_turning_points(find_turning_points(t, x))
    t = np.arange(0.0, scene.duration, scene.period / 2)
    y = decay.amplitude(t, 1.0, scene.a, scene.b, scene.c)
    sigma = np.full(t.size, scene.noise)
    return fit_decay(t, y + rng.normal(0.0, scene.noise, t.size), sigma, period=scene.period)


def _covers(value, error, true, factor):
    return error is not None and abs(value - true) <= factor * error


def _true_q_initial(scene, fit):
    omega = 2 * math.pi / scene.period
    y = decay.amplitude(np.array([fit.t0]), 1.0, scene.a, scene.b, scene.c)
    return float(decay.quality_factor(y, omega, scene.a, scene.b, scene.c)[0])


def run_verdicts(records=100, seed=2026, scenes=VERDICT_SCENES, progress=None) -> list:
    """Fit ``records`` noisy records of each scene (fixed seeds) and count the verdicts."""
    import time

    rows = []
    for number, scene in enumerate(scenes):
        if progress is not None:
            progress(f"verdicts: {scene.name}")
        truth = dict(zip("abc", (scene.a, scene.b, scene.c)))
        counts = dict.fromkeys(("true", "spurious", "missed", "unresolved"), 0)
        covered = {k: 0 for k in ("a", "b", "c", "Q")}
        start = time.perf_counter()
        for index in range(records):
            fit = _fit(scene, np.random.default_rng([seed, number, index]))
            kept = fit.selection.terms
            counts["true"] += fit.model == scene.model
            counts["spurious"] += any(k in kept and not truth[k] for k in "abc")
            counts["missed"] += any(truth[k] and k not in kept for k in "abc")
            counts["unresolved"] += not fit.resolved
            for k in "abc":
                covered[k] += _covers(fit.values[k], fit.stderr[k], truth[k],
                                      fit.interval_factor)
            q = fit.q_summary
            if q is not None:
                covered["Q"] += _covers(q["initial"], q["initial_stderr"],
                                        _true_q_initial(scene, fit), fit.interval_factor)
        seconds = (time.perf_counter() - start) / records
        coverage = {k: covered[k] / records if truth[k] else None for k in "abc"}
        coverage["Q"] = covered["Q"] / records if scene.model != "none" else None
        rows.append(VerdictRow(scene, records, *(counts[k] / records for k in
                                                 ("true", "spurious", "missed", "unresolved")),
                               coverage, seconds))
    return rows


def format_verdicts(rows) -> str:
    """The verdicts table: one line per scene."""
    lines = ["Verdicts and 95 % interval coverage (fractions of records; a missed term does "
             "not cover)",
             f"{'scene':34s} {'model':>5s} {'N':>4s} {'true':>5s} {'spur':>5s} {'miss':>5s} "
             f"{'unres':>5s} {'cov a':>5s} {'cov b':>5s} {'cov c':>5s} {'cov Q':>5s} {'ms':>6s}"]
    for row in rows:
        cells = [f"{row.coverage[k]:5.2f}" if row.coverage[k] is not None else "    -"
                 for k in ("a", "b", "c", "Q")]
        lines.append(f"{row.scene.name:34s} {row.scene.model:>5s} {row.records:4d} "
                     f"{row.true_model:5.2f} {row.spurious:5.2f} {row.missed:5.2f} "
                     f"{row.unresolved:5.2f} {' '.join(cells)} {1e3 * row.seconds:6.1f}")
    return "\n".join(lines)
