"""Per-unit time of calibrate_unit in one process at a time: main thread, a thread, a thread beside an asyncio loop, a Dask worker with and without a nanny, an in-process worker (docs/fleet.md, What separates Dask from plain processes).

    OMP_NUM_THREADS=1 python benchmarks/fleet_unit_context.py 60 3 main,thread,thread+loop20ms,dask,dask-nonanny,dask-inproc
"""
import os, sys, time, statistics, asyncio
os.environ.setdefault("OMP_NUM_THREADS", "1")
from concurrent.futures import ThreadPoolExecutor
from multiprocessing import get_context

def run_units(jobs):
    from robocal.workflows.fleet.unit import calibrate_unit
    out = []
    for j in jobs:
        t0, c0 = time.perf_counter(), time.thread_time()
        calibrate_unit(j)
        out.append((time.perf_counter() - t0, time.thread_time() - c0))
    return out

def ctx_main(jobs):
    run_units(jobs[:3]); return run_units(jobs)

def ctx_thread(jobs):
    with ThreadPoolExecutor(1) as ex:
        ex.submit(run_units, jobs[:3]).result()
        return ex.submit(run_units, jobs).result()

def ctx_thread_loop(jobs, tick=0.02):
    async def main():
        loop = asyncio.get_running_loop()
        stop = False
        async def ticker():
            while not stop:
                await asyncio.sleep(tick)
        t = asyncio.create_task(ticker())
        with ThreadPoolExecutor(1) as ex:
            await loop.run_in_executor(ex, run_units, jobs[:3])
            r = await loop.run_in_executor(ex, run_units, jobs)
        stop = True; await t
        return r
    return asyncio.run(main())

CTX = {"main": ctx_main, "thread": ctx_thread, "thread+loop20ms": ctx_thread_loop,
       "thread+loop100ms": lambda j: ctx_thread_loop(j, 0.1), "thread+loop3ms": lambda j: ctx_thread_loop(j, 0.003)}

def child(name, jobs):
    return CTX[name](jobs)

def dask_nonanny(jobs):
    import subprocess, logging, dask.config
    from dask.distributed import Client, LocalCluster
    from robocal.estimation.parallel_map import LOCAL_CONFIG, WORKER_ENV
    with dask.config.set(LOCAL_CONFIG), LocalCluster(n_workers=0, dashboard_address=":0", silence_logs=logging.WARNING) as cl, Client(cl) as c:
        env = {**os.environ, **WORKER_ENV, "DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED": "False",
               "DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL": "100ms"}
        w = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", cl.scheduler_address, "--no-nanny",
                              "--nthreads", "1", "--no-dashboard"], env=env, stderr=subprocess.DEVNULL)
        try:
            c.wait_for_workers(1)
            c.submit(run_units, jobs[:3], pure=False).result()
            return c.submit(run_units, jobs, pure=False).result()
        finally:
            w.terminate(); w.wait()

def dask_run(jobs, nanny=True, config=None):
    import dask.config, logging
    from dask.distributed import Client, LocalCluster
    from robocal.estimation.parallel_map import LOCAL_CONFIG, WORKER_ENV
    cfg = dict(LOCAL_CONFIG); cfg.update(config or {})
    with dask.config.set(cfg), LocalCluster(n_workers=1, threads_per_worker=1, processes=nanny, dashboard_address=":0",
                       silence_logs=logging.WARNING, **({"env": WORKER_ENV} if nanny else {})) as cl, Client(cl) as c:
        c.submit(run_units, jobs[:3], pure=False).result()
        return c.submit(run_units, jobs, pure=False).result()

if __name__ == "__main__":
    import tempfile
    from robocal.workflows.fleet.synthetic import simulated_fleet
    from robocal.workflows.fleet.manifest import load_fleet
    n, reps = int(sys.argv[1]), int(sys.argv[2])
    names = sys.argv[3].split(",")
    tmp = tempfile.mkdtemp()
    fleet = simulated_fleet(tmp, n, samples=30, seed=7)
    jobs = load_fleet(fleet.fleet_yaml).jobs
    ctx = get_context("spawn")
    res = {}
    for rep in range(reps):
        for name in names[rep % len(names):] + names[:rep % len(names)]:
            if name.startswith("dask"):
                r = dask_nonanny(jobs) if "nonanny" in name else dask_run(jobs, nanny=("inproc" not in name))
            else:
                with ctx.Pool(1) as p:
                    r = p.apply(child, (name, jobs))
            res.setdefault(name, []).append((statistics.median(w for w, _ in r), statistics.median(c for _, c in r),
                                             sum(w for w, _ in r)))
    print("load", os.getloadavg())
    for name in names:
        v = res[name]
        print(f"{name:<20} wall/unit ms {1e3*statistics.median(x[0] for x in v):6.1f}  cpu/unit ms {1e3*statistics.median(x[1] for x in v):6.1f}"
              f"  total s {statistics.median(x[2] for x in v):6.2f}   walls {[round(1e3*x[0],1) for x in v]}")
