"""Dask distributed against Ray for Tumble's wedges: start-up, per-task overhead, install size.

    python benchmarks/wedge_engines.py             # both engines, 2 local workers
    python benchmarks/wedge_engines.py --tasks 400

Each engine runs in its own fresh interpreter (so one engine's imports do not warm the other's),
with one worker process per core and one thread each, as `tumble wedge` uses them. Figures:

- import: seconds to import the client library;
- start-up: seconds from nothing to a local cluster that has answered one task;
- latency: round trip of one tiny task, submitted and awaited one at a time (median of 50);
- overhead: wall time per task of a burst of `--tasks` tiny tasks submitted at once, divided by
  the task count (the scheduler's cost per task when the workers are kept busy);
- shutdown: seconds to close the cluster.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

CHILD = r"""
import json, os, statistics, sys, time
engine, workers, tasks = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])

def tiny(x):
    return x + 1

out = {}
t0 = time.perf_counter()
if engine == "dask":
    import dask.distributed as dd
    out["import_s"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    cluster = dd.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                              dashboard_address=None)
    client = dd.Client(cluster)
    client.submit(tiny, 0, pure=False).result()
    out["startup_s"] = time.perf_counter() - t1
    lat = []
    for i in range(50):
        t = time.perf_counter(); client.submit(tiny, i, pure=False).result(); lat.append(time.perf_counter() - t)
    out["latency_ms"] = 1000 * statistics.median(lat)
    t = time.perf_counter()
    futures = [client.submit(tiny, i, pure=False) for i in range(tasks)]
    for f in dd.as_completed(futures):
        f.result()
    out["overhead_ms"] = 1000 * (time.perf_counter() - t) / tasks
    t = time.perf_counter(); client.close(); cluster.close(); out["shutdown_s"] = time.perf_counter() - t
else:
    import ray
    out["import_s"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, configure_logging=False)
    rtiny = ray.remote(num_cpus=1)(tiny)
    ray.get(rtiny.remote(0))
    out["startup_s"] = time.perf_counter() - t1
    lat = []
    for i in range(50):
        t = time.perf_counter(); ray.get(rtiny.remote(i)); lat.append(time.perf_counter() - t)
    out["latency_ms"] = 1000 * statistics.median(lat)
    t = time.perf_counter()
    refs = [rtiny.remote(i) for i in range(tasks)]
    ray.get(refs)
    out["overhead_ms"] = 1000 * (time.perf_counter() - t) / tasks
    t = time.perf_counter(); ray.shutdown(); out["shutdown_s"] = time.perf_counter() - t
print("RESULT " + json.dumps(out))
"""


def measure(engine: str, workers: int, tasks: int) -> dict:
    """Run one engine's measurement in a fresh interpreter; returns its figures."""
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, engine, str(workers), str(tasks)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    raise RuntimeError(f"{engine}: {proc.stderr.strip().splitlines()[-1:] or proc.returncode}")


def install_size_mb(dist: str) -> float:
    """Megabytes of the installed files of one distribution (from its RECORD)."""
    from importlib import metadata

    total = 0
    for f in metadata.distribution(dist).files or []:
        path = f.locate()
        if os.path.isfile(path):
            total += os.path.getsize(path)
    return total / 1e6


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=os.cpu_count())
    parser.add_argument("--tasks", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=2, help="runs per engine (the best is kept)")
    args = parser.parse_args()
    print(
        f"load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}, "
        f"{os.cpu_count()} cores, {args.workers} workers, {args.tasks} tasks"
    )
    sizes = {"dask": sum(install_size_mb(d) for d in ("dask", "distributed")), "ray": install_size_mb("ray")}
    for engine in ("dask", "ray"):
        runs = [measure(engine, args.workers, args.tasks) for _ in range(args.repeat)]
        best = {k: min(r[k] for r in runs) for k in runs[0]}
        print(
            f"{engine:5s} install {sizes[engine]:6.1f} MB  import {best['import_s']:5.2f} s  "
            f"start-up {best['startup_s']:5.2f} s  latency {best['latency_ms']:6.2f} ms  "
            f"overhead {best['overhead_ms']:6.2f} ms/task  shutdown {best['shutdown_s']:5.2f} s"
        )
    print(f"load after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
