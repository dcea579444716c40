"""Supports drawn under pinned cloth: posts and rails, so that pins do not float in mid-air.

A pin holds its particle in place by inverse mass 0, with nothing in the world to show what
holds it. The renderer draws, as static geometry that nothing collides with:

- a **post** from the ground up to each corner of the pins seen from above (the corners of the
  convex hull of their x, y positions; a column of pins above one point gets one post, up to
  its highest pin): the hammock's four corner posts, the two ends of a pinned top edge;
- a **rail** along each edge of the cloth's boundary whose two particles are pinned: a pinned
  border becomes a frame, a pinned top edge a rod.

Pins next to a static body (the flag's pole) are held by it already and get no post. Posts stand
on the highest level plane (normal +z) below them; without one, only rails are drawn.
Reads the cloth's particle positions, inverse masses and triangles and the world's static
bodies; costs one NumPy pass over the pins per frame (a cache keeps the result while they stay put).
"""

from __future__ import annotations

import numpy as np

from ..shapes import ShapeType

#: colour (sRGB) of posts and rails: dark wood
SUPPORT_COLOR = (0.45, 0.36, 0.28)
#: pins within this distance [m] (beyond a static body's reach) count as held by that body
HELD_BY_BODY = 0.05


def cloth_supports(world, floats: int = 13) -> np.ndarray:
    """Box instances (centre, quaternion, half extents, colour) of the posts and rails, shape (k, 13), float32."""
    if not world.has_cloth:
        return np.zeros((0, floats), dtype=np.float32)
    cloth = world.cloth
    inv_mass = getattr(cloth, "particle_inv_mass", None)
    if inv_mass is None:
        return np.zeros((0, floats), dtype=np.float32)
    inv_mass = np.asarray(inv_mass)
    pinned = np.flatnonzero(inv_mass == 0.0)
    if not len(pinned):
        return np.zeros((0, floats), dtype=np.float32)
    position = np.asarray(cloth.particle_position, dtype=np.float64).reshape(-1, 3)
    key = (id(getattr(cloth, "source", cloth)), position[pinned].tobytes())
    cached = _cache.get("key")
    if cached is not None and cached == key:
        return _cache["boxes"]
    triangles = np.asarray(cloth.triangles).reshape(-1, 3)
    extent = float(np.linalg.norm(position.max(axis=0) - position.min(axis=0)))
    radius = float(np.clip(0.012 * extent, 0.008, 0.03))

    rails = _rails(position, inv_mass, triangles, 0.6 * radius)
    boxes = [rails[~_held_by_static_bodies(world, rails[:, 0:3])]]
    ground = _ground_below(world)
    if ground is not None:
        free = ~_held_by_static_bodies(world, position[pinned])
        boxes.append(_posts(position[pinned[free]], ground, radius))
    out = np.concatenate(boxes)
    result = np.zeros((len(out), floats), dtype=np.float32)
    result[:, :10] = out
    result[:, 10:13] = SUPPORT_COLOR
    _cache.update(key=key, boxes=result)
    return result


_cache: dict = {}


def _posts(pins: np.ndarray, ground: float, radius: float) -> np.ndarray:
    """Vertical posts (k, 10): centre, quaternion, half extents, from `ground` to each hull corner's top pin."""
    if not len(pins):
        return np.zeros((0, 10))
    # one column per x, y (to 1 mm), as high as its highest pin
    cells = np.round(pins[:, :2] / 1e-3).astype(np.int64)
    _, first, inverse = np.unique(cells, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    top = np.full(len(first), -np.inf)
    np.maximum.at(top, inverse, pins[:, 2])
    xy = pins[first, :2]
    corners = convex_hull_2d(xy)
    x, y, z = xy[corners, 0], xy[corners, 1], top[corners]
    keep = z > ground + radius
    x, y, z = x[keep], y[keep], z[keep]
    out = np.zeros((len(x), 10))
    out[:, 0], out[:, 1], out[:, 2] = x, y, 0.5 * (ground + z)
    out[:, 6] = 1.0  # identity quaternion (x, y, z, w)
    out[:, 7], out[:, 8], out[:, 9] = radius, radius, 0.5 * (z - ground)
    return out


def _rails(position: np.ndarray, inv_mass: np.ndarray, triangles: np.ndarray, radius: float) -> np.ndarray:
    """Rails (k, 10) along the boundary edges of the mesh whose two ends are pinned."""
    if not len(triangles):
        return np.zeros((0, 10))
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    unique, count = np.unique(edges, axis=0, return_counts=True)
    boundary = unique[count == 1]  # an edge of one triangle only
    both = boundary[(inv_mass[boundary[:, 0]] == 0.0) & (inv_mass[boundary[:, 1]] == 0.0)]
    if not len(both):
        return np.zeros((0, 10))
    a, b = position[both[:, 0]], position[both[:, 1]]
    d = b - a
    length = np.linalg.norm(d, axis=1)
    ok = length > 1e-9
    a, d, length = a[ok], d[ok], length[ok]
    u = d / length[:, None]
    # the rotation taking +x to u: axis x cross u, quaternion (x cross u, 1 + x . u) normalised
    q = np.stack([np.zeros(len(u)), -u[:, 2], u[:, 1], 1.0 + u[:, 0]], axis=1)
    flip = q[:, 3] < 1e-9  # u = -x: half a turn about z
    q[flip] = (0.0, 0.0, 1.0, 0.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    out = np.zeros((len(u), 10))
    out[:, 0:3] = a + 0.5 * d
    out[:, 3:7] = q
    out[:, 7] = 0.5 * length + radius  # (rails overlap at the pins, so a frame has closed corners)
    out[:, 8] = out[:, 9] = radius
    return out


def _ground_below(world) -> float | None:
    """Height of the highest level plane of the world, or None."""
    from .camera import ground_level

    return ground_level(world)


def _held_by_static_bodies(world, pins: np.ndarray) -> np.ndarray:
    """For each pin, True when a static sphere or box reaches within `HELD_BY_BODY` of it (in x, y)."""
    held = np.zeros(len(pins), dtype=bool)
    if not world.body_count:
        return held
    shape = np.asarray(world.body_shape)
    static = np.flatnonzero((np.asarray(world.body_inv_mass) == 0.0) & (shape != ShapeType.PLANE))
    if not len(static):
        return held
    centre = np.asarray(world.body_position)[static, :2]
    reach = np.where(
        shape[static] == ShapeType.SPHERE,
        np.asarray(world.body_radius)[static],
        np.linalg.norm(np.asarray(world.body_half_extents)[static, :2], axis=1),
    )
    gap = np.linalg.norm(pins[:, None, :2] - centre[None, :, :], axis=2) - reach[None, :]
    return (gap < HELD_BY_BODY).any(axis=1)


def convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """Indices of the corners of the convex hull of 2D points, counter-clockwise (Andrew's monotone chain).

    Collinear points on an edge are not corners. One or two distinct points are returned as they are.
    """
    n = len(points)
    if n <= 2:
        return np.arange(n)
    order = np.lexsort((points[:, 1], points[:, 0]))

    def cross(o, a, b) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def chain(indices) -> list[int]:
        hull: list[int] = []
        for i in indices:
            while len(hull) >= 2 and cross(points[hull[-2]], points[hull[-1]], points[i]) <= 1e-12:
                hull.pop()
            hull.append(int(i))
        return hull

    lower, upper = chain(order), chain(order[::-1])
    corners = lower[:-1] + upper[:-1]
    return np.array(corners if len(corners) >= 2 else [order[0], order[-1]], dtype=np.int64)
