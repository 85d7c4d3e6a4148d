"""Steps of the equilibrium in mid-record (a sensor knocked, a clamp slipping).

The local mean of the signal over whole periods, taken three times (a kernel of three
boxcars of one period: its response has a triple zero at the oscillation's frequency and
its harmonics, so a decaying oscillation leaves a residue of order ``(1/(2*Q))**3`` of its
amplitude), is computed on a grid of ``_GRID`` points a period from the record's running
integral: one pass over the samples. A step of the equilibrium makes it rise by the step
over three periods. Its jumps over four periods, ``m(t + 2T) - m(t - 2T)``, are compared
with their scatter (the median absolute deviation over the record): a jump ``_Z`` times
beyond it and at least ``_SMALLEST`` of the amplitude there, with the oscillation on both
sides (a record held still before its release, or an oscillation stopped by dry friction
away from its centre, has none on one side), where the local mean is a line with a step
of the kernel's shape within ``_SHAPE`` of the step, is a step. Its time and size are
fitted to that shape; up to ``_MOST`` steps are found. The jumps of a step-free record
stand 1.6 to 3.3 times their scatter beyond it (white noise, drift, a random walk, a hum;
the tests in tests/test_equilibrium_step.py hold these figures).

numpy only, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mcfit.turning.common import _NORMAL_MAD, _median

__all__ = ["EquilibriumStep", "find_equilibrium_steps", "subtract_equilibrium_steps"]

_GRID = 16            # grid points per period of the local mean
_REACH = 2.0          # the jump is m(t + _REACH*T) - m(t - _REACH*T), periods
_SIDE = 3.0           # periods of level fitted on each side of the step's ramp
_Z = 8.0              # a step stands this many times beyond the scatter of the jumps
_SMALLEST = 0.01      # ... and is at least this fraction of the local amplitude
_LARGEST = 5.0        # ... and at most this many times the amplitude on either side,
_LOUD = 3.0           # ... which is this many noise sigmas at least
_SHAPE = 0.15         # rms misfit of the step's shape, as a fraction of the step, at most
_HOLD = 12.0          # periods each side over which the levels must hold
_MOST = 3             # steps found at most
_FEWEST_JUMPS = 8     # periods of jumps a record needs for their scatter
_BLOCK = 1 << 20      # samples per block of the running integral


@dataclass(frozen=True)
class EquilibriumStep:
    """A step of the equilibrium: ``size`` (signal units) at ``time`` (time units),
    ``amplitude`` the oscillation's local amplitude there (from the local variance)."""

    time: float
    size: float
    amplitude: float

    def warning(self, first, there):
        """The step, said in one line, as a fraction of the ``first`` amplitude and of the
        amplitude ``there``."""
        return (f"the equilibrium jumps by {self.size:.3g} ({_percent(self.size, first)} of "
                f"the first amplitude, {_percent(self.size, there)} of the amplitude there) "
                f"at t = {self.time:.4g} (a knock or slip?): modelled as a step")

    def to_dict(self):
        """Time, size and the amplitude there, as plain data."""
        return {"time": float(self.time), "size": float(self.size),
                "amplitude": float(self.amplitude)}


def _percent(size, amplitude):
    return f"{100.0 * abs(size) / amplitude:.2g} %" if amplitude > 0 else "an unknown share"


def find_equilibrium_steps(t, x, period, noise, gaps=()):
    """The steps of the equilibrium in a record, in time order (a tuple, empty if none).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times, increasing.
    x : ndarray, shape (n,)
        Finite samples.
    period : float
        Oscillation period (time units of ``t``).
    noise : float
        Sample noise sigma (the amplitude is measured above it; NaN counts as 0).
    gaps : sequence of (float, float)
        Gaps in the record: the local mean is not taken across them.
    """
    if not (np.isfinite(period) and period > 0) or t[-1] - t[0] < 4 * (_SIDE + 2) * period:
        return ()
    noise = float(noise) if np.isfinite(noise) else 0.0
    centres, mean, amplitude = _local_mean(t, x, period, noise, gaps)
    if centres.size < 2 * _GRID * (_REACH + _FEWEST_JUMPS):
        return ()
    steps = []
    for _ in range(_MOST):
        step = _strongest_step(centres, mean, amplitude, period, noise)
        if step is None:
            break
        steps.append(step)
        mean = mean - step.size * _ramp((centres - step.time) / period)
    return tuple(sorted(steps, key=lambda s: s.time))


