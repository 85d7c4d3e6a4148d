"""Faults of the machine and of the output side (issue 19): dying workers, stop signals,
full disks and size limits, closed pipes, devices and FIFOs as outputs, outputs that would
destroy each other or be read back, and messages that reach a terminal.

Each case checks the exit code, stderr, that the outputs are whole or absent, that no
temporary file is left and that the inputs are unchanged. Signals and limits are tried on
real ``python -m mcfit`` processes, each bounded in time.
"""

from __future__ import annotations

import hashlib
import json
import os
import resource
import signal
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit import decay
from mcfit.cli import cli
from mcfit.errors import printable
from process_tools import children, with_stop_signals

TIMEOUT = 120  # seconds any one mcfit process may take, however loaded the machine


@pytest.fixture
def runner():
    return CliRunner()


def _record(path, *, b=0.1, y0=1.0, duration=30.0, rate=50.0, noise=1e-3, seed=1):
    """A hysteretic free decay y0*exp(-b*t)*cos(2*pi*t) with Gaussian noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    x = decay.amplitude(t, y0, 0.0, b, 0.0) * np.cos(2 * np.pi * t)
    x = x + rng.normal(0.0, noise * y0, t.size)
    path.write_text("t,x\n" + "".join(f"{ti!r},{xi!r}\n" for ti, xi in zip(t.tolist(), x.tolist())))
    return path


def _records(folder, count, **options):
    folder.mkdir(exist_ok=True)
    return [_record(folder / f"run{i:02d}.csv", seed=i, **options) for i in range(count)]


def _digests(paths):
    return {str(p): hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in paths}


def _temporary_files(*folders):
    return [p for folder in folders for p in Path(folder).iterdir() if p.name.endswith(".tmp")]


def _mcfit(*arguments):
    return [sys.executable, "-m", "mcfit", *map(str, arguments)]


def _wait_for(condition, process, what):
    """Poll ``condition`` until true; fail if the process ends first or time runs out."""
    deadline = time.monotonic() + TIMEOUT
    while not condition():
        assert process.poll() is None, (what, process.communicate())
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.02)


def _lines_in_temporary(folder, name):
    temporary = list(Path(folder).glob(f".{name}.*.tmp"))
    return temporary[0].read_bytes().count(b"\n") if temporary else 0


# --------------------------------------------------------------------------- workers, signals


@pytest.mark.slow
def test_a_killed_worker_costs_only_its_record(tmp_path):
    """SIGKILL (as the out-of-memory killer sends it) to a real worker of a --jobs 2 batch."""
    if not Path(f"/proc/{os.getpid()}/task/{os.getpid()}/children").exists():
        pytest.skip("needs /proc/PID/task/TID/children to find the worker processes")
    # The bootstrap makes each record take seconds, so a worker is caught mid-record.
    files = _records(tmp_path / "runs", 5, duration=60.0)
    before = _digests(files)
    out = tmp_path / "out.csv"
    process = subprocess.Popen(_mcfit(*files, "--jobs", "2", "--bootstrap", "400",
                                      "--seed", "1", "--format", "csv", "-o", out),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for(lambda: len(children(process.pid)) == 2, process, "two workers")
        time.sleep(0.5)  # both are fitting their first record by now
        victim = children(process.pid)[0]
        os.kill(victim, signal.SIGKILL)
        stdout, stderr = process.communicate(timeout=TIMEOUT)
    finally:
        process.kill()
    assert process.returncode == 1, stderr
    assert "Traceback" not in stderr
    rows = out.read_text().splitlines()[1:]
    assert [row.split(",")[0] for row in rows] == [str(f) for f in files]  # every record
    lost = [row for row in rows if row.split(",")[1] == "error"]
    assert len(lost) == 1
    assert sum(row.split(",")[1] == "ok" for row in rows) == 4
    assert ("was killed by signal 9 (SIGKILL), likely by the out-of-memory killer; fit it "
            "again alone") in lost[0]
    assert stderr.count("\n") == 1 and stderr.startswith("Error: the worker process fitting ")
    assert not children(process.pid)
    assert _digests(files) == before
    assert not _temporary_files(tmp_path, tmp_path / "runs")


@pytest.mark.slow
@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_a_stop_signal_keeps_the_finished_records(tmp_path, stop):
    """SIGTERM (as timeout or a scheduler sends it) or SIGHUP to a real --jobs 1 batch."""
    files = _records(tmp_path / "runs", 30, duration=300.0)
    before = _digests(files)
    out = tmp_path / "out.jsonl"
    process = subprocess.Popen(_mcfit(*files, "--format", "json", "-o", out),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=with_stop_signals())
    try:
        _wait_for(lambda: _lines_in_temporary(tmp_path, "out.jsonl") >= 2, process,
                  "two finished records")
        process.send_signal(stop)
        stdout, stderr = process.communicate(timeout=TIMEOUT)
    finally:
        process.kill()
    assert process.returncode == 128 + stop, stderr
    assert "Traceback" not in stderr
    rows = [json.loads(line) for line in out.read_text().splitlines()]  # whole lines only
    assert 2 <= len(rows) < len(files)
    assert [row["source"] for row in rows] == [str(f) for f in files[:len(rows)]]
    assert stderr == (f"\nStopped by {stop.name}: {len(rows)} of 30 records finished and "
                      f"kept in {out}.\n")
    assert _digests(files) == before
    assert not _temporary_files(tmp_path, tmp_path / "runs")


@pytest.mark.slow
def test_a_stop_signal_ignored_when_mcfit_starts_stays_ignored(tmp_path):
    """``nohup mcfit ...``: SIGHUP, ignored by whoever started mcfit, does not stop the
    batch; every record is fitted and kept (it once did stop it, with exit code 129)."""
    files = _records(tmp_path / "runs", 8, duration=300.0)
    out = tmp_path / "out.jsonl"
    process = subprocess.Popen(_mcfit(*files, "--format", "json", "-o", out),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=with_stop_signals(signal.SIG_IGN))
    try:
        _wait_for(lambda: _lines_in_temporary(tmp_path, "out.jsonl") >= 2, process,
                  "two finished records")
        process.send_signal(signal.SIGHUP)
        stdout, stderr = process.communicate(timeout=TIMEOUT)
    finally:
        process.kill()
    assert process.returncode == 0, stderr
    assert "Stopped" not in stderr
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [row["source"] for row in rows] == [str(f) for f in files]


@pytest.mark.slow
def test_a_stop_signal_to_a_batch_with_workers_ends_them(tmp_path):
    files = _records(tmp_path / "runs", 4, duration=60.0)
    out = tmp_path / "out.csv"
    process = subprocess.Popen(_mcfit(*files, "--jobs", "2", "--bootstrap", "400", "--format",
                                      "csv", "-o", out),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=with_stop_signals())
    try:
        _wait_for(lambda: len(children(process.pid)) == 2, process, "two workers")
        workers = children(process.pid)
        process.send_signal(signal.SIGTERM)
        stdout, stderr = process.communicate(timeout=TIMEOUT)
    finally:
        process.kill()
    assert process.returncode == 143, stderr
    assert "Traceback" not in stderr and "Stopped by SIGTERM" in stderr
    assert out.read_text().startswith("source,status,")
    for worker in workers:  # ended with mcfit, not left fitting
        assert not Path(f"/proc/{worker}").exists() or \
            "Z" in Path(f"/proc/{worker}/stat").read_text().split()[2]
    assert not _temporary_files(tmp_path)


# --------------------------------------------------------------------------- write errors


def test_stdout_on_a_full_device_is_one_error_line(tmp_path):
    record = _record(tmp_path / "run.csv")
    with open("/dev/full", "w") as full:
        result = subprocess.run(_mcfit(record, "--format", "json"), stdout=full,
                                stderr=subprocess.PIPE, text=True, timeout=TIMEOUT)
    assert result.returncode == 1
    assert result.stderr == ("Error: cannot write stdout: No space left on device; the disk "
                             "is full; free some space or write elsewhere.\n")


def test_simulate_to_a_full_device_is_one_error_line():
    with open("/dev/full", "w") as full:
        result = subprocess.run(_mcfit("simulate", "--duration", "100"), stdout=full,
                                stderr=subprocess.PIPE, text=True, timeout=TIMEOUT)
    assert result.returncode == 1
    assert result.stderr.startswith("Error: cannot write stdout: No space left on device")
    assert result.stderr.count("\n") == 1


def _file_size_limit(limit):
    def set_limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return set_limit


@pytest.mark.parametrize("command", ["fit", "simulate"])
def test_output_past_the_file_size_limit_keeps_the_old_file(tmp_path, command):
    """A file-size limit (ulimit -f) as a full file system: the old file stays whole."""
    files = _records(tmp_path / "runs", 3)
    before = _digests(files)
    out = tmp_path / "out.csv"
    out.write_text("earlier results\n")
    arguments = ([*files, "--format", "csv"] if command == "fit"
                 else ["simulate", "--duration", "100"])
    # mcfit itself must turn SIGXFSZ (which kills by default) into the EFBIG error.
    environment = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    result = subprocess.run(_mcfit(*arguments, "-o", out), capture_output=True, text=True,
                            preexec_fn=_file_size_limit(800), env=environment,
                            timeout=TIMEOUT)
    assert result.returncode == 1, result.stderr
    assert result.stderr == (f"Error: cannot write {out}: File too large; the file-size limit "
                             f"(ulimit -f) was reached; raise it or write elsewhere; {out} was "
                             "left as it was.\n")
    assert out.read_text() == "earlier results\n"
    assert _digests(files) == before
    assert not _temporary_files(tmp_path)


@pytest.mark.parametrize("command", ["fit", "simulate"])
def test_a_closed_pipe_is_quiet(tmp_path, command):
    """``mcfit ... | head -1``: the reader goes away; no message, no traceback."""
    files = _records(tmp_path / "runs", 6)
    arguments = ([*files, "--format", "json"] if command == "fit"
                 else ["simulate", "--duration", "20000"])
    process = subprocess.Popen(_mcfit(*arguments), stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE)
    try:
        first = process.stdout.readline()
        process.stdout.close()  # as head does after its line
        stderr = process.stderr.read()
        process.wait(timeout=TIMEOUT)
    finally:
        process.kill()
        process.stderr.close()
    assert first
    assert process.returncode == 1
    assert stderr == b""
    assert not _temporary_files(tmp_path, tmp_path / "runs")


def _run_without_privileges(arguments, directory, warm_up):
    """The command line as the user nobody when run as root (root writes any file).

    The interpreter may live where nobody cannot read (/root): a first run of ``warm_up``
    as root imports every module the call needs.
    """
    runner = CliRunner()
    if os.geteuid() != 0:
        return runner.invoke(cli, arguments)
    assert runner.invoke(cli, warm_up).exit_code == 0
    os.chmod(directory, 0o777)
    os.setegid(65534)
    os.seteuid(65534)
    try:
        return runner.invoke(cli, arguments)
    finally:
        os.seteuid(0)
        os.setegid(0)


@pytest.fixture
def open_dir():
    """A directory the unprivileged user can enter (tmp_path's parents are 0700)."""
    import shutil
    import tempfile

    directory = Path(tempfile.mkdtemp(prefix="mcfit-fault-"))
    yield directory
    shutil.rmtree(directory)


def test_a_read_only_output_file_is_not_replaced(open_dir):
    """Its directory would let the file be renamed over; its mode says it is not to be."""
    record = _record(open_dir / "run.csv")
    out = open_dir / "kept.csv"
    out.write_text("earlier results\n")
    out.chmod(0o444)
    before = _digests([record])
    arguments = [str(record), "--format", "csv", "-o"]
    result = _run_without_privileges([*arguments, str(out)], open_dir,
                                     [*arguments, str(open_dir / "warm-up.csv")])
    assert result.exit_code == 1, (result.output, result.exception)
    assert result.stderr == (f"Error: cannot write {out}: Permission denied; check its "
                             "permissions, or write elsewhere.\n")
    assert out.read_text() == "earlier results\n"
    assert _digests([record]) == before
    assert sorted(p.name for p in open_dir.iterdir()) == ["kept.csv", "run.csv",
                                                          "warm-up.csv"]


# --------------------------------------------------------------------------- output targets


def test_a_device_output_is_written_in_place(runner, tmp_path):
    """As root, a rename would replace the device node /dev/null by a regular file."""
    record = _record(tmp_path / "run.csv")
    result = runner.invoke(cli, [str(record), "--format", "csv", "-o", os.devnull])
    assert result.exit_code == 0, result.output
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode)
    assert not _temporary_files(tmp_path)
    result = runner.invoke(cli, ["simulate", "--duration", "1", "-o", os.devnull])
    assert result.exit_code == 0, result.output
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode)


