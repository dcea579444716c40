"""Joints against analytic results: pendulum periods, energy, hanging chains, motors, limits, drift.

Time step dt = 1/240 s with 8 substeps (h = dt / 8) unless a test says otherwise. Semi-implicit
Euler is first order in h, and the soft joints (all but the ball joints' point rows, which are
solved exactly chain by chain) settle at errors ~ load / (m_eff omega^2) with omega = 2 pi f,
f = 0.25 / h, so the tolerances below are a few times those.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import tumble
from tolerances import in_float32, resolution, ulps

G = 9.81
DT = 1.0 / 240.0


def _crossing_period(t: np.ndarray, x: np.ndarray) -> float:
    """Mean period of x(t) from its upward zero crossings, interpolated linearly within a step."""
    i = np.nonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))[0]
    tc = t[i] + (-x[i]) / (x[i + 1] - x[i]) * (t[i + 1] - t[i])
    return float(np.diff(tc).mean())


def _swing(world, body: int, seconds: float):
    t, x = [], []
    for _ in range(round(seconds / world.dt)):
        world.step()
        t.append(world.time)
        x.append(world.body_position[body, 0])
    return np.array(t), np.array(x)


@pytest.mark.parametrize("theta0", [0.05, 0.5])
def test_simple_pendulum_period(theta0):
    """Swing a bob on a rigid rod (distance joint to the world) with T = 2 pi sqrt(L/g)(1 + theta0^2/16)."""
    L = 1.0
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    bob = world.add_sphere(position=(L * math.sin(theta0), 0, 2 - L * math.cos(theta0)), radius=0.02, mass=1.0)
    world.add_joint("distance", None, bob, anchor_a=(0, 0, 2))
    t, x = _swing(world, bob.index, 4.5)
    expected = 2 * math.pi * math.sqrt(L / G) * (1 + theta0**2 / 16)
    # the series' next term, 11 theta0^4 / 3072, is 2e-4 at 0.5 rad: well inside 0.5 %
    assert _crossing_period(t, x) == pytest.approx(expected, rel=0.005)
    assert world.joint_error.max() < 1e-5


def test_physical_pendulum_on_ball_joint():
    """Swing a sphere hung by a ball joint at distance L from its centre: T = 2 pi sqrt((L^2 + 2/5 r^2) / (g L))."""
    L, r, theta0 = 0.5, 0.1, 0.05
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    bob = world.add_sphere(position=(L * math.sin(theta0), 0, 2 - L * math.cos(theta0)), radius=r, mass=2.0)
    world.add_joint("ball", None, bob, anchor=(0, 0, 2))
    t, x = _swing(world, bob.index, 5.0)
    expected = 2 * math.pi * math.sqrt((L * L + 0.4 * r * r) / (G * L)) * (1 + theta0**2 / 16)
    assert _crossing_period(t, x) == pytest.approx(expected, rel=0.005)


@pytest.mark.parametrize("kind", ["distance", pytest.param("ball", marks=pytest.mark.slow)])
def test_double_pendulum_conserves_energy(kind):
    """Release a double pendulum from horizontal: its energy stays within 1 % of 3 m g L for 10 s."""
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    a = world.add_sphere(position=(1, 0, 2), radius=0.05, mass=1.0)
    b = world.add_sphere(position=(2, 0, 2), radius=0.05, mass=1.0)
    if kind == "distance":
        world.add_joint("distance", None, a, anchor_a=(0, 0, 2))
        world.add_joint("distance", a, b)
    else:
        world.add_joint("ball", None, a, anchor=(0, 0, 2))
        world.add_joint("ball", a, b, anchor=(1, 0, 2))
    e0 = world.kinetic_energy() + world.potential_energy()
    scale = 3 * 1.0 * G * 1.0  # energy above the hanging rest state
    worst = 0.0
    for _ in range(int(10 / DT)):
        world.step()
        worst = max(worst, abs(world.kinetic_energy() + world.potential_energy() - e0))
    assert worst < 0.01 * scale
    assert world.joint_error.max() < 1e-3
    # it did move chaotically: the outer bob went around, well away from its start
    assert world.body_position[b.index, 2] != pytest.approx(2.0, abs=0.1)


def _chain(world, points: np.ndarray, *, mass: float = 0.1, ends=(True, False)):
    """Boxes between consecutive points (links), ball joints at the shared points; the ends pinned to the world."""
    links = []
    for p, q in itertools.pairwise(points):
        d = q - p
        length = float(np.linalg.norm(d))
        axis = d / length
        # rotate +x onto the link direction
        half = np.array([0.0, -axis[2], axis[1], 1.0 + axis[0]])
        links.append(
            world.add_box(
                position=(p + q) / 2,
                half_extents=(length / 2, 0.01, 0.01),
                mass=mass,
                orientation=half / np.linalg.norm(half),
            )
        )
    for i in range(1, len(links)):
        world.add_joint("ball", links[i - 1], links[i], anchor=points[i])
    if ends[0]:
        world.add_joint("ball", None, links[0], anchor=points[0])
    if ends[1]:
        world.add_joint("ball", links[-1], None, anchor=points[-1])
    return links


def _settle(world, seconds: float) -> None:
    """Find the static equilibrium by kinetic damping: zero every velocity when the kinetic energy peaks."""
    last = 0.0
    for _ in range(round(seconds / world.dt)):
        world.step()
        energy = world.kinetic_energy()
        if energy < last:
            world.bodies.write("body_velocity", slice(0, world.body_count), 0.0)
            world.bodies.write("body_angular_velocity", slice(0, world.body_count), 0.0)
            energy = 0.0
        last = energy


def test_chain_hanging_from_one_end():
    """Hang a 20-link chain from one end, released 0.2 rad off: it settles on the vertical, its top joint carrying all."""
    n, l, m = 20, 0.05, 0.1
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    top = np.array([0.0, 0.0, 2.0])
    points = top + np.outer(np.arange(n + 1), [l * math.sin(0.2), 0.0, -l * math.cos(0.2)])
    links = _chain(world, points, mass=m)
    _settle(world, 3.0)
    world.run(duration=0.25)
    centres = world.body_position[[b.index for b in links]]
    expected = top - np.outer(np.arange(n) + 0.5, [0.0, 0.0, l])
    assert np.abs(centres - expected).max() < 0.02 * n * l
    assert world.joint_error.max() < 1e-3
    top_joint = n - 1  # the world joint was added last
    assert world.joint_force[top_joint] == pytest.approx([0.0, 0.0, n * m * G], abs=0.01 * n * m * G)


def test_chain_between_two_supports_is_a_catenary():
    """Let a 20-link chain hung between two points settle: it lies on z = a cosh(x/a) + c within 2 % of its length."""
    n, span = 20, 1.2
    length = 2.0  # 20 links of 0.1 m
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    # start as a V of two straight halves of 1 m each, 0.6 m across: a valid chain of equal links
    drop = math.sqrt(1.0 - 0.6**2)
    half = np.linspace(0.0, 1.0, n // 2 + 1)
    left = np.stack([-0.6 + 0.6 * half, np.zeros_like(half), 2.0 - drop * half], axis=1)
    right = left[::-1][1:] * [-1, 1, 1]
    points = np.vstack([left, right])
    links = _chain(world, points, ends=(True, True))
    ids = [b.index for b in links]
    _settle(world, 4.0)
    world.run(duration=0.05)
    # the catenary through both supports with arc length 2: 2 a sinh(span / (2 a)) = length
    a = brentq(lambda a: 2 * a * math.sinh(span / (2 * a)) - length, 0.05, 10.0)
    x = np.linspace(-span / 2, span / 2, 20001)
    z = 2.0 + a * (np.cosh(x / a) - math.cosh(span / (2 * a)))
    curve = np.stack([x, np.zeros_like(x), z], axis=1)
    centres = world.body_position[ids]
    gap = np.min(np.linalg.norm(centres[:, None, :] - curve[None, :, :], axis=2), axis=1)
    # link centres sit on chords of the curve: their sag is l^2 / (8 R), < 1 mm here
    assert gap.max() < 0.02 * length
    lowest = centres[:, 2].min()
    assert lowest == pytest.approx(z.min(), abs=0.02 * length)
    assert world.joint_error.max() < 1e-3


def _couple(world, body, torque_z: float) -> None:
    """A pure torque about +z on `body` for the next step: F at +x of the centre, -F at the centre."""
    x = world.body_position[body.index]
    world.apply_force(body, (0.0, torque_z, 0.0), point=x + (1.0, 0.0, 0.0))
    world.apply_force(body, (0.0, -torque_z, 0.0))


def test_hinge_motor_reaches_target_speed_against_load():
    """Spin a wheel with a motor (max 1 N m) against a 0.4 N m load: alpha = 0.6 / I until 3 rad/s, then hold."""
    world = tumble.World(gravity=(0, 0, 0), dt=DT)
    m, hx = 2.0, 0.2
    wheel = world.add_box(position=(0, 0, 1), half_extents=(hx, hx, 0.05), mass=m)
    inertia = m / 12 * (2 * hx) ** 2 * 2
    joint = world.add_joint("hinge", None, wheel, anchor=(0, 0, 1), axis=(0, 0, 1), motor_speed=3.0, max_torque=1.0)
    alpha = (1.0 - 0.4) / inertia
    steps = round(0.1 / DT)
    for _ in range(steps):
        _couple(world, wheel, -0.4)
        world.step()
    # accelerating at the torque limit: omega = alpha t (to within one step's acceleration)
    assert world.body_angular_velocity[wheel.index, 2] == pytest.approx(alpha * 0.1, abs=alpha * DT)
    for _ in range(round(0.9 / DT)):
        _couple(world, wheel, -0.4)
        world.step()
    w = world.body_angular_velocity[wheel.index]
    assert w[2] == pytest.approx(3.0, abs=1e-6)
    # the hinge's rows leave the rounding of their solve at the spin's size: in float32 a few ulps of 3 rad/s
    # (measured 1.8e-7)
    assert np.abs(w[:2]).max() < in_float32(1e-9, ulps(3.0, 4))
    # at speed the motor's torque balances the load
    assert world.joint_torque[joint.index][2] == pytest.approx(0.4, rel=1e-3)
    assert world.joint_error.max() < 1e-6


def test_hinge_motor_too_weak_for_its_load():
    """A 1 N m motor against a 1.5 N m load loses speed at (1.5 - 1) / I."""
    world = tumble.World(gravity=(0, 0, 0), dt=DT)
    wheel = world.add_box(position=(0, 0, 1), half_extents=(0.2, 0.2, 0.05), mass=2.0)
    inertia = 2.0 / 12 * 0.16 * 2
    world.add_joint("hinge", None, wheel, anchor=(0, 0, 1), axis=(0, 0, 1), motor_speed=3.0, max_torque=1.0)
    for _ in range(48):
        _couple(world, wheel, -1.5)
        world.step()
    assert world.body_angular_velocity[wheel.index, 2] == pytest.approx(-0.5 / inertia * 48 * DT, rel=1e-3)


def _arm_angle(world, arm) -> float:
    """Rotation of the arm's +x direction about +y (positive towards -z), degrees."""
    q = world.body_orientation[arm.index]
    x, y, z, w = q
    ex = np.array([1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w)])
    return math.degrees(math.atan2(-ex[2], ex[0]))


