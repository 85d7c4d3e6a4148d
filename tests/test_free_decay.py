"""Where the free decay is in a record as it was recorded: after a rest, a held push or a
strike and its transient; several excitations as several runs; a release after steady
swinging. Each record is made here with a known truth."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit import analyse, analyse_file
from mcfit.cli import cli
from mcfit.motion import simulate_record
from mcfit.turning.placement import locate_free_decay


def _ring(t, start, amplitude, frequency, rate, phase=np.pi / 2):
    """A free decay exp(-rate*s)*cos(2*pi*f*s + phase) from ``start`` on, 0 before."""
    s = t - start
    return np.where(s >= 0, amplitude * np.exp(-rate * np.clip(s, 0, None))
                    * np.cos(2 * np.pi * frequency * s + phase), 0.0)


FORK = {"frequency": 439.0, "q": 2000.0, "rate": 8000.0}


def _struck_fork(seed, strikes=(1.0,), duration=6.0):
    """A tuning fork at 439 Hz (Q 2000) struck at each of ``strikes`` after a quiet
    pre-trigger, each strike with a loud low thump (56 Hz) and a clang mode (2.6 kHz)
    that die within about 0.15 s."""
    t = np.arange(int(duration * FORK["rate"])) / FORK["rate"]
    b = np.pi * FORK["frequency"] / FORK["q"]
    x = np.zeros_like(t)
    for strike in strikes:
        x += _ring(t, strike, 1.0, FORK["frequency"], b)
        x += _ring(t, strike, 6.0, 56.0, 25.0)
        x += _ring(t, strike, 2.0, 2610.0, 40.0)
    return t, x + np.random.default_rng(seed).normal(0, 1e-3, t.size), b


def _within(fit, name, truth, z=3.0):
    return abs(fit.values[name] - truth) <= z * fit.stderr[name]


def _lvm_one_column(path, x):
    """A LabVIEW measurement file of one channel and no time column (as a sound card's
    logger writes it): the rate must be given."""
    header = ("LabVIEW Measurement\t\nWriter_Version\t2\nSeparator\tTab\n"
              "Decimal_Separator\t.\n***End_of_Header***\t\n\nChannels\t1\n"
              f"Samples\t{x.size}\n***End_of_Header***\t\nUntitled\n")
    path.write_text(header + "\n".join(f"{v:.6f}" for v in x) + "\n")


@pytest.mark.parametrize("seed", [1, 2])
def test_a_strike_and_its_transient_are_left_out(tmp_path, seed):
    t, x, b = _struck_fork(seed)
    path = tmp_path / "fork.lvm"
    _lvm_one_column(path, x)
    out = CliRunner().invoke(cli, [str(path), "--rate", "8000", "--format", "json"])
    assert out.exit_code == 0, out.output
    [row] = [json.loads(line) for line in out.output.splitlines()]
    value, stderr = row["params"]["b"]["value"], row["params"]["b"]["stderr"]
    assert row["model"] == "b" and abs(value - b) <= 3 * stderr
    assert row["period"] == pytest.approx(1 / FORK["frequency"], rel=1e-4)
    # The decay starts after the strike's other modes have died, not before the strike.
    assert 1.0 < row["release_time"] < 1.35 and row["t0"] >= row["release_time"]
    assert [part["why"] for part in row["left_out"]] == ["rest", "transient"]
    assert row["left_out"][1]["end"] == row["release_time"]


def test_a_fork_struck_twice_gives_two_runs(tmp_path):
    t, x, b = _struck_fork(3, strikes=(0.5, 3.5))
    path = tmp_path / "fork.csv"
    np.savetxt(path, np.column_stack([t, x]), delimiter=",", header="t,x", comments="",
               fmt="%.9g")
    out = CliRunner().invoke(cli, [str(path), "--format", "json"])
    assert out.exit_code == 0, out.output
    rows = [json.loads(line) for line in out.output.splitlines()]
    assert [row["run"] for row in rows] == ["Run 1", "Run 2"]
    assert rows[0]["source"].endswith("fork.csv#Run 1")
    for row, (low, high) in zip(rows, [(0.5, 3.5), (3.5, 6.0)]):
        value, stderr = row["params"]["b"]["value"], row["params"]["b"]["stderr"]
        assert row["model"] == "b" and abs(value - b) <= 3 * stderr
        assert low < row["t0"] < low + 0.35
    # --run picks one of the free decays; one not there is named.
    for number, low in ((1, 0.5), (2, 3.5)):
        one = CliRunner().invoke(cli, [str(path), "--format", "json", "--run", str(number)])
        [row] = [json.loads(line) for line in one.output.splitlines()]
        assert row["run"] == f"Run {number}" and low < row["t0"] < low + 0.35
    third = CliRunner().invoke(cli, [str(path), "--run", "3"])
    assert third.exit_code != 0 and "run 3 not found" in third.output


def _phone(path, seed, rest=0.85, rate=100.0, duration=120.0):
    """A phyphox gyroscope export of a phone used as a pendulum bob: held in the hand (a
    7 Hz tremor) until ``rest``, then swinging freely about its z axis (period 1.6 s,
    b = 0.01, first swing 2.63 rad/s); x and y hold only noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration * rate)) / rate
    z = _ring(t, rest, 2.63, 0.62, 0.01, phase=-np.pi / 2)
    z += np.where(t < rest, 0.05 * np.sin(2 * np.pi * 7 * t), 0.0)
    z += rng.normal(0, 0.01, t.size)
    x, y = rng.normal(0, 0.01, (2, t.size))
    rows = np.column_stack([t, x, y, z, np.sqrt(x * x + y * y + z * z)])
    np.savetxt(path, rows, delimiter=",", fmt="%.9E", comments="", header=(
        '"Time (s)","Gyroscope x (rad/s)","Gyroscope y (rad/s)","Gyroscope z (rad/s)",'
        '"Absolute (rad/s)"'))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_rest_before_the_release_is_left_out(tmp_path, seed):
    path = tmp_path / "Raw Data.csv"
    _phone(path, seed)
    result = analyse_file(str(path))
    assert result.record.signal_column == "Gyroscope z (rad/s)"
    assert result.status == "ok" and result.fit.model == "b"
    assert _within(result.fit, "b", 0.01)
    # The fit starts at the release, to within a few samples, not inside the rest.
    assert 0.85 <= result.record.t[0] < 0.92
    assert result.fit.values["y0"] == pytest.approx(2.63, rel=0.01)


