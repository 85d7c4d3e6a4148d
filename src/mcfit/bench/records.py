"""The bench's records, generated on the spot (nothing is read from the source tree, so the
bench runs the same from an installed wheel): noisy averaged waveforms of a scene, and the
CSV files the command line is timed on."""

from __future__ import annotations

import math
import os

import numpy as np

from mcfit import motion
from mcfit.bench.config import THROUGHPUT_SCENE, BenchConfig, FitScene

__all__ = ["fit_record_pair", "fit_record", "throughput_record", "write_csv",
           "write_throughput_files", "write_large_csv"]


def fit_record_pair(scene: FitScene, snr, samples_per_cycle, rng):
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


def fit_record(scene: FitScene, snr, samples_per_cycle, rng):
    """One noisy record of the averaged waveform: (t, x, phase, sigma_x)."""
    t, x, _, phase, sigma_x = fit_record_pair(scene, snr, samples_per_cycle, rng)
    return t, x, phase, sigma_x


def throughput_record(config: BenchConfig, seed, samples=None):
    """(t, x): record ``seed`` of :data:`THROUGHPUT_SCENE` at SNR 1e3 with ``samples``
    samples (default ``config.batch_samples``) over its 80 cycles."""
    scene = THROUGHPUT_SCENE
    rng = np.random.default_rng([config.seed, 99, seed])
    spc = ((samples or config.batch_samples) - 1) / scene.cycles
    t, x, _, _ = fit_record(scene, 1e3, spc, rng)
    return t, x


def write_csv(path, t, x):
    """A plain two-column CSV with a ``t,x`` header, as a data logger writes it."""
    np.savetxt(path, np.column_stack([t, x]), fmt="%.10g", delimiter=",", header="t,x",
               comments="")


def write_throughput_files(config: BenchConfig, directory, count):
    """Write records 0 to ``count - 1`` as ``record0000.csv``... into ``directory``."""
    os.makedirs(directory, exist_ok=True)
    for i in range(count):
        write_csv(os.path.join(directory, f"record{i:04d}.csv"), *throughput_record(config, i))


def write_large_csv(path, samples, block=1_000_000):
    """A long record as a three-column CSV (``time (s),position (m),velocity``, six
    decimals; about 29 bytes a row): 1 kHz, T = 1 s, decay time 2000 s, noise 1e-3."""
    rng = np.random.default_rng(0)
    with open(path, "w", encoding="utf-8") as handle:
        handle.write("time (s),position (m),velocity\n")
        for start in range(0, samples, block):
            t = np.arange(start, min(start + block, samples)) / 1000.0
            x = 0.4 + np.exp(-t / 2000.0) * np.cos(2 * np.pi * t)
            x += 1e-3 * rng.normal(size=t.size)
            v = -2 * np.pi * np.exp(-t / 2000.0) * np.sin(2 * np.pi * t)
            np.savetxt(handle, np.column_stack([t, x, v]), fmt="%.6f", delimiter=",")
