"""Mouse picking and the drag spring: pull a body or a cloth particle towards the cursor.

A click casts a ray from the camera through the pixel (`Camera.ray`) and picks the nearest movable body whose
bounding sphere it hits (or the nearest cloth particle within reach of the ray). While the button
is held, the grabbed point is pulled towards the cursor, kept in the plane through the grab point
that faces the camera, by a damped spring scaled by mass, so every body follows alike:

    F = m (k (x_target - x) - c v - g)

with k = (2 pi f)^2 and c = 2 zeta (2 pi f): a critically damped spring of frequency f [Hz]. The
`- m g` term holds the weight, so a held body hangs at the cursor instead of sagging below it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: drag spring frequency [Hz] and damping ratio
DRAG_FREQUENCY = 2.0
DRAG_DAMPING = 1.0
#: a force larger than this many g times the mass is clipped, so a fast flick cannot blow up a stack
MAX_DRAG_ACCELERATION = 200.0


def ray_spheres(origin, direction, centres, radii) -> tuple[int, float]:
    """First hit of a ray with a set of spheres.

    Args:
        origin, direction: the ray, shape (3,) each, direction unit length.
        centres: sphere centres [m], shape (n, 3).
        radii: sphere radii [m], shape (n,).

    Returns:
        (index, distance) of the nearest sphere hit in front of the origin, or (-1, inf).
    """
    centres = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
    if len(centres) == 0:
        return -1, math.inf
    # |o + t d - c|^2 = r^2  ->  t^2 + 2 b t + c0 = 0 with b = d.(o - c), c0 = |o - c|^2 - r^2
    oc = np.asarray(origin, dtype=np.float64) - centres
    b = oc @ np.asarray(direction, dtype=np.float64)
    c0 = np.einsum("ij,ij->i", oc, oc) - np.asarray(radii, dtype=np.float64) ** 2
    disc = b * b - c0
    hit = disc >= 0.0
    root = np.sqrt(np.where(hit, disc, 0.0))
    t = np.where(-b - root > 0.0, -b - root, -b + root)  # the far root when the origin is inside
    t = np.where(hit & (t > 0.0), t, np.inf)
    i = int(np.argmin(t))
    return (i, float(t[i])) if math.isfinite(t[i]) else (-1, math.inf)


def ray_points(origin, direction, points, reach: float) -> tuple[int, float]:
    """Nearest point (along the ray) lying within `reach` [m] of a ray, e.g. a cloth particle.

    Returns:
        (index, distance along the ray), or (-1, inf) when none is within reach.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) == 0:
        return -1, math.inf
    rel = points - np.asarray(origin, dtype=np.float64)
    t = rel @ np.asarray(direction, dtype=np.float64)
    off = rel - t[:, None] * np.asarray(direction, dtype=np.float64)
    near = (t > 0.0) & (np.einsum("ij,ij->i", off, off) <= reach * reach)
    t = np.where(near, t, np.inf)
    i = int(np.argmin(t))
    return (i, float(t[i])) if math.isfinite(t[i]) else (-1, math.inf)


def quat_rotate(q, v) -> np.ndarray:
    """Rotate vector `v` (3,) by the unit quaternion `q` = (x, y, z, w)."""
    u = np.asarray(q[:3], dtype=np.float64)
    w = float(q[3])
    v = np.asarray(v, dtype=np.float64)
    # v' = v + 2 w (u x v) + 2 u x (u x v)
    uv = np.cross(u, v)
    return v + 2.0 * w * uv + 2.0 * np.cross(u, uv)


def quat_conjugate(q) -> np.ndarray:
    """Inverse of a unit quaternion (x, y, z, w)."""
    return np.array([-q[0], -q[1], -q[2], q[3]], dtype=np.float64)


@dataclass
class Grab:
    """What the mouse holds: a body (with the grabbed point in its frame) or a cloth particle.

    Attributes:
        kind: "body" or "particle".
        index: body index or particle index.
        local_point: grabbed point in the body frame [m], shape (3,) (zero for particles).
        distance: distance from the camera to the grab point along the click ray [m].
        target: where the cursor is in the world [m], shape (3,).
        depth: depth of the grab point along the view axis [m]; the drag plane's distance.
    """

    kind: str
    index: int
    local_point: np.ndarray
    distance: float
    target: np.ndarray
    depth: float = 0.0


