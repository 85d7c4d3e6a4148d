"""The free power law dy/dt = -k*y**n (Handbook Eq. 20.51), fitted only when asked for."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import lmfit
import numpy as np

from mcfit import decay
from mcfit.fit.candidates import Candidate, information_criteria
from mcfit.fit.models import POWER, REGIME_NAMES
from mcfit.fit.reported import lmfit_least_squares
from mcfit.fit.reprs import fit_repr

__all__ = ["PowerLawFit", "fit_power_law"]

@dataclass(frozen=True)
class PowerLawFit:
    """Result of a power-law fit: ``values`` and ``stderr`` hold y0, k and n (k in
    U**(1-n) per unit of t); Q(t) = omega/(2*k*y**(n-1))."""

    status: str
    message: str | None
    domain: str
    criterion: str
    t0: float
    omega: float | None
    values: dict
    stderr: dict
    n_points: int
    rms: float
    reduced_chi_square: float
    noise_from_residuals: bool
    candidates: tuple
    t: np.ndarray = field(repr=False)
    y: np.ndarray = field(repr=False)
    y_fit: np.ndarray = field(repr=False)
    sigma: np.ndarray = field(repr=False)
    q: np.ndarray | None = field(repr=False)
    q_summary: dict | None = None
    warnings: tuple = ()
    model: str = POWER
    forced: bool = True

    def amplitude(self, t):
        """The fitted amplitude at times ``t`` (same units as the input)."""
        v = self.values
        t = np.maximum(np.asarray(t, dtype=float) - self.t0, 0)
        return decay.power_law_amplitude(t, v["y0"], v["k"], v["n"])

    def __repr__(self):
        return fit_repr(self, ("y0", "k", "n"))

    def to_dict(self) -> dict:
        """The fit as plain data (JSON-ready; None where a number is missing or not
        finite), in the form of :meth:`mcfit.fit.DecayFit.to_dict`: y0 with a, b and c 0,
        and the law's y0, k and n with their standard errors as ``power_law``."""
        from mcfit import plain

        law = {"y0": self.values["y0"], "a": 0.0, "b": 0.0, "c": 0.0}
        return {"model": self.model, "domain": self.domain, "method": "turning-points",
                "method_reason": None, "resolved": True,
                "regimes": dict.fromkeys(REGIME_NAMES.values(), False),
                "params": {k: {"value": plain.number(v), "stderr": plain.number(
                    self.stderr["y0"] if k == "y0" else None)} for k, v in law.items()},
                "t0": plain.number(self.t0), "q": plain.q_summary(self.q_summary),
                "fit": {"criterion": self.criterion, "forced": bool(self.forced),
                        "rms": plain.number(self.rms),
                        "reduced_chi_square": plain.number(self.reduced_chi_square),
                        "noise_from_residuals": bool(self.noise_from_residuals)},
                "candidates": plain.candidates(self.candidates),
                "n_points": int(self.n_points),
                "power_law": {**plain.numbers(self.values),
                              **{f"{k}_stderr": plain.number(e)
                                 for k, e in self.stderr.items()}},
                "warnings": list(self.warnings)}


def fit_power_law(scaled, t, y, sigma, omega, domain, criterion, noise_from_residuals):
    """Fit dy/dt = -k*y**n to turning points (``scaled``: the same in internal units)."""
    ts, ys, w = scaled.t, scaled.y, scaled.weights
    first = ys[0] if ys[0] > 0 else 1.0  # 1 is the largest |amplitude|
    # The tail may be <= 0 (noise): then start from a decay to 1e-6 of the first amplitude.
    start_k = -math.log(max(ys[-1] / first, 1e-6)) / max(ts[-1], 1e-12)
    params = lmfit.Parameters()
    params.add("y0", value=first, min=0.0)
    params.add("k", value=max(start_k, 1e-3), min=0.0)
    params.add("n", value=1.0, min=-2.0, max=6.0)

    def residual(p):
        v = p.valuesdict()
        return (decay.power_law_amplitude(ts, v["y0"], v["k"], v["n"]) - ys) * w

    def jacobian(p):
        v = p.valuesdict()
        return decay.power_law_jacobian(ts, v["y0"], v["k"], v["n"]) * w[:, None]

    result = lmfit_least_squares(residual, jacobian, params)
    v = result.params.valuesdict()
    n_exp = v["n"]
    # Back to physical units: y = A*y', t = T*t'  =>  k = k' * A**(1-n) / T.
    y0 = v["y0"] * scaled.amplitude_unit
    k = v["k"] * scaled.amplitude_unit ** (1 - n_exp) / scaled.time_unit
    chi_square = float(result.chisqr)
    dof = t.size - 3
    reduced = chi_square / dof if dof > 0 else math.nan
    covar = getattr(result, "covar", None)
    if covar is None or not np.all(np.isfinite(np.diag(covar))):
        jac = jacobian(result.params)
        covar = np.linalg.pinv(jac.T @ jac) * reduced
    internal = np.sqrt(np.maximum(np.diag(covar), 0.0))
    # y0 scales with A, n is dimensionless; k's unit depends on n, so its relative error
    # carries over.
    stderr = {"y0": float(internal[0] * scaled.amplitude_unit),
              "k": float(internal[1] / v["k"] * k) if v["k"] > 0 else None,
              "n": float(internal[2])}
    y_fit = decay.power_law_amplitude(t - t[0], y0, k, n_exp)
    q = q_summary = None
    if omega is not None:
        with np.errstate(divide="ignore", over="ignore"):
            q = omega / (2 * k * y_fit ** (n_exp - 1))
        finite = q[np.isfinite(q)]
        if finite.size:
            q_summary = {"initial": float(q[0]), "final": float(q[-1]),
                         "min": float(finite.min()), "max": float(finite.max())}
    aicc, bic = information_criteria(chi_square, t.size, 3)
    values = {"y0": y0, "k": k, "n": n_exp}
    candidate = Candidate(POWER, 3, chi_square, aicc, bic, bool(result.success), values,
                          int(result.nfev))
    return PowerLawFit(
        status="ok" if result.success else "error",
        message=None if result.success else "the fit did not converge", domain=domain,
        criterion=criterion, t0=float(t[0]), omega=omega, values=values, stderr=stderr,
        n_points=t.size, rms=float(np.sqrt(np.mean((y_fit - y) ** 2))),
        reduced_chi_square=float(reduced), noise_from_residuals=noise_from_residuals,
        candidates=(candidate,), t=t, y=y, y_fit=y_fit, sigma=sigma, q=q,
        q_summary=q_summary)
