"""Compiled final swings of :func:`mcfit.phase_plane.phase_plane_differences` (numba): the
last swings after a Coulomb stop of a set and of its small changes (a Jacobian's moved
sets), as :func:`mcfit.phase_plane._neighbour_swings` describes them.

Each piece of a half-swing is solved by Chebyshev collocation in time for set 0 (Newton's
method on 2*nodes equations, x and xdot at the nodes, their Jacobian reduced to the xdot
unknowns and factored by a small LU with partial pivoting: numba's ``np.linalg.solve``
costs seconds of compilation); the moved sets take one Newton step from it with its
factors (the chord method), and their reversals one from set 0's. The numpy form of the
same pieces, each set on its own, is :func:`mcfit.phase_plane._final_swings` (it stays
free of numba for :func:`mcfit.phase_plane.phase_plane_motion`). Only the waveform fit's
evaluation imports this module (:mod:`mcfit.compiled`).
"""

from __future__ import annotations

import math

import numpy as np

from mcfit.compiled import compiled

__all__ = ["NEIGHBOURS", "DIFFERENT", "ENDLESS", "neighbour_swings"]

# The status of :func:`neighbour_swings`: solved; a set's swings differ in kind from set
# 0's (reverse, or are held, in another piece); the swings did not stop within MAX_PIECES.
NEIGHBOURS, DIFFERENT, ENDLESS = 0, 1, 2
_HALF_PI = 0.5 * math.pi
# As in mcfit.phase_plane (its numpy final swings), copied so that the compiled code in
# the cache cannot keep another module's old values; a test keeps them equal.
_PIECES = (1.0, 0.1)  # half periods: a first piece of a half-swing, the others
_ITERATIONS = 30  # Newton iterations on a piece of set 0
_MAX_PIECES = 400
_GRID = 32  # intervals of a piece where a reversal is looked for
_REVERSAL_ITERATIONS = 60


@compiled
def _chebval(at, coefficients):
    """The Chebyshev series ``coefficients`` at ``at`` in [-1, 1] (Clenshaw's recurrence,
    numpy's ``chebval`` order)."""
    size = coefficients.size
    if size == 1:
        return coefficients[0]
    if size == 2:
        return coefficients[0] + coefficients[1] * at
    twice = 2 * at
    c0, c1 = coefficients[size - 2], coefficients[size - 1]
    for i in range(3, size + 1):
        c0, c1 = coefficients[size - i] - c1, c0 + c1 * twice
    return c0 + c1 * at


@compiled
def _sign(value):
    """np.sign of one float (NaN stays NaN)."""
    if value > 0:
        return 1.0
    if value < 0:
        return -1.0
    return value  # 0.0, -0.0 or NaN


@compiled
def _residual(nodes, x0, v0, length, omega, a, b, c, sense, integrate, out):
    """Residuals of a piece's collocation equations into ``out`` (shape (2*nodes,)):
    x = x0 + integral of xdot, xdot = xdot0 + integral of the force, of one set at
    ``nodes`` (x, then xdot, at the collocation points)."""
    n = integrate.shape[0]
    push = sense * (_HALF_PI * omega)
    w2 = omega * omega
    force = np.empty(n)
    for j in range(n):
        x, v = nodes[j], nodes[n + j]
        amplitude = max(math.sqrt(x * x + v * v / w2), 1e-300)
        force[j] = -w2 * x - push * (c + amplitude * (b + a * amplitude))
    for i in range(n):
        moved, pushed = 0.0, 0.0
        for j in range(n):
            moved += integrate[i, j] * nodes[n + j]
            pushed += integrate[i, j] * force[j]
        out[i] = nodes[i] - x0 - length * moved
        out[n + i] = nodes[n + i] - v0 - length * pushed


