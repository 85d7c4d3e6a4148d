"""Turning points (extrema) of a free-decay record: times, amplitudes and their uncertainties.

THEORY.md section 5, steps 1 and 2. numpy/scipy only, no I/O.

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
   the crest, with variance ``2*sigma_x**2/m`` for ``m`` samples (THEORY.md section 7). A
   magnitude ``sqrt(A**2 + B**2)`` would be biased upwards near the noise. Amplitudes of
   crests in the noise can be negative.
6. Clipped crests, half-cycles broken by gaps, a start before the free decay (the
   oscillator held still, driven or settling), a floor of vibration the decay sinks into,
   and the tail after the oscillation is lost in white noise are excluded and reported;
   beating, growth and too few turning points raise :class:`RecordError`.

The amplitude reported is the envelope ``y(t_k)`` at the crest of the phase; ``|x - e|`` where
the velocity vanishes is smaller by the factor ``1/sqrt(1 + 1/(4*Q**2))``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage, special, stats

from mcfit.errors import RecordError
from mcfit.hum import find_steady_line, subtract_steady_line

__all__ = [
    "TurningPoints",
    "find_turning_points",
    "turning_points_from_table",
    "turning_points_of",
    "MIN_TURNING_POINTS",
]

MIN_TURNING_POINTS = 4
# Samples processed at once in the local fits (bounds the memory of a 1e7-sample record).
_BLOCK_SAMPLES = 1 << 20
# Longest stretch fed to the FFT for the coarse period and noise level.
_SPECTRUM_SAMPLES = 1 << 21
_REFINE_PASSES = 6
# An amplitude below FLOOR_FACTOR times the floor level is dominated by the floor.
FLOOR_FACTOR = 1.5
# Larger times or signal values overflow float64 once squared and summed.
_LARGEST_VALUE = 1e30
# Sixth-difference windows needed to fit the equilibrium's drift as well as its offset.
_DRIFT_WINDOWS = 8
# A gap longer than this many median steps is left empty (zeros) in the spectrum.
_LONG_GAP_STEPS = 32


@dataclass(frozen=True, eq=False)
class TurningPoints:
    """Turning points of a record, with what was excluded and why.

    Attributes
    ----------
    t : ndarray, shape (k,)
        Crest times (time units of the record, or cycle number n).
    y : ndarray, shape (k,)
        Amplitudes about the equilibrium (signal units): > 0 but for crests within the
        noise, where the projection can be 0 or negative.
    sigma : ndarray, shape (k,)
        Standard deviation estimate of each amplitude.
    sign : ndarray of int, shape (k,)
        +1 for a maximum, -1 for a minimum (0 if unknown, as in unsigned tables).
    used : ndarray of bool, shape (k,)
        The points a fit should use.
    excluded_reason : tuple of str
        "" for used points, else "before release", "noise floor", "clipped", "gap" or
        "edge".
    period : float
        Oscillation period from the turning-point spacing (NaN if unknown).
    period_sigma : float
        Its standard error.
    period_drift : float
        Relative change of the period from the smallest to the largest used amplitude,
        (T(y_max) - T(y_min))/T; positive when large swings are slower.
    period_drift_sigma : float
    equilibrium : float
        Equilibrium value at the first sample.
    equilibrium_drift : float
        Slope of the equilibrium (signal units per time unit).
    noise_sigma : float
        Standard deviation of the sample noise (NaN for tables).
    noise_floor : float
        Amplitude level of the noise floor (0 if none was found).
    noise_floor_time : float
        Time from which the tail was excluded as noise floor (NaN if none).
    release_time : float
        Start of the free decay when the record starts before it: where a signal held
        still starts to move, or the first crest of the decay after amplitudes rising or
        flat (driven or settling). The turning points before it are excluded as "before
        release". NaN when the record decays freely from its start.
    gaps : tuple of (float, float)
        Start and end times of gaps in the record.
    domain : {"time", "cycle"}
    notes : tuple of str
    """

    t: np.ndarray
    y: np.ndarray
    sigma: np.ndarray
    sign: np.ndarray
    used: np.ndarray
    excluded_reason: tuple[str, ...]
    period: float = float("nan")
    period_sigma: float = float("nan")
    period_drift: float = float("nan")
    period_drift_sigma: float = float("nan")
    equilibrium: float = 0.0
    equilibrium_drift: float = 0.0
    noise_sigma: float = float("nan")
    noise_floor: float = 0.0
    noise_floor_time: float = float("nan")
    release_time: float = float("nan")
    gaps: tuple[tuple[float, float], ...] = ()
    domain: str = "time"
    notes: tuple[str, ...] = field(default=())
    steady_line: object = None  # the hum subtracted before the search (mcfit.hum.SteadyLine)

    @property
    def count(self):
        """Number of used turning points."""
        return int(np.count_nonzero(self.used))

    def to_dict(self):
        """Plain Python data (lists, floats, None for NaN), ready for JSON."""
        def number(value):
            value = float(value)
            return value if np.isfinite(value) else None

        return {
            "t": [float(v) for v in self.t],
            "y": [float(v) for v in self.y],
            "sigma": [number(v) for v in self.sigma],
            "sign": [int(v) for v in self.sign],
            "used": [bool(v) for v in self.used],
            "excluded_reason": list(self.excluded_reason),
            "period": number(self.period),
            "period_sigma": number(self.period_sigma),
            "period_drift": number(self.period_drift),
            "period_drift_sigma": number(self.period_drift_sigma),
            "equilibrium": number(self.equilibrium),
            "equilibrium_drift": number(self.equilibrium_drift),
            "noise_sigma": number(self.noise_sigma),
            "noise_floor": number(self.noise_floor),
            "noise_floor_time": number(self.noise_floor_time),
            "release_time": number(self.release_time),
            "gaps": [[float(a), float(b)] for a, b in self.gaps],
            "domain": self.domain,
            "notes": list(self.notes),
        }


def turning_points_of(record, **options):
    """Turning points of a :class:`mcfit.records.Record` (waveform or turning-point table).

    ``options`` go to :func:`find_turning_points` or :func:`turning_points_from_table`.
    """
    source = getattr(record, "source", "record")
    if record.kind == "turning-points":
        return turning_points_from_table(record.t, record.x, domain=record.domain,
                                         source=source, **options)
    return find_turning_points(record.t, record.x, domain=record.domain, source=source,
                               **options)


# --------------------------------------------------------------------------- waveforms


def find_turning_points(t, x, *, period=None, domain="time", source="record"):
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

    Returns
    -------
    TurningPoints

    Raises
    ------
    RecordError
        Constant or all-NaN signal, time not increasing, no oscillation above the noise,
        beating, a growing oscillation, or fewer than 4 usable turning points.
    """
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
    notes = []
    if not finite.all():
        tf, xf = t[finite], x[finite]
    else:
        tf, xf = t, x
    _check_range(tf, xf, source)
    if tf.size < 16:
        raise RecordError(f"{source} has only {tf.size} samples. A waveform needs several "
                          "cycles of at least 8 samples each.")
    if np.ptp(xf) == 0:
        raise RecordError(f"the signal of {source} is constant ({xf[0]:g}). Choose the signal "
                          "column with `signal_col`.")

    steps = np.diff(tf)
    dt = float(np.median(steps))
    gaps = _find_gaps(t, finite, tf, steps, dt)
    spectral_period, noise, periodogram = _spectrum(tf, xf, dt, steps)
    removed = None
    if periodogram is not None:  # a hum far from the oscillation's frequency
        frequencies, power, _, energy, _ = periodogram
        line = find_steady_line(tf, xf, periodogram, noise if np.isfinite(noise) else 0.0)
        removed = line if line is not None and line.removed else None
        if line is not None:
            notes.append(line.note())
            if line.removed:
                xf = subtract_steady_line(tf, xf, line)
                spectral_period = 1.0 / line.oscillation_frequency
                noise = _spectral_noise(power, frequencies, line.oscillation_frequency,
                                        energy, xf[:_SPECTRUM_SAMPLES])
    if gaps:
        notes.insert(0, _gap_note(gaps, spectral_period))
    if period is None:
        period = spectral_period
    period = float(period)
    if not np.isfinite(period) or period <= 2 * dt:
        raise RecordError(f"no oscillation found in {source}: the spectrum peaks at a period "
                          f"of {period:.3g}, under 2 samples. Check the signal column.")
    samples_per_cycle = period / dt

    # Coarse equilibrium: a straight line through the data, weighted towards small swings.
    e0, e1, t_ref = _equilibrium_line(tf, xf, period, noise)
    centres, signs = _coarse_extrema(tf, xf, e0, e1, t_ref, period, samples_per_cycle,
                                      noise, source)

    gamma = np.zeros((2, centres.size))  # decay rate and its slope at each crest
    valid = np.ones(centres.size, dtype=bool)
    held = _held_until(tf, xf, period, noise)  # crests before it count nowhere
    for refinement in range(_REFINE_PASSES):
        half = _local_half_periods(centres, period, valid)
        fit = _fit_windows(tf, xf, centres, signs, half, gamma, e0, e1, t_ref)
        # Equilibrium update from the alternation of maxima and minima; flattened crests
        # would bias it.
        fit.valid &= ~_clipped(fit, signs) & (np.arange(centres.size) >= _held_crests(
            centres, held, period))
        delta0, delta1 = _equilibrium_correction(centres, fit, half, t_ref)
        e0, e1 = e0 + delta0, e1 + delta1
        settled = refinement > 0 and _shifts_within_noise(fit, half, noise)
        centres = centres + np.where(fit.valid, np.clip(fit.shift, -half / 4, half / 4), 0.0)
        keep = np.concatenate([[True], np.diff(centres) > 0.25 * half[1:]])
        centres, signs, valid, y = centres[keep], signs[keep], fit.valid[keep], fit.y[keep]
        half = _local_half_periods(centres, period, valid)
        gamma = _local_decay_rates(centres, y, np.pi / half, valid)
        period = _period_estimate(centres, signs, valid, period)
        if settled:
            break

    half = _local_half_periods(centres, period, valid)
    fit = _fit_windows(tf, xf, centres, signs, half, gamma, e0, e1, t_ref)

    noise_sigma = _pooled_noise(fit)
    if not np.isfinite(noise_sigma):
        noise_sigma = noise
    magnitude = np.abs(fit.y)
    magnitude_sigma = _amplitude_sigma(noise_sigma, fit.gain)
    measured = fit.valid & ~_clipped(fit, signs)
    release_time, free, release_cause = _release(held, centres, signs, magnitude,
                                                 magnitude_sigma, measured, period)
    after_release = np.arange(centres.size) >= free
    floor_level, floor_start = _vibration_floor(
        centres, signs, magnitude, magnitude_sigma, fit, measured & after_release,
        noise_sigma=noise_sigma, period=period, t_end=tf[-1])
    before_floor = np.arange(centres.size) < (centres.size if floor_start is None else floor_start)
    in_decay = after_release & before_floor
    crest_times = centres + np.where(fit.valid, fit.shift, 0.0)
    period, period_sigma, drift, drift_sigma = _period_and_drift(
        crest_times, signs, magnitude, measured & in_decay, period,
        _phase_weights(magnitude, magnitude_sigma))

    # Crest times from the phase of all crests, continued to the end of the decay, and
    # amplitudes as projections onto that phase (THEORY.md section 7: near the noise a
    # magnitude is biased, a projection is not).
    end = int(np.count_nonzero(before_floor))
    limit = tf[-1] if floor_start is None else centres[floor_start] - 0.5 * period / 2
    half = _local_half_periods(centres, period, fit.valid)
    weights = np.where(measured, _phase_weights(magnitude, magnitude_sigma), 0.0)
    crests, crest_signs, phase_variance, phase_lost = _crest_sequence(
        crest_times[free:end], signs[free:end], half[free:end], weights[free:end], limit)
    reliable = measured & in_decay & (magnitude > 5 * magnitude_sigma)
    crest_gamma = _decay_rates_at(crests, centres, magnitude, np.pi / half, reliable)
    crest_half = _local_half_periods(crests, period, np.ones(crests.size, dtype=bool))
    projected = _fit_windows(tf, xf, crests, crest_signs, crest_half, crest_gamma, e0, e1, t_ref)
    keep = projected.count > 0  # crests filled in across a long gap have no samples
    if not keep.all():
        crests, crest_signs = crests[keep], crest_signs[keep]
        crest_half, crest_gamma = crest_half[keep], crest_gamma[:, keep]
        phase_variance = phase_variance[keep]
        projected = _fit_windows(tf, xf, crests, crest_signs, crest_half, crest_gamma,
                                 e0, e1, t_ref)
    # A phase error d scales a projection by cos(d), on average by exp(-var(d)/2) for a
    # Gaussian error: undone here. It matters in the faint tail, where the crest times are
    # least certain (there var(d) reaches about 0.1 at a few sigma).
    variance_d = np.minimum(np.nan_to_num(phase_variance, nan=0.0), _LARGEST_PHASE_VARIANCE)
    phase_gain = np.exp(0.5 * variance_d)
    y = projected.projection * phase_gain
    sigma_y = _amplitude_sigma(noise_sigma, projected.projection_gain) * phase_gain
    # The phase error also scatters the projection, y*(cos(d) + k*sin(d)) with k the
    # window's phase sensitivity (0 when symmetric, about 0.64 when cut at the crest):
    # var = y**2*((1 - e**-v)**2 + k**2*(1 - e**-2v))/2, here with y from the running
    # median of its neighbours: from the crest itself, a crest raised by noise would get a
    # larger sigma and pull the fit down.
    envelope = np.maximum(_running_median(y, 9), 0.0)
    sigma_y = np.sqrt(sigma_y**2 + (envelope * phase_gain) ** 2 / 2.0 * (
        (1.0 - np.exp(-variance_d)) ** 2
        + projected.phase_sensitivity**2 * (1.0 - np.exp(-2.0 * variance_d))))
    log_step = crest_gamma[0] * crest_half
    reasons = np.array([""] * crests.size, dtype=object)
    reasons[~projected.complete] = np.where(projected.edge[~projected.complete], "edge", "gap")
    reasons[(reasons == "") & _clipped(projected, crest_signs)] = "clipped"
    # The crests before the release and in the floor, with their magnitudes.
    parts = [_excluded_crests(slice(0, free), centres, signs, magnitude, magnitude_sigma,
                              "before release"),
             (crests, crest_signs, y, sigma_y, log_step, reasons)]
    if floor_start is not None:
        parts.append(_excluded_crests(slice(floor_start, None), centres, signs, magnitude,
                                      magnitude_sigma, "noise floor"))
    crests, crest_signs, y, sigma_y, log_step, reasons = (np.concatenate(c)
                                                          for c in zip(*parts))
    if np.isfinite(release_time):
        notes.append(_release_note(release_time, free, release_cause))
    if np.any(reasons == "clipped"):
        n_clip = int(np.count_nonzero(reasons == "clipped"))
        notes.append(f"{n_clip} clipped (saturated) extrema excluded")

    floor_time = float("nan")
    if floor_start is not None:
        floor_time = float(centres[floor_start])
        notes.append(f"noise floor at amplitude {floor_level:.3g}: "
                     f"{int(np.count_nonzero(reasons == 'noise floor'))} turning points from "
                     f"t = {floor_time:.6g} excluded")
        if phase_lost is not None and phase_lost < floor_time:
            notes.append(f"the crest phase is lost in the noise from t = {phase_lost:.6g}: "
                         f"the record from there to the noise floor is not used")
    else:
        cut = _sinks_below_noise(y, sigma_y, reasons == "")
        if cut is not None:
            in_floor = (np.arange(y.size) >= cut) & (reasons == "")
            reasons[in_floor] = "noise floor"
            floor_time = float(crests[cut])
            floor_level = float(np.median(sigma_y[reasons == ""]))
            notes.append(f"noise floor: the oscillation is lost in the noise (amplitude "
                         f"sigma {floor_level:.3g}); {int(in_floor.sum())} turning points from "
                         f"t = {floor_time:.6g} excluded")
        elif phase_lost is not None:
            floor_time = phase_lost
            floor_level = float(np.median(sigma_y[reasons == ""])) if np.any(reasons == "") \
                else 0.0
            notes.append(f"noise floor: the crest phase is lost in the noise from "
                         f"t = {floor_time:.6g} (amplitude sigma {floor_level:.3g}); the "
                         "record after it is not used")
    scatter = _amplitude_scatter(y, sigma_y, log_step, reasons == "")
    white = float(np.sqrt(np.median(sigma_y[reasons == ""] ** 2))) if np.any(reasons == "") \
        else float("nan")
    if np.isfinite(scatter) and scatter > 1.5 * white and scatter > 1e-5 * np.max(y):
        sigma_y = np.sqrt(sigma_y**2 + scatter**2 - white**2)
        notes.append(f"amplitudes scatter by {scatter:.3g} about a smooth envelope, "
                     f"{scatter / white:.3g} times what the sample noise explains (correlated "
                     "noise or disturbances): sigma includes the excess")
    used = reasons == ""
    _check_decay(crests, y, sigma_y, used, source, floor_level)
    n_used = int(np.count_nonzero(used))
    if n_used < MIN_TURNING_POINTS:
        raise RecordError(
            f"only {n_used} usable turning points in {source} (need {MIN_TURNING_POINTS}): "
            f"{y.size} found, {y.size - n_used} excluded ({_reason_summary(reasons)}). Use a "
            "longer record, or check the signal column and the noise.")

    if domain == "time" and np.isfinite(drift_sigma) and abs(drift) > 3 * drift_sigma \
            and abs(drift) > 1e-3:
        notes.append(f"the period changes by {100 * drift:+.2g}% from the smallest to the "
                     "largest amplitude (nonlinear stiffness or large swings)")
    if abs(e1) * (tf[-1] - tf[0]) > 3 * noise_sigma / np.sqrt(max(y.size, 1)) and \
            abs(e1) * (tf[-1] - tf[0]) > 1e-3 * np.max(y):
        notes.append(f"equilibrium drifts by {e1 * (tf[-1] - tf[0]):.3g} over the record")
    if samples_per_cycle < 8:
        notes.append(f"only {samples_per_cycle:.3g} samples per cycle: amplitudes are less "
                     "accurate below 8")
    return TurningPoints(
        t=_frozen(crests), y=_frozen(y), sigma=_frozen(sigma_y),
        sign=_frozen(crest_signs.astype(np.int8)), used=_frozen(used),
        excluded_reason=tuple(str(r) for r in reasons),
        period=period, period_sigma=period_sigma, period_drift=drift,
        period_drift_sigma=drift_sigma,
        equilibrium=float(e0 + e1 * (t[0] - t_ref)), equilibrium_drift=float(e1),
        noise_sigma=float(noise_sigma), noise_floor=float(floor_level),
        noise_floor_time=floor_time, release_time=release_time, gaps=tuple(gaps),
        domain=domain, notes=tuple(notes),
        steady_line=removed)


