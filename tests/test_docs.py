"""The documentation in docs/: every reference to it resolves, nothing cites the team's
notes outside the repository, and the formulas stated in docs/theory.md agree with the code.

The formulas are written out here independently, as the page states them, and compared with
mcfit.decay (and the few other functions the page names) at a few points in each regime.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from mcfit import decay

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.glob("*.md"))
# The team's notes live outside the repository; written in two parts so that this file does
# not cite them itself.
OUTSIDE_NOTES = "THEORY" + ".md"


def _cited_files():
    """README.md and every text file of src/, tests/, sample_data/ and docs/."""
    files = [ROOT / "README.md"]
    for folder in ("src", "tests", "sample_data", "docs"):
        files += [p for p in (ROOT / folder).rglob("*")
                  if p.suffix in (".py", ".md", ".txt", ".toml") and p.is_file()]
    return files


def _headings(page):
    """The headings of a page: (level, text)."""
    found, fenced = [], False
    for line in page.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            fenced = not fenced
        match = None if fenced else re.match(r"^(#{1,6})\s+(.*?)\s*$", line)
        if match:
            found.append((len(match.group(1)), match.group(2)))
    return found


def _section_numbers(page):
    """The numbers of a page's numbered sections: '## 5. Title' -> '5', '### 2.3 T' -> '2.3'."""
    numbers = set()
    for _, text in _headings(page):
        match = re.match(r"^(\d+(?:\.\d+)*)\.?\s", text)
        if match:
            numbers.add(match.group(1))
    return numbers


def _anchor(text):
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", text.strip().lower())
    return text.replace(" ", "-")


def _anchors(page):
    return {_anchor(text) for _, text in _headings(page)}


def test_the_pages_exist_with_numbered_sections():
    names = {p.name for p in PAGES}
    assert {"README.md", "theory.md", "methods.md", "guide.md", "formats.md"} <= names
    # Docstrings cite these numbers; the theory has ten sections, the methods eight.
    assert {str(n) for n in range(1, 11)} <= _section_numbers(DOCS / "theory.md")
    assert {"2.1", "2.2", "2.3", "2.4", "2.5"} <= _section_numbers(DOCS / "theory.md")
    assert {str(n) for n in range(1, 9)} <= _section_numbers(DOCS / "methods.md")


def test_nothing_cites_the_notes_outside_the_repository():
    citing = [str(p.relative_to(ROOT)) for p in _cited_files()
              if OUTSIDE_NOTES in p.read_text(encoding="utf-8", errors="replace")]
    assert citing == []


_SECTION_REFERENCE = re.compile(
    r"docs/(\w+\.md)\s+sections?\s+(\d+(?:\.\d+)*)(?:\s+and\s+(\d+(?:\.\d+)*))?")


def _section_references():
    """(file, page, section) for every "docs/X.md section N" in src, tests and README."""
    found = []
    for path in _cited_files():
        if path.parent == DOCS:
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        for match in _SECTION_REFERENCE.finditer(text):
            for number in match.group(2, 3):
                if number:
                    found.append((str(path.relative_to(ROOT)), match.group(1), number))
    return found


def test_every_section_reference_resolves():
    references = _section_references()
    # The docstrings of decay, turning, fit, motion and bounds cite the pages (22 and more).
    assert len(references) >= 22
    cited_files = {file for file, _, _ in references}
    assert {"src/mcfit/decay.py", "src/mcfit/turning/__init__.py", "src/mcfit/bounds.py",
            "src/mcfit/fit/pendulum.py", "README.md"} <= cited_files
    missing = [(file, page, number) for file, page, number in references
               if not (DOCS / page).is_file() or number not in _section_numbers(DOCS / page)]
    assert missing == []


_LINK = re.compile(r"\]\(([^)\s]+)\)")


def _links(path):
    """The targets of a Markdown file's links, outside code blocks."""
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)
    return [t for t in _LINK.findall(text) if not re.match(r"^[a-z]+:", t)]


