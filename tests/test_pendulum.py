"""The pendulum's amplitude law at large swings (mcfit.fit.pendulum, docs/theory.md section 6).

The geometric factors are checked against quadratures of the exact swing; the fit against
records from a tight integration of theta'' + 2*beta*theta' + kappa*theta'*|theta'|
+ w0**2 sin(theta) = 0, fed through find_turning_points as the command line does.
"""

import functools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from scipy import integrate, special

from mcfit.analysis import fit_turning_points
from mcfit.cli import cli
from mcfit.fit.pendulum import fundamental_amplitude, geometric_factors, names_degrees, \
    peak_from_fundamental, period_ratio
from mcfit.turning import find_turning_points

PERIOD = 1.0
OMEGA = 2 * math.pi / PERIOD
BETA = OMEGA / (2 * 100.0)  # small-angle Q = 100
NOISE = 3e-3  # radians per sample
# Quadratic drag whose fluid coefficient a = 4*kappa*w0/(3*pi) equals beta (per radian).
KAPPA = 3 * math.pi * BETA / (4 * OMEGA)


def _loop(function, theta0):
    """Integral over one cycle of function(theta) d|theta| (w0 = 1): 4 times the quarter
    swing, with theta = theta0*sin(u) to remove the square-root end point."""
    value, _ = integrate.quad(lambda u: function(theta0 * math.sin(u)) * theta0 * math.cos(u),
                              0.0, math.pi / 2, epsabs=0.0, epsrel=1e-12, limit=200)
    return 4.0 * value


@pytest.mark.parametrize("theta0", [0.3, 1.0, 1.4, 2.5])
def test_geometric_factors_match_quadratures_of_the_exact_swing(theta0):
    def speed_squared(theta):  # theta'**2 of the undamped swing, w0 = 1
        return max(2.0 * (math.cos(theta) - math.cos(theta0)), 0.0)

    period = _loop(lambda x: 1.0 / math.sqrt(speed_squared(x)) if speed_squared(x) else 0.0,
                   theta0)
    assert period / (2 * math.pi) == pytest.approx(period_ratio(theta0), rel=1e-9)
    # Energy lost per cycle over w0**2 sin(theta0) T: the rate of theta0 per unit coefficient.
    coulomb = 4 * theta0 / (math.sin(theta0) * period) * (math.pi / 2)  # c = 2 tau/(pi w0)
    viscous = 2 * _loop(lambda x: math.sqrt(speed_squared(x)), theta0) / (
        math.sin(theta0) * period)  # 2 beta loop(theta'^2 dt), b = beta
    drag = _loop(speed_squared, theta0) / (math.sin(theta0) * period) * (
        3 * math.pi / 4)  # kappa loop(|theta'|^3 dt), a = 4 kappa w0/(3 pi)
    g0, g1, g2 = geometric_factors(theta0)
    assert g0 == pytest.approx(coulomb, rel=1e-9)
    assert g1 * theta0 == pytest.approx(viscous, rel=1e-9)
    assert g2 * theta0**2 == pytest.approx(drag, rel=1e-9)


@pytest.mark.parametrize("theta0", [0.2, 1.0, 2.0])
def test_viscous_loop_integral_has_its_elliptic_closed_form(theta0):
    """Loop integral of theta'^2 dt = 16 w0 (E(k) - k'^2 K(k)), k = sin(theta0/2)."""
    reference = _loop(lambda x: math.sqrt(max(2 * (math.cos(x) - math.cos(theta0)), 0.0)),
                      theta0)
    m = math.sin(theta0 / 2) ** 2
    closed = 16 * (special.ellipe(m) - (1 - m) * special.ellipk(m))
    assert closed == pytest.approx(reference, rel=1e-10)


