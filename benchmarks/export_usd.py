"""USD export speed and size: a 2 s, 60 fps recording of 5,000 bodies written as .usdc (issue 17).

The take: 4,000 spheres (r 0.05 m) and 1,000 cubes released over the first second (so that
bodies appear part-way, through invisibleIds and zero scales), 60 fps for 2 s (121 frames), in
a 1.5 m box. By default the recording is made up (ballistic flights bouncing off the ground,
each body spinning about its own axis: no two frames alike, as in a real take) in a second; with
`--simulate` Tumble records the same bodies falling into the box (~1-2 minutes on one core).
Only the export is timed: the recording's arrays to a finished file, best of `--repeat` runs.

    PYTHONPATH=src python benchmarks/export_usd.py                 # .usdc with the PointInstancer
    PYTHONPATH=src python benchmarks/export_usd.py --formats usdc,usda,usdz --xforms --simulate

Targets: under 10 s and under 50 MB for the .usdc.
"""

from __future__ import annotations

import argparse
import csv
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.scenes import box_planes, pile_positions

TARGET_SECONDS = 10.0
TARGET_MB = 50.0


def synthetic_take(spheres: int, boxes: int, duration: float, fps: float, seed: int = 1) -> dict:
    """A recording's arrays with the take's bodies on made-up paths (same format as a real one)."""
    from tumble.io.record import FORMAT_VERSION
    from tumble.shapes import SHAPE_NAMES, ShapeType

    rng = np.random.default_rng(seed)
    planes = box_planes(1.5)
    n_planes, n = len(planes), len(planes) + spheres + boxes
    frames = round(duration * fps) + 1
    t = np.arange(frames) / fps
    shape = np.r_[np.full(n_planes, ShapeType.PLANE), np.full(spheres, ShapeType.SPHERE), np.full(boxes, ShapeType.BOX)]
    start = np.r_[np.zeros(n_planes + spheres), np.sort(rng.uniform(0.0, 1.0, boxes))]  # release times [s]
    p0 = np.r_[
        np.zeros((n_planes, 3)),
        pile_positions(spheres, 1.5, seed=seed),
        rng.uniform((-0.6, -0.6, 3.8), (0.6, 0.6, 4.2), (boxes, 3)),
    ]
    v0 = rng.normal(0.0, 0.5, (n, 3))
    age = np.maximum(t[:, None] - start[None, :], 0.0)  # (F, N)
    position = p0[None] + v0[None] * age[..., None]
    position[..., 2] -= 0.5 * 9.81 * age**2
    position[..., 2] = np.abs(position[..., 2] - 0.05) + 0.05  # bounce off the ground
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = rng.uniform(-6.0, 6.0, n)[None] * age  # (F, N) [rad]
    orientation = np.concatenate([axis[None] * np.sin(0.5 * angle)[..., None], np.cos(0.5 * angle)[..., None]], axis=2)
    for k, (normal, offset) in enumerate(planes):
        position[:, k] = normal * offset
        orientation[:, k] = (0.0, 0.0, 0.0, 1.0)
    unborn = t[:, None] < start[None, :]
    position[unborn] = np.nan
    orientation[unborn] = np.nan
    radius = np.where(shape == ShapeType.SPHERE, 0.05, 0.0)
    half = np.where((shape == ShapeType.BOX)[:, None], 0.04, 0.0) * np.ones((n, 3))
    return {
        "format_version": np.int32(FORMAT_VERSION),
        "time": t,
        "fps": np.float64(fps),
        "dt": np.float64(1 / 240),
        "position": position,
        "orientation": orientation,
        "velocity": np.zeros_like(position),
        "angular_velocity": np.zeros_like(position),
        "shape": shape.astype(np.int32),
        "shape_names": np.array(SHAPE_NAMES),
        "radius": radius,
        "half_extents": half,
        "mass": np.where(shape == ShapeType.PLANE, 0.0, 0.1),
        "gravity": np.array([0.0, 0.0, -9.81]),
        "restitution": np.full(n, 0.5),
        "friction": np.full(n, 0.5),
    }


