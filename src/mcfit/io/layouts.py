"""The export layouts of lab programs, each recognised in one entry of :data:`LAYOUTS`.

Most exports are a header over numbers, and the general stages read them (header blocks,
units rows and notes in :mod:`mcfit.io.tidying`, rounded or glitched times in
:mod:`mcfit.io.times`). What only one program writes is kept in its entry here: the
labels it gives the time, the suffix that numbers its runs side by side, and for a layout
the general stages cannot read, a ``recognise`` test on the first lines and a ``rewrite``
that turns the text into a header line over rows of numbers.

To teach the reader a new export: add one :class:`ExportLayout` to ``LAYOUTS`` and one
small file in that layout to ``sample_data/`` named by its ``sample``;
``tests/test_io_layouts.py`` reads every sample named here.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["ExportLayout", "LAYOUTS", "recognised_layout"]


@dataclass(frozen=True)
class ExportLayout:
    """One program's export layout.

    Attributes
    ----------
    name : str
        The program and export, as a person would name it in a note.
    sample : str or None
        A file of ``sample_data/`` written in this layout.
    time_names : tuple of str
        Column labels (lower case, unit left out) that name the time in this export.
    time_units : tuple of (str, str)
        Time labels whose unit the program implies, with that unit (Arduino's
        ``millis`` is in ms); they name the time too.
    run_label : re.Pattern or None
        A column-label suffix numbering runs side by side (group 1 is the number).
    recognise : callable or None
        ``recognise(lines) -> bool`` on the first lines of the text (at most
        :data:`RECOGNISE_LINES`), for a layout that needs ``rewrite``.
    rewrite : callable or None
        ``rewrite(lines) -> (lines, notes)``: the text as a header line over rows.
    """

    name: str
    sample: str | None = None
    time_names: tuple[str, ...] = ()
    time_units: tuple[tuple[str, str], ...] = ()
    run_label: re.Pattern | None = None
    recognise: Callable[[list[str]], bool] | None = None
    rewrite: Callable[[list[str]], tuple[list[str], list[str]]] | None = None


# Lines of text a layout's ``recognise`` sees.
RECOGNISE_LINES = 20


def _fields(line):
    """A preamble line's fields, split at its first tab, semicolon or comma."""
    sep = next((s for s in "\t;," if s in line), None)
    return [f.strip().strip('"') for f in (line.split(sep) if sep else [line])], sep


def _is_ni_waveform(lines):
    """NI LabVIEW "Write Waveforms to Spreadsheet": ``waveform``, ``t0``, ``delta t`` lines."""
    keys = [_fields(line)[0][0].lower() for line in lines if line.strip()][:3]
    return keys == ["waveform", "t0", "delta t"]


def _ni_waveform_rows(lines):
    """(lines, notes): the preamble dropped, the time column built from ``delta t``.

    The time column, when the export has one, holds date-times to the microsecond
    (``4/16/2021  11:27:25.437502``); ``delta t`` gives the same times exactly, as
    seconds after ``t0``. None when ``delta t`` is not one positive number.
    """
    starts = [i for i, line in enumerate(lines) if line.strip()]
    t0_fields, _ = _fields(lines[starts[1]])
    step_fields, sep = _fields(lines[starts[2]])
    try:
        steps = {float(f) for f in step_fields[1:] if f}
    except ValueError:
        return None
    if sep is None or len(steps) != 1 or not min(steps) > 0 or len(starts) < 5:
        return None
    step = steps.pop()
    header_at = starts[3]
    header, _ = _fields(lines[header_at])
    has_time = header[0].lower() == "time"
    out = [sep.join(["time (s)"] + header[has_time:])]
    rows = (line for line in lines[header_at + 1:] if line.strip())
    for i, line in enumerate(rows):
        values = line.split(sep, 1)[-1] if has_time else line
        out.append(f"{i * step!r}{sep}{values}")
    t0 = " ".join(t0_fields[1].split()) if len(t0_fields) > 1 else "?"
    return out, [f"NI LabVIEW waveform export: time built from its delta t, {step:g} s "
                 f"({1 / step:g} Hz), as seconds after t0 = {t0}"]


_PIPE_ALIGNMENT = re.compile(r"^\|?(\s*:?-+:?\s*\|)*\s*:?-+:?\s*\|?$")


