"""Amplitude law of the modified Coulomb model, its sensitivities, Q(t) and unit conversions.

Handbook Eq. 20.59: ``dy/dt = -c - b*y - a*y**2`` with ``a, b, c >= 0``; ``y`` is the
turning-point amplitude, ``c`` Coulomb (U/s), ``b`` hysteretic (1/s), ``a`` fluid (1/(U*s)).
All functions take times in the units of the coefficients (seconds, or cycles for
coefficients in cycle units) and broadcast over numpy arrays. Pure numpy: no I/O.

The closed form is docs/theory.md section 2.3::

    y = (y0 - tau*K) / (1 + tau*M),   K = c + b*y0/2,   M = a*y0 + b/2
    tau = t * Phi(sigma*t**2),        sigma = b**2/4 - a*c = D/4
    Phi(u) = tanh(sqrt(u))/sqrt(u) (u > 0),  1 (u = 0),  tan(sqrt(-u))/sqrt(-u) (u < 0)

Phi is analytic across u = 0 (a series is used there), so b**2 = 4ac needs no special case.
Where D > 0 and s*t >= 1 (s = sqrt(sigma)) the same expression is rewritten with
E = exp(-2*s*t) so that exponential tails keep their relative accuracy.

The law is written once, for one parameter set (:class:`_Law`): its constants and regime
(the sign of D, whether and when it stops) are Python floats computed once, and the times
go through a few vectorised operations (:class:`_Terms`). Arrays of parameter sets are
evaluated set by distinct set.
"""

from __future__ import annotations

import bisect
import math

import numpy as np

__all__ = [
    "amplitude",
    "amplitude_jacobian",
    "amplitude_and_jacobian",
    "amplitude_terms",
    "stop_time",
    "decay_rate",
    "quality_factor",
    "quality_parts",
    "to_cycle_units",
    "to_time_units",
    "to_q_form",
    "from_q_form",
    "energy_coefficients",
    "power_law_amplitude",
    "power_law_jacobian",
]

# Taylor coefficients of Phi(u) = tanh(sqrt u)/sqrt u = sum PHI_SERIES[k] * u**k:
# 2**(2n) * (2**(2n) - 1) * B_(2n) / (2n)!  (radius pi**2/4, terms shrink ~0.4*|u| each).
_PHI_SERIES = np.array([
    1.0, -0.3333333333333333, 0.13333333333333333, -0.05396825396825397,
    0.021869488536155203, -0.008863235529902197, 0.003592128036572481,
    -0.0014558343870513183, 0.000590027440945586, -0.00023912911424355248,
    9.691537956929451e-05, -3.927832388331683e-05,
])
_PHI_DERIVATIVE_SERIES = _PHI_SERIES[1:] * np.arange(1, _PHI_SERIES.size)
# Phi and Phi' as the rows of one matrix, so that one product with the powers of u gives both.
_SERIES = np.array([_PHI_SERIES[:-1], _PHI_DERIVATIVE_SERIES])
# Smallest |u| at which term k >= 1 of either series exceeds 2**-56 of its first term: where
# the largest |u| is below _SERIES_NEEDS[k-1], terms from k on are below rounding.
_SERIES_NEEDS = tuple(
    min(float((2.0**-56 * abs(row[0]) / abs(row[k])) ** (1.0 / k)) for row in _SERIES)
    for k in range(1, _SERIES.shape[1]))
_EXPONENTS = np.arange(float(_SERIES.shape[1]))[:, None]
# Powers of u for the series by one np.power call (about 10 ns per element) up to this many
# elements, beyond it row by row (about 1 us per call).
_POWER_CALL_LIMIT = 600
# Below this s, s*theta may underflow where theta is small: tau comes from its series there.
_TINY_S = 1e-100
# Below this |u| the series is exact to rounding (0.04**11 < 1e-15); above it the direct
# formula for Phi' loses at most 1.5*eps/|u| to cancellation.
_SERIES_LIMIT = 0.1
# Where D > 0 and s*t exceeds this, use the exponential form (no tanh -> 1 cancellation).
_EXPONENTIAL_FORM_LIMIT = 1.0
# Normalized time is capped here: by then y < 1e-100*y0 whatever the coefficients, because
# the largest normalized rate is 1 (see _Law).
_MAX_NORMALIZED_TIME = 1e100
_LOG_MAX_NORMALIZED_TIME = math.log(_MAX_NORMALIZED_TIME)


