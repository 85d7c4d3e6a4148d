"""The averaged law's bias chain (mcfit.model_error): its cost and its predictions.

Run with one BLAS thread (OPENBLAS_NUM_THREADS=1 etc.). On the 14 records of the bench's
mixed batch (``mixed_record(i, 20, 2026)``) that reach the chain: CPU ms a record of the
chain and of its stages (the noise-free waveform, the turning-point search, the fit),
each record's best of ``--runs``. Then on the 40 records of ``mixed_record(i, 40, 7)`` and
the bench's 20: the chain's z per coefficient with find_turning_points_of_model against
the record's own search (find_turning_points, the chain's search before), the largest
difference and whether a decision changed.
"""

from __future__ import annotations

import argparse
import math
import time
from unittest import mock

import numpy as np

import mcfit.turning
from mcfit import model_error
from mcfit.analysis import fit_turning_points
from mcfit.bench.waveform_speed import mixed_record
from mcfit.hysteretic_motion import hysteretic_motion
from mcfit.phase_plane import phase_plane_motion
from mcfit.turning import find_turning_points, find_turning_points_of_model


def _analysed(record):
    turning = find_turning_points(record.t, record.x)
    return record.t, turning, fit_turning_points(turning)


def _stages(t, turning, fit):
    """CPU seconds of the chain's waveform, search and fit (as model_error runs them)."""
    clock = [time.process_time()]
    used = np.flatnonzero(turning.used)
    t0 = float(turning.t[used[0]])
    times = t[t >= t0]
    theta0 = 0.0 if turning.sign[used[0]] >= 0 else math.pi
    v = fit.values
    if v["a"] == v["c"] == 0.0:
        wave = hysteretic_motion(times - t0, v["y0"], theta0, fit.omega, v["b"])[0]
    else:
        wave = phase_plane_motion(times - t0, v["y0"], theta0, fit.omega, v["a"], v["b"],
                                  v["c"])[0]
    x = turning.equilibrium_at(times) + wave
    clock.append(time.process_time())
    found = find_turning_points_of_model(
        times, x, settle_noise=model_error._positive(turning.noise_sigma))
    clock.append(time.process_time())
    model_error._fitted_values(found, fit.model)
    clock.append(time.process_time())
    return np.diff(clock)


def cost(runs):
    items = [_analysed(mixed_record(i, 20, 2026)[0]) for i in range(14)]
    chain = np.full(len(items), np.inf)
    stages = np.full((len(items), 3), np.inf)
    for _ in range(runs):
        for k, (t, turning, fit) in enumerate(items):
            start = time.process_time()
            model_error._chain_bias(t, turning, fit, model_error.noise_stderr(fit))
            chain[k] = min(chain[k], time.process_time() - start)
            stages[k] = np.minimum(stages[k], _stages(t, turning, fit))
    waveform, search, fitted = 1e3 * stages.mean(axis=0)
    print(f"chain {1e3 * chain.mean():.2f} ms a record (14 records, best of {runs}): "
          f"waveform {waveform:.2f}, search {search:.2f}, fit {fitted:.2f}")


def _record_search(times, x, settle_noise=None):
    return find_turning_points(times, x, settle_noise=settle_noise)


def predictions():
    largest, changed = 0.0, 0
    batches = [(i, 40, 7) for i in range(40)] + [(i, 20, 2026) for i in range(20)]
    for index, count, seed in batches:
        t, turning, fit = _analysed(mixed_record(index, count, seed)[0])
        cheap = model_error.averaged_law_bias(t, turning, fit)
        with mock.patch.object(mcfit.turning, "find_turning_points_of_model", _record_search):
            full = model_error.averaged_law_bias(t, turning, fit)
        difference = max((abs(cheap.z[k] - full.z[k]) for k in full.z), default=0.0)
        largest = max(largest, difference)
        changed += (cheap.largest > model_error.LIMIT) != (full.largest > model_error.LIMIT)
        if full.how == "chain":
            z = ", ".join(f"{k} {full.z[k]:+.4f} / {cheap.z[k]:+.4f}" for k in full.z)
            print(f"  mixed_record({index}, {count}, {seed}) {fit.model}: z (record's search "
                  f"/ model search) {z}")
    print(f"largest |dz| {largest:.2g}; decisions changed: {changed}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7)
    cost(parser.parse_args().runs)
    predictions()
