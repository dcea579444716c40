"""Scene files: TOML -> validated tables -> `World`.

A scene file is a TOML document with the tables described in docs/scenes.md::

    [world]
    gravity = [0, 0, -9.81]

    [[plane]]
    normal = [0, 0, 1]

    [[sphere]]
    position = [0, 0, 1]
    radius = 0.1
    mass = 1.0

The schema is data (`SCHEMA`: one `TableSpec` per table, one `Field` per key), so the
validator, the defaults and the reference tables in docs/scenes.md (`reference_markdown()`)
come from one place. Every problem raises `SceneError` naming the file, the table (e.g.
`sphere[2]` for the third `[[sphere]]`) and the key.

Loading is two steps: `parse_scene(text)` checks everything and returns a `Scene` of plain
Python values (no Warp, no World); `build_world(scene)` passes those values to the World API.
`load_scene(path)` does both.
"""

from __future__ import annotations

import difflib
import importlib.resources
import inspect
import math
import os
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict, Unpack

import numpy as np

from .. import limits
from ..cloth import system as _cloth
from ..errors import SceneError
from ..limits import show_bytes

if TYPE_CHECKING:
    from ..state import BodyId
    from ..world import World

#: directory of the bundled sample scenes, installed with the package (`tumble/samples`, which the
#: repository's `samples/` links to); override with $TUMBLE_SAMPLES
SAMPLES_DIR = Path(os.environ.get("TUMBLE_SAMPLES") or os.fspath(importlib.resources.files("tumble") / "samples"))  # type: ignore[call-overload]  # a Path here; typeshed: a Traversable

REQUIRED = object()  # marks a key without a default


class _Bad(Exception):
    """A value failed its check; the message says why (the caller adds file, table and key)."""


# ---------------------------------------------------------------------------------------- value checks
# Each check takes the TOML value and returns the Python value passed to the World API, or raises
# _Bad. `Check.kind` is the type as written in the docs.


@dataclass(frozen=True)
class Check:
    kind: str
    convert: Callable[[object], object]

    def __call__(self, value):
        return self.convert(value)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _number(value) -> float:
    if not _is_number(value):
        raise _Bad(f"must be a number, got {_show(value)}")
    v = float(value)
    if not math.isfinite(v):
        raise _Bad(f"must be finite, got {_show(value)}")
    return v


