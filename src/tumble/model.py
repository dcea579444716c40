"""Model, State and Control: the parts a `World` is built from, and the one declaration of its body arrays.

As in Newton (and MuJoCo's mjModel / mjData split):

- the **Model** holds what does not change while the world steps: each body's shape, size,
  mass and inertia, material, and the static geometry (convex prototypes, triangle meshes),
  joint definitions, the cloth's topology, rest lengths, masses and pins;
- the **State** holds what does: body poses and velocities, the contacts and joint impulses
  kept for the next step's warm start, the cloth's particles, and the clock;
- the **Control** holds this step's inputs: the forces and torques users apply, drags on cloth
  particles, the wind;
- solver **scratch** (motion since the step began, the next substep's warm start) belongs to
  the solver: it is reset every step and is never part of a snapshot.

Every per-body array is declared once, in `BODY_FIELDS`, with its name, type, role, unit and
meaning. The parts' arrays, the Warp struct the kernels take (`BodyArrays`), the World's
read-only views (`World.body_position`, ...) and their documentation all derive from it.
"""

from __future__ import annotations

import enum
import importlib
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import warp as wp

from .precision import PACKAGE
from .state import ArraySet, RowGroup, float_t, numpy_dtype, quat, vec3
from .structs import cached_struct

if TYPE_CHECKING:
    from .cloth.system import ClothControl, ClothModel, ClothState
    from .cloth.wind import Wind
    from .collision.hulls import HullSet
    from .collision.meshes import MeshSet


class Role(enum.Enum):
    """Which part of the world an array belongs to."""

    MODEL = "model"  #: does not change while stepping
    STATE = "state"  #: changes while stepping; a resume needs it
    CONTROL = "control"  #: this step's inputs, cleared after the step
    SCRATCH = "scratch"  #: the solver's, meaningless between steps


@dataclass(frozen=True)
class Field:
    """One per-row array: its name, Warp type, role, unit and meaning.

    Attributes:
        name: the array's name (entity first: "body_position").
        dtype: Warp type of one row (float_t, vec3, quat, wp.int32, ...); float types are declared
            in float64 and allocated in the world's precision (`tumble.precision.specialize`).
        role: the part of the world it belongs to.
        unit: SI unit of its values ("" for counts, flags and ratios).
        doc: what it holds.
        kernel: whether the kernels' struct of body arrays (`BodyArrays`) has it.
    """

    name: str
    dtype: type
    role: Role
    unit: str
    doc: str
    kernel: bool = False

    @property
    def shape(self) -> tuple[int, ...]:
        """Trailing shape of one row as NumPy sees it: () for scalars, (3,) for vectors, (4,) for quaternions."""
        return numpy_dtype(self.dtype)[1]

    def describe(self) -> str:
        """One line for documentation: meaning, unit and shape of the view with n rows."""
        shape = ", ".join(("n", *map(str, self.shape))) + ("," if not self.shape else "")
        unit = f" [{self.unit}]" if self.unit else ""
        kind = ", int32" if self.dtype is wp.int32 else ""
        return f"{self.doc[:1].upper()}{self.doc[1:]}{unit}, shape ({shape}){kind}."


def fields_of(declaration: tuple[Field, ...], *roles: Role) -> dict[str, type]:
    """name -> Warp type of the fields of `declaration` in `roles` (all of them when none are given)."""
    return {f.name: f.dtype for f in declaration if not roles or f.role in roles}


_M, _S, _C, _X = Role.MODEL, Role.STATE, Role.CONTROL, Role.SCRATCH

#: every per-body array: one row per body, rows reordered in space for large worlds (`World._sort_bodies`)
BODY_FIELDS: tuple[Field, ...] = (
    Field("body_id", wp.int32, _M, "", "the id given at creation (rows are reordered in space; ids stay)", kernel=True),
    Field("body_shape", wp.int32, _M, "", "shape type (ShapeType)", kernel=True),
    Field("body_kind", wp.int32, _M, "", "how the body moves (BodyKind: dynamic, static, kinematic)"),
    Field("body_radius", float_t, _M, "m", "sphere and capsule radius (0 for other shapes)", kernel=True),
    Field(
        "body_half_extents", vec3, _M, "m", "box half extents; for capsules, of the bounding box (r, r, a + r)", True
    ),
    Field("body_bound_radius", float_t, _M, "m", "radius of a bounding sphere about the centre (inf for planes)", True),
    Field(
        "body_geometry",
        wp.int32,
        _M,
        "",
        "row of a convex body's hull in `hulls`, of a mesh in `meshes` (else 0)",
        kernel=True,
    ),
    Field("body_mass", float_t, _M, "kg", "mass (0 for static and kinematic bodies)"),
    Field("body_inv_mass", float_t, _M, "1/kg", "inverse mass (0 for static and kinematic bodies)", kernel=True),
    Field("body_inv_inertia", vec3, _M, "1/(kg m^2)", "principal inverse moments of inertia, body frame", True),
    Field("body_restitution", float_t, _M, "", "coefficient of restitution", kernel=True),
    Field("body_friction", float_t, _M, "", "friction coefficient", kernel=True),
    Field("body_position", vec3, _S, "m", "centre of mass, world frame", kernel=True),
    Field("body_orientation", quat, _S, "", "body-to-world rotation, unit quaternion (x, y, z, w)", kernel=True),
    Field("body_velocity", vec3, _S, "m/s", "linear velocity", kernel=True),
    Field("body_angular_velocity", vec3, _S, "rad/s", "angular velocity, world frame", kernel=True),
    Field("body_joint_load", float_t, _S, "N m", "the joints' geometric load on the body last step (their stiffness)"),
    Field("body_force", vec3, _C, "N", "user force for the next step, at the centre of mass", kernel=True),
    Field("body_torque", vec3, _C, "N m", "user torque for the next step, world frame", kernel=True),
    Field("body_delta_position", vec3, _X, "m", "motion since the start of the step (separation updates)", True),
    Field("body_delta_rotation", vec3, _X, "rad", "rotation vector since the start of the step", kernel=True),
    Field("body_warm_velocity", vec3, _X, "m/s", "next substep's warm start, summed per body", kernel=True),
    Field("body_warm_angular_velocity", vec3, _X, "rad/s", "next substep's warm start (angular)", kernel=True),
)

