"""The Python interface: a record (arrays, a file, many files) in, an :class:`Analysis` out.

The keyword options are the command line's, spelled as Python names::

    read:  time_col, signal_col, sheet, rate, kind, domain, run, angle_from
    fit:   criterion, model, bootstrap, seed, method, pendulum, degrees, start, end

>>> import mcfit
>>> record = mcfit.simulate_record(a=0.1, b=0.1, c=0.01, y0=4.0, period=0.5,
...                                duration=20.0, rate=100.0, noise=0.005, rng=1)
>>> result = mcfit.analyse(record)
>>> result.fit.model, result.status
('abc', 'ok')
>>> round(result.summary()["params"]["b"]["value"], 2)
0.1
"""

from __future__ import annotations

import inspect
from dataclasses import replace

import numpy as np

from mcfit.analysis import Analysis, analyse_record, free_decay_runs
from mcfit.errors import UsageError
from mcfit.options import check_fit_options, check_read_options
from mcfit.record import Record, detect_kind, with_signal_unit

__all__ = ["analyse", "analyse_file", "analyse_files", "turning_points_frame"]

READ_OPTIONS = ("time_col", "signal_col", "sheet", "rate", "kind", "domain", "run",
                "angle_from")
FIT_OPTIONS = ("criterion", "model", "bootstrap", "seed", "method", "pendulum", "degrees",
               "start", "end")


def analyse(t, x=None, *, source="<arrays>", kind=None, domain="time", unit=None,
            **options) -> Analysis:
    """Find the turning points of a record and fit the damping law to them.

    Parameters
    ----------
    t, x : array_like, shape (n,)
        Times (s, or cycle numbers with ``domain="cycle"``) and the signal: a waveform, or
        a table of turning points (extrema or amplitudes). ``t`` may instead be a
        :class:`Record` (as :func:`mcfit.simulate_record` returns) with ``x`` left out.
    source : str
        The name the results carry.
    kind : {"waveform", "turning-points"}, optional
        What ``x`` holds [default: detected].
    domain : {"time", "cycle"}
    unit : str, optional
        The signal's unit (``"mm"``), for every output: the report, ``to_dict``
        (``signal_unit``, ``coefficient_units``) and the figure.
    **options
        The fit's options (``FIT_OPTIONS``), e.g. ``model="ab"``, ``method="waveform"``,
        ``bootstrap=200, seed=1``.

    Returns
    -------
    Analysis
        ``status`` "ok", or "error" with ``error`` when the record cannot be fitted.

    >>> import numpy as np, mcfit
    >>> t = np.arange(0.0, 30.0, 0.01)
    >>> noise = np.random.default_rng(1).normal(0.0, 1e-3, t.size)
    >>> x = np.exp(-0.05 * t) * np.cos(2 * np.pi * t) + noise
    >>> result = mcfit.analyse(t, x)
    >>> result.fit.model, round(result.fit.values["b"], 3)
    ('b', 0.05)
    """
    if x is None:
        if not isinstance(t, Record):
            raise UsageError("give the signal x beside the times t, or a Record as t.")
        record = t
    else:
        t, x = np.asarray(t, dtype=float), np.asarray(x, dtype=float)
        if t.shape != x.shape or t.ndim != 1:
            raise UsageError(f"t and x must be 1-D arrays of one length, not {t.shape} and "
                             f"{x.shape}.")
        record = Record(source=source, t=t, x=x, kind=kind or detect_kind(t, x),
                        domain=domain, time_unit="s" if domain == "time" else None)
    return analyse_record(with_signal_unit(record, unit), **_fit_keywords(options))


def analyse_file(path, *, unit=None, **options) -> Analysis:
    """:func:`analyse` of a record file (CSV, text, Excel...); for a file of several runs
    side by side give ``run=N``, or use :func:`analyse_files` for every run. ``unit``
    names the signal's unit for every output, in place of the header's (``Position
    (mm)``), with a note where that differs."""
    from mcfit.io import read_records

    records = read_records(path, **_taken(options, READ_OPTIONS))
    keywords = _fit_keywords(options)
    if len(records) > 1:
        raise UsageError(f"{path} holds {len(records)} runs side by side; give run=N for "
                         "one, or use analyse_files for all of them.")
    if options.get("start") is None and options.get("end") is None:
        records = free_decay_runs(records[0])
        if len(records) > 1:
            raise UsageError(f"{path} holds {len(records)} free decays (the oscillator "
                             "was excited more than once); use analyse_files for all of "
                             "them, or start= and end= for one.")
    record = with_signal_unit(records[0], unit)
    return replace(analyse_record(record, **keywords), source=record.name)


def analyse_files(paths, *, jobs=1, unit=None, **options):
    """Every record of ``paths`` (files or directories; every run of a multi-run file) as
    a pandas DataFrame with the command line's CSV columns, one row per record, in input
    order; ``jobs`` worker processes; ``unit`` the signals' unit, as for
    :func:`analyse_file`."""
    from mcfit import batch, report
    from mcfit.frames import results_frame

    chosen = _taken(options, READ_OPTIONS + FIT_OPTIONS)
    _nothing_else(options, READ_OPTIONS + FIT_OPTIONS)
    # Refused here, once, rather than in every file's row.
    _checked(check_read_options, chosen)
    chosen["model"] = _checked(check_fit_options, chosen)
    sources = batch.expand_inputs([str(p) for p in ([paths] if isinstance(paths, str)
                                                   else paths)])
    fit_options = batch.FitOptions(output_format="csv", unit=unit, **chosen)
    bootstrap = fit_options.bootstrap > 0
    rows = [report.csv_record(result["analysis"], bootstrap)
            for file_result in batch.run_jobs(sources, fit_options, [None] * len(sources),
                                              jobs=jobs)
            for result in file_result.records]
    return results_frame(rows, report.csv_columns(bootstrap))


def turning_points_frame(analysis: Analysis):
    """The turning points of ``analysis`` as a pandas DataFrame: t, amplitude, sigma, used,
    why not (``excluded_reason``) and the fitted envelope
    (:attr:`Analysis.turning_points`)."""
    return analysis.turning_points


def _checked(check, options):
    """``check`` called with the ``options`` it takes."""
    taken = inspect.signature(check).parameters
    return check(**{k: v for k, v in options.items() if k in taken})


def _taken(options, names):
    """The ``names`` found in ``options``, taken out of it."""
    return {k: options.pop(k) for k in names if k in options}


def _nothing_else(options, names):
    if options:
        raise UsageError(f"unknown options: {', '.join(sorted(options))}; give "
                         f"{', '.join(names)}.")


def _fit_keywords(options):
    """analyse_record's keywords from the fit's options."""
    keywords = _taken(options, FIT_OPTIONS)
    _nothing_else(options, FIT_OPTIONS)
    return keywords
