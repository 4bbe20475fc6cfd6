"""CPU beside the items (client process; workers outside the items) for 200 spinning 35 ms items, by batch size and Dask settings (docs/fleet.md).

    OMP_NUM_THREADS=1 python benchmarks/fleet_beside_tasks.py 3 main:1,main:3,main:10,main:30,lean2:1,lean2:10,lean2:30
"""
import os, sys, time, logging, statistics
import psutil, dask.config
from dask.distributed import Client, LocalCluster
from robocal.estimation import parallel_map as pm

def spin(x, d=0.035):
    c0 = time.thread_time()
    while time.thread_time() - c0 < d: pass
    return time.thread_time() - c0

def cpu(p):
    try: t = p.cpu_times(); return t.user + t.system
    except psutil.NoSuchProcess: return 0.0

#: robocal's LocalCluster settings before issue 37's second round (main at 701482f)
BEFORE = {"distributed.worker.profile.enabled": False, "distributed.admin.tick.interval": "100ms",
          "distributed.scheduler.work-stealing": False}
LEAN = {**BEFORE, "distributed.admin.system-monitor.interval": "2s", "distributed.admin.tick.interval": "1s"}
LEAN2 = pm.LOCAL_CONFIG   # this tree's: LEAN with the memory monitor at 1 s instead of no memory limit
CONF = {"lean2": (LEAN2, {}), "main": (BEFORE, {}), "lean": (LEAN, {"memory_limit": 0})}

if __name__ == "__main__":
    reps, ways = int(sys.argv[1]), sys.argv[2].split(",")   # way = conf:b
    res = {}
    for conf in dict.fromkeys(w.split(":")[0] for w in ways):
        cfg, kw = CONF[conf]
        with dask.config.set(cfg), LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0",
                silence_logs=logging.WARNING, env=pm.WORKER_ENV, **kw) as cl, Client(cl) as c:
            c.gather(c.map(spin, range(4), pure=False))
            me = psutil.Process(); kids = me.children(recursive=True)
            for rep in range(reps):
                for w in [w for w in ways if w.startswith(conf + ":")]:
                    b = int(w.split(":")[1])
                    old = pm.batch_size; pm.batch_size = lambda *a, **k: b
                    m0, k0, t0 = cpu(me), sum(cpu(k) for k in kids), time.perf_counter()
                    done = [r for _, r, _ in pm.completed(c, spin, list(range(200)))]
                    wall = time.perf_counter() - t0
                    res.setdefault(w, []).append((wall, cpu(me) - m0, sum(cpu(k) for k in kids) - k0 - sum(done)))
                    pm.batch_size = old
    print("load", os.getloadavg())
    for w in ways:
        v = res[w]
        print(f"{w:<10} wall {statistics.median(x[0] for x in v):5.2f}  main cpu {statistics.median(x[1] for x in v):5.3f}  worker non-task cpu {statistics.median(x[2] for x in v):5.3f}")
