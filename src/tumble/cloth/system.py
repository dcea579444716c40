"""ClothSystem: every cloth of a world, as flat particle, spring and triangle arrays.

`World.step` calls the cloth's three stages by name, handing each what it reads: `begin_step`
once at the start of the step's substeps (the step's length and substeps, gravity, clock and the
body arrays), `substep` once per world substep after the rigid bodies' positions were integrated
and relaxed (the body arrays, hulls and meshes it collides with), and `end_step` once after the
last substep. The cloth keeps no reference to the world; its data are the world's parts
(`ClothModel`, `ClothState`, `ClothControl`: `world.model.cloth`, `world.state.cloth`,
`world.control.cloth`), its particle arrays declared once in `PARTICLE_FIELDS` and stepped as one
`RowGroup` with the stage's scratch rows, its topology declared in the tables of `arrays`. One
cloth substep runs these stages, each a plain function over the arrays as the kernels take them
(the structs of `arrays`, `ClothStructs`; see `springs`, `wind` and `collide`):

1. forces: springs (structural, shear, bend) and, with wind set, drag and lift per triangle;
2. integrate: semi-implicit Euler; pinned particles move towards their targets;
3. stretch limit: tethers to the pins, then Provot's correction of structural springs stretched
   beyond (1 + max_stretch) l0;
4. self-collision: listed particle pairs closer than their thickness are pushed apart (the
   list comes from a spatial hash and is rebuilt at a step start when particles may have
   moved past its margin), then the stretch limit is checked again;
5. bodies: particles are pushed out of planes, spheres and boxes, with friction, and the bodies
   receive the opposite impulse; what the taut cloth takes without moving goes on to the pins;
   spheres small enough to pass between particles are kept off the triangles; steps 3-5 repeat
   `contact_iterations` times while bodies are near, and then the stretch limit runs once more,
   so the cloth ends each substep within its limit; a particle that this leaves inside a dynamic
   body's surface moves that body out and stops it (`collide.hold_bodies`);
6. velocities: v = (x - x_prev) / h, so every position correction also corrects the velocity.

The cloth keeps its own substep: explicit springs are stable only for h^2 k / m small, so each
world step is split into the fewest equal cloth substeps that keep the stiffest spring on its
lightest particle stable (see `springs.stable_substep` and `ClothSystem.substeps_for`); each
runs during the world substep in which it ends, so bodies and cloth stay in step. While a dynamic
body can reach the cloth, it takes at least one substep per world substep, rising to that count by
doubling a step from `RAMP_STEPS` steps before the body can arrive. Soft springs
with the stretch limit look like stiff cloth at a fraction of the cost: that is Provot's point.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import warp as wp

from .. import limits, validate
from ..errors import HandleError, SimulationError
from ..launch import LaunchCache
from ..model import Role, body_arrays, fields_of
from ..real import float_t, vec3
from ..shapes import ShapeType
from ..state import ArraySet, BodyId, ClothId, RowGroup, cast, host_view, numpy_dtype, readonly
from ..structs import cached_struct, fill_struct
from . import attach, collide, grid, springs
from .arrays import PARTICLE_FIELDS, TOPOLOGY, Limits, Particles, Springs, Stretch, Structural, Tethers
from .attach import BodyPins
from .wind import AIR_DENSITY, MODE_FIELDS, Modes, Wind, accumulate_air_forces, sample_wind

if TYPE_CHECKING:
    from ..solver.joints import JointSet

#: default spring stiffness [N/m] per kind; a square grid's sheet stiffness equals ks, at any resolution
DEFAULT_STIFFNESS = {"structural": 12.0, "shear": 1.2, "bend": 0.3}
#: default spring damping [N s/m] per kind
DEFAULT_DAMPING = {"structural": 0.002, "shear": 0.0005, "bend": 0.0001}
#: default areal density [kg/m^2] when neither mass nor areal_density is given (light cotton)
DEFAULT_AREAL_DENSITY = 0.2


class ClothStructs(NamedTuple):
    """The cloth's arrays as the kernels take them (the structs of `arrays`), built once per set of arrays."""

    particles: Any  # Particles: every particle array
    springs: Any  # Springs
    structural: Any  # Structural: the structural springs
    stretch: Any  # Stretch: the springs the stretch limit holds
    limits: Any  # Limits: each particle's limited springs
    tethers: Any  # Tethers


@dataclass(frozen=True)
class Cloth:
    """Where one cloth lives in the flat arrays.

    Attributes:
        index: creation order.
        particle_start: first particle; the cloth's particles are [start, start + nx * ny).
        nx, ny: resolution.
        size: (width, height) [m].
        triangle_start: first triangle row.
        triangle_count: 2 (nx - 1) (ny - 1).
        max_stretch: strain limit of its structural springs and tethers (None: unlimited).
    """

    index: int
    particle_start: int
    nx: int
    ny: int
    size: tuple[float, float]
    triangle_start: int
    triangle_count: int
    max_stretch: float | None = 0.1

    @property
    def particle_count(self) -> int:
        """nx * ny."""
        return self.nx * self.ny

    def particle(self, i: int, j: int) -> int:
        """Global particle index of grid point (i, j)."""
        return self.particle_start + j * self.nx + i


def _particle_set(role: Role, device: str, arrays: dict[str, wp.array]) -> ArraySet:
    """The particle rows of `role` (sized exactly to the particles: kernels run over whole arrays)."""
    return ArraySet(fields_of(PARTICLE_FIELDS, role), device=device, capacity=1, arrays=arrays)


class ClothModel:
    """The cloth's part of the world's Model (`world.model.cloth`): what does not change while stepping.

    Attributes:
        particles: the model rows of `PARTICLE_FIELDS` (masses, inverse masses: 0 = pinned,
            thickness, friction, grid place, rest shape, tethers).
        cloths: where each cloth lives in the particle rows (`Cloth`), in creation order.
        topology: name -> Warp array, the arrays of `arrays.TOPOLOGY`: springs (`spring_ids` (m, 2)
            int32, `spring_rest_length`, `spring_stiffness`, `spring_damping`), structural springs and
            rest lengths, limited springs and limits (`stretch_ids`, `stretch_limit`), `triangles`
            (T, 3) int32, and what is derived from them and from the pins (`limit_*` per particle,
            `pin_index`, `tether_pin`, `tether_limit`).
        body_pins: pins that follow bodies (cloth/attach.py).
    """

    def __init__(self, device: str, arrays: dict[str, wp.array]):
        self.particles = _particle_set(Role.MODEL, device, arrays)
        self.cloths: list[Cloth] = []
        self.topology: dict[str, wp.array] = {}
        self.body_pins = BodyPins(device)


class ClothState:
    """The cloth's part of the world's State (`world.state.cloth`): what changes while stepping.

    Attributes:
        particles: the state rows of `PARTICLE_FIELDS` (positions, velocities, pin targets).
        body_contacts: per body row, how many particles touched it in the last cloth substep (the
            coupling keeps a body in contact from one substep to the next), int32.
        pairs: the self-collision pair list, a Verlet list of particle pairs, (K, 2) int32, of which
            the first `pair_count` rows are pairs; kept from step to step while the particles stay
            within its margin, so a resumed run separates the same pairs.
        pair_count: the number of pairs in `pairs`.
        pair_margin: margin of the self-collision pair list [m].
        pair_travel: how much closer particles may have come since that list was built [m].
        substeps_last: the cloth substeps of the step under way, or of the last one between steps (0:
            none yet), from which they rise to the world's as a body approaches (`begin_step`).
    """

    def __init__(self, device: str, arrays: dict[str, wp.array]):
        self.particles = _particle_set(Role.STATE, device, arrays)
        self.body_contacts = wp.zeros(16, dtype=wp.int32, device=device)
        self.pairs = collide.pair_buffer(0, device)
        self.pair_count = 0
        self.pair_margin = 0.0
        self.pair_travel = math.inf
        self.substeps_last = 0


