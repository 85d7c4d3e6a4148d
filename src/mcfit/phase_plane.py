"""Eq. 20.55 integrated in its phase plane: fast, batched, and smooth in the parameters.

With x = A*cos(theta) and xdot = -omega*A*sin(theta), A the energy amplitude, the equation
of motion ``xddot + (pi*omega/2)*g(A)*sgn(xdot) + omega**2*x = 0``, g(A) = c + b*A + a*A**2,
becomes in each half-cycle (theta = k*pi + phi, 0 <= phi <= pi, velocity of one sign)::

    dA/dphi = -(pi/2) * g(A) * sin(phi) / D,    dt/dphi = 1 / D,
    D = omega - (pi/2) * (g(A)/A) * cos(phi),

the same equation in every half-cycle: the sign of the friction never changes inside one,
and the half-cycle ends exactly at phi = pi, so no event has to be located. Inside a
half-cycle the solution is analytic in phi: it is found by Chebyshev collocation (Newton's
method on the integrated equations at ``NODES`` Chebyshev-Lobatto points), evaluated on
``FINE`` points of the half-cycle, and x(t) between those is a cubic Hermite interpolant of
phi(t) and A(t), whose derivatives the equations give. At a
turning point from which the swing may not reach the other side of 0 (:func:`_stuck`) the
last swings are integrated in x and xdot (:func:`_with_final_swing`).

Averaged over a half-cycle, dA/dt = -g(A): the amplitude law of docs/theory.md section 1.
The half-cycles are solved all at once, by one Newton iteration over all their
collocation equations (:func:`_all_half_cycles`), started from the averaged law; the
functions take arrays of parameter sets (shape (m,)). :func:`phase_plane_differences`
gives a forward-difference Jacobian from one solution; its loops over the collocation
equations, the fine points and the samples are compiled (:mod:`mcfit.phase_plane_kernels`,
numba, imported there only: :func:`phase_plane_motion` stays numpy alone).
"""

from __future__ import annotations

import math

import numpy as np

from mcfit import decay

__all__ = ["NODES", "FINE", "phase_plane_differences", "phase_plane_motion"]

# Collocation points and interpolation points per half-cycle: x is within 1e-9 of the
# amplitude for Q >= 2 (tests/test_waveform.py, against the accurate integrator).
NODES = 16
FINE = 64
_NEWTON_ITERATIONS = 8  # per half-cycle, one after the other (the fallback)
_GLOBAL_ITERATIONS = 60  # all at once; a stop guessed too early moves a half-cycle a step
# Iterations in a row with the same held half-cycles after which a solution that has not
# converged is given up (Newton's method converges within 8 where it does; near a stop it
# can creep at a constant rate and stall above the tolerance).
_STALLED = 12
_HALF_PI = 0.5 * math.pi
# Most values in one array of the all-at-once solution (2**21 floats: 16 MiB).
_MAX_GRID = 1 << 21


def _chebyshev_matrices(nodes, fine):
    """Chebyshev-Lobatto points s on [0, 1], the matrix that integrates the interpolant of
    values at them from 0 to each point, and the one that evaluates it at ``fine``
    uniform points."""
    from numpy.polynomial import chebyshev

    x = -np.cos(np.pi * np.arange(nodes) / (nodes - 1))
    coefficients = chebyshev.chebfit(x, np.eye(nodes), nodes - 1)  # one column per node
    integral = chebyshev.chebint(coefficients, lbnd=-1.0)
    x_fine = np.linspace(-1.0, 1.0, fine)
    return ((x + 1) / 2, 0.5 * chebyshev.chebval(x, integral).T,
            chebyshev.chebval(x_fine, coefficients).T)


_S, _INTEGRATE, _EVALUATE = _chebyshev_matrices(NODES, FINE)
_FINE_S = np.linspace(0.0, 1.0, FINE)
# The kernels' copies, in one memory layout (numba compiles one version per layout).
_EVALUATE_T, _INTEGRATE_C = np.ascontiguousarray(_EVALUATE.T), np.ascontiguousarray(_INTEGRATE)


def _rates(amplitude, phi, omega, a, b, c, trig=None, derivative=True):
    """dA/dphi and dt/dphi, with d(dA/dphi)/dA (None unless ``derivative``), for arrays
    of states and parameter sets; ``trig``: cos and sin of ``phi`` where known."""
    safe = np.maximum(amplitude, 1e-100)
    friction = c + safe * (b + a * safe)
    cos, sin = (np.cos(phi), np.sin(phi)) if trig is None else trig
    denominator = np.maximum(omega - _HALF_PI * friction / safe * cos, 1e-9 * omega)
    slope = -_HALF_PI * friction * sin / denominator
    if not derivative:
        return slope, 1.0 / denominator, None
    d_denominator = -_HALF_PI * (a - c / (safe * safe)) * cos
    d_slope = -_HALF_PI * sin * ((b + 2 * a * safe) - friction * d_denominator / denominator)
    return slope, 1.0 / denominator, d_slope / denominator


def _trig(phases):
    """cos and sin of ``phases`` (m, count, k) of sets that differ in their first
    half-cycle only (:func:`_grid`): the others' are set 0's."""
    m, count, k = phases.shape
    return tuple(np.concatenate([f(phases[:, :1]), np.broadcast_to(
        f(phases[:1, 1:]), (m, count - 1, k))], axis=1) for f in (np.cos, np.sin))


