"""What the figure shows of a record besides the fit: samples, turning points, names and
units (numpy only)."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import PurePath

import numpy as np

__all__ = ["RecordView", "record_view", "figure_title"]

# "Angle, Ch 1+2 (rad) Run #1" -> "Angle, Ch 1+2": the unit and the run are said elsewhere.
_UNIT_OR_RUN = re.compile(r"\s*(\([^()]*\)|\[[^\[\]]*\])|\s*Run\s*#\s*\d+\s*$", re.IGNORECASE)
_NAMELESS = re.compile(r"^column \d+$")


@dataclass(frozen=True)
class RecordView:
    """What the figure shows of the record besides the fit.

    ``t``/``x`` are the waveform samples (None for a turning-point table); ``equilibrium``
    the estimated equilibrium at each sample (same shape as ``t``) or None;
    ``turning_t``/``turning_x`` the signed extremum positions, ``turning_y`` the amplitudes;
    ``used`` marks the turning points that entered the fit (their amplitudes are
    ``fit.y``). ``unit`` is the signal's unit (None when unknown), ``time_unit`` that of
    ``t`` ("s", or "cycle" for a record against cycle number); ``period`` the period from
    the turning points' spacing (NaN if unknown).
    """

    title: str
    t: np.ndarray | None
    x: np.ndarray | None
    equilibrium: np.ndarray | None
    turning_t: np.ndarray
    turning_x: np.ndarray
    used: np.ndarray
    turning_y: np.ndarray | None = None
    quantity: str = "signal"
    unit: str | None = None
    time_unit: str = "s"
    period: float = float("nan")
    period_sigma: float = float("nan")
    whole_t: np.ndarray | None = None  # the record as read, where t/x are its free decay
    whole_x: np.ndarray | None = None
    left_out: tuple = ()  # (start, end, why) of the stretches that are not the free decay

    @property
    def time_label(self) -> str:
        return "cycle number n" if self.time_unit == "cycle" else f"time ({self.time_unit})"

    @property
    def signal_label(self) -> str:
        """The record axis: the signal's name and unit, ``position (mm)``."""
        return self.quantity + (f" ({self.unit})" if self.unit else "")

    @property
    def amplitude_label(self) -> str:
        return "amplitude" + (f" ({self.unit})" if self.unit else "")

    @property
    def unit_symbol(self) -> str:
        """The unit in compound units (1/(mm*s), 1/((cm/s)*s)); ``U`` stands for an unknown
        one."""
        if not self.unit:
            return "U"
        return f"({self.unit})" if any(c in self.unit for c in "/* ") else self.unit


def figure_title(source: str, run: str | None = None) -> str:
    """The record's file name (not its folder), with the run for one of several."""
    name = PurePath(str(source)).name or str(source)
    return f"{name}, {run}" if run else name


def _quantity(column) -> str:
    """The signal's name without its unit: ``Position (mm)`` -> ``Position``; a column
    known only by its number is the "signal"."""
    name = _UNIT_OR_RUN.sub("", str(column or "")).strip()
    return name if name and not _NAMELESS.match(name) else "signal"


def record_view(analysis, title: str | None = None, unit: str | None = None) -> RecordView:
    """What the figure shows of a fitted :class:`mcfit.analysis.Analysis`'s record.

    ``title`` defaults to the file name (with the run); ``unit`` overrides the signal's unit
    read from the header (``Position (mm)``).
    """
    record, turning = analysis.record, analysis.turning
    if record.kind == "waveform":
        t, x = record.t, record.x
        equilibrium = turning.equilibrium_at(t)
        turning_x = _turning_positions(turning, t, x)
    else:
        t = x = equilibrium = None
        turning_x = turning.y
    run = getattr(record, "run", None)
    if title is None:
        title = figure_title(record.source, run)
    unit = unit or record.signal_unit or getattr(analysis.fit, "angle_unit", None)
    time_unit = "cycle" if record.domain == "cycle" else (record.time_unit or "s")
    return RecordView(title=title, t=t, x=x, equilibrium=equilibrium,
                      turning_t=np.asarray(turning.t), turning_x=np.asarray(turning_x),
                      used=np.asarray(turning.used), turning_y=np.asarray(turning.y),
                      quantity=_quantity(record.signal_column), unit=unit or None,
                      time_unit=time_unit, period=_finite(turning.period),
                      period_sigma=_finite(turning.period_sigma),
                      whole_t=None if record.whole is None else record.whole[0],
                      whole_x=None if record.whole is None else record.whole[1],
                      left_out=tuple(record.left_out))


def _turning_positions(turning, t, x):
    """Where each turning point is drawn on the record: a used one at the equilibrium plus
    its signed amplitude (what the fit sees); a left-out one at the record's value at its
    time, since its amplitude (a half-cycle fit's magnitude over a held start, a crest in
    the noise) need not be an amplitude the signal reaches."""
    fitted = turning.equilibrium_at(turning.t) + turning.sign * turning.y
    return np.where(turning.used, fitted, np.interp(turning.t, t, x))


def _finite(value) -> float:
    value = float(value)
    return value if math.isfinite(value) else float("nan")