def test_hinge_limits_hold():
    """Flick a hinged arm against its lower limit (-30 deg); gravity then lays it on the upper one (+30 deg)."""
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    # spinning at -8 rad/s about the pivot (the centre moves at w x r): 2.7 J, the lower limit needs 1.2 J
    arm = world.add_box(
        position=(0.25, 0, 1),
        half_extents=(0.25, 0.02, 0.02),
        mass=1.0,
        angular_velocity=(0, -8.0, 0),
        velocity=(0, 0, 2.0),
    )
    world.add_joint(
        "hinge", None, arm, anchor=(0, 0, 1), axis=(0, 1, 0), lower=math.radians(-30), upper=math.radians(30)
    )
    angles = []
    for _ in range(int(3 / DT)):
        world.step()
        angles.append(_arm_angle(world, arm))
    angles = np.array(angles)
    assert angles.min() == pytest.approx(-30.0, abs=0.5)
    assert angles.max() < 30.5
    assert angles[-1] == pytest.approx(30.0, abs=0.1)
    # the hinge keeps its axis: the arm's +y stays along world +y
    x, y, z, w = world.body_orientation[arm.index]
    ey = np.array([2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w)])
    assert ey[1] > 1 - 1e-6
    assert world.joint_error.max() < 1e-4


def test_slider_slides_freely_then_stops_at_its_limit():
    """Slide a block down a 45 degree slider: s = g t^2 / (2 sqrt 2), until it rests on the limit 0.5 m down."""
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    block = world.add_box(
        position=(0, 0, 1), half_extents=(0.05, 0.05, 0.05), mass=1.0, angular_velocity=(1.0, 2.0, 3.0)
    )
    axis = np.array([1.0, 0.0, -1.0]) / math.sqrt(2)
    world.add_joint("slider", None, block, anchor=(0, 0, 1), axis=axis, lower=-0.1, upper=0.5)
    t = 0.25
    world.run(duration=t)
    s = float(np.dot(world.body_position[block.index] - [0, 0, 1], axis))
    a = G / math.sqrt(2)
    # semi-implicit Euler over substeps h: s = a t (t + h) / 2
    assert s == pytest.approx(0.5 * a * t * (t + DT / 8), rel=1e-3)
    assert np.abs(world.body_angular_velocity[block.index]).max() < 1e-6  # the slider locks rotation
    world.run(duration=1.75)
    p = world.body_position[block.index]
    assert np.dot(p - [0, 0, 1], axis) == pytest.approx(0.5, abs=1e-3)
    assert np.linalg.norm(np.cross(p - [0, 0, 1], axis)) < 1e-4  # on the line
    assert world.joint_error.max() < 1e-4


