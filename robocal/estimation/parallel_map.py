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

import gc
import logging
import os
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable, Iterable, Iterator

import numpy as np

from robocal.errors import InputError

#: set in every LocalCluster worker: one BLAS thread per single-threaded worker process
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
#: times a finished task's lost result is awaited again (its worker died before the result was fetched)
MAX_RESULT_WAITS = 3
#: Dask's cost per task: CPU of every process (the client and scheduler, the worker's event loop, serialisation)
#: per task on a 2-worker LocalCluster of this machine, 4.0-7.4 ms measured by benchmarks/fleet.py and
#: fleet_beside_tasks.py (the CPU of 200 spinning 35 ms items sent one per task against 30 per task; docs/fleet.md,
#: "Batches"), what `batch_size` weighs items against. CPU, not wall time: on a machine whose cores the workers fill, it is taken from the workers.
TASK_OVERHEAD_S = 0.006
#: the share of a task that the per-task cost may take: 2 % of the 10 % that N workers may lose to N plain
#: processes (issue 37), the rest left to what does not scale with tasks (the cluster's own periodic work,
#: the table, the first and last tasks)
OVERHEAD_SHARE = 0.02
#: a task lasts at most this long (s) once item times are known (results flow about as often as a table is written)
MAX_TASK_S = 1.0
#: tasks in flight per worker (one running, one waiting), and at least this many tasks per worker for what is left
TASKS_PER_WORKER = 2
#: Dask settings of the LocalCluster robocal starts. Its workers share the machine's cores with the scheduler, the
#: client and the nannies, so whatever runs beside the tasks is taken from them. Off or slower: the statistical
#: profiler (it samples each task thread 100 times a second for the dashboard), work stealing (`completed` keeps
#: two tasks per worker anyway), the event-loop health check (20 ms -> 1 s), the system monitor (psutil's CPU,
#: memory, network and disk counters in every process, 500 ms -> 2 s) and the memory monitor (each worker's and
#: its nanny's RSS, 100 ms -> 1 s; the memory limits still hold, checked once a second). Measured on 2 workers
#: (benchmarks/fleet_beside_tasks.py, docs/fleet.md): the CPU of everything but the items, 0.52 s -> 0.16 s for 200
#: items of 35 ms sent 30 a task; an idle cluster 2.7-3.0 % -> 1.0 % of a core.
LOCAL_CONFIG = {"distributed.worker.profile.enabled": False, "distributed.scheduler.work-stealing": False,
                "distributed.admin.tick.interval": "1s", "distributed.admin.system-monitor.interval": "2s",
                "distributed.worker.memory.monitor-interval": "1s",
                # Dask's default also sets MALLOC_TRIM_THRESHOLD_=65536 in every worker, which fixes glibc's mmap
                # threshold: each numpy temporary above 128 kB is then mapped and unmapped afresh, and a 30-pose
                # UR5 unit ran 5-8 % slower in a process with it (benchmarks/fleet_unit_context.py, docs/fleet.md)
                "distributed.nanny.pre-spawn-environ": dict(WORKER_ENV)}


def default_workers() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


@contextmanager
def dask_client(scheduler=None, workers: int | None = None):
    """A dask.distributed Client: `scheduler` itself when it is a Client already (left open: its owner closes it),
    a new one on `scheduler` when it is an address (such as tcp://host:8786), else on a LocalCluster of `workers`
    single-threaded processes (default: the usable cores). Those it made are closed on exit.

    Handing over a running Client spares a second connection in the process, with its own event-loop thread
    beside the first (on 200 UR5 units and 2 workers the two ways measured within the benchmark's spread:
    docs/fleet.md, "What separates Dask from plain processes")."""
    from dask.distributed import Client, LocalCluster   # optional [fleet] extra

    if isinstance(scheduler, Client):
        yield scheduler
        return
    if scheduler:
        client = Client(scheduler)
        try:
            yield client
        finally:
            client.close()
        return
    import dask.config   # optional [fleet] extra

    n = workers or default_workers()
    # dashboard on a free port (never a clash with another cluster); the cluster's own logs only from WARNING;
    # LOCAL_CONFIG: less background work beside the tasks (the workers inherit it through their nannies)
    with dask.config.set(LOCAL_CONFIG), \
            LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                         silence_logs=logging.WARNING, env=WORKER_ENV) as cluster, Client(cluster) as client:
        yield client


