"""Text, JSON and CSV forms of a record's results, from their plain data: the dicts of
:meth:`mcfit.analysis.Analysis.to_dict` (strings only, no I/O; no result class imported)."""

from __future__ import annotations

import csv
import io
import json
import math
import statistics
from collections import Counter

from mcfit.fit.models import NONE, POWER, REGIME_NAMES, TERMS, regime_name
from mcfit.plain import period_resolution, time_text
from mcfit.record import coefficient_units

__all__ = ["CSV_COLUMNS", "BOOTSTRAP_CSV_COLUMNS", "LAST_CSV_COLUMNS", "TURNING_POINT_COLUMNS",
           "csv_columns", "coefficient_units", "turning_points_header", "turning_points_rows", "to_json",
           "csv_header", "csv_record", "to_csv_row", "to_text", "runs_summary"]

CSV_COLUMNS = ("source", "status", "model", "y0", "y0_stderr", "a", "a_stderr", "b", "b_stderr",
               "c", "c_stderr", "period", "q_initial", "q_final", "turning_points", "error",
               "q_initial_stderr", "q_final_stderr", "domain", "units", "method", "resolved",
               "reduced_chi_square", "warnings", "run", "signal_unit", "y0_unit", "a_unit",
               "b_unit", "c_unit")
# Appended with bootstrap intervals: the 95 % interval of each parameter and of Q.
BOOTSTRAP_CSV_COLUMNS = tuple(f"{k}_boot_{end}" for k in ("y0", "a", "b", "c", "q_initial")
                              for end in ("low", "high"))
# Appended last, after the bootstrap intervals where they are (columns are only appended,
# so that a script's column numbers hold): the version of mcfit that wrote the row.
LAST_CSV_COLUMNS = ("mcfit_version",)
_Q_KEYS = ("initial", "final", "min", "max")
_TERM_OF = {name: term for term, name in REGIME_NAMES.items()}


def _plain(result, detail=False) -> dict:
    """The plain data of a result: a dict as given, or the ``to_dict`` of an object that
    has one (an :class:`mcfit.analysis.Analysis`)."""
    to_dict = getattr(result, "to_dict", None)
    return result if to_dict is None else to_dict(detail=detail)


def to_json(data) -> str:
    """One JSON object on one line (JSON Lines friendly): ``data`` without its
    ``detail``."""
    data = _plain(data)
    return json.dumps({k: v for k, v in data.items() if k != "detail"}, allow_nan=False)


def csv_columns(bootstrap=False) -> tuple:
    """The CSV columns, with the bootstrap intervals' when ``bootstrap``, then
    :data:`LAST_CSV_COLUMNS`."""
    return CSV_COLUMNS + (BOOTSTRAP_CSV_COLUMNS if bootstrap else ()) + LAST_CSV_COLUMNS


def csv_header(bootstrap=False) -> str:
    return ",".join(csv_columns(bootstrap)) + "\n"


def csv_record(data, bootstrap=False) -> dict:
    """The CSV row of ``data`` as ``{column: plain value}`` (None where empty), in the
    order of :func:`csv_columns`."""
    data = _plain(data)
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
           "signal_unit": data.get("signal_unit"), "mcfit_version": data.get("mcfit_version")}
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
    return {k: row[k] for k in csv_columns(bootstrap)}


def to_csv_row(data, bootstrap=False) -> str:
    """One CSV line in the order of :func:`csv_columns`."""
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(
        [_csv_cell(v) for v in csv_record(data, bootstrap).values()])
    return buffer.getvalue()


TURNING_POINT_COLUMNS = ("source", "t", "amplitude", "sigma", "used", "excluded_reason",
                         "envelope")


def turning_points_header() -> str:
    return ",".join(TURNING_POINT_COLUMNS) + "\n"


