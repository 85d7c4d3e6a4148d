"""The phase-plane solution's Newton iterations: a solve that does not converge is given
up early and the fallback taken at once, with the same motion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcfit import phase_plane
from mcfit.motion import damping_terms, integrate_accurate

# Amplitude, phase, frequency, a, b, c of a fit's step on a Q = 10 record with a Coulomb
# stop, where Newton's method on all half-cycles at once creeps at a constant rate and
# stalls above its tolerance.
STALLING = (0.8898953888077809, 0.10225069729025771, 6.280018089189695,
            0.4129543922468894, 0.0, 0.06512139473247815)
T_END = 7.567746995559638
OMEGA = 2 * math.pi


def _counting(monkeypatch, name):
    calls = []
    original = getattr(phase_plane, name)

    def counted(*args, **kwargs):
        calls.append(args)
        return original(*args, **kwargs)

    monkeypatch.setattr(phase_plane, name, counted)
    return calls


def test_a_stalling_solve_is_given_up_early(monkeypatch):
    iterations = _counting(monkeypatch, "_steps")
    columns = [np.array([[v]]) for v in STALLING]
    assert phase_plane._all_half_cycles(18, T_END, *columns) is None
    assert len(iterations) <= phase_plane._STALLED + 2  # was 60


def test_the_fallback_keeps_the_motion_accurate():
    """The half-cycles one after the other, against a tight integration: within 1e-8 of
    the amplitude until the last swing before the stop (where the stop's own rule
    differs, by 6e-4 of the amplitude here)."""
    t = np.linspace(0.0, T_END, 1501)
    y0, theta0, omega, a, b, c = STALLING
    x = phase_plane.phase_plane_motion(t, *STALLING)[0]
    start = (y0 * math.cos(theta0), -omega * y0 * math.sin(theta0))
    expected = integrate_accurate(*start, omega, damping_terms(a, b, c), t, rtol=1e-13)
    before = t < expected.turning_times[-2]
    assert np.max(np.abs(x - expected.x)[before]) < 1e-8 * y0


def test_differences_skip_the_solve_at_once_after_a_failure(monkeypatch):
    """Where set 0 fails at once, its moved sets go one half-cycle after the other
    without another attempt; the changes are differences of the motion."""
    t = np.linspace(0.0, T_END, 1501)
    parameters = np.array(STALLING)
    steps = np.diag(1e-7 * np.maximum(np.abs(parameters), 1.0))[[0, 1, 2, 3, 5]]
    at_once = _counting(monkeypatch, "_all_half_cycles")
    x, changes = phase_plane.phase_plane_differences(t, parameters, steps, memory={})
    assert all(args[2].shape[0] == 1 for args in at_once)  # set 0 alone
    moved = phase_plane.phase_plane_motion(t, *(parameters + np.vstack([np.zeros(6),
                                                                        steps])).T)
    np.testing.assert_allclose(x, moved[0], atol=1e-13)
    np.testing.assert_allclose(changes, moved[1:] - moved[0], atol=1e-13)


@pytest.mark.parametrize(("a", "b", "c", "amplitude", "sign"), [
    (0.0, 0.3, 0.2, 0.1, -1.0),      # one swing, then held
    (0.0, 0.95, 0.043, 0.285, 1.0),  # several swings, the first longer than a half period
    (0.47, 0.27, 0.002, 0.197, 1.0),  # ten swings before the mass is held
    (0.0, 0.0, 0.3, 0.2, 1.0),       # Coulomb alone: held at once
])
def test_the_final_swings_match_a_tight_integration(a, b, c, amplitude, sign):
    """From a stop at rest, within 1e-9 of its amplitude of the event-locating DOP853
    integration at rtol 1e-13; each set of a batch as if alone."""
    t = np.linspace(0.0, 8.0, 1601)
    final = np.array([[3.0, amplitude, sign]])
    x = phase_plane._final_swings(t, final, np.array([a]), np.array([b]), np.array([c]),
                                  np.array([OMEGA]))[0]
    after = t >= 3.0
    expected = integrate_accurate(sign * amplitude, 0.0, OMEGA, damping_terms(a, b, c),
                                  t[after] - 3.0, rtol=1e-13).x
    assert np.max(np.abs(x - expected)) < 1e-9 * amplitude
    batch = phase_plane._final_swings(t, np.vstack([final, [[2.5, 0.15, 1.0]]]),
                                      np.array([a, 0.1]), np.array([b, 0.5]),
                                      np.array([c, 0.1]), np.array([OMEGA, 6.0]))
    np.testing.assert_allclose(batch[0], x, rtol=0, atol=1e-15)


@pytest.mark.parametrize(("a", "b", "c", "amplitude", "sign"), [
    (0.0, 0.3, 0.2, 0.1, -1.0),      # one swing, then held
    (0.0, 0.95, 0.043, 0.285, 1.0),  # several swings
    (0.47, 0.27, 0.002, 0.197, 1.0),  # ten swings before the mass is held
])
def test_neighbouring_final_swings_are_their_changes_to_first_order(a, b, c, amplitude,
                                                                    sign):
    """Sets moved by about 1e-7 (stop time, amplitude, frequency, a, b, c): set 0's x as
    :func:`phase_plane._final_swings` gives it, the others' changes within 1e-5 of the
    changes of their own final swings (the difference of two solutions, each accurate
    to its rounding)."""
    t = np.linspace(0.0, 8.0, 1601)
    steps = np.diag([1e-7, 1e-7, 1e-7, 1e-7, 1e-7, 1e-7])
    base = np.array([3.0025, amplitude, OMEGA, a, b, c])  # between samples
    sets = base + np.vstack([np.zeros(6), steps])
    final = np.column_stack([sets[:, 0], sets[:, 1], np.full(7, sign)])
    after = t >= 3.0025
    x, changes = phase_plane._neighbour_swings(t[after], final, *sets[:, 3:].T,
                                               sets[:, 2])
    each = phase_plane._final_swings(t[after], final, *sets[:, 3:].T, sets[:, 2])
    np.testing.assert_allclose(x, each[0], rtol=0, atol=1e-15)
    expected = np.array([values - each[0] for values in each[1:]])
    assert np.max(np.abs(changes - expected)) < 1e-5 * np.max(np.abs(expected))


def test_final_swings_of_another_kind_are_not_neighbours():
    """A set held a swing earlier than set 0 has no first-order change: None."""
    t = np.linspace(0.0, 8.0, 1601)
    final = np.array([[3.0, 0.285, 1.0], [3.0, 0.285, 1.0]])
    assert phase_plane._neighbour_swings(t[t >= 3.0], final, np.zeros(2),
                                         np.array([0.95, 0.95]), np.array([0.043, 0.3]),
                                         np.full(2, OMEGA)) is None


def test_final_swings_started_from_the_last_call_are_the_same():
    """The last swings of a stop, started from the last call's (``memory``), as from
    their own start."""
    t = np.linspace(0.0, 8.0, 1601)
    parameters = np.array([1.0, 0.2, OMEGA, 0.0, 1.2, 0.05])
    steps = 1e-7 * np.eye(6)[[0, 1, 2, 4, 5]]
    memory = {}
    phase_plane.phase_plane_differences(t, parameters * (1 + 1e-5), steps, memory)
    assert len(memory["swings"]) == 3  # three pieces of swings after the stop
    warm = phase_plane.phase_plane_differences(t, parameters, steps, memory)
    cold = phase_plane.phase_plane_differences(t, parameters, steps)
    np.testing.assert_allclose(warm[0], cold[0], rtol=0, atol=1e-14)
    np.testing.assert_allclose(warm[1], cold[1], rtol=0, atol=1e-14)


def test_sets_whose_swings_differ_in_kind_are_swung_one_by_one(monkeypatch):
    """Where the sets' final swings are not neighbours, each set's own (differences of
    the motion, as before)."""
    t = np.linspace(0.0, 8.0, 1601)
    parameters = np.array([1.0, 0.2, OMEGA, 0.0, 1.2, 0.05])
    steps = 1e-7 * np.eye(6)[[0, 1, 2, 4, 5]]
    fast = phase_plane.phase_plane_differences(t, parameters, steps)
    monkeypatch.setattr(phase_plane, "_neighbour_swings", lambda *args: None)
    x, changes = phase_plane.phase_plane_differences(t, parameters, steps)
    moved = phase_plane.phase_plane_motion(t, *(parameters + np.vstack([np.zeros(6),
                                                                        steps])).T)
    np.testing.assert_allclose(x, moved[0], rtol=0, atol=1e-13)
    np.testing.assert_allclose(x, fast[0], rtol=0, atol=1e-13)
    scale = np.max(np.abs(moved[1:] - moved[0]), axis=1)[:, None]
    assert np.max(np.abs(changes - (moved[1:] - moved[0])) / scale) < 1e-5
    assert np.max(np.abs(changes - fast[1]) / scale) < 1e-5


def test_a_step_as_large_as_its_parameter_is_solved_on_its_own():
    """A Coulomb coefficient of 1e-10 that is most of the friction near the stop, moved by
    2.5e-10 (the difference step's floor, from a random record's fit): a chord step from
    set 0 leaves large residuals (it ran off to 1e87), so every set is solved on its own
    and the changes are differences of the motion."""
    t = np.arange(359) * 6569.859235958306
    parameters = np.array([2.481, 3.215, 1.077e-4, 9.672e-11, 6.441e-6, 1e-10])
    steps = np.diag(1e-7 * np.maximum(np.abs(parameters),
                                      [2.5e-3, 1.0, 0.0, 4e-4, 1e-3, 2.5e-3]))
    x, changes = phase_plane.phase_plane_differences(t, parameters, steps, memory={})
    moved = phase_plane.phase_plane_motion(t, *(parameters + np.vstack([np.zeros(6),
                                                                        steps])).T)
    np.testing.assert_allclose(x, moved[0], rtol=0, atol=1e-13)
    expected = moved[1:] - moved[0]
    assert np.max(np.abs(changes - expected)) < 1e-9 * np.max(np.abs(expected))
