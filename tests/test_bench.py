"""``mcfit bench``: a smoke run of each section on a tiny grid. No test asserts a time."""

from __future__ import annotations

import dataclasses
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit import bench, decay
from mcfit.bench import cycles, edges
from mcfit.bench.throughput import CommandRate
from mcfit.bench.timing import (ChildRun, bytecode_environment, child_environment,
                                fastest_in_turn, run_child)
from mcfit.bench.verdicts import _fluid_at
from mcfit.bounds import waveform_crlb
from mcfit.cli import cli

TINY = dataclasses.replace(
    bench.QUICK, name="tiny", steps_per_period=(50, 100), rtols=(1e-6,), snrs=(1e3,),
    samples_per_cycle=(20,), repeats=2, batch_records=2, batch_samples=2000, batch_files=3,
    batch_methods=("turning-points",), startup_runs=1, verdict_records=4, method_records=1, method_qs=(5,),
    integrator_scenes=(bench.IntegratorScene("short Fig. 20.19", 0.1, 0.1, 0.01, 4.0, 0.5, 2.0),),
    fit_scenes=(bench.FitScene("short b", "b", 1.0, 0.0, 0.05, 0.0, 1.0, 30),
                bench.FitScene("short abc", "abc", 4.0, 0.1, 0.1, 0.01, 0.5, 20)),
    edge_records=1, edge_scenes=edges.EDGE_SCENES[-3:], mixed_records=2)

# Issue 17's targets, one line each in the throughput section.
TARGETS = ("turning points + fit per record", "the same with --method auto's choice",
           "mcfit DIR --jobs 1, --method turning-points", "mcfit DIR --jobs 1, --method auto",
           "--jobs 2 / --jobs 1 (wall), --method turning-points",
           "--jobs 2 / --jobs 1 (wall), --method auto", "one-record run / import floor",
           "mcfit --help / import click", "10^7 samples: time",
           "10^7 samples: peak memory / file size")


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


def _table(text, heading):
    """The rows under ``heading`` up to the next blank line, split into cells."""
    block = text.split(heading, 1)[1].split("\n\n")[0].splitlines()
    return [row.split() for row in block[2:] if row.strip() and not row.strip().startswith("(")]


