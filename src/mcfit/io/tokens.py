"""Words and number forms every reading stage shares: time and cycle names, units, fields."""

from __future__ import annotations

import csv
import re

from mcfit.io.layouts import LAYOUTS


# Labels of a time column: general ones, and those of the export layouts.
_TIME_NAMES = {"time", "t", "times", "tempo", "zeit", "temps", "tiempo", "seconds", "sec",
               "timestamp", "stamp", "elapsed", "elapsed time", "time elapsed", "time_elapsed",
               "elapsed_time", "clock", "time stamp", "time_s", "epoch", "epoch time",
               "epoch_time", "unixtime", "unix time", "unix_time", "posix time",
               *(name for layout in LAYOUTS for name in layout.time_names),
               *(name for layout in LAYOUTS for name, _ in layout.time_units)}
# Time labels whose unit the program that writes them implies.
_IMPLIED_TIME_UNITS = {name: unit for layout in LAYOUTS for name, unit in layout.time_units}
_CYCLE_NAMES = {"n", "cycle", "cycles", "cycle number", "swing", "swings", "period number",
                "peak", "peak number", "k", "index"}
_NUMBER = re.compile(r"^[+-]?(\d+([.,]\d*)?|[.,]\d+)([eE][+-]?\d+)?$")
# Time units a header may name, in seconds (the report gives coefficients per second).
_SECONDS_PER_UNIT = {
    "s": 1.0, "sec": 1.0, "secs": 1.0, "second": 1.0, "seconds": 1.0,
    "ms": 1e-3, "msec": 1e-3, "us": 1e-6, "usec": 1e-6, "ns": 1e-9,
    "min": 60.0, "mins": 60.0, "minute": 60.0, "minutes": 60.0,
    "h": 3600.0, "hr": 3600.0, "hrs": 3600.0, "hour": 3600.0, "hours": 3600.0,
}
_COMMA_DECIMAL = re.compile(r"^[+-]?\d*,\d+([eE][+-]?\d+)?$")
_UNIT = re.compile(r"^(.*?)\s*[\(\[]\s*([^\)\]]*)\s*[\)\]]\s*$")


def _split(line, sep):
    if sep is None:
        return line.split()
    if '"' in line and len(sep) == 1:  # a quoted field may hold the separator
        fields = next(csv.reader([line], delimiter=sep, skipinitialspace=True))
    else:
        fields = line.split(sep)
    return [f.strip().strip('"').strip("'").strip() for f in fields]


def _is_number(token):
    return bool(_NUMBER.match(token.strip())) or token.strip().lower() in ("nan", "inf", "-inf")


_NUMBER_TOKEN = re.compile(r"^[+-]?(\d+([.,]\d*)?|[.,]\d+)([eEdD][+-]?\d+)?$")
_SPECIAL_TOKENS = {"nan", "inf", "-inf", "+inf", "na", "n/a", "null", "none", "-nan"}
_FORTRAN_EXPONENT = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)[dD][+-]?\d+$")
# Clock times: "16:04:31.273", "4:31.2" (minutes), ISO dates with a time.
_CLOCK = re.compile(r"^(\d{1,2}:)?\d{1,2}:\d{2}([.,]\d+)?$")
_ISO_DATE_TIME = re.compile(r"^\d{4}-\d{2}-\d{2}[T ]\d{1,2}:\d{2}(:\d{2}([.,]\d+)?)?"
                            r"(Z|[+-]\d{2}:?\d{2})?$")
# A date alone, as a logger writes it in a column before the time of day.
_DATE = re.compile(r"^\d{4}([-/.])\d{2}\1\d{2}$")
# Rows as data: at most this many rows, each at least this many values long.
_MAX_ROWS_AS_DATA = 4
_KNOWN_UNITS = set(_SECONDS_PER_UNIT) | {
    "m", "mm", "cm", "km", "um", "v", "mv", "uv", "a", "ma", "rad", "mrad", "deg", "°", "n",
    "mn", "g", "kg", "hz", "m/s", "m/s^2", "m/s²", "cm/s", "mm/s", "rad/s", "deg/s", "°/s",
    "counts", "pa", "kpa", "%"}


def _count(n, noun):
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


_INNER_UNIT = re.compile(r"^(.*?)\s*[\(\[]\s*([^\)\]]*?)\s*[\)\]]\s*(.*)$")


def _base_name(label):
    """'Time (s)' -> ('time', 's'); 'angle' -> ('angle', None);
    'Position (mm) Run #1' -> ('position run #1', 'mm')."""
    match = _UNIT.match(label.strip())
    if match and match.group(1):
        return match.group(1).strip().lower(), match.group(2).strip() or None
    match = _INNER_UNIT.match(label.strip())
    if match and match.group(1) and match.group(2).lower() in _KNOWN_UNITS:
        return (f"{match.group(1)} {match.group(3)}".strip().lower(),
                match.group(2).strip())
    return label.strip().lower(), None


def _time_unit(label):
    """The unit of a time column: as its header names it, or as its name implies."""
    base, unit = _base_name(label)
    return unit if unit is not None else _IMPLIED_TIME_UNITS.get(base)


_RUN_SUFFIX = re.compile(r"\s*\brun\s*#?\s*\d+$")


def _is_time_name(label):
    """Whether a column label names the time ('Time (s)', 'Time (s) Run #1', 'X_Value')."""
    base = _base_name(label)[0]
    return base in _TIME_NAMES or _RUN_SUFFIX.sub("", base) in _TIME_NAMES


def _shown(value):
    """A cell's text for a one-line message: a quoted field may span lines."""
    text = str(value)
    text = text.replace("\r\n", "\n").replace("\r", "\n").replace("\n", "\\n")
    return text if len(text) <= 60 else text[:57] + "..."
