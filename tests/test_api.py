"""The Python interface: analyse, analyse_file, analyse_files and what an Analysis offers."""

import doctest
import html
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

import mcfit
from mcfit import report
from mcfit.errors import FitError, UsageError

ROOT = Path(__file__).parents[1]
SAMPLES = ROOT / "sample_data"


@pytest.fixture(scope="module")
def fig_20_19():
    return mcfit.analyse_file(str(SAMPLES / "fig20_19_all_three.csv"))


def test_the_readme_example_runs(monkeypatch):
    monkeypatch.chdir(ROOT)  # its paths are the fresh clone's
    result = doctest.testfile(str(ROOT / "README.md"), module_relative=False,
                              optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted >= 10 and result.failed == 0


def test_the_docstring_examples_run():
    import mcfit.api

    result = doctest.testmod(mcfit.api, optionflags=doctest.ELLIPSIS)
    assert result.attempted >= 5 and result.failed == 0


def test_an_analysis_speaks_the_command_lines_contract(fig_20_19):
    assert fig_20_19.summary() == json.loads(report.to_json(fig_20_19))
    assert fig_20_19.report() == report.to_text(fig_20_19)
    text = repr(fig_20_19)
    assert text.startswith("Analysis(source=") and "model='abc'" in text and len(text) < 200
    table = fig_20_19.turning_points
    assert len(table) == fig_20_19.turning.count
    np.testing.assert_allclose(table["t"], fig_20_19.turning.t)
    used = table[table["used"]]
    np.testing.assert_allclose(used["envelope"], fig_20_19.fit.y_fit)


def test_plot_and_figure_draw_without_a_display(fig_20_19, tmp_path):
    ax = fig_20_19.plot()
    assert ax.get_title() == "record and turning points" and len(ax.lines) >= 4
    figure = fig_20_19.figure(title="Fig. 20.19")
    figure.savefig(tmp_path / "fig.png")
    assert (tmp_path / "fig.png").stat().st_size > 10_000
    failed = mcfit.analyse(np.arange(50.0), np.ones(50))
    assert failed.status == "error" and "status='error'" in repr(failed)
    with pytest.raises(FitError, match="was not fitted"):
        failed.plot()


def test_analyse_takes_arrays_or_a_simulated_record():
    truth = 0.05
    record = mcfit.simulate_record(a=0.0, b=truth, c=0.0, y0=1.0, period=1.0, duration=20.0,
                                   rate=100.0, noise=1e-3, rng=3)
    t, x = record  # still unpacks as the arrays
    for result in (mcfit.analyse(record), mcfit.analyse(t, x, source="by hand")):
        assert result.fit.model == "b"
        assert abs(result.fit.values["b"] - truth) < 4 * result.fit.stderr["b"]
    assert mcfit.analyse(t, x, source="by hand").source == "by hand"
    forced = mcfit.analyse(record, model="ab", method="turning-points")
    assert forced.fit.model == "ab" and forced.fit.method == "turning-points"


def test_options_are_checked_in_python_words():
    record = mcfit.simulate_record(0.0, 0.05, 0.0, 1.0, 1.0, 10.0, 100.0)
    with pytest.raises(UsageError, match="unknown options: colour"):
        mcfit.analyse(record, colour="red")
    with pytest.raises(UsageError, match="unknown options: time_col"):
        mcfit.analyse(record, time_col="t")  # arrays have no columns
    with pytest.raises(UsageError, match="1-D arrays of one length"):
        mcfit.analyse(np.arange(5.0), np.arange(4.0))


# Contradictory options: the library's words, and the command line's flags for the same
# check (one place makes it; exit 2 before any file is read).
CONTRADICTIONS = [
    (dict(pendulum=True, bootstrap=5), ["--pendulum", "--bootstrap", "5"],
     "`bootstrap` is not available with `pendulum` yet."),
    (dict(pendulum=True, method="waveform"), ["--pendulum", "--method", "waveform"],
     "`method` is not available with `pendulum`"),
    (dict(pendulum=True, model="power"), ["--pendulum", "--model", "power"],
     "`model=power` is not available with `pendulum`."),
    (dict(start=5.0, end=1.0), ["--start", "5", "--end", "1"],
     "`start=5` must come before `end=1`."),
    (dict(model="bacon"), ["--model", "bacon"], "`model` 'bacon' is not a set of damping terms"),
    (dict(rate=100.0, time_col="t"), ["--rate", "100", "--time-col", "t"],
     "give either `time_col` or `rate` (time from the sample index), not both."),
    (dict(signal_col="x", angle_from=("x", "t")), ["--signal-col", "x", "--angle-from", "x,t"],
     "give `angle_from` or `signal_col`, not both"),
]


@pytest.mark.parametrize("keywords, arguments, message", CONTRADICTIONS)
def test_each_check_is_made_once_for_python_and_the_command_line(tmp_path, keywords,
                                                                  arguments, message):
    from click.testing import CliRunner

    from mcfit.cli import cli
    from mcfit.options import for_command_line

    path = tmp_path / "record.csv"
    record = mcfit.simulate_record(0.0, 0.05, 0.0, 1.0, 1.0, 10.0, 100.0)
    path.write_text("t,x\n" + "".join(f"{t!r},{x!r}\n" for t, x in zip(*record)))
    with pytest.raises(UsageError) as raised:
        mcfit.analyse_files([str(path)], **keywords)
    assert message in str(raised.value)
    fit_only = {k: v for k, v in keywords.items() if k not in ("rate", "time_col",
                                                                 "signal_col", "angle_from")}
    if fit_only == keywords:
        with pytest.raises(UsageError, match=re.escape(message)):
            mcfit.analyse(record, **keywords)
    result = CliRunner().invoke(cli, [str(path), *arguments])
    assert result.exit_code == 2
    assert for_command_line(message) in result.stderr


def test_files_and_runs():
    capstone = str(SAMPLES / "capstone_runs.csv")
    with pytest.raises(UsageError, match="5 runs side by side; give run=N"):
        mcfit.analyse_file(capstone)
    second = mcfit.analyse_file(capstone, run=2, method="turning-points")
    assert second.source == f"{capstone}#Run 2" and second.fit.model == "bc"
    table = mcfit.analyse_files([capstone, str(SAMPLES / "coulomb_stop.csv")],
                                method="turning-points")
    assert list(table.columns) == list(report.csv_columns())
    assert table["source"].tolist()[:2] == [f"{capstone}#Run 1", f"{capstone}#Run 2"]
    assert table["run"].isna().tolist() == [False] * 5 + [True]
    assert (table["status"] == "ok").all()
    np.testing.assert_allclose(table["b"][1], second.fit.values["b"])
    # Python words in Python: the options are named as keywords, not as flags.
    [missing] = mcfit.analyse_files([capstone], run=9)["error"]
    assert missing.endswith("Give one of those numbers to `run`.")


def test_fit_decay_refuses_a_raw_waveform():
    t = np.arange(0.0, 30.0, 0.01)
    x = np.exp(-0.1 * t) * np.cos(2 * np.pi * t)
    for signal in (x, x + 3.0):  # about zero, and on an offset
        with pytest.raises(FitError, match="mcfit.analyse"):
            mcfit.fit_decay(t, signal)
    # Amplitudes that scatter in the noise, or fall, are amplitudes.
    rng = np.random.default_rng(0)
    n = np.arange(200.0)
    assert mcfit.fit_decay(n, 1.0 + rng.normal(0.0, 0.01, n.size)).model == "none"
    assert mcfit.fit_decay(n, np.exp(-0.01 * n) + rng.normal(0, 1e-3, n.size)).status == "ok"


def test_the_package_lists_its_names():
    assert {"analyse", "analyse_file", "analyse_files", "Record"} <= set(dir(mcfit))


def test_the_cramer_rao_bounds_against_the_fisher_matrix_by_hand():
    """Exponential decay: dy/dy0 = exp(-b t), dy/db = -t y0 exp(-b t)."""
    import mcfit.bounds

    assert doctest.testmod(mcfit.bounds).failed == 0
    t, y0, b, sigma = np.arange(0.0, 50.0, 0.5), 1.0, 0.02, 1e-3
    e = np.exp(-b * t)
    design = np.column_stack([e, -t * y0 * e]) / sigma
    by_hand = math.sqrt(np.linalg.inv(design.T @ design)[1, 1])
    assert mcfit.amplitude_crlb(t, y0, 0.0, b, 0.0, sigma, "b")["b"] == pytest.approx(
        by_hand, rel=1e-9)
    # A waveform: the same with the carrier, plus frequency, phase and offset columns.
    omega = 2 * math.pi
    c, s = np.cos(omega * t), np.sin(omega * t)
    design = np.column_stack([e * c, -t * y0 * e * c, -y0 * e * t * s, -y0 * e * s,
                              np.ones_like(t)]) / sigma
    by_hand = math.sqrt(np.linalg.inv(design.T @ design)[1, 1])
    assert mcfit.waveform_crlb(t, y0, 0.0, b, 0.0, 1.0, sigma, "b")["b"] == pytest.approx(
        by_hand, rel=1e-9)


def test_bad_values_are_refused_by_the_shared_checks(tmp_path):
    from mcfit.analysis import fit_turning_points
    from mcfit.options import check_plot_name, parse_figsize
    from mcfit.turning import find_turning_points

    path = tmp_path / "record.csv"
    record = mcfit.simulate_record(0.0, 0.05, 0.0, 1.0, 1.0, 10.0, 100.0)
    path.write_text("t,x\n" + "".join(f"{t!r},{x!r}\n" for t, x in zip(*record)))
    for rate in (-5, "x"):
        with pytest.raises(UsageError, match="`rate` must be a"):
            mcfit.analyse_files([str(path)], rate=rate)  # once, not a row a file
    with pytest.raises(UsageError, match="`bootstrap` is not available with `pendulum`"):
        fit_turning_points(find_turning_points(*record), pendulum=True, bootstrap=5)
    with pytest.raises(UsageError, match="`figsize` 12"):
        parse_figsize(12)
    for name in (".png", "figure.gif", "figure"):
        with pytest.raises(UsageError, match="must end in .png, .pdf or .svg"):
            check_plot_name(name)
    check_plot_name("plots/figure.PDF")


def test_fit_results_have_a_short_repr(fig_20_19):
    """print(analysis.fit) gives the model, the kept coefficients with their errors, Q
    and the goodness of fit on one line, not the arrays."""
    fit = fig_20_19.fit
    text = repr(fit)
    assert "\n" not in text and len(text) < 300 and "array" not in text
    assert text.startswith("<DecayFit abc by turning points: y0 = ")
    for k in "abc":
        assert f"{k} = {fit.values[k]:.4g} +- {fit.stderr[k]:.2g}" in text
    assert f"Q initial {fit.q_summary['initial']:.4g}" in text
    assert text.endswith(f"; {fit.n_points} turning points, reduced chi-square "
                         f"{fit.reduced_chi_square:.3g}>")
    path = str(SAMPLES / "capstone_runs.csv")
    waveform = mcfit.analyse_file(path, run=4, method="waveform").fit
    assert repr(waveform).startswith("<WaveformFit bc by waveform:")
    assert f"{waveform.n_points} samples" in repr(waveform)
    power = mcfit.analyse_file(str(SAMPLES / "fig20_19_all_three.csv"), model="power").fit
    assert repr(power).startswith("<PowerLawFit power by turning points: y0 = ")
    assert " n = " in repr(power) and len(repr(power)) < 300


def test_a_pendulum_fit_has_the_short_repr_too():
    t = np.arange(0.0, 60.0, 0.02)
    theta = 0.6 * np.exp(-0.03 * t) * np.cos(2 * np.pi * t)
    fit = mcfit.analyse(t, theta, pendulum=True, model="b").fit
    assert repr(fit).startswith("<PendulumFit b by turning points: y0 = ")
    assert len(repr(fit)) < 300


def test_a_notebook_shows_the_report_and_the_figure_on_request(fig_20_19):
    page = fig_20_19._repr_html_()
    assert page.startswith("<pre>") and page.endswith("</pre>")
    assert html.unescape(page[5:-6]) == fig_20_19.report()
    assert fig_20_19._repr_mimebundle_() == {}  # not drawn unless asked for
    assert fig_20_19._repr_mimebundle_(include={"text/html"}) == {}
    png = fig_20_19._repr_mimebundle_(include={"image/png"})["image/png"]
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    failed = mcfit.analyse(np.arange(50.0), np.ones(50))
    assert "status: error" in failed._repr_html_()
    assert failed._repr_mimebundle_(include={"image/png"}) == {}
