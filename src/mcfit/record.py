"""A decay record: two float arrays and what was decided on the way (numpy only).

:func:`mcfit.io.read_record` makes one from a file, :func:`mcfit.motion.simulate_record`
from the equation of motion; :func:`mcfit.analyse` takes either.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

__all__ = ["Record", "coefficient_units", "detect_kind", "with_signal_unit"]


@dataclass(frozen=True, eq=False)
class Record:
    """A decay record as read from a file: plain arrays plus what was decided on the way.

    Attributes
    ----------
    source : str
        File name as given (``"<stdin>"`` for ``-`` or a stream).
    t : ndarray, shape (n,)
        Time (in ``time_unit``, seconds unless the header says otherwise) or cycle number
        (``domain == "cycle"``). Increasing for waveforms; turning-point tables are sorted.
    x : ndarray, shape (n,)
        Signal (waveform) or turning-point values (signed or not); NaN marks a gap.
    kind : {"waveform", "turning-points"}
    domain : {"time", "cycle"}
    time_column, signal_column : str or None
        Column names as in the file (``"column 2"`` without a header); ``time_column`` is
        None when the time was built from ``rate``.
    time_unit, signal_unit : str or None
        Units read from headers such as ``time (s)``.
    columns : tuple of str
        Every column of the file, in order.
    notes : tuple of str
        One sentence per decision or oddity, for the report.
    run : str or None
        Which of the file's runs side by side this is (``"Run 7"``), or of the free decays
        of a record excited more than once; None for a file of one run.
    left_out : tuple of (float, float, str)
        The stretches of the recorded signal left out before, between or after the free
        decay, with why (:func:`mcfit.turning.placement.locate_free_decay`).
    whole : tuple of two ndarrays or None
        The record's times and signal as read, where ``t`` and ``x`` are the free decay
        found in them (for the figure); None where they are the whole record.
    time_origin : dict or None
        What t = 0 is when the time column is a clock read as seconds from its first
        reading: ``{"clock": "unix epoch seconds", "value": 1406730000.123, "utc":
        "2014-07-30T14:20:00.123Z", "column": "Epoch"}`` (``clock`` also "unix epoch
        milliseconds", "date and time" or "time of day", whose ``value`` is the text read;
        ``utc`` None where the clock does not say its zone). None for elapsed time.
    oscillating_columns : tuple of str
        The file's other columns that oscillate above their noise (a spectral line),
        clearest first, when the signal column does not; else empty. A failed fit names
        the first.
    """

    source: str
    t: np.ndarray
    x: np.ndarray
    kind: str = "waveform"
    domain: str = "time"
    time_column: str | None = None
    signal_column: str | None = None
    time_unit: str | None = None
    signal_unit: str | None = None
    columns: tuple[str, ...] = ()
    notes: tuple[str, ...] = field(default=())
    run: str | None = None
    left_out: tuple = ()
    whole: tuple | None = field(default=None, repr=False)
    placed: bool = False  # whether the free decay was looked for (free_decay_runs)
    time_origin: dict | None = None
    oscillating_columns: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        """The source as a script names it: ``file.csv#Run 7`` for one run of several."""
        return self.source if self.run is None else f"{self.source}#{self.run}"

    def __iter__(self):
        """``t, x = record``: a record unpacks as its two arrays."""
        return iter((self.t, self.x))

    def __repr__(self):
        span = (f"t {self.t[0]:g} to {self.t[-1]:g}" if self.t.size else "empty")
        run = f", run={self.run!r}" if self.run else ""
        return (f"Record(source={self.source!r}{run}, kind={self.kind!r}, "
                f"samples={self.t.size}, {span})")

    def to_dict(self) -> dict:
        """What the record is, as plain data (JSON-ready; not its samples): source, run,
        kind, domain, number of samples, the columns chosen and all, units and notes."""
        return {"source": self.source, "run": self.run, "kind": self.kind,
                "domain": self.domain, "samples": int(self.t.size),
                "time_column": self.time_column, "signal_column": self.signal_column,
                "time_unit": self.time_unit, "signal_unit": self.signal_unit,
                "columns": list(self.columns), "notes": list(self.notes),
                "left_out": [{"start": a, "end": b, "why": why}
                             for a, b, why in self.left_out],
                "time_origin": None if self.time_origin is None else dict(self.time_origin)}


def coefficient_units(signal_unit, per) -> dict:
    """The units of y0, a, b and c for a signal in ``signal_unit`` (``"U"`` when None) and
    time in ``per`` ("s", "cycle"): ``{"y0": "mm", "a": "1/(mm*s)", "b": "1/s",
    "c": "mm/s"}`` (dy/dt = -c - b*y - a*y**2)."""
    unit = signal_unit or "U"
    factor = f"({unit})" if any(mark in unit for mark in "/* ") else unit
    return {"y0": unit, "a": f"1/({factor}*{per})", "b": f"1/{per}", "c": f"{factor}/{per}"}


def with_signal_unit(record, unit):
    """``record`` with its signal in ``unit`` (``"mm"``), as the option ``unit`` names it
    for every output: a unit its header gave is overridden, with a note. ``record`` as it
    is where ``unit`` is None or empty."""
    unit = None if unit is None else str(unit).strip()
    if not unit or unit == record.signal_unit:
        return record
    notes = record.notes
    if record.signal_unit:
        notes += (f"signal unit: {unit}, as `unit` says, in place of the header's "
                  f"{record.signal_unit}",)
    return replace(record, signal_unit=unit, notes=notes)


def detect_kind(t, x):
    """'turning-points' for a table of extrema or amplitudes, else 'waveform'."""
    finite = np.isfinite(t) & np.isfinite(x)
    count = np.count_nonzero(finite)
    if count < 3 or count > 5000:  # decided before copying a long record
        return "waveform"
    t, x = t[finite], x[finite]
    order = np.argsort(t, kind="stable")
    v = x[order]
    if np.all(v >= 0) or np.all(v <= 0):
        magnitude = np.abs(v)
        decreasing = np.count_nonzero(np.diff(magnitude) < 0) / (v.size - 1)
        return "turning-points" if decreasing >= 0.65 else "waveform"
    centred = v - np.median(v)
    alternating = np.count_nonzero(np.diff(np.sign(centred)) != 0) / (v.size - 1)
    return "turning-points" if alternating >= 0.9 else "waveform"
