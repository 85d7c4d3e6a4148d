"""Folders, names and options of a batch (issue 27, issue 26): a folder that cannot be
listed costs only itself; what a folder holds besides records (subfolders, broken links,
FIFOs, mcfit's own outputs) is named in a note; a file named twice is fitted once; long
output names work; options no record can have are usage errors.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit import batch, decay
from mcfit.cli import cli
from mcfit.options import RATE_RANGE, SAMPLES_PER_CYCLE, check_fit_options, check_read_options


@pytest.fixture
def runner():
    return CliRunner()


def _record(path, *, b=0.1, duration=20.0, rate=50.0, seed=1):
    """A hysteretic free decay exp(-b*t)*cos(2*pi*t) with a little Gaussian noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    x = decay.amplitude(t, 1.0, 0.0, b, 0.0) * np.cos(2 * np.pi * t)
    x = x + rng.normal(0.0, 1e-3, t.size)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("t,x\n" + "".join(f"{ti!r},{xi!r}\n"
                                      for ti, xi in zip(t.tolist(), x.tolist())))
    return path


def _rows(text):
    return list(csv.DictReader(io.StringIO(text)))


# --------------------------------------------------------------------------- unlistable


@pytest.fixture
def open_dir():
    """A directory the unprivileged user can enter (tmp_path's parents are 0700)."""
    directory = Path(tempfile.mkdtemp(prefix="mcfit-folders-"))
    directory.chmod(0o777)
    yield directory
    for folder in directory.iterdir():
        folder.chmod(0o755)
    shutil.rmtree(directory)


def _without_privileges(arguments, warm_up):
    """The command line as the user nobody when run as root: root lists any directory.

    A first run of ``warm_up`` as root imports every module the call needs (the
    interpreter may live where nobody cannot read).
    """
    runner = CliRunner()
    if os.geteuid() != 0:
        return runner.invoke(cli, arguments)
    assert runner.invoke(cli, warm_up).exit_code == 0
    try:
        os.setegid(65534)
        os.seteuid(65534)
    except OSError as error:
        os.setegid(0)
        pytest.skip(f"root cannot become nobody here: {error}")
    try:
        return runner.invoke(cli, arguments)
    finally:
        os.seteuid(0)
        os.setegid(0)


def test_an_unlistable_folder_costs_only_itself(open_dir):
    records = [_record(open_dir / "open" / f"run{i}.csv", seed=i) for i in range(2)]
    _record(open_dir / "locked" / "hidden.csv")
    for folder in ("open", "locked"):
        (open_dir / folder).chmod(0o777)
    for record in records:
        record.chmod(0o644)
    (open_dir / "locked").chmod(0o000)
    arguments = [str(open_dir / "locked"), str(open_dir / "open"), "--format", "csv"]
    result = _without_privileges(arguments, [str(open_dir / "open"), "--format", "csv"])
    assert result.exit_code == 1, result.output
    assert [row["source"] for row in _rows(result.stdout)] == [str(r) for r in records]
    assert [row["status"] for row in _rows(result.stdout)] == ["ok", "ok"]
    assert result.stderr == (f"Error: cannot list directory {open_dir}/locked: Permission "
                             "denied. Check its permissions, or name the files instead.\n")


def test_only_an_unlistable_folder_is_one_error(open_dir):
    _record(open_dir / "locked" / "hidden.csv")
    (open_dir / "locked").chmod(0o000)
    _record(open_dir / "warm" / "run.csv")
    (open_dir / "warm").chmod(0o777)
    (open_dir / "warm" / "run.csv").chmod(0o644)
    result = _without_privileges([str(open_dir / "locked")], [str(open_dir / "warm")])
    assert result.exit_code == 1
    assert result.stderr == (f"Error: cannot list directory {open_dir}/locked: Permission "
                             "denied. Check its permissions, or name the files instead.\n")
    assert result.stdout == ""


# --------------------------------------------------------------------------- what a folder holds


def test_broken_links_fifos_and_subfolders_are_named_in_notes(runner, tmp_path):
    runs = tmp_path / "runs"
    _record(runs / "run.csv")
    (runs / "gone.csv").symlink_to("nowhere.csv")
    os.mkfifo(runs / "live.csv")
    _record(runs / "day2" / "run.csv")
    (runs / ".cache").mkdir()  # hidden: not worth a note
    result = runner.invoke(cli, [str(runs), "--format", "csv"])
    assert result.exit_code == 0, result.output
    assert [row["source"] for row in _rows(result.stdout)] == [str(runs / "run.csv")]
    assert result.stderr == (
        f"Note: {runs}: left out its subfolders {runs}/day2 (name them to fit their "
        "records).\n"
        f"Note: {runs}: left out {runs}/gone.csv (a broken symbolic link), {runs}/live.csv "
        "(a FIFO): not regular files.\n")