def test_slider_motor_reaches_target_speed_against_load():
    """Drive a 2 kg block along a slider (max 3 N) against a 1 N load: a = (3 - 1) / m until 0.5 m/s, then hold."""
    world = tumble.World(gravity=(0, 0, 0), dt=DT)
    m, load = 2.0, 1.0
    axis = np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    block = world.add_box(position=(0, 0, 1), half_extents=(0.1, 0.05, 0.05), mass=m)
    joint = world.add_joint("slider", None, block, anchor=(0, 0, 1), axis=axis, motor_speed=0.5, max_force=3.0)
    a = (3.0 - load) / m
    steps = round(0.125 / DT)
    for _ in range(steps):
        world.apply_force(block, -load * axis)
        world.step()
    # accelerating at the force limit: v = a t (to within one step's acceleration)
    v = world.body_velocity[block.index]
    assert np.dot(v, axis) == pytest.approx(a * 0.125, abs=a * DT)
    for _ in range(round(0.875 / DT)):
        world.apply_force(block, -load * axis)
        world.step()
    v = world.body_velocity[block.index]
    assert np.dot(v, axis) == pytest.approx(0.5, abs=1e-6)
    # along the axis only: in float32 the axis and v are stored to an ulp (measured 2.1e-8 off the float64 axis)
    assert np.linalg.norm(np.cross(v, axis)) < in_float32(1e-9, ulps(0.5, 4))
    # at speed the motor's force balances the load
    assert np.dot(world.joint_force[joint.index], axis) == pytest.approx(load, rel=1e-3)
    assert world.joint_error.max() < 1e-6


