"""Grid builder: particles, triangles and springs of one rectangular cloth, on the host.

A cloth of `resolution = (nx, ny)` particles is a regular grid. Unrotated, it lies in the
xy-plane with its normal +z, centred on its position; grid index i runs along x, j along y,
and particle k = j * nx + i (row-major, i fastest). Everything here is NumPy and runs once per
`add_cloth`; nothing is stepped.

Springs (Provot 1995, "Deformation constraints in a mass-spring model"):

- structural: (i, j)-(i+1, j) and (i, j)-(i, j+1), resisting stretch;
- shear: the two diagonals of every quad, resisting shear;
- bend: (i, j)-(i+2, j) and (i, j)-(i, j+2), resisting bending.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .. import validate
from ..npmath import quat_rotate

SPRING_KINDS = ("structural", "shear", "bend")


def grid_positions(size, resolution, position, orientation) -> np.ndarray:
    """World positions [m] of the grid particles, shape (nx * ny, 3), row-major with i fastest."""
    (w, h), (nx, ny) = size, resolution
    # a single row or column sits on the centre line
    xs = (np.arange(nx) / (nx - 1) - 0.5) * w if nx > 1 else np.zeros(1)
    ys = (np.arange(ny) / (ny - 1) - 0.5) * h if ny > 1 else np.zeros(1)
    gx, gy = np.meshgrid(xs, ys)  # (ny, nx): row j, column i
    local = np.stack([gx.ravel(), gy.ravel(), np.zeros(nx * ny)], axis=1)
    return quat_rotate(np.asarray(orientation, dtype=np.float64), local) + np.asarray(position, dtype=np.float64)


def grid_triangles(nx: int, ny: int) -> np.ndarray:
    """Two triangles per grid quad, counter-clockwise seen from +z (normal +z), shape (T, 3), int32.

    Each triangle starts at its right-angle corner (the quad corner it does not share with the
    other triangle of its quad): a load spread over the triangle's area reaches the quad's four
    corners in equal quarters when the first corner takes half of it and the other two a quarter
    each (`TRIANGLE_LOAD_SHARES`), as the particles' masses are spread (`grid_area_shares`).
    """
    if nx < 2 or ny < 2:
        return np.zeros((0, 3), dtype=np.int32)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1))
    a = (j * nx + i).ravel()
    b, c, d = a + 1, a + nx + 1, a + nx
    # alternate the diagonal in a checkerboard so the mesh has no preferred shear direction
    flip = ((i + j) % 2 == 1).ravel()
    t1 = np.where(flip[:, None], np.stack([a, b, d], 1), np.stack([b, c, a], 1))
    t2 = np.where(flip[:, None], np.stack([c, d, b], 1), np.stack([d, a, c], 1))
    return np.concatenate([t1, t2]).astype(np.int32)


#: how a load spread evenly over a grid triangle (its air force) is shared by its three corners,
#: the right-angle corner first (`grid_triangles`): the quad's quarters, as the masses
TRIANGLE_LOAD_SHARES = (0.5, 0.25, 0.25)


def grid_area_shares(nx: int, ny: int) -> np.ndarray:
    """Each particle's share of the cloth's area, shape (nx * ny,), summing to 1: a quarter of each
    quad it is a corner of (so an edge particle holds half an inner one's, a corner a quarter).

    A cloth of even areal density has these as its particles' shares of the mass; a single row or
    column (no quads) shares its length the same way, half a segment at each end.
    """

    shares = np.outer(_line_shares(ny), _line_shares(nx)).ravel()
    return shares / shares.sum()


def _line_shares(n: int) -> np.ndarray:
    """Weights of the n grid lines across one direction: 1, and 1/2 for the two border lines (n > 1)."""
    w = np.ones(n)
    if n > 1:
        w[[0, -1]] = 0.5
    return w


def grid_spring_shares(nx: int, ny: int) -> dict[str, np.ndarray]:
    """The scale of each spring's stiffness and damping, kind -> shape (m,), in `grid_springs`' order.

    A structural or bend spring along a border line stands for half the strip of cloth an inner
    one does, so it is half as stiff: the cloth then resists stretch and bending evenly across its
    width, and every particle, a border one carrying half the mass and a corner a quarter
    (`grid_area_shares`), has the same stiffness per mass (so the stable substep is an inner
    particle's). Shear springs each span one quad: 1. A single row or column is a line: 1.
    """
    rows, cols = _line_shares(ny), _line_shares(nx)
    along_i = np.repeat(rows, max(nx - 1, 0))  # (i, j)-(i+1, j), row j
    along_j = np.tile(cols, max(ny - 1, 0))  # (i, j)-(i, j+1), column i
    bend_i = np.repeat(rows, max(nx - 2, 0))
    bend_j = np.tile(cols, max(ny - 2, 0))
    return {
        "structural": np.concatenate([along_i, along_j]),
        "shear": np.ones(2 * max(nx - 1, 0) * max(ny - 1, 0)),
        "bend": np.concatenate([bend_i, bend_j]),
    }


def grid_springs(nx: int, ny: int) -> dict[str, np.ndarray]:
    """Particle index pairs of each spring kind, kind -> shape (m, 2) int32."""
    idx = np.arange(nx * ny).reshape(ny, nx)

    def pairs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.stack([a.ravel(), b.ravel()], axis=1).astype(np.int32).reshape(-1, 2)

    structural = np.concatenate([pairs(idx[:, :-1], idx[:, 1:]), pairs(idx[:-1, :], idx[1:, :])])
    shear = np.concatenate([pairs(idx[:-1, :-1], idx[1:, 1:]), pairs(idx[:-1, 1:], idx[1:, :-1])])
    bend = np.concatenate([pairs(idx[:, :-2], idx[:, 2:]), pairs(idx[:-2, :], idx[2:, :])])
    return {"structural": structural, "shear": shear, "bend": bend}


def per_kind(value, name: str) -> dict[str, float]:
    """Expand a number or a {structural, shear, bend} mapping to one finite value >= 0 per kind.

    Kinds missing from a mapping are 0 (no such springs).

    Raises:
        ValueError: on unknown kinds, negative or non-finite values.
        TypeError: on a value that is not a number.
    """
    if isinstance(value, dict):
        unknown = set(value) - set(SPRING_KINDS)
        if unknown:
            raise ValueError(f"{name} has unknown spring kind(s) {sorted(unknown)}; expected {', '.join(SPRING_KINDS)}")
        out = {kind: value.get(kind, 0.0) for kind in SPRING_KINDS}
    else:
        out = {kind: value for kind in SPRING_KINDS}
    return {kind: validate.number(v, f"{name} ({kind})", low=0.0) for kind, v in out.items()}


def pin_indices(pins, nx: int, ny: int) -> np.ndarray:
    """Particle indices (row-major, i fastest) named by `pins`, sorted, int32.

    Args:
        pins: None (no pins); "corners"; "top-corners" (the two corners at j = ny - 1);
            "top-edge" (the row j = ny - 1); or a list of [i, j] grid points.

    Raises:
        ValueError: on an unknown name or a grid point outside the cloth.
    """
    if pins is None:
        return np.zeros(0, dtype=np.int32)
    if isinstance(pins, str):
        top = ny - 1
        named = {
            "corners": [(0, 0), (nx - 1, 0), (0, top), (nx - 1, top)],
            "top-corners": [(0, top), (nx - 1, top)],
            "top-edge": [(i, top) for i in range(nx)],
        }
        if pins not in named:
            raise ValueError(f"unknown pins {pins!r}: expected a list of [i, j] or one of {', '.join(named)}")
        points = named[pins]
    else:
        points = []
        for p in pins:
            if not isinstance(p, Sequence) or len(p) != 2:
                raise ValueError(f"each pin must be a grid point [i, j], got {p!r}")
            i, j = p
            if not (float(i).is_integer() and float(j).is_integer()):
                raise ValueError(f"pin grid point must be integers, got {p!r}")
            i, j = int(i), int(j)
            if not (0 <= i < nx and 0 <= j < ny):
                raise ValueError(f"pin {p!r} is outside the {nx} x {ny} grid (0 <= i < {nx}, 0 <= j < {ny})")
            points.append((i, j))
    return np.unique(np.array([j * nx + i for i, j in points], dtype=np.int32))


def tethers(rest: np.ndarray, pinned: np.ndarray, max_stretch: float, per_particle: int = 4):
    """Long-range attachments (Kim, Chentanez and Mueller 2012) from free particles to pins.

    Each free particle is tied to its `per_particle` nearest pins (in the rest shape) and may
    not move farther from them than (1 + max_stretch) times its rest distance. On a flat
    rest shape the straight-line distance is the geodesic one. A hanging cloth then cannot
    sag beyond the stretch limit, however many springs lie between it and the pin, which the
    spring-by-spring stretch limit alone would need many sweeps to achieve.

    Args:
        rest: rest positions of one cloth's particles [m], shape (n, 3).
        pinned: local indices of its pinned particles, shape (k,) int.
        max_stretch: allowed strain (0.1 = 10 %).
        per_particle: tethers per free particle.

    Returns:
        (particle, pin, limit): local particle and pin indices, int32, and largest lengths [m],
        each of shape (m,), sorted by particle.
    """
    n = len(rest)
    if len(pinned) == 0:
        return np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(0)
    free = np.setdiff1d(np.arange(n), pinned)
    k = min(per_particle, len(pinned))
    d = np.linalg.norm(rest[free][:, None, :] - rest[pinned][None, :, :], axis=2)  # (free, pins)
    nearest = np.argsort(d, axis=1, kind="stable")[:, :k]
    particle = np.repeat(free, k).astype(np.int32)
    pin = pinned[nearest].ravel().astype(np.int32)
    limit = (1.0 + max_stretch) * np.take_along_axis(d, nearest, axis=1).ravel()
    return particle, pin, limit
