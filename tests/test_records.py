"""Reading records: every format and header variant, from files made at test time."""

from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np
import pytest

from mcfit.errors import InputError, UsageError
from mcfit.io import read_record

REALDATA = Path(__file__).parents[2] / "shared" / "realdata"
needs_realdata = pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata absent")

T = np.round(np.arange(0, 10, 0.05), 4)
X = np.round(0.4 + np.exp(-0.1 * T) * np.cos(2 * np.pi * T), 6)
VELOCITY = np.round(-2 * np.pi * np.exp(-0.1 * T) * np.sin(2 * np.pi * T), 6)


@pytest.fixture(autouse=True)
def _in_tmp_path(tmp_path, monkeypatch):
    # Records are named relative to tmp_path, as a person in that folder would name them:
    # messages quote the path as given.
    monkeypatch.chdir(tmp_path)


def write(tmp_path, name, text, encoding="utf-8"):
    """``text`` written to ``tmp_path/name``; returns the path relative to tmp_path."""
    (tmp_path / name).write_bytes(text.encode(encoding))
    return Path(name)


def rows(sep, decimal=".", columns=(T, X)):
    def fmt(v):
        text = repr(float(v))
        return text.replace(".", ",") if decimal == "," else text
    return "\n".join(sep.join(fmt(c[i]) for c in columns) for i in range(T.size)) + "\n"


def check(record, kind="waveform"):
    np.testing.assert_allclose(record.t, T)
    np.testing.assert_allclose(record.x, X)
    assert record.kind == kind
    assert record.t.dtype == np.float64


@pytest.mark.parametrize("name, sep, decimal", [
    ("a.csv", ",", "."),
    ("a.tsv", "\t", "."),
    ("a.csv", ";", "."),
    ("a.csv", ";", ","),
    ("a.txt", " ", "."),
    ("a.dat", "   ", "."),
    ("a.txt", "\t", ","),
    ("a.dat", " ", ","),
])
@pytest.mark.parametrize("header", [None, "time{sep}x", "time (s){sep}angle (rad)"])
def test_separators_decimals_headers(tmp_path, name, sep, decimal, header):
    text = rows(sep, decimal)
    if header:
        text = header.format(sep=sep) + "\n" + text
    record = read_record(write(tmp_path, name, text))
    check(record)
    if header and "(s)" in header:
        assert record.time_unit == "s" and record.signal_unit == "rad"
        assert record.signal_column == "angle (rad)"
    if decimal == ",":
        assert any("decimal comma" in note for note in record.notes)


def test_comments_bom_and_extra_columns(tmp_path):
    text = ("# logger v2\n% exported 2024\n\ntime;position;velocity\n"
            + rows(";", columns=(T, X, VELOCITY)))
    record = read_record(write(tmp_path, "run.csv", "\ufeff" + text))
    check(record)
    assert record.signal_column == "position"
    assert record.columns == ("time", "position", "velocity")
    assert any("velocity" in note for note in record.notes)  # other candidates are named


def test_velocity_first_is_not_chosen_over_position(tmp_path):
    text = "t,velocity,x\n" + rows(",", columns=(T, VELOCITY, X))
    record = read_record(write(tmp_path, "run.csv", text))
    assert record.signal_column == "x"


@pytest.mark.parametrize("spec", ["x", "X", 2, "2"])
def test_column_by_name_or_index(tmp_path, spec):
    text = "t,x,v\n" + rows(",", columns=(T, X, VELOCITY))
    record = read_record(write(tmp_path, "run.csv", text), signal_col=spec, time_col=1)
    check(record)


def test_unit_may_be_left_out_of_a_column_name(tmp_path):
    text = "Time [s],Pos (mm)\n" + rows(",")
    record = read_record(write(tmp_path, "run.csv", text), time_col="time", signal_col="pos")
    check(record)
    assert record.time_unit == "s"


def test_side_by_side_runs_padded(tmp_path):
    short = T.size // 2
    lines = ["t1,x1,t2,x2"]
    for i in range(T.size):
        second = f"{T[i]},{X[i]}" if i < short else ","
        lines.append(f"{T[i]},{X[i]},{second}")
    path = write(tmp_path, "runs.csv", "\n".join(lines) + "\n")
    record = read_record(path, time_col="t2", signal_col="x2")
    np.testing.assert_allclose(record.x, X[:short])
    assert any("padding" in note for note in record.notes)
    assert read_record(path, time_col="t1", signal_col="x1").x.size == T.size