def phase_plane_motion(t, y0, theta0, omega, a, b, c):
    """x(t) of Eq. 20.55 for ``m`` parameter sets at once.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Times (s) from the start, sorted, >= 0.
    y0, theta0, omega, a, b, c : ndarray, shape (m,) (or scalars)
        Energy amplitude (U) and phase (rad) at t = 0, with x = y0*cos(theta0); angular
        frequency (rad/s); coefficients (1/(U*s), 1/s, U/s), >= 0.

    Returns
    -------
    ndarray, shape (m, n)
        The displacement (U).
    """
    t = np.asarray(t, dtype=float)
    y0, theta0, omega, a, b, c = (np.array(v, dtype=float)[:, None] for v in
                                  np.broadcast_arrays(*(np.atleast_1d(np.asarray(
                                      v, dtype=float)) for v in (y0, theta0, omega, a, b, c))))
    if not (np.any(a) or np.any(b) or np.any(c)):
        return y0 * np.cos(omega * t + theta0)  # no friction: the undamped oscillation
    return _motion(t, y0, theta0, omega, a, b, c, at_once=True)


def _motion(t, y0, theta0, omega, a, b, c, at_once):
    """As :func:`phase_plane_motion` for parameter columns of shape (m, 1); the
    half-cycles one after the other unless ``at_once``."""
    # A trial parameter set of a solver may bring a swing to a standstill inside a
    # half-cycle (D -> 0): its values are then huge but finite, and the solver steps back.
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        if at_once:
            *nodes, final = _nodes(float(t[-1]), y0, theta0, omega, a, b, c)
        else:
            *nodes, final = _nodes_one_by_one(float(t[-1]), y0, theta0, omega, a, b, c)
        x = _with_final_swing(t, _sampled(t, *nodes), final, (a, b, c), omega[:, 0])
    return np.nan_to_num(x, nan=0.0, posinf=1e300, neginf=-1e300)


def phase_plane_differences(t, parameters, steps, memory=None):
    """x(t) at one parameter set, and how it changes when the set moves by each of
    ``steps``: what a forward-difference Jacobian needs, at a fraction of its cost.

    Parameters
    ----------
    t : ndarray, shape (n,)
        As for :func:`phase_plane_motion`.
    parameters : ndarray, shape (6,)
        y0, theta0, omega, a, b, c as for :func:`phase_plane_motion`.
    steps : ndarray, shape (p, 6)
        Small changes of ``parameters`` (relative size about 1e-7).
    memory : dict, optional
        Kept between calls with nearby parameters (a solver's steps): the last solution
        starts the next one, or is the solution when ``parameters`` are the same.

    Returns
    -------
    x : ndarray, shape (n,)
        x at ``parameters`` (U), as :func:`phase_plane_motion` gives it.
    changes : ndarray, shape (p, n)
        x at ``parameters + steps[i]`` less ``x`` (U), to first order in the steps.

    Notes
    -----
    The moved sets take one Newton step from the solution at ``parameters`` with its
    Jacobian (the chord method: the error is of the order of the squared step). Their
    change at fixed time is the interpolant's, differentiated in its nodes
    (:func:`mcfit.phase_plane_kernels.hermite_changes`), at any damping. The last swings
    of a decay that stops are solved for set 0 and followed to first order by the others
    (:func:`_neighbour_swings`), or for every set on its own where a set's swings differ
    in kind; where a moved set counts its half-cycles from another multiple of pi, every
    set is solved on its own and the changes are differences of
    :func:`phase_plane_motion`.
    """
    from mcfit import phase_plane_kernels as kernels  # numba: on the waveform fit's path only

    t = np.ascontiguousarray(t, dtype=float)  # the layout the kernels are compiled for
    sets = np.asarray(parameters, dtype=float)[None, :] + np.vstack(
        [np.zeros((1, 6)), np.asarray(steps, dtype=float)])
    y0, theta0, omega, a, b, c = (sets[:, i:i + 1] for i in range(6))
    base = np.floor(theta0 / math.pi) * math.pi
    first = None
    t_end = float(t[-1])
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        damped = np.any(a) or np.any(b) or np.any(c)
        if damped and np.all(base == base[0]):
            first = _first_solution(t_end, y0, theta0 - base, omega, a, b, c, memory,
                                    kernels)
        if first is None or first is False:
            # Where Newton's method failed for set 0 it fails for its neighbours too:
            # every set one half-cycle after the other at once.
            x = (_motion(t, y0, theta0, omega, a, b, c, at_once=first is None)
                 if damped else phase_plane_motion(t, *sets.T))
            return x[0], x[1:] - x[0]
        solved = (_chord(first, y0, theta0 - base, omega, a, b, c, kernels)
                  if len(sets) > 1 else first)
        if solved is None:  # the steps are no derivatives: every set on its own
            x = _motion(t, y0, theta0, omega, a, b, c, at_once=True)
            return x[0], x[1:] - x[0]
        *nodes, final = _fine_nodes(solved, base, theta0 - base, omega, a, b, c, kernels)
        x, changes = kernels.hermite_changes(t, *nodes)
        stops = final[:, 0]
        swung = None
        if np.isfinite(stops[0]) and t[-1] >= stops[0]:
            late = t >= stops[0]
            swung = _neighbour_swings(t[late], final, a[:, 0], b[:, 0], c[:, 0], omega[:, 0],
                                      memory)
        if swung is not None:
            x[late], changes[:, late] = swung
        elif np.any(np.isfinite(stops)) and t[-1] >= np.min(stops):
            # The last swings of a stop, of every set: its own motion up to its stop.
            late = t >= np.min(stops)
            moved = _with_final_swing(t[late], x[late] + np.vstack(
                [np.zeros((1, int(np.sum(late)))), changes[:, late]]), final, (a, b, c),
                omega[:, 0])
            x[late], changes[:, late] = moved[0], moved[1:] - moved[0]
    if not (np.isfinite(x).all() and np.isfinite(changes).all()):  # one pass where finite
        x, changes = (np.nan_to_num(v, copy=False, nan=0.0, posinf=1e300, neginf=-1e300)
                      for v in (x, changes))
    return x, changes


