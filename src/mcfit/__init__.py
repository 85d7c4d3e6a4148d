"""mcfit: fit the modified Coulomb damping law dy/dt = -c - b*y - a*y**2 to free-decay records.

The public names are re-exported here lazily, so that ``import mcfit`` (and ``mcfit --help``)
does not pull in the numerical stack until one of them is used.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

_PUBLIC = {
    "analyse": "mcfit.api", "analyse_file": "mcfit.api", "analyse_files": "mcfit.api",
    "amplitude": "mcfit.decay", "amplitude_jacobian": "mcfit.decay",
    "stop_time": "mcfit.decay", "quality_factor": "mcfit.decay",
    "quality_parts": "mcfit.decay", "power_law_amplitude": "mcfit.decay",
    "fit_decay": "mcfit.fit", "DecayFit": "mcfit.fit",
    "read_record": "mcfit.io", "read_records": "mcfit.io", "Record": "mcfit.record",
    "find_turning_points": "mcfit.turning", "TurningPoints": "mcfit.turning",
    "analyse_record": "mcfit.analysis", "Analysis": "mcfit.analysis",
    "simulate_record": "mcfit.motion",
    "McfitError": "mcfit.errors",
    "amplitude_crlb": "mcfit.bounds", "waveform_crlb": "mcfit.bounds",
}
__all__ = sorted(_PUBLIC) + ["__version__"]


def __dir__():
    return __all__


def __getattr__(name):
    if name in _PUBLIC:
        return getattr(importlib.import_module(_PUBLIC[name]), name)
    raise AttributeError(f"module 'mcfit' has no attribute {name!r}")
