"""The one way mcfit compiles a kernel (numba), for the modules that only the waveform fit
and the integrated equation of motion import: numba's import costs more than a one-record
run of the turning-point fit."""

from __future__ import annotations

import numba

__all__ = ["compiled"]


def compiled(function):
    """``function`` compiled in nopython mode with numpy's float semantics (x/0 is inf or
    NaN, no ZeroDivisionError), its code cached on disk where numba finds a writable
    folder (the package's ``__pycache__``, else the user's cache folder); where it finds
    none numba raises at decoration, and the function is compiled in each process."""
    options = {"nogil": True, "error_model": "numpy"}
    try:
        return numba.njit(cache=True, **options)(function)
    except RuntimeError:  # "cannot cache function ...: no locator available"
        return numba.njit(**options)(function)
