"""The fitting section of ``mcfit bench``: on the same noisy records, the RMSE and bias of
a, b, c in units of the waveform Cramer-Rao bound (docs/theory.md section 8,
:func:`mcfit.bounds.waveform_crlb`) and the time per record, for mcfit (turning points then
:func:`mcfit.fit.fit_decay`, forced to the true model and with the model it selects), the
log decrement of single-sample peaks (:func:`log_decrement_rate`) and a Hilbert-envelope fit
(:func:`hilbert_envelope_rate`)."""

from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass

import numpy as np

from mcfit.bench.config import (HILBERT_TRIM_PERIODS, QUICK, SAMPLING_OFFSET, BenchConfig,
                                FitScene)
from mcfit.bench.records import fit_record_pair
from mcfit.bounds import waveform_crlb

__all__ = ["log_decrement_rate", "hilbert_envelope_rate", "FitCell", "run_fitting",
           "format_fitting"]


def log_decrement_rate(t, x, period):
    """b (1/s) from single-sample peaks: what is often done today.

    ``x - mean(x)`` is cut into half-periods starting at its first zero crossing; the
    largest ``|x - mean|`` sample of each full half-period is its peak, and ``-slope`` of a
    least-squares line through ``log(peak)`` against the peak's time is b.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s), uniform.
    x : ndarray, shape (n,)
        Signal (U).
    period : float
        The true period (s); given, which favours this method.

    Returns
    -------
    float
        The decay rate b (1/s); NaN with fewer than 3 peaks.
    """
    centred = np.abs(x - np.mean(x))
    crossings = np.flatnonzero(np.diff(np.signbit(x - np.mean(x))))
    if crossings.size == 0:
        return math.nan
    start = t[crossings[0]]
    half_period = 0.5 * period
    window = np.floor((t - start) / half_period).astype(np.int64)
    full = (window >= 0) & (window < np.floor((t[-1] - start) / half_period))
    window, values, times = window[full], centred[full], t[full]
    # The last sample of each window after sorting by (window, value) is that window's peak.
    order = np.lexsort((values, window))
    last = np.flatnonzero(np.diff(window[order], append=np.iinfo(np.int64).max))
    peaks = order[last]
    if peaks.size < 3:
        return math.nan
    slope = np.polyfit(times[peaks], np.log(values[peaks]), 1)[0]
    return float(-slope)


def hilbert_envelope_rate(t, x, period, trim_periods=HILBERT_TRIM_PERIODS):
    """b (1/s) from a line through the logarithm of the Hilbert envelope.

    The envelope is ``|hilbert(x - mean(x))|``; ``trim_periods`` periods are dropped at
    each end, where it is distorted, and ``-slope`` of a least-squares line through its
    logarithm against time is b.

    Parameters
    ----------
    t, x : ndarray, shape (n,)
        Sample times (s, uniform) and signal (U).
    period : float
        Period (s), for the trimming only.
    trim_periods : float, optional
        Periods dropped at each end.

    Returns
    -------
    float
        The decay rate b (1/s); NaN if the trimmed record is too short.
    """
    from scipy.signal import hilbert

    envelope = np.abs(hilbert(x - np.mean(x)))
    keep = (t >= t[0] + trim_periods * period) & (t <= t[-1] - trim_periods * period)
    keep &= envelope > 0
    if np.count_nonzero(keep) < 3:
        return math.nan
    return float(-np.polyfit(t[keep], np.log(envelope[keep]), 1)[0])


def _mcfit_estimates(t, x, model):
    """mcfit on one record: turning points, then the forced and the selected fit.

    Returns a dict with, for "forced" and "selected", the coefficients (dict), standard
    errors (dict), chosen model and seconds (turning points included); None on failure.
    """
    from mcfit.analysis import fit_turning_points
    from mcfit.errors import McfitError
    from mcfit.turning import find_turning_points

    start = time.perf_counter()
    try:
        turning = find_turning_points(t, x)
    except McfitError:
        return {"forced": None, "selected": None}
    turning_seconds = time.perf_counter() - start
    out = {}
    for name, forced in (("forced", model), ("selected", None)):
        start = time.perf_counter()
        try:
            fit = fit_turning_points(turning, model=forced)
        except McfitError:
            out[name] = None
            continue
        seconds = turning_seconds + time.perf_counter() - start
        out[name] = None if fit.status != "ok" else {
            "values": dict(fit.values), "stderr": dict(fit.stderr), "model": fit.model,
            "seconds": seconds}
    return out


