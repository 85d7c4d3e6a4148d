"""Records as they were recorded (issue 37): WAV audio from a microphone, and loggers whose
time column is a clock (Unix-epoch seconds, date and time text). Each test writes its
file and checks the numbers read and fitted against the truth it was made with."""

from __future__ import annotations

import csv
import datetime
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.io import wavfile

from mcfit.analysis import analyse_record
from mcfit.cli import cli
from mcfit.io import read_record
from mcfit.plain import time_text

SAMPLES = Path(__file__).parents[1] / "sample_data"

# A struck fork: 440 Hz at 8 kHz, viscous decay b = 3 1/s (Q = pi*f/b = 461), 1.5 s.
RATE, FREQUENCY, B, AMPLITUDE = 8000, 440.0, 3.0, 0.6


@pytest.fixture(autouse=True)
def _in_tmp_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def fork(duration=1.5, noise=3e-4, seed=1):
    t = np.arange(round(duration * RATE)) / RATE
    x = AMPLITUDE * np.exp(-B * t) * np.cos(2 * np.pi * FREQUENCY * t)
    return t, x + np.random.default_rng(seed).normal(0.0, noise, t.size)


def fit_json(*args):
    result = CliRunner().invoke(cli, [*map(str, args), "--format", "json"])
    assert result.exit_code == 0, result.output
    return json.loads(result.output)


def check_b(data, truth=B, tolerance=5.0):
    b = data["params"]["b"]
    assert data["params"]["a"]["value"] == 0 and data["params"]["c"]["value"] == 0
    assert abs(b["value"] - truth) < tolerance * b["stderr"] + 1e-4 * truth


# -- WAV ---------------------------------------------------------------------------------

def test_int16_mono_wav_time_scaling_unit_and_fit():
    t, x = fork()
    pcm = np.round(x * 32768).astype(np.int16)
    wavfile.write("fork.wav", RATE, pcm)
    record = read_record("fork.wav")
    assert record.t.size == t.size and record.t[0] == 0.0
    np.testing.assert_allclose(np.diff(record.t), 1.0 / RATE, rtol=1e-9)
    np.testing.assert_array_equal(record.x, pcm / 32768.0)
    assert record.signal_unit == "full scale" and record.signal_column == "channel 1 (full scale)"
    assert record.time_origin is None
    assert any("8000 Hz" in n and "16-bit" in n for n in record.notes)
    data = fit_json("fork.wav")
    assert data["signal_unit"] == "full scale"
    assert data["coefficient_units"]["c"] == "(full scale)/s"
    assert data["period"] == pytest.approx(1.0 / FREQUENCY, rel=1e-5)
    assert data["time_origin"] is None
    check_b(data)


def test_stereo_wav_fits_the_channel_that_swings():
    t, x = fork()
    quiet = np.random.default_rng(7).normal(0.0, 1e-3, t.size)
    wavfile.write("stereo.wav", RATE, np.round(np.stack([quiet, x], axis=1) * 32768)
                  .astype(np.int16))
    record = read_record("stereo.wav")
    assert record.signal_column == "channel 2 (full scale)"
    assert any("channel 2" in n and "swings most" in n for n in record.notes)
    check_b(fit_json("stereo.wav"))
    chosen = read_record("stereo.wav", signal_col="channel 1")
    np.testing.assert_allclose(chosen.x, np.round(quiet * 32768) / 32768)


def test_float_wav_as_it_is_and_8_bit_centred():
    t, x = fork()
    wavfile.write("float.wav", RATE, x.astype(np.float32))
    record = read_record("float.wav")
    np.testing.assert_array_equal(record.x, x.astype(np.float32).astype(np.float64))
    check_b(fit_json("float.wav"))
    wavfile.write("eight.wav", RATE, np.round(128 + 100 * x / AMPLITUDE).astype(np.uint8))
    eight = read_record("eight.wav")
    np.testing.assert_allclose(eight.x, (np.round(128 + 100 * x / AMPLITUDE) - 128) / 128)


def test_the_tuning_fork_sample_gives_its_truth():
    sys.path.insert(0, str(SAMPLES))
    try:
        from make_samples import FORK
    finally:
        sys.path.remove(str(SAMPLES))
    data = fit_json(SAMPLES / "tuning_fork.wav")
    truth = np.pi * FORK["frequency"] / FORK["q"]
    check_b(data, truth)
    assert data["period"] == pytest.approx(1 / FORK["frequency"], rel=1e-6)
    assert data["params"]["y0"]["value"] == pytest.approx(FORK["amplitude"], rel=2e-3)
    assert data["q"]["initial"] == pytest.approx(FORK["q"], rel=1e-3)


def test_rate_with_a_wav_is_refused_unless_it_is_the_files():
    # An option one file cannot satisfy fails that file (exit 1), as a column it lacks.
    wavfile.write("fork.wav", RATE, np.round(fork()[1] * 32768).astype(np.int16))
    result = CliRunner().invoke(cli, ["fork.wav", "--rate", "100"])
    assert result.exit_code == 1
    assert "8000 Hz" in result.output and "--rate" in result.output
    assert read_record("fork.wav", rate=RATE).t[1] == 1.0 / RATE


def test_a_damaged_wav_is_one_clear_line():
    Path("broken.wav").write_bytes(b"RIFF\x10\x00\x00\x00WAVEfmt garbage")
    result = CliRunner().invoke(cli, ["broken.wav"])
    assert result.exit_code == 1
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "cannot read broken.wav as WAV audio" in lines[0]
    assert "Traceback" not in result.output


