"""The methods section of ``mcfit bench``: turning-point fit against waveform fit over Q."""

from __future__ import annotations

import pytest

from mcfit import bench
from mcfit.bench.methods import format_methods, record_duration, run_methods


def test_records_decay_to_a_thousandth_within_8_cycles_and_40_s():
    assert [record_duration(q) for q in (2, 3, 5, 10, 20, 50)] == [8, 8, 11, 22, 40, 40]


def test_methods_section_is_wired_into_the_bench():
    assert "methods" in bench.SECTIONS
    assert (bench.QUICK.method_records, bench.FULL.method_records) == (3, 40)
    assert bench.FULL.method_qs == (2, 3, 5, 10, 20, 50)


@pytest.mark.slow  # about 25 s: each record is fitted by both methods and by auto
def test_waveform_fit_removes_the_turning_point_bias_at_q_3():
    messages = []
    rows = run_methods(2, seed=2026, qs=(3, 5), progress=messages.append)
    text = format_methods(rows)
    assert messages == ["methods: Q = 3", "methods: Q = 5"]
    lines = text.splitlines()
    assert lines[0].startswith("Methods against Q") and len(lines) == 4
    assert lines[1].split()[:2] == ["Q", "N"]
    for row, line in zip(rows, lines[2:]):
        cells = line.split()
        assert len(cells) == 12 and float(cells[0]) == row.q and int(cells[1]) == 2
        assert float(cells[2]) == pytest.approx(row.turning_points.bias, abs=0.006)
        assert float(cells[6]) == pytest.approx(row.waveform.bias, abs=0.006)
        for stats in (row.turning_points, row.waveform):
            assert stats.rmse >= abs(stats.bias) and 0 <= stats.coverage <= 1
            assert stats.seconds > 0
        assert 0 <= row.auto_waveform <= 1 and row.auto_seconds > 0
    q3 = rows[0]
    # The averaged law misses b by about 1.2 % at Q = 3: 100+ standard errors at SNR 1e4.
    assert abs(q3.turning_points.bias) > 20 and q3.turning_points.coverage == 0
    assert abs(q3.waveform.bias) < abs(q3.turning_points.bias)
    assert abs(q3.waveform.bias) < 5
