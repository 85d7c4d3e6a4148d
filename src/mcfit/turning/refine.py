"""Stage 2 and 3: coarse extrema split by crossings with hysteresis, then the half-cycle
fits repeated, re-centring the windows and refining the equilibrium."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mcfit.errors import RecordError, TooFewTurningPoints
from mcfit.turning.common import _BLOCK_SAMPLES, _segment_groups
from mcfit.turning.equilibrium import _equilibrium_correction
from mcfit.turning.period import _period_estimate
from mcfit.turning.release import _held_crests
from mcfit.turning.result import MIN_TURNING_POINTS
from mcfit.turning.windows import (_clipped, _fit_windows, _local_decay_rates,
                                   _local_half_periods)

# Most passes of the half-cycle fits.
_REFINE_PASSES = 6
# The coarse search smooths over this fraction of a cycle.
_SMOOTHING_CYCLES = 1 / 8
# A crest is a half-cycle from the zero line by this many noise sigmas of the smoothed
# signal; the noise must be under _MAX_NOISE_SWING of the signal's swing.
_HYSTERESIS_Z = 4.0
_MAX_NOISE_SWING = 0.3


@dataclass
class RefinedCrests:
    """Crests after the repeated half-cycle fits."""

    centres: np.ndarray  # window centres (crest times of the last pass but one)
    signs: np.ndarray
    valid: np.ndarray
    gamma: np.ndarray  # rows: decay rate and its slope at each crest
    period: float
    line: tuple  # equilibrium (e0, e1, t_ref)


def _refine(samples, centres, signs, line, period, noise, held):
    """Half-cycle fits repeated, each pass re-centring the windows on the fitted crests and
    refining the equilibrium from the alternation of maxima and minima, until the shifts are
    within the noise (at most _REFINE_PASSES). Crests before ``held`` count nowhere."""
    e0, e1, t_ref = line
    gamma = np.zeros((2, centres.size))  # decay rate and its slope at each crest
    valid = np.ones(centres.size, dtype=bool)
    for refinement in range(_REFINE_PASSES):
        half = _local_half_periods(centres, period, valid)
        fit = _fit_windows(samples, centres, signs, half, gamma, e0, e1, t_ref)
        # Flattened crests would bias the equilibrium update.
        fit.valid &= ~_clipped(fit, signs) & (np.arange(centres.size) >= _held_crests(
            centres, held, period))
        delta0, delta1 = _equilibrium_correction(centres, fit, half, t_ref, gamma,
                                                  samples.t[-1] - samples.t[0])
        e0, e1 = e0 + delta0, e1 + delta1
        # The amplitudes as the corrected line gives them, for the next pass's decay
        # rates: else the old line's alternation bends the envelope the other way.
        fit.y -= fit.offset_gain * (delta0 + delta1 * (centres - t_ref))
        settled = refinement > 0 and _shifts_within_noise(fit, half, noise)
        centres, signs, valid, y = _recentred(centres, signs, fit, half)
        del fit  # not beside the next pass's (a hundred bytes a crest)
        half = _local_half_periods(centres, period, valid)
        gamma = _local_decay_rates(centres, y, np.pi / half, valid)
        period = _period_estimate(centres, signs, valid, period)
        if settled:
            break
    return RefinedCrests(centres, signs, valid, gamma, period, (e0, e1, t_ref))


def _recentred(centres, signs, fit, half):
    """(centres, signs, valid, y) with each window moved to its fitted crest (by a quarter
    of its half-period at most), dropping a crest that comes within a quarter half-period
    of the one before."""
    centres = centres + np.where(fit.valid, np.clip(fit.shift, -half / 4, half / 4), 0.0)
    keep = np.concatenate([[True], np.diff(centres) > 0.25 * half[1:]])
    return centres[keep], signs[keep], fit.valid[keep], fit.y[keep]


def _coarse_extrema(t, x, e0, e1, t_ref, period, samples_per_cycle, noise, source):
    """Crest times and signs: half-cycles split by crossings with hysteresis."""
    width = max(1, int(samples_per_cycle * _SMOOTHING_CYCLES))
    smooth = _moving_average(x, width) if width > 1 else x.copy()
    for lo in range(0, x.size, _BLOCK_SAMPLES):
        smooth[lo:lo + _BLOCK_SAMPLES] -= e0 + e1 * (t[lo:lo + _BLOCK_SAMPLES] - t_ref)
    scale = float(np.percentile(np.abs(smooth[: min(smooth.size, 1 << 22)]), 99.5))
    threshold = _HYSTERESIS_Z * noise / np.sqrt(width)
    if not np.isfinite(threshold) or threshold <= 0:
        threshold = 1e-3 * scale
    if threshold > _MAX_NOISE_SWING * scale:
        raise RecordError(f"no oscillation above the noise in {source}: the signal spans "
                          f"{np.ptp(x):.3g} but swings by {scale:.3g} about its straight-line "
                          f"trend, and the noise is {noise:.3g}. Check the signal column.")
    first, changes = _side_changes(smooth, threshold)
    if first is None:
        raise RecordError(f"no oscillation found in {source}. Check the signal column.")
    # Each run of one side (the last definite one) is a half-cycle.
    starts = np.concatenate([[first], changes[changes > first]])
    stops = np.concatenate([starts[1:], [x.size]])
    run_sign = np.where(smooth[starts] > threshold, 1, -1).astype(np.int64)
    best = _run_crests(smooth, starts, stops, run_sign)
    # A crest on the very first or last sample is a cut half-cycle: no crest inside.
    inside = (best > 0) & (best < x.size - 1)
    centres = t[best[inside]]
    signs = run_sign[inside]
    if centres.size < MIN_TURNING_POINTS:
        raise TooFewTurningPoints(f"only {centres.size} turning points found in {source} "
                                  f"(need {MIN_TURNING_POINTS}). Use a record of several "
                                  "cycles.")
    return centres.astype(np.float64), signs


def _moving_average(x, width):
    """Mean of the ``width`` samples about each one (fewer at the ends, where the window
    is cut), from one cumulative sum."""
    n = x.size
    cumulative = np.empty(n + 1)
    cumulative[0] = 0.0
    np.cumsum(x, out=cumulative[1:])
    half = width // 2
    if width > n:
        lo = np.clip(np.arange(n) - half, 0, n)
        hi = np.clip(np.arange(n) - half + width, 0, n)
        return (cumulative[hi] - cumulative[lo]) / (hi - lo)
    smooth = np.empty_like(x)
    # Sample i averages cumulative[lo:hi] with lo = max(i - half, 0), hi = min(lo + width, n)
    # after the first ``half``: whole windows in the middle (a block at a time), cut ones at
    # the ends.
    for lo in range(0, n - width + 1, _BLOCK_SAMPLES):
        hi = min(lo + _BLOCK_SAMPLES, n - width + 1)
        smooth[half + lo:half + hi] = (cumulative[width + lo:width + hi]
                                       - cumulative[lo:hi]) / width
    head = np.arange(half) - half + width
    smooth[:half] = cumulative[head] / head
    tail = np.arange(n - width + half + 1, n) - half
    smooth[n - width + half + 1:] = (cumulative[n] - cumulative[tail]) / (n - tail)
    return smooth


def _run_crests(smooth, starts, stops, run_sign):
    """Index of the crest of each run ``starts:stops`` (contiguous, covering the record from
    ``starts[0]``): its first sample farthest out on its side, the runs of a block of
    samples at once."""
    best = np.empty(starts.size, dtype=np.int64)
    lengths = stops - starts
    for first, stop, lo, hi in _segment_groups(starts, stops[-1]):
        runs = slice(first, stop)
        signed = smooth[lo:hi] * np.repeat(run_sign[runs], lengths[runs])
        offsets = starts[runs] - lo
        peak = np.maximum.reduceat(signed, offsets)
        at_peak = np.flatnonzero(signed == np.repeat(peak, lengths[runs]))
        best[runs] = at_peak[np.searchsorted(at_peak, offsets)] + lo
    return best


def _side_changes(smooth, threshold):
    """(first sample beyond +-``threshold``, the samples beyond it on the other side from
    the last one beyond it, the first included), or (None, None) when none is beyond it.
    A block of samples at a time."""
    first, last, changes = None, 0, []
    for lo in range(0, smooth.size, _BLOCK_SAMPLES):
        block = smooth[lo:lo + _BLOCK_SAMPLES]
        state = (block > threshold).astype(np.int8) - (block < -threshold)
        marked = np.flatnonzero(state)
        if marked.size == 0:
            continue
        sides = state[marked]
        first = lo + int(marked[0]) if first is None else first
        changes.append(lo + marked[sides != np.concatenate([[last], sides[:-1]])])
        last = sides[-1]
    if first is None:
        return None, None
    return first, np.concatenate(changes)


def _shifts_within_noise(fit, half, noise):
    """True when the crest shifts of a pass are what the sample noise alone gives them
    (root-mean-square under 2 standard errors): further passes would follow the noise."""
    ok = fit.valid & np.isfinite(fit.gain) & (fit.y > 0)
    if not (np.count_nonzero(ok) >= MIN_TURNING_POINTS and noise > 0):
        return False
    phase_sigma = noise * np.sqrt(fit.gain[ok]) / fit.y[ok]
    z = fit.shift[ok] * np.pi / half[ok] / phase_sigma
    return bool(np.sqrt(np.mean(z * z)) < 2.0)