def _first_solution(t_end, y0, phi, omega, a, b, c, memory=None, kernels=None):
    """The half-cycles of set 0 (:func:`_all_half_cycles`, compiled where ``kernels``
    is :mod:`mcfit.phase_plane_kernels`), started from the last solution in ``memory``
    where it has as many; None where they are not solved at once (too many, or too few
    to reach ``t_end``), False where Newton's method fails."""
    count = float(np.ceil((omega[0, 0] * t_end + phi[0, 0]) / math.pi)) + 2
    if not _fits_at_once(count, y0.shape[0]):
        return None
    count = int(count)
    memory = {} if memory is None else memory
    key = np.array([t_end] + [v[0, 0] for v in (y0, phi, omega, a, b, c)])
    last = memory.get("solution")
    if last is not None and np.array_equal(memory["key"], key):
        return last
    guesses = ([last[0]] if last is not None and last[0].shape[1] == count else []) + [None]
    found = False
    for guess in guesses:
        try:
            first = _all_half_cycles(count, t_end, y0[:1], phi[:1], omega[:1], a[:1], b[:1],
                                     c[:1], guess, kernels)
        except np.linalg.LinAlgError:
            first = None
        if isinstance(first, str):
            found = None
        elif first is not None:
            memory.update(key=key, solution=first)
            return first
    return found


def _chord(first, y0, phi0, omega, a, b, c, kernels):
    """The half-cycles of every set from one Newton step away from ``first`` (the
    solution of set 0, as :func:`_all_half_cycles` returns it) with its Jacobian
    (:func:`mcfit.phase_plane_kernels.newton_step`; ``kernels``: that module)."""
    amplitudes, _, _, held, finished, _, _, _ = first
    count = held.shape[1]
    start_phi, length, phases = _grid(count, phi0)
    held = np.broadcast_to(held, (y0.shape[0], count))
    y0_, _, length_, omega_, coefficients = _kernel_arguments(y0, start_phi, length, omega,
                                                              a, b, c)
    free = np.where(held, 0.0, coefficients[..., None])
    fixed = (y0_, phases, length_, omega_, free, _INTEGRATE_C)
    residual, _, d_slope = kernels.collocation_residuals(amplitudes, *fixed)
    step = kernels.newton_step(residual, d_slope[:1], length_[:1], _INTEGRATE_C)
    guess = amplitudes + step
    residual, time_rate, _ = kernels.collocation_residuals(guess, *fixed)
    if not _small(residual, step, amplitudes):
        return None
    return (guess, start_phi, length, held, np.broadcast_to(finished, held.shape),
            _begins(length, time_rate, held), time_rate, list(free[..., None]))


def _small(residual, step, scale):
    """Whether a chord step (each row a set) left residuals of the order of its square,
    or of the rounding of values of ``scale``: where a set moves the solution by much of
    itself (a parameter's step near its own size, as a small Coulomb coefficient's where
    it dominates), the step is no derivative."""
    rows = residual.reshape(residual.shape[0], -1)
    steps = step.reshape(step.shape[0], -1)
    floor = 1e-10 * np.max(np.abs(scale))  # the rounding of the equations, and more
    return bool(np.all(np.isfinite(rows)) and np.all(
        np.max(np.abs(rows), axis=1) <= 1e-3 * np.max(np.abs(steps), axis=1) + floor))


def _fits_at_once(count, sets):
    """Whether ``count`` half-cycles of ``sets`` parameter sets are solved at once within
    _MAX_GRID values an array; more (a long record, or a solver's trial frequency far
    off) go one half-cycle after the other, in bounded memory."""
    per_half_cycle = max(FINE, NODES * NODES)  # the Newton Jacobian's blocks are largest
    return bool(np.isfinite(count) and count * sets * per_half_cycle <= _MAX_GRID)


def _grid(count, phi0):
    """Start phase, length and collocation phases of ``count`` half-cycles of each set,
    the first from ``phi0`` (shape (m, 1)): arrays of shape (m, count, 1 or NODES)."""
    start_phi = np.where(np.arange(count) == 0, phi0, 0.0)[..., None]
    length = math.pi - start_phi
    return start_phi, length, start_phi + length * _S


def _residual(amplitudes, y0, length, slope):
    """The collocation equations A = A_start + L*S*f(A) of every half-cycle, A_start the
    end of the one before (y0 for the first)."""
    m, count = slope.shape[:2]
    entering = np.concatenate([np.broadcast_to(y0, (m, 1)),
                               np.broadcast_to(amplitudes[:, :-1, -1], (m, count - 1))], axis=1)
    entering = entering[..., None]
    return amplitudes - entering - length * (slope @ _INTEGRATE.T)


