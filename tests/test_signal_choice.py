"""The choice of the signal column by its spectral line over its own noise: a logger's
16 channels, a weak clean oscillation beside louder noise, drifts, counters and clocks;
the note that names the other oscillating columns and the message that names the column
that swings when the chosen one does not."""

from __future__ import annotations

import datetime
import json

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit import analyse_record, read_record
from mcfit.cli import cli
from mcfit.io.lines import LINE_RATIO, line_strength

RATE = 10.0
HOLD = 14.0          # s the mass is held aside before it is released
PERIOD = 3.2         # s
B = 0.02             # 1/s: the amplitude decays as exp(-B t)
AMPLITUDE = 1.0e6    # counts
EPOCH = 1.7e9        # Unix seconds of the first row


def _logger_csv(path, seconds=300.0, seed=3):
    """A data logger's 16 columns: a sample counter, 12 ADC channels in counts written
    with explicit signs (the mass position 'Laser' held aside for HOLD s and then
    decaying, 'Noise' beside it of about 2 counts, a drifting temperature, a constant
    supply and others), epoch seconds, date and time text. Returns the epoch of the
    release."""
    rng = np.random.default_rng(seed)
    n = int((HOLD + seconds) * RATE)
    t = np.arange(n) / RATE
    after = t - HOLD
    swing = np.where(after < 0, 1.0, np.exp(-B * after) * np.cos(2 * np.pi * after / PERIOD))
    channels = {f"CH{k}": np.round(rng.normal(5 * k, 1.0, n)) for k in range(1, 5)}
    channels["Laser"] = np.round(12000 + AMPLITUDE * swing + rng.normal(0, 3, n))
    channels["Noise"] = np.round(rng.normal(0, 2, n))
    channels["Temp"] = np.round(21000 + 40 * (1 - np.exp(-t / 120)) + rng.normal(0, 1, n))
    channels["Supply"] = np.full(n, 120000.0)
    channels.update({f"CH{k}": np.full(n, 7.0 * k) for k in range(5, 9)})
    lines = [",".join(["Sample", *channels, "Timestamp", "Date", "Time"])]
    for i in range(n):
        stamp = datetime.datetime.fromtimestamp(EPOCH + t[i], datetime.timezone.utc)
        values = ",".join(f"{int(column[i]):+08d}" for column in channels.values())
        lines.append(f"{i + 1},{values},{EPOCH + t[i]:.1f},{stamp:%Y-%m-%d},"
                     f"{stamp:%H:%M:%S.%f}")
    path.write_text("\n".join(lines) + "\n")
    return EPOCH + HOLD


def _json_fit(path, *options):
    result = CliRunner().invoke(cli, [str(path), "--format", "json", *options])
    return result, (json.loads(result.output) if result.output.startswith("{") else None)


def test_the_logger_channel_that_swings_is_the_signal(tmp_path):
    """Of 16 columns (signed counts, a counter, a clock, noise of 2 counts beside the
    mass), 'Laser' is chosen; fitted after the hold, its period and b are the truth."""
    path = tmp_path / "free_period.csv"
    release = _logger_csv(path)
    record = read_record(path)
    assert record.signal_column == "Laser"
    assert record.time_column == "Timestamp"
    assert record.oscillating_columns == ()
    note = next(n for n in record.notes if n.startswith("signal column:"))
    assert note.startswith("signal column: 'Laser' (column 6) (chosen automatically")
    assert "also oscillating" not in note  # noise, drift, counter and constants do not
    # the explicit + signs are read as numbers: the held part is AMPLITUDE above 12000
    assert record.x[0] == pytest.approx(12000 + AMPLITUDE, abs=20)

    # The epoch clock is read from the record's first row: --start is seconds into it.
    # With no window, the hold is left out before the turning points.
    assert release == EPOCH + HOLD
    for options in (("--start", f"{HOLD + 5:.1f}"), ()):
        result, data = _json_fit(path, *options)
        assert result.exit_code == 0, result.output
        assert data["columns"] == {"time": "Timestamp", "signal": "Laser"}
        assert data["period"] == pytest.approx(PERIOD, rel=1e-3)
        assert data["params"]["b"]["value"] == pytest.approx(B, rel=1e-2)
    assert HOLD <= data["release_time"] < HOLD + 0.5