def _check_range(t, x, source):
    for what, values, fix in (("time", t, "give the time in other units"),
                              ("signal", x, "rescale the signal")):
        largest = float(np.max(np.abs(values))) if values.size else 0.0
        if largest > _LARGEST_VALUE:
            raise RecordError(f"the {what} of {source} reaches {largest:.3g}, beyond what mcfit "
                              f"handles in double precision ({_LARGEST_VALUE:.0e}); {fix}.")


def _frozen(array):
    array = np.ascontiguousarray(array)
    array.setflags(write=False)
    return array


def _reason_summary(reasons):
    values, counts = np.unique([r for r in reasons if r], return_counts=True)
    return ", ".join(f"{c} {v}" for v, c in zip(values, counts)) or "none"


def _find_gaps(t, finite, tf, steps, dt):
    """Stretches with missing samples or a time step over 2.5 median steps."""
    gaps = []
    long_steps = np.flatnonzero(steps > 2.5 * dt)
    for i in long_steps[:1000]:
        gaps.append((float(tf[i]), float(tf[i + 1])))
    return sorted(gaps)


def _gap_note(gaps, period):
    """Where the gaps are: the fit spans them with the turning points on both sides."""
    start, end = max(gaps, key=lambda g: g[1] - g[0])
    cycles = f", about {(end - start) / period:.3g} periods" if np.isfinite(period) else ""
    where = f"from t = {start:.6g} to {end:.6g} ({end - start:.4g} time units{cycles})"
    if len(gaps) == 1:
        head = f"a gap in the record {where}"
    else:
        total = sum(b - a for a, b in gaps)
        head = (f"{len(gaps)} gaps in the record, {total:.4g} time units in all, the longest "
                f"{where}")
    return head + ": bridged, the turning points on both sides are used"


