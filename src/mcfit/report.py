"""Text, JSON and CSV forms of an :class:`mcfit.analysis.Analysis` (strings only, no I/O)."""

from __future__ import annotations

import csv
import io
import json
import math
import statistics
from collections import Counter

from mcfit import decay
from mcfit.analysis import Analysis
from mcfit.fit import NONE, POWER, REGIME_NAMES, TERMS

__all__ = ["CSV_COLUMNS", "BOOTSTRAP_CSV_COLUMNS", "TURNING_POINT_COLUMNS", "csv_columns",
           "coefficient_units",
           "turning_points_header", "turning_points_rows", "turning_points_table",
           "to_json_dict", "to_json", "csv_header", "to_csv_row", "to_text", "runs_summary"]

CSV_COLUMNS = ("source", "status", "model", "y0", "y0_stderr", "a", "a_stderr", "b", "b_stderr",
               "c", "c_stderr", "period", "q_initial", "q_final", "turning_points", "error",
               "q_initial_stderr", "q_final_stderr", "domain", "units", "method", "resolved",
               "reduced_chi_square", "warnings", "run", "signal_unit", "y0_unit", "a_unit",
               "b_unit", "c_unit")
# Appended with bootstrap intervals: the 95 % interval of each parameter and of Q.
BOOTSTRAP_CSV_COLUMNS = tuple(f"{k}_boot_{end}" for k in ("y0", "a", "b", "c", "q_initial")
                              for end in ("low", "high"))
_Q_KEYS = ("initial", "final", "min", "max")


def _number(value):
    """float, or None for missing/NaN/inf (JSON has no NaN)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def coefficient_units(signal_unit, per) -> dict:
    """The units of y0, a, b and c for a signal in ``signal_unit`` (``"U"`` when None) and
    time in ``per`` ("s", "cycle"): ``{"y0": "mm", "a": "1/(mm*s)", "b": "1/s",
    "c": "mm/s"}`` (dy/dt = -c - b*y - a*y**2)."""
    unit = signal_unit or "U"
    factor = f"({unit})" if any(mark in unit for mark in "/* ") else unit
    return {"y0": unit, "a": f"1/({factor}*{per})", "b": f"1/{per}", "c": f"{factor}/{per}"}


def _units_of(analysis: Analysis):
    """(signal unit or None, coefficient units) of a fitted analysis: the signal's unit
    from the header (or `unit`), else a pendulum fit's angle unit; time per second, per
    the header's time unit, or per cycle."""
    record, fit = analysis.record, analysis.fit
    signal_unit = getattr(record, "signal_unit", None) or getattr(fit, "angle_unit", None)
    if fit.domain == "cycle":
        per = "cycle"
    else:
        per = getattr(record, "time_unit", None) or "s"
    return signal_unit or None, coefficient_units(signal_unit, per)


def _params_in_time_units(analysis: Analysis):
    """(values, stderrs, unit note). In the cycle domain the record gives no period in
    seconds (its "period" is 1 cycle), so the coefficients stay per cycle."""
    fit, record = analysis.fit, analysis.record
    if fit.domain == "cycle":
        unit = "per cycle"
    else:
        time_unit = getattr(record, "time_unit", None) or "s"
        unit = "per second" if time_unit == "s" else f"per {time_unit}"  # an unknown unit
    values, stderr = _law_values(fit)
    return values, stderr, unit


def _law_values(fit):
    """y0, a, b, c and their stderrs; a power-law fit has y0 only (a, b, c 0, no stderr)."""
    if fit.model != POWER:
        return dict(fit.values), dict(fit.stderr)
    values = {"y0": fit.values["y0"], "a": 0.0, "b": 0.0, "c": 0.0}
    return values, {"y0": fit.stderr["y0"], "a": None, "b": None, "c": None}


