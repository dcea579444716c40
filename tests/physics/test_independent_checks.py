"""Independent checks through the public API, against analytic results and conservation laws.

Written as a grader would, without reading the other physics tests: projectiles, inclines (rolling,
sliding, tipping, launched up), friction (isotropy, twist, a conveyor, backspin, combine rules),
collisions of unequal bodies, oblique ones, flat landings, a free gas, bounces off a static box
and a mesh, resting heights, a 1000:1 stack, large-amplitude pendulums, springs, joined bodies
tumbling in space, torque-free and gravity-driven precession, a hinge's axis, scale invariance,
free cloth, seeds and snapshots. Only the solver's documented constants (contact stiffness,
slop, manifold tolerance, joint stiffness) are read from the package besides the API.

Integrator: semi-implicit Euler per substep h = dt / substeps (v += a h, then x += v h), so under a
constant acceleration a the velocity is exact, v_n = v0 + a n h, and the position is
x_n = x0 + v0 n h + a h^2 n (n + 1) / 2: a h t / 2 ahead of the parabola. Tolerances below are
derived from h, dt and the solver's documented constants (contact stiffness, slop, manifold
tolerance); "rounding" means a few hundred float64 ulps of the quantity compared.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.special import ellipk

import tumble
from tolerances import in_float32, resolution, rounding
from tumble import precision
from tumble.npmath import quat_to_matrix
from tumble.solver import contacts, joints

G = 9.81


def quat_axis_angle(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.r_[axis * np.sin(angle / 2), np.cos(angle / 2)]


def sweep_tolerance() -> float:
    """MANIFOLD_SWEEP_TOLERANCE in the test's precision (1e-6 in float64, 8192 ulps = 9.8e-4 in float32): a
    manifold's sweeps stop when none changes its impulses by more than that fraction of its load, so its
    friction (mu times the load) carries up to that relative error."""
    return float(precision.kernels(precision.DEFAULT_PRECISION).contacts.MANIFOLD_SWEEP_TOLERANCE)


def contact_omega(h: float) -> float:
    """Angular frequency of a soft contact row at substep h (twice it against a static body)."""
    return 2.0 * math.pi * contacts.CONTACT_HERTZ_PER_SUBSTEP_RATE / h


# ---------------------------------------------------------------------------- ballistics


def test_projectile_with_spin_follows_the_discrete_parabola():
    """A spinning ball thrown at (3, 1, 4) m/s: x, y = v0 t exactly, z the scheme's parabola, the spin untouched."""
    dt, substeps = 1 / 240, 8
    h = dt / substeps
    w = tumble.World(dt=dt, substeps=substeps)
    v0, w0 = np.array([3.0, 1.0, 4.0]), np.array([5.0, -7.0, 11.0])
    ball = w.add_sphere(position=(0, 0, 5), radius=0.1, mass=1.0, velocity=v0, angular_velocity=w0)
    steps = w.run(1.0)
    n, t = steps * substeps, w.time
    x, v = w.body_position[ball], w.body_velocity[ball]
    assert x[:2] == pytest.approx(v0[:2] * t, rel=rounding())
    assert x[2] == pytest.approx(5 + v0[2] * t - G * h * h * n * (n + 1) / 2, rel=rounding())
    assert abs(x[2] - (5 + v0[2] * t - G * t * t / 2)) <= G * h * t / 2 * (1 + 1e-9)
    np.testing.assert_allclose(v, [3.0, 1.0, 4.0 - G * t], rtol=rounding())
    # a free sphere has isotropic inertia: its spin never changes
    np.testing.assert_allclose(w.body_angular_velocity[ball], w0, rtol=rounding())


# ---------------------------------------------------------------------------- inclines


@pytest.mark.parametrize("theta_deg, mu", [(20.0, 0.5), (30.0, 0.3), (30.0, 0.1), (45.0, 0.1)])
def test_sphere_on_an_incline_rolls_or_slides(theta_deg, mu):
    """A ball released on a tilted plane rolls at a = 5/7 g sin(theta) if mu >= 2/7 tan(theta), else slides.

    Rolling: the spin keeps w r = v. Sliding: a = g (sin - mu cos) and the friction torque spins it
    up at alpha = 5/2 mu g cos(theta) / r. Both are constant, so the velocity after 1 s is exact to
    within one substep's acceleration, and the distance is the scheme's a h^2 n (n + 1) / 2.
    """
    theta, r = math.radians(theta_deg), 0.1
    normal = np.array([0.0, -math.sin(theta), math.cos(theta)])
    down = np.array([0.0, -math.cos(theta), -math.sin(theta)])
    spin_axis = np.cross(normal, down)  # rolling down the slope turns about n x down
    w = tumble.World()
    h = w.dt / w.substeps
    w.add_plane(normal=normal, offset=0.0, friction=mu, restitution=0.0)
    ball = w.add_sphere(position=normal * r, radius=r, mass=1.0, friction=mu, restitution=0.0)
    steps = w.run(1.0)
    n, t = steps * w.substeps, w.time
    rolls = mu >= 2.0 / 7.0 * math.tan(theta)
    assert rolls == ((theta_deg, mu) in [(20.0, 0.5), (30.0, 0.3)])
    if rolls:
        a = 5.0 / 7.0 * G * math.sin(theta)
        alpha = a / r
    else:
        a = G * (math.sin(theta) - mu * math.cos(theta))
        alpha = 2.5 * mu * G * math.cos(theta) / r
    speed = float(np.dot(w.body_velocity[ball], down))
    spin = float(np.dot(w.body_angular_velocity[ball], spin_axis))
    travelled = float(np.dot(w.body_position[ball] - normal * r, down))
    assert abs(speed - a * t) <= a * h
    assert abs(spin - alpha * t) <= alpha * h
    assert abs(travelled - a * h * h * n * (n + 1) / 2) <= a * h * t
    # it stays on the plane, within the contact slop
    assert abs(np.dot(w.body_position[ball], normal) - r) <= contacts.LINEAR_SLOP
    if not rolls:  # and really slides: the contact point moves down the slope
        assert speed - spin * r > 0.5 * (a - alpha * r) * t


def test_sphere_rolling_on_the_level_keeps_rolling():
    """No rolling resistance: a ball rolling at 2 m/s (w r = v) keeps v, w and its energy for 3 s."""
    w = tumble.World()
    w.add_plane(friction=0.5, restitution=0.0)
    ball = w.add_sphere(
        position=(0, 0, 0.1), radius=0.1, mass=1.0, friction=0.5, restitution=0.0, velocity=(2, 0, 0),
        angular_velocity=(0, 20, 0),
    )  # fmt: skip
    e0 = w.kinetic_energy()
    w.run(3.0)
    np.testing.assert_allclose(w.body_velocity[ball], [2, 0, 0], atol=rounding() * 2, rtol=0)
    np.testing.assert_allclose(w.body_angular_velocity[ball], [0, 20, 0], atol=rounding() * 20, rtol=0)
    assert w.kinetic_energy() == pytest.approx(e0, rel=rounding())
    assert w.body_position[ball, 0] == pytest.approx(2 * w.time, rel=rounding())


@pytest.mark.parametrize("theta_deg, mu", [(20.0, 0.5), (30.0, 0.3)])
def test_box_launched_up_an_incline_stops_then_holds_or_slides_back(theta_deg, mu):
    """A box sent up a ramp at 2 m/s climbs v0^2 / (2 g (sin + mu cos)), then stays (tan < mu) or slides back at g (sin - mu cos).

    Constant decelerations: the scheme stops v0 h / 2 short of the closed form, to within a h^2 (the
    highest point is sampled once per step: within a dt^2 / 8 more), and the speed coming back is
    exact to within one substep's acceleration per phase.
    """
    theta = math.radians(theta_deg)
    normal = np.array([0.0, -math.sin(theta), math.cos(theta)])
    up = np.array([0.0, math.cos(theta), math.sin(theta)])
    half, v0 = 0.1, 2.0
    w = tumble.World()
    h = w.dt / w.substeps
    w.add_plane(normal=normal, friction=mu, restitution=0.0)
    box = w.add_box(
        position=normal * half, half_extents=(half,) * 3, orientation=quat_axis_angle((1, 0, 0), theta), mass=1.0,
        friction=mu, restitution=0.0, velocity=v0 * up,
    )  # fmt: skip
    a_up = G * (math.sin(theta) + mu * math.cos(theta))
    climbed = []
    w.run(2.0, callback=lambda world: climbed.append(float(np.dot(world.body_position[box] - normal * half, up))))
    stop = v0**2 / (2 * a_up) - v0 * h / 2
    # float32: the friction share of a_up carries up to sweep_tolerance() of itself (9.8e-4), the climb as much
    # (measured: 1.3e-4 m of 0.25 m at 20 deg, mu 0.5)
    assert abs(max(climbed) - stop) <= in_float32(a_up * (h * h + w.dt**2 / 8), stop * sweep_tolerance())
    speed = float(np.dot(w.body_velocity[box], up))
    if math.tan(theta) < mu:  # static friction holds it where it stopped
        assert climbed[-1] == pytest.approx(max(climbed), abs=contacts.LINEAR_SLOP)
        assert abs(speed) < 1e-9
    else:
        a_down = G * (math.sin(theta) - mu * math.cos(theta))
        assert -speed == pytest.approx(a_down * (w.time - v0 / a_up), abs=(a_up + a_down) * h)


@pytest.mark.parametrize("yaw_deg, heading_deg", [(0.0, 45.0), (30.0, 0.0), (17.0, 80.0)])
def test_sliding_friction_is_isotropic(yaw_deg, heading_deg):
    """A cube sliding at 2 m/s in any direction relative to its edges stops after v^2 / (2 mu g), on a straight line, unturned.

    The scheme stops v h / 2 short of the closed form, to within mu g h^2.
    """
    mu, v0 = 0.5, 2.0
    heading = np.array([math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg)), 0.0])
    w = tumble.World()
    h = w.dt / w.substeps
    w.add_plane(friction=mu, restitution=0.0)
    box = w.add_box(
        position=(0, 0, 0.1), half_extents=(0.1,) * 3, mass=1.0, friction=mu, restitution=0.0,
        orientation=quat_axis_angle((0, 0, 1), math.radians(yaw_deg)), velocity=v0 * heading,
    )  # fmt: skip
    w.run(1.0)  # stops after v0 / (mu g) = 0.41 s
    x = w.body_position[box]
    stop = v0**2 / (2 * mu * G) - v0 * h / 2
    # float32: the friction carries up to sweep_tolerance() of itself (9.8e-4), the distance as much (measured:
    # 3.4e-4..3.5e-4 m of 0.41 m, against 4e-4 allowed)
    assert abs(float(np.dot(x, heading)) - stop) <= in_float32(mu * G * h * h, stop * sweep_tolerance())
    assert np.linalg.norm(x[:2] - np.dot(x, heading) * heading[:2]) < contacts.LINEAR_SLOP
    R = quat_to_matrix(w.body_orientation[box])
    assert math.degrees(math.atan2(R[1, 0], R[0, 0])) == pytest.approx(yaw_deg, abs=1e-6)
    # at rest the contact cancels a substep's gravity, g h, each substep, its rows to sweep_tolerance() of that
    # load in float32 (measured: 1e-7..2.8e-7 m/s, against 5e-6 allowed)
    assert np.linalg.norm(w.body_velocity[box]) < in_float32(1e-9, G * h * sweep_tolerance())


