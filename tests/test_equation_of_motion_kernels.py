"""The compiled integrator of the equation of motion: against the closed form and an
independent tight solve from Q = 1.5 to 100, its dense output, its failures, where numba
is loaded and how its cache falls back."""

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

import mcfit
import mcfit.equation_of_motion as equation_of_motion
from mcfit.bench.reference_motion import integrate
from mcfit.equation_of_motion import PARAMETERS, motion_with_sensitivities
from mcfit.viscous_motion import viscous_motion_jacobian
from process_tools import python_words
from test_equation_of_motion import _central_differences

OMEGA = 2 * math.pi
QS = [1.5, 5.0, 20.0, 100.0]


def _beta(q):
    return OMEGA / (2 * q)


@pytest.mark.parametrize("q", QS)
@pytest.mark.parametrize("c", [0.0, 0.004])
def test_motion_and_sensitivities_are_the_closed_form(q, c):
    """Viscous damping with and without sliding friction (stopping inside the record at
    low Q): x within 1e-9 of y0 and each derivative within 1e-7 of its column's size, the
    closed form's derivatives being by c = 2*mu/(pi*omega) at fixed c."""
    t = np.arange(0.0, 12.0, 0.005)
    y0, theta0, beta, mu = 0.8, 0.4, _beta(q), 0.5 * math.pi * OMEGA * c
    wanted = PARAMETERS if c else PARAMETERS[:5]  # without friction: in one piece
    x, sensitivities = motion_with_sensitivities(t, y0, theta0, OMEGA, beta, 0.0, mu,
                                                 rtol=1e-11, wanted=wanted)
    expected, by = viscous_motion_jacobian(t, y0, theta0, OMEGA, beta, c)
    by_mu = by[4] * 2 / (math.pi * OMEGA)
    # At fixed mu, c = 2*mu/(pi*omega) moves with omega.
    columns = [by[0], by[1], by[2] - by[4] * c / OMEGA, by[3], None, by_mu]
    assert np.max(np.abs(x - expected)) < 1e-9 * y0
    for j, column in enumerate(columns):
        if column is None:  # kappa: no closed form
            continue
        if j == 5 and not c:
            assert np.all(np.isnan(sensitivities[:, j]))
            continue
        assert np.max(np.abs(sensitivities[:, j] - column)) < 1e-7 * np.max(np.abs(column)), \
            PARAMETERS[j]


@pytest.mark.parametrize("q", QS)
@pytest.mark.parametrize("mu", [0.0, 0.3])
@pytest.mark.parametrize("pendulum", [False, True])
def test_drag_friction_and_a_large_swing_match_an_independent_dop853_solve(q, mu, pendulum):
    """All three forces (the mass stops inside the record where mu > 0 and Q is low), a
    pendulum released at 2.5 rad: within 1e-8 rad of the reference (scipy's DOP853 at
    rtol 1e-12 between reversals located as events, mcfit.bench.reference_motion)."""
    y0, beta, kappa = 2.5 if pendulum else 1.2, _beta(q), 0.2
    restoring = (lambda x: OMEGA**2 * math.sin(x)) if pendulum else None
    t, expected = integrate(lambda _, v, __: 2 * beta * v + kappa * v * abs(v), OMEGA, y0,
                            15.0, 100.0, mu=mu, restoring=restoring)
    x, sensitivities = motion_with_sensitivities(
        t, y0, 0.0, OMEGA, beta, kappa, mu, restoring="pendulum" if pendulum else "linear",
        rtol=1e-12)
    assert np.max(np.abs(x - expected)) < 1e-8
    assert np.all(np.isfinite(sensitivities[:, :5]))


@pytest.mark.parametrize("q", [1.5, 100.0])
@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_the_sensitivities_of_a_large_swing_are_the_derivatives_of_the_motion(q, mu):
    """A pendulum from 2.5 rad with all three forces, against central differences: each
    column within 1e-4 of its size, across the reversals' jumps."""
    t = np.arange(0.0, 8.0, 0.01)
    p = np.array([2.5, 0.3, OMEGA, _beta(q), 0.2, mu])
    _, sensitivities = motion_with_sensitivities(t, *p, restoring="pendulum", rtol=1e-12)
    expected = _central_differences(t, p, "pendulum")
    for j in range(p.size):
        size = np.max(np.abs(expected[:, j]))
        assert np.max(np.abs(sensitivities[:, j] - expected[:, j])) < 1e-4 * size, \
            PARAMETERS[j]


