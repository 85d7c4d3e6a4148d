"""The pendulum's averaged amplitude law and its sensitivities (mcfit.fit.pendulum,
docs/theory.md section 6), solved by quadrature of the autonomous law, against a tight
integration of the law with its sensitivity equations; the geometric factors against
mpmath's elliptic integrals; and the fits on pendulum records against the answers the
integrated law gave (tests/data/pendulum_law_answers.json, made at commit 64f7dc8).
"""

import json
import math
from pathlib import Path

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from mcfit.fit.pendulum import _amplitude_solution, _rate_terms, geometric_factors

ANSWERS = Path(__file__).parent / "data" / "pendulum_law_answers.json"
# Times of the turning points over the span (the fit's time unit), half-cycles apart.
SPAN = np.linspace(0.0, 1.0, 61)


def _slope(theta):
    """d(h0, h1, h2)/dtheta by a five-point difference, its step a thousandth of the
    distance to 0 or pi (where the terms are singular): error about 1e-12."""
    step = 1e-3 * min(max(theta, 1e-2), math.pi - theta)
    return (8 * (_rate_terms(theta + step) - _rate_terms(theta - step))
            - (_rate_terms(theta + 2 * step) - _rate_terms(theta - 2 * step))) / (12 * step)


def _reference(t, y0, a, b, c):
    """theta0 and d theta0/d(y0, a, b, c) by integrating dtheta/dt = -F(theta) and its
    sensitivity equations (DOP853, rtol 1e-12), stopped where theta reaches 0."""
    coefficients = np.array([c, b, a])

    def rhs(_, state):
        theta = max(state[0], 0.0)
        h = _rate_terms(theta)
        out = np.empty_like(state)
        out[0] = -float(coefficients @ h)
        out[1:] = -float(coefficients @ _slope(theta)) * state[1:]
        out[2:] -= h[::-1]  # d/da, d/db, d/dc
        return out

    def stopped(_, state):
        return state[0]
    stopped.terminal, stopped.direction = True, -1

    solution = integrate.solve_ivp(rhs, (0.0, t[-1]), [y0, 1.0, 0.0, 0.0, 0.0],
                                   method="DOP853", t_eval=t, events=stopped, rtol=1e-12,
                                   atol=1e-15 * y0)
    theta, jacobian = np.zeros(t.size), np.zeros((t.size, 4))
    theta[:solution.t.size] = solution.y[0]
    jacobian[:solution.t.size] = solution.y[1:].T
    return np.maximum(theta, 0.0), jacobian, solution.t_events[0]


def _assert_matches_reference(t, y0, a, b, c):
    """theta0 within 1e-9 of y0, and each sensitivity column times its parameter's natural
    size (the change that moves theta0 by about itself over the span) too."""
    theta, jacobian = _amplitude_solution(t, y0, a, b, c)
    reference, reference_jacobian, stops = _reference(t, y0, a, b, c)
    end = t[-1]
    sizes = np.array([y0, 1.0 / (y0 * end), 1.0 / end, y0 / end])
    assert np.max(np.abs(theta - reference)) <= 1e-9 * y0
    assert np.max(np.abs((jacobian - reference_jacobian) * sizes)) <= 1e-9 * y0
    theta_only, _ = _amplitude_solution(t, y0, a, b, c, sensitivities=False)
    assert np.max(np.abs(theta_only - theta)) <= 1e-10 * y0
    return stops


# (y0, a, b, c) per span: b = 12.6 is Q = 2 over 8 cycles, 0.38 Q = 500 over 60 cycles.
CASES = [
    (0.8, 0.0, 12.6, 0.0), (0.8, 0.0, 3.0, 0.0), (0.8, 0.0, 0.38, 0.0),
    (0.05, 0.0, 12.6, 0.0), (3.0, 0.0, 2.0, 0.0), (1.4, 0.0, 0.38, 0.0),
    (0.8, 2.0, 0.0, 0.0), (3.0, 20.0, 0.0, 0.0), (0.05, 300.0, 0.0, 0.0),
    (0.8, 0.0, 0.0, 0.5), (2.5, 0.0, 0.0, 0.3),
    (0.8, 0.3, 0.5, 0.2), (1.5, 1.0, 2.0, 0.05), (2.5, 0.01, 0.01, 0.001),
    (0.8, 0.0, 5.0, 1e-4), (0.8, 0.0, 12.6, 1e-3), (3.09, 0.5, 1.0, 0.3),
]


@pytest.mark.parametrize("y0, a, b, c", CASES)
def test_amplitude_law_matches_a_tight_integration(y0, a, b, c):
    _assert_matches_reference(SPAN, y0, a, b, c)


@pytest.mark.parametrize("y0, a, b, c", [(0.8, 0.0, 0.0, 1.0), (1.5, 1.0, 2.0, 0.5),
                                         (2.0, 0.001, 0.0, 3.0), (0.05, 0.0, 1.0, 0.1)])
def test_coulomb_friction_stops_the_swing_inside_the_span(y0, a, b, c):
    [stop] = _assert_matches_reference(SPAN, y0, a, b, c)
    # Just before and after the stop: still moving, then 0 with no sensitivity.
    t = np.array([0.0, stop * (1 - 1e-6), stop * (1 + 1e-6), 1.0])
    theta, jacobian = _amplitude_solution(t, y0, a, b, c)
    assert 0 < theta[1] < 1e-5 * y0 and np.all(theta[2:] == 0)
    assert np.array_equal(_amplitude_solution(SPAN, y0, a, b, c)[0] == 0, SPAN > stop)
    assert np.all(jacobian[2:] == 0) and np.all(jacobian[1] != 0)


