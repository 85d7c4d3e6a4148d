"""Fit the amplitude law to turning points, choose the damping regimes, estimate Q(t).

The fit works on turning-point amplitudes ``y_k`` at times ``t_k`` (docs/methods.md section 3).
Each step lives in one module:

- :mod:`~mcfit.fit.models`: the candidate models and their names (no numerical imports);
- :mod:`~mcfit.fit.problem`: internal units and one model's least-squares problem;
- :mod:`~mcfit.fit.candidates`: the candidate fits, and the reported one with lmfit;
- :mod:`~mcfit.fit.reported`: the reported fit of any law (:class:`~mcfit.fit.reported.Law`);
- :mod:`~mcfit.fit.selection`: the selection rule, :func:`select_model`;
- :mod:`~mcfit.fit.uncertainty`: covariance, Q with its error, lower bound, bootstrap;
- :mod:`~mcfit.fit.diagnostics`: the warnings every fit carries;
- :mod:`~mcfit.fit.power`: the free power law, :class:`PowerLawFit`;
- :mod:`~mcfit.fit.decay_fit`: :func:`fit_decay`, which runs them in turn.
- :mod:`~mcfit.fit.pendulum`: :func:`fit_pendulum`, the same for a pendulum's swing angle
  at large amplitudes (the sin(theta) geometry, docs/theory.md section 6).
- :mod:`~mcfit.fit.waveform_laws` and :mod:`~mcfit.fit.waveform`: the record x(t) itself
  by the equation of motion, each form of the damping a law, and its fit.

numpy/scipy/lmfit only, no I/O. The names below are loaded when first used, so that
``mcfit.fit.models`` can be imported without the numerical stack.
"""

from __future__ import annotations

import importlib

_PUBLIC = {
    "CRITERIA": "models", "MODELS": "models", "NONE": "models", "POWER": "models",
    "REGIME_NAMES": "models", "TERMS": "models", "parse_model": "models",
    "Candidate": "candidates", "DecayFit": "decay_fit", "MIN_POINTS": "decay_fit",
    "fit_decay": "decay_fit", "PowerLawFit": "power", "LRT_ALPHA": "selection",
    "TIE_DELTA": "selection", "Selection": "selection",
    "boundary_lrt_p_value": "selection", "select_model": "selection",
    "PendulumFit": "pendulum", "fit_pendulum": "pendulum",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name):
    if name in _PUBLIC:
        return getattr(importlib.import_module(f"mcfit.fit.{_PUBLIC[name]}"), name)
    raise AttributeError(f"module 'mcfit.fit' has no attribute {name!r}")


def __dir__():
    return __all__
