"""The scene schema as data: one `TableSpec` per table, one `Field` per key (check, default, units, doc).

The parser, the defaults and the reference tables of docs/scenes.md (`docs.reference_markdown`)
all read `SCHEMA`. Where a key has a World API keyword of its own (the cloth's and the wind's),
its default is read from that keyword's signature, so that the file and the API share it.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from ... import limits
from ...cloth import system as _cloth
from ...precision import DEFAULT_PRECISION, PRECISIONS
from ...render.camera import DEFAULT_FOV
from ...shapes import DEFAULT_DENSITY, SOLID_DEFAULTS
from ...world import World
from .checks import (
    Bad,
    Check,
    boolean,
    choice,
    cloth_rules,
    convex_rules,
    emitter_rules,
    extent,
    file_name,
    integer,
    joint_rules,
    number,
    per_spring,
    pins,
    point_list,
    quaternion,
    resolution,
    scale_factor,
    shape_list,
    show,
    size_or_range,
    solid_rules,
    value_or_range,
    vector,
)

REQUIRED = object()  # marks a key without a default
#: the check of every seed key (the world's, an emitter's, the wind's): `validate.seed`'s range
_SEED = integer(low=0, high=limits.MAX_SEED, limit="the largest seed")


# ---------------------------------------------------------------------------------------- the schema


@dataclass(frozen=True)
class Field:
    """One key of a table: its check, default (REQUIRED or None = left to the engine), units, doc."""

    check: Check
    default: object = None
    units: str = ""
    doc: str = ""
    shown_default: str | None = None  # how the docs show a None default


@dataclass(frozen=True)
class TableSpec:
    """One table of a scene file: `[name]` (array=False) or `[[name]]` (array=True)."""

    name: str
    array: bool
    doc: str
    fields: dict[str, Field]
    rules: Callable[[dict], None] | None = None  # cross-key checks on the converted values


def _shown(value) -> str:
    """A default as the scene reference shows it, in TOML: 0.2, false, { structural = 12, shear = 1.2 }."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_shown(v)}" for k, v in value.items()) + " }"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _api_default(source: Callable | Mapping[str, Any], name: str):
    """The default of keyword `name` of the API `source`, a function or a keyword set's defaults
    (`SOLID_DEFAULTS`): a scene key and the API share one default.

    A tuple (a vector) comes back as the list of floats a scene file holds.
    """
    default = source[name] if isinstance(source, Mapping) else inspect.signature(source).parameters[name].default
    return [float(v) for v in default] if isinstance(default, tuple) else default


def _defaults(source: Callable | Mapping[str, Any]) -> Callable[[str], Any]:
    """`_api_default` of one API function or keyword set, for the keys of one table."""
    return functools.partial(_api_default, source)


_wind_default = _defaults(_cloth.ClothSystem.set_wind)


JOINT_KINDS = ("ball", "hinge", "slider", "fixed", "distance", "rope")


def body_ref() -> Check:
    """A body of the file, as its table and index ("box[2]" is the third [[box]]), or "world"."""

    what = '"plane[i]", "sphere[i]", "box[i]", "capsule[i]", "convex[i]", "mesh[i]" or "world"'

    def convert(value):
        if not isinstance(value, str):
            raise Bad(f"must name a body, {what}; got {show(value)}")
        if value == "world":
            return value
        name, _, rest = value.partition("[")
        if name not in BODY_TABLES or not rest.endswith("]") or not rest[:-1].isdigit():
            raise Bad(f"must name a body, {what}; got {show(value)}")
        return value

    return Check(what, convert)


def _material(d: Callable[[str], Any]) -> dict[str, Field]:
    """restitution and friction, with the defaults `d` reads from an API call."""
    return {
        "restitution": Field(number(low=0, high=1), d("restitution"), "", "coefficient of restitution"),
        "friction": Field(number(low=0), d("friction"), "", "Coulomb friction coefficient"),
    }


#: a solid body's mass, or its density
_MASS = {
    "mass": Field(number(low=0, low_open=True), None, "kg", "mass; give mass or density", "from density"),
    "density": Field(
        number(low=0, low_open=True), None, "kg/m^3", "density; give mass or density", _shown(DEFAULT_DENSITY)
    ),
}


