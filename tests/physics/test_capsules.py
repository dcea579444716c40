"""Capsules against analytic motion: rolling from sliding, rolling down a ramp, resting upright and on a box."""

from __future__ import annotations

import numpy as np
import pytest

import tumble
from tumble import shapes

G = 9.81


def quat_axis_angle(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.r_[axis * np.sin(angle / 2), np.cos(angle / 2)]


def quat_mul(p, q):
    pv, pw, qv, qw = p[:3], p[3], q[:3], q[3]
    return np.r_[pw * qv + qw * pv + np.cross(pv, qv), pw * qw - pv @ qv]


def spin_ratio(r, a):
    """k = I_axis / (m r^2) of a capsule, rolling on its cylinder."""
    return shapes.capsule_inertia(1.0, r, a)[2] / r**2


def test_sliding_capsule_ends_rolling():
    """A capsule launched sliding sideways with no spin ends rolling at v0 / (1 + I/(m r^2)), v = w r."""
    r, a, v0, mu = 0.1, 0.2, 2.0, 0.3
    w = tumble.World()
    w.add_plane(friction=mu, restitution=0.0)
    w.add_capsule(
        position=(0, 0, r),
        radius=r,
        half_height=a,
        orientation=quat_axis_angle((1, 0, 0), np.pi / 2),
        velocity=(v0, 0, 0),
        friction=mu,
        restitution=0.0,
        mass=1.0,
    )
    # friction mu m g decelerates it and spins it up until v = w r: after v0 k / ((1 + k) mu g) ~ 0.3 s
    w.run(1.0)
    v = w.body_velocity[1]
    omega = w.body_angular_velocity[1]
    assert v[0] == pytest.approx(v0 / (1 + spin_ratio(r, a)), rel=0.02)
    assert omega[1] * r == pytest.approx(v[0], rel=1e-3)
    # no sideways drift beyond the sequential sweep's asymmetry between the two end contacts
    assert abs(v[1]) < 1e-3 and w.body_position[1, 2] == pytest.approx(r, abs=1e-4)


@pytest.mark.parametrize("theta_deg", [10.0, 25.0])
def test_capsule_rolls_down_a_ramp(theta_deg):
    """A capsule across a ramp rolls without slipping at a = g sin(theta) / (1 + I/(m r^2))."""
    theta = np.radians(theta_deg)
    r, a, mu = 0.1, 0.3, 0.8
    n = np.array([0.0, -np.sin(theta), np.cos(theta)])  # ramp rising towards +y
    down = np.array([0.0, -np.cos(theta), -np.sin(theta)])
    # axis along x (horizontal, across the slope), then tilted with the ramp
    q = quat_mul(quat_axis_angle((1, 0, 0), theta), quat_axis_angle((0, 1, 0), np.pi / 2))
    w = tumble.World()
    w.add_plane(normal=n, friction=mu, restitution=0.0)
    w.add_capsule(position=n * r, radius=r, half_height=a, orientation=q, mass=1.0, friction=mu, restitution=0.0)
    w.run(0.25)
    x1, t1, v1 = w.body_position[1].copy(), w.time, float(np.dot(w.body_velocity[1], down))
    w.run(1.0)
    x2, t2 = w.body_position[1].copy(), w.time
    acc = G * np.sin(theta) / (1 + spin_ratio(r, a))
    # s = v1 t + a t^2 / 2 from the speed at t1
    assert np.dot(x2 - x1, down) == pytest.approx(v1 * (t2 - t1) + acc * (t2 - t1) ** 2 / 2, rel=0.01)
    assert np.dot(w.body_velocity[1], down) == pytest.approx(v1 + acc * (t2 - t1), rel=0.01)
    # it rolls straight: no drift along its axis, no lift off the ramp
    assert abs(w.body_position[1, 0]) < 1e-4
    assert np.dot(w.body_position[1], n) == pytest.approx(r, abs=2e-4)


def test_upright_capsule_stands_still():
    """An upright capsule set on a plane stays at z = a + r without drifting or tipping."""
    r, a = 0.05, 0.3
    w = tumble.World()
    w.add_plane(restitution=0.0)
    w.add_capsule(position=(0, 0, a + r), radius=r, half_height=a, restitution=0.0)
    w.run(2.0)
    np.testing.assert_allclose(w.body_position[1], [0, 0, a + r], atol=1e-4)
    assert np.linalg.norm(w.body_velocity[1]) < 1e-4


def test_capsule_comes_to_rest_lying_on_a_box_and_on_a_capsule():
    """A capsule dropped across a box rests on its face; one dropped across it rests on top."""
    r, a = 0.05, 0.3
    flat = quat_axis_angle((1, 0, 0), np.pi / 2)
    w = tumble.World()
    w.add_plane(restitution=0.0)
    w.add_box(position=(0, 0, 0.1), half_extents=(0.4, 0.2, 0.1), static=True)
    w.add_capsule(position=(0, 0, 0.2 + r + 0.02), radius=r, half_height=a, orientation=flat, restitution=0.0)
    w.add_capsule(
        position=(0, 0, 0.2 + 3 * r + 0.06),
        radius=r,
        half_height=a,
        restitution=0.0,
        orientation=quat_axis_angle((0, 1, 0), np.pi / 2),
    )
    w.run(2.0)
    assert w.body_position[2, 2] == pytest.approx(0.2 + r, abs=2e-4)
    assert w.body_position[3, 2] == pytest.approx(0.2 + 3 * r, abs=4e-4)
    assert np.abs(w.body_velocity[2:]).max() < 1e-3
