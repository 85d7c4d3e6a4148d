"""The result of a pendulum's waveform fit by its own equation of motion
(:class:`mcfit.fit.waveform_laws.PendulumWaveform`): the coefficients keep their
small-angle meaning, the amplitudes and Q(t) are the pendulum's law's (docs/theory.md
section 6), and the angle unit and small-angle period are the averaged fit's."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from mcfit.fit.pendulum import PendulumFit, _q_of, with_pendulum_entry
from mcfit.fit.uncertainty import summarise_q
from mcfit.fit.waveform import WaveformFit

__all__ = ["PendulumWaveformFit"]


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
        its amplitudes at the turning points by the pendulum's law and Q(t) the energy's
        (:func:`_energy_q`)."""
        fit = cls(**{f.name: getattr(waveform, f.name) for f in fields(WaveformFit)},
                  small_angle_period=pendulum_fit.small_angle_period,
                  small_angle_period_stderr=pendulum_fit.small_angle_period_stderr,
                  angle_unit=pendulum_fit.angle_unit)
        y_fit = fit.amplitude(fit.t)
        return replace(fit, y_fit=y_fit, **_energy_q(fit, y_fit))

    def to_dict(self) -> dict:
        return with_pendulum_entry(super().to_dict(), self)


def _energy_q(fit, y_fit) -> dict:
    """Q(t) the energy's (docs/theory.md section 6) at the amplitudes ``y_fit``, as the
    pendulum's law reports it, in place of ``fit``'s small-angle Q; Q's relative errors are
    those of the small-angle Q (both scale as 1/rate). Nothing where there is no Q."""
    if fit.q is None:
        return {}
    s, v = fit.radians_per_unit, fit.values
    q, parts = _q_of(y_fit * s, np.array([v["c"] * s, v["b"], v["a"] / s]),
                     2 * math.pi / fit.omega)
    q_stderr = None if fit.q_stderr is None else q * fit.q_stderr / fit.q
    return {"q": q, "q_stderr": q_stderr, "q_summary": summarise_q(q, q_stderr),
            "q_parts": {"coulomb": parts[0], "hysteretic": parts[1], "fluid": parts[2]}}
