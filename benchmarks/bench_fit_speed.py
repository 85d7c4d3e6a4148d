"""Time for fitting all seven models to 1000 turning points (target: under 50 ms).

Run: python benchmarks/bench_fit_speed.py   (prints figures; asserts nothing)
"""

from __future__ import annotations

import platform
import time

import numpy as np

from mcfit import decay
from mcfit.fit import fit_decay


def main(repeats: int = 20) -> None:
    rng = np.random.default_rng(1)
    period = 0.5
    t = np.arange(1000) * period / 2
    y = decay.amplitude(t, 4.0, 0.1 / 40, 0.1 / 40, 0.01 / 40)
    y = y + rng.normal(0.0, 1e-3, y.size)
    sigma = np.full(y.size, 1e-3)
    fit_decay(t, y, sigma, period=period)  # warm-up: imports and caches
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = fit_decay(t, y, sigma, period=period)
        times.append(time.perf_counter() - start)
    times = np.array(times) * 1e3
    print(f"machine: {platform.machine()} {platform.processor() or ''} python {platform.python_version()}")
    print(f"7-model fit of {t.size} turning points: median {np.median(times):.1f} ms, "
          f"min {times.min():.1f} ms, max {times.max():.1f} ms over {repeats} runs "
          f"(chosen model {result.model}; target < 50 ms)")
    evaluations = sum(c.evaluations for c in result.candidates)
    print(f"function evaluations over the seven fits: {evaluations}")


if __name__ == "__main__":
    main()