def _held_push(seed, rate=200.0, hold=(5.0, 19.0), duration=200.0):
    """A seismometer's mass pushed aside at 5 s (a brief ring while pushed), held there
    until 19 s and released: a free decay of period 6 s, b = 0.004, amplitude 1e6
    counts, with 60 Hz pickup of 2e3 counts and noise of 300."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration * rate)) / rate
    pushed = np.clip((t - hold[0]) / 1.0, 0, 1) * 1e6
    x = np.where(t < hold[1], pushed, 0.0)
    x += np.where((t > hold[0]) & (t < hold[1]),
                  1e5 * np.exp(-(t - hold[0]) / 1.5) * np.sin(2 * np.pi * 0.21 * (t - hold[0])),
                  0.0)
    x += _ring(t, hold[1], 1e6, 1 / 6.0, 0.004, phase=0.0)
    x += 2e3 * np.sin(2 * np.pi * 60 * t + 0.3)
    return t, x + rng.normal(0, 300, t.size)


def test_a_held_push_is_left_out_and_the_decay_after_its_release_fitted(tmp_path):
    t, x = _held_push(4)
    path = tmp_path / "logger.csv"
    epoch = 1406730000.0 + t
    lines = ["Sample,Time,Laser"] + [f"{i},{e:.3f},{int(round(v)):+08d}"
                                     for i, (e, v) in enumerate(zip(epoch, x))]
    path.write_text("\n".join(lines) + "\n")
    out = CliRunner().invoke(cli, [str(path), "--format", "json"])
    assert out.exit_code == 0, out.output
    [row] = [json.loads(line) for line in out.output.splitlines()]
    value, stderr = row["params"]["b"]["value"], row["params"]["b"]["stderr"]
    assert row["columns"] == {"time": "Time", "signal": "Laser"}
    assert row["model"] == "b" and abs(value - 0.004) <= 3 * stderr
    # Seconds from the record's start, not from the epoch: the release at 19 s.
    assert 19.0 <= row["release_time"] < 19.2
    assert row["period"] == pytest.approx(6.0, rel=1e-3)
    assert [part["why"] for part in row["left_out"]][-1] == "rest"
    assert row["time_origin"]["value"] == pytest.approx(1406730000.0)


def test_a_record_that_decays_from_its_start_is_not_moved():
    record = simulate_record(0.02, 0.03, 0.002, 1.0, 1.0, 60.0, 50.0, noise=0.005, rng=5)
    placement = locate_free_decay(record.t, record.x)
    assert not placement.moved and placement.runs == ((0.0, 60.0),)


def _steady_then_free(seed, lead=1.5, rate=100.0, noise=1e-3):
    """Fig. 20.19's law (a = b = 0.1, c = 0.01, y0 = 4, T = 0.5) released from a crest
    after a drive has held the swing at y0 for ``lead`` seconds."""
    free = simulate_record(0.1, 0.1, 0.01, 4.0, 0.5, 20.0, rate, method="accurate",
                           rtol=1e-9)
    n = int(round(lead * rate))
    t = np.concatenate([(np.arange(n) - n) / rate, free.t]) + lead
    x = np.concatenate([4.0 * np.cos(4 * np.pi * (np.arange(n) - n) / rate), free.x])
    return t, x + np.random.default_rng(seed).normal(0, noise, t.size)


@pytest.mark.parametrize("seed", range(6))
def test_a_release_after_steady_swinging_starts_after_its_straddling_crest(seed):
    result = analyse(*_steady_then_free(seed))
    fit = result.fit
    assert result.turning.release_time == pytest.approx(1.5, abs=0.01)
    assert result.turning.t[result.turning.used][0] > 1.7  # not the crest at the release
    assert fit.model == "abc"
    assert all(_within(fit, name, truth, z=2.6)
               for name, truth in (("a", 0.1), ("b", 0.1), ("c", 0.01)))


def test_a_swing_built_up_from_rest_is_left_out():
    """A drive builds the swing up from rest over 5 cycles, then lets it decay freely
    (b = 0.03, Q about 100): the build-up is left out before the turning points, and
    the fit starts after it."""
    t = np.arange(0.0, 40.0, 0.02)
    envelope = np.where(t < 5.0, t / 5.0, np.exp(-0.03 * (t - 5.0)))
    x = envelope * np.sin(2 * np.pi * t) + np.random.default_rng(3).normal(0, 0.005, t.size)
    result = analyse(t, x)
    assert result.record.left_out and 5.0 <= result.record.t[0] < 6.5
    assert result.fit.model == "b" and _within(result.fit, "b", 0.03)
    assert result.turning.t[result.turning.used].min() > 5.0


def _rings(t, starts, rate):
    return sum(_ring(t, start, 1.0, 2.0, rate) for start in starts)


@pytest.mark.parametrize("rate", [0.1, 0.3])
def test_a_fast_decay_struck_three_times_gives_three_runs(rate):
    """At Q 63 and 21 (the decay falls by half or more over the blocks before the next
    strike): each strike starts a run, and nothing of a decay is called a rest."""
    t = np.arange(0, 60, 1 / 200.0)
    x = _rings(t, (5.0, 25.0, 45.0), rate) + np.random.default_rng(1).normal(0, 1e-3, t.size)
    placement = locate_free_decay(t, x)
    assert len(placement.runs) == 3
    for (start, _), strike in zip(placement.runs, (5.0, 25.0, 45.0)):
        assert strike <= start < strike + 0.35
    # Between two decays only the block before a strike is left out, not a decay.
    assert all(end - start <= 1.1 for start, end, _ in placement.left_out[1:])


def test_a_beat_of_two_modes_is_one_record_and_no_noise_floor():
    """Two modes at 2.00 and 2.02 Hz: the amplitude falls into each beat's node and rises
    again; no new excitation, and the node is no faint tail where the phase is lost."""
    t = np.arange(0, 300, 1 / 200.0)
    x = np.exp(-0.002 * t) * 0.5 * (np.cos(4 * np.pi * t) + np.cos(2 * np.pi * 2.02 * t))
    x += np.random.default_rng(5).normal(0, 0.1, t.size)
    assert not locate_free_decay(t, x).moved
    result = analyse(t, x)
    assert not any("crest phase is lost" in note for note in result.turning.notes)


def test_a_drifting_rest_is_no_release():
    """A rest whose level drifts (0.05 per second) before a release at 5 s."""
    t = np.arange(0, 60, 1 / 200.0)
    x = _ring(t, 5.0, 1.0, 2.0, 0.1, phase=0.0) + 0.05 * t
    x += np.random.default_rng(2).normal(0, 1e-3, t.size)
    [(start, _)] = locate_free_decay(t, x).runs
    assert 4.99 <= start < 5.05