@compiled
def _jacobian(nodes, length, omega, a, b, c, sense, integrate, reduced, weights):
    """The Jacobian of :func:`_residual` in ``nodes``, [[I, -L*A], [L*A*D1, I + L*A*D2]]
    (A: ``integrate``, L: ``length``, D1 and D2 diagonal), reduced to the xdot block's
    Schur complement I + L*A*(D2 + L*D1*A) into ``reduced``; D1 into ``weights``."""
    n = integrate.shape[0]
    push = sense * (_HALF_PI * omega)
    w2 = omega * omega
    inner = np.empty((n, n))  # D2 + L*D1*A
    for i in range(n):
        x, v = nodes[i], nodes[n + i]
        amplitude = max(math.sqrt(x * x + v * v / w2), 1e-300)
        slope = push * (b + 2 * a * amplitude) / amplitude
        weights[i] = w2 + slope * x
        for j in range(n):
            inner[i, j] = length * weights[i] * integrate[i, j]
        inner[i, i] += slope * v / w2
    row = np.empty(n)  # a row of L*A*inner, summed apart (the compiler vectorises it)
    for i in range(n):
        _fill(row, 0.0)
        for k in range(n):
            scale = length * integrate[i, k]
            source = inner[k]
            for j in range(n):
                row[j] += scale * source[j]
        _copy(row, reduced[i])
        reduced[i, i] += 1.0


@compiled
def _step(factors, pivots, weights, length, integrate, residual):
    """``residual`` (of x, then of xdot) replaced by the Newton step, the solution of
    the Jacobian's system from its reduced ``factors`` (:func:`_jacobian`): the xdot
    part from the Schur complement, then the x part."""
    n = integrate.shape[0]
    rhs = residual[n:]  # a view: the xdot part, solved in place
    for i in range(n):
        pushed = 0.0
        for j in range(n):
            pushed += integrate[i, j] * (weights[j] * residual[j])
        rhs[i] -= length * pushed
    _solve(factors, pivots, rhs)
    for i in range(n):
        moved = 0.0
        for j in range(n):
            moved += integrate[i, j] * rhs[j]
        residual[i] += length * moved


@compiled
def _factor(matrix, pivots):
    """LU factors of ``matrix`` in place, rows swapped by partial pivoting (``pivots``:
    the row swapped with each), as LAPACK's getrf; a zero pivot leaves inf or NaN."""
    size = matrix.shape[0]
    for k in range(size):
        row, largest = k, abs(matrix[k, k])
        for i in range(k + 1, size):
            if abs(matrix[i, k]) > largest:
                row, largest = i, abs(matrix[i, k])
        pivots[k] = row
        if row != k:
            for j in range(size):
                matrix[k, j], matrix[row, j] = matrix[row, j], matrix[k, j]
        inverse = 1.0 / matrix[k, k]
        for i in range(k + 1, size):
            factor = matrix[i, k] * inverse
            matrix[i, k] = factor
            for j in range(k + 1, size):
                matrix[i, j] -= factor * matrix[k, j]


@compiled
def _solve(factors, pivots, rhs):
    """``rhs`` replaced by the solution of the system factored by :func:`_factor`."""
    size = rhs.size
    for k in range(size):
        rhs[k], rhs[pivots[k]] = rhs[pivots[k]], rhs[k]
    for i in range(size):
        for j in range(i):
            rhs[i] -= factors[i, j] * rhs[j]
    for i in range(size - 1, -1, -1):
        for j in range(i + 1, size):
            rhs[i] -= factors[i, j] * rhs[j]
        rhs[i] /= factors[i, i]


@compiled
def _start(x0, v0, length, omega, a, b, c, sense, s, nodes):
    """A cosine about the centre of the friction at the start of a piece, at the
    collocation points ``s`` (in [0, 1]), into ``nodes``."""
    n = s.size
    size = math.hypot(x0, v0 / omega)
    centre = -sense * _HALF_PI / omega * (c + size * (b + a * size))
    for j in range(n):
        phase = omega * length * s[j]
        nodes[j] = centre + (x0 - centre) * math.cos(phase) + (v0 / omega) * math.sin(phase)
        nodes[n + j] = -(x0 - centre) * omega * math.sin(phase) + v0 * math.cos(phase)


@compiled
def _newton(x0, v0, length, omega, a, b, c, sense, integrate, nodes, factors, pivots,
            weights):
    """Newton's method on a piece of one set from ``nodes`` (solved in place), until
    the step is 1e-14 of the state's size or stops falling; ``factors``, ``pivots`` and
    ``weights``: the Jacobian of the last step (:func:`_jacobian`, :func:`_factor`)."""
    size = math.hypot(x0, v0 / omega)
    step = np.empty(nodes.size)
    last = math.inf
    for _ in range(_ITERATIONS):
        _residual(nodes, x0, v0, length, omega, a, b, c, sense, integrate, step)
        _jacobian(nodes, length, omega, a, b, c, sense, integrate, factors, weights)
        _factor(factors, pivots)
        _step(factors, pivots, weights, length, integrate, step)
        change = 0.0
        for i in range(nodes.size):
            nodes[i] -= step[i]
            if abs(step[i]) > change or step[i] != step[i]:
                change = abs(step[i])
        change /= size
        if change <= 1e-14 or change > 0.5 * last or change != change:
            break
        last = change


