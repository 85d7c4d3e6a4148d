"""A package people can install, cite and read (issue 40): its name and licence, the README's
commands as CI runs them, the version in every output, a bootstrap that can be repeated,
--quiet, --unit for every output, file names completed in the shell, and a noise-free
record fitted the same way on any processor."""

from __future__ import annotations

import csv
import io
import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from click.shell_completion import ShellComplete
from click.testing import CliRunner

import mcfit
from mcfit import cli as cli_module
from mcfit.cli import cli
from mcfit.report import BOOTSTRAP_CSV_COLUMNS, CSV_COLUMNS

ROOT = Path(__file__).parents[1]
SAMPLES = ROOT / "sample_data"
FIG_20_19 = str(SAMPLES / "fig20_19_all_three.csv")
LOGGER_PRO = str(SAMPLES / "logger_pro.txt")  # header 'Position (m)'
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))


def _run(*arguments):
    return CliRunner().invoke(cli, [str(a) for a in arguments])


# --- name, licence, citation, the README's commands --------------------------------------


def test_the_distribution_has_a_free_name_and_installs_mcfit():
    project = PYPROJECT["project"]
    assert project["name"] == "mcfit-damping"  # mcfit on PyPI is another project
    assert project["scripts"] == {"mcfit": "mcfit.cli:main"}
    assert project["version"] == mcfit.__version__
    assert project["license"] == {"text": "MIT"}
    licence = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert licence.startswith("MIT License\n\nCopyright (c) 2026 the mcfit developers\n")


def test_the_citation_has_the_package_version_and_cites_the_handbook():
    citation = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    fields = dict(re.findall(r"^([a-z-]+): (.*)$", citation, flags=re.MULTILINE))
    assert fields["cff-version"] == "1.2.0"
    assert fields["version"].strip('"') == mcfit.__version__ == PYPROJECT["project"]["version"]
    assert fields["license"] == "MIT"
    assert 'collection-title: "Vibration and Shock Handbook"' in citation
    assert 'title: "Damping Theory"' in citation and "year: 2005" in citation


def _readme():
    return (ROOT / "README.md").read_text(encoding="utf-8")


def test_ci_runs_the_readme_test_command_as_written():
    quick_start = _readme().split("## Quick start", 1)[1].split("```sh\n", 1)[1]
    install_and_fit, install_and_test = quick_start.split("\n```", 1)[0].splitlines()
    assert install_and_fit.startswith("python3 -m venv .venv && .venv/bin/pip install . && ")
    assert install_and_test.startswith("python3 -m venv .venv && ")
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    commands = [line for line in ci if line.strip() and not line.startswith(("#", "set ",
                                                                               "cd ", "export "))]
    assert commands == [install_and_test]


def test_every_install_line_names_this_distribution():
    """pip install mcfit (or mcfit[dask]) would install the other project: only the
    sentence that says so may name it."""
    texts = [_readme()] + [p.read_text(encoding="utf-8") for p in (ROOT / "docs").rglob("*.md")]
    bare = re.compile(r"pip install\s+(['\"]?)mcfit(\[[^\]]*\])?\1(?![-\w])")
    found = [text[m.start():m.end() + 29] for text in texts for m in bare.finditer(text)]
    assert found and all(f == "pip install mcfit` installs that one, not this" for f in found)
    assert "pip install 'mcfit-damping[dask]'" in _readme()
    from mcfit.dask_jobs import INSTALL_HINT

    assert INSTALL_HINT.endswith("pip install 'mcfit-damping[dask]'")


def test_a_dask_worker_reports_the_mcfit_it_imports():
    from mcfit.dask_jobs import _worker_version

    assert _worker_version() == mcfit.__version__


# --- provenance: the version, the bootstrap's seed -------------------------------------


def test_json_and_csv_say_which_mcfit_wrote_them():
    result = _run(FIG_20_19, "--format", "json")
    assert result.exit_code == 0, result.output
    line = json.loads(result.stdout)
    assert line["mcfit_version"] == mcfit.__version__
    assert list(line)[-1] == "mcfit_version"  # added last: the other keys keep their order
    result = _run(FIG_20_19, "--format", "csv")
    header, row = csv.reader(io.StringIO(result.stdout))
    assert header == [*CSV_COLUMNS, "mcfit_version"]  # appended: columns keep their numbers
    assert row[-1] == mcfit.__version__
    failed = _run(str(SAMPLES / "make_samples.py"), "--format", "json")
    assert failed.exit_code == 1
    assert json.loads(failed.stdout)["mcfit_version"] == mcfit.__version__


