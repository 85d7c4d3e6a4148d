"""Compiled loops of :func:`mcfit.phase_plane.phase_plane_differences` (numba).

Only the waveform fit's evaluation imports this module: numba's import costs far more
than a one-record run of the turning-point fit (README, "Dependencies"). The compiled
code is cached beside this file, else in the user's cache folder (numba's own fallback);
where neither is writable it is compiled in each process, uncached.
"""

from __future__ import annotations

import math

import numpy as np

from mcfit.compiled import compiled

__all__ = ["collocation_residuals", "fine_nodes", "held_coefficients", "hermite_changes",
           "newton_step", "newton_update"]

_HALF_PI = 0.5 * math.pi


@compiled
def _rates(amplitude, cos, sin, omega, a, b, c):
    """dA/dphi, dt/dphi and d(dA/dphi)/dA at one state (:func:`mcfit.phase_plane._rates`,
    the same operations)."""
    safe = amplitude if not amplitude < 1e-100 else 1e-100
    friction = c + safe * (b + a * safe)
    denominator = omega - _HALF_PI * friction / safe * cos
    if denominator < 1e-9 * omega:
        denominator = 1e-9 * omega
    slope = -_HALF_PI * friction * sin / denominator
    d_denominator = -_HALF_PI * (a - c / (safe * safe)) * cos
    d_slope = -_HALF_PI * sin * ((b + 2 * a * safe) - friction * d_denominator / denominator)
    return slope, 1.0 / denominator, d_slope / denominator


@compiled
def collocation_residuals(amplitudes, y0, phases, length, omega, free, integrate):
    """The collocation equations A = A_start + L*S*f(A) of every half-cycle of each set
    (A_start the end of the one before, ``y0`` for the first): residuals, and dt/dphi
    and d(dA/dphi)/dA at the collocation points.

    Parameters
    ----------
    amplitudes : ndarray, shape (m or 1, count, nodes)
        Amplitudes (U) at the collocation points; one row: every set's.
    y0, omega : ndarray, shape (m,)
        Amplitude at the start (U), angular frequency (rad/s).
    phases : ndarray, shape (m, count, nodes)
        Collocation phases (rad); after the first half-cycle the same in every
        half-cycle of every set (from 0 to pi: :func:`mcfit.phase_plane._grid`).
    length : ndarray, shape (m, count)
        Phase length (rad) of each half-cycle.
    free : ndarray, shape (3, m, count)
        a, b, c as each half-cycle sees them (0 where the set is held).
    integrate : ndarray, shape (nodes, nodes)
        Weights of the values at the collocation points in the interpolant's integral
        from 0 to each.

    Returns
    -------
    residual, time_rate, d_slope : ndarray, shape (m, count, nodes)
    """
    m, count, size = phases.shape
    rows = amplitudes.shape[0]
    residual = np.empty((m, count, size))
    time_rate = np.empty((m, count, size))
    d_slope = np.empty((m, count, size))
    cos, sin = np.empty((2, size)), np.empty((2, size))  # the first half-cycle; the rest
    slope = np.empty(size)
    for k in range(m):
        values = amplitudes[min(k, rows - 1)]
        for h in range(count):
            row = min(h, 1)
            if h == 0 or (k == 0 and h == 1):
                for n in range(size):
                    cos[row, n] = math.cos(phases[k, h, n])
                    sin[row, n] = math.sin(phases[k, h, n])
            for n in range(size):
                slope[n], time_rate[k, h, n], d_slope[k, h, n] = _rates(
                    values[h, n], cos[row, n], sin[row, n], omega[k], free[0, k, h],
                    free[1, k, h], free[2, k, h])
            entering = y0[k] if h == 0 else values[h - 1, size - 1]
            for n in range(size):
                integral = 0.0
                for i in range(size):
                    integral += slope[i] * integrate[n, i]
                residual[k, h, n] = values[h, n] - entering - length[k, h] * integral
    return residual, time_rate, d_slope