def _line_fit(t, x):
    """Least-squares straight line x = e0 + e1*(t - t_ref), computed in chunks."""
    t_ref = float(t[0] + 0.5 * (t[-1] - t[0]))
    n = t.size
    st = sx = stt = stx = 0.0
    for start in range(0, n, _BLOCK_SAMPLES):
        tt = t[start:start + _BLOCK_SAMPLES] - t_ref
        xx = x[start:start + _BLOCK_SAMPLES]
        st += tt.sum()
        sx += xx.sum()
        stt += np.dot(tt, tt)
        stx += np.dot(tt, xx)
    denominator = n * stt - st * st
    e1 = (n * stx - st * sx) / denominator if denominator > 0 else 0.0
    e0 = (sx - e1 * st) / n
    return float(e0), float(e1), t_ref


def _equilibrium_line(t, x, period, noise):
    """Coarse equilibrium line (e0, e1, t_ref), each period weighted by 1/(its swing)**2.

    An unweighted line through a fast decay (Q of a few) is pulled towards the first
    half-cycle, which can leave every later, smaller swing on one side of it and hide its
    crests. Weighting each period by its swing about the line lets the small late swings,
    which show the equilibrium best, set it; for a slow decay the weights are nearly equal
    and the line is the plain fit. The weight is capped at 1e12 times the largest swing's.
    """
    e0, e1, t_ref = _line_fit(t, x)
    edges = np.searchsorted(t, t[0] + period * np.arange(1, int((t[-1] - t[0]) / period) + 1))
    starts = np.unique(np.concatenate([[0], edges[edges < t.size]]))
    if starts.size < 3:
        return e0, e1, t_ref
    counts = np.diff(np.append(starts, t.size))
    tau = t - t_ref
    sums = [np.add.reduceat(v, starts) for v in (tau, x, tau * tau, tau * x)]
    for _ in range(3):
        swing = np.maximum.reduceat(np.abs(x - (e0 + e1 * tau)), starts)
        largest = float(np.max(swing))
        floor = 1e-6 * largest
        if np.isfinite(noise):
            floor = max(floor, 3.0 * noise)
        if not floor > 0:
            break
        weight = (largest / np.maximum(swing, floor)) ** 2  # relative: no overflow for tiny x
        sw = float(np.dot(weight, counts))
        st, sx, stt, stx = (float(np.dot(weight, s)) for s in sums)
        denominator = sw * stt - st * st
        if not denominator > 0:
            break
        e1 = (sw * stx - st * sx) / denominator
        e0 = (sx - e1 * st) / sw
    return float(e0), float(e1), t_ref


def _spectrum(t, x, dt, steps):
    """(period, noise sigma, periodogram) from a Hann-windowed periodogram of the first
    stretch; the periodogram is (frequencies, power, window sum, window sum of squares,
    bin of the peak), or None when too short."""
    n = min(t.size, _SPECTRUM_SAMPLES)
    irregular = steps[: n - 1].size and (steps[: n - 1].max() > 1.05 * steps[: n - 1].min())
    outside = None
    if irregular:
        grid = t[0] + dt * np.arange(int((t[n - 1] - t[0]) / dt) + 1)
        grid = grid[:_SPECTRUM_SAMPLES]
        v = np.interp(grid, t[:n], x[:n])
        outside = _in_long_gaps(grid, t[:n], steps[: n - 1], dt)
    else:
        v = x[:n].astype(np.float64, copy=True)
    m = v.size
    index = np.arange(m, dtype=np.float64) - 0.5 * (m - 1)  # centred: the line's terms decouple
    if outside is None:
        slope = float(np.dot(index, v) / np.dot(index, index)) if m > 1 else 0.0
        v -= v.mean() + slope * index
    else:  # a straight line across a long gap would be a spectral line of its own: zeros
        inside = ~outside
        slope, mean = np.polyfit(index[inside], v[inside], 1)
        v -= mean + slope * index
        v[outside] = 0.0
    window = np.hanning(m)
    v *= window
    power = np.abs(np.fft.rfft(v)) ** 2
    del v
    frequencies = np.fft.rfftfreq(m, d=dt)
    lowest = 2  # periods longer than half the stretch are drift, not oscillation
    if power.size <= lowest + 2:
        return float("nan"), float("nan"), None
    k = lowest + int(np.argmax(power[lowest:]))
    if 0 < k < power.size - 1:
        a, b, c = np.log(power[k - 1:k + 2] + 1e-300)
        denominator = a - 2 * b + c
        offset = 0.5 * (a - c) / denominator if denominator < 0 else 0.0
    else:
        offset = 0.0
    f0 = (k + offset) * frequencies[1]
    energy = np.dot(window, window)
    noise = _spectral_noise(power, frequencies, f0, energy, x[:n])
    return ((1.0 / f0 if f0 > 0 else float("nan")), noise,
            (frequencies, power, float(window.sum()), energy, k))


def _spectral_noise(power, frequencies, f0, energy, x):
    """White-noise sigma from the periodogram's floor above 2.5*f0 (``energy``: the
    window's sum of squares)."""
    band = power[frequencies > 2.5 * f0]
    if band.size >= 16:
        return float(np.sqrt(np.median(band) / (np.log(2) * energy)))
    # Too few samples per cycle for a clean band: differences overestimate, safely.
    d = np.diff(x)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2))


def _in_long_gaps(grid, t, steps, dt):
    """Grid points inside gaps longer than _LONG_GAP_STEPS median steps (None if none)."""
    long_steps = np.flatnonzero(steps > _LONG_GAP_STEPS * dt)
    if long_steps.size == 0:
        return None
    edges = np.zeros(grid.size + 1)
    np.add.at(edges, np.searchsorted(grid, t[long_steps], side="right"), 1.0)
    np.add.at(edges, np.searchsorted(grid, t[long_steps + 1]), -1.0)
    return np.cumsum(edges[:-1]) > 0


