"""Mouse picking and the drag spring: pull a body or a cloth particle towards the cursor.

A click casts a ray from the camera through the pixel (`Camera.ray`) and picks the nearest movable body it
hits (spheres, boxes, capsules and convex hulls exactly; among the bodies whose bounding sphere the ray
meets), or the nearest cloth particle within reach of the ray. Static meshes and other static bodies
are not picked. A body held by joints is pulled like any other: the joints pull back. While the button
is held, the grabbed point is pulled towards the cursor, kept in the plane through the grab point
that faces the camera, by a damped spring scaled by mass, so every body follows alike:

    F = m (k (x_target - x) - c v - g)

with k = (2 pi f)^2 and c = 2 zeta (2 pi f): a critically damped spring of frequency f [Hz]. The
`- m g` term holds the weight, so a held body hangs at the cursor instead of sagging below it.
Cloth particles get the same force through `cloth.apply_force`; a pinned particle is not pulled
but moved: its pin follows the cursor (`cloth.set_pin_target`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..npmath import quat_conj, quat_rotate
from ..shapes import ShapeType

#: drag spring frequency [Hz] and damping ratio
DRAG_FREQUENCY = 2.0
DRAG_DAMPING = 1.0
#: fastest a dragged pin moves [m/s]
MAX_PIN_SPEED = 3.0
#: a force larger than this many g times the mass is clipped, so a fast flick cannot blow up a stack
MAX_DRAG_ACCELERATION = 200.0


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


@dataclass
class Grab:
    """What the mouse holds: a body (with the grabbed point in its frame) or a cloth particle.

    Attributes:
        kind: "body", "particle" (pulled by the spring) or "pin" (a pinned particle, moved to the cursor).
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
            body, t = _pick_body(world, origin, direction, movable)
            if body >= 0:
                hit = origin + t * direction
                local = quat_rotate(quat_conj(world.body_orientation[body]), hit - world.body_position[body])
                best = Grab("body", body, local, t, hit)
    cloth = cloth_of(world)
    # (a snapshot's cloth answers for the cloth it was copied from)
    system = getattr(cloth, "source", cloth)
    if cloth is not None and hasattr(system, "apply_force"):
        points = np.asarray(cloth.particle_position)
        j, t = ray_points(origin, direction, points, _particle_reach(points))
        if j >= 0 and (best is None or t < best.distance):
            # a pinned particle (inverse mass 0) is moved, pin and all; a free one is pulled
            pinned = hasattr(system, "set_pin_target") and float(np.asarray(cloth.particle_inv_mass)[j]) == 0.0
            best = Grab(
                "pin" if pinned else "particle", j, np.zeros(3), t, np.asarray(points[j], dtype=np.float64).copy()
            )
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
        if grab.kind == "pin":
            # move the pin towards the cursor at a bounded speed, so the cloth can follow
            here = np.asarray(cloth.particle_position[grab.index], dtype=np.float64)
            cloth.set_pin_target(grab.index, here + _clip(grab.target - here, MAX_PIN_SPEED * float(world.dt)))
            return
        point = np.asarray(cloth.particle_position[grab.index], dtype=np.float64)
        velocity = np.asarray(cloth.particle_velocity[grab.index], dtype=np.float64)
        mass = _particle_mass(cloth, grab.index)
        accel = _clip(k * (grab.target - point) - c * velocity - g, MAX_DRAG_ACCELERATION * 9.81)
        cloth.apply_force(grab.index, mass * accel)


def held_point(world, grab: Grab) -> np.ndarray | None:
    """Where the held point is now [m], shape (3,), or None when its body or particle is gone."""
    if grab.kind == "body":
        if grab.index >= world.body_count:
            return None
        return world.body_position[grab.index] + quat_rotate(world.body_orientation[grab.index], grab.local_point)
    cloth = cloth_of(world)
    if cloth is None or grab.index >= cloth.particle_count:
        return None
    return np.asarray(cloth.particle_position[grab.index], dtype=np.float64)


def cloth_of(world):
    """The world's cloth system if it has one with particles, without creating one."""
    return world.cloth if world.has_cloth else None


