"""Time for fitting all seven models to turning points (targets: about 5 to 8 ms for the 80
turning points of a 40-cycle record, under 50 ms for 1000 points).

Run: python benchmarks/bench_fit_speed.py   (prints figures; asserts nothing)
"""

from __future__ import annotations

import platform
import time

import numpy as np

from mcfit import decay
from mcfit.fit import fit_decay


def _turning_points(n, slower, seed):
    """n turning points of the Fig. 20.19 decay (all three regimes, T = 0.5 s), its
    coefficients divided by ``slower``, with amplitude noise 1e-3."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.5 / 2
    y = decay.amplitude(t, 4.0, 0.1 / slower, 0.1 / slower, 0.01 / slower)
    return t, y + rng.normal(0.0, 1e-3, y.size)


def _time(t, y, repeats, period=0.5):
    sigma = np.full(y.size, 1e-3)
    fit_decay(t, y, sigma, period=period)  # warm-up: imports and caches
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = fit_decay(t, y, sigma, period=period)
        times.append(time.perf_counter() - start)
    times = np.array(times) * 1e3
    evaluations = {c.model: c.evaluations for c in result.candidates}
    print(f"7-model fit of {t.size} turning points: median {np.median(times):.1f} ms, "
          f"min {times.min():.1f} ms, max {times.max():.1f} ms over {repeats} runs "
          f"(chosen model {result.model})")
    print(f"  evaluations of the law per candidate: {evaluations} "
          f"(total {sum(evaluations.values())})")


def main(repeats: int = 20) -> None:
    print(f"machine: {platform.machine()} {platform.processor() or ''} "
          f"python {platform.python_version()}")
    _time(*_turning_points(80, 1.0, seed=2), repeats)  # Fig. 20.19 itself: 20 s
    _time(*_turning_points(1000, 40.0, seed=1), repeats)  # the record timed since 0.1


if __name__ == "__main__":
    main()
