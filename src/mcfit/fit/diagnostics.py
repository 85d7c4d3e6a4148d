"""The warnings a fit carries beside its numbers, whatever law it fits: the verdict's
ties, convergence, structure in the residuals, terms on their bounds, degenerate pairs, a
misfit and no decay. Plain functions of the fit's pieces; no I/O."""

from __future__ import annotations

import math

import numpy as np

from mcfit.fit.models import REGIME_NAMES, TERMS, regime_list, terms_of

__all__ = ["fit_warnings", "tie_warning", "diagnose", "misfit_warning", "no_decay_warning"]

# |correlation| above this between two kept parameters: the record hardly tells them apart.
DEGENERATE_CORRELATION = 0.98


def fit_warnings(selection, y_fit, values, errors, weighted_residuals, converged):
    """The warnings every reported fit carries: the selection's, a tie's and
    :func:`diagnose`'s."""
    return (selection.warnings() + tie_warning(selection, y_fit)
            + diagnose(selection.terms, values, errors, weighted_residuals, converged))


def tie_warning(selection, y_fit):
    """The "cannot tell" warning, with the amplitude range the record spans."""
    if selection.resolved or selection.forced:
        return []
    tied = (selection.preferred,) + selection.ties
    if len(terms_of(selection.preferred)) == 1:
        listed = regime_list(k for k in TERMS if any(k == terms_of(m) for m in tied))
        said = "reported as constant Q"
    else:
        names = [regime_list(terms_of(m)) for m in tied]
        listed = ", ".join(names[:-1]) + " or " + names[-1]
        said = f"reported as {names[0]}, which {selection.criterion.upper()} prefers"
    low, high = float(np.min(y_fit)), float(np.max(y_fit))
    digits = max(3, 2 + int(math.ceil(-math.log10(max((high - low) / high, 1e-12)))))
    return [f"the record spans amplitudes {low:.{digits}g} to {high:.{digits}g}: {listed} "
            f"damping fit it equally well; {said}"]


def diagnose(terms, values, errors, weighted_residuals, converged):
    """Warnings a careful reader needs next to the numbers, the residuals' lag-one
    autocorrelation among them (of amplitudes, or of samples in a waveform fit)."""
    warnings = []
    if not converged:
        warnings.append("the least-squares fit did not report convergence")
    n = weighted_residuals.size
    r1 = _lag_one_autocorrelation(weighted_residuals)
    if r1 * math.sqrt(n) > 3.0:
        warnings.append(f"residuals are correlated (lag-1 autocorrelation {r1:.2f}): the "
                        "standard errors understate the uncertainty, or the model misses a "
                        "systematic effect")
    for k in terms:
        error = errors.stderr.get(k)
        if values[k] == 0.0 or (error is not None and values[k] < 1e-8 * max(error, 1e-300)):
            warnings.append(f"{REGIME_NAMES[k]} coefficient {k} sits on its bound 0")
    for pair, r in errors.correlation.items():
        if abs(r) > DEGENERATE_CORRELATION and "y0" not in pair:
            warnings.append(f"parameters {pair.replace(',', ' and ')} are nearly degenerate "
                            f"(correlation {r:+.3f}): the record hardly separates them")
    return warnings


def no_decay_warning(span, unit, q_bound):
    bound = f" (Q > {q_bound:.2g} at 95 %)" if q_bound is not None else ""
    return (f"the amplitude does not decay over the {span:.4g} {unit} of the record{bound}: "
            "either the damping is too weak to show in it or this is not a free decay (a "
            "driven steady state looks like this)")


def misfit_warning(reduced_chi_square, dof):
    """A warning when the reduced chi-square is far above 1 (beyond 1 + 5*sqrt(2/dof) and
    above 2): the law misses the amplitudes by more than their own noise."""
    if not (dof > 0 and reduced_chi_square > max(2.0, 1.0 + 5.0 * math.sqrt(2.0 / dof))):
        return []
    return [f"reduced chi-square {reduced_chi_square:.3g} is far above 1: the law does not "
            "describe the amplitudes within their noise (a disturbed start, a beat with a "
            "second mode, or noise underestimated); the standard errors are scaled by its "
            "square root"]


def _lag_one_autocorrelation(residuals):
    r = residuals - residuals.mean()
    denominator = float(np.dot(r, r))
    return float(np.dot(r[1:], r[:-1]) / denominator) if denominator > 0 else 0.0
