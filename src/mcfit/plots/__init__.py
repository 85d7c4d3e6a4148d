"""Report figure: the record, the amplitudes and fits, Q(t), and, against amplitude, the
damping rate, Q and the period (backbone).

matplotlib is used through ``matplotlib.figure.Figure`` only (no pyplot, no display
needed), and imported only when this package is: the library imports it when it draws.

Modules: :mod:`~mcfit.plots.view` (what is shown of a record: names, units, title),
:mod:`~mcfit.plots.binning` (measured rates, periods and their binned medians, numpy
only), :mod:`~mcfit.plots.style` (line styles, ranges, legends, ticks),
:mod:`~mcfit.plots.against_time` and :mod:`~mcfit.plots.against_amplitude` (the panels),
:mod:`~mcfit.plots.legends` (where each legend goes),
:mod:`~mcfit.plots.figure` (the layout and the file).
"""

from __future__ import annotations

from mcfit.plots.against_amplitude import draw_backbone, draw_q_amplitude, draw_rate
from mcfit.plots.against_time import draw_amplitudes, draw_q, draw_record
from mcfit.plots.figure import (DPI, figure_metadata, figure_size, plot_record, report_figure,
                                save_figure, summary_text)
from mcfit.plots.view import RecordView, figure_title, record_view

__all__ = ["DPI", "RecordView", "record_view", "figure_title", "report_figure", "figure_size",
           "summary_text", "draw_record", "draw_amplitudes", "draw_q",
           "draw_rate", "draw_q_amplitude", "draw_backbone", "plot_record", "save_figure",
           "figure_metadata"]