def test_a_fifo_output_is_written_in_place(runner, tmp_path):
    record = _record(tmp_path / "run.csv")
    fifo = tmp_path / "results.fifo"
    os.mkfifo(fifo)
    received = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_text()), daemon=True)
    reader.start()
    result = runner.invoke(cli, [str(record), "--format", "csv", "-o", str(fifo)])
    reader.join(timeout=TIMEOUT)
    assert result.exit_code == 0, result.output
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert received[0].startswith("source,status,") and received[0].count("\n") == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.fifo", "run.csv"]


def test_an_output_through_a_symbolic_link_keeps_the_link(runner, tmp_path):
    record = _record(tmp_path / "run.csv")
    (tmp_path / "real.csv").write_text("old\n")
    link = tmp_path / "latest.csv"
    link.symlink_to("real.csv")
    result = runner.invoke(cli, [str(record), "--format", "csv", "-o", str(link)])
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and (tmp_path / "real.csv").read_text().startswith("source,")
    assert not _temporary_files(tmp_path)


@pytest.mark.parametrize("make, message", [
    (lambda d, r: [r, "-o", d / "report.png", "--plot", d / "report.png"],
     "-o {d}/report.png and --plot both name {d}/report.png; one would overwrite the other. "
     "Give them different names."),
    (lambda d, r: [r, "-o", d / "plots" / "run.png", "--plot-dir", d / "plots"],
     "-o {d}/plots/run.png and --plot-dir both name {d}/plots/run.png; one would overwrite "
     "the other. Give them different names."),
    (lambda d, r: [d, "-o", r, "--format", "csv"],
     "-o {d}/run.csv is one of the input records; choose another output file, inputs are "
     "never overwritten."),
], ids=["-o and --plot", "-o and --plot-dir", "-o on a record of an input directory"])
def test_outputs_that_clash_are_usage_errors_before_any_work(runner, tmp_path, make, message):
    record = _record(tmp_path / "run.csv")
    before = sorted(p.name for p in tmp_path.iterdir())
    result = runner.invoke(cli, [str(a) for a in make(tmp_path, record)])
    assert result.exit_code == 2
    assert result.stderr == "Error: " + message.format(d=tmp_path) + "\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