def turning_points_rows(rows) -> str:
    """Turning points as CSV lines, each row a dict of :data:`TURNING_POINT_COLUMNS`
    (:meth:`mcfit.analysis.Analysis.turning_point_table`); "" when there are none."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    for row in rows:
        writer.writerow([_csv_cell(row[k]) for k in TURNING_POINT_COLUMNS])
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
    if value is None:
        return "-"
    if error is None or not math.isfinite(error) or error <= 0:
        return f"{value:.5g}"
    decimals = max(0, 1 - math.floor(math.log10(error)))
    return f"{value:.{decimals}f} +- {error:.2g}"


def _short(value):
    """3.1e5 rather than 3.1e+05: a bound read at a glance."""
    mantissa, _, exponent = f"{value:.2g}".partition("e")
    return f"{mantissa}e{int(exponent)}" if exponent else mantissa


def _regime_name(term, data):
    return regime_name(term, data.get("damping_form"))


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


def _regimes_lines(data) -> list[str]:
    """The verdict and the evidence for each kept term."""
    model, fit = data["model"], data["fit"]
    if model == POWER:
        law = data["power_law"]
        return [f"  model:           power law dy/dt = -k*y^n, "
                f"n = {_format(law['n'], law['n_stderr'])}, "
                f"k = {_format(law['k'], law['k_stderr'])}"]
    how = ("forced with `model`" if fit["forced"] else
           f"by {fit['criterion'].upper()} and likelihood-ratio test")
    if model == NONE:
        lines = [f"  regimes present: none: no damping detected ({how})"]
    elif not data["resolved"] and len(model) == 1:
        lines = [f"  regimes present: not resolved: reported as constant Q (model b, {how})"]
    else:
        present = ", ".join(_regime_name(k, data) for k in model)
        resolved = "" if data["resolved"] else "; not resolved"
        lines = [f"  regimes present: {present} (model {model}, {how}{resolved})"]
    for name, p in fit["lrt_p_values"].items():
        lines.append(f"    {_regime_name(_TERM_OF[name], data):11s} term: p = {_g(p, '.2g')} "
                     "(chance of so large a gain in fit by noise alone)")
    return lines


def _g(value, spec):
    """``value`` in the format ``spec``, or "-" where it is missing (not finite)."""
    return "-" if value is None else format(value, spec)


def _q_line(data) -> str | None:
    q = data["q"]
    if q["min"] is not None:  # Q is known (its extremes are over its finite values)
        errors = q["initial_stderr"] is not None
        parts = [f"{k} {_with_error(q[k], q[f'{k}_stderr'] if errors else None)}"
                 for k in _Q_KEYS]
        return "  Q:               " + ", ".join(parts)
    bound = q["lower_bound"]
    return f"  Q:               Q > {_short(bound)} (95 %)" if bound is not None else None


def _bootstrap_lines(data) -> list[str]:
    boot = data.get("bootstrap")
    if not boot or not boot["n"]:
        return []
    how = ("model fixed" if boot["selection"] == "fixed" else
           "model chosen anew in each: " + ", ".join(
               f"{m} {100 * share:.0f} %" for m, share in boot["models"].items()))
    seed = f", seed {boot['seed']}" if boot.get("seed") is not None else ""
    lines = [f"  bootstrap:       {boot['n']} resamples ({how}){seed}; 95 % intervals:"]
    for name, (low, high) in boot["interval_95"].items():
        lines.append(f"    {name:28s} [{_g(low, '.5g')}, {_g(high, '.5g')}]")
    return lines


def _fit_lines(data, detail) -> list[str]:
    """Goodness of fit with the chosen model's scores, and the kept parameters'
    correlations."""
    fit = data["fit"]
    chosen = next((c for c in data["candidates"] if c["model"] == data["model"]), None)
    n_points = detail.get("n_points")
    scores = (f" (chi-square {_g(chosen['chi_square'], '.4g')} on "
              f"{n_points - chosen['n_params']} degrees of freedom, "
              f"AICc {_g(chosen['aicc'], '.4g')}, BIC {_g(chosen['bic'], '.4g')})"
              if chosen is not None and n_points else "")
    lines = [f"  fit:             rms {_g(fit['rms'], '.3g')}, reduced chi-square "
             f"{_g(fit['reduced_chi_square'], '.3g')}{scores}"]
    correlation = detail.get("correlation") or {}
    if correlation:
        lines.append("  correlations:    " + ", ".join(
            f"{pair.replace(',', '-')} {_g(r, '+.3f')}" for pair, r in correlation.items()))
    return lines


def _candidates_line(data) -> str | None:
    """The candidates' criterion relative to the best (a missing one ranks last)."""
    criterion = data["fit"]["criterion"]

    def score(candidate):
        value = candidate[criterion]
        return math.inf if value is None else value

    ranked = sorted(data["candidates"], key=score)
    if len(ranked) < 2:
        return None
    best = ranked[0][criterion]
    scores = ", ".join(f"{c['model']} " + ("-" if c[criterion] is None or best is None
                                           else ("~" if c.get("estimated") else "")
                                           + f"{c[criterion] - best:+.1f}")
                       for c in ranked)
    estimated = any(c.get("estimated") for c in ranked)
    return (f"  candidates:      delta {criterion.upper()}: {scores}"
            + (" (~ estimated, not fitted: it cannot change the choice)" if estimated else ""))


