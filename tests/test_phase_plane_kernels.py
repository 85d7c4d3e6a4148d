"""The compiled loops of the amplitude form's evaluation (mcfit.phase_plane_kernels):
the interpolant and its changes against scipy's cubic Hermite splines, numba kept off
the turning-point path, and the compiled code's cache where folders are not writable."""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline

from mcfit import phase_plane
from mcfit import phase_plane_kernels as kernels
from mcfit.phase_plane_kernels import hermite_changes
from process_tools import python_words

OMEGA = 2 * math.pi
KERNELS = Path(phase_plane.__file__).with_name("phase_plane_kernels.py")


def _sets(q, shares, theta0):
    """Columns (m, 1) y0, phase from its multiple of pi, omega, a, b, c of a set and
    its moved sets, and that multiple of pi."""
    rate = OMEGA / (2 * q)
    p = np.array([1.0, theta0, OMEGA] + [rate * shares.get(k, 0.0) for k in "abc"])
    moved = [0, 1, 2] + [3 + "abc".index(k) for k in shares]
    sets = p + np.vstack([np.zeros(6), np.diag(1e-7 * np.maximum(np.abs(p), 1e-3))[moved]])
    y0, theta0, omega, a, b, c = (sets[:, i:i + 1] for i in range(6))
    base = np.floor(theta0 / math.pi) * math.pi
    return (y0, theta0 - base, omega, a, b, c), base


@pytest.mark.parametrize(("q", "shares", "theta0"), [
    (10.0, {"b": 1.0}, -0.4),
    (3.0, {"a": 0.2, "b": 0.7, "c": 0.1}, 7.0),
    (2.0, {"b": 0.9, "c": 0.1}, 0.2),  # held after a Coulomb stop
])
def test_the_compiled_newton_iterations_are_numpys(q, shares, theta0):
    """Newton's method on all half-cycles at once with the equations compiled and in
    numpy (which the motion without numba keeps): the same to its tolerance (1e-14 of
    the amplitude); and the moved sets' chord step from set 0's solution within 1e-6 of
    their changes solved on their own (the chord's error is of second order in 1e-7)."""
    sets, _ = _sets(q, shares, theta0)
    t_end = 4.0 * q
    count = int(np.ceil((OMEGA * t_end + sets[1][0, 0]) / math.pi)) + 2
    each = [[phase_plane._all_half_cycles(count, t_end, *(v[i:i + 1] for v in sets),
                                          kernels=compiled) for compiled in (kernels, None)]
            for i in range(len(sets[0]))]
    for compiled, numpy in each:
        for found, expected in zip(compiled[:-1], numpy[:-1]):
            np.testing.assert_allclose(found, expected, rtol=0,
                                       atol=1e-14 * np.max(np.abs(expected)))
    assert each[0][1][3].any() == ("c" in shares)  # held after a stop
    chord = phase_plane._chord(each[0][1], *sets, kernels)
    moved = np.concatenate([numpy[0] for _, numpy in each[1:]]) - each[0][1][0]
    scale = np.max(np.abs(moved), axis=(1, 2))
    error = np.max(np.abs(chord[0][1:] - chord[0][0] - moved), axis=(1, 2))
    assert np.all(error < 1e-6 * scale), error / scale


def _solved(q, shares, theta0, t_end):
    """The half-cycles of a parameter set and of its moved sets (steps of 1e-7 in y0,
    theta0, omega and each damping term), as :func:`phase_plane.phase_plane_differences`
    solves them, and the arguments of :func:`phase_plane._fine_nodes` after them."""
    sets, base = _sets(q, shares, theta0)
    first = phase_plane._first_solution(t_end, *sets, kernels=kernels)
    solved = phase_plane._chord(first, *sets, kernels)
    return solved, base, *sets[1:]


def _nodes(q, shares, theta0, t_end):
    """The nodes of the sets of :func:`_solved` (compiled) and their stops."""
    *nodes, final = phase_plane._fine_nodes(*_solved(q, shares, theta0, t_end), kernels)
    return nodes, final