def _params_per_cycle(analysis: Analysis):
    """Coefficients per cycle (a*T, b*T, c*T, as in Fig. 20.20), or None without a period."""
    fit, turning = analysis.fit, analysis.turning
    law, law_errors = _law_values(fit)
    if fit.domain == "cycle":
        return {k: {"value": _number(law[k]), "stderr": _number(law_errors[k])}
                for k in TERMS}
    period = _number(turning.period) if turning is not None else None
    if period is None:
        return None
    values = decay.to_cycle_units(*(law[k] for k in TERMS), period)
    errors = [None if law_errors[k] is None else law_errors[k] * period for k in TERMS]
    return {k: {"value": _number(v), "stderr": _number(e)}
            for k, v, e in zip(TERMS, values, errors)}


def to_json_dict(analysis: Analysis) -> dict:
    """The machine-readable contract: keys may be added, never renamed."""
    out = {"source": analysis.source, "status": analysis.status, "error": analysis.error}
    out["run"] = getattr(analysis.record, "run", None)  # "Run 7" of a file of several runs
    record, turning, fit = analysis.record, analysis.turning, analysis.fit
    out["domain"] = getattr(record, "domain", None)
    out["turning_points"] = turning.count if turning is not None else 0
    out["period"] = _number(turning.period) if turning is not None else None
    if fit is None:
        out.update({"model": None, "regimes": None, "params": None, "q": None, "fit": None,
                    "candidates": [], "warnings": []})
    else:
        values, stderr, units = _params_in_time_units(analysis)
        out["model"] = fit.model
        power = fit.model == POWER
        out["method"] = getattr(fit, "method", "turning-points")
        out["method_reason"] = getattr(fit, "method_reason", None)
        out["resolved"] = True if power else fit.resolved
        out["regimes"] = dict.fromkeys(REGIME_NAMES.values(), False) if power else dict(fit.regimes)
        out["params"] = {k: {"value": _number(values[k]), "stderr": _number(stderr[k])}
                         for k in ("y0", "a", "b", "c")}
        out["params_units"] = units
        out["signal_unit"], out["coefficient_units"] = _units_of(analysis)
        out["params_per_cycle"] = _params_per_cycle(analysis)
        out["t0"] = _number(fit.t0)  # time (or cycle) of the first turning point used, where y = y0
        q = fit.q_summary or {}
        out["q"] = {k: _number(q.get(k)) for k in _Q_KEYS}
        out["q"].update({f"{k}_stderr": _number(q.get(f"{k}_stderr")) for k in _Q_KEYS})
        out["q"]["lower_bound"] = _number(getattr(fit, "q_lower_bound", None))
        out["fit"] = {"criterion": fit.criterion, "forced": fit.forced, "rms": _number(fit.rms),
                      "reduced_chi_square": _number(fit.reduced_chi_square),
                      "noise_from_residuals": fit.noise_from_residuals}
        if not power:
            selection = fit.selection
            out["fit"].update({
                "lrt_p_values": {REGIME_NAMES[k]: _number(p)
                                 for k, p in fit.lrt_p_values.items()},
                "alpha": selection.alpha, "preferred": selection.preferred,
                "ties": list(selection.ties),
                "near_threshold": {REGIME_NAMES[k]: _number(p)
                                   for k, p in selection.near_threshold.items()}})
        out["candidates"] = [{"model": c.model, "n_params": c.n_params,
                              "chi_square": _number(c.chi_square), "aicc": _number(c.aicc),
                              "bic": _number(c.bic), "converged": c.success,
                              **({"estimated": True} if c.estimated else {})}
                             for c in fit.candidates]
        if power:
            out["power_law"] = {**{k: _number(v) for k, v in fit.values.items()},
                                **{f"{k}_stderr": _number(e) for k, e in fit.stderr.items()}}
        if getattr(fit, "bootstrap", None) is not None:
            out["bootstrap"] = _bootstrap_json(fit.bootstrap)
        if getattr(fit, "damping_form", None) is not None:
            out["damping_form"] = fit.damping_form
            out["damping_form_reason"] = fit.damping_form_reason
            out["physical"] = {name: {**entry, "value": _number(entry["value"]),
                                      "stderr": _number(entry["stderr"])}
                               for name, entry in fit.physical.items()}
        if getattr(fit, "angle_unit", None) is not None:  # the pendulum's law was fitted
            out["pendulum"] = {
                "angle_unit": fit.angle_unit,
                "small_angle_period": _number(fit.small_angle_period),
                "small_angle_period_stderr": _number(fit.small_angle_period_stderr)}
        out["warnings"] = list(analysis.warnings)
    if record is not None:
        out["columns"] = {"time": record.time_column, "signal": record.signal_column}
        out["input"] = record.kind
    if turning is not None:
        out["turning_points_excluded"] = _excluded_counts(turning)
        out["period_drift"] = _number(turning.period_drift)
        # Where the free decay starts, when the record begins held, driven or settling.
        out["release_time"] = _number(getattr(turning, "release_time", None))
        out["notes"] = list(getattr(record, "notes", ())) + list(turning.notes)
    elif record is not None:
        out["notes"] = list(record.notes)
    return out


