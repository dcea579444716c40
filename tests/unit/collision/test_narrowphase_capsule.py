"""Capsules: mass properties against independent integrals, and every narrow-phase pair with a capsule."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import tumble
from tolerances import resolution, stored
from tumble import shapes

from ..reference import quat_axis_angle, rotate

MARGIN = 0.002


LYING = quat_axis_angle((1, 0, 0), np.pi / 2)  # capsule axis along world y


def contacts(world):
    world.collide()
    return world.contact_pair, world.contact_normal, world.contact_depth, world.contact_point


# ------------------------------------------------------------------ mass properties


def slab_integrals(r, a, density=1.0):
    """Volume, Ixx, Izz of a z-axis capsule by Gauss-Legendre quadrature over thin discs.

    A disc of radius R at height z adds dV = pi R^2 dz, dIzz = pi R^4 / 2 dz and
    dIxx = pi R^2 (R^2 / 4 + z^2) dz; R(z) = r on the cylinder and sqrt(r^2 - (|z| - a)^2) on the caps.
    """
    x, wts = np.polynomial.legendre.leggauss(200)
    total = np.zeros(3)
    for lo, hi in ((-a - r, -a), (-a, a), (a, a + r)):
        z = 0.5 * (hi - lo) * x + 0.5 * (hi + lo)
        R2 = np.where(np.abs(z) <= a, r * r, np.maximum(r * r - (np.abs(z) - a) ** 2, 0.0))
        f = np.stack([np.pi * R2, np.pi * R2 * (R2 / 4 + z * z), np.pi * R2 * R2 / 2])
        total += density * 0.5 * (hi - lo) * f @ wts
    return total


@pytest.mark.parametrize("r, a", [(0.1, 0.2), (0.05, 0.5), (0.3, 0.01)])
def test_capsule_mass_properties_match_slab_integrals(r, a):
    """Match the closed-form volume and moments with a numerical integral over discs."""
    volume, ixx, izz = slab_integrals(r, a)
    assert shapes.capsule_volume(r, a) == pytest.approx(volume, rel=1e-6)
    inertia = shapes.capsule_inertia(volume, r, a)  # density 1: mass = volume
    np.testing.assert_allclose(inertia, [ixx, ixx, izz], rtol=1e-6)


def test_capsule_of_zero_length_is_a_sphere():
    """Give a capsule of half height 0 the volume and moments of a sphere."""
    assert shapes.capsule_volume(0.2, 0.0) == pytest.approx(shapes.sphere_volume(0.2))
    np.testing.assert_allclose(shapes.capsule_inertia(3.0, 0.2, 0.0), shapes.sphere_inertia(3.0, 0.2))


def test_add_capsule_uses_density_and_inertia():
    """Give add_capsule's body mass = density x volume and the capsule's inverse moments."""
    w = tumble.World()
    c = w.add_capsule(position=(0, 0, 1), radius=0.1, half_height=0.3, density=500)
    m = 500 * shapes.capsule_volume(0.1, 0.3)
    assert w.body_mass[c] == pytest.approx(m)
    i = np.diag(w.body_inertia_world[c])
    # the stored inverse moments, inverted back: a few ulps
    np.testing.assert_allclose(i, shapes.capsule_inertia(m, 0.1, 0.3), rtol=resolution(1e-12, 1.0, 4))


@pytest.mark.parametrize(
    "kwargs",
    [dict(radius=0.0, half_height=0.1), dict(radius=0.1, half_height=-1), dict(radius=float("nan"), half_height=0.1)],
)
def test_add_capsule_rejects_bad_sizes(kwargs):
    """Reject a capsule radius or half height that is not a positive number."""
    with pytest.raises(ValueError, match="radius|half_height"):
        tumble.World().add_capsule(position=(0, 0, 0), **kwargs)


# ------------------------------------------------------------------ plane-capsule


@pytest.mark.parametrize(
    "gap, expect",
    [(0.5, 0), (MARGIN / 2, 2), (0.0, 2), (-0.01, 2)],
    ids=["separated", "speculative", "touching", "overlapping"],
)
def test_plane_capsule_lying_gives_two_contacts(gap, expect):
    """Give a capsule lying on a plane one contact under each end sphere, depth -gap, normal +z."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_plane()
    w.add_capsule(position=(0, 0, 0.1 + gap), radius=0.1, half_height=0.3, orientation=LYING)
    pairs, normals, depths, points = contacts(w)
    assert len(depths) == expect
    if expect:
        # the end spheres turned by LYING: 8 ulps of the capsule's reach (0.4)
        atol = resolution(1e-12, 0.4, 8)
        np.testing.assert_allclose(depths, -gap, atol=atol)
        np.testing.assert_allclose(normals, [[0, 0, 1]] * 2, atol=resolution(1e-12, 1.0, 4))
        np.testing.assert_allclose(sorted(points[:, 1]), [-0.3, 0.3], atol=atol)


