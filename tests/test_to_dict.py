"""Results serialise themselves: Record, TurningPoints and each fit result give plain data
(``to_dict``), the analysis composes them into the JSON line, and the batch passes that
data to the command line, which alone formats it."""

from __future__ import annotations

import dataclasses
import json
import math
import pickle

import numpy as np
import pytest

import mcfit
from mcfit import batch, report
from mcfit.fit import DecayFit, PendulumFit, PowerLawFit

PLAIN = (str, int, float, bool, type(None))


def _assert_plain(data, where="data"):
    """Only dicts with str keys, lists and plain scalars (no numpy types, no NaN)."""
    if isinstance(data, dict):
        for key, value in data.items():
            assert type(key) is str, f"{where}: key {key!r}"
            _assert_plain(value, f"{where}[{key!r}]")
    elif isinstance(data, list):
        for i, value in enumerate(data):
            _assert_plain(value, f"{where}[{i}]")
    else:
        assert type(data) in PLAIN, f"{where} is {type(data).__name__}"
        assert not isinstance(data, float) or math.isfinite(data), f"{where} is {data}"


@pytest.fixture(scope="module")
def record():
    return mcfit.simulate_record(a=0.1, b=0.1, c=0.01, y0=4.0, period=0.5, duration=20.0,
                                 rate=100.0, noise=0.005, rng=3)


@pytest.fixture(scope="module")
def analysis(record):
    return mcfit.analyse(record, method="turning-points", bootstrap=20, seed=1)


def _pendulum():
    t = np.arange(0.0, 60.0, 0.02)
    theta = 0.6 * np.exp(-0.03 * t) * np.cos(2 * np.pi * t)
    return mcfit.analyse(t, theta, pendulum=True, model="b", unit="rad")


def test_each_result_gives_plain_data(record, analysis):
    power = mcfit.analyse(record, model="power")
    pendulum = _pendulum()
    assert isinstance(analysis.fit, DecayFit) and isinstance(power.fit, PowerLawFit)
    assert isinstance(pendulum.fit, PendulumFit)
    for name, data in [("record", record.to_dict()),
                       ("turning points", analysis.turning.to_dict(points=True)),
                       ("decay fit", analysis.fit.to_dict()),
                       ("power law", power.fit.to_dict()),
                       ("pendulum", pendulum.fit.to_dict()),
                       ("analysis", analysis.to_dict(detail=True)),
                       ("failed", mcfit.analysis.failed_analysis("x.csv", "bad").to_dict())]:
        _assert_plain(data, name)


def test_a_number_that_is_not_finite_is_none(analysis):
    fit = dataclasses.replace(analysis.fit, rms=math.nan, reduced_chi_square=math.inf,
                              values={**analysis.fit.values, "b": np.float64("nan")})
    data = fit.to_dict()
    assert data["fit"]["rms"] is None and data["fit"]["reduced_chi_square"] is None
    assert data["params"]["b"]["value"] is None
    assert data["params"]["a"]["value"] == analysis.fit.values["a"]
    turning = dataclasses.replace(analysis.turning, period=math.nan)
    assert turning.to_dict()["period"] is None


def test_each_class_gives_its_own_fields(record, analysis):
    described = record.to_dict()
    assert described["samples"] == record.t.size == 2001
    assert (described["kind"], described["domain"], described["run"]) == ("waveform", "time",
                                                                          None)
    turning = analysis.turning.to_dict(points=True)
    assert turning["count"] == int(np.count_nonzero(analysis.turning.used))
    assert [p["t"] for p in turning["points"]] == analysis.turning.t.tolist()
    assert turning["period"] == pytest.approx(0.5, rel=1e-3)
    fit = analysis.fit.to_dict()
    for k in ("y0", "a", "b", "c"):
        assert fit["params"][k] == {"value": analysis.fit.values[k],
                                    "stderr": analysis.fit.stderr[k]}
    assert fit["n_points"] == analysis.fit.n_points
    assert fit["bootstrap"]["n"] == 20
    assert [c["model"] for c in fit["candidates"]] == [c.model for c in analysis.fit.candidates]


def test_a_power_law_gives_y0_its_law_and_no_regimes(record):
    fit = mcfit.analyse(record, model="power").fit
    data = fit.to_dict()
    assert data["params"]["y0"]["value"] == fit.values["y0"]
    assert [data["params"][k]["value"] for k in "abc"] == [0.0, 0.0, 0.0]
    assert data["power_law"]["n"] == fit.values["n"] and not any(data["regimes"].values())