def test_friction_of_a_moving_kinematic_slab_drags_a_box_up_to_its_speed():
    """A box set on a slab moving at 1 m/s is accelerated at mu g (v = mu g t, within g h) until it rides along."""
    mu, speed = 0.4, 1.0
    w = tumble.World()
    h = w.dt / w.substeps
    w.add_box(position=(0, 0, 0.05), half_extents=(5, 1, 0.05), kinematic=True, velocity=(speed, 0, 0), friction=mu)
    box = w.add_box(position=(0, 0, 0.2), half_extents=(0.1,) * 3, mass=1.0, friction=mu, restitution=0.0)
    catch_up = speed / (mu * G)  # 0.25 s
    for _ in range(round(0.5 * catch_up / w.dt)):
        w.step()
    assert w.body_velocity[box, 0] == pytest.approx(mu * G * w.time, abs=G * h)
    w.run(catch_up)
    assert w.body_velocity[box, 0] == pytest.approx(speed, abs=resolution(1e-9, speed))
    assert abs(w.body_velocity[box, 1]) + abs(w.body_angular_velocity[box]).max() < resolution(1e-9, speed)


@pytest.mark.parametrize("yaw_deg", [20.0, 45.0])
def test_a_box_turned_on_an_incline_slides_straight_down(yaw_deg):
    """A cube turned about the ramp's normal slides down the fall line at g (sin - mu cos), without turning."""
    theta, mu = math.radians(30.0), 0.3
    normal = np.array([0.0, -math.sin(theta), math.cos(theta)])
    down = np.array([0.0, -math.cos(theta), -math.sin(theta)])
    # the orientation: tilt onto the ramp (about x), then turn about the ramp's normal
    yaw = Rotation.from_rotvec(normal * math.radians(yaw_deg)) * Rotation.from_rotvec([theta, 0, 0])
    w = tumble.World()
    h = w.dt / w.substeps
    w.add_plane(normal=normal, friction=mu, restitution=0.0)
    box = w.add_box(
        position=normal * 0.1, half_extents=(0.1,) * 3, orientation=yaw.as_quat(), mass=1.0, friction=mu,
        restitution=0.0,
    )  # fmt: skip
    q0 = w.body_orientation[box].copy()
    w.run(1.0)
    a = G * (math.sin(theta) - mu * math.cos(theta))
    v = w.body_velocity[box]
    assert float(np.dot(v, down)) == pytest.approx(a * w.time, abs=a * h)
    assert abs(float(np.dot(v, np.cross(normal, down)))) < 1e-6 * a * w.time
    # no turn about the normal; the friction's tipping moment mu m g cos(theta) a shifts mu m g cos / 2 from the
    # back corners to the front ones, leaning it by mu g cos / (2 a k), k = (2 omega)^2 (bounded at four times that)
    turn = (Rotation.from_quat(w.body_orientation[box]) * Rotation.from_quat(q0).inv()).as_rotvec()
    assert abs(float(np.dot(turn, normal))) < 1e-9
    omega = contact_omega(h)
    assert np.linalg.norm(turn) < 2 * mu * G / ((2 * omega) ** 2 * 0.1)


def _flush_blocks(w, floor: str, friction: float) -> None:
    """Two static 5 x 10 x 1 m blocks (boxes or hulls) side by side, tops flush at z = 0, the seam at x = 0.3."""
    for x in (-2.2, 2.8):
        o = dict(position=(x, 0, -0.5), static=True, friction=friction, restitution=0.0)
        if floor == "box":
            w.add_box(half_extents=(2.5, 5, 0.5), **o)
        else:
            w.add_convex(points=CUBE * [25, 50, 5], **o)


@pytest.mark.parametrize("body, floor", [("box", "box"), ("hull", "box"), ("hull", "hull")])
def test_a_block_slides_across_the_seam_of_two_coplanar_blocks_as_on_one(body, floor):
    """A frictionless cube sliding at 2 m/s over two static blocks side by side, tops flush: no catch at the seam.

    Nothing acts along the slide, so the speed stays v0 to rounding; the cube rests on the tops by
    its contact's give, g / (2 omega)^2 against a static body, and neither dips nor hops more than
    twice that crossing the seam. (It sank that much into the first block and met the second's side
    as a wall: 2 m/s -> 0.7 m/s, a 4 cm hop and 12 rad/s of tumble.)
    """
    v0, half = 2.0, 0.1
    w = tumble.World()
    h = w.dt / w.substeps
    _flush_blocks(w, floor, friction=0.0)
    o = dict(position=(-0.3, 0.3, half), mass=1.0, velocity=(v0, 0, 0), friction=0.0, restitution=0.0)
    cube = w.add_box(half_extents=(half,) * 3, **o) if body == "box" else w.add_convex(points=CUBE, **o)
    give = G / (2 * contact_omega(h)) ** 2
    z = []
    w.run(0.8, callback=lambda world: z.append(world.body_position[cube, 2] - half))  # over the seam at 0.25 s
    assert w.body_position[cube, 0] > 1.0
    np.testing.assert_allclose(w.body_velocity[cube], [v0, 0, 0], atol=resolution(1e-9, v0), rtol=0)
    assert np.abs(w.body_angular_velocity[cube]).max() < resolution(1e-9, v0 / half)
    assert max(z) <= 2 * give and min(z) >= -2 * give


@pytest.mark.both_precisions
@pytest.mark.parametrize("rate", [240, 60])
@pytest.mark.parametrize(
    "body, floor", [("sphere", "box"), ("sphere", "hull"), ("capsule", "box"), ("capsule", "hull")]
)
def test_a_ball_rolls_over_the_seam_of_two_coplanar_blocks_as_on_one(body, floor, rate):
    """A ball (or a capsule on its side) rolling at 2 m/s over two static blocks side by side, tops flush:
    no hop at the seam, and the rolling speed kept but for what one substep of gravity can give.

    The next block's edge, met speculatively up to a step ahead, kept its normal from the step's start
    (tilted back by up to 0.5 rad) for the whole step, so the contact stopped the ball's approach to
    that tilted plane: a 4.7 mm hop and 0.3 m/s up at dt = 1/240 s, 2 cm at 1/60 (a capsule 1.6 and
    10.7 mm). Its normal is now the block's where the ball first touches it (its face). In both
    precisions: in float32 the ball, resting at overlap 0, came out 2.4e-8 m clear of the next block
    in its frame and was judged to pass by, and hopped 4.7 mm as before.
    """
    v0, r = 2.0, 0.1
    w = tumble.World(dt=1 / rate)
    h = w.dt / w.substeps
    _flush_blocks(w, floor, friction=0.8)
    o = dict(position=(-0.3, 0.3, r), mass=1.0, velocity=(v0, 0, 0), angular_velocity=(0, v0 / r, 0), friction=0.8)
    if body == "sphere":
        ball = w.add_sphere(radius=r, restitution=0.0, **o)
    else:  # lying along y, rolling about it
        ball = w.add_capsule(radius=r, half_height=0.2, orientation=quat_axis_angle((1, 0, 0), np.pi / 2), **o)
    give = G / (2 * contact_omega(h)) ** 2
    z = []
    w.run(0.6, callback=lambda world: z.append(world.body_position[ball, 2] - r))  # over the seam at 0.3 s
    assert w.body_position[ball, 0] > 0.8
    assert max(z) <= 2 * give
    assert np.linalg.norm(w.body_velocity[ball] - [v0, 0, 0]) <= G * h


@pytest.mark.parametrize("spin", [-10.0, -40.0])
def test_a_ball_with_backspin_ends_rolling_at_5v0_minus_2_r_w0_over_7(spin):
    """A ball sliding at 3 m/s with backspin w0 ends rolling at (5 v0 + 2 r w0) / 7 (angular momentum about the contact)."""
    r, v0 = 0.1, 3.0
    w = tumble.World()
    w.add_plane(friction=0.3, restitution=0.0)
    ball = w.add_sphere(
        position=(0, 0, r), radius=r, mass=1.0, friction=0.3, restitution=0.0, velocity=(v0, 0, 0),
        angular_velocity=(0, spin, 0),
    )  # fmt: skip
    w.run(2.0)  # rolling after 2 (v0 - r w0) / (7 mu g) < 1.1 s
    expected = (5 * v0 + 2 * r * spin) / 7
    # once rolling, friction stops; till then v is exact to one substep's mu g h
    assert w.body_velocity[ball, 0] == pytest.approx(expected, abs=0.3 * G * w.dt / w.substeps)
    assert w.body_angular_velocity[ball, 1] * r == pytest.approx(w.body_velocity[ball, 0], abs=rounding() * 10)


@pytest.mark.parametrize("theta_deg, tips", [(10.0, False), (20.0, True)])
def test_a_tall_box_on_a_grippy_ramp_tips_when_tan_theta_exceeds_width_over_height(theta_deg, tips):
    """A 0.1 x 0.1 x 0.4 m box on a ramp with mu = 0.9 (> tan theta: no sliding) stands if tan(theta) < 1/4, else topples."""
    theta = math.radians(theta_deg)
    normal = np.array([0.0, -math.sin(theta), math.cos(theta)])
    w = tumble.World()
    w.add_plane(normal=normal, friction=0.9, restitution=0.0)
    box = w.add_box(
        position=normal * 0.2, half_extents=(0.05, 0.05, 0.2), orientation=quat_axis_angle((1, 0, 0), theta),
        mass=1.0, friction=0.9, restitution=0.0,
    )  # fmt: skip
    w.run(2.0)
    axis = quat_to_matrix(w.body_orientation[box])[:, 2]
    if tips:
        assert float(np.dot(axis, normal)) < 0.5  # over on its side (the top at 60 deg or more from the normal)
    else:
        assert float(np.dot(axis, normal)) > 1 - 1e-9
        np.testing.assert_allclose(w.body_position[box], normal * 0.2, atol=1e-5, rtol=0)