def test_factors_are_smooth_through_the_small_angle_series():
    theta = np.array([1e-6, 0.02 - 1e-12, 0.02 + 1e-12, 0.05])
    g = np.array(geometric_factors(theta))
    assert np.all(np.abs(g[:, 0] - 1) < 1e-11)
    assert np.allclose(g[:, 1], g[:, 2], rtol=1e-10, atol=0)
    assert g[1, 3] == pytest.approx(1 + 5 * 0.05**2 / 96 + 17 * 0.05**4 / 3840, rel=1e-10)


def test_fundamental_amplitude_matches_the_fourier_series_of_the_swing():
    theta0 = 1.2
    quarter = period_ratio(theta0) * PERIOD / 4
    times = np.linspace(0.0, 4 * quarter, 4097)[:-1]
    swing = integrate.solve_ivp(lambda t, s: [s[1], -OMEGA**2 * math.sin(s[0])],
                                (0, times[-1]), [theta0, 0.0], method="DOP853", rtol=1e-12,
                                atol=1e-14, t_eval=times).y[0]
    fundamental = 2 * abs(np.fft.rfft(swing)[1]) / times.size
    assert fundamental_amplitude(theta0) == pytest.approx(fundamental, rel=1e-9)
    assert peak_from_fundamental(fundamental_amplitude(theta0)) == pytest.approx(theta0,
                                                                                 rel=1e-12)


def test_names_degrees():
    assert names_degrees("angle (deg)") and names_degrees("theta [°]")
    assert not names_degrees("theta") and not names_degrees(None)


@functools.lru_cache(maxsize=None)
def _record(theta0, kappa=0.0, seed=1):
    """A swing released from rest at theta0, 50 samples per period for 150 periods, with
    Gaussian noise of NOISE rad."""
    def motion(_, state):
        theta, speed = state
        return [speed, -2 * BETA * speed - kappa * speed * abs(speed)
                - OMEGA**2 * math.sin(theta)]

    t = np.arange(0.0, 150 * PERIOD, PERIOD / 50)
    solution = integrate.solve_ivp(motion, (0.0, t[-1]), [theta0, 0.0], method="DOP853",
                                   rtol=1e-10, atol=1e-12, t_eval=t)
    rng = np.random.default_rng(seed)
    return t, solution.y[0] + NOISE * rng.standard_normal(t.size)


@pytest.mark.slow
@pytest.mark.parametrize("theta0", [0.5, 1.0, 1.4])
def test_viscous_pendulum_is_reported_as_hysteretic_at_large_swings(theta0):
    fit = fit_turning_points(find_turning_points(*_record(theta0)), pendulum=True)
    assert fit.model == "b"
    assert abs(fit.values["b"] - BETA) < 3 * fit.stderr["b"]
    assert fit.small_angle_period == pytest.approx(PERIOD, rel=1e-4)
    # Q tends to its small-angle value w0/(2 beta) as the swing dies away.
    assert fit.q_summary["final"] == pytest.approx(100.0, rel=2e-3)


@pytest.mark.slow
def test_pendulum_with_quadratic_drag_keeps_its_fluid_term():
    fit = fit_turning_points(find_turning_points(*_record(1.0, KAPPA)), pendulum=True)
    assert "a" in fit.model
    a_true = 4 * KAPPA * OMEGA / (3 * math.pi)
    assert abs(fit.values["a"] - a_true) < 3 * fit.stderr["a"]
    assert abs(fit.values["b"] - BETA) < 3 * fit.stderr["b"]


@pytest.mark.slow
def test_without_pendulum_a_fluid_term_from_the_geometry_is_named():
    fit = fit_turning_points(find_turning_points(*_record(1.0)))
    assert "a" in fit.model
    [warning] = [w for w in fit.warnings if "`pendulum`" in w]
    assert "the period grows with amplitude as a pendulum's does" in warning
    assert "a fluid term that may be this geometry alone" in warning


