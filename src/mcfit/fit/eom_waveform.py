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
from dataclasses import replace
from functools import partial

import numpy as np

from mcfit.equation_of_motion import motion_with_sensitivities
from mcfit.fit.waveform import _Waveform

__all__ = ["EquationOfMotionWaveform", "PendulumWaveform", "fit_pendulum_waveform",
           "pendulum_law_bias"]

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


def fit_pendulum_waveform(record, turning, fit, degrees=False, *, criterion="aicc",
                          model=None):
    """``fit`` (the pendulum's averaged law on the turning points), or the waveform fit
    by the pendulum's equation of motion where the averaged law would be biased by more
    than a standard error (:func:`pendulum_law_bias`) or misfits. The result says which
    and why (``method_reason``); a misfit is never silent."""
    from mcfit.analysis import (_misfit_warning, _unresolved,  # noqa: PLC0415 (cycle)
                                _without_steady_line, describes_waveform)
    from mcfit.fit.decay_fit import misfit_warning  # noqa: PLC0415
    from mcfit.fit.waveform import fit_waveform  # noqa: PLC0415

    if (record.kind != "waveform" or fit.domain != "time" or fit.omega is None
            or not fit.selection.terms):
        return fit
    dof = fit.n_points - 1 - len(fit.selection.terms)
    misfits = not fit.noise_from_residuals and bool(misfit_warning(fit.reduced_chi_square,
                                                                    dof))
    # A misfit asks for the waveform fit whatever the bias: the chain is not run.
    bias = math.nan if misfits else pendulum_law_bias(record.t, turning, fit, degrees)
    said = (f"the averaged large-swing law misfits (reduced chi-square "
            f"{fit.reduced_chi_square:.3g})" if misfits else
            f"the averaged large-swing law's bias is predicted at {bias:.2g} standard errors")
    if not misfits and bias <= 1.0:
        return replace(fit, method_reason=f"{said}: the turning-point fit suffices")
    kind = partial(PendulumWaveform, radians_per_unit=math.pi / 180.0 if degrees else 1.0)
    x = _without_steady_line(record.t, record.x, turning.steady_line)
    waveform = fit_waveform(record.t, x, turning, fit, criterion=criterion, forced=model,
                            form="velocity", kind=kind)
    waveform = _with_pendulum_q(replace(waveform, damping_form_reason=(
        "the pendulum's equation of motion, with the velocity forms of the damping (viscous, "
        "quadratic drag, sliding friction)")))
    if describes_waveform(waveform):
        return replace(waveform, method_reason=f"{said}: fitted by the pendulum's equation "
                       "of motion")
    warning = _misfit_warning(waveform)
    if not misfits:
        return replace(fit, method_reason=f"{said}, but the pendulum's equation of motion "
                       "does not fit the waveform: the turning-point fit is kept",
                       warnings=fit.warnings + (warning + "; the turning-point fit is "
                                                "reported, biased by the amount predicted",))
    return _unresolved(replace(waveform, method_reason=f"{said}: fitted by the pendulum's "
                               "equation of motion, which misfits as the averaged law does",
                               warnings=waveform.warnings + (warning,)))


def _with_pendulum_q(fit):
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


def pendulum_law_bias(t, turning, fit, degrees=False):
    """The largest shift, in standard errors, of the averaged law's coefficients fitted
    as the record's were to the noise-free swing of the fitted ones: the pendulum's
    equation of motion sampled at the record's times, its turning points found and the
    law of the same model fitted. inf where that chain fails."""
    from mcfit.analysis import fit_turning_points  # noqa: PLC0415 (import cycle)
    from mcfit.errors import McfitError  # noqa: PLC0415
    from mcfit.turning import find_turning_points  # noqa: PLC0415

    used = np.flatnonzero(turning.used)
    t0 = float(turning.t[used[0]])
    times = t[t >= t0]
    theta0 = 0.0 if turning.sign[used[0]] >= 0 else math.pi
    s = math.pi / 180.0 if degrees else 1.0
    v, omega = fit.values, fit.omega
    swing, _ = motion_with_sensitivities(
        times - t0, v["y0"] * s, theta0, omega, v["b"], 0.75 * math.pi * v["a"] / (omega * s),
        0.5 * math.pi * omega * v["c"] * s, restoring="pendulum", rtol=1e-10)
    noise = turning.noise_sigma
    try:
        found = find_turning_points(times, turning.equilibrium_at(times) + swing / s,
                                    settle_noise=noise if noise > 0 else None)
        again = fit_turning_points(found, pendulum=True, degrees=degrees, model=fit.model)
    except McfitError:
        return math.inf
    z = [abs(again.values[k] - v[k]) / fit.stderr[k] for k in fit.selection.terms
         if fit.stderr.get(k)]
    return max(z, default=math.inf)
