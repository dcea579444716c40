"""The World: owns every array and runs the step pipeline.

Typical use::

    import tumble
    world = tumble.World(gravity=(0, 0, -9.81), dt=1 / 240)
    world.add_plane(normal=(0, 0, 1), offset=0.0)
    ball = world.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0, restitution=0.5)
    world.run(duration=2.0)
    print(world.body_position[ball.index])

Units are SI throughout: metres, kilograms, seconds, radians (degrees only where a scene file
says so). Orientations are unit quaternions stored as (x, y, z, w).
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Sequence

import numpy as np
import warp as wp

from . import shapes as _shapes
from .collision import broadphase, narrowphase
from .collision.hashgrid import spatial_order
from .collision.hulls import HullSet
from .collision.meshes import MeshSet
from .errors import SimulationError
from .launch import LaunchCache
from .runtime import init_warp
from .shapes import ShapeType
from .solver import contacts as contact_solver
from .solver import integrate
from .solver import joints as joint_solver
from .state import ArraySet, BodyId, float_t, quat, readonly, vec3

#: worlds with fewer bodies keep their rows in id order (their state fits in cache anyway)
SORT_MIN_BODIES = 8192
#: steps between two renumberings of the body rows along a space-filling curve
SORT_INTERVAL = 60

#: per-body arrays, static description first, then per-step state
BODY_FIELDS = {
    # model
    "body_id": wp.int32,  # the BodyId given at creation; rows are reordered in space (see _sort_bodies)
    "body_shape": wp.int32,  # ShapeType
    "body_radius": float_t,  # sphere and capsule radius [m] (0 for other shapes)
    "body_half_extents": vec3,  # box half extents [m]; for capsules, of the bounding box (r, r, a + r)
    "body_bound_radius": float_t,  # radius of a bounding sphere [m] (inf for planes)
    "body_geometry": wp.int32,  # row of a convex body's hull in world.hulls, of a mesh in world.meshes (else 0)
    "body_mass": float_t,  # [kg] (0 for static bodies)
    "body_inv_mass": float_t,  # [1/kg] (0 for static bodies)
    "body_inv_inertia": vec3,  # principal inverse moments in the body frame [1/(kg m^2)]
    "body_restitution": float_t,
    "body_friction": float_t,
    # state
    "body_position": vec3,  # centre of mass [m]
    "body_orientation": quat,  # body-to-world rotation (x, y, z, w)
    "body_velocity": vec3,  # [m/s]
    "body_angular_velocity": vec3,  # world frame [rad/s]
    "body_force": vec3,  # user force for the next step [N]
    "body_torque": vec3,  # user torque for the next step [N m]
    # motion since the start of the step, for the solver's separation update
    "body_delta_position": vec3,  # [m]
    "body_delta_rotation": vec3,  # rotation vector [rad]
    # warm start of the next substep, summed per body by the relax pass
    "body_warm_velocity": vec3,  # [m/s]
    "body_warm_angular_velocity": vec3,  # [rad/s]
}


def _vec(value, name: str, n: int = 3) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64).reshape(-1)
    if a.shape != (n,):
        raise ValueError(f"{name} must have {n} components, got {value!r}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return a


def _rows(value, name: str, width: int, n: int | None = None) -> np.ndarray:
    """`value` as n rows of `width` floats: one row is repeated; n rows are taken as they are."""
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 1 and a.shape[0] == width and n is not None:
        a = np.broadcast_to(a, (n, width))
    if a.ndim != 2 or a.shape[1] != width or (n is not None and a.shape[0] != n):
        rows = "n" if n is None else str(n)
        raise ValueError(f"{name} must have {width} components (or shape ({rows}, {width})), got {value!r}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return np.array(a)


def _positive_rows(value, name: str, n: int) -> np.ndarray:
    """`value` (one number, or n of them) as n positive finite floats."""
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,) or not np.all(np.isfinite(a)) or np.any(a <= 0.0):
        raise ValueError(f"{name} must be a positive number (or {n} of them), got {value!r}")
    return a


def _positive(value, name: str) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return v


def _unit_interval(value, name: str) -> float:
    v = float(value)
    if not math.isfinite(v) or v < 0.0:
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    if name == "restitution" and v > 1.0:
        raise ValueError(f"restitution must be in [0, 1], got {value!r}")
    return v


def _unit_quat(value, name: str = "orientation") -> np.ndarray:
    q = _vec(value, name, 4)
    norm = np.linalg.norm(q)
    if norm < 1e-12:
        raise ValueError(f"{name} must be a non-zero quaternion (x, y, z, w), got {value!r}")
    return q / norm


def _quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p q of quaternions (x, y, z, w): rotate by q, then by p."""
    pv, pw, qv, qw = p[:3], p[3], q[:3], q[3]
    return np.r_[pw * qv + qw * pv + np.cross(pv, qv), pw * qw - pv @ qv]


def _quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """v rotated by the unit quaternion q (x, y, z, w): v + 2 u x (u x v + w v)."""
    u = q[:3]
    return v + 2.0 * np.cross(u, np.cross(u, v) + q[3] * v)


