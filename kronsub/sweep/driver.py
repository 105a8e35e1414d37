"""The Dask driver: a sweep's chunks as tasks on a ``dask.distributed`` cluster.

By default a local cluster on this machine, one thread or process per core: for runs in
compiled code a worker in this process with a thread per core (the ensemble's C call releases
the GIL, and no process has to start; the libraries are loaded while the cluster starts), for
runs with Python in them (one by one, or a closed loop's projected initial values) a process
per core of one thread each; the local cluster leaves out what only a watcher of its dashboard
would use (:data:`QUIET`), which takes CPU time from the runs on a machine whose cores all
compute; ``scheduler`` (or ``DASK_SCHEDULER_ADDRESS``) sends the chunks to a
running cluster instead, and one that cannot be reached is an error within
:data:`CONNECT_SECONDS`. The job (model, plan, C sources) goes to the workers once; at most
:func:`window` chunks are in flight, so the client's memory does not grow with the number of
runs; each finished chunk is handed to ``done`` (which writes it) as it arrives, so an
interrupt keeps every chunk finished before it. A worker lost mid-sweep has its chunks rerun
elsewhere (by the scheduler, or by the driver when a task was cancelled with the job's copy
on that worker), each at most :data:`RETRIES` times."""
from __future__ import annotations

import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable

from ..errors import KronsubError
from ..interrupts import handled
from .chunk import ONE_BY_ONE, Job, run_chunk, warm
from .ensemble import stop

__all__ = ["CONNECT_SECONDS", "ENV_SCHEDULER", "QUIET", "RETRIES", "SchedulerError", "SweepLost", "SweepProgress",
           "execute", "local_cluster", "window"]

QUIET = {  # the local cluster's settings: no one looks at its dashboard
    "distributed.worker.profile.enabled": False,  # a sample of every thread's stack each 10 ms, under the GIL
    "distributed.admin.tick.interval": "500ms",  # each event loop's check of its own delay, every 20 ms
    "distributed.admin.system-monitor.interval": "2s",  # CPU, memory and network of the process, every 0.5 s
}

CONNECT_SECONDS = 5  # a scheduler that does not answer by then is reported, not waited for
ENV_SCHEDULER = "DASK_SCHEDULER_ADDRESS"
INSTALL_HINT = "pip install 'kronsub[sweep]'"


class SchedulerError(KronsubError):
    """The Dask scheduler could not be reached, or Dask is not installed."""


class SweepLost(KronsubError):
    """A chunk failed on the cluster more than :data:`RETRIES` times."""


RETRIES = 3  # reruns of a chunk lost with its worker before the sweep stops


def window(workers: int) -> int:
    """Chunks in flight: two per worker thread keeps each busy while its next one is sent."""
    return 2 * max(workers, 1) + 2


class SweepProgress:
    """Runs done, runs per second and time left on stderr (only on a terminal)."""

    def __init__(self, total: int, enabled: bool | None = None):
        self.total, self.done, self.start = total, 0, time.perf_counter()
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.shown = False

    def update(self, runs: int) -> None:
        self.done += runs
        if not self.enabled:
            return
        elapsed = max(time.perf_counter() - self.start, 1e-9)
        rate = self.done / elapsed
        left = (self.total - self.done) / rate if rate > 0 else float("inf")
        bar = "#" * int(30 * self.done / max(self.total, 1))
        sys.stderr.write(f"\r[{bar:<30}] {self.done:,}/{self.total:,} runs  {rate:,.0f} runs/s  {left:,.0f} s left ")
        sys.stderr.flush()
        self.shown = True

    def close(self) -> None:
        if self.shown:
            sys.stderr.write("\n")


def _connect(scheduler: str | None, workers: int | None, threads: bool = False):
    """A client of ``scheduler``, or of a new local cluster (``threads``: one worker in this
    process with ``workers`` threads): ``(client, cluster or None)``."""
    try:
        from distributed import Client
    except ImportError:
        raise SchedulerError(f"kronsub sweep needs dask.distributed and pyarrow\n  hint: {INSTALL_HINT}") from None
    if scheduler:
        try:
            return Client(scheduler, timeout=f"{CONNECT_SECONDS}s", set_as_default=False), None
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise SchedulerError(f"cannot reach the Dask scheduler at {scheduler} within {CONNECT_SECONDS} s "
                                 f"({first})\n  hint: start one with `dask scheduler` and workers with "
                                 f"`dask worker ADDRESS`, or leave out --scheduler (and {ENV_SCHEDULER}) for a "
                                 "local cluster") from None
    cluster = local_cluster(workers or os.cpu_count() or 1, threads)
    return Client(cluster, set_as_default=False), cluster


