"""Emitters: rate, count, regions, cone, ranges, and no overlap at birth."""

from __future__ import annotations

import numpy as np
import pytest

import tumble
from tolerances import resolution
from tumble.shapes import ShapeType


def bound_radii(world):
    shape = world.body_shape
    return np.where(shape == ShapeType.SPHERE, world.body_radius, np.linalg.norm(world.body_half_extents, axis=1))


def test_emits_at_rate_up_to_count():
    """Bodies appear at `rate` per second until `count` have been released."""
    w = tumble.World(gravity=(0, 0, 0))
    em = w.add_emitter(rate=120, count=50, position=(0, 0, 0), region="box", extent=(2, 2, 2), radius=0.02)
    w.run(0.25)  # owes 30 bodies after 60 steps
    assert em.emitted == pytest.approx(30, abs=1)
    w.run(1.0)
    assert em.emitted == 50 and em.done and w.body_count == 50


def test_point_emitter_never_overlaps():
    """Bodies released from a single point scatter or wait rather than overlap anything."""
    w = tumble.World(seed=4)
    w.add_plane()
    em = w.add_emitter(
        shape=["sphere", "box"],
        rate=2000,
        count=200,
        position=(0, 0, 0.1),
        region="point",
        speed=(1.0, 2.0),
        cone_angle=60,
        direction=(0, 0, 1),
        radius=(0.03, 0.05),
        half_extents=(0.02, 0.04),
        random_orientation=True,
    )
    # release without moving anything, so every body is still where it was born
    for _ in range(100):
        w.emit()
    assert em.emitted > 50
    # the narrow phase (tested on its own) finds no overlap anywhere, ground included
    w.collide()
    assert w.contact_count > 0  # near neighbours are reported as speculative contacts ...
    assert np.all(w.contact_depth <= 0.0)  # ... but none overlaps


def test_new_bodies_clear_existing_ones():
    """A candidate spot taken by an existing body is not used."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_sphere(position=(0, 0, 0), radius=0.5, mass=1.0)
    w.add_emitter(rate=240, count=20, position=(0, 0, 0), region="box", extent=(1, 1, 1), radius=0.05, seed=1)
    for _ in range(10):
        before = w.body_count
        w.emit()
        x = w.body_position[before:]
        assert np.all(np.linalg.norm(x, axis=1) >= 0.55 - 1e-12)
        assert np.all(np.abs(x) <= 1.0 + 1e-12)


@pytest.mark.parametrize("shape", ["sphere", "box"])
def test_bodies_centred_outside_the_region_still_block_it(shape):
    """Only bodies reaching the region are tested, and 'reaching' counts their whole extent.

    A big body centred outside the emitter's box covers part of it: no new body may overlap it,
    and far bodies (a pile below) are left out of the test without changing any outcome.
    """
    w = tumble.World(gravity=(0, 0, 0))
    if shape == "sphere":
        w.add_sphere(position=(1.1, 0, 0), radius=1.0, mass=1.0)  # surface from x = 0.1 into the region
    else:
        w.add_box(position=(1.1, 0, 0), half_extents=(1.0, 1.0, 1.0), mass=1.0)
    far = np.stack(np.meshgrid(np.arange(10), np.arange(10), np.arange(3), indexing="ij"), -1).reshape(-1, 3)
    w.add_spheres(position=far * 0.2 + (-1.0, -1.0, -5.0), radius=0.09, mass=1.0)
    em = w.add_emitter(
        rate=2400, count=100, position=(0, 0, 0), region="box", extent=(0.2, 0.2, 0.2), radius=0.02, seed=3
    )
    first = w.body_count
    for _ in range(10):
        w.emit()
    assert em.emitted > 20
    w.collide()
    assert np.all(w.contact_depth <= 0.0)  # nothing overlaps the big body, or anything else
    x = w.body_position[first:]
    if shape == "sphere":
        assert np.all(np.linalg.norm(x - (1.1, 0, 0), axis=1) >= 1.02 - 1e-9)
    else:
        assert np.all(x[:, 0] <= 0.1 - 0.02 + 1e-9)


def test_cone_speed_and_size_ranges():
    """Launch directions lie in the cone, speeds and radii in their ranges, masses from density."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_emitter(
        rate=1e4,
        count=300,
        position=(0, 0, 0),
        region="disc",
        extent=5.0,
        direction=(1, 0, 0),
        cone_angle=20,
        speed=(2.0, 3.0),
        radius=(0.01, 0.02),
        density=500.0,
        seed=7,
    )
    w.emit(1.0)
    v = w.body_velocity
    speed = np.linalg.norm(v, axis=1)
    # velocities stored in the world's precision: a few ulps of the speed; the cone's angle from its
    # cosine, as many ulps over sin 20 degrees
    slack = resolution(1e-12, 3.0, 4)
    assert np.all((speed >= 2.0 - slack) & (speed <= 3.0 + slack))
    angle = np.degrees(np.arccos(np.clip(v[:, 0] / speed, -1, 1)))
    assert angle.max() <= 20.0 + resolution(1e-9, np.degrees(1.0 / np.sin(np.radians(20.0))), 4)
    assert angle.max() > 10.0  # the cone is used, not just its axis
    r = w.body_radius
    assert np.all((r >= 0.01) & (r <= 0.02))
    # the mass from the radius before it was stored, r^3: a few ulps
    np.testing.assert_allclose(w.body_mass, 500.0 * 4 / 3 * np.pi * r**3, rtol=resolution(1e-12, 1.0, 4))
    # the disc lies across the direction: x is constant, |(y, z)| <= 5
    x = w.body_position
    np.testing.assert_allclose(x[:, 0], 0.0, atol=1e-12)
    assert np.all(np.linalg.norm(x[:, 1:], axis=1) <= 5.0 + resolution(1e-12, 5.0, 4))


