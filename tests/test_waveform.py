"""The equation of motion in the phase plane, the waveform fit, and the choice of method,
against a tight event-locating integration (mcfit.motion.integrate_accurate)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcfit.analysis import analyse_record, fit_both_forms, fit_turning_points
from mcfit.fit import waveform
from mcfit.fit.waveform import WaveformStart, fit_waveform
from mcfit.fit.waveform_laws import amplitude_waveform
from mcfit.motion import damping_terms, integrate_accurate, simulate_record
from mcfit import phase_plane
from mcfit.phase_plane import phase_plane_motion
from mcfit.io import Record, read_record
from mcfit.turning import find_turning_points

ROOT = Path(__file__).parents[1]
REAL = ROOT.parent / "shared" / "realdata"
OMEGA = 2 * math.pi


def _reference(t, theta0, a, b, c):
    start = (math.cos(theta0), -OMEGA * math.sin(theta0))
    return integrate_accurate(*start, OMEGA, damping_terms(a, b, c), t, rtol=1e-13).x


@pytest.mark.parametrize(("a", "b", "c"), [
    (0.0, math.pi / 2, 0.0),      # Q = 2
    (0.0, math.pi / 5, 0.0),      # Q = 5
    (0.1, 0.1, 0.01),             # Fig. 20.19's coefficients
    (0.5, 0.0, 0.0),              # fluid only
    (0.0, 0.0, 0.3),              # Coulomb: stops inside the record
    (0.0, 0.3, 0.2),              # hysteretic and Coulomb: stops inside the record
])
@pytest.mark.parametrize("theta0", [0.0, 1.0, 4.0])
def test_phase_plane_motion_matches_the_accurate_integrator(a, b, c, theta0):
    t = np.linspace(0.0, 8.0, 801)
    x = phase_plane_motion(t, 1.0, theta0, OMEGA, a, b, c)[0]
    # Within 1e-7 of the amplitude while it swings; up to 3e-7 at a stop, whose time
    # the last swings set sensitively.
    assert np.max(np.abs(x - _reference(t, theta0, a, b, c))) < (5e-7 if c else 1e-7)


@settings(max_examples=12, deadline=None)
@given(q=st.floats(2.0, 1000.0), share=st.tuples(st.floats(0, 1), st.floats(0, 1),
                                                   st.floats(0, 1)),
       theta0=st.floats(0.0, 2 * math.pi))
def test_phase_plane_motion_matches_for_any_mix_of_damping(q, share, theta0):
    """Q(y0 = 1) = q split among the three terms in any proportion."""
    total = sum(share) or 1.0
    rate = OMEGA / (2 * q)
    a, b, c = (rate * s / total for s in share) if sum(share) else (0.0, rate, 0.0)
    t = np.linspace(0.0, 6.0, 601)
    x = phase_plane_motion(t, 1.0, theta0, OMEGA, a, b, c)[0]
    assert np.max(np.abs(x - _reference(t, theta0, a, b, c))) < 1e-6


def test_a_batch_is_its_parameter_sets_one_by_one():
    t = np.linspace(0.0, 5.0, 401)
    b = np.array([0.1, 0.5, 1.0])
    batch = phase_plane_motion(t, 1.0, 0.3, OMEGA, 0.0, b, 0.05)
    for i, value in enumerate(b):
        np.testing.assert_allclose(batch[i], phase_plane_motion(t, 1.0, 0.3, OMEGA, 0.0,
                                                                value, 0.05)[0], atol=1e-13)


@pytest.mark.parametrize(("a", "b", "c", "theta0"), [
    (0.0, 0.3, 0.0, 0.0),         # Q = 10
    (0.1, 0.1, 0.01, 1.0),        # Fig. 20.19's coefficients
    (0.0, 0.3, 0.2, 0.2),         # stops inside the record
    (1.5, 0.0, 0.0, 4.0),         # Q about 2 at the start
])
def test_all_half_cycles_at_once_match_one_after_the_other(a, b, c, theta0):
    t = np.linspace(0.0, 8.0, 801)
    sets = tuple(np.array([[v]]) for v in (1.0, theta0, OMEGA, a, b, c))
    at_once = phase_plane._nodes(8.0, *sets)
    one_by_one = phase_plane._nodes_one_by_one(8.0, *sets)
    np.testing.assert_allclose(at_once[-1], one_by_one[-1], atol=1e-12)
    np.testing.assert_allclose(phase_plane._sampled(t, *at_once[:-1]),
                               phase_plane._sampled(t, *one_by_one[:-1]), atol=1e-12)


def test_too_many_half_cycles_at_once_go_one_after_the_other(monkeypatch):
    """Memory stays bounded: past _MAX_GRID values an array (a long record, or a trial
    frequency far off) the half-cycles are solved one after the other, to the same x."""
    t = np.linspace(0.0, 8.0, 801)
    sets = (1.0, 0.3, OMEGA, 0.1, 0.1, 0.01)
    at_once = phase_plane_motion(t, *sets)
    differences = phase_plane.phase_plane_differences(t, np.array(sets), 1e-7 * np.eye(6))
    monkeypatch.setattr(phase_plane, "_MAX_GRID", 100)
    monkeypatch.setattr(phase_plane, "_all_half_cycles", None)  # must not be called
    np.testing.assert_allclose(phase_plane_motion(t, *sets), at_once, atol=1e-12)
    bounded = phase_plane.phase_plane_differences(t, np.array(sets), 1e-7 * np.eye(6))
    np.testing.assert_allclose(bounded[0], differences[0], atol=1e-12)
    np.testing.assert_allclose(bounded[1], differences[1], atol=1e-9)


@pytest.mark.parametrize(("a", "b", "c", "theta0"), [
    (0.0, 0.3, 0.0, 0.0),
    (0.1, 0.1, 0.01, -0.3),
    (0.0, 0.3, 0.2, 0.2),         # stops inside the record
    (0.0, math.pi / 2, 0.0, 0.5),  # Q = 2: every half-cycle strongly damped
    (0.0, 0.3, 0.0, -1e-8),       # a step of theta0 crosses a multiple of pi
])
def test_differences_are_forward_differences_of_the_motion(a, b, c, theta0):
    t = np.linspace(0.0, 12.0, 2401)
    parameters = np.array([1.0, theta0, OMEGA, a, b, c])
    columns = [0, 1, 2] + [3 + i for i in range(3) if parameters[3 + i] > 0]
    steps = np.diag(1e-7 * np.maximum(np.abs(parameters), 1.0))[columns]
    x, changes = phase_plane.phase_plane_differences(t, parameters, steps, memory={})
    moved = phase_plane_motion(t, *(parameters + np.vstack([np.zeros(6), steps])).T)
    np.testing.assert_allclose(x, moved[0], atol=1e-13)
    reference = (moved[1:] - moved[0]) / steps.sum(axis=1)[:, None]
    error = np.max(np.abs(changes / steps.sum(axis=1)[:, None] - reference), axis=1)
    assert np.all(error < 1e-3 * np.max(np.abs(reference), axis=1))


def test_differences_start_from_the_last_solution_alike():
    t = np.linspace(0.0, 8.0, 801)
    parameters = np.array([1.0, 0.3, OMEGA, 0.05, 0.2, 0.01])
    steps = 1e-7 * np.eye(6)[[0, 2, 4]]
    memory = {}
    phase_plane.phase_plane_differences(t, parameters * 1.01, steps, memory)
    warm = phase_plane.phase_plane_differences(t, parameters, steps, memory)
    cold = phase_plane.phase_plane_differences(t, parameters, steps)
    np.testing.assert_allclose(warm[0], cold[0], atol=1e-13)
    np.testing.assert_allclose(warm[1], cold[1], atol=1e-13)


def _low_q_record(q, coulomb_share, cycles, seed):
    rate = OMEGA / (2 * q)  # c/y0 + b at the start
    b, c = rate * (1 - coulomb_share), rate * coulomb_share
    t, x = simulate_record(0.0, b, c, 1.0, 1.0, cycles, 100.0, method="accurate",
                           noise=1e-4, rng=np.random.default_rng([int(10 * q), seed]))
    return t, x, {"b": b, "c": c}


@pytest.mark.slow
def test_waveform_fit_recovers_low_q_coefficients_where_turning_points_cannot():
    """Q = 2, 3, 5 from a tight integration of Eq. 20.55 at SNR 1e4: b alone, and b with a
    Coulomb term (a tenth of the initial damping; a fiftieth at Q = 2, where a larger one
    stops the swing before the fourth turning point the start needs). The waveform fit of the true model puts
    b and c within 3 standard errors in at least 80 % of records, its 95 % intervals cover
    90 to 98 % of the truths, where the turning-point fit misses b by 100+ errors."""
    within = covered = total = 0
    for q, share, cycles, model in [(2, 0.0, 5, "b"), (3, 0.0, 8, "b"), (5, 0.0, 8, "b"),
                                    (2, 0.02, 3, "bc"), (3, 0.1, 3, "bc"), (5, 0.1, 4, "bc")]:
        for seed in range(14):
            t, x, truth = _low_q_record(q, share, cycles, seed)
            turning = find_turning_points(t, x)
            averaged = fit_turning_points(turning, model=model)
            fit = fit_waveform(t, x, turning, WaveformStart.of_fit(averaged), forced=model)
            for k in model:
                z = (fit.values[k] - truth[k]) / fit.stderr[k]
                total += 1
                within += abs(z) < 3
                covered += abs(z) < fit.interval_factor
            if (q, model, seed) == (3, "b", 0):
                assert abs(averaged.values["b"] - truth["b"]) > 30 * averaged.stderr["b"]
    assert within >= 0.8 * total, (within, total)
    assert 0.90 <= covered / total <= 0.98, covered / total


def test_waveform_candidates_and_verdict():
    t, x, truth = _low_q_record(3, 0.0, 8, 1)
    record = Record(source="q3", t=t, x=x)
    fit = analyse_record(record, method="waveform").fit
    assert fit.method == "waveform" and fit.model == "b" and len(fit.candidates) == 8
    assert abs(fit.values["b"] - truth["b"]) < 3 * fit.stderr["b"]
    # Chi-square in units of the sample noise estimated from sixth differences.
    assert 0.7 < fit.reduced_chi_square < 1.4


def test_a_model_no_waveform_form_has_is_an_error_of_the_few_swings_record_not_a_crash():
    t, x, _ = _low_q_record(3, 0.0, 2, 0)
    record = Record(source="few", t=t, x=x)
    assert analyse_record(record).fit.method == "waveform"
    analysis = analyse_record(record, model="power")
    assert analysis.status == "error" and "turning points" in analysis.error


def test_bootstrap_asked_for_is_not_dropped_silently_when_the_waveform_is_reported():
    t, x, _ = _low_q_record(3, 0.0, 8, 1)
    record = Record(source="q3", t=t, x=x)
    fit = analyse_record(record, bootstrap=20, rng=np.random.default_rng(0)).fit
    assert fit.method == "waveform" and fit.bootstrap is None
    assert any("20 bootstrap refits asked for are of the turning-point fit" in w
               for w in fit.warnings)
    assert not any("bootstrap" in w for w in analyse_record(record).fit.warnings)


def _every_candidate_fitted(monkeypatch):
    """Fit every candidate of both forms in full: no estimate, no estimate taken as its
    own fit, no form stopped early (each ranked alone, the amplitude forms first)."""
    monkeypatch.setattr(waveform, "_may_not_lead", lambda opened: False)
    monkeypatch.setattr(waveform, "_may_matter", lambda *args: True)
    monkeypatch.setattr(waveform, "_from_estimate", lambda law, estimate: waveform._ranked(
        law, estimate.internal, waveform._RANKING)[0])
    ranked = waveform.rank_form
    monkeypatch.setattr(waveform, "rank_form",
                        lambda *args, rival=None, **kwargs: ranked(*args, **kwargs))


def _same_choice(quick, full):
    """The same choice; the p-values of the terms dropped within 1 % (a candidate may be
    its estimate, within the ranking's tolerance of its fit)."""
    assert (quick.model, quick.damping_form) == (full.model, full.damping_form)
    for field in ("preferred", "resolved", "ties"):
        assert getattr(quick.selection, field) == getattr(full.selection, field), field
    assert [d[:2] for d in quick.selection.dropped] == [d[:2] for d in full.selection.dropped]
    for ours, theirs in zip(quick.selection.dropped, full.selection.dropped):
        assert ours[2] == pytest.approx(theirs[2], rel=1e-2)
    assert set(quick.selection.near_threshold) == set(full.selection.near_threshold)
    for k in ("y0",) + tuple(full.model.replace("none", "")):
        assert abs(quick.values[k] - full.values[k]) < 1e-3 * full.stderr[k]


@pytest.mark.slow
@pytest.mark.parametrize("q, share, cycles, seed", [
    (3, 0.0, 8, 3), (5, 0.1, 8, 3), (2, 0.0, 5, 1), (5, 0.0, 8, 4), (3, 0.1, 3, 0)])
def test_estimated_candidates_and_a_form_stopped_early_change_no_result(
        monkeypatch, q, share, cycles, seed):
    """Candidates estimated, not fitted, and the second form stopped where it cannot tie:
    the same choice (model, form, ties, tests near the threshold) and values as fitting
    every candidate of both forms. Each estimate that was left unfitted could not have
    changed the choice: far above the best, or adding terms that lower chi-square by
    less than _NEGLIGIBLE in the fit too (within 0.5: the estimate's error)."""
    t, x, _ = _low_q_record(q, share, cycles, seed)
    turning = find_turning_points(t, x)
    start = WaveformStart.of_fit(fit_turning_points(turning))
    quick = fit_both_forms(t, x, turning, start)
    assert any(c.estimated for c in quick.candidates)
    _every_candidate_fitted(monkeypatch)
    full = fit_both_forms(t, x, turning, start)
    _same_choice(quick, full)
    for term, p in full.selection.near_threshold.items():
        assert quick.selection.near_threshold[term] == pytest.approx(p, rel=1e-2)
    for term, p in full.lrt_p_values.items():  # tails against an estimate are estimates
        if p > 1e-6:
            assert quick.lrt_p_values[term] == pytest.approx(p, rel=1e-2)
    if "equally" in full.damping_form_reason:
        return
    fitted = {c.model: c for c in full.candidates}
    best = min(fitted.values(), key=lambda c: c.aicc)
    n = full.n_points
    for c in (c for c in quick.candidates if c.estimated):
        truth = fitted[c.model]
        if set(best.terms) < set(c.terms) and truth.aicc - best.aicc <= waveform._DECISIVE:
            assert n * math.log(best.chi_square / truth.chi_square) < waveform._NEGLIGIBLE + 0.5
        else:
            assert truth.aicc - best.aicc > waveform._DECISIVE / 2


def test_a_form_that_cannot_tie_stops_after_its_first_fit(monkeypatch):
    """Eq. 20.55 at Q = 3: the velocity forms start from the amplitude forms' choice and
    stop after three steps of that fit, thousands of AICc behind (every candidate fitted,
    they take 4 fits); the reason says the gap is estimated where their choice is."""
    t, x, _ = _low_q_record(3, 0.0, 8, 1)
    turning = find_turning_points(t, x)
    start = WaveformStart.of_fit(fit_turning_points(turning))
    fits = []
    for name in ("_ranked", "_fitted_as_reported"):
        fitter = getattr(waveform, name)
        monkeypatch.setattr(waveform, name, lambda law, *args, fitter=fitter, name=name:
                            fits.append(f"{name}:{type(law).__name__}") or fitter(law, *args))
    quick = fit_both_forms(t, x, turning, start)
    assert (quick.model, quick.damping_form) == ("b", "amplitude")
    velocity = [name for name in fits if name.startswith(("_fitted_as_reported:Velocity",
                                                          "_fitted_as_reported:Equation"))]
    assert not velocity  # three steps (_glimpse), not a full fit
    assert sum(name.endswith(("VelocityWaveform", "EquationOfMotionWaveform"))
               for name in fits) == 1
    assert "AICc lower by about" in quick.damping_form_reason
    fits.clear()
    _every_candidate_fitted(monkeypatch)
    full = fit_both_forms(t, x, turning, start)
    assert sum(name.endswith(("VelocityWaveform", "EquationOfMotionWaveform"))
               for name in fits) >= 4
    assert "AICc lower by about" not in full.damping_form_reason


@pytest.mark.slow
@pytest.mark.parametrize("q, mix, seed", [(5, "abc", 6), (3, "bc", 5), (5, "bc", 2026)])
def test_no_fitted_model_ends_above_a_model_it_contains(q, mix, seed):
    """A model's least-squares minimum is at most that of any model it contains. A model
    fitted early from a poor start (b + c at Q = 5 from the turning-point fit's a + c)
    stopped at a kink of the motion, 9x above the model without its fluid term, and the
    fluid term was lost; it is refitted from the new best's estimate: a, b, c within 3
    standard errors of the truth."""
    from mcfit.bench.waveform_speed import _law, q_record

    t, x = q_record(q, mix, seed)
    turning = find_turning_points(t, x)
    fit = fit_both_forms(t, x, turning, WaveformStart.of_fit(fit_turning_points(turning)))
    fitted = [c for c in fit.candidates if not c.estimated]
    for small in fitted:
        for large in fitted:
            if set(small.terms) < set(large.terms):
                assert large.chi_square <= small.chi_square * (1 + 1e-6), (large, small)
    if (q, mix) == (5, "abc"):
        assert (fit.model, fit.damping_form) == ("abc", "amplitude")
        for k, truth in zip("abc", _law(q, mix)):
            assert abs(fit.values[k] - truth) < 3 * fit.stderr[k]


def test_a_model_only_one_form_has_is_fitted_in_that_form(monkeypatch):
    """A forced model that one form does not offer is fitted in the other, which the
    reason names (it was a crash: two forms were unpacked from one)."""
    t, x, _ = _low_q_record(3, 0.0, 8, 1)
    turning = find_turning_points(t, x)
    start = WaveformStart.of_fit(fit_turning_points(turning, model="b"))
    law, offered = waveform.FORMS["velocity"]
    monkeypatch.setitem(waveform.FORMS, "velocity",
                        (law, tuple(m for m in offered if m != "b")))
    fit = fit_both_forms(t, x, turning, start, forced="b")
    assert (fit.model, fit.damping_form) == ("b", "amplitude")
    assert fit.damping_form_reason == "only Eq. 20.55's amplitude forms have the model 'b'"


def test_estimates_of_nested_models_match_their_fits():
    """The quadratic model about the best fit (the largest model's Jacobian there) gives
    a model that adds a term or drops one the chi-square of fitting it: within 0.05 for a
    term the record does not need; for one it needs, within 30 % of the rise (the model
    is extrapolated; only far from the best is such an estimate left unfitted)."""
    t, x, _ = _low_q_record(3, 0.1, 4, 2)
    turning = find_turning_points(t, x)
    tw, xw, t0, nuisance = waveform._window(t, x, turning, 2 * math.pi)
    noise = waveform.sample_noise(xw)
    law = {m: amplitude_waveform(tw, xw, t0, m, noise) for m in ("b", "bc", "abc")}
    start = WaveformStart.of_fit(fit_turning_points(turning, model="bc"))
    best = waveform.fit_candidate(law["bc"], waveform._start_vector(
        start.values["bc"], nuisance, "bc"))[0]
    estimates = waveform._estimates(law["abc"], best, {"b", "abc"})
    for model in ("b", "abc"):
        fitted = waveform.fit_candidate(law[model], estimates[model].internal)[0]
        change = abs(fitted.chi_square - best.chi_square)
        assert estimates[model].estimated and not fitted.estimated
        assert estimates[model].chi_square == pytest.approx(
            fitted.chi_square, abs=max(0.05, 0.3 * change))
    assert estimates["b"].chi_square - best.chi_square > 100  # c is needed


def test_auto_takes_the_waveform_at_low_q_and_says_why():
    t, x, truth = _low_q_record(3, 0.0, 8, 2)
    fit = analyse_record(Record(source="q3", t=t, x=x)).fit
    assert fit.method == "waveform"
    assert fit.method_reason.startswith("the averaged law's bias is predicted at")
    assert fit.method_reason.endswith("fitted by the equation of motion")
    assert abs(fit.values["b"] - truth["b"]) < 3 * fit.stderr["b"]


def test_auto_keeps_the_turning_point_fit_on_the_fig_20_19_sample():
    record = read_record(str(ROOT / "sample_data" / "fig20_19_all_three.csv"))
    auto = analyse_record(record).fit
    plain = analyse_record(record, method="turning-points").fit
    assert auto.method == "turning-points"
    assert auto.method_reason.endswith("the turning-point fit suffices")
    assert auto.values == plain.values and auto.model == plain.model == "abc"


@pytest.mark.skipif(not REAL.is_dir(), reason="shared real records not present")
@pytest.mark.parametrize("path", sorted(str(p) for p in REAL.glob("*/*")
                                        if p.suffix in (".txt", ".csv")) if REAL.is_dir()
                         else [])
def test_auto_keeps_the_turning_point_fit_on_real_records(path):
    fit = analyse_record(read_record(path)).fit
    assert fit.method == "turning-points"


def test_auto_fits_a_viscous_oscillator_by_the_velocity_forms():
    """exp(-beta*t)*cos(w_d*t) at Q = 3 is no solution of Eq. 20.55, whose b is
    hysteretic: the velocity forms (viscous 2*beta*x') fit it within its noise, and say
    so, with b = beta and the force's coefficient beta."""
    beta = OMEGA / 6
    t = np.arange(0.0, 8.0, 0.01)
    x = (np.exp(-beta * t) * np.cos(math.sqrt(OMEGA**2 - beta**2) * t)
         + np.random.default_rng(5).normal(0.0, 1e-4, t.size))
    fit = analyse_record(Record(source="viscous", t=t, x=x)).fit
    assert fit.method == "waveform" and fit.model == "b" and fit.resolved
    assert fit.damping_form == "velocity"
    assert abs(fit.values["b"] - beta) < 3 * fit.stderr["b"]
    assert fit.physical["beta"]["value"] == fit.values["b"]
    assert fit.reduced_chi_square < 1.3


def test_a_turning_point_misfit_does_not_hide_the_averaged_laws_bias():
    """Q = 5, 6 s ending before the noise: the turning-point fit misfitted (reduced
    chi-square in the hundreds, from a biased equilibrium) and its errors, scaled by that
    misfit, once made a bias of 7 noise standard errors look like 0.3; auto kept b = 0.61
    +- 0.02. With the equilibrium unbiased the turning points follow the averaged law, whose
    b lies below Eq. 20.55's by the law's own error at low Q (docs/theory.md section 7)."""
    truth = {"a": 0.0, "b": 0.6, "c": 0.0}
    t, x = simulate_record(y0=1.0, period=1.0, duration=6.0, rate=200.0, noise=1e-4,
                           rng=np.random.default_rng(3), **truth)
    record = Record(source="q5", t=t, x=x)
    fit = analyse_record(record).fit
    points = analyse_record(record, method="turning-points").fit
    assert points.reduced_chi_square < 2
    assert 0.001 < 1 - points.values["b"] / truth["b"] < 0.01
    assert truth["b"] - points.values["b"] > 10 * points.stderr["b"]
    assert fit.method == "waveform" and fit.model == "b"
    assert abs(fit.values["b"] - truth["b"]) < 3 * fit.stderr["b"]


@pytest.mark.parametrize("scale", [1e-12, 1.0, 1e12])
def test_difference_steps_scale_with_the_signals_unit(scale):
    """A record in other units (picometres, not metres) gets the same steps in its units:
    y0, offset, drift and c scale with U, a with 1/U, the phase, frequency and b not."""
    start = np.array([1.0, 0.3, 2 * np.pi, 0.0, 0.0, 0.0, 0.0, 0.0])
    units = np.array([scale, 1.0, 1.0, scale, scale, 1.0 / scale, 1.0, scale])
    np.testing.assert_allclose(waveform._typical(start * units, "abc"),
                               waveform._typical(start, "abc") * units, rtol=1e-15)


@pytest.mark.parametrize("quality, seed", [(2.0, 1), (3.0, 2)])
def test_a_few_swings_with_friction_are_fitted_by_the_waveform(quality, seed):
    """Eq. 20.55 with b and c (c a tenth of the first decay rate), from an independent
    integration, 8 s at 100 Hz, noise 1e-3: the mass stops after a few swings, too few
    turning points for the averaged law (refused before: "only 2 turning points found").
    The waveform fit recovers b and c within 3 standard errors, in Eq. 20.55's form."""
    from mcfit.bench.reference_motion import hysteretic

    b = OMEGA / (2 * quality)
    c = b / 9
    t, x = hysteretic(0.0, b, c, OMEGA, 1.0, 8.0, 100.0)
    x = x + np.random.default_rng(seed).normal(0.0, 1e-3, t.size)
    analysis = analyse_record(Record(source="few", t=t, x=x))
    fit = analysis.fit
    assert fit is not None, analysis.error
    assert fit.method == "waveform" and fit.model == "bc" and fit.resolved
    assert fit.damping_form == "amplitude"
    assert abs(fit.values["b"] - b) < 3 * fit.stderr["b"]
    assert abs(fit.values["c"] - c) < 3 * fit.stderr["c"]
    assert fit.reduced_chi_square < 1.2
    assert analysis.turning.period == pytest.approx(1.0, rel=1e-3)


def test_a_waveform_fit_names_residual_structure_below_the_misfit_limit():
    """A viscous decay at Q = 3 with a slow disturbance of the noise's size (0.37 Hz,
    1e-3): the reduced chi-square stays under the misfit limit, but the residuals of
    neighbouring samples are correlated, and the waveform fit says so as the turning-point
    fit does."""
    beta = OMEGA / 6
    t = np.arange(0.0, 8.0, 0.01)
    x = (np.exp(-beta * t) * np.cos(math.sqrt(OMEGA**2 - beta**2) * t)
         + 1e-3 * np.sin(2 * np.pi * 0.37 * t)
         + np.random.default_rng(1).normal(0.0, 1e-3, t.size))
    fit = analyse_record(Record(source="disturbed", t=t, x=x)).fit
    assert fit.method == "waveform" and fit.reduced_chi_square < 2
    assert any(w.startswith("residuals are correlated") for w in fit.warnings)


def test_a_few_swings_fit_shows_the_fitted_motions_turning_points():
    """The stand-in turning points of a few-swings fit (a damped cosine's, which start the
    waveform fit) are replaced by the fitted law's amplitudes at their times: a figure or
    a table of them then shows the fit, not a damped cosine that disagrees with it."""
    from mcfit.bench.reference_motion import hysteretic

    b = OMEGA / 4
    t, x = hysteretic(0.0, b, b / 9, OMEGA, 1.0, 8.0, 100.0)
    x = x + np.random.default_rng(1).normal(0.0, 1e-3, t.size)
    analysis = analyse_record(Record(source="few", t=t, x=x))
    np.testing.assert_allclose(analysis.turning.y, analysis.fit.amplitude(analysis.turning.t),
                               rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(analysis.fit.y, analysis.fit.y_fit)
    assert any("not measured but the fitted motion's" in n for n in analysis.turning.notes)


@pytest.mark.parametrize("seed", [2026, 1, 2])
def test_a_decay_to_a_coulomb_stop_at_q_3_is_fitted_in_its_own_form(seed):
    """The bench's record at Q = 3 with b and a Coulomb tenth (Eq. 20.55, noise 1e-3 of
    y0): the crests' frequency, 11 % below omega here (the Coulomb stop, and the noise
    crests after it), had led every fit into another minimum, and velocity a + b + c was
    reported with a = 0.16 at 19 standard errors and correlated residuals. Retuned to the
    undamped frequency the crests imply, the amplitude form's b + c describes it, with b
    and c within 3 standard errors of the truth."""
    from mcfit.bench.waveform_speed import _law, q_record

    t, x = q_record(3, "bc", seed)
    _, b, c = _law(3, "bc")
    turning = find_turning_points(t, x)
    start = WaveformStart.of_fit(fit_turning_points(turning))
    fit = fit_both_forms(t, x, turning, start)
    assert (fit.model, fit.damping_form) == ("bc", "amplitude")
    assert abs(fit.values["b"] - b) < 3 * fit.stderr["b"]
    assert abs(fit.values["c"] - c) < 3 * fit.stderr["c"]
    assert fit.reduced_chi_square < 1.2


@pytest.mark.parametrize("q", [2.0, 3.0, 10.0])
def test_the_undamped_frequency_of_the_crests_of_b_alone_is_omega(q):
    """Eq. 20.55 with b alone (closed form, no noise): the crests' spacing gives
    sqrt(omega**2 - k**2), 3 % below omega at Q = 3; their amplitudes give it back."""
    from mcfit.hysteretic_motion import hysteretic_motion

    t = np.linspace(0.0, 6.0, 60001)
    x = hysteretic_motion(t, 1.0, 0.0, OMEGA, OMEGA / (2 * q))[0]
    turning = find_turning_points(t, x + 1e-9 * np.random.default_rng(1).standard_normal(
        t.size))
    crests = 2 * math.pi / turning.period
    assert waveform.undamped_frequency(turning, crests) == pytest.approx(OMEGA, rel=1e-3)
    if q <= 3:
        assert crests < 0.98 * OMEGA


def test_auto_starts_without_a_term_its_predicted_bias_explains():
    """At Q = 5 with b and a Coulomb tenth the turning-point fit reports a + b + c, a at
    16 standard errors, and the chain predicts a bias of a of 57: auto starts the waveform
    fit with b + c. The terms left out are still estimated and fitted where they may
    matter: the fit from there ends where the fit from a + b + c does."""
    from mcfit.analysis import auto_start
    from mcfit.bench.waveform_speed import q_record
    from mcfit.model_error import averaged_law_bias

    t, x = q_record(5, "bc", 2026)
    turning = find_turning_points(t, x)
    fit = fit_turning_points(turning)
    start = auto_start(fit, averaged_law_bias(t, turning, fit))
    assert (fit.model, start.model) == ("abc", "bc")
    ours, theirs = (fit_both_forms(t, x, turning, s)
                    for s in (start, WaveformStart.of_fit(fit)))
    assert (ours.model, ours.damping_form) == (theirs.model, theirs.damping_form) == (
        "bc", "amplitude")
    for k in "bc":
        assert abs(ours.values[k] - theirs.values[k]) < 1e-3 * theirs.stderr[k]


def test_auto_start_keeps_the_model_the_bias_does_not_explain():
    """The screen's z is no prediction, a model is never emptied, and where the chain
    fails (an infinite z: no turning points on the noise-free waveform) the fit's model
    is not trusted: no start model (the nearest candidate starts)."""
    from mcfit.analysis import auto_start
    from mcfit.model_error import ModelError, noise_stderr

    t, x = _sample_record()
    fit = fit_turning_points(find_turning_points(t, x))
    terms = fit.selection.terms
    sizes = {k: fit.values[k] / s for k, s in noise_stderr(fit).items()}
    every = {k: sizes[k] for k in terms}
    assert auto_start(fit, ModelError(every, 0.0, 5.0, "screen")).model == fit.model
    assert auto_start(fit, ModelError(every, 0.0, 5.0, "chain")).model == fit.model
    inf = {k: math.inf for k in terms}
    assert auto_start(fit, ModelError(inf, math.inf, 5.0, "chain")).model is None
    one = {k: sizes[k] if k == terms[0] else 0.0 for k in terms}
    assert auto_start(fit, ModelError(one, 0.0, 5.0, "chain")).model == "".join(terms[1:])


def _sample_record():
    record = read_record(ROOT / "sample_data" / "fig20_19_all_three.csv")
    return record.t, record.x


def test_a_second_call_at_the_same_point_reuses_the_motion_until_the_steps_change():
    """lmfit asks for the residuals again at its solution: the motion is not solved
    twice there, the residuals returned are the caller's to change, and new difference
    steps (a fit's ``typical``) make a new Jacobian."""
    t = np.linspace(0.0, 4.0, 2001)
    x = phase_plane_motion(t, 1.0, 0.0, OMEGA, 0.05, 0.3, 0.02)[0]
    law = amplitude_waveform(t, x, 0.0, ("a", "b", "c"), 1e-3)
    p = np.array([1.0, 0.0, OMEGA, 0.0, 0.0, 0.05, 0.3, 0.02])
    law.typical = waveform._typical(p, law.terms)
    solved = []
    original = law._with_jacobian
    law._with_jacobian = lambda q: solved.append(q) or original(q)
    first = law.residual(p)
    first[:] = 7.0
    again = law.residual(p.copy())
    assert len(solved) == 1 and np.all(np.abs(again) < 1e-6)
    assert law.jacobian(p) is law.jacobian(p) and len(solved) == 1
    law.typical = law.typical.copy()  # the same steps: the same Jacobian
    law.residual(p)
    assert len(solved) == 1
    law.typical = 10 * law.typical
    law.residual(p)
    assert len(solved) == 2


def test_the_second_form_takes_the_first_forms_sample_noise(monkeypatch):
    """Both forms fit the same window: its sample noise is estimated once, and the
    second form's laws carry the first's."""
    from mcfit.bench.waveform_speed import q_record

    t, x = q_record(5, "b", 2026)
    turning = find_turning_points(t, x)
    start = WaveformStart.of_fit(fit_turning_points(turning))
    calls, ranked = [], []
    counted, rank = waveform.sample_noise, waveform.rank_form
    monkeypatch.setattr(waveform, "sample_noise", lambda xw: calls.append(1) or counted(xw))
    monkeypatch.setattr(waveform, "rank_form",
                        lambda *a, **k: ranked.append(rank(*a, **k)) or ranked[-1])
    fit_both_forms(t, x, turning, start)
    assert len(ranked) == 2 and len(calls) == 1
    assert ranked[0].law.noise == ranked[1].law.noise == counted(ranked[0].law.x)


def test_where_the_chain_fails_the_fit_starts_from_the_nearest_candidate(monkeypatch):
    """At Q = 3 with b and a Coulomb stop the turning-point fit says a + c (a = 2.1) and
    no turning points are found on its own noise-free waveform, nor on b + c's. Auto then
    starts with the candidate whose start lies nearest the record, b + c, at the undamped
    frequency: one fit of b + c instead of two of a + c and more, and the same result
    as from a + c."""
    from mcfit.analysis import auto_start
    from mcfit.bench.waveform_speed import q_record
    from mcfit.model_error import averaged_law_bias

    t, x = q_record(3, "bc", 2026)
    turning = find_turning_points(t, x)
    fit = fit_turning_points(turning)
    start = auto_start(fit, averaged_law_bias(t, turning, fit))
    assert fit.model == "ac" and start.model is None
    fits = []
    for name in ("_ranked", "_fitted_as_reported"):
        fitter = getattr(waveform, name)
        monkeypatch.setattr(waveform, name, lambda law, *args, fitter=fitter: fits.append(
            (type(law).__name__, law.terms)) or fitter(law, *args))
    ours = fit_both_forms(t, x, turning, start)
    amplitude = [terms for kind, terms in fits if kind.startswith("Amplitude")]
    assert amplitude == ["bc"]
    fits.clear()
    theirs = fit_both_forms(t, x, turning, WaveformStart.of_fit(fit))
    assert [f[1] for f in fits if f[0].startswith("Amplitude")][:3] == ["ac", "ac", "bc"]
    assert (ours.model, ours.damping_form) == (theirs.model, theirs.damping_form) == (
        "bc", "amplitude")
    for k in "bc":
        assert abs(ours.values[k] - theirs.values[k]) < 1e-3 * theirs.stderr[k]


@pytest.mark.parametrize("q", [8, 2])
def test_an_estimate_is_its_own_fit_where_the_fit_would_stop_at_once(q):
    """A candidate estimated from the best fit is taken as its own fit, at one
    evaluation, where the Gauss-Newton step from it would lower chi-square by less than
    the ranking's tolerance: at Q = 8 (b alone) the ranking fit from there stops within
    that tolerance of it and within 0.01 standard errors (it takes a step and stops); at
    Q = 2, where the estimate is 0.2 off, it is fitted from there."""
    from mcfit.bench.waveform_speed import q_record

    t, x = q_record(q, "b", 2026)
    turning = find_turning_points(t, x)
    start = WaveformStart.of_fit(fit_turning_points(turning))
    tw, xw, t0, nuisance = waveform._window(t, x, turning, start.omega)
    noise = waveform.sample_noise(xw)
    law = {m: amplitude_waveform(tw, xw, t0, m, noise) for m in ("b", "bc", "abc")}
    best = waveform.fit_candidate(law["b"], waveform._start_vector(
        start.values["b"], nuisance, "b"))[0]
    estimate = waveform._estimates(law["abc"], best, {"bc"})["bc"]
    taken = waveform._from_estimate(law["bc"], estimate)
    fitted, solved = waveform._ranked(law["bc"], estimate.internal, waveform._RANKING)
    assert not taken.estimated
    if q == 2:  # the step would gain more: fitted, not taken
        assert taken.evaluations == solved.nfev > 1
        return
    assert taken.evaluations == 1 and solved.nfev == 2
    tolerance = waveform._RANKING["ftol"] * fitted.chi_square
    assert abs(taken.chi_square - fitted.chi_square) <= 2 * tolerance
    errors = np.sqrt(np.diag(np.linalg.pinv(solved.jac.T @ solved.jac)))  # noise units
    assert np.all(np.abs(taken.internal - fitted.internal) < 0.01 * errors)


@pytest.mark.parametrize("q, shares, seed", [(5, (0.2, 0.7, 0.1), 4), (4, (0.3, 0.5, 0.2), 3)])
def test_from_a_first_fit_in_another_minimum_every_candidate_that_may_matter_is_fitted(
        q, shares, seed):
    """At Q = 4 and 5 with all three terms and a noise of 1e-2 of y0, the first fit (c,
    reduced chi-square 1.9; a + c) sits in another minimum and its estimates are far
    off: fitted one at a time, b + c was estimated 65-270 AICc behind a stuck a + b + c
    and never fitted, and a + b + c was reported 6-35 standard errors off. From a best
    outside the noise every candidate that may matter is fitted: a, b, c within 3
    standard errors of the truth."""
    from mcfit.analysis import auto_start
    from mcfit.bench.methods import record_duration
    from mcfit.model_error import averaged_law_bias

    rate, duration = OMEGA / (2 * q), record_duration(q)
    truth = dict(zip("abc", (share * rate for share in shares)))
    t, x = simulate_record(*truth.values(), 1.0, 1.0, duration, 9999 / duration,
                           method="accurate", noise=1e-2,
                           rng=np.random.default_rng([seed, 5, int(10 * q), 2]))
    turning = find_turning_points(t, x)
    fit = fit_turning_points(turning)
    start = auto_start(fit, averaged_law_bias(t, turning, fit))
    ours = fit_both_forms(t, x, turning, start)
    assert (ours.model, ours.damping_form) == ("abc", "amplitude")
    for k in "abc":
        assert abs(ours.values[k] - truth[k]) < 3 * ours.stderr[k]


def test_a_model_that_only_sets_a_term_of_the_new_best_at_zero_is_not_fitted(monkeypatch):
    """At Q = 2 (b alone) b + c and a + b + c are estimated alike from b (a at 0): b + c
    is fitted first, and from it a + b + c is estimated to lower chi-square by less than
    _NEGLIGIBLE, so it is not fitted; the choice and values are those of fitting every
    candidate."""
    from mcfit.bench.waveform_speed import q_record

    t, x = q_record(2, "b", 2026)
    turning = find_turning_points(t, x)
    start = WaveformStart.of_fit(fit_turning_points(turning))
    quick = fit_both_forms(t, x, turning, start)
    candidates = {c.model: c for c in quick.candidates}
    assert not candidates["bc"].estimated and candidates["abc"].estimated
    assert quick.n_points * math.log(candidates["bc"].chi_square
                                     / candidates["abc"].chi_square) < waveform._NEGLIGIBLE
    _every_candidate_fitted(monkeypatch)
    full = fit_both_forms(t, x, turning, start)
    _same_choice(quick, full)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), columns=st.integers(1, 8), extra=st.integers(0, 3),
       bound=st.sampled_from(["none", "lower", "both"]))