@pytest.mark.parametrize("mu", [0.0, 0.2])
def test_samples_come_from_the_dense_output_not_from_steps_onto_them(mu):
    """The steps do not depend on where the samples are: the motion at every 37th sample
    (and the last) is the same as in the run at every sample."""
    t = np.linspace(0.0, 20.0, 4001)
    every = motion_with_sensitivities(t, 1.0, 0.2, OMEGA, 0.1, 0.3, mu)
    some = np.r_[np.arange(0, t.size - 1, 37), t.size - 1]
    few = motion_with_sensitivities(t[some], 1.0, 0.2, OMEGA, 0.1, 0.3, mu)
    np.testing.assert_allclose(few[0], every[0][some], rtol=0, atol=1e-14)
    np.testing.assert_allclose(few[1], every[1][some], rtol=0, atol=1e-13)


def test_too_many_steps_leave_nan_from_where_the_integration_stopped(monkeypatch):
    t = np.linspace(0.0, 20.0, 2001)
    full, _ = motion_with_sensitivities(t, 1.0, 0.0, OMEGA, 0.1, 0.3, 0.1)
    monkeypatch.setattr(equation_of_motion, "_STEPS", 100)
    monkeypatch.setattr(equation_of_motion, "_STEPS_PER_CYCLE", 0)
    x, sensitivities = motion_with_sensitivities(t, 1.0, 0.0, OMEGA, 0.1, 0.3, 0.1)
    lost = np.isnan(x)
    assert 0 < np.argmax(lost) < t.size and np.all(lost[np.argmax(lost):])
    assert np.all(np.isnan(sensitivities[lost])) and np.all(np.isfinite(sensitivities[~lost]))
    np.testing.assert_array_equal(x[~lost], full[~lost])


def test_a_record_that_keeps_its_turning_points_does_not_load_numba(tmp_path):
    """A high-Q linear record (auto keeps the turning-point fit) and no numba; integrating
    a motion then loads it. The record is made here: its closed form is compiled."""
    t = np.arange(0.0, 40.0, 0.01)
    x = viscous_motion_jacobian(t, 1.0, 0.0, 6.283, 0.01, 0.002)[0]
    np.save(tmp_path / "x.npy", x + np.random.default_rng(7).normal(0.0, 1e-4, t.size))
    code = f"""
import sys
import numpy as np
from mcfit.api import analyse
t = np.arange(0.0, 40.0, 0.01)
x = np.load({str(tmp_path / "x.npy")!r})
print(analyse(t, x).fit.method, "numba" in sys.modules)
from mcfit.equation_of_motion import motion_with_sensitivities
motion_with_sensitivities(t[:10], 1.0, 0.0, 6.283, 0.1)
print("numba" in sys.modules)
"""
    assert python_words(code) == ["turning-points", "False", "True"]


MOTION = """
import numpy as np
from mcfit.equation_of_motion import motion_with_sensitivities
import mcfit.equation_of_motion_kernels as kernels
t = np.linspace(0.0, 10.0, 1001)
x, s = motion_with_sensitivities(t, 1.2, 0.0, 6.283, 0.1, 0.3, 0.4, restoring="pendulum")
compiled = [f for f in vars(kernels).values() if hasattr(f, "signatures")]
print(repr(float(x[-1])), repr(float(s[-1, 2])), type(kernels._integrate._cache).__name__,
      sum(kernels._integrate.stats.cache_hits.values()),
      max(len(f.signatures) for f in compiled))
"""


def _expected():
    x, s = motion_with_sensitivities(np.linspace(0.0, 10.0, 1001), 1.2, 0.0, 6.283, 0.1, 0.3,
                                     0.4, restoring="pendulum")
    return [repr(float(x[-1])), repr(float(s[-1, 2]))]


@pytest.fixture
def read_only_package(tmp_path):
    """A copy of the package whose folder numba cannot write its cache into (read-only,
    and with a file where ``__pycache__`` would be, which stops root too)."""
    copy = tmp_path / "site" / "mcfit"
    shutil.copytree(Path(mcfit.__file__).parent, copy,
                    ignore=shutil.ignore_patterns("__pycache__"))
    (copy / "__pycache__").write_text("not a folder")
    folders = [copy, *(p for p in copy.rglob("*") if p.is_dir())]
    for folder in folders:
        folder.chmod(0o555)
    yield copy.parent
    for folder in folders:
        folder.chmod(0o755)


@pytest.mark.slow
def test_without_any_writable_cache_folder_it_compiles_and_agrees(read_only_package,
                                                                   tmp_path):
    blocked = tmp_path / "blocked"
    blocked.write_text("a file, so nothing can be created under it")
    out = python_words(MOTION, PYTHONPATH=str(read_only_package), PYTHONDONTWRITEBYTECODE="1",
               NUMBA_CACHE_DIR=str(blocked / "numba"), HOME=str(blocked / "home"),
               XDG_CACHE_HOME=str(blocked / "cache"))
    assert out[:2] == _expected() and out[2] == "NullCache"
    assert out[4] == "1"  # each kernel compiled once, not again for literal arguments