def test_slider_motor_too_weak_for_its_load():
    """A 1 N slider motor against a 1.5 N load loses speed at (1.5 - 1) / m."""
    world = tumble.World(gravity=(0, 0, 0), dt=DT)
    block = world.add_box(position=(0, 0, 1), half_extents=(0.1, 0.05, 0.05), mass=2.0)
    world.add_joint("slider", None, block, anchor=(0, 0, 1), axis=(1, 0, 0), motor_speed=0.5, max_force=1.0)
    for _ in range(48):
        world.apply_force(block, (-1.5, 0, 0))
        world.step()
    assert world.body_velocity[block.index, 0] == pytest.approx(-0.5 / 2.0 * 48 * DT, rel=1e-3)


def test_fixed_joint_holds_a_cantilever():
    """Weld a beam to the world at one end: it stays put and the weld carries m g and the moment m g L/2."""
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    beam = world.add_box(position=(0.5, 0, 1), half_extents=(0.5, 0.05, 0.05), mass=2.0)
    joint = world.add_joint("fixed", None, beam, anchor=(0, 0, 1))
    world.run(duration=1.0)
    assert np.abs(world.body_position[beam.index] - [0.5, 0, 1]).max() < 1e-4
    f = world.joint_force[joint.index]
    tau = world.joint_torque[joint.index]
    assert f == pytest.approx([0, 0, 2.0 * G], abs=1e-3)
    # about the beam's centre: the weld's force at r = (-0.5, 0, 0) plus its couple balance nothing else
    moment = np.cross([-0.5, 0, 0], f) + tau
    assert np.abs(moment).max() < 1e-3


# A small body on a long arm (a pendulum's bob: its moment about its centre 1.6e-4 of m r^2 about
# the anchor) is where a joint solved row after row fails: its angular rows turn the bob instead of
# moving it, and the point row turns it back. The joint's point and angular rows are solved as one block.
# Its factor is ill-conditioned (m r^2 / I = 6,250), and worked in float64 in both precisions: these
# tests run in each (in float32 a limit once stopped the bob with 1,000 times its impulse).
LIGHT_BOB = 0.02  # radius [m] of a 1 kg sphere on a 1 m arm


def test_fixed_joint_holds_a_light_body_far_from_its_anchor():
    """A 1 kg sphere of r = 2 cm welded to the world 1 m from its centre hangs at the soft joint's
    stretch under m g, g h^2 / (pi / 2)^2 (1 um; see the module's note on sag), and does not turn.
    (Row by row it sagged 25 mm and swung.)"""
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    bob = world.add_sphere(position=(1.0, 0, 0), radius=LIGHT_BOB, mass=1.0)
    world.add_joint("fixed", None, bob, anchor=(0, 0, 0))
    heights = []
    world.run(duration=1.0, callback=lambda w: heights.append(w.body_position[bob.index, 2]))
    h = DT / 8
    assert -min(heights) == pytest.approx(G * h * h / (math.pi / 2) ** 2, rel=0.01)
    assert np.abs(world.body_position[bob.index, :2] - [1.0, 0.0]).max() < 1e-9
    assert np.abs(world.body_angular_velocity[bob.index]).max() < 1e-6


def test_hinge_keeps_a_light_bob_in_its_plane():
    """A hinged bob pushed across the hinge plane at 1 m/s stays in it: the push is taken by the
    first substep's rows, so the bob strays less than a tenth of one substep's travel, v h / 10.
    (Row by row it swung 35 mm out of the plane, and stayed 10 mm out.)"""
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    bob = world.add_sphere(position=(0, 0, -1.0), radius=LIGHT_BOB, mass=1.0, velocity=(1.0, 1.0, 0.0))
    world.add_joint("hinge", None, bob, anchor=(0, 0, 0), axis=(0, 1, 0))
    across = []
    world.run(duration=2.0, callback=lambda w: across.append(w.body_position[bob.index, 1]))
    assert np.abs(across).max() < 1.0 * DT / 8 / 10