def test_forcing_the_noise_column_names_the_one_that_swings(tmp_path):
    path = tmp_path / "free_period.csv"
    _logger_csv(path)
    record = read_record(path, signal_col="Noise")
    assert record.oscillating_columns == ("Laser",)
    analysis = analyse_record(record)
    assert analysis.status == "error"
    assert "'Laser' (column 6) does" in analysis.error
    assert "`signal_col=Laser`" in analysis.error
    result = CliRunner().invoke(cli, [str(path), "--signal-col", "Noise"])
    assert result.exit_code != 0
    assert "'Noise' shows no oscillation above its noise" in result.output
    assert "use --signal-col Laser." in result.output
    assert "Traceback" not in result.output


def _write(path, columns):
    names = list(columns)
    rows = zip(*columns.values())
    path.write_text(",".join(names) + "\n"
                    + "\n".join(",".join(f"{v:.6g}" for v in row) for row in rows) + "\n")


def test_a_weak_clean_oscillation_beats_louder_noise(tmp_path):
    """Noise of variance 100 comes first; a clean swing of amplitude 2 (variance under 2)
    after it is the signal, and its fit has the truth."""
    rng = np.random.default_rng(11)
    t = np.arange(0.0, 120.0, 0.02)
    x = 2.0 * np.exp(-0.03 * t) * np.cos(2 * np.pi * t / 1.5) + rng.normal(0, 0.01, t.size)
    noise = rng.normal(0, 10.0, t.size)
    assert noise.var() > 50 * x.var()
    path = tmp_path / "weak.csv"
    _write(path, {"time": t, "hum": noise, "pos": x})
    record = read_record(path)
    assert record.signal_column == "pos"
    assert "other candidates: 'hum' (column 2)" in record.notes[-1]
    result, data = _json_fit(path)
    assert result.exit_code == 0, result.output
    assert data["period"] == pytest.approx(1.5, rel=1e-3)
    assert data["params"]["b"]["value"] == pytest.approx(0.03, rel=0.05)


def test_drift_counter_and_clock_lose_to_the_oscillation(tmp_path):
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 200.0, 0.05)
    columns = {
        "time": t,
        "count": np.arange(t.size, dtype=float),
        "seconds": np.floor(t) % 60,                       # a clock's seconds, wrapping
        "ms": np.round(t * 1000) % 10000,                  # a millisecond timer, wrapping
        "temp": 20 + np.cumsum(rng.normal(0, 0.05, t.size)) + rng.normal(0, 0.02, t.size),
        "warmup": 3 * (1 - np.exp(-t / 50)) + rng.normal(0, 0.01, t.size),
        "angle": 0.3 * np.exp(-0.01 * t) * np.cos(2 * np.pi * t / 2.0)
        + rng.normal(0, 0.002, t.size),
    }
    path = tmp_path / "drift.csv"
    _write(path, columns)
    record = read_record(path)
    assert record.signal_column == "angle"
    note = record.notes[-1]
    assert "also oscillating" not in note
    for name in ("count", "seconds", "temp", "warmup"):
        assert line_strength(columns[name]) < LINE_RATIO, name
    assert line_strength(columns["ms"]) == 0.0  # 20 cycles of a sawtooth, but a counter
    assert line_strength(columns["angle"]) >= LINE_RATIO
    assert max(line_strength(np.random.default_rng(s).normal(size=n))
               for s in range(20) for n in (500, 5000, 40000)) < LINE_RATIO


def test_the_note_names_the_other_oscillating_column(tmp_path):
    """Two columns swing: the clearer one is chosen whatever the order, the other is
    named as also oscillating, weaker."""
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 60.0, 0.01)
    geophone = 0.5 * np.cos(2 * np.pi * t / 0.8) + rng.normal(0, 0.2, t.size)
    x = 1.0 * np.exp(-0.02 * t) * np.cos(2 * np.pi * t / 0.8) + rng.normal(0, 0.001, t.size)
    path = tmp_path / "two.csv"
    _write(path, {"time": t, "Geophone": geophone, "x": x})
    record = read_record(path)
    assert record.signal_column == "x"
    assert ("signal column: 'x' (column 3) (chosen automatically; use `signal_col` to "
            "change; also oscillating: 'Geophone' (column 2) (weaker))") in record.notes


def test_line_strength_looks_at_a_bounded_sample_of_the_whole_column():
    """A column longer than the points looked at is thinned over its whole length: an
    oscillation that starts after a long flat part is still seen."""
    t = np.arange(200_000) / 100.0
    x = np.where(t < 1000, 0.0, np.cos(2 * np.pi * t / 7.3))
    assert line_strength(x) >= LINE_RATIO
    assert line_strength(np.zeros_like(t)) == 0.0
