"""Mesh benchmark (issue 16): a 5,000-sphere pour onto a 100k-triangle mesh against the same pour onto a plane.

Both worlds hold the pile's spheres (r 0.05 m, 0.1 kg, e 0.5, mu 0.5) on the pile's jittered
grid in a 2.5 m square (8 layers from z = 0.2 m), dt = 1/240 s, falling onto the ground: a
flat triangulated 6 m x 6 m square (224 x 224 cells, 100,352 triangles) in one world, a plane
in the other. The mesh lies where the plane does, so the two runs are the same physics and
the ratio of their step times is the cost of the mesh. They are stepped in alternating
chunks of 0.1 s in one process (so machine load falls on both alike), after a warm-up step
each that is not timed; the target is a ratio of at most 2 (issue 16).

Usage: `python benchmarks/run.py --scenes meshes` (or `python benchmarks/meshes.py`), with
`--duration S` (default 1 s of simulated time).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if __name__ == "__main__":
    sys.path.insert(0, str(HERE.parent))
    if (HERE.parent / "src" / "tumble").is_dir():
        sys.path.insert(0, str(HERE.parent / "src"))

from benchmarks.scenes import SPHERE_MASS, SPHERE_RADIUS, pile_positions

DT = 1.0 / 240.0
DURATION = 1.0  # [s] simulated per world
CHUNK = 24  # steps per turn (0.1 s)
SPHERES = 5_000
WIDTH = 2.5  # [m] square the spheres start in
MESH_CELLS = 224  # per side: 2 x 224^2 = 100,352 triangles
MESH_HALF = 3.0  # [m] half width of the mesh
TARGET_RATIO = 2.0  # mesh step time / plane step time (issue 16)


def ground_mesh(cells: int = MESH_CELLS, half: float = MESH_HALF) -> tuple[np.ndarray, np.ndarray]:
    """A flat square at z = 0 cut into cells x cells squares of two triangles, wound upwards."""
    xs = np.linspace(-half, half, cells + 1)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    idx = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return v, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def build(ground: str, device: str = "cpu", count: int = SPHERES):
    """The pour onto `ground` ("mesh" or "plane")."""
    import tumble

    w = tumble.World(gravity=(0.0, 0.0, -9.81), dt=DT, device=device)
    if ground == "mesh":
        v, t = ground_mesh()
        w.add_mesh(vertices=v, triangles=t, restitution=0.5, friction=0.5)
    else:
        w.add_plane(restitution=0.5, friction=0.5)
    w.add_spheres(
        position=pile_positions(count, WIDTH, seed=1),
        radius=SPHERE_RADIUS,
        mass=SPHERE_MASS,
        restitution=0.5,
        friction=0.5,
    )
    return w


def run(duration: float = DURATION, device: str = "cpu", log=print) -> dict:
    """Step both worlds in alternating chunks; ms per step of each, their ratio, stage profiles."""
    worlds = {g: build(g, device) for g in ("plane", "mesh")}
    for w in worlds.values():
        w.step()  # compile and warm up, not timed
        w.profile.clear()
    seconds = dict.fromkeys(worlds, 0.0)
    steps = max(CHUNK, round(duration / DT) // CHUNK * CHUNK)
    for _ in range(steps // CHUNK):
        for g, w in worlds.items():
            t = time.perf_counter()
            for _ in range(CHUNK):
                w.step()
            seconds[g] += time.perf_counter() - t
    ms = {g: 1e3 * s / steps for g, s in seconds.items()}
    z_low = {g: float(w.body_position[1:, 2].min()) for g, w in worlds.items()}
    row = {
        "scene": f"mesh_pour_{SPHERES // 1000}k",
        "bodies": SPHERES,
        "triangles": 2 * MESH_CELLS**2,
        "steps": steps,
        "plane_ms_per_step": ms["plane"],
        "mesh_ms_per_step": ms["mesh"],
        "ratio": ms["mesh"] / ms["plane"],
        "target_ratio": TARGET_RATIO,
        "lowest_sphere_plane_m": z_low["plane"],
        "lowest_sphere_mesh_m": z_low["mesh"],
        "load": f"{os.getloadavg()[0]:.2f}" if hasattr(os, "getloadavg") else "",
    }
    log(
        f"  plane {ms['plane']:8.2f} ms/step   mesh {ms['mesh']:8.2f} ms/step   ratio {row['ratio']:.2f} "
        f"(target <= {TARGET_RATIO:g})   load {row['load']}"
    )
    for g, w in worlds.items():
        stages = ", ".join(f"{k} {1e3 * v / steps:.2f}" for k, v in w.profile.items())
        log(f"  {g} ms/step by stage: {stages}")
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration", type=float, default=DURATION, help="simulated seconds per world (default 1)")
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args(argv)
    if not args.duration > 0:
        parser.error("--duration must be > 0")
    print(
        f"mesh_pour_5k: {SPHERES:,} spheres onto {2 * MESH_CELLS**2:,} triangles vs a plane, {args.duration:g} s",
        flush=True,
    )
    run(args.duration, args.device)
    return 0


if __name__ == "__main__":
    sys.exit(main())