@compiled
def _solve(augmented, size):
    """Each system ``augmented[:, :, h]`` (size, size + k, count: a matrix and k
    right-hand sides) solved in place, every h in step, the solutions in
    ``augmented[:, size:, h]``: Gaussian elimination with partial pivoting (LAPACK's
    getrf and getrs, the same operations). A zero pivot leaves inf or NaN, which the
    caller's test of finite steps meets."""
    _, width, count = augmented.shape
    scale = np.empty(count)
    for j in range(size):
        for h in range(count):
            pivot, largest = j, abs(augmented[j, j, h])
            for i in range(j + 1, size):
                if abs(augmented[i, j, h]) > largest:
                    pivot, largest = i, abs(augmented[i, j, h])
            if pivot != j:
                for col in range(width):
                    augmented[j, col, h], augmented[pivot, col, h] = (
                        augmented[pivot, col, h], augmented[j, col, h])
            scale[h] = 1.0 / augmented[j, j, h]
        for i in range(j + 1, size):
            for h in range(count):
                augmented[i, j, h] *= scale[h]
            for col in range(j + 1, width):
                for h in range(count):
                    augmented[i, col, h] -= augmented[i, j, h] * augmented[j, col, h]
    for i in range(size - 1, -1, -1):
        for col in range(i + 1, size):
            for r in range(size, width):
                for h in range(count):
                    augmented[i, r, h] -= augmented[i, col, h] * augmented[col, r, h]
        for r in range(size, width):
            for h in range(count):
                augmented[i, r, h] /= augmented[i, i, h]


@compiled
def newton_step(residual, d_slope, length, integrate):
    """The Newton step of the collocation equations of all half-cycles at once (multiple
    shooting): each half-cycle's Jacobian I - L*S*diag(f'(A)) solved for its own step
    (right-hand side -G) and its response to a unit change of its start (right-hand
    side 1), then the ends' recursion e_k = o_k + r_k*e_(k-1), e_(-1) = 0, and each
    step its own plus its response times the end before it. The half-cycles' systems
    are solved side by side, the half-cycle the innermost loop (:func:`_solve`).

    Parameters
    ----------
    residual : ndarray, shape (m, count, nodes)
        Residuals G of each set's equations (:func:`collocation_residuals`).
    d_slope : ndarray, shape (m or 1, count, nodes)
        d(dA/dphi)/dA at the collocation points of the sets whose Jacobians are used;
        one row: set 0's for every set (the chord method).
    length : ndarray, shape (m or 1, count)
        Phase length (rad) of each half-cycle of those sets.
    integrate : ndarray, shape (nodes, nodes)
        As for :func:`collocation_residuals`.

    Returns
    -------
    ndarray, shape (m, count, nodes)
        The step of the amplitudes (U).
    """
    m, count, size = residual.shape
    rows = d_slope.shape[0]
    sets = m if rows == 1 else 1  # the sets each Jacobian serves
    step = np.empty((m, count, size))
    carried = np.empty((rows, count, size))
    augmented = np.empty((size, size + 1 + sets, count))  # J, 1, then each set's -G
    for j in range(rows):
        for n in range(size):
            for i in range(size):
                for h in range(count):
                    augmented[n, i, h] = ((1.0 if n == i else 0.0)
                                          - length[j, h] * integrate[n, i] * d_slope[j, h, i])
            for h in range(count):
                augmented[n, size, h] = 1.0
            for r in range(sets):
                for h in range(count):
                    augmented[n, size + 1 + r, h] = -residual[j + r, h, n]
        _solve(augmented, size)
        for h in range(count):
            for n in range(size):
                carried[j, h, n] = augmented[n, size, h]
                for r in range(sets):
                    step[j + r, h, n] = augmented[n, size + 1 + r, h]
    for k in range(m):  # each set's own steps become its steps
        r = carried[min(k, rows - 1)]
        end = 0.0
        for h in range(count):
            for n in range(size):
                step[k, h, n] += r[h, n] * end
            end = step[k, h, size - 1]
    return step


