"""Files of several runs side by side, --run, the summary over runs, and --angle-from."""

import csv
import io
import json

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit.cli import cli
from mcfit.errors import UsageError
from mcfit.io import read_record, read_records

PERIOD = 1.0
RATE = 50.0
NOISE = 1e-3


def decay(b, duration, seed, amplitude=0.5):
    """A viscous free decay, x = A exp(-b t) cos(2 pi t / T), with white noise."""
    t = np.arange(0.0, duration, 1.0 / RATE)
    x = amplitude * np.exp(-b * t) * np.cos(2 * np.pi * t / PERIOD)
    return t, x + np.random.default_rng(seed).normal(0.0, NOISE, t.size)


# Ten runs of different damping and length, as PASCO Capstone exports them: per run a time,
# an angle and an angular velocity column, shorter runs padded with empty cells.
RUN_B = np.linspace(0.05, 0.14, 10)


def pasco_file(path):
    runs = [decay(b, 30.0 - 1.5 * k, seed=k) for k, b in enumerate(RUN_B)]
    header = []
    for k in range(1, len(runs) + 1):
        header += [f"Time (s) Run #{k}", f"Angle, Ch 1+2 (rad) Run #{k}",
                   f"Angular Velocity, Ch 1+2 (rad/s) Run #{k}"]
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    for i in range(runs[0][0].size):
        row = []
        for t, x in runs:
            row += ([f"{t[i]:.2f}", f"{x[i]:.5f}", f"{np.gradient(x, t)[i]:.4f}"]
                    if i < t.size else ["", "", ""])
        writer.writerow(row)
    path.write_text(buffer.getvalue())
    return str(path)


@pytest.fixture(scope="module")
def pasco(tmp_path_factory):
    return pasco_file(tmp_path_factory.mktemp("runs") / "capstone.csv")


def json_lines(result):
    assert result.exit_code == 0, result.output
    return [json.loads(line) for line in result.output.splitlines()]


def b_of(line):
    return line["params"]["b"]["value"], line["params"]["b"]["stderr"]


def test_every_run_is_a_record_of_its_own(pasco):
    result = CliRunner().invoke(cli, [pasco, "--format", "json", "--method", "turning-points"])
    lines = json_lines(result)
    assert [line["source"] for line in lines] == [f"{pasco}#Run {k}" for k in range(1, 11)]
    assert [line["run"] for line in lines] == [f"Run {k}" for k in range(1, 11)]
    # At alpha = 0.0075 per term a spurious term in one run of ten is expected now and then.
    assert sum(line["model"] == "b" for line in lines) >= 9
    for line, truth in zip(lines, RUN_B):
        assert line["columns"]["signal"].startswith("Angle, Ch 1+2")
        value, stderr = b_of(line)
        assert abs(value - truth) < 4 * stderr
    lengths = [line["turning_points"] for line in lines]
    assert lengths == sorted(lengths, reverse=True)  # the padding of shorter runs is dropped


def test_run_picks_one_and_the_csv_names_it(pasco):
    runner = CliRunner()
    [line] = json_lines(runner.invoke(cli, [pasco, "--run", "7", "--format", "json",
                                            "--method", "turning-points"]))
    assert line["source"] == f"{pasco}#Run 7"
    value, stderr = b_of(line)
    assert abs(value - RUN_B[6]) < 4 * stderr
    result = runner.invoke(cli, [pasco, "--run", "3", "--format", "csv",
                                 "--method", "turning-points"])
    [row] = list(csv.DictReader(io.StringIO(result.output)))
    assert row["run"] == "Run 3" and row["source"] == f"{pasco}#Run 3"


def test_a_run_not_in_the_file_is_one_clear_error(pasco):
    result = CliRunner().invoke(cli, [pasco, "--run", "11"])
    assert result.exit_code == 1
    assert "run 11 not found" in result.output and "1, 2, 3" in result.output
    assert "Traceback" not in result.output