def test_hinge_limit_stops_a_light_bob():
    """A bob of r = 2 cm on a 1 m arm, released level, swings down onto a 45 degree limit and stays
    there: the limit stops the whole pendulum (effective moment I + m L^2), inelastically, and it
    then rests on the limit at the soft row's give under the load, g cos45 h^2 / (L (pi / 2)^2)
    rad (see the module's note on sag; 4e-5 degrees). (With the bob's own moment the limit held it
    for I / (I + m L^2) of its swing: it ran through to 76 degrees.)"""
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    bob = world.add_sphere(position=(1.0, 0, 0), radius=LIGHT_BOB, mass=1.0)
    limit = math.radians(45)
    world.add_joint("hinge", None, bob, anchor=(0, 0, 0), axis=(0, 1, 0), lower=-0.1, upper=limit)
    angles = []

    def swing(w):
        x = w.body_position[bob.index]
        angles.append(math.atan2(-x[2], x[0]))

    world.run(duration=1.5, callback=swing)
    h = DT / 8
    give = G * math.cos(limit) * h * h / (math.pi / 2) ** 2
    angles = np.array(angles)
    hit = int(np.argmax(angles > limit - give))
    assert 0 < hit < len(angles) - 100  # it got there (a swing of 0.404 s from level to 45 degrees: 97 steps)
    assert angles.max() < limit + give
    assert angles[hit:].min() > limit - give  # no rebound
    assert world.joint_error.max() < 1e-5


def test_hinge_motor_swings_a_light_bob_at_its_torque():
    """A 1 N m motor swings a bob of r = 2 cm on a 1 m arm (no gravity) at alpha = 1 / (I + m L^2)
    up to its target 2 rad/s, then holds it: the motor drives the whole pendulum. (With the bob's
    own moment its row was I / (I + m L^2) of the pendulum's: the anchor opened 0.7 mm and the
    speed overshot to 2.0016 rad/s.)"""
    world = tumble.World(gravity=(0, 0, 0), dt=DT)
    bob = world.add_sphere(position=(1.0, 0, 0), radius=LIGHT_BOB, mass=1.0)
    world.add_joint("hinge", None, bob, anchor=(0, 0, 0), axis=(0, 0, 1), motor_speed=2.0, max_torque=1.0)
    alpha = 1.0 / (0.4 * LIGHT_BOB**2 + 1.0)
    world.run(duration=1.0)
    assert world.body_angular_velocity[bob.index, 2] == pytest.approx(alpha * 1.0, abs=alpha * DT)
    assert world.joint_error.max() < 1e-5
    world.run(duration=2.0)  # at the target after 2 / alpha = 2.0003 s
    assert world.body_angular_velocity[bob.index, 2] == pytest.approx(2.0, abs=1e-6)
    assert world.joint_error.max() < 1e-5


def test_hinge_with_one_limit_turns_freely_the_other_way_and_counts_turns():
    """upper = 1 rad and no lower limit: a wheel spun the free way at 3 rad/s keeps turning (no
    gravity, no torque: its speed exactly), past half a turn and on for turns; spun back it stops
    at the limit only after unwinding every turn, 1 rad past its start. (The angle was measured in
    (-pi, pi]: an infinite side became a stop at -pi, where the wheel stopped dead.)"""
    world = tumble.World(gravity=(0, 0, 0), dt=DT)
    wheel = world.add_box(position=(0, 0, 1), half_extents=(0.2, 0.2, 0.05), mass=2.0, angular_velocity=(0, 0, -3.0))
    world.add_joint("hinge", None, wheel, anchor=(0, 0, 1), axis=(0, 0, 1), upper=1.0)
    world.run(duration=3.0)  # 9 rad, nearly a turn and a half
    # float32: each substep's turn and hinge solve round the spin by up to an ulp of 3 rad/s (5,760 substeps;
    # measured 1.7e-6, 7 ulps)
    kept = in_float32(1e-9, ulps(3.0, world.step_count * world.substeps))
    assert world.body_angular_velocity[wheel.index, 2] == pytest.approx(-3.0, abs=kept)
    angles = []

    def turn(w):
        x, y, z, q = w.body_orientation[wheel.index]
        angles.append(2.0 * math.atan2(z, q))

    world.set_body_state(wheel, angular_velocity=(0, 0, 6.0))
    world.run(duration=2.0, callback=turn)  # back the 9 rad in 1.5 s, 1 rad more, then the stop
    assert abs(world.body_angular_velocity[wheel.index, 2]) < 1e-6  # stopped on the limit
    assert math.remainder(angles[-1] - 1.0, 2.0 * math.pi) == pytest.approx(0.0, abs=1e-3)
    assert world.joint_error.max() < 1e-6


