"""Bad and hard inputs (issue 7): a clear one-line error, never a traceback, nothing lost.

Every record of the corpus is made at test time in ``tmp_path``. A bad input must give
its exit code and exactly one line ``Error: ...`` on stderr naming the file, the problem and
the fix; a hard but valid input must fit (exit 0) and say in its JSON what it found.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit import decay
from mcfit.cli import cli
from process_tools import with_stop_signals

SEED = 1


@pytest.fixture
def runner():
    return CliRunner()


# --------------------------------------------------------------------------- record makers


def _rng():
    return np.random.default_rng(SEED)


def _write_table(path, t, x, header="t,x", sep=",", encoding="utf-8"):
    lines = [header] if header is not None else []
    lines += [f"{ti!r}{sep}{xi!r}" for ti, xi in zip(t.tolist(), x.tolist())]
    path.write_bytes(("\n".join(lines) + "\n").encode(encoding))
    return path


def _decay_record(path, *, a=0.0, b=0.1, c=0.0, y0=1.0, period=1.0, duration=30.0,
                  rate=50.0, noise=1e-3, scale=1.0, time_scale=1.0, header="t,x"):
    """A free decay y(t)*cos(w*t) of the amplitude law with Gaussian noise.

    ``scale`` multiplies the signal and ``time_scale`` the time axis, so one shape can be
    written in volts or picometres, seconds or hours.
    """
    t = np.arange(0.0, duration, 1.0 / rate)
    x = decay.amplitude(t, y0, a, b, c) * np.cos(2 * np.pi * t / period)
    x = x + _rng().normal(0.0, noise, t.size)
    return _write_table(path, t * time_scale, x * scale, header=header)


def _damped_oscillator(path, q, *, period=1.0, duration=30.0, rate=100.0, noise=1e-6):
    """The exact viscous solution exp(-w t/(2Q)) cos(w_d t): Q = w/(2b) of a pure b decay."""
    omega = 2 * np.pi / period
    gamma = omega / (2 * q)
    omega_d = np.sqrt(omega**2 - gamma**2)
    t = np.arange(0.0, duration, 1.0 / rate)
    x = np.exp(-gamma * t) * np.cos(omega_d * t) + _rng().normal(0.0, noise, t.size)
    return _write_table(path, t, x)


# Each maker takes tmp_path and returns the command-line arguments (the record first).


def _empty(tmp):
    (tmp / "empty.csv").write_bytes(b"")
    return [str(tmp / "empty.csv")]


def _blank_lines(tmp):
    (tmp / "blank.csv").write_text("\n   \n\t\n\n")
    return [str(tmp / "blank.csv")]


def _header_only(tmp):
    (tmp / "header.csv").write_text("time (s),angle (rad)\n")
    return [str(tmp / "header.csv")]


def _comments_only(tmp):
    (tmp / "notes.csv").write_text("# run 3, pendulum B\n# logger off\n")
    return [str(tmp / "notes.csv")]


def _binary_garbage(tmp):
    (tmp / "garbage.csv").write_bytes(_rng().integers(0, 256, 4096, dtype=np.uint8).tobytes())
    return [str(tmp / "garbage.csv")]


def _nul_bytes(tmp):
    (tmp / "zeros.dat").write_bytes(b"\x00" * 2048)
    return [str(tmp / "zeros.dat")]


def _utf16_without_bom(tmp):
    path = _decay_record(tmp / "utf16.csv", duration=5.0)
    path.write_bytes(path.read_text().encode("utf-16-le"))
    return [str(path)]


def _latin1_header(tmp):
    # Valid: a German logger writes Latin-1 headers with decimal commas.
    t = np.arange(0.0, 30.0, 0.02)
    x = decay.amplitude(t, 1.0, 0.0, 0.1, 0.0) * np.cos(2 * np.pi * t)
    x = x + _rng().normal(0.0, 1e-3, t.size)
    lines = ["Zeit (s);Auslenkung (°)"] + [f"{ti:.2f};{xi:.6f}".replace(".", ",")
                                            for ti, xi in zip(t, x)]
    (tmp / "latin1.csv").write_bytes(("\n".join(lines) + "\n").encode("latin-1"))
    return [str(tmp / "latin1.csv")]


def _set_signal(path, rows, value):
    """Overwrite the signal of the given data-file lines (line 0 is the header)."""
    lines = path.read_text().splitlines()
    for row in rows:
        lines[row] = lines[row].split(",")[0] + "," + value
    path.write_text("\n".join(lines) + "\n")
    return [str(path)]


def _text_in_numbers(tmp):
    return _set_signal(_decay_record(tmp / "text.csv", duration=5.0), [40], "overload")


def _open_quote(tmp):
    (tmp / "quote.csv").write_text('t,x\n0,1\n0.1,"0.5\n0.2,0.3\n0.3,-0.2\n')
    return [str(tmp / "quote.csv")]


def _latin1_past_the_first_megabyte(tmp):
    # The reader sniffs the first megabyte; a Latin-1 byte after it is found only later.
    path = _decay_record(tmp / "late.csv", b=0.001, duration=1500.0)
    text = path.read_bytes()
    cut = text.index(b"\n", 1_100_000) + 1
    path.write_bytes(text[:cut] + "réglage du zéro\n".encode("latin-1") + text[cut:])
    return [str(path)]


def _fifo(tmp):
    os.mkfifo(tmp / "pipe.csv")  # opening it to read would wait for a writer forever
    return [str(tmp / "pipe.csv")]


def _inf_in_signal(tmp):
    return _set_signal(_decay_record(tmp / "inf.csv", duration=10.0), (50, 51, 300), "inf")


def _nan_in_signal(tmp):
    return _set_signal(_decay_record(tmp / "nan.csv", duration=20.0), range(200, 205), "nan")


def _all_nan_signal(tmp):
    t = np.arange(0.0, 5.0, 0.02)
    (tmp / "allnan.csv").write_text("t,x\n" + "".join(f"{v!r},nan\n" for v in t.tolist()))
    return [str(tmp / "allnan.csv")]


def _inf_in_time(tmp):
    path = _decay_record(tmp / "inftime.csv", duration=10.0)
    lines = path.read_text().splitlines()
    lines[100] = "inf," + lines[100].split(",")[1]
    path.write_text("\n".join(lines) + "\n")
    return [str(path)]


def _single_row(tmp):
    (tmp / "one.csv").write_text("t,x\n0,1.0\n")
    return [str(tmp / "one.csv")]


def _duplicate_times(tmp):
    t = np.repeat(np.arange(0.0, 10.0, 0.1), 2)
    x = np.exp(-0.1 * t) * np.cos(2 * np.pi * t) + _rng().normal(0.0, 1e-3, t.size)
    return [str(_write_table(tmp / "dup.csv", t, x))]


def _decreasing_times(tmp):
    t = np.arange(0.0, 10.0, 0.02)
    x = np.exp(-0.1 * t) * np.cos(2 * np.pi * t)
    return [str(_write_table(tmp / "reversed.csv", t[::-1], x[::-1]))]


def _constant_signal(tmp):
    t = np.arange(0.0, 10.0, 0.02)
    return [str(_write_table(tmp / "flat.csv", t, np.full(t.size, 0.25)))]


def _pure_noise(tmp):
    t = np.arange(0.0, 20.0, 0.02)
    return [str(_write_table(tmp / "noise.csv", t, _rng().normal(0.0, 1.0, t.size)))]


def _step(tmp):
    t = np.arange(0.0, 20.0, 0.02)
    x = np.where(t < 7.0, 0.0, 1.0) + _rng().normal(0.0, 1e-3, t.size)
    return [str(_write_table(tmp / "step.csv", t, x))]


def _growing(tmp):
    t = np.arange(0.0, 30.0, 0.02)
    x = 0.1 * np.exp(0.08 * t) * np.cos(2 * np.pi * t) + _rng().normal(0.0, 1e-3, t.size)
    return [str(_write_table(tmp / "growing.csv", t, x))]


def _beating(tmp):
    t = np.arange(0.0, 60.0, 0.02)
    x = (np.cos(2 * np.pi * t) + 0.8 * np.cos(2 * np.pi * 1.05 * t)) * np.exp(-0.01 * t)
    x = x + _rng().normal(0.0, 1e-3, t.size)
    return [str(_write_table(tmp / "beating.csv", t, x))]


def _clipped_start(tmp):
    t = np.arange(0.0, 40.0, 0.01)
    x = 2.0 * np.exp(-0.08 * t) * np.cos(2 * np.pi * t) + _rng().normal(0.0, 1e-3, t.size)
    x = np.clip(x, -1.2, 1.2)  # the ADC saturates for the first cycles
    return [str(_write_table(tmp / "clipped.csv", t, x))]


def _three_turning_points(tmp):
    t = np.arange(0.0, 1.6, 0.01)
    x = np.exp(-0.1 * t) * np.sin(2 * np.pi * t + 0.1)  # crests at 0.23, 0.73, 1.23 s
    return [str(_write_table(tmp / "short.csv", t, x + _rng().normal(0.0, 1e-4, t.size)))]


def _tiny_amplitude(tmp):
    return [str(_decay_record(tmp / "tiny.csv", scale=1e-12))]


def _huge_amplitude(tmp):
    return [str(_decay_record(tmp / "huge.csv", scale=1e12))]


def _nanoseconds(tmp):
    # A 20 MHz resonator sampled every 2.5 ns, time in seconds: steps of 2.5e-9.
    return [str(_decay_record(tmp / "mems.csv", period=1.0, rate=20.0, duration=30.0,
                              time_scale=5e-8))]


def _hours(tmp):
    # A slow torsion balance: period 1 h, 60 h, sampled every 3 minutes, time in seconds.
    return [str(_decay_record(tmp / "torsion.csv", period=1.0, rate=20.0, duration=60.0,
                              b=0.05, time_scale=3600.0))]


def _low_q(tmp):
    return [str(_damped_oscillator(tmp / "q1_5.csv", 1.5, duration=6.0, rate=200.0,
                                   noise=1e-7))]


def _high_q(tmp):
    return [str(_damped_oscillator(tmp / "q1e6.csv", 1e6, duration=200.0, rate=20.0,
                                   noise=1e-7))]


def _noise_floor_tail(tmp):
    # Decays from 1 to 1e-6 in the first half, then 40 s of noise at 1e-3.
    return [str(_decay_record(tmp / "floor.csv", b=0.7, duration=60.0))]


def _pure_exponential(tmp):
    return [str(_decay_record(tmp / "exp.csv", b=0.1, noise=1e-3))]


def _all_three(tmp):
    return [str(_decay_record(tmp / "abc.csv", a=0.1, b=0.1, c=0.01, y0=4.0, period=0.5,
                              duration=20.0, rate=100.0, noise=5e-3))]


def _one_column(tmp):
    t = np.arange(0.0, 10.0, 0.02)
    x = np.exp(-0.1 * t) * np.cos(2 * np.pi * t)
    (tmp / "onecol.csv").write_text("x\n" + "".join(f"{v!r}\n" for v in x.tolist()))
    return [str(tmp / "onecol.csv")]


def _unknown_column(tmp):
    return [str(_decay_record(tmp / "run3.csv", duration=5.0)), "--signal-col", "angle"]


def _xlsx_random_zip(tmp):
    # Corrupt workbook: a zip archive without the parts of a workbook.
    with zipfile.ZipFile(tmp / "corrupt.xlsx", "w") as archive:
        archive.writestr("readme.txt", "not a workbook")
    return [str(tmp / "corrupt.xlsx")]


def _xlsx_truncated(tmp):
    (tmp / "cut.xlsx").write_bytes(b"PK\x03\x04" + _rng().bytes(500))
    return [str(tmp / "cut.xlsx")]


def _xlsx_encrypted(tmp):
    # openpyxl cannot write a password-protected workbook. Excel stores one as an OLE
    # compound file (CFB) holding the encrypted package, so a .xlsx that starts with the
    # CFB signature, padded to a sector, stands in for it.
    header = b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + bytes(16) + b"\x3e\x00\x03\x00\xfe\xff"
    (tmp / "locked.xlsx").write_bytes(header + bytes(512 - len(header)))
    return [str(tmp / "locked.xlsx")]


def _unsupported_extension(tmp):
    (tmp / "run.json").write_text('{"t": [0, 1], "x": [1, 0]}')
    return [str(tmp / "run.json")]


def _empty_directory(tmp):
    (tmp / "empty_dir").mkdir()
    return [str(tmp / "empty_dir")]


def _directory_named_like_a_record(tmp):
    (tmp / "dir.csv").mkdir()
    return [str(tmp / "dir.csv") + "/."]


def _missing_file(tmp):
    return [str(tmp / "nope.csv")]


def _path_through_a_file(tmp):
    (tmp / "notadir.csv").write_text("t,x\n")
    return [str(tmp / "notadir.csv" / "run.csv")]


def _empty_stdin(tmp):
    return ["-"]


def _unwritable_output(tmp):
    record = _decay_record(tmp / "good.csv", duration=10.0)
    return [str(record), "-o", str(tmp / "no_such_dir" / "out.json")]


def _output_below_a_file(tmp):
    record = _decay_record(tmp / "good.csv", duration=10.0)
    (tmp / "plain").write_text("")
    return [str(record), "-o", str(tmp / "plain" / "out.json")]


def _output_is_a_directory(tmp):
    record = _decay_record(tmp / "good.csv", duration=10.0)
    (tmp / "outdir").mkdir()
    return [str(record), "-o", str(tmp / "outdir")]


@dataclass(frozen=True)
class Case:
    """One corpus entry: how to make it and what the command line must say."""

    make: Callable[[Path], list]
    exit_code: int
    says: tuple = ()  # fragments of the one stderr line (after "Error: ")
    names: str | None = None  # the file the message must name (default: the record's name)
    check: Callable[[dict], None] | None = None  # for valid records: the JSON found
    stdin: str | None = None


BAD = {
    "empty": Case(_empty, 1, ("empty.csv is empty", "Give a file with")),
    "blank lines only": Case(_blank_lines, 1, ("blank.csv is empty",)),
    "header only": Case(_header_only, 1, ("header row but no data rows", "data below")),
    "comments only": Case(_comments_only, 1, ("only comments", "Give a file with data rows")),
    "binary garbage": Case(_binary_garbage, 1, ("is not a text record", "binary data",
                                                "CSV, TSV or text export")),
    "NUL bytes": Case(_nul_bytes, 1, ("is not a text record", "NUL bytes")),
    "Latin-1 past the first megabyte": Case(_latin1_past_the_first_megabyte, 1, (
        "past its first megabyte it is not utf-8 text", "Save the file as UTF-8")),
    "text in a numeric column": Case(_text_in_numbers, 1, (
        "text 'overload' in numeric column 'x' (column 2)", "data row 40", "Fix or delete")),
    "unbalanced quote": Case(_open_quote, 1, ("cannot parse", "Check the quotes")),
    "all-NaN signal": Case(_all_nan_signal, 1, ("no varying signal column", "--signal-col")),
    "single row": Case(_single_row, 1, ("has only 1 data row", "many samples")),
    "duplicate times": Case(_duplicate_times, 1, ("repeat the previous timestamp",
                                                  "--rate HZ")),
    "decreasing times": Case(_decreasing_times, 1, ("does not increase", "Sort the file")),
    "constant signal": Case(_constant_signal, 1, ("constant (0.25)", "--signal-col")),
    "pure noise": Case(_pure_noise, 1, ("no oscillation above the noise",
                                        "Check the signal column")),
    "step": Case(_step, 1, ("only 2 turning points", "several cycles")),
    "growing oscillation": Case(_growing, 1, ("grows", "not a free decay", "cut it")),
    "one column": Case(_one_column, 1, ("has one column", "no time column", "--rate HZ")),
    # An option that does not fit one file of a batch fails that file's row: exit 1.
    "unknown column": Case(_unknown_column, 1, (
        "column 'angle' not found in run3.csv; columns are: t, x. Use --signal-col.",)),
    "corrupt xlsx (zip without a workbook)": Case(_xlsx_random_zip, 1, (
        "cannot read corrupt.xlsx as an Excel workbook", "export CSV")),
    "corrupt xlsx (truncated)": Case(_xlsx_truncated, 1, ("cannot read cut.xlsx",
                                                          "export CSV")),
    "password-protected xlsx (stand-in)": Case(_xlsx_encrypted, 1, (
        "password-protected", "remove the password")),
    "unsupported extension": Case(_unsupported_extension, 1, ("unsupported file type '.json'",
                                                              "use .csv")),
    "FIFO": Case(_fifo, 1, ("not a regular file", "Copy the record to a file")),
    "empty directory": Case(_empty_directory, 2, ("holds no record files",
                                                  "name the files instead"),
                            names="empty_dir"),
    "directory named like a record": Case(_directory_named_like_a_record, 2, (
        "holds no record files",), names="dir.csv"),
    "missing file": Case(_missing_file, 1, ("file not found", "Check the path")),
    "path through a file": Case(_path_through_a_file, 1, (
        "file not found", "a part of the path is a file"), names="notadir.csv"),
    "empty stdin": Case(_empty_stdin, 1, ("<stdin> is empty",), names="<stdin>", stdin=""),
    "output directory missing": Case(_unwritable_output, 1, (
        "cannot write", "check that the directory exists"), names="out.json"),
    "output below a file": Case(_output_below_a_file, 1, (
        "cannot write", "Not a directory"), names="out.json"),
    "output path is a directory": Case(_output_is_a_directory, 2, (
        "is a directory; give a file name", "results.json"), names="outdir"),
}


def _model(expected):
    def check(data):
        assert data["model"] == expected, data
    return check


def _excluded(reason, model=None):
    def check(data):
        assert data["turning_points_excluded"].get(reason, 0) >= 1, data
        assert any(reason in note for note in data["notes"]), data["notes"]
        if model is not None:
            assert data["model"] == model, data
    return check


def _b_close_to(expected, rtol):
    def check(data):
        assert data["model"] == "b", data
        assert data["params"]["b"]["value"] == pytest.approx(expected, rel=rtol)
    return check


def _q_close_to(q, rtol):
    # The turning points' Q is w_d/(2*gamma) with the measured (damped) frequency w_d,
    # which for the viscous oscillator is w0*sqrt(1 - 1/(4*Q**2)): sqrt(Q**2 - 1/4), 1.414
    # for Q = 1.5; the velocity forms' waveform fit has w0 itself, and Q.
    def check(data):
        expected = q if data.get("damping_form") == "velocity" else np.sqrt(q**2 - 0.25)
        assert data["model"] == "b", data
        assert data["q"]["initial"] == pytest.approx(expected, rel=rtol)
        assert data["q"]["final"] == pytest.approx(expected, rel=rtol)
    return check


def _by_waveform(model):
    def check(data):
        assert data["model"] == model and data["method"] == "waveform", data
    return check


def _gaps(data):
    assert data["model"] == "b"
    assert any("without a signal value" in note for note in data["notes"]), data["notes"]


def _noted(fragment, model="b"):
    def check(data):
        assert data["model"] == model, data
        assert any(fragment in note for note in data["notes"]), data["notes"]
    return check


def _warned_and_left_out(fragment, reason):
    def check(data):
        assert any(fragment in warning for warning in data["warnings"]), data["warnings"]
        assert data["turning_points_excluded"].get(reason, 0) >= 1, data
    return check


def _latin1(data):
    assert data["model"] == "b"
    assert data["columns"] == {"time": "Zeit (s)", "signal": "Auslenkung (°)"}


VALID = {
    "pure exponential": Case(_pure_exponential, 0, check=_b_close_to(0.1, 0.02)),
    "all three regimes": Case(_all_three, 0, check=_model("abc")),
    "amplitude 1e-12": Case(_tiny_amplitude, 0, check=_b_close_to(0.1, 0.02)),
    "amplitude 1e12": Case(_huge_amplitude, 0, check=_b_close_to(0.1, 0.02)),
    "time in nanoseconds": Case(_nanoseconds, 0, check=_b_close_to(0.1 / 5e-8, 0.02)),
    "time in hours": Case(_hours, 0, check=_b_close_to(0.05 / 3600, 0.03)),
    "Q 1.5": Case(_low_q, 0, check=_q_close_to(1.5, 1e-4)),
    "3 turning points": Case(_three_turning_points, 0, check=_by_waveform("b")),
    "Q 1e6": Case(_high_q, 0, check=_q_close_to(1e6, 0.05)),
    "two beating modes": Case(_beating, 0, check=_warned_and_left_out(
        "beating of two modes", "after the decay")),
    "noise-floor tail": Case(_noise_floor_tail, 0, check=_excluded("noise floor", "b")),
    "clipped start": Case(_clipped_start, 0, check=_excluded("clipped", "b")),
    "NaN gaps in the signal": Case(_nan_in_signal, 0, check=_gaps),
    "inf in the signal": Case(_inf_in_signal, 0, check=_gaps),
    "Latin-1 header, decimal commas": Case(_latin1_header, 0, check=_latin1),
    "UTF-16 without BOM": Case(_utf16_without_bom, 0,
                               check=_noted("UTF-16 text without a byte-order mark")),
    "inf in the time column": Case(_inf_in_time, 0,
                                   check=_noted("1 rows without a time value dropped")),
}


def _no_traceback(result):
    assert "Traceback" not in result.output and "Traceback" not in result.stderr
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        repr(result.exception)


@pytest.mark.parametrize("case", BAD.values(), ids=BAD.keys())
def test_bad_input_is_one_clear_line(runner, tmp_path, case, monkeypatch):
    # Run from tmp_path with the records named relative to it, as a person there would:
    # messages quote the path as given.
    monkeypatch.chdir(tmp_path)
    arguments = [os.path.relpath(a, tmp_path) if a.startswith(str(tmp_path)) else a
                 for a in case.make(tmp_path)]
    result = runner.invoke(cli, [*arguments, "--format", "json"], input=case.stdin)
    _no_traceback(result)
    assert result.exit_code == case.exit_code, result.stderr
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("Error: "), result.stderr
    name = case.names or Path(arguments[0]).name
    assert name in result.stderr
    for fragment in case.says:
        assert fragment in result.stderr, result.stderr


@pytest.mark.parametrize("case", VALID.values(), ids=VALID.keys())
def test_hard_but_valid_input_fits(runner, tmp_path, case):
    arguments = case.make(tmp_path)
    result = runner.invoke(cli, [*arguments, "--format", "json"])
    _no_traceback(result)
    assert result.exit_code == 0, result.stderr + result.stdout
    assert result.stderr == ""
    data = json.loads(result.stdout)
    assert data["status"] == "ok" and data["error"] is None
    case.check(data)


def test_the_corpus_has_at_least_30_cases():
    assert len(BAD) + len(VALID) >= 30


# --------------------------------------------------------------------------- permissions


def _run_without_privileges(arguments, directory, warm_up):
    """Run the command line as an ordinary user, so that file permissions count.

    Root reads any file whatever its mode. Run as root, the test drops its effective user
    and group to ``nobody`` (65534) around the call instead of pretending; the kernel then
    refuses the access as it would for a lab account. The interpreter lives under /root,
    which nobody may not read, so a first run as root on a readable ``warm_up`` file
    imports every module the call needs.
    """
    runner = CliRunner()
    if os.geteuid() != 0:
        result = runner.invoke(cli, arguments)
        return result.exit_code, result.stderr, result.output
    os.chmod(directory, 0o755)
    assert runner.invoke(cli, [str(warm_up)]).exit_code == 0
    os.setegid(65534)
    os.seteuid(65534)
    try:
        result = runner.invoke(cli, arguments)
    finally:
        os.seteuid(0)
        os.setegid(0)
    return result.exit_code, result.stderr, result.output + repr(result.exception)


@pytest.fixture
def open_dir():
    """A directory that the unprivileged user can enter (tmp_path's parents are 0700)."""
    import tempfile

    directory = Path(tempfile.mkdtemp(prefix="mcfit-perm-"))
    yield directory
    for path in directory.rglob("*"):
        path.chmod(0o700)
    shutil.rmtree(directory)


@pytest.mark.parametrize("name", ["locked.csv", "locked.xlsx"])
def test_unreadable_file_is_one_clear_line(open_dir, name):
    path = open_dir / name
    if name.endswith(".csv"):
        _decay_record(path, duration=5.0)
    else:
        shutil.copy(Path(__file__).parents[1] / "sample_data" / "fig20_21_soup_can.xlsx", path)
    warm_up = open_dir / ("readable" + path.suffix)
    shutil.copy(path, warm_up)
    path.chmod(0o000)
    code, stderr, everything = _run_without_privileges([str(path)], open_dir, warm_up)
    assert "Traceback" not in everything
    assert code == 1
    assert stderr == (f"Error: cannot read {path}: Permission denied. "
                      "Check its permissions.\n")


def test_file_in_a_folder_that_cannot_be_entered(open_dir):
    closed = open_dir / "closed"
    closed.mkdir()
    record = _decay_record(closed / "run.csv", duration=5.0)
    warm_up = shutil.copy(record, open_dir / "readable.csv")
    closed.chmod(0o600)  # readable listing, but no entering (x bit)
    code, stderr, everything = _run_without_privileges([str(record)], open_dir, warm_up)
    assert "Traceback" not in everything
    assert code == 1
    assert stderr == (f"Error: cannot read {record}: Permission denied. Check the "
                      "permissions of the file and of its folders.\n")


# --------------------------------------------------------------------------- nothing lost


def _digest(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _record_files(tmp_path):
    """Every corpus record that is one plain file, each in its own folder."""
    files = []
    for number, case in enumerate([*BAD.values(), *VALID.values()]):
        folder = tmp_path / f"case{number:02d}"
        folder.mkdir()
        arguments = case.make(folder)
        if case.stdin is None and len(arguments) == 1 and Path(arguments[0]).is_file():
            files.append(arguments[0])
    return files


def test_inputs_are_never_modified(runner, tmp_path):
    files = _record_files(tmp_path)
    assert len(files) >= 25
    before = {f: (_digest(f), os.stat(f).st_mtime_ns, os.stat(f).st_mode) for f in files}
    out = tmp_path / "out.jsonl"
    # The fitting method does not touch the files; the turning points alone keep it quick.
    result = runner.invoke(cli, [*files, "--format", "json", "-o", str(out),
                                 "--method", "turning-points"])
    assert result.exit_code == 1  # the corpus holds bad records
    assert {f: (_digest(f), os.stat(f).st_mtime_ns, os.stat(f).st_mode) for f in files} \
        == before
    lines = out.read_text().splitlines()
    assert [Path(json.loads(line)["source"]).name for line in lines] \
        == [Path(f).name for f in files]


def test_a_batch_keeps_the_good_results_when_others_fail(runner, tmp_path):
    good = [_pure_exponential(tmp_path)[0], _all_three(tmp_path)[0]]
    bad = [_empty(tmp_path)[0], _growing(tmp_path)[0], str(tmp_path / "missing.csv")]
    order = [good[0], bad[0], bad[1], good[1], bad[2]]
    out = tmp_path / "results.csv"
    result = runner.invoke(cli, [*order, "--format", "csv", "-o", str(out)])
    _no_traceback(result)
    assert result.exit_code == 1
    rows = out.read_text().splitlines()[1:]
    assert [row.split(",")[1] for row in rows] == ["ok", "error", "error", "ok", "error"]
    assert rows[0].split(",")[2] == "b" and rows[3].split(",")[2] == "abc"
    assert result.stderr.count("\n") == 3 and result.stderr.count("Error: ") == 3


def test_a_bug_in_one_record_does_not_end_the_batch(runner, tmp_path, monkeypatch):
    from mcfit import analysis, batch

    first, second = _pure_exponential(tmp_path)[0], _all_three(tmp_path)[0]
    real = analysis.analyse_record

    def broken(record, **options):
        if Path(record.source).name == "abc.csv":
            raise ZeroDivisionError("float division by zero")
        return real(record, **options)

    monkeypatch.setattr(analysis, "analyse_record", broken)
    assert batch  # _job imports analyse_record from mcfit.analysis at call time
    result = runner.invoke(cli, [first, second, "--format", "json"])
    _no_traceback(result)
    assert result.exit_code == 1
    rows = [json.loads(line) for line in result.stdout.splitlines()]
    assert [row["status"] for row in rows] == ["ok", "error"]
    message = (f"internal error while fitting {second}: ZeroDivisionError: float division by "
               "zero (a bug in mcfit; please report it)")
    assert rows[1]["error"] == message
    assert result.stderr == f"Error: {message}\n"


def test_a_failing_run_leaves_no_partial_output_and_no_temporary_file(
        runner, tmp_path, monkeypatch):
    from mcfit import batch

    records = [_pure_exponential(tmp_path)[0], _all_three(tmp_path)[0]]
    out = tmp_path / "out.jsonl"
    out.write_text("previous results\n")
    real = batch.run_jobs

    def crashing(sources, options, plot_paths, jobs=1):
        results = real(sources, options, plot_paths, jobs=jobs)
        yield next(results)
        raise RuntimeError("the disk went away")

    monkeypatch.setattr(batch, "run_jobs", crashing)
    result = runner.invoke(cli, [*records, "--format", "json", "-o", str(out)])
    assert isinstance(result.exception, RuntimeError)  # a bug keeps its traceback
    assert out.read_text() == "previous results\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["abc.csv", "exp.csv", "out.jsonl"]


def test_interrupted_writer_keeps_the_finished_records(tmp_path, capsys):
    from mcfit import batch
    from mcfit.cli import _write_results

    sources = [_pure_exponential(tmp_path)[0], _all_three(tmp_path)[0], "never.csv"]
    options = batch.FitOptions(output_format="json")
    finished = list(batch.run_jobs(sources[:2], options, [None, None]))

    def interrupted():
        yield from finished
        raise KeyboardInterrupt

    out = tmp_path / "out.jsonl"
    with pytest.raises(SystemExit) as stopped:
        _write_results(interrupted(), sources, "json", str(out))
    assert stopped.value.code == 130
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [row["source"] for row in rows] == [str(s) for s in sources[:2]]
    assert "Interrupted: 2 of 3 records finished and kept in" in capsys.readouterr().err
    assert not list(tmp_path.glob("*.tmp"))


@pytest.mark.slow
def test_ctrl_c_keeps_the_records_already_finished(tmp_path):
    """A real SIGINT to ``python -m mcfit`` in the middle of a batch."""
    files = []
    # Records long enough (15000 samples) that the batch cannot end between the check for
    # two finished lines and the signal, even on a loaded machine.
    for i in range(40):
        folder = tmp_path / f"r{i:02d}"
        folder.mkdir()
        files.append(_decay_record(folder / f"run{i:02d}.csv", b=0.02, duration=300.0))
    out = tmp_path / "out.jsonl"
    process = subprocess.Popen(
        [sys.executable, "-m", "mcfit", *map(str, files), "--format", "json", "-o", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=with_stop_signals())
    deadline = time.monotonic() + 60
    try:
        while time.monotonic() < deadline:  # until the temporary file holds a whole line
            temporary = list(tmp_path.glob(".out.jsonl.*.tmp"))
            if temporary and temporary[0].read_bytes().count(b"\n") >= 2:
                break
            assert process.poll() is None, process.communicate()
            time.sleep(0.02)
        process.send_signal(signal.SIGINT)
        stdout, stderr = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 130, stderr
    assert "Traceback" not in stderr
    lines = out.read_text().splitlines()
    assert 2 <= len(lines) < len(files)
    rows = [json.loads(line) for line in lines]  # whole lines only
    assert [row["source"] for row in rows] == [str(f) for f in files[:len(rows)]]
    assert all(row["status"] == "ok" for row in rows)
    assert f"Interrupted: {len(rows)} of 40 records finished" in stderr
    assert not list(tmp_path.glob("*.tmp"))
