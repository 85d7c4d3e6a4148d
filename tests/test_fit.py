"""Fitting turning-point amplitudes: recovery of known a, b, c, regime verdicts, CRLB."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from mcfit import decay
from mcfit.bounds import amplitude_crlb
from mcfit.errors import FitError
from mcfit.fit import LRT_ALPHA, MODELS, boundary_lrt_p_value, fit_decay


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


def _turning_points(y0, a, b, c, period, duration, floor=0.02):
    """Turning points every half period while the amplitude stays above floor*y0."""
    t = np.arange(0.0, duration, period / 2)
    y = decay.amplitude(t, y0, a, b, c)
    keep = y > floor * y0
    return t[keep], y[keep]


def _noisy_fit(noise_rng, y0, a, b, c, period, duration, relative_noise, **options):
    t, y = _turning_points(y0, a, b, c, period, duration)
    sigma = np.full(t.size, relative_noise * y0)
    return fit_decay(t, y + noise_rng.normal(0.0, sigma), sigma, period=period, **options)


# name: (y0, a, b, c, period, duration, relative noise, expected model)
SCENES = {
    "fluid only": (1.0, 0.2, 0.0, 0.0, 0.5, 30.0, 1e-4, "a"),
    "hysteretic only": (1.0, 0.0, 0.05, 0.0, 1.0, 60.0, 1e-4, "b"),
    "Coulomb only": (1.0, 0.0, 0.0, 0.01, 1.0, 95.0, 1e-4, "c"),
    "fluid and hysteretic": (2.0, 0.05, 0.05, 0.0, 0.5, 40.0, 1e-4, "ab"),
    "fluid and Coulomb": (2.0, 0.05, 0.0, 0.01, 0.5, 40.0, 1e-4, "ac"),
    "hysteretic and Coulomb, stop inside": (1.0, 0.0, 0.02, 0.01, 1.0, 80.0, 1e-4, "bc"),
    "all three (Fig. 20.19)": (4.0, 0.1, 0.1, 0.01, 0.5, 20.0, 1e-4, "abc"),
    "b^2 = 4ac": (1.0, 1.0, 2.0, 1.0, 0.05, 5.0, 1e-5, "abc"),
    "Coulomb dominant, b^2 < 4ac": (1.0, 0.3, 0.05, 0.05, 0.5, 30.0, 1e-4, "abc"),
    "soup can (Fig. 20.21)": (1.0, 0.22, 0.0, 0.0, 0.5, 20.0, 1e-3, "a"),
    "evacuated pendulum (Fig. 20.22)": (1.0, 0.0012, 0.0004, 0.0, 1.0, 1400.0, 1e-4, "ab"),
}


@pytest.mark.parametrize("name", list(SCENES))
def test_recovers_coefficients_and_regimes(name, rng):
    y0, a, b, c, period, duration, noise, expected = SCENES[name]
    result = _noisy_fit(rng, y0, a, b, c, period, duration, noise)
    assert result.status == "ok"
    assert result.model == expected
    assert result.regimes == {"fluid": "a" in expected, "hysteretic": "b" in expected,
                              "coulomb": "c" in expected}
    for key, true in zip("abc", (a, b, c)):
        value, error = result.values[key], result.stderr[key]
        if true == 0:
            assert value == 0 and error is None
        else:
            assert abs(value - true) < 5 * error, (key, value, true, error)
            assert error < 0.1 * true
    assert len(result.candidates) == len(MODELS)


@pytest.mark.parametrize("q_target", [2.0, 10.0, 1e3, 1e5])
def test_hysteretic_q_from_2_to_1e5(q_target, rng):
    period = 1.0
    b = math.pi / (period * q_target)  # Qh = w/(2b)
    cycles = min(max(q_target, 3.0), 3e4)
    duration = cycles * period
    result = _noisy_fit(rng, 1.0, 0.0, b, 0.0, period, duration, 1e-4)
    assert result.model == "b"
    assert result.q_summary["initial"] == pytest.approx(q_target, rel=2e-3)


def test_pure_noise_on_an_exponential_does_not_invent_terms():
    """Over 40 records the boundary LRT at 1 % may rarely keep a spurious term; not often."""
    invented = 0
    for seed in range(40):
        result = _noisy_fit(np.random.default_rng(seed), 1.0, 0.0, 0.05, 0.0, 1.0, 60.0, 3e-3)
        assert "b" in result.model
        invented += result.model != "b"
    assert invented <= 3



def test_two_terms_that_mimic_a_third_must_pass_a_joint_test():
    """a*y**2 + c can stand in for part of b*y: on this pure exponential AICc picks abc and
    each of a and c passes its one-term test inside abc, but together they do not beat b."""
    t = np.arange(200) * 0.5
    y = decay.amplitude(t, 1.0, 0.0, 0.02, 0.0) + np.random.default_rng(89).normal(0, 0.01, 200)
    result = fit_decay(t, y, np.full(t.size, 0.01), period=1.0)
    chi = {c.model: c.chi_square for c in result.candidates}
    aicc = {c.model: c.aicc for c in result.candidates}
    assert min(aicc, key=aicc.get) == "abc"
    assert boundary_lrt_p_value(chi["bc"], chi["abc"], t.size, 4) < LRT_ALPHA
    assert boundary_lrt_p_value(chi["ab"], chi["abc"], t.size, 4) < LRT_ALPHA
    assert result.model == "b"
    [dropped] = [w for w in result.warnings if w.startswith("fluid and Coulomb terms dropped")]
    assert float(re.search(r"\(p = ([0-9.e+-]+)\)", dropped).group(1)) > LRT_ALPHA


@pytest.mark.parametrize(("terms", "correlation"),
                         [(1, 0.0), (2, 0.0), (2, 0.94), (2, -0.6), (2, 1.0)])
@pytest.mark.parametrize("statistic", [0.1, 1.0, 5.41, 9.0, 30.0])
def test_boundary_p_value_tends_to_the_chi_bar_square_mixture(terms, correlation, statistic):
    """With many points the finite-sample p-value is the large-sample chi-bar-square one."""
    from scipy import stats

    if terms == 1:
        weights = (0.5, 0.5)
    else:  # the chance that two estimates with this correlation are both > 0
        both = stats.multivariate_normal([0, 0], [[1, correlation], [correlation, 1]],
                                         allow_singular=True).cdf([0, 0])
        weights = (0.5 - both, 0.5, both)
    expected = sum(w * stats.chi2.sf(statistic, df) for df, w in enumerate(weights) if df)
    n = 10**7
    chi_square_with = 1.0
    chi_square_without = math.exp(statistic / n)
    assert boundary_lrt_p_value(chi_square_without, chi_square_with, n, 4, terms,
                                correlation) == pytest.approx(expected, rel=1e-5)


@pytest.mark.parametrize("n_points", [8, 16, 40])
@pytest.mark.parametrize("f_statistic", [0.5, 3.0, 12.0])
def test_boundary_p_value_of_one_term_is_half_the_f_test(n_points, f_statistic):
    """On a short record the statistic's null distribution is F(1, n - p), not chi2(1)."""
    from scipy import stats

    n_params = 3
    chi_square_with = 1.0
    chi_square_without = 1.0 + f_statistic / (n_points - n_params)
    expected = 0.5 * stats.f.sf(f_statistic, 1, n_points - n_params)
    assert boundary_lrt_p_value(chi_square_without, chi_square_with, n_points,
                                n_params) == pytest.approx(expected, rel=1e-9)


