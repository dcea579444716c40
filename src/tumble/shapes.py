"""Shape types and the mass properties of each shape.

Every body in a world has exactly one shape. Planes are static bodies too: they sit in the
same arrays as spheres and boxes, with inverse mass zero, so that one pair table handles
every combination.
"""

from __future__ import annotations

import enum
from typing import TypedDict

import numpy as np
from numpy.typing import ArrayLike

from .keywords import defaults

#: density [kg/m^3] of a body given neither mass nor density (water)
DEFAULT_DENSITY = 1000.0
#: default coefficient of restitution of a body (every `World.add_*`, emitters, scene tables)
DEFAULT_RESTITUTION = 0.5
#: default friction coefficient of a body
DEFAULT_FRICTION = 0.5


class SolidOptions(TypedDict, total=False):
    """The keywords every solid body's adder takes beside its position and size: `World.add_sphere`,
    `add_box`, `add_capsule`, `add_convex` and the batch adders `add_spheres`, `add_boxes`, `add_capsules`.

    A batch adder takes one value for all its bodies, or one a body (mass and density shape (n,),
    velocity and angular velocity (n, 3), orientation (n, 4)). The defaults are in the table below
    (`tumble.shapes.SOLID_DEFAULTS`).

    Keys:
        mass: [kg], > 0. Give `mass` or `density`; with neither, density is 1000 kg/m^3.
        density: [kg/m^3], > 0.
        velocity: initial linear velocity [m/s], shape (3,).
        orientation: initial orientation (x, y, z, w). A convex body's is
            its user frame's (`World.add_convex`).
        angular_velocity: initial angular velocity, world frame [rad/s], shape (3,).
        restitution: coefficient of restitution in [0, 1].
        friction: Coulomb friction coefficient (>= 0).
        static: if True the body never moves (inverse mass 0); a velocity or angular velocity
            other than 0 is refused (a kinematic body is the one that moves by a velocity).
        kinematic: if True the body moves only with the velocity it is given (at creation or by
            `World.set_body_state` / `World.set_kinematic_target`), unaffected by gravity and
            contacts, and pushes dynamic bodies as a body of infinite mass would.
    """

    mass: float | ArrayLike | None
    density: float | ArrayLike | None
    velocity: ArrayLike
    orientation: ArrayLike
    angular_velocity: ArrayLike
    restitution: float
    friction: float
    static: bool
    kinematic: bool


#: the defaults of `SolidOptions`, read by the body adders and the scene schema
SOLID_DEFAULTS = defaults(
    SolidOptions,
    mass=None,
    density=None,
    velocity=(0.0, 0.0, 0.0),
    orientation=(0.0, 0.0, 0.0, 1.0),
    angular_velocity=(0.0, 0.0, 0.0),
    restitution=DEFAULT_RESTITUTION,
    friction=DEFAULT_FRICTION,
    static=False,
    kinematic=False,
)


class ShapeType(enum.IntEnum):
    """Closed set of collision shapes, in pair-table order (see `collision.narrowphase`)."""

    PLANE = 0
    SPHERE = 1
    BOX = 2
    CAPSULE = 3
    CONVEX = 4
    MESH = 5


SHAPE_NAMES: tuple[str, ...] = tuple(s.name.lower() for s in ShapeType)


#: sizes far outside any scene's (1e300 m) overflow to inf here without a warning; the callers refuse them
_QUIET = np.errstate(over="ignore", under="ignore", invalid="ignore")


def shape_from_name(name: str) -> ShapeType:
    """Return the `ShapeType` called `name` ("plane", "sphere", "box", "capsule", ...).

    Raises:
        ValueError: for any other name, listing the known ones.
    """
    try:
        return ShapeType[str(name).upper()]
    except KeyError:
        raise ValueError(f"unknown shape {name!r}: expected one of {', '.join(SHAPE_NAMES)}") from None


@_QUIET
def sphere_volume(radius):
    """Volume of spheres [m^3]: 4/3 pi r^3 (a number or an array of radii)."""
    return 4.0 / 3.0 * np.pi * np.asarray(radius, dtype=np.float64) ** 3


@_QUIET
def box_volume(half_extents):
    """Volume of boxes [m^3]: 8 hx hy hz, half extents shape (3,) or (n, 3)."""
    h = np.asarray(half_extents, dtype=np.float64)
    return 8.0 * h[..., 0] * h[..., 1] * h[..., 2]


@_QUIET
def sphere_inertia(mass, radius) -> np.ndarray:
    """Principal moments of solid spheres [kg m^2], shape (..., 3): I = 2/5 m r^2."""
    i = 0.4 * np.asarray(mass, dtype=np.float64) * np.asarray(radius, dtype=np.float64) ** 2
    return np.repeat(i[..., None], 3, axis=-1)


@_QUIET
def box_inertia(mass, half_extents) -> np.ndarray:
    """Principal moments of solid boxes [kg m^2], shape (..., 3).

    With half extents (a, b, c): Ixx = m/3 (b^2 + c^2), and so on by cycling the axes.
    """
    h2 = np.asarray(half_extents, dtype=np.float64) ** 2
    m = np.asarray(mass, dtype=np.float64)[..., None]
    return m / 3.0 * (np.sum(h2, axis=-1, keepdims=True) - h2)


@_QUIET
def capsule_volume(radius, half_height):
    """Volume of capsules [m^3]: a cylinder of length 2 a and two hemispheres, pi r^2 (2 a + 4/3 r)."""
    r = np.asarray(radius, dtype=np.float64)
    a = np.asarray(half_height, dtype=np.float64)
    return np.pi * r**2 * (2.0 * a + 4.0 / 3.0 * r)


@_QUIET
def capsule_inertia(mass, radius, half_height) -> np.ndarray:
    """Principal moments of solid capsules about their centre [kg m^2], shape (..., 3); axis along z.

    With radius r and cylinder half length a, the mass splits by volume into the cylinder
    m_c = m 2a / (2a + 4/3 r) and two hemispheres m_h = (m - m_c) / 2 each. Then
    Izz = m_c r^2 / 2 + 2 (2/5 m_h r^2), and about a transverse axis through the centre
    Ixx = m_c (3 r^2 + (2a)^2) / 12 + 2 m_h (2/5 r^2 + a^2 + 3/4 a r): a hemisphere's moment about
    a diameter of its flat face is 2/5 m_h r^2, its centre of mass lies 3r/8 from that face, so
    moving it to the capsule's centre (distance a + 3r/8) by the parallel-axis theorem gives
    2/5 m_h r^2 - m_h (3r/8)^2 + m_h (a + 3r/8)^2.
    """
    m = np.asarray(mass, dtype=np.float64)
    r = np.asarray(radius, dtype=np.float64)
    a = np.asarray(half_height, dtype=np.float64)
    m_c = m * 2.0 * a / (2.0 * a + 4.0 / 3.0 * r)
    m_h = 0.5 * (m - m_c)
    i_z = 0.5 * m_c * r**2 + 0.8 * m_h * r**2
    i_x = m_c * (3.0 * r**2 + 4.0 * a**2) / 12.0 + 2.0 * m_h * (0.4 * r**2 + a**2 + 0.75 * a * r)
    return np.stack(np.broadcast_arrays(i_x, i_x, i_z), axis=-1)
