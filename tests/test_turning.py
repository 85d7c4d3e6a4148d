"""Turning points of synthetic decays (closed-form envelope plus offset, drift and noise)."""

from __future__ import annotations

import sys
import tracemalloc
import warnings
from pathlib import Path

import numpy as np
import pytest

from mcfit.decay import amplitude
from mcfit.errors import RecordError, UsageError
from mcfit.turning import find_turning_points, turning_points_from_table
from mcfit.turning import common, crests, equilibrium, refine, spectrum, windows
from mcfit.turning.common import _running_median
from mcfit.turning.windows import _window_sums

REALDATA = Path(__file__).parents[2] / "shared" / "realdata"
# y0, a, b, c: all three regimes present, Q of order 50 to 200.
LAW = (1.0, 0.02, 0.01, 0.002)


@pytest.fixture
def rng():
    return np.random.default_rng(20240611)


def waveform(samples_per_cycle, cycles=40, period=1.0, noise=0.0, offset=0.3, drift=0.002,
             phase=0.4, law=LAW, rng=None):
    t = np.arange(int(samples_per_cycle * cycles)) * period / samples_per_cycle
    x = amplitude(t, *law) * np.cos(2 * np.pi * t / period + phase) + offset + drift * t
    if noise:
        x = x + rng.normal(0.0, noise, t.size)
    return t, x


@pytest.mark.parametrize("samples_per_cycle", [8, 20, 200])
def test_noise_free_amplitudes_within_1e_4(samples_per_cycle):
    t, x = waveform(samples_per_cycle)
    points = find_turning_points(t, x)
    used = points.used
    assert points.count >= 75
    relative = points.y[used] / amplitude(points.t[used], *LAW) - 1
    assert np.max(np.abs(relative)) < 1e-4
    assert points.period == pytest.approx(1.0, rel=1e-5)
    assert points.equilibrium == pytest.approx(0.3, abs=1e-4)
    assert points.equilibrium_drift == pytest.approx(0.002, rel=1e-3)
    # Maxima and minima alternate.
    assert np.all(points.sign[1:] != points.sign[:-1])


@pytest.mark.parametrize("samples_per_cycle", [20, 200])
def test_noise_scatter_reaches_the_half_cycle_bound(samples_per_cycle, rng):
    sigma_x = 0.01
    errors, predicted = [], []
    for _ in range(8):
        t, x = waveform(samples_per_cycle, noise=sigma_x, rng=rng)
        points = find_turning_points(t, x)
        used = points.used
        errors.append(points.y[used] - amplitude(points.t[used], *LAW))
        predicted.append(points.sigma[used])
        assert points.noise_sigma == pytest.approx(sigma_x, rel=0.1)
    errors = np.concatenate(errors)
    bound = np.sqrt(2 * sigma_x**2 / (samples_per_cycle / 2))  # docs/theory.md section 8
    assert np.std(errors) < 1.15 * bound
    assert abs(np.mean(errors)) < 4 * bound / np.sqrt(errors.size)
    assert np.mean(np.concatenate(predicted)) == pytest.approx(bound, rel=0.15)


def test_noise_does_not_create_false_extrema(rng):
    t, x = waveform(100, noise=0.03, rng=rng)
    points = find_turning_points(t, x)
    assert np.all(np.diff(points.t) > 0.4)
    assert np.all(points.sign[1:] != points.sign[:-1])


def test_decay_into_white_noise_is_followed_until_lost(rng):
    # The crests are kept, as projections onto the crest phase, while a group of them still
    # shows the oscillation; only the pure-noise tail after that is excluded.
    law = (1.0, 0.0, 0.1, 0.0)
    t, x = waveform(50, cycles=80, noise=0.01, law=law, rng=rng)
    points = find_turning_points(t, x)
    sigma_y = np.median(points.sigma[points.used])
    assert amplitude(points.noise_floor_time, *law) < 2 * sigma_y
    assert points.noise_floor_time < 75
    assert any("noise" in note for note in points.notes)
    used = points.used
    assert np.any(points.y[used] < 0)  # noise about a vanishing envelope, kept signed
    z = (points.y[used] - amplitude(points.t[used], *law)) / points.sigma[used]
    assert np.all(np.abs(z) < 5)
    assert abs(np.mean(z)) < 4 / np.sqrt(z.size)  # unbiased down into the noise


def test_projections_are_unbiased_near_the_noise(rng):
    # Magnitudes of two-parameter fits are biased upwards near the noise (Rician); the
    # projections onto the smoothed crest phase are not.
    law = (1.0, 0.0, 0.1, 0.0)
    z = []
    for _ in range(10):
        t, x = waveform(20, cycles=60, noise=0.02, law=law, rng=rng)
        points = find_turning_points(t, x)
        used = points.used
        truth = amplitude(points.t[used], *law)
        low = truth < 3 * points.sigma[used]
        z.append(((points.y[used] - truth) / points.sigma[used])[low])
    z = np.concatenate(z)
    assert z.size > 100
    assert abs(np.mean(z)) < 3 / np.sqrt(z.size)
    assert np.std(z) == pytest.approx(1.0, abs=0.15)


