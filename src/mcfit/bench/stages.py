"""Where a record's time goes, measured in a child process held to one core (run by
:mod:`mcfit.bench.throughput` as ``python -c "from mcfit.bench.stages import main; main()"
SPEC``; SPEC and the answer are JSON).

The stages are those of :func:`mcfit.analysis.analyse_record` on a record read from a CSV:
reading it, its turning points, the turning-point fit (every candidate model and the
selection) and ``--method auto``'s choice (the predicted bias of the averaged law and,
when it asks for one, the waveform fit). CPU time (``time.process_time``), the best of a
few passes over the same records: on a shared machine the smallest figure is the least
disturbed one.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
import tempfile
import time

__all__ = ["measure_stages", "main"]

PASSES = 3


def _records(config, samples, directory):
    from mcfit.bench.records import throughput_record, write_csv

    paths = []
    for i in range(config.batch_records):
        paths.append(os.path.join(directory, f"record{samples}-{i:04d}.csv"))
        write_csv(paths[-1], *throughput_record(config, i, samples))
    return paths


def _timed_stages(paths):
    """Per stage, per record CPU seconds (best of :data:`PASSES`), and the fitted records."""
    from mcfit.analysis import fit_turning_points
    from mcfit.errors import McfitError
    from mcfit.io import read_record
    from mcfit.turning import turning_points_of

    best = dict.fromkeys(("read", "turning", "fit"), math.inf)
    for _ in range(PASSES):
        spent = dict.fromkeys(best, 0.0)
        fitted = []
        for path in paths:
            clock = time.process_time()
            record = read_record(path)
            spent["read"] += time.process_time() - clock
            clock = time.process_time()
            try:
                turning = turning_points_of(record)
            except McfitError:  # timed all the same
                spent["turning"] += time.process_time() - clock
                continue
            spent["turning"] += time.process_time() - clock
            clock = time.process_time()
            with contextlib.suppress(McfitError):
                fitted.append((record, turning, fit_turning_points(turning)))
            spent["fit"] += time.process_time() - clock
        best = {k: min(best[k], spent[k]) for k in best}
    return {k: v / len(paths) for k, v in best.items()}, fitted


def _auto_choice(fitted):
    """``--method auto``'s choice on each fitted record: CPU seconds and the method."""
    from mcfit.analysis import fit_by_method
    from mcfit.errors import McfitError

    choices = []
    for index, (record, turning, fit) in enumerate(fitted):
        clock = time.process_time()
        try:
            method = getattr(fit_by_method(record, turning, fit, "auto"), "method", None)
        except McfitError:
            method = "error"
        choices.append((index, method or "turning-points", time.process_time() - clock))
    return choices


def measure_stages(config, lengths):
    """Stages per record for records of each length in ``lengths``, and auto's choice on
    the records of the last length.

    Returns
    -------
    dict
        ``{"stages": {samples: {"read", "turning", "fit": CPU s per record}},
        "records": count, "fitted": count of the last length, "crests": their mean
        number of turning points, "auto": [[index, method, CPU s], ...]}``.
    """
    stages, fitted = {}, []
    with tempfile.TemporaryDirectory(prefix="mcfit-stages-") as directory:
        for samples in lengths:
            stages[samples], fitted = _timed_stages(_records(config, samples, directory))
    crests = sum(turning.count for _, turning, _ in fitted) / len(fitted) if fitted else 0
    return {"stages": stages, "records": config.batch_records, "fitted": len(fitted),
            "crests": crests, "auto": _auto_choice(fitted)}


def main(argv=None):
    """Read ``{"config": {...}, "lengths": [...]}`` from the first argument, print JSON."""
    import dataclasses

    from mcfit.bench.config import QUICK

    spec = json.loads((argv or sys.argv[1:])[0])
    fields = {f.name for f in dataclasses.fields(QUICK)}
    config = dataclasses.replace(QUICK, **{k: v for k, v in spec["config"].items()
                                           if k in fields})
    print(json.dumps(measure_stages(config, spec["lengths"])))