def test_every_section_runs_and_writes_the_plots(tmp_path, monkeypatch):
    monkeypatch.setattr(cycles, "QUICK_CYCLES", (100, 200))
    blocks = list(bench.run(TINY, plot_dir=tmp_path / "plots"))
    text = "\n".join(blocks)
    for heading in ("Integrators:", "Fitting:", "Verdicts and 95 %", "Methods against Q",
                    "Cycles:", "us/cycle", "Edges:", "Throughput:", "rec/s",
                    "mcfit --help", "peak resident memory", "Waveform:", "mixed batch"):
        assert heading in text
    for setting in ("dt = T/50", "dt = T/100", "rtol 1e-06", "closed form"):
        assert setting in text
    throughput = blocks[-1]
    assert throughput.startswith("Throughput:")
    for target in TARGETS:  # each target on one line, with its target and a verdict
        lines = [line for line in throughput.splitlines() if target in line]
        assert len(lines) == 1, target
        assert re.search(r"target [<>]=? [\d.]+ ?(ms|rec/s|x|s)\s+(met|NOT MET|-)$", lines[0])
    assert "on 3 files, not the 200 of the target; --full runs 200" in throughput
    assert "10^7 samples: time" in throughput and "not run" in throughput
    assert "mcfit bench --full --section throughput" in throughput
    commands = [row for row in _table(throughput, "removed by a one-file run:")
                if row[0] == "turning-points"]
    assert [row[1] for row in commands] == ["1", "2"]
    assert all(row[-2] == "3/3" for row in commands)  # the real command fitted every file
    assert "mcfit DIR --jobs 1, --method auto (default)" in throughput  # not run in TINY
    stages = _table(throughput, "read from CSV:")
    assert [int(row[0]) for row in stages] == [200, 2000]
    for row in stages:  # turning points + fit = TP + fit > 0, and records/s its inverse
        _, turning, fitting, total, rate = map(float, row[1:])
        assert total == pytest.approx(turning + fitting, abs=0.11) and total > 0
        # The total is printed to 0.1 ms and the rate, from the unrounded total, to 0.1.
        assert 1e3 / (total + 0.05) - 0.05 <= rate <= 1e3 / max(total - 0.05, 1e-9) + 0.05
    where = throughput.split("--method auto on the ", 1)[1]
    fitted = int(where.split()[0])
    kept = int(re.search(r"\): (\d+) kept", where).group(1))
    sent = 0 if "none went to the waveform fit" in where else int(
        re.search(r"\n  (\d+) went to the waveform fit", where).group(1))
    assert fitted == 2 and kept + sent == fitted
    for name in ("integrators.png", "fitting.png"):
        assert (tmp_path / "plots" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_command_rate_removes_the_start_up_of_a_one_file_run():
    def run(wall, cpu):
        return ChildRun(wall, cpu, None, 0)

    rate = CommandRate("auto", 1, 41, run(6.0, 5.0), run(2.0, 1.5), 41, 0)
    assert rate.rate == pytest.approx(40 / 4.0) and rate.cpu_rate == pytest.approx(40 / 3.5)
    noisy = CommandRate("auto", 1, 41, run(2.0, None), run(2.5, 1.0), 41, 0)
    assert math.isnan(noisy.rate) and math.isnan(noisy.cpu_rate)
    failed = CommandRate("auto", 1, 41, run(6.0, 5.0), run(2.0, 1.5), None, None)
    assert math.isnan(failed.rate)


def test_commands_in_turn_each_keep_their_fastest_run(tmp_path):
    """The commands run one after the other, round after round (A B A B, not A A B B),
    each keeping its fastest run; a command that fails keeps its failed run."""
    log = tmp_path / "order"

    def command(name, code=0):
        return [sys.executable, "-c",
                f"open({str(log)!r}, 'a').write({name!r}); raise SystemExit({code})"]

    runs = fastest_in_turn([(command("A"), None), (command("B"), {}), (command("C", 3), None)],
                           3)
    assert log.read_text() == "ABCABAB"
    assert [run.returncode for run in runs] == [0, 0, 3]


def test_a_child_environment_leaves_out_what_is_set_to_none(monkeypatch):
    monkeypatch.setenv("MCFIT_BENCH_KEPT", "1")
    monkeypatch.setenv("MCFIT_BENCH_DROPPED", "1")
    env = child_environment({"MCFIT_BENCH_DROPPED": None, "MCFIT_BENCH_ADDED": "2"})
    assert env["MCFIT_BENCH_KEPT"] == "1" and env["MCFIT_BENCH_ADDED"] == "2"
    assert "MCFIT_BENCH_DROPPED" not in env


def test_child_processes_find_mcfit_compiled_in_the_given_directory(tmp_path, monkeypatch):
    """Bytecode goes to the directory, none beside mcfit's sources, also where this
    process writes none (PYTHONDONTWRITEBYTECODE); the warm-up commands run there too."""
    import mcfit

    monkeypatch.setenv("PYTHONDONTWRITEBYTECODE", "1")
    package = Path(mcfit.__file__).parent
    before = sorted(package.rglob("*.pyc"))
    marker = tmp_path / "warmed"
    env = bytecode_environment(tmp_path / "cache", warm_up=(
        [sys.executable, "-c", f"open({str(marker)!r}, 'w').close()"],))
    assert env["PYTHONDONTWRITEBYTECODE"] is None and marker.exists()
    compiled = {path.name.split(".")[0] for path in (tmp_path / "cache").rglob("*.pyc")}
    assert {"decay", "analysis", "cli", "timing"} <= compiled
    assert sorted(package.rglob("*.pyc")) == before
    done = run_child([sys.executable, "-c", "import sys; sys.exit(sys.flags.dont_write_bytecode)"],
                     env=env)
    assert done.returncode == 0  # the variable is gone from the child's environment


@pytest.mark.skipif(sys.platform == "win32", reason="no peak memory of a child on Windows")
def test_child_peak_memory_is_in_mib():
    # 100 MiB of ones touched by the child: the peak is that plus the interpreter's. A
    # child's peak counts its parent's resident memory at the fork (Linux keeps it across
    # exec), so the child is started from a fresh interpreter, not from this test worker
    # (hundreds of MiB once the waveform tests have loaded numba).
    code = ("import sys; from mcfit.bench.timing import run_child; "
            "run = run_child([sys.executable, '-c', 'import numpy; numpy.ones(100 * 2**17).sum()']); "
            "print(run.returncode, run.cpu, run.peak_mib)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    returncode, cpu, peak_mib = done.stdout.split()
    assert int(returncode) == 0 and float(cpu) > 0
    assert 100 < float(peak_mib) < 400


def test_bench_imports_without_resource_and_without_the_source_tree(tmp_path):
    # As on Windows (no ``resource``) and from an installed wheel (run away from the tree);
    # matplotlib only when a figure is drawn, pandas only in the child processes.
    code = ("import sys; sys.modules['resource'] = None\n"
            "from mcfit.bench import QUICK, records, throughput, timing\n"
            "t, x = records.throughput_record(QUICK, 0)\n"
            "print(timing.peak_memory_mib(), t.size,\n"
            "      [m for m in ('matplotlib', 'pandas') if m in sys.modules])")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=tmp_path, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["None", "10000", "[]"]


def test_throughput_records_have_the_issue_17_size(rng):
    from mcfit.turning import find_turning_points

    t, x = bench.records.throughput_record(bench.QUICK, 3)
    assert t.size == 10_000
    assert 158 <= find_turning_points(t, x).count <= 160  # issue 17: about 159 crests


def test_large_csv_has_the_promised_rows_and_size(tmp_path):
    path = tmp_path / "large.csv"
    bench.records.write_large_csv(path, 20_000, block=7_000)
    lines = path.read_text().splitlines()
    assert lines[0] == "time (s),position (m),velocity" and len(lines) == 20_001
    assert lines[1].split(",")[0] == "0.000000" and lines[-1].split(",")[0] == "19.999000"
    assert 25 <= path.stat().st_size / 20_000 <= 32  # about 29 bytes a row, as 290 MB/1e7


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


def test_verdicts_fluid_scene_sits_its_bound_from_b_by_hand():
    # y = y0/((1 + a*y0/b)*exp(b*t) - a*y0/b): at a = 0 the derivatives in (y0, a, b) are
    # exp(-b*t), -y0**2*(exp(b*t) - 1)/b * exp(-2*b*t) and -t*y0*exp(-b*t).
    b, noise, t = 0.05, 2e-3, np.arange(0.0, 100.0, 0.5)
    growth = np.exp(b * t)
    design = np.column_stack([1 / growth, -(growth - 1) / b / growth**2, -t / growth])
    by_hand = noise * math.sqrt(np.linalg.inv(design.T @ design)[1, 1])
    assert _fluid_at(3, b, 100.0, noise) == pytest.approx(3 * by_hand, rel=1e-9)


def _cycle_rows(text):
    """The rows of the cycles section's table, as numbers (thousands separators gone)."""
    rows = _table(text, "during one more call:")
    return [[float(cell.replace(",", "")) for cell in row] for row in rows]


def test_cycles_section_prints_the_cost_per_cycle(monkeypatch):
    monkeypatch.setattr(cycles, "QUICK_CYCLES", (200, 2_000))
    result = CliRunner().invoke(cli, ["bench", "--section", "cycles"])
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "Cycles:" in out and "Throughput:" not in out
    assert "cycles: turning points of 2000 cycles" in result.stderr
    rows = _cycle_rows(out)
    assert [row[:2] for row in rows] == [[200, 5_000], [2_000, 50_000]]
    for cycle_count, samples, crests, ms, per_cycle, ratio, allocated, per_sample in rows:
        assert 2 * cycle_count - 3 <= crests <= 2 * cycle_count  # every crest found
        assert per_cycle == pytest.approx(1e3 * ms / cycle_count, rel=0.01, abs=0.01)
        # MiB printed to 0.1 and bytes a sample to 1.
        assert allocated > 0
        assert ((allocated - 0.05) * 2**20 / samples - 0.5 <= per_sample
                <= (allocated + 0.05) * 2**20 / samples + 0.5)
    assert rows[1][5] == 1.0 and rows[0][5] == pytest.approx(rows[0][4] / rows[1][4], abs=0.01)
    lines = [line for line in out.splitlines() if "   target " in line]
    assert len(lines) == 4 and all(line.endswith("-") for line in lines)  # none measured
    assert "run `mcfit bench --full --section cycles`" in out


def test_cycles_section_runs_mcfit_on_a_ringdown_file(monkeypatch):
    # --full's runs, small: 2,000 and 20,000 cycles, and a file of 10^4 samples.
    monkeypatch.setattr(cycles, "FULL_CYCLES", (2_000, 20_000))
    config = dataclasses.replace(TINY, big_samples=10_000)
    text = cycles.format_cycles(cycles.run_cycles(config))
    growth = next(line for line in text.splitlines() if "20,000 / 2,000 cycles" in line)
    assert re.search(r"\d\.\d\dx   target <= 2x\s+(met|NOT MET)$", growth)
    for label in ("CPU time", "peak memory / file size"):
        line = next(line for line in text.splitlines() if label in line)
        assert re.search(r"[\d.]+ ?(s|x)   target < [\d.]+ ?(s|x)\s+(met|NOT MET)$", line)
    assert "10^4 samples, 10^3 cycles: CPU time" in text
    assert "on 10,000 samples, 1,000 cycles" in text
    assert re.search(r"peak resident memory \d+ MiB; 1,99\d turning points", text)


def test_a_ringdown_decays_to_exp_minus_2_and_its_file_holds_it(tmp_path):
    t, x = cycles.ringdown(300, samples_per_cycle=25, seed=1)
    assert t.size == 7_500 and t[1] == pytest.approx(0.04)
    first, last = (np.max(np.abs(x[part] - cycles.OFFSET)) for part in (slice(0, 25),
                                                                          slice(-25, None)))
    assert first == pytest.approx(1.0, abs=5e-3)
    assert last == pytest.approx(math.exp(-2.0), abs=5e-3)
    path = tmp_path / "ringdown.csv"
    cycles.write_ringdown_csv(path, 300, samples_per_cycle=10, seed=1)
    lines = path.read_text().splitlines()
    assert lines[0] == "time (s),position (m),velocity" and len(lines) == 3_001
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 1], cycles.ringdown(300, 10, seed=1)[1], atol=6e-7)
    assert 20 <= path.stat().st_size / 3_000 <= 32  # about 31 bytes a row at 10^7 rows


