"""What the library and the command line share about options: the choices, once, and how
an option named in a message is spelled on the command line. No imports beyond ``re``, so
that ``mcfit --help`` stays fast.

The library names an option in its messages and notes in Python spelling between
backticks: ``Use `signal_col`.``, ``give the sample rate with `rate=HZ```. A Python user
reads that as it is; the command line turns it into ``--signal-col`` and ``--rate HZ``
(:func:`for_command_line`).
"""

from __future__ import annotations

import re

__all__ = ["KINDS", "DOMAINS", "CRITERIA", "FIT_METHODS", "SIMULATE_METHODS", "FORMATS",
           "BENCH_SECTIONS", "FLAGS", "for_command_line"]

KINDS = ("waveform", "turning-points")
DOMAINS = ("time", "cycle")
CRITERIA = ("aicc", "bic")
FIT_METHODS = ("auto", "turning-points", "waveform")
SIMULATE_METHODS = ("auto", "averaged", "cromer-euler", "symplectic", "accurate")
FORMATS = ("text", "json", "csv")
BENCH_SECTIONS = ("integrators", "fitting", "verdicts", "methods", "throughput")

# Python keyword -> command-line flag.
FLAGS = {
    "time_col": "--time-col", "signal_col": "--signal-col", "sheet": "--sheet",
    "rate": "--rate", "input": "--input", "domain": "--domain", "run": "--run",
    "angle_from": "--angle-from", "criterion": "--criterion", "model": "--model",
    "bootstrap": "--bootstrap", "seed": "--seed", "method": "--method",
    "pendulum": "--pendulum", "degrees": "--degrees", "start": "--start", "end": "--end",
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