def test_rate_builds_time_and_reports_bad_timestamps(tmp_path):
    stamps = np.repeat(np.arange(T.size // 4), 4).astype(float)  # logger bursts
    text = "stamp,x\n" + rows(",", columns=(stamps, X))
    path = write(tmp_path, "logger.csv", text)
    with pytest.raises(InputError, match="repeat.*`rate=HZ`"):
        read_record(path)
    record = read_record(path, rate=20)
    np.testing.assert_allclose(record.t, np.arange(T.size) / 20)
    assert record.time_column is None
    assert any("20 Hz" in note and "repeat" in note for note in record.notes)


def test_signal_only_file_with_rate(tmp_path):
    path = write(tmp_path, "x.txt", "\n".join(repr(float(v)) for v in X) + "\n")
    record = read_record(path, rate=20)
    np.testing.assert_allclose(record.x, X)


def test_stdin_and_streams(tmp_path, monkeypatch):
    text = "time,x\n" + rows(",")
    check(read_record(io.StringIO(text)))
    check(read_record(io.BytesIO(text.encode())))
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(text.encode())))
    record = read_record("-")
    check(record)
    assert record.source == "<stdin>"


def test_excel_with_sheets(tmp_path):
    import pandas as pd
    path = Path("book.xlsx")
    with pd.ExcelWriter(path) as writer:
        pd.DataFrame({"note": ["x"]}).to_excel(writer, sheet_name="info", index=False)
        pd.DataFrame({"time (s)": T, "angle": X}).to_excel(writer, sheet_name="run", index=False)
    check(read_record(path, sheet="run"))
    check(read_record(path, sheet=2))
    with pytest.raises(UsageError, match="sheet 'nope' not found in book.xlsx; sheets are: "
                                         "info, run"):
        read_record(path, sheet="nope")


def test_turning_point_tables(tmp_path):
    n = np.arange(1, 21)
    peaks = 7.69 * np.exp(-0.05 * n)
    record = read_record(write(tmp_path, "peaks.csv", "n,v (cm/s)\n" + "\n".join(
        f"{a},{b}" for a, b in zip(n, peaks))))
    assert record.kind == "turning-points" and record.domain == "cycle"
    record = read_record(write(tmp_path, "peaks2.csv", "\n".join(
        f"{a * 0.8},{b}" for a, b in zip(n, peaks))))
    assert record.kind == "turning-points" and record.domain == "time"
    forced = read_record(write(tmp_path, "w.csv", "time,x\n" + rows(",")),
                         kind="turning-points", domain="cycle")
    assert forced.kind == "turning-points" and forced.domain == "cycle"


def test_nan_gaps_are_kept(tmp_path):
    text = "time,x\n" + rows(",")
    lines = text.splitlines()
    lines[50] = lines[50].split(",")[0] + ","
    record = read_record(write(tmp_path, "gap.csv", "\n".join(lines) + "\n"))
    assert np.isnan(record.x[49])
    assert any("gap" in note for note in record.notes)


@pytest.mark.parametrize("name, text, message", [
    ("empty.csv", "", "empty.csv is empty"),
    ("header.csv", "time,x\n", "header.csv has a header row but no data rows"),
    ("text.csv", "time,x\n0,1\n0.1,2\n0.2,abc\n0.3,1\n",
     "text 'abc' in numeric column 'x' \\(column 2\\) of text.csv \\(data row 3\\)"),
    ("back.csv", "time,x\n0,1\n0.1,2\n0.05,3\n0.3,-1\n0.4,1\n0.5,2\n0.6,-2\n0.7,3\n0.8,-1\n",
     "time column 'time' \\(column 1\\) of back.csv does not increase"),
    ("const.csv", "time,x\n" + "".join(f"{i / 10},5\n" for i in range(40)),
     "signal column 'x' \\(column 2\\) of const.csv is constant"),
    ("nan.csv", "time,x\n" + "".join(f"{i / 10},nan\n" for i in range(40)),
     "no varying signal column in nan.csv|holds no numbers"),
    ("a.json", "{}", "unsupported file type '.json' for a.json"),
])
def test_bad_inputs(tmp_path, name, text, message):
    path = write(tmp_path, name, text)
    with pytest.raises((InputError, UsageError), match=message) as info:
        read_record(path)
    assert "\n" not in str(info.value)
    assert info.value.exit_code != 0


def test_messages_name_a_record_by_its_path_as_given(tmp_path):
    (tmp_path / "run2").mkdir()
    path = write(tmp_path, "run2/run3.csv", "t,y\n" + rows(","))
    with pytest.raises(UsageError, match="^column 'x' not found in run2/run3.csv;"):
        read_record(path, signal_col="x")
    with pytest.raises(UsageError, match="^column 'x' not found in run2/run3.csv;"), \
            open(path, "rb") as stream:
        read_record(stream, signal_col="x")


def test_unknown_column(tmp_path):
    path = write(tmp_path, "run3.csv", "t,y\n" + rows(","))
    with pytest.raises(UsageError, match="^column 'x' not found in run3.csv; columns are: t, "
                                         "y. Use `signal_col`.$"):
        read_record(path, signal_col="x")
    with pytest.raises(UsageError, match="column 5 not found in run3.csv"):
        read_record(path, time_col=5)


