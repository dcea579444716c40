"""Convex bodies against the box primitive and analytic motion: ramps, resting, stacks."""

from __future__ import annotations

import numpy as np
import pytest

import tumble

G = 9.81
CUBE = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])


def quat_axis_angle(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.r_[axis * np.sin(angle / 2), np.cos(angle / 2)]


def ramp_run(kind, theta, mu):
    """Slide a 0.2 m cube (box primitive or convex hull) down a ramp; return (travelled, time, v1)."""
    n = np.array([0.0, -np.sin(theta), np.cos(theta)])
    q = quat_axis_angle((1, 0, 0), theta)
    w = tumble.World()
    w.add_plane(normal=n, friction=mu, restitution=0.0)
    half = 0.1
    if kind == "box":
        w.add_box(position=n * half, half_extents=(half,) * 3, orientation=q, mass=1.0, friction=mu, restitution=0.0)
    else:
        w.add_convex(points=CUBE * half, position=n * half, orientation=q, mass=1.0, friction=mu, restitution=0.0)
    w.run(0.25)
    return w


@pytest.mark.parametrize("theta_deg, mu", [(30.0, 0.3), (20.0, 0.5)])
def test_convex_cube_slides_like_the_box(theta_deg, mu):
    """A convex cube on a ramp holds or slides at g (sin - mu cos) exactly as the box primitive does."""
    theta = np.radians(theta_deg)
    down = np.array([0.0, -np.cos(theta), -np.sin(theta)])
    out = {}
    for kind in ("box", "convex"):
        w = ramp_run(kind, theta, mu)
        x1, t1 = w.body_position[1].copy(), w.time
        w.run(1.0)
        out[kind] = (
            np.dot(w.body_position[1] - x1, down),
            w.time - t1,
            np.dot(w.body_velocity[1], down),
            w.body_position[1].copy(),
        )
    box, cvx = out["box"], out["convex"]
    if np.tan(theta) < mu:
        assert abs(cvx[0]) < 1e-4
    else:
        a = G * (np.sin(theta) - mu * np.cos(theta))
        v1 = cvx[2] - a * cvx[1]
        assert cvx[0] == pytest.approx(v1 * cvx[1] + a * cvx[1] ** 2 / 2, rel=0.01)
        assert cvx[2] == pytest.approx(box[2], rel=1e-3)
    np.testing.assert_allclose(cvx[3], box[3], atol=5e-4)


def test_convex_cube_rests_like_the_box_on_a_plane():
    """A convex cube and a box dropped tilted onto a plane both come to rest flat at z = h."""
    w = tumble.World()
    w.add_plane(restitution=0.0)
    q = quat_axis_angle((1, 1, 0), 0.3)
    w.add_box(position=(-0.5, 0, 0.3), half_extents=(0.1,) * 3, orientation=q, restitution=0.0)
    w.add_convex(points=CUBE * 0.1, position=(0.5, 0, 0.3), orientation=q, restitution=0.0)
    w.run(2.0)
    assert w.body_position[1, 2] == pytest.approx(0.1, abs=2e-4)
    assert w.body_position[2, 2] == pytest.approx(0.1, abs=2e-4)
    assert np.abs(w.body_velocity[1:]).max() < 1e-3
    np.testing.assert_allclose(w.body_position[2] - [1.0, 0, 0], w.body_position[1], atol=5e-3)


def convex_stack(count, half=0.1):
    w = tumble.World()
    w.add_plane(friction=0.5, restitution=0.0)
    for i in range(count):
        w.add_convex(points=CUBE * half, position=(0, 0, half + 2 * half * i), mass=1.0, friction=0.5, restitution=0.0)
    return w


def test_stack_of_five_convex_boxes_stands():
    """Five convex cubes stacked stay within 1 mm of their places for 2 s."""
    w = convex_stack(5)
    start = w.body_position.copy()
    w.run(2.0)
    assert np.abs(w.body_position - start).max() < 1e-3


@pytest.mark.slow
def test_stack_of_twenty_convex_boxes_stands_ten_seconds():
    """Twenty convex cubes stacked stand for 10 s: no cube leaves its place by more than 5 mm."""
    w = convex_stack(20)
    start = w.body_position.copy()
    w.run(10.0)
    assert np.abs(w.body_position - start).max() < 5e-3
    assert np.abs(w.body_velocity).max() < 1e-2
