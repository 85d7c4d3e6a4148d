"""Turning points (extrema) of a free-decay record: times, amplitudes and their uncertainties.

docs/methods.md sections 1 and 2. numpy/scipy only, no I/O.

Method for a waveform x(t):

1. A coarse period from the spectrum and the white-noise level from the spectrum's floor
   above 2.5 times the oscillation frequency. Gaps longer than 32 samples are left empty
   (zero) in the spectrum, not interpolated: the line across a long gap would be the
   largest peak. A steady line (mains hum) more than 3 times from the oscillation's
   frequency is subtracted here (:mod:`mcfit.hum`) and reported.
2. Coarse extrema: the signal, lightly smoothed, minus a straight-line equilibrium, is split
   into half-cycles by crossings with hysteresis (so noise cannot make false extrema).
3. Each crest is located by a least-squares fit over its half-cycle (the samples within a
   quarter period either side of the crest) of ``x - e(t) = exp(-g*s)*(A*cos(w*s) + B*sin(w*s))``,
   ``s = t - t_k``, with the local angular frequency ``w`` and decay rate ``g`` taken from the
   neighbouring turning points; the crest time is where the fitted phase is 0 or pi.
   Windows are re-centred and the fit repeated until the shifts are far inside the noise.
4. The equilibrium ``e(t) = e0 + e1*t`` is refined from the alternation of the amplitudes: an
   offset error raises every maximum and lowers every minimum, which sixth differences of
   the amplitude sequence isolate.
5. The crest times are smoothed against the crest number (a weighted local quadratic), the
   crests missed in the noise are filled in, and the sequence is continued to the end of the
   record. Each amplitude is then the projection of its half-cycle onto the envelope-shaped
   cosine at that crest: one free parameter, linear in the data, so unbiased however small
   the crest, with variance ``2*sigma_x**2/m`` for ``m`` samples (docs/theory.md section 8). A
   magnitude ``sqrt(A**2 + B**2)`` would be biased upwards near the noise. Amplitudes of
   crests in the noise can be negative.
6. Clipped crests, half-cycles broken by gaps, a start before the free decay (the
   oscillator held still, driven or settling), a floor of vibration the decay sinks into,
   and the tail after the oscillation is lost in white noise are excluded and reported;
   beating, growth and too few turning points raise :class:`RecordError`.

The amplitude reported is the envelope ``y(t_k)`` at the crest of the phase; ``|x - e|`` where
the velocity vanishes is smaller by the factor ``1/sqrt(1 + 1/(4*Q**2))``.

The stages, one module each: :mod:`.spectrum` (step 1), :mod:`.equilibrium`,
:mod:`.refine` (steps 2 to 4), :mod:`.windows` (the half-cycle fits), :mod:`.period`,
:mod:`.crests` (step 5), :mod:`.release`, :mod:`.floor` and :mod:`.checks` (step 6);
:mod:`.tables` for turning points given directly, and :mod:`.result` for the result.
"""

from __future__ import annotations

import numpy as np

from mcfit.errors import UsageError
from mcfit.hum import find_steady_line, subtract_steady_line
from mcfit.turning.checks import (_check_count, _checked_samples, _closing_notes,
                                  _cut_at_rise, _cut_at_stop)
from mcfit.turning.checks import _with_scatter
from mcfit.turning.common import _median
from mcfit.turning.crests import _phase_weights, _projected_crests, _with_excluded
from mcfit.turning.equilibrium import _equilibrium_line
from mcfit.turning.floor import _tail_notes, _vibration_floor
from mcfit.turning.period import _period_and_drift
from mcfit.turning.refine import _coarse_extrema, _refine
from mcfit.turning.release import _held_until, _release, _release_note
from mcfit.turning.result import MIN_TURNING_POINTS, TurningPoints, _frozen
from mcfit.turning.step import find_equilibrium_steps, subtract_equilibrium_steps
from mcfit.turning.spectrum import (_SPECTRUM_SAMPLES, _checked_period, _checked_sampling,
                                    _find_gaps, _gap_note, _spectral_noise, _spectrum)
from mcfit.turning.tables import turning_points_from_table
from mcfit.turning.windows import Samples, _measure

# Re-exported for the modules and tests that import them from mcfit.turning.
from mcfit.turning.checks import _check_range  # noqa: F401, E402
from mcfit.turning.common import HALF_CYCLE_SPACING, SAMPLES_PER_CYCLE  # noqa: F401, E402
from mcfit.turning.crests import _LARGEST_PHASE_VARIANCE, _crest_sequence  # noqa: F401, E402
from mcfit.turning.floor import FLOOR_FACTOR  # noqa: F401, E402

__all__ = [
    "TurningPoints",
    "find_turning_points",
    "turning_points_from_table",
    "turning_points_of",
    "MIN_TURNING_POINTS",
]


