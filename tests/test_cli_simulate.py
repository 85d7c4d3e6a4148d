"""``mcfit simulate`` and the command-line group, through click.testing.CliRunner."""

from __future__ import annotations

import subprocess
import sys

import click
import numpy as np
import pytest
from click.testing import CliRunner

import mcfit
from mcfit import motion
from mcfit.cli import McfitGroup, cli

FIG_20_19 = ["--a", "0.1", "--b", "0.1", "--c", "0.01", "--y0", "4", "--period", "0.5",
             "--duration", "2", "--rate", "50"]


@pytest.fixture
def runner():
    return CliRunner()


def _read(text):
    lines = text.splitlines()
    return lines[0], np.loadtxt(lines[1:], delimiter=",", ndmin=2)


def test_writes_csv_file_with_header_and_every_sample(runner, tmp_path):
    out = tmp_path / "rec.csv"
    result = runner.invoke(cli, ["simulate", *FIG_20_19, "--method", "accurate", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert result.stdout == ""
    header, data = _read(out.read_text())
    assert header == "t,x"
    assert data.shape == (101, 2)  # 2 s at 50 Hz, both ends included
    t, x = motion.simulate_record(0.1, 0.1, 0.01, 4.0, 0.5, 2.0, 50.0, method="accurate")
    np.testing.assert_allclose(data[:, 0], t, rtol=1e-14)
    np.testing.assert_allclose(data[:, 1], x, rtol=1e-13, atol=1e-14)
    assert [p.name for p in tmp_path.iterdir()] == ["rec.csv"]  # no temporary left


def test_writes_stdout_without_output_option(runner):
    result = runner.invoke(cli, ["simulate", "--b", "0.01", "--duration", "1", "--rate", "10"])
    assert result.exit_code == 0, result.output
    header, data = _read(result.stdout)
    assert header == "t,x"
    assert data.shape == (11, 2)
    assert data[0, 1] == 1.0  # starts at x = y0


def test_noise_is_reproducible_with_a_seed_only(runner, tmp_path):
    noisy = [*FIG_20_19, "--noise", "0.05", "--offset", "0.3", "--drift", "0.01"]
    first = runner.invoke(cli, ["simulate", *noisy, "--seed", "11", "-o", str(tmp_path / "a.csv")])
    second = runner.invoke(cli, ["simulate", *noisy, "--seed", "11", "-o", str(tmp_path / "b.csv")])
    other = runner.invoke(cli, ["simulate", *noisy, "--seed", "12", "-o", str(tmp_path / "c.csv")])
    unseeded = runner.invoke(cli, ["simulate", *noisy, "-o", str(tmp_path / "d.csv")])
    assert [r.exit_code for r in (first, second, other, unseeded)] == [0, 0, 0, 0]
    texts = [(tmp_path / f"{name}.csv").read_text() for name in "abcd"]
    assert texts[0] == texts[1]
    assert texts[0] != texts[2] and texts[0] != texts[3]
    clean = runner.invoke(cli, ["simulate", *FIG_20_19])
    residual = _read(texts[0])[1][:, 1] - _read(clean.stdout)[1][:, 1]
    t = _read(texts[0])[1][:, 0]
    assert np.std(residual - 0.3 - 0.01 * t) == pytest.approx(0.05, rel=0.25)


def test_replaces_an_existing_file(runner, tmp_path):
    out = tmp_path / "rec.csv"
    out.write_text("old\n")
    out.chmod(0o640)
    result = runner.invoke(cli, ["simulate", "--duration", "0.2", "--rate", "10", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert out.read_text().splitlines()[0] == "t,x"
    assert len(out.read_text().splitlines()) == 4
    assert out.stat().st_mode & 0o777 == 0o640


@pytest.mark.parametrize("method", ["averaged", "cromer-euler", "symplectic", "accurate"])
def test_every_method_runs(runner, method):
    result = runner.invoke(cli, ["simulate", *FIG_20_19, "--method", method])
    assert result.exit_code == 0, result.output
    assert _read(result.stdout)[1].shape == (101, 2)


def test_dt_only_with_fixed_step_methods(runner):
    result = runner.invoke(cli, ["simulate", "--method", "accurate", "--dt", "0.001"])
    assert result.exit_code == 2
    assert result.stderr == ("Error: --dt applies only to --method cromer-euler or symplectic, "
                             "not accurate; drop --dt or choose one of those methods.\n")
    assert result.stdout == ""
    result = runner.invoke(cli, ["simulate", "--method", "cromer-euler", "--dt", "0.001",
                                 "--duration", "1", "--rate", "10"])
    assert result.exit_code == 0


def test_unwritable_output_is_one_error_line(runner, tmp_path):
    result = runner.invoke(cli, ["simulate", "-o", str(tmp_path / "missing" / "rec.csv")])
    assert result.exit_code == 1
    assert result.stderr.startswith("Error: cannot write ")
    assert result.stderr.count("\n") == 1


@pytest.mark.parametrize("option, value", [("--y0", "0"), ("--rate", "-5"), ("--c", "-1"),
                                           ("--period", "nan"), ("--a", "abc")])
def test_bad_values_are_usage_errors(runner, option, value):
    result = runner.invoke(cli, ["simulate", option, value])
    assert result.exit_code == 2
    assert f"Invalid value for '{option}'" in result.stderr


def test_help_and_version(runner):
    result = runner.invoke(cli, ["simulate", "--help"])
    assert result.exit_code == 0
    assert "mcfit simulate --a 0.1 --b 0.1 --c 0.01 --y0 4 --period 0.5" in result.stdout
    result = runner.invoke(cli, ["--version"])
    assert result.stdout == f"mcfit {mcfit.__version__}\n"


def test_python_dash_m_runs_the_same_command(tmp_path):
    result = subprocess.run([sys.executable, "-m", "mcfit", "simulate", "--duration", "0.5",
                             "--rate", "10", "--b", "0.1"], capture_output=True, text=True,
                            check=True)
    assert result.stdout.splitlines()[0] == "t,x"
    assert len(result.stdout.splitlines()) == 7


def test_group_can_route_to_a_default_command(runner):
    """The hook behind ``mcfit FILE...`` (an implicit ``fit``), shown on a stand-in group."""

    class Group(McfitGroup):
        default_command = "echo"

    @click.group(cls=Group)
    def group():
        pass

    @group.command()
    @click.argument("files", nargs=-1)
    def echo(files):
        click.echo(" ".join(files))

    group.add_command(cli.commands["simulate"])
    assert runner.invoke(group, ["a.csv", "b.csv"]).stdout == "a.csv b.csv\n"
    assert runner.invoke(group, ["echo", "x"]).stdout == "x\n"
    assert runner.invoke(group, ["simulate", "--duration", "0", "--rate", "8"]).stdout == \
        "t,x\n0,1\n"