@pytest.mark.parametrize("path", [ROOT / "README.md"] + PAGES, ids=lambda p: p.name)
def test_every_link_resolves(path):
    broken = []
    for target in _links(path):
        file, _, anchor = target.partition("#")
        resolved = (path.parent / file).resolve() if file else path
        if not resolved.exists():
            broken.append(target)
        elif anchor and anchor not in _anchors(resolved):
            broken.append(target)
    assert broken == []


def test_the_pages_point_to_each_others_sections():
    """'[methods](methods.md) section 6' inside the pages names a section that exists."""
    pattern = re.compile(r"\]\((\w+\.md)\)\s+sections?\s+(\d+(?:\.\d+)*)")
    missing, count = [], 0
    for page in PAGES:
        for target, number in pattern.findall(page.read_text(encoding="utf-8")):
            count += 1
            if number not in _section_numbers(DOCS / target):
                missing.append((page.name, target, number))
    assert count >= 10
    assert missing == []


# --- the closed forms of docs/theory.md section 2 -------------------------------------------

TIMES = np.array([0.0, 0.3, 1.0, 2.5, 7.0])


def _close(value, expected):
    np.testing.assert_allclose(value, expected, rtol=1e-11, atol=1e-14)


def test_single_terms_section_2_1():
    """docs/theory.md section 2.1: exponential, 1/(1 + a*y0*t), straight line to y0/c."""
    y0 = 2.0
    _close(decay.amplitude(TIMES, y0, 0.0, 0.4, 0.0), y0 * np.exp(-0.4 * TIMES))
    _close(decay.amplitude(TIMES, y0, 0.3, 0.0, 0.0), y0 / (1 + 0.3 * y0 * TIMES))
    _close(decay.amplitude(TIMES, y0, 0.0, 0.0, 0.5), np.maximum(y0 - 0.5 * TIMES, 0.0))
    assert decay.stop_time(y0, 0.0, 0.0, 0.5) == pytest.approx(y0 / 0.5, rel=1e-14)


def test_fluid_and_hysteretic_eq_20_61_section_2_2():
    """docs/theory.md section 2.2: 1/y = (1/y0 + a/b)*exp(b*t) - a/b (Eq. 20.61)."""
    y0, a, b = 4.0, 0.1, 0.1
    expected = 1.0 / ((1 / y0 + a / b) * np.exp(b * TIMES) - a / b)
    _close(decay.amplitude(TIMES, y0, a, b, 0.0), expected)
    assert decay.stop_time(y0, a, b, 0.0) == math.inf


def test_hysteretic_and_coulomb_eq_20_62_section_2_2():
    """docs/theory.md section 2.2: y = (y0 + c/b)*exp(-b*t) - c/b until
    t* = ln(1 + b*y0/c)/b (Eq. 20.62)."""
    y0, b, c = 1.5, 0.2, 0.1
    stop = math.log(1 + b * y0 / c) / b
    expected = np.maximum((y0 + c / b) * np.exp(-b * TIMES) - c / b, 0.0)
    _close(decay.amplitude(TIMES, y0, 0.0, b, c), expected)
    assert decay.stop_time(y0, 0.0, b, c) == pytest.approx(stop, rel=1e-13)
    assert TIMES[-1] > stop  # the last time is after the stop: y = 0 there


def test_fluid_and_coulomb_tangent_form_section_2_2():
    """docs/theory.md section 2.2: y = sqrt(c/a)*tan(arctan(y0*sqrt(a/c)) - sqrt(a*c)*t)
    until t* = arctan(y0*sqrt(a/c))/sqrt(a*c)."""
    y0, a, c = 3.0, 0.2, 0.3
    s = math.sqrt(a * c)
    stop = math.atan(y0 * math.sqrt(a / c)) / s
    t = np.linspace(0.0, 0.999 * stop, 7)
    expected = math.sqrt(c / a) * np.tan(math.atan(y0 * math.sqrt(a / c)) - s * t)
    _close(decay.amplitude(t, y0, a, 0.0, c), expected)
    assert decay.stop_time(y0, a, 0.0, c) == pytest.approx(stop, rel=1e-13)
    assert decay.amplitude(1.01 * stop, y0, a, 0.0, c) == 0.0


