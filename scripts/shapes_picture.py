"""Render docs/images/rendering_shapes.png: capsules, convex pebbles and a static mesh, with joints.

A terrain-like static mesh (a tilted, wavy sheet made here with NumPy), capsules of two sizes, a
few convex hulls of random points, and a short chain of capsules hung from the world by ball
joints, drawn with `show_joints`, after 0.75 s of simulation. Run from the repository root:

    python scripts/shapes_picture.py [OUT.png]
"""

from __future__ import annotations

import math
import sys

import numpy as np

import tumble
from tumble.render import Camera, Renderer, create_context


def build() -> tumble.World:
    world = tumble.World(dt=1 / 240, seed=3)
    world.add_plane()
    # the mesh: a 2 x 1.4 m sheet, 40 x 28 quads, sloping down towards +x with gentle waves
    nx, ny = 40, 28
    x, y = np.meshgrid(np.linspace(-1.0, 1.0, nx + 1), np.linspace(-0.7, 0.7, ny + 1))
    z = 0.35 - 0.25 * x + 0.04 * np.sin(5 * x) * np.cos(4 * y) + 0.12 * y**2
    v = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    idx = np.arange(v.shape[0]).reshape(ny + 1, nx + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    world.add_mesh(vertices=v, triangles=np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]))
    rng = np.random.default_rng(3)
    for k in range(4):  # capsules lying across the slope
        q = (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))
        world.add_capsule(
            position=(-0.7 + 0.28 * k, -0.35 + 0.1 * k, 0.75),
            radius=0.05 + 0.01 * (k % 2),
            half_height=0.12,
            orientation=q,
        )
    for k in range(6):  # pebbles: hulls of 12 random points each
        points = rng.normal(size=(12, 3)) * (0.07, 0.055, 0.04)
        world.add_convex(points=points, position=(-0.5 + 0.2 * k, 0.25 - 0.05 * (k % 3), 0.7 + 0.05 * k))
    # a chain of three capsules hung from the world by ball joints
    top = np.array([0.75, 0.45, 1.25])
    previous = None
    for k in range(3):
        centre = top - (0, 0, 0.12 + 0.24 * k)
        link = world.add_capsule(position=centre, radius=0.025, half_height=0.08)
        world.add_joint("ball", previous, link, anchor=tuple(centre + (0, 0, 0.12)))
        previous = link
    return world


def main(out: str = "docs/images/rendering_shapes.png") -> None:
    from PIL import Image

    from tumble.io.atomic import atomic_path

    world = build()
    world.run(0.75)
    renderer = Renderer(create_context(), 960, 540, samples=4)
    renderer.show_joints = True
    camera = Camera(position=(2.1, -3.3, 2.0), target=(0.1, 0.05, 0.6))
    image = Image.fromarray(renderer.render(world, camera))
    with atomic_path(out) as tmp:
        image.save(tmp, format="PNG", optimize=True)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])