def test_bounded_least_squares_is_scipys_bounded_solution(seed, columns, extra, bound):
    """The unbounded solution where no bound binds, else scipy's bounded-variable least
    squares: the same minimum as bvls alone, within its bounds, for any system."""
    from scipy import optimize

    rng = np.random.default_rng(seed)
    matrix = rng.standard_normal((columns + extra, columns)) * rng.uniform(0.1, 10, columns)
    target = rng.standard_normal(columns + extra)
    lower = (np.full(columns, -np.inf) if bound == "none"
             else rng.uniform(-1.0, 0.5, columns))
    upper = rng.uniform(0.6, 2.0, columns) if bound == "both" else np.full(columns, np.inf)
    ours = waveform._bounded_least_squares(matrix, target, lower, upper)
    theirs = optimize.lsq_linear(matrix, target, bounds=(lower, upper), method="bvls").x
    assert np.all(ours >= lower - 1e-12) and np.all(ours <= upper + 1e-12)
    ours_cost, theirs_cost = (float(np.sum((matrix @ step - target) ** 2))
                              for step in (ours, theirs))
    assert ours_cost == pytest.approx(theirs_cost, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("form, terms", [("amplitude", ("b",)), ("amplitude", ("b", "c")),
                                         ("amplitude", ("a", "b", "c")),
                                         ("velocity", ("b", "c")), ("velocity", ("a", "b"))])
def test_chi_square_from_the_motion_alone_is_that_of_the_residuals(form, terms):
    """A law's chi-square without its Jacobian (the nearest start's ranking) is the sum
    of the squared residuals its fit sees, in every form (phase plane, closed forms,
    integrated), a Coulomb stop inside the record."""
    t = np.linspace(0.0, 5.0, 1501)
    x = phase_plane_motion(t, 1.0, 0.3, OMEGA, 0.0, 0.6, 0.15)[0] + 0.01
    law = waveform.FORMS[form][0](t, x, 0.0, terms, 1e-3)
    values = {"a": 0.05, "b": 0.55, "c": 0.12}
    p = np.array([0.98, 0.25, 1.01 * OMEGA, 0.02, -1e-3] + [values[k] for k in terms])
    law.typical = waveform._typical(p, law.terms)
    assert law.chi_square(p) == pytest.approx(np.sum(law.residual(p) ** 2), rel=1e-12)


def _viscous_start(q):
    """(t, x, turning points, auto's start) of the bench's linear viscous oscillator."""
    from mcfit.analysis import auto_start
    from mcfit.bench.waveform_speed import q_record
    from mcfit.model_error import averaged_law_bias

    t, x = q_record(q, "viscous", 2026)
    turning = find_turning_points(t, x)
    fit = fit_turning_points(turning)
    return t, x, turning, auto_start(fit, averaged_law_bias(t, turning, fit))


@pytest.mark.slow
@pytest.mark.parametrize("q", [3, 8])
def test_where_only_the_velocity_forms_describe_their_first_fit_they_go_first(
        monkeypatch, q):
    """A linear viscous oscillator at Q = 3 and 8: the amplitude forms' first fit, b, is
    outside the noise (reduced chi-square 3.3 and 1.8), the velocity forms' b within it.
    The velocity forms are ranked first and the amplitude forms close on estimates from
    their b: nothing else is fitted in the amplitude forms (before: b again, a + b + c
    and a + b), b is fitted once in each form, and the result is that of fitting every
    candidate of both forms in full."""
    t, x, turning, start = _viscous_start(q)
    fits = []
    for name in ("_ranked", "_fitted_as_reported", "_from_estimate"):
        fitter = getattr(waveform, name)
        monkeypatch.setattr(waveform, name, lambda law, *args, fitter=fitter: fits.append(
            (type(law).__name__, law.terms)) or fitter(law, *args))
    ours = fit_both_forms(t, x, turning, start)
    assert [f for f in fits if f[0].startswith(("Amplitude", "Hysteretic"))] == [
        ("HystereticWaveform", "b")]
    assert fits.count(("VelocityWaveform", "b")) == 1
    assert "about" in ours.damping_form_reason  # the amplitude forms' AICc is estimated
    monkeypatch.setattr(waveform, "_closed", lambda *args: None)  # ranked down to the bar
    unclosed = fit_both_forms(t, x, turning, start)
    _every_candidate_fitted(monkeypatch)
    full = fit_both_forms(t, x, turning, start)
    assert not any(c.estimated for c in full.candidates)
    _same_choice(ours, full)
    _same_choice(unclosed, full)
    assert (ours.model, ours.damping_form) == ("b", "velocity")


@pytest.mark.parametrize("q", [3, 8])
def test_after_a_misfit_the_second_form_starts_from_the_start_model(monkeypatch, q):
    """With the amplitude forms ranked first (as where the velocity forms' first fit does
    not describe the record either), a linear viscous oscillator at Q = 3 and 8: the
    amplitude forms describe it outside its noise (reduced chi-square 3.2 and 1.6) and
    select a + b + c; the velocity forms start from the turning-point fit's b (closed
    form), not from a + b + c (drag integrated, 25 evaluations at Q = 3), from both starts
    (no glimpse from a start model), and end where they did: b in the velocity forms, the
    same values."""
    monkeypatch.setattr(waveform, "_may_not_lead", lambda opened: False)
    t, x, turning, start = _viscous_start(q)
    fits = []
    fitter = waveform._fitted_as_reported
    monkeypatch.setattr(waveform, "_fitted_as_reported", lambda law, begin: fits.append(
        (type(law).__name__, law.terms)) or fitter(law, begin))
    ours = fit_both_forms(t, x, turning, start)
    assert [f for f in fits if not f[0].startswith(("Amplitude", "Hysteretic"))] == [
        ("VelocityWaveform", "b")] * 2  # from the rival's values and from its own
    monkeypatch.setattr(waveform, "_first_after", lambda rival, model, n: rival.selection.model)
    theirs = fit_both_forms(t, x, turning, start)
    assert (ours.model, ours.damping_form) == (theirs.model, theirs.damping_form) == (
        "b", "velocity")
    assert abs(ours.values["b"] - theirs.values["b"]) < 1e-3 * theirs.stderr["b"]
    assert abs(ours.values["b"] - math.pi / q) < 3 * ours.stderr["b"]


def test_the_second_form_never_starts_from_no_damping(monkeypatch):
    """At Q = 2 with b + c and a noise of 1e-2 the turning-point fit says no damping, and
    the amplitude forms' a + b + c is outside the noise (reduced chi-square 1.37): the
    velocity forms start from a + b + c, not from no damping (whose glimpse closed the
    form on estimates and left a + b + c reported 2544 AICc above the velocity forms'
    c), and end where they did before."""
    from mcfit.analysis import _selected, auto_start
    from mcfit.bench.methods import record_duration
    from mcfit.model_error import averaged_law_bias

    rate, duration = OMEGA / 4, record_duration(2)
    t, x = simulate_record(0.0, 0.9 * rate, 0.1 * rate, 1.0, 1.0, duration,
                           9999 / duration, method="accurate", noise=1e-2,
                           rng=np.random.default_rng([3, 5, 20, 2]))
    turning = find_turning_points(t, x)
    fit = fit_turning_points(turning)
    start = auto_start(fit, averaged_law_bias(t, turning, fit))
    assert start.model == "none"
    ours = fit_both_forms(t, x, turning, start)
    monkeypatch.setattr(waveform, "_first_after", lambda rival, model, n: rival.selection.model)
    theirs = fit_both_forms(t, x, turning, start)
    assert (ours.model, ours.damping_form) == (theirs.model, theirs.damping_form)
    assert ours.damping_form != "amplitude"
    assert _selected(ours).aicc == pytest.approx(_selected(theirs).aicc, abs=1e-6)


def test_a_model_dropping_only_terms_the_best_can_do_without_starts_from_its_estimate(
        monkeypatch):
    """The bench's pendulum at Q = 3 (viscous only) started from the turning-point fit's
    a + b, whose waveform fit ends at a = 2e-5: b + c drops only that a, and is fitted
    from its estimate in one evaluation, not from the turning-point values (9), with the
    same answer."""
    from functools import partial

    from mcfit.bench.waveform_speed import q_record
    from mcfit.fit.waveform_laws import PendulumWaveform

    t, x = q_record(3, "pendulum", 2026)
    turning = find_turning_points(t, x)
    start = WaveformStart.of_fit(fit_turning_points(turning, pendulum=True))
    assert start.model == "ab"
    fit = partial(fit_waveform, form="velocity", kind=PendulumWaveform)
    args = (t, x, turning, start)
    fits = []
    ranked = waveform._ranked
    monkeypatch.setattr(waveform, "_ranked", lambda law, *rest: fits.append(law.terms)
                        or ranked(law, *rest))
    ours = fit(*args)
    assert fits == []
    assert ours.candidates[[c.model for c in ours.candidates].index("bc")].evaluations == 1
    monkeypatch.setattr(waveform, "_dispensable", lambda *rest: False)
    theirs = fit(*args)
    assert "bc" in fits
    assert ours.model == theirs.model == "b"
    assert abs(ours.values["b"] - theirs.values["b"]) < 1e-3 * theirs.stderr["b"]


def test_a_term_is_dispensable_only_where_dropping_it_costs_less_than_negligible():
    """Less than _NEGLIGIBLE in the likelihood-ratio statistic, and never where the
    estimate without the term lies below the best (a quadratic model gone wrong; its
    chi-square may even be negative, which once raised a math domain error)."""
    def candidate(terms, chi_square):
        p = np.ones(5 + len(terms))
        return waveform._candidate(terms, 100, p, chi_square, True, 0, np.eye(p.size),
                                   estimated=True)

    best, estimate = candidate("ab", 100.0), candidate("bc", 100.0)
    for without, expected in ((100.4, True), (102.0, False), (99.0, False), (-5.0, False)):
        estimates = {"b": candidate("b", without)}
        assert waveform._dispensable(best, estimate, estimates, 100) is expected


def test_a_candidate_is_fitted_from_the_estimate_of_the_fit_it_extends(monkeypatch):
    """The bench's Q = 2 record with b alone: b is fitted first, then b + c (near the
    threshold), which becomes the best; a + b (within the ties) is then fitted from its
    estimate from b, which it extends, in one evaluation, not from the estimate from
    b + c (three), with the same choice and values."""
    from mcfit.analysis import auto_start
    from mcfit.bench.waveform_speed import q_record
    from mcfit.model_error import averaged_law_bias

    t, x = q_record(2, "b", 2026)
    turning = find_turning_points(t, x)
    fit = fit_turning_points(turning)
    start = auto_start(fit, averaged_law_bias(t, turning, fit))
    ours = fit_both_forms(t, x, turning, start)
    ab = next(c for c in ours.candidates if c.model == "ab")
    assert ours.model == "b" and not ab.estimated and ab.evaluations == 1
    monkeypatch.setattr(waveform, "_parent", lambda model, best, fitted, earlier:
                        earlier[id(best)])
    theirs = fit_both_forms(t, x, turning, start)
    assert next(c for c in theirs.candidates if c.model == "ab").evaluations == 3
    _same_choice(ours, theirs)


def test_the_velocity_forms_go_first_only_where_their_first_model_is_the_same():
    """Q = 3 with b and c, noise 3e-2 of y0: the chain fails, so each form starts with
    the model whose start lies nearest the record, c in the amplitude forms (reduced
    chi-square 1.16) and b + c in the velocity forms (1.05, within the noise). First fits
    of two models say only which start lay nearer: the amplitude forms go first, and b + c
    is reported in them, as before the velocity forms could go first (a first version put
    them first and closed the amplitude forms on a glimpse: velocity b + c, b 8 standard
    errors off)."""
    from mcfit.analysis import auto_start
    from mcfit.bench.methods import record_duration
    from mcfit.bench.waveform_speed import _law
    from mcfit.model_error import averaged_law_bias

    duration = record_duration(3)
    t, x = simulate_record(*_law(3, "bc"), 1.0, 1.0, duration, 9999 / duration,
                           method="accurate", noise=0.03,
                           rng=np.random.default_rng([17, 28, 30]))
    turning = find_turning_points(t, x)
    fit = fit_turning_points(turning)
    start = auto_start(fit, averaged_law_bias(t, turning, fit))
    assert start.model is None
    opened = {form: waveform.open_form(t, x, turning, start, form=form)
              for form in ("amplitude", "velocity")}
    assert (opened["amplitude"].first.model, opened["velocity"].first.model) == ("c", "bc")
    ours = fit_both_forms(t, x, turning, start)
    assert (ours.model, ours.damping_form) == ("bc", "amplitude")
    b, c = _law(3, "bc")[1:]
    assert abs(ours.values["b"] - b) < 3 * ours.stderr["b"]
    assert abs(ours.values["c"] - c) < 3 * ours.stderr["c"]