@compiled
def _chord(nodes, position, velocity, length, omega, a, b, c, sense, integrate, factors,
           pivots, weights):
    """The moved sets' nodes (rows 1 on) one Newton step from set 0's (row 0) with its
    Jacobian (``factors``, ``pivots``, ``weights``: :func:`_newton`'s); False where a
    step left residuals not of the order of its square, or of the rounding of set 0's
    values: the step is no derivative (:func:`mcfit.phase_plane._small`)."""
    n = integrate.shape[0]
    floor = 0.0  # 1e-10 of set 0's largest x, or xdot times the piece's length
    for j in range(n):
        floor = max(floor, abs(nodes[0, j]), abs(nodes[0, n + j] * length[0]))
    floor *= 1e-10
    step, residual = np.empty(2 * n), np.empty(2 * n)
    for k in range(1, nodes.shape[0]):
        _residual(nodes[0], position[k], velocity[k], length[k], omega[k], a[k], b[k],
                  c[k], sense[k], integrate, step)
        _step(factors, pivots, weights, length[0], integrate, step)
        largest = 0.0
        for i in range(2 * n):
            nodes[k, i] = nodes[0, i] - step[i]
            largest = max(largest, abs(step[i]))
        _residual(nodes[k], position[k], velocity[k], length[k], omega[k], a[k], b[k],
                  c[k], sense[k], integrate, residual)
        for i in range(2 * n):
            if not abs(residual[i]) <= 1e-3 * largest + floor:
                return False
    return True


@compiled
def _reversal(v, sense, length, derivative):
    """The first time in (0, length] where the velocity of sign ``sense`` (Chebyshev
    coefficients ``v`` on the piece) reaches 0, by Newton's method inside the bracket
    of a grid of _GRID intervals; ``length`` where it does not."""
    width = length / _GRID
    found = 0
    for i in range(1, _GRID + 1):
        time = i * width if i < _GRID else length
        if not sense * _chebval(2 * time / length - 1, v) > 0:
            found = i
            break
    if found == 0:
        return length
    low, high = (found - 1) * width, found * width if found < _GRID else length
    rate = _times(derivative, v) * (2 / length)
    time = 0.5 * (low + high)
    for _ in range(_REVERSAL_ITERATIONS):
        value = _chebval(2 * time / length - 1, v)
        if value == 0.0:
            break
        if sense * value > 0:
            low = time
        else:
            high = time
        then = time
        time = time - value / _chebval(2 * time / length - 1, rate)
        if not low < time < high:
            time = 0.5 * (low + high)
        if abs(time - then) <= 1e-15 * length:
            break
    return time


@compiled
def _kind(position, velocity, omega, a, b, c, sense):
    """The sense of each set's velocity (that of its coming swing where at rest) into
    ``sense``; 1 where the sets are held (the spring does not overcome the friction at
    rest), 0 where they swing, -1 where they differ in either."""
    held = False
    for k in range(position.size):
        size = abs(position[k])
        spring = omega[k] * omega[k] * size
        friction = _HALF_PI * omega[k]
        stuck = velocity[k] == 0.0 and (spring <= friction * c[k] or spring <= friction * (
            c[k] + size * (b[k] + a[k] * size)))
        sense[k] = _sign(velocity[k]) if velocity[k] != 0.0 else -_sign(position[k])
        if k == 0:
            held = stuck
        elif stuck != held or sense[k] != sense[0]:
            return -1
    return 1 if held else 0


@compiled
def _spans(coefficients, sense, length, derivative, grid, spans):
    """Each set's time to its reversal in the piece into ``spans`` (``length`` where it
    has none), set 0's found on its interpolant, the others' one Newton step from it;
    whether the sets reverse (-1 where some do and others do not)."""
    m, n = coefficients.shape[0], derivative.shape[1]
    span = _reversal(coefficients[0, n:], sense[0], length[0], derivative)
    turns = span < length[0]
    for k in range(1, m):
        reversing = False
        for g in range(1, grid.shape[0]):
            value = 0.0
            for j in range(n):
                value += grid[g, j] * coefficients[k, n + j]
            if sense[k] * value <= 0:
                reversing = True
                break
        if reversing != turns:
            return -1
    for k in range(m):
        spans[k] = length[k]
        if turns:
            at = 2 * span / length[k] - 1
            rate = _chebval(at, _times(derivative, coefficients[k, n:])) * 2 / length[k]
            spans[k] = span if k == 0 else span - _chebval(at, coefficients[k, n:]) / rate
    return 1 if turns else 0