def test_plane_capsule_standing_gives_one_contact():
    """Give an upright capsule only its lower end as contact, at depth r + a - z."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_plane()
    w.add_capsule(position=(0, 0, 0.39), radius=0.1, half_height=0.3)
    _, normals, depths, _ = contacts(w)
    # r + a - z: 8 ulps of the capsule's reach (0.4), or approx's 1e-6 of the depth in float64
    assert depths == pytest.approx([0.01], abs=resolution(1e-8, 0.4, 8))
    np.testing.assert_allclose(normals[0], [0, 0, 1])


# ------------------------------------------------------------------ sphere-capsule


@pytest.mark.parametrize("swapped", [False, True])
@pytest.mark.parametrize("where", ["side", "cap"])
def test_sphere_capsule(where, swapped):
    """Measure depth from the nearest segment point, normal from the first body to the second."""
    r, rc, a = 0.05, 0.1, 0.3
    # side: beside the cylinder at height 0.1; cap: above the top end
    p = np.array([0.14, 0, 0.1]) if where == "side" else np.array([0, 0, a + 0.14])
    w = tumble.World(gravity=(0, 0, 0))
    if swapped:
        w.add_capsule(position=(0, 0, 0), radius=rc, half_height=a)
        w.add_sphere(position=p, radius=r)
    else:
        w.add_sphere(position=p, radius=r)
        w.add_capsule(position=(0, 0, 0), radius=rc, half_height=a)
    pairs, normals, depths, _ = contacts(w)
    # distance from the segment: 8 ulps of the positions (up to 0.44)
    assert depths == pytest.approx([0.01], abs=resolution(1e-12, 0.5, 8))
    outward = np.array([1.0, 0, 0]) if where == "side" else np.array([0, 0, 1.0])
    sphere = 1 if swapped else 0
    expected = -outward if pairs[0, 0] == sphere else outward  # a -> b
    np.testing.assert_allclose(normals[0], expected, atol=resolution(1e-12, 1.0, 4))


def test_sphere_on_capsule_axis_gets_a_perpendicular_normal():
    """Give a sphere centred on the capsule's segment a unit normal perpendicular to the axis."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_sphere(position=(0, 0, 0.1), radius=0.05)
    w.add_capsule(position=(0, 0, 0), radius=0.1, half_height=0.3)
    _, normals, depths, _ = contacts(w)
    assert depths == pytest.approx([0.15])
    assert np.linalg.norm(normals[0]) == pytest.approx(1.0)
    assert normals[0, 2] == pytest.approx(0.0, abs=1e-12)


# ------------------------------------------------------------------ box-capsule


def brute_box_segment(p0, u, hh, half):
    """Smallest signed distance of the points p0 + t u (t in [-hh, hh]) from a box, by dense sampling."""
    t = np.linspace(-hh, hh, 20001)
    p = p0[None] + t[:, None] * u[None]
    outside = np.linalg.norm(np.maximum(np.abs(p) - half, 0.0), axis=1)
    inside = np.min(half - np.abs(p), axis=1)
    d = np.where(np.all(np.abs(p) <= half, axis=1), -inside, outside)
    return d.min()