def test_a_pendulum_names_its_angle_unit_and_small_angle_period():
    fit = _pendulum().fit
    data = fit.to_dict()
    assert data["pendulum"]["angle_unit"] == "rad"
    # T0 below the period of swings of 0.6 rad, by about theta0**2/16 (docs/theory.md section 6)
    assert data["pendulum"]["small_angle_period"] == fit.small_angle_period
    assert 0.97 < fit.small_angle_period < 1.0
    assert list(data)[-2:] == ["pendulum", "warnings"]


def test_the_analysis_composes_them_into_the_json_line(analysis):
    data = analysis.to_dict()
    assert data == json.loads(report.to_json(analysis)) == analysis.summary()
    assert data["turning_points"] == analysis.turning.to_dict()["count"]
    assert data["params"] == analysis.fit.to_dict()["params"]
    assert data["params_per_cycle"]["b"]["value"] == pytest.approx(
        analysis.fit.values["b"] * analysis.turning.period, rel=1e-12)
    assert "detail" not in data and "n_points" not in data
    detail = analysis.to_dict(detail=True)["detail"]
    assert detail == {"domain": "time", "n_points": analysis.fit.n_points,
                      "correlation": analysis.fit.correlation}
    assert "detail" not in json.loads(report.to_json(analysis.to_dict(detail=True)))


def test_the_batch_returns_data_that_the_command_line_formats(tmp_path, record):
    path = tmp_path / "run.csv"
    path.write_text("t,x\n" + "".join(f"{t!r},{x!r}\n" for t, x in zip(record.t.tolist(),
                                                                      record.x.tolist())))
    options = batch.FitOptions(method="turning-points", turning_points_out=True)
    [file_result] = batch.run_jobs([str(path)], options, [None])
    [result] = file_result.records
    # Plain data: the same after JSON (as a Dask worker or a pipe could carry it).
    assert json.loads(json.dumps(result, allow_nan=False)) == pickle.loads(pickle.dumps(
        result))
    analysis = mcfit.analyse_file(str(path), method="turning-points")
    assert result["analysis"] == analysis.to_dict(detail=True)
    assert result["turning_points"] == analysis.turning_point_table()
    assert result["plot_error"] is None
    assert report.to_text(result["analysis"]) == analysis.report()


def test_the_text_report_shows_a_missing_number_as_a_dash(analysis):
    data = analysis.to_dict(detail=True)
    data["fit"] = {**data["fit"], "reduced_chi_square": None}
    assert "reduced chi-square -" in report.to_text(data)


def test_runs_are_summarised_from_their_data():
    records = [mcfit.simulate_record(a=0.0, b=b, c=0.0, y0=1.0, period=1.0, duration=30.0,
                                     rate=50.0, noise=0.002, rng=seed)
               for seed, b in enumerate((0.05, 0.06))]
    runs = [mcfit.analyse(r, model="b", method="turning-points").to_dict() for r in records]
    text = report.runs_summary("two.csv", runs)
    mean = (runs[0]["params"]["b"]["value"] + runs[1]["params"]["b"]["value"]) / 2
    assert text.startswith("runs of two.csv: 2 of 2 fitted; models b in 2;")
    assert f"  b          {mean:.6g} +- " in text


def test_analyse_files_gives_the_frame_of_the_command_lines_csv(tmp_path):
    import csv
    import io
    from pathlib import Path

    import pandas as pd
    from click.testing import CliRunner

    from mcfit.cli import cli

    samples = Path(__file__).parents[1] / "sample_data"
    paths = [str(samples / "capstone_runs.csv"), str(samples / "coulomb_stop.csv"),
             str(tmp_path / "missing.csv")]
    printed = CliRunner().invoke(cli, [*paths, "--format", "csv", "--method",
                                       "turning-points"]).stdout
    expected = pd.read_csv(io.StringIO(printed), quoting=csv.QUOTE_MINIMAL,
                           keep_default_na=False, na_values=[""])
    table = mcfit.analyse_files(paths, method="turning-points")
    pd.testing.assert_frame_equal(table, expected)
    assert table["resolved"].tolist()[:6] == [True] * 6 and table["turning_points"].iloc[6] == 0