def test_without_pendulum_a_b_biased_by_the_swing_is_named():
    """Q = 50 released at 0.3 rad, noise 1e-3 rad: the small-angle law's b comes out
    several standard errors above the viscous rate; no fluid term shows, and the warning
    fired only for one."""
    beta = OMEGA / 100
    t = np.arange(0.0, 60 * PERIOD, PERIOD / 50)
    solution = integrate.solve_ivp(
        lambda _, s: [s[1], -2 * beta * s[1] - OMEGA**2 * math.sin(s[0])], (0.0, t[-1]),
        [0.3, 0.0], method="DOP853", rtol=1e-11, atol=1e-13, t_eval=t)
    theta = solution.y[0] + 1e-3 * np.random.default_rng(1).standard_normal(t.size)
    fit = fit_turning_points(find_turning_points(t, theta))
    assert fit.model == "b"
    z = (fit.values["b"] - beta) / fit.stderr["b"]
    assert z > 2
    [warning] = [w for w in fit.warnings if "`pendulum`" in w]
    predicted = float(warning.split("b about ")[1].split()[0])
    assert "standard errors above the viscous rate" in warning and 1 < predicted < 2 * z


def test_no_warning_for_a_linear_oscillator():
    t = np.arange(0.0, 150.0, 0.02)
    x = np.exp(-BETA * t) * np.cos(OMEGA * t) + NOISE * np.random.default_rng(2).standard_normal(
        t.size)
    fit = fit_turning_points(find_turning_points(t, x))
    assert not any("`pendulum`" in w for w in fit.warnings)


@pytest.mark.slow
def test_command_line_fits_a_record_in_degrees(tmp_path):
    t, theta = _record(1.0)
    path = tmp_path / "swing.csv"
    np.savetxt(path, np.column_stack([t, np.degrees(theta)]), delimiter=",",
               header="t,angle (deg)", comments="")
    result = CliRunner().invoke(cli, [str(path), "--pendulum", "--format", "json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["model"] == "b"
    assert data["pendulum"]["angle_unit"] == "deg"
    b = data["params"]["b"]
    assert abs(b["value"] - BETA) < 3 * b["stderr"]
    text = CliRunner().invoke(cli, [str(path), "--pendulum"]).output
    assert "pendulum:        large-swing correction applied (angle in deg" in text


REAL = Path(__file__).resolve().parents[2] / "shared" / "realdata" / "pendulum_cup"


@pytest.mark.slow
@pytest.mark.skipif(not (REAL / "trial1_rawdata.txt").exists(), reason="no real records")
def test_real_pendulum_keeps_its_air_drag_with_the_correction():
    """A cup pendulum released near 83 degrees: its fluid term is real drag."""
    from mcfit.analysis import analyse_record
    from mcfit.io import read_record

    record = read_record(str(REAL / "trial1_rawdata.txt"), signal_col=2)
    plain = analyse_record(record)
    corrected = analyse_record(record, pendulum=True)
    assert plain.fit.model == corrected.fit.model == "a"
    assert any("`pendulum`" in w for w in plain.warnings)
    # The geometry accounts for part of the amplitude dependence: Q rises.
    assert corrected.fit.q_summary["initial"] > plain.fit.q_summary["initial"] + 5


def test_a_large_swing_in_degrees_without_a_unit_is_recognised():
    """A video-tracked pendulum released at 78 degrees, its angle in degrees under a
    column name that does not say so: the period's growth matches a pendulum's once the
    swing is read in degrees (beyond pi, it cannot be radians), and the warning says so."""
    from mcfit.analysis import analyse_record
    from mcfit.bench.reference_motion import integrate
    from mcfit.record import Record

    omega = 2 * math.pi / 1.6
    t, theta = integrate(lambda _, v, __: 0.02 * v + 0.05 * v * abs(v), omega,
                         math.radians(78.0), 30.0, 30.0,
                         restoring=lambda x: omega**2 * math.sin(x))
    theta = theta + np.random.default_rng(1).normal(0.0, 2e-3, t.size)
    analysis = analyse_record(Record(source="tracker", t=t, x=np.degrees(theta)))
    [warning] = [w for w in analysis.warnings if "`pendulum`" in w]
    assert warning.startswith("read as an angle in degrees")
    assert warning.endswith("fit it with `pendulum` and `degrees`")
