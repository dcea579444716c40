"""Fixed cost per step: microseconds a step for tiny and medium Tumble worlds (issue 19).

    PYTHONPATH=src python benchmarks/overhead.py
    PYTHONPATH=src python benchmarks/overhead.py --compare /work/main/src   # A/B against another tree

Scenes (dt = 1/240 s):
* `sphere_1`: one sphere (r 0.1 m, 1 kg) resting on a ground plane: one contact every step,
  so every stage of the step runs; at 1 substep and at the default 8. What is left is the
  fixed cost of a step: Python and launch work, not arithmetic.
* `sphere_100`: 100 spheres falling into a box of five planes (the benchmarks' pile, smaller).
* `box_pyramid`: the 55-box pyramid of `benchmarks/run.py`, 8 substeps.
* any other scene of `benchmarks/run.py` (`pile_1k`, `boxes_1k`, `cloth_64`, ...), built by its
  Tumble adapter, for A/B runs of whole steps: e.g. `--scenes pile_1k/8 --warmup 48 --steps 24`
  times 0.1 s of the pouring pile while its spheres still land.

Each scene is built, stepped `--warmup` steps (kernel compilation, first recordings), then
timed over rounds of `--steps` steps; the figure is the median of the rounds' µs/step. With
`--compare TREE`, the same measurement runs in child processes that import Tumble from this
checkout and from TREE in turns, round by round, so load from other processes falls on both
alike; the last column is the ratio. Load average is printed beside the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

SCENES = ("sphere_1/1", "sphere_1/8", "sphere_100/8", "box_pyramid/8")

sys.path.insert(0, str(HERE.parent))
from benchmarks.scenes import SCENES as BENCH_SCENES  # noqa: E402


def build(name: str, substeps: int):
    """A world of scene `name` at `substeps` substeps."""
    import numpy as np

    import tumble

    world = tumble.World(gravity=(0.0, 0.0, -9.81), dt=1.0 / 240.0, substeps=substeps)
    if name == "sphere_1":
        world.add_plane()
        world.add_sphere(position=(0.0, 0.0, 0.1), radius=0.1, mass=1.0)
    elif name == "sphere_100":
        world.add_plane()
        for normal, offset in (((1, 0, 0), -0.5), ((-1, 0, 0), -0.5), ((0, 1, 0), -0.5), ((0, -1, 0), -0.5)):
            world.add_plane(normal=normal, offset=offset)
        rng = np.random.default_rng(0)
        grid = np.stack(np.meshgrid(np.arange(5), np.arange(5), np.arange(4), indexing="ij"), -1).reshape(-1, 3)
        position = (grid - (2, 2, 0)) * 0.15 + (0.0, 0.0, 0.2) + rng.uniform(-0.01, 0.01, grid.shape)
        world.add_spheres(position=position, radius=0.05, mass=0.1)
    elif name in BENCH_SCENES and name != "box_pyramid":
        from benchmarks.engines import TumbleAdapter

        world = TumbleAdapter(BENCH_SCENES[name]).world
        world.substeps = substeps
    elif name == "box_pyramid":
        from benchmarks.scenes import CUBE_HALF, CUBE_MASS, pyramid_positions

        world.add_plane()
        world.add_boxes(position=pyramid_positions(55), half_extents=(CUBE_HALF,) * 3, mass=CUBE_MASS)
    else:
        raise ValueError(f"unknown scene {name!r}")
    return world


def child(scenes: list[str], warmup: int, steps: int, rounds: int, clock=time.perf_counter) -> None:
    """Measure in this process; print one JSON line per round: {scene: µs/step}."""
    worlds = {}
    for key in scenes:
        name, substeps = key.split("/")
        world = worlds[key] = build(name, int(substeps))
        for _ in range(warmup):
            world.step()
    for _ in range(rounds):
        row = {}
        for key, world in worlds.items():
            start = clock()
            for _ in range(steps):
                world.step()
            row[key] = 1e6 * (clock() - start) / steps
        print(json.dumps(row), flush=True)


def _run_child(tree: str, scenes: list[str], args, rounds: int) -> list[dict]:
    env = dict(os.environ, PYTHONPATH=tree)
    cmd = [
        sys.executable,
        str(Path(__file__).resolve()),
        "--child",
        "--scenes",
        ",".join(scenes),
        "--warmup",
        str(args.warmup),
        "--steps",
        str(args.steps),
        "--rounds",
        str(rounds),
        "--clock",
        args.clock,
    ]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        sys.exit(f"overhead: the run with PYTHONPATH={tree} failed:\n{out.stderr.strip()[-2000:]}")
    return [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]


def _median(values: list[float]) -> float:
    values = sorted(values)
    m = len(values) // 2
    return values[m] if len(values) % 2 else 0.5 * (values[m - 1] + values[m])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--scenes", default=",".join(SCENES), help="comma-separated scene/substeps (default: %(default)s)"
    )
    parser.add_argument("--steps", type=int, default=200, help="steps per timed round")
    parser.add_argument("--rounds", type=int, default=5, help="timed rounds (the median is reported)")
    parser.add_argument("--warmup", type=int, default=50, help="untimed steps first")
    parser.add_argument("--compare", default=None, help="another source tree (its src/) to time in turns")
    parser.add_argument(
        "--clock",
        choices=("wall", "cpu"),
        default="wall",
        help="wall time, or the process's CPU time (leaves out time the machine gave other processes)",
    )
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    scenes = [s for s in args.scenes.split(",") if s]
    for key in scenes:
        name, _, substeps = key.partition("/")
        names = {s.split("/")[0] for s in SCENES} | set(BENCH_SCENES)
        if name not in names or not substeps.isdigit() or int(substeps) < 1:
            print(
                f"overhead: bad scene {key!r}: expected NAME/SUBSTEPS with NAME one of {sorted(names)}", file=sys.stderr
            )
            return 2
    if args.child:
        child(
            scenes,
            args.warmup,
            args.steps,
            args.rounds,
            time.process_time if args.clock == "cpu" else time.perf_counter,
        )
        return 0
    here = str(HERE.parent / "src")
    trees = [here] + ([str(Path(args.compare).resolve())] if args.compare else [])
    rows: dict[str, list[dict]] = {t: [] for t in trees}
    load = os.getloadavg()
    # alternate the trees round by round (each child warms up once per call: few long calls)
    turns = 1 if len(trees) == 1 else max(1, args.rounds)
    per_turn = args.rounds if len(trees) == 1 else 1
    for _ in range(turns):
        for t in trees:
            rows[t] += _run_child(t, scenes, args, per_turn)
    load = tuple(0.5 * (a + b) for a, b in zip(load, os.getloadavg()))
    head = f"{'scene/substeps':<16}{'µs/step':>10}"
    if len(trees) > 1:
        head += f"{'compare':>10}{'ratio':>8}"
    print(f"load average {load[0]:.2f} (1 min), {args.rounds} rounds of {args.steps} steps, median, {args.clock} time")
    print(head)
    for key in scenes:
        mine = _median([r[key] for r in rows[here]])
        line = f"{key:<16}{mine:>10.1f}"
        if len(trees) > 1:
            other = _median([r[key] for r in rows[trees[1]]])
            line += f"{other:>10.1f}{mine / other:>8.3f}"
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
