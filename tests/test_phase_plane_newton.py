"""The amplitude form's Newton iterations compiled (mcfit.phase_plane_kernels: newton_step,
held_coefficients, newton_update): an evaluation gives the numbers numpy's step gave,
stored in tests/data/phase_plane_newton.npz; the step is numpy's solve and
multiple-shooting recursion, the bookkeeping and the iteration numpy's, on random sets."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from mcfit import phase_plane
from mcfit import phase_plane_kernels as kernels

OMEGA = 2 * math.pi
# x and changes of phase_plane_differences (every 100th of 10^4 samples, before the first
# stop of any set) and each set's stop, as numpy's solve and multiple-shooting recursion
# gave them (commit cf967c3): a call with a fresh memory, then one 1e-4 away from it.
REFERENCE = Path(__file__).with_name("data") / "phase_plane_newton.npz"
# Q, shares of the damping rate, theta0 (rad), cycles of the record.
CASES = [
    (2.0, {"b": 1.0}, 0.3, 8),
    (3.0, {"a": 0.3, "b": 0.7}, -0.4, 10),
    (5.3, {"a": 0.5, "b": 0.5}, 3.26, 20),
    (10.0, {"b": 1.0}, -0.4, 20),
    (20.0, {"a": 0.2, "b": 0.7, "c": 0.1}, 1.0, 30),
    (50.0, {"b": 1.0}, 0.0, 40),
    (2.0, {"b": 0.9, "c": 0.1}, 0.2, 8),
    (5.0, {"a": 0.2, "b": 0.7, "c": 0.1}, 7.0, 15),
    (8.0, {"b": 0.6, "c": 0.4}, 2.0, 20),
    (30.0, {"a": 0.6, "b": 0.2, "c": 0.2}, -2.5, 40),
    (3.0, {"c": 1.0}, 0.5, 10),
    (15.0, {"a": 1.0}, 0.1, 25),
]


def _arguments(q, shares, theta0, cycles):
    """Times (10^4 samples), a parameter set of amplitude 1 and its steps (1e-7 of each
    parameter in y0, theta0, omega and each damping term present)."""
    rate = OMEGA / (2 * q)
    p = np.array([1.0, theta0, OMEGA] + [rate * shares.get(k, 0.0) for k in "abc"])
    moved = [0, 1, 2] + [3 + "abc".index(k) for k in shares]
    steps = np.diag(1e-7 * np.maximum(np.abs(p), 1e-3))[moved]
    return np.linspace(0.0, cycles, 10_000), p, steps


def _stops(t, p, steps):
    """Each set's stop (start, amplitude, sign; inf where it swings on)."""
    sets = p[None, :] + np.vstack([np.zeros((1, 6)), steps])
    y0, theta0, omega, a, b, c = (sets[:, i:i + 1] for i in range(6))
    base = np.floor(theta0 / math.pi) * math.pi
    phi = theta0 - base
    first = phase_plane._first_solution(t[-1], y0, phi, omega, a, b, c, None, kernels)
    solved = phase_plane._chord(first, y0, phi, omega, a, b, c, kernels)
    return phase_plane._fine_nodes(solved, base, phi, omega, a, b, c, kernels)[-1]


@pytest.mark.parametrize("case", range(len(CASES)))
def test_the_differences_are_those_of_numpys_newton_step(case):
    """x and changes within 1e-12 of the amplitude of numpy's, with a fresh memory and
    started from the last solution; the stops to rounding."""
    reference = np.load(REFERENCE)
    t, p, steps = _arguments(*CASES[case])
    np.testing.assert_allclose(_stops(t, p, steps), reference[f"stops_{case}"],
                               rtol=1e-13, atol=0)
    samples = reference[f"samples_{case}"]
    memory = {}
    for call, scale in enumerate((1.0, 1.0 + 1e-4)):
        x, changes = phase_plane.phase_plane_differences(t, p * scale, steps, memory)
        found = np.vstack([x, changes])[:, samples]
        np.testing.assert_allclose(found, reference[f"values_{case}_{call}"], rtol=0,
                                   atol=1e-12 * p[0])


def _numpy_step(residual, d_slope, length):
    """The Newton step of :func:`kernels.newton_step` by numpy's solve of the stacked
    Jacobians and :func:`phase_plane._steps`."""
    jacobian = (np.eye(phase_plane.NODES)
                - length[..., None, None] * phase_plane._INTEGRATE * d_slope[..., None, :])
    jacobian = np.broadcast_to(jacobian, residual.shape + (residual.shape[-1],))
    own = np.linalg.solve(jacobian, -residual[..., None])[..., 0]
    carried = np.linalg.solve(jacobian, np.ones(residual.shape + (1,)))[..., 0]
    return phase_plane._steps(own, carried)


