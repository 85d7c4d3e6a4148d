"""Where the free decay is in a record: the stretch after a rest, a held push or a strike
and its transient, up to a new excitation; a record excited more than once gives one
stretch (a run) each. numpy only, no I/O; linear in the record.

The record is demodulated in blocks of about two periods at the frequency that lasts
longest:

1. The steady frequency: the record is cut into 24 (or 12, or 6) stretches, each stretch's
   spectral peak is found, and the frequency held by the most stretches wins (a strike's
   loud transient lasts one stretch, the decay many); it is refined on the span of those
   stretches.
2. Each block is fitted by ``m + s*tau + A*cos(w*t + phi)``: its amplitude ``A`` and the
   scatter ``r`` of its residuals.
3. A new excitation is a block whose amplitude is at least twice that of two blocks
   before, beyond the noise (a release from rest or a hold, a second strike).
4. Between two excitations the free decay starts at the first block whose amplitude is
   not exceeded later (its envelope only falls) and whose residuals are not those of a
   transient (several times those of the blocks after it: the strike's other modes, the
   hand letting go), and ends where the next excitation begins.

A stretch counts as a run when it holds at least :data:`MIN_BLOCKS` free blocks and
swings at least :data:`MIN_SHARE` of the largest run's amplitude; the others (a brief
ring while the mass is pushed aside) are named in a note and left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.fft import next_fast_len, rfft

from mcfit.plain import period_resolution, time_text

__all__ = ["Placement", "free_decay_runs", "locate_free_decay", "with_placed_release"]

# Stretches whose spectral peaks vote for the steady frequency (fewer where it has fewer
# than _MIN_PERIODS periods in one), and the votes it needs.
_STRETCH_COUNTS = (24, 12, 6)
_MIN_PERIODS = 4
_MIN_VOTES = 3
# A stretch's spectral line counts where it stands this many times over the median of its
# spectrum (pure noise's highest bin of 10^4 stands about 13 times over).
_STRONG_LINE = 30.0
# A frequency above this many cycles a sample (under 4 samples a cycle) is not placed.
_FASTEST = 0.25
# Samples demodulated at a time (bounds the memory of a long record).
_CHUNK_SAMPLES = 1 << 18
# Periods in one demodulation block, and the fewest samples in one.
_BLOCK_PERIODS = 2.0
_MIN_BLOCK_SAMPLES = 8
# A new excitation: the amplitude at least this factor above that of two blocks before,
# and by this many amplitude standard errors.
_RISE_FACTOR = 2.0
_RISE_Z = 5.0
# Blocks before a rise over which a fall into it marks a dip.
_DIP_BLOCKS = 4
# Within a run, a later amplitude above this many standard errors (and this fraction of
# the block's) over a block's shows the envelope still rising.
_LATER_Z = 4.0
_LATER_FRACTION = 0.02
# A transient: residuals, for the amplitude, this many times the median of those of the
# blocks within _AHEAD after it that swing at least _SIMILAR of its amplitude (at least
# _MIN_ALIKE of them), beyond the noise; or a level that moves this many times as much
# as the levels after it, and by _TRANSIENT_Z amplitude sigmas.
_TRANSIENT_FACTOR = 3.0
_TRANSIENT_Z = 5.0
_AHEAD = 64
_SIMILAR = 0.7
_MIN_ALIKE = 4
# Blocks judged at a time when looking for the start of a free decay.
_SCAN = 256
# A still stretch swings by less than this share of the decay's first amplitude; the
# signal has left it where it is this many times its band away from its level.
_STILL_SHARE = 0.05
_DEPARTURE_FACTOR = 3.0
# The noise after a decay is left out where it is more than this share of the record
# (judged over windows of _QUIET_WINDOW blocks, swinging above _QUIET_Z amplitude sigmas).
_QUIET_SHARE = 0.3
_QUIET_WINDOW = 32
_QUIET_Z = 4.0
# A run needs this many free blocks, and this share of the largest run's amplitude.
MIN_BLOCKS = 3
MIN_SHARE = 0.25


@dataclass(frozen=True)
class Placement:
    """Where the free decays of a record are.

    Attributes
    ----------
    runs : tuple of (float, float)
        Start and end time of each free decay, in time order (the end is the last
        sample's time for the last run).
    left_out : tuple of (float, float, str)
        The stretches left out, with why ("rest", "transient", "rising", "brief ring",
        "noise").
    period : float
        The steady period found (NaN when the record was not placed).
    notes : tuple of str
        One sentence per decision.
    """

    runs: tuple = ()
    left_out: tuple = ()
    period: float = float("nan")
    notes: tuple = ()

    @property
    def moved(self) -> bool:
        """Whether any part of the record was left out (else it is one free decay)."""
        return bool(self.left_out)


def locate_free_decay(t, x) -> Placement:
    """The free decays of a sampled record x(t): see the module's docstring.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times, evenly spaced (a record with gaps, NaN or uneven steps is not
        placed: the whole record is returned as one run).
    x : ndarray, shape (n,)
        Signal.

    Returns
    -------
    Placement
        One run spanning the record where it cannot be placed or is one free decay from
        its start.
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    whole = Placement(runs=((float(t[0]), float(t[-1])),) if t.size else ())
    if not _placeable(t, x):
        return whole
    dt = (t[-1] - t[0]) / (t.size - 1)
    frequency = _steady_frequency(x, dt)
    if frequency is None or frequency * dt > _FASTEST:
        return whole
    blocks = _demodulated(t, x, frequency)
    if blocks is None:
        return whole
    return _placement(t, x, blocks, 1.0 / frequency) or whole