def test_missing_file_directory_corrupt_excel(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        read_record(tmp_path / "nope.csv")
    with pytest.raises(InputError, match="is a directory"):
        read_record(tmp_path)
    with pytest.raises(InputError, match="cannot read bad.xlsx as an Excel workbook"):
        read_record(write(tmp_path, "bad.xlsx", "not a zip file"))


def test_options_are_checked(tmp_path):
    path = write(tmp_path, "a.csv", "t,x\n" + rows(","))
    with pytest.raises(UsageError, match="rate"):
        read_record(path, rate=-1)
    with pytest.raises(UsageError, match="kind"):
        read_record(path, kind="spectrum")
    with pytest.raises(UsageError, match="either `time_col` or `rate`"):
        read_record(path, rate=10, time_col="t")


@needs_realdata
def test_real_records_need_no_options():
    lab = read_record(REALDATA / "pendulum_cup" / "lab1_data.txt")
    assert lab.signal_column == "column 2" and lab.time_column == "column 1"
    assert lab.x.size == 2330
    assert read_record(REALDATA / "pendulum_cup" / "lab1_data.txt", signal_col=2).x.size == 2330
    table = read_record(REALDATA / "pendulum_cup" / "trial1_extrema.txt")
    assert table.kind == "turning-points" and np.all(np.diff(table.t) > 0)
    raw = read_record(REALDATA / "pendulum_cup" / "trial1_rawdata.txt")
    assert raw.kind == "waveform" and raw.x.size == 500
    for run in (1, 2):
        name = f"molla_durissima_discopieno_14.91945_0.2016_{run}.csv"
        spring = read_record(REALDATA / "spring_mass_disk" / name)
        assert spring.time_column == "time" and spring.signal_column == "position"
        assert spring.t[0] == 1.0


@pytest.mark.parametrize("unit, factor", [("ms", 1e-3), ("µs", 1e-6), ("ns", 1e-9),
                                          ("min", 60.0), ("h", 3600.0), ("s", 1.0)])
def test_time_units_in_the_header_become_seconds(tmp_path, unit, factor):
    path = write(tmp_path, "units.csv", f"time ({unit}),x\n" + rows(",", columns=(T / factor, X)))
    record = read_record(path)
    np.testing.assert_allclose(record.t, T, rtol=1e-12, atol=1e-15)
    assert record.time_unit == "s"
    assert any("converted" in note for note in record.notes) == (factor != 1.0)


def test_an_unknown_time_unit_is_kept_and_said(tmp_path):
    path = write(tmp_path, "frames.csv", "time (frames),x\n" + rows(","))
    record = read_record(path)
    np.testing.assert_allclose(record.t, T)
    assert any("'frames' not recognised" in note for note in record.notes)


@pytest.mark.parametrize("quoted", [False, True])
def test_time_column_after_the_signal(tmp_path, quoted):
    # Quoted values are read by the second, column-by-column parse; plain ones in one parse.
    def q(v):
        return f'"{v!r}"' if quoted else repr(v)
    text = "angle,time (s)\n" + "".join(f"{q(float(x))},{q(float(t))}\n" for t, x in zip(T, X))
    path = write(tmp_path, "late.csv", text)
    record = read_record(path)
    check(record)
    assert record.time_column == "time (s)" and record.signal_column == "angle"
    check(read_record(path, time_col=2, signal_col=1))


def test_a_plain_numeric_file_is_parsed_once(tmp_path, monkeypatch):
    import pandas as pd
    calls = []
    real = pd.read_csv

    def counting(*args, **kwargs):
        calls.append(kwargs.get("usecols"))
        return real(*args, **kwargs)

    monkeypatch.setattr(pd, "read_csv", counting)
    check(read_record(write(tmp_path, "plain.csv", "t,x\n" + rows(","))))
    assert len(calls) == 1
    calls.clear()
    check(read_record(write(tmp_path, "plain.txt", "# run 1\ntime (s) x\n" + rows(" "))))
    assert len(calls) == 1


@pytest.mark.parametrize("variant", ["crlf", "cr", "quoted values", "quoted header",
                                     "quote in a comment", "blank lines", "padding spaces"])
def test_text_variants_read_as_the_plain_file(tmp_path, variant):
    lines = ("t,x\n" + rows(",")).splitlines()
    if variant == "quoted values":
        lines = [lines[0]] + ['"' + line.replace(",", '","') + '"' for line in lines[1:]]
    elif variant == "quoted header":
        lines[0] = '"t","x"'
    elif variant == "quote in a comment":
        lines = ['# exported by "logger', *lines]
    elif variant == "blank lines":
        lines = lines[:10] + ["", "  "] + lines[10:]
    elif variant == "padding spaces":
        lines = [lines[0]] + [line.replace(",", ",  ") + " " for line in lines[1:]]
    eol = {"crlf": "\r\n", "cr": "\r"}.get(variant, "\n")
    record = read_record(write(tmp_path, "variant.csv", eol.join(lines) + eol))
    check(record)
    assert record.time_column == "t" and record.signal_column == "x"