def test_seeded_emitters_repeat():
    """The same seed gives the same bodies."""

    def positions():
        w = tumble.World(gravity=(0, 0, 0), seed=11)
        w.add_emitter(rate=500, count=40, position=(0, 0, 0), region="box", extent=(1, 1, 1), radius=0.05)
        w.run(0.2)
        return w.body_position.copy()

    np.testing.assert_array_equal(positions(), positions())


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(rate=0), "rate"),
        (dict(count=-3), "count"),
        (dict(shape="cylinder"), "unknown shape"),
        (dict(shape="plane"), "cannot emit planes"),
        (dict(region="cube"), "region"),
        (dict(direction=(0, 0, 0)), "direction"),
        (dict(cone_angle=200), "cone_angle"),
        (dict(radius=(0.2, 0.1)), "min must not exceed max"),
        (dict(radius=-0.1), "radius"),
        (dict(mass=1.0, density=2.0), "mass or density"),
        (dict(position=(0, float("nan"), 0)), "position"),
    ],
)
def test_bad_emitter_arguments_are_named(kwargs, message):
    """Each bad argument raises a ValueError naming it."""
    w = tumble.World()
    with pytest.raises(ValueError, match=message):
        w.add_emitter(**kwargs)


def test_emitter_above_a_large_static_box_releases():
    """Candidates are checked against a box's true shape, not its bounding sphere."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_box(position=(0, 0, -0.5), half_extents=(5, 5, 0.5), static=True)
    em = w.add_emitter(rate=240, count=10, position=(0, 0, 0.5), region="box", extent=(1, 1, 0.2), radius=0.05)
    w.run(0.1)
    assert em.emitted == 10
    w.collide()
    assert np.all(w.contact_depth <= 0.0)


# ---------------------------------------------------------------------------- capsules and convex hulls

PEBBLE = np.random.default_rng(3).normal(size=(16, 3)) * (1.0, 0.8, 0.5)  # a flattened random blob [m]


def _shape_emitter(seed=7, **kwargs):
    w = tumble.World(gravity=(0, 0, 0), seed=seed)
    args = dict(rate=2400, count=30, position=(0, 0, 0), region="box", extent=(3, 3, 3), random_orientation=True)
    args.update(kwargs)
    em = w.add_emitter(**args)
    w.run(0.05)
    assert em.emitted == 30
    return w, em


def test_capsules_are_emitted_with_sizes_in_range():
    """Capsules get a radius and half height from their ranges times a scale from its range, exact mass."""
    w, _ = _shape_emitter(shape="capsule", radius=(0.02, 0.04), half_height=(0.05, 0.1), scale=(0.5, 2.0), density=800)
    assert np.all(w.body_shape == ShapeType.CAPSULE)
    r = w.body_radius
    a = w.body_half_extents[:, 2] - r
    np.testing.assert_allclose(w.body_half_extents[:, 0], r)
    # sizes stored in the world's precision, a read back as (a + r) - r: a few ulps of a + r (0.28)
    slack = resolution(1e-12, 0.28, 4)
    assert np.all((r >= 0.01 - slack) & (r <= 0.08 + slack))
    assert np.all((a >= 0.025 - slack) & (a <= 0.2 + slack))
    # both sizes of one body carry the same scale: a / r stays within the ratio of the unscaled ranges
    ratio = resolution(1e-9, 0.1 / 0.02, 8)
    assert np.all((a / r >= 0.05 / 0.04 - ratio) & (a / r <= 0.1 / 0.02 + ratio))
    assert np.ptp(r) > 0.02  # the scale range was used, not only the radius range
    # the mass from the sizes before they were stored: 8 ulps (a's cancellation included)
    mass = 800 * np.pi * r**2 * (2 * a + 4 / 3 * r)
    np.testing.assert_allclose(w.body_mass, mass, rtol=resolution(1e-12, 1.0, 8))


def test_convex_bodies_are_scaled_copies_of_the_hull():
    """Each emitted hull is one of 16 copies of the prototype scaled within range: volume s^3, moments s^5."""
    from tumble.collision.hulls import hull_from_points
    from tumble.emitters import HULL_SCALES

    w, em = _shape_emitter(shape="convex", points=PEBBLE, scale=(0.02, 0.05), density=2500)
    base = hull_from_points(PEBBLE)
    assert np.all(w.body_shape == ShapeType.CONVEX)
    rows = w.body_geometry
    assert len(em.hull_rows) == HULL_SCALES == len(w.hulls.prototypes) - 1  # made when added, not while emitting
    assert set(rows.tolist()) <= set(em.hull_rows.tolist()) and len(set(rows.tolist())) > 5
    for i, g in enumerate(rows):
        proto = w.hulls.prototypes[g]
        s = proto.bound_radius / base.bound_radius
        assert 0.02 - 1e-12 <= s <= 0.05 + 1e-12
        np.testing.assert_allclose(proto.vertex, base.vertex * s, atol=1e-15)
        # the mass and the moments stored in the world's precision: a few ulps
        assert w.body_mass[i] == pytest.approx(2500 * base.volume * s**3, rel=resolution(1e-12, 1.0, 4))
    # inertia: the body's moments are the hull's unit-density moments times density s^5
    inv = w.bodies.numpy("body_inv_inertia")
    s = np.array([w.hulls.prototypes[g].bound_radius for g in rows]) / base.bound_radius
    moments = 2500 * base.inertia[None] * s[:, None] ** 5
    np.testing.assert_allclose(1.0 / inv, moments, rtol=resolution(1e-10, 1.0, 4))
    # random orientations: the body frame is the hull's principal frame turned by a random rotation
    assert np.ptp(w.body_orientation, axis=0).min() > 0.5


def test_a_fixed_scale_shares_one_hull_and_no_orientation_keeps_the_user_frame():
    """A fixed scale adds one prototype for all bodies; without random_orientation the user frame is unrotated."""
    w, _ = _shape_emitter(shape="convex", points=PEBBLE, scale=0.03, random_orientation=False)
    assert len(set(w.body_geometry.tolist())) == 1
    proto = w.hulls.prototypes[int(w.body_geometry[0])]
    np.testing.assert_allclose(w.body_orientation, np.tile(proto.rotation, (30, 1)), atol=1e-15)


def test_convex_emitter_takes_a_mesh_file(tmp_path):
    """A mesh file's vertices are hulled once; a file that is not watertight gives a one-line notice."""
    trimesh = pytest.importorskip("trimesh")
    path = tmp_path / "rock.stl"
    trimesh.creation.icosphere(subdivisions=1, radius=1.0).export(path)
    w, _ = _shape_emitter(shape="convex", file=str(path), scale=0.05)
    proto = w.hulls.prototypes[int(w.body_geometry[0])]
    assert proto.bound_radius == pytest.approx(0.05, rel=1e-6)
    assert len(proto.vertex) == 42


