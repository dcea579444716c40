"""Cloth benchmark: a square cloth hanging from two corners, steps per second and largest strain.

Usage (from the repository root)::

    PYTHONPATH=src python benchmarks/cloth.py                  # 64 x 64 and 128 x 128, 2 s each
    PYTHONPATH=src python benchmarks/cloth.py --resolution 64 --duration 2 --wind
    PYTHONPATH=src python benchmarks/cloth.py --no-self-collision

Scene (as the peer comparison's): a 1 m x 1 m cloth, 0.2 kg, hanging in a vertical plane from
its two top corners, released at rest; dt = 1/240 s with the world's default substeps. The
first step (kernel loading) is not timed; only `world.step()` is, not the strain measurement.
Steps per second are wall-clock; CPU seconds (process time) are printed too, since a shared
machine inflates wall time. The largest strain is (|xj - xi| - l0) / l0 over the structural
springs, largest over every step.
"""

from __future__ import annotations

import argparse
import sys
import time

import tumble

# hanging in the yz-plane: grid i along +y, j along +z, normal +x
FACING_X = (0.5, 0.5, 0.5, 0.5)


def run(resolution: int, duration: float, *, wind: bool, self_collision: bool, device: str) -> dict:
    """Simulate one cloth; returns steps, wall and CPU seconds, steps/s, largest strain, cloth substeps."""
    world = tumble.World(dt=1.0 / 240.0, device=device)
    world.add_cloth(
        size=(1.0, 1.0),
        resolution=(resolution, resolution),
        position=(0.0, 0.0, 1.5),
        orientation=FACING_X,
        pins="top-corners",
        mass=0.2,
    )
    if wind:
        world.set_wind(velocity=(4.0, 0.0, 0.0), turbulence=1.5, scale=0.5, seed=1)
    cloth = world.cloth
    cloth.self_collision = self_collision
    world.step()  # load kernels
    strain = cloth.max_strain()
    steps = int(round(duration / world.dt)) - 1
    wall = cpu = 0.0
    for _ in range(steps):
        w0, c0 = time.perf_counter(), time.process_time()
        world.step()
        wall += time.perf_counter() - w0
        cpu += time.process_time() - c0
        strain = max(strain, cloth.max_strain())  # measured outside the timed step
    return {
        "resolution": resolution,
        "particles": cloth.particle_count,
        "springs": cloth.spring_count,
        "steps": steps,
        "wall_s": wall,
        "cpu_s": cpu,
        "steps_per_s": steps / wall,
        "steps_per_cpu_s": steps / cpu,
        "max_strain": strain,
        "cloth_substeps": cloth.substeps_for(world.dt),
        "world_substeps": world.substeps,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, nargs="+", default=[64, 128], help="particles per side")
    parser.add_argument("--duration", type=float, default=2.0, help="simulated seconds")
    parser.add_argument("--wind", action="store_true", help="add gusty wind (4 m/s, turbulence 1.5 m/s)")
    parser.add_argument("--no-self-collision", action="store_true", help="turn cloth self-collision off")
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args(argv)
    print(
        "resolution,particles,springs,world_substeps,cloth_substeps,steps,wall_s,cpu_s,steps_per_s,"
        "steps_per_cpu_s,max_strain"
    )
    for n in args.resolution:
        r = run(n, args.duration, wind=args.wind, self_collision=not args.no_self_collision, device=args.device)
        print(
            f"{r['resolution']},{r['particles']},{r['springs']},{r['world_substeps']},{r['cloth_substeps']},"
            f"{r['steps']},{r['wall_s']:.3f},{r['cpu_s']:.3f},{r['steps_per_s']:.1f},{r['steps_per_cpu_s']:.1f},"
            f"{r['max_strain']:.4f}"
        )
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