def test_the_figure_files_say_which_mcfit_drew_them(tmp_path):
    from PIL import Image

    from mcfit.plots import save_figure

    png = tmp_path / "fig.png"
    result = _run(FIG_20_19, "--plot", png)
    assert result.exit_code == 0, result.output
    assert Image.open(png).text["Software"].startswith(f"mcfit {mcfit.__version__} (matplotlib ")
    figure = mcfit.analyse_file(FIG_20_19).figure()
    save_figure(figure, tmp_path / "fig.pdf")
    save_figure(figure, tmp_path / "fig.svg")
    pdf = (tmp_path / "fig.pdf").read_bytes()
    assert f"/Creator (mcfit {mcfit.__version__})".encode() in pdf
    assert f"/Producer (mcfit {mcfit.__version__} \\(matplotlib ".encode() in pdf
    svg = (tmp_path / "fig.svg").read_text(encoding="utf-8")
    assert re.search(r"<dc:creator>\s*<cc:Agent>\s*<dc:title>mcfit "
                     + re.escape(mcfit.__version__), svg)


def _intervals(stdout):
    return json.loads(stdout)["bootstrap"]["interval_95"]


def test_an_unseeded_bootstrap_reports_the_seed_that_repeats_it():
    first = _run(FIG_20_19, "--bootstrap", "8", "--format", "json")
    assert first.exit_code == 0, first.output
    seed = json.loads(first.stdout)["bootstrap"]["seed"]
    assert isinstance(seed, int) and seed >= 0
    again = _run(FIG_20_19, "--bootstrap", "8", "--format", "json", "--seed", seed)
    assert json.loads(again.stdout)["bootstrap"]["seed"] == seed
    assert _intervals(again.stdout) == _intervals(first.stdout)
    other = _run(FIG_20_19, "--bootstrap", "8", "--format", "json")
    assert json.loads(other.stdout)["bootstrap"]["seed"] != seed  # drawn afresh (p = 2^-32)
    text = _run(FIG_20_19, "--bootstrap", "8", "--seed", seed).stdout
    assert f"), seed {seed}; 95 % intervals:" in text


def test_the_library_reports_the_seed_too():
    record = mcfit.simulate_record(a=0.0, b=0.05, c=0.01, y0=1.0, period=1.0, duration=30.0,
                                   rate=50.0, noise=0.002, rng=3)
    drawn = mcfit.analyse(record, bootstrap=6).fit.bootstrap
    repeated = mcfit.analyse(record, bootstrap=6, seed=drawn["seed"]).fit.bootstrap
    assert repeated == drawn
    given = mcfit.analyse(record, bootstrap=6, seed=7).summary()["bootstrap"]
    assert given["seed"] == 7
    # A generator of one's own: its seed is not known to mcfit.
    own = mcfit.analyse_record(record, bootstrap=6, rng=np.random.default_rng(7))
    assert own.fit.bootstrap["seed"] is None
    assert own.fit.bootstrap["interval_95"] == given["interval_95"]


# --- --quiet ------------------------------------------------------------------------------


@pytest.fixture
def folder(tmp_path):
    """Two records and a subfolder (a note says it is left out)."""
    for name in ("fig20_19_all_three.csv", "coulomb_stop.csv"):
        (tmp_path / name).write_bytes((SAMPLES / name).read_bytes())
    (tmp_path / "more").mkdir()
    return tmp_path


def test_quiet_leaves_out_notes_and_progress_but_not_errors(folder, monkeypatch):
    monkeypatch.setattr(cli_module, "_is_terminal", lambda stream: True)  # a progress bar
    loud = _run(folder, "--format", "csv")
    assert loud.exit_code == 0, loud.output
    assert "Note: " in loud.stderr and "left out its subfolders" in loud.stderr
    assert "fitting" in loud.stderr  # the progress bar's label
    for flag in ("--quiet", "-q"):
        quiet = _run(folder, "--format", "csv", flag)
        assert quiet.exit_code == 0 and quiet.stderr == ""
        assert quiet.stdout == loud.stdout
    (folder / "empty.csv").write_text("t,x\n", encoding="utf-8")
    failing = _run(folder, "--format", "csv", "-q")
    assert failing.exit_code == 1
    assert failing.stderr.startswith("Error: ") and "empty.csv" in failing.stderr
    assert len(failing.stderr.splitlines()) == 1


# --- --unit ------------------------------------------------------------------------------


def test_unit_names_the_signal_in_text_json_and_csv_without_a_figure():
    result = _run(FIG_20_19, "--unit", "mm")
    assert result.exit_code == 0, result.output  # it was a usage error without --plot
    assert re.search(r"a \(fluid\) +0\.0998\S* \+- \S+ +1/\(mm\*s\)", result.stdout)
    assert re.search(r"c \(Coulomb\) +0\.0099\S* \+- \S+ +mm/s", result.stdout)
    assert "U: the signal's unit" not in result.stdout
    plain = json.loads(_run(FIG_20_19, "--format", "json").stdout)
    named = json.loads(_run(FIG_20_19, "--format", "json", "--unit", "mm").stdout)
    assert (plain["signal_unit"], named["signal_unit"]) == (None, "mm")
    assert named["coefficient_units"] == {"y0": "mm", "a": "1/(mm*s)", "b": "1/s",
                                          "c": "mm/s"}
    assert named["params"] == plain["params"]  # names, not numbers
    row = next(csv.DictReader(io.StringIO(
        _run(FIG_20_19, "--format", "csv", "--unit", "mm").stdout)))
    assert (row["signal_unit"], row["y0_unit"], row["a_unit"], row["c_unit"]) == (
        "mm", "mm", "1/(mm*s)", "mm/s")