def _as_flat_arrays(*values):
    """Broadcast to a common shape and flatten to 1-D float arrays (restored by callers)."""
    arrays = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in values))
    return [np.ravel(v) for v in arrays]


def _shape_of(*values):
    return np.broadcast(*(np.asarray(v) for v in values)).shape


def _log(value):
    return math.log(value) if value > 0 else -math.inf


def _exp(value):
    """math.exp, with inf instead of OverflowError."""
    return math.exp(value) if value < 709.0 else math.inf


class _Law:
    """One parameter set (y0 > 0, a, b, c >= 0, all finite) in normalized units.

    ``y(t; y0, a, b, c) = y0 * eta(r*t; 1, a*y0/r, b/r, c/(y0*r))`` holds for every r > 0;
    r is the largest of c/y0, b and a*y0, so the normalized coefficients are at most 1 and
    nothing overflows. The constants of the closed form and the stop are computed here,
    once, as Python floats.
    """

    def __init__(self, y0, a, b, c):
        self.y0 = y0
        rate_c, rate_a = c / y0, a * y0  # Python floats give inf on overflow, no exception
        rate = max(rate_c, b, rate_a)
        self.log_rate = None
        if rate < math.inf:
            rate = rate if rate > 0 else 1.0
            a, b, c = rate_a / rate, b / rate, rate_c / rate
        else:  # a rate beyond the float range: the same scaling, done in logarithms
            logs = (_log(a) + math.log(y0), _log(b), _log(c) - math.log(y0))
            self.log_rate = max(logs)
            a, b, c = (math.exp(v - self.log_rate) for v in logs)
        self.rate, self.a, self.b, self.c = rate, a, b, c
        g = math.sqrt(a) * math.sqrt(c)
        self.sigma = (0.5 * b - g) * (0.5 * b + g)  # b**2/4 - a*c without overflow
        self.s = math.sqrt(abs(self.sigma))
        self.k = c + 0.5 * b
        self.m = a + 0.5 * b
        self.theta_stop = self._normalized_stop_time()
        self.t_stop = self.per_rate(self.theta_stop)  # exactly what stop_time() returns

    def _normalized_stop_time(self):
        a, b, c, s, k, sigma = self.a, self.b, self.c, self.s, self.k, self.sigma
        if c <= 0:
            return math.inf
        tau_stop = 1.0 / k  # y = 0 where tau*K = 1
        if sigma > 0:
            # 1 - z written without cancellation: b/2 - s = a*c/(b/2 + s).
            one_minus_z = (c + a * c / (0.5 * b + s)) / k
            if one_minus_z == 0:
                return math.inf  # a Coulomb term too faint to stop within floats
            result = 0.5 * math.log1p(2.0 * (s * tau_stop) / one_minus_z) / s
        elif sigma < 0:
            result = math.atan(s * tau_stop) / s
        else:
            result = tau_stop
        return result if result == result else math.inf

    def per_rate(self, value):
        """A normalized time or derivative over r (value/r), as a float."""
        if self.log_rate is None:
            return value / self.rate
        if value == 0 or value == math.inf:
            return value
        return math.copysign(_exp(math.log(abs(value)) - self.log_rate), value)

    def time(self, t):
        """Normalized time r*t, capped at _MAX_NORMALIZED_TIME (no overflow on the way)."""
        if self.log_rate is None:
            if t.size and float(t[-1]) * self.rate <= _MAX_NORMALIZED_TIME:  # t is sorted
                return t * self.rate
            return np.minimum(t, _MAX_NORMALIZED_TIME / self.rate) * self.rate
        with np.errstate(divide="ignore"):
            size = np.exp(np.minimum(self.log_rate + np.log(np.abs(t)),
                                     _LOG_MAX_NORMALIZED_TIME))
        return np.copysign(size, t)