def test_mixed_shapes_do_not_overlap_at_birth():
    """Spheres, boxes, capsules and hulls from one point emitter land clear of each other and the ground."""
    w = tumble.World(seed=2)
    w.add_plane()
    em = w.add_emitter(
        shape=["sphere", "box", "capsule", "convex"],
        rate=4000,
        count=120,
        position=(0, 0, 0.2),
        region="box",
        extent=(0.4, 0.4, 0.1),
        radius=(0.02, 0.03),
        half_extents=0.02,
        half_height=(0.02, 0.04),
        points=PEBBLE * 0.03,
        scale=(0.6, 1.0),
        random_orientation=True,
    )
    for _ in range(60):
        w.emit()
    assert em.emitted > 60
    assert {1, 2, 3, 4} <= set(w.body_shape.tolist())
    w.collide()
    assert np.all(w.contact_depth <= 1e-9)


def test_a_run_with_emitted_hulls_restores_from_a_snapshot_bit_for_bit():
    """Snapshot while a convex emitter runs, run on, restore, run again: the same state hash."""
    w = tumble.World(seed=1)
    w.add_plane()
    w.add_emitter(
        shape="convex",
        points=PEBBLE * 0.03,
        scale=(0.8, 1.2),
        rate=200,
        count=20,
        position=(0, 0, 0.5),
        region="box",
        extent=(0.3, 0.3, 0.1),
        random_orientation=True,
    )
    w.run(0.05)
    snap = w.snapshot()
    w.run(0.1)
    first = w.state_hash()
    w.restore(snap)
    w.run(0.1)
    assert w.state_hash() == first


