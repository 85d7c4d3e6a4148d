"""mcfit --dask (issue 17): the batch on a Dask cluster, here a local one of two worker
processes started by the tests.

The rows must be those of --jobs 1, in input order; a bad file and a task the cluster
loses (a worker killed) cost only their own row; closing the batch cancels what is left;
only a few tasks are in flight; workers without this mcfit, an unreachable scheduler and
the usage errors are one line each, before any output.
"""

from __future__ import annotations

import gc
import json
import os
import signal
import socket
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest
from click.testing import CliRunner

import mcfit
from mcfit import batch, dask_jobs
from mcfit.cli import cli

distributed = pytest.importorskip("distributed")
dask = pytest.importorskip("dask")

TIMEOUT = 120  # seconds any one mcfit process may take, however loaded the machine
FAST = ["--format", "json", "--method", "turning-points"]
NAMES = ["rec0.csv", "rec1.csv", "rec2.csv", "rec2_bad.csv", "rec3.csv", "rec4.csv"]


@pytest.fixture(scope="module")
def cluster():
    """Two single-thread worker processes; a task whose worker dies fails at once instead
    of being tried on another worker."""
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as local:
        yield local
    # distributed leaves its event loops' sockets to the garbage collector: collect them
    # here, with their ResourceWarnings, not in whichever test of this process runs next.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        gc.collect()


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """A folder of small records, one of them unreadable, and their paths in input order."""
    folder = tmp_path_factory.mktemp("records")
    for seed, name in enumerate(NAMES):
        if "bad" in name:
            (folder / name).write_text("t,x\nnot,numbers\n")
            continue
        rng = np.random.default_rng(seed)
        t = np.linspace(0.0, 20.0, 1000, endpoint=False)
        x = np.exp(-0.1 * t) * np.cos(2 * np.pi * t) + rng.normal(0.0, 1e-3, t.size)
        (folder / name).write_text("t,x\n" + "".join(f"{ti!r},{xi!r}\n" for ti, xi
                                                     in zip(t.tolist(), x.tolist())))
    return folder, [str(folder / name) for name in NAMES]


@pytest.fixture
def runner():
    return CliRunner()


def _mcfit(*arguments, cwd=None):
    """mcfit in a process of its own; the turning-point method, as the batch is tested."""
    return subprocess.run([sys.executable, "-m", "mcfit", *map(str, arguments),
                           "--method", "turning-points"],
                          capture_output=True, text=True, timeout=TIMEOUT, cwd=cwd)


def _sources(stdout):
    return [json.loads(line)["source"] for line in stdout.splitlines()]


def test_rows_are_those_of_jobs_1_in_input_order(cluster, records):
    folder, paths = records
    on_cluster = _mcfit(folder, "--dask", cluster.scheduler_address, "--format", "json")
    local = _mcfit(folder, "--jobs", "1", "--format", "json")
    assert on_cluster.returncode == local.returncode == 1, on_cluster.stderr
    assert on_cluster.stdout == local.stdout
    assert _sources(on_cluster.stdout) == paths
    statuses = [json.loads(line)["status"] for line in on_cluster.stdout.splitlines()]
    assert statuses == ["error" if "bad" in path else "ok" for path in paths]
    assert on_cluster.stderr == local.stderr
    assert on_cluster.stderr.count("Error:") == 1 and "rec2_bad.csv" in on_cluster.stderr


def test_a_slow_first_record_keeps_its_place(cluster, records, runner, monkeypatch):
    _, paths = records
    fit = batch._job

    def slow_first(argument):
        if argument[0] == paths[0]:
            time.sleep(2.0)  # the other workers finish the rest meanwhile
        return fit(argument)

    monkeypatch.setattr(batch, "_job", slow_first)
    result = runner.invoke(cli, [*paths, "--dask", cluster.scheduler_address, *FAST])
    assert result.exit_code == 1, result.output
    assert _sources(result.stdout) == paths


def test_a_killed_worker_costs_only_its_record(cluster, records, runner, monkeypatch):
    _, paths = records
    fit = batch._job

    def kill_on_second(argument):
        if argument[0] == paths[1]:
            os.kill(os.getpid(), signal.SIGKILL)  # as the out-of-memory killer would
        return fit(argument)

    monkeypatch.setattr(batch, "_job", kill_on_second)
    # One task per worker: the worker killed holds no other task that would fail with it.
    monkeypatch.setattr(dask_jobs, "TASKS_PER_THREAD", 1)
    monkeypatch.setattr(dask_jobs, "MIN_IN_FLIGHT", 1)
    good = [path for path in paths if "bad" not in path]
    result = runner.invoke(cli, [*good, "--dask", cluster.scheduler_address, *FAST])
    assert result.exit_code == 1, result.output
    rows = [json.loads(line) for line in result.stdout.splitlines()]
    assert [row["source"] for row in rows] == good
    assert [row["status"] for row in rows] == ["ok", "error", "ok", "ok", "ok"]
    assert "KilledWorker" in rows[1]["error"] and "died" in rows[1]["error"]
    assert result.stderr.count("Error:") == 1
    cluster.wait_for_workers(2, timeout=60)  # the nanny starts a new worker


