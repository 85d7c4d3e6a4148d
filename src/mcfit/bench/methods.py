"""The methods section of ``mcfit bench``: the turning-point fit against the waveform fit by
the equation of motion (:func:`mcfit.fit.waveform.fit_waveform`), over Q (docs/theory.md
section 7, README "Low Q: fitting the waveform").

The records are pure hysteretic decays, b = omega/(2Q), from a tight integration of
Eq. 20.55 (``simulate_record(..., method="accurate")``): period 1 s, y0 = 1, 100 samples
per second, sample noise 1e-4 (SNR 1e4), long enough for the amplitude to fall to 1e-3 of
y0 but at least 8 cycles and at most 40 s. Both methods fit the true model (b forced); b's
error is measured in the fit's own standard errors, z = (b - b_true) / stderr, and the
95 % interval is b +- ``interval_factor`` * stderr. Alongside, ``method="auto"`` of
:func:`mcfit.analysis.analyse_record` (free model selection) shows how often it chose the
waveform fit. Times are wall-clock medians per record: the turning-point time includes
finding the turning points, the waveform time is the waveform fit alone (started from the
turning-point fit) and auto's is the whole of ``analyse_record``; nothing here asserts a
time.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

__all__ = ["METHOD_QS", "MethodStats", "MethodRow", "record_duration", "run_methods",
           "format_methods"]

METHOD_QS = (2, 3, 5, 10, 20, 50)
PERIOD = 1.0  # s
RATE = 100.0  # samples per second
NOISE = 1e-4  # with y0 = 1: SNR 1e4
DECAY_TO = 1e-3  # the record runs until y/y0 falls to this ...
MIN_CYCLES = 8  # ... but for at least this many periods ...
MAX_DURATION = 40.0  # ... and at most this long (s), so that Q = 50 stays cheap


@dataclass(frozen=True)
class MethodStats:
    """One method's b over the records of a row: mean and rms of z (bias and RMSE in
    standard errors), share of 95 % intervals that cover b_true, median seconds."""

    bias: float
    rmse: float
    coverage: float
    seconds: float


@dataclass(frozen=True)
class MethodRow:
    """One Q: both methods' statistics over ``records`` records, and what auto chose."""

    q: float
    duration: float
    records: int
    turning_points: MethodStats
    waveform: MethodStats
    auto_waveform: float  # share of records where method auto chose the waveform fit
    auto_seconds: float  # median


def record_duration(q) -> float:
    """Whole periods until y/y0 = DECAY_TO, within [MIN_CYCLES, MAX_DURATION] seconds."""
    decay_time = math.log(1 / DECAY_TO) * 2 * q / (2 * math.pi / PERIOD)
    return min(max(math.ceil(decay_time / PERIOD), MIN_CYCLES) * PERIOD, MAX_DURATION)


def _timed(function, *args, **kwargs):
    start = time.perf_counter()
    result = function(*args, **kwargs)
    return time.perf_counter() - start, result


def _z(fit, truth):
    """(z of b, whether the 95 % interval covers b_true)."""
    z = (fit.values["b"] - truth) / fit.stderr["b"]
    return z, abs(z) <= fit.interval_factor


def _one_record(q, seed, index):
    """Per method (turning points, waveform, auto): (z, covered, seconds); auto's method."""
    from mcfit.analysis import analyse_record, fit_turning_points
    from mcfit.fit.waveform import WaveformStart, fit_waveform
    from mcfit.motion import simulate_record
    from mcfit.io import Record
    from mcfit.turning import find_turning_points

    b = math.pi / (q * PERIOD)
    t, x = simulate_record(0.0, b, 0.0, 1.0, PERIOD, record_duration(q), RATE,
                           method="accurate", noise=NOISE,
                           rng=np.random.default_rng([seed, int(10 * q), index]))
    turning_s, turning = _timed(find_turning_points, t, x)
    tp_s, tp = _timed(fit_turning_points, turning, model="b")
    wf_s, wf = _timed(fit_waveform, t, x, turning, WaveformStart.of_fit(tp), forced="b")
    auto_s, auto = _timed(analyse_record, Record(source=f"Q {q:g}", t=t, x=x))
    return ((*_z(tp, b), turning_s + tp_s), (*_z(wf, b), wf_s),
            auto.fit is not None and auto.fit.method == "waveform", auto_s)


def _stats(results) -> MethodStats:
    z, covered, seconds = (np.array(column, dtype=float) for column in zip(*results))
    return MethodStats(float(np.mean(z)), float(np.sqrt(np.mean(z ** 2))),
                       float(np.mean(covered)), float(np.median(seconds)))


def run_methods(n_records=40, seed=2026, qs=METHOD_QS, progress=None) -> list:
    """Fit ``n_records`` records at each Q (fixed seeds) by both methods and by auto."""
    rows = []
    for q in qs:
        if progress is not None:
            progress(f"methods: Q = {q:g}")
        results = [_one_record(q, seed, index) for index in range(n_records)]
        tp, wf, chose_waveform, auto_s = zip(*results)
        rows.append(MethodRow(q, record_duration(q), n_records, _stats(tp), _stats(wf),
                              float(np.mean(chose_waveform)), float(np.median(auto_s))))
    return rows


def format_methods(rows) -> str:
    """The methods table: one line per Q."""
    lines = ["Methods against Q (pure b, SNR 1e4, b forced): b's bias and RMSE in standard "
             "errors, 95 % coverage, median ms",
             f"{'Q':>4s} {'N':>4s} {'TP bias':>7s} {'TP rms':>7s} {'TP cov':>6s} {'TP ms':>6s} "
             f"{'WF bias':>7s} {'WF rms':>7s} {'WF cov':>6s} {'WF ms':>7s} {'auto wf':>7s} "
             f"{'auto ms':>7s}"]
    for row in rows:
        tp, wf = row.turning_points, row.waveform
        lines.append(f"{row.q:4g} {row.records:4d} {tp.bias:7.2f} {tp.rmse:7.2f} "
                     f"{tp.coverage:6.2f} {1e3 * tp.seconds:6.1f} {wf.bias:7.2f} "
                     f"{wf.rmse:7.2f} {wf.coverage:6.2f} {1e3 * wf.seconds:7.0f} "
                     f"{row.auto_waveform:7.2f} {1e3 * row.auto_seconds:7.0f}")
    return "\n".join(lines)