def test_text_report_ends_with_the_spread_over_runs(pasco):
    result = CliRunner().invoke(cli, [pasco, "--method", "turning-points"])
    assert result.exit_code == 0
    summary = result.output[result.output.index(f"runs of {pasco}: 10 of 10 fitted"):]
    assert "models b in 9, abc in 1" in summary  # run 6 keeps two terms near the threshold
    b_line = next(line for line in summary.splitlines() if line.strip().startswith("b "))
    mean, sd = (float(v) for v in b_line.split()[1:4:2])
    assert mean == pytest.approx(RUN_B.mean(), rel=0.01)
    assert sd == pytest.approx(RUN_B.std(ddof=1), rel=0.05)


def test_reading_runs_in_python(pasco):
    records = read_records(pasco)
    assert [r.run for r in records] == [f"Run {k}" for k in range(1, 11)]
    assert records[9].t.size == 30.0 * RATE - 9 * 1.5 * RATE
    with pytest.raises(UsageError, match="10 runs side by side"):
        read_record(pasco)
    assert read_record(pasco, run=4).signal_column == "Angle, Ch 1+2 (rad) Run #4"
    # A column by number pins its run; a name that every run holds is chosen in each.
    [pinned] = read_records(pasco, signal_col=6)
    assert pinned.run == "Run 2" and pinned.time_column == "Time (s) Run #2"
    velocity = read_records(pasco, signal_col="Angular Velocity, Ch 1+2 (rad/s)")
    assert [r.signal_column for r in velocity][-1].startswith("Angular Velocity")
    assert len(velocity) == 10


def test_repeated_time_and_signal_columns_are_runs(tmp_path):
    first, second = decay(0.05, 20.0, seed=1), decay(0.1, 15.0, seed=2)
    lines = ["time,x,time,x"]
    for i in range(first[0].size):
        tail = f"{second[0][i]:.2f},{second[1][i]:.5f}" if i < second[0].size else ","
        lines.append(f"{first[0][i]:.2f},{first[1][i]:.5f},{tail}")
    path = tmp_path / "pairs.csv"
    path.write_text("\n".join(lines) + "\n")
    records = read_records(str(path))
    assert [r.run for r in records] == ["Run 1", "Run 2"]
    np.testing.assert_allclose(records[1].x, np.round(second[1], 5))
    # Named, the signal of each run is its own column of that name.
    records = read_records(str(path), signal_col="x")
    np.testing.assert_allclose(records[0].x, np.round(first[1], 5))
    np.testing.assert_allclose(records[1].x, np.round(second[1], 5))


def shared_time_file(path):
    t, x1 = decay(0.05, 20.0, seed=3)
    _, x2 = decay(0.1, 20.0, seed=4)
    body = "".join(f"{a:.2f},{b:.5f},{c:.5f}\n" for a, b, c in zip(t, x1, x2))
    path.write_text("Time (s),Position (m) Run #1,Position (m) Run #2\n" + body)
    return str(path)


def test_a_shared_time_column_belongs_to_every_run(tmp_path):
    records = read_records(shared_time_file(tmp_path / "shared.csv"))
    assert [(r.run, r.time_column) for r in records] == [("Run 1", "Time (s)"),
                                                         ("Run 2", "Time (s)")]
    np.testing.assert_allclose(records[1].x, np.round(decay(0.1, 20.0, seed=4)[1], 5))
    result = CliRunner().invoke(cli, [str(tmp_path / "shared.csv"), "--method",
                                      "turning-points"])
    assert "models b in 2" in result.output
    assert "0 in every run (not detected)" in result.output  # a and c


def test_one_run_files_keep_their_plain_source(tmp_path):
    t, x = decay(0.05, 20.0, seed=5)
    path = tmp_path / "one.csv"
    path.write_text("Time (s) Run #1,Position (m) Run #1\n"
                    + "".join(f"{a:.2f},{b:.5f}\n" for a, b in zip(t, x)))
    [record] = read_records(str(path))
    assert record.run is None and record.name == str(path)
    assert read_record(str(path), run=1).run is None
    with pytest.raises(UsageError, match="run 2 not found"):
        read_record(str(path), run=2)