def test_the_same_record_in_other_units_gives_the_same_result(rng):
    t, y = _turning_points(4.0, 0.1, 0.1, 0.01, 0.5, 20.0)
    y = y + rng.normal(0.0, 4e-4, y.size)
    base = fit_decay(t, y, period=0.5)
    microvolts_hours = fit_decay(t / 3600, y * 1e6, period=0.5 / 3600)
    assert microvolts_hours.model == base.model
    for key, factor in (("y0", 1e6), ("a", 3600 / 1e6), ("b", 3600), ("c", 3600 * 1e6)):
        assert microvolts_hours.values[key] == pytest.approx(base.values[key] * factor, rel=1e-9)
    evaluations = {c.model: c.evaluations for c in base.candidates}
    converted = {c.model: c.evaluations for c in microvolts_hours.candidates}
    assert converted[base.model] == evaluations[base.model]
    # Converting units changes the inputs by an ulp. A misfitting model whose stop falls
    # inside the record (a kink in its objective) may then end one step earlier or later.
    assert all(abs(converted[m] - evaluations[m]) <= 1 for m in evaluations)
    assert microvolts_hours.q_summary["initial"] == pytest.approx(base.q_summary["initial"],
                                                                    rel=1e-9)


@pytest.mark.parametrize("scene", ["all three (Fig. 20.19)", "fluid and hysteretic"])
def test_rmse_reaches_the_cramer_rao_bound_on_amplitudes(scene, rng):
    """Amplitudes with known Gaussian noise: RMSE <= 1.25 CRLB and |bias| <= 0.2 CRLB."""
    y0, a, b, c, period, duration, noise, model = SCENES[scene]
    t, y = _turning_points(y0, a, b, c, period, duration)
    sigma = 1e-3 * y0
    truth = np.array([a, b, c])[["abc".index(k) for k in model]]
    estimates = []
    for _ in range(300):
        result = fit_decay(t, y + rng.normal(0.0, sigma, y.size), np.full(y.size, sigma),
                           period=period, model=model)
        estimates.append([result.values[k] for k in model])
    estimates = np.array(estimates)
    bound = np.array(list(amplitude_crlb(t - t[0], y0, a, b, c, sigma, model).values()))
    rmse = np.sqrt(np.mean((estimates - truth) ** 2, axis=0))
    bias = np.abs(np.mean(estimates, axis=0) - truth)
    assert np.all(rmse <= 1.25 * bound), rmse / bound
    # The mean of 300 draws has its own scatter of RMSE/sqrt(300) = 0.06 CRLB.
    assert np.all(bias <= 0.2 * bound), bias / bound


