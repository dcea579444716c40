"""Shape types and the mass properties of each shape.

Every body in a world has exactly one shape. Planes are static bodies too: they sit in the
same arrays as spheres and boxes, with inverse mass zero, so that one pair table handles
every combination.
"""

from __future__ import annotations

import enum

import numpy as np


class ShapeType(enum.IntEnum):
    """Closed set of collision shapes, in pair-table order (see `collision.narrowphase`)."""

    PLANE = 0
    SPHERE = 1
    BOX = 2


SHAPE_NAMES: tuple[str, ...] = tuple(s.name.lower() for s in ShapeType)


def shape_from_name(name: str) -> ShapeType:
    """Return the `ShapeType` called `name` ("plane", "sphere" or "box").

    Raises:
        ValueError: for any other name, listing the known ones.
    """
    try:
        return ShapeType[str(name).upper()]
    except KeyError:
        raise ValueError(f"unknown shape {name!r}: expected one of {', '.join(SHAPE_NAMES)}") from None


def sphere_volume(radius: float) -> float:
    """Volume of a sphere [m^3]: 4/3 pi r^3."""
    return 4.0 / 3.0 * np.pi * radius**3


def box_volume(half_extents) -> float:
    """Volume of a box [m^3]: 8 hx hy hz."""
    h = np.asarray(half_extents, dtype=np.float64)
    return float(8.0 * h[0] * h[1] * h[2])


def sphere_inertia(mass: float, radius: float) -> np.ndarray:
    """Principal moments of a solid sphere [kg m^2], shape (3,): I = 2/5 m r^2."""
    return np.full(3, 0.4 * mass * radius * radius)


def box_inertia(mass: float, half_extents) -> np.ndarray:
    """Principal moments of a solid box [kg m^2], shape (3,).

    With half extents (a, b, c): Ixx = m/3 (b^2 + c^2), and so on by cycling the axes.
    """
    a, b, c = np.asarray(half_extents, dtype=np.float64)
    return mass / 3.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
