"""The averaged law's predicted bias (mcfit.model_error): the chain that repeats a record's
turning-point search and fit on its noise-free waveform."""

from __future__ import annotations

from pathlib import Path

import pytest

import mcfit.turning
from mcfit.analysis import analyse_record
from mcfit.model_error import LIMIT, averaged_law_bias
from mcfit.records import read_record
from mcfit.turning import refine

CAPSTONE = Path(__file__).parents[1] / "sample_data" / "capstone_runs.csv"


def _counting_window_passes(monkeypatch):
    """A list that grows by one for every pass of half-cycle fits of the refinement."""
    passes = []
    fit_windows = refine._fit_windows

    def counted(*args, **kwargs):
        passes.append(1)
        return fit_windows(*args, **kwargs)

    monkeypatch.setattr(refine, "_fit_windows", counted)
    return passes


@pytest.mark.parametrize("run", [3, 4, 5])
def test_the_chain_searches_as_the_record_was_searched(run, monkeypatch):
    """Capstone runs 3 to 5 sit near the limit (0.26 to 0.31 standard errors), where the
    chain decides. Given the record's period and noise, the search of the noise-free
    waveform stops refining where the record's did, in fewer passes than a search that
    refines the clean crests to the last digit, and predicts the same bias within 0.01
    standard errors."""
    record = read_record(str(CAPSTONE), run=run)
    analysis = analyse_record(record, method="turning-points")
    passes = _counting_window_passes(monkeypatch)
    hinted = averaged_law_bias(record.t, analysis.turning, analysis.fit)
    hinted_passes = len(passes)
    search = mcfit.turning.find_turning_points
    monkeypatch.setattr(mcfit.turning, "find_turning_points",
                        lambda t, x, **_: search(t, x))  # the period and noise from the spectrum
    passes.clear()
    searched = averaged_law_bias(record.t, analysis.turning, analysis.fit)
    assert hinted.how == searched.how == "chain"
    assert hinted_passes < len(passes)
    assert hinted.z.keys() == searched.z.keys()
    for term, z in searched.z.items():
        assert abs(hinted.z[term] - z) < 0.01
    assert (hinted.largest > LIMIT) == (searched.largest > LIMIT)
