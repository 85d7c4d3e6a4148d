"""The reported fit, written once for every law: lmfit's bounded least squares from the
ranking solution, chi-square with the record's weights and the parameters' covariance.

A law is anything with this small interface (:class:`Law`): the names of its free
parameters, the residuals and their Jacobian at a vector of them, the scale from the
solver's chi-square to the record's, and the unscaled covariance (J^T J)^-1 with the
record's weights. The averaged law (:class:`mcfit.fit.problem.Problem`), the pendulum's
amplitude law and the waveform by the equation of motion (each form) supply it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Protocol

import lmfit
import numpy as np

__all__ = ["Law", "Solution", "solve_reported", "lmfit_least_squares", "lmfit_parameters"]

# Stop when chi-square changes by < 1e-10 relative: 1e-5 of a standard error in the
# parameters, and far enough above chi-square's rounding floor (~1e-15) that the same
# record in other units stops after the same iterations.
TOLERANCES = {"ftol": 1e-10, "xtol": 1e-10, "gtol": 1e-10}


class Law(Protocol):
    """One model's least-squares problem, in its free parameters."""

    free: tuple  # names of the free parameters, in the order of the vectors below
    chi_square_scale: float  # the record's chi-square over the solver's

    def residual(self, x) -> np.ndarray: ...

    def jacobian(self, x) -> np.ndarray: ...

    def covariance(self, x) -> np.ndarray | None: ...


@dataclass(frozen=True)
class Solution:
    """The reported fit of a law: its free parameters ``x``, chi-square with the record's
    weights, their covariance (scaled by the reduced chi-square; None if unknown), whether
    lmfit converged and how many evaluations it took."""

    x: np.ndarray
    chi_square: float
    covariance: np.ndarray | None
    success: bool
    evaluations: int


def solve_reported(law: Law, params: lmfit.Parameters) -> Solution:
    """lmfit's fit of ``law`` from ``params`` (named as ``law.free``, with their bounds):
    the one solver of every reported fit."""
    result = lmfit_least_squares(lambda p: law.residual(_vector(p, law.free)),
                                 lambda p: law.jacobian(_vector(p, law.free)), params)
    x = _vector(result.params, law.free)
    chi_square = float(result.chisqr) * law.chi_square_scale
    return Solution(x, chi_square, _covariance(law, x, result, chi_square),
                    bool(result.success), int(result.nfev))


def lmfit_parameters(names, values, lower, upper) -> lmfit.Parameters:
    """lmfit Parameters ``names`` at ``values`` (clipped into their bounds)."""
    params = lmfit.Parameters()
    for name, value, low, high in zip(names, values, lower, upper):
        params.add(name, value=min(max(float(value), low), high), min=low, max=high)
    return params


def lmfit_least_squares(residual, jacobian, params):
    """lmfit's bounded least squares (scipy's trust-region-reflective solver) with the
    analytic Jacobian and mcfit's tolerances."""
    with warnings.catch_warnings():
        # lmfit takes the square root of its covariance's diagonal, which rounding makes
        # slightly negative where a parameter is nearly unconstrained (Q of 1e6, or a
        # constant record): numpy's warning there is lmfit's, and the caller checks covar.
        warnings.filterwarnings("ignore", category=RuntimeWarning, module=r"lmfit\.")
        minimizer = lmfit.Minimizer(residual, params)
        result = minimizer.minimize(method="least_squares", jac=jacobian, x_scale="jac",
                                    **TOLERANCES)
    # The result's call_kws hold the minimizer's bound Jacobian, the minimizer holds the
    # result: a reference cycle that kept the law's arrays and the solver's Jacobian (200
    # MiB for 2x10^6 turning points) alive until the next full garbage collection.
    minimizer.result = None
    return result


def _covariance(law, x, result, chi_square):
    """lmfit's (J^T J)^-1 times the reduced chi-square where it is sound, else the same
    from the law's pseudo-inverse (finite where J^T J is singular to rounding)."""
    dof = result.ndata - len(law.free)
    if dof <= 0:
        return None
    covar = getattr(result, "covar", None)  # lmfit sets it only where it could
    if covar is not None and np.all(np.isfinite(covar)) and np.all(np.diag(covar) >= 0):
        return covar
    unscaled = law.covariance(x)
    return None if unscaled is None else unscaled * chi_square / dof


def _vector(params, names):
    return np.array([params[name].value for name in names])