def _show(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return "a table"
    text = repr(value)
    return text if len(text) <= 80 else text[:76] + " ..."  # a deeply nested or long value stays readable


def number(
    *, low: float | None = None, high: float | None = None, low_open: bool = False, limit: str | None = None
) -> Check:
    """A finite float, optionally bounded: low < v (low_open) or low <= v, v <= high.

    `limit` names what `high` is (e.g. "the largest dt Tumble supports"), for the message.
    """

    def convert(value):
        v = _number(value)
        if low is not None and (v <= low if low_open else v < low):
            raise _Bad(f"must be {'>' if low_open else '>='} {low:g}, got {_show(value)}")
        if high is not None and v > high:
            raise _Bad(
                f"{_show(value)} is too large: must be <= {high:g}"
                + (f" ({limit}, docs/scenes.md#limits)" if limit else "")
            )
        return v

    if low == 0 and low_open and high is None:
        kind = "float > 0"
    elif low is not None and high is not None:
        kind = f"float in [{low:g}, {high:g}]" if not low_open else f"float in ({low:g}, {high:g}]"
    elif low is not None:
        kind = f"float {'>' if low_open else '>='} {low:g}"
    else:
        kind = "float"
    return Check(kind, convert)


def integer(*, low: int | None = None, high: int | None = None, limit: str | None = None) -> Check:
    """An integer, optionally >= low and <= high (`limit` names what `high` is, as for `number`)."""

    def convert(value):
        if isinstance(value, bool) or not isinstance(value, int):
            raise _Bad(f"must be an integer, got {_show(value)}")
        if low is not None and value < low:
            raise _Bad(f"must be >= {low}, got {value}")
        if high is not None and value > high:
            raise _Bad(
                f"{value:,} is too large: must be <= {high:,}" + (f" ({limit}, docs/scenes.md#limits)" if limit else "")
            )
        return int(value)

    if high is not None:
        return Check(f"integer in [{low}, {high}]", convert)
    return Check("integer" if low is None else f"integer >= {low}", convert)


def boolean() -> Check:
    def convert(value):
        if not isinstance(value, bool):
            raise _Bad(f"must be true or false, got {_show(value)}")
        return value

    return Check("bool", convert)


def choice(*names: str) -> Check:
    def convert(value):
        if not isinstance(value, str):
            raise _Bad(f"must be a string, one of {', '.join(map(repr, names))}; got {_show(value)}")
        if value not in names:
            raise _Bad(f"unknown value {value!r}: expected one of {', '.join(map(repr, names))}")
        return value

    quoted = [f'"{n}"' for n in names]
    return Check(quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " or " + quoted[-1], convert)


def _vector(value, n: int) -> list[float]:
    if not isinstance(value, list):
        raise _Bad(f"must be a list of {n} numbers, got {_show(value)}")
    if len(value) != n:
        raise _Bad(f"must have {n} components, got {len(value)}")
    if not all(_is_number(v) for v in value):
        raise _Bad(f"must be a list of {n} numbers, got {_show(value)}")
    out = [float(v) for v in value]
    if not all(math.isfinite(v) for v in out):
        raise _Bad(f"must be finite, got {_show(value)}")
    return out


def vector(n: int, *, nonzero: bool = False, positive: bool = False, nonneg: bool = False) -> Check:
    """A list of n finite floats; optionally not all zero, or each > 0, or each >= 0."""

    def convert(value):
        v = _vector(value, n)
        if nonzero and math.sqrt(sum(x * x for x in v)) < 1e-12:
            raise _Bad("must not be the zero vector")
        if positive and any(x <= 0 for x in v):
            raise _Bad(f"components must all be > 0, got {_show(value)}")
        if nonneg and any(x < 0 for x in v):
            raise _Bad(f"components must all be >= 0, got {_show(value)}")
        return v

    names = {2: "[a, b]", 3: "[x, y, z]", 4: "[x, y, z, w]"}[n]
    qual = ", non-zero" if nonzero else ", each > 0" if positive else ", each >= 0" if nonneg else ""
    return Check(f"{names} floats{qual}", convert)


def quaternion() -> Check:
    """A non-zero quaternion (x, y, z, w); the World normalises it."""

    def convert(value):
        v = _vector(value, 4)
        if math.sqrt(sum(x * x for x in v)) < 1e-12:
            raise _Bad("must be a non-zero quaternion [x, y, z, w]")
        return v

    return Check("[x, y, z, w] floats, non-zero", convert)


def value_or_range(*, positive: bool) -> Check:
    """A number v or a range [min, max] with min <= max; v > 0 (positive) or v >= 0."""
    op = ">" if positive else ">="

    def one(v, value):
        x = _number(v)
        if x < 0 or (positive and x == 0):
            raise _Bad(f"must be {op} 0, got {_show(value)}")
        return x

    def convert(value):
        if isinstance(value, list):
            if len(value) != 2:
                raise _Bad(f"must be a number or a range [min, max], got {len(value)} values")
            lo, hi = one(value[0], value), one(value[1], value)
            if lo > hi:
                raise _Bad(f"range [min, max] must have min <= max, got {_show(value)}")
            return (lo, hi)
        return one(value, value)

    return Check(f"float or [min, max], {op} 0", convert)


def size_or_range() -> Check:
    """Box half extents for an emitter: h, [hx, hy, hz], [hmin, hmax] (cubes) or [[x, y, z], [x, y, z]]."""

    def convert(value):
        if isinstance(value, list) and len(value) == 2 and all(isinstance(v, list) for v in value):
            lo = vector(3, positive=True)(value[0])
            hi = vector(3, positive=True)(value[1])
            if any(a > b for a, b in zip(lo, hi)):
                raise _Bad(f"range [min, max] must have min <= max in each component, got {_show(value)}")
            return (tuple(lo), tuple(hi))
        if isinstance(value, list) and len(value) == 3:
            return tuple(vector(3, positive=True)(value))
        return value_or_range(positive=True)(value)

    return Check("float, [x, y, z], [min, max] or [[x, y, z], [x, y, z]], > 0", convert)


def extent() -> Check:
    """Emitter region extent: a radius (disc) or half-sizes [x, y, z] (box); checked against region later."""

    def convert(value):
        if isinstance(value, list):
            return vector(3, nonneg=True)(value)
        return number(low=0, low_open=True)(value)

    return Check("float (disc radius) or [x, y, z] (box half-sizes)", convert)


def shape_list() -> Check:
    names = ("sphere", "box", "capsule", "convex")

    def convert(value):
        items = value if isinstance(value, list) else [value]
        if not items:
            raise _Bad("must name at least one shape")
        for item in items:
            if not isinstance(item, str):
                raise _Bad(f"must be a shape name or a list of them, got {_show(value)}")
            if item not in names:
                raise _Bad(f'unknown shape {item!r}: expected "sphere", "box", "capsule" or "convex"')
        return value if isinstance(value, str) else list(items)

    return Check('"sphere", "box", "capsule", "convex" or a list of them', convert)


SPRING_KINDS = ("structural", "shear", "bend")


def point_list() -> Check:
    """A list of at least four [x, y, z] points (the convex hull is taken)."""

    def convert(value):
        if not isinstance(value, list) or len(value) < 4:
            raise _Bad(f"must be a list of at least 4 points [x, y, z], got {_show(value)}")
        return [_vector(v, 3) for v in value]

    return Check("list of [x, y, z] floats, at least 4", convert)


def file_name() -> Check:
    """A file path (relative paths are taken from the scene file's folder)."""

    def convert(value):
        if not isinstance(value, str) or not value.strip():
            raise _Bad(f"must be a file name in quotes, got {_show(value)}")
        return value

    return Check("string (a path)", convert)


def scale_factor() -> Check:
    """One positive factor, or three (per axis)."""

    def convert(value):
        if _is_number(value):
            v = _number(value)
            if not (math.isfinite(v) and v > 0):
                raise _Bad(f"must be > 0, got {_show(value)}")
            return v
        return vector(3, positive=True).convert(value)

    return Check("float > 0 or [x, y, z] floats, each > 0", convert)


def _convex_rules(values: dict) -> None:
    _mass_or_density(values)
    if (values.get("points") is None) == (values.get("file") is None):
        raise _KeyBad("points", "give points or file (one of them)")


def per_spring() -> Check:
    """A number >= 0 for every spring kind, or a table with some of {structural, shear, bend}."""
    each = number(low=0)

    def convert(value):
        if isinstance(value, dict):
            out = {}
            for k, v in value.items():
                if k not in SPRING_KINDS:
                    raise _Bad(f"unknown spring kind {k!r}: expected {', '.join(SPRING_KINDS)}")
                try:
                    out[k] = each(v)
                except _Bad as exc:
                    raise _Bad(f"{k} {exc}") from None
            return out
        return each(value)

    return Check("float >= 0 or { structural, shear, bend }", convert)


PIN_NAMES = ("corners", "top-corners", "top-edge")


def pins() -> Check:
    def convert(value):
        if isinstance(value, str):
            return choice(*PIN_NAMES)(value)
        if not isinstance(value, list):
            raise _Bad(f"must be {', '.join(map(repr, PIN_NAMES))} or a list of [i, j], got {_show(value)}")
        out = []
        for item in value:
            if (
                not isinstance(item, list)
                or len(item) != 2
                or not all(isinstance(v, int) and not isinstance(v, bool) for v in item)
            ):
                raise _Bad(f"each pin must be a grid point [i, j] of two integers, got {_show(item)}")
            out.append((int(item[0]), int(item[1])))
        return out

    return Check('"corners", "top-corners", "top-edge" or a list of [i, j]', convert)


def resolution() -> Check:
    def convert(value):
        if not isinstance(value, list) or len(value) != 2:
            raise _Bad(f"must be [nx, ny], got {_show(value)}")
        out = [integer(low=2)(v) for v in value]
        return out

    return Check("[nx, ny] integers >= 2", convert)


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
    """A default as the scene reference shows it, in TOML: 0.2, { structural = 12, shear = 1.2 }."""
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_shown(v)}" for k, v in value.items()) + " }"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _api_default(function: Callable, name: str):
    """The default of keyword `name` of the API `function`: a scene key and the API share one default."""
    return inspect.signature(function).parameters[name].default


