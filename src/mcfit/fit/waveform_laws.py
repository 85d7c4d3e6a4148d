"""The waveform laws: the residuals of a record x(t) and their Jacobian under each
form of the damping forces, behind the interface of :class:`mcfit.fit.reported.Law`.

Parameters y0, theta0, omega, offset e0, drift e1, then the averaged law's a, b, c
(docs/theory.md section 5): :class:`AmplitudeWaveform` by Eq. 20.55's amplitude forms
(:mod:`mcfit.phase_plane`; :class:`HystereticWaveform` in closed form for b alone,
:mod:`mcfit.hysteretic_motion`), :class:`VelocityWaveform` by viscous damping and sliding
friction in closed form (:mod:`mcfit.viscous_motion`), :class:`EquationOfMotionWaveform`
with quadratic drag beside them and :class:`PendulumWaveform` with a pendulum's
restoring force, integrated (:mod:`mcfit.equation_of_motion`). The fit that uses them
is :mod:`mcfit.fit.waveform`.
"""

from __future__ import annotations

import math

import numpy as np

from mcfit.equation_of_motion import motion_with_sensitivities
from mcfit.fit.models import TERMS
from mcfit.hysteretic_motion import hysteretic_motion_jacobian
from mcfit.phase_plane import phase_plane_differences
from mcfit.viscous_motion import viscous_motion_jacobian

__all__ = ["AmplitudeWaveform", "HystereticWaveform", "VelocityWaveform",
           "EquationOfMotionWaveform", "PendulumWaveform", "amplitude_waveform",
           "velocity_waveform", "NUISANCE"]

# Nuisance parameters of the waveform besides y0: phase, frequency, offset, drift.
NUISANCE = ("theta0", "omega", "e0", "e1")

# The integration's relative tolerance: this share of the noise over the amplitude (the
# error at the end of a long record is a few times the tolerance), within these limits.
_ACCURACY = 1e-2
_RTOL_LIMITS = (1e-11, 1e-7)
# The rows of viscous_motion_jacobian's derivatives.
_VELOCITY_ROWS = ("y0", "theta0", "omega", "b", "c")


class AmplitudeWaveform:
    """The samples to fit, the residuals of the model x(t) and their Jacobian at a
    parameter vector (y0, theta0, omega, e0, e1, then the model's terms)."""

    chi_square_scale = 1.0  # residuals in noise units: chi-square as it is

    def __init__(self, t, x, t0, terms, noise):
        self.t, self.x, self.t0, self.terms, self.noise = t, x, t0, terms, noise
        self.names = self.free = ("y0",) + NUISANCE + tuple(terms)
        self.memory = {}  # the last solution of the motion starts the next

    @property
    def typical(self):
        """The sizes below which the difference steps stop shrinking (set per fit)."""
        return self._typical

    @typical.setter
    def typical(self, value):
        if not np.array_equal(value, getattr(self, "_typical", None)):
            self._kept = None  # a kept Jacobian had the old steps
        self._typical = value

    def covariance(self, parameters):
        """Unscaled (J^T J)^-1 (pseudo-inverse)."""
        jacobian = self.jacobian(parameters)
        return np.linalg.pinv(jacobian.T @ jacobian)

    def _motion(self, p):
        """(y0, theta0, omega, a, b, c) of each row of ``p``."""
        motion = np.zeros((p.shape[0], 6))
        motion[:, :3] = p[:, :3]
        for i, k in enumerate(self.terms):
            motion[:, 3 + TERMS.index(k)] = p[:, 5 + i]
        return motion

    def residual(self, parameters):
        """Residuals in noise units; the Jacobian at the same point comes with them (the
        solver asks for it next at every step it takes) and is kept for :meth:`jacobian`,
        and both for a second call at the same point (lmfit's at its solution)."""
        p = np.array(parameters, dtype=float)
        kept = self._kept_at(p)
        if kept is None:
            x, (_, jacobian) = self._with_jacobian(p)
            kept = self._kept = (p, jacobian, (x - self.x) / self.noise)
        return kept[2].copy()

    def chi_square(self, parameters):
        """Chi-square at ``parameters`` from the motion alone (no Jacobian where the law
        can spare it: the phase plane's differences take a solution per parameter)."""
        p = np.asarray(parameters, dtype=float)
        tau = self.t - self.t0
        motion = self._motion_jacobian(tau, p, [])[0]
        return float(np.sum(((motion + p[3] + p[4] * tau - self.x) / self.noise) ** 2))

    def jacobian(self, parameters):
        p = np.asarray(parameters, dtype=float)
        kept = self._kept_at(p)
        return self._with_jacobian(p)[1][1] if kept is None else kept[1]

    def _kept_at(self, p):
        kept = getattr(self, "_kept", None)
        return kept if kept is not None and np.array_equal(kept[0], p) else None

    def _with_jacobian(self, p):
        """x at ``p``, and (p, the Jacobian of the residuals) by forward differences of the
        motion (:meth:`_motion_jacobian`); offset and drift enter linearly."""
        tau = self.t - self.t0
        moved = [0, 1, 2] + list(range(5, p.size))
        motion, derivatives = self._motion_jacobian(tau, p, moved)
        columns = np.empty((p.size, self.t.size))  # the Jacobian's columns, filled in rows
        columns[moved] = derivatives
        columns[3] = 1.0
        columns[4] = tau
        columns /= self.noise
        return motion + p[3] + p[4] * tau, (p.copy(), columns.T)

    def _motion_jacobian(self, tau, p, moved):
        """The motion at ``p`` and its derivatives in the parameters of ``moved``, shape
        (len(moved), n): forward differences from one solution
        (:func:`mcfit.phase_plane.phase_plane_differences`)."""
        steps = 1e-7 * np.maximum(np.abs(p), self.typical)
        motion, changes = phase_plane_differences(tau, self._motion(p[None])[0],
                                                  self._motion(np.diag(steps)[moved]),
                                                  self.memory)
        changes /= steps[moved, None]
        return motion, changes


