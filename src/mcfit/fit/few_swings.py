"""A record of a few swings, where fewer than four turning points stand above the noise (Q
about 2, or a short record): no averaged law can be fitted to so few, but the waveform
can. The start comes from a damped cosine fitted to the samples (frequency from the zero
crossings, decay from the ratio of the swings); its turning points stand in for the
record's, to start :func:`mcfit.fit.waveform.fit_waveform` in each form.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from mcfit.errors import RecordError
from mcfit.fit.models import MODELS
from mcfit.fit.waveform import FORMS, WaveformStart, fit_candidate, sample_noise
from mcfit.turning.result import TurningPoints, _frozen
from mcfit.viscous_motion import viscous_motion

__all__ = ["few_swings_start", "with_fitted_amplitudes"]

# Fewest zero crossings after the first crest: a period needs two.
_MIN_CROSSINGS = 2
# Turning points of the damped cosine kept while above this many noise sigmas.
_VISIBLE_Z = 3.0


def few_swings_start(t, x, source="record"):
    """(turning points, :class:`WaveformStart`) of a damped cosine fitted to ``x(t)`` from its largest
    swing on, for :func:`mcfit.fit.waveform.fit_waveform`.

    Raises :class:`mcfit.errors.RecordError` where the record has no two zero crossings
    after its largest swing or the damped cosine cannot be fitted."""
    finite = np.isfinite(x)
    t, x = np.asarray(t, float)[finite], np.asarray(x, float)[finite]
    noise = sample_noise(x)
    start, first = _damped_cosine_start(t, x, noise, source)
    t0 = t[first]
    after = t >= t0
    p = _fitted_damped_cosine(t[after], x[after], t0, start, noise, source)
    y0, theta0, omega, e0, e1, beta = p
    damped = math.sqrt(max(omega**2 - beta**2, 1e-12 * omega**2))
    half = math.pi / damped
    times = t0 + half * np.arange(int((t[-1] - t0) / half) + 1)
    motion = viscous_motion(times - t0, y0, theta0, omega, beta)
    visible = np.abs(motion) > _VISIBLE_Z * noise
    times, motion = times[visible], motion[visible]
    if times.size < 2:
        raise RecordError(f"{source} holds fewer than two swings above its noise. Use a "
                          "record of several cycles.")
    return (_turning_points(t, times, motion, damped, e0, e1, noise),
            _start_fit(times, np.abs(motion), damped, beta))


def _damped_cosine_start(t, x, noise, source):
    """((y0, theta0, omega, e0, e1, b), index of the largest swing) from the samples: the
    crossings of the median between samples clear of the noise (a still end, or noise,
    would add crossings of its own)."""
    e0 = float(np.median(x))
    u = x - e0
    first = int(np.argmax(np.abs(u)))
    clear = np.flatnonzero(np.abs(u) > _VISIBLE_Z * noise)
    clear = clear[clear >= first]
    change = np.flatnonzero(np.signbit(u[clear[1:]]) != np.signbit(u[clear[:-1]]))
    if change.size < _MIN_CROSSINGS:
        raise RecordError(f"{source} crosses its mean fewer than {_MIN_CROSSINGS} times after "
                          "its largest swing: no oscillation to fit. Use a record of several "
                          "cycles.")
    before, after = clear[change], clear[change + 1]
    times = t[before] - u[before] * (t[after] - t[before]) / (u[after] - u[before])
    # The first swings are the largest: their crossings and peaks are the clearest.
    half = float(times[1] - times[0])
    second = float(np.max(np.abs(u[after[0]:before[1] + 1])))
    beta = max(math.log(max(abs(u[first]) / second, 1.0)) / half, 1e-6 / half)
    omega = math.hypot(math.pi / half, beta)
    theta0 = 0.0 if u[first] > 0 else math.pi
    return np.array([abs(u[first]), theta0, omega, e0, 0.0, beta]), first


def _fitted_damped_cosine(t, x, t0, start, noise, source):
    """The damped cosine (y0, theta0, omega, e0, e1, beta) least-squares fitted: the
    velocity form's viscous model of :mod:`mcfit.fit.waveform`."""
    kind, _ = FORMS["velocity"]
    candidate, result = fit_candidate(kind(t, x, t0, "b", noise), start)
    if not candidate.success:
        raise RecordError(f"no damped oscillation could be fitted to {source}. Check the "
                          "signal column.")
    return result.x


def _turning_points(t, times, motion, damped, e0, e1, noise):
    count = times.size
    return TurningPoints(
        t=_frozen(times), y=_frozen(np.abs(motion)), sigma=_frozen(np.full(count, noise)),
        sign=_frozen(np.sign(motion).astype(np.int8)), used=_frozen(np.ones(count, bool)),
        excluded_reason=("",) * count, period=2 * math.pi / damped,
        equilibrium=float(e0 + e1 * (t[0] - times[0])), equilibrium_drift=float(e1),
        noise_sigma=float(noise), t_start=float(t[0]),
        notes=(f"too few turning points for the averaged law: the {count} shown are not "
               "measured but the fitted motion's, at the crest times of a damped cosine "
               "fitted to the samples (which starts the waveform fit)",))


def _start_fit(times, amplitudes, omega, beta):
    """The waveform fit's start: every candidate model from the damped cosine's y0 and b
    (the other terms 0)."""
    values = {"y0": float(amplitudes[0]), "a": 0.0, "b": float(beta), "c": 0.0}
    return WaveformStart({m: dict(values) for m in MODELS}, "b",
                         float(omega), times, amplitudes, np.full(times.size, np.nan))


def with_fitted_amplitudes(turning, fit):
    """``turning`` and the waveform ``fit`` started from it, with the stand-in amplitudes
    (the damped cosine's) replaced by the fitted law's at the same times, and the period
    by the fit's: what a figure or table of the turning points should show."""
    amplitudes = np.asarray(fit.y_fit, dtype=float)
    return (replace(turning, y=_frozen(amplitudes), period=2 * math.pi / fit.omega),
            replace(fit, y=amplitudes))