def test_a_quoted_header_may_hold_the_separator(tmp_path):
    t, x = decay(0.05, 20.0, seed=6)
    path = tmp_path / "quoted.csv"
    path.write_text('"Time (s)","Angle, Ch 1+2 (rad)"\n'
                    + "".join(f"{a:.2f},{b:.5f}\n" for a, b in zip(t, x)))
    record = read_record(str(path))
    assert record.columns == ("Time (s)", "Angle, Ch 1+2 (rad)")
    assert record.signal_unit == "rad"


def test_plot_of_a_file_of_runs_is_one_figure_per_run(tmp_path, pasco):
    shared = shared_time_file(tmp_path / "shared.csv")
    runner = CliRunner()
    result = runner.invoke(cli, [shared, "--plot", str(tmp_path / "fig.png"), "--method",
                                 "turning-points"])
    assert result.exit_code == 0
    assert sorted(p.name for p in tmp_path.glob("fig*")) == ["fig-run1.png", "fig-run2.png"]
    result = runner.invoke(cli, [pasco, "--run", "2", "--plot-dir", str(tmp_path / "figs"),
                                 "--method", "turning-points", "--format", "csv"])
    assert result.exit_code == 0  # one run of several: the file's own name
    assert [p.name for p in (tmp_path / "figs").iterdir()] == ["capstone.png"]


# --------------------------------------------------------------------------- --angle-from

LENGTH = 0.8


def bob_file(path, downwards=False):
    """A video-tracked bob: x = L sin(theta), y = -L cos(theta) (pivot at the origin)."""
    t, theta = decay(0.05, 30.0, seed=7, amplitude=0.2)
    x, y = LENGTH * np.sin(theta), -LENGTH * np.cos(theta)
    y = -y if downwards else y
    path.write_text("t (s),x (m),y (m)\n"
                    + "".join(f"{a:.2f},{b:.6f},{c:.6f}\n" for a, b, c in zip(t, x, y)))
    return str(path), theta


@pytest.mark.parametrize("downwards", [False, True])
def test_angle_from_the_bob_position(tmp_path, downwards):
    path, theta = bob_file(tmp_path / "bob.csv", downwards)
    record = read_record(path, angle_from=("x", "y"))
    np.testing.assert_allclose(record.x, theta, atol=2e-6)
    assert record.signal_unit == "rad" and record.signal_column == "angle from x (m), y (m)"
    assert any("downwards" in note for note in record.notes) == downwards
    [line] = json_lines(CliRunner().invoke(cli, [path, "--angle-from", "2,3", "--format",
                                                 "json", "--method", "turning-points"]))
    value, stderr = b_of(line)
    assert line["model"] == "b" and abs(value - 0.05) < 4 * stderr


def test_angle_from_needs_two_columns_and_no_signal_column(tmp_path):
    path, _ = bob_file(tmp_path / "bob.csv")
    runner = CliRunner()
    for options in (["--angle-from", "x"], ["--angle-from", "x,y", "--signal-col", "x"]):
        result = runner.invoke(cli, [path, *options])
        assert result.exit_code == 2 and "--angle-from" in result.output


def test_a_window_too_short_says_so(tmp_path):
    t, x = decay(0.05, 20.0, seed=8)
    path = tmp_path / "short.csv"
    path.write_text("t,x\n" + "".join(f"{a:.2f},{b:.5f}\n" for a, b in zip(t, x)))
    result = CliRunner().invoke(cli, [str(path), "--start", "10", "--end", "11"])
    assert result.exit_code == 1
    assert "in the window from 10 s to 11 s asked for: widen it" in result.output


def test_the_sample_export_of_five_runs():
    from pathlib import Path

    sample = Path(__file__).parents[1] / "sample_data" / "capstone_runs.csv"
    lines = json_lines(CliRunner().invoke(cli, [str(sample), "--format", "json"]))
    assert [line["run"] for line in lines] == [f"Run {k}" for k in range(1, 6)]
    for k, line in enumerate(lines):  # make_samples.py: b = 0.03 + 0.02 k, c = 0.004
        assert line["model"] == "bc"
        for name, truth in (("b", 0.03 + 0.02 * k), ("c", 0.004)):
            value, stderr = line["params"][name]["value"], line["params"][name]["stderr"]
            assert abs(value - truth) < 4 * stderr
