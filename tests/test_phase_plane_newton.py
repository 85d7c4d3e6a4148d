"""The amplitude form's Newton iterations (mcfit.phase_plane's all-at-once solve and the
moved sets' chord step): the evaluation gives the numbers it gave before its step was
compiled, stored in tests/data/phase_plane_newton.npz."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

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