@pytest.mark.parametrize(("q", "shares", "theta0"), [
    (10.0, {"b": 1.0}, -0.4),
    (3.0, {"a": 0.2, "b": 0.7, "c": 0.1}, 7.0),  # counted from 2*pi
    (2.0, {"b": 0.9, "c": 0.1}, 0.2),  # at rest after a Coulomb stop
])
def test_the_compiled_fine_nodes_are_numpys(q, shares, theta0):
    """The compiled nodes against numpy's (which the motion without numba keeps), to
    rounding: their differences between sets too, which the changes are made of."""
    arguments = _solved(q, shares, theta0, 4.0 * q)
    compiled = phase_plane._fine_nodes(*arguments, kernels)
    expected = phase_plane._fine_nodes(*arguments)
    np.testing.assert_array_equal(compiled[-1], expected[-1])  # the stops
    for found, values in zip(compiled[:-1], expected[:-1]):
        scale = np.max(np.abs(values))
        np.testing.assert_allclose(found, values, rtol=0, atol=1e-15 * scale)
        np.testing.assert_allclose(found[1:] - found[0], values[1:] - values[0], rtol=0,
                                   atol=2e-15 * scale)


def _spline_x(t, times, phases, amplitudes, phase_rates, amplitude_rates):
    """x of one set at ``t``: scipy's cubic Hermite spline of its phase and amplitude in
    each interval between distinct nodes; outside them, the state of the nearest end."""
    x = np.where(t < times[0], amplitudes[0] * np.cos(phases[0]),
                 amplitudes[-1] * np.cos(phases[-1]))
    for j in np.flatnonzero(np.diff(times) > 0):
        inside = (t >= times[j]) & (t < times[j + 1])
        ends = slice(j, j + 2)
        phase = CubicHermiteSpline(times[ends], phases[ends], phase_rates[ends])(t[inside])
        amplitude = CubicHermiteSpline(times[ends], amplitudes[ends],
                                       amplitude_rates[ends])(t[inside])
        x[inside] = amplitude * np.cos(phase)
    return x


@pytest.mark.parametrize(("q", "shares", "theta0"), [
    (10.0, {"b": 1.0}, -0.4),
    (3.0, {"a": 0.2, "b": 0.7, "c": 0.1}, 1.0),
    (2.0, {"b": 0.9, "c": 0.1}, 0.2),  # a Coulomb stop: nodes at rest after it
])
def test_the_interpolant_and_its_changes_are_scipys_splines(q, shares, theta0):
    """x of set 0 to rounding; each moved set's change within 1e-5 of the difference of
    its own spline and set 0's (the rounding of that difference; the first-order error
    is of the order of the 1e-7 steps), before the first stop of any set."""
    t = np.linspace(0.0, 4.0 * q, 4001)
    nodes, final = _nodes(q, shares, theta0, t[-1])
    x, changes = hermite_changes(t, *nodes)
    each = np.array([_spline_x(t, *(v[i] for v in nodes)) for i in range(len(nodes[0]))])
    np.testing.assert_allclose(x, each[0], rtol=0, atol=1e-14)
    before = t < np.min(final[:, 0])
    assert np.isfinite(final[0, 0]) == ("c" in shares)
    expected = (each[1:] - each[0])[:, before]
    scale = np.max(np.abs(expected), axis=1)[:, None]
    assert np.max(np.abs(changes[:, before] - expected) / scale) < 1e-5


def test_one_compiled_version_serves_every_layout():
    """Times as a strided view give the same numbers through the version compiled for
    contiguous arrays (another would cost a compilation in every new process)."""
    every = np.linspace(0.0, 20.0, 4001)
    parameters = np.array([1.0, 0.3, OMEGA, 0.05, 0.3, 0.01])
    steps = 1e-7 * np.eye(6)
    strided = phase_plane.phase_plane_differences(every[::2], parameters, steps)
    contiguous = phase_plane.phase_plane_differences(every[::2].copy(), parameters, steps)
    for found, expected in zip(strided, contiguous):
        np.testing.assert_array_equal(found, expected)
    for kernel in (kernels.hermite_changes, kernels.fine_nodes,
                   kernels.collocation_residuals):
        assert len(kernel.signatures) == 1, kernel.signatures