def _law_or_none(y0, a, b, c):
    """The _Law of one parameter set, or None where there is none (y0 <= 0, a negative,
    infinite or NaN value)."""
    if y0 > 0 and 0 <= a < math.inf and 0 <= b < math.inf and 0 <= c < math.inf \
            and y0 < math.inf:
        return _Law(y0, a, b, c)
    return None


class _Terms:
    """The normalized amplitude of one parameter set at sorted times ``t`` (flat) and the
    pieces its Jacobian reuses; the Jacobian is computed only when asked for.

    tau = tanh(s*theta)/s or tan(s*theta)/s, and theta*Phi(u) by its series where
    |u| = |sigma|*theta**2 is small; d tau/d sigma = theta**3 * Phi'(u) likewise. Normalized
    time grows with t, so each branch (series, direct, exponential form, stopped) covers
    one contiguous slice of the times: the branches work on views, without masks. On a
    fit's 10 to 1000 points each numpy call costs more than its arithmetic.
    """

    def __init__(self, law, t):
        self.law = law
        n = t.size
        theta = law.time(t)
        # Running while t < t_stop (exactly what stop_time() returns); y = 0 after, and at
        # a time that is NaN (sorted last).
        n_run = n if n == 0 or float(t[-1]) < law.t_stop else int(t.searchsorted(law.t_stop))
        if n_run < n or law.theta_stop < math.inf:
            theta = np.minimum(theta[:n_run], law.theta_stop)  # no step past tan's pole
        s, sigma, k, m = law.s, law.sigma, law.k, law.m
        # Slices: [series_start, series_end) where |u| < _SERIES_LIMIT, [far, n_run) where
        # s*theta >= 1 and D > 0 (the exponential form).
        series_start = series_end = 0
        far = n_run
        if sigma == 0:
            tau = theta
        else:
            z = s * theta
            trig = np.tanh(z) if sigma > 0 else np.tan(z)
            tau = trig / s
            self.z, self.trig = z, trig
            if n_run:
                limit = math.sqrt(_SERIES_LIMIT)  # |u| = z**2 < _SERIES_LIMIT
                first, last = float(z[0]), float(z[-1])
                series_start = int(z.searchsorted(-limit, "right")) if first <= -limit else 0
                series_end = int(z.searchsorted(limit)) if last >= limit else n_run
                if sigma > 0 and last >= _EXPONENTIAL_FORM_LIMIT:
                    far = int(z.searchsorted(_EXPONENTIAL_FORM_LIMIT))
        self.n_run, self.series, self.far = n_run, (series_start, series_end), far
        self.theta, self.tau = theta, tau
        if s < _TINY_S and series_end > series_start:  # s*theta may underflow: theta*Phi(u)
            theta_s, phi = self._series(series_start, series_end, 0)
            np.multiply(theta_s, phi, out=tau[series_start:series_end])
        self.denominator = 1.0 + tau * m
        eta = np.zeros(n)
        running = eta[:n_run]
        np.divide(1.0 - tau[:far] * k, self.denominator[:far], out=running[:far])
        if far < n_run:  # written with E = exp(-2z), so exponential tails keep their digits
            a, c = law.a, law.c
            e = np.exp(-2.0 * self.z[far:])
            h = 0.5 * law.b + s
            np.divide(e * (s + k) - c * (1.0 + a / h), (s + m) - e * (a * (1.0 + c / h)),
                      out=running[far:])
        np.maximum(running, 0.0, out=running)
        self.eta = eta

    def _series(self, start, end, row):
        """Row ``row`` of _SERIES (0: Phi, 1: Phi') at u = sigma*theta**2 on [start, end)."""
        theta = self.theta[start:end]
        if theta.size == 0:
            return theta, theta
        u = self.law.sigma * (theta * theta)
        largest = max(abs(float(u[0])), abs(float(u[-1])))  # theta is sorted
        degree = bisect.bisect_right(_SERIES_NEEDS, largest)
        if u.size * degree <= _POWER_CALL_LIMIT:
            powers = u ** _EXPONENTS[:degree + 1]
        else:
            powers = np.empty((degree + 1, u.size))
            powers[0] = 1.0
            for j in range(1, degree + 1):
                np.multiply(powers[j - 1], u, out=powers[j])
        return theta, _SERIES[row, :degree + 1] @ powers

    def amplitude(self):
        """y = y0 * eta, flat."""
        return self.law.y0 * self.eta

    def _dtau_dsigma(self):
        """d tau/d sigma = theta**3 * Phi'(u) (<= 0) while running."""
        law, theta = self.law, self.theta
        sigma, s = law.sigma, law.s
        if sigma == 0:  # Phi'(0) = -1/3
            return theta * theta * theta * _PHI_DERIVATIVE_SERIES[0]
        start, end = self.series
        if start == 0 and end == self.n_run:  # (where 1/s**3 may overflow)
            theta_s, dphi = self._series(start, end, 1)
            return theta_s * theta_s * theta_s * dphi
        # The direct formula. Where s*theta >= 1, 1 - tanh**2 keeps only an absolute error
        # of eps, but the result is at least 0.34 and z*sech(z)**2 < eps beyond z = 19: the
        # result stays within about 60 ulp.
        z, trig = self.z, self.trig
        square = trig * trig
        if sigma > 0:
            dtau = z * (1.0 - square) - trig
        else:
            dtau = trig - z * (1.0 + square)
        dtau *= 0.5 / (s * s * s)
        if end > start:
            theta_s, dphi = self._series(start, end, 1)
            np.multiply(theta_s * theta_s * theta_s, dphi, out=dtau[start:end])
        return dtau

    def jacobian(self):
        """dy/d(y0, a, b, c), shape (4, n)."""
        law, n_run, far = self.law, self.n_run, self.far
        eta = self.eta[:n_run]
        a, b, c, k, m = law.a, law.b, law.c, law.k, law.m
        # Normalized units: the rows of the basis [T, S, eta*T, 1, eta, eta**2], with
        # T = tau/(1 + tau*M) and S = (d tau/d sigma)*(K + eta*M)/(1 + tau*M) (<= 0), combine
        # into d eta/da = c*S - eta*T, d eta/db = -(b*S + T + eta*T)/2, d eta/dc = a*S - T,
        # and dy/dy0 = P(y)/P(y0) (the flow of an autonomous ODE), by one matrix product.
        basis = np.empty((6, n_run))
        t_part, s_part = basis[0], basis[1]
        np.divide(self.tau, self.denominator, out=t_part)
        np.multiply(eta, m, out=s_part)
        s_part += k
        s_part *= self._dtau_dsigma()
        s_part /= self.denominator
        np.multiply(eta, t_part, out=basis[2])
        basis[3] = 1.0
        basis[4] = eta
        np.multiply(eta, eta, out=basis[5])
        total = a + b + c  # >= 1 after normalizing, unless there is no damping at all
        y0_row = ((0.0, 0.0, 0.0, c / total, b / total, a / total) if total > 0
                  else (0.0, 0.0, 0.0, 1.0, 0.0, 0.0))
        combination = np.array([y0_row, (0.0, c, -1.0, 0.0, 0.0, 0.0),
                                (-0.5, -0.5 * b, -0.5, 0.0, 0.0, 0.0),
                                (-1.0, a, 0.0, 0.0, 0.0, 0.0)])
        if n_run == self.eta.size:
            jacobian = combination @ basis
        else:
            jacobian = np.zeros((4, self.eta.size))
            jacobian[:, :n_run] = combination @ basis
        if far < n_run:
            # Where s*theta >= 1: the time-scaling identity a*dy/da + b*dy/db + c*dy/dc
            # = -t*P(y) gives dy/db without the cancellation of the formula above.
            d_y0, d_a, d_b, d_c = jacobian[:, far:n_run]
            rate_theta = d_y0 * (total * -1.0 / b)
            rate_theta *= self.theta[far:]
            np.subtract(rate_theta, (c / b) * d_c + (a / b) * d_a, out=d_b)
        self._to_physical(jacobian[1:])
        return jacobian

    def _to_physical(self, derivatives):
        """d eta/d(normalized a, b, c) -> dy/d(a, b, c), in place."""
        law, y0 = self.law, self.law.y0
        y0_per_rate = law.per_rate(y0)
        factors = (y0_per_rate * y0, y0_per_rate, law.per_rate(1.0))
        if derivatives.size == 0:
            return
        flat = derivatives.reshape(-1)
        if max(factors) <= 1e150 and float(flat @ flat) <= 1e300:  # no overflow below
            derivatives *= np.array(factors)[:, None]
            return
        d_a, d_b, d_c = derivatives
        with np.errstate(over="ignore", under="ignore", invalid="ignore"):
            # In two steps, so that an intermediate product cannot overflow where the
            # result does not; an infinite factor must not turn an exact zero into NaN.
            np.multiply(d_a, y0_per_rate, out=d_a, where=d_a != 0)
            d_a *= y0
            d_b *= y0
            for row in (d_b, d_c):
                if law.log_rate is None:
                    row /= law.rate
                else:
                    np.multiply(row, math.exp(-law.log_rate), out=row, where=np.isfinite(row))