# --------------------------------------------------------------------------- messages


def test_control_characters_in_a_message_are_escaped(runner, tmp_path):
    name = tmp_path / "run\x1b[2J\x07.csv"  # would clear the screen and ring the bell
    result = runner.invoke(cli, [str(name)])
    assert result.exit_code == 1
    assert result.stderr == (f"Error: file not found: {tmp_path}/run\\x1b[2J\\x07.csv. Check "
                             "the path and the working directory.\n")


def test_control_characters_in_a_column_name_are_escaped(runner, tmp_path):
    record = _record(tmp_path / "run.csv")
    result = runner.invoke(cli, [str(record), "--signal-col", "\x1b]0;owned\x07"])
    assert result.exit_code == 1
    assert "column '\\x1b]0;owned\\x07' not found" in result.stderr
    assert not any(c < " " for c in result.stderr.replace("\n", ""))


def test_notes_of_a_text_report_are_escaped(runner, tmp_path):
    record = _record(tmp_path / "run.csv")
    record.write_text(record.read_text().replace("t,x", "t,x\x1b[31m", 1))
    result = runner.invoke(cli, [str(record)])
    assert result.exit_code == 0, result.output
    assert "x\\x1b[31m" in result.stdout
    assert not any(c < " " for c in result.stdout.replace("\n", ""))