class ClothControl:
    """The cloth's part of the world's Control (`world.control.cloth`): this step's inputs.

    Attributes:
        particles: the control rows of `PARTICLE_FIELDS` (user forces during the current step).
        forces: particle -> user force [N] for the next step (`ClothSystem.apply_force`, a viewer drag).
        forces_applied: whether the current step's forces are not all zero (cleared by the next step).
        wind: the wind for the next steps (`world.control.wind`; `World.set_wind` writes it), None: still air.
    """

    def __init__(self, device: str, arrays: dict[str, wp.array]):
        self.particles = _particle_set(Role.CONTROL, device, arrays)
        self.forces: dict[int, np.ndarray] = {}
        self.forces_applied = False
        self.wind: Wind | None = None


#: world steps before a dynamic body can reach the cloth from which its substeps rise to the world's
RAMP_STEPS = 4


class ClothSystem:
    """All cloth of one world: the cloth stage of the step, over the cloth's parts.

    Its parts are the world's: `model` (`world.model.cloth`), `state` (`world.state.cloth`) and
    `control` (`world.control.cloth`), whose particle rows, with the stage's scratch rows, are one
    `RowGroup` (`particles`) over one dict of arrays, as the body rows are.

    Tuning attributes (change at any time):
        stretch_iterations: (min, max) Provot sweeps per substep; sweeps stop after the minimum
            as soon as one finds no structural spring over its limit.
        stretch_relaxation: over-relaxation of the Provot corrections from the third sweep on
            (1 = exact projection; 1.5 converges several times faster on cloth pulled taut
            everywhere, by wind or a hard swing, where plain sweeps can stall above the limit).
            Not used while bodies are near the cloth: there it keeps a hammock and its balls
            from settling (1.8 even let a ball through).
        self_collision: push apart particles closer than their thickness (candidate pairs from a
            spatial hash, rebuilt when particles may have moved past its margin; separated at
            every substep).
        substeps: cloth substeps per world step; None (default) picks the fewest that keep the
            springs stable, at least `min_substeps` (see `substeps_for`), and at least the
            world's substeps in steps where a dynamic body can reach the cloth.
        contact_iterations: passes over stretch limit and body contacts per substep while some
            body is near the cloth (1 pass otherwise).
        strict_limit: contacts never stretch the cloth past its limit: a particle gives way to a
            body only within the slack its limited springs and tethers leave it, and the body is
            pushed out the rest of the way (default False: the default already keeps the limit
            under bodies; strict cloth is rigid where taut, and a box rocks on it for seconds;
            see docs/design.md, "Cloth with bodies").

    Args:
        device: Warp device of the particle arrays.
        world_key: `World.key` of the owning world, to refuse another world's cloth handles (None: any).
        gravity: [m/s^2], shape (3,): what `potential_energy` measures against until a step passes its own.
    """

    # caches of the structs the kernels take, built on first use and again when their arrays change; class
    # defaults, so that a world restored from a snapshot older than them has them too
    _structs: tuple | None = None  # the particle and topology arrays (`_kernel_structs`)
    _near_bodies: tuple | None = None  # the bodies near the cloth (`_near`)
    _modes: tuple | None = None  # the wind's modes (`wind.Modes`)

    def __init__(
        self,
        device: str = "cpu",
        *,
        world_key: int | None = None,
        gravity: Sequence[float] | np.ndarray = (0.0, 0.0, -9.81),
    ):
        self.device = device
        self.world_key = world_key
        self._gravity = np.array(gravity, dtype=np.float64)
        # the parts, and every particle array as one table (model, state, control and the stage's scratch)
        shared: dict[str, wp.array] = {}
        self.model = ClothModel(device, shared)
        self.state = ClothState(device, shared)
        self.control = ClothControl(device, shared)
        self.particles = RowGroup(
            self.model.particles,
            self.state.particles,
            self.control.particles,
            _particle_set(Role.SCRATCH, device, shared),
        )
        self._strain = wp.zeros(1, dtype=float_t, device=device)  # max_strain's scratch
        self.stretch_iterations = (1, 128)
        self.stretch_relaxation = 1.5
        self.self_collision = True
        self.contact_iterations = 2
        self.strict_limit = False
        self.last_stretch_sweeps = 0  # sweeps taken by the last substep (diagnostics)
        self.substeps: int | None = None
        self.min_substeps = 1

        self._stable_h = math.inf
        self._substep_index = 0
        self._cloth_done = 0
        self._cloth_h = 0.0
        self._clock = 0.0
        self._candidates = wp.zeros(0, dtype=wp.int32, device=self.device)
        self._candidates_host = np.zeros(0, dtype=np.int32)
        self._reach = 0.0
        self._contacts_next = wp.zeros(16, dtype=wp.int32, device=self.device)  # this substep's body_contacts
        # per body row: the pushes of a contact pass, applied when it ends (`collide.apply_pushes`)
        self._pushes = tuple(wp.zeros(16, dtype=vec3, device=self.device) for _ in range(4))
        # per body row: the particles on it at a substep's start if it is a first touch (`collide.near_bodies`)
        self._fresh = wp.zeros(16, dtype=wp.int32, device=self.device)
        self._wind_modes: tuple[wp.array, ...] | None = None  # of control.wind, by `wind.MODE_FIELDS`
        self._grid: collide.SelfCollisionGrid | None = None
        self._bodies_near = False  # a dynamic body can reach the cloth this step
        self._features_near = False  # a static mesh or box can reach the cloth this step
        self._edge_owner = wp.zeros(0, dtype=wp.int32, device=self.device)  # collide.edge_owners of the triangles
        self._bodies: tuple | None = None  # this step's body arrays as a Warp struct (model.body_arrays; a cache)
        self._pin_dt = 0.0
        self._cache = LaunchCache()
        self._violated = wp.zeros(1, dtype=wp.int32, device=self.device)

    @property
    def parts(self) -> tuple[ClothModel, ClothState, ClothControl]:
        """The cloth's model, state and control parts (the world's `model.cloth`, `state.cloth`, `control.cloth`)."""
        return self.model, self.state, self.control

    @property
    def cloths(self) -> list[Cloth]:
        """Where each cloth lives in the particle arrays, in creation order (kept in the model part)."""
        return self.model.cloths

    @property
    def body_pins(self) -> BodyPins:
        """Pins that follow bodies (kept in the model part)."""
        return self.model.body_pins

    # ------------------------------------------------------------------ building

    def add_cloth(
        self,
        *,
        size: Sequence[float] = (1.0, 1.0),
        resolution: Sequence[int] = (32, 32),
        position: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
        orientation: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0, 1.0),
        mass: float | None = None,
        areal_density: float | None = None,
        stiffness: float | dict[str, float] | None = None,
        damping: float | dict[str, float] | None = None,
        max_stretch: float | None = 0.1,
        pins: str | Sequence[Sequence[int]] | None = None,
        thickness: float = 0.01,
        friction: float = 0.3,
    ) -> int:
        """Add a rectangular cloth; returns its index (creation order).

        Unrotated, the cloth lies in the xy-plane with normal +z, centred on `position`, with grid
        index i along x and j along y; particle j * nx + i of the cloth sits at grid point (i, j).

        Args:
            size: (width along i, height along j) [m], both > 0.
            resolution: (nx, ny) particles (a 2 x 1 "cloth" is a single spring, handy for tests).
            position: centre [m], shape (3,).
            orientation: rotation of the cloth (x, y, z, w).
            mass: total mass [kg], spread as an even areal density: each particle carries a quarter of
                each grid quad it is a corner of (an edge particle half an inner one's, a corner a
                quarter). Give `mass` or `areal_density`; with neither, the areal density is 0.2 kg/m^2.
            areal_density: [kg/m^2].
            stiffness: spring stiffness ks [N/m], one number for every kind or a mapping with keys
                structural, shear, bend (missing kinds get no springs). Default 12 / 1.2 / 0.3.
            damping: spring damping kd [N s/m], as `stiffness`. Default 0.002 / 0.0005 / 0.0001.
            max_stretch: largest strain of structural springs kept by the stretch limit (0.1 = 10 %);
                None for no limit.
            pins: None, "corners", "top-corners", "top-edge" or a list of [i, j] grid points.
            thickness: distance kept from bodies and between non-neighbouring particles [m], > 0 and at most
                100 times the cloth's larger side.
            friction: Coulomb friction coefficient against bodies (>= 0).

        Raises:
            ValueError: naming the bad argument.
        """
        width, height = (float(v) for v in validate.positive_vector(size, "cloth size", 2))
        size = (width, height)
        nx, ny = validate.integers(resolution, "cloth resolution", 2, low=1)
        if nx * ny < 2:
            raise ValueError(f"cloth resolution must be at least 2 particles, e.g. 2 x 1, got {(nx, ny)!r}")
        if self.particles.count + nx * ny > limits.MAX_PARTICLES_INT32:
            raise limits.LimitError(
                f"cloth resolution: {nx:,} x {ny:,} = {nx * ny:,} particles; cloth indices are int32, which allows "
                f"at most {limits.MAX_PARTICLES_INT32:,} particles in all"
            )
        limits.check_memory("cloth resolution", "particles", nx * ny, limits.BYTES_PER_PARTICLE)
        position = validate.vector(position, "position")
        q = validate.quaternion(orientation, "cloth orientation")
        if mass is not None and areal_density is not None:
            raise ValueError("give the cloth's mass or areal_density, not both")
        if mass is not None:
            total = validate.positive(mass, "mass")
        else:
            density = (
                DEFAULT_AREAL_DENSITY if areal_density is None else validate.positive(areal_density, "areal_density")
            )
            total = density * size[0] * size[1]
        if not validate.mass_properties_usable(total / (nx * ny), []):
            raise ValueError(
                f"cloth mass: {total:g} kg over {nx * ny:,} particles is {total / (nx * ny):g} kg each; the mass or "
                "areal_density and size must give particles whose mass is finite and > 0, with a finite inverse, "
                "in float64"
            )
        ks = grid.per_kind(DEFAULT_STIFFNESS if stiffness is None else stiffness, "stiffness")
        kd = grid.per_kind(DEFAULT_DAMPING if damping is None else damping, "damping")
        if max_stretch is not None:
            max_stretch = validate.number(max_stretch, "max_stretch", low=0.0)
        thickness = validate.positive(thickness, "thickness")
        if thickness > 100.0 * max(size):
            # (1e300 was taken, and the cloth diverged in its first step, "lower its stiffness")
            raise ValueError(
                f"thickness {thickness:g} m is more than 100 times the cloth's size {width:g} x {height:g} m: it is the "
                "distance the cloth keeps from bodies and from itself, a few millimetres for fabric"
            )
        friction = validate.friction(friction)
        pinned = grid.pin_indices(pins, nx, ny)

        # particles
        count = nx * ny
        start = self.particles.count
        x = grid.grid_positions(size, (nx, ny), position, q)
        # an even areal density: each particle carries the area around it (edges half, corners a quarter)
        m = total * grid.grid_area_shares(nx, ny)
        inv_m = 1.0 / m
        inv_m[pinned] = 0.0
        jj, ii = np.divmod(np.arange(count), nx)
        new = {
            "particle_mass": m,
            "particle_inv_mass": inv_m,
            "particle_thickness": np.full(count, thickness),
            "particle_friction": np.full(count, friction),
            "particle_cloth": np.full(count, len(self.cloths), dtype=np.int32),
            "particle_i": ii.astype(np.int32),
            "particle_j": jj.astype(np.int32),
            "particle_rest_position": x,
            "particle_position": x,
            "particle_velocity": np.zeros((count, 3)),
            "particle_pin_target": x,
        }

        # springs: every kind with ks > 0 or kd > 0; structural ones also get the stretch limit
        # (border springs at half strength, as the border particles carry half the mass)
        kinds = grid.grid_springs(nx, ny)
        shares = grid.grid_spring_shares(nx, ny)
        ids, rest, stiff, damp = [], [], [], []
        for kind, pairs in kinds.items():
            if ks[kind] == 0.0 and kd[kind] == 0.0:
                continue
            length = np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1)
            ids.append(pairs + start)
            rest.append(length)
            stiff.append(ks[kind] * shares[kind])
            damp.append(kd[kind] * shares[kind])
        structural = kinds["structural"]
        structural_rest = np.linalg.norm(x[structural[:, 1]] - x[structural[:, 0]], axis=1)
        limited = structural if max_stretch is not None else structural[:0]
        triangles = grid.grid_triangles(nx, ny) + start

        rows = {
            **new,
            "spring_ids": np.concatenate(ids) if ids else np.zeros((0, 2), np.int32),
            "spring_rest_length": np.concatenate(rest) if rest else np.zeros(0),
            "spring_stiffness": np.concatenate(stiff) if stiff else np.zeros(0),
            "spring_damping": np.concatenate(damp) if damp else np.zeros(0),
            "structural_ids": structural + start,
            "structural_rest_length": structural_rest,
            "stretch_ids": limited + start,
            "stretch_limit": (1.0 + (max_stretch or 0.0)) * structural_rest[: len(limited)],
            "triangles": triangles,
        }
        # a value the world's precision cannot hold (a stiffness of 1e39 in float32) is refused by name
        # here, before anything of the cloth is added
        floats = numpy_dtype(float_t)[0]
        for name, values in rows.items():
            if values.dtype.kind == "f":
                cast(values, floats, name)

        cloth = Cloth(
            index=len(self.cloths),
            particle_start=start,
            nx=nx,
            ny=ny,
            size=size,
            triangle_start=self.triangle_count,
            triangle_count=len(triangles),
            max_stretch=max_stretch,
        )
        self.cloths.append(cloth)
        self._append(rows)
        return cloth.index

    def set_wind(
        self,
        *,
        velocity: Sequence[float] = (0.0, 0.0, 0.0),
        turbulence: float = 0.0,
        scale: float = 1.0,
        seed: int = 0,
        drag: float = 1.2,
        lift: float = 0.3,
        air_density: float = AIR_DENSITY,
    ) -> None:
        """Set the wind acting on every cloth; see `tumble.cloth.wind.Wind` for the model.

        Args:
            velocity: mean wind velocity [m/s], shape (3,).
            turbulence: RMS strength of the turbulent part per component [m/s].
            scale: size of the gusts [m].
            seed: seed of the turbulence field.
            drag, lift: aerodynamic coefficients of a cloth face.
            air_density: [kg/m^3].
        """
        self.control.wind = Wind(
            velocity=validate.vector(velocity, "velocity"),
            turbulence=validate.number(turbulence, "turbulence", low=0.0),
            scale=validate.positive(scale, "scale"),
            seed=validate.integer(seed, "seed", low=0),
            drag=validate.number(drag, "drag", low=0.0),
            lift=validate.number(lift, "lift", low=0.0),
            air_density=validate.number(air_density, "air_density", low=0.0),
        )
        # the turbulence modes on the device: the stage's, derived from the wind
        modes = zip(MODE_FIELDS.values(), self.control.wind.mode_arrays(), strict=True)
        self._wind_modes = tuple(wp.array(values, dtype=dtype, device=self.device) for dtype, values in modes)

    @property
    def wind(self) -> Wind | None:
        """The wind acting on every cloth (kept in the control part: `world.control.wind`), None for still air."""
        return self.control.wind

    def _append(self, rows: dict[str, np.ndarray]) -> None:
        """Concatenate a new cloth's rows onto the host description and the device state; re-upload."""
        # the live rows (positions, pins, ...) and topology, with the new cloth's after them
        n = self.particles.count
        host = {name: values if not n else np.concatenate([self._host(name), values]) for name, values in rows.items()}
        p = len(host["particle_mass"])
        # every particle row anew, at exactly p rows (kernels run over whole arrays)
        for part in self.particles.parts:
            rows_of: dict[str, np.ndarray] = {}
            for name, dtype in part.fields.items():
                np_type, tail = numpy_dtype(dtype)
                rows_of[name] = (
                    np.ascontiguousarray(host[name], np_type) if name in host else np.zeros((p, *tail), np_type)
                )
            part.load(rows_of, count=p, capacity=p)
        for name in TOPOLOGY:
            if name in host:  # the rows a cloth gives; the rest is derived from them below
                self._put(name, host[name])
        self._strain = wp.zeros(len(host["structural_ids"]), dtype=float_t, device=self.device)
        self._build_limits()
        self._edge_owner = wp.array(collide.edge_owners(host["triangles"]), dtype=wp.int32, device=self.device)
        self._grid = collide.SelfCollisionGrid(self.device)
        self.state.pairs = collide.pair_buffer(p, self.device)
        self.state.pair_count = 0
        self.state.pair_travel = math.inf
        self._reach = float(host["particle_thickness"].max())
        self._update_pins()

    def _put(self, name: str, values: np.ndarray) -> None:
        """The topology array `name` (of `arrays.TOPOLOGY`) anew, holding `values`."""
        row: Any = TOPOLOGY[name]
        dtype = row.dtype if isinstance(row, wp.array) else row  # an array type: rows of int32 pairs or triples
        self.model.topology[name] = wp.array(
            np.ascontiguousarray(values, numpy_dtype(dtype)[0]), dtype=dtype, device=self.device
        )

    def _build_limits(self) -> None:
        """Per particle: its limited springs (other end and limit, `arrays.Limits`)."""
        dev, p = self.device, self.particles.count
        ids, limit = self._host("stretch_ids"), self._host("stretch_limit")
        ends = np.concatenate([ids[:, 0], ids[:, 1]]).astype(np.int64)
        order = np.argsort(ends, kind="stable")
        count = np.bincount(ends, minlength=p).astype(np.int32)
        first = (np.cumsum(count) - count).astype(np.int32)
        other = np.concatenate([ids[:, 1], ids[:, 0]])[order].astype(np.int32)
        length = np.concatenate([limit, limit])[order]
        self._put("limit_first", first)
        self._put("limit_count", count)
        self._put("limit_other", np.resize(other, max(1, len(other))))
        self._put("limit_length", np.resize(length, max(1, len(length))))
        self._pin_impulse = wp.zeros(1, dtype=vec3, device=dev)

    def _update_pins(self) -> None:
        """After pins changed: rebuild the tethers to the pins and the stable substep."""
        self.state.pair_travel = math.inf
        inv_m = self.particles.numpy("particle_inv_mass")
        rest = self._host("particle_rest_position")
        parts, pins, limits = [], [], []
        for cloth in self.cloths:
            if cloth.max_stretch is None:
                continue
            sl = slice(cloth.particle_start, cloth.particle_start + cloth.particle_count)
            pinned = np.nonzero(inv_m[sl] == 0.0)[0]
            particle, pin, limit = grid.tethers(rest[sl], pinned, cloth.max_stretch)
            parts.append(particle + cloth.particle_start)
            pins.append(pin + cloth.particle_start)
            limits.append(limit)

        def cat(xs, dtype):
            return np.concatenate(xs).astype(dtype) if xs else np.zeros(0, dtype)

        self._put("pin_index", np.flatnonzero(inv_m == 0.0))
        self._put("tether_pin", cat(pins, np.int32))
        self._put("tether_limit", cat(limits, np.float64))
        # per particle: its first tether and how many (tethers are sorted by particle)
        owner = cat(parts, np.int32)
        p = self.particles.count
        count = np.bincount(owner, minlength=p).astype(np.int32)
        first = (np.cumsum(count) - count).astype(np.int32)
        self.particles.write("particle_tether_first", slice(0, p), first)
        self.particles.write("particle_tether_count", slice(0, p), count)
        self._cache.clear()
        self._update_stable_step()

    def _update_stable_step(self) -> None:
        """Largest stable substep for the current springs, masses and pins."""
        p = self.particles.count
        ids = self._host("spring_ids")
        stiffness = np.zeros(p)
        damping = np.zeros(p)
        for end in (0, 1):
            np.add.at(stiffness, ids[:, end], self._host("spring_stiffness"))
            np.add.at(damping, ids[:, end], self._host("spring_damping"))
        self._stable_h = springs.stable_substep(
            stiffness, damping, self.particles.arrays["particle_inv_mass"].numpy()[:p]
        )

    # ------------------------------------------------------------------ stepping

    def substeps_for(self, dt: float) -> int:
        """Number of cloth substeps per world step of `dt` seconds.

        `substeps` if set, else the fewest that keep the springs stable (at least `min_substeps`).

        Raises:
            LimitError: beyond `limits.MAX_CLOTH_SUBSTEPS` (springs far too stiff or damped for the step).
        """
        if self.substeps is not None:
            n: float = max(1, int(self.substeps))
            key = f"cloth substeps: {n:,} is too large"
        else:
            if not math.isfinite(self._stable_h):
                n = 1
            elif self._stable_h > 0.0:
                n = math.ceil(dt / self._stable_h - 1e-9)
            else:  # the stable substep underflowed
                n = math.inf
            n = max(1, int(self.min_substeps), n)
            shown = f"{n:,}" if n < 1e15 else f"{n:.3g}"
            key = f"cloth stiffness and damping: springs this stiff need {shown} cloth substeps in a step of {dt:g} s"
        if n > limits.MAX_CLOTH_SUBSTEPS:
            raise limits.LimitError(
                f"{key}; the limit is {limits.MAX_CLOTH_SUBSTEPS:,} (lower the stiffness, damping or dt; "
                "docs/scenes.md#limits)"
            )
        return int(n)

    def check_finite(self, time: float, step: int) -> float:
        """The particles' largest speed [m/s]; SimulationError naming the particle if a velocity is not
        finite (at simulated time `time`, step `step`, for the message): the cloth diverged."""
        p = self.particles.count
        v = self.particles.arrays["particle_velocity"].numpy()[:p]
        with np.errstate(over="ignore", invalid="ignore"):
            speed2 = np.einsum("ij,ij->i", v, v)
        speed = float(np.sqrt(speed2.max())) if p else 0.0
        if not math.isfinite(speed):
            # report where the cloth blew up rather than let NaNs spread into the bodies
            bad = int(np.nonzero(~np.isfinite(speed2))[0][0])
            cloth = next(c for c in self.cloths if c.particle_start <= bad < c.particle_start + c.particle_count)
            j, i = divmod(bad - cloth.particle_start, cloth.nx)
            # a body light at its pins overshoots whatever the substeps (docs/design.md, "Cloth with bodies")
            remedy = "lower its stiffness or set world.cloth.substeps higher"
            if self.control.wind is not None:
                remedy += ", or check the wind's speed and turbulence"
            if self.body_pins.count:
                remedy += ", and spread the load of bodies pinned to it over more pins"
            raise SimulationError(
                f"velocity of cloth {cloth.index} particle {bad} (grid point i = {i}, j = {j}) is not finite at "
                f"t = {time:.6g} s (step {step}); the cloth diverged: {remedy}"
            )
        return speed

    def substep(self, h: float, *, bodies, hulls, meshes) -> None:
        """Stage, once per world substep of `h` seconds: the cloth substeps that end in it, coupled to the bodies.

        The cloth keeps its own clock: it takes `substeps_for(dt)` equal substeps per world step
        (from `begin_step`), each one run in the world substep during which it ends. With the
        world at 8 substeps and a cloth stable at 4, every other world substep runs one cloth
        substep twice as long; a cloth that needs more runs several per world substep.

        Args:
            h: the world's substep [s].
            bodies: the world's body `ArraySet` (read; dynamic bodies receive the cloth's pushes and pulls).
            hulls: the world's `Hulls` struct; meshes: its static meshes (`MeshSet.struct()`).
        """
        if self.particles.count == 0:
            return
        self._clock += h
        hc = self._cloth_h
        # run the cloth substeps that end within this world substep (rounding: 1e-9 of a substep)
        while self._cloth_done < self.state.substeps_last and self._clock >= (self._cloth_done + 1 - 1e-9) * hc:
            self._cloth_substep(hc, bodies, hulls, meshes)
            self._cloth_done += 1

    def end_step(self, *, bodies, hulls, meshes) -> None:
        """Stage, once after the world step's last substep: any cloth substep that rounding left is run,
        so that every step runs exactly `substeps_for(dt)` of them (arguments as `substep`)."""
        if self.particles.count == 0:
            return
        while self._cloth_done < self.state.substeps_last:
            self._cloth_substep(self._cloth_h, bodies, hulls, meshes)
            self._cloth_done += 1

    def _kernel_structs(self) -> ClothStructs:
        """The particle and topology arrays as the kernels take them, built again only when some array was
        (a new cloth, new pins, a restored snapshot)."""
        held = [*self.particles.arrays.values(), *self.model.topology.values()]
        cached = self._structs
        if cached is None or len(cached[1]) != len(held) or not all(a is b for a, b in zip(cached[1], held)):
            a, top = self.particles.arrays, self.model.topology
            built = ClothStructs(
                fill_struct(Particles, a, "particle_"),
                fill_struct(Springs, top, "spring_"),
                fill_struct(Structural, top, "structural_"),
                fill_struct(Stretch, top, "stretch_"),
                fill_struct(Limits, top, "limit_"),
                fill_struct(Tethers, top, "tether_"),
            )
            cached = self._structs = (built, held)
        return cached[0]

    def _cloth_substep(self, hi: float, bodies, hulls, meshes) -> None:
        """One cloth substep of `hi` seconds: forces, integration, constraints, collisions, velocities."""
        gravity = self._gravity
        top = self.model.topology
        s = self._kernel_structs()
        particles = s.particles
        total = self.state.substeps_last
        cache = self._cache
        # forces: springs, then air on every triangle
        springs.accumulate_spring_forces(particles, s.springs, cache=cache)
        if self.wind is not None:
            w = self.wind
            accumulate_air_forces(particles, top["triangles"], w.drag, w.lift, w.air_density, cache=cache)

        self.body_pins.react(particles, bodies, gravity, hi)  # the pull on body pins moves their bodies
        attach.sum_pin_load(top["pin_index"], particles.force, particles, gravity, self._pin_impulse, hi, cache=cache)

        # integrate: semi-implicit Euler; pins cover the rest of the way to their targets evenly
        remaining = max(1, total - self._substep_index)
        springs.integrate(particles, gravity, hi, 1.0 / remaining, cache=cache)
        self._substep_index += 1
        self.body_pins.follow(particles, bodies)  # body pins sit on their body points

        # constraints, solved together by repeating them while bodies are near (position-based
        # dynamics): a stretch limit and a body contact solved once each would fight over the
        # substeps and pump energy into a ball resting in a hammock (with `strict_limit` the
        # contacts never stretch the cloth past its limit: see docs/design.md, "Cloth with bodies")
        touching = self._candidates.shape[0] > 0
        near = self._near(hi, hulls, meshes) if touching else None
        particles.pin_load.zero_()
        # pins on bodies the stretch limit moves (`Carried`): they give way to the pushes of other bodies
        carried = self.body_pins.begin_constraints(particles, self.particles.count, bodies)
        if near is not None:
            # a body's first touch: the particles on it now share its push, which waits for the pass's end
            self._fresh.zero_()
            collide.count_first_touches(s.particles, near, cache=self._cache)
        for _ in range(self.contact_iterations if touching else 1):
            # stretch limit: tethers to the pins, then Provot on structural springs, at most (1 + max_stretch) l0
            self.last_stretch_sweeps = self._limit(s, carried, 1.0 if touching else self.stretch_relaxation)

            # self-collision: pairs listed at the start of the step pushed to their thickness; then
            # the stretch limit again, only if those pushes over-stretched a spring
            if self.self_collision and self.state.pair_count:
                collide.separate_pairs(particles, self.state.pairs, self.state.pair_count, cache=cache)
                self._limit(s, carried, 1.0, tethers=False, min_iterations=0)

            # bodies: out of planes, spheres, boxes, capsules, hulls and meshes, with friction;
            # bodies get the reaction
            if near is not None:
                self._collide_bodies(s, near, carried)
                # bodies pushed some particles into the layer above: part them, then push out of
                # the bodies once more (only the part of a fold that touches a body settles here)
                if self.self_collision and self.state.pair_count:
                    collide.separate_pairs(particles, self.state.pairs, self.state.pair_count, cache=cache)
                    self._collide_bodies(s, near, carried)

        # the triangles against the sharp features of static meshes and boxes, once the particles
        # are settled against the faces (once a substep: their cost is one BVH query a triangle)
        if near is not None and self._features_near:
            collide.collide_features(particles, top["triangles"], self._edge_owner, near, cache=cache)

        # with a body near, the stretch limit has the last word: the cloth ends every substep within
        # its limit; what it takes back from the contacts stays inside the particles' thickness and
        # is pushed out again next substep (the body's push that the taut cloth held went on to the
        # pins in `collide`). Static bodies too: a cloth wrapping a cube's top corners, where no
        # inextensible sheet fits, was left 23 % stretched as it landed and 14 % at rest
        if near is not None:
            self._limit(s, carried, 1.0)
            # what the limit left inside a body's surface the cloth cannot give: the body is moved out and
            # stopped (a body much heavier than the cloth fell through it, `collide.hold_bodies`)
            collide.hold_bodies(s.particles, s.tethers, near, carried, cache=self._cache)

        # the pins' reactions: bodies move as the stretch limit's corrections at their pins moved them,
        # their pins with them, and feel the pull as a velocity change; every pin's load is summed
        self.body_pins.move_bodies(carried, bodies)
        self.body_pins.follow(particles, bodies)
        self.body_pins.react_constraints(particles, bodies, hi)
        attach.sum_pin_load(
            top["pin_index"], particles.pin_load, particles, (0.0, 0.0, 0.0), self._pin_impulse, 1.0 / hi, cache=cache
        )

        # each body and its pins take one rigid motion; then velocities from the corrected positions,
        # the pins' from their bodies
        self.body_pins.weld(particles, bodies)
        springs.update_velocities(particles, hi, cache=cache)
        self.body_pins.ride(particles, bodies)

    def _limit(
        self,
        s: ClothStructs,
        carried: attach.Carried,
        relax: float,
        *,
        tethers: bool = True,
        min_iterations: int | None = None,
    ) -> int:
        """The stretch limit: tethers to the pins (unless `tethers` is False), then Provot's sweeps
        (`stretch_iterations`, the minimum replaced by `min_iterations` if given; over-relaxed by
        `relax`); the pins' share goes into `particle_pin_load`, and pins on dynamic bodies give way
        with their bodies (`carried`). Returns the number of sweeps."""
        if tethers:
            springs.limit_tethers(s.particles, s.tethers, carried, cache=self._cache)
        lo_it, hi_it = self.stretch_iterations
        return springs.limit_stretch(
            s.particles,
            s.stretch,
            self._violated,
            carried,
            min_iterations=lo_it if min_iterations is None else min_iterations,
            max_iterations=hi_it,
            relax=relax,
            cache=self._cache,
        )

    def _near(self, hi: float, hulls, meshes) -> collide.Near:
        """The bodies near the cloth as the contact kernels take them (`collide.near_bodies`), built
        again only when what it holds changed: the candidates, the body arrays, the substep."""
        assert self._bodies is not None  # set by begin_step
        counts = (self.state.body_contacts, self._contacts_next)
        shield, pinned = self.body_pins.shielded(self.particles.count, self._host("structural_ids"))
        size = self.state.body_contacts.shape[0]
        if self._fresh.shape[0] != size:  # per body row, as the counts (the pushes zero between passes)
            self._pushes = tuple(wp.zeros(size, dtype=vec3, device=self.device) for _ in range(4))
            self._fresh = wp.zeros(size, dtype=wp.int32, device=self.device)
        held = (self._candidates, self._bodies[0], hulls, meshes, *counts, shield, pinned, *self._pushes, self._fresh)
        settings = (hi, self.strict_limit)
        cached = self._near_bodies
        if cached is None or cached[2] != settings or any(a is not b for a, b in zip(cached[1], held, strict=True)):
            near = collide.near_bodies(
                self._candidates,
                self._bodies[0],
                hulls,
                meshes,
                counts,
                hi,
                shield,
                pinned,
                self._pushes,
                self._fresh,
                strict=self.strict_limit,
            )
            cached = self._near_bodies = (near, held, settings)
        return cached[0]

    def _collide_bodies(self, s: ClothStructs, near: collide.Near, carried: attach.Carried) -> None:
        """Particles, then triangles against small spheres, out of the near bodies; bodies pushed back."""
        self._contacts_next.zero_()
        collide.collide_bodies(s.particles, s.tethers, s.limits, near, carried, cache=self._cache)
        collide.apply_pushes(near, cache=self._cache)  # those of bodies touched first
        triangles = self.model.topology["triangles"]
        collide.catch_small_spheres(s.particles, s.tethers, triangles, near, carried, cache=self._cache)
        # this pass's counts are the next pass's previous ones (copied: the struct keeps its arrays)
        if self.device == "cpu":
            host_view(self.state.body_contacts)[:] = host_view(self._contacts_next)  # the host views are the arrays
        else:
            wp.copy(self.state.body_contacts, self._contacts_next)

    def begin_step(
        self,
        h: float,
        substeps: int,
        *,
        bodies,
        gravity,
        time: float,
        step: int = 0,
        joints: JointSet | None = None,
    ) -> None:
        """Stage, once at the start of a world step: cloth substeps, user forces, wind, candidate bodies.

        Args:
            h: the world's substep [s]; the step is `substeps` of them.
            substeps: the world's substeps in this step.
            bodies: the world's body `ArraySet` (read: which bodies can reach the cloth this step).
            gravity: [m/s^2], shape (3,), for this step.
            time: the world's clock at the start of the step [s] (the wind's time).
            step: the world's step count (named in errors).
            joints: the world's `JointSet`, if any: the stretch limit leaves the pins of bodies that joints
                hold in place and hands them its pull, as it cannot know what the joints let them do, but
                turns those held about a fixed point or line about it (`BodyPins.hold`).
        """
        if self.particles.count == 0:
            return
        self.body_pins.hold(joints)
        dt = h * max(1, int(substeps))
        a = self.particles.arrays
        self._gravity = np.array(gravity, dtype=np.float64)
        self._bodies = body_arrays(bodies, self._bodies)
        self._substep_index = 0
        self._pin_impulse.zero_()
        self._pin_dt = dt
        self._cloth_done = 0
        self._clock = 0.0
        p = self.particles.count

        # user forces apply during this step only
        if self.control.forces or self.control.forces_applied:
            f = np.zeros((p, 3))
            for i, force in self.control.forces.items():
                f[i] += force
            a["particle_external_force"].assign(f)
            self.control.forces_applied = bool(self.control.forces)
            self.control.forces = {}

        # wind: sample the field at every particle at the start of the step
        wind = self.control.wind
        if wind is not None:
            assert self._wind_modes is not None  # set with the wind
            self._modes = cached_struct(
                Modes, dict(zip(MODE_FIELDS, self._wind_modes, strict=True)), "mode_", self._modes
            )
            sample_wind(self._kernel_structs().particles, wind.velocity, self._modes[0], time, cache=self._cache)

        speed = self.check_finite(time, step)

        # self-collision, a Verlet list: the pairs closer than their thickness + margin; two
        # particles close in by at most 2 v_max dt per step, so the list stays valid until that
        # sum reaches the margin, then it is rebuilt (rarely, once the cloth has settled)
        assert self._grid is not None  # made with the first cloth (_append)
        if self.self_collision:
            self.state.pair_travel += 2.0 * speed * dt
            if self.state.pair_travel >= self.state.pair_margin:
                self.state.pair_margin = min(max(0.25 * self._reach, 2.0 * speed * dt), self._reach)
                self.state.pair_travel = 2.0 * speed * dt
                self.state.pairs, self.state.pair_count = self._grid.find_pairs(
                    self.state.pairs,
                    self._kernel_structs().particles,
                    self._reach,
                    self.state.pair_margin,
                    cache=self._cache,
                )
        else:
            self.state.pair_count = 0
            self.state.pair_travel = math.inf

        # bodies that can reach the cloth during this step
        n_bodies = bodies.count
        candidates = self._candidates_host[:0]
        if n_bodies:
            x = a["particle_position"].numpy()[:p]
            lo, hi = x.min(axis=0), x.max(axis=0)
            reach = self._reach + dt * (speed + 1.0)
            candidates = collide.candidate_bodies(bodies, lo, hi, reach, dt)
        if not np.array_equal(candidates, self._candidates_host):
            self._candidates_host = candidates
            self._candidates = wp.array(candidates, dtype=wp.int32, device=self.device)
        if self.state.body_contacts.shape[0] < n_bodies:
            size = max(16, 2 * n_bodies)
            prev = np.zeros(size, dtype=np.int32)
            prev[: self.state.body_contacts.shape[0]] = self.state.body_contacts.numpy()
            self.state.body_contacts = wp.array(prev, dtype=wp.int32, device=self.device)
            self._contacts_next = wp.zeros(size, dtype=wp.int32, device=self.device)

        # cloth substeps: the springs' stable count; while a dynamic body can reach the cloth, at
        # least the world's, so that a body's push and the stretch limit meet every world substep
        # (the limit's overshoot under a landing body grows with the cloth substep). A body that
        # only holds pins of the cloth (a flag's pole) counts while it touches it. The count rises
        # to the world's by doubling a step, from RAMP_STEPS steps before a body can arrive: switched
        # at once from 1 to 8 while a hammock snapped taut, the cloth's energy rose 0.19 J in a step
        self._bodies_near = bool(len(self._dynamic(candidates, bodies)))
        approaching = self._bodies_near
        if n_bodies and not approaching and self.substeps is None and int(substeps) > self.substeps_for(dt):
            steps = RAMP_STEPS * dt
            soon = collide.candidate_bodies(bodies, lo, hi, self._reach + steps * (speed + 1.0), steps)
            approaching = bool(len(self._dynamic(soon, bodies)))
        shape = bodies.numpy("body_shape")[candidates]
        static_box = (shape == int(ShapeType.BOX)) & (bodies.numpy("body_inv_mass")[candidates] == 0.0)
        self._features_near = bool(np.any((shape == int(ShapeType.MESH)) | static_box))
        total = self.substeps_for(dt)
        if approaching and self.substeps is None and int(substeps) > total:
            last = self.state.substeps_last  # (on the first step, the world's at once)
            total = max(total, min(int(substeps), 2 * last if last else int(substeps)))
        self.state.substeps_last = total  # this step's, the last one's once it is done
        self._cloth_h = dt / total

    def _dynamic(self, rows: np.ndarray, bodies) -> np.ndarray:
        """The dynamic bodies among `rows`, but for those that only hold pins of the cloth and touch it not."""
        near = rows[bodies.numpy("body_inv_mass")[rows] > 0.0] if len(rows) else rows
        if len(near) and self.body_pins.count:
            holder = np.isin(near, self.body_pins.body.numpy()[: self.body_pins.count])
            near = near[~holder | (self.state.body_contacts.numpy()[near] > 0)]
        return near

    def remap_bodies(self, slot: np.ndarray) -> None:
        """The world renumbered its body rows (row i is now `slot[i]`, -1 for a removed body): move
        the last substep's per-body contact counts (the next substep's are zeroed before use)."""
        self.body_pins.remap_bodies(slot)
        n = len(slot)
        size = self.state.body_contacts.shape[0]
        host = np.zeros(max(size, n), dtype=np.int32)
        host[:size] = self.state.body_contacts.numpy()
        kept = slot >= 0  # a removed body (-1) takes its counts with it
        moved = host[:n][kept]
        host[:n] = 0
        host[slot[kept]] = moved
        if len(host) == size:
            self.state.body_contacts.assign(host)
        else:
            self.state.body_contacts = wp.array(host, dtype=wp.int32, device=self.device)
            self._contacts_next = wp.zeros(len(host), dtype=wp.int32, device=self.device)

    # ------------------------------------------------------------------ user interaction

    def apply_force(self, particle: int, force: Sequence[float]) -> None:
        """Apply a force [N] to one particle during the next world step only (e.g. a viewer drag)."""
        i = self._particle(particle)
        f = validate.vector(force, "force")
        self.control.forces[i] = self.control.forces.get(i, np.zeros(3)) + f

    def set_pin_target(self, particle: int, position: Sequence[float]) -> None:
        """Move a pinned particle to `position` [m] by the end of the next world step (pins it if free)."""
        i = self._particle(particle)
        target = validate.vector(position, "position")
        self._write("particle_pin_target", i, target)
        if self.particles.arrays["particle_inv_mass"].numpy()[i] != 0.0:
            self._write("particle_inv_mass", i, 0.0)
            self._update_pins()

    def pin(self, particle: int) -> None:
        """Pin a particle where it is now."""
        i = self._particle(particle)
        self.set_pin_target(i, self.particles.arrays["particle_position"].numpy()[i])
        self._write("particle_velocity", i, np.zeros(3))

    def pin_to_body(self, particles, body: BodyId) -> None:
        """Pin particles (indices) to a body where they are now: they follow it and pull on it (two-way).

        `body` is the `BodyId` its world gave out; the world finds its row (`World.pin_cloth_to_body`).
        """
        if not isinstance(body, BodyId) or body.world_key is None:
            raise TypeError(f"body must be the BodyId its World gave out, got {validate.show(body)}")
        if self.world_key is not None and body.world_key != self.world_key:
            raise HandleError(f"body {int(body)} belongs to another World")
        body.world.pin_cloth_to_body(particles, body)

    def attach_to_body(self, particles, row: int, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Pin particles (indices) to the body in row `row` of the body arrays, now at `position` [m] and
        `orientation` (x, y, z, w), where they are now (the world's side of `pin_to_body`)."""
        idx = np.unique(np.asarray([self._particle(p) for p in np.atleast_1d(particles)], dtype=np.int64))
        x, q = np.asarray(position, dtype=np.float64), np.asarray(orientation, dtype=np.float64)
        offset = self.particles.arrays["particle_position"].numpy()[idx] - x
        # into the body frame: rotate by the conjugate quaternion (x, y, z, w)
        u, w = -q[:3], q[3]
        t = 2.0 * np.cross(u, offset)
        local = offset + w * t + np.cross(u, t)
        for i in idx:
            self.pin(int(i))
        self.body_pins.add(idx, row, local)

    def unpin(self, particle: int) -> None:
        """Release a pinned particle; it keeps its current velocity."""
        i = self._particle(particle)
        self.body_pins.remove([i])
        self._write("particle_inv_mass", i, 1.0 / self._host("particle_mass")[i])
        self._update_pins()

    def _particle(self, particle) -> int:
        i = validate.integer(particle, "particle", low=0)
        if not 0 <= i < self.particles.count:
            raise ValueError(f"particle index {particle!r} out of range 0..{self.particles.count - 1}")
        return i

    def _host(self, name: str) -> np.ndarray:
        """Host view of a particle array or of the topology's `name`, its rows in use (no rows before the first cloth)."""
        if name in self.particles.fields:
            return self.particles.numpy(name)
        top = self.model.topology
        if name not in top:  # no cloth yet
            return np.zeros((0, 3) if name == "triangles" else (0, 2) if name.endswith("_ids") else 0, np.int32)
        return host_view(top[name])

    def _write(self, name: str, index: int, value) -> None:
        self.particles.write(name, index, value)

    def set_state(self, *, position=None, velocity=None) -> None:
        """Overwrite particle positions [m] and/or velocities [m/s], each shape (P, 3).

        Pinned particles also get `position` as their pin target.
        """
        p = self.particles.count
        for name, values in (("particle_position", position), ("particle_velocity", velocity)):
            if values is None:
                continue
            a = validate.array(values, name.split("_")[1], f"finite numbers of shape ({p}, 3)")
            if a.shape != (p, 3) or not np.all(np.isfinite(a)):
                raise ValueError(f"{name.split('_')[1]} must be finite with shape ({p}, 3), got shape {a.shape}")
            self.particles.arrays[name].assign(a)
            self.state.pair_travel = math.inf  # rebuild the self-collision pairs
            if name == "particle_position":
                pinned = self.particle_inv_mass == 0.0
                target = self.particles.arrays["particle_pin_target"].numpy()[:p].copy()
                target[pinned] = a[pinned]
                self.particles.arrays["particle_pin_target"].assign(target)

    # ------------------------------------------------------------------ views and diagnostics

    def _view(self, name: str) -> np.ndarray:
        """A read-only copy of one particle array (read afresh on each access, as the World's views)."""
        if self.particles.count == 0:
            return readonly(np.zeros((0, 3)))
        return readonly(self.particles.arrays[name].numpy()[: self.particles.count].copy())

    def cloth(self, handle: ClothId | int) -> Cloth:
        """Where the cloth `handle` (from `World.add_cloth`) lives in the particle arrays."""
        return self.cloths[ClothId.checked_index(handle, len(self.cloths), self.world_key)]

    @property
    def particle_count(self) -> int:
        """Number of cloth particles, P (all cloths)."""
        return self.particles.count

    @property
    def triangle_count(self) -> int:
        """Number of cloth triangles, T (all cloths)."""
        return len(self._host("triangles"))

    @property
    def spring_count(self) -> int:
        """Number of springs of every kind (all cloths)."""
        return len(self._host("spring_ids"))

    def particle_values(self, name: str) -> np.ndarray:
        """Any particle array of `PARTICLE_FIELDS` by name: a read-only copy, shape (P, ...)."""
        return self._view(name)

    particle_position = property(
        lambda self: self._view("particle_position"),
        doc="Particle positions [m], shape (P, 3), cloths in creation order, i fastest.",
    )
    particle_velocity = property(
        lambda self: self._view("particle_velocity"), doc="Particle velocities [m/s], shape (P, 3)."
    )
    rest_position = property(
        lambda self: self._view("particle_rest_position"),
        doc="Particle positions when the cloth was added [m], shape (P, 3).",
    )

    @property
    def particle_mass(self) -> np.ndarray:
        """Particle masses [kg], shape (P,)."""
        return readonly(self._host("particle_mass"))

    @property
    def particle_inv_mass(self) -> np.ndarray:
        """Particle inverse masses [1/kg], shape (P,); 0 for pinned particles."""
        if self.particles.count == 0:
            return readonly(np.zeros(0))
        return readonly(self.particles.arrays["particle_inv_mass"].numpy()[: self.particles.count])

    @property
    def triangles(self) -> np.ndarray:
        """Triangles as particle indices, shape (T, 3), int32, cloths in creation order."""
        return readonly(self._host("triangles"))

    @property
    def structural_springs(self) -> np.ndarray:
        """Particle pairs of the structural springs, shape (s, 2), int32."""
        return readonly(self._host("structural_ids"))

    def particle_position_numpy(self) -> np.ndarray:
        """A copy of the particle positions [m], shape (P, 3)."""
        return np.array(self._view("particle_position"))

    def max_strain(self) -> float:
        """Largest strain (|xj - xi| - l0) / l0 over the structural springs (0.1 = 10 % longer)."""
        if self.particles.count == 0 or len(self._host("structural_ids")) == 0:
            return 0.0
        structs = self._kernel_structs()
        return float(springs.strain(structs.particles, structs.structural, self._strain).max())

    def pin_force(self) -> np.ndarray:
        """Mean force [N] the cloth exerted on all its pins (fixed and on bodies) over the last world
        step, shape (3,): the springs' and the stretch limit's pull on them and the pinned particles'
        weight. At rest it balances the weight of the cloth and of whatever the cloth carries."""
        if self.particles.count == 0 or not getattr(self, "_pin_dt", 0.0):
            return np.zeros(3)
        return self._pin_impulse.numpy()[0] / self._pin_dt

    def kinetic_energy(self) -> float:
        """Kinetic energy of the cloth [J]: sum 1/2 m v^2."""
        if self.particles.count == 0:
            return 0.0
        v = self._view("particle_velocity")
        return 0.5 * float(np.sum(self._host("particle_mass") * np.einsum("ij,ij->i", v, v)))

    def elastic_energy(self) -> float:
        """Energy stored in the springs [J]: sum 1/2 ks (|x_j - x_i| - l0)^2 over every spring
        (structural, shear, bend). With `kinetic_energy` and `potential_energy`, the cloth's total:
        a cloth released from its pins turns this into motion."""
        ids = self._host("spring_ids")
        if len(ids) == 0 or self.particles.count == 0:
            return 0.0
        x = self._view("particle_position")
        length = np.linalg.norm(x[ids[:, 1]] - x[ids[:, 0]], axis=1)
        stretch = length - self._host("spring_rest_length")
        return 0.5 * float(np.sum(self._host("spring_stiffness") * stretch * stretch))

    def momentum(self) -> np.ndarray:
        """Linear momentum of the cloth [kg m/s]: sum m v, shape (3,)."""
        if self.particles.count == 0:
            return np.zeros(3)
        return self._host("particle_mass") @ self._view("particle_velocity")

    def potential_energy(self, gravity: Sequence[float] | np.ndarray | None = None) -> float:
        """Gravitational potential energy relative to the origin [J]: -sum m g . x.

        Args:
            gravity: [m/s^2], shape (3,); default the last step's (or the world's when the cloth was made).
        """
        if self.particles.count == 0:
            return 0.0
        g = self._gravity if gravity is None else np.asarray(gravity, dtype=np.float64)
        x = self._view("particle_position")
        return -float(np.sum(self._host("particle_mass") * (x @ g)))

    def center_of_mass(self) -> np.ndarray:
        """Centre of mass of all cloth [m], shape (3,)."""
        m = self._host("particle_mass")
        return (m[:, None] * self._view("particle_position")).sum(axis=0) / m.sum()