def _steps(own, carried):
    """Newton steps of all half-cycles: each one's ``own`` step plus its response
    ``carried`` (to a unit change of its start) times the step of the end before it.

    The ends obey e_k = o_k + r_k*e_(k-1), e_(-1) = 0: with P_k = r_0*...*r_k,
    e_k = P_k * sum_(j<=k) o_j/P_j, unless P leaves the floating-point range (a loop then).
    """
    ratio = carried[..., -1]
    with np.errstate(all="ignore"):
        product = np.cumprod(np.broadcast_to(ratio, own.shape[:2]), axis=1)
        ends = product * np.cumsum(own[..., -1] / product, axis=1)
    if not (np.all(np.isfinite(ends)) and np.all(np.abs(product) > 1e-200)
            and np.all(np.abs(product) < 1e200)):
        end = np.zeros(own.shape[0])
        ends = np.empty(own.shape[:2])
        for k in range(own.shape[1]):
            end = own[:, k, -1] + ratio[:, k] * end
            ends[:, k] = end
    before = np.concatenate([np.zeros((own.shape[0], 1)), ends[:, :-1]], axis=1)
    return own + carried * before[..., None]


def _half_cycle(amplitude, now, phi, omega, a, b, c):
    """The solution from ``phi`` (shape (m, 1)) to pi: amplitude and time at the
    collocation points, by Newton's method on A = A0 + L*S*f(A)."""
    length = math.pi - phi
    phases = phi + length * _S
    guess = np.repeat(amplitude, _S.size, axis=1)
    identity = np.eye(_S.size)
    for _ in range(_NEWTON_ITERATIONS):
        slope, _, d_slope = _rates(guess, phases, omega, a, b, c)
        residual = guess - amplitude - length * (slope @ _INTEGRATE.T)
        jacobian = identity - length[:, :, None] * _INTEGRATE[None] * d_slope[:, None, :]
        step = np.linalg.solve(jacobian, residual[..., None])[..., 0]
        guess = guess - step
        if np.max(np.abs(step)) <= 1e-14 * np.max(np.abs(guess)):
            break
    _, time_rate, _ = _rates(guess, phases, omega, a, b, c)
    return guess, now + length * (time_rate @ _INTEGRATE.T), phases, length


def _stuck(amplitude, omega, a, b, c):
    """At a turning point: the swing may not reach the other side of 0. Under a friction
    force held at its start value (pi*omega/2)*g(A) the mass swings about
    x_c = (pi/(2*omega))*g(A) and ends at 2*x_c - A, beyond 0 only if A > 2*x_c. From
    there on the motion is :func:`_with_final_swing`."""
    return omega * amplitude <= math.pi * (c + amplitude * (b + a * amplitude))


def _nodes(t_end, amplitude, theta0, omega, a, b, c):
    """Times, total phases, amplitudes and their time derivatives on FINE points of each
    half-cycle, until every set has passed ``t_end`` or is held, arrays of shape
    (m, nodes), and each set's stop (start, amplitude, sign; inf where it swings on). A
    half-cycle boundary is a node twice, once with the rates of either side (the friction
    changes sign there). All half-cycles are solved at once (:func:`_all_half_cycles`);
    where that fails, one after the other (:func:`_nodes_one_by_one`)."""
    base = np.floor(theta0 / math.pi) * math.pi
    phi = theta0 - base
    # Friction slows the phase on average, so a half-cycle lasts at least about pi/omega.
    count = float(np.max(np.ceil((omega * t_end + phi) / math.pi))) + 2
    solved = None
    for _ in range(3):
        if not _fits_at_once(count, amplitude.shape[0]):
            break
        count = int(count)
        try:
            solved = _all_half_cycles(count, t_end, amplitude, phi, omega, a, b, c)
        except np.linalg.LinAlgError:
            solved = None
        if not isinstance(solved, str):
            break
        count *= 2
    if solved is None or isinstance(solved, str):
        return _nodes_one_by_one(t_end, amplitude, theta0, omega, a, b, c)
    return _fine_nodes(solved, base, phi, omega, a, b, c)


def _all_half_cycles(count, t_end, y0, phi0, omega, a, b, c, guess=None, kernels=None):
    """The collocation amplitudes of ``count`` successive half-cycles of every set, by
    Newton's method on all of them at once (multiple shooting).

    Half-cycle k starts where k - 1 ends, so its Newton step is its own step plus the
    response to the step of that end amplitude: J_k d_k = -G_k + 1*e_(k-1), solved for
    both right-hand sides, leaves a scalar recursion for the ends. The start is the
    averaged law at each half-cycle's start (within O(1/Q) of the solution), or ``guess``
    (amplitudes, shape (m, count, NODES)). Returns (amplitudes, start phases, lengths,
    held, finished, start times, time rates, coefficients as held sets see them), "short"
    when the half-cycles end before ``t_end``, None without convergence. ``kernels``:
    :mod:`mcfit.phase_plane_kernels` for the iteration compiled (:func:`_compiled_step`)."""
    start_phi, length, phases = _grid(count, phi0)
    index = np.arange(count)
    if guess is None:
        elapsed = np.where(index == 0, 0.0, index * math.pi - phi0) / omega
        guess = np.repeat(decay.amplitude(elapsed, y0, a, b, c)[..., None], _S.size, axis=2)
    guess = np.array(guess, dtype=float, order="C")  # stepped in place
    if kernels is None:
        trig = (np.cos(phases), np.sin(phases))
        step = _numpy_step(t_end, y0, start_phi, length, phases, trig, omega, a, b, c)
    else:
        arguments = _kernel_arguments(y0, start_phi, length, omega, a, b, c)
        step = _compiled_step(t_end, phases, arguments, kernels)
    if _iterated(guess, step) is None:
        return None
    if kernels is None:
        held = _held(guess[..., 0], start_phi[..., 0], omega, a, b, c)
        free = [np.where(held, 0.0, k)[..., None] for k in (a, b, c)]
        _, time_rate, _ = _rates(guess, phases, omega[..., None], *free, trig=trig,
                                 derivative=False)
    else:
        y0_, start_, length_, omega_, coefficients = arguments
        held, free = kernels.held_coefficients(guess, start_, omega_, coefficients)
        _, time_rate, _ = kernels.collocation_residuals(guess, y0_, phases, length_, omega_,
                                                        free, _INTEGRATE_C)
        free = list(free[..., None])
    begins = _begins(length, time_rate, held)
    finished = held | (begins >= t_end)
    if not np.all(np.any(finished, axis=1) | (begins[:, -1] + length[:, -1, 0] * (
            time_rate[:, -1] @ _INTEGRATE[-1]) >= t_end)):
        return "short"
    return guess, start_phi, length, held, finished, begins, time_rate, free