@pytest.mark.parametrize("kind", ["hinge", "slider"])
def test_equal_limits_lock_the_joint(kind):
    """lower == upper locks a hinge's angle (a slider's travel) there: a box pushed along the joint's
    axis (turned about it) by a constant 2 N (N m) stays put, the limit rows carrying the load at
    their soft give, F h^2 / (m (pi / 2)^2) (the module's note on sag; I_x for the hinge)."""
    world = tumble.World(gravity=(0, 0, 0), dt=DT)
    box = world.add_box(position=(0, 0, 1), half_extents=(0.2, 0.1, 0.1), mass=1.0)
    world.add_joint(kind, None, box, anchor=(0, 0, 1), axis=(1, 0, 0), lower=0.0, upper=0.0)
    for _ in range(240):
        if kind == "hinge":  # a couple about +x: 2 N at +y, -2 N at the centre, both along +z
            world.apply_force(box, (0, 0, 2.0), point=world.body_position[box.index] + (0, 1.0, 0))
            world.apply_force(box, (0, 0, -2.0))
        else:
            world.apply_force(box, (2.0, 0, 0))
        world.step()
    h = DT / 8
    x, y, z, w = world.body_orientation[box.index]
    offset = world.body_position[box.index] - [0, 0, 1]
    if kind == "hinge":
        inertia = 1.0 / 12 * (0.2**2 + 0.2**2)
        assert 2.0 * math.atan2(x, w) == pytest.approx(2.0 * h * h / (inertia * (math.pi / 2) ** 2), rel=0.01)
        assert np.abs(offset).max() < 1e-9
    else:
        assert offset[0] == pytest.approx(2.0 * h * h / (1.0 * (math.pi / 2) ** 2), rel=0.01)
        assert abs(2.0 * math.atan2(x, w)) < 1e-9
    assert np.abs(world.body_velocity[box.index]).max() < 1e-9


def test_joint_breaks_over_its_force():
    """A rope of break force 50 N snaps under 10 kg, and the weight falls freely; 200 N holds."""
    for limit, breaks in ((50.0, True), (200.0, False)):
        world = tumble.World(gravity=(0, 0, -G), dt=DT)
        weight = world.add_sphere(position=(0, 0, 1), radius=0.05, mass=10.0)
        world.add_joint("rope", None, weight, anchor_a=(0, 0, 2), break_force=limit)
        world.run(duration=0.5)
        assert bool(world.joint_broken[0]) is breaks
        z = world.body_position[weight.index, 2]
        if breaks:
            assert z < 1.0 - 0.5 * G * 0.4**2
        else:
            assert z == pytest.approx(1.0, abs=1e-3)
            assert world.joint_force[0][2] == pytest.approx(10.0 * G, rel=1e-3)


def test_a_removed_joint_lets_its_body_fall_freely():
    """A weight hanging at rest on a rope: after `remove_joint` it falls as semi-implicit Euler gives,
    v_n = v_0 - g n h and z_n = z_0 + n h v_0 - g h^2 n (n + 1) / 2 after n substeps of h, and the
    joint reads as broken with no force."""
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    weight = world.add_sphere(position=(0, 0, 1), radius=0.05, mass=2.0)
    other = world.add_sphere(position=(3, 0, 1), radius=0.05, mass=1.0)
    rope = world.add_joint("rope", None, weight, anchor_a=(0, 0, 2))
    world.add_joint("rope", None, other, anchor_a=(3, 0, 2))
    world.run(duration=0.5)
    assert world.joint_force[rope.index][2] == pytest.approx(2.0 * G, rel=1e-3)
    world.remove_joint(rope)
    assert bool(world.joint_broken[rope.index]) and not world.joint_broken[1]
    assert not world.joint_force[rope.index].any() and not world.joint_torque[rope.index].any()
    z0, v0 = world.body_position[weight.index, 2], world.body_velocity[weight.index, 2]
    steps = 48
    for _ in range(steps):
        world.step()
    n, h = steps * world.substeps, world.dt / world.substeps
    v = v0 - G * n * h
    z = z0 + n * h * v0 - G * h * h * n * (n + 1) / 2
    assert world.body_velocity[weight.index, 2] == pytest.approx(v, abs=ulps(G * n * h, 4 * n))
    assert world.body_position[weight.index, 2] == pytest.approx(z, abs=ulps(1.0, 4 * n))
    assert not world.joint_force[rope.index].any()
    # the other rope still holds its weight
    assert world.body_position[other.index, 2] == pytest.approx(1.0, abs=1e-3)
    assert world.joint_force[1][2] == pytest.approx(1.0 * G, rel=1e-3)


