"""The figure's look: line styles that stay apart in black and white, legends outside the
data, axis ranges from the data and the selected fit, readable logarithmic ticks."""

from __future__ import annotations

import math

import numpy as np
from matplotlib import ticker

__all__ = ["DATA", "LEFT_OUT", "RAW", "BINNED", "SELECTED", "TOTAL", "REGIME_STYLE",
           "legend_outside", "span_of", "padded", "readable_log_axis", "off_scale_note",
           "clipped"]

# Okabe-Ito colours (safe for colour-blind readers), each line with its own dash pattern
# and each point set with its own marker, so that a grey print still tells them apart.
DATA = dict(fmt="o", ms=3.5, color="#0072B2", mfc="#0072B2", elinewidth=0.8)
LEFT_OUT = dict(ls="none", marker="x", ms=4.5, color="0.2")
RAW = dict(ls="none", marker=".", ms=3.5, color="0.72", zorder=1)
BINNED = dict(fmt="s", ms=5, color="k", mfc="white", mew=1.2, elinewidth=1.1, capsize=2.5,
              zorder=4)
SELECTED = dict(color="#D55E00", lw=1.9, ls="-", zorder=3)
TOTAL = dict(color="k", lw=1.9, ls="-", zorder=3)
# fluid / hysteretic / Coulomb: (colour, dash pattern)
REGIME_STYLE = {"a": ("#E69F00", (0, (6, 2))), "b": ("#009E73", (0, (6, 2, 1.5, 2))),
                "c": ("#CC79A7", (0, (1.5, 1.5)))}
REGIME_OF_PART = {"fluid": "a", "hysteretic": "b", "coulomb": "c"}


def legend_outside(axes, **options) -> None:
    """The legend to the right of the axes, never over the data; only for labelled
    artists (curves left out as off-scale carry no label)."""
    handles, labels = axes.get_legend_handles_labels()
    if not handles:
        return
    axes.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0),
                borderaxespad=0.0, fontsize=8, frameon=False, handlelength=2.8, **options)


def span_of(*arrays, positive=False):
    """(low, high) of the finite values of ``arrays`` (only > 0 with ``positive``), or
    None when there are none."""
    values = np.concatenate([np.ravel(np.asarray(a, dtype=float)) for a in arrays
                             if a is not None] or [np.empty(0)])
    values = values[np.isfinite(values)]
    if positive:
        values = values[values > 0]
    if not values.size:
        return None
    return float(values.min()), float(values.max())


def padded(span, log=False, fraction=0.06):
    """``span`` widened by ``fraction`` of its width (of its decades on a log axis)."""
    low, high = span
    if log:
        width = math.log10(high / low) if high > low else 0.2
        factor = 10.0 ** (fraction * max(width, 0.2))
        return low / factor, high * factor
    width = high - low if high > low else max(abs(high), 1e-12) * 0.2
    return low - fraction * width, high + fraction * width


def readable_log_axis(axis, low, high) -> None:
    """Plain-number ticks (0.2, 0.5, 1) on a logarithmic ``axis`` showing ``low`` to
    ``high``: more of them within a decade, no 2x10^-1 labels, no crowded minor labels."""
    decades = math.log10(high / low) if high > low > 0 else 0.0
    if decades < 0.6:
        axis.set_major_locator(ticker.MaxNLocator(nbins=5, steps=[1, 2, 2.5, 5, 10]))
    elif decades < 1.0:
        axis.set_major_locator(ticker.LogLocator(base=10, subs=(1.0, 2.0, 3.0, 5.0)))
    elif decades < 1.8:
        axis.set_major_locator(ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    elif decades < 2.5:
        axis.set_major_locator(ticker.LogLocator(base=10, subs=(1.0, 3.0)))
    else:
        axis.set_major_locator(ticker.LogLocator(base=10, numticks=8))
    axis.set_major_formatter(ticker.FuncFormatter(lambda value, _: f"{value:g}"))
    axis.set_minor_formatter(ticker.NullFormatter())


def clipped(values, low, high):
    """``values`` with NaN outside [low, high] but for the first point beyond each edge
    (so that the line runs on to the frame, where the axes clip it): a comparison curve
    then never pulls the axis with it, whatever draws it later."""
    values = np.array(values, dtype=float)
    inside = (values >= low) & (values <= high)
    near = inside.copy()
    near[1:] |= inside[:-1]
    near[:-1] |= inside[1:]
    values[~near] = np.nan
    return values


def visible(values, low, high) -> bool:
    """Whether any finite value of ``values`` lies within [low, high]."""
    values = np.asarray(values, dtype=float)
    return bool(np.any(np.isfinite(values) & (values >= low) & (values <= high)))


def off_scale_note(axes, count: int) -> None:
    """Say how many measured points lie outside the range shown (they are not drawn)."""
    if count:
        axes.text(0.99, 0.01, f"{count} point{'s' if count > 1 else ''} off scale",
                  ha="right", va="bottom", fontsize=7, color="0.35",
                  transform=axes.transAxes)