#: field name -> its declaration
BODY_FIELD = {f.name: f for f in BODY_FIELDS}


#: the fields the kernels' struct of body arrays has (`tumble.real.BodyArrays`, one per precision)
KERNEL_FIELDS = tuple(f for f in BODY_FIELDS if f.kernel)


def body_arrays_struct(precision: str) -> Any:
    """The Warp struct of body arrays (`BodyArrays`) of the kernels of `precision`."""
    return importlib.import_module(f"{PACKAGE[precision]}.real").BodyArrays


def body_arrays(bodies, cached: tuple | None = None) -> tuple:
    """The `BodyArrays` struct (of the group's precision) over a body row group's arrays, as (struct, arrays).

    `cached` (a previous return) comes back while the arrays are the same ones, so that a
    recorded launch re-packs nothing; callers keep it as a cache, rebuilt on demand.
    """
    return cached_struct(body_arrays_struct(bodies.precision), bodies.arrays, "body_", cached)


#: body row group -> its last `body_arrays` (dropped with the group)
_STRUCTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def body_struct(bodies) -> Any:
    """The `BodyArrays` struct over a body row group's arrays, the same one while its arrays are.

    For the stages that keep no cache of their own (the narrow phase): a recorded launch then
    finds the struct it recorded and re-packs nothing.
    """
    cached = _STRUCTS[bodies] = body_arrays(bodies, _STRUCTS.get(bodies))
    return cached[0]


class _Part:
    """What a world's parts share: their rows of `BODY_FIELDS` in the world's one dict of body arrays
    (`role` picks them) and their share of the cloth, set with the first cloth."""

    def __init__(self, role: Role, device: str, arrays: dict, precision: str):
        self.bodies = ArraySet(fields_of(BODY_FIELDS, role), device=device, arrays=arrays, precision=precision)


class Model(_Part):
    """What does not change while the world steps (users may still edit it between steps).

    Attributes:
        bodies: the model rows of `BODY_FIELDS` (shape, size, mass, inertia, material).
        hulls: convex prototypes, row 0 the unit box.
        meshes: static triangle meshes and their BVHs.
        joints: the model rows of `solver.joints.JOINT_FIELDS` (kind, bodies, anchors, axes, limits,
            motors, break force), None for a world without a joint solver.
        cloth: the cloth's topology, rest shape, masses and pins (`cloth.system.ClothModel`), None
            until the first cloth.
    """

    def __init__(self, device: str, arrays: dict, precision: str, hulls: HullSet, meshes: MeshSet, joints: ArraySet):
        super().__init__(Role.MODEL, device, arrays, precision)
        self.hulls = hulls
        self.meshes = meshes
        self.joints = joints
        self.cloth: ClothModel | None = None


class State(_Part):
    """What changes while the world steps; with the emitters' counters and random generators it is
    everything `World.snapshot` copies, compares and saves.

    Attributes:
        bodies: the state rows of `BODY_FIELDS` (pose and velocities).
        contacts: last step's contacts with their impulses, the next step's warm start.
        joints: the state rows of `solver.joints.JOINT_FIELDS` (accumulated impulses, the warm
            start; forces; broken flags).
        cloth: the cloth's particle positions, velocities and pin targets, and its contact counts
            (`cloth.system.ClothState`), None until the first cloth.
        step_count: steps taken.
    """

    def __init__(self, device: str, arrays: dict, precision: str, contacts: ArraySet, joints: ArraySet):
        super().__init__(Role.STATE, device, arrays, precision)
        self.contacts = contacts
        self.joints = joints
        self.cloth: ClothState | None = None
        self.step_count = 0


class Control(_Part):
    """This step's inputs: user forces and drags, cleared once the step has used them, and the wind.

    Attributes:
        bodies: the control rows of `BODY_FIELDS` (user forces and torques).
        cloth: the cloth's inputs (`cloth.system.ClothControl`: forces on particles, the wind), None
            until the first cloth.
    """

    def __init__(self, device: str, arrays: dict, precision: str):
        super().__init__(Role.CONTROL, device, arrays, precision)
        self.cloth: ClothControl | None = None

    @property
    def wind(self) -> Wind | None:
        """The wind acting on cloth in the next steps (`World.set_wind` sets it), None for still air."""
        return None if self.cloth is None else self.cloth.wind


def body_row_group(device: str, arrays: dict, model: Model, state: State, control: Control) -> RowGroup:
    """The row group over the parts' body arrays and the solver's scratch rows, in one arrays dict."""
    scratch = ArraySet(
        fields_of(BODY_FIELDS, Role.SCRATCH), device=device, arrays=arrays, precision=model.bodies.precision
    )
    return RowGroup(model.bodies, state.bodies, control.bodies, scratch)


__all__ = [
    "BODY_FIELDS",
    "KERNEL_FIELDS",
    "Control",
    "Field",
    "Model",
    "Role",
    "State",
    "body_arrays",
    "body_arrays_struct",
    "body_struct",
    "fields_of",
]
