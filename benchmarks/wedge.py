"""A 16-variant wedge of the 1k sphere pile: `tumble wedge` on a local cluster against the 16 run one after another.

    PYTHONPATH=src python benchmarks/wedge.py                   # 16 seeds, 2 s each, one worker per core
    PYTHONPATH=src python benchmarks/wedge.py --variants 8 --duration 1
    PYTHONPATH=src python benchmarks/wedge.py --end-to-end       # on an idle machine

Both sides do the same work per variant (`tumble.wedge.run_variant`: build the scene, step it
round(duration / dt) times, measure, render the final frame). The serial side runs the variants in
this process after an untimed warm-up (so its kernels are loaded: the baseline most favourable to
serial). The wedge side is `tumble.wedge` calls (planning, every variant, the manifest and the
contact sheet) plus the start-up of a local cluster. On a shared machine the load changes from
minute to minute, so by default the two sides alternate in rounds of `--workers` variants on one
cluster (each round waits for its slowest variant, which favours serial); `--end-to-end` runs the
16 serially and then one wedge of all 16 from a cold start, the plain statement of the target
for an idle machine. Figures:

- ratio: wedge wall time / serial wall time (target <= 0.6 on 2 cores);
- start-up: a local cluster of the same size up and answering one tiny task;
- overhead per task: (wedge wall - start-up - sum of variant wall times / workers) / variants,
  i.e. what the wedge costs per variant beyond the simulation itself;
- the load average before and after (other processes on the machine distort every figure).

On Linux with autogroup scheduling (/proc/sys/kernel/sched_autogroup_enabled = 1) a busy CPU is
shared equally between sessions, so on a machine shared with other users the two workers of one
wedge get no more CPU than a single serial process: the ratio then says nothing about the
parallelism. `--own-sessions` (under `setsid`) puts each worker in a session of its own, as on a
machine where they would have a core each.

A row is appended to benchmarks/results/wedge.csv.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
if (HERE.parent / "src" / "tumble").is_dir():
    sys.path.insert(0, str(HERE.parent / "src"))

import tumble
from tumble.wedge import Settings, cluster, plan_wedge, run_variant

RESULTS = HERE / "results" / "wedge.csv"


def _noop() -> int:
    return 0


def _serial(plan, variants, settings) -> tuple[float, list[dict]]:
    start = time.perf_counter()
    rows = [
        run_variant(
            {
                "name": v.name,
                "text": v.text,
                "path": str(plan.source),
                "folder": "/nonexistent",
                "settings": settings.identity(),
            }
        )
        for v in variants
    ]
    return time.perf_counter() - start, rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="sphere_pile")
    parser.add_argument("--variants", type=int, default=16)
    parser.add_argument("--duration", type=float, default=2.0)
    parser.add_argument("--workers", type=int, default=os.cpu_count())
    parser.add_argument(
        "--end-to-end",
        action="store_true",
        help="all serial runs, then one wedge of every variant (for an idle machine); by default "
        "the two alternate in rounds of --workers variants on one cluster",
    )
    parser.add_argument(
        "--own-sessions",
        action="store_true",
        help="put each worker in a session of its own (setsid); run this script under setsid too. "
        "Linux's autogroup scheduler shares a busy CPU between sessions, not processes, so "
        "on a shared machine all the workers of one session get one session's share",
    )
    parser.add_argument("--no-csv", action="store_true")
    args = parser.parse_args()
    if args.own_sessions and os.getsid(0) != os.getpid():
        print("--own-sessions: run this script as `setsid python benchmarks/wedge.py --own-sessions`")
        return 2

    load_before = os.getloadavg()
    vary = {"world.seed": f"0..{args.variants - 1}"}
    plan = plan_wedge(args.scene, vary)
    settings = Settings(duration=args.duration)
    mode = "end-to-end" if args.end_to_end else f"alternating rounds of {args.workers}"
    print(
        f"{args.variants} variants of {plan.source.name}, {args.duration:g} s each, {args.workers} workers, "
        f"{mode}; load {load_before[0]:.2f} {load_before[1]:.2f} {load_before[2]:.2f}",
        flush=True,
    )

    # warm-up of this process (kernels loaded), not timed
    run_variant(
        {
            "name": "warm",
            "text": plan.variants[0].text,
            "path": str(plan.source),
            "folder": "/nonexistent",
            "settings": Settings(duration=0.05).identity(),
        }
    )

    # start-up alone: a local cluster answering one task
    start = time.perf_counter()
    with cluster(workers=args.workers) as client:
        client.submit(_noop, pure=False).result()
        startup = time.perf_counter() - start
    print(f"start-up {startup:7.2f} s  (local cluster of {args.workers} answering one task)", flush=True)

    out = Path(tempfile.mkdtemp(prefix="tumble-wedge-bench-"))
    serial, wall, serial_rows, table_rows = 0.0, 0.0, [], []
    try:
        if args.end_to_end:
            serial, serial_rows = _serial(plan, plan.variants, settings)
            start = time.perf_counter()
            table = tumble.wedge(
                args.scene, vary, out=out / "w", duration=args.duration, workers=args.workers, progress=False
            )
            wall = time.perf_counter() - start
            table_rows = table.rows
        else:
            # the same load falls on both sides: serial, then the wedge, a round of --workers variants at a time,
            # the wedge on one cluster (its start-up counted once, above)
            with cluster(workers=args.workers) as client:
                client.submit(_noop, pure=False).result()
                if args.own_sessions:
                    client.run(os.setsid)
                for k in range(0, args.variants, args.workers):
                    seeds = f"{k}..{min(k + args.workers, args.variants) - 1}"
                    t, rows = _serial(plan, plan.variants[k : k + args.workers], settings)
                    serial += t
                    serial_rows += rows
                    start = time.perf_counter()
                    table = tumble.wedge(
                        args.scene,
                        {"world.seed": seeds},
                        out=out / f"w{k}",
                        duration=args.duration,
                        address=client,
                        progress=False,
                    )
                    wall += time.perf_counter() - start
                    table_rows += table.rows
                    print(
                        f"  round {k // args.workers + 1}: serial {t:6.2f} s, wedge {table_rows[-1]['wall_s']:6.2f} s "
                        f"a variant; load {os.getloadavg()[0]:.2f}",
                        flush=True,
                    )
            wall += startup
    finally:
        shutil.rmtree(out, ignore_errors=True)
    failed = [r for r in serial_rows + table_rows if r["status"] != "ok"]
    if failed:
        print(f"a variant failed: {failed[0]['error']}")
        return 1
    print(f"serial   {serial:7.2f} s  ({serial / args.variants:.2f} s a variant)", flush=True)
    same = [r["state_hash"] for r in table_rows] == [r["state_hash"] for r in serial_rows]
    busy = sum(r["wall_s"] for r in table_rows) / args.workers
    overhead = (wall - startup - busy) / args.variants
    load_after = os.getloadavg()
    ratio = wall / serial
    print(
        f"wedge    {wall:7.2f} s  ratio {ratio:.3f} (target <= 0.6); overhead {1000 * overhead:.0f} ms a task; "
        f"state hashes {'identical to' if same else 'DIFFERENT from'} the serial runs"
    )
    print(f"load after {load_after[0]:.2f} {load_after[1]:.2f} {load_after[2]:.2f}")

    if not args.no_csv:
        row = {
            "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M"),
            "scene": plan.source.stem,
            "variants": args.variants,
            "duration_s": args.duration,
            "workers": args.workers,
            "cores": os.cpu_count(),
            "mode": ("end-to-end" if args.end_to_end else "rounds") + (", own sessions" if args.own_sessions else ""),
            "serial_s": round(serial, 3),
            "wedge_s": round(wall, 3),
            "ratio": round(ratio, 4),
            "startup_s": round(startup, 3),
            "overhead_ms_per_task": round(1000 * overhead, 1),
            "identical": same,
            "load_before": f"{load_before[0]:.2f}",
            "load_after": f"{load_after[0]:.2f}",
            "cpu": platform.processor() or platform.machine(),
            "python": platform.python_version(),
        }
        new = not RESULTS.exists()
        RESULTS.parent.mkdir(exist_ok=True)
        with open(RESULTS, "a", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(row))
            if new:
                writer.writeheader()
            writer.writerow(row)
    return 0 if ratio <= 0.6 and same else 1


if __name__ == "__main__":
    sys.exit(main())
