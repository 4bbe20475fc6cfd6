"""CPU of an idle 2-worker LocalCluster by process, for Dask settings (docs/fleet.md).

    OMP_NUM_THREADS=1 python benchmarks/fleet_idle.py 8 default,before,+memlimit0,+sysmon2s,+sysmon2s+tick1s,LOCAL_CONFIG
"""
import sys, time, logging
import psutil, dask.config
from dask.distributed import Client, LocalCluster
from robocal.estimation.parallel_map import LOCAL_CONFIG, WORKER_ENV

#: robocal's LocalCluster settings before issue 37's second round (main at 701482f)
BEFORE = {"distributed.worker.profile.enabled": False, "distributed.admin.tick.interval": "100ms",
          "distributed.scheduler.work-stealing": False}
VARIANTS = {
    "default": ({}, {}),
    "LOCAL_CONFIG": (LOCAL_CONFIG, {}),
    "before": (BEFORE, {}),
    "+memlimit0": (BEFORE, {"memory_limit": 0}),
    "+sysmon2s": ({**BEFORE, "distributed.admin.system-monitor.interval": "2s"}, {"memory_limit": 0}),
    "+sysmon2s+tick1s": ({**BEFORE, "distributed.admin.system-monitor.interval": "2s",
                          "distributed.admin.tick.interval": "1s"}, {"memory_limit": 0}),
}

def cpu(p):
    t = p.cpu_times(); return t.user + t.system

def measure(name, secs):
    cfg, kw = VARIANTS[name]
    with dask.config.set(cfg), LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0",
            silence_logs=logging.WARNING, env=WORKER_ENV, **kw) as cl, Client(cl) as c:
        c.submit(sum, [1], pure=False).result(); time.sleep(1)
        me = psutil.Process()
        procs = {"client+scheduler+nannies": me}
        for ch in me.children(recursive=True):
            procs[f"workers{ch.pid}"] = ch     # the nannies live in this process (LocalCluster)
        c0 = {k: cpu(p) for k, p in procs.items()}
        time.sleep(secs)
        d = {k: (cpu(p) - c0[k]) / secs for k, p in procs.items()}
    agg = {}
    for k, v in d.items():
        kk = "".join(ch for ch in k if not ch.isdigit())
        agg[kk] = agg.get(kk, 0) + v
    print(f"{name:<20}" + "  ".join(f"{k} {100*v:5.2f}%" for k, v in agg.items()) + f"  total {100*sum(agg.values()):5.2f}% of a core", flush=True)

if __name__ == "__main__":
    for name in sys.argv[2].split(","):
        measure(name, float(sys.argv[1]))