def _coarse_extrema(t, x, e0, e1, t_ref, period, samples_per_cycle, noise, source):
    """Crest times and signs: half-cycles split by crossings with hysteresis."""
    width = max(1, int(samples_per_cycle / 8))
    if width > 1:
        cumulative = np.concatenate([[0.0], np.cumsum(x)])
        smooth = np.empty_like(x)
        half = width // 2
        lo = np.clip(np.arange(x.size) - half, 0, x.size)
        hi = np.clip(np.arange(x.size) - half + width, 0, x.size)
        smooth[:] = (cumulative[hi] - cumulative[lo]) / (hi - lo)
        del cumulative, lo, hi
    else:
        smooth = x.copy()
    smooth -= e0 + e1 * (t - t_ref)
    scale = float(np.percentile(np.abs(smooth[: min(smooth.size, 1 << 22)]), 99.5))
    threshold = 4.0 * noise / np.sqrt(width)
    if not np.isfinite(threshold) or threshold <= 0:
        threshold = 1e-3 * scale
    if threshold > 0.3 * scale:
        raise RecordError(f"no oscillation above the noise in {source}: the signal swings by "
                          f"{scale:.3g} about its mean and the noise is {noise:.3g}. Check the "
                          "signal column.")
    state = np.zeros(x.size, dtype=np.int8)
    state[smooth > threshold] = 1
    state[smooth < -threshold] = -1
    marked = np.flatnonzero(state)
    if marked.size == 0:
        raise RecordError(f"no oscillation found in {source}. Check the signal column.")
    # Forward-fill the last definite side: each run of one side is a half-cycle.
    filled_index = np.maximum.accumulate(np.where(state != 0, np.arange(x.size), -1))
    side = np.where(filled_index >= 0, state[np.maximum(filled_index, 0)], 0)
    del state, filled_index
    changes = np.flatnonzero(np.diff(side) != 0) + 1
    starts = np.concatenate([[marked[0]], changes[changes > marked[0]]])
    stops = np.concatenate([starts[1:], [x.size]])
    run_sign = side[starts].astype(np.int64)
    del side
    # Crest of each run: index of its largest value on its side.
    best = np.empty(starts.size, dtype=np.int64)
    for k in range(starts.size):
        segment = smooth[starts[k]:stops[k]]
        best[k] = starts[k] + (np.argmax(segment) if run_sign[k] > 0 else np.argmin(segment))
    # A crest on the very first or last sample is a cut half-cycle: no crest inside.
    inside = (best > 0) & (best < x.size - 1)
    centres = t[best[inside]]
    signs = run_sign[inside]
    if centres.size < MIN_TURNING_POINTS:
        raise RecordError(f"only {centres.size} turning points found in {source} (need "
                          f"{MIN_TURNING_POINTS}). Use a record of several cycles.")
    return centres.astype(np.float64), signs


def _local_half_periods(centres, period, valid):
    """Half-period at each crest from the spacing of valid neighbours, robust to misses."""
    nominal = 0.5 * period
    index = np.flatnonzero(valid)
    if index.size < 2:
        return np.full(centres.size, nominal)
    spacing = np.diff(centres[index]) / np.maximum(np.diff(index), 1)
    spacing = np.where((spacing > 0.6 * nominal) & (spacing < 1.4 * nominal), spacing, nominal)
    if spacing.size >= 5:  # the spacing of noisy crests scatters: smooth it over 5 crests
        spacing = _running_median(spacing, 5)
    middle = 0.5 * (centres[index][1:] + centres[index][:-1])
    if middle.size == 1:
        return np.full(centres.size, spacing[0])
    return np.interp(centres, middle, spacing)


def _local_decay_rates(centres, y, omega, valid):
    """Rows (g, dg/dt): -d ln(y)/dt at each crest from valid neighbours, smoothed, and its
    slope; 0 where unknown. The slope lets a window's envelope, exp(-g*s - dg/dt*s**2/2),
    follow a decay rate that changes within the half-cycle (low Q with fluid or Coulomb
    damping), which would otherwise bias the amplitudes."""
    index = np.flatnonzero(valid & (y > 0))
    if index.size < 3:
        return np.zeros((2, centres.size))
    log_y = np.log(y[index])
    rate = -np.diff(log_y) / np.diff(centres[index])
    if rate.size >= 7:
        rate = _running_median(rate, 7)
    middle = 0.5 * (centres[index][1:] + centres[index][:-1])
    gamma = np.clip(_interpolate_extending_ends(centres, middle, rate), -0.3 * omega,
                    0.3 * omega)
    slope = np.zeros(centres.size)
    if rate.size >= 7:
        slope = _interpolate_extending_ends(
            centres, middle[1:-1], (rate[2:] - rate[:-2]) / (middle[2:] - middle[:-2]))
        # Under the law |dg/dt| = |c/y**2 - a|*P(y) <= g**2 (|n - 1|*g**2 for dy/dt =
        # -k*y**n): twice that bounds a slope from noisy or gapped rates, which could
        # otherwise bend a window's envelope by 10 %.
        limit = np.minimum(2.0 * gamma**2, 0.1 * omega**2)
        slope = np.clip(_running_median(slope, 7), -limit, limit)
    return np.vstack([gamma, slope])


def _interpolate_extending_ends(x, xp, fp):
    """np.interp, but continued past the first and last points by the parabola through the
    three outermost ones, not held flat: the first and last crests lie half an interval
    beyond the outermost rate midpoints, where the decay rate of a low-Q record still
    curves (a straight continuation leaves 1e-5 errors in the first amplitudes at Q 12)."""
    values = np.interp(x, xp, fp)
    if xp.size >= 3:
        for outside, ends in ((x < xp[0], slice(0, 3)), (x > xp[-1], slice(-3, None))):
            if np.any(outside):
                values[outside] = _parabola(x[outside], xp[ends], fp[ends])
    elif xp.size == 2:
        slope = (fp[1] - fp[0]) / (xp[1] - xp[0])
        values = np.where(x < xp[0], fp[0] + (x - xp[0]) * slope, values)
        values = np.where(x > xp[1], fp[1] + (x - xp[1]) * slope, values)
    return values


def _parabola(x, xp, fp):
    """The quadratic through three points (xp, fp), evaluated at x (Lagrange form)."""
    (x0, x1, x2), (f0, f1, f2) = xp, fp
    return (f0 * (x - x1) * (x - x2) / ((x0 - x1) * (x0 - x2))
            + f1 * (x - x0) * (x - x2) / ((x1 - x0) * (x1 - x2))
            + f2 * (x - x0) * (x - x1) / ((x2 - x0) * (x2 - x1)))


# Crests either side of each one in the local fit of crest time against crest number.
_PHASE_HALF_WIDTH = 10
# Beyond this phase variance (rad**2) a crest's phase is mostly noise: its projection's
# bias is corrected no further.
_LARGEST_PHASE_VARIANCE = 1.0
# Crests whose phase is known to 0.1 rad (inverse variance 100 rad**-2) are numbered
# reliably by their spacing; the others are numbered against them (_renumbered).
_RELIABLE_PHASE_WEIGHT = 100.0
# A smoothed crest phase this certain (rad**2) keeps the local quadratic, which follows an
# amplitude-dependent period without bias, whatever a line's variance.
_CERTAIN_PHASE_VARIANCE = 1e-3


def _crest_numbers(times, signs, half):
    """Whole half-periods from the first crest: each step is the nearest whole number of
    local half-periods whose parity agrees with the signs (odd when they alternate)."""
    if times.size < 2:
        return np.zeros(times.size, dtype=np.int64)
    ratio = np.diff(times) / (0.5 * (half[1:] + half[:-1]))
    step = np.maximum(np.rint(ratio), 1.0)
    wrong = (step % 2 == 1) != (signs[1:] != signs[:-1])
    nearer = np.where(ratio > step, step + 1, step - 1)
    step = np.where(wrong, np.where(nearer >= 1, nearer, step + 1), step)
    return np.concatenate([[0], np.cumsum(step)]).astype(np.int64)


