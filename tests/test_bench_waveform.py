"""The waveform section of ``mcfit bench``: its records, a tiny run and its report. No
test asserts a time."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from mcfit.bench import QUICK, waveform_speed
from mcfit.bench.waveform_speed import WaveformSpeed, format_waveform_speed, mixed_record
from mcfit.turning import find_turning_points


def test_the_mixed_batch_is_the_issues():
    """100 records of 10^4 samples over 40 cycles, half with Q <= 8, Q from 5 to 200, the
    four mixes in turn, noise within 1e-4..1e-2 of y0."""
    rows = [mixed_record(i, 100, 2026)[1:] for i in range(0, 100, 7)] + [
        mixed_record(i, 100, 2026)[1:] for i in (49, 50, 99)]
    qs = {i: mixed_record(i, 100, 2026)[1] for i in (0, 49, 50, 99)}
    assert qs[0] == pytest.approx(5.0) and qs[49] == pytest.approx(8.0)
    assert 8.0 < qs[50] < 9.0 and qs[99] == pytest.approx(200.0)
    assert {mix for _, mix, _ in rows} == {"b", "ab", "bc", "abc"}
    assert all(1e-4 <= noise <= 1e-2 for _, _, noise in rows)
    record, q, mix, noise = mixed_record(3, 100, 2026)
    assert record.t.size == 10_000 and record.t[-1] == pytest.approx(40.0)
    # The first decay rate is omega/(2Q): the first crests fall by exp(-pi/Q) a cycle.
    crests = find_turning_points(record.t, record.x)
    first = np.abs(crests.y[:6])
    assert first[2] / first[0] == pytest.approx(math.exp(-math.pi / q), rel=0.05)


@pytest.mark.parametrize("kind", ["b", "viscous", "pendulum"])
def test_a_tiny_run_reports_every_record(monkeypatch, capsys, kind):
    monkeypatch.setattr(waveform_speed, "WAVEFORM_QS", (10,))
    monkeypatch.setattr(waveform_speed, "WAVEFORM_MIXES", (kind,))
    monkeypatch.setattr("sys.argv", ["-", json.dumps({"records": 2, "runs": 1,
                                                       "seed": 1})])
    waveform_speed.main()
    found = json.loads(capsys.readouterr().out)
    assert [row[1] for row in found["mixed"]] == ["b", "ab"]
    assert all(row[4] > 0 and row[5] > 0 for row in found["mixed"])
    (q, mix, seconds), = found["waveform"]
    assert (q, mix) == (10, kind) and seconds > 0


@pytest.mark.parametrize("kind", ["viscous", "pendulum"])
def test_the_other_forms_records_are_what_they_say(kind):
    """10^4 samples decaying at Q = 10: the viscous oscillator's crests fall by
    exp(-pi/Q) a cycle, and the pendulum swings from 0.8 rad and is fitted by its own
    equation of motion to b = omega/(2*Q) within 3 standard errors."""
    from mcfit.bench.waveform_speed import _waveform_fit_as_auto, q_record

    t, x = q_record(10, kind, 1)
    assert t.size == waveform_speed.SAMPLES
    crests = find_turning_points(t, x)
    fit, args = _waveform_fit_as_auto(t, x, crests, kind == "pendulum")
    if kind == "viscous":
        first = np.abs(crests.y[:6])
        assert first[2] / first[0] == pytest.approx(math.exp(-math.pi / 10), rel=0.02)
        return
    assert np.max(np.abs(x)) == pytest.approx(waveform_speed.PENDULUM_RELEASE, abs=0.01)
    result = fit(*args)
    assert abs(result.values["b"] - math.pi / 10) < 3 * result.stderr["b"]


def test_the_report_names_each_target_and_its_verdict():
    mixed = ((5.0, "b", 1e-3, "waveform", 0.5, 0.01), (50.0, "ab", 1e-3, "turning-points",
                                                        0.012, 0.01),
             (6.0, "bc", 1e-3, None, None, 0.01))
    waveform = {(q, mix): 0.04 for q in waveform_speed.WAVEFORM_QS
                for mix in waveform_speed.WAVEFORM_MIXES}
    waveform[(2, "bc")] = None
    text = format_waveform_speed(WaveformSpeed(QUICK, mixed, waveform))
    # auto 2 records in 0.512 s (3.9 a second), turning points 2 in 0.02 s: 25.6 times.
    assert "auto / turning points, CPU per record (mixed batch)        25.6x" in text
    assert "auto: records per CPU second (mixed batch)                   3.9" in text
    assert "40 ms   target <= 50 ms    met" in text
    assert "(1 records refused by a method, left out)" in text
    assert "     2        40         -" in text