def _wind_default(name: str):
    return _api_default(_cloth.ClothSystem.set_wind, name)


def _mass_or_density(values: dict) -> None:
    if values.get("mass") is not None and values.get("density") is not None:
        raise _KeyBad("density", "give mass or density, not both")
    _mass_representable(values)


def _extremes(value) -> list[float]:
    """The smallest and largest number in a value, a range or a nested list of them."""
    flat = np.asarray([value], dtype=object).ravel().tolist()
    while any(isinstance(v, (list, tuple)) for v in flat):
        flat = [x for v in flat for x in (v if isinstance(v, (list, tuple)) else [v])]
    return [min(flat), max(flat)] if flat else []


def _mass_representable(values: dict) -> None:
    """Refuse sizes or masses whose mass or inertia (or their inverses) overflow or vanish in float64.

    A sphere of radius 1e300 would weigh inf kg and one of radius 1e-300 nothing; the solver
    divides by both. A box is checked with its half extents; an emitter's ranges by their
    extremes (as spheres or cubes).
    """
    from ..shapes import box_inertia, box_volume, sphere_inertia, sphere_volume

    mass, density = values.get("mass"), values.get("density")
    for key in ("radius", "half_extents"):
        size = values.get(key)
        if size is None:
            continue
        exact_box = key == "half_extents" and isinstance(size, list) and len(size) == 3
        shapes = [size] if exact_box else [[r, r, r] if key == "half_extents" else r for r in _extremes(size)]
        with np.errstate(all="ignore"):
            for h in shapes:
                volume = float(box_volume(h) if key == "half_extents" else sphere_volume(h))
                masses = _extremes(mass) if mass is not None else [d * volume for d in _extremes(density or 1000.0)]
                for m in masses:
                    inertia = box_inertia(m, h) if key == "half_extents" else sphere_inertia(m, h)
                    numbers = np.concatenate([[m], np.ravel(inertia)])
                    if not (
                        np.all(np.isfinite(numbers)) and np.all(numbers > 0) and np.all(np.isfinite(1.0 / numbers))
                    ):
                        shown = _show(h if exact_box else (h[0] if isinstance(h, list) else h))
                        raise _KeyBad(
                            key,
                            f"a size of {shown} m gives a mass of {m:g} kg and moments of inertia "
                            f"down to {float(np.min(inertia)):g} kg m^2; both (and their inverses) "
                            "must be finite and > 0 in float64",
                        )


class _KeyBad(Exception):
    """A cross-key rule failed at `key`."""

    def __init__(self, key: str, message: str):
        super().__init__(message)
        self.key = key


def _emitter_rules(values: dict) -> None:
    _mass_or_density(values)
    shapes = [values["shape"]] if isinstance(values["shape"], str) else values["shape"]
    if "sphere" in shapes and values.get("radius") is None:
        raise _KeyBad("radius", "a sphere emitter needs radius (a value or [min, max])")
    if "box" in shapes and values.get("half_extents") is None:
        raise _KeyBad("half_extents", "a box emitter needs half_extents (a value or [min, max])")
    if "capsule" in shapes and (values.get("radius") is None or values.get("half_height") is None):
        key = "radius" if values.get("radius") is None else "half_height"
        raise _KeyBad(key, "a capsule emitter needs radius and half_height (each a value or [min, max])")
    if "convex" in shapes and (values.get("points") is None) == (values.get("file") is None):
        raise _KeyBad("points", "a convex emitter needs points or file (one of them)")
    if "convex" not in shapes and (values.get("points") is not None or values.get("file") is not None):
        key = "points" if values.get("points") is not None else "file"
        raise _KeyBad(key, f'{key} is for shape "convex", which this emitter does not emit')
    region, ext = values["region"], values.get("extent")
    if region == "box" and not isinstance(ext, list):
        raise _KeyBad("extent", 'region "box" needs extent = [x, y, z] half-sizes')
    if region == "disc" and not isinstance(ext, float):
        raise _KeyBad("extent", 'region "disc" needs extent = a radius in m')


def _cloth_rules(values: dict) -> None:
    if values.get("mass") is not None and values.get("areal_density") is not None:
        raise _KeyBad("areal_density", "give mass or areal_density, not both")
    nx, ny = values["resolution"]
    if isinstance(values.get("pins"), list):
        for i, j in values["pins"]:
            if not (0 <= i < nx and 0 <= j < ny):
                raise _KeyBad("pins", f"pin [{i}, {j}] is outside the {nx} x {ny} grid")


JOINT_KINDS = ("ball", "hinge", "slider", "fixed", "distance", "rope")


def body_ref() -> Check:
    """A body of the file, as its table and index ("box[2]" is the third [[box]]), or "world"."""

    def convert(value):
        if not isinstance(value, str):
            raise _Bad(f'must name a body, "plane[i]", "sphere[i]" or "box[i]", or "world"; got {_show(value)}')
        if value == "world":
            return value
        name, _, rest = value.partition("[")
        if name not in BODY_TABLES or not rest.endswith("]") or not rest[:-1].isdigit():
            raise _Bad(f'must name a body, "plane[i]", "sphere[i]" or "box[i]", or "world"; got {_show(value)}')
        return value

    return Check('"plane[i]", "sphere[i]", "box[i]" or "world"', convert)


def _joint_rules(values: dict) -> None:
    if values["body_a"] == values["body_b"]:
        raise _KeyBad("body_b", f"a joint needs two different bodies, got {values['body_b']!r} twice")
    for lo, hi in (("lower", "upper"), ("min_length", "max_length")):
        if values.get(lo) is not None and values.get(hi) is not None and values[lo] > values[hi]:
            raise _KeyBad(lo, f"{lo} {values[lo]:g} > {hi} {values[hi]:g}")


