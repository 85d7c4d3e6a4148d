"""Time and peak memory of reading a 1e7-sample CSV and of turning-point extraction.

Run: python benchmarks/bench_turning.py [--samples N]. Each phase runs in a fresh child
process so that its peak resident memory (ru_maxrss) is its own; the figure printed is
the peak minus the child's resident size after imports, next to the tracemalloc peak
(numpy arrays only; pandas' parser buffers are not traced).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time


def _rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux: kB


def _make_csv(path, samples):
    import numpy as np
    t = np.arange(samples) / 1000.0
    x = 0.4 + np.exp(-t / 2000.0) * np.cos(2 * np.pi * t) + 1e-3 * np.random.default_rng(0).normal(
        size=samples)
    with open(path, "w") as handle:
        handle.write("time (s),position (m),velocity\n")
        block = 1_000_000
        for start in range(0, samples, block):
            chunk = np.column_stack([t[start:start + block], x[start:start + block],
                                     x[start:start + block]])
            np.savetxt(handle, chunk, fmt="%.6f", delimiter=",")


def _child(phase, path):
    import tracemalloc

    import numpy as np

    from mcfit.io import read_record
    from mcfit.turning import find_turning_points
    base = _rss_mb()
    if phase == "turning":
        samples = int(path)
        t = np.arange(samples) / 1000.0
        x = 0.4 + np.exp(-t / 2000.0) * np.cos(2 * np.pi * t)
        x += 1e-3 * np.random.default_rng(0).normal(size=samples)
        base = _rss_mb()
    tracemalloc.start()
    start = time.perf_counter()
    if phase == "read":
        record = read_record(path)
        result = f"{record.x.size} samples, signal '{record.signal_column}'"
    else:
        points = find_turning_points(t, x)
        result = f"{points.count} turning points, period {points.period:.6g}"
    elapsed = time.perf_counter() - start
    traced = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    print(f"{elapsed:.2f} {_rss_mb() - base:.0f} {traced:.0f} {result}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=10_000_000)
    parser.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(*args.child)
        return
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "big.csv")
        _make_csv(path, args.samples)
        size = os.path.getsize(path) / 2**20
        print(f"CSV: {args.samples} rows, 3 columns, {size:.0f} MiB")
        for phase, argument in (("read", path), ("turning", str(args.samples))):
            out = subprocess.run([sys.executable, __file__, "--child", phase, argument],
                                 capture_output=True, text=True, check=True).stdout.split(" ", 3)
            print(f"{phase:8s} {float(out[0]):6.2f} s  peak RSS +{out[1]} MiB  "
                  f"tracemalloc peak {out[2]} MiB  ({out[3].strip()})")


if __name__ == "__main__":
    main()