def _placeable(t, x):
    if t.size < _STRETCH_COUNTS[0] * 4 * _MIN_BLOCK_SAMPLES or not np.all(np.isfinite(x)):
        return False
    steps = np.diff(t)
    return bool(np.all(steps > 0) and steps.max() <= 1.5 * steps.min()
                and np.ptp(x) > 0)


def _steady_frequency(x, dt):
    """The frequency (Hz) that the most stretches of the record peak at, refined on their
    span; None when no frequency holds _MIN_VOTES stretches. Fewer, longer stretches are
    tried where the winner has fewer than _MIN_PERIODS periods in a stretch."""
    for count in _STRETCH_COUNTS:
        length = x.size // count
        stretches = x[:length * count].reshape(count, length)
        size = next_fast_len(length, real=True)
        peaks, contrast = _stretch_peaks(stretches, size)
        strong = contrast > _STRONG_LINE
        votes = np.bincount(peaks[strong], minlength=size // 2 + 1)
        # Neighbouring bins vote together: a line between two bins, or drifting a little.
        pooled = votes + np.concatenate(([0], votes[:-1])) + np.concatenate((votes[1:], [0]))
        best = int(np.argmax(pooled))
        if pooled[best] < _MIN_VOTES and strong.any():
            # A decay that sinks into a long noise tail holds few stretches: the one
            # whose line stands highest above its floor.
            best = int(peaks[np.argmax(contrast)])
        if best * length < _MIN_PERIODS * size:
            continue
        if not strong.any():
            return None
        held = np.flatnonzero(strong & (np.abs(peaks - best) <= 1))
        span = x[held[0] * length:(held[-1] + 1) * length]
        return _refined_peak(span, dt, (best - 1.5) / (size * dt), (best + 1.5) / (size * dt))
    return None


def _stretch_peaks(stretches, size):
    """(peak bin of each stretch's spectrum of ``size`` points, its power over the
    median of the stretch's spectrum)."""
    centred = stretches - stretches.mean(axis=1, keepdims=True)
    centred *= np.hanning(stretches.shape[1])
    power = np.abs(rfft(centred, n=size, axis=1)) ** 2
    power[:, :2] = 0.0  # the mean and drift, not an oscillation
    peaks = np.argmax(power, axis=1)
    top = power[np.arange(power.shape[0]), peaks]
    floor = np.median(power[:, 2:], axis=1)
    return peaks, top / np.maximum(floor, 1e-300)


def _refined_peak(span, dt, low, high):
    """The spectral peak of ``span`` between ``low`` and ``high`` Hz, interpolated."""
    centred = span - span.mean()
    size = next_fast_len(max(span.size, 4 * int(round(1.0 / (low * dt))) if low > 0
                             else span.size), real=True)
    power = np.abs(rfft(centred * np.hanning(span.size), n=size)) ** 2
    frequencies = np.fft.rfftfreq(size, dt)
    inside = np.flatnonzero((frequencies >= low) & (frequencies <= high))
    if inside.size == 0:
        return None
    k = int(inside[np.argmax(power[inside])])
    if 0 < k < power.size - 1:
        below, top, above = np.log(power[k - 1:k + 2] + 1e-300)
        bend = below - 2 * top + above
        shift = 0.5 * (below - above) / bend if bend < 0 else 0.0
        return float((k + np.clip(shift, -0.5, 0.5)) / (size * dt))
    return float(frequencies[k])


@dataclass(frozen=True)
class _Blocks:
    amplitude: np.ndarray
    residual: np.ndarray  # rms of the residuals
    level: np.ndarray  # the fitted line at each block's middle
    size: int  # samples per block (block k starts at sample k*size)


def _demodulated(t, x, frequency):
    """Each block of about _BLOCK_PERIODS periods fitted by a line and one sinusoid, a
    bounded number of blocks at a time."""
    dt = (t[-1] - t[0]) / (t.size - 1)
    size = max(_MIN_BLOCK_SAMPLES, int(round(_BLOCK_PERIODS / (frequency * dt))))
    count = x.size // size
    if count < 2 * MIN_BLOCKS:
        return None
    step = max(1, _CHUNK_SAMPLES // size)
    parts = [_block_fits(t, x, frequency, size, first, min(first + step, count))
             for first in range(0, count, step)]
    return _Blocks(amplitude=np.concatenate([p[0] for p in parts]),
                   residual=np.concatenate([p[1] for p in parts]),
                   level=np.concatenate([p[2] for p in parts]), size=size)


def _block_fits(t, x, frequency, size, first, stop):
    """(amplitude, rms residual, level) of blocks ``first:stop`` of ``size`` samples."""
    shape = (stop - first, size)
    span = slice(first * size, stop * size)
    phase = 2 * np.pi * frequency * (t[span] - t[0])
    tau = np.broadcast_to(np.linspace(-1.0, 1.0, size), shape)
    design = np.stack([np.ones(shape), tau, np.cos(phase).reshape(shape),
                       np.sin(phase).reshape(shape)], axis=-1)
    values = x[span].reshape(shape)
    normal = np.einsum("kni,knj->kij", design, design)
    right = np.einsum("kni,kn->ki", design, values)[..., None]
    coefficients = np.linalg.solve(normal, right)[..., 0]
    residual = values - np.einsum("kni,ki->kn", design, coefficients)
    return (np.hypot(coefficients[:, 2], coefficients[:, 3]),
            np.sqrt(np.mean(residual * residual, axis=1)), coefficients[:, 0])


def _placement(t, x, blocks, period):
    """The runs and the parts left out, or None where the record is one free decay."""
    noise = float(np.median(blocks.residual))
    amplitude_sigma = max(noise * np.sqrt(2.0 / blocks.size), 1e-300)
    onsets = _onsets(blocks.amplitude, amplitude_sigma)
    edges = np.concatenate(([0], onsets, [blocks.amplitude.size]))
    stretches = [_free_stretch(blocks, edges[i], edges[i + 1], amplitude_sigma, noise)
                 for i in range(edges.size - 1)]
    largest = max((blocks.amplitude[s:e].max() for s, e in stretches if e - s >= MIN_BLOCKS),
                  default=0.0)
    if largest == 0.0:
        return None
    runs, left_out = [], []
    for (low, high), (free, end) in zip(zip(edges[:-1], edges[1:]), stretches):
        swing = blocks.amplitude[free:end].max() if end > free else 0.0
        if end - free < MIN_BLOCKS or swing < MIN_SHARE * largest:
            if high > low:
                left_out.append((_time(t, blocks, low), _time(t, blocks, high),
                                 _why_not_run(swing, amplitude_sigma)))
            continue
        if low == 0 and free > 0 and not _still_at_start(t, x, blocks, free, period):
            free = 0  # swinging from the record's start: the turning points judge that
        first = _time(t, blocks, free)
        if free > low:
            why = _why(blocks, low, free)
            departure = None if why == "transient" else _departure(
                t, x, blocks, low, free, period)
            if departure is not None and departure < _time(t, blocks, free - 1):
                # Built up over whole blocks after the rest: rest, then rising.
                left_out += [(_time(t, blocks, low), departure, "rest"),
                             (departure, first, "rising")]
            else:
                first, why = (departure, "rest") if departure is not None else (first, why)
                left_out.append((_time(t, blocks, low), first, why))
        quiet = _quiet_from(blocks, free, high, amplitude_sigma)
        if quiet is not None:
            left_out.append((_time(t, blocks, quiet), _time(t, blocks, high), "noise"))
        runs.append((first, _time(t, blocks, high if quiet is None else quiet)))
    if not left_out or not runs:
        return None
    left_out = _merged(left_out)
    notes = _notes(runs, left_out, period)
    return Placement(runs=tuple(runs), left_out=tuple(left_out), period=period,
                     notes=tuple(notes))


def _quiet_from(blocks, free, high, sigma):
    """The block from which a decay ``free:high`` has long sunk into the noise, where that
    noise is more than _QUIET_SHARE of the record, else None: the last block where half
    of the next _QUIET_WINDOW swing above _QUIET_Z amplitude sigmas, and a quarter of
    the decay's length (at least _QUIET_WINDOW blocks) beyond it for the floor's stage."""
    above = (blocks.amplitude[free:high] > _QUIET_Z * sigma).astype(float)
    if above.size < 2 * _QUIET_WINDOW:
        return None
    share = np.convolve(above, np.ones(_QUIET_WINDOW) / _QUIET_WINDOW, mode="valid")
    swinging = np.flatnonzero(share >= 0.5)
    if swinging.size == 0:
        return None
    last = int(swinging[-1]) + _QUIET_WINDOW
    quiet = free + last + max(_QUIET_WINDOW, last // 4)
    return quiet if high - quiet > _QUIET_SHARE * blocks.amplitude.size else None


def _still_at_start(t, x, blocks, free, period):
    """Whether the record starts still (a rest, a hold, a quiet pre-trigger): its first
    quarter-period, or a block before the free decay, swings under _STILL_SHARE of the
    decay's amplitude."""
    quarter = max(3, int(round(0.25 * period / (t[1] - t[0]))))
    still = x[:quarter]
    limit = _STILL_SHARE * blocks.amplitude[free]
    band = float(np.max(np.abs(still - np.median(still))))
    return band < limit or bool(blocks.amplitude[:free].min() < limit)


def _departure(t, x, blocks, low, free, period):
    """The moment the signal leaves the still level it held before a free decay (a rest,
    a hold), to the sample; None where it was not still. Searched first from the block
    before the first free one to that block's end (a block that holds the end of a hold
    can swing enough to count as free), against the half-period before (a knock long
    before the release does not end the rest; a line fits a quarter of a swing too
    well), then from the stretch's start, against its first half-period (a swing that
    builds up slowly from rest)."""
    quarter = max(3, int(round(0.5 * period / (t[1] - t[0]))))  # a half-period
    search = (free - 1) * blocks.size
    for begin in (search - quarter, low * blocks.size):
        if begin < low * blocks.size:
            continue
        found = _left_level(t, x, begin, quarter, min((free + 1) * blocks.size, x.size),
                            _STILL_SHARE * blocks.amplitude[free])
        if found is not None:
            return found
    return None


def _left_level(t, x, begin, quarter, end, largest_band):
    """The first of two samples from ``begin + quarter`` to ``end`` that are
    _DEPARTURE_FACTOR times the band of ``x[begin:begin + quarter]`` about its line from
    that line continued, where that band is under ``largest_band``; else None."""
    # The still level as a line: a drift is no departure.
    span = t[begin:begin + quarter]
    slope, level = np.polyfit(span - span[0], x[begin:begin + quarter], 1)
    band = float(np.max(np.abs(x[begin:begin + quarter] - level - slope * (span - span[0]))))
    if not band < largest_band:
        return None
    start = begin + quarter
    line = level + slope * (t[start:end] - span[0])
    away = np.abs(x[start:end] - line) > _DEPARTURE_FACTOR * band
    moving = np.flatnonzero(away[:-1] & away[1:])  # two samples: not one spike
    return float(t[start + moving[0]]) if moving.size else None


def _merged(left_out):
    """Neighbouring stretches left out for the same reason as one."""
    merged = [left_out[0]]
    for start, end, why in left_out[1:]:
        if why == merged[-1][2] and start <= merged[-1][1]:
            merged[-1] = (merged[-1][0], end, why)
        else:
            merged.append((start, end, why))
    return merged


def _time(t, blocks, index):
    """The time block ``index`` starts at; the last sample's for the end of the blocks."""
    if index >= blocks.amplitude.size:
        return float(t[-1])
    return float(t[int(index) * blocks.size])


def _onsets(amplitude, sigma):
    """Blocks where a new excitation starts: the amplitude at least _RISE_FACTOR times
    that of two blocks before, by _RISE_Z standard errors, after a level that did not
    itself fall by _RISE_FACTOR into the rise (a beat's minimum: a dip, not an
    excitation), unless it rises _RISE_FACTOR times above that level too (a low Q's
    fast decay struck again)."""
    before = np.maximum(amplitude[:-2], amplitude[1:-1])
    rise = (amplitude[2:] >= _RISE_FACTOR * before) & (amplitude[2:] - before > _RISE_Z * sigma)
    onsets = np.flatnonzero(rise) + 2
    if onsets.size:
        earlier = np.array([amplitude[max(j - 2 - _DIP_BLOCKS, 0):j - 1].max() for j in onsets])
        trough = np.array([amplitude[j - 2:j].min() for j in onsets])
        no_dip = earlier < _RISE_FACTOR * trough + _RISE_Z * sigma
        above = amplitude[onsets] >= _RISE_FACTOR * earlier  # clears the level before too
        onsets = onsets[no_dip | above]
    # One excitation rises over a few blocks: keep the first block of each rise.
    keep = np.concatenate(([True], np.diff(onsets) > 2)) if onsets.size else onsets
    return onsets[keep] - 1  # the block before the rise already holds its start


def _free_stretch(blocks, low, high, sigma, noise):
    """(first free block, end block) of the stretch of blocks ``low:high``: the first
    block that is neither still rising nor a transient, judged _SCAN blocks at a time.
    A transient shows in a block's residuals (a strike's other modes, a hand letting
    go) or in its level, off both its neighbours' (a slow mode's remnant under a fast
    one, such as a struck fork's thump, which a block's line takes up but the decay's
    equilibrium does not; a release or a hold moves it once)."""
    amplitude, residual = blocks.amplitude[low:high], blocks.residual[low:high]
    later = np.maximum.accumulate(amplitude[::-1])[::-1]  # the largest from each on
    later = np.concatenate((later[1:], [0.0]))
    rising = later > amplitude + _LATER_Z * sigma + _LATER_FRACTION * amplitude
    moves = np.abs(np.diff(blocks.level[low:high]))
    level_moves = np.minimum(np.concatenate(([np.nan], moves)), np.concatenate((moves, [np.nan])))
    level_moves = np.nan_to_num(level_moves, nan=0.0)
    for first in range(0, amplitude.size, _SCAN):
        stop = min(first + _SCAN, amplitude.size)
        free = np.flatnonzero(~(rising[first:stop]
                                | _transient(amplitude, residual, noise, first, stop)
                                | _transient(amplitude, level_moves, _TRANSIENT_Z * sigma,
                                             first, stop)))
        if free.size:
            return low + first + int(free[0]), high
    return high, high


def _transient(amplitude, spread, floor, first, stop):
    """Whether each block ``first:stop`` is a transient: its ``spread`` (residual scatter
    or level move), for its amplitude, _TRANSIENT_FACTOR times that of the blocks within
    _AHEAD after it that swing at least _SIMILAR of its amplitude (a harmonic or a period
    that changes with amplitude is alike there; a strike's other modes, a hand letting go
    are not), and beyond ``floor``. Where the amplitude falls faster, no judgement."""
    count = stop - first
    reach = slice(first, stop + _AHEAD)
    ratio = np.zeros(amplitude.size)
    ratio[reach] = spread[reach] / np.maximum(amplitude[reach], 1e-300)
    padding = np.zeros(_AHEAD)
    ahead_ratio = np.concatenate((ratio[first + 1:stop + _AHEAD], padding))
    ahead_amplitude = np.concatenate((amplitude[first + 1:stop + _AHEAD], padding))
    windows = np.lib.stride_tricks.sliding_window_view
    own = amplitude[first:stop, None]
    alike = windows(ahead_amplitude, _AHEAD)[:count] >= _SIMILAR * own
    enough = np.count_nonzero(alike, axis=1) >= _MIN_ALIKE
    typical = _masked_median(windows(ahead_ratio, _AHEAD)[:count], alike)
    return enough & (spread[first:stop] > _TRANSIENT_FACTOR * typical * own[:, 0] + floor)


def _masked_median(values, mask):
    """The median of ``values`` along axis 1 where ``mask``, row by row (NaN where none)."""
    masked = np.where(mask, values, np.inf)
    counts = np.count_nonzero(mask, axis=1)
    ordered = np.sort(masked, axis=1)
    rows = np.arange(values.shape[0])
    half = np.maximum(counts - 1, 0) // 2
    middle = 0.5 * (ordered[rows, half] + ordered[rows, np.maximum(counts, 1) // 2])
    return np.where(counts > 0, middle, np.nan)


def _why(blocks, low, free):
    """Why the blocks ``low:free`` before a free decay are left out."""
    peak = low + int(np.argmax(blocks.amplitude[low:free + 1]))
    if peak >= free:  # the largest swing is the decay's: what came before rose to it
        quiet = blocks.amplitude[low:free].max() < 0.1 * blocks.amplitude[free]
        return "rest" if quiet else "rising"
    return "transient"


def _why_not_run(swing, sigma):
    if swing <= 2 * _LATER_Z * sigma:
        return "rest"
    return "brief ring"


_WORDS = {"rest": "a rest or hold before the release",
          "rising": "the swing still rising (a release or a drive)",
          "transient": "the excitation's transient (a strike's other modes, a hand letting go)",
          "brief ring": "a brief ring too short or weak for a decay (a push, a knock)",
          "noise": "the noise long after the decay has sunk into it"}


def _notes(runs, left_out, period):
    def at(value):
        return time_text(value, period_resolution(period))

    notes = [f"free decay located: {len(runs)} run{'s' * (len(runs) > 1)} "
             + ", ".join(f"from t = {at(a)} to {at(b)}" for a, b in runs)
             + " (use `start` and `end` to choose by hand)"]
    for a, b, why in left_out:
        notes.append(f"left out t = {at(a)} to {at(b)}: {_WORDS[why]}")
    return notes


def with_placed_release(turning, record):
    """``turning`` with the release where the free decay was found to start after the
    record's first sample (:func:`free_decay_runs`), unless it found a later one."""
    start = float(record.t[0]) if record.t.size else math.nan
    placed = any(end == start for _, end, _ in record.left_out)
    if not placed or math.isfinite(turning.release_time):
        return turning
    return replace(turning, release_time=start)


def free_decay_runs(record) -> list:
    """``record`` kept to its free decay, or one record per free decay where it was excited
    more than once (``run`` "Run 1", "Run 2", ...; within a run of several side by side,
    "Run 3.1"...), by :func:`mcfit.turning.placement.locate_free_decay`. A table of turning
    points, a record against cycle number and a record already placed come back as they
    are. The parts left out are in ``left_out`` and the notes."""
    if (record.kind != "waveform" or record.domain != "time" or record.whole is not None
            or record.placed):
        return [record]
    placement = locate_free_decay(record.t, record.x)
    if not placement.moved:
        return [replace(record, placed=True)]
    several = len(placement.runs) > 1
    runs = []
    for number, (start, end) in enumerate(placement.runs, 1):
        low, high = np.searchsorted(record.t, [start, end], side="left")
        high = record.t.size if end >= record.t[-1] else high
        run = record.run
        if several:
            run = f"Run {number}" if record.run is None else f"{record.run}.{number}"
        runs.append(replace(record, t=record.t[low:high], x=record.x[low:high], run=run,
                            notes=record.notes + placement.notes, placed=True,
                            left_out=placement.left_out, whole=(record.t, record.x)))
    return runs
