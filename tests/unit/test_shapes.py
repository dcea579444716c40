"""shapes.py: shape names, and volumes and principal moments against independent integrals.

The references integrate the density over the solid with Gauss-Legendre quadrature (exact for
the polynomial integrands used here), or take the volume and inertia tensor of the box's
polyhedron from collision/hulls (a different algorithm: a sum over tetrahedra).
"""

from __future__ import annotations

import numpy as np
import pytest

from tumble import shapes
from tumble.collision.hulls import polyhedron_mass_properties
from tumble.shapes import ShapeType

#: Gauss-Legendre nodes and weights on [-1, 1]: exact for polynomials up to degree 2 * 8 - 1
NODES, WEIGHTS = np.polynomial.legendre.leggauss(8)


def integrate(f, lo: float, hi: float) -> float:
    """The integral of f over [lo, hi] by 8-point Gauss-Legendre."""
    x = 0.5 * (hi - lo) * NODES + 0.5 * (hi + lo)
    return float(0.5 * (hi - lo) * np.sum(WEIGHTS * f(x)))


def test_shape_names_round_trip_in_pair_table_order():
    """Every name maps to its ShapeType; the order is the pair table's (plane first)."""
    assert shapes.SHAPE_NAMES == ("plane", "sphere", "box", "capsule", "convex", "mesh")
    for k, name in enumerate(shapes.SHAPE_NAMES):
        assert shapes.shape_from_name(name) is ShapeType(k)
        assert shapes.shape_from_name(name.upper()) is ShapeType(k)


def test_unknown_shape_name_lists_the_known_ones():
    """An unknown name raises ValueError naming it and every known shape."""
    with pytest.raises(ValueError, match=r"unknown shape 'cone': expected one of plane, sphere, box"):
        shapes.shape_from_name("cone")


@pytest.mark.parametrize("r", [0.05, 0.5, 2.0])
def test_sphere_volume_and_inertia_match_disc_slabs(r):
    """A sphere as discs of radius rho(z) = sqrt(r^2 - z^2): V = int pi rho^2, I_z = int pi rho^4 / 2."""
    volume = integrate(lambda z: np.pi * (r * r - z * z), -r, r)
    i_z = integrate(lambda z: 0.5 * np.pi * (r * r - z * z) ** 2, -r, r)  # per unit density
    assert shapes.sphere_volume(r) == pytest.approx(volume, rel=1e-12)
    mass = 3.0
    expected = mass / volume * i_z
    assert shapes.sphere_inertia(mass, r) == pytest.approx([expected] * 3, rel=1e-12)


def test_box_volume_and_inertia_match_the_triple_integral():
    """I_xx = rho int (y^2 + z^2) dV over [-a, a] x [-b, b] x [-c, c], for a batch of boxes."""
    half = np.array([[0.5, 0.5, 0.5], [1.0, 0.2, 0.05], [0.1, 3.0, 0.7]])
    mass = np.array([1.0, 2.5, 0.3])
    inertia = shapes.box_inertia(mass, half)
    volume = shapes.box_volume(half)
    assert inertia.shape == (3, 3) and volume.shape == (3,)
    for k, (h, m) in enumerate(zip(half, mass)):
        length = 2.0 * h  # edge lengths
        second = np.array([integrate(lambda u: u * u, -hi, hi) for hi in h])  # int u^2 du per axis
        v = float(np.prod(length))
        # int (y^2 + z^2) dV = (int y^2 dy) L_x L_z + (int z^2 dz) L_x L_y, and so on
        moments = [sum(second[j] * v / length[j] for j in range(3) if j != i) for i in range(3)]
        assert volume[k] == pytest.approx(v, rel=1e-12)
        assert inertia[k] == pytest.approx(m / v * np.array(moments), rel=1e-12)


def test_box_inertia_matches_its_polyhedron():
    """The box formula agrees with the tetrahedron sum of collision/hulls for the same solid."""
    h = np.array([0.3, 0.7, 1.1])
    corners = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], dtype=float) * h
    faces = [np.array(f) for f in ([0, 2, 3, 1], [4, 5, 7, 6], [0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3])]
    volume, com, tensor = polyhedron_mass_properties(corners, faces)
    assert volume == pytest.approx(shapes.box_volume(h), rel=1e-12)
    assert com == pytest.approx(np.zeros(3), abs=1e-12)
    # polyhedron moments are at density 1: mass = volume
    assert np.diag(tensor) == pytest.approx(shapes.box_inertia(volume, h), rel=1e-12)
    assert tensor - np.diag(np.diag(tensor)) == pytest.approx(np.zeros((3, 3)), abs=1e-12)


@pytest.mark.parametrize(("r", "a"), [(0.1, 0.3), (0.5, 0.05), (0.2, 2.0)])
def test_capsule_volume_matches_disc_slabs(r, a):
    """A capsule along z as discs: radius r over |z| <= a, sqrt(r^2 - (|z| - a)^2) over the caps."""
    cylinder = 2.0 * a * np.pi * r * r
    caps = 2.0 * integrate(lambda z: np.pi * (r * r - (z - a) ** 2), a, a + r)
    assert shapes.capsule_volume(r, a) == pytest.approx(cylinder + caps, rel=1e-12)


def test_capsule_without_cylinder_is_a_sphere_and_broadcasts():
    """Half height 0 gives the sphere's moments; arrays of radii give one row per capsule."""
    assert shapes.capsule_inertia(2.0, 0.3, 0.0) == pytest.approx(shapes.sphere_inertia(2.0, 0.3), rel=1e-12)
    assert shapes.capsule_volume(0.3, 0.0) == pytest.approx(shapes.sphere_volume(0.3), rel=1e-12)
    rows = shapes.capsule_inertia(np.array([1.0, 2.0]), np.array([0.1, 0.2]), np.array([0.5, 0.0]))
    assert rows.shape == (2, 3)
    assert rows[1] == pytest.approx(shapes.sphere_inertia(2.0, 0.2), rel=1e-12)
    # a long thin capsule tends to a rod: I_x -> m L^2 / 12, I_z -> m r^2 / 2
    rod = shapes.capsule_inertia(1.0, 1e-4, 1.0)
    assert rod[0] == pytest.approx(1.0 * 2.0**2 / 12.0, rel=1e-3)
    assert rod[2] == pytest.approx(0.5 * 1e-8, rel=1e-3)