def _iterated(guess, step):
    """Newton's method from ``guess`` (updated in place) by ``step``: the amplitudes, or
    None where a step is not finite, the held half-cycles keep changing, or it stalls
    (``_STALLED`` iterations in a row with the same held ones) or runs out."""
    held_before, steady = None, 0
    for _ in range(_GLOBAL_ITERATIONS):
        held, change, size = step(guess)
        if not np.isfinite(change + size):
            return None
        same = held_before is not None and np.array_equal(held, held_before)
        if change <= 1e-14 * size and same:
            return guess
        steady = steady + 1 if same else 0
        if steady >= _STALLED:
            return None
        held_before = held
    return None


def _numpy_step(t_end, y0, start_phi, length, phases, trig, omega, a, b, c):
    """The Newton step of :func:`_all_half_cycles` in numpy, as a function of the
    amplitudes (moved in place): the held half-cycles, and the largest change and
    amplitude of those that move before ``t_end``."""
    identity = np.eye(_S.size)

    def step(guess):
        held = _held(guess[..., 0], start_phi[..., 0], omega, a, b, c)
        free = [np.where(held, 0.0, k)[..., None] for k in (a, b, c)]
        slope, time_rate, d_slope = _rates(guess, phases, omega[..., None], *free, trig=trig)
        residual = _residual(guess, y0, length, slope)
        jacobian = identity - length[..., None] * _INTEGRATE * d_slope[..., None, :]
        both = np.linalg.solve(jacobian, np.stack([-residual, np.ones(guess.shape)], axis=-1))
        moved = _steps(both[..., 0], both[..., 1])
        guess += moved
        relevant = ~held & (_begins(length, time_rate, held) < t_end)
        return (held, np.max(np.abs(moved[relevant]), initial=0.0),
                np.max(np.abs(guess[relevant]), initial=0.0))

    return step


def _kernel_arguments(y0, start_phi, length, omega, a, b, c):
    """y0, start phases, lengths, omega and a, b, c (shape (3, m)) as the kernels take
    them, C-ordered."""
    return tuple(np.ascontiguousarray(v) for v in (
        y0[:, 0], start_phi[..., 0], length[..., 0], omega[:, 0],
        np.concatenate([a, b, c], axis=1).T))


def _compiled_step(t_end, phases, arguments, kernels):
    """As :func:`_numpy_step`, compiled (:mod:`mcfit.phase_plane_kernels`; ``arguments``
    from :func:`_kernel_arguments`)."""
    y0, start_phi, length, omega, coefficients = arguments

    def step(guess):
        held, free = kernels.held_coefficients(guess, start_phi, omega, coefficients)
        residual, time_rate, d_slope = kernels.collocation_residuals(
            guess, y0, phases, length, omega, free, _INTEGRATE_C)
        moved = kernels.newton_step(residual, d_slope, length, _INTEGRATE_C)
        change, size = kernels.newton_update(guess, moved, held, time_rate, length,
                                             float(t_end), _INTEGRATE_C)
        return held, change, size

    return step


def _held(starts, start_phi, omega, a, b, c):
    """Whether each half-cycle (m, count) starts at or after a turning point where the set
    is held (:func:`_stuck`)."""
    stuck = (start_phi == 0.0) & _stuck(starts, omega, a, b, c)
    return np.cumsum(stuck, axis=1) > 0


def _begins(length, time_rate, held):
    """Start time of each half-cycle (held ones last no time)."""
    durations = np.where(held, 0.0, length[..., 0] * (time_rate @ _INTEGRATE[-1]))
    return np.cumsum(durations, axis=1) - durations


def _fine_nodes(solved, base, phi, omega, a, b, c, kernels=None):
    """The solved half-cycles on FINE points each; from the first finished half-cycle on
    (held, or starting after the record) the state of its start, at rest. ``kernels``:
    :mod:`mcfit.phase_plane_kernels` where the caller has loaded it (the same nodes,
    compiled)."""
    amplitudes, start_phi, length, held, finished, begins, time_rate, free = solved
    m, count = held.shape
    first = np.where(np.any(finished, axis=1), np.argmax(finished, axis=1), count)
    rows = np.arange(m)
    last = np.minimum(first, count - 1)
    stop_t = begins[rows, last]
    stop_phase = base[:, 0] + last * math.pi + start_phi[rows, last, 0]
    stop_a = amplitudes[rows, last, 0]
    final = np.full((m, 3), np.inf)
    stops = np.any(held, axis=1)
    h = np.argmax(held, axis=1)
    final[stops] = np.column_stack([begins[rows, h], amplitudes[rows, h, 0],
                                    np.cos(base[:, 0] + h * math.pi)])[stops]
    if kernels is not None:
        def fitted(v):  # writable and C-ordered, as the kernels are compiled for
            return np.array(np.broadcast_to(v, (m, count)), dtype=float)

        nodes = kernels.fine_nodes(
            np.ascontiguousarray(amplitudes), np.ascontiguousarray(time_rate),
            fitted(start_phi[..., 0]), fitted(length[..., 0]), fitted(begins),
            np.stack([fitted(k[..., 0]) for k in free]), np.array(omega[:, 0]),
            np.array(base[:, 0]), first, np.column_stack([stop_t, stop_phase, stop_a]),
            _EVALUATE_T, _INTEGRATE_C, _FINE_S)
        return tuple(nodes) + (final,)
    fine_a = amplitudes @ _EVALUATE.T
    fine_t = begins[..., None] + (length * (time_rate @ _INTEGRATE.T)) @ _EVALUATE.T
    fine_phi = start_phi + length * _FINE_S
    slope, fine_rate, _ = _rates(fine_a, fine_phi, omega[..., None], *free,
                                 trig=_trig(fine_phi), derivative=False)
    total = base[..., None] + np.arange(count)[:, None] * math.pi + fine_phi
    rest = (np.arange(count) >= first[:, None])[..., None]
    nodes = (np.where(rest, stop_t[:, None, None], fine_t),
             np.where(rest, stop_phase[:, None, None], total),
             np.where(rest, stop_a[:, None, None], fine_a),
             np.where(rest, 0.0, 1.0 / fine_rate), np.where(rest, 0.0, slope / fine_rate))
    return tuple(v.reshape(m, -1) for v in nodes) + (final,)