def test_a_long_ringdown_keeps_no_crest_whose_phase_has_slipped():
    # Q = 1e4, 5e4 cycles at 20 samples a cycle into noise 1e-3: the crests are followed
    # until the amplitude is a few times the noise, not into it, where the smoothed phase
    # slips by up to a radian and the projections come out low (a decay that looks as if
    # it sped up at small amplitude: a false Coulomb term).
    rate, b = 20.0, np.pi / 1e4
    t = np.arange(50000 * 20) / rate
    rng = np.random.default_rng(12)
    x = np.exp(-b * t) * np.cos(2 * np.pi * t + 0.3) + rng.normal(0, 1e-3, t.size)
    points = find_turning_points(t, x)
    used = points.used
    truth = np.exp(-b * points.t[used])
    z = (points.y[used] - truth) / points.sigma[used]
    faint = truth < 20 * points.sigma[used]
    assert faint.sum() > 500 and abs(np.mean(z[faint])) < 4 / np.sqrt(faint.sum())
    assert np.min(truth / points.sigma[used]) > 4
    crest = (np.rint((2 * np.pi * points.t[used] + 0.3) / np.pi) * np.pi - 0.3) / (2 * np.pi)
    assert np.max(np.abs(points.t[used] - crest)) * 2 * np.pi < 0.5  # rad


def test_the_last_crests_of_a_record_ending_near_the_noise_are_unbiased(rng):
    # Fig. 20.19 at SNR 1e2: the record ends with crests at about 3 sigma, where the smoothed
    # crest phase is least certain (one-sided). A phase error d shrinks a projection by
    # cos(d); uncorrected, the last crests come out about 0.1 sigma low.
    law, period, phase = (4.0, 0.1, 0.1, 0.01), 0.5, 0.4
    z = []
    for _ in range(300):
        t, x = waveform(20.29, cycles=40, period=period, noise=0.04, offset=0.1, drift=0.0,
                        phase=phase, law=law, rng=rng)
        points = find_turning_points(t, x)
        crest = (np.rint((2 * np.pi * points.t / period + phase) / np.pi) * np.pi - phase) \
            * period / (2 * np.pi)  # the true crest nearest each one found
        last = np.flatnonzero(points.used)[-6:]
        z.append((points.y[last] - amplitude(crest[last], *law)) / points.sigma[last])
    z = np.concatenate(z)
    assert abs(np.mean(z)) < 3 / np.sqrt(z.size)
    assert np.std(z) == pytest.approx(1.0, abs=0.1)


def test_a_displaced_crest_in_the_tail_does_not_shift_the_numbering():
    # Crests every 0.25 s; the last two measured ones are faint, 0.58 and 0.45 rad off,
    # after four crests lost in the noise, where the local half-period reads short (0.19).
    # Counted by spacing, the gap takes 7 half-periods instead of 5 and every later crest
    # is a period off; numbered against the well-measured crests, none is.
    from mcfit.turning import _crest_sequence

    number = np.concatenate([np.arange(70), [74, 75]])
    truth = 0.1 + 0.25 * number
    times = truth + np.concatenate([np.zeros(70), [0.58, -0.45]]) * 0.25 / np.pi
    signs = np.where(number % 2 == 0, 1, -1)
    weights = np.concatenate([np.full(60, 1e4), np.full(10, 50.0), [30.0, 22.0]])
    half = np.where(number < 66, 0.25, 0.19)
    crests, crest_signs, variance, lost = _crest_sequence(times, signs, half, weights,
                                                          limit=19.2)
    expected = 0.1 + 0.25 * np.arange(crests.size)
    assert crests.size == 77
    np.testing.assert_allclose(crests, expected, atol=0.03)
    np.testing.assert_array_equal(crest_signs, np.where(np.arange(77) % 2 == 0, 1, -1))
    assert np.all(np.diff(variance[60:]) > 0)  # the phase grows less certain into the tail
    assert lost is None