class _NoLaw:
    """y0 = 0, or no law at all (a negative, infinite or NaN value: NaN out)."""

    def __init__(self, t, y0, a, b, c):
        self.t, self.b, self.c = t, b, c
        self.zero = y0 == 0 and 0 <= a < math.inf and 0 <= b < math.inf \
            and 0 <= c < math.inf

    def amplitude(self):
        return np.zeros(self.t.size) if self.zero else np.full(self.t.size, np.nan)

    def jacobian(self):
        if not self.zero:
            return np.full((4, self.t.size), np.nan)
        jacobian = np.zeros((4, self.t.size))
        if self.c == 0:  # y stays 0 unless c = 0, where y = y0*exp(-b*t) to first order
            with np.errstate(over="ignore"):
                jacobian[0] = np.exp(-self.b * self.t)
        return jacobian


def _one_set(t, y0, a, b, c):
    law = _law_or_none(y0, a, b, c)
    return _NoLaw(t, y0, a, b, c) if law is None else _Terms(law, t)


class _Evaluated:
    """The law evaluated at every time, its Jacobian computed only on demand: what
    :func:`amplitude_terms` returns. Each parameter set is evaluated once at its times in
    increasing order (:class:`_Terms`), and the results are put back in place."""

    def __init__(self, t, y0, a, b, c):
        self._sets = []
        if type(y0) is float and type(a) is float and type(b) is float and type(c) is float \
                and type(t) is np.ndarray and t.ndim == 1 and t.dtype == np.float64:
            self.shape = t.shape  # a fit's case, without the general checks below
            self._add(None, t, (y0, a, b, c))
            return
        self.shape = _shape_of(t, y0, a, b, c)
        parameters = [np.asarray(v, dtype=float) for v in (y0, a, b, c)]
        if all(v.size == 1 for v in parameters):
            times = np.ravel(np.broadcast_to(np.asarray(t, dtype=float), self.shape))
            self._add(None, times, [float(v.item()) for v in parameters])
            return
        times, *parameters = _as_flat_arrays(t, *parameters)
        # Each distinct parameter set once: its regime is chosen once for all its times.
        distinct, which = np.unique(np.column_stack(parameters), axis=0, return_inverse=True)
        which = which.ravel()
        for i, row in enumerate(distinct):
            index = np.flatnonzero(which == i)
            self._add(index, times[index], [float(v) for v in row])

    def _add(self, index, times, parameters):
        """One parameter set at ``times`` (positions ``index`` of the output, None for all)."""
        if times.size > 1 and np.count_nonzero(times[1:] >= times[:-1]) < times.size - 1:
            order = np.argsort(times, kind="stable")
            times = times[order]
            index = order if index is None else index[order]
        self._sets.append((index, _one_set(times, *parameters)))

    def _gather(self, rows, method):
        if self._sets[0][0] is None:
            return getattr(self._sets[0][1], method)()
        out = np.empty((rows, math.prod(self.shape))) if rows else np.empty(
            math.prod(self.shape))
        for index, terms in self._sets:
            out[..., index] = getattr(terms, method)()
        return out

    def amplitude(self):
        """y(t), shaped as the broadcast inputs; a float for scalar inputs."""
        y = self._gather(0, "amplitude").reshape(self.shape)
        return y[()] if y.ndim == 0 else y

    def jacobian(self):
        """dy/d(y0, a, b, c), shape (..., 4)."""
        return self._gather(4, "jacobian").T.reshape(self.shape + (4,))