def _pick_body(world, origin, direction, candidates) -> tuple[int, float]:
    """Nearest body hit by the ray: spheres exactly, boxes, capsules and hulls inside their bounding sphere."""
    centres = np.asarray(world.body_position)[candidates]
    radii = _bound_radii(world)[candidates]
    # bounding-sphere hits, nearest first; a sphere's bound is the sphere itself
    oc = origin - centres
    b = oc @ direction
    disc = b * b - (np.einsum("ij,ij->i", oc, oc) - radii**2)
    order = [k for k in np.argsort(np.where(disc >= 0.0, -b, np.inf)) if disc[k] >= 0.0]
    best_body, best_t = -1, math.inf
    for k in order:
        body = int(candidates[k])
        shape = int(world.body_shape[body])
        if shape == ShapeType.BOX:
            t = ray_box(origin, direction, centres[k], world.body_orientation[body], world.body_half_extents[body])
        elif shape == ShapeType.CAPSULE:
            radius = float(world.body_radius[body])
            t = ray_capsule(
                origin,
                direction,
                centres[k],
                world.body_orientation[body],
                radius,
                float(world.body_half_extents[body][2]) - radius,
            )
        elif shape == ShapeType.CONVEX and _hull(world, body) is not None:
            proto = _hull(world, body)
            t = ray_convex(origin, direction, centres[k], world.body_orientation[body], proto.normal, proto.offset)
        else:
            root = math.sqrt(disc[k])
            t = -b[k] - root if -b[k] - root > 0.0 else -b[k] + root
        if 0.0 < t < best_t:
            best_body, best_t = body, t
    return best_body, best_t


def ray_box(origin, direction, centre, orientation, half_extents) -> float:
    """Distance along a ray to an oriented box (slab test in the box frame), or inf if missed."""
    inv_q = quat_conj(orientation)
    o = quat_rotate(inv_q, np.asarray(origin, dtype=np.float64) - centre)
    d = quat_rotate(inv_q, direction)
    h = np.asarray(half_extents, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-h - o) / d, (h - o) / d
    t1 = np.where(np.abs(d) < 1e-12, np.where(np.abs(o) <= h, -np.inf, np.inf), t1)
    t2 = np.where(np.abs(d) < 1e-12, np.where(np.abs(o) <= h, np.inf, -np.inf), t2)
    near, far = float(np.max(np.minimum(t1, t2))), float(np.min(np.maximum(t1, t2)))
    if near > far or far <= 0.0:
        return math.inf
    return near if near > 0.0 else far


def ray_capsule(origin, direction, centre, orientation, radius: float, half_height: float) -> float:
    """Distance along a ray to a capsule (segment of half length `half_height` on the body's z axis), or inf."""
    inv_q = quat_conj(orientation)
    o = quat_rotate(inv_q, np.asarray(origin, dtype=np.float64) - centre)
    d = quat_rotate(inv_q, direction)
    hits = []
    # the side: |(o + t d)_xy|^2 = r^2, within the segment's length
    a = d[0] ** 2 + d[1] ** 2
    b = o[0] * d[0] + o[1] * d[1]
    c = o[0] ** 2 + o[1] ** 2 - radius**2
    if a > 1e-12 and b * b - a * c >= 0.0:
        for t in ((-b - math.sqrt(b * b - a * c)) / a, (-b + math.sqrt(b * b - a * c)) / a):
            if abs(o[2] + t * d[2]) <= half_height:
                hits.append(t)
    # the two end caps: spheres at +-half_height on z
    for z in (half_height, -half_height):
        oc = o - np.array([0.0, 0.0, z])
        bb = float(oc @ d)
        disc = bb * bb - (float(oc @ oc) - radius**2)
        if disc >= 0.0:
            hits += [-bb - math.sqrt(disc), -bb + math.sqrt(disc)]
    ahead = [t for t in hits if t > 0.0]
    return min(ahead) if ahead else math.inf


def ray_convex(origin, direction, centre, orientation, normal, offset) -> float:
    """Distance along a ray to a convex polyhedron {x : n_i . x <= d_i} in its body frame (Cyrus-Beck), or inf."""
    inv_q = quat_conj(orientation)
    o = quat_rotate(inv_q, np.asarray(origin, dtype=np.float64) - centre)
    d = quat_rotate(inv_q, direction)
    n = np.asarray(normal, dtype=np.float64)
    gap = np.asarray(offset, dtype=np.float64) - n @ o  # >= 0 inside each face's half space
    rate = n @ d
    parallel = np.abs(rate) < 1e-12
    if np.any(parallel & (gap < 0.0)):
        return math.inf
    with np.errstate(divide="ignore", invalid="ignore"):
        t = gap / rate
    near = float(np.max(t[(rate < 0.0) & ~parallel], initial=-math.inf))
    far = float(np.min(t[(rate > 0.0) & ~parallel], initial=math.inf))
    if near > far or far <= 0.0:
        return math.inf
    return near if near > 0.0 else far


def _hull(world, body: int):
    hulls = getattr(world, "hulls", None)
    geometry = getattr(world, "body_geometry", None)
    if hulls is None or geometry is None:
        return None
    index = int(np.asarray(geometry)[body])
    return hulls.prototypes[index] if 0 <= index < len(hulls.prototypes) else None


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
    mass = float(np.asarray(cloth.particle_mass)[index])
    return mass if mass > 0.0 else 1.0


def _clip(v: np.ndarray, limit: float) -> np.ndarray:
    norm = float(np.linalg.norm(v))
    return v if norm <= limit else v * (limit / norm)