def test_numba_stays_off_the_turning_point_path():
    """A record that keeps the turning-point fit (Q about 160) is analysed without
    importing numba; the amplitude form's evaluation imports it."""
    code = (
        "import sys\n"
        "import numpy as np\n"
        "from mcfit.analysis import analyse_record\n"
        "from mcfit.motion import simulate_record\n"
        "record = simulate_record(0.0, 0.02, 0.002, 1.0, 1.0, 60.0, 100.0, noise=1e-3,"
        " rng=1)\n"
        "analysis = analyse_record(record)\n"
        "print(analysis.to_dict()['method'], 'mcfit.phase_plane' in sys.modules,"
        " 'numba' in sys.modules)\n"
        "from mcfit.phase_plane import phase_plane_differences\n"
        "phase_plane_differences(np.linspace(0, 5, 50), [1, 0, 6.3, 0, 0.1, 0],"
        " 1e-7 * np.eye(6))\n"
        "print('numba' in sys.modules)\n")
    assert python_words(code) == ["turning-points", "True", "False", "True"]


_RUN = (
    "import sys\n"
    "import numpy as np\n"
    "import phase_plane_kernels as kernels\n"
    "inputs = np.load(sys.argv[1])\n"
    "x, changes = kernels.hermite_changes(*(inputs[f'a{i}'] for i in range(6)))\n"
    "np.save(sys.argv[2], np.vstack([x, changes]))\n"
    "print(kernels.hermite_changes.stats.cache_hits.total(),"
    " kernels.hermite_changes.stats.cache_path)\n")


def _run_copy(folder, tmp_path, cache_home):
    """Run the kernel from a copy of its module in ``folder``, with the user's cache
    folder at ``cache_home``: its output and (cache hits, cache folder or None)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(PYTHONPATH=str(folder), HOME=str(cache_home), XDG_CACHE_HOME=str(cache_home),
               PYTHONDONTWRITEBYTECODE="1")
    out = tmp_path / "out.npy"
    result = subprocess.run([sys.executable, "-c", _RUN, str(tmp_path / "in.npz"), str(out)],
                            capture_output=True, text=True, env=env, check=True,
                            timeout=300, cwd=tmp_path)
    hits, path = result.stdout.split()
    return np.load(out), (int(hits), None if path == "None" else path)


def test_the_cache_falls_back_where_folders_are_not_writable(tmp_path):
    """The module's folder not writable (a file where its __pycache__ would be, which
    stops root too): cached in the user's cache folder and loaded from there by the
    next process; that one not writable either: compiled without a cache. The same
    numbers in each case."""
    t = np.linspace(0.0, 20.0, 2001)
    nodes, _ = _nodes(5.0, {"a": 0.3, "b": 0.7}, 0.5, t[-1])
    np.savez(tmp_path / "in.npz", **{f"a{i}": v for i, v in enumerate([t, *nodes])})
    expected = np.vstack(hermite_changes(t, *nodes))
    folder = tmp_path / "package"
    folder.mkdir()
    shutil.copy(KERNELS, folder)
    (folder / "__pycache__").write_text("not a folder")
    blocked = tmp_path / "blocked"
    blocked.write_text("not a folder")
    user = tmp_path / "cache"
    for home, hits, where in [(user, 0, user), (user, 1, user), (blocked / "cache", 0, None)]:
        found, (cache_hits, path) = _run_copy(folder, tmp_path, home)
        np.testing.assert_allclose(found, expected, rtol=1e-15, atol=0)
        assert cache_hits == hits
        assert (path is None) == (where is None)
        assert where is None or Path(path).is_relative_to(where)
    assert list(user.rglob("phase_plane_kernels.hermite_changes-*.nbi"))
