"""A steady line (mains hum) far from the oscillation is removed; rows missing (the time
column jumps) are bridged (issue 19)."""

from __future__ import annotations

import numpy as np
import pytest

from mcfit import decay
from mcfit.analysis import analyse_record
from mcfit.errors import RecordError
from mcfit.hum import peak_frequency
from mcfit.motion import simulate_record
from mcfit.io import Record
from mcfit.turning import find_turning_points

B = 0.1


def _decay(seed, *, rate, duration=30.0, hum=0.0, hum_frequency=50.0, harmonics=(),
           missing=None, noise=0.01):
    """b = 0.1 /s, period 1 s, amplitude 1, plus a hum of amplitude ``hum`` (and
    ``harmonics``: (order, amplitude) pairs); rows in ``missing`` (start, length) dropped."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    x = decay.amplitude(t, 1.0, 0.0, B, 0.0) * np.cos(2 * np.pi * t)
    x = x + rng.normal(0.0, noise, t.size)
    phase = rng.uniform(0.0, 2 * np.pi)
    for order, amplitude in ((1, hum), *harmonics):
        x = x + amplitude * np.sin(2 * np.pi * order * hum_frequency * t + order * phase)
    if missing is not None:
        keep = (t < missing[0]) | (t >= missing[0] + missing[1])
        t, x = t[keep], x[keep]
    return t, x


def _fit(t, x):
    analysis = analyse_record(Record(source="record", t=t, x=x))
    assert analysis.status == "ok", analysis.error
    return analysis


def _b_within_3_sigma(analysis):
    fit = analysis.fit
    assert fit.model == "b"
    b, sigma = fit.values["b"], fit.stderr["b"]
    assert abs(b - B) < 3 * sigma, (b, sigma)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_50_hz_hum_at_30_percent_is_removed(seed):
    # 1 kHz, hum at 30 % of the initial amplitude: it was the spectrum's peak, taken as the
    # oscillation, and the fit said model a (or none) with b = 0.
    analysis = _fit(*_decay(seed, rate=1000.0, hum=0.3))
    _b_within_3_sigma(analysis)
    notes = [n for n in analysis.turning.notes if "hum" in n]
    assert len(notes) == 1 and "removed" in notes[0] and "frequency 50 " in notes[0]
    assert "amplitude 0.3" in notes[0]
    assert analysis.turning.period == pytest.approx(1.0, rel=1e-3)


def test_a_weak_hum_with_harmonics_is_removed_with_them():
    # Weaker than the oscillation (found as the second line), with 2nd and 3rd harmonics.
    t, x = _decay(3, rate=1000.0, hum=0.05, harmonics=((2, 0.03), (3, 0.04)))
    points = find_turning_points(t, x)
    note = next(n for n in points.notes if "hum" in n)
    assert "2 harmonic(s)" in note
    clean = find_turning_points(*_decay(3, rate=1000.0))
    np.testing.assert_allclose(points.y[points.used], clean.y[clean.used],
                               atol=3 * np.max(clean.sigma[clean.used]))


def test_a_steady_line_below_the_oscillation_is_removed():
    analysis = _fit(*_decay(4, rate=100.0, hum=0.3, hum_frequency=0.23))
    _b_within_3_sigma(analysis)
    assert any("hum" in n and "0.23 times" in n for n in analysis.turning.notes)


def test_a_record_without_hum_is_untouched(monkeypatch):
    # The same turning points, bit for bit, as with the hum step switched off.
    import mcfit.turning as turning

    t, x = _decay(5, rate=1000.0)
    points = find_turning_points(t, x)
    assert not any("hum" in n for n in points.notes)
    monkeypatch.setattr(turning, "find_steady_line", lambda *args: None)
    plain = find_turning_points(t, x)
    for name in ("t", "y", "sigma", "used"):
        np.testing.assert_array_equal(getattr(points, name), getattr(plain, name))
    assert points.notes == plain.notes


def test_a_decaying_higher_mode_is_not_a_hum():
    # A second line 5.3 times the frequency that decays with the first is left alone.
    t, x = _decay(6, rate=200.0)
    x = x + 0.3 * np.exp(-0.2 * t) * np.cos(2 * np.pi * 5.3 * t)
    points = find_turning_points(t, x)
    assert not any("hum" in n for n in points.notes)


@pytest.mark.parametrize("seed", [1, 2, 4])
def test_six_seconds_of_missing_rows_are_bridged(seed):
    # A paused logger: the time column jumps from 10 to 16 s (no NaN). The line drawn
    # across the gap was the spectrum's peak (period 17 s): "only 2 usable turning points".
    t, x = _decay(seed, rate=100.0, missing=(10.0, 6.0))
    analysis = _fit(t, x)
    _b_within_3_sigma(analysis)
    turning = analysis.turning
    assert turning.gaps == ((pytest.approx(9.99), pytest.approx(16.0)),)
    note = next(n for n in turning.notes if "gap" in n)
    assert "from t = 9.99 to 16 " in note and "6.01 time units" in note and "bridged" in note
    used = turning.t[turning.used]
    assert np.count_nonzero(used < 10) >= 18 and np.count_nonzero(used > 16) >= 26


def test_a_gap_and_a_hum_together():
    analysis = _fit(*_decay(7, rate=1000.0, hum=0.3, missing=(10.0, 6.0)))
    _b_within_3_sigma(analysis)
    notes = analysis.turning.notes
    assert any("hum" in n for n in notes)
    assert any("gap" in n and "about 6 periods" in n for n in notes)


def test_the_waveform_fit_sees_the_record_without_its_hum():
    """Q = 3 at SNR 1e4 with a 50 Hz hum: auto fits the waveform, hum removed, b unbiased
    (with the hum left in, the waveform misfits and the turning points' b is 300 SE low)."""
    from mcfit.motion import simulate_record

    t, x = simulate_record(0.0, 1.0, 0.0, 1.0, 1.0, 8.0, 400.0, method="accurate",
                           noise=1e-4, rng=np.random.default_rng(1))
    x = x + 0.02 * np.sin(2 * np.pi * 50.0 * t)
    fit = analyse_record(Record(source="q3 hum", t=t, x=x)).fit
    assert fit.method == "waveform" and fit.model == "b"
    assert abs(fit.values["b"] - 1.0) < 3 * fit.stderr["b"]


def test_a_peak_frequency_stays_between_the_neighbouring_bins():
    """The parabola through the log power finds a Gaussian line between bins, at its peak
    bin (20.3 from bin 20) and from the bin beside it (the edge of a band searched: 20.3
    from bin 21); where the log power is nearly straight, the vertex stays within a bin
    instead of anywhere."""
    frequencies = np.arange(64) * 0.05
    bins = np.arange(64)
    line = np.exp(-0.5 * ((bins - 20.3) / 1.5) ** 2)
    for k in (20, 21):
        assert peak_frequency(line, frequencies, k) == pytest.approx(20.3 * 0.05, rel=1e-12)
    slope = np.exp(-0.2 * bins - 1e-7 * (bins - 9) ** 2)  # straight but for a hair
    assert abs(peak_frequency(slope, frequencies, 9) - 9 * 0.05) <= 0.05


def test_a_hum_search_at_the_edge_of_its_band_is_no_crash():
    """A decay whose spectrum's strongest line apart from the oscillation sat on the lowest
    bin searched, with nearly straight log power there: the hum's frequency came out at
    -816 and the harmonics' search raised a ValueError (a traceback for the user). Now the
    record gets the turning-point search's own verdict: the decay stops (c = 0.018) and
    what follows is left out."""
    t, x = simulate_record(0.24409898330981858, 0.001261810135739639, 0.018465360816708534,
                           1.0, 1.0, 37.0, 15.0, method="accurate", noise=1 / 4091.57,
                           rng=np.random.default_rng(186092))
    points = find_turning_points(t, x)
    assert points.count >= 20 and not points.warnings
    assert any(note.startswith(("the motion stops by", "the decay ends in the noise"))
               for note in points.notes)
