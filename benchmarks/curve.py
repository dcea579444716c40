"""Quality against cost: what each substep count buys (issue 19, "defaults chosen by measurement").

    PYTHONPATH=src python benchmarks/curve.py                      # substeps 1, 2, 4, 8, 16 (~4 min)
    PYTHONPATH=src python benchmarks/curve.py --substeps 2,4,8 --rows pile_1k,bounce

Tumble's one solver knob is the substep count: every substep integrates, solves the contacts once
with bias and once without (relax), so "solver passes" are two a substep. For each count the
script runs the scenes below at dt = 1/240 s on the CPU and prints one table, quality figures
beside steps/s:

* `bounce`: a sphere (r 0.05 m, e 0.5) dropped 1 m onto a plane; the first rebound's apex against
  the analytic e^2 H (relative error), and its lowest point below the plane (penetration).
* `pile_1k`: the benchmarks' 1,000-sphere pile after 2 s: largest overlap and ground penetration,
  kinetic energy.
* `box_pyramid`: the 55-cube pyramid after 2 s: the top cube's drift from its start, largest
  overlap, kinetic energy.
* `cloth_64`: the 64 x 64 cloth pinned at two corners over 1 s: largest strain (its limit is 10 %).
  A cloth with no body near keeps its own substeps (`ClothSystem.substeps`, by default the fewest
  that keep its springs stable), so this row sets those: `auto` is that default.

Steps/s are measured in this one process over the same interval for every count, so they
compare with each other (not with other machines); the load average is printed with them.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from benchmarks import quality  # noqa: E402
from benchmarks.engines import TumbleAdapter  # noqa: E402
from benchmarks.scenes import CUBE_HALF, SCENES, SPHERE_RADIUS, cloth_edges  # noqa: E402

DT = 1.0 / 240.0
ROWS = ("bounce", "pile_1k", "box_pyramid", "cloth_64")


def _timed(step, steps: int) -> float:
    """Steps/s of `steps` calls of `step()`."""
    start = time.perf_counter()
    for _ in range(steps):
        step()
    return steps / (time.perf_counter() - start)


def bounce(substeps: int) -> dict[str, float]:
    """A 1 m drop of a sphere with e = 0.5: the first rebound apex against e^2 H."""
    import tumble

    r, drop, e = 0.05, 1.0, 0.5
    world = tumble.World(dt=DT, substeps=substeps)
    world.add_plane(restitution=e)
    world.add_sphere(position=(0.0, 0.0, r + drop), radius=r, mass=0.1, restitution=e)
    heights, lowest = [], np.inf
    start = time.perf_counter()
    steps = int(round(1.6 / DT))  # impact at 0.45 s, apex of the first rebound at ~0.68 s
    for _ in range(steps):
        world.step()
        z = float(world.body_position[1, 2])
        heights.append(z)
        lowest = min(lowest, z - r)
    rate = steps / (time.perf_counter() - start)
    z = np.array(heights)
    first = int(np.argmin(z[: int(round(0.8 / DT))]))  # the first impact
    apex = float(np.max(z[first:])) - r
    return {
        "steps/s": rate,
        "rebound error %": 100.0 * (apex / (e * e * drop) - 1.0),
        "ground mm": max(0.0, -1e3 * lowest),
    }


def _bodies(name: str, substeps: int, duration: float) -> tuple[TumbleAdapter, float]:
    adapter = TumbleAdapter(SCENES[name])
    adapter.world.substeps = substeps
    rate = _timed(adapter.world.step, int(round(duration / DT)))
    return adapter, rate


def pile_1k(substeps: int) -> dict[str, float]:
    """The 1,000-sphere pile after 2 s."""
    adapter, rate = _bodies("pile_1k", substeps, 2.0)
    b = adapter.bodies()
    mass, inertia = adapter.init.mass, 0.4 * adapter.init.mass * SPHERE_RADIUS**2
    return {
        "steps/s": rate,
        "overlap mm": 1e3 * quality.sphere_max_overlap(b["position"], SPHERE_RADIUS),
        "ground mm": 1e3
        * float(quality.plane_penetration(b["position"], adapter.init.planes[:1], radius=SPHERE_RADIUS)[0]),
        "KE J": quality.kinetic_energy(b["velocity"], b["angular_velocity"], mass, inertia),
    }


def box_pyramid(substeps: int) -> dict[str, float]:
    """The 55-cube pyramid after 2 s: its top cube's drift."""
    adapter = TumbleAdapter(SCENES["box_pyramid"])
    adapter.world.substeps = substeps
    top0 = adapter.bodies()["position"][-1].copy()
    rate = _timed(adapter.world.step, int(round(2.0 / DT)))
    b = adapter.bodies()
    mass = adapter.init.mass
    inertia = mass * (2 * CUBE_HALF) ** 2 / 6.0
    half = np.asarray(adapter.init.half_extents, dtype=float) * np.ones(3)
    return {
        "steps/s": rate,
        "top drift mm": 1e3 * float(np.linalg.norm(b["position"][-1] - top0)),
        "overlap mm": 1e3 * quality.box_max_overlap(b["position"], b["orientation"], half),
        "KE J": quality.kinetic_energy(b["velocity"], b["angular_velocity"], mass, inertia),
    }


def cloth_64(substeps: int | None) -> dict[str, float]:
    """The 64 x 64 cloth over 1 s at `substeps` cloth substeps a step (None: its default): its
    largest strain, sampled every 0.1 s."""
    scene = dataclasses.replace(SCENES["cloth_64"])
    adapter = TumbleAdapter(scene)
    adapter.world.cloth.substeps = substeps
    n = scene.count
    edges, rest = cloth_edges(n), adapter.cloth_init.spacing
    strain, rates = 0.0, []
    for _ in range(10):
        rates.append(_timed(adapter.world.step, int(round(0.1 / DT))))
        strain = max(strain, quality.cloth_max_strain(adapter.cloth_position(), edges, rest))
    return {"steps/s": len(rates) / sum(1.0 / r for r in rates), "strain %": 100.0 * strain}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--substeps", default="1,2,4,8,16", help="comma-separated substep counts")
    parser.add_argument("--rows", default=",".join(ROWS), help=f"comma-separated rows of {', '.join(ROWS)}")
    args = parser.parse_args(argv)
    counts = [int(s) for s in args.substeps.split(",")]
    rows = args.rows.split(",")
    for row in rows:
        if row not in ROWS:
            parser.error(f"unknown row {row!r}; rows are {', '.join(ROWS)}")
    runners = {"bounce": bounce, "pile_1k": pile_1k, "box_pyramid": box_pyramid, "cloth_64": cloth_64}
    for row in rows:
        runners[row](counts[0])  # warm-up: kernel compilation and first recordings, not timed
        print(f"\n{row} (dt 1/240 s), load average {os.getloadavg()[0]:.2f}")
        settings: list[int | None] = [None, *counts] if row == "cloth_64" else list(counts)
        results = {s: runners[row](s) for s in settings}
        columns = list(next(iter(results.values())))
        print("substeps " + " ".join(f"{c:>16}" for c in columns))
        for s, figures in results.items():
            print(f"{'auto' if s is None else s:>8} " + " ".join(f"{figures[c]:>16.4g}" for c in columns))
        print(f"load average {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