def _bootstrap_json(boot):
    intervals = boot["interval_95"]
    return {**boot, "interval_95": None if intervals is None else
            {k: [_number(low), _number(high)] for k, (low, high) in intervals.items()}}


def to_json(analysis: Analysis) -> str:
    """One JSON object on one line (JSON Lines friendly)."""
    return json.dumps(to_json_dict(analysis), allow_nan=False)


def _excluded_counts(turning) -> dict:
    counts = {}
    for reason, used in zip(turning.excluded_reason, turning.used):
        if not used:
            counts[reason or "other"] = counts.get(reason or "other", 0) + 1
    return counts


def csv_columns(bootstrap=False) -> tuple:
    """The CSV columns, with the bootstrap intervals' when ``bootstrap``."""
    return CSV_COLUMNS + (BOOTSTRAP_CSV_COLUMNS if bootstrap else ())


def csv_header(bootstrap=False) -> str:
    return ",".join(csv_columns(bootstrap)) + "\n"


def to_csv_row(analysis: Analysis, bootstrap=False) -> str:
    """One CSV line in the order of :func:`csv_columns`."""
    data = to_json_dict(analysis)
    params = data.get("params") or {}
    q = data.get("q") or {}
    row = {"source": data["source"], "status": data["status"], "model": data.get("model"),
           "period": data.get("period"), "q_initial": q.get("initial"), "q_final": q.get("final"),
           "q_initial_stderr": q.get("initial_stderr"), "q_final_stderr": q.get("final_stderr"),
           "turning_points": data.get("turning_points"), "error": data.get("error"),
           "domain": data.get("domain"), "units": data.get("params_units"),
           "method": data.get("method"), "resolved": data.get("resolved"),
           "reduced_chi_square": (data.get("fit") or {}).get("reduced_chi_square"),
           "warnings": "; ".join(data.get("warnings") or ()) or None, "run": data.get("run"),
           "signal_unit": data.get("signal_unit")}
    for k, unit in (data.get("coefficient_units") or dict.fromkeys(TERMS + ("y0",))).items():
        row[f"{k}_unit"] = unit
    for k in ("y0", "a", "b", "c"):
        row[k] = (params.get(k) or {}).get("value")
        row[f"{k}_stderr"] = (params.get(k) or {}).get("stderr")
    intervals = (data.get("bootstrap") or {}).get("interval_95") or {}
    for column in BOOTSTRAP_CSV_COLUMNS:
        name, _, end = column.rpartition("_boot_")
        bounds = intervals.get(name)
        row[column] = None if bounds is None else bounds[0 if end == "low" else 1]
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(
        [_csv_cell(row[k]) for k in csv_columns(bootstrap)])
    return buffer.getvalue()


TURNING_POINT_COLUMNS = ("source", "t", "amplitude", "sigma", "used", "excluded_reason",
                         "envelope")


def turning_points_header() -> str:
    return ",".join(TURNING_POINT_COLUMNS) + "\n"


