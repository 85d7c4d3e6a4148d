"""Range checks, the scatter of the amplitudes, and the checks that the record decays."""

from __future__ import annotations

import numpy as np

from mcfit.errors import RecordError, TooFewTurningPoints
from mcfit.turning.common import (SAMPLES_PER_CYCLE, _median, _robust_sigma,
                                  _running_median, _time_at)
from mcfit.turning.release import _release_at_rise, _rise
from mcfit.turning.result import MIN_TURNING_POINTS

# Larger times or signal values overflow float64 once squared and summed.
_LARGEST_VALUE = 1e30
# Amplitudes that scatter by more than this factor times what the sample noise gives have
# the excess added to their sigma.
_EXCESS_SCATTER = 1.5


def _checked_samples(t, x, source):
    """(t, tf, xf): the time as float64 and the finite samples of a waveform, or
    RecordError for a record that cannot be one."""
    t = np.asarray(t, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    if t.ndim != 1 or t.shape != x.shape:
        raise ValueError("t and x must be 1-D arrays of the same length")
    finite = np.isfinite(x)
    if not finite.any():
        raise RecordError(f"the signal of {source} is all NaN. Choose the signal column with "
                          "`signal_col`.")
    if not np.all(np.isfinite(t)):
        raise RecordError(f"the time of {source} has missing values. Remove those rows or "
                          "use `rate=HZ`.")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        raise RecordError(f"the time of {source} does not increase. Sort the record or use "
                          "`rate=HZ`.")
    tf, xf = (t[finite], x[finite]) if not finite.all() else (t, x)
    _check_range(tf, xf, source)
    if tf.size < 2 * SAMPLES_PER_CYCLE:
        raise RecordError(f"{source} has only {tf.size} samples. A waveform needs several "
                          f"cycles of at least {SAMPLES_PER_CYCLE} samples each.")
    if np.ptp(xf) == 0:
        raise RecordError(f"the signal of {source} is constant ({xf[0]:g}). Choose the signal "
                          "column with `signal_col`.")
    return t, tf, xf


def _with_scatter(y, sigma_y, log_step, used):
    """(sigma, notes): ``sigma_y`` with the scatter of the amplitudes about a smooth
    envelope added where it is clearly more than the sample noise explains."""
    scatter = _amplitude_scatter(y, sigma_y, log_step, used)
    white = float(np.sqrt(_median(sigma_y[used] ** 2))) if np.any(used) else float("nan")
    if not (np.isfinite(scatter) and scatter > _EXCESS_SCATTER * white
            and scatter > 1e-5 * np.max(y)):
        return sigma_y, []
    return np.sqrt(sigma_y**2 + scatter**2 - white**2), [
        f"amplitudes scatter by {scatter:.3g} about a smooth envelope, "
        f"{scatter / white:.3g} times what the sample noise explains (correlated "
        "noise or disturbances): sigma includes the excess"]


def _check_count(y, reasons, source):
    """RecordError when fewer than MIN_TURNING_POINTS turning points are usable."""
    n_used = int(np.count_nonzero(reasons == ""))
    if n_used < MIN_TURNING_POINTS:
        raise TooFewTurningPoints(
            f"only {n_used} usable turning points in {source} (need {MIN_TURNING_POINTS}): "
            f"{y.size} found, {y.size - n_used} excluded ({_reason_summary(reasons)}). Use a "
            "longer record, or check the signal column and the noise.")


def _closing_notes(domain, drift, drift_sigma, drift_over_record, noise_sigma, y,
                   samples_per_cycle):
    """Notes on a period that changes with amplitude, a drifting equilibrium
    (``drift_over_record``: its change over the record) and a coarse sampling."""
    notes = []
    if domain == "time" and np.isfinite(drift_sigma) and abs(drift) > 3 * drift_sigma \
            and abs(drift) > 1e-3:
        notes.append(f"the period changes by {100 * drift:+.2g}% from the smallest to the "
                     "largest amplitude (nonlinear stiffness or large swings)")
    if abs(drift_over_record) > 3 * noise_sigma / np.sqrt(max(y.size, 1)) and \
            abs(drift_over_record) > 1e-3 * np.max(y):
        notes.append(f"equilibrium drifts by {drift_over_record:.3g} over the record")
    if samples_per_cycle < SAMPLES_PER_CYCLE:
        notes.append(f"only {samples_per_cycle:.3g} samples per cycle: amplitudes are less "
                     f"accurate below {SAMPLES_PER_CYCLE}")
    return notes


def _check_range(t, x, source):
    for what, values, fix in (("time", t, "give the time in other units"),
                              ("signal", x, "rescale the signal")):
        largest = float(np.max(np.abs(values))) if values.size else 0.0
        if largest > _LARGEST_VALUE:
            raise RecordError(f"the {what} of {source} reaches {largest:.3g}, beyond what mcfit "
                              f"handles in double precision ({_LARGEST_VALUE:.0e}); {fix}.")


def _reason_summary(reasons):
    values, counts = np.unique([r for r in reasons if r], return_counts=True)
    return ", ".join(f"{c} {v}" for v, c in zip(values, counts)) or "none"


def _amplitude_scatter(y, sigma, log_step, candidate):
    """Robust scatter of amplitudes about a smooth envelope, from third differences.

    Third differences cancel the envelope's curvature (var = 20*sigma**2 for independent
    errors); an alternating offset error shows up in them too, as it should. A fast decay
    has third differences of its own, about ``log_step**3 * y`` for a decrement
    ``log_step`` per crest: only the crests where that is small against the noise count.
    """
    index = np.flatnonzero(candidate)
    if index.size < 8:
        return float("nan")
    d3 = np.diff(y[index], 3)
    middle = index[1:-2]
    with np.errstate(invalid="ignore"):
        negligible = np.abs(log_step[middle]) ** 3 * np.abs(y[middle]) < \
            0.3 * np.sqrt(20.0) * sigma[middle]
    if np.count_nonzero(negligible) < 8:
        return float("nan")
    d3 = d3[negligible]
    return float(_robust_sigma(d3) / np.sqrt(20.0))


# A crest amplitude this many of its sigmas below zero is no crest: the motion has ended.
_BELOW_ZERO_Z = 3.0


def _cut_at_stop(centres, y, sigma_y, reasons):
    """Notes: the used turning points from the first whose amplitude lies clearly below
    zero where the mass rests (:func:`_rests`) are left out in ``reasons`` as "after the
    decay" (changed in place). A swing has its crest beyond the equilibrium; a mass that
    Coulomb friction holds off centre reads, crest by crest, as amplitudes alternating
    about zero."""
    index = np.flatnonzero(reasons == "")
    z = np.divide(y[index], sigma_y[index], out=np.zeros(index.size),
                  where=sigma_y[index] > 0)
    below = [k for k in np.flatnonzero(z < -_BELOW_ZERO_Z) if _rests(y[index[k:]])]
    if not below or below[0] < MIN_TURNING_POINTS:
        return []
    first = index[below[0]]
    stopped = np.arange(y.size) >= first
    count = int(np.count_nonzero(stopped & (reasons == "")))
    reasons[stopped & (reasons == "")] = "after the decay"
    return [f"the motion stops by t = {_time_at(centres[first], centres)}: the amplitude there is "
            f"{y[first]:.3g}, {-y[first] / sigma_y[first]:.3g} sigma below zero (the mass "
            f"rests off centre, held by friction, or the record ends its swings); the {count} "
            "turning points from there are left out"]


def _rests(y, crests=4):
    """Whether amplitudes from one clearly below zero read as a mass at rest off centre:
    the next ``crests`` alternate in sign at one size (within a factor 2), where a beat's
    node turns the phase over and the amplitudes grow again."""
    head = y[:crests]
    if head.size < 2:
        return False
    size = np.abs(head)
    return bool(np.all(np.sign(head[1:]) == -np.sign(head[:-1]))
                and size.max() <= 2 * size.min())


def _cut_at_rise(centres, y, sigma_y, reasons, source, floor=0.0):
    """(release time or NaN, notes, warnings): where the smoothed amplitudes rise again
    after a fall, the part the decay does not need is left out in ``reasons`` (changed in
    place) instead of refusing the record. A rise that starts the free decay (as
    :func:`mcfit.turning.release._release_at_rise` decides) leaves out the crests before
    it ("before release"); any other rise ends the decay where the amplitude first reaches
    its dip ("after the decay"). Raises :class:`RecordError` only for an oscillation that
    grows as a whole."""
    release, notes, ending, beat = float("nan"), [], None, False
    index = np.flatnonzero(reasons == "")
    _check_growth(centres, y, sigma_y, index, source)
    while index.size >= MIN_TURNING_POINTS:
        smooth = _running_median(y[index], 5 if index.size >= 10 else 3)
        noise = _median(sigma_y[index])
        k = _rise(smooth, noise, sigma_y[index], floor)
        if k is None:
            break
        dip = int(np.argmin(smooth[:k + 1]))
        started = _release_at_rise(centres[index], smooth, k, noise, sigma_y[index], floor)
        if started is not None:
            reasons[index[:k]] = "before release"
            release, note = started
            notes.append(note)
        else:
            end = _end_of_decay(smooth, dip, noise, sigma_y[index])
            low = f"{smooth[end]:.3g} at t = {_time_at(centres[index[end]], centres)}"
            high = f"{smooth[k]:.3g} at t = {_time_at(centres[index[k]], centres)}"
            if end == 0:
                raise RecordError(
                    f"the amplitude in {source} rises from {low} to {high} with no decay "
                    "before it (a beat, a disturbance or a drive): this is not a free decay. "
                    "Check the record, or cut it to a decaying part with `start` and `end`.")
            reasons[index[end]:] = np.where(reasons[index[end]:] == "", "after the decay",
                                            reasons[index[end]:])
            beat = beat or smooth[dip] > 3 * max(noise, floor)
            # A later pass cuts earlier: its words replace the earlier ones.
            ending = (f"the amplitude falls to {low} and rises again to {high}",
                      float(centres[index[end]]))
        index = np.flatnonzero(reasons == "")
    if ending is None:
        return release, notes, []
    said, start = ending
    left_out = (f"the {np.count_nonzero(reasons == 'after the decay')} turning points from "
                f"t = {_time_at(start, centres)} are left out and the decay before them is fitted")
    if beat:
        return release, notes, [f"{said}: beating of two modes, or a disturbance; {left_out}. "
                                "Excite one mode only, or check the record"]
    return release, notes + [f"the decay ends in the noise or stops: {said} (noise, an "
                             f"offset where the motion stopped, or a disturbance); {left_out}"
                             ], []


def _check_growth(centres, y, sigma_y, index, source):
    """Raise for an oscillation that grows from its start to its end."""
    if index.size < MIN_TURNING_POINTS:
        return
    smooth = _running_median(y[index], 5 if index.size >= 10 else 3)
    noise = _median(sigma_y[index])
    start = _median(smooth[: max(2, index.size // 10)])
    end = _median(smooth[-max(2, index.size // 10):])
    if end > 1.3 * start and end - start > 5 * noise:
        raise RecordError(
            f"the oscillation in {source} grows (amplitude {start:.3g} at t = "
            f"{_time_at(centres[index[0]], centres)} to {end:.3g} at t = "
            f"{_time_at(centres[index[-1]], centres)}): this is "
            "not a free decay. Check the record, or cut it to the decaying part.")


def _end_of_decay(smooth, dip, noise, sigma):
    """The first of the smoothed amplitudes up to ``dip`` within two sigma of the dip's
    level: where the decay reaches the level it rises from."""
    level = smooth[dip] + 2 * np.maximum(noise, sigma[:dip + 1])
    return int(np.flatnonzero(smooth[:dip + 1] <= level)[0])
