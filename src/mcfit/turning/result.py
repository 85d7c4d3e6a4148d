"""The result of the turning-point search: :class:`TurningPoints`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# Fewest used turning points a fit needs.
MIN_TURNING_POINTS = 4


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
        "" for used points, else "before release", "noise floor", "after the decay"
        (after the amplitude rises again), "clipped", "gap" or "edge".
    period : float
        Oscillation period from the turning-point spacing (NaN if unknown).
    period_sigma : float
        Its standard error.
    period_drift : float
        Relative change of the period from the smallest to the largest used amplitude,
        (T(y_max) - T(y_min))/T; positive when large swings are slower.
    period_drift_sigma : float
    equilibrium : float
        Equilibrium value at ``t_start``, the first sample.
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
    warnings : tuple of str
        What the record holds that the fit does not model (a beat or a disturbance, left
        out of the fit).
    t_start : float
        Time of the record's first sample, where the equilibrium line starts (see
        :meth:`equilibrium_at`).
    equilibrium_steps : tuple of mcfit.turning.step.EquilibriumStep
        Steps of the equilibrium in mid-record (a knock, a slip), in time order: the
        equilibrium is the line plus each step's ``size`` from its ``time`` on, and the
        crests on either side are measured about it. Each is named in ``warnings``.
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
    warnings: tuple[str, ...] = field(default=())
    steady_line: object = None  # the hum subtracted before the search (mcfit.hum.SteadyLine)
    t_start: float = 0.0
    equilibrium_steps: tuple = ()

    def equilibrium_at(self, t):
        """The equilibrium at times ``t``: ``equilibrium`` at ``t_start``, changing by
        ``equilibrium_drift`` per time unit, and by each of ``equilibrium_steps`` from its
        time on."""
        t = np.asarray(t)
        line = self.equilibrium + self.equilibrium_drift * (t - self.t_start)
        for step in self.equilibrium_steps:
            line = line + np.where(t >= step.time, step.size, 0.0)
        return line

    def used_sigma(self):
        """The used turning points' uncertainties, or None unless each is finite and > 0
        (then a fit takes its noise scale from the residuals alone)."""
        sigma = self.sigma[self.used]
        return sigma if np.all(np.isfinite(sigma)) and np.all(sigma > 0) else None

    @property
    def count(self):
        """Number of used turning points."""
        return int(np.count_nonzero(self.used))

    def to_dict(self, *, points=False) -> dict:
        """The turning points as plain data (JSON-ready; None where a number is missing or
        not finite): how many are used, the period and its drift, where the free decay
        starts, how many were left out for each reason, the notes and warnings; with
        ``points`` also each point's t, amplitude, sigma, used and excluded_reason."""
        from mcfit.plain import number

        excluded = {}
        for reason, used in zip(self.excluded_reason, self.used):
            if not used:
                excluded[reason or "other"] = excluded.get(reason or "other", 0) + 1
        out = {"count": self.count, "domain": self.domain, "period": number(self.period),
               "period_sigma": number(self.period_sigma),
               "period_drift": number(self.period_drift),
               "release_time": number(self.release_time),
               "noise_sigma": number(self.noise_sigma), "excluded": excluded,
               "notes": list(self.notes), "warnings": list(self.warnings)}
        if self.equilibrium_steps:
            out["equilibrium_steps"] = [step.to_dict() for step in self.equilibrium_steps]
        if points:
            out["points"] = [
                {"t": number(t), "amplitude": number(y), "sigma": number(s), "used": bool(u),
                 "excluded_reason": reason or None}
                for t, y, s, u, reason in zip(self.t.tolist(), self.y.tolist(),
                                              self.sigma.tolist(), self.used.tolist(),
                                              self.excluded_reason)]
        return out


def _frozen(array):
    array = np.ascontiguousarray(array)
    array.setflags(write=False)
    return array