def turning_points_table(analysis: Analysis) -> list[tuple]:
    """One row per turning point of the record, in :data:`TURNING_POINT_COLUMNS` order
    (used or left out, with the reason; the fitted envelope at the used ones)."""
    turning, fit = analysis.turning, analysis.fit
    if turning is None:
        return []
    amplitude, sigma = list(turning.y), list(turning.sigma)
    envelope = [None] * len(turning.t)
    used = [i for i, flag in enumerate(turning.used) if flag]
    # The fit's own amplitudes where it converted them (a pendulum's peak angles).
    for name, column in (("y", amplitude), ("sigma", sigma), ("y_fit", envelope)):
        values = getattr(fit, name, None)
        if values is not None and len(values) == len(used):
            for i, value in zip(used, values):
                column[i] = value
    return [(analysis.source, float(turning.t[i]), _number(amplitude[i]), _number(sigma[i]),
             bool(turning.used[i]), turning.excluded_reason[i] or None, _number(envelope[i]))
            for i in range(len(turning.t))]


def turning_points_rows(analysis: Analysis) -> str:
    """:func:`turning_points_table` as CSV lines; "" when there are none."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    for row in turning_points_table(analysis):
        writer.writerow([_csv_cell(v) for v in row])
    return buffer.getvalue()


def _csv_cell(value):
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else value


def _format(value, error=None):
    if value is None:
        return "-"
    if error is None:
        return f"{value:.6g}"
    return f"{value:.6g} +- {error:.2g}"


def _with_error(value, error):
    """``value +- error``, the value rounded to the error's second significant digit."""
    if error is None or not math.isfinite(error) or error <= 0:
        return f"{value:.5g}"
    decimals = max(0, 1 - math.floor(math.log10(error)))
    return f"{value:.{decimals}f} +- {error:.2g}"


def _short(value):
    """3.1e5 rather than 3.1e+05: a bound read at a glance."""
    mantissa, _, exponent = f"{value:.2g}".partition("e")
    return f"{mantissa}e{int(exponent)}" if exponent else mantissa


_B_NAMES = {"velocity": "viscous", "cannot tell": "viscous or hysteretic"}


def _b_name(form):
    """What b is called: viscous where the velocity forms were fitted, either where the
    record cannot tell the forms apart, else hysteretic."""
    return _B_NAMES.get(form, REGIME_NAMES["b"])


def _regime_name(term, fit):
    return _b_name(getattr(fit, "damping_form", None)) if term == "b" else REGIME_NAMES[term]


def _damping_form_lines(data) -> list[str]:
    """The physical form of the damping forces, and their coefficients (per unit mass)."""
    form = data.get("damping_form")
    if form is None:
        return []
    lines = [f"  damping form:    {form} ({data['damping_form_reason']})"]
    signal_unit = data.get("signal_unit") or "U"
    for name, entry in data["physical"].items():
        lines.append(f"    {entry['force']:24s} {name} = "
                     f"{_format(entry['value'], entry['stderr'])} "
                     f"{entry['unit'].replace('U', signal_unit)}")
    return lines


def _regimes_lines(fit) -> list[str]:
    """The verdict and the evidence for each kept term."""
    if fit.model == POWER:
        v, e = fit.values, fit.stderr
        return [f"  model:           power law dy/dt = -k*y^n, n = {_format(v['n'], e['n'])}, "
                f"k = {_format(v['k'], e['k'])}"]
    how = ("forced with `model`" if fit.forced else
           f"by {fit.criterion.upper()} and likelihood-ratio test")
    if fit.model == NONE:
        lines = [f"  regimes present: none: no damping detected ({how})"]
    elif not fit.resolved and len(fit.model) == 1:
        lines = [f"  regimes present: not resolved: reported as constant Q (model b, {how})"]
    else:
        present = ", ".join(_regime_name(k, fit) for k in fit.model)
        resolved = "" if fit.resolved else "; not resolved"
        lines = [f"  regimes present: {present} (model {fit.model}, {how}{resolved})"]
    for k, p in fit.lrt_p_values.items():
        lines.append(f"    {_regime_name(k, fit):11s} term: p = {p:.2g} (chance of so large a gain in "
                     "fit by noise alone)")
    return lines