def test_the_crest_sequence_stops_where_its_phase_is_lost():
    # Bright crests, then faint ones, then one faint crest alone far beyond: it is left out
    # (alone it fixes neither time nor slope), and the sequence continues from the faint
    # crests only while its phase is known to 1 rad.
    from mcfit.turning import _LARGEST_PHASE_VARIANCE, _crest_sequence

    number = np.concatenate([np.arange(70), [95]])
    times = 0.1 + 0.25 * number
    signs = np.where(number % 2 == 0, 1, -1)
    weights = np.concatenate([np.full(60, 1e4), np.full(10, 30.0), [30.0]])
    crests, _, variance, lost = _crest_sequence(times, signs, np.full(71, 0.25), weights,
                                                limit=50.0)
    assert np.all(np.isfinite(variance))
    assert np.all(variance <= _LARGEST_PHASE_VARIANCE)
    assert 70 < crests.size < 196
    assert lost == pytest.approx(crests[-1] + 0.25)
    np.testing.assert_allclose(crests, 0.1 + 0.25 * np.arange(crests.size), atol=1e-9)


def test_noise_floor_points_are_excluded(rng):
    # A sustained small vibration the decay sinks into: the envelope flattens.
    law = (1.0, 0.0, 0.12, 0.0)
    t = np.arange(0, 60, 0.02)
    x = (amplitude(t, *law) * np.cos(2 * np.pi * t)
         + 0.01 * np.cos(2 * np.pi * 1.37 * t) + rng.normal(0, 1e-3, t.size))
    points = find_turning_points(t, x)
    assert "noise floor" in points.excluded_reason
    assert 15 < points.noise_floor_time < 45
    assert not points.used[-1]


def test_clipped_extrema_are_excluded(rng):
    t, x = waveform(40, cycles=30, noise=0.001, drift=0.0, rng=rng)
    x = np.minimum(x, 0.3 + 0.8)
    points = find_turning_points(t, x)
    clipped = np.array([r == "clipped" for r in points.excluded_reason])
    assert clipped.sum() >= 3
    assert np.all(points.sign[clipped] == 1)
    assert any("clipped" in note for note in points.notes)
    used = points.used
    assert np.max(np.abs(points.y[used] / amplitude(points.t[used], *LAW) - 1)) < 0.01


def test_uneven_sampling_and_gaps(rng):
    t = np.sort(rng.uniform(0, 40, 1200))
    x = amplitude(t, *LAW) * np.cos(2 * np.pi * t + 0.3) + 0.1
    x[300:340] = np.nan
    points = find_turning_points(t, x)
    assert points.gaps
    assert any("gap" in note for note in points.notes)
    used = points.used
    assert np.max(np.abs(points.y[used] / amplitude(points.t[used], *LAW) - 1)) < 1e-3


def _gapped_record(seed, resume, law=(1.0, 0.0, 0.02, 0.0), noise=1e-3):
    """100 cycles at 40 samples per cycle, without the samples from t = 60 to ``resume``."""
    rng = np.random.default_rng(seed)
    t = np.arange(100 * 40) / 40
    x = amplitude(t, *law) * np.cos(2 * np.pi * t + 0.4) + rng.normal(0.0, noise, t.size)
    keep = (t < 60) | (t > resume)
    return t[keep], x[keep]


def test_a_long_gap_leaves_the_equilibrium_alone():
    # Sixth differences of amplitudes taken across a 36-cycle gap saw the decay over the
    # gap as alternation: the equilibrium drifted by 5e-3 over the record and the crests
    # after the gap alternated by 1.6 to 2 sigma about the envelope.
    alternation = []
    for seed in range(6):
        points = find_turning_points(*_gapped_record(seed, 96.3))
        assert abs(points.equilibrium_drift) < 1e-5
        assert not any("equilibrium drifts" in note for note in points.notes)
        after = points.used & (points.t > 96.3)
        z = (points.y - amplitude(points.t, 1.0, 0.0, 0.02, 0.0)) / points.sigma
        alternation.append(np.mean(z[after] * points.sign[after]))
    assert abs(np.mean(alternation)) < 0.8


def fast_viscous_decay(how, seed, duration=6.0, offset=0.0, drift=0.0):
    """(t, x, beta): x = exp(-0.8 t) cos(2 pi t) (Q = 3.9) in closed form, or viscous
    damping 2*beta*x' at Q = 4 from an integration that shares no code with mcfit;
    ``duration`` s at 400 Hz, noise 1e-4, about an equilibrium offset + drift*t."""
    from mcfit.bench.reference_motion import viscous

    if how == "closed form":
        beta = 0.8
        t = np.arange(0.0, duration, 1 / 400)
        x = np.exp(-beta * t) * np.cos(2 * np.pi * t)
    else:
        beta = np.pi / 4
        t, x = viscous(beta, 2 * np.pi, 1.0, duration, 400.0)
    noise = np.random.default_rng(seed).normal(0.0, 1e-4, t.size)
    return t, x + offset + drift * t + noise, beta