def turning_points_of(record, **options):
    """Turning points of a :class:`mcfit.record.Record` (waveform or turning-point table).

    ``options`` go to :func:`find_turning_points` or :func:`turning_points_from_table`.
    """
    source = getattr(record, "source", "record")
    if record.kind == "turning-points":
        return turning_points_from_table(record.t, record.x, domain=record.domain,
                                         source=source, **options)
    return find_turning_points(record.t, record.x, domain=record.domain, source=source,
                               **options)


def find_turning_points(t, x, *, period=None, domain="time", source="record",
                        settle_noise=None):
    """Turning points of a sampled waveform x(t), with amplitudes from half-cycle fits.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times, strictly increasing (any spacing).
    x : ndarray, shape (n,)
        Signal; NaN marks missing samples (gaps). Offset and linear drift are estimated.
    period : float, optional
        Period guess in units of ``t`` (default: from the spectrum).
    domain : {"time", "cycle"}
        Meaning of ``t``, passed through to the result.
    source : str
        Name of the record for messages.
    settle_noise : float, optional
        Sample noise sigma within which the crests' shifts count as settled, which ends
        their refinement (default: the spectrum's noise level). For a noise-free copy of
        a record, the record's noise: its crests are then refined as far as the record's
        were (a noise-free waveform never settles, and takes every pass).

    Returns
    -------
    TurningPoints

    Raises
    ------
    RecordError
        Constant or all-NaN signal, time not increasing, no oscillation above the noise,
        a growing oscillation, or fewer than 4 usable turning points. A rise of the
        amplitude after a fall is no error: the part the decay does not need is left out
        and said in ``notes`` (the end of a decay) or ``warnings`` (a beat or disturbance).
    UsageError
        ``settle_noise`` not a positive number.
    """
    if settle_noise is not None and not (np.isfinite(settle_noise) and settle_noise > 0):
        raise UsageError(f"settle_noise must be a positive number, not {settle_noise!r}")
    t, tf, xf = _checked_samples(t, x, source)
    steps = np.diff(tf)
    dt = float(_median(steps))
    gaps = _find_gaps(tf, steps, dt)
    spectral_period, noise, xf, hum, notes, jumps = _coarse_spectrum(tf, xf, dt, steps, gaps,
                                                                      period)
    del steps  # record-sized: each pass of half-cycle fits finds its wide steps itself
    if gaps:
        notes.insert(0, _gap_note(gaps, spectral_period))
    period = _checked_period(spectral_period if period is None else period, dt, source)
    samples_per_cycle = _checked_sampling(period / dt, source)

    # Coarse extrema about a coarse equilibrium, then half-cycle fits.
    line = _equilibrium_line(tf, xf, period, noise)
    centres, signs = _coarse_extrema(tf, xf, *line, period, samples_per_cycle, noise, source)
    held = _held_until(tf, xf, period, noise)  # crests before it count nowhere
    samples = Samples.of(tf, xf)
    refined = _refine(samples, centres, signs, line, period,
                      noise if settle_noise is None else float(settle_noise), held)
    del centres, signs  # the coarse crests: not needed once refined
    line = refined.line
    m = _measure(samples, refined, noise)
    refined_period = refined.period
    del refined  # its decay rates (two rows as long as the crests) are not needed again

    # Where the free decay starts, and where it ends in a floor.
    release_time, free, release_cause = _release(
        held, m.centres, m.signs, m.magnitude, m.magnitude_sigma, m.measured, refined_period)
    end, floor_level, floor_start = _decay_end(m, free, refined_period, tf[-1])
    in_decay = np.zeros(m.centres.size, dtype=bool)
    in_decay[free:end] = True
    period, period_sigma, drift, drift_sigma = _period_and_drift(
        m.crest_times, m.signs, m.magnitude, m.measured & in_decay, refined_period,
        _phase_weights(m.magnitude, m.magnitude_sigma))

    # The crest phase, continued, and the amplitudes projected onto it.
    limit = tf[-1] if floor_start is None else m.centres[floor_start] - 0.5 * period / 2
    columns, phase_lost = _projected_crests(samples, m, period, line, slice(free, end), limit)
    crests, crest_signs, y, sigma_y, log_step, reasons = _with_excluded(
        m, free, floor_start, columns)

    # Notes, the tail in the noise, the scatter, and the checks.
    notes += _exclusion_notes(release_time, free, release_cause, reasons, crests)
    floor_time = float("nan") if floor_start is None else float(m.centres[floor_start])
    floor_time, floor_level, tail = _tail_notes(crests, y, sigma_y, reasons, floor_time,
                                                floor_level, phase_lost)
    sigma_y, scatter = _with_scatter(y, sigma_y, log_step, reasons == "")
    notes += tail + scatter
    notes += _cut_at_stop(crests, y, sigma_y, reasons)
    rise_release, rise_notes, warnings = _cut_at_rise(crests, y, sigma_y, reasons, source,
                                                      floor_level)
    notes += rise_notes
    warnings = _step_warnings(jumps, crests, y, reasons == "") + list(warnings)
    release_time = rise_release if np.isfinite(rise_release) else release_time
    used = reasons == ""
    _check_count(y, reasons, source)
    e0, e1, t_ref = line
    notes += _closing_notes(domain, drift, drift_sigma, e1 * (tf[-1] - tf[0]), m.noise_sigma,
                            y, samples_per_cycle)
    return TurningPoints(
        t=_frozen(crests), y=_frozen(y), sigma=_frozen(sigma_y),
        sign=_frozen(crest_signs.astype(np.int8)), used=_frozen(used),
        excluded_reason=tuple(str(r) for r in reasons),
        period=period, period_sigma=period_sigma, period_drift=drift,
        period_drift_sigma=drift_sigma,
        equilibrium=float(e0 + e1 * (t[0] - t_ref)), equilibrium_drift=float(e1),
        noise_sigma=float(m.noise_sigma), noise_floor=float(floor_level),
        noise_floor_time=floor_time, release_time=release_time, gaps=tuple(gaps),
        domain=domain, notes=tuple(notes), warnings=tuple(warnings), steady_line=hum,
        t_start=float(t[0]), equilibrium_steps=jumps)