def _q_line(fit) -> str | None:
    q = fit.q_summary
    if q and q.get("initial_stderr") is not None:
        parts = [f"{k} {_with_error(q[k], q[f'{k}_stderr'])}" for k in _Q_KEYS]
        return "  Q:               " + ", ".join(parts)
    if q:
        return "  Q:               " + ", ".join(f"{k} {q[k]:.5g}" for k in _Q_KEYS)
    bound = getattr(fit, "q_lower_bound", None)
    return f"  Q:               Q > {_short(bound)} (95 %)" if bound is not None else None


def _bootstrap_lines(fit) -> list[str]:
    boot = getattr(fit, "bootstrap", None)
    if not boot or not boot["n"]:
        return []
    how = ("model fixed" if boot["selection"] == "fixed" else
           "model chosen anew in each: " + ", ".join(
               f"{m} {100 * share:.0f} %" for m, share in boot["models"].items()))
    lines = [f"  bootstrap:       {boot['n']} resamples ({how}); 95 % intervals:"]
    for name, (low, high) in boot["interval_95"].items():
        lines.append(f"    {name:28s} [{low:.5g}, {high:.5g}]")
    return lines


def _fit_lines(fit) -> list[str]:
    """Goodness of fit with the chosen model's scores, and the kept parameters'
    correlations."""
    chosen = next((c for c in fit.candidates if c.model == fit.model), None)
    n_points = getattr(fit, "n_points", None)
    scores = (f" (chi-square {chosen.chi_square:.4g} on {n_points - chosen.n_params} "
              f"degrees of freedom, AICc {chosen.aicc:.4g}, BIC {chosen.bic:.4g})"
              if chosen is not None and n_points else "")
    lines = [f"  fit:             rms {fit.rms:.3g}, reduced chi-square "
             f"{fit.reduced_chi_square:.3g}{scores}"]
    correlation = getattr(fit, "correlation", None) or {}
    if correlation:
        lines.append("  correlations:    " + ", ".join(
            f"{pair.replace(',', '-')} {r:+.3f}" for pair, r in correlation.items()))
    return lines


def to_text(analysis: Analysis) -> str:
    """The readable report for a person at a terminal."""
    data = to_json_dict(analysis)
    lines = [f"mcfit report: {analysis.source}"]
    if analysis.status != "ok":
        lines.append(f"  status: error: {analysis.error}")
        return "\n".join(lines) + "\n"
    record, turning, fit = analysis.record, analysis.turning, analysis.fit
    if record is not None:
        source_columns = (f"time = {record.time_column or 'sample index / rate'}, "
                          f"signal = {record.signal_column}")
        lines.append(f"  input:           {record.kind}, columns {source_columns}")
    excluded = data.get("turning_points_excluded") or {}
    excluded_text = ", ".join(f"{n} {reason}" for reason, n in excluded.items()) or "none"
    lines.append(f"  turning points:  {turning.count} used; left out: {excluded_text}")
    if data["period"] is not None:
        drift = data.get("period_drift")
        drift_text = (f", changes by {100 * drift:+.2f} % from smallest to largest amplitude"
                      if drift is not None else "")
        lines.append(f"  period:          {data['period']:.6g} {'s' if fit.domain == 'time' else 'cycle'}"
                     f"{drift_text}")
    if data.get("method_reason"):
        lines.append(f"  method:          {data['method'].replace('-', ' ')} "
                     f"({data['method_reason']})")
    pendulum = data.get("pendulum")
    if pendulum is not None:
        period0 = pendulum["small_angle_period"]
        period0_error = pendulum["small_angle_period_stderr"]
        period0_text = (f"; small-angle period {_with_error(period0, period0_error)} s"
                        if period0 is not None else "")
        lines.append(f"  pendulum:        large-swing correction applied (angle in "
                     f"{pendulum['angle_unit']}{period0_text}); coefficients are small-angle "
                     "values, Q = 2*pi*E/(energy lost per cycle)")
    lines += _damping_form_lines(data)
    lines += _regimes_lines(fit)
    params = data["params"]
    unit = data.get("params_units", "per second")
    lines.append(f"  parameters ({unit}):")
    at = f"{fit.t0:.4g} s" if fit.domain == "time" else f"n = {fit.t0:.4g}"
    labels = {"y0": f"y0 (amplitude at {at})",
              "a": "a (fluid)", "b": f"b ({_b_name(data.get('damping_form'))})",
              "c": "c (Coulomb)"}
    units = data["coefficient_units"]
    for k in ("y0",) if fit.model == POWER else ("y0", "a", "b", "c"):
        value = _format(params[k]["value"], params[k]["stderr"])
        lines.append(f"    {labels[k]:28s} {value:24s} {units[k]}")
    if data["signal_unit"] is None:
        lines.append("    (U: the signal's unit, not named in the record)")
    per_cycle = data.get("params_per_cycle")
    if per_cycle is not None and unit == "per second" and fit.model not in (POWER, NONE):
        lines.append("  per cycle:       " + ", ".join(
            f"{k}*T = {per_cycle[k]['value']:.4g}" for k in TERMS if per_cycle[k]["value"]))
    q_line = _q_line(fit)
    if q_line:
        lines.append(q_line)
    lines += _fit_lines(fit)
    ranked = sorted(fit.candidates, key=lambda c: getattr(c, fit.criterion))
    if len(ranked) > 1:
        best = getattr(ranked[0], fit.criterion)
        scores = ", ".join(f"{c.model} {'~' if c.estimated else ''}"
                           f"{getattr(c, fit.criterion) - best:+.1f}" for c in ranked)
        lines.append(f"  candidates:      delta {fit.criterion.upper()}: {scores}"
                     + (" (~ estimated, far from contention)"
                        if any(c.estimated for c in ranked) else ""))
    lines += _bootstrap_lines(fit)
    for note in data.get("notes", []):
        lines.append(f"  note: {note}")
    for warning in analysis.warnings:
        lines.append(f"  warning: {warning}")
    return "\n".join(lines) + "\n"