@pytest.mark.slow
def test_a_read_only_package_caches_in_the_users_folder(read_only_package, tmp_path):
    cache = tmp_path / "cache"
    environment = {"PYTHONPATH": str(read_only_package), "PYTHONDONTWRITEBYTECODE": "1",
                   "XDG_CACHE_HOME": str(cache), "HOME": str(tmp_path)}
    environment = {**environment, "NUMBA_CACHE_DIR": ""}
    first, again = python_words(MOTION, **environment), python_words(MOTION, **environment)
    assert first[:2] == again[:2] == _expected()
    assert first[2] == again[2] == "FunctionCache" and first[3] == "0" and again[3] != "0"
    assert list((cache / "numba").rglob("*_integrate*.nbi"))


@pytest.mark.parametrize("restoring", ["linear", "pendulum"])
def test_at_a_fits_tolerance_the_motion_is_smooth_in_the_parameters(restoring):
    """At rtol 1e-9, central differences of steps 1e-6 of each parameter are its
    sensitivity within 1e-5 of the column's size: the integration error does not jump
    with the parameters (a step across a reversal sees no kink of the drag)."""
    t = np.arange(0.0, 6.0, 0.01)
    p = np.array([1.2, 0.3, OMEGA, 0.1, 0.4, 0.8])
    _, sensitivities = motion_with_sensitivities(t, *p, restoring=restoring, rtol=1e-9)
    for j in range(p.size):
        up, down = p.copy(), p.copy()
        up[j] += 1e-6 * p[j]
        down[j] -= 1e-6 * p[j]
        expected = (motion_with_sensitivities(t, *up, restoring=restoring, rtol=1e-9)[0]
                    - motion_with_sensitivities(t, *down, restoring=restoring, rtol=1e-9)[0]
                    ) / (2e-6 * p[j])
        size = np.max(np.abs(expected))
        assert np.max(np.abs(sensitivities[:, j] - expected)) < 1e-5 * size, PARAMETERS[j]


def test_a_tolerance_of_zero_ends_the_integration_in_nan_not_an_exception():
    """No step meets rtol = atol = 0 (the error's scale is 0): NaN after the start, as
    LSODA's refusal gave."""
    x, sensitivities = motion_with_sensitivities(np.linspace(0.0, 2.0, 5), 1.0, 0.0, OMEGA,
                                                 0.1, rtol=0.0)
    assert x[0] == 1.0 and np.all(np.isnan(x[1:])) and np.all(np.isnan(sensitivities[1:]))


def test_a_span_shorter_than_a_step_fills_its_last_sample():
    """The last step ends at the last sample exactly: t + h had rounded one unit below
    it on this span (a third of a cycle), and the last sample came back NaN."""
    times = np.array([0.0, 0.07154878711979673, 0.10384364177076476])
    x, sensitivities = motion_with_sensitivities(
        times, 1.0, -0.18129172773416047, OMEGA, 0.023888813978811707, 0.0,
        0.06556315241841992, rtol=7.208507599473106e-08)
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(sensitivities[:, :4]))
    dense = motion_with_sensitivities(np.linspace(0.0, times[-1], 50), 1.0,
                                      -0.18129172773416047, OMEGA, 0.023888813978811707,
                                      0.0, 0.06556315241841992, rtol=1e-12)[0]
    assert abs(x[-1] - dense[-1]) < 1e-6


@pytest.mark.parametrize("turns", [1, 2, 3])
def test_a_start_on_a_trough_takes_the_forward_phase_derivative(turns):
    """theta0 a multiple of pi with friction: sin(theta0) is 1e-16, not 0; the motion
    starts at rest, and dx/dtheta0 is the forward difference's (the waveform fit steps
    forward from there), as the closed form's; a velocity of -1e-16 had made it the
    backward one, 10 % off."""
    t = np.linspace(0.0, 5.0, 2001)
    theta0 = turns * math.pi
    x, sensitivities = motion_with_sensitivities(t, 1.0, theta0, OMEGA, 0.3, 0.0, 2.0,
                                                 rtol=1e-12)
    step = 1e-7
    forward = (motion_with_sensitivities(t, 1.0, theta0 + step, OMEGA, 0.3, 0.0, 2.0,
                                         rtol=1e-12)[0] - x) / step
    scale = np.max(np.abs(forward))
    assert np.max(np.abs(sensitivities[:, 1] - forward)) < 1e-6 * scale
    closed = viscous_motion_jacobian(t, 1.0, theta0, OMEGA, 0.3, 4.0 / (math.pi * OMEGA))[1]
    assert np.max(np.abs(sensitivities[:, 1] - closed[1])) < 1e-6 * scale