def test_cycle_domain_gives_per_cycle_coefficients_and_q(rng):
    """Fig. 20.20's form: peak speed per swing against cycle number n."""
    n = np.arange(0, 40, 1.0)
    y = decay.amplitude(n, 7.69, 0.036, 0.025, 0.0)
    result = fit_decay(n, y * (1 + rng.normal(0.0, 1e-4, n.size)), domain="cycle")
    assert result.model == "ab"
    assert result.values["a"] == pytest.approx(0.036, rel=0.02)
    assert result.values["b"] == pytest.approx(0.025, rel=0.02)
    # 1/Q = (c_n/y + b_n + a_n*y)/pi
    expected_q0 = math.pi / (0.025 + 0.036 * 7.69)
    assert result.q_summary["initial"] == pytest.approx(expected_q0, rel=0.01)


def test_q_band_and_parts_are_consistent(rng):
    result = _noisy_fit(rng, 4.0, 0.1, 0.1, 0.01, 0.5, 20.0, 1e-3)
    q, parts = result.q, result.q_parts
    np.testing.assert_allclose(1 / q, 1 / parts["coulomb"] + 1 / parts["hysteretic"]
                               + 1 / parts["fluid"], rtol=1e-10)
    assert np.all(result.q_stderr > 0) and np.all(result.q_stderr < 0.1 * q)
    # Fig. 20.19: Q rises while the fluid term fades, then falls as Coulomb takes over.
    assert result.q_summary["max"] > result.q_summary["initial"]


def test_power_law_recovers_the_exponent(rng):
    t, y = _turning_points(1.0, 0.2, 0.0, 0.0, 0.5, 30.0)
    result = fit_decay(t, y * (1 + rng.normal(0, 1e-4, y.size)), period=0.5, model="power")
    assert result.model == "power"
    assert result.values["n"] == pytest.approx(2.0, abs=0.01)
    assert result.values["k"] == pytest.approx(0.2, rel=0.02)
    t, y = _turning_points(1.0, 0.0, 0.05, 0.0, 1.0, 60.0)
    result = fit_decay(t, y * (1 + rng.normal(0, 1e-4, y.size)), period=1.0, model="power")
    assert result.values["n"] == pytest.approx(1.0, abs=0.01)