# The edges section.

def test_the_reference_integration_imports_nothing_from_mcfit():
    """It checks mcfit's records, so it must not share mcfit's code."""
    import ast

    tree = ast.parse(Path(edges.motion.__file__).read_text(encoding="utf-8"))
    imported = [alias.name for node in ast.walk(tree) if isinstance(node, ast.Import)
                for alias in node.names]
    imported += [node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)]
    assert imported and not any(name.split(".")[0] == "mcfit" for name in imported)


def test_the_edges_section_prints_one_row_per_scene(monkeypatch):
    """Through the command line: a row per scene, the three outcomes' counts summing to N,
    each with an interval around its rate."""
    scenes = (edges.EDGE_SCENES[5], edges.EDGE_SCENES[-1])  # the held start, 8 bits
    monkeypatch.setattr(bench, "QUICK", dataclasses.replace(
        TINY, name="quick", edge_records=2, edge_scenes=scenes))
    result = CliRunner().invoke(cli, ["bench", "--section", "edges"])
    assert result.exit_code == 0, result.output
    assert "edges: held 1.5 s, then Fig. 20.19" in result.stderr
    rows = result.stdout.split("Edges:", 1)[1].strip().splitlines()
    assert rows[1].split() == ["scene", "N", "right", "flagged", "silently", "wrong", "ms"]
    assert len(rows) == 2 + len(scenes)
    for row, scene in zip(rows[2:], scenes):
        assert row.startswith(scene.name)
        cells = re.findall(r"(\d+) \((\d\.\d\d)-(\d\.\d\d)\)", row[len(scene.name):])
        assert len(cells) == 3
        assert row[len(scene.name):].split()[0] == "2"
        assert sum(int(count) for count, _, _ in cells) == 2
        for count, low, high in cells:
            assert float(low) <= int(count) / 2 <= float(high)
        assert float(row.split()[-1]) > 0