@pytest.mark.parametrize("quality", [2.0, 3.9, 10.0])
def test_the_equilibrium_of_a_fast_decay_is_unbiased(quality):
    """The midpoints of successive crests of a decaying cosine lie off its equilibrium
    (by 6e-3 at Q = 3.9, with a drift of -2e-3 per second over 11 crests): the line
    refined from the crests' alternation, with the decay's envelope divided out, lies
    on the equilibrium."""
    t = np.arange(0.0, 6.0, 1 / 400)
    x = np.exp(-np.pi / quality * t) * np.cos(2 * np.pi * t)
    points = find_turning_points(t, x)
    assert abs(points.equilibrium) < 1e-6 and abs(points.equilibrium_drift) < 1e-6
    np.testing.assert_allclose(points.y, np.exp(-np.pi / quality * points.t), atol=2e-6)


@pytest.mark.parametrize("how", ["closed form", "integrated"])
def test_turning_points_of_a_fast_viscous_decay_fit_within_their_noise(how):
    """Issue 25's textbook oscillator (Q = 3.9, 6 s at 400 Hz, noise 1e-4) once gave a
    reduced chi-square of 2,350-2,700 by its turning points and a false note "equilibrium
    drifts by -0.055"; a viscous decay's turning points follow dy/dt = -b*y exactly, so
    b = beta within its error, the reduced chi-square near 1, and no drift is said."""
    from mcfit import analyse

    fits = []
    for seed in range(6):
        t, x, beta = fast_viscous_decay(how, seed)
        analysis = analyse(t, x, method="turning-points")
        fit = analysis.fit
        assert fit.model == "b" and abs(fit.values["b"] - beta) < 3 * fit.stderr["b"]
        assert not any("equilibrium drifts" in note for note in analysis.turning.notes)
        assert abs(analysis.turning.equilibrium_drift) < 1e-4
        fits.append(fit.reduced_chi_square)
    assert max(fits) < 3 and np.mean(fits) < 1.5


def test_a_real_drift_of_a_fast_decays_equilibrium_is_still_found():
    """The viscous decay at Q = 4 about an equilibrium 0.3 + 0.02*t: the drift is found to
    within 1e-4 per second, said in a note, and the turning points fit within their noise."""
    from mcfit import analyse

    for seed in range(3):
        t, x, beta = fast_viscous_decay("integrated", seed, offset=0.3, drift=0.02)
        analysis = analyse(t, x, method="turning-points")
        assert analysis.turning.equilibrium_drift == pytest.approx(0.02, abs=1e-4)
        assert "equilibrium drifts by 0.12 over the record" in analysis.turning.notes
        assert analysis.fit.reduced_chi_square < 3
        assert abs(analysis.fit.values["b"] - beta) < 3 * analysis.fit.stderr["b"]


def test_a_fast_decay_of_seven_crests_fits_within_its_noise():
    """3.6 s of the viscous decay at Q = 4: seven crests, too few for a window of seven,
    so the equilibrium comes from fourth differences (the coarse line's drift was kept
    before, and the fit misfitted by a reduced chi-square in the thousands)."""
    from mcfit import analyse

    fits = []
    for seed in range(6):
        t, x, beta = fast_viscous_decay("integrated", seed, duration=3.6)
        analysis = analyse(t, x, method="turning-points")
        assert np.count_nonzero(analysis.turning.used) == 7
        assert analysis.fit.model == "b"
        assert abs(analysis.fit.values["b"] - beta) < 3 * analysis.fit.stderr["b"]
        assert not any("equilibrium drifts" in note for note in analysis.turning.notes)
        fits.append(analysis.fit.reduced_chi_square)
    assert max(fits) < 4 and np.mean(fits) < 2


@pytest.mark.parametrize("seed", range(6))
def test_a_crest_just_after_a_long_gap_keeps_its_amplitude(seed):
    # The decay rate's slope extrapolated across the gap reached its old bound, 0.1*omega**2,
    # which bent the window's envelope by about 10 %: the crest was 3 to 7 sigma low.
    points = find_turning_points(*_gapped_record(seed, 99.2))
    first_after = np.flatnonzero(points.used & (points.t > 96.3))[0]
    expected = amplitude(points.t[first_after], 1.0, 0.0, 0.02, 0.0)
    assert abs(points.y[first_after] - expected) < 3 * points.sigma[first_after]


def test_the_sigma_of_a_cut_window_includes_its_phase_error():
    # The last crest's window ends at the record's end, so a crest-phase error d moves its
    # projection to first order (by about 0.64*y*d). After a long gap the phase of the few
    # crests left is known to about 0.01 rad: without that term in sigma the last crest
    # was 2 to 5 sigma off in a third of the records.
    z = []
    for seed in range(12):
        points = find_turning_points(*_gapped_record(seed, 99.2))
        last = np.flatnonzero(points.used)[-1]
        z.append((points.y[last] - amplitude(points.t[last], 1.0, 0.0, 0.02, 0.0))
                 / points.sigma[last])
    assert np.sqrt(np.mean(np.square(z))) < 1.5
    assert np.max(np.abs(z)) < 3.5