def test_a_folder_of_only_a_broken_link_and_a_fifo_names_them(runner, tmp_path):
    (tmp_path / "gone.csv").symlink_to("nowhere.csv")
    os.mkfifo(tmp_path / "live.csv")
    result = runner.invoke(cli, [str(tmp_path)])
    assert result.exit_code == 2
    assert result.stderr.startswith(f"Error: directory {tmp_path} holds no record files (")
    assert result.stderr.endswith(
        f"); it holds {tmp_path}/gone.csv (a broken symbolic link), {tmp_path}/live.csv "
        "(a FIFO): not regular files; name the files instead.\n")


def test_many_subfolders_are_counted_past_the_first_five(tmp_path):
    _record(tmp_path / "run.csv")
    for i in range(7):
        (tmp_path / f"sub{i}").mkdir()
    [note] = batch.find_inputs([str(tmp_path)]).notes
    assert note == (f"{tmp_path}: left out its subfolders " + ", ".join(
        f"{tmp_path}/sub{i}" for i in range(5)) + " and 2 more (name them to fit their "
        "records).")


@pytest.mark.parametrize("output_format, name", [("csv", "results.csv"),
                                                 ("text", "report.txt"),
                                                 ("json", "results.txt")])
def test_a_results_file_in_the_folder_read_is_left_out_the_next_time(runner, tmp_path,
                                                                     output_format, name):
    runs = tmp_path / "runs"
    records = [_record(runs / f"run{i}.csv", seed=i) for i in range(2)]
    out = runs / name
    arguments = [str(runs), "--format", output_format, "-o", str(out)]
    first = runner.invoke(cli, arguments)
    assert first.exit_code == 0, first.output
    assert first.stderr == ""
    written = out.read_text()
    second = runner.invoke(cli, arguments)
    assert second.exit_code == 0, second.output
    assert second.stderr == f"Note: {runs}: left out {out}: output of mcfit, not records.\n"
    assert out.read_text().count("\n") == written.count("\n")  # the same two records
    if output_format == "csv":
        assert [row["source"] for row in _rows(out.read_text())] == [str(r) for r in records]


def test_a_turning_points_file_in_the_folder_read_is_left_out(runner, tmp_path):
    record = _record(tmp_path / "run.csv")
    points = tmp_path / "points.csv"
    first = runner.invoke(cli, [str(tmp_path), "--turning-points-out", str(points)])
    assert first.exit_code == 0, first.output
    second = runner.invoke(cli, [str(tmp_path), "--format", "csv"])
    assert second.exit_code == 0, second.output
    assert [row["source"] for row in _rows(second.stdout)] == [str(record)]
    assert second.stderr == f"Note: {tmp_path}: left out {points}: output of mcfit, not records.\n"


def test_the_output_signatures_are_the_first_lines_mcfit_writes(tmp_path):
    from mcfit import analyse_file, report

    analysis = analyse_file(str(_record(tmp_path / "run.csv")))
    results_csv, points_csv, text, json_line = batch.OUTPUT_SIGNATURES
    assert report.csv_header().startswith(results_csv)
    assert report.csv_header(bootstrap=True).startswith(results_csv)
    assert report.turning_points_header().startswith(points_csv)
    assert report.to_text(analysis).startswith(text)
    assert report.to_json(analysis).startswith(json_line)
    assert json.loads(report.to_json(analysis))["source"]


def test_a_record_that_merely_has_a_source_column_is_read(tmp_path):
    (tmp_path / "log.csv").write_text("source,t,x\nA,0,1\n")
    assert batch.find_inputs([str(tmp_path)]).files == (str(tmp_path / "log.csv"),)


# --------------------------------------------------------------------------- names