def test_shape_emitters_repeat_with_the_seed_and_differ_without():
    """The same seed releases the same capsules and hulls bit for bit; another seed others."""

    def run(seed):
        w, _ = _shape_emitter(
            seed=seed,
            shape=["capsule", "convex"],
            radius=0.02,
            half_height=(0.02, 0.05),
            points=PEBBLE,
            scale=(0.01, 0.03),
        )
        return np.concatenate(
            [w.body_position.ravel(), w.body_orientation.ravel(), w.body_mass, w.body_half_extents.ravel()]
        )

    a, b, c = run(5), run(5), run(6)
    assert a.tobytes() == b.tobytes()
    assert a.shape != c.shape or a.tobytes() != c.tobytes()


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(shape="convex"), "needs points or file"),
        (dict(shape="convex", points=PEBBLE, file="rock.obj"), "needs points or file"),
        (dict(shape="sphere", points=PEBBLE), "points and file are for shape 'convex'"),
        (dict(shape="mesh"), "cannot emit meshs|cannot emit meshes"),
        (dict(shape="convex", points=PEBBLE[:3]), "at least 4 points"),
        (dict(shape="convex", file="/nonexistent/rock.obj"), "rock.obj"),
        (dict(shape="capsule", half_height=(0.2, 0.1)), "min must not exceed max"),
        (dict(scale=0.0), "scale must be > 0"),
        (dict(scale=(2.0, 1.0)), "min must not exceed max"),
    ],
)
def test_bad_shape_emitter_arguments_are_named(kwargs, message):
    """Each bad capsule/convex/scale argument raises one ValueError (or OSError for a file) naming it."""
    w = tumble.World()
    with pytest.raises((ValueError, OSError), match=message):
        w.add_emitter(**kwargs)


def _plate_world():
    """A 2 m square plate mesh at z = 0 (open, facing +z), zero g."""
    w = tumble.World(gravity=(0, 0, 0))
    square = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    w.add_mesh(vertices=square, triangles=[[0, 1, 2], [0, 2, 3]])
    return w


def test_emitted_bodies_clear_a_mesh():
    """A region that straddles a mesh plate releases bodies only where they clear its triangles:
    before meshes were tested, 14 of these 60 spheres were born in the plate."""
    w = _plate_world()
    em = w.add_emitter(rate=2400, count=60, position=(0, 0, 0.05), region="box", extent=(0.5, 0.5, 0.2), radius=0.05)
    first = w.body_count
    for _ in range(10):
        w.emit()
    assert em.emitted > 30
    z = w.body_position[first:][:, 2]
    assert np.all(np.abs(z) >= 0.05)  # a sphere's centre at least its radius from the plate
    w.collide()
    assert np.all(w.contact_depth <= 0.0)


def test_no_body_is_released_inside_a_closed_mesh():
    """A closed mesh is a solid: a region inside a hollow-less 1 m cube mesh releases nothing (the
    emitter waits), while one beside it releases."""
    w = tumble.World(gravity=(0, 0, 0))
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    w.add_mesh(vertices=corners, triangles=[t for f in faces for t in ((f[0], f[1], f[2]), (f[0], f[2], f[3]))])
    inside = w.add_emitter(rate=240, count=5, position=(0, 0, 0), region="box", extent=(0.1, 0.1, 0.1), radius=0.05)
    beside = w.add_emitter(rate=240, count=5, position=(2, 0, 0), region="box", extent=(0.1, 0.1, 0.1), radius=0.05)
    for _ in range(10):
        w.emit()
    assert inside.emitted == 0
    assert beside.emitted == 5
