"""Supports drawn under pinned cloth (tumble.render.supports): posts from the ground to pinned corners,
rails along pinned edges, none where a static body holds the pins; the 2-D convex hull they use."""

from __future__ import annotations

import numpy as np
import pytest

import tumble
from tumble.render.supports import cloth_supports, convex_hull_2d


def test_pinned_cloth_corners_stand_on_posts():
    """A cloth pinned at its four corners gets four posts from the ground up to the pins."""
    world = tumble.World()
    world.add_plane()
    world.add_cloth(size=(1.0, 1.0), resolution=(8, 8), position=(0.0, 0.0, 1.0), pins="corners")
    boxes = cloth_supports(world)
    assert len(boxes) == 4
    pins = np.asarray(world.cloth.particle_position)[np.asarray(world.cloth.particle_inv_mass) == 0.0]
    for pin in pins:
        k = np.argmin(np.linalg.norm(boxes[:, :2] - pin[:2], axis=1))
        assert np.allclose(boxes[k, :2], pin[:2], atol=1e-6)
        # centre halfway up, half height up to the pin: from z = 0 to the pin's height
        assert boxes[k, 2] - boxes[k, 9] == pytest.approx(0.0, abs=1e-6)
        assert boxes[k, 2] + boxes[k, 9] == pytest.approx(pin[2], abs=1e-6)


def test_a_pinned_border_gets_a_frame_and_corner_posts():
    """Pins along the whole border: rails along its edges and four posts (not one per pin)."""
    world = tumble.World()
    world.add_plane()
    n = 6
    border = [[i, j] for i in range(n) for j in range(n) if i in (0, n - 1) or j in (0, n - 1)]
    world.add_cloth(size=(1.0, 1.0), resolution=(n, n), position=(0.0, 0.0, 1.0), pins=border)
    boxes = cloth_supports(world)
    posts = boxes[np.isclose(boxes[:, 6], 1.0) & (boxes[:, 9] > 0.3)]
    rails = len(boxes) - len(posts)
    assert len(posts) == 4
    assert rails == 4 * (n - 1)


def test_pins_on_a_static_pole_get_no_post():
    """Pins beside a static body (the flag's pole) are held by it: no post is drawn."""
    world = tumble.World()
    world.add_plane()
    world.add_box(position=(-0.53, 0.0, 1.0), half_extents=(0.02, 0.02, 1.0), static=True)
    world.add_cloth(
        size=(1.0, 0.6),
        resolution=(6, 4),
        position=(0.0, 0.0, 1.5),
        orientation=(0.7071067811865476, 0, 0, 0.7071067811865476),
        pins=[[0, j] for j in range(4)],
    )
    boxes = cloth_supports(world)
    assert len(boxes) == 0


def test_convex_hull_corners():
    """The hull of a square with points on its edges and inside is its four corners."""
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0], [0.5, 0.5], [1, 0.3], [0.2, 0.9]], dtype=float)
    assert sorted(convex_hull_2d(pts).tolist()) == [0, 1, 2, 3]
    assert sorted(convex_hull_2d(pts[[0, 4, 1]]).tolist()) == [0, 2]  # collinear: the two ends


def test_a_world_without_cloth_has_no_supports():
    """No cloth, or cloth with no pins: no boxes, in the documented row layout (13 floats a row)."""
    world = tumble.World()
    world.add_plane()
    assert cloth_supports(world).shape == (0, 13)
    world.add_cloth(size=(1.0, 1.0), resolution=(4, 4), position=(0.0, 0.0, 1.0))
    assert cloth_supports(world).shape == (0, 13)


def test_convex_hull_of_points_on_a_circle_and_inside_it():
    """Of 12 points on a circle and 20 inside it, the hull is the 12, in order around it."""
    rng = np.random.default_rng(3)
    angles = np.arange(12) * 2 * np.pi / 12
    ring = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    inside = rng.uniform(-0.6, 0.6, size=(20, 2))
    order = rng.permutation(32)
    pts = np.concatenate([ring, inside])[order]
    hull = convex_hull_2d(pts)
    assert sorted(order[hull].tolist()) == list(range(12))
    # consecutive hull edges turn left: a counter-clockwise convex polygon, not a zig-zag
    p = pts[hull]
    e = np.roll(p, -1, axis=0) - p
    turns = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
    assert np.all(turns > 0)  # counter-clockwise, as documented