def test_box_capsule_lying_on_face_gives_a_line_contact():
    """Give a capsule lying across a box's top face the two ends of the part over the face."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_box(position=(0, 0, 0), half_extents=(0.5, 0.2, 0.1), static=True)
    w.add_capsule(position=(0, 0, 0.19), radius=0.1, half_height=0.4, orientation=LYING)  # axis along y
    _, normals, depths, points = contacts(w)
    # the segment turned by LYING and clipped to the face: 8 ulps of the shapes' size (0.5)
    np.testing.assert_allclose(depths, [0.01, 0.01], atol=resolution(1e-12, 0.5, 8))
    np.testing.assert_allclose(normals, [[0, 0, 1]] * 2, atol=resolution(1e-12, 1.0, 4))
    np.testing.assert_allclose(sorted(points[:, 1]), [-0.2, 0.2], atol=resolution(1e-9, 0.5, 8))  # clipped to the face


def test_box_capsule_across_an_edge():
    """Give a capsule crossing a box edge one contact whose normal bisects the two faces."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_box(position=(0, 0, 0), half_extents=(0.1, 0.1, 0.1), static=True)
    # axis along y, centre diagonally out from the edge x = z = 0.1
    d = 0.1 + (0.1 - 0.005) / np.sqrt(2)
    w.add_capsule(position=(d, 0, d), radius=0.1, half_height=0.4, orientation=LYING)
    pairs, normals, depths, _ = contacts(w)
    assert depths == pytest.approx([0.005], abs=resolution(1e-7, 0.3, 16))
    # the segment runs parallel to the edge, so its distance from the box is flat along the 0.2 m
    # over it: golden section stopped up to sqrt(2 eps) of the distance past the flat part, and the
    # normal tilted by as much along y (2e-8 in float64, 4e-4 in float32) until the segment point
    # was projected back over the edge (`_nearest_on_segment`): now square to it but for rounding
    np.testing.assert_allclose(normals[0], [2**-0.5, 0, 2**-0.5], atol=resolution(1e-6, 1.0, 16))


@settings(max_examples=80, deadline=None)
@given(
    centre=st.tuples(*[st.floats(-0.5, 0.5)] * 3),
    axis=st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 0.2),
    box_angle=st.floats(0, 3),
)
def test_box_capsule_deepest_matches_brute_force(centre, axis, box_angle):
    """Make the deepest box-capsule contact the brute-force smallest signed distance, less the radius."""
    r, hh, half = 0.08, 0.25, np.array([0.2, 0.15, 0.1])
    qb = stored(quat_axis_angle((1, 2, 3), box_angle))
    centre = stored(centre)
    u = np.asarray(axis) / np.linalg.norm(axis)
    z = np.array([0.0, 0.0, 1.0])
    c = np.cross(z, u)
    qc = np.r_[c, 1.0 + z @ u] if np.linalg.norm(c) > 1e-9 or z @ u > 0 else np.array([1.0, 0, 0, 0])
    qc = stored(qc / np.linalg.norm(qc))
    w = tumble.World(gravity=(0, 0, 0))
    w.add_box(position=(0, 0, 0), half_extents=half, orientation=qb, static=True)
    w.add_capsule(position=centre, radius=r, half_height=hh, orientation=qc)
    # the segment in the box frame
    inv = np.r_[-qb[:3], qb[3]]
    p0 = rotate(inv, np.asarray(centre))
    ul = rotate(inv, rotate(qc, z))
    expected = brute_box_segment(p0, ul, hh, half) - r
    _, normals, depths, _ = contacts(w)
    if expected > 0.01:
        assert len(depths) == 0
        return
    if expected < -0.001 or len(depths):
        assert len(depths) >= 1
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, rtol=resolution(1e-7, 1.0, 4))
        if expected > -r:
            # the segment is outside the box: the deepest contact is the true one (sampling: +-1e-4)
            assert -depths.max() == pytest.approx(expected, abs=2e-4)
        else:
            # the segment enters the box: depths along the chosen face are at least the true one
            assert -depths.max() <= expected + 2e-4


# ------------------------------------------------------------------ capsule-capsule