@pytest.mark.parametrize("decaying", [True, False])
def test_window_sums_are_each_windows_sums_by_hand(decaying, rng):
    """The sums of every window at once (one complex exponential for the envelope, cos and
    sin) against each window's sums written out, on uneven times with an empty window;
    with decay rates, and without (the first pass, envelope 1)."""
    t = np.cumsum(rng.uniform(0.5, 1.5, 400)) * 0.01
    x = rng.normal(0.0, 1.0, t.size)
    lo, hi = np.array([3, 60, 60, 150, 290]), np.array([50, 60, 140, 260, 400])
    centres = 0.5 * (t[lo] + t[hi - 1])
    omega = rng.uniform(5.0, 9.0, lo.size)
    gamma = rng.uniform(-0.5, 0.5, (2, lo.size)) * decaying
    line = (0.2, -0.03, 1.0)
    sums = _window_sums(t, x, lo, hi, centres, omega, gamma, line)
    for k in range(lo.size):
        s = t[lo[k]:hi[k]] - centres[k]
        envelope = np.exp(-gamma[0, k] * s - 0.5 * gamma[1, k] * s**2)
        u1, u2 = envelope * np.cos(omega[k] * s), envelope * np.sin(omega[k] * s)
        r = x[lo[k]:hi[k]] - line[0] - line[1] * (t[lo[k]:hi[k]] - line[2])
        by_hand = [np.sum(v) for v in (u1 * u1, u1 * u2, u2 * u2, u1 * r, u2 * r, u1, u2,
                                        r * r)]
        np.testing.assert_allclose(sums[:, k], by_hand, rtol=1e-12, atol=1e-12)


def test_a_settle_noise_ends_the_refinement_of_clean_crests(monkeypatch):
    """A noise-free waveform settles only in its (rounding) noise; told a sample noise, the
    refinement stops sooner, once the crests' shifts are within it, and the amplitudes stay
    within a tenth of what that noise would scatter them by."""
    from mcfit.turning import refine

    passes = []
    fit_windows = refine._fit_windows
    monkeypatch.setattr(refine, "_fit_windows",
                        lambda *args, **kwargs: passes.append(1) or fit_windows(*args, **kwargs))
    t, x = waveform(50)
    refined = find_turning_points(t, x)
    every_pass = len(passes)
    passes.clear()
    noise = 1e-3
    settled = find_turning_points(t, x, settle_noise=noise)
    assert len(passes) < every_pass <= refine._REFINE_PASSES
    assert np.array_equal(settled.used, refined.used)
    amplitude_sigma = noise * np.sqrt(2 / 50)  # a half-cycle of 25 samples
    assert np.max(np.abs(settled.y - refined.y)) < 0.1 * amplitude_sigma


@pytest.mark.parametrize("noise", [0.0, -1e-3, np.nan, np.inf])
def test_a_settle_noise_must_be_a_positive_number(noise):
    t, x = waveform(50)
    with pytest.raises(UsageError, match="settle_noise must be a positive number"):
        find_turning_points(t, x, settle_noise=noise)


def test_period_drift_with_amplitude():
    # Period grows with amplitude, as for a pendulum: T = 1 + 0.05*y**2.
    t = np.linspace(0, 60, 12001)
    y = np.exp(-0.03 * t)
    phase = np.cumsum(2 * np.pi / (1 + 0.05 * y**2)) * (t[1] - t[0])
    points = find_turning_points(t, y * np.cos(phase))
    assert points.period_drift > 3 * points.period_drift_sigma
    expected = 0.05 * (np.max(points.y) ** 2 - np.min(points.y[points.used]) ** 2)
    assert points.period_drift == pytest.approx(expected, rel=0.3)
    assert any("period changes" in note for note in points.notes)


def test_a_beat_is_fitted_before_its_first_node_and_named_in_a_warning():
    t = np.arange(0, 60, 0.05)
    x = np.cos(2 * np.pi * t) + 0.8 * np.cos(2 * np.pi * 1.1 * t)
    points = find_turning_points(t, x, source="beat.csv")
    assert len(points.warnings) == 1 and "beating of two modes" in points.warnings[0]
    # The envelope |1 + 0.8 exp(0.2 pi i t)| falls to its node at t = 5.
    assert np.all(points.t[points.used] < 5.0)
    after = np.array(points.excluded_reason) == "after the decay"
    assert np.all(points.t[after] > 4.0) and np.count_nonzero(after) > 100


def test_growth_is_an_error():
    t = np.arange(0, 60, 0.05)
    with pytest.raises(RecordError, match="grows.*not a free decay"):
        find_turning_points(t, np.exp(0.05 * t) * np.cos(2 * np.pi * t))