def test_every_list_of_types_names_wav_and_the_others():
    listed = (".wav", ".xls", ".ods", ".lvm", ".xlsx", ".csv")
    Path("notes.json").write_text("{}")
    refused = CliRunner().invoke(cli, ["notes.json"])
    Path("empty").mkdir()
    Path("empty/notes.json").write_text("{}")
    folder = CliRunner().invoke(cli, ["empty"])
    helped = CliRunner().invoke(cli, ["fit", "--help"])
    for output in (refused.output, folder.output, " ".join(helped.output.split())):
        assert all(kind in output for kind in listed), output
    Path("batch").mkdir()
    wavfile.write("batch/fork.wav", RATE, np.round(fork()[1] * 32768).astype(np.int16))
    result = CliRunner().invoke(cli, ["batch", "--format", "json"])
    assert result.exit_code == 0 and json.loads(result.output)["source"].endswith("fork.wav")


# -- clocks ------------------------------------------------------------------------------

EPOCH0 = 1406721600.123  # 2014-07-30 12:00:00.123 UTC
STEP, PERIOD, DECAY = 0.1, 2.0, 0.02


def logger_rows(n=1200):
    t = np.arange(n) * STEP
    x = 5.0 * np.exp(-DECAY * t) * np.cos(2 * np.pi * t / PERIOD)
    x += np.random.default_rng(3).normal(0.0, 0.01, n)
    return t, x


def write_logger(name="logger.csv", epoch_name="Epoch", scale=1.0, counter="Sample"):
    t, x = logger_rows()
    with open(name, "w", newline="") as stream:
        out = csv.writer(stream)
        out.writerow([counter, epoch_name, "Date", "Time", "Angle (deg)"])
        for i, (ti, xi) in enumerate(zip(t, x)):
            clock = EPOCH0 + ti
            stamp = datetime.datetime.fromtimestamp(clock, datetime.timezone.utc)
            out.writerow([i, f"{clock * scale:.{3 if scale == 1 else 0}f}",
                          f"{stamp:%Y-%m-%d}", f"{stamp:%H:%M:%S.%f}"[:-3], f"{xi:.5f}"])
    return Path(name)


@pytest.mark.parametrize("epoch_name", ["Epoch", "UnixTime", "Time", "value"])
def test_epoch_seconds_are_re_based_and_the_origin_kept(epoch_name):
    write_logger(epoch_name=epoch_name)
    record = read_record("logger.csv")
    assert record.time_column == epoch_name
    t, _ = logger_rows()
    np.testing.assert_allclose(record.t, t, atol=2e-6)
    assert record.t[0] == 0.0
    origin = record.time_origin
    assert origin["clock"] == "unix epoch seconds" and origin["value"] == EPOCH0
    assert origin["utc"] == "2014-07-30T12:00:00.123Z"
    data = fit_json("logger.csv")
    assert data["time_origin"]["utc"] == "2014-07-30T12:00:00.123Z"
    assert data["t0"] < PERIOD
    check_b(data, DECAY, tolerance=5.0)
    assert data["period"] == pytest.approx(PERIOD, rel=1e-3)


def test_epoch_milliseconds_without_a_name_after_a_counter():
    write_logger(epoch_name="col", scale=1000.0, counter="index")
    record = read_record("logger.csv")
    assert record.time_column == "col" and record.domain == "time"
    assert record.time_origin["clock"] == "unix epoch milliseconds"
    np.testing.assert_allclose(record.t, logger_rows()[0], atol=1e-6)


def test_date_and_time_text_columns_make_one_clock():
    write_logger()
    record = read_record("logger.csv", time_col="Time")
    np.testing.assert_allclose(record.t, logger_rows()[0], atol=1e-9)
    assert record.time_origin["clock"] == "date and time"
    assert record.time_origin["value"] == "2014-07-30T12:00:00.123"


def test_start_is_seconds_from_the_first_sample():
    write_logger()
    record = read_record("logger.csv")
    analysis = analyse_record(record, start=19.5)
    used = analysis.turning.t[analysis.turning.used]
    assert 19.5 < used[0] < 19.5 + PERIOD
    whole = analyse_record(record)
    assert whole.turning.t[whole.turning.used][0] < 2.0
    assert any("19.5 s" in n for n in analysis.turning.notes + record.notes
               + tuple(analysis.to_dict()["notes"]))
    outside = CliRunner().invoke(cli, ["logger.csv", "--start", "500"])
    assert outside.exit_code != 0 and "no samples in the window" in outside.output


def test_printed_times_are_readable():
    write_logger()
    text = CliRunner().invoke(cli, ["logger.csv"]).output
    assert "e+09" not in text and "1.407e" not in text
    assert "time origin:     t = 0 s is Epoch = 1406721600.123 = 2014-07-30T12:00:00.123Z" in text
    assert "(amplitude at 1 s)" in text or "(amplitude at 0" in text


def test_elapsed_time_not_starting_at_zero_stays_as_it_is():
    t, x = logger_rows()
    Path("run.csv").write_text("time (s),x\n" + "".join(
        f"{1.0 + a:.2f},{b:.5f}\n" for a, b in zip(t, x)))
    record = read_record("run.csv")
    assert record.t[0] == 1.0 and record.time_origin is None
    np.testing.assert_array_equal(record.t, np.round(1.0 + t, 2))


def test_time_text_carries_the_digits_a_period_needs():
    assert time_text(19.5, 0.02) == "19.5"
    assert time_text(1234.56789, 2.27e-5) == "1234.56789"
    assert time_text(1406721619.623, 0.02) == "1406721619.62"
    assert time_text(None) == "-"
    assert time_text(0.0011363, None, digits=4) == "0.001136"