def test_a_file_named_twice_is_fitted_once(runner, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _record(tmp_path / "a.csv")
    _record(tmp_path / "b.csv", seed=2)
    result = runner.invoke(cli, ["a.csv", ".", "./b.csv", "--format", "csv"])
    assert result.exit_code == 0, result.output
    assert [row["source"] for row in _rows(result.stdout)] == ["a.csv", "b.csv"]
    assert result.stderr == ("Note: a.csv is named twice; fitted once.\n"
                             "Note: ./b.csv is b.csv, named before; fitted once.\n")


def test_a_missing_file_named_twice_fails_once(runner, tmp_path):
    missing = str(tmp_path / "missing.csv")
    result = runner.invoke(cli, [missing, missing, "--format", "csv"])
    assert result.exit_code == 1
    assert len(_rows(result.stdout)) == 1


def test_a_long_legal_output_name_is_written(runner, tmp_path):
    record = _record(tmp_path / "run.csv")
    out = tmp_path / ("r" * 246 + ".csv")  # 250 characters: legal, NAME_MAX is 255
    figure = tmp_path / ("f" * 246 + ".png")
    result = runner.invoke(cli, [str(record), "--format", "csv", "-o", str(out),
                                 "--plot", str(figure)])
    assert result.exit_code == 0, result.output
    assert _rows(out.read_text())[0]["status"] == "ok"
    assert figure.read_bytes().startswith(b"\x89PNG")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([out.name, figure.name,
                                                                 "run.csv"])


def test_a_plot_in_a_missing_folder_names_the_plot_not_its_temporary(runner, tmp_path,
                                                                     monkeypatch):
    monkeypatch.chdir(tmp_path)
    _record(tmp_path / "run.csv")
    result = runner.invoke(cli, ["run.csv", "--plot", "nodir/fig.png"])
    assert result.exit_code == 1
    assert result.stderr == ("Error: cannot write plot nodir/fig.png: No such file or "
                             "directory; check that the directory exists and is writable.\n")


def test_the_batch_names_options_in_python_spelling():
    """Only the command line spells flags; batch.py's messages mark options as `jobs=1`."""
    text = Path(batch.__file__).read_text(encoding="utf-8")
    assert re.findall(r"--[a-z][a-z-]*", text) == []
    assert "`jobs=1`" in text


# --------------------------------------------------------------------------- options


@pytest.mark.parametrize("option, value, message", [
    ("--start", "nan", "--start must be a finite time (or cycle number), not nan."),
    ("--end", "nan", "--end must be a finite time (or cycle number), not nan."),
    ("--start", "-inf", "--start must be a finite time (or cycle number), not -inf."),
    ("--rate", "1e308", "--rate 1e+308 is not a sample rate a record has; give the samples "
                        "per second, from 1e-06 to 1e+12."),
    ("--rate", "1e300", "--rate 1e+300 is not a sample rate a record has; give the samples "
                        "per second, from 1e-06 to 1e+12."),
    ("--rate", "1e-308", "--rate 1e-308 is not a sample rate a record has; give the samples "
                         "per second, from 1e-06 to 1e+12."),
])
def test_options_no_record_can_have_are_usage_errors(runner, tmp_path, option, value,
                                                     message):
    record = tmp_path / "signal.csv"
    record.write_text("x\n" + "".join(f"{np.cos(i / 8):.6f}\n" for i in range(400)))
    result = runner.invoke(cli, [str(record), option, value])
    assert result.exit_code == 2
    assert result.stderr == f"Error: {message}\n"


def test_the_rate_range_holds_for_the_library_too():
    low, high = RATE_RANGE
    check_read_options(rate=low)
    check_read_options(rate=high)
    for rate in (low / 2, high * 2):
        with pytest.raises(Exception) as refused:
            check_read_options(rate=rate)
        assert refused.value.option == "rate" and refused.value.exit_code == 2
    with pytest.raises(Exception) as refused:
        check_fit_options(end=float("nan"))
    assert refused.value.option == "end" and refused.value.exit_code == 2


def test_simulate_refuses_too_few_samples_a_cycle(runner):
    result = runner.invoke(cli, ["simulate", "--rate", "1", "--period", "1"])
    assert result.exit_code == 2
    assert result.stderr == ("Error: --rate 1 gives 1 sample a cycle of --period 1 s; mcfit "
                             "finds turning points from 8 a cycle: give --rate 8 or more.\n")
    result = runner.invoke(cli, ["simulate", "--rate", "13", "--period", "0.6"])
    assert result.exit_code == 2
    assert result.stderr.endswith("give --rate 13.34 or more.\n")  # rounded up, not down
    enough = runner.invoke(cli, ["simulate", "--rate", "13.34", "--period", "0.6",
                                 "--duration", "1"])
    assert enough.exit_code == 0, enough.output


def test_the_samples_a_cycle_are_those_the_turning_points_need():
    from mcfit.turning.common import SAMPLES_PER_CYCLE as NEEDED

    assert SAMPLES_PER_CYCLE == NEEDED