def _smooth_crest_times(numbers, times, weights, count):
    """Crest times at numbers 0..count-1: a weighted local quadratic in the crest number
    over 2*_PHASE_HALF_WIDTH + 1 crests (tricube kernel), local linear where too few crests
    are measured, and past the last measured crest the straight line continuing it.

    ``weights`` are the inverse variances of the measured crest phases (rad**-2).

    Returns (times, half-period at the last measured crest, phase variance, growth). The
    variance (rad**2) of each smoothed crest phase is that of a linear smoother,
    ``e1' M^-1 N M^-1 e1`` with ``M`` the kernel-weighted and ``N`` the squared-kernel-
    weighted moments. ``growth`` = (covariance of the last measured crest's phase with the
    continuing slope, variance of that slope) per crest: the variance ``k`` crests further
    on is ``variance[last] + 2*k*growth[0] + k**2*growth[1]``.
    """
    have = weights > 0
    first, last = numbers[have][0], numbers[have][-1]
    slope = (times[have][-1] - times[have][0]) / max(last - first, 1)
    origin = times[have][0] - first * slope
    w = np.zeros(count)
    r = np.zeros(count)
    n_measured = min(last + 1, count)
    inside = numbers < count
    w[numbers[inside]] = weights[inside]
    r[numbers[inside]] = (times - (origin + numbers * slope))[inside]
    d = np.arange(-_PHASE_HALF_WIDTH, _PHASE_HALF_WIDTH + 1, dtype=np.float64)
    kernel = (1.0 - (np.abs(d) / (_PHASE_HALF_WIDTH + 1)) ** 3) ** 3
    # Moments sum_d K(d) d**p w(m+d), sum_d K(d)**2 d**p w(m+d) (for the variances) and
    # sum_d K(d) d**p w(m+d) r(m+d) about each m.
    moment = np.array([ndimage.correlate1d(w, kernel * d**p, mode="constant")
                       for p in range(5)])
    spread = np.array([ndimage.correlate1d(w, kernel**2 * d**p, mode="constant")
                       for p in range(5)])
    target = np.array([ndimage.correlate1d(w * r, kernel * d**p, mode="constant")
                       for p in range(3)])
    points = ndimage.correlate1d((w > 0).astype(np.float64), np.ones(d.size), mode="constant")
    # Per crest: the 3x3 and 2x2 moment matrices (quadratic, linear), and the cross
    # moments of the two fits (3x2), all Hankel in the moments.
    hankel3 = np.array([[i + j for j in range(3)] for i in range(3)])
    matrix3 = np.moveaxis(moment[hankel3], -1, 0)
    matrix2 = matrix3[:, :2, :2]
    spread3 = np.moveaxis(spread[hankel3], -1, 0)
    smooth = np.full(count, np.nan)
    variance = np.full(count, np.nan)
    row3 = np.full((count, 3), np.nan)  # the quadratic fit's weights on the moments
    with np.errstate(divide="ignore", invalid="ignore"):
        det3 = np.linalg.det(matrix3)
        quadratic = (points >= 4) & (np.abs(det3) > 1e-12 * moment[0] ** 3)
        if np.any(quadratic):
            row3[quadratic] = np.linalg.inv(matrix3[quadratic])[:, 0]
        det2 = moment[0] * moment[2] - moment[1] ** 2
        linear = (points >= 2) & (det2 > 1e-12 * moment[0] ** 2)
        inverse2 = np.zeros((count, 2, 2))
        inverse2[linear] = np.linalg.inv(matrix2[linear])
        row2 = np.column_stack([inverse2[:, 0], np.zeros(count)])
        variance2 = np.einsum("ij,ijk,ik->i", row2, spread3, row2)
        variance3 = np.einsum("ij,ijk,ik->i", row3, spread3, row3)
        # The line gives the crest time where the quadratic is not determined, or is far
        # less certain than the line and not certain in itself (few crests measured on
        # one side: an edge, or crests lost in the noise), where its curvature is noise.
        fill = linear & ~(quadratic & ((variance3 <= 2.0 * variance2)
                                       | (variance3 <= _CERTAIN_PHASE_VARIANCE)))
        row3[fill] = row2[fill]
        smooth = np.einsum("ij,ji->i", row3, target)
        variance = np.where(fill, variance2, variance3)
        local_slope = np.einsum("ij,ji->i", inverse2[:, 1], target[:2])
    grid = np.arange(count)
    known = np.isfinite(smooth[:n_measured])
    if not known.any():
        return origin + grid * slope, slope, np.full(count, np.nan), (np.nan, np.nan)
    # Across a stretch with no measured crest in reach, both are interpolated (the variance
    # a little low there).
    for values in (smooth, variance):
        values[:n_measured] = np.interp(grid[:n_measured], grid[:n_measured][known],
                                        values[:n_measured][known])
    tail_slope = local_slope[last] if linear[last] else 0.0
    growth = (np.nan, np.nan)
    if linear[last] and np.isfinite(smooth[last]):
        slope_row = inverse2[last, 1]
        growth = (float(row3[last] @ spread3[last, :, :2] @ slope_row),
                  float(slope_row @ spread3[last, :2, :2] @ slope_row))
    beyond = grid > last
    steps = grid[beyond] - last
    smooth[beyond] = smooth[last] + tail_slope * steps
    variance[beyond] = _continued_variance(variance[last], growth, steps)
    return origin + grid * slope + smooth, slope + tail_slope, variance, growth


def _continued_variance(variance, growth, steps):
    """Phase variance ``steps`` crests past the last measured one (see
    _smooth_crest_times)."""
    return variance + 2.0 * steps * growth[0] + steps**2 * growth[1]


def _phase_weights(magnitude, sigma):
    """Inverse variances (rad**-2) of crest phases measured with amplitude ``magnitude``
    and standard deviation ``sigma`` in each of the window's two components.

    The phase error is about B/A with A ~ N(y, sigma**2), B ~ N(0, sigma**2): its variance
    is sigma**2/y**2 * (1 + 3*sigma**2/y**2) to second order, and y**2 is estimated without
    the Rician bias as magnitude**2 - 2*sigma**2 (the weight is 0 where that is <= 0).
    """
    floor = (1e-9 * np.max(magnitude, initial=0.0)) ** 2 + 1e-300  # a noise-free record
    variance = np.maximum(sigma**2, floor)
    square = np.maximum(magnitude**2 - 2.0 * variance, 0.0)
    return square**2 / (variance * (square + 3.0 * variance))


def _crest_sequence(times, signs, half, weights, limit):
    """Every crest from the first measured one to ``limit``: smoothed times, signs, the
    variance of each smoothed phase (rad**2; NaN where unknown), and the time of the first
    crest left out because its phase is lost (None if none is).

    ``times`` are measured crest times, ``weights`` the inverse variances of their phases
    (rad**-2; 0: not measured). Crests missed in between (noise) are filled in, and the
    sequence goes on past the last crest found, at the local half-period, to ``limit`` or
    until its phase variance passes _LARGEST_PHASE_VARIANCE (the phase is lost there).
    A measured crest with no other within the smoother's reach is left out: alone, it
    sets neither time nor slope.
    """
    if np.count_nonzero(weights > 0) < 3:
        return times, signs, np.full(times.size, np.nan), None
    numbers = _crest_numbers(times, signs, half)
    first_sign = signs[0]
    measured = weights > 0
    numbers, times, weights = numbers[measured], times[measured], weights[measured]
    signs = signs[measured]
    reliable = weights >= min(_RELIABLE_PHASE_WEIGHT, 0.1 * float(np.max(weights)))
    if np.count_nonzero(reliable) >= 3 and not reliable.all():
        numbers, times, weights = _renumbered(numbers, times, signs, weights, reliable,
                                              first_sign)
    gaps = np.diff(numbers)
    accompanied = np.minimum(np.concatenate([[np.inf], gaps]),
                             np.concatenate([gaps, [np.inf]])) <= _PHASE_HALF_WIDTH
    if np.count_nonzero(accompanied) >= 3:
        numbers, times, weights = numbers[accompanied], times[accompanied], weights[accompanied]
    count = int(numbers[-1]) + 1
    smooth, step, variance, growth = _smooth_crest_times(numbers, times, weights, count)
    phase_lost = None
    if step > 0 and smooth[-1] < limit:
        extra = int(np.floor((limit - smooth[-1]) / step))
        if extra > 0:
            last = int(numbers[-1])
            more = _continued_variance(variance[last], growth,
                                       np.arange(count, count + extra) - last)
            lost = np.flatnonzero(more > _LARGEST_PHASE_VARIANCE)
            if lost.size:  # not past the crest where the phase is lost
                extra = int(lost[0])
                phase_lost = float(smooth[-1] + step * (extra + 1))
            smooth = np.concatenate([smooth, smooth[-1] + step * np.arange(1, extra + 1)])
            variance = np.concatenate([variance, more[:extra]])
    grid = np.arange(smooth.size)
    crest_signs = np.where(grid % 2 == 0, first_sign, -first_sign).astype(signs.dtype)
    ordered = np.concatenate([[True], np.diff(smooth) > 0])
    return smooth[ordered], crest_signs[ordered], variance[ordered], phase_lost


def _renumbered(numbers, times, signs, weights, reliable, first_sign):
    """(numbers, times, weights) of the measured crests, numbered by the smoothed times of
    the reliable ones instead of by their spacing.

    Numbering by spacing counts the half-periods between neighbours; in the faint tail one
    crest displaced by noise can make it count one period too many, and every later crest
    is then a period off. Here each crest takes the number of the nearest crest of its
    sign on the curve through the reliable crests (continued straight past its ends); a
    crest more than half a half-period from it, numbered < 0, or the weaker of two with
    one number is dropped.
    """
    count = int(numbers[reliable][-1]) + 1
    curve, end_step, _, _ = _smooth_crest_times(numbers[reliable], times[reliable],
                                                weights[reliable], count)
    grid = np.arange(count, dtype=np.float64)
    position = np.interp(times, curve, grid)
    start_step = curve[1] - curve[0]
    before, after = times < curve[0], times > curve[-1]
    position[before] = (times[before] - curve[0]) / start_step
    position[after] = count - 1 + (times[after] - curve[-1]) / end_step
    number = np.rint(position)
    # A crest of the wrong sign for its nearest number is more than half a half-period
    # from any crest of its own sign.
    expected_sign = np.where(number % 2 == 0, first_sign, -first_sign)
    keep = (number >= 0) & (expected_sign == signs)
    # One crest per number: the best measured.
    order = np.flatnonzero(keep)[np.lexsort((-weights[keep], number[keep]))]
    order = order[np.concatenate([[True], np.diff(number[order]) > 0])]
    return number[order].astype(np.int64), times[order], weights[order]