def _is_pipe_table(lines):
    """A markdown pipe table: its first lines start and end with ``|``."""
    content = [line.strip() for line in lines if line.strip()][:3]
    return len(content) >= 2 and all(line.startswith("|") and line.endswith("|")
                                     for line in content)


def _pipe_table_rows(lines):
    """(lines, notes): the cells of a pipe table, tab-separated, alignment rows dropped."""
    out = []
    for line in lines:
        stripped = line.strip()
        if not stripped or _PIPE_ALIGNMENT.match(stripped):
            continue
        if stripped.startswith("|") and stripped.endswith("|") and len(stripped) > 1:
            stripped = stripped[1:-1]
        out.append("\t".join(cell.strip() for cell in stripped.split("|")))
    return out, ["markdown pipe table: cells read between the | marks"]


_SERIAL_MONITOR = re.compile(r"^(\d{1,2}:\d{2}:\d{2}\.\d{3}) -> ?(.*)$")


def _is_serial_monitor(lines):
    """The Arduino IDE's serial monitor with timestamps: ``16:04:31.273 -> 512``."""
    content = [line.strip() for line in lines if line.strip()][:5]
    return len(content) >= 3 and all(_SERIAL_MONITOR.match(line) for line in content)


def _serial_monitor_rows(lines):
    """(lines, notes): the clock time and the values printed after ``->`` of each line,
    tab-separated under a header (the sketch's own, if it printed one first)."""
    rows, other = [], 0
    for line in lines:
        match = _SERIAL_MONITOR.match(line.strip())
        values = re.split(r"[,;\s]+", match.group(2).strip()) if match else []
        if values and values[0]:
            rows.append((match.group(1), values))
        else:
            other += bool(line.strip())
    if not rows:
        return None
    names = rows[0][1] if not any(c.isdigit() for c in "".join(rows[0][1])) else None
    if names is not None:
        rows = rows[1:]
    width = max(len(values) for _, values in rows)
    if names is None:
        names = ["value"] if width == 1 else [f"value {k + 1}" for k in range(width)]
    out = ["\t".join(["clock"] + names)]
    out += ["\t".join([stamp] + values) for stamp, values in rows]
    notes = ["Arduino serial monitor log: the timestamps before -> read as clock times"]
    if other:
        lines_skipped = f"{other} line" + ("s" if other > 1 else "")
        notes.append(f"{lines_skipped} of the log without a timestamped value skipped")
    return out, notes


LAYOUTS = (
    ExportLayout("NI LabVIEW waveform to spreadsheet", sample="ni_waveform.csv",
                 recognise=_is_ni_waveform, rewrite=_ni_waveform_rows),
    ExportLayout("markdown pipe table", sample="pipe_table.md", recognise=_is_pipe_table,
                 rewrite=_pipe_table_rows),
    ExportLayout("PASCO Capstone runs side by side", sample="capstone_runs.csv",
                 run_label=re.compile(r"\brun\s*#?\s*(\d+)\s*$", re.IGNORECASE)),
    ExportLayout("LabVIEW measurement file (.lvm)", sample="labview.lvm",
                 time_names=("x_value",)),
    ExportLayout("Vernier Logger Pro", sample="logger_pro.txt", time_names=("latest: time",)),
    # A sensor's x, y and z columns: the one that oscillates most is the signal (columns).
    ExportLayout("phyphox (Excel .xls)", sample="phyphox_gyroscope.xls"),
    # Times printed to 3 significant figures are rebuilt as even steps (times).
    ExportLayout("Tracker (Open Source Physics)", sample="tracker.txt"),
    ExportLayout("Arduino serial monitor with timestamps", sample="serial_monitor.txt",
                 recognise=_is_serial_monitor, rewrite=_serial_monitor_rows),
    # A sketch's own time column, from millis() or micros().
    ExportLayout("serial logger (Arduino and others)", sample="serial_logger.csv",
                 time_units=(("millis", "ms"), ("micros", "us"))),
)


def recognised_layout(lines):
    """The first entry of :data:`LAYOUTS` whose ``recognise`` accepts ``lines``, or None."""
    head = lines[:RECOGNISE_LINES]
    return next((layout for layout in LAYOUTS
                 if layout.recognise is not None and layout.recognise(head)), None)
