"""Emitters: rate, count, regions, cone, ranges, and no overlap at birth."""

from __future__ import annotations

import numpy as np
import pytest

import tumble
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
    em = w.add_emitter(shape=["sphere", "box"], rate=2000, count=200, position=(0, 0, 0.1), region="point",
                       speed=(1.0, 2.0), cone_angle=60, direction=(0, 0, 1), radius=(0.03, 0.05),
                       half_extents=(0.02, 0.04), random_orientation=True)
    # release without moving anything, so every body is still where it was born
    for _ in range(100):
        em.emit(w, w.dt)
    assert em.emitted > 50
    # the narrow phase (tested on its own) finds no overlap anywhere, ground included
    w.collide()
    assert w.contact_count > 0  # near neighbours are reported as speculative contacts ...
    assert np.all(w.contact_depth <= 0.0)  # ... but none overlaps


def test_new_bodies_clear_existing_ones():
    """A candidate spot taken by an existing body is not used."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_sphere(position=(0, 0, 0), radius=0.5, mass=1.0)
    em = w.add_emitter(rate=240, count=20, position=(0, 0, 0), region="box", extent=(1, 1, 1), radius=0.05, seed=1)
    for _ in range(10):
        before = w.body_count
        em.emit(w, w.dt)
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
    em = w.add_emitter(rate=2400, count=100, position=(0, 0, 0), region="box", extent=(0.2, 0.2, 0.2),
                       radius=0.02, seed=3)
    first = w.body_count
    for _ in range(10):
        em.emit(w, w.dt)
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
    em = w.add_emitter(rate=1e4, count=300, position=(0, 0, 0), region="disc", extent=5.0, direction=(1, 0, 0),
                       cone_angle=20, speed=(2.0, 3.0), radius=(0.01, 0.02), density=500.0, seed=7)
    em.emit(w, 1.0)
    v = w.body_velocity
    speed = np.linalg.norm(v, axis=1)
    assert np.all((speed >= 2.0 - 1e-12) & (speed <= 3.0 + 1e-12))
    angle = np.degrees(np.arccos(np.clip(v[:, 0] / speed, -1, 1)))
    assert angle.max() <= 20.0 + 1e-9
    assert angle.max() > 10.0  # the cone is used, not just its axis
    r = w.body_radius
    assert np.all((r >= 0.01) & (r <= 0.02))
    np.testing.assert_allclose(w.body_mass, 500.0 * 4 / 3 * np.pi * r**3, rtol=1e-12)
    # the disc lies across the direction: x is constant, |(y, z)| <= 5
    x = w.body_position
    np.testing.assert_allclose(x[:, 0], 0.0, atol=1e-12)
    assert np.all(np.linalg.norm(x[:, 1:], axis=1) <= 5.0 + 1e-12)


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