@compiled
def held_coefficients(amplitudes, start_phi, omega, coefficients):
    """Where each set is held: from the first half-cycle that starts at a turning point
    from which the swing may not cross 0 (:func:`mcfit.phase_plane._held`, the same
    operations); and a, b, c as each half-cycle sees them.

    Parameters
    ----------
    amplitudes : ndarray, shape (m, count, nodes)
        Amplitudes (U) at the collocation points.
    start_phi : ndarray, shape (m, count)
        Phase of each half-cycle's start (rad).
    omega : ndarray, shape (m,)
        Angular frequency (rad/s).
    coefficients : ndarray, shape (3, m)
        a, b, c of each set.

    Returns
    -------
    held : ndarray of bool, shape (m, count)
    free : ndarray, shape (3, m, count)
        a, b, c, 0 where the set is held.
    """
    m, count = start_phi.shape
    held = np.empty((m, count), dtype=np.bool_)
    free = np.empty((3, m, count))
    for k in range(m):
        a, b, c = coefficients[0, k], coefficients[1, k], coefficients[2, k]
        stuck = False
        for h in range(count):
            amplitude = amplitudes[k, h, 0]
            stuck = stuck or (start_phi[k, h] == 0.0 and omega[k] * amplitude
                              <= math.pi * (c + amplitude * (b + a * amplitude)))
            held[k, h] = stuck
            for i in range(3):
                free[i, k, h] = 0.0 if stuck else coefficients[i, k]
    return held, free


@compiled
def newton_update(amplitudes, step, held, time_rate, length, t_end, integrate):
    """``amplitudes`` moved by ``step`` in place, and the size of the step where it
    matters: the largest change and amplitude of the half-cycles that are not held and
    start before ``t_end`` (held ones last no time; :func:`mcfit.phase_plane._begins`).

    Parameters
    ----------
    amplitudes, step : ndarray, shape (m, count, nodes)
        Amplitudes (U) at the collocation points and their Newton step.
    held : ndarray of bool, shape (m, count)
    time_rate : ndarray, shape (m, count, nodes)
        dt/dphi (s) at the collocation points before the step.
    length : ndarray, shape (m, count)
        Phase length (rad) of each half-cycle.
    t_end : float
        End of the record (s).
    integrate : ndarray, shape (nodes, nodes)
        As for :func:`collocation_residuals`.

    Returns
    -------
    change, size : float
        Largest |step| and |amplitude| (U), 0 where no half-cycle counts; NaN where one
        of them is not finite.
    """
    m, count, size = amplitudes.shape
    change, largest, finite = 0.0, 0.0, True
    for k in range(m):
        elapsed = 0.0  # to the end of half-cycle h
        for h in range(count):
            duration = 0.0
            if not held[k, h]:
                for i in range(size):
                    duration += time_rate[k, h, i] * integrate[size - 1, i]
                duration *= length[k, h]
            elapsed += duration
            counts = not held[k, h] and elapsed - duration < t_end
            for n in range(size):
                amplitudes[k, h, n] += step[k, h, n]
                if counts:
                    moved, value = abs(step[k, h, n]), abs(amplitudes[k, h, n])
                    finite = finite and math.isfinite(moved + value)
                    change, largest = max(change, moved), max(largest, value)
    return (change, largest) if finite else (math.nan, math.nan)


