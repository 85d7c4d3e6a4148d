"""Turning points given directly, as a table of amplitudes or signed extrema."""

from __future__ import annotations

import numpy as np

from mcfit.errors import RecordError
from mcfit.turning.checks import _check_count, _check_range, _cut_at_rise
from mcfit.turning.common import _median, _robust_sigma
from mcfit.turning.equilibrium import _table_equilibrium
from mcfit.turning.result import MIN_TURNING_POINTS, TurningPoints, _frozen


def turning_points_from_table(t, values, *, domain="time", source="record"):
    """Turning points given directly: amplitudes (or signed extrema) against time or cycle n.

    Parameters
    ----------
    t : ndarray, shape (k,)
        Times or cycle numbers, distinct (sorted here).
    values : ndarray, shape (k,)
        Amplitudes (all >= 0 or all <= 0) or signed extrema about an equilibrium, which is
        then estimated from the alternation of maxima and minima.
    domain : {"time", "cycle"}
    source : str

    Returns
    -------
    TurningPoints
        ``sigma`` is one scatter estimate for all points (from second differences);
        ``period`` is 1 in the cycle domain, twice the median spacing for signed extrema, and
        NaN for unsigned amplitudes in time (one or two per period cannot be told apart).
    """
    t = np.asarray(t, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    if t.ndim != 1 or t.shape != values.shape:
        raise ValueError("t and values must be 1-D arrays of the same length")
    finite = np.isfinite(t) & np.isfinite(values)
    t, values = t[finite], values[finite]
    _check_range(t, values, source)
    if t.size < MIN_TURNING_POINTS:
        raise RecordError(f"only {t.size} turning points in {source} (need "
                          f"{MIN_TURNING_POINTS}). Use a longer table.")
    order = np.argsort(t, kind="stable")
    t, values = t[order], values[order]
    if np.any(np.diff(t) == 0):
        raise RecordError(f"the turning-point table {source} repeats a time. Remove the "
                          "duplicate rows.")
    notes = []
    equilibrium = 0.0
    if np.all(values >= 0) or np.all(values <= 0):
        signs = np.zeros(values.size, dtype=np.int8)
        y = np.abs(values)
        if np.all(values <= 0):
            notes.append("negative amplitudes taken as magnitudes")
    else:
        equilibrium = _table_equilibrium(values)
        signs = np.where(values >= equilibrium, 1, -1).astype(np.int8)
        y = np.abs(values - equilibrium)
        notes.append(f"signed extrema: amplitudes taken about the equilibrium {equilibrium:.4g}")
    d2 = np.diff(y, 2)
    scatter = float(_robust_sigma(d2) / np.sqrt(6.0)) if d2.size >= 3 else float("nan")
    sigma = np.full(y.size, scatter)
    used = y > 0
    reasons = np.where(used, "", "zero amplitude").astype(object)
    release, rise_notes, warnings = _cut_at_rise(
        t, y, np.where(np.isfinite(sigma), sigma, 0.0), reasons, source)
    notes += rise_notes
    used = reasons == ""
    _check_count(y, reasons, source)
    spacing = float(_median(np.diff(t)))
    if domain == "cycle":
        period = 1.0
    elif np.any(signs != 0):
        period = 2 * spacing
    else:
        period = float("nan")
        notes.append(f"turning points are {spacing:.4g} apart; whether that is a period or a "
                     "half-period is unknown, so no period is given")
    return TurningPoints(
        t=_frozen(t), y=_frozen(y), sigma=_frozen(sigma), sign=_frozen(signs),
        used=_frozen(used), excluded_reason=tuple(str(r) for r in reasons), period=period,
        equilibrium=float(equilibrium), equilibrium_drift=0.0, domain=domain,
        notes=tuple(notes), warnings=tuple(warnings), release_time=release,
        t_start=float(t[0]))