def test_a_long_message_keeps_its_cause_and_its_fix():
    message = "cause " + "\x00" * 3000 + " " + "y" * 5000 + " fix"
    shown = printable(message)
    assert shown.startswith("cause \\x00*3000 yyy") and shown.endswith("yyy fix")
    assert len(shown) == 1000 and " ... " in shown
    assert printable("tab\there, line\nthere") == "tab here, line there"
    assert printable("\u202eevil") == "\\u202eevil"


def test_numpy_warnings_never_reach_stderr(tmp_path):
    """An amplitude of 1e-300 underflows on the way; only the Error line is shown."""
    record = _record(tmp_path / "tiny.csv", y0=1e-300, duration=20.0)
    result = subprocess.run(_mcfit(record, "--format", "json"), capture_output=True,
                            text=True, timeout=TIMEOUT)
    assert "Warning" not in result.stderr
    assert all(line.startswith("Error: ") for line in result.stderr.splitlines())
    assert result.returncode in (0, 1)


def test_a_stop_signal_while_simulate_writes_leaves_no_temporary_file(runner, tmp_path,
                                                                        monkeypatch):
    out = tmp_path / "record.csv"
    out.write_text("earlier record\n")

    def stopped_midway(*arguments, **options):
        os.kill(os.getpid(), signal.SIGTERM)  # handled by mcfit: raises in this thread

    monkeypatch.setattr(np, "savetxt", stopped_midway)  # simulate writes with np.savetxt
    handler = signal.getsignal(signal.SIGTERM)
    result = runner.invoke(cli, ["simulate", "--duration", "1", "-o", str(out)])
    assert result.exit_code == 143
    assert result.stderr == f"\nInterrupted: the record was not written whole; {out} was " \
                            "left as it was.\n"
    assert out.read_text() == "earlier record\n"
    assert not _temporary_files(tmp_path)
    assert signal.getsignal(signal.SIGTERM) == handler  # restored after the run
