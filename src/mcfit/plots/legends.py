"""Where a panel's legend goes: inside the axes on the spot the drawn lines, points, bands
and notes leave emptiest, or under the axes when no spot is empty, so that a legend never
costs the plot its width nor hides its data."""

from __future__ import annotations

import warnings

import numpy as np
from matplotlib.collections import Collection
from matplotlib.transforms import offset_copy

__all__ = ["place_legend", "place_legends", "LEGEND_STYLE"]

LEGEND_STYLE = dict(fontsize=8, handlelength=2.8, framealpha=0.85, borderaxespad=0.4)
# Inside spots, the corners first: among equally empty spots the first is taken.
_SPOTS = ("upper right", "upper left", "lower left", "lower right", "upper center",
          "lower center", "center right", "center left")
# A spot is empty when the drawn things it covers add up to less than this (each counted
# as the fraction of its length, or of its points, under the legend).
_EMPTY = 0.002
# Points along each line and patch outline, and the most vertices taken of one line.
_ALONG, _VERTICES = 400, 5000
# Padding around the legend (a fraction of its size) when testing a spot: a margin.
_MARGIN = 0.06


def place_legend(axes, below=True) -> bool:
    """The legend of ``axes``' labelled artists on its emptiest inside spot, or under the
    axes (below the tick labels and the axis label) when none is empty and ``below``; no
    legend when nothing is labelled. Place it after the data, ranges, scales and labels
    are set. Returns whether the legend went under the axes."""
    handles, labels = axes.get_legend_handles_labels()
    if axes.get_legend() is not None:
        axes.get_legend().remove()
    if not handles:
        return False
    legend = axes.legend(handles, labels, loc="upper right", **LEGEND_STYLE)
    frame = axes.get_window_extent()
    if not (frame.width > 0 and frame.height > 0):  # axes squeezed to nothing
        return False
    box = legend.get_window_extent()
    size = ((1 + _MARGIN) * box.width / frame.width, (1 + _MARGIN) * box.height / frame.height)
    pad = LEGEND_STYLE["borderaxespad"] * LEGEND_STYLE["fontsize"] * axes.figure.dpi / 72
    pads = (pad / frame.width, pad / frame.height)
    ink = _ink(axes)
    covered = {spot: _covered(ink, _spot_box(spot, size, pads)) for spot in _SPOTS}
    spot = min(_SPOTS, key=covered.get)
    legend.remove()
    if not below or (size[0] < 1 and size[1] < 1 and covered[spot] < _EMPTY):
        axes.legend(handles, labels, loc=spot, **LEGEND_STYLE)
        return False
    _legend_below(axes, handles, labels)
    return True


def place_legends(figure) -> None:
    """:func:`place_legend` again on every axes with a legend, with the figure laid out
    (the panels placed theirs before the layout fixed their sizes); all inside if the
    legends under the axes leave a small figure no room for its panels."""
    engine = figure.get_layout_engine()
    if engine is None:
        return
    engine.execute(figure)  # the layout only: no line of the record is drawn
    with_legend = [axes for axes in figure.axes if axes.get_legend() is not None]
    if not any([place_legend(axes) for axes in with_legend]):
        return
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        engine.execute(figure)
    if any("collapsed" in str(warning.message) for warning in caught):
        for axes in with_legend:
            place_legend(axes, below=False)


def _legend_below(axes, handles, labels):
    """Under the axes, below what is drawn beneath them (tick labels, axis label), in
    columns so that it stays about as wide as the axes."""
    frame = axes.get_window_extent()
    beneath = max(frame.y0 - axes.get_tightbbox().y0, 0.0) * 72 / axes.figure.dpi
    anchor = offset_copy(axes.transAxes, fig=axes.figure, y=-beneath - 2, units="points")
    axes.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0),
                bbox_transform=anchor, ncols=min(len(handles), 2),
                **{**LEGEND_STYLE, "borderaxespad": 0.0})


def _spot_box(spot, size, pads):
    """(x0, y0, x1, y1) of a legend of ``size`` at ``spot``, in fractions of the axes."""
    (width, height), (pad_x, pad_y) = size, pads
    vertical, _, horizontal = spot.partition(" ")
    x0 = {"left": pad_x, "right": 1 - pad_x - width, "center": 0.5 - width / 2}[horizontal]
    y0 = {"lower": pad_y, "upper": 1 - pad_y - height, "center": 0.5 - height / 2}[vertical]
    return x0, y0, x0 + width, y0 + height


def _covered(ink, box):
    """The drawn things under ``box``: each counted as the fraction of its points there."""
    (x, y), weight = ink
    x0, y0, x1, y1 = box
    return float(np.sum(weight[(x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)]))


def _ink(axes):
    """What is drawn in ``axes``, as points in fractions of the axes, each weighted by
    1/(points of its artist): each line's vertices and points along it, each band's
    outline, each note's box. Returns ((x, y), weight)."""
    to_axes = axes.transAxes.inverted()
    found = []
    for line in axes.lines:
        if line.get_visible():
            xy = line.get_xydata()
            xy = xy[:: xy.shape[0] // _VERTICES + 1]  # a long record: a sample suffices
            xy = to_axes.transform(line.get_transform().transform(xy))
            found.append(_points(xy, line.get_linestyle() != "None"))
    for artist in list(axes.collections) + list(axes.patches):
        if not artist.get_visible():
            continue
        paths = artist.get_paths() if isinstance(artist, Collection) else [artist.get_path()]
        if not paths:
            continue
        # One outline (a band) is followed along; many paths (error bars) by their ends.
        xy = np.concatenate([path.vertices for path in paths])
        xy = to_axes.transform(artist.get_transform().transform(xy))
        found.append(_points(xy, len(paths) == 1))
    for text in axes.texts:
        if text.get_visible() and text.get_text():
            x0, y0, x1, y1 = to_axes.transform(text.get_window_extent()).ravel()
            grid = np.mgrid[x0:x1:8j, y0:y1:8j].reshape(2, -1).T
            found.append(grid)
    found = [points for points in found if points.size] or [np.empty((0, 2))]
    weight = np.concatenate([np.full(len(points), 1.0 / max(len(points), 1))
                             for points in found])
    return np.concatenate(found).T, weight


def _points(xy, joined):
    """Finite vertices of ``xy`` (at most _VERTICES of them) and, when ``joined``, points
    evenly spaced along the polyline through them."""
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    if not joined or xy.shape[0] < 2:
        return xy
    length = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    if not length[-1] > 0:
        return xy
    along = np.linspace(0.0, length[-1], _ALONG)
    return np.vstack([xy, np.column_stack([np.interp(along, length, xy[:, 0]),
                                           np.interp(along, length, xy[:, 1])])])
