"""The compiled final swings after a Coulomb stop (mcfit.swing_kernels): the same x and
changes as each set's own final swings in numpy (:func:`mcfit.phase_plane._final_swings`),
to rounding, and numba only where the Jacobian is needed."""

from __future__ import annotations

import math
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcfit import phase_plane
from process_tools import python_words

OMEGA = 2 * math.pi


def _parameters(q, share, mix, theta0=0.3):
    """y0 = 1, theta0, omega, a, b, c whose first decay rate c + b + a is omega/(2*q), a
    fraction ``share`` of it Coulomb's, the rest b's (or half a's for "abc"); and a
    duration that reaches the stop (a bound from b and c alone) and 3 periods more."""
    rate = OMEGA / (2 * q)
    c, rest = share * rate, (1 - share) * rate
    a, b = (rest / 2, rest / 2) if mix == "abc" else (0.0, rest)
    duration = math.log1p(b / c) / b + 3 * 2 * math.pi / OMEGA
    return np.array([1.0, theta0, OMEGA, a, b, c]), duration


def _steps(parameters):
    """Forward-difference steps of the non-zero parameters, 1e-8 of each (of 1 for the
    phase): the changes' second-order terms, where the compiled swings (first order)
    and each set's own differ, are then 1e-14 of y0 at most, 1e-12 at 1e-7."""
    size = 1e-8 * np.maximum(np.abs(parameters), np.array([0, 1, 0, 0, 0, 0]))
    return np.diag(size)[parameters != 0.0]


def _both(t, parameters, steps):
    """phase_plane_differences with the compiled swings (asserting it took them), and
    with each set's own final swings in numpy; the number of pieces swung."""
    calls, memory = [], {}
    compiled = phase_plane._neighbour_swings

    def counted(*args):
        calls.append(compiled(*args))
        return calls[-1]

    with mock.patch.object(phase_plane, "_neighbour_swings", counted):
        fast = phase_plane.phase_plane_differences(t, parameters, steps, memory)
    assert calls and calls[0] is not None  # a stop inside the record, swung as neighbours
    with mock.patch.object(phase_plane, "_neighbour_swings", lambda *args: None):
        each = phase_plane.phase_plane_differences(t, parameters, steps)
    return fast, each, len(memory["swings"])


# Q, Coulomb share, mix, and the pieces of swings after the stop.
CASES = [(2.0, 0.05, "bc", 4), (2.0, 0.3, "bc", 3), (3.0, 0.5, "bc", 2),
         (5.0, 0.1, "bc", 2), (10.0, 0.5, "bc", 2), (50.0, 0.4, "bc", 2),
         (2.0, 0.2, "abc", 3), (3.0, 0.3, "abc", 2), (5.0, 0.5, "abc", 2),
         (8.0, 0.1, "abc", 2), (20.0, 0.5, "abc", 2), (50.0, 0.2, "abc", 2)]


@pytest.mark.parametrize(("q", "share", "mix", "pieces"), CASES)
def test_the_swings_are_each_sets_own_to_rounding(q, share, mix, pieces):
    """x and the moved sets' changes within 1e-12 of y0 of each set's own final swings
    (they differ by 1e-14 of y0 and less: the changes' second order)."""
    parameters, duration = _parameters(q, share, mix)
    t = np.linspace(0.0, duration, 4001)
    (x, changes), (x_each, changes_each), swung = _both(t, parameters, _steps(parameters))
    assert swung == pieces
    assert np.max(np.abs(x - x_each)) <= 1e-12
    assert np.max(np.abs(changes - changes_each)) <= 1e-12
    assert np.min(np.max(np.abs(changes), axis=1)) > 1e-11  # every step moves x


@settings(max_examples=25, deadline=None)
@given(q=st.floats(2.0, 50.0), share=st.floats(0.05, 0.5),
       mix=st.sampled_from(["bc", "abc"]), theta0=st.floats(0.0, 2 * math.pi))
def test_random_decays_swing_as_each_set_alone(q, share, mix, theta0):
    """As above at random Q 2-50 and Coulomb shares 0.05-0.5 of the first decay rate."""
    parameters, duration = _parameters(q, share, mix, theta0)
    t = np.linspace(0.0, duration, 3001)
    (x, changes), (x_each, changes_each), _ = _both(t, parameters, _steps(parameters))
    assert np.max(np.abs(x - x_each)) <= 1e-12
    assert np.max(np.abs(changes - changes_each)) <= 1e-12