def _coarse_spectrum(tf, xf, dt, steps, gaps, period=None):
    """Step 1: (period, noise sigma, signal, hum removed or None, notes, steps of the
    equilibrium) from the spectrum.

    A steady line (mains hum) far from the oscillation's frequency is subtracted from the
    signal, and the period and noise are then those of the oscillation. Steps of the
    equilibrium (:mod:`.step`) are looked for in the signal as given (the local mean over
    whole periods is blind to a hum) and subtracted; the hum is then looked for again, in
    the signal without them, so that a step is never taken for a slow hum.
    """
    found = _hum_spectrum(tf, xf, dt, steps)
    guess = found[0] if period is None else float(period)
    jumps = find_equilibrium_steps(tf, xf, guess, found[1], gaps)
    if jumps:
        found = _hum_spectrum(tf, subtract_equilibrium_steps(tf, xf, jumps), dt, steps)
    return (*found, jumps)


def _hum_spectrum(tf, xf, dt, steps):
    """(period, noise sigma, signal, hum removed or None, notes) from the spectrum."""
    spectral_period, noise, periodogram = _spectrum(tf, xf, dt, steps)
    notes, removed = [], None
    if periodogram is None:
        return spectral_period, noise, xf, removed, notes
    frequencies, power, _, energy = periodogram[:4]
    line = find_steady_line(tf, xf, periodogram, noise if np.isfinite(noise) else 0.0)
    if line is not None:
        notes.append(line.note())
        if line.removed:
            removed = line
            xf = subtract_steady_line(tf, xf, line)
            spectral_period = 1.0 / line.oscillation_frequency
            noise = _spectral_noise(power, frequencies, line.oscillation_frequency, energy,
                                    xf[:_SPECTRUM_SAMPLES])
    return spectral_period, noise, xf, removed, notes


def _step_warnings(jumps, crests, y, used):
    """The warnings naming the steps of the equilibrium, each as a share of the first used
    amplitude and of the used amplitudes there (interpolated)."""
    if not jumps or not used.any():
        return [jump.warning(np.nan, np.nan) for jump in jumps]
    times, amplitudes = crests[used], y[used]
    return [jump.warning(float(amplitudes[0]), float(np.interp(jump.time, times, amplitudes)))
            for jump in jumps]


def _exclusion_notes(release_time, free, release_cause, reasons, crests=()):
    """Notes on the crests excluded before the release and as clipped."""
    notes = []
    if np.isfinite(release_time):
        notes.append(_release_note(release_time, free, release_cause, crests))
    if np.any(reasons == "clipped"):
        n_clip = int(np.count_nonzero(reasons == "clipped"))
        notes.append(f"{n_clip} clipped (saturated) extrema excluded")
    return notes


def _decay_end(m, free, period, t_end):
    """(end, floor level, index of the first crest in a vibration floor or None): the
    crests of the free decay are ``free:end``."""
    after_release = np.arange(m.centres.size) >= free
    floor_level, floor_start = _vibration_floor(
        m.centres, m.signs, m.magnitude, m.magnitude_sigma, m.gain, m.measured & after_release,
        noise_sigma=m.noise_sigma, period=period, t_end=t_end)
    end = m.centres.size if floor_start is None else floor_start
    return end, floor_level, floor_start
