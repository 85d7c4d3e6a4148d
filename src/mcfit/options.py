"""What the library and the command line share about options: the choices and the checks,
once, and how an option named in a message is spelled on the command line. Nothing
numerical is imported, so that ``mcfit --help`` stays fast.

The library names an option in its messages and notes in Python spelling between
backticks: ``Use `signal_col`.``, ``give the sample rate with `rate=HZ```. A Python user
reads that as it is; the command line turns it into ``--signal-col`` and ``--rate HZ``
(:func:`for_command_line`).
"""

from __future__ import annotations

import math
import os
import re

from mcfit.errors import UsageError

__all__ = ["KINDS", "DOMAINS", "CRITERIA", "FIT_METHODS", "SIMULATE_METHODS", "FORMATS",
           "BENCH_SECTIONS", "PANELS", "DEFAULT_PANELS", "PLOT_SUFFIXES", "RATE_RANGE",
           "SAMPLES_PER_CYCLE", "FLAGS", "for_command_line", "parse_model",
           "check_read_options", "check_fit_options", "check_plot_name",
           "parse_panels", "parse_figsize"]

KINDS = ("waveform", "turning-points")
DOMAINS = ("time", "cycle")
CRITERIA = ("aicc", "bic")
FIT_METHODS = ("auto", "turning-points", "waveform")
SIMULATE_METHODS = ("auto", "averaged", "cromer-euler", "symplectic", "accurate")
FORMATS = ("text", "json", "csv")
BENCH_SECTIONS = ("integrators", "fitting", "verdicts", "methods", "cycles", "edges",
                  "throughput", "waveform")
# The report figure's panels: the record, the amplitudes with the fits (and residuals),
# Q(t), the damping rate, Q and the period (backbone) against amplitude.
PANELS = ("record", "amplitude", "q", "rate", "qamp", "backbone")
DEFAULT_PANELS = ("record", "amplitude", "q", "rate")
PLOT_SUFFIXES = (".png", ".pdf", ".svg")
# Sample rates in Hz a record can have: one sample in 11.6 days to a terahertz. Beyond
# them the sample times underflow or overflow on the way (1/rate, n/rate).
RATE_RANGE = (1e-6, 1e12)
# Samples per cycle from which the turning points are found (mcfit.turning.common's).
SAMPLES_PER_CYCLE = 8
_TERMS = "abc"

# Python keyword -> command-line flag.
FLAGS = {
    "time_col": "--time-col", "signal_col": "--signal-col", "sheet": "--sheet",
    "rate": "--rate", "kind": "--input", "domain": "--domain", "run": "--run",
    "angle_from": "--angle-from", "criterion": "--criterion", "model": "--model",
    "bootstrap": "--bootstrap", "seed": "--seed", "method": "--method",
    "pendulum": "--pendulum", "degrees": "--degrees", "start": "--start", "end": "--end",
    "unit": "--unit", "title": "--title", "panels": "--panels", "figsize": "--figsize",
    "dpi": "--dpi", "jobs": "--jobs", "dask": "--dask",
}
_MARKED = re.compile(r"`([a-z_]+)(?:=([^`\s]*))?`")


def for_command_line(text: str) -> str:
    """``text`` with each option marked in Python spelling given as its flag:
    ```signal_col``` -> ``--signal-col``, ```rate=HZ``` -> ``--rate HZ``."""
    def flag(match):
        name, value = match.groups()
        if name not in FLAGS:
            return match.group(0)
        return FLAGS[name] if value is None else f"{FLAGS[name]} {value}"

    return _MARKED.sub(flag, text)


def parse_model(text) -> str:
    """A model name from what a person wrote: letters from "abc" in any order and case
    ("BA" -> "ab"), ``"none"`` or ``"power"``.

    Raises :class:`mcfit.errors.UsageError` (``option="model"``) for anything else, e.g.
    ``"bacon"`` or a repeated letter.
    """
    word = str(text).strip().lower()
    if word in ("none", "power"):
        return word
    if word and set(word) <= set(_TERMS) and len(set(word)) == len(word):
        return "".join(k for k in _TERMS if k in word)
    raise UsageError(f"`model` {str(text)!r} is not a set of damping terms: use letters from "
                     "abc (a fluid, b hysteretic, c Coulomb; e.g. ab), none or power.",
                     option="model")


def _check_choice(name, value, choices):
    if value is not None and value not in choices:
        raise UsageError(f"`{name}` must be one of {', '.join(choices)}, not {value!r}.",
                         option=name)


