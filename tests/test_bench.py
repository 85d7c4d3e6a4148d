"""``mcfit bench``: a smoke run of each section on a tiny grid. No test asserts a time."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit import bench, decay
from mcfit.bounds import waveform_crlb
from mcfit.cli import cli

TINY = dataclasses.replace(
    bench.QUICK, name="tiny", steps_per_period=(50, 100), rtols=(1e-6,), snrs=(1e3,),
    samples_per_cycle=(20,), repeats=2, batch_records=2, batch_samples=2000, startup_runs=1,
    method_records=1, method_qs=(5,),
    integrator_scenes=(bench.IntegratorScene("short Fig. 20.19", 0.1, 0.1, 0.01, 4.0, 0.5, 2.0),),
    fit_scenes=(bench.FitScene("short b", "b", 1.0, 0.0, 0.05, 0.0, 1.0, 30),
                bench.FitScene("short abc", "abc", 4.0, 0.1, 0.1, 0.01, 0.5, 20)))


@pytest.fixture
def rng():
    return np.random.default_rng(6)


def test_quick_fitting_section_prints_every_method(monkeypatch):
    monkeypatch.setattr(bench, "QUICK", dataclasses.replace(TINY, name="quick"))
    result = CliRunner().invoke(cli, ["bench", "--section", "fitting", "--repeats", "2"])
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "mcfit bench (quick)" in out
    assert "over 2 records per row" in out
    for method in ("mcfit (b forced)", "mcfit (abc forced)", "mcfit (selected)",
                   "log decrement", "Hilbert envelope"):
        assert method in out
    assert "Integrators:" not in out and "Throughput:" not in out
    assert "fitting: short b" in result.stderr  # progress goes to stderr


def test_every_section_runs_and_writes_the_plots(tmp_path):
    blocks = list(bench.run(TINY, plot_dir=tmp_path / "plots"))
    text = "\n".join(blocks)
    for heading in ("Integrators:", "Fitting:", "Methods against Q", "Throughput:", "records/s",
                    "mcfit --help", "peak resident memory"):
        assert heading in text
    for setting in ("dt = T/50", "dt = T/100", "rtol 1e-06", "closed form"):
        assert setting in text
    throughput = blocks[-1]
    assert throughput.startswith("Throughput:")
    assert throughput.count(" 2/2") == 3  # in memory, mcfit DIR --jobs 1 and 2: both fitted
    stages = throughput.split("by record length:")[1].split("\n\n")[0].splitlines()[2:]
    assert [int(row.split()[0]) for row in stages] == [200, 2000]
    for row in stages:  # turning points + fit = total > 0, and records/s its inverse
        turning, fitting, total, rate = map(float, row.split()[1:])
        assert total == pytest.approx(turning + fitting, abs=0.11) and total > 0
        assert rate == pytest.approx(1e3 / total, rel=0.1)
    for name in ("integrators.png", "fitting.png"):
        assert (tmp_path / "plots" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bench_help_lists_the_options():
    result = CliRunner().invoke(cli, ["bench", "--help"])
    assert result.exit_code == 0
    for option in ("--full", "--section", "--repeats", "--seed", "--output-dir"):
        assert option in result.output


def test_unknown_section_is_refused():
    with pytest.raises(ValueError, match="unknown bench sections"):
        list(bench.run(TINY, sections=("speed",)))


def test_reference_methods_recover_b_without_noise():
    period, b = 1.0, 0.02
    t = np.arange(0, 100, 1 / 20.29)
    x = 0.1 + decay.amplitude(t, 1.0, 0.0, b, 0.0) * np.cos(2 * np.pi * t / period + 0.3)
    assert bench.hilbert_envelope_rate(t, x, period) == pytest.approx(b, rel=1e-2)
    assert bench.log_decrement_rate(t, x, period) == pytest.approx(b, rel=5e-2)


def test_crlb_of_b_matches_a_pure_exponential_by_hand():
    # With phase, omega and x_eq known, the bound of b for y0*exp(-b*t)*cos(w*t) follows
    # from the 2x2 Fisher matrix in (y0, b); the full bound (5 parameters) is no smaller.
    t = np.arange(0, 50, 0.05)
    y0, b, sigma = 1.0, 0.05, 1e-3
    carrier = np.cos(2 * np.pi * t)
    y = y0 * np.exp(-b * t)
    design = np.column_stack([y / y0 * carrier, -t * y * carrier])
    by_hand = math.sqrt(np.linalg.inv(design.T @ design)[1, 1]) * sigma
    bound = waveform_crlb(t, y0, 0.0, b, 0.0, 1.0, sigma, "b")["b"]
    assert by_hand <= bound <= 1.1 * by_hand
