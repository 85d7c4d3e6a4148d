"""A decay record: two float arrays and what was decided on the way (numpy only).

:func:`mcfit.io.read_record` makes one from a file, :func:`mcfit.motion.simulate_record`
from the equation of motion; :func:`mcfit.analyse` takes either.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Record", "coefficient_units", "detect_kind"]


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
        Which of the file's runs side by side this is (``"Run 7"``); None for a file of
        one run.
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
                "columns": list(self.columns), "notes": list(self.notes)}


def coefficient_units(signal_unit, per) -> dict:
    """The units of y0, a, b and c for a signal in ``signal_unit`` (``"U"`` when None) and
    time in ``per`` ("s", "cycle"): ``{"y0": "mm", "a": "1/(mm*s)", "b": "1/s",
    "c": "mm/s"}`` (dy/dt = -c - b*y - a*y**2)."""
    unit = signal_unit or "U"
    factor = f"({unit})" if any(mark in unit for mark in "/* ") else unit
    return {"y0": unit, "a": f"1/({factor}*{per})", "b": f"1/{per}", "c": f"{factor}/{per}"}


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