def _static_field() -> Field:
    """The `static` key of a solid body's table (spheres, boxes, capsules, convex bodies)."""
    return Field(
        boolean(), _solid("static"), "", "immovable (inverse mass 0; a velocity other than 0 is refused: use kinematic)"
    )


def _body_fields(size_key: str, size: Field) -> dict[str, Field]:
    """The keys of a solid body's table; the defaults are the body adders' (`SOLID_DEFAULTS`)."""
    return {
        "position": Field(vector(3), REQUIRED, "m", "centre of mass"),
        size_key: size,
        "velocity": Field(vector(3), _solid("velocity"), "m/s", "initial linear velocity"),
        **_MASS,
        **_material(_solid),
        "static": _static_field(),
        "kinematic": Field(
            boolean(),
            _solid("kinematic"),
            "",
            "moves only by its velocity and angular velocity, unaffected by gravity and contacts (infinite mass)",
        ),
        "orientation": Field(quaternion(), _solid("orientation"), "", "initial orientation quaternion (x, y, z, w)"),
        "angular_velocity": Field(
            vector(3), _solid("angular_velocity"), "rad/s", "initial angular velocity, world frame"
        ),
    }


_world = _defaults(World.__init__)
_plane = _defaults(World.add_plane)
_solid = _defaults(SOLID_DEFAULTS)
_convex = _defaults(World.add_convex)
_mesh = _defaults(World.add_mesh)
_emitter = _defaults(World.add_emitter)
_cloth_default = _defaults(_cloth.ClothSystem.add_cloth)
_joint = _defaults(World.add_joint)