def record_take(spheres: int, boxes: int, duration: float, fps: float) -> dict:
    """Simulate the take and return its recording's arrays (tumble.io.record format)."""
    import tumble
    from tumble.io.record import Recorder

    world = tumble.World(dt=1 / 240)
    for normal, offset in box_planes(1.5):
        world.add_plane(normal=normal, offset=offset)
    world.add_spheres(position=pile_positions(spheres, 1.5, seed=1), radius=0.05, mass=0.1)
    world.add_emitter(
        shape="box",
        rate=boxes / 1.0,
        count=boxes,
        position=(0, 0, 4.0),
        region="box",
        extent=(0.6, 0.6, 0.2),
        half_extents=0.04,
        mass=0.1,
        seed=1,
    )
    recorder = Recorder(world, fps=fps)
    frames = round(duration * fps) + 1
    while recorder.frame_count < frames:
        world.step()
        recorder(world)
    return recorder.arrays()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", type=int, default=4000)
    parser.add_argument("--boxes", type=int, default=1000)
    parser.add_argument("--duration", type=float, default=2.0)
    parser.add_argument("--fps", type=float, default=60.0)
    parser.add_argument("--formats", default="usdc", help="comma-separated: usd, usdc, usda, usdz")
    parser.add_argument("--simulate", action="store_true", help="record a real simulation of the take (slow)")
    parser.add_argument("--xforms", action="store_true", help="also time --bodies xforms (one Xform per body)")
    parser.add_argument("--repeat", type=int, default=2, help="runs per case; the best is reported")
    parser.add_argument("--csv", default=str(HERE / "results" / "export_usd.csv"), help="append results here")
    args = parser.parse_args(argv)

    from tumble.io import usd

    start = time.perf_counter()
    take = record_take if args.simulate else synthetic_take
    rec = take(args.spheres, args.boxes, args.duration, args.fps)
    n_frames = len(rec["time"])
    n_bodies = int((rec["mass"] > 0).sum())
    born_late = int((~np.isfinite(rec["position"][0, :, 0])).sum())
    print(
        f"take: {n_bodies:,} bodies ({born_late:,} released after frame 0), {n_frames} frames; "
        f"{'simulated' if args.simulate else 'made up'} in {time.perf_counter() - start:.1f} s"
    )

    cases = [(fmt, "instancer") for fmt in args.formats.split(",")]
    if args.xforms:
        cases.append(("usdc", "xforms"))
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for fmt, bodies in cases:
            out = Path(folder) / f"take.{fmt}"
            best = float("inf")
            for _ in range(max(1, args.repeat)):
                t0 = time.perf_counter()
                usd.export(rec, out, bodies=bodies)
                best = min(best, time.perf_counter() - t0)
            mb = out.stat().st_size / 1e6
            ok = (
                ""
                if fmt != "usdc" or bodies != "instancer"
                else ("  (targets met)" if best < TARGET_SECONDS and mb < TARGET_MB else "  (TARGET MISSED)")
            )
            print(f"{fmt:5} {bodies:9} {best:7.2f} s {mb:8.1f} MB{ok}")
            rows.append(
                {
                    "date": time.strftime("%Y-%m-%d %H:%M"),
                    "machine": platform.node(),
                    "take": "simulated" if args.simulate else "synthetic",
                    "format": fmt,
                    "bodies": bodies,
                    "body_count": n_bodies,
                    "frames": n_frames,
                    "seconds": f"{best:.3f}",
                    "megabytes": f"{mb:.2f}",
                }
            )
    if args.csv:
        path = Path(args.csv)
        new = not path.exists()
        with path.open("a", newline="", encoding="utf-8") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            if new:
                writer.writeheader()
            writer.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
