"""Amplitude law of the modified Coulomb model, its sensitivities, Q(t) and unit conversions.

Handbook Eq. 20.59: ``dy/dt = -c - b*y - a*y**2`` with ``a, b, c >= 0``; ``y`` is the
turning-point amplitude, ``c`` Coulomb (U/s), ``b`` hysteretic (1/s), ``a`` fluid (1/(U*s)).
All functions take times in the units of the coefficients (seconds, or cycles for
coefficients in cycle units) and broadcast over numpy arrays. Pure numpy: no I/O.

The closed form is THEORY.md section 3::

    y = (y0 - tau*K) / (1 + tau*M),   K = c + b*y0/2,   M = a*y0 + b/2
    tau = t * Phi(sigma*t**2),        sigma = b**2/4 - a*c = D/4
    Phi(u) = tanh(sqrt(u))/sqrt(u) (u > 0),  1 (u = 0),  tan(sqrt(-u))/sqrt(-u) (u < 0)

Phi is analytic across u = 0 (a series is used there), so b**2 = 4ac needs no special case.
Where D > 0 and s*t >= 1 (s = sqrt(sigma)) the same expression is rewritten with
E = exp(-2*s*t) so that exponential tails keep their relative accuracy.

One parameter set at sorted times (a fit's case) is evaluated by a faster path with the
same formulas; parameter arrays and unsorted times by the general one.
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
# Below this |u| the series is exact to rounding (0.04**11 < 1e-15); above it the direct
# formula for Phi' loses at most 1.5*eps/|u| to cancellation.
_SERIES_LIMIT = 0.1
# Where D > 0 and s*t exceeds this, use the exponential form (no tanh -> 1 cancellation).
_EXPONENTIAL_FORM_LIMIT = 1.0


def _phi(u):
    """Phi(u) and dPhi/du, evaluated stably for every real u (see module docstring)."""
    u = np.asarray(u, dtype=float)
    phi = np.empty_like(u)
    dphi = np.empty_like(u)
    small = np.abs(u) < _SERIES_LIMIT
    if np.any(small):
        phi[small] = np.polynomial.polynomial.polyval(u[small], _PHI_SERIES)
        dphi[small] = np.polynomial.polynomial.polyval(u[small], _PHI_DERIVATIVE_SERIES)

    positive = (~small) & (u > 0)
    z = np.sqrt(u[positive])
    e = np.exp(-2.0 * z)
    tanh = (1.0 - e) / (1.0 + e)
    sech2 = 4.0 * e / (1.0 + e) ** 2
    phi[positive] = tanh / z
    dphi[positive] = (z * sech2 - tanh) / (2.0 * z**3)

    negative = (~small) & (u < 0)
    z = np.sqrt(-u[negative])
    tan = np.tan(z)
    phi[negative] = tan / z
    dphi[negative] = -(z * (1.0 + tan**2) - tan) / (2.0 * z**3)
    return phi, dphi


def _discriminant_quarter(a, b, c):
    """sigma = b**2/4 - a*c, factored so that no product overflows."""
    g = np.sqrt(a) * np.sqrt(c)
    return (0.5 * b - g) * (0.5 * b + g)


def _as_flat_arrays(*values):
    """Broadcast to a common shape and flatten to 1-D float arrays (restored by callers)."""
    arrays = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in values))
    return [np.ravel(v) for v in arrays]


def _shape_of(*values):
    return np.broadcast(*(np.asarray(v) for v in values)).shape


# Normalized time is capped here: by then y < 1e-100*y0 whatever the coefficients, because
# the largest normalized rate is 1 (see _normalize).
_MAX_NORMALIZED_TIME = 1e100


class _Normalized:
    """The law in units where y0 = 1 and the largest of c/y0, b, a*y0 is 1.

    ``y(t; y0, a, b, c) = y0 * eta(r*t; 1, a*y0/r, b/r, c/(y0*r))`` holds for every r > 0,
    so all arithmetic below works on numbers of order one and nothing overflows.
    """

    def __init__(self, y0, a, b, c):
        self.y0 = np.where(y0 > 0, y0, 1.0)  # y0 = 0 is handled by the callers
        with np.errstate(over="ignore"):
            rate_c = c / self.y0
            rate_a = a * self.y0
        rate = np.maximum(np.maximum(rate_c, b), rate_a)
        self.log_rate = None
        if np.all(np.isfinite(rate)):
            self.rate = np.where(rate > 0, rate, 1.0)
            self.a = rate_a / self.rate
            self.b = b / self.rate
            self.c = rate_c / self.rate
        else:  # a rate beyond the float range: the same scaling, done in logarithms
            with np.errstate(divide="ignore"):
                logs = np.stack([np.log(a) + np.log(self.y0), np.log(b),
                                 np.log(c) - np.log(self.y0)])
            log_rate = np.max(logs, axis=0)
            log_rate = np.where(np.isfinite(log_rate), log_rate, 0.0)
            self.a, self.b, self.c = np.exp(logs - log_rate)
            self.log_rate = log_rate
            with np.errstate(over="ignore"):
                self.rate = np.exp(log_rate)

    def time(self, t):
        """Normalized time r*t, capped at _MAX_NORMALIZED_TIME."""
        if self.log_rate is None:
            with np.errstate(over="ignore"):
                return np.minimum(self.rate * t, _MAX_NORMALIZED_TIME)
        with np.errstate(divide="ignore"):
            log_time = np.minimum(self.log_rate + np.log(t), np.log(_MAX_NORMALIZED_TIME))
        return np.exp(log_time)

    def per_rate(self, value):
        """value / r, without overflow or underflow to a wrong zero where avoidable."""
        if self.log_rate is None:
            return value / self.rate
        with np.errstate(invalid="ignore"):
            return np.where(np.isinf(value), value, value * np.exp(-self.log_rate))


def _normalized_stop_time(a, b, c):
    """Stop time of the normalized law (y0 = 1); inf where c == 0."""
    sigma = _discriminant_quarter(a, b, c)
    k = c + 0.5 * b
    result = np.full(a.shape, np.inf)
    stops = c > 0
    tau_stop = np.zeros(a.shape)
    s = np.sqrt(np.abs(sigma))
    # A Coulomb term below ~1e-308 of the largest rate stops the motion beyond any float
    # time: those stop times come out as inf, which is what they are for every use here.
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        tau_stop[stops] = 1.0 / k[stops]
        overdamped = stops & (sigma > 0)
        so, ao, co, ko, to = (v[overdamped] for v in (s, a, c, k, tau_stop))
        z = so * to
        # 1 - z written without cancellation: b/2 - s = a*c/(b/2 + s).
        one_minus_z = (co + ao * co / (0.5 * b[overdamped] + so)) / ko
        result[overdamped] = 0.5 * np.log1p(2.0 * z / one_minus_z) / so
        underdamped = stops & (sigma < 0)
        result[underdamped] = np.arctan(s[underdamped] * tau_stop[underdamped]) / s[underdamped]
    result = np.where(np.isnan(result), np.inf, result)

    critical = stops & (sigma == 0)
    result[critical] = tau_stop[critical]
    return result


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
    if _is_scalar(y0) and _is_scalar(a) and _is_scalar(b) and _is_scalar(c):
        # The scalar code _SortedTerms uses, so that amplitude() is 0 from this time on.
        law = _one_law(float(y0), float(a), float(b), float(c))
        if law is not None:
            return np.float64(_one_law_constants(*law[1:])[2] / law[0])
    shape = _shape_of(y0, a, b, c)
    y0, a, b, c = _as_flat_arrays(y0, a, b, c)
    law = _Normalized(y0, a, b, c)
    with np.errstate(over="ignore"):
        result = law.per_rate(_normalized_stop_time(law.a, law.b, law.c))
    result = np.where((y0 == 0) & (c > 0), 0.0, result).reshape(shape)
    return result[()] if result.ndim == 0 else result


def _at(values, mask):
    """values[mask] for per-time arrays; a size-1 parameter array as it is (it broadcasts)."""
    return values if values.size == 1 else values[mask]


class _LawTerms:
    """The normalized amplitude and the pieces its Jacobian reuses."""

    def __init__(self, t, y0, a, b, c):
        self.shape = _shape_of(t, y0, a, b, c)
        if math.prod(_shape_of(y0, a, b, c)) == 1:
            # One parameter set (a fit's case): keep its constants as size-1 arrays that
            # broadcast against t, so each is computed once, not once per time.
            t = np.ravel(np.broadcast_to(np.asarray(t, dtype=float), self.shape))
            y0, a, b, c = (np.asarray(v, dtype=float).reshape(1) for v in (y0, a, b, c))
        else:
            t, y0, a, b, c = _as_flat_arrays(t, y0, a, b, c)
        self.t_in, self.y0_in, self.c_in = t, y0, c
        law = self.law = _Normalized(y0, a, b, c)
        a, b, c = law.a, law.b, law.c
        theta = law.time(t)
        theta_stop = _normalized_stop_time(a, b, c)
        with np.errstate(over="ignore"):
            t_stop = law.per_rate(theta_stop)  # exactly what stop_time() returns
        self.running = (t < t_stop) & (y0 > 0)
        theta = np.minimum(theta, theta_stop)
        # After the stop y = 0; evaluate there at theta = 0, far from tan's pole.
        theta = np.where(self.running, theta, 0.0)
        sigma = _discriminant_quarter(a, b, c)
        s = np.sqrt(np.abs(sigma))
        z = s * theta
        self.exponential = (sigma > 0) & (z >= _EXPONENTIAL_FORM_LIMIT)
        tau = np.empty_like(theta)
        dtau_dsigma = np.empty_like(theta)
        near = ~self.exponential
        phi, dphi = _phi(_at(sigma, near) * theta[near] ** 2)
        tau[near] = theta[near] * phi
        dtau_dsigma[near] = theta[near] ** 3 * dphi
        # Far in the exponential regime theta**3 * Phi'(u) = -(tanh z - z*sech(z)**2)/(2 s**3).
        far = self.exponential
        e = np.exp(-2.0 * z[far])
        tanh = (1.0 - e) / (1.0 + e)
        s_far = _at(s, far)
        tau[far] = tanh / s_far
        dtau_dsigma[far] = -(tanh - z[far] * 4.0 * e / (1.0 + e) ** 2) / (2.0 * s_far**3)

        k = c + 0.5 * b
        m = a + 0.5 * b
        eta = (1.0 - tau * k) / (1.0 + tau * m)
        if np.any(far):
            sf, af, bf, cf, kf, mf = (_at(v, far) for v in (s, a, b, c, k, m))
            h = 0.5 * bf + sf
            numerator = e * (sf + kf) - cf * (1.0 + af / h)
            denominator = (sf + mf) - e * af * (1.0 + cf / h)
            eta[far] = numerator / denominator
        self.eta = np.where(self.running, np.maximum(eta, 0.0), 0.0)
        self.theta, self.tau, self.dtau_dsigma, self.k, self.m = theta, tau, dtau_dsigma, k, m

    def amplitude(self):
        y = (self.y0_in * self.eta).reshape(self.shape)
        return y[()] if y.ndim == 0 else y

    def jacobian(self):
        law, eta, tau, k, m = self.law, self.eta, self.tau, self.k, self.m
        a, b, c = law.a, law.b, law.c
        denominator = 1.0 + tau * m
        shared = self.dtau_dsigma * (k + eta * m)  # d tau/d sigma times (K + eta*M), <= 0
        d_a = (-eta * tau + c * shared) / denominator
        d_c = (-tau + a * shared) / denominator
        d_b = (-0.5 * tau * (1.0 + eta) - 0.5 * b * shared) / denominator
        rate_eta = c + b * eta + a * eta**2
        with np.errstate(divide="ignore", invalid="ignore"):
            d_b_scaling = -(rate_eta * self.theta + c * d_c + a * d_a) / b
        d_b = np.where(self.exponential, d_b_scaling, d_b)
        # P(y)/P(y0); after normalizing a + b + c >= 1 unless there is no damping at all.
        total = a + b + c
        d_y0 = np.where(total > 0, rate_eta / np.where(total > 0, total, 1.0), 1.0)
        y0 = law.y0
        with np.errstate(over="ignore", under="ignore", invalid="ignore"):
            d_a = np.where(d_a == 0, 0.0, d_a * law.per_rate(y0) * y0)
            d_b = np.where(d_b == 0, 0.0, law.per_rate(d_b * y0))
            d_c = np.where(d_c == 0, 0.0, law.per_rate(d_c))
        # y0 = 0: y stays 0 unless c = 0, where y = y0*exp(-b*t) to first order in y0.
        zero_start = self.y0_in == 0
        d_y0 = np.where(zero_start,
                        np.where(self.c_in == 0, np.exp(-law.b * law.time(self.t_in)), 0.0),
                        d_y0)
        jacobian = np.stack([d_y0, d_a, d_b, d_c], axis=-1)
        jacobian = np.where(self.running[:, None] | (zero_start[:, None] & (np.arange(4) == 0)),
                            jacobian, 0.0)
        return jacobian.reshape(self.shape + (4,))


# Smallest |u| at which each term k >= 1 of the Phi' series exceeds 2**-56 of the first,
# so a slice whose largest |u| is below _PHI_DERIVATIVE_NEEDS[k-1] needs no term past k-1.
_PHI_DERIVATIVE_NEEDS = tuple(
    float((2.0**-56 * abs(_PHI_DERIVATIVE_SERIES[0]) / abs(d)) ** (1.0 / k))
    for k, d in enumerate(_PHI_DERIVATIVE_SERIES[1:], start=1))
_EXPONENTS = np.arange(float(_PHI_DERIVATIVE_SERIES.size))
# Powers of u for the series by one np.power call (about 10 ns per element) up to this many
# elements, beyond it row by row (about 1 us per call).
_POWER_CALL_LIMIT = 600


def _is_scalar(value):
    """True for a real number or a 0-d array (np.ndim is slow for the fit's inner loop)."""
    return isinstance(value, (float, int, np.floating, np.integer)) or (
        isinstance(value, np.ndarray) and value.ndim == 0)


def _one_law(y0, a, b, c):
    """(rate, a, b, c) of _Normalized for one parameter set, as floats; None where the
    array code is needed (y0 <= 0, a rate beyond the float range, or invalid input)."""
    if not (y0 > 0 and a >= 0 and b >= 0 and c >= 0):
        return None
    rate_c = c / y0
    rate_a = a * y0  # Python floats give inf, not an exception, on overflow
    rate = max(rate_c, b, rate_a)
    if not rate < math.inf:
        return None
    if rate == 0:
        rate = 1.0
    return rate, rate_a / rate, b / rate, rate_c / rate


def _one_law_constants(a, b, c):
    """sigma, s and the normalized stop time of one normalized law (scalar
    _discriminant_quarter and _normalized_stop_time)."""
    g = math.sqrt(a) * math.sqrt(c)
    sigma = (0.5 * b - g) * (0.5 * b + g)
    s = math.sqrt(abs(sigma))
    if c <= 0:
        return sigma, s, math.inf
    k = c + 0.5 * b
    tau_stop = 1.0 / k
    if sigma > 0:
        # 1 - z written without cancellation: b/2 - s = a*c/(b/2 + s).
        one_minus_z = (c + a * c / (0.5 * b + s)) / k
        if one_minus_z == 0:
            return sigma, s, math.inf  # a Coulomb term too faint to stop within floats
        result = 0.5 * math.log1p(2.0 * (s * tau_stop) / one_minus_z) / s
    elif sigma < 0:
        result = math.atan(s * tau_stop) / s
    else:
        result = tau_stop
    return sigma, s, result if result == result else math.inf


class _SortedTerms:
    """_LawTerms for one parameter set at sorted times >= 0: a fit's case, made fast.

    Normalized time grows with t, so each branch of tau (series, direct, exponential
    form, stopped) covers one contiguous slice of the times: every branch works on a view,
    without masks, and the constants are computed once as Python floats. The formulas are
    those of _LawTerms, with tau = tanh(s*theta)/s or tan(s*theta)/s in place of
    theta*Phi(u) (the same function), so that the series is needed for Phi' only. On the
    fit's 10 to 1000 points each numpy call costs more than its arithmetic: the code is
    written to make few of them.
    """

    def __init__(self, t, shape, y0, law):
        rate, a, b, c = law
        sigma, s, theta_stop = _one_law_constants(a, b, c)
        n = t.size
        if float(t[-1]) * rate <= _MAX_NORMALIZED_TIME:
            theta = t * rate
        else:
            with np.errstate(over="ignore"):
                theta = np.minimum(t * rate, _MAX_NORMALIZED_TIME)
        # Running while t < t_stop, with t_stop exactly what stop_time() returns.
        n_run = n if theta_stop == math.inf else int(t.searchsorted(theta_stop / rate))
        theta = theta[:n_run]
        if theta_stop < math.inf:
            theta = np.minimum(theta, theta_stop)
        # Branch boundaries: |u| = |sigma|*theta**2 < _SERIES_LIMIT, s*theta >= 1.
        if sigma == 0:
            n_series = n_exp = n_run
        else:
            n_series = int(theta.searchsorted(math.sqrt(_SERIES_LIMIT / abs(sigma))))
            n_exp = (int(theta.searchsorted(_EXPONENTIAL_FORM_LIMIT / s)) if sigma > 0
                     else n_run)
        k = c + 0.5 * b
        m = a + 0.5 * b

        dtau = np.empty(n_run)  # d tau / d sigma = theta**3 * Phi'(u)
        if sigma == 0:  # Phi(0) = 1, Phi'(0) = -1/3
            tau = theta
            np.multiply(theta * theta, theta * _PHI_DERIVATIVE_SERIES[0], out=dtau)
        else:
            z = s * theta
            trig = np.tanh(z) if sigma > 0 else np.tan(z)  # before tan's pole: see stop_time
            tau = trig / s
        if sigma != 0 and n_series:  # the series, with only the terms that matter
            theta_s = theta[:n_series]
            square = theta_s * theta_s
            u = sigma * square
            degree = bisect.bisect_right(_PHI_DERIVATIVE_NEEDS, abs(float(u[-1])))
            if n_series * degree <= _POWER_CALL_LIMIT:
                powers = u ** _EXPONENTS[:degree + 1, None]
            else:
                powers = np.empty((degree + 1, n_series))
                powers[0] = 1.0
                for j in range(1, degree + 1):
                    np.multiply(powers[j - 1], u, out=powers[j])
            np.multiply(square * theta_s, _PHI_DERIVATIVE_SERIES[:degree + 1] @ powers,
                        out=dtau[:n_series])
        if n_exp > n_series:  # the closed form of Phi' where |u| >= _SERIES_LIMIT
            zd = z[n_series:n_exp]
            td = trig[n_series:n_exp]
            numerator = zd * (1.0 - td * td) - td if sigma > 0 else td - zd * (1.0 + td * td)
            np.multiply(numerator, 0.5 / (s * s * s), out=dtau[n_series:n_exp])
        denominator = 1.0 + tau * m
        eta = np.zeros(n)
        running = eta[:n_run]
        np.divide(1.0 - tau[:n_exp] * k, denominator[:n_exp], out=running[:n_exp])
        if n_run > n_exp:  # s*theta >= 1: written with E = exp(-2z), so tails keep digits
            zf = z[n_exp:]
            e = np.exp(-2.0 * zf)
            one_plus_e = 1.0 + e
            sech2 = 4.0 * e / (one_plus_e * one_plus_e)
            np.multiply(trig[n_exp:] - zf * sech2, -0.5 / (s * s * s), out=dtau[n_exp:])
            h = 0.5 * b + s
            np.divide(e * (s + k) - c * (1.0 + a / h), (s + m) - e * (a * (1.0 + c / h)),
                      out=running[n_exp:])
        np.maximum(running, 0.0, out=running)
        self.shape, self.y0, self.rate, self.a, self.b, self.c = shape, y0, rate, a, b, c
        self.n_run, self.n_exp, self.theta, self.k, self.m = n_run, n_exp, theta, k, m
        self.tau, self.dtau, self.denominator, self.eta = tau, dtau, denominator, eta

    def amplitude(self):
        y = (self.y0 * self.eta).reshape(self.shape)
        return y[()] if y.ndim == 0 else y

    def jacobian(self):
        a, b, c, k, m = self.a, self.b, self.c, self.k, self.m
        n_run, n_exp = self.n_run, self.n_exp
        eta = self.eta[:n_run]
        # The formulas of _LawTerms.jacobian as one matrix product: rows of the basis
        # B = [S, T, eta*T, 1, eta, eta**2] with T = tau/(1 + tau*M) and S = (d tau/d sigma)
        # * (K + eta*M)/(1 + tau*M) (<= 0) combine into dy/d(y0, a, b, c) in normalized units.
        basis = np.empty((6, n_run))
        np.divide(self.tau, self.denominator, out=basis[1])
        np.multiply(eta, m, out=basis[0])
        basis[0] += k
        basis[0] *= self.dtau
        basis[0] /= self.denominator
        np.multiply(eta, basis[1], out=basis[2])
        basis[3] = 1.0
        basis[4] = eta
        np.multiply(eta, eta, out=basis[5])
        # dy/dy0 = P(y)/P(y0); after normalizing a + b + c >= 1 unless there is no damping.
        total = a + b + c
        y0_row = (0.0, 0.0, 0.0, c / total, b / total, a / total) if total > 0 else (
            0.0, 0.0, 0.0, 1.0, 0.0, 0.0)
        combination = np.array([y0_row,
                                (c, 0.0, -1.0, 0.0, 0.0, 0.0),
                                (-0.5 * b, -0.5, -0.5, 0.0, 0.0, 0.0),
                                (a, -1.0, 0.0, 0.0, 0.0, 0.0)])
        jacobian = np.empty((4, self.eta.size))
        np.matmul(combination, basis, out=jacobian[:, :n_run])
        jacobian[:, n_run:] = 0.0
        if n_run > n_exp:
            # Where s*theta >= 1: the time-scaling identity a*dy/da + b*dy/db + c*dy/dc
            # = -t*P(y) gives dy/db without the cancellation of the formula above.
            d_y0, d_a, d_b, d_c = jacobian[:, n_exp:n_run]
            rate_eta = c + b * basis[4, n_exp:] + a * basis[5, n_exp:]
            np.divide(rate_eta * self.theta[n_exp:] + c * d_c + a * d_a, -b, out=d_b)
        # Back from normalized units, in the order of _LawTerms.jacobian.
        y0, rate = self.y0, self.rate
        y0_per_rate = y0 / rate
        factors = (y0_per_rate * y0, y0_per_rate, 1.0 / rate)
        if max(factors) <= 1e150 and float(np.abs(jacobian).max()) <= 1e150:  # no overflow
            jacobian[1:] *= np.array(factors)[:, None]
        else:
            d_a, d_b, d_c = jacobian[1:]
            with np.errstate(over="ignore", under="ignore", invalid="ignore"):
                # An infinite factor must not turn an exact zero into NaN.
                np.multiply(d_a, y0_per_rate, out=d_a, where=d_a != 0)
                d_a *= y0
                d_b *= y0
                d_b /= rate
                d_c /= rate
        return jacobian.T.reshape(self.shape + (4,))


def _law_terms(t, y0, a, b, c):
    """The law's terms: _SortedTerms where it applies (one parameter set, y0 > 0, sorted
    times >= 0), _LawTerms otherwise (parameter arrays, unsorted times, extreme rates)."""
    if _is_scalar(y0) and _is_scalar(a) and _is_scalar(b) and _is_scalar(c):
        times = np.asarray(t, dtype=float)
        flat = times.ravel()
        if flat.size and flat[0] >= 0 and (flat.size == 1 or (flat[1:] >= flat[:-1]).all()):
            law = _one_law(float(y0), float(a), float(b), float(c))
            if law is not None:
                return _SortedTerms(flat, times.shape, float(y0), law)
    return _LawTerms(t, y0, a, b, c)


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
    return _law_terms(t, y0, a, b, c).amplitude()


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
    return _law_terms(t, y0, a, b, c).jacobian()


def amplitude_and_jacobian(t, y0, a, b, c):
    """``(amplitude(...), amplitude_jacobian(...))`` from one evaluation of the law."""
    terms = _law_terms(t, y0, a, b, c)
    return terms.amplitude(), terms.jacobian()


def amplitude_terms(t, y0, a, b, c):
    """The law evaluated once, its Jacobian computed only on demand.

    Returns an object whose ``amplitude()`` and ``jacobian()`` give what :func:`amplitude`
    and :func:`amplitude_jacobian` return. A least-squares solver needs the Jacobian only
    at the steps it accepts, and the residuals at every trial step.
    """
    return _law_terms(t, y0, a, b, c)


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
    """Coefficients per second -> per cycle: ``(a*T, b*T, c*T)`` (THEORY.md section 1)."""
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