def _decay_rates_at(crests, centres, magnitude, omega, reliable):
    """Decay rate and its slope (rows) at ``crests``, from the reliable crests among
    ``centres``, held at the value of the nearest reliable crest beyond them."""
    gamma = _local_decay_rates(centres, magnitude, omega, reliable)
    index = np.flatnonzero(reliable)
    if index.size == 0:
        return np.zeros((2, crests.size))
    return np.vstack([np.interp(crests, centres[index], row[index]) for row in gamma])


class _WindowFits:
    """Per-window results of the half-cycle fits."""

    def __init__(self, k):
        self.y = np.zeros(k)          # signed amplitude (sign * envelope at the crest)
        self.shift = np.zeros(k)      # crest time minus window centre
        self.gain = np.full(k, np.inf)  # var(y) / sigma**2
        self.offset_gain = np.zeros(k)  # dy / d(equilibrium error)
        self.rss = np.zeros(k)
        self.count = np.zeros(k, dtype=np.int64)
        self.valid = np.zeros(k, dtype=bool)
        self.complete = np.zeros(k, dtype=bool)  # the window covers its half-cycle, no gap
        self.edge = np.zeros(k, dtype=bool)
        self.projection = np.zeros(k)  # amplitude with the crest fixed at the centre
        self.projection_gain = np.full(k, np.inf)  # var(projection) / sigma**2
        self.phase_sensitivity = np.zeros(k)  # d(projection)/d(crest phase) / projection
        self.peak = np.zeros(k)       # fitted extreme value of x (equilibrium included)
        self.at_max = np.zeros(k, dtype=np.int64)  # samples at the record's max / min level
        self.at_min = np.zeros(k, dtype=np.int64)


def _fit_windows(t, x, centres, signs, half, gamma, e0, e1, t_ref):
    """Least-squares fit of exp(-g*s - h*s**2/2)*(A cos ws + B sin ws) over each half-cycle.

    ``gamma`` holds g (row 0) and h = dg/dt (row 1) at each crest."""
    k = centres.size
    out = _WindowFits(k)
    lo = np.searchsorted(t, centres - 0.5 * half, side="left")
    hi = np.searchsorted(t, centres + 0.5 * half, side="left")
    lo[1:] = np.maximum(lo[1:], hi[:-1])  # windows must not share samples
    hi = np.maximum(hi, lo)
    omega = np.pi / half
    top = float(np.max(x))
    bottom = float(np.min(x))
    tolerance = 1e-9 * (top - bottom)
    out.edge = (centres - 0.5 * half < t[0]) | (centres + 0.5 * half > t[-1])
    first = 0
    while first < k:
        # Windows whose samples fit in one block.
        cumulative = np.cumsum(hi[first:] - lo[first:])
        last = first + max(1, int(np.searchsorted(cumulative, _BLOCK_SAMPLES, side="right")))
        last = min(last, k)
        sel = slice(first, last)
        lengths = hi[sel] - lo[sel]
        total = int(lengths.sum())
        count = last - first
        starts = np.cumsum(lengths) - lengths
        nonempty = lengths > 0
        window = np.repeat(np.arange(count), lengths)
        index = np.arange(total) + np.repeat(lo[sel] - starts, lengths)
        tt = t[index]
        xx = x[index]
        s = tt - centres[sel][window]
        r = xx - (e0 + e1 * (tt - t_ref))
        ws = omega[sel][window] * s
        envelope = np.exp(-(gamma[0][sel][window] + 0.5 * gamma[1][sel][window] * s) * s)
        u1 = envelope * np.cos(ws)
        u2 = envelope * np.sin(ws)
        # Windows are contiguous runs of the gathered samples: sum each run at once.
        columns = np.empty((10, total))
        for row, (left, right) in enumerate(((u1, u1), (u1, u2), (u2, u2), (u1, r), (u2, r),
                                             (u1, 1.0), (u2, 1.0), (r, r))):
            np.multiply(left, right, out=columns[row])
        np.greater_equal(xx, top - tolerance, out=columns[8])
        np.less_equal(xx, bottom + tolerance, out=columns[9])
        sums = np.zeros((columns.shape[0], count))
        s_min = np.full(count, np.inf)
        s_max = np.full(count, -np.inf)
        max_step = np.zeros(count)
        if total:
            begin = starts[nonempty]
            sums[:, nonempty] = np.add.reduceat(columns, begin, axis=1)
            s_min[nonempty] = s[begin]
            s_max[nonempty] = s[begin + lengths[nonempty] - 1]
            # Largest step inside each window: a gap.
            step = np.diff(tt, prepend=tt[0])
            step[begin] = 0.0
            max_step[nonempty] = np.maximum.reduceat(step, begin)
        s11, s12, s22, b1, b2, s1, s2, rr, at_max, at_min = sums
        del tt, xx, s, r, ws, envelope, u1, u2, index, window, columns

        det = s11 * s22 - s12 * s12
        good = (lengths >= 3) & (det > 1e-12 * np.maximum(s11 * s22, 1e-300))
        det = np.where(good, det, 1.0)
        a = (s22 * b1 - s12 * b2) / det
        b = (s11 * b2 - s12 * b1) / det
        sg = signs[sel]
        angle = np.arctan2(sg * b, sg * a)  # crest phase: cos(w*s - angle) = sign there
        shift = angle / omega[sel]
        decay = np.exp(-(gamma[0][sel] + 0.5 * gamma[1][sel] * shift) * shift)
        g1 = sg * decay * np.cos(angle)
        g2 = sg * decay * np.sin(angle)
        y_signed = (a * g1 + b * g2) * sg
        gain = (g1 * g1 * s22 - 2 * g1 * g2 * s12 + g2 * g2 * s11) / det
        c1 = (s22 * s1 - s12 * s2) / det
        c2 = (s11 * s2 - s12 * s1) / det
        offset_gain = g1 * c1 + g2 * c2
        rss = np.maximum(rr - a * b1 - b * b2, 0.0)
        span = s_max - s_min
        hs = half[sel]
        complete = ((lengths >= 3) & (s11 > 0) & (span >= 0.4 * hs) & (s_min < 0.1 * hs)
                    & (s_max > -0.1 * hs) & (max_step < 0.5 * hs))
        valid = complete & good & (np.abs(angle) < 0.5 * np.pi)
        # With the phase known, one free parameter: linear in the data, so unbiased however
        # small the crest (the magnitude of the two-parameter fit is not).
        s11_safe = np.where(s11 > 0, s11, 1.0)
        out.projection[sel] = np.where(complete, sg * b1 / s11_safe, 0.0)
        out.projection_gain[sel] = np.where(complete, 1.0 / s11_safe, np.inf)
        # Moving the crest by a phase d changes the projection by -y*d*s12/s11 to first
        # order: nothing for a symmetric window, the most for a window cut at its crest.
        out.phase_sensitivity[sel] = np.where(complete, -s12 / s11_safe, 0.0)
        out.complete[sel] = complete
        out.y[sel] = y_signed * sg  # amplitude along the expected sign (< 0 if wrong)
        out.shift[sel] = shift
        out.gain[sel] = np.where(good, gain, np.inf)
        out.offset_gain[sel] = np.where(good, offset_gain, 0.0)
        out.rss[sel] = rss
        out.count[sel] = lengths
        out.valid[sel] = valid & (out.y[sel] > 0)
        out.peak[sel] = (e0 + e1 * (centres[sel] + shift - t_ref)) + sg * out.y[sel]
        out.at_max[sel] = at_max.astype(np.int64)
        out.at_min[sel] = at_min.astype(np.int64)
        first = last
    out.y = np.abs(out.y)  # envelope amplitude (already positive for valid windows)
    return out


def _equilibrium_correction(centres, fit, half, t_ref):
    """(d0, d1): equilibrium error from the alternation of the amplitude sequence, in runs
    of consecutive crests (``half``: local half-periods; a gap breaks a run)."""
    valid = fit.valid
    y = fit.y
    kappa = fit.offset_gain  # y_observed = y_true + kappa*(equilibrium error)
    # Sixth differences: they remove the decay's smooth trend up to fifth order (second
    # differences leave its curvature, which biases the offset when Q is low) while the
    # alternation, at the sequence's Nyquist frequency, gains 64 against white noise's
    # sqrt(924), more than second differences' 4 against sqrt(6).
    coefficients = np.array([1.0, -6.0, 15.0, -20.0, 15.0, -6.0, 1.0])
    width = coefficients.size
    if valid.size < width:
        return 0.0, 0.0
    window_valid = np.all(np.lib.stride_tricks.sliding_window_view(valid, width), axis=1)
    # Across a gap the decay is not smooth in the crest index: windows whose neighbouring
    # crests are all about one half-period apart are used when there are enough of them
    # to fit offset and drift; otherwise every window, as a sparse record needs.
    step_ok = np.diff(centres) < 0.75 * (half[1:] + half[:-1])
    clean = window_valid & np.all(np.lib.stride_tricks.sliding_window_view(step_ok, width - 1),
                                  axis=1)
    if np.count_nonzero(clean) >= _DRIFT_WINDOWS:
        window_valid = clean
    index = np.flatnonzero(window_valid)  # first point of each full window
    if index.size < 3:
        return 0.0, 0.0
    offsets = np.arange(width)
    y_window = y[index[:, None] + offsets]
    k_window = kappa[index[:, None] + offsets]
    tau_window = centres[index[:, None] + offsets] - t_ref
    rows = y_window @ coefficients
    f0 = k_window @ coefficients
    f1 = (k_window * tau_window) @ coefficients
    if index.size >= _DRIFT_WINDOWS:
        design = np.stack([f0, f1], axis=1)
    else:
        design = f0[:, None]
    solution, *_ = np.linalg.lstsq(design, rows, rcond=None)
    if not np.all(np.isfinite(solution)):
        return 0.0, 0.0
    # y_obs = y_true + kappa*(e_true - e_used): the correction adds the error to e.
    d0 = float(solution[0])
    d1 = float(solution[1]) if solution.size > 1 else 0.0
    return d0, d1


