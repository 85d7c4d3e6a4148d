"""Where `pendulum=True` starts the waveform fit by the pendulum's equation of motion: the
averaged large-swing law's predicted bias of each term (the chain), and the start model
without the terms that bias explains. Records from an integration that shares no code with
mcfit (mcfit.bench.reference_motion) or the waveform bench's, fixed seeds."""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mcfit.analysis import (
    _pendulum_law_error,
    _pendulum_start,
    _without_steady_line,
    analyse_record,
    fit_turning_points,
)
from mcfit.bench import reference_motion as motion
from mcfit.bench.waveform_speed import q_record
from mcfit.fit.pendulum import fit_turning_points_of_pendulum
from mcfit.fit.waveform import WaveformStart, fit_waveform
from mcfit.fit.waveform_laws import PendulumWaveform
from mcfit.model_error import ModelError, pendulum_law_bias
from mcfit.record import Record
from mcfit.turning import find_turning_points

OMEGA = 2 * math.pi


def _swing(t, turning, fit):
    """The noise-free swing of ``fit``'s coefficients from the first used turning point,
    by scipy's DOP853 (theta'' + 2*b*theta' + kappa*theta'*|theta'| + w^2 sin(theta) = 0,
    kappa = 3*pi*a/(4*w): the velocity form of the fluid term), at the record's times."""
    first = np.flatnonzero(turning.used)[0]
    t0 = turning.t[first]
    times = t[t >= t0]
    v, w = fit.values, fit.omega
    kappa = 0.75 * math.pi * v["a"] / w
    solution = solve_ivp(
        lambda _, y: [y[1], -2 * v["b"] * y[1] - kappa * y[1] * abs(y[1]) - w * w * math.sin(
            y[0])], (0.0, times[-1] - t0), [math.copysign(v["y0"], turning.sign[first]), 0.0],
        method="DOP853", rtol=1e-12, atol=1e-14, t_eval=times - t0)
    return times, turning.equilibrium_at(times) + solution.y[0]


def test_the_bias_of_each_term_is_signed_and_in_the_noise_standard_errors():
    """Q = 5, a + b fitted to a viscous swing released at 0.8 rad: the chain's shift of
    each term, against the same turning-point fit of an independent integration, divided
    by the noise's standard errors (the reported ones over the root of the reduced
    chi-square, 6.1 here). The law reads the swing's geometry as drag: a's shift is
    positive, b's negative."""
    t, x = q_record(5, "pendulum", 2026)
    turning = find_turning_points(t, x)
    fit = fit_turning_points(turning, pendulum=True)
    assert fit.model == "ab"
    times, swing = _swing(t, turning, fit)
    found = find_turning_points(times, swing, settle_noise=turning.noise_sigma)
    again = fit_turning_points_of_pendulum(found, found.used_sigma(), model="ab").values
    assert fit.reduced_chi_square > 2
    scale = math.sqrt(fit.reduced_chi_square)
    expected = {k: (again[k] - fit.values[k]) * scale / fit.stderr[k] for k in "ab"}

    error = pendulum_law_bias(t, turning, fit)
    assert error.how == "chain" and set(error.z) == {"a", "b"}
    for k in "ab":
        assert error.z[k] == pytest.approx(expected[k], abs=0.05), k
    assert error.z["a"] > 5 and error.z["b"] < -2
    assert error.largest == max(abs(z) for z in error.z.values())


def _viscous_swing(q, noise, seed):
    """A viscous pendulum released at 0.8 rad at ``q``, 10^4 samples until the swing is
    down to 1e-3 of its start (as the waveform bench's), ``noise`` rad."""
    duration = q * math.log(1e3) / math.pi
    t, x = motion.pendulum(math.pi / q, OMEGA, 0.8, duration, 9999 / duration)
    rng = np.random.default_rng([seed, 7])
    return Record(source=f"Q{q}", t=t, x=x + rng.normal(0.0, noise, t.size))


def test_a_drag_the_bias_explains_is_left_out_of_the_start():
    """Q = 10, viscous only, noise 3e-3 rad: the averaged law fits a + b without misfit
    and its bias is predicted above a standard error, so the waveform fit runs; a, less
    its predicted bias, is within 2 noise standard errors, so that fit starts from b and
    ends at b, as it does from a + b."""
    record = _viscous_swing(10, 3e-3, 2)
    turning = find_turning_points(record.t, record.x)
    fit = fit_turning_points(turning, pendulum=True)
    error = _pendulum_law_error(record.t, turning, fit, False)
    assert fit.model == "ab" and error is not None and error.largest > 1
    start = _pendulum_start(fit, error)
    assert start.model == "b" and start.values == WaveformStart.of_fit(fit).values
    analysis = analyse_record(record, pendulum=True)
    assert analysis.fit.method == "waveform" and analysis.fit.model == "b"
    assert abs(analysis.fit.values["b"] - math.pi / 10) < 3 * analysis.fit.stderr["b"]