def test_a_removed_joint_lets_the_bodies_it_kept_apart_collide():
    """Two spheres overlapping by 5 cm on a ball joint (which keeps its pair from colliding) stay as they
    are; once the joint is removed, their contact pushes the overlap out to the contact slop, without
    speed (the relax pass takes the push's speed back), each sphere by half, about their fixed centre
    of mass."""
    from tumble.solver.contacts import LINEAR_SLOP

    r = 0.1
    world = tumble.World(gravity=(0, 0, 0), dt=DT)
    a = world.add_sphere(position=(0, 0, 0), radius=r, mass=1.0)
    b = world.add_sphere(position=(0.15, 0, 0), radius=r, mass=1.0)
    joint = world.add_joint("ball", a, b, anchor=(0.075, 0, 0))
    world.run(duration=24 * DT)
    assert world.body_position[b.index, 0] - world.body_position[a.index, 0] == pytest.approx(0.15, abs=ulps(0.15))
    world.remove_joint(joint)
    world.run(duration=48 * DT)
    xa, xb = world.body_position[a.index], world.body_position[b.index]
    assert xb[0] - xa[0] == pytest.approx(2 * r - LINEAR_SLOP, abs=resolution(1e-6, 0.2))
    assert (xa[0] + xb[0]) / 2 == pytest.approx(0.075, abs=ulps(0.2))
    assert np.abs(world.body_velocity).max() == 0.0


@pytest.mark.parametrize("ratio", [1.0, 100.0])
def test_mass_ratio_chain_drift(ratio):
    """Hang a ball of 100x the link mass on a 10-link chain: drift < 1 mm at rest, < 1 cm swinging from level."""
    n, l = 10, 0.1
    # at rest, hanging
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    points = np.array([[0, 0, 2 - i * l] for i in range(n + 1)], dtype=float)
    _chain(world, points, mass=1.0)
    ball = world.add_sphere(position=(0, 0, 2 - n * l - 0.1), radius=0.1, mass=ratio)
    world.add_joint("ball", world.body_count - 2, ball, anchor=points[-1])
    world.run(duration=2.0)
    assert world.joint_error.max() < 1e-3
    # violent: released from horizontal, the chain whips round under the heavy ball
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    points = np.array([[i * l, 0, 2] for i in range(n + 1)], dtype=float)
    _chain(world, points, mass=1.0)
    ball = world.add_sphere(position=(n * l + 0.1, 0, 2), radius=0.1, mass=ratio)
    world.add_joint("ball", world.body_count - 2, ball, anchor=points[-1])
    worst, lowest = 0.0, 2.0
    for _ in range(int(3 / DT)):
        world.step()
        worst = max(worst, world.joint_error.max())
        lowest = min(lowest, world.body_position[ball.index, 2])
    assert worst < 1e-2
    assert lowest < 1.0  # it did fall and swing


def _sphere_chain(world, n: int, start, step) -> list:
    """n spheres (r 8 mm, 10 g, the benchmark's links) at start + i step, ball-jointed midway, the first to the world."""
    start, step = np.asarray(start, dtype=float), np.asarray(step, dtype=float)
    links = [world.add_sphere(position=start + i * step, radius=0.008, mass=0.01) for i in range(n)]
    world.add_joint("ball", None, links[0], anchor=start - step / 2)
    for i in range(1, n):
        world.add_joint("ball", links[i - 1], links[i], anchor=start + (i - 0.5) * step)
    return links


@pytest.mark.parametrize("n", [200, pytest.param(1000, marks=pytest.mark.slow)])
def test_long_chain_at_rest_holds_together(n):
    """Hang n 10 g links: every joint holds to 1 um (the issue asks 1 mm).

    Soft rows alone would be springs of stiffness m_eff omega^2 (m_eff = m / 2, omega = 2 pi 0.25 / h):
    joint 1, carrying n m g, stretched 2 n g / omega^2 (0.43 mm at 200 links, 2.2 mm at 1,000). The
    ball joints' chain is solved exactly (rigid rows), so at rest only rounding is left.
    """
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    _sphere_chain(world, n, (0, 0, 0), (0, 0, -0.02))
    _settle(world, 1.5)
    world.run(duration=0.25)
    assert world.joint_error.max() < 1e-6
    # and it hangs still, its top joint carrying the whole chain
    assert world.kinetic_energy() < 1e-9
    assert world.joint_force[0][2] == pytest.approx(n * 0.01 * G, rel=1e-6)