def test_a_swing_at_rest_and_a_zero_amplitude():
    theta, jacobian = _amplitude_solution(np.zeros(3), 0.8, 1.0, 2.0, 0.3)
    assert np.all(theta == 0.8) and np.array_equal(jacobian, np.tile([1.0, 0, 0, 0], (3, 1)))
    theta, jacobian = _amplitude_solution(SPAN, 0.0, 1.0, 2.0, 0.3)
    assert np.all(theta == 0) and np.array_equal(jacobian[:, 0], SPAN == 0)
    assert np.all(jacobian[:, 1:] == 0)


@pytest.mark.parametrize("a, b, c", [(0.0, 0.0, 0.0), (1e-300, 0.0, 0.0), (0.0, 1e-14, 0.0),
                                     (0.0, 0.0, 1e-200)])
def test_without_damping_the_amplitude_stays(a, b, c):
    """No damping, or next to none (no overflow of 1/F**2 either): theta0 = y0 - F(y0)*t,
    the sensitivities -h*t."""
    theta, jacobian = _amplitude_solution(SPAN, 1.2, a, b, c)
    h = _rate_terms(1.2)
    assert np.allclose(theta, 1.2, rtol=1e-13, atol=0) and np.all(jacobian[:, 0] == 1)
    assert np.allclose(jacobian[:, 1:], -SPAN[:, None] * h[::-1], rtol=1e-15, atol=0)


@pytest.mark.parametrize("y0, a, b, c", [(0.8, 0.0, -0.1, 0.0), (1.0, -0.05, 0.3, 0.1)])
def test_negative_coefficients_are_integrated_as_before(y0, a, b, c):
    """Outside the fits' bounds the law is integrated as an ODE; a swing that grows."""
    _assert_matches_reference(SPAN, y0, a, b, c)


@settings(deadline=None, max_examples=12)
@given(y0=st.floats(0.05, 3.0), q=st.floats(2.0, 500.0), cycles=st.integers(8, 60),
       mix=st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
       absent=st.sampled_from(["", "a", "b", "c", "ab", "bc", "ac"]))
def test_amplitude_law_matches_a_tight_integration_for_any_damping(y0, q, cycles, mix,
                                                                   absent):
    """A rate of about pi/Q per cycle over the span, shared among the terms in any mix; at
    most 4*Q cycles (e**-12.6 at small angles): below about 1e-15 of y0 the reference
    integration's own error may take the swing to 0 and stop it."""
    rate = math.pi / q * min(cycles, 4 * q)
    weights = np.array([0.0 if name in absent else w for name, w in zip("abc", mix)])
    if not weights.sum() > 0:
        weights = np.array([0.0, 1.0, 0.0])
    a, b, c = rate * weights / weights.sum() * np.array([1 / y0, 1.0, y0])
    _assert_matches_reference(SPAN, y0, a, b, c)


@pytest.mark.parametrize("theta0", [1e-3, 0.019, 0.021, 0.3, 1.0, 2.0, 3.1])
def test_geometric_factors_match_the_elliptic_integrals(theta0):
    """The closed forms of the module's docstring in 40-digit arithmetic (mpmath)."""
    mpmath.mp.dps = 40
    theta = mpmath.mpf(theta0)
    m = mpmath.sin(theta / 2) ** 2
    big_k, big_e, s = mpmath.ellipk(m), mpmath.ellipe(m), mpmath.sin(theta)
    expected = [mpmath.pi * theta / (2 * big_k * s),
                8 * (big_e - (1 - m) * big_k) / (big_k * theta * s),
                3 * mpmath.pi * (s - theta * mpmath.cos(theta)) / (2 * big_k * theta**2 * s)]
    tolerance = 1e-9 if theta0 < 0.02 else 1e-14  # the series below 0.02 rad
    for value, exact in zip(geometric_factors(theta0), expected):
        assert float(value) == pytest.approx(float(exact), rel=tolerance)


def _records():
    """The records of the answers: Q = 3 at 0.8 rad, 10**4 samples; the edges' pendulum
    scenes fitted with the correction (Q = 50 at 0.8 and 1.4 rad), two seeds each."""
    from mcfit.bench import reference_motion as motion
    from mcfit.bench.edges import EDGE_SCENES, noisy_record, scene_key
    from mcfit.record import Record

    omega = 2 * math.pi
    t, x = motion.pendulum(omega / 6, omega, 0.8, 12.0, 10000 / 12.0)
    yield "Q3", Record("p", t, x + 1e-4 * np.random.default_rng(1).standard_normal(x.size))
    for scene in (s for s in EDGE_SCENES if s.pendulum):
        clean = scene.make()
        for index in range(2):
            yield f"{scene.name} #{index}", noisy_record(scene, clean,
                                                         [2026, scene_key(scene), index])


def _assert_same_fit(fit, answer):
    assert fit.model == answer["model"]
    assert list(fit.warnings) == answer["warnings"]
    for name, stderr in answer["stderr"].items():
        if stderr is None:
            assert fit.stderr.get(name) is None and fit.values[name] == answer["values"][name]
        else:
            assert abs(fit.values[name] - answer["values"][name]) <= 1e-4 * stderr
            assert fit.stderr[name] == pytest.approx(stderr, rel=1e-4)


@pytest.mark.slow
def test_pendulum_fits_give_the_answers_of_the_integrated_law():
    from mcfit.analysis import analyse_record, fit_turning_points

    answers = json.loads(ANSWERS.read_text())["records"]
    names = []
    for name, record in _records():
        analysis = analyse_record(record, pendulum=True)
        _assert_same_fit(analysis.fit, answers[name]["analysis"])
        _assert_same_fit(fit_turning_points(analysis.turning, pendulum=True),
                         answers[name]["turning_points"])
        names.append(name)
    assert names == list(answers)
