"""The start of the free decay: a signal held still, amplitudes rising or flat (knee), or
a rise of the amplitude to its largest after a fall. Every decision on where a free decay
starts is taken here; :mod:`.checks` asks :func:`_release_at_rise` about each rise."""

from __future__ import annotations

import numpy as np

from mcfit.turning.common import _median, _robust_sigma, _time_at
from mcfit.turning.result import MIN_TURNING_POINTS

# A record may start before the free decay: the oscillator held still, or driven or still
# settling. A still stretch scatters by less than _HELD_NOISE noise sigmas in each
# half-period, and is left where the signal first moves _DEPARTURE_Z noise sigmas from
# its level. A driven or settling start has amplitudes rising or flat (slope above
# -_FLAT_Z standard errors) over _MIN_BEFORE crests at least, then falling more steeply
# by _RELEASE_Z standard errors (judged over _KNEE_CRESTS crests either side, and 2 and 4
# times as many: _KNEE_SCALES sizes), within the first _RELEASE_SEARCH crests.
_HELD_NOISE = 2.0
_DEPARTURE_Z = 5.0
_FLAT_Z = 3.0
_RELEASE_Z = 5.0
_MIN_BEFORE = 3
_KNEE_CRESTS = 4
_KNEE_SCALES = 3
_RELEASE_SEARCH = 400
# The amplitude has clearly fallen below its highest so far by this share of it, at least.
_FALLEN_SHARE = 0.01
# Third differences of crest magnitudes needed to measure their scatter.
_SCATTER_DIFFERENCES = 16
# The decay after a release must not rise again while above this many sigma.
_RISE_SNR = 10.0
# A crest is excluded when its half-cycle starts more than this many half-periods before
# the release.
_RELEASE_SLACK = 0.1
_RELEASE_CAUSES = {"held": "signal held still", "knee": "amplitude rising or flat"}


def _release(held, centres, signs, magnitude, magnitude_sigma, measured, period):
    """(release time, index of the first crest of the free decay, cause), or (NaN, 0, "")
    for a record that decays freely from its start.

    Held: the record starts still and then swings at ``held`` (see _held_until); the
    crests whose half-cycle begins before are excluded. Driven or settling: the amplitude
    rises or stays flat over the first crests, then falls; the decay starts at the crest
    where it turns (see _knee). Both can apply (held, then settling).
    """
    first = _held_crests(centres, held, period)
    index = np.flatnonzero(measured[first:]) + first
    if index.size >= MIN_TURNING_POINTS + 2 * _KNEE_CRESTS:
        knee = _knee(centres[index], magnitude[index], signs[index],
                     _release_scatter(magnitude[index], signs[index], magnitude_sigma[index]))
        if knee:
            # The motion became free after the crest before the knee's: the knee's own
            # half-cycle may straddle that moment, so the decay's first crest is the next.
            return (float(centres[index[knee]]), int(index[min(knee + 1, index.size - 1)]),
                    _RELEASE_CAUSES["knee"])
    if held is not None:
        return float(held), first, _RELEASE_CAUSES["held"]
    return float("nan"), 0, ""


def _held_crests(centres, held, period):
    """Number of crests whose half-cycle starts before the release at ``held`` (0 for
    None)."""
    if held is None:
        return 0
    return int(np.searchsorted(centres - 0.25 * period, held - _RELEASE_SLACK * period / 2))


