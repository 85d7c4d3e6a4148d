"""Text, JSON and CSV forms of an :class:`mcfit.analysis.Analysis` (strings only, no I/O)."""

from __future__ import annotations

import csv
import io
import json
import math

from mcfit import decay
from mcfit.analysis import Analysis
from mcfit.fit import REGIME_NAMES, TERMS

__all__ = ["CSV_COLUMNS", "to_json_dict", "to_json", "csv_header", "to_csv_row", "to_text"]

CSV_COLUMNS = ("source", "status", "model", "y0", "y0_stderr", "a", "a_stderr", "b", "b_stderr",
               "c", "c_stderr", "period", "q_initial", "q_final", "turning_points", "error")


def _number(value):
    """float, or None for missing/NaN/inf (JSON has no NaN)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _params_in_time_units(analysis: Analysis):
    """(values, stderrs, unit note). In the cycle domain the record gives no period in
    seconds (its "period" is 1 cycle), so the coefficients stay per cycle."""
    fit, record = analysis.fit, analysis.record
    if fit.domain == "cycle":
        unit = "per cycle"
    else:
        time_unit = getattr(record, "time_unit", None) or "s"
        unit = "per second" if time_unit == "s" else f"per {time_unit}"  # an unknown unit
    return dict(fit.values), dict(fit.stderr), unit


def _params_per_cycle(analysis: Analysis):
    """Coefficients per cycle (a*T, b*T, c*T, as in Fig. 20.20), or None without a period."""
    fit, turning = analysis.fit, analysis.turning
    if fit.domain == "cycle":
        return {k: {"value": _number(fit.values[k]), "stderr": _number(fit.stderr[k])}
                for k in TERMS}
    period = _number(turning.period) if turning is not None else None
    if period is None:
        return None
    values = decay.to_cycle_units(*(fit.values[k] for k in TERMS), period)
    errors = [None if fit.stderr[k] is None else fit.stderr[k] * period for k in TERMS]
    return {k: {"value": _number(v), "stderr": _number(e)}
            for k, v, e in zip(TERMS, values, errors)}


def to_json_dict(analysis: Analysis) -> dict:
    """The machine-readable contract: keys may be added, never renamed."""
    out = {"source": analysis.source, "status": analysis.status, "error": analysis.error}
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
        out["regimes"] = dict(fit.regimes)
        out["params"] = {k: {"value": _number(values[k]), "stderr": _number(stderr[k])}
                         for k in ("y0", "a", "b", "c")}
        out["params_units"] = units
        out["params_per_cycle"] = _params_per_cycle(analysis)
        out["t0"] = _number(fit.t0)  # time (or cycle) of the first turning point used, where y = y0
        q = fit.q_summary or {}
        out["q"] = {k: _number(q.get(k)) for k in ("initial", "final", "min", "max")}
        out["fit"] = {"criterion": fit.criterion, "forced": fit.forced, "rms": _number(fit.rms),
                      "reduced_chi_square": _number(fit.reduced_chi_square),
                      "lrt_p_values": {REGIME_NAMES.get(k, k): _number(p)
                                       for k, p in fit.lrt_p_values.items()},
                      "noise_from_residuals": fit.noise_from_residuals}
        out["candidates"] = [{"model": c.model, "n_params": c.n_params,
                              "chi_square": _number(c.chi_square), "aicc": _number(c.aicc),
                              "bic": _number(c.bic), "converged": c.success}
                             for c in fit.candidates]
        if fit.power_law is not None:
            out["power_law"] = {k: _number(v) for k, v in fit.power_law.items()}
        if fit.bootstrap is not None:
            out["bootstrap"] = fit.bootstrap
        out["warnings"] = list(analysis.warnings)
    if record is not None:
        out["columns"] = {"time": record.time_column, "signal": record.signal_column}
        out["input"] = record.kind
    if turning is not None:
        out["turning_points_excluded"] = _excluded_counts(turning)
        out["period_drift"] = _number(turning.period_drift)
        out["notes"] = list(getattr(record, "notes", ())) + list(turning.notes)
    elif record is not None:
        out["notes"] = list(record.notes)
    return out


def to_json(analysis: Analysis) -> str:
    """One JSON object on one line (JSON Lines friendly)."""
    return json.dumps(to_json_dict(analysis), allow_nan=False)


def _excluded_counts(turning) -> dict:
    counts = {}
    for reason, used in zip(turning.excluded_reason, turning.used):
        if not used:
            counts[reason or "other"] = counts.get(reason or "other", 0) + 1
    return counts


def csv_header() -> str:
    return ",".join(CSV_COLUMNS) + "\n"


def to_csv_row(analysis: Analysis) -> str:
    """One CSV line in the order of :data:`CSV_COLUMNS`."""
    data = to_json_dict(analysis)
    params = data.get("params") or {}
    q = data.get("q") or {}
    row = {"source": data["source"], "status": data["status"], "model": data.get("model"),
           "period": data.get("period"), "q_initial": q.get("initial"), "q_final": q.get("final"),
           "turning_points": data.get("turning_points"), "error": data.get("error")}
    for k in ("y0", "a", "b", "c"):
        row[k] = (params.get(k) or {}).get("value")
        row[f"{k}_stderr"] = (params.get(k) or {}).get("stderr")
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(
        ["" if row[k] is None else (repr(row[k]) if isinstance(row[k], float) else row[k])
         for k in CSV_COLUMNS])
    return buffer.getvalue()


def _format(value, error=None):
    if value is None:
        return "-"
    if error is None:
        return f"{value:.6g}"
    return f"{value:.6g} +- {error:.2g}"


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
    if fit.model == "power":
        p = fit.power_law
        lines.append(f"  model:           power law dy/dt = -k*y^n, n = {_format(p['n'], p['n_stderr'])}, "
                     f"k = {_format(p['k'], p.get('k_stderr'))}")
    else:
        present = [REGIME_NAMES[k] for k in fit.model]
        how = ("forced with --model" if fit.forced else
               f"by {fit.criterion.upper()} and likelihood-ratio test")
        lines.append(f"  regimes present: {', '.join(present)} (model {fit.model}, {how})")
        for k, p in fit.lrt_p_values.items():
            if len(fit.model) > 1:
                lines.append(f"    {REGIME_NAMES[k]:11s} term: p = {p:.2g} that the record "
                             "does without it")
    params = data["params"]
    unit = data.get("params_units", "per second")
    lines.append(f"  parameters ({unit}):")
    at = f"{fit.t0:.4g} s" if fit.domain == "time" else f"n = {fit.t0:.4g}"
    labels = {"y0": f"y0 (amplitude at {at})",
              "a": "a (fluid)", "b": "b (hysteretic)", "c": "c (Coulomb)"}
    for k in ("y0",) if fit.model == "power" else ("y0", "a", "b", "c"):
        lines.append(f"    {labels[k]:28s} {_format(params[k]['value'], params[k]['stderr'])}")
    per_cycle = data.get("params_per_cycle")
    if per_cycle is not None and unit == "per second" and fit.model != "power":
        lines.append("  per cycle:       " + ", ".join(
            f"{k}*T = {per_cycle[k]['value']:.4g}" for k in TERMS if per_cycle[k]["value"]))
    q = data["q"]
    if q and q["initial"] is not None:
        lines.append(f"  Q:               initial {q['initial']:.5g}, final {q['final']:.5g}, "
                     f"min {q['min']:.5g}, max {q['max']:.5g}")
    lines.append(f"  fit:             rms {fit.rms:.3g}, reduced chi-square "
                 f"{fit.reduced_chi_square:.3g}")
    ranked = sorted(fit.candidates, key=lambda c: getattr(c, fit.criterion))
    if len(ranked) > 1:
        best = getattr(ranked[0], fit.criterion)
        scores = ", ".join(f"{c.model} {getattr(c, fit.criterion) - best:+.1f}" for c in ranked)
        lines.append(f"  candidates:      delta {fit.criterion.upper()}: {scores}")
    for note in data.get("notes", []):
        lines.append(f"  note: {note}")
    for warning in analysis.warnings:
        lines.append(f"  warning: {warning}")
    return "\n".join(lines) + "\n"