@settings(max_examples=60, deadline=None)
@given(sets=st.integers(1, 4), count=st.integers(1, 12), chord=st.booleans(),
       data=st.data())
def test_the_compiled_step_is_numpys_solve(sets, count, chord, data):
    """To rounding (1e-12 of the step), with one Jacobian a set or set 0's for all."""
    rows = 1 if chord else sets
    floats = st.floats(-1.0, 1.0)
    residual = data.draw(hnp.arrays(float, (sets, count, phase_plane.NODES), elements=floats))
    d_slope = data.draw(hnp.arrays(float, (rows, count, phase_plane.NODES), elements=floats))
    length = data.draw(hnp.arrays(float, (rows, count), elements=st.floats(0.1, math.pi)))
    found = kernels.newton_step(residual, d_slope, length, phase_plane._INTEGRATE_C)
    expected = _numpy_step(residual, d_slope, length)
    np.testing.assert_allclose(found, expected, rtol=0,
                               atol=1e-12 * max(np.max(np.abs(expected)), 1e-300))


@settings(max_examples=40, deadline=None)
@given(matrices=hnp.arrays(float, (3, 6, 6), elements=st.integers(-3, 3).map(float)),
       vectors=hnp.arrays(float, (3, 6), elements=st.integers(-9, 9).map(float)))
def test_the_elimination_solves_as_lapack(matrices, vectors):
    """Integer matrices with zeros on the diagonal, which need the row exchanges, side by
    side: each solution to rounding where the matrix is well conditioned (a singular one
    may meet a pivot of 0 or of rounding, here or in LAPACK); a second right-hand side
    twice the first, twice the solution."""
    augmented = np.ascontiguousarray(np.concatenate(
        [matrices, vectors[:, :, None], 2 * vectors[:, :, None]], axis=2).transpose(1, 2, 0))
    with np.errstate(all="ignore"):
        kernels._solve(augmented, 6)
    columns = augmented[:, 6:]
    np.testing.assert_array_equal(columns[:, 1], 2 * columns[:, 0])
    for h, (matrix, vector) in enumerate(zip(matrices, vectors)):
        if np.linalg.cond(matrix) < 1e8:
            found = columns[:, 0, h]
            np.testing.assert_allclose(matrix @ found, vector, rtol=0, atol=1e-12 * max(
                np.max(np.abs(np.linalg.solve(matrix, vector))), 1.0))


def test_a_zero_pivot_leaves_no_finite_solution():
    """A matrix with a column of zeros: the step is not finite, and the iteration gives
    it up (as numpy's solve raises)."""
    augmented = np.column_stack([np.diag([1.0, 0.0, 2.0]), np.ones(3)])[:, :, None]
    with np.errstate(all="ignore"):
        kernels._solve(augmented, 3)
    assert not np.any(np.isfinite(augmented[1:, 3]))


def _columns(q, shares, theta0):
    """Columns (1, 1) y0, phase from its multiple of pi, omega, a, b, c."""
    rate = OMEGA / (2 * q)
    p = [1.0, theta0 % math.pi, OMEGA] + [rate * shares.get(k, 0.0) for k in "abc"]
    return [np.array([[v]]) for v in p]


MIXES = [{"b": 1.0}, {"a": 0.5, "b": 0.5}, {"a": 0.2, "b": 0.7, "c": 0.1},
         {"b": 0.8, "c": 0.2}, {"a": 1.0}, {"c": 1.0}]


@settings(max_examples=30, deadline=None)
@given(q=st.floats(2.0, 50.0), mix=st.sampled_from(MIXES), share=st.floats(0.0, 1.0),
       theta0=st.floats(0.0, math.pi, exclude_max=True), cycles=st.floats(1.0, 12.0))
def test_the_compiled_iteration_is_numpys(q, mix, share, theta0, cycles):
    """All half-cycles at once, compiled and in numpy: the same outcome (converged or
    not), and where converged the same amplitudes, held half-cycles and start times to
    1e-13 (the tolerance is 1e-14 of the amplitude); the mix's terms weighted by
    ``share`` and its complement in the order drawn."""
    weights = {k: (share if i == 0 else 1.0 - share if i == 1 else 1.0) * v
               for i, (k, v) in enumerate(mix.items())}
    columns = _columns(q, weights, theta0)
    t_end = cycles
    count = int(np.ceil((OMEGA * t_end + theta0) / math.pi)) + 2
    found, expected = (phase_plane._all_half_cycles(count, t_end, *columns, kernels=k)
                       for k in (kernels, None))
    assert type(found) is type(expected)
    if isinstance(expected, tuple):
        for name, i in (("amplitudes", 0), ("held", 3), ("finished", 4), ("begins", 5)):
            np.testing.assert_allclose(found[i], expected[i], rtol=0, atol=1e-13,
                                       err_msg=name)


