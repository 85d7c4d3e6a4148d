"""Which damping terms the record supports: the selection rule, in one place.

:func:`select_model` takes the fitted candidates and returns a :class:`Selection`:

1. The information criterion (AICc or BIC) ranks the eight candidates, the empty model
   (constant amplitude, "no damping") among them.
2. The kept terms must also pass a likelihood-ratio test at level ``alpha`` against every
   model with fewer terms, nested or not (two terms can mimic a third between them).
   A coefficient >= 0 sits on its bound under the null, so the statistic is a mixture
   (chi-bar-square); the noise scale is estimated from the residuals, so each component is
   the exact finite-sample (F, or beta) distribution of a linear model rather than its
   large-sample chi-square limit (:func:`boundary_lrt_p_value`).
3. "Cannot tell": when another model with as many terms fits within ``TIE_DELTA`` of the
   criterion, the record does not say which regime damps it: one model of a size is
   preferred over another only on evidence of the term tests' strength (the two-sided
   chi-square of one degree of freedom at ``alpha``, a little above the boundary
   mixture's 5.9; Burnham and Anderson's 2, "substantial support", let a pure decay
   falling 10 % over 10 cycles come out fluid or Coulomb, resolved, in 3 of 20 records at
   noise 0.5 %). With one term, the record then fixes only a mean decay rate, and it is
   reported as constant Q (model ``b``, Handbook's "universal" damping) with
   ``resolved = False``; with two, the model the criterion prefers is reported, also with
   ``resolved = False``.
4. Terms whose test statistic lies within a factor ``NEAR_FACTOR`` of the critical value,
   either way, are named: the model choice there is a coin toss the intervals do not show.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from scipy import special

from mcfit.fit.models import NONE, TERMS, regime_list, terms_of

__all__ = ["LRT_ALPHA", "TIE_DELTA", "NEAR_FACTOR", "Selection", "select_model",
           "boundary_lrt_p_value"]

LRT_ALPHA = 0.0075
TIE_DELTA = 7.15  # chi2.isf(LRT_ALPHA, 1)
NEAR_FACTOR = 3.0


@dataclass(frozen=True)
class Selection:
    """The model a record supports, with the evidence.

    ``model`` is reported; ``preferred`` is what the criterion and the tests chose before
    the "cannot tell" rule (equal to ``model`` when ``resolved``). ``p_values`` holds, for
    each term of ``model``, the p-value of the test of ``model`` against it without that
    term. ``ties`` lists the models that fit as well as ``preferred``; ``near_threshold``
    maps a term to the p-value of its test where the decision is close; ``dropped`` lists
    (larger model, smaller model, p) for each step where the tests overruled the criterion.
    """

    model: str
    preferred: str
    resolved: bool
    criterion: str
    alpha: float
    forced: bool
    p_values: dict
    ties: tuple = ()
    near_threshold: dict = field(default_factory=dict)
    dropped: tuple = ()

    @property
    def terms(self) -> str:
        return terms_of(self.model)

    def warnings(self) -> list[str]:
        """What a reader must know about the choice (the tie warning, which needs the
        record's amplitudes, is written by the caller)."""
        out = []
        for larger, smaller, p in self.dropped:
            gone = [k for k in terms_of(larger) if k not in terms_of(smaller)]
            names = regime_list(gone)
            them = "them" if len(gone) > 1 else "it"
            out.append(f"{names} term{'s' if len(gone) > 1 else ''} dropped: "
                       f"{self.criterion.upper()} kept {them} but the likelihood-ratio test "
                       f"does not support {them} (p = {p:.2g})")
        for state in ("kept", "left out"):
            near = {k: p for k, p in self.near_threshold.items()
                    if (k in self.terms) == (state == "kept")}
            if near:
                names = regime_list(near)
                ps = ", ".join(f"{p:.2g}" for p in near.values())
                out.append(f"{names} term{'s' if len(near) > 1 else ''} {state} near the "
                           f"detection threshold (p = {ps} against alpha = {self.alpha:g}): "
                           "the intervals do not include the uncertainty of this choice; "
                           "bootstrap intervals redo it")
        return out


def boundary_lrt_p_value(chi_square_without, chi_square_with, n_points, n_params_with,
                         terms=1, correlation=0.0):
    """p-value of adding ``terms`` (1 or 2) coefficients >= 0 to a least-squares model.

    Under the null each new coefficient sits on its bound, and the noise scale is
    estimated. For a linear model, when i of the new estimates are > 0, the relative drop
    in chi-square E = (chi2_without - chi2_with)/chi2_without follows
    Beta(i/2, (n - p0 - i)/2) (the F-test), p0 the parameters without the terms. The
    p-value mixes these with the chance that i estimates are > 0: 1/2 for one term; for
    two whose estimates correlate by rho, 1/2 and 1/4 + asin(rho)/(2*pi) (Kudo 1963). For
    many points this is the chi-bar-square mixture of n*log(chi2_without/chi2_with).
    """
    if terms not in (1, 2):
        raise ValueError("terms must be 1 or 2")
    if not chi_square_without > 0:
        return 1.0
    drop = (chi_square_without - max(chi_square_with, 0.0)) / chi_square_without
    if drop <= 0:
        return 1.0
    rest = n_points - (n_params_with - terms)
    rho = min(1.0, max(-1.0, correlation)) if math.isfinite(correlation) else 0.0
    weights = (0.5,) if terms == 1 else (0.5, 0.25 + math.asin(rho) / (2.0 * math.pi))
    p = 0.0
    for i, weight in enumerate(weights, start=1):
        if rest - i <= 0:
            return 1.0  # as many parameters as points: the record cannot test the term
        p += weight * float(special.betainc(0.5 * (rest - i), 0.5 * i, 1.0 - drop))
    return min(p, 1.0)


def select_model(candidates, criterion="aicc", alpha=LRT_ALPHA, *, n_points, forced=None):
    """Choose the model the record supports among fitted ``candidates``.

    Parameters
    ----------
    candidates : dict
        ``{model: Candidate}`` as :func:`mcfit.fit.candidates.fit_candidates` returns:
        all eight models, or a forced model and those one term smaller.
    criterion : {"aicc", "bic"}
    alpha : float
        Level of the likelihood-ratio tests a kept term must pass.
    n_points : int
        Number of turning points fitted.
    forced : str, optional
        A model given by the user: it is reported as it is, with its tests.

    Returns
    -------
    Selection
    """
    def score(model):
        return candidates[model].score(criterion)

    def test(larger, smaller):
        union = _union(larger, smaller)
        big = candidates[union]
        gone = "".join(k for k in terms_of(union) if k not in terms_of(smaller))
        rho = big.correlation.get(",".join(gone), 0.0) if len(gone) == 2 else 0.0
        return boundary_lrt_p_value(candidates[smaller].chi_square,
                                    candidates[larger].chi_square, n_points, big.n_params,
                                    len(gone), rho)

    if forced is not None:
        return Selection(forced, forced, True, criterion, alpha, True,
                         _term_p_values(forced, candidates, test))
    preferred, dropped = _tested_choice(candidates, score, test, alpha)
    ties = tuple(m for m in candidates if m != preferred
                 and len(terms_of(m)) == len(terms_of(preferred)) and terms_of(m)
                 and score(m) - score(preferred) <= TIE_DELTA)
    model = "b" if ties and len(terms_of(preferred)) == 1 else preferred
    return Selection(model, preferred, not ties, criterion, alpha, False,
                     _term_p_values(model, candidates, test), ties,
                     _near_threshold(preferred, candidates, test, alpha), tuple(dropped))


def _union(first, second):
    terms = set(terms_of(first)) | set(terms_of(second))
    return "".join(k for k in TERMS if k in terms) or NONE


def _tested_choice(candidates, score, test, alpha):
    """The criterion's best model, reduced while a model with fewer terms is not rejected
    by the likelihood-ratio test at ``alpha``.

    A smaller model that is not nested (b against ac: a*y**2 + c can mimic b*y) is tested
    as if against the union of both (abc), which fits at least as well as the larger
    model: the p-value is then conservative. Tests dropping three terms are not made.
    """
    chosen = min(candidates, key=score)
    dropped = []
    while terms_of(chosen):
        tests = {m: test(chosen, m) for m in candidates
                 if len(terms_of(m)) < len(terms_of(chosen))
                 and len(set(terms_of(_union(chosen, m))) - set(terms_of(m))) <= 2
                 and _union(chosen, m) in candidates}
        weakest = max(tests, key=lambda m: (tests[m], -score(m)))
        if tests[weakest] < alpha:
            break
        dropped.append((chosen, weakest, tests[weakest]))
        chosen = weakest
    return chosen, dropped


def _without(model, term):
    rest = terms_of(model).replace(term, "")
    return rest or NONE


def _term_p_values(model, candidates, test):
    """For each term of ``model``, the test against ``model`` without it (where fitted)."""
    return {k: test(model, _without(model, k)) for k in terms_of(model)
            if _without(model, k) in candidates}


def _near_threshold(model, candidates, test, alpha):
    """Terms kept or left out whose test statistic is within NEAR_FACTOR of the critical
    value, in the units of a one-term boundary test, as {term: p}."""
    critical = _statistic(alpha)
    near = {}
    for k in TERMS:
        if k in terms_of(model):
            larger, smaller = model, _without(model, k)
        else:
            larger = "".join(t for t in TERMS if t in terms_of(model) + k)
            smaller = model
        if larger in candidates and smaller in candidates:
            p = test(larger, smaller)
            if critical / NEAR_FACTOR <= _statistic(p) <= critical * NEAR_FACTOR:
                near[k] = p
    return near


def _statistic(p):
    """The chi-square(1) statistic whose boundary-test p-value (half its tail) is ``p``."""
    return float(special.chdtri(1, 2.0 * p)) if p < 0.5 else 0.0