def pick(world, origin, direction, view_forward=None) -> Grab | None:
    """Pick the nearest movable body (bounding sphere) or cloth particle on a ray, or None.

    `view_forward` (the camera's unit view axis, default the ray) sets the drag plane's depth.
    """
    origin = np.asarray(origin, dtype=np.float64)
    direction = np.asarray(direction, dtype=np.float64)
    best: Grab | None = None
    n = world.body_count
    if n:
        inv_mass = np.asarray(world.body_inv_mass)
        movable = np.nonzero(inv_mass > 0.0)[0]
        if len(movable):
            radii = _bound_radii(world)[movable]
            i, t = ray_spheres(origin, direction, np.asarray(world.body_position)[movable], radii)
            if i >= 0:
                body = int(movable[i])
                hit = origin + t * direction
                local = quat_rotate(quat_conjugate(world.body_orientation[body]), hit - world.body_position[body])
                best = Grab("body", body, local, t, hit)
    cloth = cloth_of(world)
    if cloth is not None and hasattr(cloth, "apply_force") and cloth.particle_count:
        points = np.asarray(cloth.particle_position)
        j, t = ray_points(origin, direction, points, _particle_reach(points))
        if j >= 0 and (best is None or t < best.distance):
            best = Grab("particle", j, np.zeros(3), t, np.asarray(points[j], dtype=np.float64).copy())
    if best is not None:
        forward = direction if view_forward is None else np.asarray(view_forward, dtype=np.float64)
        best.depth = best.distance * float(direction @ forward)
    return best


def drag_target(grab: Grab, origin, direction, view_forward) -> np.ndarray:
    """Cursor position in the world: where the ray meets the camera-facing plane through the grab point."""
    denom = float(np.asarray(direction) @ np.asarray(view_forward))
    t = grab.depth / denom if denom > 1e-6 else grab.distance
    return np.asarray(origin, dtype=np.float64) + t * np.asarray(direction, dtype=np.float64)


def apply_drag(world, grab: Grab) -> None:
    """Apply this step's spring force pulling the grabbed point towards `grab.target`."""
    omega = 2.0 * math.pi * DRAG_FREQUENCY
    k, c = omega * omega, 2.0 * DRAG_DAMPING * omega
    g = np.asarray(world.gravity, dtype=np.float64)
    if grab.kind == "body":
        i = grab.index
        if i >= world.body_count:
            return
        mass = float(world.body_mass[i])
        r = quat_rotate(world.body_orientation[i], grab.local_point)
        point = world.body_position[i] + r
        velocity = world.body_velocity[i] + np.cross(world.body_angular_velocity[i], r)
        accel = _clip(k * (grab.target - point) - c * velocity - g, MAX_DRAG_ACCELERATION * 9.81)
        world.apply_force(i, mass * accel, point=point)
    else:
        cloth = cloth_of(world)
        if cloth is None or grab.index >= cloth.particle_count:
            return
        point = np.asarray(cloth.particle_position[grab.index], dtype=np.float64)
        velocity = np.asarray(cloth.particle_velocity[grab.index], dtype=np.float64)
        mass = _particle_mass(cloth, grab.index)
        accel = _clip(k * (grab.target - point) - c * velocity - g, MAX_DRAG_ACCELERATION * 9.81)
        cloth.apply_force(grab.index, mass * accel)


def cloth_of(world):
    """The world's cloth system if it has one with particles, without creating one."""
    cloth = getattr(world, "_cloth", None)
    if cloth is None or not getattr(cloth, "particle_count", 0):
        return None
    return cloth


def _bound_radii(world) -> np.ndarray:
    radius = np.asarray(world.body_radius, dtype=np.float64)
    half = np.asarray(world.body_half_extents, dtype=np.float64)
    return np.maximum(radius, np.linalg.norm(half, axis=1))


def _particle_reach(points: np.ndarray) -> float:
    """How close a ray must pass to grab a particle: about half the typical particle spacing."""
    if len(points) < 2:
        return 0.05
    extent = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    return max(0.01, 0.75 * extent / math.sqrt(len(points)))


def _particle_mass(cloth, index: int) -> float:
    for name in ("particle_mass",):
        masses = getattr(cloth, name, None)
        if masses is not None:
            m = float(np.asarray(masses)[index])
            if m > 0.0:
                return m
    return 1.0


def _clip(v: np.ndarray, limit: float) -> np.ndarray:
    norm = float(np.linalg.norm(v))
    return v if norm <= limit else v * (limit / norm)
