"""Emitters release bodies over time, never on top of another body.

Any dynamic shape: spheres, boxes, capsules and convex hulls (of points, or of a mesh file's
vertices, hulled once when the emitter is made), each body with its own random size (`radius`,
`half_extents`, `half_height` ranges, and a `scale` range applied to every shape) and, with
`random_orientation`, a uniformly random orientation. Convex bodies share `HULL_SCALES` scaled
copies of the hull (exact: volume s^3, moments s^5), made when the emitter is added to a world:
a convex body's drawn scale is rounded to the nearest of them (a fixed scale makes one). So the
world's hull prototypes do not grow while it runs (snapshots restore, the renderer instances
per prototype, the narrow phase's hull arrays stay put).

An emitter holds a rate [bodies/s] and a count; each step it owes `rate * dt` more bodies.
Candidates are drawn from the region (a point, a box or a disc) and redrawn a few times (from a
point: scattered ever wider around it) until a candidate's bounding sphere clears every body
already in the world (a mesh by its triangles, and a closed mesh's inside too) and every candidate
accepted before it; a candidate that finds no free spot waits for a later step
(the emitter falls behind rather than overlap). This replaces the design report's "release
speed" workaround: nothing overlaps at birth, so the solver never has to untangle a knot.

Cost per step: O(k * n) vectorised NumPy distance tests for k new bodies among n, outside the
kernels; k is small for any sensible rate. A mesh adds its triangles near the region to each test,
and a closed mesh whose bounds hold a candidate all of its triangles (the winding number).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from . import validate
from .collision.meshes import closest_on_triangles, winding_number
from .limits import MAX_RELEASE_PER_STEP
from .npmath import quat_mul, quat_to_matrix
from .shapes import (
    DEFAULT_DENSITY,
    DEFAULT_FRICTION,
    DEFAULT_RESTITUTION,
    ShapeType,
    box_inertia,
    box_volume,
    capsule_inertia,
    capsule_volume,
    shape_from_name,
    sphere_inertia,
    sphere_volume,
)

if TYPE_CHECKING:
    from .collision.hulls import HullSet
    from .collision.meshes import MeshSet
    from .state import RowGroup

#: jittered tries per candidate before it waits for the next step
TRIES = 8
#: extra clearance between a new body and its neighbours [m]
CLEARANCE = 1e-3
#: scaled copies of a convex emitter's hull, evenly spaced over its scale range
HULL_SCALES = 16


class Emitter:
    """Releases spheres, boxes, capsules and convex bodies at a rate, from a region, in a cone.

    Args:
        shape: "sphere", "box", "capsule", "convex", or a list of them (chosen at random per body).
        rate: bodies per second (> 0).
        count: total bodies to release (> 0).
        position: centre of the region [m], shape (3,).
        region: "point", "box" (half sizes `extent`, shape (3,)) or "disc" (radius `extent`,
            in the plane orthogonal to `direction`).
        extent: region size, see `region`.
        direction: mean launch direction, shape (3,), need not be unit.
        cone_angle: half-angle of the launch cone [degrees].
        speed: launch speed [m/s], a value or [min, max].
        radius: sphere radius [m], a value or [min, max].
        half_extents: box half extents [m], a 3-vector or [[min...], [max...]]; a single number
            gives cubes, a [min, max] pair of numbers gives random cubes.
        half_height: capsule half height [m] (of its segment; `radius` is its radius), a value or [min, max].
        points: the points whose convex hull a "convex" body is, shape (n, 3) [m], in its frame;
            or `file`, a mesh file (OBJ, STL, PLY, OFF, glTF/GLB) whose vertices are hulled.
        scale: a factor applied to each body's size (radius, half extents, half height, hull),
            a value or [min, max] drawn per body (default 1); a convex body's is rounded to the
            nearest of `HULL_SCALES` shared hull copies spread over the range.
        mass: body mass [kg], a value or [min, max]; or `density` [kg/m^3] (default 1000).
        restitution, friction: material of the bodies.
        random_orientation: give each body a uniformly random orientation.
        angular_speed: initial spin [rad/s] about a random axis, a value or [min, max].
        seed: seed of this emitter's random generator (default: drawn from the world's).
    """

    def __init__(
        self,
        *,
        shape: str | Sequence[str] = "sphere",
        rate: float = 100.0,
        count: int = 100,
        position: Sequence[float] | np.ndarray = (0.0, 0.0, 1.0),
        region: str = "point",
        extent: float | Sequence[float] = 0.0,
        direction: Sequence[float] | np.ndarray = (0.0, 0.0, -1.0),
        cone_angle: float = 0.0,
        speed: float | Sequence[float] = 0.0,
        radius: float | Sequence[float] = 0.05,
        half_extents: float | Sequence = 0.05,
        half_height: float | Sequence[float] = 0.05,
        points: ArrayLike | None = None,
        file: str | os.PathLike[str] | None = None,
        scale: float | Sequence[float] = 1.0,
        mass: float | Sequence[float] | None = None,
        density: float | Sequence[float] | None = None,
        restitution: float = DEFAULT_RESTITUTION,
        friction: float = DEFAULT_FRICTION,
        random_orientation: bool = False,
        angular_speed: float | Sequence[float] = 0.0,
        seed: int | None = None,
    ):
        if not isinstance(shape, (str, list, tuple)):
            raise TypeError(f"shape must be a shape name or a list of them, got {validate.show(shape)}")
        names = [shape] if isinstance(shape, str) else list(shape)
        if not names:
            raise ValueError("shape must name at least one shape")
        self.shapes = [shape_from_name(validate.text(s, "shape")) for s in names]
        for fixed in (ShapeType.PLANE, ShapeType.MESH):
            if fixed in self.shapes:
                raise ValueError(
                    f"an emitter cannot emit {fixed.name.lower()}s (static): use shape 'sphere', "
                    "'box', 'capsule' or 'convex'"
                )
        self.rate = validate.positive(rate, "rate")  # > 0 to start with; the setter allows 0 (paused)
        self.count = validate.integer(count, "count", low=1)
        self.position = validate.vector(position, "position")
        self.region = validate.text(region, "region", ("point", "box", "disc"))
        ext: np.ndarray | None  # None: a box extent of the wrong shape
        ext = validate.array(extent, "extent", "a number or [x, y, z] half sizes")
        if region == "box":
            ext = np.broadcast_to(ext, (3,)).copy() if ext.shape in ((), (3,)) else None
            if ext is None:
                raise ValueError(f"extent of a box region must be half sizes [x, y, z], got {extent!r}")
        elif region == "disc" and ext.shape != ():
            raise ValueError(f"extent of a disc region must be its radius, got {extent!r}")
        if ext is not None and (not np.all(np.isfinite(ext)) or np.any(ext < 0)):
            raise ValueError(f"extent must be finite and >= 0, got {extent!r}")
        self.extent = ext
        self.direction = validate.direction(direction, "direction")
        self.cone_angle = validate.number(cone_angle, "cone_angle", low=0.0, high=180.0)
        self.speed = validate.bounds(speed, "speed")
        self.radius = validate.bounds(radius, "radius")
        h = validate.array(half_extents, "half_extents", "a number, a 3-vector or a [min, max] pair")
        if h.shape == (2,):  # random cubes: [min, max] of one half extent
            self.half_extents = (np.full(3, h[0]), np.full(3, h[1]))
            self._cubes = True
        else:
            self.half_extents = validate.bounds(half_extents, "half_extents", 3)
            self._cubes = h.shape == ()
        self.half_height = validate.bounds(half_height, "half_height")
        self.scale = validate.bounds(scale, "scale")
        self.hull = None  # the convex prototype, at scale 1
        if ShapeType.CONVEX in self.shapes:
            self.hull = _emitted_hull(points, file)
        elif points is not None or file is not None:
            raise ValueError("points and file are for shape 'convex', which this emitter does not emit")
        self.hull_rows: np.ndarray | None = None  # rows in world.hulls of the scaled hulls (`add_hulls`)
        if mass is not None and density is not None:
            raise ValueError("give mass or density, not both")
        self.mass = None if mass is None else validate.bounds(mass, "mass")
        self.density = validate.bounds(DEFAULT_DENSITY if density is None else density, "density")
        for name, (lo, _hi) in (
            ("speed", self.speed),
            ("radius", self.radius),
            ("half_extents", self.half_extents),
            ("half_height", self.half_height),
            ("scale", self.scale),
            ("density", self.density),
        ) + ((("mass", self.mass),) if self.mass else ()):
            if np.any(lo < 0) or (name != "speed" and np.any(lo <= 0)):
                raise ValueError(f"{name} must be > 0, got {lo!r}")
        self.restitution = validate.restitution(restitution)
        self.friction = validate.friction(friction)
        self.random_orientation = validate.flag(random_orientation, "random_orientation")
        self.angular_speed = validate.bounds(angular_speed, "angular_speed")
        self.seed = None if seed is None else validate.seed(seed)
        self.world_key: int | None = None  # the World it was added to (`World.add_emitter`)
        self.emitted = 0
        #: simulated seconds for which the emitter has owed bodies and found no free spot in its
        #: region for any (0 while it releases them): a region inside a mesh or a heap never releases
        self.blocked_for = 0.0
        self._owed = 0.0
        self.reset_rng()

    @property
    def rate(self) -> float:
        """Bodies released per second; may be changed while the world runs (>= 0: 0 pauses the emitter)."""
        return self._rate

    @rate.setter
    def rate(self, value: float) -> None:
        self._rate = validate.number(value, "rate", low=0.0)

    def reset_rng(self) -> None:
        """Restart the emitter's random generator from its `seed` (done when it is added to a world)."""
        self.rng = np.random.default_rng(self.seed)

    @property
    def done(self) -> bool:
        """True once `count` bodies have been released."""
        return self.emitted >= self.count

    # ------------------------------------------------------------------ sampling

    def _uniform(self, lo, hi, k: int) -> np.ndarray:
        return lo + (hi - lo) * self.rng.random((k,) + np.shape(lo))

    def _sample_positions(self, k: int) -> np.ndarray:
        if self.region == "point":
            return np.repeat(self.position[None], k, axis=0)
        if self.region == "box":
            return self.position + self.extent * (2.0 * self.rng.random((k, 3)) - 1.0)
        # disc orthogonal to the direction, uniform in area
        u, v = _basis(self.direction)
        r = float(self.extent) * np.sqrt(self.rng.random(k))
        phi = 2.0 * np.pi * self.rng.random(k)
        return self.position + (r * np.cos(phi))[:, None] * u + (r * np.sin(phi))[:, None] * v

    def _region_half_size(self, jitter: float) -> np.ndarray:
        """Half size of a box around `position` holding every spot `emit` may try, per axis [m]."""
        if self.region == "box":
            return np.asarray(self.extent, dtype=float)
        if self.region == "disc":
            return np.full(3, float(self.extent))
        return np.full(3, jitter * (TRIES - 1))  # a point scatters its later tries

    def _sample_directions(self, k: int) -> np.ndarray:
        # uniform on the spherical cap of half-angle theta around the direction
        cos_max = math.cos(math.radians(self.cone_angle))
        z = 1.0 - self.rng.random(k) * (1.0 - cos_max)
        phi = 2.0 * np.pi * self.rng.random(k)
        s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        u, v = _basis(self.direction)
        return (s * np.cos(phi))[:, None] * u + (s * np.sin(phi))[:, None] * v + z[:, None] * self.direction

    def _sample_bodies(self, k: int) -> dict[str, np.ndarray]:
        rng = self.rng
        # the draws of spheres and boxes come first, in their original order (a scene of those
        # emits the same bodies as before capsules, hulls and scale existed); then the new ones,
        # each only when it varies
        shape = np.asarray(self.shapes, dtype=np.int32)[rng.integers(0, len(self.shapes), k)]
        radius = self._uniform(*self.radius, k)
        half = self._uniform(*self.half_extents, k)
        if self._cubes:
            half = np.repeat(half[:, :1], 3, axis=1)
        drawn_mass = self._uniform(*self.mass, k) if self.mass is not None else None
        drawn_density = self._uniform(*self.density, k) if self.mass is None else None
        velocity = self._sample_directions(k) * self._uniform(*self.speed, k)[:, None]
        if self.random_orientation:
            q = rng.normal(size=(k, 4))
            orientation = q / np.linalg.norm(q, axis=1, keepdims=True)
        else:
            orientation = np.tile([0.0, 0.0, 0.0, 1.0], (k, 1))
        axis = rng.normal(size=(k, 3))
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        angular_velocity = axis * self._uniform(*self.angular_speed, k)[:, None]
        scale = self._varying(self.scale, k)
        hull_level = self._hull_level(scale)
        half_height = self._varying(self.half_height, k) if ShapeType.CAPSULE in self.shapes else np.zeros(k)

        # sizes, volumes, bounding radii and unit-density moments, per shape
        is_sphere = shape == ShapeType.SPHERE
        is_box = shape == ShapeType.BOX
        is_capsule = shape == ShapeType.CAPSULE
        is_hull = shape == ShapeType.CONVEX
        radius = np.where(is_sphere | is_capsule, radius * scale, 0.0)
        a = np.where(is_capsule, half_height * scale, 0.0)
        half = np.where(is_box[:, None], half * scale[:, None], 0.0)
        half = np.where(is_capsule[:, None], np.stack([radius, radius, a + radius], axis=1), half)
        volume = np.select(
            [is_sphere, is_box, is_capsule], [sphere_volume(radius), box_volume(half), capsule_volume(radius, a)], 0.0
        )

        bound = np.select([is_sphere, is_box, is_capsule], [radius, np.linalg.norm(half, axis=1), a + radius], 0.0)
        if self.hull is not None:
            hull = self.hull
            s = self.hull_scales[hull_level]  # the scale of the shared copy
            scale = np.where(is_hull, s, scale)
            volume = np.where(is_hull, hull.volume * scale**3, volume)
            bound = np.where(is_hull, hull.bound_radius * scale, bound)
            half = np.where(is_hull[:, None], np.abs(hull.vertex).max(axis=0) * scale[:, None], half)
            # the body frame is the hull's principal frame: the drawn orientation is the user frame's
            turned = quat_mul(orientation, hull.rotation).reshape(k, 4)
            orientation = np.where(is_hull[:, None], turned, orientation)
        mass = drawn_mass if drawn_mass is not None else drawn_density * volume
        with np.errstate(invalid="ignore", divide="ignore"):  # each shape's formula on every row, one kept
            inertia = np.select(
                [is_sphere[:, None], is_box[:, None], is_capsule[:, None]],
                [sphere_inertia(mass, radius), box_inertia(mass, half), capsule_inertia(mass, radius, a)],
                0.0,
            )
        if self.hull is not None:
            # moments at density 1 scale as s^5, the volume as s^3: I = I_1 s^5 m / (V_1 s^3)
            moments = self.hull.inertia[None] * (scale**2 * mass / self.hull.volume)[:, None]
            inertia = np.where(is_hull[:, None], moments, inertia)
        return dict(
            shape=shape,
            radius=radius,
            half_extents=half,
            mass=mass,
            inertia=inertia,
            velocity=velocity,
            orientation=orientation,
            angular_velocity=angular_velocity,
            bound=bound,
            hull_level=hull_level,
        )

    def _varying(self, bounds: tuple[np.ndarray, np.ndarray], k: int) -> np.ndarray:
        """k draws from [lo, hi]; no draw (the generator untouched) when lo == hi."""
        lo, hi = bounds
        if float(lo) == float(hi):
            return np.full(k, float(lo))
        return self._uniform(lo, hi, k)

    @property
    def hull_scales(self) -> np.ndarray:
        """The scales of the shared hull copies: `HULL_SCALES` evenly over [min, max], one for a fixed scale."""
        lo, hi = float(self.scale[0]), float(self.scale[1])
        return np.array([lo]) if lo == hi else np.linspace(lo, hi, HULL_SCALES)

    def _hull_level(self, scale: np.ndarray) -> np.ndarray:
        """Index of the shared hull copy nearest each drawn scale."""
        levels = self.hull_scales
        if len(levels) == 1:
            return np.zeros(len(scale), dtype=np.int64)
        t = (scale - levels[0]) / (levels[-1] - levels[0]) * (len(levels) - 1)
        return np.clip(np.rint(t), 0, len(levels) - 1).astype(np.int64)

    def add_hulls(self, hulls: HullSet) -> None:
        """Store the scaled hull copies in the `HullSet` `hulls` (`World.add_emitter` does, before any step)."""
        if self.hull is not None:
            copies = [self.hull.scaled(float(s)) for s in self.hull_scales]
            for s, copy in zip(self.hull_scales, copies):  # all checked before the first is added
                if not validate.mass_properties_usable(copy.volume, copy.inertia):
                    raise ValueError(
                        f"scale {s:g} gives the hull a volume of {copy.volume:g} m^3 and unit-density moments "
                        f"down to {float(np.min(copy.inertia)):g} m^5; both must be finite and > 0 in float64"
                    )
            self.hull_rows = np.array([hulls.add(copy) for copy in copies], dtype=np.int32)

    # ------------------------------------------------------------------ emission

    def _mesh_walls(self, bodies: RowGroup, meshes: MeshSet, rows: np.ndarray, half: np.ndarray) -> list[tuple]:
        """For each mesh body in `rows` (a mask of the body rows): its pose (rotation matrix, position)
        and, in its frame, its triangles' corners (a, b, c) that may reach a candidate (the region's
        box of half size `half` holds every candidate's bounding sphere); with, for a closed mesh (a
        solid) whose bounds the box may reach, all its triangles and those bounds, to tell a spot
        inside it. Distances and the winding number are the same in the mesh's frame."""
        walls = []
        reach = float(np.linalg.norm(half))  # the box, as the sphere around it
        rows = np.flatnonzero(rows)
        geometry = bodies.numpy("body_geometry")[rows]
        rotations = quat_to_matrix(bodies.numpy("body_orientation")[rows])
        positions = bodies.numpy("body_position")[rows]
        for row, rotation, position in zip(map(int, geometry), rotations, positions):
            centre = rotation.T @ (self.position - position)
            lo, hi = centre - reach, centre + reach
            a, b, c = meshes.corners(row)
            near = np.all((np.minimum(np.minimum(a, b), c) <= hi) & (np.maximum(np.maximum(a, b), c) >= lo), axis=1)
            solid = None
            if meshes.closed[row]:
                low, high = meshes.vertices[row].min(axis=0), meshes.vertices[row].max(axis=0)
                if np.all((low <= hi) & (high >= lo)):
                    solid = (a, b, c, low, high)
            if near.any() or solid is not None:
                walls.append((rotation, position, a[near], b[near], c[near], solid))
        return walls

    def release(self, bodies: RowGroup, dt: float, meshes: MeshSet | None = None) -> dict[str, np.ndarray] | None:
        """The bodies owed for this step that find a free spot among `bodies` (the world's body arrays)
        and the triangles of `meshes` (the world's meshes, placed by their bodies).

        Returns the new bodies' rows, as the keywords of the world's body append (the world's emit
        stage adds them), or None when none is released this step. The emitter counts them as released.
        """
        if self.done:
            return None
        self._owed += self.rate * dt
        # at most MAX_RELEASE_PER_STEP a step: each candidate is placed in a NumPy loop below
        k = min(int(self._owed), self.count - self.emitted, MAX_RELEASE_PER_STEP)
        if k <= 0:
            return None
        cand = self._sample_bodies(k)
        shape = bodies.numpy("body_shape")
        # what is already there: spheres by centre and radius, boxes as oriented boxes, planes
        x_all = bodies.numpy("body_position")
        jitter = max(float(np.max(cand["bound"])), 1e-3)
        # only bodies whose bounding sphere reaches the region (grown by the largest candidate)
        # can block a spot: test those, not all n bodies n times (planes always reach)
        half = self._region_half_size(jitter) + jitter + CLEARANCE
        gap = np.linalg.norm(x_all - np.clip(x_all, self.position - half, self.position + half), axis=1)
        near = gap < bodies.numpy("body_bound_radius")
        spheres = (shape == ShapeType.SPHERE) & near
        boxes = (shape == ShapeType.BOX) & near
        # capsules by their segment, convex bodies by their bounding sphere, meshes by their triangles
        capsules = (shape == ShapeType.CAPSULE) & near
        hulls = (shape == ShapeType.CONVEX) & near
        planes = shape == ShapeType.PLANE
        sphere_x, sphere_r = x_all[spheres], bodies.numpy("body_radius")[spheres]
        box_x, box_h = x_all[boxes], bodies.numpy("body_half_extents")[boxes]
        box_rot = quat_to_matrix(bodies.numpy("body_orientation")[boxes])
        capsule_x, capsule_r = x_all[capsules], bodies.numpy("body_radius")[capsules]
        capsule_a = bodies.numpy("body_half_extents")[capsules][:, 2] - capsule_r
        capsule_u = quat_to_matrix(bodies.numpy("body_orientation")[capsules])[:, :, 2]
        hull_x, hull_r = x_all[hulls], bodies.numpy("body_bound_radius")[hulls]
        plane_n = quat_to_matrix(bodies.numpy("body_orientation")[planes])[:, :, 2]  # each plane's local +z, by row
        plane_x = x_all[planes]
        walls = []
        if meshes is not None and np.any((shape == ShapeType.MESH) & near):
            walls = self._mesh_walls(bodies, meshes, (shape == ShapeType.MESH) & near, half)
        accepted = []
        placed_x: list[np.ndarray] = []
        placed_r: list[float] = []
        for i in range(k):
            ri = cand["bound"][i] + CLEARANCE
            for attempt in range(TRIES):
                # a fresh spot in the region; a point region scatters its tries ever wider instead
                p = self._sample_positions(1)[0]
                if attempt and self.region == "point":
                    p = p + jitter * attempt * (2.0 * self.rng.random(3) - 1.0)
                # the candidate's bounding sphere must clear everything (exactly for spheres, boxes
                # and planes; bounding spheres among the candidates of this step)
                clear = not np.any(np.linalg.norm(sphere_x - p, axis=1) < sphere_r + ri)
                if clear and len(hull_x):
                    clear = not np.any(np.linalg.norm(hull_x - p, axis=1) < hull_r + ri)
                if clear and len(capsule_x):
                    t = np.clip(np.einsum("ij,ij->i", capsule_u, p - capsule_x), -capsule_a, capsule_a)
                    nearest = capsule_x + t[:, None] * capsule_u
                    clear = not np.any(np.linalg.norm(nearest - p, axis=1) < capsule_r + ri)
                if clear and len(box_x):
                    local = np.einsum("nji,nj->ni", box_rot, p - box_x)  # R^T (p - x)
                    outside = local - np.clip(local, -box_h, box_h)
                    clear = not np.any(np.linalg.norm(outside, axis=1) < ri)
                if clear and placed_x:
                    clear = not np.any(np.linalg.norm(np.asarray(placed_x) - p, axis=1) < np.asarray(placed_r) + ri)
                if clear and len(plane_n):
                    clear = not np.any(np.einsum("ij,ij->i", plane_n, p - plane_x) < ri)
                if clear and walls:
                    clear = _clear_of_meshes(p, ri, walls)
                if clear:
                    accepted.append(i)
                    placed_x.append(p)
                    placed_r.append(cand["bound"][i])
                    break
        if not accepted:
            self.blocked_for += dt
            return None  # no room this step: wait, and try again next step
        self.blocked_for = 0.0
        idx = np.asarray(accepted)
        shape = cand["shape"][idx]
        convex = shape == ShapeType.CONVEX
        geometry = np.zeros(len(idx), dtype=np.int32)  # a convex body's row in the world's hulls
        if convex.any():
            assert self.hull_rows is not None  # made with the convex shapes (add_hulls)
            geometry[convex] = self.hull_rows[cand["hull_level"][idx][convex]]
        self.emitted += len(idx)
        self._owed -= len(idx)
        return {
            "shape": shape,
            "position": np.asarray(placed_x),
            "orientation": cand["orientation"][idx],
            "radius": cand["radius"][idx],
            "half_extents": cand["half_extents"][idx],
            "mass": cand["mass"][idx],
            "inertia": cand["inertia"][idx],
            "restitution": self.restitution,
            "friction": self.friction,
            "velocity": cand["velocity"][idx],
            "angular_velocity": cand["angular_velocity"][idx],
            "bound": np.where(convex, cand["bound"][idx], np.inf),
            "geometry": geometry,
        }


def _clear_of_meshes(p: np.ndarray, r: float, walls: list[tuple]) -> bool:
    """Whether the sphere of radius r at p clears the triangles of every mesh in `walls`
    (`Emitter._mesh_walls`) and lies outside every closed one."""
    for rotation, position, a, b, c, solid in walls:
        q = rotation.T @ (p - position)  # p in the mesh's frame
        if len(a) and np.min(np.linalg.norm(closest_on_triangles(q, a, b, c) - q, axis=1)) < r:
            return False
        if solid is not None:
            sa, sb, sc, low, high = solid
            if np.all((q >= low) & (q <= high)) and abs(winding_number(q, sa, sb, sc)) > 0.5:
                return False
    return True


def _basis(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to unit `d` and to each other."""
    a = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(d, a)
    u /= np.linalg.norm(u)
    return u, np.cross(d, u)


def _emitted_hull(points, file):
    """The hull prototype (scale 1) of a convex emitter, from points or a mesh file's vertices."""
    from .collision.hulls import hull_from_points
    from .io.meshfile import hull_points

    if (points is None) == (file is None):
        raise ValueError("a convex emitter needs points or file (one of them)")
    p, name = hull_points(points, file)
    return hull_from_points(p, name=name)
