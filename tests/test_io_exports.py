"""Exports of lab programs written in their own layout: NI LabVIEW waveforms, phyphox .xls."""

from datetime import datetime, timedelta

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit.cli import cli
from mcfit.errors import InputError
from mcfit.io import read_record

STEP = 2e-6  # s: NI's "delta t" in the example
RATE_B = 500.0  # 1/s: the ringing's decay rate, dy/dt = -b*y


def _ni_waveform(path, n=3000, with_time=True):
    """An NI "Write Waveforms to Spreadsheet" CSV: preamble, blank line, header, rows."""
    t = np.arange(n) * STEP
    v = np.exp(-RATE_B * t) * np.cos(2 * np.pi * 3000.0 * t)
    start = datetime(2021, 4, 16, 11, 27, 25, 437502)

    def stamp(k):
        moment = start + timedelta(microseconds=2 * k)
        return f"{moment.month}/{moment.day}/{moment.year}  {moment:%H:%M:%S.%f}"
    lines = ["waveform,Trig,V_C", f"t0,{stamp(0)},{stamp(0)}",
             "delta t,2.000000E-6,2.000000E-6", "", "time,Trig,V_C" if with_time else "Trig,V_C"]
    lines += [(f"{stamp(k)}," if with_time else "") + f"{5.0 * (k > 50):.1f},{v[k]:.7f}"
              for k in range(n)]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("with_time", [True, False])
def test_an_ni_waveform_export_takes_its_time_from_delta_t(tmp_path, with_time):
    path = _ni_waveform(tmp_path / "scope.csv", with_time=with_time)
    record = read_record(path, signal_col="V_C")
    assert record.signal_column == "V_C" and record.time_unit == "s"
    np.testing.assert_allclose(record.t, np.arange(3000) * STEP, rtol=1e-12, atol=0)
    assert record.x[0] == 1.0
    assert any("delta t, 2e-06 s (500000 Hz)" in note and "11:27:25.437502" in note
               for note in record.notes)


def test_a_well_sampled_ringing_beside_a_trigger_step_is_the_signal(tmp_path):
    # 36 crossings in 3000 samples: rare per step, yet eighteen cycles.
    record = read_record(_ni_waveform(tmp_path / "scope.csv"))
    assert record.signal_column == "V_C"
    assert "other candidates: 'Trig' (column 2)" in record.notes[-1]


def test_an_ni_waveform_fits_v_c_from_the_command_line(tmp_path):
    import json
    path = _ni_waveform(tmp_path / "scope.csv")
    result = CliRunner().invoke(cli, [str(path), "--signal-col", "V_C", "--format", "json"])
    assert result.exit_code == 0, result.output
    fit = json.loads(result.stdout)
    assert fit["model"] == "b" and fit["params"]["b"]["value"] == pytest.approx(RATE_B, rel=0.01)


def _phyphox_xls(path, swinging):
    """A phyphox gyroscope sheet (.xls): the column ``swinging`` holds a decay, the
    others noise; written with xlwt as phyphox writes legacy Excel."""
    xlwt = pytest.importorskip("xlwt")
    rng = np.random.default_rng(3)
    t = np.arange(1500) / 50.0
    book = xlwt.Workbook()
    sheet = book.add_sheet("Raw Data")
    labels = ["Time (s)"] + [f"Rotation {axis} (rad/s)" for axis in "xyz"]
    for j, label in enumerate(labels):
        sheet.write(0, j, label)
        for i in range(t.size):
            if j == 0:
                value = t[i]
            elif label == f"Rotation {swinging} (rad/s)":
                value = 1.5 * np.exp(-0.05 * t[i]) * np.cos(2 * np.pi * t[i] / 1.6)
            else:
                value = rng.normal(0.0, 0.02)
            sheet.write(i + 1, j, float(value))
    book.save(str(path))
    return path


@pytest.mark.parametrize("swinging", ["x", "z"])
def test_a_phyphox_xls_gives_the_axis_that_oscillates_most(tmp_path, swinging):
    record = read_record(_phyphox_xls(tmp_path / "gyro.xls", swinging))
    assert record.signal_column == f"Rotation {swinging} (rad/s)"
    [note] = [n for n in record.notes if n.startswith("signal column")]
    assert "the component that oscillates most" in note
    for axis in set("xyz") - {swinging}:
        assert f"'Rotation {axis} (rad/s)'" in note