def _body_fields(size_key: str, size: Field) -> dict[str, Field]:
    return {
        "position": Field(vector(3), REQUIRED, "m", "centre of mass"),
        size_key: size,
        "velocity": Field(vector(3), [0.0, 0.0, 0.0], "m/s", "initial linear velocity"),
        "mass": Field(number(low=0, low_open=True), None, "kg", "mass; give mass or density", "from density"),
        "density": Field(number(low=0, low_open=True), None, "kg/m^3", "density; give mass or density", "1000"),
        "restitution": Field(number(low=0, high=1), 0.5, "", "coefficient of restitution"),
        "friction": Field(number(low=0), 0.5, "", "Coulomb friction coefficient"),
        "static": Field(boolean(), False, "", "immovable (inverse mass 0)"),
        "orientation": Field(quaternion(), [0.0, 0.0, 0.0, 1.0], "", "initial orientation quaternion (x, y, z, w)"),
        "angular_velocity": Field(vector(3), [0.0, 0.0, 0.0], "rad/s", "initial angular velocity, world frame"),
    }


SCHEMA: dict[str, TableSpec] = {
    spec.name: spec
    for spec in [
        TableSpec(
            "world",
            False,
            "Global settings.",
            {
                "gravity": Field(vector(3), [0.0, 0.0, -9.81], "m/s^2", "gravitational acceleration"),
                "dt": Field(
                    number(low=0, low_open=True, high=limits.MAX_DT, limit="the largest dt Tumble supports"),
                    1.0 / 240.0,
                    "s",
                    "fixed time step",
                    "1/240",
                ),
                "substeps": Field(
                    integer(low=1, high=limits.MAX_SUBSTEPS, limit="the most Tumble supports"),
                    8,
                    "",
                    "solver substeps per step",
                ),
                "seed": Field(integer(low=0), 0, "", "seed of the world's random generator (emitters without a seed)"),
                "restitution_threshold": Field(
                    number(low=0),
                    0.5,
                    "m/s",
                    "impact speed below which contacts that carry load do not bounce (others bounce down to 2 g h)",
                ),
            },
        ),
        TableSpec(
            "plane",
            True,
            "Static infinite planes {x : dot(normal, x) = offset}; bodies stay on the +normal side.",
            {
                "normal": Field(vector(3, nonzero=True), [0.0, 0.0, 1.0], "", "plane normal (normalised on load)"),
                "offset": Field(number(), 0.0, "m", "distance of the plane from the origin along the normal"),
                "restitution": Field(number(low=0, high=1), 0.5, "", "coefficient of restitution"),
                "friction": Field(number(low=0), 0.5, "", "Coulomb friction coefficient"),
            },
        ),
        TableSpec(
            "sphere",
            True,
            "Solid spheres.",
            _body_fields("radius", Field(number(low=0, low_open=True), REQUIRED, "m", "radius")),
            _mass_or_density,
        ),
        TableSpec(
            "box",
            True,
            "Solid boxes.",
            _body_fields(
                "half_extents", Field(vector(3, positive=True), REQUIRED, "m", "half sizes along the body axes")
            ),
            _mass_or_density,
        ),
        TableSpec(
            "capsule",
            True,
            "Solid capsules: the points within radius of a segment of length 2 half_height along the body z axis.",
            _body_fields("radius", Field(number(low=0, low_open=True), REQUIRED, "m", "radius"))
            | {"half_height": Field(number(low=0, low_open=True), REQUIRED, "m", "half length of the segment")},
            _mass_or_density,
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
                "scale": Field(scale_factor(), 1.0, "", "factor(s) applied to the points or the file"),
                "position": Field(vector(3), REQUIRED, "m", "origin of the points' frame"),
                "orientation": Field(quaternion(), [0.0, 0.0, 0.0, 1.0], "", "orientation of the points' frame"),
                "velocity": Field(vector(3), [0.0, 0.0, 0.0], "m/s", "initial linear velocity"),
                "angular_velocity": Field(vector(3), [0.0, 0.0, 0.0], "rad/s", "initial angular velocity, world frame"),
                "mass": Field(number(low=0, low_open=True), None, "kg", "mass; give mass or density", "from density"),
                "density": Field(number(low=0, low_open=True), None, "kg/m^3", "density; give mass or density", "1000"),
                "restitution": Field(number(low=0, high=1), 0.5, "", "coefficient of restitution"),
                "friction": Field(number(low=0), 0.5, "", "Coulomb friction coefficient"),
                "static": Field(boolean(), False, "", "immovable (inverse mass 0)"),
            },
            _convex_rules,
        ),
        TableSpec(
            "mesh",
            True,
            "Static triangle meshes from files, read with trimesh; faces wound counter-clockwise seen from "
            "where bodies stay (outward on a closed mesh).",
            {
                "file": Field(file_name(), REQUIRED, "", "mesh file: OBJ, STL, PLY, OFF, glTF/GLB"),
                "scale": Field(scale_factor(), 1.0, "", "factor(s) applied in the mesh's frame"),
                "position": Field(vector(3), [0.0, 0.0, 0.0], "m", "origin of the mesh's frame"),
                "orientation": Field(quaternion(), [0.0, 0.0, 0.0, 1.0], "", "orientation of the mesh's frame"),
                "restitution": Field(number(low=0, high=1), 0.5, "", "coefficient of restitution"),
                "friction": Field(number(low=0), 0.5, "", "Coulomb friction coefficient"),
            },
        ),
        TableSpec(
            "emitter",
            True,
            "Sources releasing bodies over time; a new body never overlaps an existing one.",
            {
                "shape": Field(shape_list(), "sphere", "", "shape of the bodies; with a list, chosen at random"),
                "rate": Field(number(low=0, low_open=True), REQUIRED, "1/s", "bodies released per second"),
                "count": Field(integer(low=1), REQUIRED, "", "total number of bodies released"),
                "position": Field(vector(3), REQUIRED, "m", "centre of the region"),
                "region": Field(choice("point", "box", "disc"), "point", "", "where bodies appear"),
                "extent": Field(extent(), None, "m", "half-sizes [x, y, z] for box, radius for disc", "none"),
                "direction": Field(vector(3, nonzero=True), [0.0, 0.0, -1.0], "", "mean release direction"),
                "cone_angle": Field(number(low=0, high=180), 0.0, "deg", "half-angle of the spread cone"),
                "speed": Field(value_or_range(positive=False), 0.0, "m/s", "release speed, value or [min, max]"),
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
                    "1",
                ),
                "mass": Field(value_or_range(positive=True), None, "kg", "mass, value or [min, max]", "from density"),
                "density": Field(value_or_range(positive=True), None, "kg/m^3", "density, value or [min, max]", "1000"),
                "restitution": Field(number(low=0, high=1), 0.5, "", "coefficient of restitution"),
                "friction": Field(number(low=0), 0.5, "", "Coulomb friction coefficient"),
                "seed": Field(integer(low=0), None, "", "seed of this emitter's generator", "from [world] seed"),
                "random_orientation": Field(boolean(), None, "", "uniformly random initial orientations", "false"),
                "angular_speed": Field(
                    value_or_range(positive=False), None, "rad/s", "spin about a random axis, value or [min, max]", "0"
                ),
            },
            _emitter_rules,
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
                "orientation": Field(quaternion(), [0.0, 0.0, 0.0, 1.0], "", "orientation quaternion (x, y, z, w)"),
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
                    _api_default(_cloth.ClothSystem.add_cloth, "max_stretch"),
                    "",
                    "largest strain of a structural spring (Provot)",
                ),
                "pins": Field(pins(), None, "", "pinned grid points", "none"),
                "thickness": Field(
                    number(low=0, low_open=True),
                    None,
                    "m",
                    "distance kept from bodies and between layers of cloth",
                    _shown(_api_default(_cloth.ClothSystem.add_cloth, "thickness")),
                ),
                "friction": Field(
                    number(low=0),
                    None,
                    "",
                    "Coulomb friction against bodies",
                    _shown(_api_default(_cloth.ClothSystem.add_cloth, "friction")),
                ),
                "pin_body": Field(body_ref(), None, "", 'body the pins follow and pull on, e.g. "box[0]"', "none"),
            },
            _cloth_rules,
        ),
        TableSpec(
            "wind",
            False,
            "Wind acting on cloth: a mean velocity plus smooth, seeded, time-varying turbulence.",
            {
                "velocity": Field(vector(3), list(_wind_default("velocity")), "m/s", "mean wind velocity"),
                "turbulence": Field(
                    number(low=0), _wind_default("turbulence"), "m/s", "strength of the turbulent part"
                ),
                "scale": Field(
                    number(low=0, low_open=True), _wind_default("scale"), "m", "length scale of the turbulence"
                ),
                "seed": Field(integer(low=0), _wind_default("seed"), "", "seed of the turbulence field"),
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
                    choice("world", "body"), "world", "", "frame of anchor_a/anchor_b (each body's) and axis (a's)"
                ),
                "axis": Field(vector(3, nonzero=True), None, "", "hinge / slider axis", "[0, 0, 1]"),
                "lower": Field(number(), None, "deg or m", "lower limit: hinge angle (deg), slider offset (m)", "none"),
                "upper": Field(number(), None, "deg or m", "upper limit: hinge angle (deg), slider offset (m)", "none"),
                "motor_speed": Field(
                    number(), None, "deg/s or m/s", "motor target speed of b relative to a", "no motor"
                ),
                "max_torque": Field(number(low=0), None, "N m", "hinge motor's largest torque", "none"),
                "max_force": Field(number(low=0), None, "N", "slider motor's largest force", "none"),
                "length": Field(number(low=0), None, "m", "distance joint rest length", "current distance"),
                "min_length": Field(number(low=0), None, "m", "distance joint shortest length", "rod: length; rope: 0"),
                "max_length": Field(number(low=0), None, "m", "distance joint longest length", "length"),
                "stiffness": Field(number(low=0), 0.0, "N/m", "distance joint spring stiffness (0 = none)"),
                "damping": Field(number(low=0), 0.0, "N s/m", "distance joint spring damping"),
                "break_force": Field(number(low=0, low_open=True), None, "N", "force that breaks the joint", "never"),
                "collide": Field(boolean(), False, "", "whether the two bodies still collide"),
            },
            _joint_rules,
        ),
        TableSpec(
            "camera",
            False,
            'Initial view for the viewer and video export (stored in world.metadata["camera"]).',
            {
                "position": Field(vector(3), [3.0, -3.0, 2.0], "m", "eye position"),
                "target": Field(vector(3), [0.0, 0.0, 0.5], "m", "point looked at"),
                "fov": Field(number(low=0, high=179, low_open=True), 25.0, "deg", "vertical field of view"),
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


# ---------------------------------------------------------------------------------------- parsing


@dataclass
class Scene:
    """A validated scene: for each table its converted values (defaults filled in).

    `tables[name]` is a dict for a single table (absent tables are missing) and a list of
    dicts for an array table (possibly empty).
    """

    path: str | None
    tables: dict[str, Any] = field(default_factory=dict)  # a dict, or a list of dicts for an array table
    text: str | None = None  # the TOML it was parsed from (kept so that snapshots can rebuild the world)

    def items(self, name: str) -> list[dict]:
        """The entries of an array table (empty when absent)."""
        return list(self.tables.get(name, []))

    def table(self, name: str) -> dict | None:
        """A single table's values, or None when the file does not have it."""
        return self.tables.get(name)

    def counts(self) -> dict[str, int]:
        """Number of entries per table present in the file."""
        return {
            name: (len(value) if isinstance(value, list) else 1)
            for name, value in self.tables.items()
            if not isinstance(value, list) or value
        }

    def summary(self) -> str:
        """One line: counts per table, e.g. "[world], 5 planes, 1 emitter (1000 bodies)"."""
        parts = []
        for name, n in self.counts().items():
            label = name if n == 1 else name + ("es" if name.endswith(("x", "s")) else "s")
            if not SCHEMA[name].array:
                parts.append(f"[{name}]")
                continue
            text = f"{n} {label}"
            if name == "emitter":
                text += f" ({sum(e['count'] for e in self.items('emitter'))} bodies)"
            if name == "cloth":
                text += f" ({sum(c['resolution'][0] * c['resolution'][1] for c in self.items('cloth'))} particles)"
            parts.append(text)
        return ", ".join(parts) if parts else "empty scene"


def _table_label(name: str, index: int | None) -> str:
    return name if index is None else f"{name}[{index}]"


def _suggest(word: str, options) -> str:
    close = difflib.get_close_matches(word, list(options), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _parse_table(spec: TableSpec, raw, path, index: int | None) -> dict:
    label = _table_label(spec.name, index)
    if not isinstance(raw, dict):
        raise SceneError(f"must be a table, got {_show(raw)}", path=path, table=label)
    values = {}
    for key, value in raw.items():
        if key not in spec.fields:
            raise SceneError(
                f"unknown key {key!r}{_suggest(key, spec.fields)}; "
                f"[{'[' if spec.array else ''}{spec.name}{']' if spec.array else ''}] takes: {', '.join(spec.fields)}",
                path=path,
                table=label,
                key=key,
            )
        try:
            values[key] = spec.fields[key].check(value)
        except _Bad as exc:
            raise SceneError(str(exc), path=path, table=label, key=key) from None
    for key, f in spec.fields.items():
        if key not in values:
            if f.default is REQUIRED:
                raise SceneError("missing required key", path=path, table=label, key=key)
            values[key] = _copy(f.default)
    if spec.rules is not None:
        try:
            spec.rules(values)
        except _KeyBad as exc:
            raise SceneError(str(exc), path=path, table=label, key=exc.key) from None
    return values


def _copy(value):
    return list(value) if isinstance(value, list) else value


def parse_scene(text: str, path=None) -> Scene:
    """Validate scene-file text and return a `Scene` with every default filled in.

    Args:
        text: the TOML document.
        path: the file it came from, used in error messages.

    Raises:
        SceneError: malformed TOML (with the line), an unknown table or key, a value of the
            wrong type, length or range; the message names the file, the table and the key.
    """
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"invalid TOML: {exc}", path=path) from None
    except RecursionError:
        raise SceneError("invalid TOML: arrays or tables nested too deeply", path=path) from None
    scene = Scene(path=None if path is None else str(path), text=text)
    for name, raw in doc.items():
        spec = SCHEMA.get(name)
        if spec is None:
            kind = "table" if isinstance(raw, (dict, list)) else "top-level key"
            raise SceneError(
                f"unknown {kind} {name!r}{_suggest(name, SCHEMA)}; tables are: "
                + ", ".join(f"[[{s.name}]]" if s.array else f"[{s.name}]" for s in SCHEMA.values()),
                path=path,
                table=name,
            )
        if spec.array:
            if isinstance(raw, dict):
                raise SceneError(f"write [[{name}]] (an array of tables), not [{name}]", path=path, table=name)
            if not isinstance(raw, list):
                raise SceneError(f"must be an array of tables [[{name}]], got {_show(raw)}", path=path, table=name)
            scene.tables[name] = [_parse_table(spec, item, path, i) for i, item in enumerate(raw)]
        else:
            if isinstance(raw, list):
                raise SceneError(f"write [{name}] (one table), not [[{name}]]", path=path, table=name)
            scene.tables[name] = _parse_table(spec, raw, path, None)
    check_limits(scene)
    return scene


def check_limits(scene: Scene, *, dt: float | None = None) -> None:
    """Refuse a scene asking for more than Tumble can do or this machine can hold (docs/scenes.md#limits).

    Checked before anything is allocated: bodies released per emitter step, steps of the
    [check] duration, cloth indices (int32), and the memory of every body and cloth particle
    the scene will hold against `limits.available_memory()`.

    Args:
        dt: the time step the scene will run at (default its [world] dt).

    Raises:
        SceneError: naming the table and key asking too much, the request and the limit.
    """
    path = scene.path
    world = scene.table("world") or {}
    dt = float(world.get("dt", SCHEMA["world"].fields["dt"].default) if dt is None else dt)

    # solver limits: bodies released in one step, steps of the check run
    for i, e in enumerate(scene.items("emitter")):
        per_step = min(e["rate"] * dt, e["count"])
        if per_step > limits.MAX_RELEASE_PER_STEP:
            raise SceneError(
                f"{e['rate']:g} bodies/s at dt {dt:g} s releases {per_step:,.0f} bodies in one step; "
                f"the limit is {limits.MAX_RELEASE_PER_STEP:,} a step (docs/scenes.md#limits)",
                path=path,
                table=_table_label("emitter", i),
                key="rate",
            )
    check = scene.table("check")
    if check is not None:
        try:
            limits.check_steps("duration", check["duration"], dt)
        except limits.LimitError as exc:
            raise SceneError(str(exc), path=path, table="check") from None

    # memory: every body (listed and emitted) and every cloth particle, blamed on the largest request
    requests: list[tuple[int, str, str | None, int, str, int]] = []  # (bytes, table, key, count, what, bytes each)
    for name in BODY_TABLES:
        n = len(scene.items(name))
        if n:
            requests.append((n * limits.BYTES_PER_BODY, name, None, n, f"{name} bodies", limits.BYTES_PER_BODY))
    for i, e in enumerate(scene.items("emitter")):
        requests.append(
            (
                e["count"] * limits.BYTES_PER_BODY,
                _table_label("emitter", i),
                "count",
                e["count"],
                "bodies",
                limits.BYTES_PER_BODY,
            )
        )
    particles = 0
    for i, c in enumerate(scene.items("cloth")):
        n = c["resolution"][0] * c["resolution"][1]
        particles += n
        if particles > limits.MAX_PARTICLES_INT32:
            raise SceneError(
                f"{c['resolution'][0]:,} x {c['resolution'][1]:,} = {n:,} particles; cloth indices are int32, "
                f"which allows at most {limits.MAX_PARTICLES_INT32:,} particles in all (docs/scenes.md#limits)",
                path=path,
                table=_table_label("cloth", i),
                key="resolution",
            )
        requests.append(
            (
                n * limits.BYTES_PER_PARTICLE,
                _table_label("cloth", i),
                "resolution",
                n,
                "particles",
                limits.BYTES_PER_PARTICLE,
            )
        )
    need = sum(r[0] for r in requests)
    if requests:
        have = limits.available_memory()
        if need > have:
            _, table, key, count, what, each = max(requests, key=lambda r: r[0])
            others = need - count * each
            try:
                limits.check_memory(key or f"[[{table}]]", what, count, each, available=max(0, have - others))
            except limits.LimitError as exc:
                message = str(exc).split(": ", 1)[1] if key is not None else str(exc)
                if others > 0.01 * have:
                    message += f" beside the {show_bytes(others)} the rest of the scene needs"
                raise SceneError(message, path=path, table=table if key is not None else None, key=key) from None


def read_scene(path) -> Scene:
    """Read and validate a scene file (see `parse_scene`). Raises `SceneError`, or `OSError` if unreadable."""
    path = resolve_scene_path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(f"not a UTF-8 text file ({exc.reason})", path=path) from None
    return parse_scene(text, path=path)


def validate_scene(path) -> Scene:
    """Check a scene file without building or running it; returns the validated `Scene`."""
    return read_scene(path)


def resolve_scene_path(path) -> Path:
    """`path` itself, or, for a bare name like "sphere_pile", the bundled sample of that name."""
    p = Path(path)
    if not p.exists() and p.parent == Path(".") and (SAMPLES_DIR / p.with_suffix(".toml").name).exists():
        return SAMPLES_DIR / p.with_suffix(".toml").name
    if not p.exists():
        raise FileNotFoundError(f"{path}: no such scene file")
    if p.is_dir():
        raise IsADirectoryError(f"{path}: is a directory, not a scene file")
    return p


def list_samples() -> list[Path]:
    """The bundled sample scenes (`SAMPLES_DIR/*.toml`), sorted by name."""
    return sorted(SAMPLES_DIR.glob("*.toml"))


# ---------------------------------------------------------------------------------------- building


class WorldOverrides(TypedDict, total=False):
    """World settings that replace a scene file's [world] values (`load_scene`); None keeps the file's."""

    gravity: Sequence[float] | None
    dt: float | None
    substeps: int | None
    seed: int | None
    restitution_threshold: float | None
    device: str | None


WORLD_OVERRIDES = tuple(WorldOverrides.__annotations__)


def build_world(scene: Scene, **overrides: Unpack[WorldOverrides]) -> World:
    """Make a `World` from a validated `Scene`.

    Args:
        scene: from `parse_scene` / `read_scene`.
        **overrides: World settings replacing the file's [world] values
            (gravity, dt, substeps, seed, restitution_threshold, device).

    Raises:
        SceneError: when the World API rejects a value (named by table).
    """
    from ..world import World

    unknown = set(overrides) - set(WORLD_OVERRIDES)
    if unknown:
        raise TypeError(f"unknown override(s) {', '.join(sorted(unknown))}; expected {', '.join(WORLD_OVERRIDES)}")
    path = scene.path
    settings = dict(scene.table("world") or _parse_table(SCHEMA["world"], {}, path, None))
    settings.update({k: v for k, v in overrides.items() if v is not None})

    with _api_errors(path, "world"):
        world = World(**settings)
    world.metadata["path"] = path
    world.metadata["overrides"] = {k: v for k, v in overrides.items() if v is not None}
    world.metadata["scene"] = scene
    world.metadata["check"] = scene.table("check") or _parse_table(SCHEMA["check"], {}, path, None)
    if (camera := scene.table("camera")) is not None:
        world.metadata["camera"] = dict(camera)

    # bodies: planes, spheres, boxes, capsules, convex bodies, meshes, each in file order
    made: dict[str, list[BodyId]] = {}
    for name, add in (
        ("plane", world.add_plane),
        ("sphere", world.add_sphere),
        ("box", world.add_box),
        ("capsule", world.add_capsule),
        ("convex", world.add_convex),
        ("mesh", world.add_mesh),
    ):
        made[name] = []
        for i, values in enumerate(scene.items(name)):
            values = dict(values)
            if values.get("file") is not None and path is not None:
                values["file"] = str(Path(path).parent / Path(values["file"]).expanduser())
            if values.get("points") is not None:
                values["points"] = np.asarray(values["points"], dtype=np.float64)
            with _api_errors(path, _table_label(name, i)):
                made[name].append(add(**_given(values)))
    for i, values in enumerate(scene.items("emitter")):
        values = dict(values)
        if values.get("file") is not None and path is not None:
            values["file"] = str(Path(path).parent / Path(values["file"]).expanduser())
        if values.get("points") is not None:
            values["points"] = np.asarray(values["points"], dtype=np.float64)
        with _api_errors(path, _table_label("emitter", i)):
            world.add_emitter(**_given(values))
    for i, values in enumerate(scene.items("cloth")):
        label = _table_label("cloth", i)
        args = _given(values)
        pin_body = args.pop("pin_body", None)
        with _api_errors(path, label):
            cloth = world.cloth.cloths[world.add_cloth(**args)]
        if pin_body is not None:
            body = _named_body(made, pin_body, path, label, "pin_body")
            start = cloth.particle_start
            pinned = start + np.nonzero(world.cloth.particle_inv_mass[start : start + cloth.nx * cloth.ny] == 0.0)[0]
            with _api_errors(path, label):
                world.cloth.pin_to_body(pinned, body)
    if (wind := scene.table("wind")) is not None:
        with _api_errors(path, "wind"):
            world.set_wind(**wind)
    for i, values in enumerate(scene.items("joint")):
        _add_joint(world, made, values, path, _table_label("joint", i))
    return world


def _named_body(made: dict, ref: str, path, label: str, key: str):
    """The BodyId of "box[2]" among the bodies the file made, or a SceneError at `key`."""
    name, index = ref[:-1].split("[")
    if ref == "world" or int(index) >= len(made[name]):
        have = "no world here" if ref == "world" else f"the file has {len(made[name])} [[{name}]]"
        raise SceneError(f"no body {ref!r}: {have}", path=path, table=label, key=key)
    return made[name][int(index)]


def _add_joint(world, made: dict, values: dict, path, label: str) -> None:
    """One [[joint]]: body names to ids (checked against the file's bodies), hinge degrees to radians."""
    from ..solver.joints import JointArgumentError

    args = _given(values)
    ends: list[BodyId | None] = []
    for key in ("body_a", "body_b"):
        ref = args.pop(key)
        if ref == "world":
            ends.append(None)
            continue
        ends.append(_named_body(made, ref, path, label, key))
    if args["kind"] == "hinge":
        for key in ("lower", "upper", "motor_speed"):
            if key in args:
                args[key] = math.radians(args[key])
    try:
        world.add_joint(args.pop("kind"), *ends, **args)
    except JointArgumentError as exc:
        raise SceneError(exc.reason, path=path, table=label, key=exc.key) from None


def load_scene(path: str | os.PathLike[str], **overrides: Unpack[WorldOverrides]) -> World:
    """Read, validate and build a scene file into a `World` (see docs/scenes.md).

    Args:
        path: the .toml file, or the name of a bundled sample ("sphere_pile").
        **overrides: World settings replacing the file's [world] values, e.g. seed=3, device="cuda".
    """
    return build_world(read_scene(path), **overrides)


def _given(values: dict) -> dict:
    """Keyword arguments for the World API: keys left to the engine (None) are not passed."""
    return {
        k: (tuple(v) if isinstance(v, list) and all(_is_number(x) for x in v) else v)
        for k, v in values.items()
        if v is not None
    }


class _api_errors:
    """Turn a ValueError/TypeError from the World API into a SceneError naming file and table."""

    def __init__(self, path, table: str):
        self.path, self.table = path, table

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if exc is not None and isinstance(exc, (ValueError, TypeError)) and not isinstance(exc, SceneError):
            raise SceneError(str(exc), path=self.path, table=self.table) from exc
        return False


# ---------------------------------------------------------------------------------------- checks


def check_world(world, check: dict | None = None) -> list[str]:
    """Failures of a world against a sample's [check] table (empty list = pass).

    Always: every body and cloth particle value finite, no dynamic body centre (or cloth particle)
    behind a plane, every coordinate within max_extent. Then the optional limits of `check`.
    """
    if check is None:
        check = world.metadata.get("check") or _parse_table(SCHEMA["check"], {}, None, None)
    failures = []
    from ..shapes import ShapeType

    shape = np.asarray(world.body_shape)
    position = np.asarray(world.body_position)
    velocity = np.asarray(world.body_velocity)
    dynamic = np.asarray(world.body_inv_mass) > 0
    parts = [position[dynamic]]
    cloth = world.cloth if world.has_cloth else None
    if cloth is not None:
        parts.append(np.asarray(cloth.particle_position))
    points = np.concatenate(parts) if parts else np.zeros((0, 3))

    for name, values in (
        ("body_position", position),
        ("body_velocity", velocity),
        ("body_angular_velocity", np.asarray(world.body_angular_velocity)),
        ("cloth particle_position", points),
    ):
        if not np.isfinite(values).all():
            failures.append(f"{name} is not finite")
    if failures:
        return failures

    planes = np.nonzero(shape == ShapeType.PLANE)[0]
    normals = np.asarray(world.body_plane_normal)
    for p in planes:
        distance = (points - position[p]) @ normals[p]
        if len(distance) and distance.min() < 0.0:
            failures.append(f"a body centre is {-distance.min():.4g} m behind plane {p}")
    if len(points) and np.abs(points).max() > check["max_extent"]:
        failures.append(f"a body is {np.abs(points).max():.4g} m from the origin (max_extent {check['max_extent']:g})")
    if check.get("min_z") is not None and dynamic.any() and position[dynamic, 2].min() < check["min_z"]:
        failures.append(f"lowest body centre z = {position[dynamic, 2].min():.4g} m < min_z {check['min_z']:g}")
    if check.get("max_speed") is not None and dynamic.any():
        speed = float(np.linalg.norm(velocity[dynamic], axis=1).max())
        if speed > check["max_speed"]:
            failures.append(f"fastest body {speed:.4g} m/s > max_speed {check['max_speed']:g}")
    if check.get("max_kinetic_energy") is not None:
        energy = world.kinetic_energy()
        if energy > check["max_kinetic_energy"]:
            failures.append(f"kinetic energy {energy:.4g} J > max_kinetic_energy {check['max_kinetic_energy']:g}")
    if check.get("max_strain") is not None and cloth is not None:
        strain = float(cloth.max_strain())
        if strain > check["max_strain"]:
            failures.append(f"cloth strain {strain:.4g} > max_strain {check['max_strain']:g}")
    if check.get("max_joint_error") is not None and world.joint_count:
        drift = float(np.max(world.joint_error))
        if drift > check["max_joint_error"]:
            failures.append(f"joint drift {drift:.4g} m > max_joint_error {check['max_joint_error']:g}")
    return failures


# ---------------------------------------------------------------------------------------- docs


def reference_markdown() -> str:
    """The key reference of every table, as Markdown (pasted into docs/scenes.md; a test compares)."""
    lines = []
    for spec in SCHEMA.values():
        header = f"[[{spec.name}]]" if spec.array else f"[{spec.name}]"
        lines += [
            f"### `{header}`",
            "",
            spec.doc,
            "",
            "| key | type | default | units | meaning |",
            "|---|---|---|---|---|",
        ]
        for key, f in spec.fields.items():
            if f.default is REQUIRED:
                default = "required"
            elif f.default is None:
                default = f.shown_default or "none"
            elif f.shown_default is not None:
                default = f.shown_default
            else:
                default = _toml_value(f.default)
            lines.append(f"| `{key}` | {f.check.kind} | {default} | {f.units} | {f.doc} |")
        lines.append("")
    return "\n".join(lines)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "`true`" if value else "`false`"
    if isinstance(value, str):
        return f'`"{value}"`'
    if isinstance(value, list):
        return "`[" + ", ".join(f"{v:g}" for v in value) + "]`"
    if isinstance(value, float):
        return f"`{value:g}`"
    return f"`{value}`"


if __name__ == "__main__":  # python -m tumble.io.scene > reference.md (for docs/scenes.md)
    print(reference_markdown())