def test_too_few_turning_points_is_an_error():
    t = np.arange(0, 1.6, 0.02)
    with pytest.raises(RecordError, match="need 4"):
        find_turning_points(t, np.cos(2 * np.pi * t + 0.5), source="short.csv")


@pytest.mark.parametrize("x, message", [
    (np.ones(100), "constant"),
    (np.full(100, np.nan), "all NaN"),
])
def test_bad_signals(x, message):
    with pytest.raises(RecordError, match=message):
        find_turning_points(np.arange(100.0), x)


def test_time_not_increasing():
    t = np.arange(100.0)
    t[50] = t[49]
    with pytest.raises(RecordError, match="does not increase"):
        find_turning_points(t, np.cos(t))


def test_table_of_signed_extrema_about_an_offset():
    n = np.arange(20)
    y = amplitude(n * 0.5, 1.0, 0.0, 0.05, 0.0)
    values = np.where(n % 2 == 0, 1.0, -1.0) * y + 0.07
    order = np.argsort(n % 2, kind="stable")  # maxima first, then minima, as in a file
    points = turning_points_from_table(n[order] * 0.5, values[order])
    assert np.all(np.diff(points.t) > 0)
    assert points.equilibrium == pytest.approx(0.07, abs=1e-3)
    np.testing.assert_allclose(points.y, y, atol=2e-3)
    assert points.period == pytest.approx(1.0)


def test_table_of_amplitudes_against_cycle_number():
    n = np.arange(1, 41, dtype=float)
    y = amplitude(n, 7.69, 0.036, 0.025, 0.0)
    points = turning_points_from_table(n, y, domain="cycle")
    np.testing.assert_array_equal(points.y, y)
    assert points.period == 1.0
    assert points.count == 40


