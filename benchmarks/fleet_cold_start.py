"""CPU and wall of starting, first tasks and closing a 2-worker LocalCluster against a spawned pool of 2 (docs/fleet.md).

    OMP_NUM_THREADS=1 python benchmarks/fleet_cold_start.py
"""
import os, time, statistics
import psutil
from robocal.estimation.parallel_map import dask_client
from multiprocessing import get_context
def cpu_all():
    me = psutil.Process(); t = me.cpu_times(); tot = t.user + t.system + t.children_user + t.children_system
    for c in me.children(recursive=True):
        try: ct = c.cpu_times(); tot += ct.user + ct.system
        except psutil.NoSuchProcess: pass
    return tot
def imp(_):
    import robocal.workflows.fleet.unit  # noqa: F401  (the imports a unit needs)
    return os.getpid()
if __name__ == "__main__":
    res = {"dask": [], "pool": []}
    for rep in range(4):
        t0, c0 = time.perf_counter(), cpu_all()
        with dask_client(workers=2) as c:
            t1, c1 = time.perf_counter(), cpu_all()
            c.gather(c.map(imp, range(2), pure=False))
            t2, c2 = time.perf_counter(), cpu_all()
        res["dask"].append((t1 - t0, c1 - c0, t2 - t1, c2 - c1, time.perf_counter() - t2, cpu_all() - c2))
        t0, c0 = time.perf_counter(), cpu_all()
        with get_context("spawn").Pool(2) as p:
            t1, c1 = time.perf_counter(), cpu_all()
            p.map(imp, range(2), chunksize=1)
            t2, c2 = time.perf_counter(), cpu_all()
        res["pool"].append((t1 - t0, c1 - c0, t2 - t1, c2 - c1, time.perf_counter() - t2, cpu_all() - c2))
    for k, v in res.items():
        m = [statistics.median(x[i] for x in v) for i in range(6)]
        print(f"{k}: start wall {m[0]:.2f} cpu {m[1]:.2f} | first tasks (robocal import) wall {m[2]:.2f} cpu {m[3]:.2f} | close wall {m[4]:.2f} cpu {m[5]:.2f}")
    print("load", os.getloadavg())
