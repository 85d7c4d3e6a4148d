"""The result of a pendulum's waveform fit by its own equation of motion
(:class:`mcfit.fit.waveform_laws.PendulumWaveform`): the coefficients keep their
small-angle meaning, the amplitudes and Q(t) are the pendulum's law's (THEORY.md section
8), and the angle unit and small-angle period are the averaged fit's."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from mcfit.fit.pendulum import PendulumFit, with_pendulum_entry
from mcfit.fit.waveform import WaveformFit

__all__ = ["PendulumWaveformFit", "with_pendulum_q"]


@dataclass(frozen=True, eq=False, repr=False)  # DecayFit's short repr
class PendulumWaveformFit(WaveformFit):
    """A :class:`WaveformFit` of a pendulum's swing by its own equation of motion: the
    coefficients keep their small-angle meaning, the amplitude is the pendulum's law's
    (:meth:`PendulumFit.amplitude`), and the angle unit and T0 are the averaged fit's."""

    small_angle_period: float | None = None
    small_angle_period_stderr: float | None = None
    angle_unit: str = "rad"

    radians_per_unit = PendulumFit.radians_per_unit
    amplitude = PendulumFit.amplitude

    @classmethod
    def of(cls, waveform, pendulum_fit):
        """``waveform`` (a :class:`WaveformFit`) with ``pendulum_fit``'s angle unit and T0,
        its amplitudes at the turning points by the pendulum's law."""
        fit = cls(**{f.name: getattr(waveform, f.name) for f in fields(WaveformFit)},
                  small_angle_period=pendulum_fit.small_angle_period,
                  small_angle_period_stderr=pendulum_fit.small_angle_period_stderr,
                  angle_unit=pendulum_fit.angle_unit)
        return replace(fit, y_fit=fit.amplitude(fit.t))

    def to_dict(self) -> dict:
        return with_pendulum_entry(super().to_dict(), self)


def with_pendulum_q(fit):
    """``fit`` with its amplitudes by the pendulum's law and Q(t) the energy's (THEORY.md
    section 8), as the pendulum's law reports them; Q's relative errors are those of the
    small-angle Q it replaces (both scale as 1/rate)."""
    from mcfit.fit.pendulum import _q_of  # noqa: PLC0415
    from mcfit.fit.uncertainty import summarise_q  # noqa: PLC0415

    if fit.q is None:
        return fit
    y_fit = fit.amplitude(fit.t)
    s, v = fit.radians_per_unit, fit.values
    q, parts = _q_of(y_fit * s, np.array([v["c"] * s, v["b"], v["a"] / s]),
                     2 * math.pi / fit.omega)
    q_stderr = None if fit.q_stderr is None else q * fit.q_stderr / fit.q
    return replace(fit, y_fit=y_fit, q=q, q_stderr=q_stderr, q_summary=summarise_q(q, q_stderr),
                   q_parts={"coulomb": parts[0], "hysteretic": parts[1], "fluid": parts[2]})
