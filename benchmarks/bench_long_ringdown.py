"""Long high-Q ringdowns against the Cramer-Rao bound (issue 38), and against the peer.

Run: python benchmarks/bench_long_ringdown.py [--q 1e4] [--records 30] [--peer N]

Each record is exp(-b*t)*cos(2*pi*t + phase) + white noise (closed form, independent of
mcfit): period 1 s, 20 samples a cycle, 1e5 cycles (2e6 samples), noise 1e-3 of the first
amplitude, b = pi/Q, the phase drawn from the record's seed (seeds 0 .. records-1). Printed
per Q: how often b alone is chosen, the root-mean-square error of b over the waveform
Cramer-Rao bound (mcfit.bounds.waveform_crlb), how often the 95 % intervals of b and of
the initial Q cover the truth, and the median CPU seconds per record of mcfit.analyse.
With --peer N, the first N records through ringdownanalysis's RingDownAnalyzer.analyze_array
(its selected Q; `pip install ringdownanalysis`, not a dependency of mcfit) in the same
run: its Q's root-mean-square error over the bound and its median CPU seconds.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import mcfit
from mcfit.bounds import waveform_crlb

CYCLES, SAMPLES_PER_CYCLE, NOISE = 10**5, 20, 1e-3


def ringdown(seed, q):
    """(t, x, b, phase) of one record."""
    rng = np.random.default_rng(seed)
    t = np.arange(CYCLES * SAMPLES_PER_CYCLE) / SAMPLES_PER_CYCLE
    b = math.pi / q
    phase = rng.uniform(0.0, 2 * math.pi)
    x = np.exp(-b * t) * np.cos(2 * math.pi * t + phase) + NOISE * rng.standard_normal(t.size)
    return t, x, b, phase


def _mcfit_row(t, x, b):
    start = time.process_time()
    fit = mcfit.analyse(t, x).fit
    seconds = time.process_time() - start
    value, stderr = fit.values["b"], fit.stderr.get("b") or math.nan
    q = fit.q_summary or {}
    q_value, q_stderr = q.get("initial"), q.get("initial_stderr")
    q_covered = (q_value is not None and q_stderr is not None
                 and abs(q_value - math.pi / b) <= 1.96 * q_stderr)
    return fit.model, value - b, abs(value - b) <= 1.96 * stderr, q_covered, seconds


def _peer_row(t, x, b):
    import logging

    from ringdownanalysis import RingDownAnalyzer

    logging.disable(logging.CRITICAL)  # it logs each stage
    start = time.process_time()
    result = RingDownAnalyzer().analyze_array(t, x)
    seconds = time.process_time() - start
    return float(result["Q_selected"]) - math.pi / b, seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--q", type=float, action="append")
    parser.add_argument("--records", type=int, default=30)
    parser.add_argument("--peer", type=int, default=0, metavar="N",
                        help="also the peer, on the first N records")
    options = parser.parse_args()
    for q in options.q or [1e3, 1e4, 1e5]:
        t, _, b, phase = ringdown(0, q)
        bound = waveform_crlb(t, 1.0, 0.0, b, 0.0, 1.0, NOISE, model="b", phase=phase)["b"]
        rows = [_mcfit_row(*ringdown(seed, q)[:2], b) for seed in range(options.records)]
        errors = np.array([row[1] for row in rows])
        print(f"Q = {q:g}, {options.records} records, Cramer-Rao bound of b {bound:.3g} 1/s")
        print(f"  mcfit: b alone in {sum(row[0] == 'b' for row in rows)}, "
              f"RMSE(b)/bound {np.sqrt(np.mean(errors**2)) / bound:.2f}, b covered in "
              f"{sum(row[2] for row in rows)}, Q covered in {sum(row[3] for row in rows)}, "
              f"median CPU {np.median([row[4] for row in rows]):.2f} s")
        if options.peer > 0:
            peer = [_peer_row(*ringdown(seed, q)[:2], b) for seed in range(options.peer)]
            q_errors = np.array([row[0] for row in peer])
            q_bound = q * bound / b  # dQ = Q * db / b
            print(f"  ringdownanalysis: RMSE(Q)/bound {np.sqrt(np.mean(q_errors**2)) / q_bound:.2f}, "
                  f"median CPU {np.median([row[1] for row in peer]):.2f} s")


if __name__ == "__main__":
    main()