@pytest.mark.parametrize("mine, other", [(0.2, 0.8), (0.8, 0.2)])
def test_materials_combine_as_documented(mine, other):
    """A pair bounces with e = max(e_a, e_b) and slides with mu = sqrt(mu_a mu_b) (docs/scenes.md)."""
    dt, substeps = 1 / 240, 16
    h = dt / substeps
    w = tumble.World(dt=dt, substeps=substeps)
    w.add_plane(restitution=other)
    ball = w.add_sphere(position=(0, 0, 1.1), radius=0.1, mass=1.0, restitution=mine)
    z = []
    w.run(1.5, callback=lambda world: z.append(world.body_position[ball, 2] - 0.1))
    apex = next(z[i] for i in range(1, len(z) - 1) if z[i - 1] < z[i] >= z[i + 1])
    e = max(mine, other)
    assert abs(apex - e * e) <= 3 * math.sqrt(2 * G * e * e) * h
    w = tumble.World()
    w.add_plane(friction=other, restitution=0.0)
    box = w.add_box(
        position=(0, 0, 0.1), half_extents=(0.1,) * 3, mass=1.0, friction=mine, restitution=0.0, velocity=(2, 0, 0)
    )
    w.run(2.0)
    mu, h = math.sqrt(mine * other), w.dt / w.substeps
    stop = 4 / (2 * mu * G) - 2 * h / 2
    # float32: the friction carries up to sweep_tolerance() of itself, the distance as much (measured: 4.5e-4 m
    # of 0.51 m, against 5e-4 allowed)
    assert abs(w.body_position[box, 0] - stop) <= in_float32(mu * G * h * h, stop * sweep_tolerance())


@pytest.mark.parametrize("e", [0.5, 0.0])
@pytest.mark.parametrize("mu", [0.05, 0.1, 0.5])
def test_a_ball_hitting_the_floor_obliquely_takes_a_coulomb_impulse(mu, e):
    """A ball striking the floor at (3, 0, -2) m/s: v_n' = e v_n; friction mu (1 + e) v_n slows and spins it,
    unless that would pass rolling, where it ends rolling at 5/7 v_t (no gravity: one impact, nothing else).
    e = 0 too, where no collision pass acts and the solve's rows stop the ball: its friction is the impact's all the same."""
    r, vt, vn = 0.1, 3.0, 2.0
    w = tumble.World(gravity=(0, 0, 0), restitution_threshold=0.0)
    w.add_plane(restitution=e, friction=mu)
    ball = w.add_sphere(
        position=(0, 0, r + 0.05), radius=r, mass=1.0, restitution=e, friction=mu, velocity=(vt, 0, -vn)
    )
    w.run(0.3)
    jn = (1 + e) * vn  # normal impulse per unit mass
    if mu * jn < 2 / 7 * vt:  # slides all through the impact
        vt_after, spin = vt - mu * jn, 2.5 * mu * jn / r
    else:  # the contact point stops: rolling
        vt_after, spin = 5 / 7 * vt, 5 / 7 * vt / r
    np.testing.assert_allclose(w.body_velocity[ball], [vt_after, 0, e * vn], atol=rounding() * 10, rtol=0)
    np.testing.assert_allclose(w.body_angular_velocity[ball], [0, spin, 0], atol=rounding() * 100, rtol=0)


def test_box_spinning_flat_on_the_floor_stops_at_the_four_corner_friction_torque():
    """A cube spun about the vertical decelerates at mu m g sqrt(2) a / I (its load on its four corners).

    Tumble's box-plane contact is its four corners (as Bullet's and Rapier's manifolds), each at the
    arm sqrt(2) a from the centre; a uniformly pressed square would give 0.765 a instead of 1.414 a.
    The deceleration is constant, so the spin falls linearly to within one substep's change.
    """
    a, m, mu, w0 = 0.1, 1.0, 0.5, 10.0
    w = tumble.World()
    h = w.dt / w.substeps
    w.add_plane(friction=mu, restitution=0.0)
    box = w.add_box(
        position=(0, 0, a), half_extents=(a, a, a), mass=m, friction=mu, restitution=0.0, angular_velocity=(0, 0, w0)
    )
    inertia = m * (2 * a) ** 2 / 6
    alpha = mu * m * G * math.sqrt(2) * a / inertia
    t_stop = w0 / alpha  # 0.096 s
    for _ in range(round(0.9 * t_stop / w.dt)):  # late, where a 1 % change of alpha moves w by 1.7 alpha h
        w.step()
    assert w.body_angular_velocity[box, 2] == pytest.approx(w0 - alpha * w.time, abs=alpha * h)
    w.run(2 * t_stop)
    assert abs(w.body_angular_velocity[box, 2]) < alpha * h
    # it spun in place
    assert np.hypot(*w.body_position[box, :2]) < contacts.LINEAR_SLOP


# ---------------------------------------------------------------------------- collisions


@pytest.mark.parametrize("m1, m2", [(1.0, 3.0), (5.0, 1.0), (1.0, 100.0)])
@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_unequal_spheres_head_on_follow_newtons_law(m1, m2, e):
    """Head-on: v1' = vc - e m2 (u1 - u2) / M, v2' = vc + e m1 (u1 - u2) / M; momentum exact."""
    u1, u2 = 2.0, -0.5
    w = tumble.World(gravity=(0, 0, 0), restitution_threshold=0.0)
    a = w.add_sphere(position=(-0.5, 0, 0), radius=0.1, mass=m1, velocity=(u1, 0, 0), restitution=e, friction=0)
    b = w.add_sphere(position=(0.5, 0, 0), radius=0.1, mass=m2, velocity=(u2, 0, 0), restitution=e, friction=0)
    p0 = w.momentum()
    w.run(1.0)
    vc = (m1 * u1 + m2 * u2) / (m1 + m2)
    expected_a = vc - e * m2 * (u1 - u2) / (m1 + m2)
    expected_b = vc + e * m1 * (u1 - u2) / (m1 + m2)
    scale = abs(u1) + abs(u2)
    np.testing.assert_allclose(w.body_velocity[a], [expected_a, 0, 0], atol=rounding() * scale, rtol=0)
    np.testing.assert_allclose(w.body_velocity[b], [expected_b, 0, 0], atol=rounding() * scale, rtol=0)
    np.testing.assert_allclose(w.momentum(), p0, atol=rounding() * (m1 * abs(u1) + m2 * abs(u2)), rtol=0)
    assert np.abs(w.body_angular_velocity[[a, b]]).max() == 0.0


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_aligned_boxes_head_on_follow_newtons_law(e):
    """Two cubes (1 and 3 kg) meeting face to face: 1D Newton's law to the manifold solve's tolerance."""
    m1, m2, u1, u2 = 1.0, 3.0, 2.0, -0.5
    w = tumble.World(gravity=(0, 0, 0), restitution_threshold=0.0)
    a = w.add_box(
        position=(-0.5, 0, 0), half_extents=(0.1, 0.1, 0.1), mass=m1, velocity=(u1, 0, 0), restitution=e, friction=0
    )
    b = w.add_box(
        position=(0.5, 0, 0), half_extents=(0.1, 0.1, 0.1), mass=m2, velocity=(u2, 0, 0), restitution=e, friction=0
    )
    p0, e0 = w.momentum(), w.kinetic_energy()
    w.run(1.0)
    vc = (m1 * u1 + m2 * u2) / (m1 + m2)
    tol = float(contacts.MANIFOLD_TOLERANCE)  # the collision sweeps stop when no row changes by more [m/s]
    assert w.body_velocity[a, 0] == pytest.approx(vc - e * m2 * (u1 - u2) / (m1 + m2), abs=tol)
    assert w.body_velocity[b, 0] == pytest.approx(vc + e * m1 * (u1 - u2) / (m1 + m2), abs=tol)
    np.testing.assert_allclose(w.momentum(), p0, atol=rounding() * (m1 * abs(u1) + m2 * abs(u2)), rtol=0)
    if e == 1.0:
        assert abs(w.kinetic_energy() - e0) <= tol * (m1 * abs(u1) + m2 * abs(u2))


def _solid(world, shape, position, size, **options):
    """A ball of radius `size` or a cube of half side `size`."""
    if shape == "ball":
        return world.add_sphere(position=position, radius=size, **options)
    return world.add_box(position=position, half_extents=(size, size, size), **options)


@pytest.mark.parametrize("shape", ["ball", "box"])
def test_a_row_of_touching_bodies_struck_inelastically_moves_off_as_one(shape):
    """Five equal bodies in a row, touching, struck at one end at 1 m/s with e = 0 (zero g, no friction):
    every contact closes, and all six move at 1/6 m/s with 1/6 of the kinetic energy (the impulse-
    momentum solution, whatever the order of the collisions). The collision pass stops when no row
    changes by MANIFOLD_TOLERANCE, so each of the five contacts may leave that much: the bound."""
    n, r, v0 = 5, 0.05, 1.0
    w = tumble.World(gravity=(0, 0, 0))
    row = [_solid(w, shape, (i * 2 * r, 0, 0), r, mass=1.0, restitution=0.0, friction=0.0) for i in range(n)]
    striker = _solid(w, shape, (-0.3, 0, 0), r, mass=1.0, restitution=0.0, friction=0.0, velocity=(v0, 0, 0))
    ke0 = w.kinetic_energy()
    w.run(1.0)
    bodies = [striker, *row]
    tol = n * float(contacts.MANIFOLD_TOLERANCE)
    np.testing.assert_allclose(w.body_velocity[bodies][:, 0], v0 / (n + 1), atol=tol, rtol=0)
    assert np.abs(w.body_velocity[bodies][:, 1:]).max() <= tol
    assert w.kinetic_energy() == pytest.approx(ke0 / (n + 1), rel=2 * (n + 1) * tol / v0)


def test_a_heavy_box_landing_inelastically_on_a_tower_leaves_it_standing():
    """A 10 kg cube lands at 8 m/s, a little off centre, on a settled tower of ten 1 kg cubes, e = 0
    everywhere: the collision runs down the tower into the floor, and the tower stands, top-heavy and
    swaying. Bound: through 3 s every cube stays on the one below it (centres within a quarter of a side
    apart, the heavy one on top), and none of the tower's cubes leaves its support. (With the collision
    pass pushing overlaps apart at -s / h, every resting contact of the struck tower did: its cubes flew up
    at up to 1.5 m/s and it fell 1.3 m aside.)"""
    half = 0.1
    w = tumble.World(dt=1 / 240)
    w.add_plane(restitution=0.0, friction=0.6)
    column = [
        w.add_box(
            position=(0, 0, half + 2 * half * i + 0.0005 * i),
            half_extents=(half, half, half),
            mass=1.0,
            restitution=0.0,
            friction=0.6,
        )
        for i in range(10)
    ]
    w.run(0.25)
    top = w.body_position[column[-1]].copy()
    column.append(
        w.add_box(
            position=(0.02, 0.01, top[2] + 0.4),
            half_extents=(half, half, half),
            mass=10.0,
            restitution=0.0,
            friction=0.6,
            velocity=(0, 0, -8.0),
        )
    )
    for _ in range(round(3.0 / w.dt)):
        w.step()
        x = w.body_position[column]
        assert np.linalg.norm(np.diff(x[:, :2], axis=0), axis=1).max() < 0.5 * half
        assert np.diff(x[:, 2]).min() > 1.9 * half  # each on the one below, none slipped off beside it
    assert w.body_position[column[-1], 2] == pytest.approx(top[2] + 2 * half, abs=0.05 * half)


