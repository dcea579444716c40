"""The rule framework of scene files: value checks, cross-key rules and the error they raise.

A `Check` takes a TOML value and returns the Python value passed to the World API, or raises
`Bad` with the reason (the parser adds file, table and key). A table's cross-key rule (mass or
density, an emitter's shapes and region, ...) runs on the converted values and raises `KeyBad`
naming the key it blames. `Check.kind` is the type as the scene reference writes it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ... import validate


class Bad(Exception):
    """A value failed its check; the message says why (the caller adds file, table and key)."""


# ---------------------------------------------------------------------------------------- value checks
# Each check takes the TOML value and returns the Python value passed to the World API, or raises
# Bad. `Check.kind` is the type as written in the docs. The rules (what is a number, in range, a
# zero vector) are `tumble.validate`'s, which the World API applies; the words are TOML's.


@dataclass(frozen=True)
class Check:
    kind: str
    convert: Callable[[object], object]

    def __call__(self, value):
        return self.convert(value)


def _number(value) -> float:
    if not validate.is_real(value):
        raise Bad(f"must be a number, got {show(value)}")
    v = validate.as_float(value)
    if not validate.within(v):
        raise Bad(f"must be finite, got {show(value)}")
    return v


def show(value) -> str:
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
        if not validate.within(v, low=low, above=low_open):
            raise Bad(f"must be {'>' if low_open else '>='} {low:g}, got {show(value)}")
        if not validate.within(v, high=high):
            raise Bad(
                f"{show(value)} is too large: must be <= {high:g}"
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
            raise Bad(f"must be an integer, got {show(value)}")
        if low is not None and value < low:
            raise Bad(f"must be >= {low}, got {value}")
        if high is not None and value > high:
            # (a number of 400 digits as its power of ten, not a line of 400 digits)
            shown = f"{value:,}" if value < 10**24 else f"about 1e{int(value.bit_length() * math.log10(2))}"
            raise Bad(
                f"{shown} is too large: must be <= {high:,}" + (f" ({limit}, docs/scenes.md#limits)" if limit else "")
            )
        return int(value)

    if high is not None:
        return Check(f"integer in [{low}, {high}]", convert)
    return Check("integer" if low is None else f"integer >= {low}", convert)


def boolean() -> Check:
    def convert(value):
        if not isinstance(value, bool):
            raise Bad(f"must be true or false, got {show(value)}")
        return value

    return Check("bool", convert)


def choice(*names: str) -> Check:
    def convert(value):
        if not isinstance(value, str):
            raise Bad(f"must be a string, one of {', '.join(map(repr, names))}; got {show(value)}")
        if value not in names:
            raise Bad(f"unknown value {value!r}: expected one of {', '.join(map(repr, names))}")
        return value

    quoted = [f'"{n}"' for n in names]
    return Check(quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " or " + quoted[-1], convert)


def _vector(value, n: int) -> list[float]:
    if not isinstance(value, list):
        raise Bad(f"must be a list of {n} numbers, got {show(value)}")
    if len(value) != n:
        raise Bad(f"must have {n} components, got {len(value)}")
    if not all(validate.is_real(v) for v in value):
        raise Bad(f"must be a list of {n} numbers, got {show(value)}")
    out = [validate.as_float(v) for v in value]
    if not all(validate.within(v) for v in out):
        raise Bad(f"must be finite, got {show(value)}")
    return out


def vector(n: int, *, nonzero: bool = False, positive: bool = False, nonneg: bool = False) -> Check:
    """A list of n finite floats; optionally not all zero, or each > 0, or each >= 0."""

    def convert(value):
        v = _vector(value, n)
        if nonzero and validate.is_zero(v):
            raise Bad("must not be the zero vector")
        if positive and any(x <= 0 for x in v):
            raise Bad(f"components must all be > 0, got {show(value)}")
        if nonneg and any(x < 0 for x in v):
            raise Bad(f"components must all be >= 0, got {show(value)}")
        return v

    names = {2: "[a, b]", 3: "[x, y, z]", 4: "[x, y, z, w]"}[n]
    qual = ", non-zero" if nonzero else ", each > 0" if positive else ", each >= 0" if nonneg else ""
    return Check(f"{names} floats{qual}", convert)


def quaternion() -> Check:
    """A non-zero quaternion (x, y, z, w); the World normalises it."""

    def convert(value):
        v = _vector(value, 4)
        if validate.is_zero(v):
            raise Bad("must be a non-zero quaternion [x, y, z, w]")
        return v

    return Check("[x, y, z, w] floats, non-zero", convert)


def value_or_range(*, positive: bool) -> Check:
    """A number v or a range [min, max] with min <= max; v > 0 (positive) or v >= 0."""
    op = ">" if positive else ">="

    def one(v, value):
        x = _number(v)
        if not validate.within(x, low=0.0, above=positive):
            raise Bad(f"must be {op} 0, got {show(value)}")
        return x

    def convert(value):
        if isinstance(value, list):
            if len(value) != 2:
                raise Bad(f"must be a number or a range [min, max], got {len(value)} values")
            lo, hi = one(value[0], value), one(value[1], value)
            if lo > hi:
                raise Bad(f"range [min, max] must have min <= max, got {show(value)}")
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
                raise Bad(f"range [min, max] must have min <= max in each component, got {show(value)}")
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
            raise Bad("must name at least one shape")
        for item in items:
            if not isinstance(item, str):
                raise Bad(f"must be a shape name or a list of them, got {show(value)}")
            if item not in names:
                raise Bad(f'unknown shape {item!r}: expected "sphere", "box", "capsule" or "convex"')
        return value if isinstance(value, str) else list(items)

    return Check('"sphere", "box", "capsule", "convex" or a list of them', convert)


SPRING_KINDS = ("structural", "shear", "bend")


def point_list() -> Check:
    """A list of at least four [x, y, z] points (the convex hull is taken)."""

    def convert(value):
        if not isinstance(value, list) or len(value) < 4:
            raise Bad(f"must be a list of at least 4 points [x, y, z], got {show(value)}")
        return [_vector(v, 3) for v in value]

    return Check("list of [x, y, z] floats, at least 4", convert)


def file_name() -> Check:
    """A file path (relative paths are taken from the scene file's folder)."""

    def convert(value):
        if not isinstance(value, str) or not value.strip():
            raise Bad(f"must be a file name in quotes, got {show(value)}")
        return value

    return Check("string (a path)", convert)


def scale_factor() -> Check:
    """One positive factor, or three (per axis)."""

    def convert(value):
        if validate.is_real(value):
            v = _number(value)
            if not validate.within(v, low=0.0, above=True):
                raise Bad(f"must be > 0, got {show(value)}")
            return v
        return vector(3, positive=True).convert(value)

    return Check("float > 0 or [x, y, z] floats, each > 0", convert)


def convex_rules(values: dict) -> None:
    solid_rules(values)
    if (values.get("points") is None) == (values.get("file") is None):
        raise KeyBad("points", "give points or file (one of them)")


def per_spring() -> Check:
    """A number >= 0 for every spring kind, or a table with some of {structural, shear, bend}."""
    each = number(low=0)

    def convert(value):
        if isinstance(value, dict):
            out = {}
            for k, v in value.items():
                if k not in SPRING_KINDS:
                    raise Bad(f"unknown spring kind {k!r}: expected {', '.join(SPRING_KINDS)}")
                try:
                    out[k] = each(v)
                except Bad as exc:
                    raise Bad(f"{k} {exc}") from None
            return out
        return each(value)

    return Check("float >= 0 or { structural, shear, bend }", convert)


PIN_NAMES = ("corners", "top-corners", "top-edge")


def pins() -> Check:
    def convert(value):
        if isinstance(value, str):
            return choice(*PIN_NAMES)(value)
        if not isinstance(value, list):
            raise Bad(f"must be {', '.join(map(repr, PIN_NAMES))} or a list of [i, j], got {show(value)}")
        out = []
        for item in value:
            if (
                not isinstance(item, list)
                or len(item) != 2
                or not all(isinstance(v, int) and not isinstance(v, bool) for v in item)
            ):
                raise Bad(f"each pin must be a grid point [i, j] of two integers, got {show(item)}")
            out.append((int(item[0]), int(item[1])))
        return out

    return Check('"corners", "top-corners", "top-edge" or a list of [i, j]', convert)


def resolution() -> Check:
    def convert(value):
        if not isinstance(value, list) or len(value) != 2:
            raise Bad(f"must be [nx, ny], got {show(value)}")
        out = [integer(low=2)(v) for v in value]
        return out

    return Check("[nx, ny] integers >= 2", convert)


def mass_or_density(values: dict, *, emitter: bool = False) -> None:
    if values.get("mass") is not None and values.get("density") is not None:
        raise KeyBad("density", "give mass or density, not both")
    _mass_representable(values, emitter=emitter)


def solid_rules(values: dict) -> None:
    """The cross-key rules of a solid body's table: mass or density, and a static body given no velocity."""
    mass_or_density(values)
    if values.get("static"):
        for key in ("velocity", "angular_velocity"):
            if any(values.get(key) or ()):
                raise KeyBad(
                    key,
                    "a static body never moves, so it cannot be given a velocity; "
                    "set kinematic = true (not static) to move it by a velocity",
                )


def _extremes(value) -> list[float]:
    """The smallest and largest number in a value, a range or a nested list of them (one if they are equal)."""
    flat = np.asarray([value], dtype=object).ravel().tolist()
    while any(isinstance(v, (list, tuple)) for v in flat):
        flat = [x for v in flat for x in (v if isinstance(v, (list, tuple)) else [v])]
    return sorted({min(flat), max(flat)}) if flat else []  # one value when they are equal


def _mass_representable(values: dict, *, emitter: bool = False) -> None:
    """Refuse sizes or masses whose mass or inertia (or their inverses) overflow or vanish in float64.

    A sphere of radius 1e300 would weigh inf kg and one of radius 1e-300 nothing; the solver
    divides by both. A box is checked with its half extents; an emitter's ranges by their
    extremes (as spheres or cubes), each times the extremes of its `scale`, and its `points` as
    the box they span.
    """
    from ...shapes import DEFAULT_DENSITY, box_inertia, box_volume, sphere_inertia, sphere_volume

    mass, density = values.get("mass"), values.get("density")
    scales = _extremes(1.0 if values.get("scale") is None else values["scale"]) if emitter else [1.0]
    sizes: list[tuple[str, bool, str, Any]] = []  # (key, box or not, shown size, size)
    for key in ("radius", "half_extents"):
        size = values.get(key)
        if size is None:
            continue
        if key == "half_extents" and isinstance(size, list) and len(size) == 3:
            sizes.append((key, True, show(size), size))  # a box's own half extents
            continue
        for r in _extremes(size):  # a range's extremes, as spheres or cubes
            sizes.append((key, key == "half_extents", show(r), [r, r, r] if key == "half_extents" else r))
    points = values.get("points")
    if points is not None and emitter:
        span = [float(v) for v in (np.max(points, axis=0) - np.min(points, axis=0)) / 2.0]
        if min(span) == 0.0:  # (the hull, taken when the scene is built, finds any other flat set)
            raise KeyBad("points", "the points span no volume (they are coplanar or collinear)")
        sizes.append(("points", True, show(span), span))
    with np.errstate(all="ignore"):
        for key, box, shown, unscaled in sizes:
            for s in scales:
                h = np.multiply(unscaled, s)
                volume = float(box_volume(h) if box else sphere_volume(h))
                masses = (
                    _extremes(mass) if mass is not None else [d * volume for d in _extremes(density or DEFAULT_DENSITY)]
                )
                for m in masses:
                    inertia = box_inertia(m, h) if box else sphere_inertia(m, h)
                    if not validate.mass_properties_usable(m, inertia):
                        raise KeyBad(
                            key if s == 1.0 else "scale",
                            f"a size of {shown} m{'' if s == 1.0 else f' times scale {s:g}'} gives a mass of "
                            f"{m:g} kg and moments of inertia down to {float(np.min(inertia)):g} kg m^2; both "
                            "(and their inverses) must be finite and > 0 in float64",
                        )


class KeyBad(Exception):
    """A cross-key rule failed at `key`."""

    def __init__(self, key: str, message: str):
        super().__init__(message)
        self.key = key


def emitter_rules(values: dict) -> None:
    mass_or_density(values, emitter=True)
    shapes = [values["shape"]] if isinstance(values["shape"], str) else values["shape"]
    if "sphere" in shapes and values.get("radius") is None:
        raise KeyBad("radius", "a sphere emitter needs radius (a value or [min, max])")
    if "box" in shapes and values.get("half_extents") is None:
        raise KeyBad("half_extents", "a box emitter needs half_extents (a value or [min, max])")
    if "capsule" in shapes and (values.get("radius") is None or values.get("half_height") is None):
        key = "radius" if values.get("radius") is None else "half_height"
        raise KeyBad(key, "a capsule emitter needs radius and half_height (each a value or [min, max])")
    if "convex" in shapes and (values.get("points") is None) == (values.get("file") is None):
        raise KeyBad("points", "a convex emitter needs points or file (one of them)")
    if "convex" not in shapes and (values.get("points") is not None or values.get("file") is not None):
        key = "points" if values.get("points") is not None else "file"
        raise KeyBad(key, f'{key} is for shape "convex", which this emitter does not emit')
    region, ext = values["region"], values.get("extent")
    if region == "box" and not isinstance(ext, list):
        raise KeyBad("extent", 'region "box" needs extent = [x, y, z] half-sizes')
    if region == "disc" and not isinstance(ext, float):
        raise KeyBad("extent", 'region "disc" needs extent = a radius in m')


def cloth_rules(values: dict) -> None:
    if values.get("mass") is not None and values.get("areal_density") is not None:
        raise KeyBad("areal_density", "give mass or areal_density, not both")
    nx, ny = values["resolution"]
    if isinstance(values.get("pins"), list):
        for i, j in values["pins"]:
            if not (0 <= i < nx and 0 <= j < ny):
                raise KeyBad("pins", f"pin [{i}, {j}] is outside the {nx} x {ny} grid")


def joint_rules(values: dict) -> None:
    if values["body_a"] == values["body_b"]:
        raise KeyBad("body_b", f"a joint needs two different bodies, got {values['body_b']!r} twice")
    for lo, hi in (("lower", "upper"), ("min_length", "max_length")):
        if values.get(lo) is not None and values.get(hi) is not None and values[lo] > values[hi]:
            raise KeyBad(lo, f"{lo} {values[lo]:g} > {hi} {values[hi]:g}")
