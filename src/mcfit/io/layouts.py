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
    run_label: re.Pattern | None = None
    recognise: Callable[[list[str]], bool] | None = None
    rewrite: Callable[[list[str]], tuple[list[str], list[str]]] | None = None


# Lines of text a layout's ``recognise`` sees.
RECOGNISE_LINES = 20

LAYOUTS = (
    ExportLayout("PASCO Capstone runs side by side", sample="capstone_runs.csv",
                 run_label=re.compile(r"\brun\s*#?\s*(\d+)\s*$", re.IGNORECASE)),
    ExportLayout("LabVIEW measurement file (.lvm)", time_names=("x_value",)),
    ExportLayout("Vernier Logger Pro", time_names=("latest: time",)),
    ExportLayout("phyphox"),
    ExportLayout("Tracker (Open Source Physics)"),
    ExportLayout("serial logger (Arduino and others)"),
)


def recognised_layout(lines):
    """The first entry of :data:`LAYOUTS` whose ``recognise`` accepts ``lines``, or None."""
    head = lines[:RECOGNISE_LINES]
    return next((layout for layout in LAYOUTS
                 if layout.recognise is not None and layout.recognise(head)), None)