@compiled
def _values(local, first, stop, start, length, offset, coefficients, derivative, x,
            changes):
    """x of set 0 at its times ``local[first:]`` before ``stop`` in a piece (``start``,
    ``length`` and Chebyshev ``coefficients`` of x of each set), into ``x``, and the
    other sets' changes: each set's polynomial at set 0's position in the piece plus set
    0's rate there times the shift of the position (the sets' stops are ``offset``
    before set 0's). Returns the index of the first time after the piece."""
    last = first
    while last < local.size and local[last] < stop:
        last += 1
    count, n = last - first, derivative.shape[1]
    at, basis = np.empty(count), np.empty((n, count))
    for i in range(count):
        at[i] = 2 * (local[first + i] - start[0]) / length[0] - 1
        basis[0, i], basis[1, i] = 1.0, at[i]
    for j in range(2, n):  # Chebyshev polynomials at the times, as chebvander
        for i in range(count):
            basis[j, i] = basis[j - 1, i] * (2 * at[i]) - basis[j - 2, i]
    rate = _combined(basis[:n - 1], _times(derivative, coefficients[0, :n]))
    _copy(_combined(basis, coefficients[0, :n]), x[first:last])
    difference = np.empty(n)
    for k in range(1, coefficients.shape[0]):
        for j in range(n):
            difference[j] = coefficients[k, j] - coefficients[0, j]
        change = _combined(basis, difference)
        for i in range(count):
            shift = 2 * (local[first + i] + offset[k] - start[k]) / length[k] - 1
            changes[k - 1, first + i] = change[i] + rate[i] * (shift - at[i])
    return last


@compiled
def _combined(basis, weights):
    """The sum of the rows of ``basis`` with ``weights`` (a loop over the columns
    innermost, which the compiler vectorises)."""
    out = np.zeros(basis.shape[1])
    for j in range(basis.shape[0]):
        for i in range(basis.shape[1]):
            out[i] += weights[j] * basis[j, i]
    return out


@compiled
def _copy(source, target):
    """``target[:] = source``, a loop (a slice assignment compiles its error message)."""
    for i in range(source.size):
        target[i] = source[i]


@compiled
def _fill(target, value):
    """``target[:] = value``, a loop."""
    for i in range(target.size):
        target[i] = value


@compiled
def _times(matrix, vector):
    """``matrix @ vector``, a loop (numba's matmul calls BLAS, for sizes too small)."""
    out = np.zeros(matrix.shape[0])
    for i in range(matrix.shape[0]):
        for j in range(matrix.shape[1]):
            out[i] += matrix[i, j] * vector[j]
    return out


@compiled
def _fit(nodes, fit, coefficients):
    """Chebyshev coefficients of x and of xdot of each set from their node values."""
    n = fit.shape[0]
    for k in range(nodes.shape[0]):
        _copy(_times(fit, nodes[k, :n]), coefficients[k, :n])
        _copy(_times(fit, nodes[k, n:]), coefficients[k, n:])


@compiled
def _evaluated(coefficients, spans, length, turns, position, velocity, now):
    """Each set's state at the end of its piece (at rest where it reversed)."""
    n = coefficients.shape[1] // 2
    for k in range(coefficients.shape[0]):
        at = 2 * spans[k] / length[k] - 1
        position[k] = _chebval(at, coefficients[k, :n])
        velocity[k] = 0.0 if turns else _chebval(at, coefficients[k, n:])
        now[k] += spans[k]


@compiled
def _kept(kept, count, state, nodes):
    """``kept`` with row ``count`` set to ``state`` and ``nodes`` (doubled when full)."""
    if count == kept.shape[0]:
        larger = np.empty((2 * count, kept.shape[1]))
        for i in range(count):
            _copy(kept[i], larger[i])
        kept = larger
    _copy(state, kept[count, :3])
    _copy(nodes, kept[count, 3:])
    return kept


