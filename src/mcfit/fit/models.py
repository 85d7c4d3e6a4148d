"""The candidate models and their names: plain constants, no numerical imports.

A model is the set of damping terms it keeps, written as letters in the order a, b, c
("ab", "c"); the empty set, constant amplitude, is written ``"none"``. The command line
takes its choices from here without importing the numerical stack.
"""

from __future__ import annotations

import itertools

from mcfit.options import CRITERIA, parse_model

__all__ = ["TERMS", "NONE", "POWER", "MODELS", "REGIME_NAMES", "CRITERIA", "terms_of",
           "parse_model", "regime_list", "regime_name", "models_to_fit"]

TERMS = ("a", "b", "c")
NONE = "none"  # constant amplitude: no damping
POWER = "power"  # dy/dt = -k*y**n, fitted only when asked for
# The eight subsets of {a, b, c}, smallest first: "none", then as letters in the order a, b, c.
MODELS = (NONE,) + tuple("".join(s) for n in (1, 2, 3)
                         for s in itertools.combinations(TERMS, n))
REGIME_NAMES = {"a": "fluid", "b": "hysteretic", "c": "coulomb"}
# b's name by the form of the damping forces a waveform fit found (mcfit.fit.waveform).
_B_NAMES = {"velocity": "viscous", "cannot tell": "viscous or hysteretic"}


def terms_of(model: str) -> str:
    """The letters of the terms a model keeps ("" for ``"none"``)."""
    return "" if model == NONE else model


def regime_name(term, damping_form=None) -> str:
    """A term's regime: b is viscous where the velocity forms were fitted, either where the
    record cannot tell the forms apart, else hysteretic (``damping_form`` None: no
    waveform fit)."""
    return _B_NAMES.get(damping_form, REGIME_NAMES["b"]) if term == "b" else REGIME_NAMES[term]


def regime_list(terms) -> str:
    """The regimes of ``terms`` for a sentence: "fluid, hysteretic and Coulomb"."""
    names = [REGIME_NAMES[k].replace("coulomb", "Coulomb") for k in terms]
    return ", ".join(names[:-1]) + " and " + names[-1] if len(names) > 1 else "".join(names)


def models_to_fit(forced=None) -> tuple:
    """All eight models, or a ``forced`` one and those one term smaller (for its tests)."""
    if forced is None:
        return MODELS
    terms = set(terms_of(forced))
    return tuple(m for m in MODELS if m == forced or (
        len(terms_of(m)) == len(terms) - 1 and set(terms_of(m)) <= terms))
