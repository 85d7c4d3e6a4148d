"""Running a batch on a Dask distributed cluster (``dask=ADDRESS``).

Each file is the same job as with ``jobs`` (:func:`mcfit.batch._job`), submitted to the
cluster's scheduler; the results come back in input order, each as soon as it and the
files before it are done. Only a few tasks per worker thread are in flight at a time, so
that a million files are not all submitted at once. ``distributed`` is imported here
only, when ``dask`` is given: it is an optional extra (``pip install 'mcfit-damping[dask]'``).
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from concurrent.futures import CancelledError
from itertools import islice

from mcfit import batch
from mcfit.errors import McfitError, UsageError

__all__ = ["run_jobs", "DaskBatch"]

INSTALL_HINT = "`dask` needs the dask extra: pip install 'mcfit-damping[dask]'"
TASKS_PER_THREAD = 4  # in flight per worker thread: each is busy while its next one waits
MIN_IN_FLIGHT = 8  # while the cluster has few workers, or none yet
RECOUNT_SECONDS = 10.0  # how often the cluster's threads are counted again (it may grow)


def run_jobs(sources, options, plot_paths, address):
    """Connect to the scheduler at ``address`` (or named in a scheduler file) and return the
    batch: iterate it for a :class:`batch.FileResult` per source, in input order; close it
    to cancel what is left and disconnect.

    Raises UsageError when the extra is missing or the workers would not find the files,
    McfitError when the scheduler cannot be reached or its workers lack this mcfit; nothing
    has been submitted then.
    """
    client = _connect(address)
    try:
        _check_workers(client, [*sources, *plot_paths])
    except BaseException:
        client.close()
        raise
    arguments = [(source, options, plot) for source, plot in zip(sources, plot_paths)]
    return DaskBatch(client, arguments)


def _connect(address):
    try:
        from distributed import Client
    except ImportError:
        raise UsageError(INSTALL_HINT) from None
    scheduler = _scheduler_address(address)
    try:
        return Client(scheduler, set_as_default=False)
    except (OSError, ValueError, TypeError) as error:  # TimeoutError is an OSError
        raise McfitError(f"cannot reach the Dask scheduler at {address}: {_one_line(error)}; "
                         "start it with 'dask scheduler' or check the address.") from None


def _scheduler_address(text):
    """The address given, or the one in a scheduler file (the one ``dask scheduler``
    writes where told to), checked here: given a malformed one, distributed's Client hangs
    for a minute when it is collected."""
    from distributed.comm import get_address_host_port

    address = text
    if os.path.isfile(text):
        try:
            with open(text, encoding="utf-8") as file:
                address = json.load(file)["address"]
        except (OSError, ValueError, KeyError, TypeError):
            address = None
    try:
        get_address_host_port(address)
    except (ValueError, TypeError):
        raise UsageError(f"`dask={text}` is not a scheduler's address or scheduler file; "
                         "give e.g. tcp://HOST:8786, or the scheduler file that dask scheduler "
                         "writes.") from None
    return address


def _check_workers(client, paths):
    """The workers present must have this version of mcfit (a worker that cannot import it
    dies on its first task) and, for relative paths, run in this directory.

    A worker is asked for the version of the mcfit it imports (:func:`_worker_version`),
    not for an installed distribution's: that works from a source tree on the path, and
    a worker whose ``mcfit`` is the other package of that name (fast integral
    transforms) cannot run it, and counts as lacking mcfit."""
    from mcfit import __version__

    found = client.run(_worker_version, on_error="return").values()
    other = sorted({v if isinstance(v, str) else "" for v in found} - {__version__})
    if other:
        has = f"has mcfit {other[-1]}" if other[-1] else "cannot import mcfit"
        raise McfitError(f"a Dask worker {has}, this is mcfit {__version__}; install mcfit "
                         f"{__version__} on every worker (pip install "
                         f"'mcfit-damping[dask]=={__version__}').")
    relative = [path for path in paths if path is not None and not os.path.isabs(path)]
    if not relative:
        return
    here = os.getcwd()
    elsewhere = sorted(set(client.run(os.getcwd).values()) - {here})
    if elsewhere:
        raise UsageError(f"`dask`: the workers run in {elsewhere[0]}, not in {here}, and "
                         f"would not find {relative[0]}; give absolute paths, or start the "
                         "workers in this directory.")


def _worker_version():
    """The version of the mcfit a worker imports (run there by :func:`_check_workers`)."""
    from mcfit import __version__

    return __version__


class DaskBatch:
    """The results of a batch on the cluster, in input order; :meth:`close` cancels the
    tasks still in flight and closes the connection (also when iteration never began)."""

    def __init__(self, client, arguments):
        self._client = client
        self._results = _stream(client, arguments)

    def __iter__(self):
        return self._results

    def close(self):
        try:
            self._results.close()
        finally:
            self._client.close()


def _stream(client, arguments):
    from distributed import as_completed

    unsent = enumerate(arguments)
    pending = {}  # future -> index of its file
    finished = {}  # index -> FileResult, held until the files before it are yielded
    completed = as_completed(loop=client.loop)
    limit = _InFlightLimit(client)
    next_index = 0
    try:
        while next_index < len(arguments):
            _submit(client, islice(unsent, max(limit() - len(pending), 0)), pending,
                    completed, finished)
            if next_index not in finished:  # then it is in flight: wait for a task
                future = next(completed)
                index = pending.pop(future)
                finished[index] = _result(future, arguments[index])
            while next_index in finished:
                yield finished.pop(next_index)
                next_index += 1
    finally:
        with contextlib.suppress(Exception):  # a client already closed has nothing to cancel
            client.cancel(list(pending), force=True)
        client.close()


def _submit(client, tasks, pending, completed, finished):
    for index, argument in tasks:
        try:
            future = client.submit(batch._job, argument, pure=False)
        except Exception as error:  # noqa: BLE001 - the client closed: scheduler lost
            finished[index] = _failed(argument, error)
            continue
        pending[future] = index
        completed.add(future)


class _InFlightLimit:
    """How many tasks to keep in flight: a few per thread of the cluster, counted again
    every RECOUNT_SECONDS as workers come and go."""

    def __init__(self, client):
        self._client = client
        self._value = MIN_IN_FLIGHT
        self._counted_at = None

    def __call__(self):
        now = time.monotonic()
        if self._counted_at is None or now - self._counted_at >= RECOUNT_SECONDS:
            self._counted_at = now
            try:
                threads = sum(self._client.nthreads().values())
            except Exception:  # noqa: BLE001 - reconnecting: keep the last count
                return self._value
            self._value = max(TASKS_PER_THREAD * threads, MIN_IN_FLIGHT)
        return self._value


def _result(future, argument):
    """The task's FileResult, or an error one when the cluster failed to run it (the job
    itself never raises)."""
    try:
        return future.result()
    except Exception as error:  # noqa: BLE001 - KilledWorker, cancelled, lost connection
        return _failed(argument, error)


def _failed(argument, error):
    source = argument[0]
    name = batch._display_name(source)
    kind = type(error).__name__
    if kind == "KilledWorker":
        message = (f"every Dask worker that tried to fit {name} died "
                   f"({error.allowed_failures + 1} tried; KilledWorker); fit it alone with "
                   "`jobs=1` to see why, or give the workers more memory.")
    elif isinstance(error, CancelledError):  # the scheduler lost, or the client closed
        message = (f"the Dask cluster dropped the fit of {name} (cancelled, reason: "
                   f"{getattr(error, 'reason', 'unknown')}); check that the scheduler is "
                   "running, then fit it again.")
    elif isinstance(error, ImportError):
        message = (f"a Dask worker could not run the fit of {name}: {kind}: "
                   f"{_one_line(error)}; install mcfit on every worker.")
    else:
        message = (f"the Dask cluster could not fit {name}: {kind}: {_one_line(error)}; "
                   "check the scheduler and workers, then fit it again.")
    return batch.FileResult.failed(source, message)


def _one_line(error, longest=300):
    text = " ".join(str(error).split()).rstrip(".") or "no details"
    return text if len(text) <= longest else text[:longest - 3] + "..."