def test_only_a_few_tasks_are_in_flight(cluster, records, runner, monkeypatch):
    _, paths = records
    monkeypatch.setattr(dask_jobs, "TASKS_PER_THREAD", 1)
    monkeypatch.setattr(dask_jobs, "MIN_IN_FLIGHT", 1)
    sent, back, in_flight = [], [], []
    submit, result_of = distributed.Client.submit, dask_jobs._result

    def counting_submit(self, *arguments, **options):
        sent.append(1)
        in_flight.append(len(sent) - len(back))
        return submit(self, *arguments, **options)

    def counting_result(future, argument):
        back.append(1)
        return result_of(future, argument)

    monkeypatch.setattr(distributed.Client, "submit", counting_submit)
    monkeypatch.setattr(dask_jobs, "_result", counting_result)
    result = runner.invoke(cli, [*paths, "--dask", cluster.scheduler_address, *FAST])
    assert _sources(result.stdout) == paths
    assert len(sent) == len(paths) and max(in_flight) == 2  # one per worker thread


def test_workers_elsewhere_and_relative_paths_are_a_usage_error(cluster, records):
    folder, _ = records
    result = _mcfit(folder.name, "--dask", cluster.scheduler_address, cwd=folder.parent)
    assert result.returncode == 2
    assert result.stderr.startswith("Error: --dask: the workers run in ")
    assert "give absolute paths" in result.stderr and result.stdout == ""


def test_closing_the_batch_cancels_the_tasks_left(cluster, records, monkeypatch):
    _, paths = records
    fit = batch._job

    def slow(argument):
        time.sleep(0.5 if argument[0] == paths[0] else 2.0)
        return fit(argument)

    monkeypatch.setattr(batch, "_job", slow)
    options = batch.FitOptions(output_format="json", method="turning-points")
    results = dask_jobs.run_jobs(paths, options, [None] * len(paths),
                                 cluster.scheduler_address)
    assert next(iter(results)).records[0]["analysis"]["source"] == paths[0]
    results.close()
    deadline = time.monotonic() + 10
    while cluster.scheduler.tasks and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not cluster.scheduler.tasks
    assert results._client.status == "closed"


def test_workers_without_this_mcfit_are_refused(cluster, records, runner, monkeypatch):
    _, paths = records
    monkeypatch.setattr(mcfit, "__version__", "0.0.1")  # the workers have the real one
    result = runner.invoke(cli, [*paths, "--dask", cluster.scheduler_address])
    assert result.exit_code == 1 and result.stdout == ""
    assert result.stderr.startswith("Error: a Dask worker has mcfit ")
    assert "install mcfit 0.0.1 on every worker" in result.stderr


def test_an_unreachable_scheduler_is_one_error_line(records):
    _, paths = records
    with socket.socket() as probe:  # a port that nothing listens on
        probe.bind(("127.0.0.1", 0))
        address = f"tcp://127.0.0.1:{probe.getsockname()[1]}"
    result = subprocess.run([sys.executable, "-m", "mcfit", paths[0], "--dask", address],
                            capture_output=True, text=True, timeout=TIMEOUT,
                            env={**os.environ, "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "1s"})
    assert result.returncode == 1 and result.stdout == ""
    assert result.stderr.startswith(f"Error: cannot reach the Dask scheduler at {address}: ")
    assert len(result.stderr.splitlines()) == 1


@pytest.mark.parametrize("arguments, message", [
    (["--jobs", "2"], "give --dask ADDRESS or --jobs N, not both"),
    (["-"], "--dask cannot read stdin (-)"),
    (["--dask", "no-port-here"], "is not a scheduler's address or scheduler file"),
])
def test_usage_errors(runner, records, arguments, message):
    _, paths = records
    files = [] if "-" in arguments else paths[:1]
    dask_address = [] if "--dask" in arguments else ["--dask", "tcp://127.0.0.1:8786"]
    result = runner.invoke(cli, [*files, *arguments, *dask_address], input="t,x\n")
    assert result.exit_code == 2
    assert message in result.stderr and len(result.stderr.splitlines()) == 1


def test_without_the_extra_one_line_says_how_to_install_it(runner, records, monkeypatch):
    _, paths = records
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    result = runner.invoke(cli, [paths[0], "--dask", "tcp://127.0.0.1:8786"])
    assert result.exit_code == 2
    assert result.stderr == "Error: --dask needs the dask extra: pip install 'mcfit-damping[dask]'\n"