def runs_summary(source: str, analyses) -> str:
    """Mean and spread of each coefficient and of Q over the fitted runs of one file, with
    the typical stderr of one run: a spread well above it is a difference between runs.
    A term left out of a run's model counts as 0 there."""
    fitted = [a for a in analyses if a.status == "ok" and a.fit is not None]
    lines = [f"runs of {source}: {len(fitted)} of {len(analyses)} fitted"]
    if not fitted:
        return lines[0] + "\n"
    models = Counter(a.fit.model for a in fitted)
    unit = _params_in_time_units(fitted[0])[2]
    lines[0] += (f"; models {', '.join(f'{m} in {n}' for m, n in models.most_common())}; "
                 f"mean +- sd over runs (sem; median stderr of a run), {unit}:")
    columns = {k: [_law_values(a.fit) for a in fitted] for k in ("y0",) + TERMS}
    units = _units_of(fitted[0])[1]
    for key, pairs in columns.items():
        lines.append(_spread_line(key, [v[key] for v, _ in pairs], [e[key] for _, e in pairs],
                                  units[key]))
    q = [(a.fit.q_summary or {}) for a in fitted]
    lines.append(_spread_line("Q initial", [d.get("initial") for d in q],
                              [d.get("initial_stderr") for d in q]))
    return "\n".join(lines) + "\n"


def _spread_line(name, values, errors, unit=None):
    values = [v for v in values if v is not None and math.isfinite(v)]
    errors = [e for e in errors if e is not None and math.isfinite(e)]
    if not values:
        return f"  {name:<10} -"
    if not any(values):
        return f"  {name:<10} 0 in every run (not detected)"
    mean = statistics.fmean(values)
    sd = statistics.stdev(values) if len(values) > 1 else float("nan")
    sem = sd / math.sqrt(len(values))
    typical = f"{statistics.median(errors):.2g}" if errors else "-"
    unit = f" {unit}" if unit else ""
    return (f"  {name:<10} {mean:.6g} +- {sd:.2g}{unit} (sem {sem:.2g}; run stderr {typical}; "
            f"{len(values)} runs)")