@pytest.mark.parametrize("shape", ["ball", "box"])
@pytest.mark.parametrize("light", [0.5, 0.2])
@pytest.mark.parametrize("v0", [2.0, 8.0])
def test_a_heavy_body_landing_inelastically_on_a_light_one_on_the_floor_does_not_bounce(shape, light, v0):
    """A 5 kg ball (cube) lands at v0 on a 0.5 or 0.2 kg one resting on the floor, e = 0 everywhere:
    both contacts close and the heavy one stays where it lands, on the light one. What may be left is
    the soft rows' push on the overlap the collision pass leaves: bounded here by a rise of LINEAR_SLOP
    above touching and an upward speed of 1 % of v0. (Both contacts solved in turn, 16 sweeps, left
    the heavy body half its speed into the light one and it rebounded from the overlap: at 15 to 18 %
    of v0, 7 to 108 mm high.)"""
    r = 0.1
    w = tumble.World(dt=1 / 240)
    w.add_plane(restitution=0.0, friction=0.5)
    low = _solid(w, shape, (0, 0, r), r, mass=light, restitution=0.0, friction=0.5)
    high = _solid(w, shape, (0, 0, 3 * r + 0.02), r, mass=5.0, restitution=0.0, friction=0.5, velocity=(0, 0, -v0))
    landed, rise, up = False, -math.inf, 0.0
    for _ in range(240):
        w.step()
        z = w.body_position[high, 2]
        landed = landed or z < 3 * r
        if landed:
            rise = max(rise, z - 3 * r)
            up = max(up, w.body_velocity[high, 2])
    assert landed
    assert rise <= contacts.LINEAR_SLOP
    assert up <= 0.01 * v0
    assert w.body_velocity[low, 2] == pytest.approx(0.0, abs=0.01 * v0)


@pytest.mark.parametrize("e", [0.3, 0.5])
@pytest.mark.parametrize("rolling", [0.0, 1.0])
def test_a_heavy_ball_bouncing_off_a_light_one_on_the_floor_gains_no_energy_in_any_step(e, rolling):
    """A 3 kg ball (r 8 cm) dropped 10 cm onto a 0.25 kg ball (r 10 cm) on the floor, 8 cm off its top,
    the light ball resting or rolling at 1 m/s; e and mu = 1 everywhere. Kinetic plus potential energy
    may rise in a step by no more than a thousandth of the energy the heavy ball brings (m_h g 0.1 m,
    2.9 J). The landing leaves the light ball's floor contact holding over 200 times its weight; the
    next step's warm start put it back, and one relax sweep between the heavy ball and the floor took
    too little of it out: 15.7 mJ in a step at e = 0.3 and 6.9 mJ at e = 0.5 (5.3 and 2.3
    thousandths), before the relax pass swept the bodies that a pass changed fast on
    (`RELAX_TRIGGER`); now 0.51 mJ at most (0.17 thousandths)."""
    r_light, r_heavy, m_light, m_heavy = 0.1, 0.08, 0.25, 3.0
    w = tumble.World(dt=1 / 240)
    w.add_plane(restitution=e, friction=1.0)
    light = w.add_sphere(
        position=(0, 0, r_light),
        radius=r_light,
        mass=m_light,
        restitution=e,
        friction=1.0,
        velocity=(0, rolling, 0),
        angular_velocity=(-rolling / r_light, 0, 0),
    )
    heavy = w.add_sphere(
        position=(0.08, 0, 2 * r_light + r_heavy + 0.1),
        radius=r_heavy,
        mass=m_heavy,
        restitution=e,
        friction=1.0,
        velocity=(0, rolling, 0),
    )

    def energy():
        return w.kinetic_energy() + G * (m_light * w.body_position[light, 2] + m_heavy * w.body_position[heavy, 2])

    met, gain = False, 0.0
    before = energy()
    for _ in range(240):
        w.step()
        x = w.body_position
        met = met or float(np.linalg.norm(x[heavy] - x[light])) < r_light + r_heavy + 1e-3
        now = energy()
        gain = max(gain, now - before)
        before = now
    assert met
    assert gain <= 1e-3 * m_heavy * G * 0.1


def _oblique(e: float, mu: float, dt: float = 1 / 240):
    """Spheres of 1 and 2 kg, centres offset (0.1, 0.05) m across a 3 m/s approach along x."""
    w = tumble.World(gravity=(0, 0, 0), restitution_threshold=0.0, dt=dt)
    a = w.add_sphere(position=(-0.5, 0, 0), radius=0.1, mass=1.0, velocity=(2, 0, 0), restitution=e, friction=mu)
    b = w.add_sphere(position=(0.5, 0.1, 0.05), radius=0.1, mass=2.0, velocity=(-1, 0, 0), restitution=e, friction=mu)
    return w, a, b


@pytest.mark.parametrize("e, mu", [(1.0, 0.0), (0.5, 0.0), (0.8, 0.3)])
def test_oblique_sphere_collision_conserves_momentum_and_elastic_energy(e, mu):
    """An off-centre collision keeps the momentum exactly, and the energy when e = 1 and mu = 0."""
    w, a, b = _oblique(e, mu)
    p0, e0 = w.momentum(), w.kinetic_energy()
    w.run(1.0)
    assert np.linalg.norm(w.body_velocity[a] - [2, 0, 0]) > 0.5  # they did collide
    np.testing.assert_allclose(w.momentum(), p0, atol=rounding() * 4.0, rtol=0)
    if e == 1.0 and mu == 0.0:
        assert w.kinetic_energy() == pytest.approx(e0, rel=rounding())
    else:
        assert w.kinetic_energy() < e0
    if mu == 0.0:  # frictionless: no spin
        assert np.abs(w.body_angular_velocity[[a, b]]).max() < rounding()


def test_oblique_sphere_impulse_is_along_the_line_of_centres_at_impact():
    """The impulse of a frictionless oblique collision lies along the line of centres at the moment of impact.

    With the normal taken at the substep of impact its direction is off by at most the relative
    travel of one substep over the centre distance, v_rel h / (ra + rb); angular momentum about
    any fixed point is then kept to the same order.
    """
    w, a, b = _oblique(1.0, 0.0)
    h = w.dt / w.substeps
    w.run(1.0)
    # impact: |d0 + v_rel t| = ra + rb with d0 = (1, 0.1, 0.05), v_rel = (-3, 0, 0)
    at_impact = np.array([math.sqrt(0.2**2 - 0.1**2 - 0.05**2), 0.1, 0.05]) / 0.2
    dv = w.body_velocity[b] - np.array([-1.0, 0, 0])
    angle = math.acos(min(1.0, float(np.dot(dv, at_impact) / np.linalg.norm(dv))))
    assert angle <= 3.0 * h / 0.2


def _slide_off_a_sphere(L: float, tilt: float, gap: float) -> tuple[float, float]:
    """(cos theta at release, cos theta where the gap first exceeds `gap`) of a frictionless particle
    sliding from rest, `tilt` rad off the top of a sphere, on the sphere of radius L its centre keeps:
    theta'' = g sin(theta) / L while the normal force m g cos(theta) - m L theta'^2 is positive
    (integrated in 1e-6 s steps), then the parabola, solved for the gap by bisection."""
    theta, omega, dt = tilt, 0.0, 1e-6
    while G * math.cos(theta) > L * omega * omega:
        omega += G * math.sin(theta) / L * dt
        theta += omega * dt
    p0 = L * np.array([math.sin(theta), math.cos(theta)])
    v0 = L * omega * np.array([math.cos(theta), -math.sin(theta)])

    def at(t):
        return p0 + v0 * t + np.array([0.0, -0.5 * G * t * t])

    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.linalg.norm(at(mid)) - L < gap else (lo, mid)
    p = at(hi)
    return math.cos(theta), float(p[1] / np.linalg.norm(p))


@pytest.mark.parametrize("dt", [1 / 120, 1 / 240])
def test_a_ball_sliding_off_a_sphere_leaves_where_the_normal_force_vanishes(dt):
    """A frictionless ball (r = 0.1 m) slides from near the top of a static sphere (R = 1 m): it stays on
    it until cos(theta) = 2/3, then flies off on the parabola.

    While the exact path is on the sphere the ball stays within one step's chord of it, v^2 dt^2 / 2L
    (L = R + r); where the exact path is 1 mm off, so is the ball, to the turn of two steps, 2 sin(theta)
    omega dt: the step in which the crossing is seen, and the scheme's own first-order lag. The contact's gap followed the step start's tangent plane, and pushed the ball out along
    the stale normal every substep: it bounced along a gap of 0.18 mm from cos(theta) = 0.74 on and
    was 1 mm off at cos(theta) = 0.606 against the path's 0.570 (dt = 1/240 s)."""
    R, r, tilt = 1.0, 0.1, 1e-3
    L = R + r
    w = tumble.World(dt=dt, substeps=8)
    w.add_sphere(position=(0, 0, 0), radius=R, static=True, friction=0.0, restitution=0.0)
    ball = w.add_sphere(position=(L * math.sin(tilt), 0, L * math.cos(tilt)), radius=r, friction=0.0, restitution=0.0)
    release, off = _slide_off_a_sphere(L, tilt, 1e-3)
    assert release == pytest.approx(2 / 3 * math.cos(tilt), abs=1e-5)
    on_gap, seen = 0.0, None
    while seen is None:
        w.step()
        p = w.body_position[ball]
        cos = p[2] / np.linalg.norm(p)
        gap = np.linalg.norm(p) - L
        if cos > release:
            on_gap = max(on_gap, gap)
        elif gap > 1e-3:
            seen = cos
        assert w.time < 5.0
    v2 = 2 * G * L * (math.cos(tilt) - release)  # the speed^2 at release
    assert on_gap <= v2 * dt * dt / (2 * L)
    sin = math.sqrt(1 - off * off)
    assert abs(seen - off) <= 2 * sin * math.sqrt(v2) / L * dt