def stop_time(y0, a, b, c):
    """Time at which the amplitude reaches zero.

    Parameters
    ----------
    y0, a, b, c : float or ndarray
        Initial amplitude (U) and coefficients (a in 1/(U*s), b in 1/s, c in U/s), all >= 0.

    Returns
    -------
    ndarray or float
        The stop time in s; ``inf`` when ``c == 0`` (the amplitude only tends to zero),
        0 when ``y0 == 0`` and ``c > 0``.
    """
    shape = _shape_of(y0, a, b, c)
    result = np.array([_one_stop_time(*values) for values in zip(*_as_flat_arrays(
        y0, a, b, c))]).reshape(shape)
    return result[()] if result.ndim == 0 else result


def _one_stop_time(y0, a, b, c):
    law = _law_or_none(float(y0), float(a), float(b), float(c))
    if law is not None:
        return law.t_stop
    if y0 == 0 and 0 <= a < math.inf and 0 <= b < math.inf and 0 <= c < math.inf:
        return 0.0 if c > 0 else math.inf
    return math.nan


def amplitude(t, y0, a, b, c):
    """Amplitude y(t) of the modified Coulomb law (Handbook Eq. 20.59, stable form).

    Parameters
    ----------
    t : float or ndarray
        Time since the amplitude was ``y0``, >= 0 (s, or cycles with cycle-unit coefficients).
    y0 : float or ndarray
        Amplitude at ``t = 0`` (signal units U), >= 0.
    a, b, c : float or ndarray
        Fluid (1/(U*s)), hysteretic (1/s) and Coulomb (U/s) coefficients, >= 0.

    Returns
    -------
    ndarray or float
        y(t) >= 0, exactly 0 from the stop time on (only when ``c > 0``).

    Notes
    -----
    Valid in every regime (b**2 > 4ac, = 4ac, < 4ac, any coefficient zero) without 0/0,
    overflow or NaN for finite non-negative inputs. Relative accuracy is a few ulp except
    close to the stop time, where y -> 0 and the absolute error stays about eps*y0.
    """
    return _Evaluated(t, y0, a, b, c).amplitude()


