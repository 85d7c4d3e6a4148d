"""What a script relies on: one JSON line per record, the CSV columns, a time window, the
turning points' file, and the text report's goodness of fit."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from mcfit.cli import cli
from mcfit.fit.diagnostics import misfit_warning
from mcfit.report import (BOOTSTRAP_CSV_COLUMNS, CSV_COLUMNS, LAST_CSV_COLUMNS,
                          TURNING_POINT_COLUMNS)

SAMPLES = Path(__file__).parents[1] / "sample_data"
FIG_20_19 = str(SAMPLES / "fig20_19_all_three.csv")
STOP = str(SAMPLES / "coulomb_stop.csv")


def _run(*arguments):
    return CliRunner().invoke(cli, [str(a) for a in arguments])


def test_json_of_one_record_is_one_line():
    result = _run(FIG_20_19, "--format", "json")
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert len(lines) == 1 and json.loads(lines[0])["model"] == "abc"


def test_csv_has_domain_units_method_resolved_chi_square_and_warnings():
    result = _run(FIG_20_19, STOP, "--format", "csv")
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(io.StringIO(result.output)))
    assert tuple(rows[0]) == CSV_COLUMNS + LAST_CSV_COLUMNS
    by_source = {Path(r["source"]).name: r for r in rows}
    fig = by_source["fig20_19_all_three.csv"]
    assert (fig["domain"], fig["units"], fig["method"], fig["resolved"]) == (
        "time", "per second", "turning-points", "true")
    assert float(fig["reduced_chi_square"]) == pytest.approx(0.88, abs=0.01)
    assert fig["warnings"] == ""
    # The Coulomb stop's turning points after the mass sticks are left out: the swings
    # before it fit the averaged law within their noise (it warned of a misfit before).
    stop = by_source["coulomb_stop.csv"]
    assert stop["warnings"] == "" and float(stop["reduced_chi_square"]) < 2


def test_csv_with_bootstrap_has_the_intervals():
    result = _run(FIG_20_19, "--format", "csv", "--bootstrap", "30", "--seed", "3")
    assert result.exit_code == 0, result.output
    row = next(csv.DictReader(io.StringIO(result.output)))
    assert tuple(row) == CSV_COLUMNS + BOOTSTRAP_CSV_COLUMNS + LAST_CSV_COLUMNS
    for k in ("a", "b", "c"):
        low, high = float(row[f"{k}_boot_low"]), float(row[f"{k}_boot_high"])
        assert low < float(row[k]) < high


def test_window_crops_the_record_and_says_so():
    whole = json.loads(_run(FIG_20_19, "--format", "json").output)
    part = json.loads(_run(FIG_20_19, "--format", "json", "--start", "5", "--end", "15").output)
    assert part["turning_points"] < whole["turning_points"] / 2 + 2
    assert 4.9 < part["t0"] < 5.6
    assert any(n.startswith("window: 5 s to 15 s as asked") for n in part["notes"])


def test_window_errors():
    reversed_window = _run(FIG_20_19, "--start", "5", "--end", "1")
    assert reversed_window.exit_code == 2
    assert "--start 5 must come before --end 1" in reversed_window.output
    outside = _run(FIG_20_19, "--start", "50")
    assert outside.exit_code == 1
    assert "no samples in the window from 50 s to the end; the record spans 0 to 20 s" \
        in outside.output


def test_turning_points_out(tmp_path):
    target = tmp_path / "points.csv"
    result = _run(FIG_20_19, STOP, "--format", "json", "--turning-points-out", target)
    assert result.exit_code == 0, result.output
    reports = [json.loads(line) for line in result.output.splitlines()]
    rows = list(csv.DictReader(io.StringIO(target.read_text())))
    assert tuple(rows[0]) == TURNING_POINT_COLUMNS
    for report in reports:
        mine = [r for r in rows if r["source"] == report["source"]]
        used = [r for r in mine if r["used"] == "true"]
        assert len(used) == report["turning_points"]
        assert len(mine) - len(used) == sum(report["turning_points_excluded"].values())
        # The envelope is the fit at each used point: within 5 sigma of the amplitude.
        assert all(abs(float(r["amplitude"]) - float(r["envelope"])) < 5 * float(r["sigma"])
                   for r in used)
        assert all(r["envelope"] == "" and r["excluded_reason"] for r in mine
                   if r["used"] == "false")


def test_turning_points_out_may_not_clash_with_the_report(tmp_path):
    target = tmp_path / "same.csv"
    result = _run(FIG_20_19, "-o", target, "--turning-points-out", target)
    assert result.exit_code == 2 and not target.exists()


def test_text_report_gives_scores_and_correlations():
    result = _run(FIG_20_19)
    assert "(chi-square 65.92 on 75 degrees of freedom, AICc" in result.output
    assert "correlations:    y0-a +0.586" in result.output


def test_misfit_warning_threshold():
    assert misfit_warning(220.0, 100) and misfit_warning(3.0, 20)
    assert not misfit_warning(1.5, 100) and not misfit_warning(1.9, 10_000)
    assert not misfit_warning(3.0, 2)  # 1 + 5*sqrt(2/2) = 6


def test_turning_points_and_results_may_not_share_stdout():
    result = _run(FIG_20_19, "--turning-points-out", "-")
    assert result.exit_code == 2 and "share stdout" in result.output


def test_method_is_refused_with_pendulum():
    result = _run(FIG_20_19, "--pendulum", "--method", "waveform")
    assert result.exit_code == 2 and "--method is not available with --pendulum" in result.output


CYCLES = str(SAMPLES / "fig20_20_peak_speed_cycles.csv")
CAPSTONE = str(SAMPLES / "capstone_runs.csv")


@pytest.mark.parametrize("path, signal_unit, units", [
    (FIG_20_19, None, ("U", "1/(U*s)", "1/s", "U/s")),
    (CAPSTONE, "rad", ("rad", "1/(rad*s)", "1/s", "rad/s")),
    (CYCLES, "cm/s", ("cm/s", "1/((cm/s)*cycle)", "1/cycle", "(cm/s)/cycle")),
])
def test_the_units_of_y0_a_b_c_in_text_json_and_csv(path, signal_unit, units):
    """dy/dt = -c - b*y - a*y^2 with y in U: c in U per time, b per time, a per U per
    time; the text report, the JSON and the CSV give the same."""
    options = ["--run", "1"] if path == CAPSTONE else []
    data = json.loads(_run(path, *options, "--format", "json").output)
    assert data["signal_unit"] == signal_unit
    assert tuple(data["coefficient_units"][k] for k in ("y0", "a", "b", "c")) == units
    text = _run(path, *options).output
    for label, unit in zip(("y0 (amplitude", "a (fluid)", "b (hysteretic)", "c (Coulomb)"),
                           units):
        line = next(line for line in text.splitlines() if line.strip().startswith(label))
        assert line.endswith(" " + unit), line
    assert ("U: the signal's unit" in text) == (signal_unit is None)
    row = next(csv.DictReader(io.StringIO(_run(path, *options, "--format", "csv").output)))
    assert row["signal_unit"] == (signal_unit or "")
    assert tuple(row[f"{k}_unit"] for k in ("y0", "a", "b", "c")) == units


def test_the_figure_and_the_report_name_the_same_units():
    import matplotlib

    matplotlib.use("Agg")
    from mcfit.api import analyse_file

    analysis = analyse_file(CYCLES)
    units = analysis.summary()["coefficient_units"]
    box = next(t.get_text() for a in analysis.figure(panels="record").axes for t in a.texts
               if "reduced chi-square" in t.get_text())
    for k in ("a", "b"):
        assert f"{k} ({units[k]})" in box


def test_the_runs_summary_gives_each_coefficients_unit():
    text = _run(CAPSTONE, "--method", "turning-points").output
    summary = text[text.index("runs of "):].splitlines()
    lines = {line.split()[0]: line for line in summary[1:] if line.strip()}
    assert " rad (sem " in lines["y0"] and " 1/s (sem " in lines["b"]
    assert " rad/s (sem " in lines["c"]
    assert lines["a"].endswith("0 in every run (not detected)")