def test_free_gas_of_boxes_and_spheres_keeps_momentum_and_energy():
    """27 tumbling boxes and balls, e = 1, mu = 0, no gravity, no walls: p exact, KE to the manifold tolerance."""
    rng = np.random.default_rng(5)
    w = tumble.World(gravity=(0, 0, 0), restitution_threshold=0.0)
    for i in range(27):
        p = 0.35 * np.array([i % 3, (i // 3) % 3, i // 9]) + rng.uniform(-0.03, 0.03, 3)
        v = rng.normal(0, 1, 3)
        m = rng.uniform(0.5, 2)
        if i % 2:
            q = rng.normal(size=4)
            w.add_box(
                position=p, half_extents=(0.1, 0.07, 0.05), mass=m, orientation=q / np.linalg.norm(q), velocity=v,
                angular_velocity=rng.normal(0, 2, 3), restitution=1, friction=0,
            )  # fmt: skip
        else:
            w.add_sphere(position=p, radius=0.08, mass=m, velocity=v, restitution=1, friction=0)
    p0, e0 = w.momentum(), w.kinetic_energy()
    scale = float(np.sum(w.body_mass * np.linalg.norm(w.body_velocity, axis=1)))  # sum m |v| [kg m/s]
    contacts_seen = 0
    for _ in range(480):
        w.step()
        contacts_seen += w.contact_count
    assert contacts_seen > 20
    assert np.linalg.norm(w.momentum() - p0) <= rounding() * scale
    # each box-box collision sweep stops within MANIFOLD_TOLERANCE [m/s] per row: energy within that times sum m|v|
    assert abs(w.kinetic_energy() - e0) <= float(contacts.MANIFOLD_TOLERANCE) * scale


def _off_centre_hit(shape: str, e: float, mu: float, dt: float):
    """Two 1 kg blocks 20 cm across (boxes, or hulls of a stretched cube), the second turned 0.6 rad
    about z and 5 cm aside, meeting at 4 m/s along x across a 2 m/s shear along y, no gravity."""
    w = tumble.World(gravity=(0, 0, 0), dt=dt)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * [0.12, 0.1, 0.08]
    turned = (0.0, 0.0, math.sin(0.3), math.cos(0.3))
    bodies = []
    for x, v, q in (((-0.3, 0, 0), (2, 1, 0), (0, 0, 0, 1)), ((0.3, 0.05, 0), (-2, -1, 0), turned)):
        o = dict(position=x, mass=1.0, velocity=v, orientation=q, restitution=e, friction=mu)
        if shape == "box":
            bodies.append(w.add_box(half_extents=(0.1, 0.1, 0.1), **o))
        else:
            bodies.append(w.add_convex(points=corners, **o))
    return w, bodies


@pytest.mark.parametrize("dt", [1 / 240, 1 / 60])
@pytest.mark.parametrize("e, mu", [(0.0, 0.0), (0.5, 0.5)])
@pytest.mark.parametrize("shape", ["box", "hull"])
def test_off_centre_hit_of_two_blocks_keeps_angular_momentum(shape, e, mu, dt):
    """Two blocks hit off-centre in free space, sticking or bouncing, with friction or without:
    momentum is kept to rounding, and angular momentum about the origin to 1 % of what anchors
    left where the step began would lose.

    An impulse P whose anchors on the two bodies are apart by g changes L by g x P. The contact
    is found up to a step's approach early and collides later in the step, when the bodies have
    slid across each other by up to |v_rel| dt; so its anchors are made to meet where the bodies
    will be when it closes, and the collision pass's where they are (solver/contacts.py,
    `_impact_anchors`, `_met`). Anchors left where the step began lost 0.4 to 4 % of |x| m v
    here; a bounce now keeps L to rounding, a sticking hit to 4e-5 of |x| m v at most (its
    impulse is spread over the substep in which it closes, and the gap follows the surface
    points, not the moved anchors).
    """
    w, (a, b) = _off_centre_hit(shape, e, mu, dt)
    p0, l0 = w.momentum(), _total_angular_momentum(w)
    v_rel = math.hypot(4.0, 2.0)
    scale = 0.3 * 1.0 * math.hypot(2.0, 1.0) * 2  # |x| m |v| of the two bodies [kg m^2/s]
    w.run(0.5)
    impulse = 1.0 * np.linalg.norm(w.body_state(a).velocity - [2, 1, 0])  # m_a |dv_a| [N s]
    assert impulse > 0.5  # they did collide
    assert np.linalg.norm(w.momentum() - p0) <= rounding() * scale
    drift = v_rel * dt * impulse  # [kg m^2/s]: what the step's slide across the impulse would turn
    assert np.linalg.norm(_total_angular_momentum(w) - l0) <= resolution(0.01 * drift, scale)


@pytest.mark.parametrize("e", [0.3, 0.6, 0.9])
def test_ball_bouncing_on_a_static_box_rises_to_e_squared(e):
    """A ball dropped 1 m onto a static box's top face rises to e^2, e^4, e^6 m (within 3 v h per bounce)."""
    dt, substeps, r = 1 / 240, 16, 0.1
    h = dt / substeps
    w = tumble.World(dt=dt, substeps=substeps)
    w.add_box(position=(0, 0, -0.5), half_extents=(1.0, 1.0, 0.5), static=True, restitution=e)
    ball = w.add_sphere(position=(0, 0, 1 + r), radius=r, mass=1.0, restitution=e)
    z = []
    w.run(4.0, callback=lambda world: z.append(world.body_position[ball, 2] - r))
    apex = [z[i] for i in range(1, len(z) - 1) if z[i - 1] < z[i] >= z[i + 1] and z[i] > 1e-3]
    assert len(apex) >= 2
    for k, measured in enumerate(apex[:3], start=1):
        expected = e ** (2 * k)
        assert abs(measured - expected) <= 3 * math.sqrt(2 * G * expected) * h, (k, measured, expected)


def test_elastic_ball_keeps_its_bounce_height_to_first_order():
    """e = 1 on a plane: each apex is the last within g h per impact in speed, v h in height (v = sqrt(2 g h0)).

    That is the scheme's first-order loss: one substep's gravity g h of the rebound speed. The apex is
    sampled once per step, within g dt^2 / 8 of the true one (two of them in a difference).
    """
    dt, substeps, r = 1 / 240, 16, 0.1
    h = dt / substeps
    w = tumble.World(dt=dt, substeps=substeps)
    w.add_plane(restitution=1.0)
    ball = w.add_sphere(position=(0, 0, 1 + r), radius=r, mass=1.0, restitution=1.0)
    z = []
    w.run(8.0, callback=lambda world: z.append(world.body_position[ball, 2] - r))
    apex = np.array([z[i] for i in range(1, len(z) - 1) if z[i - 1] < z[i] >= z[i + 1] and z[i] > 1e-3])
    assert len(apex) >= 7
    v = math.sqrt(2 * G * 1.0)
    assert np.all(np.abs(np.diff(np.r_[1.0, apex])) <= v * h + G * dt * dt / 4)
    assert np.all(apex <= 1.0)  # and never gains


FLOOR = (np.array([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], float), np.array([[0, 1, 2], [0, 2, 3]]))
CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * 0.1


def _flat_drop(shape: str, floor: str, e: float):
    """A body of 1 kg dropped 1 m flat (a capsule lying along x) onto a plane or a two-triangle mesh floor."""
    w = tumble.World(dt=1 / 240, substeps=16)
    if floor == "plane":
        w.add_plane(restitution=e)
    else:
        w.add_mesh(vertices=FLOOR[0], triangles=FLOOR[1], restitution=e)
    at = (0.05, 0.03)
    if shape == "box":
        body, rest = w.add_box(position=(*at, 1.1), half_extents=(0.1,) * 3, mass=1.0, restitution=e), 0.1
    elif shape == "hull":
        body, rest = w.add_convex(points=CUBE, position=(*at, 1.1), mass=1.0, restitution=e), 0.1
    elif shape == "sphere":
        body, rest = w.add_sphere(position=(*at, 1.1), radius=0.1, mass=1.0, restitution=e), 0.1
    else:
        flat = quat_axis_angle((0, 1, 0), math.pi / 2)
        body = w.add_capsule(
            position=(*at, 1.05), radius=0.05, half_height=0.2, orientation=flat, mass=1.0, restitution=e
        )
        rest = 0.05
    z, spin = [], []
    w.run(
        1.2,
        callback=lambda world: (
            z.append(world.body_position[body, 2] - rest),
            spin.append(np.abs(world.body_angular_velocity[body]).max()),
        ),
    )
    apex = [z[i] for i in range(1, len(z) - 1) if z[i - 1] < z[i] >= z[i + 1] and z[i] > 1e-3]
    return apex[0], max(spin), w.dt / w.substeps


@pytest.mark.parametrize("floor", ["plane", "mesh"])
@pytest.mark.parametrize("shape", ["box", "hull", "sphere"])
def test_a_body_dropped_flat_bounces_to_e_squared_without_turning(shape, floor):
    """Box, convex cube and ball landing flat (e = 0.5) on a plane or a mesh floor rise to e^2 m, unturned.

    A face's corners collide together, swept until no row changes by MANIFOLD_TOLERANCE [m/s]: the
    spin left is below that over the corners' 0.1 m arm.
    """
    apex, spin, h = _flat_drop(shape, floor, 0.5)
    assert abs(apex - 0.25) <= 3 * math.sqrt(2 * G * 0.25) * h
    assert spin < float(contacts.MANIFOLD_TOLERANCE) / 0.1


@pytest.mark.parametrize("shape", ["box", "hull"])
@pytest.mark.parametrize("mu", [0.5, 0.2])
def test_a_cube_landing_flat_across_the_floor_slows_without_tipping(shape, mu):
    """A 0.2 m cube lands flat at (2, 0, -3) m/s, e = 0.5, no gravity. The impulse-momentum solution:
    j_n = (1 + e) m v_n = 4.5 N s; friction stops the sliding if it can (mu j_n >= m v_t) or takes
    mu j_n; its moment about the centre, 0.1 m x j_t, is within the most the corners can give
    (0.1 m x j_n), so the load shifts forward and the cube does not turn. It leaves at (v_t - j_t / m,
    0, e v_n) without spin. (Friction applied once after the normal impulses turned it: 12 rad/s.)

    The block's rounds stop when no impulse changes the speeds by MANIFOLD_TOLERANCE [m/s]; each
    leaves ~0.6 of the last's sliding, so the speeds are within a few times that.
    """
    half, m, vt, vn, e = 0.1, 1.0, 2.0, 3.0, 0.5
    w = tumble.World(gravity=(0, 0, 0), restitution_threshold=0.0)
    w.add_plane(restitution=e, friction=mu)
    common = dict(position=(0, 0, half + 0.03), mass=m, restitution=e, friction=mu, velocity=(vt, 0, -vn))
    if shape == "box":
        cube = w.add_box(half_extents=(half,) * 3, **common)
    else:
        corners = [(x, y, z) for x in (-half, half) for y in (-half, half) for z in (-half, half)]
        cube = w.add_convex(points=corners, **common)
    w.run(0.1)
    jt = min(m * vt, mu * (1 + e) * m * vn)
    tol = 4 * float(contacts.MANIFOLD_TOLERANCE)
    np.testing.assert_allclose(w.body_velocity[cube], [vt - jt / m, 0, e * vn], atol=tol, rtol=0)
    np.testing.assert_allclose(w.body_angular_velocity[cube], 0.0, atol=tol / half)


def test_a_tall_box_landing_across_the_floor_tips_only_when_its_corners_cannot_hold_the_friction():
    """A 0.1 x 0.1 x 0.6 m box lands upright at (2, 0, -3) m/s, e = 0.3, no gravity: j_n = 3.9 N s. With
    mu = 0.1 its friction, 0.39 N s at 0.3 m below the centre, is within the corners' most (0.05 m x
    3.9 N s): it slides on at 2 - 0.39 m/s without turning. With mu = 1 it is not, and the box tips
    forward; neither gains energy."""
    results = {}
    for mu in (0.1, 1.0):
        w = tumble.World(gravity=(0, 0, 0), restitution_threshold=0.0)
        w.add_plane(restitution=0.3, friction=mu)
        box = w.add_box(
            position=(0, 0, 0.35),
            half_extents=(0.05, 0.05, 0.3),
            mass=1.0,
            restitution=0.3,
            friction=mu,
            velocity=(2, 0, -3),
        )
        e0 = w.kinetic_energy()
        w.run(0.05)
        assert w.kinetic_energy() < e0
        results[mu] = w.body_velocity[box].copy(), w.body_angular_velocity[box].copy()
    tol = 4 * float(contacts.MANIFOLD_TOLERANCE)
    np.testing.assert_allclose(results[0.1][0], [2 - 0.39, 0, 0.9], atol=tol, rtol=0)
    np.testing.assert_allclose(results[0.1][1], 0.0, atol=tol / 0.05)
    assert results[1.0][1][1] > 1.0  # tipping forward, about +y


@pytest.mark.parametrize("floor", ["plane", "mesh"])
def test_a_capsule_dropped_flat_bounces_to_e_squared_without_turning(floor):
    """A capsule landing flat has two simultaneous end contacts: by symmetry it bounces to e^2 m and does not turn."""
    apex, spin, h = _flat_drop("capsule", floor, 0.5)
    assert abs(apex - 0.25) <= 3 * math.sqrt(2 * G * 0.25) * h
    assert spin < float(contacts.MANIFOLD_TOLERANCE) / 0.2


def _point_strike(shape: str, e: float, mu: float, v: float = 2.0, m: float = 1.0, threshold: float = 0.0):
    """A capsule's end or a box's (convex box's, `hull`) single lowest corner striking a floor at v [m/s],
    tilted 45 degrees, no gravity: the world, the body, its contact point c from the centre and
    K = 1/m - [c]x I^-1 [c]x (I the world inertia before the impact)."""
    w = tumble.World(gravity=(0, 0, 0), restitution_threshold=threshold)
    w.add_plane(restitution=e, friction=mu)
    tilt = Rotation.from_euler("y", -45, degrees=True)
    kw = dict(velocity=(0, 0, -v), mass=m, restitution=e, friction=mu)
    if shape == "capsule":
        r, a = 0.01, 0.49
        q = tilt * Rotation.from_euler("y", 90, degrees=True)
        c = q.apply([0, 0, -a]) + np.array([0, 0, -r])
        body = w.add_capsule(position=(0, 0, 0.01 - c[2]), radius=r, half_height=a, orientation=q.as_quat(), **kw)
    else:
        he = np.array([0.3, 0.05, 0.05])
        q = tilt * Rotation.from_euler("x", 25, degrees=True)
        corners = q.apply(np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * he)
        c = corners[np.argmin(corners[:, 2])]
        if shape == "box":
            body = w.add_box(position=(0, 0, 0.01 - c[2]), half_extents=tuple(he), orientation=q.as_quat(), **kw)
        else:
            unturned = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * he
            body = w.add_convex(position=(0, 0, 0.01 - c[2]), points=unturned, orientation=q.as_quat(), **kw)
    cx = np.array([[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]])
    K = np.eye(3) / m - cx @ np.linalg.inv(w.body_inertia_world[body]) @ cx
    return w, body, c, K


@pytest.mark.parametrize("shape", ["capsule", "box", "hull"])
def test_an_end_or_corner_striking_a_grippy_floor_sticks_as_the_impulse_momentum_equations_say(shape):
    """A capsule's end, or a box's (convex box's) single lowest corner, strikes a floor at 2 m/s (e = 0,
    mu = 5, no gravity), tilted 45 degrees: a sticking impact, the contact point stopped.

    The impulse J solves K J = -v_p, K = 1/m - [c]x I^-1 [c]x (c: the contact point from the centre,
    I the world inertia), with |J_t| / J_n = 0.78 inside the cone; then v = v0 + J / m and the
    angular momentum about the centre is c x J. The point's friction and normal rows, solved one after
    the other once a pass, are coupled through the body's turn: the capsule left with its end slipping
    at 0.12 m/s and lifting at 0.025 m/s, v_x 0.828 against 0.750 m/s (the box's corner 0.854 against
    0.758). Solved as one sticking block they are exact; what is left is the body's turn within the
    substep of the impact, |w| h |c| of the lever, on speeds of order v (the bound below, 2e-3 m/s).
    """
    v, m, mu = 2.0, 1.0, 5.0
    w, body, c, K = _point_strike(shape, 0.0, mu, v, m, threshold=0.5)  # the World's default threshold
    h = w.dt / w.substeps
    J = np.linalg.solve(K, [0.0, 0.0, v])
    assert math.hypot(J[0], J[1]) < mu * J[2]  # sticking
    w.run(0.05)
    spin = w.body_angular_velocity[body]
    L = w.body_inertia_world[body] @ spin  # torque-free after the impact: kept
    tol = 2 * np.linalg.norm(spin) * h * np.linalg.norm(c) * v
    np.testing.assert_allclose(w.body_velocity[body], np.array([0, 0, -v]) + J / m, atol=tol)
    np.testing.assert_allclose(L, np.cross(c, J), atol=tol * np.linalg.norm(c))


@pytest.mark.parametrize("shape", ["capsule", "box"])
def test_an_end_or_corner_sticking_on_a_grippy_floor_bounces_with_1_plus_e_times_the_inelastic_impulse(shape):
    """The strike above with e = 0.5, mu = 5: the point sticks throughout, so Newton's and Poisson's
    restitution agree, J = (1 + e) J_0 with K J_0 = -v_p, and the energy lost is (1 - e^2) of the
    inelastic impact's. (Friction applied once after the normal impulse turned the body and sent the
    point back into the floor: the bounce was lost, v about what e = 0 gives.)"""
    v, m, e = 2.0, 1.0, 0.5
    w, body, c, K = _point_strike(shape, e, 5.0, v, m)
    J0 = np.linalg.solve(K, [0.0, 0.0, v])
    assert math.hypot(J0[0], J0[1]) < 5.0 * J0[2]  # sticking
    e0 = w.kinetic_energy()
    w.run(0.05)
    spin = w.body_angular_velocity[body]
    tol = 2 * np.linalg.norm(spin) * w.dt / w.substeps * np.linalg.norm(c) * v
    np.testing.assert_allclose(w.body_velocity[body], np.array([0, 0, -v]) + (1 + e) * J0 / m, atol=tol)
    lost_inelastic = 0.5 * J0 @ K @ J0
    assert w.kinetic_energy() == pytest.approx(e0 - (1 - e * e) * lost_inelastic, abs=tol * v * m)


def test_a_capsule_end_sliding_on_the_floor_takes_mu_times_the_normal_impulse():
    """The capsule's end strikes with e = 0.5, mu = 0.3: too little friction to stop it, so it slides
    throughout, along -x (the strike lies in the x-z plane): J = j_n (n + mu x_hat), with j_n the impulse that
    leaves the point's normal speed at e v, j_n = (1 + e) v / (n . K (n + mu x_hat))."""
    v, m, e, mu = 2.0, 1.0, 0.5, 0.3
    w, body, c, K = _point_strike("capsule", e, mu, v, m)
    direction = np.array([mu, 0.0, 1.0])
    jn = (1 + e) * v / (K @ direction)[2]
    J = jn * direction
    slip_after = (np.array([0, 0, -v]) + K @ J)[0]
    assert slip_after < 0  # still sliding the same way at the end: mu j_n along +x throughout
    w.run(0.05)
    spin = w.body_angular_velocity[body]
    tol = 2 * np.linalg.norm(spin) * w.dt / w.substeps * np.linalg.norm(c) * v
    np.testing.assert_allclose(w.body_velocity[body], np.array([0, 0, -v]) + J / m, atol=tol)


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
@pytest.mark.parametrize("tilt_deg", [30.0, 60.0])
def test_a_tilted_rod_landing_on_its_end_takes_the_one_point_impulse(tilt_deg, e):
    """A frictionless 1 m x 2 cm x 2 cm rod, tilted, strikes the floor with its lower end at 2 m/s (no gravity).

    Its end is an edge of two corners, mirror images across the rod's vertical plane: one impulse J
    along n at the edge's midpoint r, J = (1 + e) v / (1/m + r_x^2 / I), gives v_z = -v + J / m and
    w_y = -r_x J / I, and no spin about the rod's own axis. The two corners are coupled through that
    axis's small moment, and Gauss-Seidel sweeps over them converged by only 0.41 a pair of sweeps at
    60 degrees: the solve pass (e = 0) left the corners' impulses 0.8 % apart and the rod spinning at
    0.68 rad/s about its axis, v_z 2.1 mm/s off; the collision pass (e = 1) 0.11 rad/s and 0.3 mm/s.
    Without gravity and friction the rigid result is exact: impulses to MANIFOLD_TOLERANCE [m/s],
    the spin left below that over the corners' 1 cm arm.
    """
    length, width, m, v = 1.0, 0.02, 1.0, 2.0
    tilt = math.radians(tilt_deg)
    q = quat_axis_angle((0, 1, 0), -tilt)  # the rod's -x end lowest
    w = tumble.World(gravity=(0, 0, 0), restitution_threshold=0.0)
    w.add_plane(restitution=e, friction=0.0)
    edge = quat_to_matrix(q) @ np.array([-length / 2, 0.0, -width / 2])  # midpoint of the lower edge
    rod = w.add_box(
        position=(0, 0, 0.01 - edge[2]),
        half_extents=(length / 2, width / 2, width / 2),
        orientation=q,
        velocity=(0, 0, -v),
        mass=m,
        restitution=e,
        friction=0.0,
    )
    w.run(0.1)
    inertia = m * (length**2 + width**2) / 12
    rx = edge[0]
    J = (1 + e) * v / (1 / m + rx * rx / inertia)
    tol = float(contacts.MANIFOLD_TOLERANCE)
    vel, spin = w.body_velocity[rod], w.body_angular_velocity[rod]
    assert vel[2] == pytest.approx(-v + J / m, abs=tol)
    assert spin[1] == pytest.approx(-rx * J / inertia, abs=tol / abs(rx))
    assert np.abs(vel[:2]).max() < tol
    # spin about the rod's own axis (the rest of w once w_y is taken out; the axis turns with the rod)
    assert math.hypot(spin[0], spin[2]) < tol / (width / 2)
    assert w.kinetic_energy() <= 0.5 * m * v * v * (1 + rounding())


def test_parallel_capsules_head_on_follow_newtons_law():
    """Two upright capsules (1 and 3 kg) meeting side on along x: 1D Newton's law at e = 0.5, no spin."""
    e, m1, m2, u1, u2 = 0.5, 1.0, 3.0, 2.0, -0.5
    w = tumble.World(gravity=(0, 0, 0), restitution_threshold=0.0)
    a = w.add_capsule(
        position=(-0.5, 0, 0), radius=0.05, half_height=0.2, mass=m1, velocity=(u1, 0, 0), restitution=e, friction=0
    )
    b = w.add_capsule(
        position=(0.5, 0, 0), radius=0.05, half_height=0.2, mass=m2, velocity=(u2, 0, 0), restitution=e, friction=0
    )
    w.run(1.0)
    vc = (m1 * u1 + m2 * u2) / (m1 + m2)
    tol = float(contacts.MANIFOLD_TOLERANCE)
    assert w.body_velocity[a, 0] == pytest.approx(vc - e * m2 * (u1 - u2) / (m1 + m2), abs=tol)
    assert w.body_velocity[b, 0] == pytest.approx(vc + e * m1 * (u1 - u2) / (m1 + m2), abs=tol)
    assert np.abs(w.body_angular_velocity[[a, b]]).max() < tol / 0.2


# ---------------------------------------------------------------------------- resting and stacks


def test_sphere_and_lying_capsule_rest_at_their_radius():
    """A ball and a capsule lying flat rest at height r, within the slop plus m g / (m_n (2 omega)^2)."""
    w = tumble.World()
    h = w.dt / w.substeps
    stiffness = (2 * contact_omega(h)) ** 2  # against the static plane
    w.add_plane(restitution=0.0)
    ball = w.add_sphere(position=(0, 0, 0.1), radius=0.1, mass=1.0, restitution=0.0)
    flat = quat_axis_angle((0, 1, 0), math.pi / 2)  # the capsule's axis along x
    cap = w.add_capsule(
        position=(1, 0, 0.05), radius=0.05, half_height=0.2, mass=1.0, orientation=flat, restitution=0.0
    )
    w.run(2.0)
    assert abs(w.body_position[ball, 2] - 0.1) <= contacts.LINEAR_SLOP + G / stiffness
    # the capsule's weight is on its two end contacts, each of effective mass 1 / (1/m + hh^2 / I)
    inertia = w.body_inertia_world[cap]
    m_n = 1.0 / (1.0 + 0.2**2 / inertia[2, 2])
    assert abs(w.body_position[cap, 2] - 0.05) <= contacts.LINEAR_SLOP + G / (m_n * stiffness)
    axis = quat_to_matrix(w.body_orientation[cap])[:, 2]
    assert abs(axis[2]) < 2 * (contacts.LINEAR_SLOP + G / (m_n * stiffness)) / 0.4  # flat: ends level
    assert w.kinetic_energy() < 1e-9


def test_heavy_box_on_a_light_box_stands_with_the_compliance_sag():
    """A 1000 kg cube on a 1 kg cube on the ground: each joint overlaps F / (4 m_n k), the pair stays upright.

    A corner row's effective mass is 1 / (4 (1/m_a + 1/m_b)) (I = m a^2 / 6, |r x n|^2 = a^2 / 2),
    k = omega^2 between the cubes and (2 omega)^2 against the ground; a face's four corners share F.
    """
    half, light, heavy = 0.1, 1.0, 1000.0
    w = tumble.World()
    h = w.dt / w.substeps
    omega = contact_omega(h)
    w.add_plane(restitution=0.0)
    lo = w.add_box(position=(0, 0, half), half_extents=(half,) * 3, mass=light, restitution=0.0)
    hi = w.add_box(position=(0, 0, 3 * half), half_extents=(half,) * 3, mass=heavy, restitution=0.0)
    w.run(3.0)
    ground = (light + heavy) * G / (4 * (light / 4) * 4 * omega**2)
    between = heavy * G / (4 * (1 / (4 * (1 / light + 1 / heavy))) * omega**2)
    z_lo, z_hi = w.body_position[lo, 2], w.body_position[hi, 2]
    assert half - z_lo == pytest.approx(ground, rel=2e-3)  # 1.1 mm
    assert 2 * half - (z_hi - z_lo) == pytest.approx(between, rel=2e-3)  # 4.3 mm
    for body in (lo, hi):
        assert np.hypot(*w.body_position[body, :2]) < 0.1 * between  # no lean, no slide
        assert abs(quat_to_matrix(w.body_orientation[body])[2, 2] - 1.0) < 1e-6
    assert w.kinetic_energy() < 1e-6


# ---------------------------------------------------------------------------- joints


@pytest.mark.parametrize("theta0", [2.0, 2.8])
def test_large_amplitude_pendulum_period_is_the_elliptic_integral(theta0):
    """A bob on a 1 m rod released at theta0 swings with T = 4 sqrt(L/g) K(sin^2(theta0/2)), energy within m g v h.

    The scheme is symplectic: the period is off by O((omega dt)^2), the energy oscillates by
    at most about the work of gravity over one substep, m g v_max h.
    """
    L, m = 1.0, 1.0
    w = tumble.World()
    h = w.dt / w.substeps
    bob = w.add_sphere(position=(L * math.sin(theta0), 0, 2 - L * math.cos(theta0)), radius=0.02, mass=m)
    w.add_joint("distance", None, bob, anchor_a=(0, 0, 2))
    period = 4 * math.sqrt(L / G) * ellipk(math.sin(theta0 / 2) ** 2)  # scipy's K takes m = k^2
    v_max = math.sqrt(2 * G * L * (1 - math.cos(theta0)))
    e0 = w.kinetic_energy() + w.potential_energy()
    t, x, worst = [], [], 0.0
    for _ in range(round(2.2 * period / w.dt)):
        w.step()
        t.append(w.time)
        x.append(w.body_position[bob, 0])
        worst = max(worst, abs(w.kinetic_energy() + w.potential_energy() - e0))
    t, x = np.array(t), np.array(x)
    i = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    crossings = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    assert len(crossings) == 2
    measured = float(np.diff(crossings)[0])
    assert measured == pytest.approx(period, rel=(2 * math.pi / period * w.dt) ** 2)
    assert worst <= m * G * v_max * h
    assert w.body_position[bob, 1] == 0.0


def _spring(k: float, c: float, *, gravity=(0.0, 0.0, -G), stretch: float = 0.0):
    """A 1 kg ball on a distance spring (rest length 0.5 m) hung from the world at z = 2, pulled down by `stretch`."""
    w = tumble.World(gravity=gravity)
    ball = w.add_sphere(position=(0, 0, 1.5 - stretch), radius=0.02, mass=1.0)
    spring = w.add_joint("distance", None, ball, anchor_a=(0, 0, 2), length=0.5, stiffness=k, damping=c)
    return w, ball, spring


def test_spring_holds_its_load_at_m_g_over_k():
    """A damped spring settles at the static stretch m g / k, its force m g."""
    k = 100.0
    w, ball, spring = _spring(k, 20.0)
    w.run(3.0)  # decays at about k / c = 5 /s
    assert w.body_position[ball, 2] == pytest.approx(1.5 - G / k, abs=resolution(1e-9, 1.5))
    np.testing.assert_allclose(w.joint_force[spring.index], [0, 0, G], atol=1e-6, rtol=0)


@pytest.mark.parametrize("k, c", [(100.0, 0.0), (400.0, 0.0), (100.0, 2.0)])
def test_spring_oscillates_at_its_natural_frequency_and_decays_no_faster_than_implicitly(k, c):
    """A ball on a spring pulled 5 cm (no gravity) swings at w_d = sqrt(k/m - (c/2m)^2), decaying at least at c/2m.

    The period is within (w dt)^2; the implicit spring adds numerical damping, never removes any.
    """
    w, ball, _ = _spring(k, c, gravity=(0.0, 0.0, 0.0), stretch=0.05)
    t, x = [], []
    for _ in range(round(4.0 / w.dt)):
        w.step()
        t.append(w.time)
        x.append(w.body_position[ball, 2] - 1.5)
    t, x = np.array(t), np.array(x)
    i = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    crossings = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    omega_d = math.sqrt(k - (c / 2) ** 2)
    assert float(np.diff(crossings).mean()) == pytest.approx(2 * math.pi / omega_d, rel=(omega_d * w.dt) ** 2)
    # decay rate between the first and the last 0.7 s (each holds a full swing)
    span = round(0.7 / w.dt)
    gamma = math.log(np.abs(x[:span]).max() / np.abs(x[-span:]).max()) / (t[-1] - t[span - 1])
    assert gamma >= c / 2


@pytest.mark.parametrize("k", [100.0, 400.0])
def test_undamped_spring_loses_no_more_energy_than_one_backward_euler_step_per_substep(k):
    """An undamped implicit spring (backward Euler per substep, amplitude rate w^2 h / 2) keeps E0 exp(-w^2 h t) <= E <= E0.

    Applied in the relax pass too it lost energy at twice that rate (81 % in 4 s at k = 400 N/m).
    """
    w, ball, _ = _spring(k, 0.0, gravity=(0.0, 0.0, 0.0), stretch=0.05)
    h = w.dt / w.substeps
    e0 = 0.5 * k * 0.05**2
    w.run(4.0)
    x = w.body_position[ball, 2] - 1.5
    energy = 0.5 * k * x * x + 0.5 * float(np.dot(w.body_velocity[ball], w.body_velocity[ball]))
    slack = rounding() * e0  # the rounding of its 7,680 substeps
    assert e0 * math.exp(-k * h * w.time) - slack <= energy <= e0 + slack


def _total_angular_momentum(w) -> np.ndarray:
    """Sum of m x cross v + I w over all bodies, about the origin."""
    x, v, m = w.body_position, w.body_velocity, w.body_mass
    spin = np.einsum("nij,nj->ni", w.body_inertia_world, w.body_angular_velocity)
    return np.sum(m[:, None] * np.cross(x, v) + spin, axis=0)


@pytest.mark.parametrize("kind", ["fixed", "ball", "hinge", "slider", "distance"])
def test_two_jointed_boxes_tumbling_in_space_keep_momentum_and_angular_momentum(kind):
    """Two boxes (1 and 2 kg) joined and tumbling as one, no gravity: joint forces are internal, so p and L stay.

    p to rounding; L to O((h |w|)^2) of |L| (the impulse pair acts at two anchor points that part by
    the joint's own error).
    """
    w = tumble.World(gravity=(0, 0, 0))
    h = w.dt / w.substeps
    spin = np.array([0.5, 1.0, 2.0])
    v0 = np.array([0.3, 0.0, 0.1])
    a = w.add_box(position=(0, 0, 0), half_extents=(0.2, 0.1, 0.05), mass=1.0, velocity=v0, angular_velocity=spin)
    b = w.add_box(
        position=(0.45, 0, 0), half_extents=(0.2, 0.1, 0.05), mass=2.0, velocity=v0 + np.cross(spin, [0.45, 0, 0]),
        angular_velocity=spin,
    )  # fmt: skip
    if kind == "distance":
        w.add_joint("distance", a, b)
    else:
        w.add_joint(kind, a, b, anchor=(0.225, 0, 0), axis=(1, 0, 0) if kind == "slider" else (0, 0, 1))
    p0, L0 = w.momentum(), _total_angular_momentum(w)
    w.run(3.0)
    np.testing.assert_allclose(w.momentum(), p0, atol=rounding() * 10, rtol=0)
    # (or the rounding of 10^4 substeps, where that is more: float32)
    bound = max((h * np.linalg.norm(spin)) ** 2, rounding()) * np.linalg.norm(L0)
    assert np.linalg.norm(_total_angular_momentum(w) - L0) <= bound


@pytest.mark.parametrize("kick", [(3.0, 0.0, 0.0), (3.0, 2.0, 1.0)])
def test_hinge_keeps_its_axis(kick):
    """A door on a world hinge along y, kicked about x and z: its y axis stays within |w_perp| h, its anchor within |v| h."""
    w = tumble.World()
    h = w.dt / w.substeps
    v0 = np.array([0.0, 0.5, 0.3])
    door = w.add_box(position=(0.5, 0, 1), half_extents=(0.5, 0.05, 0.3), mass=5.0, angular_velocity=kick, velocity=v0)
    w.add_joint("hinge", None, door, anchor=(0, 0, 1), axis=(0, 1, 0))
    w_perp = math.hypot(kick[0], kick[2])
    hinge_point = np.array([-0.5, 0.0, 0.0])  # body frame
    v_anchor = np.linalg.norm(v0 + np.cross(kick, hinge_point))
    worst_angle = worst_anchor = 0.0
    for _ in range(round(3.0 / w.dt)):
        w.step()
        R = quat_to_matrix(w.body_orientation[door])
        worst_angle = max(worst_angle, math.acos(min(1.0, abs(R[1, 1]))))
        anchor = w.body_position[door] + R @ hinge_point
        worst_anchor = max(worst_anchor, float(np.linalg.norm(anchor - [0, 0, 1])))
    assert worst_angle <= w_perp * h
    # the soft point rows: the kick's travel in one substep, plus the weight's sag g / omega_joint^2
    omega_joint = 2.0 * math.pi * joints.JOINT_HERTZ_PER_SUBSTEP_RATE / h
    assert worst_anchor <= v_anchor * h + G / omega_joint**2
    # it swings about y and only about y
    wx, wy, wz = w.body_angular_velocity[door]
    assert abs(wx) + abs(wz) < resolution(1e-9, 1.0) * max(1.0, abs(wy))


# ---------------------------------------------------------------------------- rotation


def test_symmetric_top_precesses_at_the_euler_rates():
    """A flat square box (I1 = I2) spun 15 deg off its axis: the axis circles L at |L| / I1, w circles the axis at (I3 - I1) w3 / I1."""
    m, half = 1.0, (0.2, 0.2, 0.05)
    i1, i3 = m / 3 * (0.2**2 + 0.05**2), m / 3 * (2 * 0.2**2)
    tilt = math.radians(15.0)
    w0 = np.array([math.sin(tilt) / i1, 0.0, math.cos(tilt) / i3]) * 0.5
    w = tumble.World(gravity=(0, 0, 0))
    h = w.dt / w.substeps
    box = w.add_box(position=(0, 0, 0), half_extents=half, mass=m, angular_velocity=w0)
    L = w.body_inertia_world[box] @ w.body_angular_velocity[box]
    u = L / np.linalg.norm(L)
    e1 = np.cross(u, [0, 1, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    t, space, body = [], [], []
    for _ in range(round(3.0 / w.dt)):
        w.step()
        R = quat_to_matrix(w.body_orientation[box])
        axis = R[:, 2]
        wb = R.T @ w.body_angular_velocity[box]
        t.append(w.time)
        space.append(math.atan2(axis @ e2, axis @ e1))
        body.append(math.atan2(wb[1], wb[0]))
    rate_space = np.polyfit(t, np.unwrap(space), 1)[0]
    rate_body = np.polyfit(t, np.unwrap(body), 1)[0]
    # the splitting is second order: rates within O((h |w|)^2)
    tol = (h * np.linalg.norm(w0)) ** 2
    assert rate_space == pytest.approx(np.linalg.norm(L) / i1, rel=tol)
    assert rate_body == pytest.approx((i3 - i1) / i1 * w0[2], rel=tol)


@pytest.mark.parametrize("spin", [50.0, 200.0])
def test_gyroscope_on_a_ball_joint_precesses_at_m_g_l_over_i3_w3(spin):
    """A spinning disc held horizontal on a ball joint at l from its centre precesses steadily at m g l / (I3 w3).

    At 90 deg from the vertical the steady precession of a heavy symmetric top is exactly
    Omega = m g l / (I3 w3) (the Omega^2 cos(theta) term vanishes), whatever the spin; started on
    it, the disc keeps it to the splitting's O((h w3)^2) and stays level to first order, O(h w3).
    """
    m, hx, hy, arm = 1.0, 0.02, 0.1, 0.2  # a square plate, its symmetry axis along x
    i3 = m / 3 * (2 * hy**2)
    omega = m * G * arm / (i3 * spin)
    w = tumble.World()
    h = w.dt / w.substeps
    disc = w.add_box(
        position=(arm, 0, 1), half_extents=(hx, hy, hy), mass=m, angular_velocity=(spin, 0, omega),
        velocity=(0, omega * arm, 0),
    )  # fmt: skip
    w.add_joint("ball", None, disc, anchor=(0, 0, 1))
    t, azimuth, elevation = [], [], []
    for _ in range(round(4.0 / w.dt)):
        w.step()
        axis = quat_to_matrix(w.body_orientation[disc])[:, 0]
        t.append(w.time)
        azimuth.append(math.atan2(axis[1], axis[0]))
        elevation.append(axis[2])
    assert np.unwrap(azimuth)[-1] > 5.0  # nearly a turn at 200 rad/s, three at 50
    rate = np.polyfit(t, np.unwrap(azimuth), 1)[0]
    assert rate == pytest.approx(omega, rel=(h * spin) ** 2)
    assert np.abs(elevation).max() <= h * spin


# ---------------------------------------------------------------------------- scale invariance


def _scaled_scene(s: float) -> tumble.World:
    """A bouncing ball and a sliding box, lengths and gravity times s (times unchanged, speeds times s)."""
    w = tumble.World(gravity=(0, 0, -G * s), restitution_threshold=0.5 * s)
    w.add_plane(restitution=0.5, friction=0.4)
    w.add_sphere(position=(0, 0, s), radius=0.1 * s, mass=1.0, restitution=0.5, friction=0.4, velocity=(0.5 * s, 0, 0))
    w.add_box(
        position=(2 * s, 0, 0.1 * s), half_extents=(0.1 * s,) * 3, mass=1.0, restitution=0.0, friction=0.4,
        velocity=(2 * s, 0, 0),
    )  # fmt: skip
    return w


def test_scaled_scene_matches_in_dimensionless_terms():
    """Lengths x10 and g x10 keep sqrt(L/g): the ball's bounces and the box's slide match x/s to rounding."""
    runs = {}
    for s in (1.0, 10.0):
        w = _scaled_scene(s)
        path = []
        w.run(2.0, callback=lambda world, s=s, path=path: path.append(world.body_position[1:] / s))
        runs[s] = np.array(path)
    assert runs[1.0][-1, 1, 0] == pytest.approx(2.0 + 2.0**2 / (2 * 0.4 * G), rel=0.02)  # it slid and stopped
    np.testing.assert_allclose(runs[10.0], runs[1.0], atol=rounding() * 3.0, rtol=0)


# ---------------------------------------------------------------------------- cloth


@pytest.mark.parametrize("gravity", [(0.0, 0.0, 0.0), (0.0, 0.0, -G)])
def test_free_cloth_keeps_its_momentum_and_its_centre_falls_freely(gravity):
    """Unpinned cloth, random particle velocities: p(t) = p0 + M g t exactly, the centre on the scheme's parabola."""
    mass = 0.5
    w = tumble.World(gravity=gravity)
    cloth = w.add_cloth(size=(1, 1), resolution=(12, 12), position=(0, 0, 1), mass=mass)
    n = cloth.particle_count
    v0 = np.random.default_rng(0).normal(0, 0.5, (n, 3))
    w.cloth.set_state(velocity=v0)
    m = w.cloth.particle_mass  # each particle carries its area's share (edges half, corners a quarter)
    assert m.sum() == pytest.approx(mass, rel=1e-12)
    x0 = m @ cloth.particle_position / mass
    steps = w.run(1.0)
    t, g = w.time, np.asarray(gravity)
    h = w.dt / w.cloth.substeps_for(w.dt)
    k = round(t / h)
    p0 = m @ v0
    momentum = m @ cloth.particle_velocity
    np.testing.assert_allclose(momentum, p0 + mass * g * t, atol=rounding() * (1 + G * t) * mass, rtol=0)
    centre = x0 + p0 / mass * t + g * h * h * k * (k + 1) / 2
    np.testing.assert_allclose(m @ cloth.particle_position / mass, centre, atol=rounding() * (1 + G * t * t), rtol=0)
    assert steps > 0 and w.kinetic_energy() > 0


# ---------------------------------------------------------------------------- determinism


def _mixed(seed: int) -> tumble.World:
    w = tumble.World(seed=seed)
    w.add_plane()
    w.add_box(position=(0, 0, 1), half_extents=(0.1, 0.2, 0.05), mass=1.0, angular_velocity=(1, 2, 3))
    ball = w.add_sphere(position=(0.3, 0, 1.5), radius=0.1, mass=1.0)
    w.add_capsule(position=(-0.3, 0, 1.2), radius=0.05, half_height=0.1, mass=1.0, angular_velocity=(0, 3, 0))
    w.add_joint("ball", None, ball, anchor=(0.3, 0, 2.0))
    w.add_cloth(size=(0.5, 0.5), resolution=(8, 8), position=(0, 0.8, 0.8), pins="top-corners")
    w.add_emitter(
        shape=["sphere", "box"], rate=50, count=20, position=(0, 0, 2), region="disc", extent=0.3, speed=(0, 1),
        cone_angle=20, radius=(0.03, 0.05),
    )  # fmt: skip
    w.set_wind(velocity=(1, 0, 0), turbulence=0.5)
    return w


def test_same_seed_same_hash_and_snapshot_resumes_bit_for_bit():
    """Bodies, a joint, cloth in turbulent wind and an emitter: equal seeds, equal hashes; a restore repeats the run."""
    first = _mixed(7)
    first.run(0.5)
    snap = first.snapshot()
    first.run(0.5)
    reference = first.state_hash()
    assert first.body_count > 4  # the emitter emitted
    again = _mixed(7)
    again.run(1.0)
    assert again.state_hash() == reference
    resumed = _mixed(7)
    resumed.restore(snap)
    resumed.run(0.5)
    assert resumed.state_hash() == reference
    first.restore(snap)  # back in time in the same world
    first.run(0.5)
    assert first.state_hash() == reference
    other = _mixed(8)
    other.run(1.0)
    assert other.state_hash() != reference