def _nodes_one_by_one(t_end, amplitude, theta0, omega, a, b, c):
    """As :func:`_nodes`, one half-cycle after the other."""
    base = np.floor(theta0 / math.pi) * math.pi
    phi = theta0 - base
    now = np.zeros_like(amplitude)
    held = np.zeros(amplitude.shape, dtype=bool)
    final = np.full((amplitude.shape[0], 3), np.inf)  # start, amplitude, sign
    pieces = []
    # Friction at Q >= 1 speeds the phase by less than a factor 2: a bound on the loop.
    for _ in range(int(2 * np.max(omega) * t_end / math.pi) + 4):
        stuck = ~held & (phi == 0.0) & _stuck(amplitude, omega, a, b, c)
        if np.any(stuck):
            rows = stuck[:, 0]
            final[rows] = np.column_stack([now, amplitude, np.cos(base)])[rows]
        held = held | stuck
        free = [np.where(held, 0.0, k) for k in (a, b, c)]  # a held set needs no solution
        amplitudes, times, phases, length = _half_cycle(amplitude, now, phi, omega, *free)
        fine_a, fine_t = amplitudes @ _EVALUATE.T, times @ _EVALUATE.T
        fine_phi = phi + length * _FINE_S
        slope, time_rate, _ = _rates(fine_a, fine_phi, omega, *free)
        moving = ~held
        pieces.append((np.where(moving, fine_t, now), np.where(moving, base + fine_phi, base + phi),
                       np.where(moving, fine_a, amplitude), np.where(moving, 1.0 / time_rate, 0.0),
                       np.where(moving, slope / time_rate, 0.0)))
        amplitude = np.where(held, amplitude, fine_a[:, -1:])
        now = np.where(held, now, fine_t[:, -1:])
        base = np.where(held, base, base + math.pi)
        phi = np.where(held, phi, 0.0)
        if np.all(held | (now >= t_end)):
            break
    return tuple(np.concatenate(v, axis=1) for v in zip(*pieces)) + (final,)


def _with_final_swing(t, x, final, coefficients, omega):
    """The end of a decay that stops, from the turning point where :func:`_stuck` holds:
    the last swings are short of crossing 0 and the friction changes much within them, so
    they are solved in x and xdot, every set at once (:func:`_final_swings`), and the mass
    is held where static friction wins (as :func:`mcfit.motion.integrate_accurate` does).
    """
    rows = [i for i, start in enumerate(final[:, 0])
            if np.isfinite(start) and t.size and t[-1] >= start]
    if rows:
        a, b, c = (np.array([k[i, 0] for i in rows]) for k in coefficients)
        swung = _final_swings(t, final[rows], a, b, c, omega[rows])
        for i, values in zip(rows, swung):
            after = t >= final[i, 0]
            x[i, after] = values
    return x


# Collocation points of a piece of a half-swing of the final swings. A piece spans a
# half period (the reversal of a swing about a centre held still) or a tenth of one after
# it: the motion continued past its reversal nears a singularity of the friction's
# amplitude, which a longer piece would reach.
_SWING_NODES = 24
_SWING_S, _SWING_INTEGRATE, _ = _chebyshev_matrices(_SWING_NODES, 2)
# Node values -> Chebyshev coefficients on the piece.
_SWING_FIT = np.polynomial.chebyshev.chebfit(2 * _SWING_S - 1, np.eye(_SWING_NODES),
                                             _SWING_NODES - 1)
# Coefficients -> those of the derivative (in the variable on [-1, 1]).
_SWING_DERIVATIVE = np.polynomial.chebyshev.chebder(np.eye(_SWING_NODES))
# Coefficients -> values at the 33 points of a piece where a reversal is looked for.
_SWING_GRID = np.polynomial.chebyshev.chebvander(np.linspace(-1.0, 1.0, 33),
                                                 _SWING_NODES - 1)
_SWING_PIECES = (1.0, 0.1)  # half periods: the first piece of a half-swing, the others
_SWING_ITERATIONS = 30
_MAX_PIECES = 400
_REVERSAL_ITERATIONS = 60
# (mcfit.swing_kernels holds its own copies of these, compiled in: a test keeps them equal.)
# The compiled final swings' matrices, C-ordered (numba compiles one version per layout),
# and the pieces of a first call.
_SWING_KERNEL = tuple(np.ascontiguousarray(v) for v in (
    _SWING_S, _SWING_INTEGRATE, _SWING_FIT, _SWING_DERIVATIVE, _SWING_GRID))