@pytest.mark.slow
def test_long_chain_falling_from_level_stays_together():
    """Release the benchmark's 1,000-link chain level: drift stays under 1 cm and it gains no energy.

    Without the joints' geometric stiffness the links' zig-zag mode, sqrt(2 T r / I) ~ 2,000 rad/s
    near the top, went unstable at 8 substeps: links spun at 1,200 rad/s, the energy rose 25 J and
    the drift reached 11 mm.
    """
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    _sphere_chain(world, 1000, (0, 0, 0), (0.02, 0, 0))
    worst, energy = 0.0, []
    for _ in range(40):
        world.run(duration=6 * DT)
        worst = max(worst, world.joint_error.max())
        energy.append(world.kinetic_energy() + world.potential_energy())
    assert worst < 1e-2
    assert worst < 1e-3  # the bound at rest holds in the fall too (soft rows alone: 2.0 mm)
    # the chain fell (about 20 m of it hangs), and no step made energy: E stays at or below its start, 0
    assert world.kinetic_energy() > 100.0
    assert max(energy) < 0.1
    # nor lost much: rigid rows whose push-back velocity is relaxed away do no work (soft rows: -33 J of 371)
    assert energy[-1] > -0.01 * world.kinetic_energy()


def test_jointed_pair_does_not_collide_unless_asked():
    """Two overlapping boxes joined by a ball joint make no contact, unless collide=True."""
    for collide in (False, True):
        world = tumble.World(gravity=(0, 0, 0), dt=DT)
        a = world.add_box(position=(0, 0, 1), half_extents=(0.1, 0.1, 0.1))
        b = world.add_box(position=(0.15, 0, 1), half_extents=(0.1, 0.1, 0.1))
        world.add_joint("ball", a, b, anchor=(0.075, 0, 1), collide=collide)
        world.step()
        assert (world.contact_count > 0) is collide


def test_joints_are_deterministic():
    """Run a swinging chain twice: the same state hash, bit for bit."""
    hashes = []
    for _ in range(2):
        world = tumble.World(gravity=(0, 0, -G), dt=DT)
        world.add_plane()
        points = np.array([[0.1 * i, 0, 1.0] for i in range(11)])
        _chain(world, points)
        world.run(duration=1.0)
        hashes.append(world.state_hash())
    assert hashes[0] == hashes[1]


def test_newtons_cradle_passes_the_swing_along():
    """Release the first ball of the cradle sample: the last rises to 95 % of its height, the middle ones stay."""
    world = tumble.load_scene("newtons_cradle")
    z0 = world.body_position[1, 2]
    rest = world.body_position[2:5].copy()
    highest, moved = 0.0, 0.0
    for _ in range(round(0.8 / world.dt)):
        world.step()
        highest = max(highest, world.body_position[5, 2])
        moved = max(moved, np.abs(world.body_position[2:5] - rest).max())
    rest_z = rest[0, 2]
    assert highest - rest_z > 0.95 * (z0 - rest_z)
    assert moved < 0.01
    assert world.joint_error.max() < 1e-4


def test_cloth_pinned_to_a_body_pulls_on_it():
    """Hang a cloth from a box on a rope: the pins follow the box and the rope carries both weights."""
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    box = world.add_box(position=(0, 0, 1.5), half_extents=(0.25, 0.05, 0.05), mass=2.0)
    rope = world.add_joint("rope", None, box, anchor_a=(0, 0, 2.0), anchor_b=(0, 0, 1.55))
    nx = ny = 8
    # rotated 90 degrees about x, the cloth hangs in the xz-plane with grid j along +z: its top row under the box
    index = world.add_cloth(
        size=(0.4, 0.4),
        resolution=(nx, ny),
        position=(0, 0, 1.25),
        orientation=(0.7071067811865476, 0, 0, 0.7071067811865476),
        mass=0.2,
        pins=[(i, ny - 1) for i in range(nx)],
        stiffness=200.0,
        damping=0.05,
        max_stretch=None,
    )  # carried by its springs: the pins feel all of its weight
    cloth = world.cloth.cloths[index]
    pins = [cloth.particle(i, ny - 1) for i in range(nx)]
    assert world.cloth.particle_position[pins, 2] == pytest.approx(1.45)
    world.cloth.pin_to_body(pins, box)
    forces = []
    for k in range(int(3 / DT)):
        if k == int(1 / DT):  # then give the box a push: the pins must follow it
            world.apply_force(box, (200.0, 0, 0))
        world.step()
        forces.append(world.joint_force[rope.index][2])
    local = np.array([[-0.2 + 0.4 * i / (nx - 1), 0.0, -0.05] for i in range(nx)])
    x, q = world.body_position[box.index], world.body_orientation[box.index]
    u, w = q[:3], q[3]
    t = 2 * np.cross(u, local)
    expected = x + local + w * t + np.cross(u, t)
    # the pins are placed by the body's pose in the world's precision: float32 rounds the transform to a few
    # ulps of the positions (~1.5 m; measured 9.6e-8)
    assert np.abs(world.cloth.particle_position[pins] - expected).max() < in_float32(1e-12, ulps(1.5, 4))
    assert world.body_position[box.index, 0] > 0.01  # it swung
    # over the first second (before the push) the rope holds the box and the cloth: 2.2 kg
    assert np.mean(forces[int(0.5 / DT) : int(1 / DT)]) == pytest.approx(2.2 * G, rel=0.01)