@dataclass(frozen=True)
class FitCell:
    """Statistics of one method on one (scene, SNR, samples per cycle) cell.

    ``rmse_ratio`` and ``bias_ratio`` map a coefficient letter to RMSE/CRLB and
    mean(error)/CRLB; ``stderr_ratio`` to mean(reported stderr)/RMSE (mcfit only);
    ``model_right`` is the number of records whose selected model is the true one.
    """

    scene: str
    snr: float
    samples_per_cycle: float
    method: str
    crlb: dict
    rmse_ratio: dict
    bias_ratio: dict
    stderr_ratio: dict
    milliseconds: float
    records: int
    failed: int
    model_right: int | None = None


def _cell_statistics(scene, snr, spc, method, crlb, estimates, seconds, stderr=None,
                     right=None):
    """Reduce the per-record estimates of one method to a :class:`FitCell`."""
    truth = scene.values
    letters = list(crlb)
    ok = [e for e in estimates if e is not None and all(math.isfinite(e[k]) for k in letters)]
    rmse, bias, se_ratio = {}, {}, {}
    for k in letters:
        errors = np.array([e[k] - truth[k] for e in ok])
        if errors.size:
            rmse[k] = float(np.sqrt(np.mean(errors**2)) / crlb[k])
            bias[k] = float(np.mean(errors) / crlb[k])
            if stderr is not None:
                reported = [s[k] for s in stderr if s is not None and s.get(k) is not None]
                if reported:
                    se_ratio[k] = float(np.mean(reported) / (rmse[k] * crlb[k]))
    milliseconds = 1e3 * float(np.mean(seconds)) if seconds else math.nan
    return FitCell(scene.name, snr, spc, method, dict(crlb), rmse, bias, se_ratio,
                   milliseconds, len(estimates), len(estimates) - len(ok), right)


def _run_cell(scene: FitScene, snr, nominal_spc, config: BenchConfig, cell_seed):
    """All methods on the same ``config.repeats`` records of one cell."""
    rng = np.random.default_rng(cell_seed)
    spc = nominal_spc + SAMPLING_OFFSET
    per_method = {name: ([], []) for name in ("forced", "selected", "log", "hilbert")}
    stderrs, right, variances = [], 0, []
    for repeat in range(config.repeats):
        if repeat % 2 == 0:  # antithetic pairs: the second record negates the noise
            t, x, mirrored, phase, sigma_x = fit_record_pair(scene, snr, spc, rng)
            bound = waveform_crlb(t, scene.y0, scene.a, scene.b, scene.c, scene.period,
                                  sigma_x, scene.model, phase=phase)
        else:
            x = mirrored
        variances.append({k: v**2 for k, v in bound.items()})
        mcfit = _mcfit_estimates(t, x, scene.model)
        for name in ("forced", "selected"):
            result = mcfit[name]
            per_method[name][0].append(None if result is None else result["values"])
            if result is not None:
                per_method[name][1].append(result["seconds"])
        stderrs.append(None if mcfit["forced"] is None else mcfit["forced"]["stderr"])
        right += mcfit["selected"] is not None and mcfit["selected"]["model"] == scene.model
        if scene.model == "b":
            for name, function in (("log", log_decrement_rate), ("hilbert", hilbert_envelope_rate)):
                start = time.perf_counter()
                rate = function(t, x, scene.period)
                per_method[name][1].append(time.perf_counter() - start)
                per_method[name][0].append({"b": rate})
    # The RMSE over records of random phase is bounded by the root of the mean bound**2.
    crlb = {k: math.sqrt(statistics.fmean(v[k] for v in variances)) for k in scene.model}
    labels = {"forced": f"mcfit ({scene.model} forced)", "selected": "mcfit (selected)",
              "log": "log decrement", "hilbert": "Hilbert envelope"}
    cells = [
        _cell_statistics(scene, snr, spc, labels["forced"], crlb, *per_method["forced"],
                         stderr=stderrs),
        _cell_statistics(scene, snr, spc, labels["selected"], crlb, *per_method["selected"],
                         right=right),
    ]
    if scene.model == "b":
        cells += [_cell_statistics(scene, snr, spc, labels[name], crlb, *per_method[name])
                  for name in ("log", "hilbert")]
    return cells


