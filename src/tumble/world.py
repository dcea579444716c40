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

import math
import os
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, Unpack, overload

import numpy as np
import warp as wp
from numpy.typing import ArrayLike

from . import limits, snapshot, validate
from . import precision as precisions
from . import shapes as _shapes
from .cloth.system import ClothSystem  # its add_cloth's and set_wind's keywords are World's (both precisions')
from .collision.hashgrid import spatial_order
from .emitters import Emitter
from .errors import HandleError, NoSuchIdError, SimulationError
from .keywords import given, keywords_of
from .launch import LaunchCache
from .model import BODY_FIELD, Control, Model, State, body_row_group
from .npmath import inertia_world, quat_from_z, quat_mul, quat_rotate, rotation_vector
from .precision import Precision
from .runtime import init_warp
from .shapes import DEFAULT_FRICTION, DEFAULT_RESTITUTION, SOLID_DEFAULTS, ShapeType, SolidOptions
from .snapshot import Snapshot
from .solver import joints as joint_solver
from .state import (
    BodyId,
    BodyKind,
    ClothId,
    Handle,
    JointId,
    cast,
    host_values,
    host_view,
    readonly,
    register_world,
)

if TYPE_CHECKING:  # the classes of the float64 copy; each world's come from `kernels(precision)`
    from .collision.broadphase import BroadPhase
    from .collision.hulls import HullSet
    from .collision.meshes import MeshSet
    from .solver.contacts import ContactSet
    from .solver.joints import JointSet

#: worlds with fewer bodies keep their rows in id order (their state fits in cache anyway)
SORT_MIN_BODIES = 8192
#: steps between two renumberings of the body rows along a space-filling curve
SORT_INTERVAL = 60
#: worlds of up to this many bodies check their state's finiteness with Python's `sum` over the
#: values (3 per body and vector: under a microsecond), larger ones with NumPy (~2.5 us a call, then fast)
VALIDATE_SUM_BODIES = 16
#: the body state the step checks is finite before it starts
_CHECKED_FINITE = ("body_position", "body_velocity", "body_angular_velocity")


class BodyState(NamedTuple):
    """One body's state (copies), from `World.body_state`."""

    position: np.ndarray  #: centre of mass [m], shape (3,)
    orientation: np.ndarray  #: (x, y, z, w), shape (4,)
    velocity: np.ndarray  #: [m/s], shape (3,)
    angular_velocity: np.ndarray  #: world frame [rad/s], shape (3,)
    kind: BodyKind


#: BodyState field -> body array
_STATE_NAMES = {
    "position": "body_position",
    "orientation": "body_orientation",
    "velocity": "body_velocity",
    "angular_velocity": "body_angular_velocity",
}


class BodyView(property):
    """A read-only view of one body array (`World.body_position`, ...), documented from its declaration
    in `tumble.model.BODY_FIELDS`: a copy of that moment's values, one row per body id."""

    def __init__(self, name: str) -> None:
        super().__init__(lambda world: world._view(name))
        self.name = name
        self.__doc__ = BODY_FIELD[name].describe()

    @overload
    def __get__(self, world: None, owner: type | None = None) -> BodyView: ...
    @overload
    def __get__(self, world: World, owner: type | None = None) -> np.ndarray: ...
    def __get__(self, world, owner=None):
        return super().__get__(world, owner)