def test_where_the_law_misfits_the_start_is_the_nearest_of_its_models():
    """The bench's Q = 8 pendulum (viscous only): the law misfits (reduced chi-square 8,
    no chain run) and says a + b + c. The start is the model nearest the record among
    those a + b + c contains, b (b + c's c starts at 2e-10, and counts as a term), at the
    crests' frequency; from there the answer is the one from a + b + c."""
    from functools import partial

    from mcfit.fit.waveform import open_form

    t, x = q_record(8, "pendulum", 2026)
    turning = find_turning_points(t, x)
    fit = fit_turning_points(turning, pendulum=True)
    assert _pendulum_law_error(t, turning, fit, False) is None
    assert fit.model == "abc"
    start = _pendulum_start(fit, None)
    assert start.model is None
    assert set(start.among) == {"a", "b", "c", "ab", "ac", "bc", "abc"}
    assert start.omega == fit.omega
    fitted = partial(fit_waveform, t, x, turning, form="velocity", kind=PendulumWaveform)
    opened = open_form(t, x, turning, start, form="velocity", kind=PendulumWaveform)
    assert opened.first.model == "b"
    ours, theirs = fitted(start), fitted(WaveformStart.of_fit(fit))
    assert ours.model == theirs.model == "b"
    assert abs(ours.values["b"] - theirs.values["b"]) < 1e-3 * theirs.stderr["b"]


def test_where_the_chain_fails_the_start_is_the_fit_s_model():
    """A failed chain (infinite bias) or a term without a predicted bias starts from the
    fit's own model, not the candidate nearest the record."""
    t, x = q_record(8, "pendulum", 2026)
    fit = fit_turning_points(find_turning_points(t, x), pendulum=True)
    failed = ModelError(dict.fromkeys(fit.selection.terms, math.inf), math.inf, None, "chain")
    assert _pendulum_start(fit, failed).model == fit.model == "abc"
    # A term with no standard error has no predicted bias: no term is judged.
    incomplete = ModelError({"a": 1e3, "b": 0.0}, 1e3, None, "chain")
    assert _pendulum_start(fit, incomplete).model == fit.model


def _drag_swing(q, drag_share, noise, seed):
    """A pendulum released at 0.8 rad at ``q`` (of its first decay rate), ``drag_share``
    of that rate from quadratic drag and the rest viscous, as :func:`_viscous_swing`."""
    duration = q * math.log(1e3) / math.pi
    rate = OMEGA / (2 * q)
    kappa = drag_share * rate * 3 * math.pi / (4 * OMEGA * 0.8)
    t, x = motion.pendulum((1 - drag_share) * rate, OMEGA, 0.8, duration, 9999 / duration,
                           kappa=kappa)
    rng = np.random.default_rng([seed, 7])
    return Record(source=f"Q{q}", t=t, x=x + rng.normal(0.0, noise, t.size)), kappa


def test_a_real_drag_is_kept_and_found_from_a_start_without_it():
    """Q = 10 with 4 % of the rate from quadratic drag, noise 3e-3 rad: the drag (11
    standard errors in the answer) is not explained by the bias and stays in the start
    and the answer, kappa within 3 standard errors; a waveform fit started from b alone
    still finds it, within 0.1 standard error of the same values."""
    record, kappa = _drag_swing(10, 0.04, 3e-3, 2)
    turning = find_turning_points(record.t, record.x)
    fit = fit_turning_points(turning, pendulum=True)
    start = _pendulum_start(fit, _pendulum_law_error(record.t, turning, fit, False))
    assert "a" in start.model
    answer = analyse_record(record, pendulum=True).fit
    assert answer.method == "waveform" and answer.model == "ab"
    drag = answer.physical["kappa"]
    assert abs(drag["value"] - kappa) < 3 * drag["stderr"]

    x = _without_steady_line(record.t, record.x, turning.steady_line)
    from_b = fit_waveform(record.t, x, turning, replace(start, model="b"), form="velocity",
                          kind=PendulumWaveform)
    assert from_b.model == "ab"
    for k in "ab":
        assert abs(from_b.values[k] - answer.values[k]) < 0.1 * answer.stderr[k], k


@pytest.mark.parametrize("q, release, drag_share, coulomb_share, seed, noise", [
    (10, 1.2, 0.3, 0.1, 3, 1e-3), (15, 1.0, 0.2, 0.05, 4, 1.6e-3)])
def test_a_start_from_the_nearest_model_that_stops_short_is_fitted_from_the_law_s_too(
        q, release, drag_share, coulomb_share, seed, noise):
    """Viscous damping, quadratic drag and Coulomb friction (shares of the first decay
    rate): the law misfits and says a + b + c. From the nearest of its models, b + c,
    a + b + c is reached from an estimate and stops short: at Q = 10 at reduced
    chi-square 1.82, at Q = 15 within the noise (1.0004) but a 4.5 and b 6.4 standard
    errors off. The waveform fit is then started from the law's model too, and the
    better kept: a + b + c at 0.99 and 0.98, the drag within 3 standard errors."""
    from mcfit.bench.methods import record_duration

    duration, rate = min(record_duration(q), 60.0), OMEGA / (2 * q)
    kappa = drag_share * rate * 3 * math.pi / (4 * OMEGA * release)
    viscous = 2 * (1 - drag_share - coulomb_share) * rate
    t, x = motion.integrate(lambda x, v, _: viscous * v + kappa * v * abs(v), OMEGA,
                            release, duration, 9999 / duration,
                            mu=coulomb_share * rate * release * OMEGA / 2,
                            restoring=lambda x: OMEGA * OMEGA * math.sin(x))
    record = Record(source="drag and friction", t=t,
                    x=x + np.random.default_rng([seed, 7]).normal(0.0, noise, t.size))
    answer = analyse_record(record, pendulum=True).fit
    assert answer.method == "waveform" and answer.model == "abc"
    assert answer.reduced_chi_square < 1.05
    drag = answer.physical["kappa"]
    assert abs(drag["value"] - kappa) < 3 * drag["stderr"]
    assert abs(answer.values["b"] - viscous / 2) < 3 * answer.stderr["b"]