def test_unit_overrides_the_header_with_a_note():
    header = json.loads(_run(LOGGER_PRO, "--format", "json").stdout)
    assert header["signal_unit"] == "m"
    named = json.loads(_run(LOGGER_PRO, "--format", "json", "--unit", "cm").stdout)
    assert named["signal_unit"] == "cm" and named["coefficient_units"]["a"] == "1/(cm*s)"
    assert "signal unit: cm, as --unit says, in place of the header's m" in named["notes"]
    assert named["params"] == header["params"]


def test_unit_in_python_reaches_every_output():
    from mcfit.plots import record_view

    result = mcfit.analyse_file(FIG_20_19, unit="mm")
    assert result.summary()["coefficient_units"]["a"] == "1/(mm*s)"
    assert "1/(mm*s)" in result.report()
    assert record_view(result).unit == "mm"  # the figure's axes
    table = mcfit.analyse_files([LOGGER_PRO], unit="cm")
    assert table.loc[0, "signal_unit"] == "cm" and table.loc[0, "a_unit"] == "1/(cm*s)"
    t = np.arange(0.0, 20.0, 0.01)
    x = np.exp(-0.1 * t) * np.cos(2 * np.pi * t) + 1e-3 * np.random.default_rng(1).normal(
        size=t.size)
    assert mcfit.analyse(t, x, unit="V").summary()["coefficient_units"]["c"] == "V/s"


# --- shell completion -------------------------------------------------------------------------


def _completions(words, incomplete):
    complete = ShellComplete(cli, {}, "mcfit", "_MCFIT_COMPLETE")
    return [(item.type, item.value) for item in complete.get_completions(words, incomplete)]


def test_fit_completes_file_names():
    assert _completions(["fit"], "sam") == [("file", "sam")]
    assert _completions(["fit", FIG_20_19], "") == [("file", "")]
    assert ("plain", "--unit") in _completions(["fit"], "--un")


def test_the_default_command_completes_file_names_and_the_commands():
    offered = _completions([], "")
    assert {("plain", "fit"), ("plain", "simulate"), ("plain", "bench"),
            ("file", "")} <= set(offered)
    assert _completions([], "sam") == [("file", "sam")]
    # A record named first: the default command's arguments; no error for a name that
    # is neither a file nor a command (it would be a usage error when run).
    assert _completions([FIG_20_19], "") == [("file", "")]
    assert _completions(["fitt"], "x") == [("file", "x")]


def test_the_shell_gets_file_completion_from_the_command():
    """As bash asks: the command run with _MCFIT_COMPLETE=bash_complete."""
    environment = {**os.environ, "_MCFIT_COMPLETE": "bash_complete",
                   "COMP_WORDS": "mcfit fit sample_data/fig", "COMP_CWORD": "2"}
    done = subprocess.run([sys.executable, "-m", "mcfit"], capture_output=True, text=True,
                          env=environment, cwd=ROOT, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["file,sample_data/fig"]


# --- a noise-free record is fitted the same way on any processor ---------------------------


def _pendulum_swing():
    t = np.arange(0.0, 60.0, 0.02)
    return t, 0.6 * np.exp(-0.03 * t) * np.cos(2 * np.pi * t)


@pytest.mark.parametrize("seed", range(6))
def test_a_noise_free_record_has_no_noise_whatever_its_last_bits(seed):
    """Rounding the samples differently (a processor's fused multiply-add, another
    library's exp) moves each by an ulp or two: the record's noise stays 0, not the last
    bits (4e-10 from one rounding, which made the pendulum's fit a waveform fit at
    reduced chi-square 2.5e12), and the turning-point fit is kept."""
    t, theta = _pendulum_swing()
    ulps = np.random.default_rng(seed).integers(-2, 3, t.size)
    x = theta * (1.0 + np.finfo(float).eps * ulps)
    assert mcfit.find_turning_points(t, x).noise_sigma == 0.0
    fit = mcfit.analyse(t, x, pendulum=True, model="b").fit
    assert type(fit).__name__ == "PendulumFit" and fit.method == "turning-points"
    assert fit.values["b"] == pytest.approx(0.03, rel=0.01)


def test_noise_above_the_rounding_is_still_measured():
    t, theta = _pendulum_swing()
    for sigma in (1e-7, 1e-5):
        noise = sigma * np.random.default_rng(2).standard_normal(t.size)
        assert mcfit.find_turning_points(t, theta + noise).noise_sigma == pytest.approx(
            sigma, rel=0.1)