class World:
    """A simulated world of planes, spheres, boxes, emitters and cloth.

    Args:
        gravity: gravitational acceleration [m/s^2], shape (3,).
        dt: fixed time step [s] used by `step()` and `run()`, in [1e-9, 0.1] (`tumble.limits.MIN_DT`, `MAX_DT`).
        substeps: solver substeps per step (more = stiffer stacks, less penetration), an integer in
            [1, 1000] (`tumble.limits.MAX_SUBSTEPS`); `run` refuses more than 10^9 steps. Contact
            stiffness is 1/8 of the substep rate, so a stack's sag goes as (dt / substeps)^2: for
            tall stacks keep dt / substeps at the default 1/1920 s (32 substeps at dt = 1/60 s;
            docs/performance.md, "Tall stacks").
        seed: seed of the world's random generator (emitters, turbulence), an integer >= 0.
        device: Warp device, "cpu" (default) or "cuda".
        restitution_threshold: impact speed [m/s] below which contacts that carry load do not
            bounce, so that resting bodies stay at rest (a contact carrying none bounces down to
            2 |g| h, h = dt / substeps; >= 0).
        precision: "float32" or "float64" (`tumble.precision.DEFAULT_PRECISION` when None): the
            float type of every array and kernel of the world. float64 keeps momentum and energy
            bookkeeping to ~1e-15 of their size; float32 halves the memory traffic (docs/performance.md).

    Raises:
        TypeError, ValueError: naming the argument and the value, for a bad argument.

    `gravity`, `dt`, `substeps` and `restitution_threshold` may be set at any time (checked as
    here) and take effect on the next step.
    """

    def __init__(
        self,
        *,
        gravity: Sequence[float] | np.ndarray = (0.0, 0.0, -9.81),
        dt: float = 1.0 / 240.0,
        substeps: int = 8,
        seed: int = 0,
        device: str = "cpu",
        restitution_threshold: float = 0.5,
        precision: Precision | None = None,
    ):
        # the default is read at each call, so that a program (or a test) may set it once for all its worlds
        self._precision: Precision = precisions.DEFAULT_PRECISION if precision is None else precisions.check(precision)
        #: the kernel modules of this world's precision (`tumble.precision.kernels`)
        self._k = k = precisions.kernels(self._precision)
        self.gravity = gravity
        self.dt = dt
        self.substeps = substeps
        self.restitution_threshold = restitution_threshold
        self.seed = validate.seed(seed)
        validate.text(device, "device")
        init_warp()
        if device.startswith("cuda") and not wp.is_cuda_available():
            raise ValueError(f"device {device!r}: Warp finds no CUDA device on this machine; use device='cpu'")
        try:
            self.device = str(wp.get_device(device))
        except (RuntimeError, ValueError) as exc:
            raise ValueError(f"device {device!r}: {exc}") from None
        self.rng = np.random.default_rng(self.seed)
        # time = sum over runs of equal dt of (steps in the run) * dt, so it is exact to one rounding
        self._time_base = 0.0
        self._segment_dt = self.dt
        self._segment_steps = 0
        self.profile: dict[str, float] = {}
        self._lap = _Laps(self, self.device)
        self._finite_held: tuple | None = None  # (see _finite_values)
        self.metadata: dict = {}
        self._key = register_world(self)

        # the parts (tumble.model): one dict holds the body arrays of all four, which share their rows
        # (the joint solver's rows are split the same way: definitions to the model, impulses to the state)
        shared: dict[str, wp.array] = {}
        self.joints: JointSet = k.joints.JointSet(self.device)
        hulls: HullSet = k.hulls.HullSet(self.device)
        meshes: MeshSet = k.meshes.MeshSet(self.device)
        self.model = Model(self.device, shared, self._precision, hulls, meshes, self.joints.definitions)
        self.contacts: ContactSet = k.contacts.ContactSet(self.device)
        self.state = State(self.device, shared, self._precision, self.contacts.previous, self.joints.impulses)
        self.control = Control(self.device, shared, self._precision)
        # every body array as one table, for the stages (model, state, control and the solver's scratch)
        self.bodies = body_row_group(self.device, shared, self.model, self.state, self.control)
        self.emitters: list[Emitter] = []
        self.broadphase: BroadPhase = k.broadphase.BroadPhase(self.device)
        self._cloth: ClothSystem | None = None  # created on the first add_cloth
        self._launches = LaunchCache()
        self._launch_sizes: tuple[int, int] | None = None
        # body ids: `body_count` of them; rows hold only live bodies, so after a reorder or a
        # removal `_slot_of_id` maps each id to its row (-1 for a removed body)
        self._slot_of_id: np.ndarray | None = None  # None while row i holds id i
        self._id_count = 0
        self._free_ids = 0
        # each id's generation: that of the handle of the body holding it now (a snapshot keeps it), and
        # the highest handed out at it in this world's life (a snapshot leaves it out: a restore never
        # lowers it, so a handle made after a snapshot never names a body added after the restore)
        self._body_generation = np.zeros(16, dtype=np.int64)
        self._issued_generation = np.full(16, -1, dtype=np.int64)
        self._sorted_at = -SORT_INTERVAL

    # ------------------------------------------------------------------ settings

    @property
    def precision(self) -> Precision:
        """ "float32" or "float64": the float type of the world's arrays and kernels, fixed at creation."""
        return self._precision

    @property
    def gravity(self) -> np.ndarray:
        """Gravitational acceleration [m/s^2], shape (3,); may be set (or changed in place)."""
        return self._gravity

    @gravity.setter
    def gravity(self, value: Sequence[float] | np.ndarray) -> None:
        g = validate.vector(value, "gravity")
        cast(g, precisions.types_of(self._precision).numpy, "gravity")  # (a float32 world's kernels take it)
        self._gravity = g

    @property
    def dt(self) -> float:
        """Time step [s] of `step()` and `run()`, > 0."""
        return self._dt

    @dt.setter
    def dt(self, value: float) -> None:
        self._dt = _step_length(value)

    @property
    def substeps(self) -> int:
        """Solver substeps per step, an integer >= 1."""
        return self._substeps

    @substeps.setter
    def substeps(self, value: int) -> None:
        substeps = validate.integer(value, "substeps", low=1)
        if substeps > limits.MAX_SUBSTEPS:
            raise ValueError(f"substeps must be an integer in [1, {limits.MAX_SUBSTEPS}], got {validate.show(value)}")
        self._substeps = substeps

    @property
    def restitution_threshold(self) -> float:
        """Approach speed [m/s] below which contacts do not bounce, >= 0."""
        return self._restitution_threshold

    @restitution_threshold.setter
    def restitution_threshold(self, value: float) -> None:
        self._restitution_threshold = validate.number(value, "restitution_threshold", low=0.0)

    @property
    def step_count(self) -> int:
        """Steps taken (kept in `world.state`)."""
        return self.state.step_count

    @step_count.setter
    def step_count(self, value: int) -> None:
        self.state.step_count = validate.integer(value, "step_count", low=0)

    @property
    def hulls(self) -> HullSet:
        """Convex prototypes (a `HullSet`, kept in `world.model`), row 0 the unit box; `hulls.prototypes[body_geometry[i]]`
        keeps a convex body's user frame."""
        return self.model.hulls

    @property
    def meshes(self) -> MeshSet:
        """Static triangle meshes and their Warp BVHs (a `MeshSet`, kept in `world.model`); add them with `add_mesh`."""
        return self.model.meshes

    @property
    def key(self) -> int:
        """This world's identity, carried by the handles it gives out (unique in the process)."""
        return self._key

    @property
    def time(self) -> float:
        """Simulated time [s]: steps taken times their dt, summed over runs of equal dt (exact to one rounding)."""
        return self._time_base + self._segment_steps * self._segment_dt

    # ------------------------------------------------------------------ bodies

    def add_plane(
        self,
        *,
        normal: Sequence[float] | np.ndarray = (0.0, 0.0, 1.0),
        offset: float = 0.0,
        restitution: float = DEFAULT_RESTITUTION,
        friction: float = DEFAULT_FRICTION,
    ) -> BodyId:
        """Add a static infinite plane {x : dot(normal, x) = offset}; bodies stay on the +normal side.

        Args:
            normal: plane normal, shape (3,); need not be unit length but must not be zero.
            offset: signed distance of the plane from the origin along the normal [m].
            restitution: coefficient of restitution in [0, 1].
            friction: Coulomb friction coefficient (>= 0).
        """
        n = validate.direction(normal, "normal")
        offset = validate.number(offset, "offset")
        return self._add_bodies(
            shape=ShapeType.PLANE,
            position=(n * offset)[None],
            orientation=quat_from_z(n)[None],
            radius=np.zeros(1),
            half_extents=np.zeros((1, 3)),
            mass=np.zeros(1),
            inertia=np.zeros((1, 3)),
            restitution=validate.restitution(restitution),
            friction=validate.friction(friction),
        )[0]

    def add_sphere(
        self, *, position: Sequence[float] | np.ndarray, radius: float, **options: Unpack[SolidOptions]
    ) -> BodyId:
        """Add a solid sphere.

        Args:
            position: centre [m], shape (3,).
            radius: [m], > 0.
            options: mass or density, velocity, orientation, angular velocity, material, static or
                kinematic: `tumble.SolidOptions`.

        Returns:
            The sphere's `BodyId`.
        """
        validate.positive(radius, "radius")
        o = given(options, SOLID_DEFAULTS, "World.add_sphere")
        return self.add_spheres(position=validate.vector(position, "position")[None], radius=radius, **o)[0]

    def add_box(
        self,
        *,
        position: Sequence[float] | np.ndarray,
        half_extents: Sequence[float] | np.ndarray,
        **options: Unpack[SolidOptions],
    ) -> BodyId:
        """Add a solid box. Arguments as `add_sphere`, with half extents [m], shape (3,), all > 0."""
        o = given(options, SOLID_DEFAULTS, "World.add_box")
        x = validate.vector(position, "position")[None]
        return self.add_boxes(position=x, half_extents=validate.vector(half_extents, "half_extents"), **o)[0]

    def add_spheres(
        self, *, position: ArrayLike, radius: float | ArrayLike, **options: Unpack[SolidOptions]
    ) -> list[BodyId]:
        """Add n spheres in one call, much faster than n calls of `add_sphere`.

        Args:
            position: centres [m], shape (n, 3).
            radius: one value for all, or shape (n,).
            options: as `add_sphere`'s, one value for all or one a body (`tumble.SolidOptions`).

        Returns:
            The new bodies' ids, in order.
        """
        o = given(options, SOLID_DEFAULTS, "World.add_spheres")
        x = self._body_positions(position)
        r = validate.positive_rows(radius, "radius", len(x))
        m = self._masses(o, _shapes.sphere_volume(r))
        inertia = _shapes.sphere_inertia(m, r)
        return self._add_solids(
            ShapeType.SPHERE, x, o, radius=r, half_extents=np.zeros((len(x), 3)), mass=m, inertia=inertia
        )

    def add_boxes(
        self, *, position: ArrayLike, half_extents: ArrayLike, **options: Unpack[SolidOptions]
    ) -> list[BodyId]:
        """Add n boxes in one call; arguments as `add_spheres`, with half extents [m], shape (3,) or (n, 3)."""
        o = given(options, SOLID_DEFAULTS, "World.add_boxes")
        x = self._body_positions(position)
        h = validate.rows(half_extents, "half_extents", 3, len(x))
        if np.any(h <= 0.0):
            raise ValueError(f"half_extents must all be > 0, got {validate.show(half_extents)}")
        m = self._masses(o, _shapes.box_volume(h))
        inertia = _shapes.box_inertia(m, h)
        return self._add_solids(ShapeType.BOX, x, o, radius=np.zeros(len(x)), half_extents=h, mass=m, inertia=inertia)

    def add_capsule(
        self,
        *,
        position: Sequence[float] | np.ndarray,
        radius: float,
        half_height: float,
        **options: Unpack[SolidOptions],
    ) -> BodyId:
        """Add a solid capsule: the points within `radius` of a segment along the body's z axis.

        Args:
            radius: [m], > 0.
            half_height: half the length of the segment [m], > 0 (the capsule is
                2 (half_height + radius) long).
            Others as `add_sphere`.
        """
        o = given(options, SOLID_DEFAULTS, "World.add_capsule")
        x = validate.vector(position, "position")[None]
        return self.add_capsules(position=x, radius=radius, half_height=half_height, **o)[0]

    def add_capsules(
        self,
        *,
        position: ArrayLike,
        radius: float | ArrayLike,
        half_height: float | ArrayLike,
        **options: Unpack[SolidOptions],
    ) -> list[BodyId]:
        """Add n capsules in one call; arguments as `add_spheres`, with `half_height` one value or shape (n,)."""
        o = given(options, SOLID_DEFAULTS, "World.add_capsules")
        x = self._body_positions(position)
        r = validate.positive_rows(radius, "radius", len(x))
        a = validate.positive_rows(half_height, "half_height", len(x))
        m = self._masses(o, _shapes.capsule_volume(r, a))
        inertia = _shapes.capsule_inertia(m, r, a)
        # half extents of the body-frame bounding box; the kernels read the half height as h_z - r
        h = np.stack([r, r, a + r], axis=1)
        return self._add_solids(ShapeType.CAPSULE, x, o, radius=r, half_extents=h, mass=m, inertia=inertia)

    def add_convex(
        self,
        *,
        points: ArrayLike | None = None,
        file: str | os.PathLike[str] | None = None,
        scale: float | Sequence[float] = 1.0,
        position: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
        **options: Unpack[SolidOptions],
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
            position: the user frame's origin [m]; its orientation is the option `orientation`.
            options: as `add_sphere`'s (`tumble.SolidOptions`).
        """
        o = given(options, SOLID_DEFAULTS, "World.add_convex")
        from .collision.hulls import hull_from_points
        from .io.meshfile import hull_points

        if (points is None) == (file is None):
            raise ValueError(
                f"add_convex takes points or file, {'neither was given' if points is None else 'not both'}"
            )
        points, name = hull_points(points, file)
        factor = validate.scale(scale)
        proto = hull_from_points(np.asarray(points, dtype=np.float64) * factor, name=name)
        q_user = validate.quaternion(o["orientation"])
        x = validate.vector(position, "position") + quat_rotate(q_user, proto.offset_com)
        m = self._masses(o, np.array([proto.volume]))
        inertia = proto.inertia[None] * (m[0] / proto.volume)
        index = self.hulls.add(proto)
        ids = self._add_solids(
            ShapeType.CONVEX,
            x[None],
            {**o, "orientation": quat_mul(q_user, proto.rotation)},
            radius=np.zeros(1),
            half_extents=np.abs(proto.vertex).max(axis=0)[None],
            mass=m,
            inertia=inertia,
            bound=np.array([proto.bound_radius]),
        )
        self.bodies.write("body_geometry", self._row(ids[0]), index)
        return ids[0]

    def add_mesh(
        self,
        *,
        file: str | os.PathLike[str] | None = None,
        vertices: ArrayLike | None = None,
        triangles: ArrayLike | None = None,
        scale: float | Sequence[float] = 1.0,
        position: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
        orientation: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0, 1.0),
        restitution: float = DEFAULT_RESTITUTION,
        friction: float = DEFAULT_FRICTION,
    ) -> BodyId:
        """Add a static triangle mesh, from a file (OBJ, STL, PLY, OFF, glTF/GLB through trimesh) or arrays.

        Spheres, capsules, boxes, convex bodies and cloth (particles and triangles) collide with it through
        its BVH (`wp.Mesh`).
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
        factor = validate.scale(scale)
        v = v * factor
        index = self.meshes.add(v, t)
        ids = self._add_bodies(
            shape=ShapeType.MESH,
            position=validate.vector(position, "position")[None],
            orientation=validate.quaternion(orientation)[None],
            radius=np.zeros(1),
            half_extents=np.abs(v).max(axis=0)[None],
            mass=np.zeros(1),
            inertia=np.zeros((1, 3)),
            restitution=validate.restitution(restitution),
            friction=validate.friction(friction),
            bound=np.array([float(np.linalg.norm(v, axis=1).max())]),
        )
        self.bodies.write("body_geometry", self._row(ids[0]), index)
        return ids[0]

    def add_body(self, shape: str | ShapeType, **kwargs: Any) -> BodyId:
        """Factory: add a body by shape name ("plane", "sphere", "box", "capsule", "convex" or "mesh") with that
        shape's keywords (those of `add_plane`, `add_sphere`, ...)."""
        kind = shape if isinstance(shape, ShapeType) else _shapes.shape_from_name(validate.text(shape, "shape"))
        adders: dict[ShapeType, Callable[..., BodyId]] = {
            ShapeType.PLANE: self.add_plane,
            ShapeType.SPHERE: self.add_sphere,
            ShapeType.BOX: self.add_box,
            ShapeType.CAPSULE: self.add_capsule,
            ShapeType.CONVEX: self.add_convex,
            ShapeType.MESH: self.add_mesh,
        }
        return adders[kind](**kwargs)

    @keywords_of(Emitter.__init__)
    def add_emitter(self, **keywords: Any) -> Emitter:
        """Add an emitter that releases bodies over time; the keywords are `tumble.Emitter`'s.

        Returns:
            The `Emitter` (the emitter's handle), whose `rate` may be changed while the world runs.
        """
        emitter = Emitter(**keywords)
        if emitter.seed is None:
            emitter.seed = int(self.rng.integers(0, 2**31 - 1))
        emitter.reset_rng()
        emitter.add_hulls(self.hulls)
        emitter.world_key = self._key
        self.emitters.append(emitter)
        return emitter

    def remove_emitter(self, emitter: Emitter) -> None:
        """Stop and forget an emitter of this world (the bodies it released stay)."""
        if not isinstance(emitter, Emitter):
            raise TypeError(f"emitter must be an Emitter, got {validate.show(emitter)}")
        if emitter.world_key != self._key or not any(e is emitter for e in self.emitters):
            raise HandleError("emitter does not belong to this World (added to another one, or removed)")
        self.emitters = [e for e in self.emitters if e is not emitter]
        emitter.world_key = None

    @keywords_of(ClothSystem.add_cloth)
    def add_cloth(self, **keywords: Any) -> ClothId:
        """Add a rectangular mass-spring cloth; the keywords are `ClothSystem.add_cloth`'s.

        Returns:
            The cloth's `ClothId` (an int, its index in creation order); `world.cloth` holds the
            particles of every cloth.
        """
        return ClothId(self.cloth.add_cloth(**keywords), 0, self._key)

    @property
    def has_cloth(self) -> bool:
        """Whether the world holds cloth particles (asking does not create the `ClothSystem`)."""
        return self._cloth is not None and self._cloth.particle_count > 0

    @property
    def cloth(self) -> ClothSystem:
        """The world's `ClothSystem` (created on first use)."""
        if self._cloth is None:
            self._cloth = self._k.cloth.ClothSystem(self.device, world_key=self._key, gravity=self.gravity)
            # the cloth's parts are the world's: topology and pins, particles, drags and wind
            self.model.cloth, self.state.cloth, self.control.cloth = self._cloth.parts
        return self._cloth

    def pin_cloth_to_body(self, particles, body: BodyId | int) -> None:
        """Pin cloth particles (indices into `world.cloth`'s arrays) to a body where they are now: they
        follow it and pull on it (two-way). Same as `world.cloth.pin_to_body(particles, body)`.

        The particles at and next to the pins do not touch the body. The stretch limit moves a free body
        with its pins, however light; a jointed body light at its pins (lighter than their particles,
        or turned about a long lever) other than one hinged or ball-jointed to the world alone takes
        the cloth's pull as an impulse and can overshoot: share its load over more pins
        (docs/design.md, "Cloth with bodies")."""
        row = self._row(body)
        b = self.bodies
        self.cloth.attach_to_body(particles, row, b.numpy("body_position")[row], b.numpy("body_orientation")[row])

    @keywords_of(ClothSystem.set_wind)
    def set_wind(self, **keywords: Any) -> None:
        """Set the wind acting on cloth; the keywords are `ClothSystem.set_wind`'s (model: `tumble.Wind`)."""
        self.cloth.set_wind(**keywords)

    def set_material(self, *, restitution: float | None = None, friction: float | None = None) -> None:
        """Set restitution and/or friction of every body (planes included), effective at once."""
        n = self.bodies.count
        if restitution is not None:
            self.bodies.write("body_restitution", slice(0, n), validate.restitution(restitution))
        if friction is not None:
            self.bodies.write("body_friction", slice(0, n), validate.friction(friction))

    def add_joint(
        self,
        kind: str,
        body_a: BodyId | int | None,
        body_b: BodyId | int | None,
        *,
        anchor: ArrayLike | None = None,
        anchor_a: ArrayLike | None = None,
        anchor_b: ArrayLike | None = None,
        axis: ArrayLike | None = None,
        frame: str = "world",
        lower: float | None = None,
        upper: float | None = None,
        motor_speed: float | None = None,
        max_torque: float | None = None,
        max_force: float | None = None,
        length: float | None = None,
        min_length: float | None = None,
        max_length: float | None = None,
        stiffness: float = 0.0,
        damping: float = 0.0,
        break_force: float = math.inf,
        collide: bool = False,
    ) -> JointId:
        """Join two bodies (either may be None: the world, a fixed frame); see `tumble.solver.joints`.

        Args:
            kind: "ball", "hinge", "slider", "fixed", "distance" or "rope".
            body_a, body_b: BodyId (or index) of the two bodies, or None for the world.
            anchor: shared anchor, world point at creation [m]; or anchor_a / anchor_b, one per body
                (world points, or body-frame points with frame="body"; either wins over anchor for its
                body). Default: a's centre (distance and rope: each body's centre).
            axis: hinge / slider axis, world (or a's frame with frame="body"); default (0, 0, 1).
            lower, upper: hinge angle limits [rad] on the angle turned since creation, whole turns
                counted (a range may span turns; an infinite or missing side is no limit there), or
                slider translation limits [m] (from creation); lower == upper locks the joint there.
            motor_speed: hinge [rad/s] / slider [m/s] target speed of b relative to a, with max_torque [N m]
                (hinge) or max_force [N] (slider).
            length, min_length, max_length: distance joint rest length (default: the current distance)
                and bounds (default: rigid rod; rope: 0 to length; spring: unbounded).
            stiffness, damping: distance spring [N/m], [N s/m].
            break_force: the joint breaks when its force exceeds this [N], > 0 (default never).
            collide: whether the two bodies still collide (default False).

        Returns:
            The new joint's `JointId`; `joint_force[id.index]` is its force on b [N].
        """
        ends = [
            joint_solver.JointBody.world() if body is None else self._joint_body(body, key)
            for key, body in (("body_a", body_a), ("body_b", body_b))
        ]
        rows = joint_solver.joint_rows(
            kind,
            *ends,
            anchor=anchor,
            anchor_a=anchor_a,
            anchor_b=anchor_b,
            axis=axis,
            frame=frame,
            lower=lower,
            upper=upper,
            motor_speed=motor_speed,
            max_torque=max_torque,
            max_force=max_force,
            length=length,
            min_length=min_length,
            max_length=max_length,
            stiffness=stiffness,
            damping=damping,
            break_force=break_force,
            collide=collide,
        )
        return JointId(self.joints.add(rows)[0], 0, self._key)

    def remove_joint(self, joint: JointId | int) -> None:
        """Stop a joint for good, at once: as PyBullet's `removeConstraint` or Rapier's joint removal.

        From the next step it holds nothing and its warm start is gone; if it kept its two bodies
        from colliding, they collide again; a body no other joint or pin holds can be removed. Its
        row stays, as a broken joint's does (`joint_broken` is True there, `joint_force` and
        `joint_torque` zero), so every other joint keeps its index and its `JointId`. Removing it
        again changes nothing.
        """
        k = JointId.checked_index(joint, self.joints.count, self._key)
        stopped = (
            "joint_enabled",
            "joint_force",
            "joint_torque",
            "joint_impulse_linear",
            "joint_impulse_angular",
            "joint_impulse_axial",
            "joint_impulse_lower",
            "joint_impulse_upper",
        )
        for name in stopped:
            self.joints.write(name, slice(k, k + 1), 0)

    def _joint_body(self, body, key: str):
        try:
            i = self._row(body)
        except HandleError as exc:  # another world's, or a removed one: say which
            raise joint_solver.JointArgumentError(key, str(exc)) from None
        except (IndexError, TypeError, ValueError):
            raise joint_solver.JointArgumentError(
                key, f"no body {body!r} (the world has {self.bodies.count} bodies)"
            ) from None
        b = self.bodies
        return joint_solver.JointBody(
            i,
            b.numpy("body_position")[i].copy(),
            b.numpy("body_orientation")[i].copy(),
            bool(b.numpy("body_inv_mass")[i] > 0.0),
        )

    def apply_force(self, body: BodyId | int, force: Sequence[float], *, point: Sequence[float] | None = None) -> None:
        """Apply a force [N] (at a world `point`, default the centre of mass) during the next step only.

        Static and kinematic bodies are not moved by forces.
        """
        i = self._row(body)
        f = validate.vector(force, "force")
        self.bodies.write("body_force", i, self.bodies.numpy("body_force")[i] + f)
        if point is not None:
            r = validate.vector(point, "point") - self.bodies.numpy("body_position")[i]
            self.bodies.write("body_torque", i, self.bodies.numpy("body_torque")[i] + np.cross(r, f))

    # ------------------------------------------------------------------ body state and removal

    def body_state(self, body: BodyId | int) -> BodyState:
        """One body's position, orientation, velocity, angular velocity and kind, as copies.

        As PyBullet's `getBasePositionAndOrientation` and `getBaseVelocity` in one call;
        `body.position` and the other handle properties read the same.
        """
        i = self._row(body)
        b = self.bodies
        return BodyState(
            # the four state arrays, then the kind (mypy cannot count a starred generator)
            *(np.array(b.numpy(name)[i]) for name in _STATE_NAMES.values()),  # type: ignore[misc, arg-type]
            kind=BodyKind(int(b.numpy("body_kind")[i])),
        )

    def set_body_state(
        self,
        body: BodyId | int | Sequence[BodyId | int],
        *,
        position: ArrayLike | None = None,
        orientation: ArrayLike | None = None,
        velocity: ArrayLike | None = None,
        angular_velocity: ArrayLike | None = None,
    ) -> None:
        """Set the pose and/or velocities of one body, or of several at once; effective at once.

        As PyBullet's `resetBasePositionAndOrientation` and `resetBaseVelocity`, and Rapier's
        `set_translation` / `set_linvel`; the handle properties (`ball.position = ...`) call this.
        A moved body teleports: contacts are found anew at the next step (a contact that is
        still there keeps its warm start). Static bodies may be moved but not given a velocity;
        make them kinematic for that.

        Args:
            body: a `BodyId` (or int id), or a sequence of k of them.
            position: centre of mass [m], shape (3,), or (k, 3) for k bodies.
            orientation: unit quaternion (x, y, z, w), shape (4,) or (k, 4) (normalised here).
            velocity: [m/s], shape (3,) or (k, 3).
            angular_velocity: world frame [rad/s], shape (3,) or (k, 3).

        Raises:
            TypeError, ValueError: a bad value, named; HandleError: a removed or foreign body.
        """
        ids, rows = self._rows(body)
        k = len(rows)
        values = {}
        if position is not None:
            values["body_position"] = validate.rows(position, "position", 3, k)
        if orientation is not None:
            values["body_orientation"] = validate.quaternion(orientation, "orientation", k)
        if velocity is not None:
            values["body_velocity"] = validate.rows(velocity, "velocity", 3, k)
        if angular_velocity is not None:
            values["body_angular_velocity"] = validate.rows(angular_velocity, "angular_velocity", 3, k)
        if velocity is not None or angular_velocity is not None:
            static = self.bodies.numpy("body_kind")[rows] == BodyKind.STATIC
            if np.any(static):
                raise ValueError(
                    f"body {int(ids[np.argmax(static)])} is static and cannot be given a velocity; "
                    "add it with kinematic=True to move it by a velocity"
                )
        for name, v in values.items():
            self.bodies.write(name, rows, v)

    def set_kinematic_target(
        self,
        body: BodyId | int | Sequence[BodyId | int],
        *,
        position: ArrayLike | None = None,
        orientation: ArrayLike | None = None,
        dt: float | None = None,
    ) -> None:
        """Give kinematic bodies the velocities that carry them to a pose by the end of the next step.

        As Rapier's `set_next_kinematic_translation` / `_rotation`: the body sweeps there at a
        constant velocity, so dynamic bodies in its way are pushed, not tunnelled through.
        v = (target - x) / dt; w = axis * angle / dt for the rotation from the current orientation
        to the target (the shorter way).

        Args:
            body: a kinematic body's `BodyId` (or int id), or a sequence of k of them.
            position: target centre [m], shape (3,) or (k, 3); None keeps the linear velocity.
            orientation: target orientation (x, y, z, w), shape (4,) or (k, 4); None keeps the
                angular velocity.
            dt: the next step's length [s] (default `world.dt`).
        """
        ids, rows = self._rows(body)
        k = len(rows)
        h = self.dt if dt is None else _step_length(dt)
        kinds = self.bodies.numpy("body_kind")[rows]
        if np.any(kinds != BodyKind.KINEMATIC):
            raise ValueError(
                f"body {int(ids[np.argmax(kinds != BodyKind.KINEMATIC)])} is not kinematic; "
                "add it with kinematic=True to drive it by targets"
            )
        if position is not None:
            target = validate.rows(position, "position", 3, k)
            self.bodies.write("body_velocity", rows, (target - self.bodies.numpy("body_position")[rows]) / h)
        if orientation is not None:
            target = validate.quaternion(orientation, "orientation", k)
            rotation = rotation_vector(target, self.bodies.numpy("body_orientation")[rows])
            self.bodies.write("body_angular_velocity", rows, rotation / h)

    def remove_body(self, body: BodyId | int) -> None:
        """Remove one body; see `remove_bodies`."""
        self.remove_bodies([body])

    def remove_bodies(self, bodies: Sequence[BodyId | int]) -> None:
        """Remove bodies from the world, effective at once.

        Their contacts (and warm starts) go with them; other bodies keep their ids. A removed
        body's id is given to the next body added, with a new generation, so its old
        handle raises `HandleError`. Until then the id's row in the views is NaN (shape and
        kind -1) and `body_alive` is False there; removing the highest ids shortens the views.
        A body that an acting joint or a cloth pin holds is refused (`ValueError`, nothing removed):
        remove its joints first (`remove_joint`).
        """
        ids, rows = self._rows(bodies)
        if len(np.unique(ids)) != len(ids):
            raise ValueError("bodies lists a body twice")
        # joints and cloth pins on a body would lose their body: refused (a broken or removed joint holds
        # nothing: it follows the removed body to the world, -1, as `JointSet.remap_bodies` does)
        jointed = np.isin(rows, self.joints.held_bodies())
        if jointed.any():
            body, row = int(ids[jointed][0]), rows[jointed][0]
            j = self.joints
            on = j.numpy("joint_enabled") != 0
            joint = int(np.flatnonzero(on & ((j.numpy("joint_body_a") == row) | (j.numpy("joint_body_b") == row)))[0])
            raise ValueError(f"body {body} is held by joint {joint}; remove its joints first (World.remove_joint)")
        if self._cloth is not None:
            pins = self._cloth.body_pins
            pinned = np.isin(rows, pins.body.numpy()[: pins.count])
            if pinned.any():
                raise ValueError(f"body {int(ids[pinned][0])} is held by a cloth pin; pinned bodies cannot be removed")
        n = self.bodies.count
        keep = np.ones(n, dtype=bool)
        keep[rows] = False
        order = np.flatnonzero(keep)
        slot = np.full(n, -1, dtype=np.int64)  # new row of each old row, -1 for a removed one
        slot[order] = np.arange(len(order))
        self.bodies.take(order)
        self.contacts.remap_bodies(slot, current=True)
        if self._cloth is not None:
            self._cloth.remap_bodies(slot)
        self.joints.remap_bodies(slot)  # joints on other bodies follow their rows
        self.broadphase.bodies_changed()
        # ids: removed ones are freed (generation + 1); the others follow their rows
        of_id = np.arange(self._id_count) if self._slot_of_id is None else self._slot_of_id
        live = of_id >= 0
        of_id = of_id.copy()
        of_id[live] = slot[of_id[live]]
        self._set_id_rows(of_id)

    def has_body(self, body: BodyId | int) -> bool:
        """True if `body` names a live body of this world (False for a removed or foreign handle)."""
        try:
            self._row(body)
        except (HandleError, IndexError):
            return False
        return True

    def body(self, index: int) -> BodyId:
        """The handle of the live body with id `index` (e.g. from `contact_pair` or a picked row)."""
        i = validate.integer(index, "index", low=0)
        self._row(i)
        return BodyId(i, int(self._body_generation[i]), self._key)

    @property
    def body_alive(self) -> np.ndarray:
        """True for ids of live bodies, False for removed ones, shape (body_count,), bool."""
        if self._slot_of_id is None:
            return readonly(np.ones(self._id_count, dtype=bool))
        return readonly(self._slot_of_id >= 0)

    def body_row(self, body: BodyId | int) -> int:
        """Row of a live body in the arrays of `world.bodies` (`world.model.bodies`, ...).

        Rows are in id order until bodies are removed or a large world renumbers them along a
        space-filling curve (`SORT_MIN_BODIES`); the `body_*` views are always in id order.
        """
        return self._row(body)

    @property
    def body_rows(self) -> np.ndarray:
        """Row of each body id in the arrays of `world.bodies`, -1 for removed ids, shape (body_count,), int64."""
        if self._slot_of_id is None:
            return readonly(np.arange(self._id_count))
        return readonly(self._slot_of_id.copy())

    def _set_id_rows(self, of_id: np.ndarray) -> None:
        """Take `of_id` (row of each id, -1 = free) as the id table: trailing free ids are dropped."""
        alive = np.flatnonzero(of_id >= 0)
        count = int(alive[-1]) + 1 if len(alive) else 0
        of_id = of_id[:count]
        self._id_count = count
        self._free_ids = count - len(alive)
        self._slot_of_id = None if self._free_ids == 0 and np.array_equal(of_id, np.arange(count)) else of_id

    def _new_ids(self, k: int) -> np.ndarray:
        """Ids for k new bodies: freed ids first (lowest first), then new ones."""
        reused = np.zeros(0, dtype=np.int64)
        if self._free_ids and self._slot_of_id is not None:
            reused = np.flatnonzero(self._slot_of_id < 0)[:k]
        fresh = np.arange(self._id_count, self._id_count + k - len(reused))
        ids = np.concatenate([reused, fresh])
        end = self._id_count + len(fresh)
        for name, blank in (("_body_generation", 0), ("_issued_generation", -1)):
            table = getattr(self, name)
            if len(table) < end:
                grown = np.full(max(2 * len(table), end), blank, dtype=np.int64)
                grown[: len(table)] = table
                setattr(self, name, grown)
        # a new generation at each id, above every handle ever made at it (so stale handles stay stale)
        self._issued_generation[ids] += 1
        self._body_generation[ids] = self._issued_generation[ids]
        return ids

    def _row(self, body) -> int:
        """Row of one body in the body arrays, after checking its handle."""
        return int(self._rows(body, single=True)[1][0])

    def _rows(self, body, *, single: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(ids, rows) of one body or a sequence of bodies, each checked: a live body of this world."""
        many = not single and isinstance(body, (list, tuple, range, np.ndarray))
        items = list(body) if many else [body]
        ids = np.empty(len(items), dtype=np.int64)
        for k, b in enumerate(items):
            if isinstance(b, (bool, np.bool_)) or not isinstance(b, (int, np.integer)):
                raise TypeError(f"body must be a BodyId (or an int id), got {validate.show(b)}")
            i = int(b)
            if isinstance(b, Handle):
                if not isinstance(b, BodyId):
                    raise TypeError(f"body must be a BodyId, got the {type(b).__name__} {b!r}")
                if b.world_key is not None and b.world_key != self._key:
                    raise HandleError(f"body {i} belongs to another World")
                if b.world_key is not None and not 0 <= i < self._id_count:  # its id was freed with it
                    raise HandleError(f"body {i} was removed from this World")
            if not 0 <= i < self._id_count:
                raise NoSuchIdError(f"body {i} does not exist (the world has {self._id_count} body ids)")
            if isinstance(b, Handle):
                if b.generation != self._body_generation[i]:
                    raise HandleError(
                        f"body {i} was removed from this World (its id now names a newer body)"
                        if self._slot_of_id is None or self._slot_of_id[i] >= 0
                        else f"body {i} was removed from this World"
                    )
            ids[k] = i
        rows = ids if self._slot_of_id is None else self._slot_of_id[ids]
        if np.any(rows < 0):
            raise HandleError(f"body {int(ids[np.argmax(rows < 0)])} was removed from this World")
        return ids, rows

    def _masses(self, options: dict[str, Any], volume: np.ndarray) -> np.ndarray:
        """The masses of solids of `volume` from the `SolidOptions` mass or density."""
        mass, density = options["mass"], options["density"]
        if mass is not None and density is not None:
            raise ValueError("give mass or density, not both")
        if mass is not None:
            return validate.positive_rows(mass, "mass", len(volume))
        return (
            validate.positive_rows(_shapes.DEFAULT_DENSITY if density is None else density, "density", len(volume))
            * volume
        )

    def _add_solids(
        self, shape, position, options: dict[str, Any], *, radius, half_extents, mass, inertia, bound=None
    ) -> list[BodyId]:
        """Add solids of one shape at `position` with the `SolidOptions` `options` (defaults filled in)."""
        n = len(position)
        q = validate.quaternion(options["orientation"], "orientation", n)
        v = validate.rows(options["velocity"], "velocity", 3, n)
        w = validate.rows(options["angular_velocity"], "angular_velocity", 3, n)
        restitution = validate.restitution(options["restitution"])
        friction = validate.friction(options["friction"])
        static, kinematic = validate.flag(options["static"], "static"), validate.flag(options["kinematic"], "kinematic")
        if static and kinematic:
            raise ValueError("a body is static or kinematic, not both")
        kind = BodyKind.DYNAMIC
        if not (static or kinematic or validate.mass_properties_usable(mass, inertia)):
            bad = next(i for i in range(n) if not validate.mass_properties_usable(mass[i], inertia[i]))
            raise ValueError(
                f"a {ShapeType(shape).name.lower()} of mass {float(mass[bad]):g} kg and moments of inertia down to "
                f"{float(np.min(inertia[bad])):g} kg m^2: its size and mass (or density) must give a mass and "
                "inertia that are finite and > 0, with finite inverses, in float64"
            )
        if static or kinematic:
            kind = BodyKind.STATIC if static else BodyKind.KINEMATIC
            mass, inertia = np.zeros(n), np.zeros((n, 3))
        if static and (np.any(v) or np.any(w)):
            # (as set_body_state: a velocity given to a static body would be dropped without a word)
            name = "velocity" if np.any(v) else "angular_velocity"
            raise ValueError(
                f"{name}: a static body never moves, so it cannot be given a velocity; "
                "add it with kinematic=True to move it by a velocity"
            )
        return self._add_bodies(
            shape=shape,
            position=position,
            velocity=v,
            orientation=q,
            angular_velocity=w,
            radius=radius,
            half_extents=half_extents,
            mass=mass,
            inertia=inertia,
            restitution=restitution,
            friction=friction,
            kind=kind,
            bound=bound,
        )

    def _body_positions(self, position) -> np.ndarray:
        """The rows of `position` (`validate.rows`) for new bodies, refused before they are copied when the
        world's bodies would not fit in memory (`limits.check_memory`: a broadcast of 10^9 rows was
        copied until the system ended the process)."""
        try:
            shape = np.shape(position)
        except ValueError:  # ragged rows: validate.rows names them
            shape = ()
        if len(shape) == 2:
            limits.check_memory("position", "bodies", self.body_count + shape[0], limits.BYTES_PER_BODY)
        return validate.rows(position, "position", 3)

    def _add_bodies(
        self,
        *,
        shape,
        position,
        orientation,
        radius,
        half_extents,
        mass,
        inertia,
        restitution,
        friction,
        velocity=None,
        angular_velocity=None,
        kind=None,
        bound=None,
        geometry=None,
    ) -> list[BodyId]:
        """Append k bodies given as arrays with k rows (vectorised; the emit stage adds emitters' releases).

        `kind` (BodyKind) defaults to static for bodies of mass 0, else dynamic; `bound` (k,)
        overrides the bounding radius where finite (convex bodies: the hull's bounding sphere);
        `geometry` (k,) is each body's row in `hulls` or `meshes` (default 0).
        """
        k = len(position)
        if k == 0:
            return []
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
        if kind is None:
            kind = np.where(mass > 0.0, BodyKind.DYNAMIC, BodyKind.STATIC)
        ids = self._new_ids(k)
        rows = self.bodies.append(
            {
                "body_id": ids,
                "body_shape": shape,
                "body_kind": np.broadcast_to(np.asarray(kind, dtype=np.int32), (k,)),
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
                **({} if geometry is None else {"body_geometry": geometry}),
            }
        )
        if self._slot_of_id is None and len(ids) and ids[0] == self._id_count:
            self._id_count += k  # the common case: new ids at the end, rows in id order
        else:
            of_id = np.arange(self._id_count) if self._slot_of_id is None else self._slot_of_id
            grown = np.full(max(self._id_count, int(ids.max()) + 1), -1, dtype=np.int64)
            grown[: len(of_id)] = of_id
            grown[ids] = np.asarray(rows)
            self._set_id_rows(grown)
        generation = self._body_generation[ids]
        return [BodyId(i, g, self._key) for i, g in zip(ids.tolist(), generation.tolist())]

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
        self.broadphase.rows_changed()
        of_id = np.full(self._id_count, -1, dtype=np.int64)
        of_id[self.bodies.numpy("body_id")] = np.arange(n)
        self._slot_of_id = of_id

    # ------------------------------------------------------------------ stepping

    def step(self, dt: float | None = None) -> None:
        """Advance the world by one step of `dt` seconds (default `self.dt`; at most `limits.MAX_DT`, 0.1 s, as `dt`)."""
        dt = self.dt if dt is None else _step_length(dt)
        if dt != self._segment_dt:
            # a new run of steps of another length: bank the time of the last run
            self._time_base = self.time
            self._segment_dt, self._segment_steps = dt, 0
        h = dt / self.substeps
        bodies, contacts = self.bodies, self.contacts

        narrowphase = self._k.narrowphase
        lap = self._lap  # lap(stage) adds the time since the last lap to profile[stage]
        lap.start()

        # validate: finite state, so a NaN is reported where it appeared rather than spreading (and gravity,
        # which may be changed in place: a NaN there was reported as the bodies' or the cloth's divergence)
        g = self._gravity
        if not math.isfinite(float(g[0]) + float(g[1]) + float(g[2])):
            raise ValueError(
                f"gravity must be finite, got {validate.show(g.tolist())} (set in place since the last step)"
            )
        self._validate()
        lap("validate")

        # emit: emitters release bodies where they overlap nothing
        self._emit(dt)
        lap("emit")

        # layout: now and then, renumber body rows so that neighbours in space share cache lines
        self._sort_bodies()
        lap("layout")

        # broad phase: spatial hash -> candidate pairs of bodies whose swept bounds overlap
        # (with the narrow phase's launch, one recorded graph while the world keeps its shape)
        launches = self._launch_cache()
        graph = self._collision_graph(dt)
        if graph is None:
            pairs = self.broadphase.find_pairs(bodies, dt, cache=launches)
            pairs = self.joints.filter_pairs(pairs, bodies)  # jointed pairs collide only if asked
        else:
            wp.capture_launch(graph)
            pairs = self.broadphase
            if pairs.end(bodies, launches):
                graph = None  # the pair buffers overflowed and were grown: collide the pairs again
        lap("broad_phase")

        # narrow phase: pair table -> contact points with normal, separation and anchors
        if graph is None:
            narrowphase.collide(bodies, pairs, contacts, dt, self.hulls, self.meshes, cache=launches)
        else:
            while not narrowphase.collected(contacts):  # overflowed: grown, collide again
                narrowphase.launch_pairs(bodies, pairs, contacts, dt, self.hulls, self.meshes, launches)
        lap("narrow_phase")

        # solver: the stages below, replayed as one recorded graph when nothing they depend on changed
        graph = self._solver_graph(dt, h)
        if graph is not None:
            wp.capture_launch(graph)
        else:
            lap("solver")
            self._solve(dt, h, launches)  # (laps its own stages)
        lap("solver")
        contacts.end_solve()

        self._segment_steps += 1
        self.state.step_count += 1  # not through the setter, which checks what a user gives it

    def _solve(self, dt: float, h: float, launches: LaunchCache | None) -> None:
        """The solver stages of one step, after the narrow phase (all launches, no host decisions)."""
        bodies, contacts, cloth = self.bodies, self.contacts, self._cloth
        contact_solver, integrate = self._k.contacts, self._k.integrate  # this world's precision

        lap = self._lap

        # contact prepare: match last step's contacts for warm starting, effective masses
        contacts.match_previous(bodies)
        contact_solver.prepare(bodies, contacts, dt)
        integrate.begin_step(bodies)
        lap("solver")

        # cloth, step start: its substeps, user forces, wind, the bodies that can reach it
        if cloth is not None:
            hulls, meshes = self.hulls.struct(), self.meshes.struct()
            cloth.begin_step(
                h,
                self.substeps,
                bodies=bodies,
                gravity=self.gravity,
                time=self.time,
                step=self.step_count,
                joints=self.joints,
            )
            lap("cloth")

        # impacts (restitution) for the first substep, before its gravity kick, as every later one's come
        # (an impulse between a substep's kick and its position update adds energy); then the substeps:
        # integrate velocities (+ warm start) -> solve -> integrate positions -> impacts (for the next
        # substep) -> relax -> cloth
        contact_solver.impacts(bodies, contacts, self.gravity, h, self.restitution_threshold, cache=launches)
        lap("solver")
        for substep in range(self.substeps):
            integrate.integrate_velocities(bodies, self.gravity, h, warm=substep > 0, cache=launches)
            lap("integrate")
            if substep == 0:
                contact_solver.warm_start(bodies, contacts)
                self.joints.warm_start(bodies, h, cache=launches)
            self.joints.solve(bodies, h, use_bias=True, cache=launches)
            contact_solver.solve(bodies, contacts, h, use_bias=True, cache=launches)
            lap("solver")
            integrate.integrate_positions(bodies, h, cache=launches)
            lap("integrate")
            self.joints.solve(bodies, h, use_bias=False, cache=launches)
            contact_solver.impacts(bodies, contacts, self.gravity, h, self.restitution_threshold, cache=launches)
            contact_solver.solve(bodies, contacts, h, use_bias=False, cache=launches)
            lap("solver")
            if cloth is not None:
                cloth.substep(h, bodies=bodies, hulls=hulls, meshes=meshes)
                lap("cloth")

        # cloth, step end: a cloth substep left over by rounding
        if cloth is not None:
            cloth.end_step(bodies=bodies, hulls=hulls, meshes=meshes)
            lap("cloth")

        # keep this step's impulses for the next step's warm start
        contacts.store_impulses(bodies)
        self.joints.finish(bodies, dt, cache=launches)  # joint forces; joints over their break force break
        integrate.clear_forces(bodies)

    def _solver_graph(self, dt: float, h: float):
        """The solver stages recorded as one graph (`wp.capture_begin` on the CPU), or None to run them one by one.

        A recorded graph replays its launches in C++ (well under a microsecond each, against
        ~10 us for a launch from Python), so a small world's step costs little more than its
        arithmetic. The graph holds the arrays and scalars of the launches: it is recorded
        again when any of them changes (a capacity grows, dt or gravity is set, a joint is
        added), and only after the same key was seen on two steps running, so a world that
        changes every step runs its stages directly. Counts that change every step (contacts)
        are read by the kernels from the device. Cloth steps run directly.
        """
        contacts, joints = self.contacts, self.joints
        key = contacts.begin_solve(self.bodies)
        if self.device != "cpu" or self._cloth is not None:
            return None
        # (gravity by its bytes: it may be changed in place; a tuple of it took 3 us)
        key += (
            self.bodies.count,
            joints.count,
            self.substeps,
            dt,
            h,
            self._gravity.tobytes(),
            self.restitution_threshold,
        )
        if joints.count:
            joints.refresh(self.bodies.count)
            # every array the joint stages may launch with (a buffer made anew each step: no graph)
            key += tuple(map(id, _arrays_of(joints)))
        return self._launches.graph(
            "solver",
            key,
            lambda: self._solve(dt, h, None),
            lambda: _arrays_of(self.bodies, contacts, contacts.previous, joints),
            self.device,
        )

    def _collision_graph(self, dt: float):
        """The broad and narrow phases' launches recorded as one graph, or None to run them one by one.

        As `_solver_graph`; the cell edge and the pair count stay on the device, and the host
        reads the pair and contact counts after the replay (growing the buffers and colliding
        again directly if they overflowed). Worlds with joints (which filter the pairs on the
        host) and worlds of fewer than two bodies run directly.
        """
        bodies, bp, contacts = self.bodies, self.broadphase, self.contacts
        if self.device != "cpu" or self.joints.count or not bp.begin(bodies):
            return None
        hulls, meshes = self.hulls.struct(), self.meshes.ids()
        key = (
            dt,
            bodies.count,
            bodies.capacity,
            id(bodies.arrays["body_velocity"]),
            *bp.graph_key(),
            contacts.capacity,
            id(contacts.arrays["contact_body_a"]),
            id(hulls),
            id(meshes),
        )
        return self._launches.graph(
            "collision",
            key,
            lambda: (  # a tuple only to run both launches in one lambda; its value is unused
                bp.launch(bodies, dt),  # type: ignore[func-returns-value]
                self._k.narrowphase.launch_pairs(bodies, bp, contacts, dt, self.hulls, self.meshes),
            ),
            lambda: [*_arrays_of(bodies, bp, bp.grid, contacts), *bp.graph_arrays(), meshes, hulls],
            self.device,
        )

    def emit(self, dt: float | None = None) -> int:
        """Let every emitter release what it owes for `dt` seconds (the step's emit stage), without stepping.

        Returns:
            The number of bodies released.
        """
        return self._emit(self.dt if dt is None else validate.positive(dt, "dt"))

    def _emit(self, dt: float) -> int:
        """The emit stage for a `dt` already checked (`step` has; `emit` checks it)."""
        count = 0
        for emitter in self.emitters:
            released = emitter.release(self.bodies, dt, self.meshes)
            if released is not None:
                count += len(self._add_bodies(**released))
        return count

    def collide(self, dt: float | None = None) -> int:
        """Find contacts for the current state without stepping (broad + narrow phase only).

        Contacts within the speculative distance of one step of `dt` are included, as in `step`.

        Returns:
            The number of contacts; read them with `contact_point`, `contact_normal`, ...
        """
        dt = self.dt if dt is None else validate.positive(dt, "dt")
        pairs = self.broadphase.find_pairs(self.bodies, dt)
        self._k.narrowphase.collide(self.bodies, pairs, self.contacts, dt, self.hulls, self.meshes)
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
        duration = validate.positive(duration, "duration")
        limits.check_steps("duration", duration, self.dt)  # no run of 10^12 steps that never ends
        steps = int(round(duration / self.dt))
        validate.callable_or_none(callback, "callback")
        for _ in range(steps):
            self.step()
            if callback is not None:
                callback(self)
        self.check_finite()  # (each step checks the state it starts from: this is the last one's result)
        return steps

    def check_finite(self) -> None:
        """Raise `SimulationError`, naming the body or cloth particle, if a state is not finite.

        Every step checks the state it starts from; code that steps and then saves, records or exports
        what the last step left (as `run` and the command line do) calls this first, so that a run
        that diverged in its last step is not saved as if it had not.
        """
        self._validate()
        if self._cloth is not None:
            self._cloth.check_finite(self.time, self.step_count)

    def _validate(self) -> None:
        n = self.bodies.count
        if n == 0:
            return
        arrays = self.bodies.arrays
        # a sum is finite when every value is (one pass, no temporary); if not, look closer
        if n <= VALIDATE_SUM_BODIES and self.device == "cpu":
            k = 3 * n
            x, v, w = self._finite_values(arrays)
            if math.isfinite(sum(x[:k]) + sum(v[:k]) + sum(w[:k])):
                return
        for name in _CHECKED_FINITE:
            state = host_view(arrays[name])[:n]
            if not math.isfinite(np.add.reduce(state, axis=None)) and not np.isfinite(state).all():
                bad = int(self.bodies.numpy("body_id")[np.nonzero(~np.isfinite(state).all(axis=1))[0][0]])
                raise SimulationError(
                    f"{name} of body {bad} is not finite at t = {self.time:.6g} s "
                    f"(step {self.step_count}); the simulation diverged or was given NaN"
                )

    def _finite_values(self, arrays: dict) -> tuple:
        """The checked state's values (`host_values`), kept while the arrays are the same ones (looking
        them up afresh took 1.7 of a one-sphere step's ~60 us)."""
        held = self._finite_held
        x, v, w = arrays["body_position"], arrays["body_velocity"], arrays["body_angular_velocity"]
        if held is None or held[0] is not x or held[1] is not v or held[2] is not w:
            held = self._finite_held = (x, v, w, (host_values(x), host_values(v), host_values(w)))
        return held[3]

    # ------------------------------------------------------------------ read-only views
    #
    # Every view is read afresh on each access: a read-only copy of that moment's state, one
    # row per body id. An array kept from an earlier access is a snapshot: it never changes
    # (not when the world steps, grows or reorders its rows); read the property again.

    def _view(self, name: str) -> np.ndarray:
        """A read-only copy of one body array, rows in id order; NaN (or -1) in the rows of removed ids."""
        values = self.bodies.numpy(name)
        slot = self._slot_of_id
        if slot is None:
            return readonly(values.copy())
        if not self._free_ids:
            return readonly(values[slot])
        out = np.full((len(slot),) + values.shape[1:], -1 if values.dtype.kind in "iu" else np.nan, values.dtype)
        live = slot >= 0
        out[live] = values[slot[live]]
        return readonly(out)

    def body_values(self, name: str) -> np.ndarray:
        """Any declared body array (`tumble.model.BODY_FIELDS`) by name, as the views give it: a
        read-only copy, one row per body id (`body_values("body_mass")` is `body_mass`)."""
        if name not in BODY_FIELD:
            raise ValueError(f"no body array {name!r}; the declared ones are {', '.join(BODY_FIELD)}")
        return self._view(name)

    @property
    def body_count(self) -> int:
        """Number of body ids, planes included: the rows of every per-body view.

        Without removals this is the number of bodies; see `remove_bodies` and `body_alive`.
        """
        return self._id_count

    @property
    def contact_count(self) -> int:
        """Number of contact points found by the last step (speculative ones included)."""
        return self.contacts.count

    body_shape = BodyView("body_shape")
    body_kind = BodyView("body_kind")
    body_radius = BodyView("body_radius")
    body_geometry = BodyView("body_geometry")
    body_half_extents = BodyView("body_half_extents")
    body_mass = BodyView("body_mass")
    body_inv_mass = BodyView("body_inv_mass")
    body_restitution = BodyView("body_restitution")
    body_friction = BodyView("body_friction")
    body_position = BodyView("body_position")
    body_orientation = BodyView("body_orientation")
    body_velocity = BodyView("body_velocity")
    body_angular_velocity = BodyView("body_angular_velocity")

    joint_count = property(lambda self: self.joints.count, doc="Number of joints, broken ones included.")
    joint_force = property(
        lambda self: self.joints.view("joint_force"),
        doc="Force of each joint on its body b over the last substep, world [N], shape (j, 3).",
    )
    joint_torque = property(
        lambda self: self.joints.view("joint_torque"),
        doc="Torque of each joint on its body b, world [N m], shape (j, 3).",
    )
    joint_error = property(
        lambda self: readonly(self._k.joints.joint_error(self.joints, self.bodies)),
        doc="Position error (drift) of each joint [m], shape (j,).",
    )
    joint_broken = property(
        lambda self: readonly(self.joints.numpy("joint_enabled") == 0),
        doc="Whether each joint has broken, shape (j,), bool.",
    )

    @property
    def body_plane_normal(self) -> np.ndarray:
        """Unit normals of plane bodies (the body's local +z in world), shape (n, 3); zero for non-planes."""
        q = self.body_orientation
        x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
        normal = np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)
        return np.where((self.body_shape == ShapeType.PLANE)[:, None], normal, 0.0)

    @property
    def body_inertia_world(self) -> np.ndarray:
        """World-frame inertia tensors [kg m^2], shape (n, 3, 3) (zero for static and kinematic bodies)."""
        return inertia_world(self._view("body_inv_inertia"), self.body_orientation)

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
            inertia = inertia_world(self.bodies.numpy("body_inv_inertia"), self.bodies.numpy("body_orientation"))
            energy += 0.5 * float(np.einsum("ni,nij,nj->", w, inertia, w))
        if self._cloth is not None:
            energy += self._cloth.kinetic_energy()
        return energy

    def potential_energy(self) -> float:
        """Gravitational potential energy of bodies (and cloth) relative to the origin [J]: -m g . x."""
        m = self.bodies.numpy("body_mass")
        energy = -float(np.sum(m * (self.bodies.numpy("body_position") @ self.gravity)))
        if self._cloth is not None:
            energy += self._cloth.potential_energy(self.gravity)
        return energy

    def momentum(self) -> np.ndarray:
        """Total linear momentum of bodies [kg m/s], shape (3,)."""
        return np.sum(self.bodies.numpy("body_mass")[:, None] * self.bodies.numpy("body_velocity"), axis=0)

    def snapshot(self) -> Snapshot:
        """The whole simulation state now, to `restore` later or write with `tumble.save_snapshot`.

        It holds every body row (emitted ones included), contacts and joints with their warm-start
        impulses, cloth particles, emitter counters, random generators and the clock. Restoring it
        and stepping repeats this run bit for bit (docs/design.md#snapshots).
        """
        return snapshot.take(self)

    def restore(self, state: Snapshot) -> None:
        """Put back a state taken by `snapshot` from this world, or from one built the same way.

        Raises:
            tumble.snapshot.SnapshotError: the snapshot comes from a different kind of world (other
                stages, emitters or cloth, or convex or mesh shapes added since it was taken); nothing
                is changed then.
        """
        if not isinstance(state, Snapshot):
            raise TypeError(f"restore takes a Snapshot (from world.snapshot()), got {type(state).__name__}")
        snapshot.restore(self, state)
        self._keep_issued_generations()
        self.broadphase.bodies_changed()  # (it searches afresh: its grid and kept list are not in a snapshot)
        self.bodies.sync()  # the solver's scratch rows, which snapshots leave out, to the restored capacity
        self._launch_sizes = None  # derived from the arrays that the restore replaced

    def _keep_issued_generations(self) -> None:
        """After a restore: the generations handed out stay counted, and the restored ones too (the
        snapshot may come from another world built the same way), so no id's next handle repeats one."""
        generation, issued = self._body_generation, self._issued_generation
        n = max(len(generation), len(issued))
        high = np.full(n, -1, dtype=np.int64)
        high[: len(issued)] = issued
        high[: len(generation)] = np.maximum(high[: len(generation)], generation)
        self._issued_generation = high  # (`_new_ids` grows the restored table when it needs to)

    def state_hash(self) -> str:
        """SHA-256 of the state arrays, to check determinism bit for bit."""
        import hashlib

        digest = hashlib.sha256()
        for name in ("body_position", "body_orientation", "body_velocity", "body_angular_velocity"):
            digest.update(np.ascontiguousarray(self._view(name)).tobytes())
        if self._cloth is not None:
            digest.update(np.ascontiguousarray(self._cloth.particle_position_numpy()).tobytes())
        return digest.hexdigest()


def _step_length(dt) -> float:
    """A step's length [s] as `World.dt`, `step(dt)` and `set_kinematic_target(dt=)` take it: in
    [`limits.MIN_DT`, `limits.MAX_DT`] (a step(0.5) was taken where dt = 0.5 was refused; a step of
    5e-324 s raised ZeroDivisionError). `emit(dt)` and `collide(dt)`, which step nothing, take any
    positive length."""
    return validate.number(dt, "dt", low=limits.MIN_DT, high=limits.MAX_DT)


class _Laps:
    """The clock of a step's stages: `start()` when the step starts, then `lap(stage)` after each
    stage adds the wall time since the last lap to `world.profile[stage]`.

    One clock read and one addition a stage: a `with` block a stage (a context manager's enter and
    exit) cost 1.2 us against 0.4, and a step has seven stages or more, of a small world's ~70 us.
    On other devices kernels run asynchronously, so each lap waits for them first.
    """

    __slots__ = ("world", "device", "mark")

    def __init__(self, world: World, device: str):
        self.world = world
        self.device = None if device == "cpu" else device
        self.mark = 0.0

    def start(self) -> None:
        self.mark = time.perf_counter()

    def __call__(self, stage: str) -> None:
        if self.device is not None:
            wp.synchronize_device(self.device)
        now = time.perf_counter()
        profile = self.world.profile  # (read afresh: a user may give the world a new dict)
        profile[stage] = profile.get(stage, 0.0) + now - self.mark
        self.mark = now


def _arrays_of(*owners) -> list:
    """The Warp arrays some objects hold: their attributes and, for an ArraySet, its named arrays."""
    return [
        a
        for owner in owners
        for a in (*(v for v in vars(owner).values() if isinstance(v, wp.array)), *getattr(owner, "arrays", {}).values())
    ]