SCHEMA: dict[str, TableSpec] = {
    spec.name: spec
    for spec in [
        TableSpec(
            "world",
            False,
            "Global settings.",
            {
                "gravity": Field(vector(3), _world("gravity"), "m/s^2", "gravitational acceleration"),
                "dt": Field(
                    number(low=limits.MIN_DT, high=limits.MAX_DT, limit="the largest dt Tumble supports"),
                    _world("dt"),
                    "s",
                    "fixed time step",
                    "1/240",
                ),
                "substeps": Field(
                    integer(low=1, high=limits.MAX_SUBSTEPS, limit="the most Tumble supports"),
                    _world("substeps"),
                    "",
                    "solver substeps per step",
                ),
                "seed": Field(
                    _SEED,
                    _world("seed"),
                    "",
                    "seed of the world's random generator (emitters without a seed)",
                ),
                "restitution_threshold": Field(
                    number(low=0),
                    _world("restitution_threshold"),
                    "m/s",
                    "impact speed below which contacts that carry load do not bounce (others bounce down to 2 g h)",
                ),
                "precision": Field(
                    choice(*PRECISIONS),
                    None,
                    "",
                    "float type of every array and kernel: float32 or float64",
                    DEFAULT_PRECISION,
                ),
            },
        ),
        TableSpec(
            "plane",
            True,
            "Static infinite planes {x : dot(normal, x) = offset}; bodies stay on the +normal side.",
            {
                "normal": Field(vector(3, nonzero=True), _plane("normal"), "", "plane normal (normalised on load)"),
                "offset": Field(
                    number(), _plane("offset"), "m", "distance of the plane from the origin along the normal"
                ),
                **_material(_plane),
            },
        ),
        TableSpec(
            "sphere",
            True,
            "Solid spheres.",
            _body_fields("radius", Field(number(low=0, low_open=True), REQUIRED, "m", "radius")),
            solid_rules,
        ),
        TableSpec(
            "box",
            True,
            "Solid boxes.",
            _body_fields(
                "half_extents",
                Field(vector(3, positive=True), REQUIRED, "m", "half sizes along the body axes"),
            ),
            solid_rules,
        ),
        TableSpec(
            "capsule",
            True,
            "Solid capsules: the points within radius of a segment of length 2 half_height along the body z axis.",
            _body_fields("radius", Field(number(low=0, low_open=True), REQUIRED, "m", "radius"))
            | {"half_height": Field(number(low=0, low_open=True), REQUIRED, "m", "half length of the segment")},
            solid_rules,
        ),
        TableSpec(
            "convex",
            True,
            "Solid convex bodies: the convex hull of points, or of a mesh file's vertices. Their frame is "
            "placed at position/orientation; the body's centre of mass is where the hull puts it.",
            {
                "points": Field(point_list(), None, "m", "points whose hull is the body, in its frame", "none"),
                "file": Field(
                    file_name(), None, "", "mesh file (OBJ, STL, PLY, OFF, glTF/GLB) whose hull is the body", "none"
                ),
                "scale": Field(scale_factor(), _convex("scale"), "", "factor(s) applied to the points or the file"),
                "position": Field(vector(3), REQUIRED, "m", "origin of the points' frame"),
                "orientation": Field(quaternion(), _solid("orientation"), "", "orientation of the points' frame"),
                "velocity": Field(vector(3), _solid("velocity"), "m/s", "initial linear velocity"),
                "angular_velocity": Field(
                    vector(3), _solid("angular_velocity"), "rad/s", "initial angular velocity, world frame"
                ),
                **_MASS,
                **_material(_solid),
                "static": _static_field(),
            },
            convex_rules,
        ),
        TableSpec(
            "mesh",
            True,
            "Static triangle meshes from files, read with trimesh; faces wound counter-clockwise seen from "
            "where bodies stay (outward on a closed mesh). Cloth may lie on either side of an open mesh "
            "(a plate, a terrain); a closed one is a solid.",
            {
                "file": Field(file_name(), REQUIRED, "", "mesh file: OBJ, STL, PLY, OFF, glTF/GLB"),
                "scale": Field(scale_factor(), _mesh("scale"), "", "factor(s) applied in the mesh's frame"),
                "position": Field(vector(3), _mesh("position"), "m", "origin of the mesh's frame"),
                "orientation": Field(quaternion(), _mesh("orientation"), "", "orientation of the mesh's frame"),
                **_material(_mesh),
            },
        ),
        TableSpec(
            "emitter",
            True,
            "Sources releasing bodies over time; a new body never overlaps an existing one.",
            {
                "shape": Field(
                    shape_list(), _emitter("shape"), "", "shape of the bodies; with a list, chosen at random"
                ),
                "rate": Field(number(low=0, low_open=True), REQUIRED, "1/s", "bodies released per second"),
                "count": Field(integer(low=1), REQUIRED, "", "total number of bodies released"),
                "position": Field(vector(3), REQUIRED, "m", "centre of the region"),
                "region": Field(choice("point", "box", "disc"), _emitter("region"), "", "where bodies appear"),
                "extent": Field(extent(), None, "m", "half-sizes [x, y, z] for box, radius for disc", "none"),
                "direction": Field(vector(3, nonzero=True), _emitter("direction"), "", "mean release direction"),
                "cone_angle": Field(
                    number(low=0, high=180), _emitter("cone_angle"), "deg", "half-angle of the spread cone"
                ),
                "speed": Field(
                    value_or_range(positive=False), _emitter("speed"), "m/s", "release speed, value or [min, max]"
                ),
                "radius": Field(value_or_range(positive=True), None, "m", "sphere radius, value or [min, max]", "none"),
                "half_extents": Field(size_or_range(), None, "m", "box half sizes, value or [min, max]", "none"),
                "half_height": Field(
                    value_or_range(positive=True),
                    None,
                    "m",
                    "capsule half height (of its segment), value or [min, max]",
                    "none",
                ),
                "points": Field(point_list(), None, "m", "points whose hull a convex body is, in its frame", "none"),
                "file": Field(file_name(), None, "", "mesh file whose vertices' hull a convex body is", "none"),
                "scale": Field(
                    value_or_range(positive=True),
                    None,
                    "",
                    "factor on each body's size (all shapes), value or [min, max]",
                    _shown(_emitter("scale")),
                ),
                "mass": Field(value_or_range(positive=True), None, "kg", "mass, value or [min, max]", "from density"),
                "density": Field(
                    value_or_range(positive=True),
                    None,
                    "kg/m^3",
                    "density, value or [min, max]",
                    _shown(DEFAULT_DENSITY),
                ),
                **_material(_emitter),
                "seed": Field(
                    _SEED,
                    None,
                    "",
                    "seed of this emitter's generator",
                    "from [world] seed",
                ),
                "random_orientation": Field(
                    boolean(), None, "", "uniformly random initial orientations", _shown(_emitter("random_orientation"))
                ),
                "angular_speed": Field(
                    value_or_range(positive=False),
                    None,
                    "rad/s",
                    "spin about a random axis, value or [min, max]",
                    _shown(_emitter("angular_speed")),
                ),
            },
            emitter_rules,
        ),
        TableSpec(
            "cloth",
            True,
            "Rectangular mass-spring cloths. Unrotated, a cloth lies in the xy-plane with normal +z, grid "
            "index i along x and j along y.",
            {
                "size": Field(vector(2, positive=True), REQUIRED, "m", "[width, height]"),
                "resolution": Field(resolution(), REQUIRED, "", "particles [nx, ny]"),
                "position": Field(vector(3), REQUIRED, "m", "centre of the cloth"),
                "orientation": Field(
                    quaternion(), _cloth_default("orientation"), "", "orientation quaternion (x, y, z, w)"
                ),
                "mass": Field(
                    number(low=0, low_open=True),
                    None,
                    "kg",
                    "total mass; give mass or areal_density",
                    "from areal_density",
                ),
                "areal_density": Field(
                    number(low=0, low_open=True),
                    None,
                    "kg/m^2",
                    "mass per area; give mass or areal_density",
                    _shown(_cloth.DEFAULT_AREAL_DENSITY),
                ),
                "stiffness": Field(
                    per_spring(),
                    None,
                    "N/m",
                    "spring stiffness ks, one value or per kind (a missing kind has no springs)",
                    _shown(_cloth.DEFAULT_STIFFNESS),
                ),
                "damping": Field(
                    per_spring(),
                    None,
                    "N s/m",
                    "spring damping kd, one value or per kind",
                    _shown(_cloth.DEFAULT_DAMPING),
                ),
                "max_stretch": Field(
                    number(low=0),
                    _cloth_default("max_stretch"),
                    "",
                    "largest strain of a structural spring (Provot)",
                ),
                "pins": Field(pins(), None, "", "pinned grid points", "none"),
                "thickness": Field(
                    number(low=0, low_open=True),
                    None,
                    "m",
                    "distance kept from bodies and between layers of cloth",
                    _shown(_cloth_default("thickness")),
                ),
                "friction": Field(
                    number(low=0),
                    None,
                    "",
                    "Coulomb friction against bodies",
                    _shown(_cloth_default("friction")),
                ),
                "pin_body": Field(body_ref(), None, "", 'body the pins follow and pull on, e.g. "box[0]"', "none"),
            },
            cloth_rules,
        ),
        TableSpec(
            "wind",
            False,
            "Wind acting on cloth: a mean velocity plus smooth, seeded, time-varying turbulence.",
            {
                "velocity": Field(vector(3), _wind_default("velocity"), "m/s", "mean wind velocity"),
                "turbulence": Field(
                    number(low=0), _wind_default("turbulence"), "m/s", "strength of the turbulent part"
                ),
                "scale": Field(
                    number(low=0, low_open=True), _wind_default("scale"), "m", "length scale of the turbulence"
                ),
                "seed": Field(
                    _SEED,
                    _wind_default("seed"),
                    "",
                    "seed of the turbulence field",
                ),
                "drag": Field(number(low=0), _wind_default("drag"), "", "drag coefficient of a cloth face"),
                "lift": Field(number(low=0), _wind_default("lift"), "", "lift coefficient of a cloth face"),
                "air_density": Field(number(low=0), _wind_default("air_density"), "kg/m^3", "density of the air"),
            },
        ),
        TableSpec(
            "joint",
            True,
            "Joints between two bodies, or a body and the world. Bodies are named by table and index "
            '("box[0]" is the first [[box]]); anchors and axis are world coordinates at creation unless '
            'frame = "body".',
            {
                "kind": Field(choice(*JOINT_KINDS), REQUIRED, "", "joint type"),
                "body_a": Field(body_ref(), "world", "", "first body"),
                "body_b": Field(body_ref(), REQUIRED, "", "second body (the joint force is on it)"),
                "anchor": Field(vector(3), None, "m", "shared anchor point, world", "a's centre"),
                "anchor_a": Field(vector(3), None, "m", "anchor on a (instead of anchor)", "anchor"),
                "anchor_b": Field(vector(3), None, "m", "anchor on b (instead of anchor)", "anchor"),
                "frame": Field(
                    choice("world", "body"),
                    _joint("frame"),
                    "",
                    "frame of anchor_a/anchor_b (each body's) and axis (a's)",
                ),
                "axis": Field(vector(3, nonzero=True), None, "", "hinge / slider axis", "[0, 0, 1]"),
                "lower": Field(
                    number(),
                    None,
                    "deg or m",
                    "lower limit: hinge angle turned since creation (deg, whole turns counted), slider offset (m)",
                    "none",
                ),
                "upper": Field(
                    number(),
                    None,
                    "deg or m",
                    "upper limit: hinge angle turned since creation (deg, whole turns counted), slider offset (m)",
                    "none",
                ),
                "motor_speed": Field(
                    number(), None, "deg/s or m/s", "motor target speed of b relative to a", "no motor"
                ),
                "max_torque": Field(number(low=0), None, "N m", "hinge motor's largest torque", "none"),
                "max_force": Field(number(low=0), None, "N", "slider motor's largest force", "none"),
                "length": Field(number(low=0), None, "m", "distance joint rest length", "current distance"),
                "min_length": Field(number(low=0), None, "m", "distance joint shortest length", "rod: length; rope: 0"),
                "max_length": Field(number(low=0), None, "m", "distance joint longest length", "length"),
                "stiffness": Field(
                    number(low=0), _joint("stiffness"), "N/m", "distance joint spring stiffness (0 = none)"
                ),
                "damping": Field(number(low=0), _joint("damping"), "N s/m", "distance joint spring damping"),
                "break_force": Field(number(low=0, low_open=True), None, "N", "force that breaks the joint", "never"),
                "collide": Field(boolean(), _joint("collide"), "", "whether the two bodies still collide"),
            },
            joint_rules,
        ),
        TableSpec(
            "camera",
            False,
            'Initial view for the viewer and video export (stored in world.metadata["camera"]).',
            {
                "position": Field(vector(3), [3.0, -3.0, 2.0], "m", "eye position"),
                "target": Field(vector(3), [0.0, 0.0, 0.5], "m", "point looked at"),
                "fov": Field(number(low=0, high=179, low_open=True), DEFAULT_FOV, "deg", "vertical field of view"),
            },
        ),
        TableSpec(
            "check",
            False,
            'What the sample tests assert after running the scene headless (stored in world.metadata["check"]). '
            "Always checked: all values finite, no body centre behind a plane, every body within max_extent.",
            {
                "duration": Field(number(low=0, low_open=True), 1.0, "s", "simulated time the test runs"),
                "min_z": Field(number(), None, "m", "lowest allowed body centre height", "none"),
                "max_speed": Field(number(low=0, low_open=True), None, "m/s", "fastest allowed body", "none"),
                "max_kinetic_energy": Field(
                    number(low=0, low_open=True), None, "J", "largest allowed total kinetic energy", "none"
                ),
                "max_extent": Field(
                    number(low=0, low_open=True), 100.0, "m", "largest allowed absolute value of a coordinate"
                ),
                "max_strain": Field(
                    number(low=0, low_open=True), None, "", "largest allowed cloth spring strain", "none"
                ),
                "max_joint_error": Field(
                    number(low=0, low_open=True), None, "m", "largest allowed joint drift (world.joint_error)", "none"
                ),
            },
        ),
    ]
}

# bodies are created in this order: every [[plane]], then [[sphere]], [[box]], [[capsule]], [[convex]]
# and [[mesh]], each in file order
BODY_TABLES = ("plane", "sphere", "box", "capsule", "convex", "mesh")
