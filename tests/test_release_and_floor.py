"""A start before the free decay (held still, driven) and the noise floor at the end."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mcfit.analysis import analyse_record
from mcfit.decay import amplitude
from mcfit.errors import RecordError
from mcfit.motion import simulate_record
from mcfit.io import Record
from mcfit.turning import find_turning_points, turning_points_from_table

REALDATA = Path(__file__).parents[2] / "shared" / "realdata"
# y0, a, b, c: all three regimes, Q about 60 to 150 at a period of 1.
LAW = (1.0, 0.02, 0.03, 0.002)
RATE = 50.0


def _noisy(x, seed, noise):
    return x + np.random.default_rng(seed).normal(0.0, noise, x.size)


def _held_record(seed, release=3.0, duration=40.0, noise=0.005, struck=False):
    """Still (with noise) until ``release``, then a free decay of LAW: let go from its
    largest swing (a pendulum held aside), or struck at rest (``struck``)."""
    t = np.arange(0.0, duration, 1.0 / RATE)
    s = np.clip(t - release, 0.0, None)
    swing = np.sin if struck else np.cos
    x = amplitude(s, *LAW) * swing(2 * np.pi * s)
    x[t < release] = 0.0 if struck else LAW[0]
    return t, _noisy(x + 0.2, seed, noise)


def _driven_record(seed, ramp=5.0, duration=40.0, noise=0.005):
    """Amplitude rising linearly from half its peak for ``ramp`` cycles while driven,
    then a free decay. The record swings from its start, so the turning points judge
    where the decay starts (a swing built up from rest is left out before them: see
    tests/test_free_decay.py)."""
    t = np.arange(0.0, duration, 1.0 / RATE)
    rise = LAW[0] * (0.5 + 0.5 * t / ramp)
    envelope = np.where(t < ramp, rise, amplitude(np.clip(t - ramp, 0.0, None), *LAW))
    return t, _noisy(envelope * np.sin(2 * np.pi * t) + 0.2, seed, noise)


def _analysis(t, x):
    analysis = analyse_record(Record(source="test.csv", t=t, x=x), model="abc",
                              method="turning-points")
    assert analysis.status == "ok", analysis.error
    return analysis


def _assert_law_recovered(fit):
    for name, true in zip("abc", LAW[1:]):
        assert abs(fit.values[name] - true) < 3 * fit.stderr[name], (name, fit.values)


@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("struck", [False, True], ids=["held-aside", "struck-at-rest"])
def test_a_held_start_is_excluded_and_the_fit_starts_at_the_release(seed, struck):
    analysis = _analysis(*_held_record(seed, struck=struck))
    points = analysis.turning
    assert abs(points.release_time - 3.0) < 1.0
    assert not np.any(points.used & (points.t < 3.0))
    before = np.array(points.excluded_reason) == "before release"
    assert np.all(points.t[before] < 3.0)
    # Found before the turning points, where the signal leaves its still level.
    assert any(n.startswith("left out t = 0 to ") and "a rest or hold before the release" in n
               for n in analysis.record.notes)
    assert analysis.record.left_out[0][2] == "rest"
    _assert_law_recovered(analysis.fit)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_driven_start_is_excluded_and_the_fit_starts_after_the_largest_crest(seed):
    analysis = _analysis(*_driven_record(seed))
    points = analysis.turning
    assert abs(points.release_time - 5.0) < 1.0
    before = np.array(points.excluded_reason) == "before release"
    assert np.count_nonzero(before) >= 8 and np.all(points.t[before] < 6.0)
    assert points.t[points.used].min() > 5.0 and not analysis.record.left_out
    # The largest crest's half-cycle straddles the end of the drive: the decay's first
    # crest is the next one.
    first = np.flatnonzero(points.used)[0]
    largest = int(np.argmax(np.where(points.t < 6.0, points.y, -np.inf)))
    assert before[largest] and largest < first <= largest + 2
    note = next(n for n in points.notes if n.startswith("release at t = "))
    assert "turning points before it excluded (amplitude rising or flat)" in note
    _assert_law_recovered(analysis.fit)


def _asymmetric(x, up=1.15, down=0.87):
    return np.where(x > 0, up * x, down * x)


def _beat():
    t = np.arange(0.0, 60.0, 1.0 / RATE)
    x = np.exp(-0.03 * t) * (np.cos(2 * np.pi * t) + 0.05 * np.cos(2 * np.pi * 1.01 * t))
    return t, _noisy(x, 3, 1e-3)


def _unequal_swings():
    t = np.arange(0.0, 60.0, 1.0 / RATE)
    return t, _noisy(_asymmetric(amplitude(t, *LAW) * np.cos(2 * np.pi * t + 0.7)), 4, 0.01)


def _noisy_high_q():
    t = np.arange(0.0, 60.0, 1.0 / RATE)
    return t, _noisy(np.exp(-0.005 * t) * np.cos(2 * np.pi * t), 5, 0.1)


def _simulated(a, b, c, duration, noise):
    return simulate_record(a, b, c, 1.0, 1.0, duration, RATE, noise=noise, offset=0.1,
                           rng=np.random.default_rng(6))


ORDINARY_DECAYS = {
    "slow beat": _beat,
    "unequal swings": _unequal_swings,
    "noisy high Q": _noisy_high_q,
    "viscous Q 3": lambda: _simulated(0, np.pi / 3, 0, 8, 1e-3),
    "viscous Q 30": lambda: _simulated(0, np.pi / 30, 0, 30, 1e-2),
    "viscous Q 300": lambda: _simulated(0, np.pi / 300, 0, 60, 1e-2),
    "Coulomb to a stop": lambda: _simulated(0, 0, 0.1, 14, 1e-3),
    "fluid": lambda: _simulated(0.3, 0, 0, 40, 1e-3),
    "all three": lambda: _simulated(0.1, 0.1, 0.01, 30, 1e-2),
}


@pytest.mark.parametrize("name", ORDINARY_DECAYS)
def test_no_release_in_an_ordinary_decay(name):
    points = find_turning_points(*ORDINARY_DECAYS[name]())
    assert np.isnan(points.release_time)
    assert "before release" not in points.excluded_reason
    assert not any("release" in n for n in points.notes)


def _slowing_decay(seed, shape):
    """A decay from 12 to 2.8 over 115 cycles that slows as it dies away (dy/dt = -k*y**3),
    still far above the noise (0.1) at its end, with swings of equal or unequal size."""
    t = np.arange(0.0, 46.0, 0.4 / 50)
    k = (2.8**-2 - 12.0**-2) / (2 * t[-1])
    x = (12.0**-2 + 2 * k * t) ** -0.5 * np.cos(2 * np.pi * t / 0.4)
    return t, _noisy(_asymmetric(x) if shape == "asymmetric" else x, seed, 0.1)


@pytest.mark.parametrize("seed, shape", [(1, "equal"), (5, "equal"), (1, "asymmetric")])
def test_a_decay_still_above_the_noise_has_no_floor(seed, shape):
    points = find_turning_points(*_slowing_decay(seed, shape))
    assert np.isnan(points.noise_floor_time)
    assert points.used.all()


@pytest.mark.parametrize("shape", ["harmonic", "half-cycles"])
def test_swings_of_unequal_size_up_and_down_are_no_floor(shape):
    t = np.arange(0.0, 100.0, 1.0 / RATE)
    envelope = amplitude(t, 10.0, 0.0, 0.005, 0.02624)  # 10 to 4, Coulomb and viscous
    wave = (np.cos(2 * np.pi * t) + 0.1 * np.cos(4 * np.pi * t) if shape == "harmonic"
            else _asymmetric(np.cos(2 * np.pi * t)))
    points = find_turning_points(t, _noisy(envelope * wave, 7, 0.1))
    assert np.isnan(points.noise_floor_time)
    assert points.used.all()


@pytest.mark.parametrize("ratio", [1.0, 1.37])
def test_a_decay_into_a_steady_vibration_ends_at_the_floor(ratio):
    t = np.arange(0.0, 100.0, 1.0 / RATE)
    x = 10.0 * np.exp(-0.08 * t) * np.cos(2 * np.pi * t) + 0.5 * np.cos(
        2 * np.pi * ratio * t + 0.3)
    points = find_turning_points(t, _noisy(x, 8, 0.1))
    assert points.noise_floor == pytest.approx(0.5, rel=0.2)
    # The envelope meets 1.5 times the floor at 32 s and the floor itself at 37 s.
    assert 30.0 < points.noise_floor_time < 50.0
    assert "noise floor" in points.excluded_reason
    assert not np.any(points.used & (points.t > points.noise_floor_time))


def test_a_decay_into_white_noise_is_cut_where_it_is_lost():
    t = np.arange(0.0, 100.0, 1.0 / RATE)
    points = find_turning_points(t, _noisy(10.0 * np.exp(-0.1 * t) * np.cos(2 * np.pi * t),
                                           2, 0.1))
    sigma_y = np.median(points.sigma[points.used])
    assert 40.0 < points.noise_floor_time < 75.0
    assert 10.0 * np.exp(-0.1 * points.noise_floor_time) < 3 * sigma_y
    assert not np.any(points.used & (points.t > points.noise_floor_time))


@pytest.mark.parametrize("seed", range(10))
def test_a_long_tail_of_noise_is_cut_where_the_signal_ends(seed):
    """A decay over 3,000 crests, then 200,000 crests of noise alone (a long record that
    rang out early): a chance run of noise far out must not count as signal. At the fixed
    threshold of 4 standard errors, noise alone crosses it somewhere in such a tail."""
    from mcfit.turning.floor import _NOISE_GROUP, _sinks_below_noise

    rng = np.random.default_rng(seed)
    signal = np.concatenate([20.0 * np.exp(-np.arange(3000) / 400.0), np.zeros(200_000)])
    sigma = np.ones(signal.size)
    cut = _sinks_below_noise(signal + rng.normal(0.0, 1.0, signal.size), sigma,
                             np.ones(signal.size, dtype=bool))
    # The signal's group mean falls below 4 sigma near crest 400*ln(20*3/4) = 1083.
    assert cut is not None and 900 < cut < 3000 + 3 * _NOISE_GROUP


def test_a_rise_at_the_start_starts_the_free_decay():
    n = np.arange(40.0)
    y = np.concatenate([[1.0, 0.5, 0.45, 0.6, 0.8, 1.2], 1.5 * np.exp(-0.05 * n)])
    points = turning_points_from_table(np.arange(y.size, dtype=float), y, domain="cycle")
    assert points.release_time == 6.0 and not points.warnings
    assert points.excluded_reason[:6] == ("before release",) * 6
    assert np.all(points.used[6:])
    assert any(note.startswith("the free decay starts at t = 6,") for note in points.notes)


def test_one_function_decides_whether_a_rise_starts_the_free_decay():
    """release._release_at_rise, which the table and waveform paths both ask: a rise to
    the largest amplitude early on starts the decay; a rise in the middle, or to the
    largest amplitude late in the record, does not."""
    from mcfit.turning.release import _release_at_rise, _rise

    n = np.arange(40.0)
    for y, starts in ((np.concatenate([[1.0, 0.5, 0.45, 0.6, 0.8, 1.2],
                                       1.5 * np.exp(-0.05 * n)]), 6.0),
                      (np.concatenate([np.exp(-0.05 * n[:20]), [0.6, 0.7, 0.8],
                                       0.7 * np.exp(-0.05 * n)]), None),
                      (np.concatenate([np.exp(-0.05 * n[:30]), 1.5 * np.exp(-0.05 * n[:10])]),
                       None)):
        sigma = np.full(y.size, 0.01)
        k = _rise(y, 0.01, sigma, 0.0)
        assert k is not None
        found = _release_at_rise(np.arange(y.size, dtype=float), y, k, 0.01, sigma, 0.0)
        assert (found and found[0]) == starts


def test_a_rise_in_the_middle_is_left_out_with_a_warning():
    n = np.arange(40.0)
    y = np.concatenate([np.exp(-0.05 * n[:20]), [0.6, 0.7, 0.8], 0.7 * np.exp(-0.05 * n)])
    points = turning_points_from_table(np.arange(y.size, dtype=float), y, domain="cycle")
    assert np.flatnonzero(points.used).max() < 20
    assert points.count >= 15
    assert "beating of two modes, or a disturbance" in points.warnings[0]


def test_the_handbook_decay_recorded_past_its_coulomb_stop_is_fitted_up_to_it():
    """Fig. 20.19's parameters for 30 s (the motion stops at 24.4 s): the mass rests off
    centre, which reads as crests alternating about zero and then 'rising'. That was
    refused as beating; now the decay is fitted up to the stop, and a note says where."""
    t, x = simulate_record(0.1, 0.1, 0.01, 4.0, 0.5, 30.0, 100.0, method="accurate",
                           noise=1e-4, rng=np.random.default_rng(3))
    points = find_turning_points(t, x)
    assert not points.warnings
    used = points.t[points.used]
    assert used.max() < 25.5 and used.min() < 1.0
    assert any(note.startswith(("the decay ends in the noise or stops", "the motion stops by")) for note in points.notes)


@pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata absent")
@pytest.mark.parametrize("path", [
    "pendulum_cup/lab1_data.txt", "pendulum_cup/trial1_rawdata.txt",
    "spring_mass_disk/molla_durissima_discopieno_14.91945_0.2016_1.csv"])
def test_real_records_start_free_and_have_no_floor(path):
    from mcfit.io import read_record
    from mcfit.turning import turning_points_of
    points = turning_points_of(read_record(REALDATA / path))
    assert np.isnan(points.release_time)
    assert np.isnan(points.noise_floor_time)


def test_the_release_reaches_the_json_and_the_turning_points_file(tmp_path):
    import json

    from click.testing import CliRunner

    from mcfit.cli import cli

    t, x = _driven_record(1)
    record = tmp_path / "driven.csv"
    record.write_text("t,x\n" + "".join(f"{a:.4f},{b:.6f}\n" for a, b in zip(t, x)))
    points = tmp_path / "points.csv"
    result = CliRunner().invoke(cli, [str(record), "--format", "json", "--method",
                                      "turning-points", "--turning-points-out", str(points)])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert 4.5 < data["release_time"] < 6.5
    excluded = data["turning_points_excluded"]["before release"]
    assert any(note.startswith("release at t = ") for note in data["notes"])
    rows = [line.split(",") for line in points.read_text().splitlines()[1:]]
    assert sum(row[5] == "before release" for row in rows) == excluded


def test_a_held_start_with_a_knock_is_released_where_the_swing_starts():
    """A spring held off centre for 8.39 s, knocked at 0.46 s, then let go (viscous damping
    and sliding friction, independent integration): the knock ended the still start there,
    so the held stretch and the release crest, half held and half swinging, were fitted
    (reduced chi-square in the thousands). Now the release is where the swing starts, and
    the crest there is left out with the held ones."""
    from mcfit.bench.reference_motion import viscous

    omega = 2 * np.pi / 0.8
    t = np.arange(0.0, 30.0, 0.02)
    tau, swing = viscous(0.05, omega, 0.3, 22.0, 50.0, mu=0.002 * np.pi * omega / 2)
    x = np.where(t < 8.39, 0.3, np.interp(t - 8.39, tau, swing))
    x = x + np.where(np.abs(t - 0.46) < 0.05, -0.05, 0.0)
    x = x + np.random.default_rng(1).normal(0.0, 5e-4, t.size)
    analysis = analyse_record(Record(source="held", t=t, x=x))
    assert 8.39 <= analysis.turning.release_time < 8.5
    assert analysis.turning.t[analysis.turning.used].min() > 8.6
    fit = analysis.fit
    assert fit.model == "bc"
    assert abs(fit.values["b"] - 0.05) < 3 * fit.stderr["b"]
    assert abs(fit.values["c"] - 0.002) < 3 * fit.stderr["c"]