@compiled
def neighbour_swings(local, offset, start, omega, a, b, c, last, s, integrate, fit,
                     derivative, grid):
    """x of set 0 at its times since its stop, and the other sets' changes there, to
    first order in the sets' differences.

    Parameters
    ----------
    local : ndarray, shape (n,)
        Times (s) since set 0's stop, sorted, >= 0.
    offset : ndarray, shape (m,)
        Set 0's stop time less each set's (s).
    start : ndarray, shape (m,)
        The displacement (U) at each set's stop, at rest.
    omega, a, b, c : ndarray, shape (m,)
        Each set's angular frequency (rad/s) and coefficients (1/(U*s), 1/s, U/s).
    last : ndarray, shape (pieces, 3 + 2*nodes)
        Set 0's pieces of a last call, each its state (x, xdot/omega, length*omega) and
        x and xdot at its nodes: a piece that starts within 1e-3 of the same state starts
        Newton's method there.
    s, integrate, fit, derivative, grid : ndarray
        Collocation points in [0, 1] (nodes,); the weights that integrate node values
        from 0 to each node (nodes, nodes); node values -> Chebyshev coefficients (nodes,
        nodes); coefficients -> those of the derivative (nodes - 1, nodes); coefficients
        -> values at _GRID + 1 points of [-1, 1] (_GRID + 1, nodes).

    Returns
    -------
    status : int
        NEIGHBOURS, DIFFERENT (x and changes are then empty) or ENDLESS.
    x : ndarray, shape (n,)
        x of set 0 (U).
    changes : ndarray, shape (m - 1, n)
        Each other set's x less set 0's (U).
    kept : ndarray, shape (pieces, 3 + 2*nodes)
        Set 0's pieces of this call, for ``last`` of the next.
    """
    m, n = start.size, s.size
    position, velocity, now = start.copy(), np.zeros(m), np.zeros(m)
    sense, length, spans = np.empty(m), np.empty(m), np.empty(m)
    nodes, coefficients = np.empty((m, 2 * n)), np.empty((m, 2 * n))
    factors, pivots, weights = np.empty((n, n)), np.empty(n, dtype=np.int64), np.empty(n)
    x, changes = np.empty(local.size), np.empty((m - 1, local.size))
    kept = np.empty((max(last.shape[0], 4), 3 + 2 * n))
    pieces, done = np.int64(0), np.int64(0)  # not literal: one compilation of callees
    different = (DIFFERENT, np.empty(0), np.empty((m - 1, 0)), kept[:0])
    for _ in range(_MAX_PIECES):
        kind = _kind(position, velocity, omega, a, b, c, sense)
        if kind < 0:
            return different
        if kind == 1 or now[0] >= local[-1]:
            break
        for k in range(m):
            length[k] = (_PIECES[0] if velocity[k] == 0.0 else _PIECES[1]) * (
                math.pi / omega[k])
        state = np.array([position[0], velocity[0] / omega[0], length[0] * omega[0]])
        if pieces < last.shape[0] and max(abs(last[pieces, 0] - state[0]), abs(
                last[pieces, 1] - state[1]), abs(last[pieces, 2] - state[2])) <= 1e-3 * (
                abs(state[0]) + abs(state[1])):
            _copy(last[pieces, 3:], nodes[0])
        else:
            _start(position[0], velocity[0], length[0], omega[0], a[0], b[0], c[0],
                   sense[0], s, nodes[0])
        _newton(position[0], velocity[0], length[0], omega[0], a[0], b[0], c[0], sense[0],
                integrate, nodes[0], factors, pivots, weights)
        kept = _kept(kept, pieces, state, nodes[0])
        pieces += 1
        if not _chord(nodes, position, velocity, length, omega, a, b, c, sense, integrate,
                      factors, pivots, weights):
            return different
        _fit(nodes, fit, coefficients)
        turns = _spans(coefficients, sense, length, derivative, grid, spans)
        if turns < 0:
            return different
        done = _values(local, done, now[0] + spans[0], now, length, offset, coefficients,
                       derivative, x, changes)
        _evaluated(coefficients, spans, length, turns == 1, position, velocity, now)
    else:
        return (ENDLESS, np.empty(0), np.empty((m - 1, 0)), kept[:0])
    _fill(x[done:], position[0])
    for k in range(1, m):
        _fill(changes[k - 1, done:], position[k] - position[0])
    return NEIGHBOURS, x, changes, kept[:pieces]