def test_crossed_capsules_one_contact():
    """Give two crossed capsules one contact at depth r1 + r2 - distance of the axes."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_capsule(position=(0, 0, 0), radius=0.1, half_height=0.3, orientation=quat_axis_angle((0, 1, 0), np.pi / 2))
    w.add_capsule(position=(0, 0, 0.18), radius=0.1, half_height=0.3, orientation=LYING)
    pairs, normals, depths, points = contacts(w)
    assert depths == pytest.approx([0.02])
    # closest points of two turned segments: 8 ulps of their reach (0.3)
    n = [0, 0, 1] if pairs[0, 0] == 0 else [0, 0, -1]
    np.testing.assert_allclose(normals[0], n, atol=resolution(1e-12, 1.0, 8))
    np.testing.assert_allclose(points[0], [0, 0, 0.09], atol=resolution(1e-12, 0.3, 8))


@pytest.mark.parametrize("shift", [0.0, 0.2])
def test_parallel_capsules_two_contacts_at_the_overlap(shift):
    """Give parallel capsules side by side a contact at each end of their overlap along the axis."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_capsule(position=(0, 0, 0), radius=0.1, half_height=0.3, orientation=LYING)
    w.add_capsule(position=(0, shift, 0.19), radius=0.1, half_height=0.3, orientation=LYING)
    _, normals, depths, points = contacts(w)
    # two segments turned by LYING, their overlap clipped: 8 ulps of their reach (0.5)
    atol = resolution(1e-12, 0.5, 8)
    np.testing.assert_allclose(depths, [0.01, 0.01], atol=atol)
    np.testing.assert_allclose(np.abs(normals[:, 2]), 1.0, atol=resolution(1e-12, 1.0, 4))
    np.testing.assert_allclose(sorted(points[:, 1]), [-0.3 + shift, 0.3], atol=atol)


def brute_segments(pa, ua, la, pb, ub, lb):
    s = np.linspace(-la, la, 1201)
    t = np.linspace(-lb, lb, 1201)
    A = pa[None] + s[:, None] * ua[None]
    B = pb[None] + t[:, None] * ub[None]
    best = np.inf
    for chunk in np.array_split(A, 12):
        best = min(best, np.sqrt(((chunk[:, None] - B[None]) ** 2).sum(-1)).min())
    return best


@settings(max_examples=60, deadline=None)
@given(
    centre=st.tuples(*[st.floats(-0.4, 0.4)] * 3),
    qa=st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda v: np.linalg.norm(v) > 0.2),
    qb=st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda v: np.linalg.norm(v) > 0.2),
)
def test_capsule_capsule_matches_brute_force(centre, qa, qb):
    """Make the deepest capsule-capsule contact the sampled segment distance less both radii."""
    ra, rb, la, lb = 0.1, 0.07, 0.3, 0.2
    qa = stored(np.asarray(qa) / np.linalg.norm(qa))
    qb = stored(np.asarray(qb) / np.linalg.norm(qb))
    centre = stored(centre)
    w = tumble.World(gravity=(0, 0, 0))
    w.add_capsule(position=(0, 0, 0), radius=ra, half_height=la, orientation=qa)
    w.add_capsule(position=centre, radius=rb, half_height=lb, orientation=qb)
    z = np.array([0.0, 0, 1])
    dist = brute_segments(np.zeros(3), rotate(qa, z), la, np.asarray(centre), rotate(qb, z), lb)
    expected = dist - ra - rb
    pairs, normals, depths, points = contacts(w)
    if expected > 0.01:
        assert len(depths) == 0
        return
    if expected < -0.001 or len(depths):
        assert -depths.max() == pytest.approx(expected, abs=1e-3)
        # normal from a to b: moving b along it separates the segments
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, rtol=resolution(1e-7, 1.0, 4))


# ------------------------------------------------------------------ scene table


def test_capsule_table_builds_a_capsule(write_scene):
    """Build a [[capsule]] table into a capsule body with its radius and half height."""
    from tumble.io.scene import load_scene

    path = write_scene(
        "[[plane]]\n[[capsule]]\nposition = [0, 0, 1]\nradius = 0.1\nhalf_height = 0.25\n"
        "orientation = [0.7071068, 0, 0, 0.7071068]\n"
    )
    w = load_scene(path)
    assert list(w.body_shape) == [tumble.ShapeType.PLANE, tumble.ShapeType.CAPSULE]
    assert w.body_radius[1] == pytest.approx(0.1)
    np.testing.assert_allclose(w.body_half_extents[1], [0.1, 0.1, 0.35])
    assert w.body_mass[1] == pytest.approx(1000 * shapes.capsule_volume(0.1, 0.25))


def test_capsule_table_needs_half_height(write_scene):
    """Reject a [[capsule]] without half_height with one line naming the key."""
    from tumble.errors import SceneError
    from tumble.io.scene import read_scene

    path = write_scene("[[capsule]]\nposition = [0, 0, 1]\nradius = 0.1\n")
    with pytest.raises(SceneError, match="half_height"):
        read_scene(path)
