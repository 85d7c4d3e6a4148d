"""Reading decay records (CSV, TSV, whitespace text, Excel, stdin) into a :class:`Record`.

This package is the only part of mcfit that imports pandas. It turns whatever file a person
has into two float64 arrays, ``t`` and ``x``, and says in ``Record.notes`` what it decided on
the way (columns chosen, decimal commas, padding dropped, timestamps ignored...). Every failure
a person can fix raises :class:`mcfit.errors.InputError` (or ``UsageError`` for contradictory
options) with one line naming the file, the problem and the fix.

One module a stage, in the order a file meets them:

- :mod:`~mcfit.io.opening`: a path, stdin or stream to a table, judged by content (a gzip or
  workbook signature, else text); :mod:`~mcfit.io.decoding` finds the text's encoding and
  refuses binary data; :mod:`~mcfit.io.excel` turns a sheet into text.
- :mod:`~mcfit.io.layouts`: the export layouts of lab programs (Capstone, LabVIEW, Logger Pro,
  phyphox, Tracker, serial loggers...), each recognised in one entry of ``LAYOUTS``.
- :mod:`~mcfit.io.sniffing` finds the separator and the block of numbers;
  :mod:`~mcfit.io.tidying` rewrites a file that is more than a header over numbers (header
  blocks, rules, units rows, repeated headers, notes, clock times, rows of data) as one
  header line over tab-separated numbers; :mod:`~mcfit.io.table` parses it with pandas.
- :mod:`~mcfit.io.columns`: runs side by side and the choice of time and signal columns.
- :mod:`~mcfit.io.times`: rounded, event-driven and glitched timestamps.
- :mod:`~mcfit.io.assembly`: the checks and notes that make the :class:`Record`.

Column choice without options: a column named like time (``time``, ``t``, ``time (s)``...)
or else the first strictly increasing column is the time; the signal is the first other
column that oscillates (velocity, acceleration, residual and fit columns come last).
"""

from __future__ import annotations

import numpy as np

from mcfit.errors import UsageError
from mcfit.io.assembly import _build_record
from mcfit.io.columns import _chosen_runs
from mcfit.io.opening import EXCEL_EXTENSIONS, TEXT_EXTENSIONS, _open_table
from mcfit.options import check_read_options
from mcfit.record import Record

__all__ = ["Record", "read_record", "read_records", "TEXT_EXTENSIONS", "EXCEL_EXTENSIONS"]


def read_record(source, *, time_col=None, signal_col=None, sheet=None, rate=None,
                kind=None, domain=None, run=None, angle_from=None):
    """Read a decay record from a file, ``"-"`` (stdin) or an open stream.

    Parameters
    ----------
    source : str, os.PathLike or file-like
        Delimited text of any extension (separator sniffed: comma, semicolon, tab or
        whitespace; decimal comma accepted), gzip-compressed text, ``.xlsx``/``.xlsm``,
        ``.ods`` and ``.xls`` (with pandas' engine installed), ``"-"`` for stdin, or an open
        text or binary stream holding delimited text.
    time_col, signal_col : str or int, optional
        Column name (units in parentheses may be left out, case ignored) or 1-based index.
    sheet : str or int, optional
        Excel sheet name or 1-based index (default: the first sheet that holds numbers).
    rate : float, optional
        Sample rate in Hz: ``t = index / rate`` (for files without a usable time column).
    kind : {"waveform", "turning-points"}, optional
        Override the detected kind of record.
    domain : {"time", "cycle"}, optional
        Override the detected meaning of the time column (seconds or cycle number n).
    run : int, optional
        For a file of runs side by side, the run to read (its number, ``7`` for
        ``Run #7``, or its place in the file); needed when the file holds several.
    angle_from : (str or int, str or int), optional
        Columns of a tracked pendulum bob's x and y (pivot at the origin): the signal is
        the swing angle ``atan2(x, -y)`` in radians.

    Returns
    -------
    Record

    Raises
    ------
    InputError
        The file cannot be read or holds no usable columns (message: file, problem, fix).
    UsageError
        Contradictory or invalid options.
    """
    records = read_records(source, time_col=time_col, signal_col=signal_col, sheet=sheet,
                           rate=rate, kind=kind, domain=domain, run=run,
                           angle_from=angle_from)
    if len(records) > 1:
        runs = ", ".join(r.run for r in records)
        raise UsageError(f"{records[0].source} holds {len(records)} runs side by side "
                         f"({runs}); pick one with run=N, or read them all with "
                         "read_records.")
    return records[0]


def read_records(source, *, time_col=None, signal_col=None, sheet=None, rate=None,
                 kind=None, domain=None, run=None, angle_from=None):
    """Every run of a file as a :class:`Record`, in file order; see :func:`read_record`.

    Runs side by side are columns labelled ``Run #N`` (columns without a label, such as a
    shared time, belong to every run) or repeated groups of columns that each start with a
    time column. A file without them is one record with ``run`` None.
    """
    check_read_options(kind=kind, domain=domain, rate=rate, time_col=time_col,
                       signal_col=signal_col, angle_from=angle_from)
    rate = _checked_rate(rate)
    table = _open_table(source, sheet)
    if table.rate is not None:
        rate = _file_rate(table, rate, time_col)
    # The column heuristics (spans, slopes, steps) overflow to inf or NaN for values near
    # the float64 limit, which then fail their tests as they should; the turning-point
    # search rejects such values with a message.
    with np.errstate(over="ignore", invalid="ignore"):
        runs = _chosen_runs(table, run, (time_col, signal_col) + tuple(angle_from or ()))
        return [_build_record(table, time_col, signal_col, rate, kind, domain,
                              run=run_of_file, angle_from=angle_from)
                for run_of_file in runs]


def _file_rate(table, rate, time_col):
    """The sample rate of a file that gives one (WAV audio); ``rate`` or ``time_col`` that
    would contradict it are refused."""
    if rate is not None and rate != table.rate:
        raise UsageError(f"{table.name} is WAV audio sampled at {table.rate:g} Hz, which sets "
                         f"its time; `rate` ({rate:g} Hz) does not apply. Leave it out.",
                         option="rate")
    if time_col is not None:
        raise UsageError(f"{table.name} is WAV audio: its time is the file's sample rate, and "
                         "it has no time column. Leave `time_col` out.", option="time_col")
    return table.rate


def _checked_rate(rate):
    """The sample rate as a float, or None (checked by :func:`check_read_options`)."""
    return None if rate is None else float(rate)