def test_forced_model_and_bootstrap_interval(rng):
    result = _noisy_fit(rng, 4.0, 0.1, 0.1, 0.01, 0.5, 20.0, 1e-3, model="ab", bootstrap=40,
                        rng=rng)
    assert result.model == "ab" and result.values["c"] == 0
    interval = result.bootstrap["interval_95"]
    assert interval["a"][0] < result.values["a"] < interval["a"][1]
    assert result.bootstrap["n"] == 40


def test_missing_term_shows_as_correlated_residuals(rng):
    """Forcing a single exponential on an air-damped record must not pass silently."""
    result = _noisy_fit(rng, 2.0, 0.05, 0.02, 0.0, 0.5, 40.0, 1e-4, model="b")
    assert any("correlated" in w for w in result.warnings)


@pytest.mark.parametrize("t, y, message", [
    ([0, 1, 2], [3, 2, 1], "only 3 turning points"),
    ([0, 1, 1, 2], [3, 2, 1.5, 1], "strictly increasing"),
    ([0, 1, 2, 3], [0, -1, -2, -0.5], "no turning-point amplitude is > 0"),
    ([0, 1, 2, 3], [0, 0, 0, 0], "no turning-point amplitude is > 0"),
    ([0, 1, 2, 3], [3, 2, np.nan, 1], "NaN"),
    ([0, 1, 2, 3], [3e31, 2, -1, 1], "rescale the signal"),
])
def test_invalid_turning_points_raise_a_clear_error(t, y, message):
    with pytest.raises(FitError, match=message):
        fit_decay(np.array(t, float), np.array(y, float))


def _noisy_tail(noise_rng, y0, a, b, c, period, duration, noise):
    """Signed amplitudes: the law plus Gaussian noise, kept where the envelope is in the noise."""
    t = np.arange(0.0, duration, period / 2)
    return t, decay.amplitude(t, y0, a, b, c) + noise_rng.normal(0.0, noise, t.size)


@pytest.mark.parametrize("y0, a, b, c, period, duration, noise, expected", [
    (1.0, 0.0, 0.05, 0.0, 1.0, 150.0, 3e-3, "b"),
    (2.0, 0.05, 0.05, 0.0, 0.5, 150.0, 2e-3, "ab"),
])
def test_amplitudes_down_to_and_below_zero_in_the_noise(y0, a, b, c, period, duration, noise,
                                                        expected, rng):
    """The end of a record where the envelope is within the noise: zeros and negative values
    are kept (dropping them would bias the fit towards a slower decay)."""
    t, y = _noisy_tail(rng, y0, a, b, c, period, duration, noise)
    y[-3] = 0.0
    assert np.sum(y < 0) > 10
    result = fit_decay(t, y, np.full(t.size, noise), period=period)
    assert result.status == "ok"
    assert result.model == expected
    for key, true in zip("abc", (a, b, c)):
        if true:
            error = result.stderr[key]
            assert abs(result.values[key] - true) < 5 * error, (key, result.values[key], error)
            assert error < 0.05 * true
    assert np.all(result.y_fit >= 0)
    # The reduced chi-square of a good fit with the right noise is about 1.
    assert 0.7 < result.reduced_chi_square < 1.4



@pytest.mark.parametrize("failing", ["every", "every other"])
def test_bootstrap_refits_that_fail_are_counted_and_said(rng, monkeypatch, failing):
    import dataclasses

    from mcfit.fit import decay_fit

    real = decay_fit.fit_candidates
    calls = []

    def sometimes_failing(*args):
        calls.append(None)
        fitted = real(*args)
        refit = len(calls) - 1  # the first call is the fit itself
        if refit and (failing == "every" or refit % 2 == 0):
            return {m: dataclasses.replace(c, success=False) for m, c in fitted.items()}
        return fitted

    monkeypatch.setattr(decay_fit, "fit_candidates", sometimes_failing)
    t, y = _noisy_tail(rng, 1.0, 0.0, 0.05, 0.0, 1.0, 60.0, 3e-3)
    result = fit_decay(t, y, period=1.0, model="b", bootstrap=6, rng=rng)
    assert result.status == "ok"
    if failing == "every":
        assert result.bootstrap == {"n": 0, "failed": 6, "models": {}, "interval_95": None,
                                    "selection": "fixed"}
        assert "no bootstrap refit of 6 converged: no intervals" in result.warnings
    else:
        assert result.bootstrap["n"] == 3 and result.bootstrap["failed"] == 3
        assert any(w.startswith("3 of 6 bootstrap refits did not converge")
                   for w in result.warnings)


