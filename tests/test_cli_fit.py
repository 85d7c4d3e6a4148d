"""The fit command: formats, batches with bad files, exit codes, -o safety, plots."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit import decay
from mcfit.cli import cli
from mcfit.report import CSV_COLUMNS, LAST_CSV_COLUMNS

SAMPLE_DATA = Path(__file__).parents[1] / "sample_data"


@pytest.fixture
def runner():
    return CliRunner()


@pytest.fixture
def rng():
    return np.random.default_rng(7)


def _write_record(path, rng, a=0.1, b=0.1, c=0.01, y0=4.0, period=0.5, duration=20.0):
    t = np.arange(0.0, duration, 1 / 100)
    x = decay.amplitude(t, y0, a, b, c) * np.cos(2 * np.pi * t / period)
    x = x + rng.normal(0.0, 0.005, t.size)
    path.write_text("t,x\n" + "\n".join(f"{ti:.4f},{xi:.6f}" for ti, xi in zip(t, x)) + "\n")
    return path


def test_text_report_for_one_record(runner, tmp_path, rng):
    record = _write_record(tmp_path / "run.csv", rng)
    result = runner.invoke(cli, [str(record)])
    assert result.exit_code == 0, result.output
    assert "regimes present: fluid, hysteretic, coulomb" in result.output
    assert "Q:" in result.output and "period:" in result.output


def test_fit_word_is_optional(runner, tmp_path, rng):
    record = _write_record(tmp_path / "run.csv", rng)
    with_word = runner.invoke(cli, ["fit", str(record), "--format", "json"])
    without = runner.invoke(cli, [str(record), "--format", "json"])
    options_first = runner.invoke(cli, ["--format", "json", str(record)])
    assert with_word.exit_code == without.exit_code == options_first.exit_code == 0
    assert json.loads(with_word.output) == json.loads(without.output) == json.loads(
        options_first.output)


def test_json_contract_for_one_record(runner, tmp_path, rng):
    record = _write_record(tmp_path / "run.csv", rng)
    result = runner.invoke(cli, [str(record), "--format", "json"])
    assert result.exit_code == 0
    data = json.loads(result.output)
    for key in ("source", "status", "error", "domain", "turning_points", "period", "model",
                "regimes", "params", "q", "fit", "candidates", "warnings"):
        assert key in data
    assert data["status"] == "ok" and data["error"] is None and data["domain"] == "time"
    assert data["model"] == "abc"
    assert data["regimes"] == {"fluid": True, "hysteretic": True, "coulomb": True}
    assert set(data["params"]) == {"y0", "a", "b", "c"}
    assert abs(data["params"]["a"]["value"] - 0.1) < 5 * data["params"]["a"]["stderr"]
    assert set(data["q"]) == {"initial", "final", "min", "max", "initial_stderr",
                              "final_stderr", "min_stderr", "max_stderr", "lower_bound"}
    assert data["resolved"] is True
    assert 0 < data["q"]["initial_stderr"] < 0.05 * data["q"]["initial"]
    assert {"criterion", "rms", "reduced_chi_square"} <= set(data["fit"])
    assert len(data["candidates"]) == 8
    # The same coefficients per cycle: a*T, b*T, c*T.
    for k in "abc":
        assert data["params_per_cycle"][k]["value"] == pytest.approx(
            data["params"][k]["value"] * data["period"], rel=1e-12)


def test_absent_regime_has_zero_value_and_null_stderr(runner, tmp_path, rng):
    record = _write_record(tmp_path / "soup.csv", rng, a=0.22, b=0.0, c=0.0, y0=1.0)
    data = json.loads(runner.invoke(cli, [str(record), "--format", "json"]).output)
    assert data["model"] == "a"
    assert data["params"]["b"] == {"value": 0.0, "stderr": None}
    assert data["params"]["c"] == {"value": 0.0, "stderr": None}


def test_batch_with_a_bad_file_keeps_going_and_exits_1(runner, tmp_path, rng):
    good1 = _write_record(tmp_path / "a.csv", rng)
    bad = tmp_path / "b.csv"
    bad.write_text("t,x\n")
    good2 = _write_record(tmp_path / "c.csv", rng, a=0.22, b=0.0, c=0.0, y0=1.0)
    result = runner.invoke(cli, [str(good1), str(bad), str(good2), "--format", "json"])
    assert result.exit_code == 1
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    assert [d["source"] for d in lines] == [str(good1), str(bad), str(good2)]  # as given
    assert [d["status"] for d in lines] == ["ok", "error", "ok"]
    assert "b.csv" in lines[1]["error"]
    assert result.stderr.count("Error:") == 1 and "Traceback" not in result.output


def test_a_failed_record_is_said_once_in_text_and_kept_in_a_report_file(runner, tmp_path,
                                                                       rng):
    good = _write_record(tmp_path / "a.csv", rng)
    bad = tmp_path / "b.csv"
    bad.write_text("t,x\n")
    result = runner.invoke(cli, [str(bad), str(good)])
    assert result.exit_code == 1
    assert result.stderr.count("\n") == 1 and result.stderr.startswith(f"Error: {bad}")
    assert result.stdout.startswith(f"mcfit report: {good}\n")  # no block for b.csv
    assert "b.csv" not in result.stdout
    report = tmp_path / "report.txt"
    result = runner.invoke(cli, [str(bad), str(good), "-o", str(report)])
    assert result.exit_code == 1
    blocks = report.read_text().split("\n\nmcfit report: ")
    assert blocks[0].startswith(f"mcfit report: {bad}\n  status: error: {bad}")
    assert blocks[1].startswith(f"{good}\n")


def test_csv_output_has_the_contract_columns_once(runner, tmp_path, rng):
    files = [str(_write_record(tmp_path / f"r{i}.csv", rng)) for i in range(2)]
    result = runner.invoke(cli, [*files, "--format", "csv"])
    assert result.exit_code == 0
    rows = list(csv.reader(io.StringIO(result.stdout)))
    assert tuple(rows[0]) == CSV_COLUMNS + LAST_CSV_COLUMNS
    assert len(rows) == 3 and rows[1][1] == "ok" and rows[1][2] == "abc"


def test_directory_input_and_jobs_keep_input_order(runner, tmp_path, rng):
    for name in ("b.csv", "a.csv", "c.csv"):
        _write_record(tmp_path / name, rng)
    result = runner.invoke(cli, [str(tmp_path), "--format", "json", "--jobs", "2"])
    assert result.exit_code == 0, result.output
    names = [Path(json.loads(line)["source"]).name for line in result.stdout.splitlines()]
    assert names == ["a.csv", "b.csv", "c.csv"]


def test_a_directory_yields_every_kind_of_record_file(tmp_path):
    from mcfit.batch import expand_inputs

    names = ("a.lvm", "b.log", "c.csv.gz", "d.ods", "e.xls", "f.TXT", "notes.md", "g.gz")
    for name in names:
        (tmp_path / name).write_bytes(b"")
    found = [Path(p).name for p in expand_inputs([str(tmp_path)])]
    assert found == ["a.lvm", "b.log", "c.csv.gz", "d.ods", "e.xls", "f.TXT"]


def test_output_file_is_written_and_an_input_is_never_overwritten(runner, tmp_path, rng):
    record = _write_record(tmp_path / "run.csv", rng)
    before = record.read_bytes()
    refused = runner.invoke(cli, [str(record), "-o", str(record)])
    assert refused.exit_code == 2
    assert "is one of the input records" in refused.stderr
    assert record.read_bytes() == before
    out = tmp_path / "results.csv"
    written = runner.invoke(cli, [str(record), "--format", "csv", "-o", str(out)])
    assert written.exit_code == 0
    assert out.read_text().startswith(",".join(CSV_COLUMNS))
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_output_to_an_unwritable_place_is_one_error_line(runner, tmp_path, rng):
    record = _write_record(tmp_path / "run.csv", rng)
    result = runner.invoke(cli, [str(record), "-o", str(tmp_path / "missing" / "out.json")])
    assert result.exit_code == 1
    assert result.stderr.startswith("Error: cannot write") and result.stderr.count("\n") == 1


def test_plot_file_and_plot_dir(runner, tmp_path, rng):
    record = _write_record(tmp_path / "run.csv", rng)
    plot = tmp_path / "run.png"
    result = runner.invoke(cli, [str(record), "--plot", str(plot)])
    assert result.exit_code == 0 and plot.stat().st_size > 10_000
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    second = _write_record(tmp_path / "other.csv", rng)
    plots = tmp_path / "plots"
    result = runner.invoke(cli, [str(record), str(second), "--plot-dir", str(plots)])
    assert result.exit_code == 0
    assert sorted(p.name for p in plots.iterdir()) == ["other.png", "run.png"]
    refused = runner.invoke(cli, [str(record), str(second), "--plot", str(plot)])
    assert refused.exit_code == 2 and "--plot-dir" in refused.stderr


@pytest.mark.parametrize("arguments, message", [
    (["--model", "xyz"], "--model 'xyz' is not a set of damping terms"),
    (["--plot", "out.gif"], "must end in .png, .pdf or .svg"),
])
def test_usage_errors_exit_2(runner, tmp_path, rng, arguments, message):
    record = _write_record(tmp_path / "run.csv", rng)
    result = runner.invoke(cli, [str(record), *arguments])
    assert result.exit_code == 2
    assert message in result.stderr


def test_missing_file_is_one_clear_line(runner, tmp_path):
    result = runner.invoke(cli, [str(tmp_path / "nope.csv")])
    assert result.exit_code == 1
    assert result.stderr.count("\n") == 1 and "nope.csv" in result.stderr
    assert "Traceback" not in result.output


def test_stdin_record(runner, tmp_path, rng):
    record = _write_record(tmp_path / "run.csv", rng)
    result = runner.invoke(cli, ["-", "--format", "json"], input=record.read_text())
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["model"] == "abc"


@pytest.mark.parametrize("name, model", [
    ("fig20_19_all_three.csv", "abc"), ("fig20_21_soup_can.csv", "a"),
    ("fig20_21_soup_can.xlsx", "a"), ("coulomb_stop.csv", "bc"),
    ("fig20_20_peak_speed_cycles.csv", "ab"),
])
def test_sample_data_verdicts(runner, name, model):
    result = runner.invoke(cli, [str(SAMPLE_DATA / name), "--format", "json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["model"] == model


def test_fit_help_gives_the_exit_codes_and_every_option(runner):
    result = runner.invoke(cli, ["fit", "--help"])
    assert result.exit_code == 0
    assert "Exit codes:" in result.stdout and "--dask ADDRESS" in result.stdout





def test_cycle_domain_coefficients_are_reported_per_cycle(runner):
    """A peak table against cycle number n gives a_n, b_n, c_n: never labelled per second."""
    result = runner.invoke(cli, [str(SAMPLE_DATA / "fig20_20_peak_speed_cycles.csv"),
                                 "--format", "json"])
    data = json.loads(result.stdout)
    assert data["domain"] == "cycle" and data["params_units"] == "per cycle"
    assert data["params"]["a"]["value"] == pytest.approx(0.036, rel=0.03)
    assert data["params_per_cycle"]["a"] == data["params"]["a"]
    text = runner.invoke(cli, [str(SAMPLE_DATA / "fig20_20_peak_speed_cycles.csv")]).stdout
    assert "parameters (per cycle)" in text and "per second" not in text


def test_a_forced_model_is_reported_as_forced(runner, tmp_path, rng):
    record = _write_record(tmp_path / "run.csv", rng)
    text = runner.invoke(cli, [str(record), "--model", "ab"]).stdout
    assert "(model ab, forced with --model)" in text
    data = json.loads(runner.invoke(cli, [str(record), "--model", "ab", "--format",
                                          "json"]).stdout)
    assert data["fit"]["forced"] is True and data["model"] == "ab"


def test_a_mistyped_command_is_not_taken_for_a_file(runner):
    result = runner.invoke(cli, ["simulat", "--a", "0.1"])
    assert result.exit_code == 2
    assert "did you mean 'mcfit simulate'?" in result.stderr


def test_plots_of_records_sharing_a_stem_keep_their_extension(runner, tmp_path):
    plots = tmp_path / "plots"
    result = runner.invoke(cli, [str(SAMPLE_DATA / "fig20_21_soup_can.csv"),
                                 str(SAMPLE_DATA / "fig20_21_soup_can.xlsx"),
                                 "--plot-dir", str(plots)])
    assert result.exit_code == 0
    assert sorted(p.name for p in plots.iterdir()) == ["fig20_21_soup_can.png",
                                                       "fig20_21_soup_can.xlsx.png"]


def test_an_unknown_time_unit_labels_the_coefficients(runner, tmp_path, rng):
    record = _write_record(tmp_path / "run.csv", rng)
    lines = record.read_text().splitlines()
    days = tmp_path / "days.csv"
    days.write_text("\n".join(["time (days),x"] + lines[1:]) + "\n")
    data = json.loads(runner.invoke(cli, [str(days), "--format", "json"]).stdout)
    assert data["params_units"] == "per days"
    assert "parameters (per days)" in runner.invoke(cli, [str(days)]).stdout


def test_output_file_keeps_the_mode_of_the_file_it_replaces(runner, tmp_path, rng):
    record = _write_record(tmp_path / "run.csv", rng)
    out = tmp_path / "private.csv"
    out.write_text("old\n")
    out.chmod(0o600)
    assert runner.invoke(cli, [str(record), "--format", "csv", "-o", str(out)]).exit_code == 0
    assert out.stat().st_mode & 0o777 == 0o600 and out.read_text().startswith("source,")


@pytest.mark.parametrize("arguments, message", [
    (["--rate", "100", "--time-col", "t"], "not both"),
    (["--plot", "a.png", "--plot-dir", "plots"], "not both"),
])
def test_contradictory_options_exit_2_before_any_file_is_read(runner, tmp_path, rng,
                                                             arguments, message):
    record = _write_record(tmp_path / "run.csv", rng)
    result = runner.invoke(cli, [str(record), *arguments])
    assert result.exit_code == 2 and message in result.stderr
    assert result.stdout == ""


def test_a_single_term_is_tested_against_no_damping(runner, tmp_path, rng):
    record = _write_record(tmp_path / "soup.csv", rng, a=0.22, b=0.0, c=0.0, y0=1.0)
    data = json.loads(runner.invoke(cli, [str(record), "--format", "json"]).stdout)
    assert data["model"] == "a" and set(data["fit"]["lrt_p_values"]) == {"fluid"}
    assert data["fit"]["lrt_p_values"]["fluid"] < 1e-10


def test_public_names_are_reexported_lazily():
    import mcfit

    assert mcfit.fit_decay.__module__.startswith("mcfit.fit")
    assert "fit_decay" in mcfit.__all__
    with pytest.raises(AttributeError):
        mcfit.no_such_name  # noqa: B018


def test_a_record_with_the_time_column_last_is_fitted(runner, tmp_path, rng):
    record = _write_record(tmp_path / "run.csv", rng)
    lines = [",".join(reversed(line.split(","))) for line in record.read_text().splitlines()]
    swapped = tmp_path / "x_then_t.csv"
    swapped.write_text("\n".join(lines) + "\n")
    result = runner.invoke(cli, [str(swapped), "--format", "json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["columns"] == {"time": "t", "signal": "x"} and data["model"] == "abc"


@pytest.mark.parametrize("output_format", ["text", "json", "csv"])
def test_each_job_returns_data_that_the_command_line_formats(runner, tmp_path, rng,
                                                             output_format):
    from mcfit import batch, report
    from mcfit.options import for_command_line

    record = str(_write_record(tmp_path / "run.csv", rng))
    options = batch.FitOptions(output_format=output_format)
    [file_result] = batch.run_jobs([record], options, [None])
    [result] = file_result.records
    data = result["analysis"]
    assert data["status"] == "ok" and data["source"] == record and data["model"] == "abc"
    printed = runner.invoke(cli, [record, "--format", output_format]).stdout
    expected = {"json": report.to_json(data) + "\n",
                "csv": report.csv_header() + report.to_csv_row(data),
                "text": report.to_text(data)}[output_format]
    assert printed == for_command_line(expected)
    assert printed.startswith({"json": '{"source": ', "csv": "source,status,model,",
                               "text": f"mcfit report: {record}\n"}[output_format])