_NO_SWINGS = np.empty((0, 3 + 2 * _SWING_NODES))


def _final_swings(t, final, a, b, c, omega):
    """x at the times ``t >= start`` of each set after its stop (``final``: start,
    amplitude, sign), a list of arrays. Each half-swing (a velocity of one sign) is
    solved by Chebyshev collocation in time in pieces, every set at once (each set's
    numbers its own: a set solved alone gives the same); at a turning point where the
    spring does not overcome the friction, the mass is held."""
    friction = _HALF_PI * omega
    m = final.shape[0]
    now = np.zeros(m)  # time since the stop
    position, velocity = final[:, 2] * final[:, 1], np.zeros(m)
    held = np.zeros(m, dtype=bool)
    ends = t[-1] - final[:, 0]
    pieces = [[] for _ in range(m)]  # (start, end, length, x in time) of each piece
    for _ in range(_MAX_PIECES):
        size = np.abs(position)
        spring = omega * omega * size
        held |= (velocity == 0.0) & ((spring <= friction * c)
                                     | (spring <= friction * (c + size * (b + a * size))))
        active = ~held & (now < ends)
        if not np.any(active):
            break
        rows = np.flatnonzero(active)
        length = np.where(velocity[rows] == 0.0, _SWING_PIECES[0], _SWING_PIECES[1]) * (
            math.pi / omega[rows])
        spans, x_of, v_of = _swing_piece(position[rows], velocity[rows], length,
                                         omega[rows], a[rows], b[rows], c[rows])
        for k, i in enumerate(rows):
            pieces[i].append((now[i], now[i] + spans[k], length[k], x_of[k]))
            now[i] += spans[k]
            position[i] = x_of[k](spans[k])
            velocity[i] = 0.0 if spans[k] < length[k] else v_of[k](spans[k])
    else:
        raise RuntimeError("the final swings did not stop")  # pragma: no cover
    found = []
    for i in range(m):
        local = t[t >= final[i, 0]] - final[i, 0]
        values = np.full(local.size, position[i])
        for begin, stop, length, polynomial in pieces[i]:
            inside = (local >= begin) & (local < stop)
            values[inside] = polynomial(local[inside] - begin)
        found.append(values)
    return found


def _neighbour_swings(t, final, a, b, c, omega, memory=None):
    """As :func:`_final_swings` for sets that are small changes of set 0 (a Jacobian's
    moved sets): x of set 0 at the times ``t >= final[0, 0]``, and each other set's
    change there, shape (m - 1, n), to first order in the changes; None where a set's
    swings differ in kind (reverse, or are held, in another piece).

    Set 0's pieces are solved as :func:`_final_swings` solves them; the others take one
    Newton step from them with set 0's Jacobian, and their reversals one from set 0's.
    Each set's polynomial is evaluated at set 0's position in the piece, plus set 0's
    rate there times the difference of the positions. Set 0's pieces of the last call,
    kept in ``memory``, start Newton's method where they start nearly alike. Compiled:
    :func:`mcfit.swing_kernels.neighbour_swings`."""
    from mcfit import swing_kernels  # numba: on the waveform fit's path only

    memory = {} if memory is None else memory
    last = memory.get("swings", _NO_SWINGS)
    status, x, changes, kept = swing_kernels.neighbour_swings(
        np.ascontiguousarray(t - final[0, 0]), final[0, 0] - final[:, 0],
        final[:, 2] * final[:, 1], *(np.ascontiguousarray(k, dtype=float)
                                     for k in (omega, a, b, c)), last, *_SWING_KERNEL)
    if status == swing_kernels.ENDLESS:
        raise RuntimeError("the final swings did not stop")  # pragma: no cover
    if status != swing_kernels.NEIGHBOURS:
        return None
    memory["swings"] = kept  # one row a piece
    return x, changes


def _swing_piece(x0, v0, length, omega, a, b, c):
    """A piece of ``length`` of a half-swing from (``x0``, ``v0``) of each set: the time
    to the reversal of the velocity within it (``length`` where there is none), and x
    and xdot as functions of the time since its start."""
    sense, x, v = _swing_nodes(x0, v0, length, omega, a, b, c)
    x_of = [_interpolant(x[k], length[k]) for k in range(x0.size)]
    v_of = [_interpolant(v[k], length[k]) for k in range(x0.size)]
    spans = [_reversal(v_of[k], sense[k, 0], length[k]) for k in range(x0.size)]
    return spans, x_of, v_of


def _swing_nodes(x0, v0, length, omega, a, b, c):
    """The sense of the velocity (shape (m, 1)), x and xdot at the collocation points of
    a piece of ``length`` of a half-swing from (``x0``, ``v0``) of each set, by Newton's
    method from a cosine about the centre of the friction at its start."""
    sense = np.where(v0 != 0.0, np.sign(v0), -np.sign(x0))[:, None]  # of the velocity
    size = np.hypot(x0, v0 / omega)
    centre = -sense[:, 0] * _HALF_PI / omega * (c + size * (b + a * size))
    phase = omega[:, None] * length[:, None] * _SWING_S
    x = (centre[:, None] + (x0 - centre)[:, None] * np.cos(phase)
         + (v0 / omega)[:, None] * np.sin(phase))
    v = (-(x0 - centre)[:, None] * omega[:, None] * np.sin(phase)
         + v0[:, None] * np.cos(phase))
    n = _SWING_NODES
    last = math.inf
    for _ in range(_SWING_ITERATIONS):
        residual, jacobian = _swing_equations(x, v, x0, v0, length, omega, a, b, c, sense)
        step = np.linalg.solve(jacobian, residual[..., None])[..., 0]
        x, v = x - step[:, :n], v - step[:, n:]
        change = np.max(np.abs(step)) / np.max(size)
        # Converged, or at the rounding floor (it stops falling).
        if change <= 1e-14 or change > 0.5 * last:
            break
        last = change
    return sense, x, v


