"""The figure's look: line styles that stay apart in black and white, axis ranges from the
data and the selected fit, readable logarithmic ticks, notes of what is off scale."""

from __future__ import annotations

import math

import numpy as np
from matplotlib import ticker

__all__ = ["DATA", "LEFT_OUT", "RAW", "BINNED", "SELECTED", "TOTAL", "REGIME_STYLE",
           "span_of", "padded", "readable_log_axis", "off_scale_note",
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
# The gid of a panel's note of what is off scale.
_NOTE = "off-scale"


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


def off_scale_note(axes, count: int = 0, curves=()) -> None:
    """Say what lies outside the range shown and is not drawn: ``count`` measured points,
    and ``curves``, (label, values) pairs, each with the range of its finite values. A
    second call adds its lines to the note."""
    lines = [f"{count} point{'s' if count > 1 else ''} off scale"] if count else []
    for label, values in curves:
        values = np.asarray(values, dtype=float)
        values = values[np.isfinite(values)]
        span = ""
        if values.size:
            low, high = float(values.min()), float(values.max())
            span = (f" ({_three_digits(low)})" if low == high else
                    f" ({_three_digits(low)} to {_three_digits(high)})")
        lines.append(f"{label} off scale{span}")
    if not lines:
        return
    note = next((t for t in axes.texts if t.get_gid() == _NOTE), None)
    if note is not None:
        note.set_text("\n".join([note.get_text()] + lines))
        return
    axes.text(0.99, 0.01, "\n".join(lines), ha="right", va="bottom", fontsize=7,
              color="0.35", transform=axes.transAxes, gid=_NOTE)


def _three_digits(value) -> str:
    """Three significant digits without an exponent where a plain number is short:
    2690, 0.0123, 1.23e+07."""
    return f"{float(f'{value:.3g}'):g}"