def _held_until(t, x, period, noise):
    """Time at which a record that starts still (only noise about a level, for a
    half-period at least) starts to move, or None. A brief disturbance while it is held
    (a knock, a hand) does not end the stillness: the last still half-period before the
    largest swing does."""
    if not noise > 0:
        return None
    largest = int(np.argmax(np.abs(x - _median(x))))
    # Half-periods that end before the largest swing, and the spread of each.
    edges = np.unique(np.searchsorted(t, np.arange(t[0], t[largest], 0.5 * period)))
    if edges.size < 2:
        return None
    counts = np.diff(edges)
    middle = x[edges[0]:edges[-1]] - x[edges[0]]  # shifted: no cancellation in the sums
    sums = np.add.reduceat(middle, edges[:-1] - edges[0])
    squares = np.add.reduceat(middle * middle, edges[:-1] - edges[0])
    spread = np.sqrt(np.maximum(squares / counts - (sums / counts) ** 2, 0.0))
    still = (counts >= 3) & (spread <= _HELD_NOISE * noise)
    if not still[0]:
        return None
    last = int(np.flatnonzero(still)[-1])
    start, stop = edges[last], edges[last + 1]
    level = _median(x[start:stop])
    away = np.abs(x[start:] - level) > _DEPARTURE_Z * noise
    moving = np.flatnonzero(away[:-1] & away[1:])  # two samples: not one noise spike
    return float(t[start + moving[0]]) if moving.size else None


def _release_scatter(values, signs, sigma):
    """Standard deviation of the crest magnitudes: robust third differences along the
    maxima and along the minima (so unequal swings up and down do not count); what the
    sample noise gives when there are too few crests."""
    d3 = np.concatenate([np.diff(values[signs == s], 3) for s in (-1, 1)])
    if d3.size < _SCATTER_DIFFERENCES:
        return float(_median(sigma))
    return float(_robust_sigma(d3) / np.sqrt(20.0))


def _knee(times, values, signs, sigma):
    """Index of the first crest of the free decay after a rising or flat start, or 0.

    A knee between two crests is judged from L crests on either side (L = _KNEE_CRESTS
    times 1, 2, 4, ..., _KNEE_SCALES sizes): a straight line through each (plus a term
    for maxima against minima), joined at the knee. It counts when the amplitude does not
    fall before the knee (slope above -_FLAT_Z standard errors), falls after it, the
    slope drops across it by _RELEASE_Z standard errors (a free decay falls most steeply
    at its start), and a parabola fits those crests worse by _RELEASE_Z**2 in chi-square
    (a slow beat bends, it has no knee). The most significant drop wins; the knees tried
    end where the amplitude has fallen clearly below its highest so far. The decay then
    starts at the crest found by _first_free_crest, unless the amplitude falls before it,
    rises again after it, or bends downwards just after it (a beat, not a release).
    """
    best, best_z, best_window = 0, _RELEASE_Z, None
    for k in range(_MIN_BEFORE, _search_end(values, signs, sigma) + 1):
        knee = 0.5 * (times[k - 1] + times[k])
        for scale in range(_KNEE_SCALES):
            width = _KNEE_CRESTS << scale
            window = slice(max(0, k - width), min(values.size, k + width))
            z = _knee_significance(times[window] - knee, values[window], signs[window],
                                   sigma)
            if z > best_z:
                best, best_z, best_window = k, z, window
    if best == 0:
        return 0
    first = _first_free_crest(times, values, signs, sigma,
                              _knee_position(times, values, signs, best_window),
                              best_window.stop - 1)
    free = (_flat_before(times, values, signs, sigma, first)
            and not _rises_again(values[first:], signs[first:], sigma)
            and _convex_after(times, values, signs, sigma, first))
    return first if free else 0


def _flat_before(times, values, signs, sigma, first):
    """Whether the amplitude does not fall over the crests before ``first`` (a straight
    line, plus a term for maxima against minima, above -_FLAT_Z standard errors, or by
    less than _FALLEN_SHARE over those crests)."""
    before = slice(0, first)
    s = times[before] - times[first]
    design = np.column_stack([np.ones_like(s), signs[before], s])
    solution, _, covariance = _crest_fit(design, values[before], sigma)
    # Crests of a drive's plateau measured beside a decay may fall by a little more than
    # their noise: up to _FALLEN_SHARE over the stretch counts as flat.
    span = max(float(s[-1] - s[0]), float(np.finfo(float).tiny)) if s.size > 1 else 1.0
    allowed = _FLAT_Z * np.sqrt(covariance[2, 2]) + _FALLEN_SHARE * abs(solution[0]) / span
    return bool(solution[2] > -allowed)