def test_core_imports_no_pandas():
    import subprocess
    code = ("import sys, mcfit.turning; "
            "print(any(m in sys.modules for m in ('pandas', 'matplotlib', 'click')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


needs_realdata = pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata absent")


@needs_realdata
def test_real_pendulum_turning_points():
    from mcfit.io import read_record
    from mcfit.turning import turning_points_of
    points = turning_points_of(read_record(REALDATA / "pendulum_cup" / "lab1_data.txt"))
    assert points.count > 130
    assert points.period == pytest.approx(1.64, rel=0.01)
    used = points.y[points.used]
    assert used[0] == pytest.approx(0.67, rel=0.05)
    assert used[-1] == pytest.approx(0.19, rel=0.1)


@needs_realdata
def test_real_large_swing_period_depends_on_amplitude():
    from mcfit.io import read_record
    from mcfit.turning import turning_points_of
    points = turning_points_of(read_record(REALDATA / "pendulum_cup" / "trial1_rawdata.txt"))
    assert points.count >= 17
    assert points.period_drift > 3 * points.period_drift_sigma
    table = turning_points_of(read_record(REALDATA / "pendulum_cup" / "trial1_extrema.txt"))
    assert table.count == 19
    # The author's single-sample extrema and ours agree to a few percent.
    ours = np.interp(table.t, points.t, points.y)
    inside = (table.t > points.t[0]) & (table.t < points.t[-1])
    np.testing.assert_allclose(ours[inside], table.y[inside], rtol=0.03)


@needs_realdata
@pytest.mark.parametrize("run", [1, 2])
def test_real_spring_mass(run):
    from mcfit.io import read_record
    from mcfit.turning import turning_points_of
    name = f"molla_durissima_discopieno_14.91945_0.2016_{run}.csv"
    points = turning_points_of(read_record(REALDATA / "spring_mass_disk" / name))
    assert points.count > 300
    assert points.period == pytest.approx(0.7435, rel=0.01)
    assert points.equilibrium == pytest.approx(0.417, abs=0.002)


def _median_of_each_window(values, width):
    """Reference running median: np.median of each window, the ends held level."""
    half = width // 2
    padded = np.concatenate([np.full(half, values[0]), values, np.full(half, values[-1])])
    return np.array([np.median(padded[i:i + 2 * half + 1]) for i in range(values.size)])


@pytest.mark.parametrize("width", [3, 6, 64, 65, 66, 201, 999])
def test_running_median_is_the_median_of_each_window(width, rng):
    # Rounded: ties as well. Widths on both sides of the wide-window switch.
    values = np.round(rng.normal(size=1000), 1)
    np.testing.assert_array_equal(_running_median(values, width),
                                  _median_of_each_window(values, width))


def test_a_wide_running_median_takes_memory_in_proportion_to_the_values(rng):
    # One partition of all the windows would hold 20,000 x 2,001 values (320 MB).
    values = rng.normal(size=20_000)
    tracemalloc.start()
    try:
        smooth = _running_median(values, 2001)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 10 * values.nbytes
    np.testing.assert_array_equal(smooth[::997], _median_of_each_window(values, 2001)[::997])


def test_the_floor_of_a_long_record_is_found_as_by_one_partition(monkeypatch, rng):
    # 3,000 crests: the floor check's running median spans 99 of them. The envelope
    # meets 1.5 times the floor at 663 s and the floor itself at 730 s.
    t = np.arange(0, 1500, 0.05)
    x = (np.exp(-t * np.log(300) / 900) * np.cos(2 * np.pi * t)
         + 0.01 * np.cos(2 * np.pi * 1.37 * t) + rng.normal(0, 1e-3, t.size))
    points = find_turning_points(t, x)
    assert 650 < points.noise_floor_time < 850
    assert points.noise_floor == pytest.approx(0.01, rel=0.3)
    monkeypatch.setattr(common, "_WIDE_MEDIAN", 10**9)  # every window by the partition
    by_partition = find_turning_points(t, x)
    assert by_partition.noise_floor_time == points.noise_floor_time
    for name in ("t", "y", "sigma", "used"):
        np.testing.assert_array_equal(getattr(points, name), getattr(by_partition, name))
    assert points.excluded_reason == by_partition.excluded_reason


def _rfft_lengths(monkeypatch):
    """The lengths np.fft.rfft is called at, from now on in the test."""
    lengths = []
    rfft = np.fft.rfft

    def counted(a, n=None, *args, **kwargs):
        lengths.append(np.shape(a)[-1] if n is None else n)
        return rfft(a, n, *args, **kwargs)

    monkeypatch.setattr(np.fft, "rfft", counted)
    return lengths


def _long_decay(samples, rng, hum=0.0):
    """25 samples a cycle of period 1, decaying to exp(-2), noise 1e-3; and a hum of
    amplitude ``hum`` at 0.13 cycles per time unit."""
    t = np.arange(samples) / 25.0
    x = (np.exp(-2.0 * t / t[-1]) * np.cos(2 * np.pi * t) + hum * np.cos(0.26 * np.pi * t)
         + rng.normal(0.0, 1e-3, samples))
    return t, x


def _is_5_smooth(n):
    for p in (2, 3, 5):
        while n % p == 0:
            n //= p
    return n == 1


@pytest.mark.parametrize("samples", [100_003, pytest.param(1_000_001, marks=pytest.mark.slow)])
def test_a_long_spectrum_is_padded_to_a_fast_length(samples, monkeypatch, rng):
    t, x = _long_decay(samples, rng)
    lengths = _rfft_lengths(monkeypatch)
    points = find_turning_points(t, x)
    assert samples < lengths[0] < 1.05 * samples and _is_5_smooth(lengths[0])
    assert points.period == pytest.approx(1.0, rel=1e-6)
    assert points.noise_sigma == pytest.approx(1e-3, rel=0.05)


def test_a_short_spectrum_keeps_its_own_length(monkeypatch, rng):
    t, x = _long_decay(10_007, rng)  # prime: its results stay as they were
    lengths = _rfft_lengths(monkeypatch)
    find_turning_points(t, x)
    assert lengths[0] == 10_007


def test_the_padded_periodogram_gives_the_period_and_noise_of_the_unpadded(monkeypatch, rng):
    t, x = _long_decay(100_003, rng)
    steps = np.diff(t)
    padded = spectrum._spectrum(t, x, 0.04, steps)
    monkeypatch.setattr(spectrum, "_PADDED_SAMPLES", 10**9)
    unpadded = spectrum._spectrum(t, x, 0.04, steps)
    assert padded[2][5] > 1.0 and unpadded[2][5] == 1.0
    assert padded[0] == pytest.approx(unpadded[0], rel=1e-5)  # 0.04 of a bin
    assert padded[1] == pytest.approx(unpadded[1], rel=0.02)


def test_a_hum_is_removed_from_a_padded_spectrum(rng):
    t, x = _long_decay(100_003, rng, hum=0.02)
    points = find_turning_points(t, x)
    notes = [n for n in points.notes if "hum" in n]
    assert len(notes) == 1 and "removed" in notes[0]
    assert "frequency 0.13 " in notes[0] and "amplitude 0.02" in notes[0]
    assert points.period == pytest.approx(1.0, rel=1e-6)


def _decay_into_a_floor(rng):
    """A decay sinking into a steady vibration at 1.37 times its frequency."""
    t = np.arange(0, 60, 0.02)
    x = (amplitude(t, 1.0, 0.0, 0.12, 0.0) * np.cos(2 * np.pi * t)
         + 0.01 * np.cos(2 * np.pi * 1.37 * t) + rng.normal(0, 1e-3, t.size))
    return t, x


@pytest.mark.parametrize("scale", [1e-155, 1e-160, 1e-164, 1e-300])
def test_a_tiny_amplitude_raises_no_numpy_warning(scale, rng):
    # Squares of such amplitudes underflow: the phase weights were 0/0, polyfit's column
    # norms 0, and the hum's Gauss-Newton step 0/0, each with a RuntimeWarning.
    records = (waveform(20, noise=1e-3, rng=rng),
               _decay_into_a_floor(np.random.default_rng(20240611)))  # with a steady line
    for t, x in records:
        reference = find_turning_points(t, x)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                points = find_turning_points(t, scale * x)
            except RecordError:  # the spectrum's power underflows: no period found
                assert scale < 1e-160
                continue
        if scale >= 1e-155:  # the same crests, in proportion
            np.testing.assert_allclose(points.t, reference.t, rtol=1e-9)
            np.testing.assert_allclose(points.y / scale, reference.y, rtol=1e-9)
            assert points.period_drift == pytest.approx(reference.period_drift, rel=1e-9)


def test_turning_points_do_not_depend_on_the_blocks_they_are_taken_in(monkeypatch, rng):
    # 8,000 samples and 800 crests in blocks of 1,000 samples and 64 crests: every seam
    # between blocks (periods, half-cycle runs, windows, crest fits, running medians).
    t, x = waveform(10, cycles=400, noise=1e-3, rng=rng)
    whole = find_turning_points(t, x)
    for module in (common, equilibrium, refine, windows, crests):
        for name, size in (("_BLOCK_SAMPLES", 1000), ("_CREST_BLOCK", 64)):
            if hasattr(module, name):
                monkeypatch.setattr(module, name, size)
    blocks = find_turning_points(t, x)
    np.testing.assert_allclose(blocks.t, whole.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(blocks.y, whole.y, rtol=1e-12)
    np.testing.assert_allclose(blocks.sigma, whole.sigma, rtol=1e-12)
    assert blocks.excluded_reason == whole.excluded_reason
    assert blocks.period == pytest.approx(whole.period, rel=1e-14)


def test_the_crest_smoother_takes_memory_in_proportion_to_the_crests(rng):
    # The moment matrices of every crest at once took about 1 kB a crest.
    count = 400_000
    numbers = np.arange(count)
    times = 0.5 * numbers + rng.normal(0.0, 1e-3, count)
    weights = np.full(count, 1e4)
    tracemalloc.start()
    try:
        smooth, _, variance, _ = crests._smooth_crest_times(numbers, times, weights, count)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 300 * count
    np.testing.assert_allclose(smooth, 0.5 * numbers, atol=5e-3)  # 5 sigma of a time
    assert np.all(variance < 1e-4)  # no more than one crest's own (weight 1e4)


def test_a_steady_line_is_found_in_a_periodogram_without_its_padding(rng):
    # mcfit.hum.find_steady_line is public: a periodogram of five items (unpadded) works.
    from mcfit.hum import find_steady_line

    t, x = _long_decay(50_000, rng, hum=0.02)
    periodogram = spectrum._spectrum(t, x, 0.04, np.diff(t))[2]
    assert periodogram[5] == 1.0
    line = find_steady_line(t, x, periodogram[:5], 1e-3)
    assert line == find_steady_line(t, x, periodogram, 1e-3)
    assert line.removed and line.frequency == pytest.approx(0.13, rel=1e-4)


def test_a_straight_ramp_is_said_to_span_its_range():
    """A ramp from 0 to 12 has no oscillation; the message said it "swings by 2.66e-15
    about its mean" (its swing about the fitted line), though it spans 12."""
    t = np.arange(0.0, 20.0, 0.01)
    x = 0.6 * t + np.random.default_rng(1).normal(0.0, 1e-3, t.size)
    with pytest.raises(RecordError, match=r"the signal spans 12 but swings by .* about its "
                                          r"straight-line trend"):
        find_turning_points(t, x, source="ramp.csv")


def test_an_adc_record_is_clipped_only_where_it_sits_on_a_rail():
    """An 8-bit record spanning 28-227 counts: its largest crest holds the top count for
    the few samples a cosine's top keeps within one count, which read as "clipped" in 150
    of 200 records. The same record clipped at 60 and 200 counts is clipped."""
    t = np.arange(0.0, 30.0, 0.02)
    beta = np.pi / 30
    swing = 113.0 * np.exp(-beta * t) * np.cos(np.sqrt(4 * np.pi**2 - beta**2) * t) + 114.0
    false_notes = 0
    for seed in range(20):
        counts = np.round(swing + np.random.default_rng(seed).normal(0.0, 0.3, t.size))
        points = find_turning_points(t, counts)
        false_notes += "clipped" in points.excluded_reason
    assert false_notes == 0
    railed = np.round(np.clip(swing + np.random.default_rng(1).normal(0.0, 0.3, t.size),
                              60, 200))
    assert "clipped" in find_turning_points(t, railed).excluded_reason
