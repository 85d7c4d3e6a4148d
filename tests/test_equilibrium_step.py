"""A step of the equilibrium in mid-record (a knock, a slip) is found, named and modelled;
it is not taken for a hum, and records without one are left as they were (issue 37)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from mcfit.analysis import analyse_record
from mcfit.io import Record
from mcfit.motion import simulate_record
from mcfit.turning import find_turning_points
from mcfit.turning.step import find_equilibrium_steps, subtract_equilibrium_steps


def _record(seed, *, b=0.1, duration=30.0, rate=100.0, noise=0.01, a=0.0, c=0.0,
            drift=0.0, hum=0.0, hum_frequency=50.0):
    """Law records: period 1 s, first amplitude 1, offset 0.3; plus a hum of amplitude
    ``hum``."""
    rng = np.random.default_rng(seed)
    record = simulate_record(a, b, c, 1.0, 1.0, duration, rate, noise=noise, offset=0.3,
                             drift=drift, rng=rng)
    t, x = np.asarray(record.t), np.asarray(record.x)
    if hum:
        x = x + hum * np.sin(2 * np.pi * hum_frequency * t + rng.uniform(0, 2 * np.pi))
    return t, x


def _analysed(t, x, model=None):
    analysis = analyse_record(Record(source="record", t=t, x=x), model=model)
    assert analysis.status == "ok", analysis.error
    return analysis


@pytest.mark.parametrize("seed, size, when", [(1, 0.05, 12.3), (2, -0.02, 16.7),
                                              (3, 0.10, 14.4)])
def test_a_step_is_found_named_and_modelled(seed, size, when):
    # Unmodelled, the step inflated the amplitudes' scatter: b's standard error 8-16 times
    # that of the same record without the step.
    t, x = _record(seed)
    plain = _analysed(t, x, model="b").fit  # the same model: its errors compared
    analysis = _analysed(t, x + size * (t >= when))
    assert analysis.fit.model == "b"
    forced = _analysed(t, x + size * (t >= when), model="b").fit
    (step,) = analysis.turning.equilibrium_steps
    assert step.time == pytest.approx(when, abs=0.06)  # 6 % of a period
    assert step.size == pytest.approx(size, abs=0.003)
    fit = analysis.fit
    assert abs(fit.values["b"] - 0.1) < 3 * fit.stderr["b"]
    assert forced.stderr["b"] == pytest.approx(plain.stderr["b"], rel=0.15)
    (warning,) = analysis.turning.warnings
    said = re.fullmatch(r"the equilibrium jumps by (\S+) \((\S+) % of the first amplitude, "
                        r"\S+ % of the amplitude there\) at t = (\S+) \(a knock or slip\?\): "
                        r"modelled as a step", warning)
    assert said is not None, warning
    assert float(said[1]) == pytest.approx(size, abs=0.003)
    assert float(said[2]) == pytest.approx(100 * abs(size) / 0.95, rel=0.1)  # y0 = 0.95
    assert float(said[3]) == pytest.approx(when, abs=0.06)
    data = json.loads(json.dumps(analysis.to_dict()))
    assert warning in data["warnings"]
    (carried,) = data["equilibrium_steps"]
    assert carried["time"] == pytest.approx(when, abs=0.06)
    assert carried["size"] == pytest.approx(size, abs=0.003)


def test_a_step_is_not_taken_for_a_slow_hum():
    # At a noise of 1e-3 the step was removed as a 0.17 Hz "hum": b's standard error 80
    # times that of the record without the step.
    t, x = _record(1, b=0.05, duration=50.0, noise=1e-3)
    plain = _analysed(t, x).fit
    analysis = _analysed(t, x + 0.05 * (t >= 25.0))
    assert not any("hum" in note for note in analysis.turning.notes)
    (step,) = analysis.turning.equilibrium_steps
    assert step.time == pytest.approx(25.0, abs=0.03) and step.size == pytest.approx(0.05,
                                                                                     abs=1e-3)
    assert analysis.fit.stderr["b"] == pytest.approx(plain.stderr["b"], rel=0.1)
    assert abs(analysis.fit.values["b"] - 0.05) < 3 * analysis.fit.stderr["b"]


def test_a_hum_and_a_step_together():
    # A 50 Hz hum at 20 % is still found and removed; the step is found beside it.
    t, x = _record(2, b=0.05, duration=30.0, rate=1000.0, hum=0.2)
    analysis = _analysed(t, x - 0.03 * (t >= 14.0))
    notes = [n for n in analysis.turning.notes if "hum" in n]
    assert len(notes) == 1 and "removed" in notes[0] and "frequency 50 " in notes[0]
    (step,) = analysis.turning.equilibrium_steps
    assert step.time == pytest.approx(14.0, abs=0.03)
    assert step.size == pytest.approx(-0.03, abs=1e-3)
    assert abs(analysis.fit.values["b"] - 0.05) < 3 * analysis.fit.stderr["b"]


def test_two_steps_are_both_found_and_the_equilibrium_follows_them():
    t, x = _record(4, b=0.05, duration=40.0, noise=0.003)
    points = find_turning_points(t, x + 0.04 * (t >= 10.0) - 0.06 * (t >= 24.0))
    found = [(round(s.time, 1), round(s.size, 2)) for s in points.equilibrium_steps]
    assert found == [(10.0, 0.04), (24.0, -0.06)]
    assert len(points.warnings) == 2
    before, between, after = points.equilibrium_at(np.array([5.0, 15.0, 30.0]))
    assert between - before == pytest.approx(0.04, abs=2e-3)
    assert after - between == pytest.approx(-0.06, abs=2e-3)
    assert before == pytest.approx(0.3, abs=2e-3)


def test_subtracting_the_steps_brings_the_level_after_each_back():
    from mcfit.turning.step import EquilibriumStep

    t = np.arange(0.0, 10.0, 0.5)
    x = np.where(t >= 4.0, 1.5, 1.0)
    out = subtract_equilibrium_steps(t, x, (EquilibriumStep(4.0, 0.5, 1.0),))
    np.testing.assert_array_equal(out, np.ones_like(t))
    np.testing.assert_array_equal(x[t >= 4.0], 1.5)  # the input is left alone


KINDS = {
    "white noise": dict(),
    "50 Hz hum": dict(rate=1000.0, hum=0.3),
    "slow hum": dict(hum=0.3, hum_frequency=0.23),
    "drift": dict(b=0.05, duration=40.0, noise=0.005, drift=0.003),
    "Q = 3, faint noise": dict(b=1.0, rate=200.0, noise=1e-4),
    "Q = 10, faint noise": dict(b=0.3, duration=25.0, rate=200.0, noise=1e-5),
    "drag and Coulomb": dict(a=0.2, b=0.0, c=0.01, duration=40.0, noise=0.003),
    "Coulomb stop": dict(b=0.0, c=0.03, duration=40.0, noise=0.002),
}


@pytest.mark.parametrize("kind", KINDS)
def test_no_step_is_found_in_step_free_records(kind):
    # 6 seeds a kind here (the Monte Carlo of the change: 84 records of 14 kinds, none).
    for seed in range(6):
        t, x = _record(seed, **KINDS[kind])
        assert find_equilibrium_steps(t, x, 1.0, float(np.std(np.diff(x))) / 2) == ()
        if seed < 2:
            assert find_turning_points(t, x).equilibrium_steps == ()


def test_a_record_held_still_before_its_release_has_no_step():
    # Held at 1 for 5 s, then released: the centre moves from 1 to 0 at the release.
    t, x = _record(5, b=0.05, duration=30.0, noise=0.003)
    held = np.concatenate([np.full(500, 1.3), x])
    times = np.arange(held.size) / 100.0
    points = find_turning_points(times, held)
    assert points.equilibrium_steps == ()
    assert points.release_time == pytest.approx(5.0, abs=0.05)


def test_a_step_free_record_is_untouched(monkeypatch):
    # The same turning points, bit for bit, as with the step search switched off.
    import mcfit.turning as turning

    t, x = _record(7)
    points = find_turning_points(t, x)
    monkeypatch.setattr(turning, "find_equilibrium_steps", lambda *args: ())
    plain = find_turning_points(t, x)
    for name in ("t", "y", "sigma", "used"):
        np.testing.assert_array_equal(getattr(points, name), getattr(plain, name))
    assert points.notes == plain.notes and points.warnings == plain.warnings
    assert "equilibrium_steps" not in points.to_dict()