def run_fitting(config: BenchConfig = QUICK, progress=None) -> list:
    """RMSE and bias against the Cramer-Rao bound, and time per record, for every cell.

    Every method sees the same records: ``config.repeats`` per cell, each the averaged
    waveform from a random phase plus ``x_eq`` plus white noise ``sigma_x = y0/SNR``,
    sampled at ``samples_per_cycle + SAMPLING_OFFSET`` per period. The records come in
    antithetic pairs (one noise draw with both signs), so that the bias is measured well
    below the scatter of the RMSE. The methods that give
    only b run on the hysteretic-only scene.

    Returns
    -------
    list of FitCell
    """
    # Imported here so that no record's time includes loading them.
    import scipy.signal  # noqa: F401

    import mcfit.analysis  # noqa: F401
    import mcfit.fit  # noqa: F401
    import mcfit.turning  # noqa: F401

    cells = []
    for i, scene in enumerate(config.fit_scenes):
        for j, snr in enumerate(config.snrs):
            for k, spc in enumerate(config.samples_per_cycle):
                if progress:
                    progress(f"fitting: {scene.name}, SNR {snr:g}, {spc} samples/cycle")
                cells += _run_cell(scene, snr, spc, config, [config.seed, i, j, k])
    return cells


def format_fitting(cells, config: BenchConfig) -> str:
    """The fitting tables: one per scene."""
    lines = [f"Fitting: RMSE and bias over {config.repeats} records per row, in units of the "
             "waveform Cramer-Rao bound",
             "  (y0, the model's coefficients, omega, phase, x_eq free; RMS over the records' "
             "random phases);",
             f"  SNR = y0/sigma_x; samples/cycle = nominal + {SAMPLING_OFFSET} (crests drift "
             "across the sample grid);",
             "  se/RMSE = mean stderr reported by mcfit over the observed RMSE; ms = wall time "
             "per record",
             f"  (mcfit: turning points + fit); statistical scatter of RMSE/CRLB about "
             f"{100 / math.sqrt(config.repeats):.0f} %; records in antithetic pairs (the same "
             "noise with both signs),",
             "  so the bias, a mean, cancels the noise to first order and is known to a few "
             "hundredths."]
    for scene in config.fit_scenes:
        rows = [c for c in cells if c.scene == scene.name]
        if not rows:
            continue
        letters = scene.model
        lines += ["", f"{scene.name}: {scene.describe()}"]
        head = f"  {'SNR':>6}{'spc':>7}  {'method':<20}"
        head += "".join(_cell("CRLB " + k, 10) for k in letters)
        head += "".join(_cell("RMSE/CRLB " + k, 13) for k in letters)
        head += "".join(_cell("bias " + k, 10) for k in letters)
        head += "".join(_cell("se/RMSE " + k, 10) for k in letters)
        head += f"{'ms':>7}{'failed':>8}{'model ok':>10}"
        lines.append(head)
        for c in rows:
            row = f"  {c.snr:>6.0e}{c.samples_per_cycle:>7.4g}  {c.method:<20}"
            row += "".join(_number(c.crlb[k], 10, ".2e") for k in letters)
            row += "".join(_number(c.rmse_ratio.get(k), 13, ".3g") for k in letters)
            row += "".join(_number(c.bias_ratio.get(k), 10, "+.2g") for k in letters)
            row += "".join(_number(c.stderr_ratio.get(k), 10, ".2f") for k in letters)
            row += f"{c.milliseconds:>7.3g}{c.failed:>8d}"
            row += f"{c.model_right:>6d}/{c.records:<3d}" if c.model_right is not None else ""
            lines.append(row.rstrip())
    return "\n".join(lines)


def _number(value, width, spec):
    return _cell("-" if value is None else format(value, spec), width)


def _cell(text, width):
    """``text`` right-aligned in ``width`` characters, always after a space: a long value
    (a negative bias, -0.00052) never runs into the column before it."""
    return " " + text.rjust(width - 1)