def test_columns_that_are_not_axes_keep_the_first_that_oscillates(tmp_path):
    rng = np.random.default_rng(4)
    t = np.arange(400) * 0.05
    rows = "\n".join(f"{a:.2f},{rng.normal(0, 0.01):.5f},{np.cos(2 * a) * np.exp(-0.1 * a):.5f}"
                     for a in t)
    path = tmp_path / "two.csv"
    path.write_text("t,first,second\n" + rows + "\n")
    assert read_record(path).signal_column == "first"  # as before: no axis letters


def test_a_text_file_that_is_not_a_table_says_so(tmp_path):
    lines = ["# mcfit", "", "Fit the damping law to free-decay records, and report Q.", ""]
    for k in range(30):
        lines += [f"- item {k}: the reader copes with what loggers write,", "  and says so."]
    lines[20], lines[40] = "1000", "    9"  # numbers alone on a line, as in a code block
    path = tmp_path / "notes.md"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"notes.md is not a table of numbers: 2 of its 61 "
                                         r"lines are numbers \(it reads as prose or markup\)"):
        read_record(path)


def test_the_check_for_prose_stops_at_the_first_block_of_numbers(tmp_path, monkeypatch):
    """A CSV of 10^4 rows is a table after its header and five rows of numbers: the check
    for prose reads no further (reading all 10^4 lines took 29 ms, 8 times the rest of
    reading the file), and the record is read as before."""
    from mcfit.io import sniffing

    t = np.arange(10_000) * 0.004
    path = tmp_path / "long.csv"
    path.write_text("t,x\n" + "\n".join(f"{a:.3f},{np.cos(7 * a):.6f}" for a in t) + "\n")
    seen = []
    flags = sniffing._numeric_flags
    monkeypatch.setattr(sniffing, "_numeric_flags", lambda lines: (
        seen.append(1) or flag for flag in flags(lines)))
    assert not sniffing._is_prose(path.read_text().splitlines())
    assert len(seen) == 6  # the header, then five rows
    record = read_record(path)
    assert record.t.size == 10_000 and record.x[1] == pytest.approx(np.cos(7 * 0.004), abs=1e-6)


def _counts(n=600, step=0.02):
    t = np.arange(n) * step
    return t, np.round(512 + 300 * np.exp(-0.1 * t) * np.cos(2 * np.pi * t / 1.3)).astype(int)


@pytest.mark.parametrize("header", [None, "angle"])
def test_the_arduino_serial_monitor_with_timestamps(tmp_path, header):
    t, counts = _counts()
    start = datetime(2021, 4, 16, 23, 59, 55, 273000)  # across midnight
    stamps = [f"{start + timedelta(seconds=float(a)):%H:%M:%S.%f}"[:-3] for a in t]
    lines = [f"{stamps[0]} -> {header}"] if header else []
    lines += [f"{s} -> {c}" for s, c in zip(stamps, counts)]
    path = tmp_path / "monitor.txt"
    path.write_text("\n".join(lines) + "\n")
    record = read_record(path)
    np.testing.assert_allclose(record.t, t, atol=1e-9)
    np.testing.assert_array_equal(record.x, counts)
    assert record.signal_column == (header or "value")
    assert "Arduino serial monitor log: the timestamps before -> read as clock times" in (
        record.notes)


def test_several_values_on_a_serial_monitor_line(tmp_path):
    t, counts = _counts()
    path = tmp_path / "monitor.txt"
    lines = [f"16:04:{31 + a:06.3f} -> {c},{1023 - c}" for a, c in zip(t, counts)]
    lines.insert(100, "ets Jul 29 2019 12:21:46 (a board reset message)")
    path.write_text("\n".join(lines) + "\n")
    record = read_record(path, signal_col="value 2")
    np.testing.assert_array_equal(record.x, 1023 - counts)
    assert "1 line of the log without a timestamped value skipped" in record.notes


@pytest.mark.parametrize("label, scale", [("millis", 1e3), ("micros", 1e6)])
def test_an_arduino_time_column_is_in_its_own_unit(tmp_path, label, scale):
    t, counts = _counts()
    path = tmp_path / "log.csv"
    path.write_text(f"adc,{label}\n" + "".join(f"{c},{round(a * scale) + 4312}\n"
                                                for a, c in zip(t, counts)))
    record = read_record(path)
    assert record.time_column == label and record.time_unit == "s"
    np.testing.assert_allclose(np.diff(record.t), 0.02, rtol=1e-9)
    assert f"time converted from {'ms' if label == 'millis' else 'us'} to seconds" in (
        record.notes)