def test_three_terms_eq_20_60_section_2_3():
    """docs/theory.md section 2.3: Eq. 20.60 for D = b**2 - 4ac > 0, where it is usable."""
    y0, a, b, c = 4.0, 0.1, 0.1, 0.01  # Fig. 20.19
    r = math.sqrt(b * b - 4 * a * c)
    alpha, beta = 2 * a * y0 + b - r, 2 * a * y0 + b + r
    t = np.array([0.1, 1.0, 5.0, 20.0])
    p = alpha / beta * np.exp(-r * t)
    expected = (b * (p - 1) + r * (p + 1)) / (2 * a * (1 - p))
    _close(decay.amplitude(t, y0, a, b, c), expected)


def _tau_form(t, y0, a, b, c):
    """The tau form of docs/theory.md section 2.3, as the page writes it."""
    d = b * b - 4 * a * c
    s = math.sqrt(abs(d)) / 2
    if d > 0:
        tau, stop_tau = np.tanh(s * t) / s, math.atanh(s * y0 / (c + b * y0 / 2)) / s
    elif d < 0:
        tau, stop_tau = np.tan(s * t) / s, math.atan(s * y0 / (c + b * y0 / 2)) / s
    else:
        tau, stop_tau = t, y0 / (c + b * y0 / 2)
    k, m = c + b * y0 / 2, a * y0 + b / 2
    return np.where(t < stop_tau, (y0 - tau * k) / (1 + tau * m), 0.0), stop_tau


@pytest.mark.parametrize("y0, a, b, c", [
    (4.0, 0.1, 0.1, 0.01),   # D > 0
    (1.0, 0.5, 0.2, 0.3),    # D < 0: the Coulomb-dominant case Eq. 20.60 cannot give
    (2.0, 0.25, 1.0, 1.0),   # D = 0 exactly
])
def test_tau_form_and_its_stop_times_section_2_3(y0, a, b, c):
    """docs/theory.md section 2.3: one expression in every regime, with the stop times of
    its table (artanh, tau*, arctan)."""
    stop = decay.stop_time(y0, a, b, c)
    t = np.concatenate([np.linspace(0.0, 0.99 * stop, 9), [1.5 * stop]])
    expected, stop_expected = _tau_form(t, y0, a, b, c)
    assert stop == pytest.approx(stop_expected, rel=1e-12)
    np.testing.assert_allclose(decay.amplitude(t, y0, a, b, c), expected, rtol=1e-10,
                               atol=1e-13 * y0)


def test_free_power_law_section_2_4():
    """docs/theory.md section 2.4: y = y0*(1 + (n-1)*k*y0**(n-1)*t)**(-1/(n-1))."""
    y0, k = 2.0, 0.3
    for n in (0.5, 1.5, 2.0, 3.0):  # for n < 1 the bracket reaches 0: the stop
        bracket = np.maximum(1 + (n - 1) * k * y0 ** (n - 1) * TIMES, 0.0)
        _close(decay.power_law_amplitude(TIMES, y0, k, n), y0 * bracket ** (-1 / (n - 1)))
    _close(decay.power_law_amplitude(TIMES, y0, k, 1.0), y0 * np.exp(-k * TIMES))


def test_derivative_identities_section_2_5():
    """docs/theory.md section 2.5: dy/dy0 = P(y)/P(y0) and
    a*dy/da + b*dy/db + c*dy/dc = -t*P(y)."""
    for y0, a, b, c in [(4.0, 0.1, 0.1, 0.01), (1.0, 0.5, 0.2, 0.3)]:
        t = np.array([0.2, 1.0, 3.0]) * min(decay.stop_time(y0, a, b, c), 10.0) / 3.5
        y = decay.amplitude(t, y0, a, b, c)
        jacobian = decay.amplitude_jacobian(t, y0, a, b, c)
        rate = decay.decay_rate(y, a, b, c)
        _close(jacobian[:, 0], rate / decay.decay_rate(y0, a, b, c))
        _close(a * jacobian[:, 1] + b * jacobian[:, 2] + c * jacobian[:, 3], -t * rate)