def subtract_equilibrium_steps(t, x, steps):
    """x with the steps taken out (the level after each brought back to the one before):
    a new array."""
    out = np.array(x, dtype=np.float64)
    for step in steps:
        out[np.searchsorted(t, step.time):] -= step.size
    return out


def _local_mean(t, x, period, noise, gaps):
    """(centres, mean, amplitude): the local mean of x under the three-boxcar kernel on
    a grid, and the local amplitude sqrt(2*(variance - noise**2)); NaN where the kernel
    reaches past the record's ends or across a gap."""
    h = period / _GRID
    nodes = t[0] + h * np.arange(int((t[-1] - t[0]) / h) + 1)
    reference = float(x[0])
    first, second = _integrals_at(t, x - reference, nodes)
    # The boxcars: one exact over the samples, two over the grid (a sum of _GRID points
    # a period apart vanishes for the oscillation and its harmonics up to _GRID - 1).
    mean = _moving(_moving((first[_GRID:] - first[:-_GRID]) / period))
    square = _moving(_moving((second[_GRID:] - second[:-_GRID]) / period))
    centres = _moving(_moving(nodes[:-_GRID] + 0.5 * period))
    variance = square - mean * mean - noise * noise
    amplitude = np.sqrt(2.0 * np.maximum(variance, 0.0))
    bad = np.zeros(centres.size, dtype=bool)
    for start, end in gaps:
        bad |= (centres + 1.5 * period > start) & (centres - 1.5 * period < end)
    mean = np.where(bad, np.nan, mean + reference)
    return centres, mean, np.where(bad, np.nan, amplitude)


def _moving(values):
    """Means of _GRID neighbouring values."""
    total = np.concatenate([[0.0], np.cumsum(values)])
    return (total[_GRID:] - total[:-_GRID]) / _GRID


def _integrals_at(t, x, nodes):
    """Running integrals of x and of x**2 (their linear interpolants' trapezoids) from
    t[0] to each node, by blocks of samples."""
    first = np.empty(nodes.size)
    second = np.empty(nodes.size)
    carry = np.zeros(2)
    for start in range(0, max(t.size - 1, 1), _BLOCK):
        stop = min(start + _BLOCK, t.size - 1)
        tt, xx = t[start:stop + 1], x[start:stop + 1]
        dt = np.diff(tt)
        for out, values, k in ((first, xx, 0), (second, xx * xx, 1)):
            running = carry[k] + np.concatenate(
                [[0.0], np.cumsum(0.5 * (values[1:] + values[:-1]) * dt)])
            lo = np.searchsorted(nodes, tt[0], side="left")
            hi = np.searchsorted(nodes, tt[-1], side="right")
            out[lo:hi] = np.interp(nodes[lo:hi], tt, running)
            carry[k] = running[-1]
    return first, second


def _ramp(z):
    """The rise of the three-boxcar kernel's local mean over a unit step at 0, at ``z``
    periods from it (the distribution function of a sum of three uniform variables)."""
    u = np.clip(np.asarray(z, dtype=float) + 1.5, 0.0, 3.0)
    middle = (-2.0 * u ** 3 + 9.0 * u ** 2 - 9.0 * u + 3.0) / 6.0
    return np.where(u < 1.0, u ** 3 / 6.0, np.where(u < 2.0, middle, 1.0 - (3.0 - u) ** 3 / 6.0))