def amplitude_jacobian(t, y0, a, b, c):
    """Derivatives of y(t) with respect to (y0, a, b, c), for a fit's Jacobian.

    Parameters are those of :func:`amplitude`.

    Returns
    -------
    ndarray, shape (..., 4)
        ``[dy/dy0, dy/da, dy/db, dy/dc]`` at each time; zero after the stop.

    Notes
    -----
    dy/dy0 = P(y)/P(y0) with P(y) = c + b*y + a*y**2 (the flow of an autonomous ODE).
    dy/da and dy/dc differentiate the tau form; their terms share one sign, so there is no
    cancellation. dy/db comes from the tau form where s*t < 1 and otherwise from the
    time-scaling identity a*dy/da + b*dy/db + c*dy/dc = -t*P(y).
    """
    return _Evaluated(t, y0, a, b, c).jacobian()


def amplitude_and_jacobian(t, y0, a, b, c):
    """``(amplitude(...), amplitude_jacobian(...))`` from one evaluation of the law."""
    terms = _Evaluated(t, y0, a, b, c)
    return terms.amplitude(), terms.jacobian()


def amplitude_rows(t, y0, a, b, c):
    """The law of one parameter set at sorted times, for a fit's inner loop.

    ``t`` must be a 1-D float array in increasing order and ``y0, a, b, c`` floats; nothing
    is checked or reshaped. Returns an object whose ``amplitude()`` is y(t), shape (n,),
    and whose ``jacobian()`` is dy/d(y0, a, b, c) as rows, shape (4, n), computed on demand.
    """
    return _one_set(t, y0, a, b, c)