def _quat_from_z(normal: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w) rotating +z onto `normal` (unit)."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(np.dot(z, normal))
    if c < -1.0 + 1e-12:
        return np.array([1.0, 0.0, 0.0, 0.0])
    axis = np.cross(z, normal)
    q = np.array([axis[0], axis[1], axis[2], 1.0 + c])
    return q / np.linalg.norm(q)


class World:
    """A simulated world of planes, spheres, boxes, emitters and cloth.

    Args:
        gravity: gravitational acceleration [m/s^2], shape (3,).
        dt: fixed time step [s] used by `step()` and `run()`.
        substeps: solver substeps per step (more = stiffer stacks, less penetration).
        seed: seed of the world's random generator (emitters, turbulence).
        device: Warp device, "cpu" (default) or "cuda".
        restitution_threshold: impact speed [m/s] below which contacts that carry load do not
            bounce, so that resting bodies stay at rest (a contact carrying none bounces down to
            2 |g| h, h = dt / substeps).
    """

    def __init__(
        self,
        *,
        gravity: Sequence[float] = (0.0, 0.0, -9.81),
        dt: float = 1.0 / 240.0,
        substeps: int = 8,
        seed: int = 0,
        device: str = "cpu",
        restitution_threshold: float = 0.5,
    ):
        init_warp()
        if str(device).startswith("cuda") and not wp.is_cuda_available():
            raise ValueError(f"device {device!r}: Warp finds no CUDA device on this machine; use device='cpu'")
        try:
            self.device = str(wp.get_device(device))
        except (RuntimeError, ValueError) as exc:
            raise ValueError(f"device {device!r}: {exc}") from None
        self.gravity = _vec(gravity, "gravity")
        self.dt = _positive(dt, "dt")
        self.substeps = int(substeps)
        if self.substeps < 1:
            raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
        self.seed = int(seed)
        self.restitution_threshold = float(restitution_threshold)
        self.rng = np.random.default_rng(self.seed)
        self.time = 0.0
        self.step_count = 0
        self.profile: dict[str, float] = {}
        self.metadata: dict = {}

        self.bodies = ArraySet(BODY_FIELDS, device=self.device)
        self.emitters: list = []
        self.broadphase = broadphase.BroadPhase(self.device)
        self.contacts = contact_solver.ContactSet(self.device)
        self.joints = joint_solver.JointSet(self.device)
        self.hulls = HullSet(self.device)  # convex prototypes, row 0 the unit box
        self.meshes = MeshSet(self.device)  # static triangle meshes and their BVHs
        self._cloth = None  # created on the first add_cloth
        self._launches = LaunchCache()
        self._launch_sizes = None
        self._slot_of_id: np.ndarray | None = None  # row of each body id; None while rows are in id order
        self._sorted_at = -SORT_INTERVAL

    # ------------------------------------------------------------------ bodies

    def add_plane(
        self,
        *,
        normal: Sequence[float] = (0.0, 0.0, 1.0),
        offset: float = 0.0,
        restitution: float = 0.5,
        friction: float = 0.5,
    ) -> BodyId:
        """Add a static infinite plane {x : dot(normal, x) = offset}; bodies stay on the +normal side.

        Args:
            normal: plane normal, shape (3,); need not be unit length but must not be zero.
            offset: signed distance of the plane from the origin along the normal [m].
            restitution: coefficient of restitution in [0, 1].
            friction: Coulomb friction coefficient (>= 0).
        """
        n = _vec(normal, "normal")
        length = np.linalg.norm(n)
        if length < 1e-12:
            raise ValueError(f"normal must not be zero, got {normal!r}")
        n = n / length
        offset = float(offset)
        if not math.isfinite(offset):
            raise ValueError(f"offset must be finite, got {offset!r}")
        return self._add_bodies(
            shape=ShapeType.PLANE,
            position=(n * offset)[None],
            orientation=_quat_from_z(n)[None],
            radius=np.zeros(1),
            half_extents=np.zeros((1, 3)),
            mass=np.zeros(1),
            inertia=np.zeros((1, 3)),
            restitution=_unit_interval(restitution, "restitution"),
            friction=_unit_interval(friction, "friction"),
        )[0]

    def add_sphere(
        self,
        *,
        position: Sequence[float],
        radius: float,
        mass: float | None = None,
        density: float | None = None,
        velocity: Sequence[float] = (0.0, 0.0, 0.0),
        orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
        angular_velocity: Sequence[float] = (0.0, 0.0, 0.0),
        restitution: float = 0.5,
        friction: float = 0.5,
        static: bool = False,
    ) -> BodyId:
        """Add a solid sphere.

        Args:
            position: centre [m], shape (3,).
            radius: [m], > 0.
            mass: [kg], > 0. Give `mass` or `density`; with neither, density is 1000 kg/m^3.
            density: [kg/m^3], > 0.
            velocity: initial linear velocity [m/s].
            orientation: initial orientation (x, y, z, w).
            angular_velocity: initial angular velocity, world frame [rad/s].
            restitution: coefficient of restitution in [0, 1].
            friction: Coulomb friction coefficient (>= 0).
            static: if True the sphere never moves (inverse mass 0).
        """
        return self.add_spheres(
            position=_vec(position, "position")[None], radius=radius, mass=mass, density=density, velocity=velocity,
            orientation=orientation, angular_velocity=angular_velocity, restitution=restitution, friction=friction,
            static=static,
        )[0]

    def add_box(
        self,
        *,
        position: Sequence[float],
        half_extents: Sequence[float],
        mass: float | None = None,
        density: float | None = None,
        velocity: Sequence[float] = (0.0, 0.0, 0.0),
        orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
        angular_velocity: Sequence[float] = (0.0, 0.0, 0.0),
        restitution: float = 0.5,
        friction: float = 0.5,
        static: bool = False,
    ) -> BodyId:
        """Add a solid box. Arguments as `add_sphere`, with half extents [m], shape (3,), all > 0."""
        return self.add_boxes(
            position=_vec(position, "position")[None], half_extents=_vec(half_extents, "half_extents"), mass=mass,
            density=density, velocity=velocity, orientation=orientation, angular_velocity=angular_velocity,
            restitution=restitution, friction=friction, static=static,
        )[0]

    def add_spheres(self, *, position, radius, mass=None, density=None, velocity=(0.0, 0.0, 0.0),
                    orientation=(0.0, 0.0, 0.0, 1.0), angular_velocity=(0.0, 0.0, 0.0), restitution: float = 0.5,
                    friction: float = 0.5, static: bool = False) -> list[BodyId]:
        """Add n spheres in one call, much faster than n calls of `add_sphere`.

        Args:
            position: centres [m], shape (n, 3).
            radius, mass, density: one value for all, or shape (n,); see `add_sphere`.
            velocity, angular_velocity: shape (3,) for all, or (n, 3).
            orientation: shape (4,) for all, or (n, 4), (x, y, z, w).
            restitution, friction, static: one value for all.

        Returns:
            The new bodies' ids, in order.
        """
        x = _rows(position, "position", 3)
        r = _positive_rows(radius, "radius", len(x))
        m = self._masses(mass, density, _shapes.sphere_volume(r))
        inertia = _shapes.sphere_inertia(m, r)
        return self._add_solids(ShapeType.SPHERE, x, velocity, orientation, angular_velocity, radius=r,
                                half_extents=np.zeros((len(x), 3)), mass=m, inertia=inertia,
                                restitution=restitution, friction=friction, static=static)

    def add_boxes(self, *, position, half_extents, mass=None, density=None, velocity=(0.0, 0.0, 0.0),
                  orientation=(0.0, 0.0, 0.0, 1.0), angular_velocity=(0.0, 0.0, 0.0), restitution: float = 0.5,
                  friction: float = 0.5, static: bool = False) -> list[BodyId]:
        """Add n boxes in one call; arguments as `add_spheres`, with half extents [m], shape (3,) or (n, 3)."""
        x = _rows(position, "position", 3)
        h = _rows(half_extents, "half_extents", 3, len(x))
        if np.any(h <= 0.0):
            raise ValueError(f"half_extents must all be > 0, got {half_extents!r}")
        m = self._masses(mass, density, _shapes.box_volume(h))
        inertia = _shapes.box_inertia(m, h)
        return self._add_solids(ShapeType.BOX, x, velocity, orientation, angular_velocity, radius=np.zeros(len(x)),
                                half_extents=h, mass=m, inertia=inertia, restitution=restitution,
                                friction=friction, static=static)

    def add_capsule(
        self,
        *,
        position: Sequence[float],
        radius: float,
        half_height: float,
        mass: float | None = None,
        density: float | None = None,
        velocity: Sequence[float] = (0.0, 0.0, 0.0),
        orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
        angular_velocity: Sequence[float] = (0.0, 0.0, 0.0),
        restitution: float = 0.5,
        friction: float = 0.5,
        static: bool = False,
    ) -> BodyId:
        """Add a solid capsule: the points within `radius` of a segment along the body's z axis.

        Args:
            radius: [m], > 0.
            half_height: half the length of the segment [m], > 0 (the capsule is
                2 (half_height + radius) long).
            Others as `add_sphere`.
        """
        return self.add_capsules(
            position=_vec(position, "position")[None], radius=radius, half_height=half_height, mass=mass,
            density=density, velocity=velocity, orientation=orientation, angular_velocity=angular_velocity,
            restitution=restitution, friction=friction, static=static,
        )[0]

    def add_capsules(self, *, position, radius, half_height, mass=None, density=None, velocity=(0.0, 0.0, 0.0),
                     orientation=(0.0, 0.0, 0.0, 1.0), angular_velocity=(0.0, 0.0, 0.0), restitution: float = 0.5,
                     friction: float = 0.5, static: bool = False) -> list[BodyId]:
        """Add n capsules in one call; arguments as `add_spheres`, with `half_height` one value or shape (n,)."""
        x = _rows(position, "position", 3)
        r = _positive_rows(radius, "radius", len(x))
        a = _positive_rows(half_height, "half_height", len(x))
        m = self._masses(mass, density, _shapes.capsule_volume(r, a))
        inertia = _shapes.capsule_inertia(m, r, a)
        # half extents of the body-frame bounding box; the kernels read the half height as h_z - r
        h = np.stack([r, r, a + r], axis=1)
        return self._add_solids(ShapeType.CAPSULE, x, velocity, orientation, angular_velocity, radius=r,
                                half_extents=h, mass=m, inertia=inertia, restitution=restitution,
                                friction=friction, static=static)

    def add_convex(
        self,
        *,
        points=None,
        file=None,
        scale: float | Sequence[float] = 1.0,
        position: Sequence[float] = (0.0, 0.0, 0.0),
        orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
        mass: float | None = None,
        density: float | None = None,
        velocity: Sequence[float] = (0.0, 0.0, 0.0),
        angular_velocity: Sequence[float] = (0.0, 0.0, 0.0),
        restitution: float = 0.5,
        friction: float = 0.5,
        static: bool = False,
    ) -> BodyId:
        """Add a solid convex body: the convex hull of `points`, or of the vertices of a mesh `file`.

        The points are given in a frame of the user's ("user frame"), placed at `position` with
        `orientation`. The body's own frame has its origin at the hull's centre of mass and its
        axes along the principal axes of inertia, so `body_position` is the centre of mass;
        `world.hulls.prototypes[world.body_geometry[i]]` keeps the user frame (`offset_com`,
        `rotation`). Mass properties come from the hull's exact polyhedron integrals.

        Args:
            points: shape (n, 3) [m], n >= 4, spanning a volume.
            file: a mesh file (OBJ, STL, PLY, OFF, glTF/GLB) read with trimesh; a mesh that is
                not watertight still gives its hull, with a one-line notice.
            scale: one factor or three (per user axis) applied to the points first.
            position, orientation: the user frame's pose (x, y, z, w).
            Others as `add_sphere`.
        """
        from .collision.hulls import hull_from_points
        from .io.meshfile import notice, read_mesh_file

        if (points is None) == (file is None):
            raise ValueError("add_convex takes points or file, not both")
        name = "points"
        if file is not None:
            points, _triangles, mesh = read_mesh_file(file)
            name = str(file)
            if not getattr(mesh, "is_watertight", False):
                notice(f"{file}: the mesh is not watertight; its convex hull is used")
        factor = np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,))
        if not np.all(np.isfinite(factor)) or np.any(factor <= 0.0):
            raise ValueError(f"scale must be one positive number or three, got {scale!r}")
        proto = hull_from_points(np.asarray(points, dtype=np.float64) * factor, name=name)
        q_user = _unit_quat(orientation)
        x = _vec(position, "position") + _quat_rotate(q_user, proto.offset_com)
        q = _quat_mul(q_user, proto.rotation)
        m = self._masses(mass, density, np.array([proto.volume]))
        inertia = proto.inertia[None] * (m[0] / proto.volume)
        index = self.hulls.add(proto)
        ids = self._add_solids(ShapeType.CONVEX, x[None], velocity, q, angular_velocity, radius=np.zeros(1),
                               half_extents=np.abs(proto.vertex).max(axis=0)[None], mass=m, inertia=inertia,
                               restitution=restitution, friction=friction, static=static,
                               bound=np.array([proto.bound_radius]))
        self.bodies.write("body_geometry", self._slot(ids[0]), index)
        return ids[0]

    def add_mesh(
        self,
        *,
        file=None,
        vertices=None,
        triangles=None,
        scale: float | Sequence[float] = 1.0,
        position: Sequence[float] = (0.0, 0.0, 0.0),
        orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
        restitution: float = 0.5,
        friction: float = 0.5,
    ) -> BodyId:
        """Add a static triangle mesh, from a file (OBJ, STL, PLY, OFF, glTF/GLB through trimesh) or arrays.

        Spheres, capsules, boxes and convex bodies collide with it through its BVH (`wp.Mesh`).
        Faces are one-sided: wound counter-clockwise seen from where bodies stay (outward on a
        closed mesh). NaN vertices, bad indices and zero-area triangles are dropped with a
        one-line notice each.

        Args:
            file: the mesh file; or give `vertices` (n, 3) [m] and `triangles` (m, 3) int.
            scale: one factor or three, applied in the mesh's frame.
            position, orientation: the mesh frame's pose (x, y, z, w).
            restitution, friction: as `add_plane`.
        """
        from .io.meshfile import load_mesh

        v, t, _watertight = load_mesh(file=file, vertices=vertices, triangles=triangles)
        factor = np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,))
        if not np.all(np.isfinite(factor)) or np.any(factor <= 0.0):
            raise ValueError(f"scale must be one positive number or three, got {scale!r}")
        v = v * factor
        index = self.meshes.add(v, t)
        ids = self._add_bodies(
            shape=ShapeType.MESH, position=_vec(position, "position")[None],
            orientation=_unit_quat(orientation)[None], radius=np.zeros(1),
            half_extents=np.abs(v).max(axis=0)[None], mass=np.zeros(1), inertia=np.zeros((1, 3)),
            restitution=_unit_interval(restitution, "restitution"), friction=_unit_interval(friction, "friction"),
            bound=np.array([float(np.linalg.norm(v, axis=1).max())]),
        )
        self.bodies.write("body_geometry", self._slot(ids[0]), index)
        return ids[0]

    def add_body(self, shape: str | ShapeType, **kwargs) -> BodyId:
        """Factory: add a body by shape name ("plane", "sphere" or "box") with that shape's keywords."""
        kind = shape if isinstance(shape, ShapeType) else _shapes.shape_from_name(shape)
        return {ShapeType.PLANE: self.add_plane, ShapeType.SPHERE: self.add_sphere, ShapeType.BOX: self.add_box,
                ShapeType.CAPSULE: self.add_capsule, ShapeType.CONVEX: self.add_convex,
                ShapeType.MESH: self.add_mesh}[kind](**kwargs)

    def add_emitter(self, **kwargs):
        """Add an emitter that releases bodies over time; see `tumble.emitters.Emitter` for keywords.

        Returns:
            The `Emitter`, whose `rate` may be changed while the world runs.
        """
        from .emitters import Emitter

        emitter = Emitter(**kwargs)
        if emitter.seed is None:
            emitter.seed = int(self.rng.integers(0, 2**31 - 1))
        emitter.reset_rng()
        self.emitters.append(emitter)
        return emitter

    def add_cloth(self, **kwargs):
        """Add a rectangular mass-spring cloth; see `tumble.cloth.ClothSystem.add_cloth` for keywords."""
        return self.cloth.add_cloth(**kwargs)

    @property
    def cloth(self):
        """The world's `ClothSystem` (created on first use)."""
        if self._cloth is None:
            from .cloth import ClothSystem

            self._cloth = ClothSystem(self)
        return self._cloth

    def set_wind(self, **kwargs) -> None:
        """Set the wind acting on cloth; see `tumble.cloth.Wind` for keywords."""
        self.cloth.set_wind(**kwargs)

    def set_material(self, *, restitution: float | None = None, friction: float | None = None) -> None:
        """Set restitution and/or friction of every body (planes included), effective at once."""
        n = self.bodies.count
        if restitution is not None:
            self.bodies.write("body_restitution", slice(0, n), _unit_interval(restitution, "restitution"))
        if friction is not None:
            self.bodies.write("body_friction", slice(0, n), _unit_interval(friction, "friction"))

    def add_joint(self, kind: str, body_a, body_b, **kwargs):
        """Join two bodies (either may be None: the world, a fixed frame); see `tumble.solver.joints`.

        Args:
            kind: "ball", "hinge", "slider", "fixed", "distance" or "rope".
            body_a, body_b: BodyId (or index) of the two bodies, or None for the world.
            anchor: shared anchor, world point at creation [m]; or anchor_a / anchor_b, one per body
                (world points, or body-frame points with frame="body"). Default: a's centre (distance
                and rope: each body's centre).
            axis: hinge / slider axis, world (or a's frame with frame="body"); default (0, 0, 1).
            lower, upper: hinge angle limits [rad] or slider translation limits [m] (from creation).
            motor_speed: hinge [rad/s] / slider [m/s] target speed of b relative to a, with max_torque [N m]
                (hinge) or max_force [N] (slider).
            length, min_length, max_length: distance joint rest length (default: the current distance)
                and bounds (default: rigid rod; rope: 0 to length; spring: unbounded).
            stiffness, damping: distance spring [N/m], [N s/m].
            break_force: the joint breaks when its force exceeds this [N] (default never).
            collide: whether the two bodies still collide (default False).

        Returns:
            The new joint's `JointId`; `joint_force[id.index]` is its force on b [N].
        """
        ends = [joint_solver.JointBody.world() if body is None else self._joint_body(body, key)
                for key, body in (("body_a", body_a), ("body_b", body_b))]
        rows = joint_solver.joint_rows(kind, *ends, **kwargs)
        return joint_solver.JointId(self.joints.add(rows)[0])

    def _joint_body(self, body, key: str):
        try:
            i = self._slot(body)
        except (IndexError, TypeError, ValueError):
            raise joint_solver.JointArgumentError(
                key, f"no body {body!r} (the world has {self.bodies.count} bodies)") from None
        b = self.bodies
        return joint_solver.JointBody(i, b.numpy("body_position")[i].copy(), b.numpy("body_orientation")[i].copy(),
                                      bool(b.numpy("body_inv_mass")[i] > 0.0))

    def apply_force(self, body, force: Sequence[float], *, point: Sequence[float] | None = None) -> None:
        """Apply a force [N] (at a world `point`, default the centre of mass) during the next step only."""
        i = self._slot(body)
        f = _vec(force, "force")
        self.bodies.write("body_force", i, self.bodies.numpy("body_force")[i] + f)
        if point is not None:
            r = _vec(point, "point") - self.bodies.numpy("body_position")[i]
            self.bodies.write("body_torque", i, self.bodies.numpy("body_torque")[i] + np.cross(r, f))

    def _masses(self, mass, density, volume: np.ndarray) -> np.ndarray:
        if mass is not None and density is not None:
            raise ValueError("give mass or density, not both")
        if mass is not None:
            return _positive_rows(mass, "mass", len(volume))
        return _positive_rows(1000.0 if density is None else density, "density", len(volume)) * volume

    def _add_solids(self, shape, position, velocity, orientation, angular_velocity, *, radius, half_extents,
                    mass, inertia, restitution, friction, static, bound=None) -> list[BodyId]:
        n = len(position)
        q = _rows(orientation, "orientation", 4, n)
        norm = np.linalg.norm(q, axis=1, keepdims=True)
        if np.any(norm < 1e-12):
            raise ValueError(f"orientation must be a non-zero quaternion (x, y, z, w), got {orientation!r}")
        v = _rows(velocity, "velocity", 3, n)
        w = _rows(angular_velocity, "angular_velocity", 3, n)
        if static:
            mass, inertia, v, w = np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
        return self._add_bodies(
            shape=shape, position=position, velocity=v, orientation=q / norm, angular_velocity=w, radius=radius,
            half_extents=half_extents, mass=mass, inertia=inertia,
            restitution=_unit_interval(restitution, "restitution"), friction=_unit_interval(friction, "friction"),
            bound=bound,
        )

    def _add_bodies(self, *, shape, position, orientation, radius, half_extents, mass, inertia,
                    restitution, friction, velocity=None, angular_velocity=None, bound=None) -> list[BodyId]:
        """Append k bodies given as arrays with k rows (vectorised; used by emitters too)."""
        k = len(position)
        shape = np.broadcast_to(np.asarray(shape, dtype=np.int32), (k,))
        given = bound
        bound = np.where(
            shape == ShapeType.SPHERE,
            radius,
            np.where(shape == ShapeType.BOX, np.linalg.norm(half_extents, axis=1), np.inf),
        )
        bound = np.where(shape == ShapeType.CAPSULE, half_extents[:, 2], bound)  # half height + radius
        if given is not None:  # convex bodies: the hull's bounding sphere
            bound = np.where(np.isfinite(given), given, bound)
        with np.errstate(divide="ignore"):
            inv_mass = np.where(mass > 0.0, 1.0 / np.where(mass > 0.0, mass, 1.0), 0.0)
            inv_inertia = np.where(inertia > 0.0, 1.0 / np.where(inertia > 0.0, inertia, 1.0), 0.0)
        first = self.bodies.count  # ids are creation order, and bodies are never removed
        rows = self.bodies.append(
            {
                "body_id": np.arange(first, first + k, dtype=np.int32),
                "body_shape": shape,
                "body_radius": radius,
                "body_half_extents": half_extents,
                "body_bound_radius": bound,
                "body_mass": mass,
                "body_inv_mass": inv_mass,
                "body_inv_inertia": inv_inertia,
                "body_restitution": np.broadcast_to(restitution, (k,)),
                "body_friction": np.broadcast_to(friction, (k,)),
                "body_position": position,
                "body_orientation": orientation,
                "body_velocity": np.zeros((k, 3)) if velocity is None else velocity,
                "body_angular_velocity": np.zeros((k, 3)) if angular_velocity is None else angular_velocity,
            }
        )
        if self._slot_of_id is not None:
            self._slot_of_id = np.concatenate([self._slot_of_id, np.arange(first, first + k)])
        return [BodyId(i) for i in rows]

    def _slot(self, body) -> int:
        """Row of the body with id `body` in the body arrays."""
        i = int(body)
        if not 0 <= i < self.bodies.count:
            raise IndexError(f"body {i} does not exist (the world has {self.bodies.count} bodies)")
        return i if self._slot_of_id is None else int(self._slot_of_id[i])

    def _sort_bodies(self) -> None:
        """Renumber the body rows along a space-filling curve (ids stay the same).

        Contacts come out of the broad phase in row order, so when neighbours in space are
        neighbours in memory the solver reads body state from cache rather than from all over
        the arrays: 2x fewer solver cycles for 20,000 bodies added in random order. Worlds
        under `SORT_MIN_BODIES` fit in cache anyway and are never reordered.
        """
        n = self.bodies.count
        if n < SORT_MIN_BODIES or self.step_count - self._sorted_at < SORT_INTERVAL:
            return
        self._sorted_at = self.step_count
        bound = self.bodies.numpy("body_bound_radius")
        finite = bound[np.isfinite(bound) & (bound > 0.0)]
        cell = 2.0 * float(np.median(finite)) if len(finite) else 1.0  # a typical body's diameter
        order = spatial_order(self.bodies.numpy("body_position"), cell)
        if np.array_equal(order, np.arange(n)):
            return
        self.bodies.permute(order)
        slot = np.empty(n, dtype=np.int64)
        slot[order] = np.arange(n)
        self.contacts.remap_bodies(slot)
        if self._cloth is not None:
            self._cloth.remap_bodies(slot)
        self.joints.remap_bodies(slot)
        self._slot_of_id = np.empty(n, dtype=np.int64)
        self._slot_of_id[self.bodies.numpy("body_id")] = np.arange(n)

    # ------------------------------------------------------------------ stepping

    def step(self, dt: float | None = None) -> None:
        """Advance the world by one step of `dt` seconds (default `self.dt`)."""
        dt = self.dt if dt is None else _positive(dt, "dt")
        h = dt / self.substeps
        bodies, contacts = self.bodies, self.contacts
        cloth = self._cloth

        # validate: finite state, so a NaN is reported where it appeared rather than spreading
        with self._timer("validate"):
            self._validate()

        # emit: emitters release bodies where they overlap nothing
        with self._timer("emit"):
            for emitter in self.emitters:
                emitter.emit(self, dt)

        # layout: now and then, renumber body rows so that neighbours in space share cache lines
        with self._timer("layout"):
            self._sort_bodies()

        # broad phase: spatial hash -> candidate pairs of bodies whose swept bounds overlap
        with self._timer("broad_phase"):
            pairs = self.broadphase.find_pairs(bodies, dt)
            pairs = self.joints.filter_pairs(pairs, bodies)  # jointed pairs collide only if asked

        # narrow phase: pair table -> contact points with normal, separation and anchors
        with self._timer("narrow_phase"):
            narrowphase.collide(bodies, pairs, contacts, dt, self.hulls, self.meshes)

        # contact prepare: match last step's contacts for warm starting, effective masses
        with self._timer("solver"):
            contacts.match_previous(bodies)
            contact_solver.prepare(bodies, contacts, self.gravity)
            integrate.begin_step(bodies)

        # substeps: integrate velocities (+ warm start) -> impacts (restitution) -> solve -> integrate positions
        # -> relax -> cloth
        launches = self._launch_cache()
        for substep in range(self.substeps):
            with self._timer("integrate"):
                integrate.integrate_velocities(bodies, self.gravity, h, warm=substep > 0, cache=launches)
            with self._timer("solver"):
                if substep == 0:
                    contact_solver.warm_start(bodies, contacts)
                    self.joints.warm_start(bodies, h, cache=launches)
                    contact_solver.impacts(bodies, contacts, self.gravity, h, self.restitution_threshold, ahead=False,
                                           cache=launches)
                self.joints.solve(bodies, h, use_bias=True, cache=launches)
                contact_solver.solve(bodies, contacts, h, use_bias=True, cache=launches)
            with self._timer("integrate"):
                integrate.integrate_positions(bodies, h, cache=launches)
            with self._timer("solver"):
                self.joints.solve(bodies, h, use_bias=False, cache=launches)
                contact_solver.impacts(bodies, contacts, self.gravity, h, self.restitution_threshold, ahead=True,
                                       cache=launches)
                contact_solver.solve(bodies, contacts, h, use_bias=False, cache=launches)
            if cloth is not None:
                with self._timer("cloth"):
                    cloth.substep(h)

        # keep this step's impulses for the next step's warm start
        with self._timer("solver"):
            contacts.store_impulses(bodies)
            self.joints.finish(dt, cache=launches)  # joint forces; joints over their break force break
            integrate.clear_forces(bodies)

        self.time += dt
        self.step_count += 1

    def collide(self, dt: float | None = None) -> int:
        """Find contacts for the current state without stepping (broad + narrow phase only).

        Contacts within the speculative distance of one step of `dt` are included, as in `step`.

        Returns:
            The number of contacts; read them with `contact_point`, `contact_normal`, ...
        """
        dt = self.dt if dt is None else _positive(dt, "dt")
        pairs = self.broadphase.find_pairs(self.bodies, dt)
        narrowphase.collide(self.bodies, pairs, self.contacts, dt, self.hulls, self.meshes)
        return self.contacts.count

    def _launch_cache(self) -> LaunchCache:
        """Recorded launches of the substep kernels, forgotten when an array set is reallocated."""
        sizes = (self.bodies.capacity, self.contacts.capacity)
        if sizes != self._launch_sizes:
            self._launches.clear()
            self._launch_sizes = sizes
        return self._launches

    def run(self, duration: float, *, callback: Callable[[World], None] | None = None) -> int:
        """Step for `duration` seconds of simulated time; call `callback(world)` after each step.

        Returns:
            The number of steps taken.
        """
        steps = int(round(_positive(duration, "duration") / self.dt))
        for _ in range(steps):
            self.step()
            if callback is not None:
                callback(self)
        return steps

    @contextlib.contextmanager
    def _timer(self, stage: str):
        start = time.perf_counter()
        yield
        if self.device != "cpu":
            wp.synchronize_device(self.device)
        self.profile[stage] = self.profile.get(stage, 0.0) + time.perf_counter() - start

    def _validate(self) -> None:
        n = self.bodies.count
        if n == 0:
            return
        for name in ("body_position", "body_velocity", "body_angular_velocity"):
            values = self.bodies.numpy(name)
            if not np.isfinite(values).all():
                bad = int(self.bodies.numpy("body_id")[np.nonzero(~np.isfinite(values).all(axis=1))[0][0]])
                raise SimulationError(
                    f"{name} of body {bad} is not finite at t = {self.time:.6g} s "
                    f"(step {self.step_count}); the simulation diverged or was given NaN"
                )

    # ------------------------------------------------------------------ read-only views

    def _view(self, name: str) -> np.ndarray:
        """Rows in id order (a copy once the rows have been reordered), read-only."""
        values = self.bodies.numpy(name)
        return readonly(values if self._slot_of_id is None else values[self._slot_of_id])

    @property
    def body_count(self) -> int:
        """Number of bodies, planes included."""
        return self.bodies.count

    @property
    def contact_count(self) -> int:
        """Number of contact points found by the last step (speculative ones included)."""
        return self.contacts.count

    body_shape = property(lambda self: self._view("body_shape"), doc="Shape types (ShapeType), shape (n,), int32.")
    body_radius = property(lambda self: self._view("body_radius"), doc="Sphere and capsule radii [m], shape (n,).")
    body_geometry = property(lambda self: self._view("body_geometry"),
                             doc="Row of each convex body's hull in `hulls.prototypes`, shape (n,), int32.")
    body_half_extents = property(lambda self: self._view("body_half_extents"), doc="Box half extents [m], shape (n, 3).")
    body_mass = property(lambda self: self._view("body_mass"), doc="Masses [kg], shape (n,); 0 for static bodies.")
    body_inv_mass = property(lambda self: self._view("body_inv_mass"), doc="Inverse masses [1/kg], shape (n,).")
    body_restitution = property(lambda self: self._view("body_restitution"), doc="Restitution, shape (n,).")
    body_friction = property(lambda self: self._view("body_friction"), doc="Friction coefficients, shape (n,).")
    body_position = property(lambda self: self._view("body_position"), doc="Positions [m], shape (n, 3).")
    body_orientation = property(lambda self: self._view("body_orientation"), doc="Orientations (x, y, z, w), shape (n, 4).")
    body_velocity = property(lambda self: self._view("body_velocity"), doc="Linear velocities [m/s], shape (n, 3).")
    body_angular_velocity = property(
        lambda self: self._view("body_angular_velocity"), doc="Angular velocities, world frame [rad/s], shape (n, 3)."
    )

    joint_count = property(lambda self: self.joints.count, doc="Number of joints, broken ones included.")
    joint_force = property(lambda self: self.joints.view("joint_force"),
                           doc="Force of each joint on its body b over the last substep, world [N], shape (j, 3).")
    joint_torque = property(lambda self: self.joints.view("joint_torque"),
                            doc="Torque of each joint on its body b, world [N m], shape (j, 3).")
    joint_error = property(lambda self: readonly(joint_solver.joint_error(self.joints, self.bodies)),
                           doc="Position error (drift) of each joint [m], shape (j,).")
    joint_broken = property(lambda self: readonly(self.joints.numpy("joint_enabled") == 0),
                            doc="Whether each joint has broken, shape (j,), bool.")

    @property
    def body_plane_normal(self) -> np.ndarray:
        """Unit normals of plane bodies (the body's local +z in world), shape (n, 3); zero for non-planes."""
        q = self.body_orientation
        x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
        normal = np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)
        return np.where((self.body_shape == ShapeType.PLANE)[:, None], normal, 0.0)

    @property
    def body_inertia_world(self) -> np.ndarray:
        """World-frame inertia tensors [kg m^2], shape (n, 3, 3) (zero for static bodies)."""
        inv_i = self._view("body_inv_inertia")
        with np.errstate(divide="ignore"):
            inertia = np.where(inv_i > 0.0, 1.0 / np.where(inv_i > 0.0, inv_i, 1.0), 0.0)
        rot = quat_to_matrix(self.body_orientation)
        return np.einsum("nij,nj,nkj->nik", rot, inertia, rot)

    @property
    def contact_point(self) -> np.ndarray:
        """Contact points (midway between the surfaces) [m], shape (k, 3)."""
        return readonly(self.contacts.numpy("contact_point"))

    @property
    def contact_normal(self) -> np.ndarray:
        """Contact normals, unit, pointing from body a to body b, shape (k, 3)."""
        return readonly(self.contacts.numpy("contact_normal"))

    @property
    def contact_depth(self) -> np.ndarray:
        """Penetration depths [m] at the start of the last step, shape (k,); negative = speculative gap."""
        return readonly(-self.contacts.numpy("contact_separation"))

    @property
    def contact_pair(self) -> np.ndarray:
        """Body indices (a, b) of each contact, shape (k, 2), int32."""
        c = self.contacts
        pair = np.stack([c.numpy("contact_body_a"), c.numpy("contact_body_b")], axis=1)
        return readonly(pair if self._slot_of_id is None else self.bodies.numpy("body_id")[pair])

    # ------------------------------------------------------------------ diagnostics

    def kinetic_energy(self) -> float:
        """Total kinetic energy of bodies (and cloth) [J]: sum 1/2 m v^2 + 1/2 w . I w."""
        m = self.bodies.numpy("body_mass")
        v = self.bodies.numpy("body_velocity")
        w = self.bodies.numpy("body_angular_velocity")
        energy = 0.5 * float(np.sum(m * np.einsum("ij,ij->i", v, v)))
        if len(m):
            energy += 0.5 * float(np.einsum("ni,nij,nj->", w, self.body_inertia_world, w))
        if self._cloth is not None:
            energy += self._cloth.kinetic_energy()
        return energy

    def potential_energy(self) -> float:
        """Gravitational potential energy of bodies (and cloth) relative to the origin [J]: -m g . x."""
        m = self.bodies.numpy("body_mass")
        energy = -float(np.sum(m * (self.bodies.numpy("body_position") @ self.gravity)))
        if self._cloth is not None:
            energy += self._cloth.potential_energy()
        return energy

    def momentum(self) -> np.ndarray:
        """Total linear momentum of bodies [kg m/s], shape (3,)."""
        return np.sum(self.bodies.numpy("body_mass")[:, None] * self.bodies.numpy("body_velocity"), axis=0)

    def state_hash(self) -> str:
        """SHA-256 of the state arrays, to check determinism bit for bit."""
        import hashlib

        digest = hashlib.sha256()
        for name in ("body_position", "body_orientation", "body_velocity", "body_angular_velocity"):
            digest.update(np.ascontiguousarray(self._view(name)).tobytes())
        if self._cloth is not None:
            digest.update(np.ascontiguousarray(self._cloth.particle_position_numpy()).tobytes())
        return digest.hexdigest()


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices of unit quaternions (x, y, z, w), shape (n, 4) -> (n, 3, 3)."""
    x, y, z, w = (q[:, i] for i in range(4))
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=1),
        ],
        axis=1,
    )