def test_the_wilson_interval_is_the_score_interval():
    """By hand: 0 of n gives (0, z^2/(n + z^2)); 5 of 10 is symmetric about 1/2."""
    z2 = 1.959963984540054**2
    low, high = edges.wilson_interval(0, 5)
    assert low == pytest.approx(0.0, abs=1e-12) and high == pytest.approx(z2 / (5 + z2))
    low, high = edges.wilson_interval(5, 10)
    half = math.sqrt(z2) * math.sqrt(0.25 / 10 + z2 / 400) / (1 + z2 / 10)
    assert (low, high) == pytest.approx((0.5 - half, 0.5 + half))


def _result(model="bc", values=None, stderr=None, *, warnings=(), resolved=True,
            form="amplitude", notes=(), status="ok", error=None, n_points=800):
    """A hand-made analysis with the attributes the classifier reads."""
    from types import SimpleNamespace

    fit = SimpleNamespace(model=model, values=values or {}, stderr=stderr or {},
                          interval_factor=1.96, resolved=resolved, damping_form=form)
    return SimpleNamespace(status=status, error=error, warnings=tuple(warnings),
                           fit=fit if status == "ok" else None,
                           turning=SimpleNamespace(notes=tuple(notes)))


BC = edges.EdgeScene("b + c", None, 1e-3, {"b": 1.0, "c": 0.1}, "amplitude")


