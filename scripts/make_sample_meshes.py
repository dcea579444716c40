"""Write the small OBJ meshes of the geometry samples (samples/meshes/), all generated here.

    python scripts/make_sample_meshes.py          # rewrites samples/meshes/*.obj
    python scripts/make_sample_meshes.py --points # prints the pebble points of pebble_bowl.toml

- `bowl.obj`: a paraboloid bowl z = k r^2 out to r = 0.5 m (rim 0.25 m), on polar rings, wound
  upwards (towards the inside of the bowl), for `pebble_bowl.toml`;
- `statue.obj`: a smooth hill on a 2.4 m square of terrain (a rounded knoll with a shoulder),
  wound upwards, for `cloth_statue.toml`;
- `slope.obj`: a height field slope down a 1.2 m wide channel (walls rising 0.54 m) into a hollow and up a short lip,
  with small ripples, for `capsule_slope.toml`.

Faces are wound counter-clockwise seen from above (the side bodies stay on). Coordinates are
written with 5 decimals (10 um), so the files stay small and identical run to run.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "src" / "tumble" / "samples" / "meshes"
sys.path.insert(0, str(ROOT / "src"))


def height_field(height, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices z = height(x, y) on the grid xs x ys, and two upward triangles per cell."""
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), height(X, Y).ravel()], axis=1)
    idx = np.arange(X.size).reshape(X.shape)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return v, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def bowl(radius: float = 0.5, rim: float = 0.25, rings: int = 12, sectors: int = 36):
    """Paraboloid z = rim (r / radius)^2 on polar rings around a centre vertex."""
    k = rim / radius**2
    v = [[0.0, 0.0, 0.0]]
    for i in range(1, rings + 1):
        r = radius * i / rings
        for j in range(sectors):
            phi = 2 * np.pi * j / sectors
            v.append([r * np.cos(phi), r * np.sin(phi), k * r * r])
    t = []
    for j in range(sectors):  # the centre fan
        t.append([0, 1 + j, 1 + (j + 1) % sectors])
    for i in range(rings - 1):
        inner, outer = 1 + i * sectors, 1 + (i + 1) * sectors
        for j in range(sectors):
            j1 = (j + 1) % sectors
            t.append([inner + j, outer + j, outer + j1])
            t.append([inner + j, outer + j1, inner + j1])
    return np.array(v), np.array(t)


def statue():
    """A knoll (a rounded hill 0.45 m high) with a lower shoulder beside it, on flat ground."""

    def h(x, y):
        knoll = 0.45 * np.exp(-(((x**2 + y**2) / 0.12) ** 1.5))
        shoulder = 0.2 * np.exp(-(((x - 0.35) ** 2 + (y + 0.25) ** 2) / 0.05))
        return knoll + shoulder

    s = np.linspace(-1.2, 1.2, 33)
    return height_field(h, s, s)


def slope():
    """A channel falling 1.06 m over 2.3 m into a hollow, then a 1.21 m lip (higher than the start); walls z = 1.5 y^2; ripples of 8 mm."""

    def h(x, y):
        fall = np.where(x < 1.0, 0.2, 1.0) * (x - 1.0) ** 2
        return fall + 1.5 * y**2 + 0.008 * np.sin(9 * x) * np.cos(7 * y)

    return height_field(h, np.linspace(-1.3, 2.1, 58), np.linspace(-0.6, 0.6, 19))


def write_obj(path: Path, v: np.ndarray, t: np.ndarray, title: str) -> None:
    from tumble.io.atomic import atomic_path

    lines = [f"# {title} (scripts/make_sample_meshes.py)"]
    lines += [f"v {x:.5f} {y:.5f} {z:.5f}" for x, y, z in v]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in t]
    with atomic_path(path) as tmp:
        Path(tmp).write_text("\n".join(lines) + "\n", encoding="ascii")
    print(f"wrote {path.relative_to(ROOT)}: {len(v)} vertices, {len(t)} triangles")


def pebble_points(seed: int = 16, n: int = 10) -> np.ndarray:
    """n points of a flattened blob (radius 1 along x) whose hull is a pebble."""
    p = np.random.default_rng(seed).normal(size=(n, 3)) * (1.0, 0.75, 0.45)
    return p / np.linalg.norm(p, axis=1).max()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--points", action="store_true", help="print the pebble points (TOML) and exit")
    args = parser.parse_args(argv)
    if args.points:
        print("points = [" + ", ".join(f"[{x:.3f}, {y:.3f}, {z:.3f}]" for x, y, z in pebble_points()) + "]")
        return 0
    OUT.mkdir(parents=True, exist_ok=True)
    write_obj(OUT / "bowl.obj", *bowl(), "paraboloid bowl, r 0.5 m, rim 0.25 m")
    write_obj(OUT / "statue.obj", *statue(), "a knoll with a shoulder on a 2.4 m square")
    write_obj(OUT / "slope.obj", *slope(), "a rippled channel slope into a hollow")
    return 0


if __name__ == "__main__":
    sys.exit(main())
