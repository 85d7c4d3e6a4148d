"""The end of the decay: a floor of vibration, or the oscillation lost in white noise."""

from __future__ import annotations

import numpy as np
from scipy.special import ndtri

from mcfit.turning.common import _median, _running_median, _time_at
from mcfit.turning.result import MIN_TURNING_POINTS

# An amplitude below FLOOR_FACTOR times the floor level is dominated by the floor.
FLOOR_FACTOR = 1.5
# Significance (standard errors) of the tests for a floor, the fewest crests in the
# stretch at the end of the record that must not decay, the fraction of the floor's
# half-periods in which a crest must be found, and the top of the amplitudes (in floor
# levels) whose decay rate the floor's is compared with.
_FLOOR_Z = 3.0
_FLOOR_END_CRESTS = 5
_FLOOR_DENSITY = 0.5
_FLOOR_REACH = 4.0


def _vibration_floor(centres, signs, magnitude, magnitude_sigma, gain, candidate, *,
                     noise_sigma, period, t_end):
    """(floor level, index of the first crest in the floor) or (0.0, None); ``gain`` is
    var(amplitude)/sigma**2 of each crest's half-cycle fit.

    A floor of vibration, hum or quantization: the envelope stops decaying at the end of
    the record, well below its start and well above what white noise gives a half-cycle
    fit. The tail within FLOOR_FACTOR of its final level is the floor when its crests go
    on to the end of the record (at least _FLOOR_DENSITY of its half-periods have one),
    the end of the record (the tail's second half) does not decay, and the tail decays
    more slowly than the law dy/dt = -c - b*y - a*y**2 allows after the crests before it
    (those below _FLOOR_REACH times the floor), both by _FLOOR_Z standard errors of the
    scatter measured there. A slower decay that still shows above the noise is no floor,
    nor are swings of unequal size up and down (a sign term takes them out). (A decay
    into white noise is no floor either: its crests are kept, as projections, until the
    oscillation is lost in the noise; see _sinks_below_noise.)
    """
    index = np.flatnonzero(candidate)
    if index.size < 2 * MIN_TURNING_POINTS:
        return 0.0, None
    values = magnitude[index]
    smooth = _running_median(values, max(5, (index.size // 30) | 1))
    white = noise_sigma * np.sqrt(2.0 * _median(gain[index]))
    m = max(5, index.size // 8)
    final = float(_median(smooth[-m:]))
    if not (index.size >= 3 * m and final < 0.25 * np.max(smooth) and final > 3 * white):
        return 0.0, None
    above = np.flatnonzero(smooth >= FLOOR_FACTOR * final)
    if above.size == 0:
        return 0.0, None
    start = above[-1] + 1
    length = index.size - start
    if length < 2 * _FLOOR_END_CRESTS or start < 5:
        return 0.0, None
    if length < _FLOOR_DENSITY * (t_end - centres[index[start]]) / (0.5 * period):
        return 0.0, None  # crests found here and there in the noise: no steady floor
    high = np.flatnonzero(smooth[:start] >= _FLOOR_REACH * final)
    first = max(0, min(start - m, int(high[-1]) if high.size else 0))
    rate_end, sigma_end, _ = _log_decay_rate(
        index[-max(_FLOOR_END_CRESTS, length // 2):], centres, signs, magnitude,
        magnitude_sigma)
    rate_in, sigma_in, level_in = _log_decay_rate(index[start:], centres, signs, magnitude,
                                                  magnitude_sigma)
    rate_before, sigma_before, level_before = _log_decay_rate(
        index[first:start], centres, signs, magnitude, magnitude_sigma)
    # The slowest decay the law allows in the tail: all fluid, -d ln(y)/dt in proportion
    # to y.
    ratio = level_in / level_before
    stopped = rate_end > -_FLOOR_Z * sigma_end
    slower = rate_in - ratio * rate_before > _FLOOR_Z * np.hypot(sigma_in, ratio * sigma_before)
    if stopped and slower:
        return final, int(index[start])
    return 0.0, None


def _log_decay_rate(index, centres, signs, magnitude, magnitude_sigma):
    """(d ln(y)/dt, its standard error, typical amplitude) over the crests ``index``: a
    line in time plus a term for maxima against minima, so that swings of unequal size up
    and down do not count as scatter. The error is from the scatter about the line, at
    least what the sample noise gives."""
    y = magnitude[index]
    relative = magnitude_sigma[index] / y
    s = centres[index] - np.mean(centres[index])
    sign = signs[index]
    design = np.column_stack([np.ones_like(s), s, sign])
    if sign.size == 0 or not (sign != sign[0]).any():
        design = design[:, :2]
    log_y = np.log(y)
    solution, _, rank, _ = np.linalg.lstsq(design, log_y, rcond=None)
    dof = index.size - rank
    level = float(np.exp(solution[0]))
    if dof < 1:
        return float(solution[1]), float("inf"), level
    residual = log_y - design @ solution
    scale = max(float(np.sqrt(residual @ residual / dof)), float(_median(relative)))
    covariance = np.linalg.pinv(design.T @ design)
    return float(solution[1]), scale * float(np.sqrt(covariance[1, 1])), level


# Crests per group in the test for a signal left in the tail.
_NOISE_GROUP = 9
# A group's mean amplitude this many standard errors above 0 shows a signal; on a long
# tail of noise, enough more that noise alone crosses it in one record of this many.
_PRESENT_Z = 4.0
_LOOK_ELSEWHERE = 100


def _sinks_below_noise(y, sigma, candidate):
    """Index of the first crest after the oscillation is lost in the noise, or None.

    The signal counts as present while the mean of some _NOISE_GROUP successive amplitudes
    is 4 standard errors above 0, or more on a long record: the threshold that noise
    alone crosses once in _LOOK_ELSEWHERE records, however many groups are scanned. One
    more group is kept past the last such, so that every crest where the envelope is
    near the noise stays in the fit.
    """
    index = np.flatnonzero(candidate & np.isfinite(sigma) & (sigma > 0))
    group = _NOISE_GROUP
    if index.size < 3 * group:
        return None
    z = y[index] / sigma[index]
    mean_z = np.convolve(z, np.ones(group), mode="valid") / np.sqrt(group)
    threshold = max(_PRESENT_Z, -float(ndtri(1.0 / (_LOOK_ELSEWHERE * mean_z.size))))
    present = np.flatnonzero(mean_z > threshold)
    if present.size == 0:
        return None
    cut = int(present[-1]) + 2 * group
    if index.size - cut < group:
        return None
    return int(index[cut])


def _tail_notes(crests, y, sigma_y, reasons, floor_time, floor_level, phase_lost):
    """(floor time, floor level, notes) of the end of the decay. With a floor of vibration
    from ``floor_time`` (NaN: none), the record between the phase lost and the floor is
    not used; without one, the crests after the oscillation is lost in the noise are
    marked "noise floor" in ``reasons``, or the record after the phase is lost is not
    used."""
    if np.isfinite(floor_time):
        notes = [f"noise floor at amplitude {floor_level:.3g}: "
                 f"{int(np.count_nonzero(reasons == 'noise floor'))} turning points from "
                 f"t = {_time_at(floor_time, crests)} excluded"]
        if phase_lost is not None and phase_lost < floor_time:
            notes.append(f"the crest phase is lost in the noise from t = "
                         f"{_time_at(phase_lost, crests)}: "
                         f"the record from there to the noise floor is not used")
        return floor_time, floor_level, notes
    cut = _sinks_below_noise(y, sigma_y, reasons == "")
    if cut is not None:
        in_floor = (np.arange(y.size) >= cut) & (reasons == "")
        reasons[in_floor] = "noise floor"
        floor_time = float(crests[cut])
        floor_level = float(_median(sigma_y[reasons == ""]))
        return floor_time, floor_level, [
            f"noise floor: the oscillation is lost in the noise (amplitude sigma "
            f"{floor_level:.3g}); {int(in_floor.sum())} turning points from "
            f"t = {_time_at(floor_time, crests)} excluded"]
    if phase_lost is not None:
        floor_level = float(_median(sigma_y[reasons == ""])) if np.any(reasons == "") \
            else 0.0
        return phase_lost, floor_level, [
            f"noise floor: the crest phase is lost in the noise from t = "
            f"{_time_at(phase_lost, crests)} "
            f"(amplitude sigma {floor_level:.3g}); the record after it is not used"]
    return floor_time, floor_level, []