def _shifts_within_noise(fit, half, noise):
    """True when the crest shifts of a pass are what the sample noise alone gives them
    (root-mean-square under 2 standard errors): further passes would follow the noise."""
    ok = fit.valid & np.isfinite(fit.gain) & (fit.y > 0)
    if not (np.count_nonzero(ok) >= MIN_TURNING_POINTS and noise > 0):
        return False
    phase_sigma = noise * np.sqrt(fit.gain[ok]) / fit.y[ok]
    z = fit.shift[ok] * np.pi / half[ok] / phase_sigma
    return bool(np.sqrt(np.mean(z * z)) < 2.0)


def _period_estimate(centres, signs, valid, period):
    pairs = valid[:-1] & valid[1:] & (signs[:-1] != signs[1:])
    spacing = np.diff(centres)[pairs]
    spacing = spacing[(spacing > 0.3 * period) & (spacing < 0.7 * period)]
    return float(2 * np.median(spacing)) if spacing.size >= 2 else period


def _pooled_noise(fit):
    """Sample noise sigma from the fit residuals: median of the per-window variances."""
    dof = fit.count - 2
    ok = fit.valid & (dof >= 2)
    if np.count_nonzero(ok) < 3:
        return float("nan")
    variance = fit.rss[ok] / dof[ok]
    # Each window's variance is sigma**2 * chi2(dof)/dof: rescale by its median (chdtri
    # gives the quantile of stats.chi2.median without the distribution's overhead).
    normalized = variance / (special.chdtri(dof[ok], 0.5) / dof[ok])
    return float(np.sqrt(np.median(normalized)))


def _clipped(fit, signs):
    """Crests flattened at the record's extreme level (saturation)."""
    clipped = np.zeros(signs.size, dtype=bool)
    for count in (np.where(signs > 0, fit.at_max, 0), np.where(signs < 0, fit.at_min, 0)):
        hits = count >= 2
        if np.count_nonzero(hits) >= 2 or np.any(count >= 3):
            clipped |= hits
    return clipped