def amplitude_terms(t, y0, a, b, c):
    """The law evaluated once, its Jacobian computed only on demand.

    Returns an object whose ``amplitude()`` and ``jacobian()`` give what
    :func:`amplitude` and :func:`amplitude_jacobian` return. A least-squares solver needs
    the Jacobian only at the steps it accepts, and the residuals at every trial step.
    """
    return _Evaluated(t, y0, a, b, c)


def decay_rate(y, a, b, c):
    """-dy/dt = c + b*y + a*y**2 at amplitude ``y`` (U/s)."""
    y = np.asarray(y, dtype=float)
    return c + b * y + a * y**2


def quality_parts(y, omega, a, b, c):
    """Q of each damping regime at amplitude ``y`` (Handbook Eq. 20.56).

    Parameters
    ----------
    y : float or ndarray
        Amplitude (U).
    omega : float
        Angular frequency (rad/s); with cycle-unit coefficients pass ``omega = 2*pi``.
    a, b, c : float
        Coefficients in the same time unit as ``omega``.

    Returns
    -------
    (q_coulomb, q_hysteretic, q_fluid) : tuple of ndarray
        ``Qc = omega*y/(2c)``, ``Qh = omega/(2b)``, ``Qf = omega/(2*a*y)``; ``inf`` where
        the regime is absent (its coefficient is zero).
    """
    y = np.asarray(y, dtype=float)
    shape = np.broadcast(y, a, b, c).shape
    q_coulomb = np.full(shape, np.inf)
    q_hysteretic = np.full(shape, np.inf)
    q_fluid = np.full(shape, np.inf)
    np.divide(omega * y, 2.0 * c, out=q_coulomb, where=np.broadcast_to(c > 0, shape))
    np.divide(omega, 2.0 * np.broadcast_to(b, shape), out=q_hysteretic,
              where=np.broadcast_to(b > 0, shape))
    np.divide(omega, 2.0 * a * y, out=q_fluid, where=np.broadcast_to(a * y > 0, shape))
    return q_coulomb, q_hysteretic, q_fluid


def quality_factor(y, omega, a, b, c):
    """Total Q at amplitude ``y``: ``1/Q = (2/omega)*(c/y + b + a*y)`` (Handbook Eq. 20.56).

    Returns ``omega*y/(2*P(y))``, ``inf`` without damping and 0 at ``y = 0`` when ``c > 0``.
    """
    y = np.asarray(y, dtype=float)
    rate = np.broadcast_to(decay_rate(y, a, b, c), np.broadcast(y, a, b, c).shape)
    q = np.full(rate.shape, np.inf)
    np.divide(omega * y, 2.0 * rate, out=q, where=rate > 0)
    return q[()] if q.ndim == 0 else q


def to_cycle_units(a, b, c, period):
    """Coefficients per second -> per cycle: ``(a*T, b*T, c*T)`` (docs/theory.md section 1)."""
    return a * period, b * period, c * period


def to_time_units(a_n, b_n, c_n, period):
    """Coefficients per cycle -> per second: ``(a_n/T, b_n/T, c_n/T)``."""
    return a_n / period, b_n / period, c_n / period


def to_q_form(y0, a, b, c, omega):
    """``(Qf0, Qh, Qc0)`` of Handbook Eq. 20.56 at the initial amplitude ``y0``."""
    q_coulomb, q_hysteretic, q_fluid = quality_parts(y0, omega, a, b, c)
    return q_fluid[()], q_hysteretic[()], q_coulomb[()]


