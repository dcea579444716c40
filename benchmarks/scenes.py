"""Benchmark scenes: one description each, and the initial conditions every engine starts from.

A `Scene` says what to build; `initial_bodies(scene)` and `initial_cloth(scene)` give the exact
starting positions (seeded, so Tumble, PyBullet and MuJoCo start from the same numbers). The
engine adapters in `engines.py` turn these into worlds.

Geometry (z up, SI units):

* sphere pile: spheres of radius 0.05 m, mass 0.1 kg, restitution 0.5, friction 0.5, dropped
  into a square box of inner width `box_width` (1 m; 5 m for the 100k pile) made of a ground
  plane z = 0 and four wall planes x, y = +-box_width / 2. They start on a grid with spacing
  0.11 m, jittered by up to +-4 mm per axis (so no two overlap), the lowest layer at z = 0.2 m.
* box rain: 1,000 cubes of 0.1 m edge (1 kg, e = 0.5, mu = 0.5) on a 10 x 10 x 10 grid with
  0.25 m spacing and +-6 cm jitter, axis-aligned, lowest layer at z = 0.5 m, falling onto a
  ground plane (no walls).
* cloth: an n x n grid of particles, 1 m x 1 m, total mass 0.2 kg, horizontal at z = 1.5 m,
  pinned at the two corners of the edge y = +0.5 m, swinging down under gravity (no ground,
  no self-collision).
* large pyramid: Box3D's `large_pyramid` benchmark (erincatto/box3d, `shared/benchmarks.c`,
  `CreateLargePyramid`), z up instead of y: 4,095 cubes of 1 m (half extent 0.5 m, density 1,
  so 1 kg), 90 on the ground and one fewer in each row up, each row shifted by half a cube so
  that every cube rests on two; no gaps (neighbours in a row touch, rows rest on each other);
  friction 0.6 and restitution 0 (Box3D's defaults), gravity 10 m/s^2, dt = 1/60 s. Box3D's
  ground is a static 200 m x 200 m box with its top at 0; here it is the plane z = 0.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

DT = 1.0 / 240.0
DURATION = 2.0

SPHERE_RADIUS = 0.05  # [m]
SPHERE_MASS = 0.1  # [kg]
RESTITUTION = 0.5
FRICTION = 0.5

PILE_SPACING = 0.11  # grid spacing [m]: > 2 r + 2 jitter, so no overlap at the start
PILE_JITTER = 0.004  # [m] per axis
PILE_FIRST_LAYER = 0.2  # height of the lowest layer of centres [m]

CUBE_HALF = 0.05  # [m]
CUBE_MASS = 1.0  # [kg]
RAIN_SPACING = 0.25  # [m]
RAIN_JITTER = 0.06  # [m], horizontal only
RAIN_FIRST_LAYER = 0.5  # [m]
PYRAMID_GAP = 0.01  # [m] between neighbouring cubes of a row

CLOTH_SIZE = 1.0  # side [m]
CLOTH_MASS = 0.2  # total [kg] (0.2 kg/m^2, Tumble's default areal density)
CLOTH_HEIGHT = 1.5  # [m]

NO_RAPIER_CLOTH = "Rapier has no mass-spring cloth to compare"

# Box3D's large pyramid (see the module docstring)
LARGE_PYRAMID_BASE = 90
LARGE_PYRAMID_HALF = 0.5  # [m]
LARGE_PYRAMID_MASS = 1.0  # [kg]: density 1 kg/m^3 times 1 m^3
LARGE_PYRAMID_FRICTION = 0.6
LARGE_PYRAMID_GRAVITY = 10.0  # [m/s^2]
#: Tumble's recommended substeps at dt = 1/60 s for tall stacks: h = 1/1920 s, the default
#: substep (1/240 s in 8), so contacts as stiff as at the defaults (docs/performance.md)
LARGE_PYRAMID_SUBSTEPS = 32
#: the top cube must stay within this of its start after 10 s [m] (issue 19)
LARGE_PYRAMID_TOP_TOLERANCE = 0.02
#: Box3D's figure: 1,614.82 ms for the benchmark's 200 steps of 1/60 s with 4 substeps, one
#: thread of an AMD 7950X, SSE2 build (erincatto/box3d benchmark/amd7950x_sse2/large_pyramid.csv,
#: commit 23367c3; its AVX2 build: 1,067.06 ms, benchmark/amd7950x_avx2/large_pyramid.csv, commit
#: 688c058). benchmark/main.c times the 199 steps after an untimed first one, so per timed step it
#: is 8.11 ms; 8.07 ms is the total over 200, as issue 19 quotes it.
BOX3D_LARGE_PYRAMID_MS = 1614.82 / 200


@dataclass(frozen=True)
class Scene:
    """One benchmark scene, built the same way in every engine.

    Attributes:
        name: short name used on the command line and in the results ("pile_5k").
        kind: "pile", "boxes", "pyramid" or "cloth".
        count: bodies (pile, boxes) or particles per side (cloth).
        box_width: inner width of the pile's box [m] (pile only).
        dt: time step [s].
        duration: simulated time [s] for Tumble.
        peer_duration: simulated time [s] for PyBullet and MuJoCo (shorter where they are slow;
            Tumble's figures are then also taken at this time, so ratios compare equal intervals).
        peers: whether PyBullet and MuJoCo run this scene at all.
        seed: seed of the jitter.
        skip: peers left out of this scene by default, with the reason (run.py --all-peers
            runs them anyway).
        substeps: Tumble's substeps (None: its default).
        gravity: magnitude of gravity [m/s^2], along -z.
    """

    name: str
    kind: str
    count: int
    box_width: float = 1.0
    dt: float = DT
    duration: float = DURATION
    peer_duration: float = DURATION
    peers: bool = True
    seed: int = 7
    skip: tuple[tuple[str, str], ...] = ()
    substeps: int | None = None
    gravity: float = 9.81

    @property
    def steps(self) -> int:
        """Steps Tumble takes."""
        return int(round(self.duration / self.dt))

    @property
    def peer_steps(self) -> int:
        """Steps the peers take."""
        return int(round(self.peer_duration / self.dt))

    @property
    def body_count(self) -> int:
        """Moving bodies (cloth: particles), the factor from steps to body-steps."""
        return self.count * self.count if self.kind == "cloth" else self.count

    def shortened(self, duration: float) -> Scene:
        """The same scene simulated for at most `duration` seconds (for --quick)."""
        return dataclasses.replace(
            self, duration=min(self.duration, duration), peer_duration=min(self.peer_duration, duration)
        )


SCENES: dict[str, Scene] = {
    s.name: s
    for s in (
        Scene("pile_1k", "pile", 1_000),
        Scene("pile_5k", "pile", 5_000),
        Scene("pile_20k", "pile", 20_000, peer_duration=0.5),
        Scene("pile_100k", "pile", 100_000, box_width=5.0, peers=False),
        Scene("boxes_1k", "boxes", 1_000),
        Scene("box_pyramid", "pyramid", 55),
        Scene(
            "large_pyramid",
            "large_pyramid",
            LARGE_PYRAMID_BASE * (LARGE_PYRAMID_BASE + 1) // 2,
            dt=1.0 / 60.0,
            duration=10.0,
            peer_duration=10.0,
            peers=False,
            substeps=LARGE_PYRAMID_SUBSTEPS,
            gravity=LARGE_PYRAMID_GRAVITY,
        ),
        Scene("cloth_64", "cloth", 64, skip=(("rapier", NO_RAPIER_CLOTH),)),
        Scene(
            "cloth_128",
            "cloth",
            128,
            peer_duration=0.5,
            skip=(
                (
                    "pybullet",
                    "building a 128 x 128 soft body takes PyBullet 4-7 minutes (its build time "
                    "grows as about N^2.7 in the particle count)",
                ),
                ("rapier", NO_RAPIER_CLOTH),
            ),
        ),
    )
}


# ---------------------------------------------------------------------- initial conditions


@dataclass(frozen=True)
class Bodies:
    """Initial state of the moving bodies of a pile or box-rain scene.

    Attributes:
        shape: "sphere" or "box".
        position: centres [m], shape (n, 3).
        radius: sphere radius [m] (spheres only).
        half_extents: box half extents [m], shape (3,) (boxes only).
        mass: mass of each body [kg].
        planes: static planes as (normal (3,), offset) with dot(normal, x) = offset, bodies on
            the +normal side; the ground first.
        friction: friction coefficient of every body and plane.
        restitution: restitution of every body and plane.
    """

    shape: str
    position: np.ndarray
    radius: float
    half_extents: np.ndarray
    mass: float
    planes: list[tuple[np.ndarray, float]]
    friction: float = FRICTION
    restitution: float = RESTITUTION


def box_planes(width: float) -> list[tuple[np.ndarray, float]]:
    """Ground z = 0 and the four walls of a square box of inner width `width` [m]."""
    h = 0.5 * width
    return [
        (np.array([0.0, 0.0, 1.0]), 0.0),
        (np.array([1.0, 0.0, 0.0]), -h),
        (np.array([-1.0, 0.0, 0.0]), -h),
        (np.array([0.0, 1.0, 0.0]), -h),
        (np.array([0.0, -1.0, 0.0]), -h),
    ]


def pile_positions(count: int, width: float, seed: int) -> np.ndarray:
    """Sphere centres on a jittered grid filling the box layer by layer, shape (count, 3) [m].

    Per axis k = floor((width - 2 r - 2 jitter) / spacing) + 1 centres fit, centred on the box.
    """
    k = int(math.floor((width - 2 * SPHERE_RADIUS - 2 * PILE_JITTER) / PILE_SPACING)) + 1
    layers = -(-count // (k * k))
    ix, iy, iz = np.meshgrid(np.arange(k), np.arange(k), np.arange(layers), indexing="ij")
    # layer by layer, bottom first
    order = np.lexsort((ix.ravel(), iy.ravel(), iz.ravel()))
    grid = np.stack([ix.ravel(), iy.ravel(), iz.ravel()], axis=1)[order][:count].astype(np.float64)
    position = np.empty_like(grid)
    position[:, :2] = (grid[:, :2] - 0.5 * (k - 1)) * PILE_SPACING
    position[:, 2] = PILE_FIRST_LAYER + grid[:, 2] * PILE_SPACING
    rng = np.random.default_rng(seed)
    return position + rng.uniform(-PILE_JITTER, PILE_JITTER, size=position.shape)


def rain_positions(count: int, seed: int) -> np.ndarray:
    """Cube centres on a 10 x 10 x ... grid with horizontal jitter, shape (count, 3) [m]."""
    k = 10
    layers = -(-count // (k * k))
    ix, iy, iz = np.meshgrid(np.arange(k), np.arange(k), np.arange(layers), indexing="ij")
    order = np.lexsort((ix.ravel(), iy.ravel(), iz.ravel()))
    grid = np.stack([ix.ravel(), iy.ravel(), iz.ravel()], axis=1)[order][:count].astype(np.float64)
    position = np.empty_like(grid)
    position[:, :2] = (grid[:, :2] - 0.5 * (k - 1)) * RAIN_SPACING
    position[:, 2] = RAIN_FIRST_LAYER + grid[:, 2] * RAIN_SPACING
    rng = np.random.default_rng(seed)
    position[:, :2] += rng.uniform(-RAIN_JITTER, RAIN_JITTER, size=(count, 2))
    return position


def pyramid_positions(count: int) -> np.ndarray:
    """Cube centres of a 2D pyramid, `base` cubes on the ground and one fewer each row up, 1 cm
    apart, resting on each other; count = base (base + 1) / 2 (55 for a base of 10), shape (count, 3)."""
    base = int(round((math.sqrt(8 * count + 1) - 1) / 2))
    if base * (base + 1) // 2 != count:
        raise ValueError(f"a pyramid has a triangular number of cubes, not {count}")
    pitch = 2 * CUBE_HALF + PYRAMID_GAP
    rows = [(i - (base - 1 - row) / 2) * pitch for row in range(base) for i in range(base - row)]
    heights = [CUBE_HALF + 2 * CUBE_HALF * row for row in range(base) for _ in range(base - row)]
    return np.stack([np.array(rows), np.zeros(count), np.array(heights)], axis=1)


def large_pyramid_positions(base: int, half: float = LARGE_PYRAMID_HALF) -> np.ndarray:
    """Cube centres of Box3D's large pyramid with `base` cubes on the ground, shape (base (base + 1) / 2, 3) [m].

    Row i (from 0 at the ground) has base - i cubes at z = (2 i + 1) h, x = (i + 1) h + 2 (j - i) h - base h
    for j = i .. base - 1: touching neighbours, each row shifted by h over the one below, as in
    Box3D's `CreateLargePyramid` (its y is z here); the top cube is the last row.
    """
    i, j = np.nonzero(np.triu(np.ones((base, base), dtype=bool)))  # row i, j = i .. base - 1, row by row
    x = (i + 1.0) * half + 2.0 * (j - i) * half - half * base
    return np.stack([x, np.zeros(len(i)), (2.0 * i + 1.0) * half], axis=1)


def initial_bodies(scene: Scene) -> Bodies:
    """The moving bodies and static planes of a pile or box-rain scene."""
    if scene.kind == "pile":
        return Bodies(
            "sphere",
            pile_positions(scene.count, scene.box_width, scene.seed),
            SPHERE_RADIUS,
            np.zeros(3),
            SPHERE_MASS,
            box_planes(scene.box_width),
        )
    if scene.kind == "boxes":
        return Bodies(
            "box",
            rain_positions(scene.count, scene.seed),
            0.0,
            np.full(3, CUBE_HALF),
            CUBE_MASS,
            box_planes(0.0)[:1],
        )
    if scene.kind == "pyramid":
        return Bodies(
            "box",
            pyramid_positions(scene.count),
            0.0,
            np.full(3, CUBE_HALF),
            CUBE_MASS,
            box_planes(0.0)[:1],
        )
    if scene.kind == "large_pyramid":
        base = int(round((math.sqrt(8 * scene.count + 1) - 1) / 2))
        if base * (base + 1) // 2 != scene.count:
            raise ValueError(f"a pyramid has a triangular number of cubes, not {scene.count}")
        return Bodies(
            "box",
            large_pyramid_positions(base),
            0.0,
            np.full(3, LARGE_PYRAMID_HALF),
            LARGE_PYRAMID_MASS,
            box_planes(0.0)[:1],
            friction=LARGE_PYRAMID_FRICTION,
            restitution=0.0,
        )
    raise ValueError(f"scene {scene.name!r} of kind {scene.kind!r} has no rigid bodies")


@dataclass(frozen=True)
class Cloth:
    """Initial state of a cloth scene.

    Attributes:
        n: particles per side.
        position: particle positions [m], shape (n * n, 3); particle (i, j) at row j * n + i,
            x = -0.5 + i * spacing, y = -0.5 + j * spacing.
        spacing: rest distance of neighbouring particles [m].
        pins: indices of the two pinned particles, (0, n - 1) of the row j = n - 1.
        mass: total mass [kg].
        triangles: two triangles per grid cell, shape (2 (n - 1)^2, 3), int32.
    """

    n: int
    position: np.ndarray
    spacing: float
    pins: tuple[int, int]
    mass: float
    triangles: np.ndarray


def initial_cloth(scene: Scene) -> Cloth:
    """The particle grid of a cloth scene."""
    if scene.kind != "cloth":
        raise ValueError(f"scene {scene.name!r} of kind {scene.kind!r} is not a cloth")
    n = scene.count
    spacing = CLOTH_SIZE / (n - 1)
    jj, ii = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    position = np.stack(
        [
            -0.5 * CLOTH_SIZE + ii.ravel() * spacing,
            -0.5 * CLOTH_SIZE + jj.ravel() * spacing,
            np.full(n * n, CLOTH_HEIGHT),
        ],
        axis=1,
    )
    # two triangles per cell (i, j): (a, b, c) and (a, c, d), counter-clockwise seen from +z
    ci, cj = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (cj * n + ci).ravel()
    b, c, d = a + 1, a + n + 1, a + n
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int32)
    pins = ((n - 1) * n, n * n - 1)
    return Cloth(n, position, spacing, pins, CLOTH_MASS, triangles)


def cloth_edges(n: int) -> np.ndarray:
    """Structural edges (grid neighbours along x and y) of an n x n cloth, shape (2 n (n - 1), 2)."""
    idx = np.arange(n * n).reshape(n, n)  # [j, i]
    along_x = np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], axis=1)
    along_y = np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], axis=1)
    return np.concatenate([along_x, along_y])