def _rises_again(values, signs, sigma):
    """Whether the amplitude, while above _RISE_SNR sigma, rises again by _RELEASE_Z sigma
    (the mean of a maximum and a minimum above its lowest before): a beat or a
    disturbance, not a free decay after a release."""
    faint = np.flatnonzero(values < _RISE_SNR * sigma)
    pairs = _pair_means(values[:faint[0] if faint.size else values.size], signs)
    return bool(np.any(pairs - np.fmin.accumulate(pairs) > _RELEASE_Z * sigma))


def _pair_means(values, signs):
    """Means of neighbouring crests, a maximum and a minimum (so that swings of unequal
    size up and down cancel); NaN where two neighbours have the same sign."""
    alternate = signs[1:values.size] != signs[:values.size - 1]
    return np.where(alternate, 0.5 * (values[1:] + values[:-1]), np.nan)


def _convex_after(times, values, signs, sigma, first):
    """Whether the amplitude bends upwards (or not clearly downwards) over the
    2*_KNEE_CRESTS crests from ``first``, as a free decay's does: the top of a slow beat
    bends downwards."""
    after = slice(first, first + 2 * _KNEE_CRESTS)
    s = times[after] - times[first]
    design = np.column_stack([np.ones_like(s), signs[after], s, s**2])
    solution, _, covariance = _crest_fit(design, values[after], sigma)
    return bool(solution[3] > -_FLAT_Z * np.sqrt(covariance[3, 3]))


def _knee_position(times, values, signs, window):
    """Index of the first crest after the best-fitting knee in ``window``: a line before
    it joined to a parabola after it (the decay bends), plus a term for maxima against
    minima."""
    t, y, sg = times[window], values[window], signs[window]
    candidates = range(_MIN_BEFORE, t.size - _MIN_BEFORE + 1)
    chi2 = []
    for k in candidates:
        s = t - 0.5 * (t[k - 1] + t[k])
        after = np.maximum(s, 0.0)
        design = np.column_stack([np.ones_like(s), sg, np.minimum(s, 0.0), after, after**2])
        chi2.append(_crest_fit(design, y, 1.0)[1])
    return window.start + candidates[int(np.argmin(chi2))]


def _first_free_crest(times, values, signs, sigma, first, last):
    """The first crest from ``first`` to ``last`` that starts the decay (else ``first``):
    the 2*_KNEE_CRESTS crests after it decay (a straight line in the logarithm of the
    amplitude, plus a term for maxima against minima, falling by _FLAT_Z standard
    errors), and it lies on that line continued back (a crest of a held, driven or
    rising start lies below it by more than _FLAT_Z standard errors)."""
    span = 2 * _KNEE_CRESTS
    for k in range(first, min(last, values.size - span) + 1):
        after = slice(k + 1, k + 1 + span)
        s = times[after] - times[k]
        weight = values[after] / sigma
        design = np.column_stack([np.ones_like(s), signs[after], s])
        solution, _, covariance = _crest_fit(design * weight[:, None],
                                             np.log(values[after]) * weight, 1.0)
        at_k = np.array([1.0, signs[k], 0.0])
        spread = np.sqrt(at_k @ covariance @ at_k + (sigma / values[k]) ** 2)
        decays = solution[2] < -_FLAT_Z * np.sqrt(covariance[2, 2])
        if decays and np.log(values[k]) > at_k @ solution - _FLAT_Z * spread:
            return k
    return first


