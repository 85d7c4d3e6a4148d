"""pandas DataFrames of results' plain data (the dicts and rows the results give), for the
Python interface; pandas is imported here only, not by the numerical core."""

from __future__ import annotations

import pandas as pd

from mcfit.report import TURNING_POINT_COLUMNS

__all__ = ["results_frame", "turning_points_frame"]


def turning_points_frame(rows) -> pd.DataFrame:
    """The turning points' rows (:meth:`mcfit.analysis.Analysis.turning_point_table`) as a
    DataFrame: t, amplitude, sigma, used, excluded_reason and envelope (NaN where none)."""
    table = pd.DataFrame(list(rows), columns=TURNING_POINT_COLUMNS)
    return table.drop(columns="source").astype({"amplitude": float, "sigma": float,
                                                "envelope": float})


def results_frame(rows, columns) -> pd.DataFrame:
    """``rows`` (dicts of plain values, None for missing) as a DataFrame with ``columns``,
    typed as a CSV reader types them: numbers as float or int, true/false as bool, NaN for
    missing."""
    frame = pd.DataFrame.from_records(list(rows), columns=list(columns))
    return frame.apply(_typed_column)


def _typed_column(column):
    values = column.dropna()
    if values.empty:
        return column.astype(float)
    if all(isinstance(v, bool) for v in values):
        return column.astype(bool) if len(values) == len(column) else _nan_for_none(column)
    if all(isinstance(v, (int, float)) for v in values):
        return pd.to_numeric(column)
    return _nan_for_none(column)


def _nan_for_none(column):
    return column.where(column.notna(), float("nan"))
