"""The least-squares problem of one record: internal units and one model's residuals.

Internally time is measured from the first turning point in units of the record's span and
amplitudes in units of the largest one, so a record in volts or microvolts, seconds or hours
gives the same relative result after the same iterations.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize

from mcfit import decay

__all__ = ["PARAMETERS", "ScaledRecord", "Problem"]

# The law's parameters, in the column order of decay.amplitude_jacobian.
PARAMETERS = ("y0", "a", "b", "c")
_COLUMN = {name: i for i, name in enumerate(PARAMETERS)}


class ScaledRecord:
    """Turning points in internal units: time from t0 over the span, amplitude over max|y|
    (a tail in the noise can reach below -max(y))."""

    def __init__(self, t, y, sigma):
        self.t0 = float(t[0])
        self.time_unit = float(t[-1] - t[0])
        self.amplitude_unit = float(np.max(np.abs(y)))
        self.t = (t - self.t0) / self.time_unit
        self.y = y / self.amplitude_unit
        self.weights = self.amplitude_unit / sigma
        # The solvers see the residuals over the largest weight. Chi-square's scale, unlike
        # its relative changes, depends on the units (sigma is 1 U when not given), and
        # scipy's gtol is an absolute threshold: a solver started close to its optimum would
        # otherwise stop after a different number of steps in microvolts than in volts.
        self.weight_scale = float(np.max(self.weights))
        self.solver_weights = self.weights / self.weight_scale
        self._design = None

    def with_amplitudes(self, y):
        """The same record in the same internal units, with amplitudes ``y`` (physical)."""
        other = object.__new__(ScaledRecord)
        other.__dict__.update(self.__dict__)
        other.y = y / self.amplitude_unit
        other._design = None
        return other

    def physical_factors(self):
        """Factors f with physical = f * internal for (y0, a, b, c)."""
        return np.array([self.amplitude_unit, 1.0 / (self.amplitude_unit * self.time_unit),
                         1.0 / self.time_unit, self.amplitude_unit / self.time_unit])

    def to_physical(self, values):
        """(y0, a, b, c) in internal units -> a dict in physical units."""
        return dict(zip(PARAMETERS, map(float, np.asarray(values) * self.physical_factors())))

    def starting_values(self, terms):
        """Linear estimate (y0, a, b, c) from the integrated law
        y_k = y0 - c*t_k - b*int(y) - a*int(y^2), with every coefficient >= 0.

        Integrals by the trapezoid rule over the turning points: integrating, unlike
        differencing neighbours, does not amplify the amplitude noise.
        """
        design = self._reduced_design()
        columns = [0] + [_COLUMN[k] for k in terms]
        solution, _ = optimize.nnls(design[:, columns], design[:, 4])
        start = np.zeros(4)
        start[columns] = solution
        # A zero start sits on the bound where the Jacobian may vanish; nudge it inside.
        rate_scale = max(1.0, -math.log(max(self.y[-1], 1e-3)))
        for k in terms:
            if start[_COLUMN[k]] <= 0:
                start[_COLUMN[k]] = 1e-3 * rate_scale
        if start[0] <= 0:
            start[0] = self.y[0] if self.y[0] > 0 else 1.0  # 1 is the largest |amplitude|
        return start

    def _reduced_design(self):
        """[A | y*w] = Q R reduced to R's 4 x 5 block: |A x - y*w| differs from
        |R[:, :4] x - R[:, 4]| by a constant, so every model's linear estimate comes from a
        4-row problem (long records fit faster)."""
        if self._design is None:
            t, y, w = self.t, self.y, self.weights
            steps = np.diff(t)
            int_y = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * steps)])
            int_y2 = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] ** 2 + y[:-1] ** 2) * steps)])
            columns = np.column_stack([np.ones_like(t), -int_y2, -int_y, -t, y]) * w[:, None]
            self._design = np.linalg.qr(columns, mode="r")[:4]
        return self._design


class Problem:
    """One model's least-squares problem in internal units, in its free parameters.

    The solvers ask for the Jacobian where they just evaluated the residuals, so the law is
    evaluated once per parameter vector, and its Jacobian only where asked for (not at
    rejected trial steps). Residuals and Jacobian use the solver weights; chi-square and
    covariance, the weights of the record.
    """

    def __init__(self, scaled: ScaledRecord, terms: str):
        self.t, self.y = scaled.t, scaled.y
        self.weights, self.solver_weights = scaled.weights, scaled.solver_weights
        # Chi-square with the record's weights over that with the solver weights.
        self.chi_square_scale = scaled.weight_scale**2
        self.free = ("y0",) + tuple(terms)
        self.columns = [_COLUMN[k] for k in self.free]
        # The law and its Jacobian at the last two parameter vectors: a solver's answer is
        # often the point before its last trial step, and the callers ask for it again.
        # Each entry is [amplitude, the law's pieces, Jacobian]: the pieces (six arrays as
        # long as the record) only until the Jacobian is made from them, and one Jacobian
        # (the latest asked for) in all: long records need their memory.
        self._cache = {}

    def values(self, free_values):
        """(y0, a, b, c) with the absent terms 0."""
        values = np.zeros(4)
        values[self.columns] = free_values
        return values

    def _key(self, free_values):
        """(y0, a, b, c) as a tuple of floats."""
        free = (free_values.tolist() if isinstance(free_values, np.ndarray)
                else [float(v) for v in free_values])
        if len(free) == 4:  # y0, a, b, c in order
            return tuple(free)
        values = [0.0, 0.0, 0.0, 0.0]
        for column, value in zip(self.columns, free):
            values[column] = value
        return tuple(values)

    def _entry(self, free_values):
        key = self._key(free_values)
        entry = self._cache.get(key)
        if entry is None:
            if len(self._cache) >= 2:
                del self._cache[next(iter(self._cache))]
            law = decay.amplitude_rows(self.t, *key)
            entry = self._cache[key] = [law.amplitude(), law, None]
        return entry

    def law(self, free_values):
        """y(t) at the parameters, shape (n,) (computed once per parameter vector)."""
        return self._entry(free_values)[0]

    def law_jacobian(self, free_values):
        """dy/d(y0, a, b, c) as rows, shape (4, n), unweighted (kept for the latest
        parameter vector asked for)."""
        entry = self._entry(free_values)
        if entry[2] is None:
            for other in self._cache.values():
                other[2] = None
            law = (entry[1] if entry[1] is not None
                   else decay.amplitude_rows(self.t, *self._key(free_values)))
            entry[1], entry[2] = None, law.jacobian()
        return entry[2]

    def residual(self, free_values):
        return (self.law(free_values) - self.y) * self.solver_weights

    def jacobian_rows(self, free_values):
        """The Jacobian of the residuals, transposed: shape (free parameters, n)."""
        rows = self.law_jacobian(free_values)[self.columns]  # a copy: weighted in place
        rows *= self.solver_weights
        return rows

    def jacobian(self, free_values):
        return self.jacobian_rows(free_values).T

    def chi_square(self, free_values):
        return float(np.sum(((self.law(free_values) - self.y) * self.weights) ** 2))

    def covariance(self, free_values):
        """Unscaled covariance (J^T J)^-1 of the free parameters, record weights (times
        the reduced chi-square for the parameters' covariance)."""
        rows = self.law_jacobian(free_values)[self.columns]
        rows *= self.weights
        try:
            return np.linalg.pinv(rows @ rows.T)
        except np.linalg.LinAlgError:
            return None

    def gradient(self, free_values):
        """Cosines between the residuals and the Jacobian column of each of y0, a, b, c
        (free or not): the chi-square gradient, normalized as MINPACK's gtol test does."""
        w = self.solver_weights
        rows = self.law_jacobian(free_values) * w
        residual = (self.law(free_values) - self.y) * w
        along = rows @ residual
        squares = np.square(rows, out=rows)  # in place: four record-sized rows are enough
        norms = np.sqrt(np.sum(squares, axis=1)) * math.sqrt(float(residual @ residual))
        return along / np.where(norms > 0, norms, 1.0)
