"""The equation of motion (Handbook Eq. 20.55) and its integrators, against references.

References: the handbook's Figure 20.19 run (Table 20.1), a tight DOP853 solve of the smooth
equation between velocity reversals, the closed-form amplitude law of mcfit.decay, and the
exact Coulomb decrement pi*c/omega per half-cycle.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from mcfit import decay, motion

TWO_PI = 2.0 * math.pi


@pytest.fixture
def rng():
    return np.random.default_rng(20_05)


def _coefficients(kind, q0, y0=1.0, period=1.0):
    """(a, b, c) of one regime (or an even mix) with total Q(y0) = q0 (Eq. 20.56)."""
    rate = (TWO_PI / period) / (2.0 * q0)  # P(y0)/y0
    parts = {"c": (0.0, 0.0, rate * y0), "b": (0.0, rate, 0.0), "a": (rate / y0, 0.0, 0.0),
             "abc": (rate / (3 * y0), rate / 3, rate * y0 / 3),
             "bc": (0.0, rate / 2, rate * y0 / 2)}
    return parts[kind]


# --- Figure 20.19 --------------------------------------------------------------------------

def test_figure_20_19_quality_factors():
    """Cromer-Euler, y0 = 4, T = 0.5 s, a = b = 0.1, c = 0.01, dt = 0.002 s: Q 12.50 -> 22.06.

    Table 20.1 prints ``q = 2*pi*E/loss``, which is Eq. 20.56 evaluated at the energy
    amplitude A = sqrt(x**2 + (xdot/omega)**2) of the current step. Initially A = y0 = 4:
    Q = 12.504 ("12.50"; the QuickBasic ``10*INT(q)/10`` truncates, the figure says 12).
    At the end, 20 s is exactly 40 periods, so the run ends one step (t = 20.000 s)
    before a turning point (t = 20.002 s). Eq. 20.56 at that turning point's amplitude
    |x| = 0.05577 gives Q = 22.056, and at the step's energy amplitude A = 0.05581 it gives
    22.065 (22.062 with Table 20.1's own loss, whose friction is taken before the step):
    all "22.06". The turning point before it (t = 19.75 s, |x| = 0.0598) would give
    Q = 23.0, so "the last turning point" is the one that closes the 20-s run. The closed
    form at t = 20 s gives y = 0.05590 and Q = 22.086 ("22.09"): the integration's
    amplitude is 0.2 % lower, the averaging error of order 1/Q.
    """
    a, b, c, y0, period, dt = 0.1, 0.1, 0.01, 4.0, 0.5, 0.002
    omega = TWO_PI / period
    n_steps = round(20.0 / dt)
    t, x, v = motion.integrate_cromer_euler(y0, 0.0, omega, motion.damping_terms(a, b, c),
                                            dt, n_steps + 50)
    assert t[n_steps] == pytest.approx(20.0)
    q_initial = decay.quality_factor(y0, omega, a, b, c)
    assert round(float(q_initial), 2) == 12.50

    # The turning point that closes the run: the first velocity reversal after 20 s.
    reversals = np.flatnonzero(np.sign(v[1:]) != np.sign(v[:-1]))
    last = reversals[reversals >= n_steps - 1][0]  # v[last] > 0 >= v[last + 1]
    assert 20.0 <= t[last] + dt <= 20.0 + 2 * dt
    turning_amplitude = abs(x[last])  # x[last + 1] = x[last] + v[last + 1]*dt is lower
    assert turning_amplitude == pytest.approx(0.05577, abs=1e-5)
    q_final_turning = decay.quality_factor(turning_amplitude, omega, a, b, c)
    assert q_final_turning == pytest.approx(22.06, abs=0.01)

    energy_amplitude = math.hypot(x[n_steps], v[n_steps] / omega)
    assert energy_amplitude == pytest.approx(0.0558, abs=1e-4)
    q_final_energy = decay.quality_factor(energy_amplitude, omega, a, b, c)
    assert q_final_energy == pytest.approx(22.06, abs=0.01)

    q_closed_form = decay.quality_factor(decay.amplitude(20.0, y0, a, b, c), omega, a, b, c)
    assert round(float(q_closed_form), 2) == 22.09


# --- order of convergence ------------------------------------------------------------------

def _smooth_case():
    """Start mid-swing (x = 0, v = -omega*y0) and stop at 0.15 T, before the first reversal.

    sgn(v) is then constant and the right-hand side is analytic (A > 0), so a scheme's
    order is the one it has on Eq. 20.55 itself, with all three friction terms large
    (Q0 = 5.7). Across a reversal every fixed-step scheme meets a jump of size
    pi*omega*F(A) inside a step and drops to first order; that is why the accurate
    integrator ends its steps there instead.
    """
    a, b, c, y0, period = 0.3, 0.2, 0.05, 1.0, 1.0
    omega = TWO_PI / period
    terms = motion.damping_terms(a, b, c)
    t_end = 0.15 * period

    def rhs(_, y):  # sgn(v) = -1 throughout
        return [y[1], -omega**2 * y[0] + 0.5 * math.pi * omega
                * motion.friction_bracket(math.hypot(y[0], y[1] / omega), terms)]

    reference = solve_ivp(rhs, (0.0, t_end), [0.0, -omega * y0], method="DOP853",
                          rtol=1e-13, atol=1e-15)
    assert np.all(reference.y[1] < 0)  # no reversal inside the window
    return terms, omega, y0, t_end, reference.y[:, -1]


@pytest.mark.parametrize("integrate, order", [(motion.integrate_cromer_euler, 1),
                                              (motion.integrate_symplectic, 2)])
def test_fixed_step_order_on_a_smooth_stretch(integrate, order):
    """Error ratio when dt halves: 1.99-2.00 (Cromer-Euler), 4.000 (Strang splitting)."""
    terms, omega, y0, t_end, (x_ref, v_ref) = _smooth_case()
    errors = []
    for n_steps in (32, 64, 128, 256):
        _, x, v = integrate(0.0, -omega * y0, omega, terms, t_end / n_steps, n_steps)
        errors.append(math.hypot(x[-1] - x_ref, (v[-1] - v_ref) / omega))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    np.testing.assert_allclose(ratios, 2.0**order, rtol=0.02)


def test_accurate_converges_to_its_tolerance():
    """Over five periods with reversals, max|x - x_ref| <= 10*rtol*y0 (measured 1.2 to 6.5)."""
    a, b, c, y0, omega = 0.3, 0.2, 0.05, 1.0, TWO_PI
    terms = motion.damping_terms(a, b, c)
    t = np.linspace(0.0, 5.0, 101)
    reference = motion.integrate_accurate(y0, 0.0, omega, terms, t, rtol=1e-13)
    errors = []
    for rtol in (1e-6, 1e-8, 1e-10):
        result = motion.integrate_accurate(y0, 0.0, omega, terms, t, rtol=rtol)
        errors.append(np.max(np.abs(result.x - reference.x)))
        assert errors[-1] <= 10 * rtol * y0
    assert errors[0] > errors[1] > errors[2]


# --- averaged model ------------------------------------------------------------------------

@pytest.mark.parametrize("q0", [10.0, 100.0])
@pytest.mark.parametrize("kind", ["c", "b", "a", "abc", "bc"])
def test_averaged_error_constant(kind, q0):
    """max|x_averaged - x_true|/y0 * Q(y0) lies in [0.75, pi/4]: AVERAGED_ERROR_CONSTANT = 0.8.

    Measured 0.7854 = pi/4 for Coulomb damping at every Q (the true half-swings are centred
    on +-pi*c/(2*omega), the averaged one on 0), 0.76 to 0.784 for the others, rising to
    pi/4 as Q grows (0.71 at Q0 = 2). The largest error is in the first quarter cycle,
    where the friction force is largest; the record runs to the stop or 1*Q0 seconds.
    """
    a, b, c = _coefficients(kind, q0)
    y0, period = 1.0, 1.0
    duration = min(decay.stop_time(y0, a, b, c) + 1.0, q0)
    t = np.arange(0.0, duration, period / 64)
    true = motion.integrate_accurate(y0, 0.0, TWO_PI / period, motion.damping_terms(a, b, c), t)
    averaged = motion.averaged_motion(t, y0, a, b, c, period)
    ratio = np.max(np.abs(averaged - true.x)) / y0 * q0
    assert 0.75 <= ratio <= math.pi / 4 + 1e-6
    assert ratio <= motion.AVERAGED_ERROR_CONSTANT
    assert motion.averaged_error_estimate(y0, a, b, c, period) == pytest.approx(
        motion.AVERAGED_ERROR_CONSTANT / q0)


@pytest.mark.parametrize("q0", [100.0, 300.0])
@pytest.mark.parametrize("kind", ["c", "b", "a", "abc", "bc"])
def test_accurate_turning_points_follow_the_amplitude_law(kind, q0):
    """Turning-point amplitudes vs the closed form: relative difference <= 0.35/Q_min**2.

    Q_min = min(Q(y0), Q(y_k)) is the smallest Q met so far (Q(y) of Eq. 20.56 has no
    interior minimum). That is second order in 1/Q, far inside the averaging error 1/Q:
    measured |y_k/y(t_k) - 1| * Q_min**2 = 0.31 (hysteretic), 0.051 (fluid), 0.058 (a, b, c
    mixed), 0.029 (b, c mixed), the same at Q0 = 30, 100 and 300; Coulomb damping agrees to
    1e-9 because its decrement pi*c/omega per half-cycle is exact. Amplitudes below 5 % of
    y0 are left out (Q -> 0 at a Coulomb stop).
    """
    a, b, c = _coefficients(kind, q0)
    y0, omega = 1.0, TWO_PI
    duration = min(decay.stop_time(y0, a, b, c), q0)
    result = motion.integrate_accurate(y0, 0.0, omega, motion.damping_terms(a, b, c),
                                       np.array([0.0, duration]))
    y_k = np.abs(result.turning_x)
    y_law = decay.amplitude(result.turning_times, y0, a, b, c)
    kept = y_k > 0.05 * y0
    assert kept.sum() > 20
    relative = np.abs(y_k / y_law - 1.0)[kept]
    q_min = np.minimum(decay.quality_factor(y_k[kept], omega, a, b, c), q0)
    assert np.max(relative * q_min**2) <= 0.35
    assert np.max(relative) <= 0.05 / q0  # the averaging error itself is ~0.8/Q
    if kind == "c":
        assert np.max(np.abs(y_k - y_law)) <= 1e-9


# --- Coulomb stop --------------------------------------------------------------------------

def test_coulomb_decay_loses_pi_c_over_omega_per_half_cycle_and_sticks():
    """y0 = 1.01, c = 0.05, T = 1 s: 40 half-cycles of -0.025 each, then held at |x| = 0.01.

    0.01 is inside the static band omega*|x| <= pi*c/2 (|x| <= 0.0125), so the mass stays
    there: x constant, v = 0 and no sign flips after t = 20 s. Cromer-Euler on the same
    case (no static friction, sgn(0) = -1) chatters about the origin instead.
    """
    y0, c, omega = 1.01, 0.05, TWO_PI
    terms = motion.damping_terms(0.0, 0.0, c)
    t = np.arange(0.0, 40.0, 0.01)
    result = motion.integrate_accurate(y0, 0.0, omega, terms, t)
    decrements = -np.diff(np.abs(result.turning_x))
    np.testing.assert_allclose(decrements, math.pi * c / omega, atol=1e-9)
    assert result.turning_x.size == 41  # start, 39 reversals, stop
    assert result.stop_time == pytest.approx(20.0, abs=1e-8)
    assert abs(result.turning_x[-1]) == pytest.approx(0.01, abs=1e-9)

    held = t >= result.stop_time
    assert np.all(result.x[held] == result.turning_x[-1])
    assert np.all(result.v[held] == 0.0)
    moving = result.v[result.v != 0.0]
    assert np.count_nonzero(np.diff(np.sign(moving))) == 39

    _, x, v = motion.integrate_cromer_euler(y0, 0.0, omega, terms, 0.002, 20_000)
    assert np.count_nonzero(np.diff(np.sign(v[10_500:]))) > 100  # naive sgn(): chatter


def test_start_inside_the_static_band_never_moves():
    t = np.linspace(0.0, 5.0, 11)
    result = motion.integrate_accurate(0.01, 0.0, TWO_PI, motion.damping_terms(0, 0, 0.05), t)
    assert result.stop_time == 0.0
    assert np.all(result.x == 0.01) and np.all(result.v == 0.0)


# --- records -------------------------------------------------------------------------------

def test_record_grid_noise_offset_and_drift(rng):
    args = (0.02, 0.01, 0.002, 1.0, 1.0, 10.0, 100.0)
    t, clean = motion.simulate_record(*args, method="averaged")
    assert t.size == 1001 and t[0] == 0.0 and t[-1] == pytest.approx(10.0)
    _, noisy = motion.simulate_record(*args, method="averaged", noise=0.01, offset=0.5,
                                      drift=0.02, rng=np.random.default_rng(7))
    _, again = motion.simulate_record(*args, method="averaged", noise=0.01, offset=0.5,
                                      drift=0.02, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(noisy, again)
    residual = noisy - clean - 0.5 - 0.02 * t
    assert np.std(residual) == pytest.approx(0.01, rel=0.1)
    assert abs(np.mean(residual)) < 0.002
    _, other = motion.simulate_record(*args, method="averaged", noise=0.01, rng=rng)
    assert not np.array_equal(other, noisy - 0.5 - 0.02 * t)


def test_auto_picks_the_averaged_model_only_when_it_meets_rtol():
    a, b, c, y0, period = 0.0, 0.001, 0.0, 1.0, 1.0  # Q = pi/0.001 = 3142: error 2.5e-4
    estimate = motion.averaged_error_estimate(y0, a, b, c, period)
    assert estimate == pytest.approx(0.8 / (math.pi / 0.001))
    assert motion.choose_method(y0, a, b, c, period, rtol=1e-3) == "averaged"
    assert motion.choose_method(y0, a, b, c, period, rtol=1e-4) == "accurate"
    t, x = motion.simulate_record(a, b, c, y0, period, 5.0, 50.0, rtol=1e-3)
    np.testing.assert_array_equal(x, motion.averaged_motion(t, y0, a, b, c, period))
    _, x_accurate = motion.simulate_record(a, b, c, y0, period, 5.0, 50.0, method="accurate")
    assert np.max(np.abs(x - x_accurate)) <= 1e-3 * y0
    _, x_auto = motion.simulate_record(a, b, c, y0, period, 5.0, 50.0, rtol=1e-4)
    np.testing.assert_allclose(x_auto, x_accurate, atol=1e-9)


def test_fixed_step_resampling_matches_the_scheme_order():
    """Without damping the Strang scheme is an exact rotation, so what is left is the cubic
    Hermite interpolation, (omega*dt)**4/384 = 3e-10 for dt = 0.003 s; a step dividing the
    sample interval is taken as it is (rounding only)."""
    t, x = motion.simulate_record(0, 0, 0, 1.0, 1.0, 10.0, 100.0, method="symplectic", dt=0.003)
    assert np.max(np.abs(x - np.cos(TWO_PI * t))) < 1e-9
    t, x = motion.simulate_record(0, 0, 0, 1.0, 1.0, 10.0, 100.0, method="symplectic",
                                  dt=0.0025)
    assert np.max(np.abs(x - np.cos(TWO_PI * t))) < 1e-12
    # Cromer-Euler: every 5th step for dt = 0.002; the straight chords otherwise.
    _, x_steps, _ = motion.integrate_cromer_euler(1.0, 0.0, TWO_PI, (), 0.002, 5000)
    t, x = motion.simulate_record(0, 0, 0, 1.0, 1.0, 10.0, 100.0, method="cromer-euler",
                                  dt=0.002)
    np.testing.assert_array_equal(x, x_steps[::5])
    t, x = motion.simulate_record(0, 0, 0, 1.0, 1.0, 10.0, 100.0, method="cromer-euler",
                                  dt=0.003)
    assert np.max(np.abs(x - np.cos(TWO_PI * t))) < 0.1  # first order: ~omega**2*dt*t/2


def test_default_step_divides_the_sample_interval():
    assert motion.default_step(0.5, 500.0) == pytest.approx(0.002)
    step = motion.default_step(1.0, 30.0)
    assert step <= 1.0 / 250 and round(1 / 30 / step) * step == pytest.approx(1 / 30)


@pytest.mark.parametrize("bad", [dict(y0=0.0), dict(rate=-1.0), dict(c=-0.1),
                                 dict(method="rk4"), dict(duration=math.nan)])
def test_record_rejects_bad_arguments(bad):
    arguments = dict(a=0.0, b=0.1, c=0.0, y0=1.0, period=1.0, duration=1.0, rate=10.0)
    arguments.update(bad)
    with pytest.raises(ValueError):
        motion.simulate_record(**arguments)


# --- laws that hold for every input --------------------------------------------------------

@settings(max_examples=25, deadline=None)
@given(x=st.floats(-10, 10), v=st.floats(-50, 50), a=st.floats(0, 2), b=st.floats(0, 2),
       c=st.floats(0, 2))
def test_friction_is_odd_and_averages_to_the_law(x, v, a, b, c):
    terms = motion.damping_terms(a, b, c)
    omega = 3.0
    assert motion.acceleration(-x, -v, omega, terms) == pytest.approx(
        -motion.acceleration(x, v, omega, terms), abs=1e-12)
    amplitude = math.hypot(x, v / omega)
    assert motion.friction_bracket(amplitude, terms) == pytest.approx(
        decay.decay_rate(amplitude, a, b, c), rel=1e-14)


@settings(max_examples=15, deadline=None)
@given(q0=st.floats(3, 200), mix=st.tuples(*(st.floats(0, 1),) * 3).filter(lambda m: sum(m) > 0.1))
def test_turning_amplitudes_always_decrease(q0, mix):
    """Friction only removes energy: |x| at successive turning points strictly decreases."""
    rate = math.pi / q0
    weights = np.array(mix) / sum(mix)
    a, b, c = rate * weights
    result = motion.integrate_accurate(1.0, 0.0, TWO_PI, motion.damping_terms(a, b, c),
                                       np.array([0.0, 5.0]))
    assert np.all(np.diff(np.abs(result.turning_x)) < 0)


def test_accurate_start_with_a_velocity_below_the_tolerance_is_a_turning_point():
    """cos and sin of theta0 = 2*pi leave xdot = 1.5e-15 at x = 1: not a half-cycle."""
    t = np.linspace(0.0, 2.0, 201)
    omega = 2 * np.pi
    terms = motion.damping_terms(0.0, 0.5, 0.0)
    velocity = -omega * math.sin(2 * math.pi - 1e-16)
    assert 0 < velocity < 1e-14
    tiny = motion.integrate_accurate(1.0, velocity, omega, terms, t)
    rest = motion.integrate_accurate(1.0, 0.0, omega, terms, t)
    np.testing.assert_allclose(tiny.x, rest.x, atol=1e-12)