def check_read_options(*, kind=None, domain=None, rate=None, time_col=None, signal_col=None,
                       angle_from=None) -> None:
    """Refuse reading options that are unknown or contradict each other."""
    _check_choice("kind", kind, KINDS)
    _check_choice("domain", domain, DOMAINS)
    if rate is not None:
        _check_rate(rate)
    if rate is not None and time_col is not None:
        raise UsageError("give either `time_col` or `rate` (time from the sample index), "
                         "not both.", option="rate")
    if angle_from is not None and signal_col is not None:
        raise UsageError("give `angle_from` or `signal_col`, not both: the angle is the "
                         "signal.", option="angle_from")
    if angle_from is not None and len(angle_from) != 2:
        raise UsageError("`angle_from` takes two columns, the bob's x and y.",
                         option="angle_from")


def _check_rate(rate):
    try:
        rate = float(rate)
    except (TypeError, ValueError):
        raise UsageError(f"`rate` must be a number of samples per second, not {rate!r}.",
                         option="rate") from None
    if not (math.isfinite(rate) and rate > 0):
        raise UsageError(f"`rate` must be a positive number of samples per second, not "
                         f"{rate:g}.", option="rate")
    low, high = RATE_RANGE
    if not low <= rate <= high:
        raise UsageError(f"`rate={rate:g}` is not a sample rate a record has; give the "
                         f"samples per second, from {low:g} to {high:g}.", option="rate")


def check_fit_options(*, criterion="aicc", model=None, bootstrap=0, method="auto",
                      pendulum=False, start=None, end=None) -> str | None:
    """The model as :func:`parse_model` gives it, after refusing fit options that are
    unknown or contradict each other."""
    _check_choice("criterion", criterion, CRITERIA)
    _check_choice("method", method, FIT_METHODS)
    model = None if model is None else parse_model(model)
    if pendulum and bootstrap:
        raise UsageError("`bootstrap` is not available with `pendulum` yet.",
                         option="bootstrap")
    if pendulum and method != "auto":
        raise UsageError("`method` is not available with `pendulum`: the pendulum's fit "
                         "chooses between its law on the turning points and its equation of "
                         "motion itself.", option="method")
    if pendulum and model == "power":
        raise UsageError("`model=power` is not available with `pendulum`.", option="model")
    for name, value in (("start", start), ("end", end)):
        if value is not None and not math.isfinite(value):
            raise UsageError(f"`{name}` must be a finite time (or cycle number), not "
                             f"{value}.", option=name)
    if start is not None and end is not None and not start < end:
        raise UsageError(f"`start={start:g}` must come before `end={end:g}`.",
                         option="start")
    return model


def parse_panels(panels) -> tuple:
    """The report figure's panels from names or one comma-separated string
    (``"amplitude,q,rate"``), in the order given; :class:`mcfit.errors.UsageError`
    (``option="panels"``) for an unknown, repeated or missing name."""
    if isinstance(panels, str):
        panels = [name.strip().lower() for name in panels.split(",") if name.strip()]
    panels = tuple(panels)
    if not panels or len(set(panels)) != len(panels) or not set(panels) <= set(PANELS):
        raise UsageError(f"`panels` {','.join(map(str, panels))!r}: give some of "
                         f"{', '.join(PANELS)}, each once, e.g. amplitude,q,rate.",
                         option="panels")
    return panels


def parse_figsize(size) -> tuple:
    """(width, height) in inches from two numbers or ``"W,H"``; both must be > 0 and
    at most 100. :class:`mcfit.errors.UsageError` (``option="figsize"``) otherwise."""
    try:
        parts = size.split(",") if isinstance(size, str) else list(size)
        width, height = (float(part) for part in parts)
    except (TypeError, ValueError):
        width = height = float("nan")
    if not (0 < width <= 100 and 0 < height <= 100):
        raise UsageError(f"`figsize` {size!r}: give the width and height in inches as W,H, "
                         "e.g. 12,9.", option="figsize")
    return width, height


def check_plot_name(path) -> None:
    """Refuse a figure file name whose suffix is not a format we write."""
    stem, suffix = os.path.splitext(os.path.basename(str(path)))
    if not stem or suffix.lower() not in PLOT_SUFFIXES:
        raise UsageError(f"plot file {path}: the name must end in .png, .pdf or .svg.",
                         option="plot")