def local_cluster(count: int, threads: bool):
    """The local cluster of ``count`` cores: one worker in this process with a thread per core
    (``threads``), else a process per core with one thread."""
    import dask
    from distributed import LocalCluster

    # the scheduler's HTTP server on a free port: two sweeps at once do not warn of a taken one
    with dask.config.set(QUIET):  # read as the scheduler and workers start (and passed to worker processes)
        if threads:
            return LocalCluster(n_workers=1, threads_per_worker=count, processes=False, dashboard_address=":0",
                                silence_logs=logging.ERROR)
        # the workers ignore Ctrl-C, which the terminal sends the whole process group: the client
        # keeps the finished chunks and closes the cluster
        with handled(lambda signum: signum == signal.SIGINT, signal.SIG_IGN):
            return LocalCluster(n_workers=count, threads_per_worker=1, processes=True, dashboard_address=":0",
                                silence_logs=logging.ERROR)


def execute(job: Job, todo: Iterable[int], done: Callable[[int, dict], None], *, scheduler: str | None = None,
            workers: int | None = None, progress: SweepProgress | None = None) -> None:
    """Run the chunks ``todo`` of ``job``, calling ``done(index, rows)`` on the client as each
    finishes (in the order they finish)."""
    from distributed import as_completed

    stop(False)  # (a sweep stopped before in this process)
    # threads where the runs are C calls; a closed loop's initial values are projected in Python
    threads = job.route != ONE_BY_ONE and job.system.implicit is None
    if threads and not scheduler:  # the workers will be threads of this process: their libraries loaded meanwhile
        threading.Thread(target=warm, args=(job,), name="kronsub-sweep-warm", daemon=True).start()
    client, cluster = _connect(scheduler, workers, threads=threads)
    pending = list(todo)[::-1]
    tries: dict[int, int] = {}
    try:
        count = sum(w.get("nthreads", 1) for w in client.scheduler_info().get("workers", {}).values()) or (workers or 1)
        shared = [client.scatter(job, broadcast=True, hash=False)]
        chunk_of = {}

        def submit():
            index = pending.pop()
            future = client.submit(run_chunk, shared[0], index, pure=False,
                                   key=f"kronsub-sweep-{index}-{os.urandom(4).hex()}")
            chunk_of[future.key] = index
            return future

        with client.as_current():  # as_completed asks for the current client
            futures = as_completed([submit() for _ in range(min(window(count), len(pending)))], with_results=True,
                                   raise_errors=False)
            for future, rows in futures:
                index = chunk_of.pop(future.key)
                if future.status != "finished" or isinstance(rows, BaseException):
                    # lost with a worker (the job's copy there, or the task itself): run it again
                    tries[index] = tries.get(index, 0) + 1
                    future.release()
                    if tries[index] > RETRIES:
                        raise SweepLost(f"chunk {index} failed {tries[index]} times on the cluster "
                                        f"({type(rows).__name__}: {rows})\n  hint: check the workers' logs; "
                                        "--resume finishes the sweep without the chunks already written")
                    if future.status == "cancelled":
                        shared[0] = client.scatter(job, broadcast=True, hash=False)
                    pending.append(index)
                    futures.add(submit())
                    continue
                done(index, rows)
                if progress is not None:
                    progress.update(len(rows["run"]))
                future.release()
                if pending:
                    futures.add(submit())
    except BaseException:
        for name in ("distributed", "distributed.client", "distributed.scheduler", "tornado", "tornado.application"):
            logging.getLogger(name).setLevel(logging.CRITICAL + 1)  # the cancelled futures are not news
        stop()  # this process's worker threads start no further run: the cluster closes within a run, not a chunk
        raise
    finally:
        if progress is not None:
            progress.close()
        client.close()
        if cluster is not None:
            cluster.close()