def test_amplitudes_further_below_zero_than_above_fit_without_overflow():
    # The internal unit is max|y|: with max(y) = 1e-200 the negative values overflowed.
    result = fit_decay(np.arange(6.0), [1e-200, -1.0, -0.5, -0.2, -0.1, -0.05])
    assert result.status == "ok"
    assert all(math.isfinite(v) for v in result.values.values())

def test_non_positive_tail_with_forced_models_and_bootstrap(rng):
    t, y = _noisy_tail(rng, 1.0, 0.0, 0.05, 0.0, 1.0, 150.0, 3e-3)
    assert np.any(y <= 0)
    boot = fit_decay(t, y, period=1.0, model="b", bootstrap=30, rng=rng)
    # Every draw is refitted, values <= 0 and all: none is dropped, none fails.
    assert boot.bootstrap["n"] == 30 and boot.bootstrap["failed"] == 0
    low, high = boot.bootstrap["interval_95"]["b"]
    assert low < boot.values["b"] < high
    assert high - low == pytest.approx(2 * 1.96 * boot.stderr["b"], rel=0.5)
    power = fit_decay(t, y, period=1.0, model="power")
    assert power.status == "ok"
    assert power.values["n"] == pytest.approx(1.0, abs=0.1)
    # A first amplitude <= 0 as well: the largest one still sets the scale.
    y[0] = -1e-3
    assert fit_decay(t, y, period=1.0).status == "ok"
    assert fit_decay(t, y, period=1.0, model="power").status == "ok"


def test_sigma_from_the_residuals_is_the_noise_they_show(rng):
    """Without amplitude uncertainties the result's sigma is the residual scatter, not 1."""
    t, y = _turning_points(1.0, 0.0, 0.05, 0.0, 1.0, 60.0)
    noisy = y + rng.normal(0.0, 2e-3, y.size)
    result = fit_decay(t, noisy, period=1.0)
    assert result.noise_from_residuals
    assert np.all(result.sigma == pytest.approx(2e-3, rel=0.25))


@pytest.mark.parametrize("model", ["b", "bc", "abc"])
def test_the_values_alone_are_those_of_the_reported_fit(rng, model):
    """fit_model_values (the bias prediction's refit) gives the forced fit's values."""
    from mcfit.fit.decay_fit import fit_model_values

    t, y = _turning_points(4.0, 0.1, 0.1, 0.01, 0.5, 20.0)
    sigma = np.full(y.size, 1e-3)
    noisy = y + rng.normal(0.0, 1e-3, y.size)
    reported = fit_decay(t, noisy, sigma, period=0.5, model=model)
    values = fit_model_values(t, noisy, sigma, model=model)
    for k in ("y0",) + tuple(model):
        assert abs(values[k] - reported.values[k]) < 1e-4 * reported.stderr[k]


def test_turning_points_in_the_noise_below_zero_are_amplitudes_not_samples():
    """A decay whose last turning points sit in the noise, about half of them below zero
    by less than their sigma (a Coulomb decay's end): these are amplitudes, and fitted.
    Without sigma, so many values below zero read as samples of a waveform."""
    t = np.arange(52.0)
    y = np.concatenate([1.0 - 0.05 * t[:20], np.tile([0.001, -0.001], 16)])
    sigma = np.full(t.size, 0.002)
    fit = fit_decay(t, y, sigma, model="c")
    assert abs(fit.values["c"] - 0.05) < 3 * fit.stderr["c"]
    with pytest.raises(FitError, match="like samples of the oscillation"):
        fit_decay(t, y)
