"""How far the averaged law misleads on a record: its predicted bias in standard errors.

The averaged law is first order in 1/Q. On records of Eq. 20.55 the turning-point fit of b
alone is biased by about ``SCREEN_CONSTANT/Q**2`` of b (tight integrations, Q = 3 to 10:
0.103 to 0.108). That rule screens every record at no cost; where it could reach
``LIMIT/3`` standard errors, the record's own chain is repeated on Eq. 20.55: the waveform
of the fitted coefficients is sampled at the record's times (no noise), its turning points
found and fitted as the record's were, and the coefficients' shift is the prediction.
numpy only beside mcfit's own stages; no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mcfit.hysteretic_motion import hysteretic_motion
from mcfit.phase_plane import phase_plane_motion

__all__ = ["LIMIT", "SCREEN_CONSTANT", "ModelError", "averaged_law_bias", "misfit_scale",
           "noise_stderr", "pendulum_law_bias"]

# The waveform fit is worth its cost where the averaged law's bias exceeds this many
# standard errors of a coefficient.
LIMIT = 0.3
SCREEN_CONSTANT = 0.11


@dataclass(frozen=True)
class ModelError:
    """The predicted bias of each kept coefficient in its standard errors (``z``), the
    largest, the record's smallest Q of its viscous and fluid terms, and how it was found
    ("screen" or "chain")."""

    z: dict
    largest: float
    q_min: float | None
    how: str


def averaged_law_bias(t, turning, fit) -> ModelError:
    """Predicted bias of the turning-point ``fit`` of the waveform record ``t`` with
    ``turning`` points, in standard errors."""
    terms = fit.selection.terms
    q_min = _smallest_rate_q(fit)
    if not terms or q_min is None or any(not fit.stderr[k] for k in terms):
        return ModelError({}, 0.0, q_min, "screen")
    stderr = noise_stderr(fit)
    relative = SCREEN_CONSTANT / q_min**2
    z = {k: relative * fit.values[k] / stderr[k] for k in terms}
    if max(z.values()) <= LIMIT / 3:
        return ModelError(z, max(z.values()), q_min, "screen")
    z = _chain_bias(t, turning, fit, stderr)
    return ModelError(z, max(map(abs, z.values()), default=0.0), q_min, "chain")


def noise_stderr(fit):
    """The standard errors the noise alone gives: a misfit (reduced chi-square above 1,
    by which the reported errors are scaled) must not hide the averaged law's bias, which
    may be its very cause."""
    scale = misfit_scale(fit)
    return {k: fit.stderr[k] / scale for k in fit.selection.terms}


def misfit_scale(fit) -> float:
    """How many times the noise's standard errors the reported ones are: the square root
    of the reduced chi-square where it exceeds 1, else 1."""
    reduced = fit.reduced_chi_square
    return math.sqrt(reduced) if math.isfinite(reduced) and reduced > 1 else 1.0


def _smallest_rate_q(fit):
    """Q of the viscous and fluid terms at the largest amplitude, omega/(2*(b + a*y0)).

    The Coulomb term is left out: the averaged law's Coulomb decrement is exact in a linear
    oscillator and its corrections scale with the other terms' damping ratio. None when
    there is no frequency; inf when there is no viscous or fluid damping.
    """
    if fit.omega is None:
        return None
    rate = fit.values["b"] + fit.values["a"] * fit.values["y0"]
    return fit.omega / (2.0 * rate) if rate > 0 else math.inf


def _chain_bias(t, turning, fit, stderr):
    from mcfit.errors import McfitError
    from mcfit.turning import find_turning_points

    used = np.flatnonzero(turning.used)
    t0 = float(turning.t[used[0]])
    times = t[t >= t0]
    theta0 = 0.0 if turning.sign[used[0]] >= 0 else math.pi
    v = fit.values
    equilibrium = turning.equilibrium_at(times)
    if v["a"] == v["c"] == 0.0:  # b alone: the closed form
        x = equilibrium + hysteretic_motion(times - t0, v["y0"], theta0, fit.omega, v["b"])[0]
    else:
        x = equilibrium + phase_plane_motion(times - t0, v["y0"], theta0, fit.omega, v["a"],
                                             v["b"], v["c"])[0]
    try:
        # Refined as far as the record's crests were: until their shifts are within the
        # record's sample noise (a noise-free waveform would take every pass).
        found = find_turning_points(times, x, settle_noise=_positive(turning.noise_sigma))
        again = _fitted_values(found, fit.model)
    except McfitError:
        return {k: math.inf for k in fit.selection.terms}
    return {k: (again[k] - v[k]) / stderr[k] for k in fit.selection.terms}


def _fitted_values(turning, model) -> dict:
    """The values of ``model`` fitted to the used turning points, and nothing else, with
    their uncertainties where every one is finite and > 0 (as the record's fit had)."""
    from mcfit.fit.decay_fit import fit_model_values

    used = turning.used
    return fit_model_values(turning.t[used], turning.y[used], turning.used_sigma(),
                            model=model)


def pendulum_law_bias(t, turning, fit, degrees=False) -> ModelError:
    """Predicted bias of the pendulum's averaged-law ``fit`` of the swing ``t`` with
    ``turning`` points: the shift of each kept coefficient (``z``, signed, in the noise's
    standard errors as :func:`noise_stderr` gives them) when the law of the same model is
    fitted as the record's was to the noise-free swing of the fitted coefficients (the
    pendulum's equation of motion sampled at the record's times, its turning points
    found). Terms with no standard error are left out; inf for every term where the chain
    fails. ``q_min`` is None: no screen is used."""
    from mcfit.equation_of_motion import motion_with_sensitivities
    from mcfit.errors import McfitError
    from mcfit.fit.pendulum import fit_turning_points_of_pendulum
    from mcfit.turning import find_turning_points

    used = np.flatnonzero(turning.used)
    t0 = float(turning.t[used[0]])
    times = t[t >= t0]
    theta0 = 0.0 if turning.sign[used[0]] >= 0 else math.pi
    s = math.pi / 180.0 if degrees else 1.0
    v, omega = fit.values, fit.omega
    swing, _ = motion_with_sensitivities(
        times - t0, v["y0"] * s, theta0, omega, v["b"], 0.75 * math.pi * v["a"] / (omega * s),
        0.5 * math.pi * omega * v["c"] * s, restoring="pendulum", rtol=1e-10)
    terms = [k for k in fit.selection.terms if fit.stderr.get(k)]
    try:
        found = find_turning_points(times, turning.equilibrium_at(times) + swing / s,
                                    settle_noise=_positive(turning.noise_sigma))
        again = fit_turning_points_of_pendulum(found, found.used_sigma(), degrees,
                                               model=fit.model).values
    except McfitError:
        return ModelError(dict.fromkeys(terms, math.inf), math.inf, None, "chain")
    scale = misfit_scale(fit)
    z = {k: (again[k] - v[k]) * scale / fit.stderr[k] for k in terms}
    return ModelError(z, max(map(abs, z.values()), default=math.inf), None, "chain")


def _positive(value):
    """``value`` where it is a positive number, else None."""
    return value if math.isfinite(value) and value > 0 else None