def _search_end(values, signs, sigma):
    """Last crest that may start the free decay: before the mean of a maximum and a
    minimum falls _RELEASE_Z sigma (and _FALLEN_SHARE) below the highest so far, with _KNEE_CRESTS crests
    after it, within the first _RELEASE_SEARCH."""
    pairs = _pair_means(values, signs)
    highest = np.fmax.accumulate(pairs)
    # Clearly: a crest measured about a drive's plateau can be off by more than its noise.
    fallen = np.flatnonzero(pairs < highest - np.maximum(_RELEASE_Z * sigma,
                                                         _FALLEN_SHARE * highest))
    end = int(fallen[0]) + 1 if fallen.size else values.size
    return min(end, values.size - _KNEE_CRESTS, _RELEASE_SEARCH)


def _crest_fit(design, y, sigma):
    """(solution, chi-square, covariance) of a least-squares fit with errors sigma."""
    solution = np.linalg.lstsq(design, y, rcond=None)[0]
    residual = y - design @ solution
    return (solution, float(residual @ residual) / sigma**2,
            sigma**2 * np.linalg.pinv(design.T @ design))


def _knee_significance(s, y, signs, sigma):
    """Drop of the slope across s = 0 in standard errors (see _knee), or 0."""
    ones = np.ones_like(s)
    solution, chi2, covariance = _crest_fit(
        np.column_stack([ones, signs, np.minimum(s, 0.0), np.maximum(s, 0.0)]), y, sigma)
    slope_before, slope_after = solution[2], solution[3]
    spread = covariance[2, 2] + covariance[3, 3] - 2.0 * covariance[2, 3]
    if not (spread > 0 and slope_after < -_RELEASE_Z * np.sqrt(covariance[3, 3])
            and slope_before > -_FLAT_Z * np.sqrt(covariance[2, 2])):
        return 0.0
    smooth = _crest_fit(np.column_stack([ones, signs, s, s**2]), y, sigma)[1]
    if smooth - chi2 < _RELEASE_Z**2:
        return 0.0
    return float((slope_before - slope_after) / np.sqrt(spread))


def _release_at_rise(times, smooth, k, noise, sigma, floor):
    """(release time, note) where the rise of the smoothed amplitudes ``smooth`` (at
    ``times``) to crest ``k`` (found by :func:`_rise`) starts the free decay, else None.

    It does where the amplitude rises to its largest, in the first half of the crests,
    with the decay undisturbed after it (no clear rise there): the oscillator was held,
    driven or disturbed before. ``noise``, ``sigma`` and ``floor`` as for :func:`_rise`.
    Only amplitudes are needed, so this serves turning-point tables too.
    """
    if not (smooth[k] >= smooth[0] and 2 * k < smooth.size
            and _rise(smooth[k:], noise, sigma[k:], floor) is None):
        return None
    dip = int(np.argmin(smooth[:k + 1]))
    release = float(times[k])
    return release, (f"the free decay starts at t = {_time_at(release, times)}, where the "
                     f"amplitude rises to its largest ({smooth[k]:.3g}) after falling to "
                     f"{smooth[dip]:.3g}: held, driven or disturbed before it; {k} turning "
                     "points before it left out")


def _rise(smooth, noise, sigma, floor):
    """Index of the largest clear rise of the smoothed amplitudes after a fall, or None."""
    running_min = np.minimum.accumulate(smooth)
    rise = smooth - running_min
    # Crests in the noise can be <= 0: a rise from there is judged against the noise.
    k = int(np.argmax(rise / np.maximum(running_min, max(noise, 1e-300))))
    # Near the ends the median is the crest itself, often an edge-cut window: judge the
    # rise against that crest's own uncertainty when it is the larger.
    if (smooth[k] > 1.3 * running_min[k] and rise[k] > 5 * max(noise, sigma[k])
            and running_min[k] < smooth[0] and smooth[k] > 3 * floor):
        return k
    return None


def _release_note(time, count, cause, crests=()):
    excluded = (f"{count} turning point{'s' if count != 1 else ''} before it excluded"
                if count else "no turning point before it")
    return f"release at t = {_time_at(time, crests)}: {excluded} ({cause})"