# --- Q, the equation of motion and the limits: docs/theory.md sections 3 to 9 ----------------

def test_quality_factor_and_its_parts_section_3():
    """docs/theory.md section 3: Q = w*y/(2*P(y)), 1/Q = 1/Qc + 1/Qh + 1/Qf with
    Qc = w*y/(2c), Qh = w/(2b), Qf = w/(2*a*y); in cycle units 1/Q = (c_n/y + b_n + a_n*y)/pi."""
    y, omega, a, b, c = np.array([0.2, 1.0, 4.0]), 4 * math.pi, 0.1, 0.1, 0.01
    q = decay.quality_factor(y, omega, a, b, c)
    _close(q, omega * y / (2 * (c + b * y + a * y * y)))
    q_c, q_h, q_f = decay.quality_parts(y, omega, a, b, c)
    _close(q_c, omega * y / (2 * c))
    _close(q_h, omega / (2 * b))
    _close(q_f, omega / (2 * a * y))
    _close(1 / q, 1 / q_c + 1 / q_h + 1 / q_f)
    a_n, b_n, c_n = decay.to_cycle_units(a, b, c, 0.5)
    _close(1 / q, (c_n / y + b_n + a_n * y) / math.pi)
    _close(decay.quality_factor(y, 2 * math.pi, a_n, b_n, c_n), q)


def test_energy_form_eq_20_58_section_1():
    """docs/theory.md section 1: c1 = 2*c*sqrt(kappa), c2 = 2*b, c3 = 2*a/sqrt(kappa)."""
    assert decay.energy_coefficients(0.1, 0.2, 0.3, 4.0) == pytest.approx((1.2, 0.4, 0.1))


def test_figure_20_19_values_section_4():
    """docs/theory.md section 4: initial Q 12.50 (the figure prints 12), the closed form's
    Q 22.09 at 20 s with amplitude 0.0559."""
    omega, (y0, a, b, c) = 4 * math.pi, (4.0, 0.1, 0.1, 0.01)
    assert decay.quality_factor(y0, omega, a, b, c) == pytest.approx(4 * math.pi * 4 / 4.02)
    assert decay.quality_factor(y0, omega, a, b, c) == pytest.approx(12.50, abs=0.005)
    y20 = decay.amplitude(20.0, y0, a, b, c)
    assert y20 == pytest.approx(0.0559, abs=5e-5)
    assert decay.quality_factor(y20, omega, a, b, c) == pytest.approx(22.09, abs=0.005)


def test_velocity_forms_coefficients_section_5():
    """docs/theory.md section 5: a = 4*kappa*w/(3*pi) and c = 2*mu/(pi*w)."""
    from mcfit.fit.waveform import physical_coefficients

    omega, a, b, c = 3.0, 0.2, 0.05, 0.01
    found = physical_coefficients("velocity", "abc", {"a": a, "b": b, "c": c},
                                  {"a": None, "b": None, "c": None}, omega)
    assert a == pytest.approx(4 * found["kappa"]["value"] * omega / (3 * math.pi))
    assert found["beta"]["value"] == b
    assert c == pytest.approx(2 * found["mu"]["value"] / (math.pi * omega))