class HystereticWaveform(AmplitudeWaveform):
    """As :class:`AmplitudeWaveform` for the hysteretic term alone, whose motion and
    derivatives are closed forms
    (:func:`mcfit.hysteretic_motion.hysteretic_motion_jacobian`)."""

    def _motion_jacobian(self, tau, p, moved):
        # ``moved`` is (y0, theta0, omega, b): the closed form's order.
        return hysteretic_motion_jacobian(tau, *p[[0, 1, 2, 5]])


class VelocityWaveform(AmplitudeWaveform):
    """As :class:`AmplitudeWaveform` for the velocity forms: viscous b and sliding friction c, the
    motion and its derivatives in closed form
    (:func:`mcfit.viscous_motion.viscous_motion_jacobian`)."""

    def _motion_jacobian(self, tau, p, moved):
        terms = dict(zip(self.terms, p[5:]))
        b, omega = terms.get("b", 0.0), p[2]
        x, by = viscous_motion_jacobian(tau, p[0], p[1], omega, min(b, 0.99 * omega),
                                        terms.get("c", 0.0))
        if b > 0.99 * omega:  # beta held below omega
            by[2] += 0.99 * by[3]
            by[3] *= 0.0
        rows = [_VELOCITY_ROWS.index(self.names[i]) for i in moved]
        # The rows in place where they are the first ones (no copy).
        return x, by[:len(rows)] if rows == list(range(len(rows))) else by[rows]


class EquationOfMotionWaveform(AmplitudeWaveform):
    """Residuals and Jacobian of x(t) = e0 + e1*(t - t0) + u(t), u the motion of
    x'' + 2*b*x' + kappa*x'*|x'| + mu*sgn(x') + R(x) = 0 from amplitude y0 and phase
    theta0 at t0; R linear (``restoring``)."""

    restoring = "linear"
    radians_per_unit = 1.0

    def chi_square(self, parameters):
        """Chi-square at ``parameters`` (the motion is integrated with its sensitivities)."""
        return float(np.sum(self.residual(parameters) ** 2))

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


def amplitude_waveform(t, x, t0, terms, noise):
    """Eq. 20.55's amplitude forms: in closed form for the hysteretic term alone, in the
    phase plane else."""
    kind = HystereticWaveform if tuple(terms) == ("b",) else AmplitudeWaveform
    return kind(t, x, t0, terms, noise)


def velocity_waveform(t, x, t0, terms, noise):
    """The velocity forms: in closed form without quadratic drag, integrated with it."""
    if "a" not in terms:
        return VelocityWaveform(t, x, t0, terms, noise)
    return EquationOfMotionWaveform(t, x, t0, terms, noise)