def _swing_equations(x, v, x0, v0, length, omega, a, b, c, sense):
    """Residuals (shape (m, 2*_SWING_NODES)) of a piece's collocation equations
    x = x0 + integral of xdot, xdot = xdot0 + integral of the force, and their Jacobian
    (:func:`mcfit.swing_kernels.neighbour_swings` compiles the same)."""
    push = sense * (_HALF_PI * omega)[:, None]
    w2 = (omega * omega)[:, None]
    a3, b3, c3 = a[:, None], b[:, None], c[:, None]
    amplitude = np.maximum(np.sqrt(x * x + v * v / w2), 1e-300)
    force = -w2 * x - push * (c3 + amplitude * (b3 + a3 * amplitude))
    span = length[:, None]
    residual = np.concatenate([x - x0[:, None] - span * (v @ _SWING_INTEGRATE.T),
                               v - v0[:, None] - span * (force @ _SWING_INTEGRATE.T)],
                              axis=1)
    n = _SWING_NODES
    slope = push * (b3 + 2 * a3 * amplitude) / amplitude
    scale = span[..., None] * _SWING_INTEGRATE  # integrates node values from 0
    matrix = np.empty((x.shape[0], 2 * n, 2 * n))
    matrix[:, :n, :n] = np.eye(n)
    matrix[:, :n, n:] = -scale
    matrix[:, n:, :n] = scale * (w2 + slope * x)[:, None, :]
    matrix[:, n:, n:] = np.eye(n) + scale * (slope * v / w2)[:, None, :]
    return residual, matrix


class _Interpolant:
    """The Chebyshev interpolant of node values on [0, length], callable at times."""

    def __init__(self, coefficients, length):
        self.coefficients, self.length = coefficients, length

    def __call__(self, time):
        return np.polynomial.chebyshev.chebval(2 * np.asarray(time) / self.length - 1,
                                               self.coefficients)

    def derivative(self):
        return _Interpolant(_SWING_DERIVATIVE @ self.coefficients
                            * (2 / self.length), self.length)


def _interpolant(values, length):
    return _Interpolant(_SWING_FIT @ values, length)


def _reversal(v_of, sense, length):
    """The first time in (0, length] where the velocity of sign ``sense`` reaches 0
    (Newton's method on the interpolant inside the bracket of a grid; ``length`` where
    it does not)."""
    grid = np.linspace(0.0, length, _SWING_GRID.shape[0])
    moving = sense * v_of(grid) > 0
    moving[0] = True
    stopped = np.flatnonzero(~moving)
    if not stopped.size:
        return length
    low, high = grid[stopped[0] - 1], grid[stopped[0]]
    rate = v_of.derivative()
    time = 0.5 * (low + high)
    for _ in range(_REVERSAL_ITERATIONS):
        value = float(v_of(time))
        if value == 0.0:
            break
        if sense * value > 0:
            low = time
        else:
            high = time
        then, time = time, time - value / float(rate(time))
        if not low < time < high:
            time = 0.5 * (low + high)
        if abs(time - then) <= 1e-15 * length:
            break
    return time


def _sampled(t, times, phases, amplitudes, phase_rates, amplitude_rates):
    """x at times ``t`` from the nodes, by cubic Hermite interpolation of the total phase
    and the amplitude in time; past the last node the state stays where it was held.
    (:func:`mcfit.phase_plane_kernels.hermite_changes` is the same interpolant, compiled,
    with its changes; this path stays free of numba for :func:`phase_plane_motion`.)"""
    x = np.empty((times.shape[0], t.size))
    for i in range(times.shape[0]):
        amplitude, phase = _interpolated(t, times[i], phases[i], amplitudes[i],
                                         phase_rates[i], amplitude_rates[i])
        x[i] = amplitude * np.cos(phase)
    return x


def _interpolated(t, times, phases, amplitudes, phase_rates, amplitude_rates):
    """The amplitude and total phase at times ``t`` from the nodes of one set (cubic
    Hermite basis h00, h01, h10, h11 of s in [0, 1] in each interval)."""
    j = np.clip(np.searchsorted(times, t, side="right") - 1, 0, times.size - 2)
    span = times[j + 1] - times[j]
    width = np.where(span > 0, span, 1.0)
    s = np.where(span > 0, np.clip((t - times[j]) / width, 0.0, 1.0), 0.0)
    s2, s3 = s * s, s * s * s
    basis = (2 * s3 - 3 * s2 + 1, -2 * s3 + 3 * s2, s3 - 2 * s2 + s, s3 - s2)
    slopes = (basis[2] * width, basis[3] * width)
    phase = (basis[0] * phases[j] + slopes[0] * phase_rates[j] + basis[1] * phases[j + 1]
             + slopes[1] * phase_rates[j + 1])
    amplitude = (basis[0] * amplitudes[j] + slopes[0] * amplitude_rates[j]
                 + basis[1] * amplitudes[j + 1] + slopes[1] * amplitude_rates[j + 1])
    after = t >= times[-1]
    return np.where(after, amplitudes[-1], amplitude), np.where(after, phases[-1], phase)