def _strongest_step(centres, mean, amplitude, period, noise):
    """The largest jump of the local mean, as an :class:`EquilibriumStep` if it is one."""
    reach = int(round(_REACH * _GRID))
    jumps = np.full(mean.size, np.nan)
    jumps[reach:-reach] = mean[2 * reach:] - mean[:-2 * reach]
    valid = np.isfinite(jumps)
    if np.count_nonzero(valid) < _FEWEST_JUMPS * _GRID:
        return None
    deviation = np.abs(jumps - _median(jumps[valid]))
    scatter = _median(deviation[valid]) / _NORMAL_MAD
    # Candidates where the step's shape can be fitted: a low Q's residue at the record's
    # start, far beyond a faint noise's scatter, is no candidate and hides none.
    half = int(round((1.5 + _SIDE) * _GRID)) + _GRID
    deviation[:half] = deviation[-half:] = np.nan
    if not np.any(np.isfinite(deviation)):
        return None
    k = int(np.nanargmax(deviation))
    if not deviation[k] > _Z * scatter:
        return None
    step = _fitted_step(centres, mean, k, period)
    if step is None:
        return None
    time, size, misfit = step
    before, after = (amplitude[int(np.clip(np.searchsorted(centres, time + side * period),
                                           0, centres.size - 1))] for side in (-_REACH, _REACH))
    there = 0.5 * (before + after)
    # The oscillation on both sides: not a record held still before its release, nor one
    # stopped by dry friction away from its centre.
    loud = min(before, after) >= max(abs(size) / _LARGEST, _LOUD * noise)
    if not (abs(size) > _Z * scatter and misfit <= _SHAPE * abs(size)
            and _SMALLEST * there <= abs(size) and loud
            and _levels_hold(centres, mean, time, size, period)):
        return None
    return EquilibriumStep(float(time), float(size), float(there))


def _levels_hold(centres, mean, time, size, period):
    """Whether the local mean holds its level on each side of a step at ``time``, from the
    ramp's end out to _HOLD periods (where the record reaches; a period's grid at least):
    a line within _SHAPE of the step there, the two lines ``size`` apart at the step
    within twice that. A slow oscillation (a second mode's remnant under a fast
    one) makes half a period look like a step, and does not hold."""
    sides = []
    for inner, outer in ((-_HOLD, -2.0), (2.0, _HOLD)):
        inside = ((centres >= time + inner * period) & (centres <= time + outer * period)
                  & np.isfinite(mean))
        if np.count_nonzero(inside) < _GRID:
            return False
        z = (centres[inside] - time) / period
        line = np.polyfit(z, mean[inside], 1)
        if np.sqrt(np.mean((mean[inside] - np.polyval(line, z)) ** 2)) > _SHAPE * abs(size):
            return False
        sides.append(np.polyval(line, 0.0))
    return abs(sides[1] - sides[0] - size) <= _SHAPE * abs(size) * 2


def _fitted_step(centres, mean, k, period):
    """(time, size, rms misfit) of a line with a step of the kernel's shape fitted to the
    local mean within _SIDE periods beyond the ramp about grid point k, the time searched
    on the grid within a period of it and refined by a parabola; None off the record."""
    half = int(round((1.5 + _SIDE) * _GRID))
    lo, hi = k - half - _GRID, k + half + _GRID + 1
    if lo < 0 or hi > mean.size or not np.all(np.isfinite(mean[lo:hi])):
        return None
    misfits, fits = [], []
    for j in range(k - _GRID, k + _GRID + 1):
        z = (centres[j - half:j + half + 1] - centres[j]) / period
        design = np.column_stack([np.ones_like(z), z, _ramp(z)])
        rows = mean[j - half:j + half + 1]
        solution = np.linalg.lstsq(design, rows, rcond=None)[0]
        misfits.append(float(np.sqrt(np.mean((rows - design @ solution) ** 2))))
        fits.append(solution[2])
    best = int(np.argmin(misfits))
    offset = 0.0
    if 0 < best < len(misfits) - 1:
        a, b, c = (m * m for m in misfits[best - 1:best + 2])
        curvature = a - 2.0 * b + c
        offset = 0.5 * (a - c) / curvature if curvature > 0 else 0.0
    j = k - _GRID + best
    time = centres[j] + offset * (centres[1] - centres[0])
    return time, fits[best], misfits[best]
