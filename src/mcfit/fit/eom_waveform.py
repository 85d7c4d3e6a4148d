"""The waveform fit by the integrated equation of motion with the velocity forms of the
damping (:mod:`mcfit.equation_of_motion`): quadratic drag kappa*x'*|x'| beside viscous
2*beta*x' and sliding friction mu*sgn(x'), and a pendulum's restoring force
w**2*sin(theta).

The parameters are those of :class:`mcfit.fit.waveform._Waveform`: y0, theta0, omega,
offset e0, drift e1, then the averaged law's a, b, c (THEORY.md section 9: beta = b,
kappa = 3*pi*a/(4*omega), mu = pi*omega*c/2), so candidates start from the turning-point
fit and report a, b, c as every other fit does. The Jacobian comes from the
sensitivities of the same integration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from mcfit.equation_of_motion import motion_with_sensitivities
from mcfit.fit.pendulum import PendulumFit, with_pendulum_entry
from mcfit.fit.waveform import WaveformFit, _Waveform

__all__ = ["EquationOfMotionWaveform", "PendulumWaveform", "PendulumWaveformFit",
           "with_pendulum_q"]

# The integration's relative tolerance: this share of the noise over the amplitude (the
# error at the end of a long record is a few times the tolerance), within these limits.
_ACCURACY = 1e-2
_RTOL_LIMITS = (1e-11, 1e-7)


class EquationOfMotionWaveform(_Waveform):
    """Residuals and Jacobian of x(t) = e0 + e1*(t - t0) + u(t), u the motion of
    x'' + 2*b*x' + kappa*x'*|x'| + mu*sgn(x') + R(x) = 0 from amplitude y0 and phase
    theta0 at t0; R linear (``restoring``)."""

    restoring = "linear"
    radians_per_unit = 1.0

    def _with_jacobian(self, p):
        tau = self.t - self.t0
        y0, theta0, omega = (float(v) for v in p[:3])
        terms = dict(zip(self.terms, (float(v) for v in p[5:])))
        a, b, c = (terms.get(k, 0.0) for k in ("a", "b", "c"))
        s = self.radians_per_unit  # the motion is integrated in radians for a pendulum
        drag, friction = 0.75 * math.pi / omega, 0.5 * math.pi * omega  # kappa/a, mu/c
        rtol = min(max(_ACCURACY * self.noise / max(abs(y0), 1e-300), _RTOL_LIMITS[0]),
                   _RTOL_LIMITS[1])
        wanted = {"a": "kappa", "b": "beta", "c": "mu"}
        motion, sens = motion_with_sensitivities(
            tau, y0 * s, theta0, omega, b, drag * a / s, friction * c * s,
            restoring=self.restoring, rtol=rtol,
            wanted=("y0", "theta0", "omega") + tuple(wanted[k] for k in self.terms))
        columns = {"y0": sens[:, 0], "theta0": sens[:, 1] / s, "omega": sens[:, 2] / s,
                   "e0": np.ones_like(tau), "e1": tau}
        if "a" in terms:  # kappa and mu depend on omega too
            columns["a"] = sens[:, 4] * drag / (s * s)
            columns["omega"] = columns["omega"] - sens[:, 4] * drag * a / (omega * s * s)
        if "b" in terms:
            columns["b"] = sens[:, 3] / s
        if "c" in terms:
            columns["c"] = sens[:, 5] * friction
            columns["omega"] = columns["omega"] + sens[:, 5] * friction * c / omega
        jacobian = np.column_stack([columns[name] for name in self.names])
        # Where a trial step's motion cannot be followed (NaN), a huge finite misfit: the
        # solvers step back from it (lmfit refuses NaN).
        motion = np.nan_to_num(motion, nan=1e100 * max(abs(y0 * s), 1.0))
        jacobian = np.nan_to_num(jacobian, nan=0.0)
        return motion / s + p[3] + p[4] * tau, (p.copy(), jacobian / self.noise)


class PendulumWaveform(EquationOfMotionWaveform):
    """As :class:`EquationOfMotionWaveform` for a pendulum's swing angle, R = w**2*sin:
    in radians, or in the units of which ``radians_per_unit`` make a radian."""

    restoring = "pendulum"

    def __init__(self, t, x, t0, terms, noise, radians_per_unit=1.0):
        super().__init__(t, x, t0, terms, noise)
        self.radians_per_unit = radians_per_unit


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