def _running_median(values, width):
    if values.size < width or width < 3:
        return values.copy()
    # The ends repeat the end values, as if the sequence went on level.
    return ndimage.median_filter(values, size=2 * (width // 2) + 1, mode="nearest")


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
    return float(1.4826 * np.median(np.abs(d3 - np.median(d3))) / np.sqrt(20.0))


def _amplitude_sigma(noise_sigma, gain):
    """Standard deviation of window amplitudes from the sample noise and each window's
    gain; infinite for windows without a fit, even on a noise-free record (0 * inf is NaN)."""
    sigma = np.full(gain.shape, np.inf)
    finite = np.isfinite(gain)
    sigma[finite] = noise_sigma * np.sqrt(gain[finite])
    return sigma


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
            return float(centres[index[knee]]), int(index[knee]), _RELEASE_CAUSES["knee"]
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
    half-period at least) starts to move, or None."""
    if not noise > 0:
        return None
    start = stop = 0
    while True:  # half-period windows, while they are still
        end = int(np.searchsorted(t, t[stop] + 0.5 * period))
        if end >= t.size or end - stop < 3 or np.std(x[stop:end]) > _HELD_NOISE * noise:
            break
        start, stop = stop, end
    if stop == 0:
        return None
    level = np.median(x[:stop])
    away = np.abs(x[start:] - level) > _DEPARTURE_Z * noise
    moving = np.flatnonzero(away[:-1] & away[1:])  # two samples: not one noise spike
    return float(t[start + moving[0]]) if moving.size else None


def _release_scatter(values, signs, sigma):
    """Standard deviation of the crest magnitudes: robust third differences along the
    maxima and along the minima (so unequal swings up and down do not count); what the
    sample noise gives when there are too few crests."""
    d3 = np.concatenate([np.diff(values[signs == s], 3) for s in (-1, 1)])
    if d3.size < _SCATTER_DIFFERENCES:
        return float(np.median(sigma))
    return float(stats.median_abs_deviation(d3, scale="normal") / np.sqrt(20.0))


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
    line, plus a term for maxima against minima, above -_FLAT_Z standard errors)."""
    before = slice(0, first)
    s = times[before] - times[first]
    design = np.column_stack([np.ones_like(s), signs[before], s])
    solution, _, covariance = _crest_fit(design, values[before], sigma)
    return bool(solution[2] > -_FLAT_Z * np.sqrt(covariance[2, 2]))


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
    minimum falls _RELEASE_Z sigma below the highest so far, with _KNEE_CRESTS crests
    after it, within the first _RELEASE_SEARCH."""
    pairs = _pair_means(values, signs)
    fallen = np.flatnonzero(pairs < np.fmax.accumulate(pairs) - _RELEASE_Z * sigma)
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


def _release_note(time, count, cause):
    excluded = (f"{count} turning point{'s' if count != 1 else ''} before it excluded"
                if count else "no turning point before it")
    return f"release at t = {time:.6g}: {excluded} ({cause})"


def _excluded_crests(select, centres, signs, magnitude, magnitude_sigma, reason):
    """Columns (t, sign, y, sigma, log_step, reason) of the crests ``select``, excluded for
    ``reason``, with the magnitudes of their half-cycle fits."""
    t = centres[select]
    return (t, signs[select], magnitude[select], magnitude_sigma[select],
            np.full(t.size, np.nan), np.full(t.size, reason, dtype=object))


# Significance (standard errors) of the tests for a floor, the fewest crests in the
# stretch at the end of the record that must not decay, the fraction of the floor's
# half-periods in which a crest must be found, and the top of the amplitudes (in floor
# levels) whose decay rate the floor's is compared with.
_FLOOR_Z = 3.0
_FLOOR_END_CRESTS = 5
_FLOOR_DENSITY = 0.5
_FLOOR_REACH = 4.0


def _vibration_floor(centres, signs, magnitude, magnitude_sigma, fit, candidate, *,
                     noise_sigma, period, t_end):
    """(floor level, index of the first crest in the floor) or (0.0, None).

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
    white = noise_sigma * np.sqrt(2.0 * np.median(fit.gain[index]))
    m = max(5, index.size // 8)
    final = float(np.median(smooth[-m:]))
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
    design = np.column_stack([np.ones_like(s), s, signs[index]])
    if np.unique(signs[index]).size < 2:
        design = design[:, :2]
    solution, _, rank, _ = np.linalg.lstsq(design, np.log(y), rcond=None)
    dof = index.size - rank
    level = float(np.exp(solution[0]))
    if dof < 1:
        return float(solution[1]), float("inf"), level
    residual = np.log(y) - design @ solution
    scale = max(float(np.sqrt(residual @ residual / dof)), float(np.median(relative)))
    covariance = np.linalg.pinv(design.T @ design)
    return float(solution[1]), scale * float(np.sqrt(covariance[1, 1])), level


# Crests per group in the test for a signal left in the tail.
_NOISE_GROUP = 9


def _sinks_below_noise(y, sigma, candidate):
    """Index of the first crest after the oscillation is lost in the noise, or None.

    The signal counts as present while the mean of some _NOISE_GROUP successive amplitudes
    is 4 standard errors above 0; one more group is kept past the last such, so that
    every crest where the envelope is near the noise stays in the fit.
    """
    index = np.flatnonzero(candidate & np.isfinite(sigma) & (sigma > 0))
    group = _NOISE_GROUP
    if index.size < 3 * group:
        return None
    z = y[index] / sigma[index]
    mean_z = np.convolve(z, np.ones(group), mode="valid") / np.sqrt(group)
    present = np.flatnonzero(mean_z > 4.0)
    if present.size == 0:
        return None
    cut = int(present[-1]) + 2 * group
    if index.size - cut < group:
        return None
    return int(index[cut])


def _check_decay(centres, y, sigma_y, used, source, floor=0.0):
    """Raise for a growing oscillation or beating (the envelope rises again)."""
    index = np.flatnonzero(used)
    if index.size < MIN_TURNING_POINTS:
        return
    values = y[index]
    smooth = _running_median(values, 5 if index.size >= 10 else 3)
    noise = np.median(sigma_y[index])
    start = np.median(smooth[: max(2, index.size // 10)])
    end = np.median(smooth[-max(2, index.size // 10):])
    if end > 1.3 * start and end - start > 5 * noise:
        raise RecordError(
            f"the oscillation in {source} grows (amplitude {start:.3g} at t = "
            f"{centres[index[0]]:.4g} to {end:.3g} at t = {centres[index[-1]]:.4g}): this is "
            "not a free decay. Check the record, or cut it to the decaying part.")
    k = _rise(smooth, noise, sigma_y[index], floor)
    if k is not None:
        dip = int(np.argmin(smooth[:k + 1]))
        # A rise to the largest amplitude early on, with the decay undisturbed after it:
        # the record starts before the free decay.
        starts_late = (smooth[k] >= smooth[0] and 2 * k < smooth.size
                       and _rise(smooth[k:], noise, sigma_y[index[k:]], floor) is None)
        raise RecordError(
            f"the amplitude in {source} falls to {smooth[dip]:.3g} at t = "
            f"{centres[index[dip]]:.4g} and rises again to {smooth[k]:.3g} at t = "
            f"{centres[index[k]]:.4g}: "
            + _rise_advice(starts_late, centres[index[dip]], centres[index[k]]))


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


def _rise_advice(starts_late, dip_time, peak_time):
    """What a rise of the amplitude means, and what to do."""
    if starts_late:
        return ("the free decay starts at the rise (the oscillator was held, driven or "
                f"disturbed before it). Fit from there with `start={peak_time:.4g}`.")
    return ("beating of two modes, or a disturbance. Excite one mode only, or fit the "
            f"record before the rise with `end={dip_time:.4g}`.")


def _period_and_drift(centres, signs, y, used, period, weights=None):
    """Period from the crest times and its relative change with amplitude."""
    pairs = used[:-1] & used[1:] & (signs[:-1] != signs[1:])
    spacing = np.diff(centres)
    ok = pairs & (spacing > 0.3 * period) & (spacing < 0.7 * period)
    halves = spacing[ok]
    if halves.size < 2:
        return period, float("nan"), float("nan"), float("nan")
    result = 2 * float(np.mean(halves))
    result_sigma = 2 * float(np.std(halves, ddof=1) / np.sqrt(halves.size))
    if weights is not None:
        result, result_sigma = _period_by_crest_times(centres, signs, used, result, weights,
                                                      result_sigma)
    # Full periods from same-sign neighbours cancel the max/min crest-time asymmetry.
    triple = used[:-2] & used[1:-1] & used[2:] & ok[:-1] & ok[1:]
    if np.count_nonzero(triple) < 4:
        return result, result_sigma, float("nan"), float("nan")
    middle = np.flatnonzero(triple) + 1
    full = centres[middle + 1] - centres[middle - 1]
    amplitude = y[middle]
    spread = np.ptp(amplitude)
    if spread <= 0:
        return result, result_sigma, float("nan"), float("nan")
    centred = amplitude - np.mean(amplitude)  # better conditioned; the slope is the same
    fit, covariance = np.polyfit(centred, full, 1, cov="unscaled")
    residual = full - np.polyval(fit, centred)
    dof = max(full.size - 2, 1)
    s2 = float(np.dot(residual, residual) / dof)
    variance = float(covariance[0, 0]) * s2
    if not (np.isfinite(variance) and variance >= 0):  # amplitudes too alike to tell
        return result, result_sigma, float("nan"), float("nan")
    slope_sigma = float(np.sqrt(variance))
    drift = float(fit[0] * spread / result)
    drift_sigma = float(slope_sigma * spread / result)
    return result, result_sigma, drift, drift_sigma


def _period_by_crest_times(times, signs, used, period, weights, fallback_sigma):
    """Period and its standard error from a weighted straight line through the crest times
    against half-cycle number, with an offset between maxima and minima.

    The mean of the half-cycle spacings depends on the first and last crest alone, which
    are often the faintest; the line weighs every crest by the inverse variance of its
    phase. The noise scale is estimated from the residuals, so a period that drifts with
    amplitude widens the error rather than hiding in it.
    """
    keep = used & (weights > 0) & np.isfinite(times)
    if np.count_nonzero(keep) < 5:
        return period, fallback_sigma
    t = times[keep]
    number = np.round((t - t[0]) / (0.5 * period))
    design = np.column_stack([np.ones_like(t), 0.5 * number, 0.5 * signs[keep]])
    root = np.sqrt(weights[keep] / np.max(weights[keep]))
    solution, _, rank, _ = np.linalg.lstsq(design * root[:, None], t * root, rcond=None)
    dof = t.size - 3
    if rank < 3 or dof <= 0 or np.unique(number).size != number.size:
        return period, fallback_sigma
    residual = (t - design @ solution) * root
    covariance = np.linalg.pinv((design * root[:, None]).T @ (design * root[:, None]))
    variance = covariance[1, 1] * float(residual @ residual) / dof
    return float(solution[1]), float(np.sqrt(max(variance, 0.0)))


# --------------------------------------------------------------------------- tables


def turning_points_from_table(t, values, *, domain="time", source="record"):
    """Turning points given directly: amplitudes (or signed extrema) against time or cycle n.

    Parameters
    ----------
    t : ndarray, shape (k,)
        Times or cycle numbers, distinct (sorted here).
    values : ndarray, shape (k,)
        Amplitudes (all >= 0 or all <= 0) or signed extrema about an equilibrium, which is
        then estimated from the alternation of maxima and minima.
    domain : {"time", "cycle"}
    source : str

    Returns
    -------
    TurningPoints
        ``sigma`` is one scatter estimate for all points (from second differences);
        ``period`` is 1 in the cycle domain, twice the median spacing for signed extrema, and
        NaN for unsigned amplitudes in time (one or two per period cannot be told apart).
    """
    t = np.asarray(t, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    if t.ndim != 1 or t.shape != values.shape:
        raise ValueError("t and values must be 1-D arrays of the same length")
    finite = np.isfinite(t) & np.isfinite(values)
    t, values = t[finite], values[finite]
    _check_range(t, values, source)
    if t.size < MIN_TURNING_POINTS:
        raise RecordError(f"only {t.size} turning points in {source} (need "
                          f"{MIN_TURNING_POINTS}). Use a longer table.")
    order = np.argsort(t, kind="stable")
    t, values = t[order], values[order]
    if np.any(np.diff(t) == 0):
        raise RecordError(f"the turning-point table {source} repeats a time. Remove the "
                          "duplicate rows.")
    notes = []
    equilibrium = 0.0
    if np.all(values >= 0) or np.all(values <= 0):
        signs = np.zeros(values.size, dtype=np.int8)
        y = np.abs(values)
        if np.all(values <= 0):
            notes.append("negative amplitudes taken as magnitudes")
    else:
        equilibrium = _table_equilibrium(values)
        signs = np.where(values >= equilibrium, 1, -1).astype(np.int8)
        y = np.abs(values - equilibrium)
        notes.append(f"signed extrema: amplitudes taken about the equilibrium {equilibrium:.4g}")
    d2 = np.diff(y, 2)
    scatter = float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0)) \
        if d2.size >= 3 else float("nan")
    sigma = np.full(y.size, scatter)
    used = y > 0
    reasons = tuple("" if u else "zero amplitude" for u in used)
    _check_decay(t, y, np.where(np.isfinite(sigma), sigma, 0.0), used, source)
    if np.count_nonzero(used) < MIN_TURNING_POINTS:
        raise RecordError(f"only {np.count_nonzero(used)} non-zero amplitudes in {source} "
                          f"(need {MIN_TURNING_POINTS}). Use a longer table.")
    spacing = float(np.median(np.diff(t)))
    if domain == "cycle":
        period = 1.0
    elif np.any(signs != 0):
        period = 2 * spacing
    else:
        period = float("nan")
        notes.append(f"turning points are {spacing:.4g} apart; whether that is a period or a "
                     "half-period is unknown, so no period is given")
    return TurningPoints(
        t=_frozen(t), y=_frozen(y), sigma=_frozen(sigma), sign=_frozen(signs),
        used=_frozen(used), excluded_reason=reasons, period=period,
        equilibrium=float(equilibrium), equilibrium_drift=0.0, domain=domain,
        notes=tuple(notes))


def _table_equilibrium(values):
    """Level about which maxima and minima give one smooth amplitude sequence.

    An error in the level raises one kind of extremum and lowers the other, which shows in
    the second differences of the amplitude sequence; choose the level that removes it.
    """
    level = float(np.median(values))
    for _ in range(5):
        signs = np.where(values >= level, 1.0, -1.0)
        rows = np.diff(signs * (values - level), 2)
        feature = -np.diff(signs, 2)  # d(amplitude)/d(level) is -sign
        denominator = np.dot(feature, feature)
        if denominator == 0:
            break
        level -= float(np.dot(feature, rows) / denominator)
    return level
