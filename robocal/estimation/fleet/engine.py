"""The distributed engine: a Dask client on a LocalCluster (default) or on an existing scheduler.

Workers are processes with one thread each and BLAS pinned to one thread (OMP_NUM_THREADS=1 and the
like), so N workers use N cores without oversubscription. `map_tasks` is what fleet calibration and
Monte-Carlo studies share: a function mapped over items, results in input order, identical to the
serial loop as long as `fn` is deterministic in its item (a seed per item, never a shared RNG).
"""
from __future__ import annotations

import logging
import os
from contextlib import contextmanager
from typing import Callable, Iterable, Iterator

#: set in every LocalCluster worker: one BLAS thread per single-threaded worker process
#: times a finished task's lost result is awaited again (its worker died before the result was fetched)
MAX_RESULT_WAITS = 3
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def default_workers() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None):
    """A dask.distributed Client: on `scheduler` (an address such as tcp://host:8786) if given, else on a
    LocalCluster of `workers` single-threaded processes (default: the usable cores). Closed on exit."""
    from dask.distributed import Client, LocalCluster   # optional [fleet] extra

    if scheduler:
        client = Client(scheduler)
        try:
            yield client
        finally:
            client.close()
        return
    n = workers or default_workers()
    # dashboard on a free port (never a clash with another cluster); the cluster's own logs only from WARNING
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.WARNING, env=WORKER_ENV) as cluster, Client(cluster) as client:
        yield client


def completed(client, fn: Callable, items: list) -> Iterator[tuple[int, object, BaseException | None]]:
    """Submit fn(item) for every item; yield (index, result, None) or (index, None, exception) as each
    task finishes. A task whose workers died more often than the scheduler allows (KilledWorker) comes
    back as an exception; every other task is re-run elsewhere by Dask when its worker is lost."""
    from dask.distributed import as_completed   # optional [fleet] extra

    futures = [client.submit(fn, item, pure=False) for item in items]
    index = {f.key: i for i, f in enumerate(futures)}
    waits = dict.fromkeys(index, 0)
    pending = as_completed(futures)
    for future in pending:
        i = index[future.key]
        try:
            result = future.result()
        except Exception as exc:
            # A result that lived on a worker which died before it was fetched is computed again by
            # Dask (the future is no longer 'error'): wait for that instead of reporting a loss.
            if future.status != "error" and waits[future.key] < MAX_RESULT_WAITS:
                waits[future.key] += 1
                pending.add(future)
                continue
            yield i, None, exc   # the task's own error, or lost for good (KilledWorker): the caller records it
        else:
            yield i, result, None
        future.release()


def map_tasks(fn: Callable, items: Iterable, scheduler: str | None = None, workers: int | None = None) -> list:
    """[fn(item) for item in items], on Dask when `scheduler` or `workers` is given, else in this process.

    Results come back in input order; a task's exception is raised here.
    """
    items = list(items)
    if scheduler is None and workers is None:
        return [fn(item) for item in items]
    with dask_client(scheduler, workers) as client:
        futures = client.map(fn, items, pure=False)
        return client.gather(futures)
