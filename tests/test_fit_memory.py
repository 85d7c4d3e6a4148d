"""Memory of the turning-point fit on long records (issue 28: 10^7 samples with 10^6
cycles within 3 times the file's size): what a fit allocates per turning point."""

from __future__ import annotations

import gc
import tracemalloc
import weakref

import numpy as np
import pytest

from mcfit import decay
from mcfit.fit import candidates, fit_decay, uncertainty
from mcfit.fit.reported import lmfit_parameters, solve_reported
from mcfit.fit.problem import Problem, ScaledRecord


@pytest.fixture
def rng():
    return np.random.default_rng(28)


def _crests(n, rng):
    t = np.arange(n) * 0.5
    y = decay.amplitude(t, 1.0, 1e-6, 2e-5, 1e-7) + rng.normal(0.0, 1e-3, n)
    return t, y


def test_a_long_fit_allocates_under_300_bytes_a_turning_point(rng):
    """2*10^5 turning points: the peak allocated during the whole fit (every candidate,
    the report, Q and its error) was 490 bytes a point."""
    t, y = _crests(200_000, rng)
    fit_decay(t[:1000], y[:1000], period=1.0)  # imports and caches warm
    tracemalloc.start()
    try:
        fit = fit_decay(t, y, period=1.0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert fit.status == "ok"
    assert peak / t.size < 300


def test_a_problem_keeps_one_jacobian_and_gives_the_same_law(rng):
    t, y = _crests(500, rng)
    problem = Problem(ScaledRecord(t, y, np.full(t.size, 1e-3)), "bc")
    first, second = np.array([1.0, 0.02, 1e-4]), np.array([1.0, 0.021, 1e-4])
    jacobian = problem.law_jacobian(first).copy()
    problem.law_jacobian(second)
    assert sum(entry[2] is not None for entry in problem._cache.values()) == 1
    np.testing.assert_array_equal(problem.law_jacobian(first), jacobian)  # made again
    law = decay.amplitude_rows(problem.t, *problem.values(first))
    np.testing.assert_array_equal(problem.law(first), law.amplitude())
    np.testing.assert_array_equal(jacobian, law.jacobian())


def test_q_and_its_error_block_by_block_are_the_same(monkeypatch, rng):
    t = np.linspace(0.0, 50.0, 1001)
    values = {"y0": 1.0, "a": 0.01, "b": 0.02, "c": 0.001}
    covariance = np.diag([1e-6, 1e-8, 1e-8, 1e-10])
    arguments = (t, values, covariance, ("y0", "a", "b", "c"), 2 * np.pi, 1e-4)
    whole = uncertainty.q_with_stderr(*arguments)
    monkeypatch.setattr(uncertainty, "_BLOCK", 64)
    blocks = uncertainty.q_with_stderr(*arguments)
    np.testing.assert_array_equal(blocks[0], whole[0])
    np.testing.assert_array_equal(blocks[1], whole[1])
    assert uncertainty.q_with_stderr(t, values, None, ("y0",), 2 * np.pi)[1] is None


class _Line:
    """y = p0 + p1*t as a law of :mod:`mcfit.fit.reported`."""

    free = ("p0", "p1")
    chi_square_scale = 1.0

    def __init__(self, t, y):
        self.t, self.y = t, y

    def residual(self, x):
        return x[0] + x[1] * self.t - self.y

    def jacobian(self, x):
        return np.column_stack([np.ones_like(self.t), self.t])

    def covariance(self, x):
        return None


def test_the_reported_fit_frees_its_law_without_a_garbage_collection(rng):
    """lmfit's result and minimizer referred to each other: the law and the solver's
    Jacobian (200 MiB at 2x10^6 turning points) lived on until a full collection."""
    t = np.linspace(0.0, 1.0, 50)
    y = 0.5 + 2.0 * t + rng.normal(0.0, 1e-3, t.size)
    law = _Line(t, y)
    params = lmfit_parameters(law.free, [0.0, 1.0], [-np.inf] * 2, [np.inf] * 2)
    gone = weakref.ref(law)
    gc.disable()
    try:
        solution = solve_reported(law, params)
        del law
        assert gone() is None
    finally:
        gc.enable()
    np.testing.assert_allclose(solution.x, np.polyfit(t, y, 1)[::-1], rtol=1e-9)


def test_ranking_stopped_by_its_evaluation_limit_is_unconverged_and_silent(monkeypatch, rng):
    """Without full_output (no covariance, no copies of the Jacobian), leastsq warns where
    it stops at maxfev: the ranking reads its status instead, and says nothing."""
    t, y = _crests(400, rng)
    scaled = ScaledRecord(t, y, np.full(t.size, 1e-3))
    problem = Problem(scaled, "b")
    start = scaled.starting_values("b") * np.array([0.9, 1.0, 1.5, 1.0])
    monkeypatch.setattr(candidates, "_RANKING_EVALUATIONS", 2)
    solution, lowest, evaluations, left = candidates._levenberg_marquardt(problem, start)
    assert solution is None and not left
    assert evaluations >= 2 and np.isfinite(lowest)
    monkeypatch.setattr(candidates, "_RANKING_EVALUATIONS", 400)
    solution, *_ = candidates._levenberg_marquardt(problem, start)
    assert solution is not None


@pytest.mark.parametrize("terms", ["b", "abc"])
def test_weighting_in_place_leaves_the_kept_jacobian_as_it_was(terms, rng):
    t, y = _crests(300, rng)
    problem = Problem(ScaledRecord(t, y, rng.uniform(1e-3, 2e-3, t.size)), terms)
    x = np.array([1.0, 0.02, 1e-3, 1e-4])[: len(problem.free)]
    kept = problem.law_jacobian(x).copy()
    rows = problem.jacobian_rows(x)
    covariance = problem.covariance(x)
    gradient = problem.gradient(x)
    np.testing.assert_array_equal(problem.law_jacobian(x), kept)
    np.testing.assert_array_equal(rows, kept[problem.columns] * problem.solver_weights)
    weighted = kept[problem.columns] * problem.weights
    np.testing.assert_allclose(covariance, np.linalg.pinv(weighted @ weighted.T), rtol=1e-12)
    all_rows = kept * problem.solver_weights
    residual = (problem.law(x) - problem.y) * problem.solver_weights
    norms = np.linalg.norm(all_rows, axis=1) * np.linalg.norm(residual)
    np.testing.assert_allclose(gradient, all_rows @ residual / norms, rtol=1e-12)