@pytest.mark.parametrize(("a", "b", "c", "amplitude", "sign", "reversals"), [
    (0.0, 0.95, 0.043, 0.285, 1.0, 4),
    (0.47, 0.27, 0.002, 0.197, 1.0, 10),
    (1.0, 0.5, 0.01, 0.1, -1.0, 7),
    (0.0, 0.6, 0.005, 0.04, 1.0, 6),
])
def test_several_reversals_are_each_sets_own_to_rounding(a, b, c, amplitude, sign,
                                                         reversals):
    """From a stop at rest with several swings before the mass is held, sets moved by
    1e-8 (stop time, amplitude, frequency, a, b, c): set 0's x and the others' changes
    within 1e-12 of the amplitude of each set's own final swings."""
    t = np.linspace(0.0, 8.0, 1601)
    base = np.array([3.0025, amplitude, OMEGA, a, b, c])  # between samples
    sets = base + np.vstack([np.zeros(6), 1e-8 * np.diag(base)[base != 0.0]])
    final = np.column_stack([sets[:, 0], sets[:, 1], np.full(len(sets), sign)])
    after = t >= base[0]
    memory = {}
    x, changes = phase_plane._neighbour_swings(t[after], final, *sets[:, 3:].T,
                                               sets[:, 2], memory)
    each = phase_plane._final_swings(t[after], final, *sets[:, 3:].T, sets[:, 2])
    assert np.sum(memory["swings"][:, 1] == 0.0) == reversals  # pieces started at rest
    assert np.max(np.abs(x - each[0])) <= 1e-12 * amplitude
    expected = np.array([values - each[0] for values in each[1:]])
    assert np.max(np.abs(changes - expected)) <= 1e-12 * amplitude
    assert np.min(np.max(np.abs(expected), axis=1)) > 1e-12


@pytest.mark.parametrize(("change", "neighbours"), [(1e-7, True), (1e-4, False)])
def test_a_set_far_from_set_0_is_no_neighbour(change, neighbours):
    """b moved by 1e-4: the sets swing and reverse alike, but the chord step of the
    ninth piece leaves residuals above 1e-3 of the step (it is no derivative), and the
    sets are swung on their own (None); by 1e-7 they are neighbours."""
    t = np.linspace(0.0, 8.0, 1601)
    final = np.array([[3.0, 0.285, 1.0], [3.0, 0.285, 1.0]])
    swung = phase_plane._neighbour_swings(t[t >= 3.0], final, np.zeros(2),
                                          np.array([0.95, 0.95 * (1 + change)]),
                                          np.full(2, 0.043), np.full(2, OMEGA))
    assert (swung is not None) == neighbours


def test_the_final_swings_load_numba_on_the_jacobians_path_only():
    """phase_plane_motion swings a stop in numpy; the Jacobian's differences load the
    kernels."""
    parameters, duration = _parameters(3.0, 0.3, "bc")
    code = (
        "import sys\n"
        "import numpy as np\n"
        "from mcfit import phase_plane\n"
        f"t, p = np.linspace(0, {duration!r}, 2001), np.array({parameters.tolist()!r})\n"
        "print(np.isfinite(phase_plane.phase_plane_motion(t, *p)).all(),"
        " 'numba' in sys.modules, 'mcfit.swing_kernels' in sys.modules)\n"
        "phase_plane.phase_plane_differences(t, p, 1e-7 * np.eye(6)[[0, 1, 2, 4, 5]])\n"
        "print('mcfit.swing_kernels' in sys.modules)\n")
    assert python_words(code) == ["True", "False", "False", "True"]


def test_the_compiled_swings_take_the_numpy_swings_constants():
    """The kernel's compiled-in copies of the pieces, iterations and grid are
    mcfit.phase_plane's."""
    from mcfit import phase_plane, swing_kernels

    assert swing_kernels._PIECES == phase_plane._SWING_PIECES
    assert swing_kernels._ITERATIONS == phase_plane._SWING_ITERATIONS
    assert swing_kernels._MAX_PIECES == phase_plane._MAX_PIECES
    assert swing_kernels._REVERSAL_ITERATIONS == phase_plane._REVERSAL_ITERATIONS
    assert swing_kernels._GRID + 1 == phase_plane._SWING_GRID.shape[0]