def from_q_form(y0, q_fluid0, q_hysteretic, q_coulomb0, omega):
    """``(a, b, c)`` from ``(Qf0, Qh, Qc0)``; an infinite Q means the regime is absent."""
    with np.errstate(divide="ignore"):
        a = omega / (2.0 * y0 * np.asarray(q_fluid0, dtype=float))
        b = omega / (2.0 * np.asarray(q_hysteretic, dtype=float))
        c = omega * y0 / (2.0 * np.asarray(q_coulomb0, dtype=float))
    return a[()], b[()], c[()]


def energy_coefficients(a, b, c, energy_per_amplitude_squared=1.0):
    """``(c1, c2, c3)`` of the energy form dE/dt = -(c1 + c2*sqrt(E) + c3*E)*sqrt(E).

    Handbook Eq. 20.58 with ``E = kappa*y**2`` (``kappa = energy_per_amplitude_squared``,
    e.g. k/2 for a spring of stiffness k): ``c1 = 2*c*sqrt(kappa)``, ``c2 = 2*b``,
    ``c3 = 2*a/sqrt(kappa)``.
    """
    root = np.sqrt(energy_per_amplitude_squared)
    return 2.0 * c * root, 2.0 * b, 2.0 * a / root


def _power_law_terms(t, y0, k, n):
    t, y0, k, n = _as_flat_arrays(t, y0, k, n)
    epsilon = n - 1.0
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        w = k * y0**epsilon * t
    x = epsilon * w
    running = x > -1.0  # for n < 1 the amplitude stops where 1 + (n-1)*k*y0**(n-1)*t = 0
    x_run = np.where(running, x, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_term = np.where(epsilon == 0, w, np.log1p(x_run) / np.where(epsilon == 0, 1.0, epsilon))
    y = np.where(running, y0 * np.exp(-log_term), 0.0)
    return t, y0, k, epsilon, w, x_run, y, running


def power_law_amplitude(t, y0, k, n):
    """Amplitude of the free power law dy/dt = -k*y**n (Handbook Eq. 20.51, n = 2*lambda).

    ``y = y0 * (1 + (n-1)*k*y0**(n-1)*t)**(-1/(n-1))``, evaluated with log1p so that it is
    continuous through ``n = 1`` (``y0*exp(-k*t)``); for ``n < 1`` it is 0 after the stop.
    """
    y = _power_law_terms(t, y0, k, n)[6].reshape(_shape_of(t, y0, k, n))
    return y[()] if y.ndim == 0 else y


def power_law_jacobian(t, y0, k, n):
    """Derivatives of :func:`power_law_amplitude` with respect to (y0, k, n), shape (..., 3)."""
    shape = _shape_of(t, y0, k, n)
    t, y0, k, epsilon, w, x, y, running = _power_law_terms(t, y0, k, n)
    one_plus_x = 1.0 + x
    d_y0 = (y / y0) / one_plus_x
    d_k = -y * (y0**epsilon * t) / one_plus_x
    # d/d(epsilon) of log1p(eps*w)/eps at fixed w = [x/(1+x) - log1p(x)]/eps**2, by series
    # where x is small: sum_{j>=2} (-1)**(j+1) * (1 - 1/j) * x**(j-2) * w**2 (no power of
    # w alone that could overflow; other times are masked out of the series).
    small = np.abs(x) < 0.05
    j = np.arange(2, 16)
    x_small, w_small = np.where(small, x, 0.0), np.where(small, w, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        series = w_small**2 * np.sum(((-1.0) ** (j + 1) * (1 - 1 / j))
                                     * x_small[..., None] ** (j - 2), axis=-1)
        direct = (x / one_plus_x - np.log1p(x)) / epsilon**2
    d_log_fixed_w = np.where(small, series, direct)
    d_log = d_log_fixed_w + w * np.log(y0) / one_plus_x
    d_n = -y * d_log
    jacobian = np.stack([d_y0, d_k, d_n], axis=-1)
    return np.where(running[:, None], jacobian, 0.0).reshape(shape + (3,))