def test_hysteretic_half_cycle_and_the_low_q_bias_sections_5_and_7():
    """docs/theory.md sections 5 and 7: Eq. 20.55 with b alone falls by (w - k)/(w + k),
    k = pi*b/2, in a half-cycle pi/sqrt(w**2 - k**2); the rate its turning points show is
    b*(1 - pi**2/(96*Q**2) + ...), Q = w/(2b): -0.103/Q**2, the 0.11/Q**2 of the page."""
    from mcfit.hysteretic_motion import hysteretic_motion

    omega = 2 * math.pi
    biases = {}
    for q in (3.0, 10.0, 100.0):
        b = omega / (2 * q)
        k = math.pi * b / 2
        nu = math.sqrt(omega**2 - k**2)
        # From a turning point (phase 0) to the next one, half a cycle later.
        x = np.ravel(hysteretic_motion(np.array([0.0, math.pi / nu]), 1.0, 0.0, omega, b))
        assert -x[1] / x[0] == pytest.approx((omega - k) / (omega + k), rel=1e-9)
        rate = nu / math.pi * math.log((omega + k) / (omega - k))
        biases[q] = rate / b - 1
    # The leading term at high Q, the page's 0.103 to 0.108 over Q = 3 to 10, and b 1.2 %
    # low at Q = 3.
    assert biases[100.0] == pytest.approx(-math.pi**2 / (96 * 100.0**2), rel=1e-3)
    assert math.pi**2 / 96 == pytest.approx(0.103, abs=5e-4)
    for q in (3.0, 10.0):
        assert 0.1025 <= -biases[q] * q * q <= 0.108
    assert biases[3.0] == pytest.approx(-0.012, abs=5e-4)


def test_observed_against_undamped_q_section_3():
    """docs/theory.md section 3: for viscous damping Q_observed = sqrt(Q0**2 - 1/4),
    1.4 % below Q0 at Q0 = 3."""
    omega0, q0 = 2 * math.pi, 3.0
    beta = omega0 / (2 * q0)
    q_observed = math.sqrt(omega0**2 - beta**2) / (2 * beta)
    assert q_observed == pytest.approx(math.sqrt(q0**2 - 0.25), rel=1e-14)
    assert 1 - q_observed / q0 == pytest.approx(0.014, abs=5e-4)


def test_pendulum_factors_section_6():
    """docs/theory.md section 6: G1(1 rad) = 1.057, the period T0*(1 + theta0**2/16 +
    11*theta0**4/3072 + ...), and G0 as the page writes it."""
    from scipy import special

    from mcfit.fit.pendulum import geometric_factors, period_ratio

    g0, g1, g2 = (float(v) for v in geometric_factors(1.0))
    assert g1 == pytest.approx(1.057, abs=5e-4)
    theta0 = 0.3
    assert period_ratio(theta0) == pytest.approx(1 + theta0**2 / 16 + 11 * theta0**4 / 3072,
                                                 rel=1e-6)
    k = math.sin(0.5)
    big_k = special.ellipk(k * k)
    assert g0 == pytest.approx(math.pi * 1.0 / (2 * big_k * math.sin(1.0)), rel=1e-10)
    assert g2 == pytest.approx(3 * math.pi * (math.sin(1.0) - math.cos(1.0))
                               / (2 * big_k * math.sin(1.0)), rel=1e-10)


def test_cramer_rao_example_section_8():
    """docs/theory.md section 8: 100 amplitudes every 0.5 s, y0 = 1, b = 0.02 /s, noise
    1e-3: b's bound is 1.15e-5 /s."""
    from mcfit.bounds import amplitude_crlb

    bound = amplitude_crlb(np.arange(0.0, 50.0, 0.5), 1.0, 0.0, 0.02, 0.0, sigma=1e-3,
                           model="b")
    assert bound["b"] == pytest.approx(1.15e-5, abs=5e-8)


def test_handbook_reference_values_section_9():
    """docs/theory.md section 9: Fig. 20.22's Qf = 8000 is Qh = w/(2b) = 7854 for
    b = 0.0004 /s at T = 1 s."""
    q_h = decay.quality_parts(1.0, 2 * math.pi, 0.0, 0.0004, 0.0)[1]
    assert float(q_h) == pytest.approx(7854, abs=0.5)