def batch_size(unit_seconds: float | None, left: int, workers: int, overhead_seconds: float | None = None,
               share: float | None = None, max_task_seconds: float | None = None) -> int:
    """Items per Dask task: the fewest that keep Dask's per-task cost (overhead_seconds, default
    TASK_OVERHEAD_S) at most `share` (OVERHEAD_SHARE) of a task, b >= overhead (1 - share) / (share unit_seconds);
    at most what lasts max_task_seconds (MAX_TASK_S: results reach the caller, and a fleet's rows its table,
    about as often as the table is written) and at most an even share of what is left over TASKS_PER_WORKER
    tasks per worker (no worker idles while another finishes a long task at the end). 1 while the item time
    is not known yet. The defaults are read when called (a benchmark may set the module's constants)."""
    overhead_seconds = TASK_OVERHEAD_S if overhead_seconds is None else overhead_seconds
    share = OVERHEAD_SHARE if share is None else share
    max_task_seconds = MAX_TASK_S if max_task_seconds is None else max_task_seconds
    if not unit_seconds or unit_seconds <= 0:
        return 1
    wanted = int(np.ceil(overhead_seconds * (1 - share) / (share * unit_seconds)))
    by_time = max(1, int(max_task_seconds / unit_seconds + 1e-9))
    by_balance = max(1, left // (TASKS_PER_WORKER * max(workers, 1)))
    return max(1, min(wanted, by_time, by_balance))


@dataclass
class Batch:
    """fn over a list of items in one task: per item (result, exception, seconds, warm), where warm says the
    process had run an item before (the first one in a fresh worker also pays its imports). origin: the process
    that made the batch (the caller's heap is never frozen, should a task run there)."""
    fn: Callable
    origin: int = field(default_factory=os.getpid)

    def __call__(self, items: list) -> list[tuple]:
        out = []
        for item in items:
            warm = RUNS[0] > 0
            RUNS[0] += 1
            t0 = time.perf_counter()
            try:
                out.append((self.fn(item), None, time.perf_counter() - t0, warm))
            except Exception as exc:       # this item's error: reported for it alone, the batch goes on
                out.append((None, exc, time.perf_counter() - t0, warm))
        if not FROZEN and os.getpid() != self.origin:
            freeze_heap()
        return out


#: items this process has run in Batch tasks (a worker's first one includes its imports)
RUNS = [0]
#: set once this process's heap has been frozen (freeze_heap)
FROZEN: list = []


def freeze_heap() -> None:
    """After a worker's first task: collect, then move every object alive (the interpreter's, Dask's and robocal's
    modules, the worker's own state: ~90k objects, against ~50k in a plain process) into the permanent generation
    (gc.freeze), so the cyclic collector stops walking them at each full collection while the items run. They stay
    alive anyway; reference counting still frees them. Measured on 200 UR5 units and 2 workers (docs/fleet.md,
    "What separates Dask from plain processes"): 90 % -> 96 % of 2 plain processes' speed in a probe of
    `completed`, 90 % -> 92 % in benchmarks/fleet.py's `fleet run` (15 repeats)."""
    gc.collect()
    gc.freeze()
    FROZEN.append(True)


def completed(client, fn: Callable, items: list) -> Iterator[tuple[int, object, BaseException | None]]:
    """fn(item) for every item on the client's cluster; yield (index, result, None) or (index, None, exception)
    as each finishes. Items go in batches (`batch_size`, from the item times measured so far: single items
    first), with TASKS_PER_WORKER tasks in flight per worker, so a worker always has its next task waiting.
    A task whose workers died more often than the scheduler allows (KilledWorker) comes back as an exception
    for each of its items; every other task is re-run elsewhere by Dask when its worker is lost, so no item
    is lost and each is yielded exactly once."""
    from dask.distributed import as_completed   # optional [fleet] extra

    task = Batch(fn)
    queue, seconds = list(range(len(items))), []
    batch_of: dict[str, list[int]] = {}
    waits: dict[str, int] = {}
    pending = as_completed()

    known = [-np.inf, 1]        # (when, task slots): asked of the scheduler at most once a second (an RPC)

    def slots() -> int:
        if time.monotonic() - known[0] > 1.0:
            known[:] = [time.monotonic(), max(1, sum(client.nthreads().values()))]
        return known[1]

    def submit() -> None:
        n = slots()
        unit = float(np.median(seconds)) if seconds else None
        while queue and len(batch_of) < TASKS_PER_WORKER * n:
            take = batch_size(unit, len(queue), n)
            idx, queue[:take] = queue[:take], []
            future = client.submit(task, [items[i] for i in idx], pure=False)
            batch_of[future.key], waits[future.key] = idx, 0
            pending.add(future)

    submit()
    for future in pending:
        idx = batch_of[future.key]
        try:
            out = future.result()
        except Exception as exc:
            # A result that lived on a worker which died before it was fetched is computed again by
            # Dask (the future is no longer 'error'): wait for that instead of reporting a loss.
            if future.status != "error" and waits[future.key] < MAX_RESULT_WAITS:
                waits[future.key] += 1
                pending.add(future)
                continue
            out = [(None, exc, 0.0, False)] * len(idx)   # lost for good (KilledWorker): the caller records it
        del batch_of[future.key]
        future.release()
        seconds += [t for _, e, t, warm in out if warm and e is None]
        submit()                       # the next tasks go out before the caller handles these results
        for i, (result, exc, _, _) in zip(idx, out):
            yield i, result, exc


def map_tasks(fn: Callable, items: Iterable, scheduler=None, workers: int | None = None) -> list:
    """[fn(item) for item in items], on Dask when `scheduler` (an address or a Client: dask_client) or `workers`
    is given, else in this process.

    Results come back in input order; an item's exception is raised here (after every item has run).
    """
    items = list(items)
    if scheduler is None and workers is None:
        return [fn(item) for item in items]
    results, errors = [None] * len(items), {}
    with dask_client(scheduler, workers) as client:
        for i, result, exc in completed(client, fn, items):
            results[i] = result
            if exc is not None:
                errors[i] = exc
    if errors:
        raise errors[min(errors)]
    return results


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


def monte_carlo(trial: Callable, n: int, seed=0, scheduler=None, workers: int | None = None) -> list:
    """[trial(rng_0), ..., trial(rng_{n-1})], rng_k = default_rng(SeedSequence(seed).spawn(n)[k]).

    In this process by default; on a LocalCluster of `workers` processes or on the Dask scheduler at
    `scheduler` otherwise (the optional [fleet] extra), with the same results in the same order, as long
    as `trial` draws only from the Generator it is given. `trial` and what it returns must pickle for Dask.
    """
    return map_tasks(SeededTrial(trial), repetition_seeds(seed, n), scheduler, workers)