@pytest.mark.parametrize("result, outcome", [
    (_result("bc", {"b": 1.01, "c": 0.1}, {"b": 0.01, "c": 0.01}), "right"),
    # A true value just outside its interval: wrong without a word, flagged with one.
    (_result("bc", {"b": 1.03, "c": 0.1}, {"b": 0.01, "c": 0.01}), "wrong"),
    (_result("bc", {"b": 1.03, "c": 0.1}, {"b": 0.01, "c": 0.01},
             warnings=("misfit",)), "flagged"),
    # b dropped, a fluid term invented, resolved: the issue's Q = 3 scene.
    (_result("ac", {"a": 0.5, "c": 0.22}, {"a": 0.01, "c": 0.01, "b": None}), "wrong"),
    (_result("ac", {"a": 0.5, "c": 0.22}, {"a": 0.01, "c": 0.01}, resolved=False), "flagged"),
    (_result("ac", {"a": 0.5, "c": 0.22}, {"a": 0.01, "c": 0.01}, form="cannot tell"),
     "flagged"),
    (_result(status="error", error="f.csv: only 2 turning points found (need 4)"), "flagged"),
    # The right numbers with the wrong form claimed outright are not right.
    (_result("bc", {"b": 1.0, "c": 0.1}, {"b": 0.01, "c": 0.01}, form="velocity"), "wrong"),
    (_result("bc", {"b": 1.0, "c": 0.1}, {"b": 0.01, "c": 0.01}, form="cannot tell"),
     "right"),
    (_result("bc", {"b": 1.0, "c": 0.1}, {"b": 0.01, "c": None}), "wrong"),
])
def test_the_classifier_puts_each_result_where_it_belongs(result, outcome):
    assert edges.classify(result, BC) == outcome


def test_the_classifier_judges_ties_beats_and_clipping_by_their_own_rule():
    tie = edges.EdgeScene("tie", None, 5e-3, {"b": 0.01}, "velocity", kind="tie")
    assert edges.classify(_result("a", resolved=False), tie) == "right"
    assert edges.classify(_result("b", {"b": 0.011}, {"b": 0.001}), tie) == "right"
    assert edges.classify(_result("b", {"b": 0.02}, {"b": 0.001}), tie) == "wrong"
    assert edges.classify(_result("a", {"a": 0.1}, {"a": 0.01}), tie) == "wrong"
    beat = edges.EdgeScene("beat", None, 1e-3, {"b": 0.01}, kind="beat")
    named = "the amplitude rises again at t = 50: beating of two modes, or a disturbance"
    assert edges.classify(_result("b", warnings=(named,)), beat) == "right"
    assert edges.classify(_result("bc", {"b": 0.01}, {"b": 0.001}), beat) == "wrong"
    assert edges.classify(_result("bc", warnings=("misfit",)), beat) == "flagged"
    clip = edges.EdgeScene("8 bits", None, 0.3, {"b": 0.1}, kind="clip", quantum=1.0)
    assert edges.classify(_result("b"), clip) == "right"
    clipped = _result("b", notes=("3 clipped (saturated) extrema excluded",))
    assert edges.classify(clipped, clip) == "wrong"


def test_noisy_records_are_seeded_and_quantised():
    scene = edges.EDGE_SCENES[-1]
    clean = (np.arange(0.0, 1.0, 0.1), np.linspace(28.0, 227.0, 10))
    one, two = (edges.noisy_record(scene, clean, [1, 2]) for _ in range(2))
    np.testing.assert_array_equal(one.x, two.x)
    np.testing.assert_array_equal(one.x, np.round(one.x))
    assert not np.array_equal(one.x, edges.noisy_record(scene, clean, [1, 3]).x)