def to_text(data) -> str:
    """The readable report for a person at a terminal, from :meth:`Analysis.to_dict`'s
    data with its ``detail``."""
    data = _plain(data, detail=True)
    lines = [f"mcfit report: {data['source']}"]
    if data["status"] != "ok":
        lines.append(f"  status: error: {data['error']}")
        return "\n".join(lines) + "\n"
    detail = data.get("detail") or {}
    domain = detail.get("domain", data.get("domain"))
    if "columns" in data:
        columns = data["columns"]
        source_columns = (f"time = {columns['time'] or 'sample index / rate'}, "
                          f"signal = {columns['signal']}")
        lines.append(f"  input:           {data['input']}, columns {source_columns}")
    origin = data.get("time_origin")
    if origin:
        zone = f" = {origin['utc']}" if origin.get("utc") else ""
        lines.append(f"  time origin:     t = 0 s is {origin['column']} = {origin['value']}"
                     f"{zone} ({origin['clock']}); times are seconds from there")
    excluded = data.get("turning_points_excluded") or {}
    excluded_text = ", ".join(f"{n} {reason}" for reason, n in excluded.items()) or "none"
    lines.append(f"  turning points:  {data['turning_points']} used; left out: {excluded_text}")
    if data["period"] is not None:
        drift = data.get("period_drift")
        drift_text = (f", changes by {100 * drift:+.2f} % from smallest to largest amplitude"
                      if drift is not None else "")
        lines.append(f"  period:          {data['period']:.6g} "
                     f"{'s' if domain == 'time' else 'cycle'}{drift_text}")
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
    lines += _regimes_lines(data)
    params = data["params"]
    unit = data.get("params_units", "per second")
    lines.append(f"  parameters ({unit}):")
    t0 = time_text(data["t0"], period_resolution(data["period"]), digits=4)
    at = f"{t0} s" if domain == "time" else f"n = {t0}"
    labels = {"y0": f"y0 (amplitude at {at})",
              "a": "a (fluid)", "b": f"b ({regime_name('b', data.get('damping_form'))})",
              "c": "c (Coulomb)"}
    units = data["coefficient_units"]
    for k in ("y0",) if data["model"] == POWER else ("y0", "a", "b", "c"):
        value = _format(params[k]["value"], params[k]["stderr"])
        lines.append(f"    {labels[k]:28s} {value:24s} {units[k]}")
    if data["signal_unit"] is None:
        lines.append("    (U: the signal's unit, not named in the record)")
    per_cycle = data.get("params_per_cycle")
    if per_cycle is not None and unit == "per second" and data["model"] not in (POWER, NONE):
        lines.append("  per cycle:       " + ", ".join(
            f"{k}*T = {per_cycle[k]['value']:.4g}" for k in TERMS if per_cycle[k]["value"]))
    q_line = _q_line(data)
    if q_line:
        lines.append(q_line)
    lines += _fit_lines(data, detail)
    candidates = _candidates_line(data)
    if candidates:
        lines.append(candidates)
    lines += _bootstrap_lines(data)
    for note in data.get("notes", []):
        lines.append(f"  note: {note}")
    for warning in data["warnings"]:
        lines.append(f"  warning: {warning}")
    return "\n".join(lines) + "\n"


def runs_summary(source: str, results) -> str:
    """Mean and spread of each coefficient and of Q over the fitted runs of one file (each
    result :meth:`Analysis.to_dict`'s data), with the typical stderr of one run: a spread
    well above it is a difference between runs. A term left out of a run's model counts
    as 0 there."""
    results = [_plain(result) for result in results]
    fitted = [r for r in results if r["status"] == "ok" and r["model"] is not None]
    lines = [f"runs of {source}: {len(fitted)} of {len(results)} fitted"]
    if not fitted:
        return lines[0] + "\n"
    models = Counter(r["model"] for r in fitted)
    lines[0] += (f"; models {', '.join(f'{m} in {n}' for m, n in models.most_common())}; "
                 f"mean +- sd over runs (sem; median stderr of a run), "
                 f"{fitted[0]['params_units']}:")
    units = fitted[0]["coefficient_units"]
    for key in ("y0",) + TERMS:
        lines.append(_spread_line(key, [r["params"][key]["value"] for r in fitted],
                                  [r["params"][key]["stderr"] for r in fitted], units[key]))
    lines.append(_spread_line("Q initial", [r["q"]["initial"] for r in fitted],
                              [r["q"]["initial_stderr"] for r in fitted]))
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
