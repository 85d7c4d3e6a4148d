"""Time columns that are clocks: Unix-epoch seconds or milliseconds, date-time text.

A logger's clock (``1406730000.123``) is read as it is and re-based to the record's first
sample, ``t = clock - clock[0]``, so that times, ``start`` and ``end`` are seconds into
the record; the clock reading at t = 0 is kept as the record's ``time_origin``. Elapsed
times that merely do not start at 0 are left as they are.
"""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np

# First readings of a Unix-epoch clock: 1979 to 2103, in seconds and in milliseconds.
_EPOCH_SECONDS = (3.0e8, 4.2e9)
_EPOCH_MILLISECONDS = (3.0e11, 4.2e12)


def epoch_scale(values, unit=None):
    """1.0 for Unix-epoch seconds, 1e-3 for milliseconds, None for anything else: by the
    range of the first finite value (and the unit a header names, ``s`` or ``ms``)."""
    finite = values[np.isfinite(values)] if values.size else values
    if finite.size < 2:
        return None
    first = float(finite[0])
    unit = (unit or "").strip().lower()
    if unit in ("", "s", "sec", "secs", "second", "seconds") and (
            _EPOCH_SECONDS[0] <= first <= _EPOCH_SECONDS[1]):
        return 1.0
    if unit in ("", "ms", "msec") and _EPOCH_MILLISECONDS[0] <= first <= _EPOCH_MILLISECONDS[1]:
        return 1e-3
    return None


def _utc_text(seconds):
    stamp = datetime(1970, 1, 1, tzinfo=timezone.utc) + timedelta(seconds=seconds)
    return stamp.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"


def rebased_epoch(t, time_unit, column, notes):
    """(t, time unit, origin): epoch times as seconds from the first sample, with the
    clock's origin, or ``t`` unchanged and None when the column is no epoch clock."""
    scale = epoch_scale(t, time_unit)
    if scale is None or t.size == 0 or not np.isfinite(t[0]):
        return t, time_unit, None
    first = float(t[0])
    t = (t - first) * scale if scale != 1.0 else t - first
    what = "seconds" if scale == 1.0 else "milliseconds"
    utc = _utc_text(first * scale)
    notes.append(f"time column '{column}' is a clock (Unix-epoch {what}): times re-based to "
                 f"the first sample, t = 0 s at {utc} ({first:.15g})")
    origin = {"clock": f"unix epoch {what}", "value": first, "utc": utc, "column": column}
    return t, "s", origin


def text_clock_origin(first, column):
    """The origin of a clock-time text column whose first reading is ``first``
    (``"2014-07-30 12:00:00.123"``, ``"16:04:31.273"``): read as seconds after it."""
    from mcfit.io.tokens import _ISO_DATE_TIME
    utc = None
    if _ISO_DATE_TIME.match(first):
        try:
            stamp = datetime.fromisoformat(first.replace(",", ".").replace("Z", "+00:00"))
        except ValueError:
            stamp = None
        if stamp is not None and stamp.tzinfo is not None:
            utc = _utc_text((stamp - datetime(1970, 1, 1, tzinfo=timezone.utc))
                            .total_seconds())
        clock = "date and time"
    else:
        clock = "time of day"
    return {"clock": clock, "value": first, "utc": utc, "column": column}
