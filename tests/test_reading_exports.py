"""Reading exports as loggers and lab programs write them (issue 16), from files made at
test time: each test checks the numbers read, not only that reading succeeds."""

from __future__ import annotations

import datetime
import gzip
import sys
from pathlib import Path

import numpy as np
import pytest

from mcfit.errors import InputError
from mcfit.io import read_record

REALDATA = Path(__file__).parents[2] / "shared" / "realdata"

# A decay at 50 Hz over 20 s, printed to 4 decimals as most exports print it.
T = np.round(np.arange(0, 1000) * 0.02, 2)
X = np.round(50.0 * np.exp(-0.1 * T) * np.cos(2 * np.pi * T), 4)


@pytest.fixture(autouse=True)
def _in_tmp_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def write(name, text, encoding="utf-8"):
    Path(name).write_bytes(text.encode(encoding) if isinstance(text, str) else text)
    return Path(name)


def body(sep=",", decimal=".", t=T, x=X):
    def fmt(v, digits):
        text = f"{v:.{digits}f}"
        return text.replace(".", ",") if decimal == "," else text
    return "".join(f"{fmt(a, 3)}{sep}{fmt(b, 4)}\n" for a, b in zip(t, x))


def check(record, t=T, x=X):
    np.testing.assert_allclose(record.t, t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(record.x, x, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- decimal commas


def test_one_column_with_decimal_commas_keeps_its_digits():
    # The values of issue 16: split at the comma they gave y0 = 46.1 instead of 50.3.
    values = np.round(38.0169 + X / 10, 4)
    text = "Position (mm) Run #1\n" + "".join(f"{v:.4f}".replace(".", ",") + "\n"
                                             for v in values)
    record = read_record(write("run1.csv", text), rate=50)
    np.testing.assert_allclose(record.x, values, rtol=0, atol=1e-12)
    np.testing.assert_allclose(record.t, np.arange(values.size) / 50)
    assert record.signal_column == "Position (mm) Run #1" and record.signal_unit == "mm"
    assert "decimal commas read as decimal points" in record.notes


@pytest.mark.parametrize("sep", [";", "\t", " "])
def test_three_columns_with_decimal_commas(sep):
    velocity = np.round(np.gradient(X, T), 4)
    lines = [sep.join(("Zeit (s)", "Weg (mm)", "v (mm/s)"))]
    lines += [sep.join(f"{v:.4f}".replace(".", ",") for v in row)
              for row in zip(T, X, velocity)]
    if sep == " ":
        lines[0] = "Zeit Weg v"
    record = read_record(write("drei.txt", "\n".join(lines) + "\n"))
    check(record)


# --------------------------------------------------------------------------- header layouts


def test_serial_logger_header_with_a_line_of_dashes_and_clock_times():
    lines = ["Timestamp, Time_Elapsed(s), Angle(deg)", "-" * 40]
    for t, x in zip(T, X):
        clock = datetime.datetime(2024, 3, 1, 16, 4, 31, 273000) + datetime.timedelta(seconds=t)
        lines.append(f"{clock:%H:%M:%S.%f}"[:-3] + f", {t:.3f}, {x:.4f}")
    path = write("serial.csv", "\n".join(lines) + "\n")
    record = read_record(path)
    check(record)
    assert record.time_column == "Time_Elapsed(s)" and record.signal_column == "Angle(deg)"
    assert "1 separator line (dashes or equals signs) skipped" in record.notes
    check(read_record(path, signal_col=3))
    # The clock times alone are a time column too, in seconds after the first.
    clock_only = read_record(path, time_col=1, signal_col=3)
    np.testing.assert_allclose(clock_only.t, T, atol=1e-9)
    assert any("clock times in 'Timestamp'" in note and "16:04:31.273" in note
               for note in clock_only.notes)


def test_clock_times_across_midnight_and_iso_dates():
    start = datetime.datetime(2024, 3, 1, 23, 59, 50)
    stamps = [start + datetime.timedelta(seconds=float(t)) for t in T]
    text = "time,angle\n" + "".join(f"{s:%H:%M:%S.%f},{x:.4f}\n" for s, x in zip(stamps, X))
    check(read_record(write("midnight.csv", text)))
    text = "date time angle\n" + "".join(f"{s.isoformat(sep=' ')} {x:.4f}\n"
                                         for s, x in zip(stamps, X))
    check(read_record(write("iso.txt", text)))


def test_units_row_under_the_header():
    text = "time;x\nms;mm\n" + body(";", t=T * 1000)
    record = read_record(write("units.csv", text))
    check(record)
    assert record.time_column == "time (ms)" and record.signal_unit == "mm"
    assert "time converted from ms to seconds" in record.notes


def test_repeated_headers_trailing_notes_and_equals_lines():
    lines = ["t,x", "====,===="]
    for i, row in enumerate(body().splitlines()):
        if i and i % 250 == 0:
            lines += ["t,x", "====,===="]
        lines.append(row)
    lines += ["", "End of data", "Logger stopped by user"]
    record = read_record(write("logger.csv", "\n".join(lines) + "\n"))
    check(record)
    assert "3 repeated header lines skipped" in record.notes
    assert "2 lines of text after the data skipped (starting 'End of data')" in record.notes


def test_fortran_d_exponents():
    text = "".join(f"{t:.6E}  {x:.6E}\n".replace("E", "D") for t, x in zip(T, X))
    record = read_record(write("fortran.dat", text))
    check(record)


def test_labview_lvm_with_two_header_blocks():
    block = ("LabVIEW Measurement\t\nWriter_Version\t2\nSeparator\tTab\nDecimal_Separator\t,\n"
             "Date\t2019/10/08\nTime\t16:04:33,123\n***End_of_Header***\t\n\nChannels\t1\t\n"
             "Samples\t1000\t\nX_Dimension\tTime\t\nDelta_X\t0,020000\t\n***End_of_Header***\t\n")
    text = block + "X_Value\tUntitled\tComment\n" + "".join(
        f"{t:.6f}\t{x:.6f}\t\n".replace(".", ",") for t, x in zip(T, X))
    record = read_record(write("run.lvm", text))
    check(record)
    assert record.time_column == "X_Value" and record.signal_column == "Untitled"
    assert any("header block starting 'LabVIEW Measurement'" in note for note in record.notes)


def test_vernier_and_capstone_headers():
    vernier = ("Vernier Format 2\nUntitled.cmbl 10/8/2019 16:04:33 .\nLatest\n"
               "Time\tPosition\tVelocity\nt\tx\tv\ns\tm\tm/s\n\n")
    velocity = np.round(np.gradient(X, T), 4)
    rows = "".join(f"{t:.3f}\t{x:.4f}\t{v:.4f}\n" for t, x, v in zip(T, X, velocity))
    record = read_record(write("vernier.txt", vernier + rows))
    check(record)
    assert record.time_column == "Time (s)" and record.signal_column == "Position (m)"
    capstone = "Run #1\t\nTime (s)\tPosition (m)\n"
    record = read_record(write("capstone.txt", capstone + body("\t")))
    check(record)
    assert record.time_column == "Time (s)"


@pytest.mark.parametrize("name", ["run.log", "run", "run.lvm"])
def test_a_text_file_is_judged_by_its_content(name):
    check(read_record(write(name, "time,x\n" + body())))


def test_seconds_spelled_out_are_seconds():
    record = read_record(write("s.csv", "t (seconds),x\n" + body()))
    check(record)
    assert record.time_unit == "s"


# --------------------------------------------------------------------------- timestamps


def test_a_few_glitched_timestamps_are_set_right():
    # phyphox: 12 timestamps stepping back in 18,000 rows (a phone-sensor glitch).
    rng = np.random.default_rng(16)
    t = np.arange(18000) * 0.01
    x = np.round(2 * np.exp(-0.02 * t) * np.cos(2 * np.pi * 0.8 * t), 6)
    stamped = t.copy()
    bad = rng.choice(np.arange(100, t.size - 100), 12, replace=False)
    stamped[bad] -= 0.015
    text = '"Time (s)","Angle (rad)"\n' + "".join(f"{a:.6E},{b:.6E}\n"
                                                  for a, b in zip(stamped, x))
    record = read_record(write("phyphox.csv", text))
    check(record, t, x)
    assert any(note.startswith("12 glitched timestamps") and "12 set to the middle" in note
               for note in record.notes)


def test_a_repeated_timestamp_is_set_right_and_a_wild_one_dropped():
    t = np.arange(2000) * 0.01
    x = np.round(np.exp(-0.05 * t) * np.cos(2 * np.pi * t), 6)
    stamped = t.copy()
    stamped[500] = stamped[499]      # repeated
    stamped[1200:1202] = 3.0         # two in a row, far back: dropped
    text = "time,x\n" + "".join(f"{a:.2f},{b}\n" for a, b in zip(stamped, x))
    record = read_record(write("glitch.csv", text))
    keep = np.ones(t.size, dtype=bool)
    keep[1200:1202] = False
    check(record, t[keep], x[keep])
    assert any("3 glitched timestamps" in note and "1 set to the middle" in note
               and "2 rows dropped" in note for note in record.notes)


def test_many_repeats_are_still_bursts():
    t = np.repeat(np.arange(0.0, 10.0, 0.1), 2)
    x = np.exp(-0.1 * t) * np.cos(2 * np.pi * t)
    text = "t,x\n" + "".join(f"{a:.1f},{b:.6f}\n" for a, b in zip(t, x))
    with pytest.raises(InputError, match="repeat the previous timestamp.*`rate=HZ`"):
        read_record(write("bursts.csv", text))


def test_tracker_time_rounded_to_three_significant_figures():
    t = np.arange(1, 900) / 30.0
    x = np.round(0.3 * np.exp(-0.05 * t) * np.cos(2 * np.pi * 0.7 * t), 4)
    printed = [np.format_float_positional(v, precision=3, unique=False, fractional=False)
               for v in t]
    printed = [p.rstrip(".") if p.endswith(".") else p for p in printed]
    text = "mass A\nt\tx\n" + "".join(f"{p}\t{b}\n" for p, b in zip(printed, x))
    record = read_record(write("tracker.txt", text))
    check(record, t, x)
    assert any("is rounded (to 3 significant figures)" in note and "30 Hz" in note
               for note in record.notes)
    assert not any("burst" in note for note in record.notes)


def test_event_driven_encoder_log_keeps_its_times():
    # An Arduino writes a line each time the encoder count changes: uneven times are real.
    fine = np.arange(0, 60, 1e-5)
    counts = np.round(12 * np.exp(-0.03 * fine) * np.cos(2 * np.pi * 0.5 * fine))
    change = np.flatnonzero(np.diff(counts) != 0) + 1
    micros = np.floor(fine[change] * 1e6).astype(np.int64)
    text = "micros,count\n" + "".join(f"{a},{int(b)}\n" for a, b in zip(micros, counts[change]))
    record = read_record(write("encoder.txt", text))
    check(record, micros * 1e-6, counts[change])  # micros() counts microseconds
    assert not any("`rate" in note for note in record.notes)
    assert any("event-driven" in note for note in record.notes)


# --------------------------------------------------------------------------- rows, bytes


def test_data_written_in_rows():
    text = ",".join(f"{t:.3f}" for t in T) + "\n" + ",".join(f"{x:.4f}" for x in X) + "\n"
    record = read_record(write("rows.csv", text))
    check(record)
    assert "data written in rows (2 rows of 1000 values) read as columns" in record.notes
    matlab = "[" + " ".join(f"{t:.3f}" for t in T) + "; " + " ".join(f"{x:.4f}" for x in X) + "]"
    check(read_record(write("matlab.txt", matlab + "\n")))


def test_a_megabyte_on_one_line_is_a_row_vector():
    values = np.round(np.tile(X, 140), 4)
    text = " ".join(f"{v:.4f}" for v in values) + "\n"
    assert len(text) > 1 << 20
    path = write("vector.txt", text)
    with pytest.raises(InputError, match=r"has one column \(its values written in one row\).*"
                                         "`rate=HZ`"):
        read_record(path)
    record = read_record(path, rate=50)
    np.testing.assert_allclose(record.x, values, rtol=0, atol=1e-12)


def test_csv_gz():
    path = write("run.csv.gz", gzip.compress(("time,x\n" + body()).encode()))
    record = read_record(path)
    check(record)
    assert "gzip-compressed file decompressed" in record.notes


@pytest.mark.parametrize("cut", [0, 7])
def test_nul_bytes_at_the_end_are_dropped(cut):
    text = ("time,x\n" + body()).encode()
    path = write("copy.csv", text[:len(text) - cut] + b"\x00" * 8192)
    record = read_record(path)
    n = T.size - (1 if cut else 0)
    check(record, T[:n], X[:n])
    assert any("8192 NUL bytes at the end dropped" in note for note in record.notes)


def test_nul_bytes_inside_are_refused_without_printing_them():
    text = ("time,x\n" + body()).encode()
    path = write("holes.csv", text[:500] + b"\x00" * 64 + text[500:])
    with pytest.raises(InputError, match="holds binary data \\(NUL bytes\\)") as info:
        read_record(path)
    assert "\x00" not in str(info.value)


# --------------------------------------------------------------------------- workbooks


def test_excel_first_sheet_of_notes_and_date_time_cells():
    import pandas as pd
    start = datetime.datetime(2024, 3, 1, 16, 4, 31)
    stamps = [start + datetime.timedelta(seconds=float(t)) for t in T]
    with pd.ExcelWriter("book.xlsx") as writer:
        pd.DataFrame({"Notes": ["pendulum B, released at 20 degrees"]}).to_excel(
            writer, sheet_name="notes", index=False)
        pd.DataFrame({"Zeit": stamps, "angle (deg)": X}).to_excel(
            writer, sheet_name="data", index=False)
    record = read_record("book.xlsx")
    np.testing.assert_allclose(record.t, T, rtol=0, atol=2e-6)  # Excel keeps microseconds
    np.testing.assert_allclose(record.x, X, rtol=0, atol=1e-12)
    assert record.notes[:2] == ("sheet 'data'", "the first sheet, 'notes', holds no data")
    assert any("clock times in 'Zeit'" in note for note in record.notes)


def test_excel_header_block_and_units_row():
    import openpyxl
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.append(["Experiment 3, spring B"])
    sheet.append([])
    sheet.append(["time", "position"])
    sheet.append(["s", "m"])
    for t, x in zip(T, X):
        sheet.append([float(t), float(x)])
    book.save("block.xlsx")
    record = read_record("block.xlsx")
    check(record)
    assert record.time_column == "time (s)" and record.signal_unit == "m"


def test_excel_formulas_without_saved_values_say_how_to_fix_it():
    import openpyxl
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.append(["t", "x"])
    for i, t in enumerate(T[:200]):
        sheet.append([float(t), f"=COS(6.283*A{i + 2})"])
    book.save("formulas.xlsx")
    with pytest.raises(InputError, match="^the formula cells of sheet 'Sheet' of formulas.xlsx "
                                         "have no saved values \\(column 'x', cell B2, row 2\\)"
                                         ".*Open it in a spreadsheet program.*and save it"):
        read_record("formulas.xlsx")


def test_ods_workbook():
    pytest.importorskip("odf")
    import pandas as pd
    pd.DataFrame({"time (s)": T, "x": X}).to_excel("run.ods", index=False, engine="odf")
    check(read_record("run.ods"))


def test_xls_without_its_engine_names_the_package(monkeypatch):
    # A dependency, so only a broken install lacks it.
    monkeypatch.setitem(sys.modules, "python_calamine", None)
    path = write("old.xls", b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + bytes(504))
    with pytest.raises(InputError, match="^reading .xls workbooks such as old.xls needs the "
                                         "Python package python-calamine: install it "
                                         "\\(pip install python-calamine\\)"):
        read_record(path)


# --------------------------------------------------------------------------- real records


@pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata absent")
@pytest.mark.parametrize("name, columns, samples", [
    ("pendulum_cup/lab1_data.txt", ("column 1", "column 2"), None),
    ("pendulum_cup/trial1_rawdata.txt", ("column 1", "column 2"), None),
    ("spring_mass_disk/molla_durissima_discopieno_14.91945_0.2016_1.csv",
     ("time", "position"), None),
])
def test_real_records_read_as_before(name, columns, samples):
    record = read_record(REALDATA / name)
    assert (record.time_column, record.signal_column) == columns
    assert np.all(np.diff(record.t) > 0)
    assert not any("skipped" in note or "glitched" in note for note in record.notes)


def test_a_bad_value_in_the_last_row_is_reported_not_dropped():
    text = "t,x\n" + body() + "20.000,overload\n"
    with pytest.raises(InputError, match="text 'overload' in numeric column 'x' \\(column 2\\)"
                                         " of end.csv \\(data row 1001\\)"):
        read_record(write("end.csv", text))


def test_a_clock_time_that_cannot_be_read_names_its_column_row_and_options():
    lines = ["Timestamp,Angle(deg)"] + [f"16:04:{31 + 0.02 * i:06.3f},{x:.4f}"
                                        for i, x in enumerate(X[:1000])]
    lines[1 + 400] = "16h04m39.0," + lines[1 + 400].split(",")[1]
    lines.insert(2, "-----,-----")
    with pytest.raises(InputError, match="^'16h04m39.0' in the clock-time column 'Timestamp' "
                                         "\\(column 1\\) of clock.csv \\(data row 401\\) is "
                                         "not a clock time like the others.*`time_col`"):
        read_record(write("clock.csv", "\n".join(lines) + "\n"))


def test_a_quoted_field_over_two_lines_is_shown_on_one_line():
    rows = body().splitlines()
    rows.insert(100, '2.001,"over\nload"')
    text = "t,x\n" + "\n".join(rows) + "\n"
    with pytest.raises(InputError, match="text 'over\\\\nload' in numeric column 'x'") as info:
        read_record(write("quoted.csv", text))
    assert "\n" not in str(info.value)


def test_one_column_with_decimal_commas_and_no_header():
    values = np.round(38.0169 + X / 10, 4)
    text = "".join(f"{v:.4f}".replace(".", ",") + "\n" for v in values)
    record = read_record(write("bare.csv", text), rate=50)
    np.testing.assert_allclose(record.x, values, rtol=0, atol=1e-12)
    # Two integer columns stay two columns.
    pairs = "".join(f"{i},{int(v * 100)}\n" for i, v in enumerate(values))
    record = read_record(write("pairs.csv", pairs))
    np.testing.assert_allclose(record.x, np.floor(values * 100 + 1e-9))


def test_capstone_run_headers_name_the_time():
    text = "Time (s) Run #1,Position (m) Run #1\n" + body()
    record = read_record(write("capstone.csv", text))
    check(record)
    assert record.time_column == "Time (s) Run #1" and record.time_unit == "s"
    assert any("chosen automatically" in note and "Time (s) Run #1" in note
               for note in record.notes)


def test_files_past_the_first_megabyte():
    t = np.round(np.arange(80000) * 0.01, 2)
    x = np.round(np.exp(-0.01 * t) * np.cos(2 * np.pi * t), 6)
    rows = "".join(f"{a:.2f};{b:.6f}\n".replace(".", ",") for a, b in zip(t, x))
    assert len(rows) > 1 << 20
    record = read_record(write("long.csv", "t;x\ns;V\n" + rows + "\nEnd of run\n"))
    check(record, t, x)
    assert "1 line of text after the data skipped (starting 'End of run')" in record.notes
    path = write("cut.csv", ("t;x\n" + rows).encode() + b"\x00" * 5000)
    check(read_record(path), t, x)
