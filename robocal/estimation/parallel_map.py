"""A general parallel map: a function over items, in this process or on Dask, results in input order.

`map_tasks(fn, items)` runs in this process by default and on Dask (a LocalCluster of single-threaded
worker processes, or an existing scheduler) when asked; `monte_carlo(trial, n, seed)` maps a seeded trial
over n repetitions. Results are identical to the serial loop as long as `fn` is deterministic in its item
(a seed per item, never a shared RNG). Workers have BLAS pinned to one thread (OMP_NUM_THREADS=1 and the
like), so N workers use N cores without oversubscription. Fleet calibration (robocal.workflows.fleet),
plans, Monte-Carlo studies of the machines and robocal.testing use it. Dask is the optional [fleet]
extra: imported only inside the functions that start a cluster.

Monte-Carlo seeds: repetition k draws from its own Generator, seeded by the k-th child of numpy's
SeedSequence(seed) (SeedSequence.spawn): independent streams that depend on (seed, k) only, never on
which worker ran which repetition or in what order (docs/fleet.md, "Monte-Carlo studies on the cluster").
"""
from __future__ import annotations

import logging
import os
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Callable, Iterable, Iterator

import numpy as np

from robocal.errors import InputError

#: times a finished task's lost result is awaited again (its worker died before the result was fetched)
MAX_RESULT_WAITS = 3
#: set in every LocalCluster worker: one BLAS thread per single-threaded worker process
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

def repetition_seeds(seed, n: int) -> list[np.random.SeedSequence]:
    """The n child seeds of SeedSequence(seed), repetition k's being the k-th."""
    if int(n) != n or n < 0:
        raise InputError(f"the number of repetitions must be a non-negative integer, got {n}", field="n")
    return np.random.SeedSequence(seed).spawn(int(n))


@dataclass
class SeededTrial:
    """trial(Generator) as a function of a repetition's SeedSequence (picklable when trial is)."""
    trial: Callable

    def __call__(self, seed_sequence: np.random.SeedSequence):
        return self.trial(np.random.default_rng(seed_sequence))


def monte_carlo(trial: Callable, n: int, seed=0, scheduler: str | None = None, workers: int | None = None) -> list:
    """[trial(rng_0), ..., trial(rng_{n-1})], rng_k = default_rng(SeedSequence(seed).spawn(n)[k]).

    In this process by default; on a LocalCluster of `workers` processes or on the Dask scheduler at
    `scheduler` otherwise (the optional [fleet] extra), with the same results in the same order, as long
    as `trial` draws only from the Generator it is given. `trial` and what it returns must pickle for Dask.
    """
    return map_tasks(SeededTrial(trial), repetition_seeds(seed, n), scheduler, workers)