# A fit's step on a Q = 10 record with a Coulomb stop where the solve at once stalls
# (tests/test_phase_plane.py): y0, theta0, omega, a, b, c, and the record's end.
STALLING = (0.8898953888077809, 0.10225069729025771, 6.280018089189695,
            0.4129543922468894, 0.0, 0.06512139473247815)
T_END = 7.567746995559638


def test_the_compiled_iteration_gives_up_as_numpys():
    """A solve that stalls near a Coulomb stop, and one whose steps overflow from a
    start of 1e300: no solution, compiled or not."""
    columns = [np.array([[v]]) for v in STALLING]
    start = np.full((1, 18, phase_plane.NODES), 1e300)
    for guess in (None, start):
        for compiled in (kernels, None):
            with np.errstate(all="ignore"):
                assert phase_plane._all_half_cycles(18, T_END, *columns, guess=guess,
                                                    kernels=compiled) is None


def test_one_compiled_version_of_the_newton_kernels():
    """The iteration and the chord step call the step with arrays of one layout (another
    would cost a compilation in every new process)."""
    t, p, steps = _arguments(*CASES[4])
    phase_plane.phase_plane_differences(t, p, steps)
    assert len(kernels.newton_step.signatures) == 1, kernels.newton_step.signatures


@settings(max_examples=40, deadline=None)
@given(starts=hnp.arrays(float, (3, 10), elements=st.floats(0.0, 2.0)),
       first=st.sampled_from([0.0, 0.5]), terms=hnp.arrays(float, (3, 3),
                                                          elements=st.floats(0.0, 3.0)))
def test_the_compiled_held_half_cycles_are_numpys(starts, first, terms):
    """Held from the first stuck turning point on (none inside a first half-cycle that
    starts off one), and the coefficients 0 there: as :func:`phase_plane._held`."""
    amplitudes = np.repeat(starts[..., None], phase_plane.NODES, axis=2)
    start_phi = np.zeros((3, 10))
    start_phi[:, 0] = first
    omega = np.array([OMEGA, 2.0, 10.0])
    held, free = kernels.held_coefficients(amplitudes, start_phi, omega, terms)
    columns = [v[:, None] for v in (omega, *terms)]
    expected = phase_plane._held(starts, start_phi, *columns)
    np.testing.assert_array_equal(held, expected)
    np.testing.assert_array_equal(free, np.where(expected, 0.0, terms[:, :, None]))


@settings(max_examples=40, deadline=None)
@given(data=st.data(), sets=st.integers(1, 3), count=st.integers(1, 8),
       t_end=st.floats(0.0, 5.0))
def test_the_compiled_update_is_numpys(data, sets, count, t_end):
    """The step applied, and its largest change and amplitude over the half-cycles that
    are not held and start before ``t_end``, as numpy's iteration takes them; NaN where
    one of those is not finite."""
    shape = (sets, count, phase_plane.NODES)
    values = st.floats(-1.0, 1.0)
    amplitudes = data.draw(hnp.arrays(float, shape, elements=values))
    step = data.draw(hnp.arrays(float, shape, elements=st.one_of(values, st.just(np.inf))))
    held = data.draw(hnp.arrays(bool, (sets, count)))
    time_rate = data.draw(hnp.arrays(float, shape, elements=st.floats(0.05, 0.5)))
    length = data.draw(hnp.arrays(float, (sets, count), elements=st.floats(0.1, math.pi)))
    moved = amplitudes.copy()
    with np.errstate(invalid="ignore"):
        change, size = kernels.newton_update(moved, step, held, time_rate, length, t_end,
                                             phase_plane._INTEGRATE_C)
    np.testing.assert_array_equal(moved, amplitudes + step)
    begins = phase_plane._begins(length[..., None], time_rate, held)
    relevant = ~held & (begins < t_end)
    expected = [np.max(np.abs(v[relevant]), initial=0.0) for v in (step, moved)]
    if np.isfinite(sum(expected)):
        np.testing.assert_allclose([change, size], expected, rtol=1e-15, atol=0)
    else:
        assert math.isnan(change) and math.isnan(size)


def test_values_that_are_not_finite_come_back_bounded(monkeypatch):
    """A trial set that brings a swing to a standstill: NaN as 0, inf as 1e300."""
    t, p, steps = _arguments(*CASES[3])
    interpolated = kernels.hermite_changes

    def broken(*args):
        x, changes = interpolated(*args)
        x[:3] = [np.nan, np.inf, -np.inf]
        changes[0, 5] = np.nan
        return x, changes

    monkeypatch.setattr(kernels, "hermite_changes", broken)
    x, changes = phase_plane.phase_plane_differences(t, p, steps)
    np.testing.assert_array_equal(x[:3], [0.0, 1e300, -1e300])
    assert changes[0, 5] == 0.0 and np.all(np.isfinite(changes))