@compiled
def fine_nodes(amplitudes, time_rates, start_phi, length, begins, free, omega, base,
               first, rest, evaluate, integrate, fine_s):
    """The solved half-cycles of each set on ``fine`` points each, as nodes of the
    interpolant: time, total phase, amplitude and their time derivatives (Eq. 20.55 in
    its phase plane, :func:`mcfit.phase_plane._rates`); from half-cycle ``first`` on,
    the state ``rest`` at rest.

    Parameters
    ----------
    amplitudes, time_rates : ndarray, shape (m, count, nodes)
        Amplitude (U) and dt/dphi (s) at each half-cycle's collocation points.
    start_phi, length, begins : ndarray, shape (m, count)
        Phase of the start (rad), phase length (rad) and start time (s) of each; after
        the first, every half-cycle runs from 0 to pi (:func:`mcfit.phase_plane._grid`).
    free : ndarray, shape (3, m, count)
        a, b, c as each half-cycle sees them (0 where the set is held).
    omega, base : ndarray, shape (m,)
        Angular frequency (rad/s); the multiple of pi each set's phase counts from.
    first : ndarray of int, shape (m,)
        Each set's first half-cycle at rest (``count`` where none is).
    rest : ndarray, shape (m, 3)
        Time, total phase and amplitude of each set at rest.
    evaluate, integrate : ndarray, shape (nodes, fine) and (nodes, nodes)
        Weights of the collocation values in the interpolant's values at ``fine_s``
        and in its integral from 0 to each collocation point.
    fine_s : ndarray, shape (fine,)
        The fine points' positions in a half-cycle, from 0 to 1.

    Returns
    -------
    ndarray, shape (5, m, count * fine)
        Times, total phases, amplitudes, phase rates and amplitude rates.
    """
    m, count, size = amplitudes.shape
    fine = fine_s.size
    out = np.zeros((5, m, count * fine))
    cos, sin = np.empty(fine), np.empty(fine)
    elapsed, fine_a, fine_t = np.empty(size), np.empty(fine), np.empty(fine)
    trig_of = -1  # 0: the first half-cycle's cos and sin in ``cos``, ``sin``; 1: the rest's
    for h in range(count):
        for k in range(m):
            at = h * fine
            if h >= first[k]:
                out[0, k, at:at + fine] = rest[k, 0]
                out[1, k, at:at + fine] = rest[k, 1]
                out[2, k, at:at + fine] = rest[k, 2]
                continue
            if h == 0 or trig_of != 1:  # after the first, every half-cycle's are alike
                trig_of = min(h, 1)
                for f in range(fine):
                    phi = start_phi[k, h] + length[k, h] * fine_s[f]
                    cos[f], sin[f] = math.cos(phi), math.sin(phi)
            for n in range(size):
                integral = 0.0
                for i in range(size):
                    integral += time_rates[k, h, i] * integrate[n, i]
                elapsed[n] = length[k, h] * integral
            fine_a[:] = 0.0
            fine_t[:] = 0.0
            for n in range(size):  # inner loops over the fine points: vectorised
                for f in range(fine):
                    fine_a[f] += amplitudes[k, h, n] * evaluate[n, f]
                    fine_t[f] += elapsed[n] * evaluate[n, f]
            a, b, c = free[0, k, h], free[1, k, h], free[2, k, h]
            for f in range(fine):
                slope, rate, _ = _rates(fine_a[f], cos[f], sin[f], omega[k], a, b, c)
                out[0, k, at + f] = begins[k, h] + fine_t[f]
                out[1, k, at + f] = (base[k] + h * math.pi
                                     + (start_phi[k, h] + length[k, h] * fine_s[f]))
                out[2, k, at + f] = fine_a[f]
                out[3, k, at + f] = 1.0 / rate
                out[4, k, at + f] = slope / rate
    return out


