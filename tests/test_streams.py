"""Standard streams that fail or are closed, and file names no encoding can write (issue 27).

Messages are secondary to results: a stderr that cannot take them never costs a result; a
closed stdout or stdin is one Error line; a file name that is not UTF-8, or that holds a
newline, is shown and written escaped. Each case runs a real ``python -m mcfit`` process,
bounded in time, with the stream as a shell would leave it.
"""

from __future__ import annotations

import csv
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mcfit import decay

TIMEOUT = 120  # seconds any one mcfit process may take, however loaded the machine
LATIN1_NAME = os.fsdecode(b"caf\xe9.csv")  # a latin-1 byte: not UTF-8


def _record(path, *, b=0.1, duration=20.0, rate=50.0, seed=1):
    """A hysteretic free decay exp(-b*t)*cos(2*pi*t) with a little Gaussian noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    x = decay.amplitude(t, 1.0, 0.0, b, 0.0) * np.cos(2 * np.pi * t)
    x = x + rng.normal(0.0, 1e-3, t.size)
    path.write_text("t,x\n" + "".join(f"{ti!r},{xi!r}\n" for ti, xi in zip(t.tolist(), x.tolist())))
    return path


def _mcfit(*arguments, closed=(), env=None, **streams):
    """Run mcfit in ``tmp`` with the descriptors in ``closed`` shut, as ``2>&-`` does."""
    def close():
        for descriptor in closed:
            os.close(descriptor)

    environment = dict(os.environ, **(env or {}))
    return subprocess.run([sys.executable, "-m", "mcfit", *map(str, arguments)],
                          preexec_fn=close if closed else None, env=environment,
                          timeout=TIMEOUT, **streams)


def _rows(text):
    return list(csv.DictReader(io.StringIO(text)))


@pytest.fixture
def batch(tmp_path):
    """good.csv, missing.csv (absent) and b.csv: a batch of two results and one failure."""
    _record(tmp_path / "good.csv")
    _record(tmp_path / "b.csv", seed=2)
    return [tmp_path / "good.csv", tmp_path / "missing.csv", tmp_path / "b.csv"]


def test_a_full_stderr_keeps_the_output_file_whole(tmp_path, batch):
    out = tmp_path / "out.csv"
    with open("/dev/full", "w") as full:
        result = _mcfit(*batch, "--format", "csv", "-o", out, stdout=subprocess.PIPE,
                        stderr=full, text=True)
    assert result.returncode == 1  # the batch's code: one record failed
    rows = _rows(out.read_text())
    assert [row["source"] for row in rows] == [str(f) for f in batch]
    assert [row["status"] for row in rows] == ["ok", "error", "ok"]
    assert not list(tmp_path.glob(".*.tmp"))


def test_a_full_stderr_keeps_every_row_on_stdout(batch):
    with open("/dev/full", "w") as full:
        result = _mcfit(*batch, "--format", "csv", stdout=subprocess.PIPE, stderr=full,
                        text=True)
    assert result.returncode == 1
    assert [row["status"] for row in _rows(result.stdout)] == ["ok", "error", "ok"]


def test_a_closed_stderr_keeps_the_results(tmp_path, batch):
    out = tmp_path / "out.csv"
    result = _mcfit(batch[0], batch[2], "--format", "csv", "-o", out, closed=(2,),
                    stdout=subprocess.PIPE)
    assert result.returncode == 0
    assert [row["status"] for row in _rows(out.read_text())] == ["ok", "ok"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.csv", "good.csv", "out.csv"]


def test_a_closed_stderr_takes_no_result_lines(tmp_path, batch):
    """Descriptor 2 is held on /dev/null: the output file never gets it, so nothing that
    writes to "stderr" can land in the results."""
    out = tmp_path / "out.csv"
    result = _mcfit(*batch, "--format", "csv", "-o", out, closed=(2,))
    assert result.returncode == 1
    assert [row["status"] for row in _rows(out.read_text())] == ["ok", "error", "ok"]


@pytest.mark.parametrize("arguments", [["{good}"], ["{good}", "--format", "json"],
                                       ["simulate", "--duration", "2"]],
                         ids=["text", "json", "simulate"])
def test_a_closed_stdout_is_one_error_line(tmp_path, batch, arguments):
    arguments = [a.format(good=batch[0]) for a in arguments]
    result = _mcfit(*arguments, closed=(1,), stderr=subprocess.PIPE, text=True)
    assert result.returncode == 1
    assert result.stderr == ("Error: cannot write stdout: it is closed; open it, or write "
                             "to a file instead.\n")


def test_a_closed_stdin_is_one_error_line():
    result = _mcfit("-", closed=(0,), capture_output=True, text=True)
    assert result.returncode == 1
    assert result.stderr == ("Error: cannot read stdin (-): it is closed; pipe a record "
                             "into mcfit or name a file.\n")
    assert result.stdout == ""


@pytest.mark.parametrize("output_format", ["csv", "text", "json"])
@pytest.mark.parametrize("locale", [None, "C"], ids=["default locale", "LANG=C"])
def test_a_name_that_is_not_utf8_is_written_escaped(tmp_path, batch, output_format, locale):
    latin1 = _record(tmp_path / LATIN1_NAME, seed=3)
    out = tmp_path / f"r.{output_format}"
    env = {"LANG": locale, "LC_ALL": locale} if locale else None
    result = _mcfit(batch[0], latin1, "--format", output_format, "-o", out, env=env,
                    capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    shown = f"{tmp_path}/caf\\xe9.csv"
    text = out.read_text(encoding="utf-8")
    if output_format == "csv":
        assert [row["source"] for row in _rows(text)] == [str(batch[0]), shown]
    elif output_format == "json":
        assert [json.loads(line)["source"] for line in text.splitlines()] == \
            [str(batch[0]), shown]
    else:
        assert f"mcfit report: {shown}\n" in text


def test_a_name_that_is_not_utf8_on_stdout(tmp_path, batch):
    latin1 = _record(tmp_path / LATIN1_NAME, seed=3)
    result = _mcfit(latin1, env={"PYTHONUTF8": "0", "LC_ALL": "C.UTF-8"},
                    capture_output=True)
    assert result.returncode == 0, result.stderr
    assert f"mcfit report: {tmp_path}/caf\\xe9.csv\n".encode() in result.stdout


def test_a_name_that_is_not_utf8_keeps_its_figure(tmp_path):
    latin1 = _record(tmp_path / LATIN1_NAME, seed=3)
    plots = tmp_path / "plots"
    result = _mcfit(latin1, "--format", "csv", "--plot-dir", plots, capture_output=True,
                    text=True)
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert [p.name for p in plots.iterdir()] == [os.fsdecode(b"caf\xe9.png")]
    assert (plots / os.fsdecode(b"caf\xe9.png")).read_bytes().startswith(b"\x89PNG")


def test_a_newline_in_a_bad_file_name_is_shown_escaped(tmp_path):
    bad = tmp_path / "bad\nname.csv"
    bad.write_text("t,x\n")
    result = _mcfit(bad, "--format", "csv", capture_output=True, text=True)
    assert result.returncode == 1
    assert result.stderr.startswith(f"Error: {tmp_path}/bad\\nname.csv has a header row but no "
                                    "data rows.")
    assert result.stderr.count("\n") == 1
    assert _rows(result.stdout)[0]["source"] == f"{tmp_path}/bad\\nname.csv"


def test_display_name():
    from mcfit.files import display_name

    assert display_name("plain/run.csv") == "plain/run.csv"
    assert display_name(os.fsdecode(b"a\xe9\xff.csv")) == "a\\xe9\\xff.csv"
    assert display_name("caf\u00e9.csv") == "caf\u00e9.csv"  # UTF-8 names stay as they are
    assert display_name("a\nb\tc\x1b.csv") == "a\\nb\\tc\\x1b.csv"
    assert display_name(Path("x.csv")) == "x.csv"