@compiled
def _node_changes(times, values, rates):
    """Per node of set 0 and moved set (rows 1 on): the change of the interpolated
    quantity at the node's fixed time, and its slopes in s at the start and the end of
    the interval the node starts (the rates' changes less the derivative in s of the
    interpolant's rate at either end times the node's shift in time), shape
    (count, sets, 3)."""
    m, count = times.shape
    table = np.zeros((count, m - 1, 3))
    for i in range(count):
        for k in range(m - 1):
            shift = times[k + 1, i] - times[0, i]
            table[i, k, 0] = (values[k + 1, i] - values[0, i]) - rates[0, i] * shift
    for i in range(count - 1):
        span = times[0, i + 1] - times[0, i]
        width = span if span > 0 else 1.0
        m0, m1 = rates[0, i], rates[0, i + 1]
        mean = (values[0, i + 1] - values[0, i]) / width
        for k in range(m - 1):
            start = times[k + 1, i] - times[0, i]
            end = times[k + 1, i + 1] - times[0, i + 1]
            table[i, k, 1] = ((rates[k + 1, i] - m0) * width
                              - (6 * mean - 4 * m0 - 2 * m1) * start)
            table[i, k, 2] = ((rates[k + 1, i + 1] - m1) * width
                              - (2 * m0 + 4 * m1 - 6 * mean) * end)
    return table


@compiled
def hermite_changes(t, times, phases, amplitudes, phase_rates, amplitude_rates):
    """x of set 0 at times ``t`` by cubic Hermite interpolation of its total phase and
    amplitude in time between its nodes, and the changes of the moved sets there to
    first order: the interpolant differentiated in its nodes' times, values and rates.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s), sorted.
    times, phases, amplitudes, phase_rates, amplitude_rates : ndarray, shape (m, count)
        Each set's nodes (row 0 the set the others are small changes of): times (s),
        total phase (rad), amplitude (U), and their time derivatives.

    Returns
    -------
    x : ndarray, shape (n,)
        x of set 0 (U); past its last node, held at the last node's state.
    changes : ndarray, shape (m - 1, n)
        x of each moved set less ``x`` (U), to first order: in an interval the change of
        phase or amplitude at a fixed time is itself a cubic Hermite interpolant in s, of
        its changes at the two nodes and its slopes there (:func:`_node_changes`).
    """
    m, count = times.shape
    phase_table = _node_changes(times, phases, phase_rates)
    amplitude_table = _node_changes(times, amplitudes, amplitude_rates)
    knots, p, q = times[0], phase_table, amplitude_table
    x = np.empty(t.size)
    changes = np.empty((m - 1, t.size))
    j = 0
    for i in range(t.size):
        # The interval of t[i]: the last node at or before it, at most the last but one
        # (the nodes and samples are sorted, but for rounding at half-cycle ends).
        while j < count - 2 and knots[j + 1] <= t[i]:
            j += 1
        span = knots[j + 1] - knots[j]
        width = span if span > 0 else 1.0
        s = 0.0
        if span > 0:
            s = (t[i] - knots[j]) / width
            s = 0.0 if s < 0.0 else (1.0 if s > 1.0 else s)
        s2 = s * s
        s3 = s2 * s
        h00, h01 = 2 * s3 - 3 * s2 + 1, -2 * s3 + 3 * s2
        h10, h11 = s3 - 2 * s2 + s, s3 - s2
        if t[i] >= knots[count - 1]:
            phase, amplitude = phases[0, count - 1], amplitudes[0, count - 1]
        else:
            phase = (h00 * phases[0, j] + h10 * width * phase_rates[0, j]
                     + h01 * phases[0, j + 1] + h11 * width * phase_rates[0, j + 1])
            amplitude = (h00 * amplitudes[0, j] + h10 * width * amplitude_rates[0, j]
                         + h01 * amplitudes[0, j + 1]
                         + h11 * width * amplitude_rates[0, j + 1])
        cos, sin = math.cos(phase), math.sin(phase)
        x[i] = amplitude * cos
        along = -amplitude * sin  # dx/dphase; dx/damplitude is cos
        for k in range(m - 1):
            changes[k, i] = (
                along * (h00 * p[j, k, 0] + h01 * p[j + 1, k, 0] + h10 * p[j, k, 1]
                         + h11 * p[j, k, 2])
                + cos * (h00 * q[j, k, 0] + h01 * q[j + 1, k, 0] + h10 * q[j, k, 1]
                         + h11 * q[j, k, 2]))
    return x, changes
