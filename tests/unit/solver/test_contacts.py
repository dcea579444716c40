"""solver/contacts.py, one contact row at a time, against closed-form impulses.

Each test builds a world through the public API, finds its contacts with `World.collide`,
and runs the solver's stages (`prepare`, `solve`, `impacts`) directly on the world's body
and contact arrays, without gravity unless said, so that every impulse has a closed form:
- effective mass along d: m_d = 1 / (1/m_a + 1/m_b + (r_a x d) . I_a^-1 (r_a x d) + (r_b x d) . I_b^-1 (r_b x d));
- normal: jn = max(0, m_n (-v_n - s / h)) (speculative gap s >= 0), never negative;
- friction: the disc |jt| <= mu jn, applied against the slip; a sphere that sticks keeps
  5/7 of its speed (m_t = 2 m / 7);
- push-out of an overlap beyond the slop with the soft-step coefficients (Catto 2024):
  omega = 2 pi f, a1 = 2 zeta + h omega, a2 = h omega a1; bias = omega / a1, mass scale a2 / (1 + a2);
- impacts: v_n -> -e v_n, the 1D two-body collision v_1' = ((m_1 - e m_2) v_1 + (1 + e) m_2 v_2) / (m_1 + m_2).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import tumble
from tolerances import resolution
from tumble import shapes
from tumble.precision import kernels
from tumble.solver.contacts import LINEAR_SLOP  # (a constant: the same in both precisions' copies)

from ..reference import quat_matrix

DT = 2.0**-6  # one substep: h = dt
ZERO_G = np.zeros(3)


def solver_of(world: tumble.World):
    """The contact solver (`tumble.solver.contacts`) in the world's own precision: its kernels take
    only that precision's arrays (`tumble.precision.kernels`)."""
    return kernels(world.precision).contacts


def prepared(world: tumble.World):
    """The world's contacts found and prepared for one step of DT: (bodies, contacts)."""
    assert world.collide(DT) > 0
    bodies, contacts = world.bodies, world.contacts
    contacts.begin_solve(bodies)
    kernels(world.precision).integrate.begin_step(bodies)
    solver_of(world).prepare(bodies, contacts, DT)
    return bodies, contacts


def ball_on_plane(*, z=0.5, velocity=(0.0, 0.0, 0.0), friction=0.5, restitution=0.0, mass=2.0):
    world = tumble.World(dt=DT, substeps=1, gravity=(0.0, 0.0, 0.0))
    world.add_plane(friction=friction, restitution=restitution)
    ball = world.add_sphere(
        position=(0.0, 0.0, z), radius=0.5, mass=mass, velocity=velocity, friction=friction, restitution=restitution
    )
    return world, ball


def test_prepare_gives_the_effective_masses_of_a_tilted_box_corner():
    """m_n, m_t1, m_t2 of every contact of a tilted box on a plane equal the formula with I_world = R I R^T."""
    world = tumble.World(dt=DT, substeps=1, gravity=(0.0, 0.0, 0.0))
    world.add_plane(friction=0.8, restitution=0.1)
    half, mass = np.array([0.4, 0.25, 0.1]), 3.0
    q = np.array([math.sin(0.2), 0.0, 0.0, math.cos(0.2)])  # 0.4 rad about x
    q = q / np.linalg.norm(q)
    R = quat_matrix(q)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
    lowest = (corners @ R.T)[:, 2].min()
    box = world.add_box(
        position=(0.0, 0.0, -lowest), half_extents=half, mass=mass, orientation=q, friction=0.2, restitution=0.6
    )
    R = quat_matrix(box.orientation)  # the orientation the world holds (q rounded to its precision)
    bodies, contacts = prepared(world)
    k = contacts.count
    assert k >= 2  # the lowest edge of the box
    inv_i_world = R @ np.diag(1.0 / shapes.box_inertia(mass, half)) @ R.T
    n = contacts.numpy("contact_normal")
    r_b = contacts.row_values("r_b")
    # anchors in the world frame: a vector of ~0.5 m turned, a few ulps
    reach = resolution(1e-12, 0.5, 4)
    np.testing.assert_allclose(r_b, contacts.numpy("contact_local_b") @ R.T, atol=reach)
    # the contacts share the normal, so they are one patch: its friction rows sit on its first row,
    # anchored at the patch centre (the mean anchor), the other rows have none (solver/contacts.py)
    centre = np.zeros_like(r_b)
    centre[0] = r_b.mean(axis=0)
    np.testing.assert_allclose(contacts.row_values("centre_b")[0], centre[0], atol=reach)
    first = (np.arange(k) == 0).astype(float)
    # effective masses: cross products, the turned inverse inertia and a reciprocal, 16 ulps
    for name, d, at, on in (
        ("n", n, r_b, np.ones(k)),
        ("t1", contacts.row_values("tangent1"), centre, first),
        ("t2", contacts.row_values("tangent2"), centre, first),
    ):
        c = np.cross(at, d)
        expected = 1.0 / (1.0 / mass + np.einsum("ki,ij,kj->k", c, inv_i_world, c)) * on
        np.testing.assert_allclose(contacts.row_values(f"mass_{name}"), expected, rtol=resolution(1e-12, 1.0, 16))
        angular = (c @ inv_i_world.T) * on[:, None]
        np.testing.assert_allclose(
            contacts.row_values(f"angular_b_{name}"), angular, atol=resolution(1e-12, np.abs(angular).max(), 16)
        )
    # and its twist row about n: effective mass 1 / (n . I^-1 n)
    twist = 1.0 / np.einsum("i,ij,j->", n[0], inv_i_world, n[0])
    np.testing.assert_allclose(contacts.row_values("mass_twist"), twist * first, rtol=resolution(1e-12, 1.0, 16))
    # the tangents complete the normal to a right-handed orthonormal basis
    t1, t2 = contacts.row_values("tangent1"), contacts.row_values("tangent2")
    unit = resolution(1e-12, 1.0, 4)
    np.testing.assert_allclose(np.einsum("ki,ki->k", t1, n), 0.0, atol=unit)
    np.testing.assert_allclose(np.cross(n, t1), t2, atol=unit)
    np.testing.assert_allclose(np.linalg.norm(t1, axis=1), 1.0, atol=unit)
    # materials: mu = sqrt(mu_a mu_b), e = max(e_a, e_b) (the stored materials, a few ulps)
    np.testing.assert_allclose(contacts.row_values("friction"), math.sqrt(0.8 * 0.2), rtol=resolution(1e-12, 1.0, 4))
    np.testing.assert_allclose(contacts.row_values("restitution"), 0.6)


def test_normal_impulse_stops_the_approach():
    """A ball touching the plane at 0.7 m/s: jn = m v, the ball stops along n. The normal row runs first, so
    the same pass's friction is bounded by this jn (mu jn = 0.7 N s): it stops the slip of 0.3 m/s, which takes
    m_t v_t = (2/7) m 0.3 = 0.171 N s, and the ball rolls at 5/7 of it."""
    world, ball = ball_on_plane(velocity=(0.3, 0.0, -0.7))
    bodies, contacts = prepared(world)
    solver = solver_of(world)
    assert contacts.count == 1
    solver.solve(bodies, contacts, DT, use_bias=False)
    assert contacts.row_values("impulse_n")[0] == pytest.approx(2.0 * 0.7, rel=1e-12)
    np.testing.assert_allclose(ball.velocity, [0.3 * 5 / 7, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(ball.angular_velocity, [0.0, 0.3 * 5 / 7 / 0.5, 0.0], atol=1e-12)


def test_normal_impulse_never_pulls():
    """A ball leaving the plane: jn clamps at 0 and the velocity stays."""
    world, ball = ball_on_plane(velocity=(0.0, 0.0, 0.4))
    bodies, contacts = prepared(world)
    solver = solver_of(world)
    for use_bias in (True, False):
        solver.solve(bodies, contacts, DT, use_bias=use_bias)
    assert contacts.row_values("impulse_n")[0] == 0.0
    np.testing.assert_allclose(ball.velocity, [0.0, 0.0, 0.4], atol=0)


@pytest.mark.parametrize("speed", [3.0, 0.8])
def test_speculative_contact_lets_the_gap_close_in_one_substep(speed):
    """Gap s = 1 cm, approach v > s / h: jn = m (v - s / h), so the ball arrives exactly at the plane."""
    gap = 0.01
    world, ball = ball_on_plane(z=0.5 + gap, velocity=(0.0, 0.0, -speed))
    bodies, contacts = prepared(world)
    solver = solver_of(world)
    # the gap is the difference of the centre's height and the radius: a few ulps of them
    s = contacts.numpy("contact_separation")[0]
    assert s == pytest.approx(gap, rel=1e-12, abs=resolution(1e-12, 0.5, 4))
    solver.solve(bodies, contacts, DT, use_bias=False)
    # the impulse and the arrival speed from the gap the contact holds (that rounding, magnified by
    # m / h, is not the solver's): a few ulps of the speeds they cancel
    jn = 2.0 * (speed - s / DT)
    assert jn > 0.0
    assert contacts.row_values("impulse_n")[0] == pytest.approx(jn, rel=1e-12, abs=resolution(1e-12, 2.0 * speed, 4))
    assert ball.velocity[2] == pytest.approx(-s / DT, rel=1e-12, abs=resolution(1e-12, speed, 4))


def test_friction_is_clamped_to_the_disc_against_the_slip():
    """Sliding fast: |jt| = mu jn along -slip (not clamped per tangent), dv = -mu jn / m, dw = I^-1 (r x jt)."""
    mu, mass, radius = 0.4, 2.0, 0.5
    slip = np.array([3.0, -4.0, 0.0])
    world, ball = ball_on_plane(velocity=(slip[0], slip[1], -1.0), friction=mu, mass=mass)
    bodies, contacts = prepared(world)
    solver = solver_of(world)
    solver.solve(bodies, contacts, DT, use_bias=False)  # normal only: friction saw jn = 0
    jn = contacts.row_values("impulse_n")[0]
    assert jn == pytest.approx(mass * 1.0, rel=1e-12)
    solver.solve(bodies, contacts, DT, use_bias=False)  # friction with jn, at the cone
    jt = contacts.row_values("impulse_t1")[0] * contacts.row_values("tangent1")[0]
    jt = jt + contacts.row_values("impulse_t2")[0] * contacts.row_values("tangent2")[0]
    direction = slip / np.linalg.norm(slip)
    # one friction row from the stored materials and speeds: 8 ulps of each quantity's size
    np.testing.assert_allclose(jt, -mu * jn * direction, atol=resolution(1e-12, mu * jn, 8))
    np.testing.assert_allclose(
        ball.velocity, slip - mu * jn / mass * direction, atol=resolution(1e-12, np.linalg.norm(slip), 8)
    )
    r = np.array([0.0, 0.0, -radius])
    inertia = 0.4 * mass * radius**2
    spin = np.cross(r, jt) / inertia
    np.testing.assert_allclose(ball.angular_velocity, spin, atol=resolution(1e-12, np.linalg.norm(spin), 8))
    assert contacts.row_values("impulse_n")[0] == pytest.approx(jn, rel=1e-12)  # the normal row is done


def test_a_sticking_ball_rolls_on_at_five_sevenths_of_its_speed():
    """Friction within the cone removes the slip at the contact: v' = 5/7 v, w' = v' / r (m_t = 2 m / 7)."""
    mass, radius = 2.0, 0.5
    world, ball = ball_on_plane(velocity=(0.05, 0.0, -2.0), friction=1.0, mass=mass)
    bodies, contacts = prepared(world)
    solver = solver_of(world)
    # an effective mass and two passes of impulses: a few ulps
    rel = resolution(1e-12, 1.0, 4)
    np.testing.assert_allclose(contacts.row_values("mass_t1"), 2.0 * mass / 7.0, rtol=rel)
    for _ in range(2):
        solver.solve(bodies, contacts, DT, use_bias=False)
    v, w = ball.velocity, ball.angular_velocity
    assert v[0] == pytest.approx(5.0 / 7.0 * 0.05, rel=rel)
    assert w[1] == pytest.approx(v[0] / radius, rel=rel)  # rolling: v + w x r = 0 at the contact
    np.testing.assert_allclose(v + np.cross(w, [0.0, 0.0, -radius]), 0.0, atol=resolution(1e-12, 0.05, 4))


def test_overlap_is_pushed_out_softly_and_the_relax_pass_removes_the_push():
    """Overlap d > slop against a static plane: v_n = -ms bias (soft step, twice as stiff); relax takes it back."""
    world, ball = ball_on_plane(z=0.5 - 2.0e-3)
    bodies, contacts = prepared(world)
    solver = solver_of(world)
    # the overlap the contact holds: 0.5 - z, whose rounding (an ulp of 0.5, 1.5e-5 of the 2 mm in
    # float32) is the narrow phase's, not the solver's
    depth = -contacts.numpy("contact_separation")[0]
    assert depth == pytest.approx(2.0e-3, rel=1e-9, abs=resolution(1e-12, 0.5, 4))
    solver.solve(bodies, contacts, DT, use_bias=True)
    # the soft step at stiffness 2 f (a static body), f = CONTACT_HERTZ_PER_SUBSTEP_RATE / h
    h = DT
    omega = 2.0 * math.pi * 2.0 * solver.CONTACT_HERTZ_PER_SUBSTEP_RATE / h
    a1 = 2.0 * solver.CONTACT_DAMPING_RATIO + h * omega
    a2 = h * omega * a1
    bias = max(omega / a1 * (-depth + solver.LINEAR_SLOP), -solver.MAX_PUSH_VELOCITY)
    push = -a2 / (1.0 + a2) * bias
    assert push > 0.0
    # the soft-step coefficients and the push: 8 ulps
    assert ball.velocity[2] == pytest.approx(push, rel=resolution(1e-9, 1.0, 8))
    solver.solve(bodies, contacts, DT, use_bias=False)
    # the relax pass takes back what the push added, to a few ulps of it
    assert ball.velocity[2] == pytest.approx(0.0, abs=resolution(1e-12, push, 4))
    assert contacts.row_values("impulse_n")[0] == pytest.approx(0.0, abs=resolution(1e-12, 2.0 * push, 4))


def test_overlap_within_the_slop_is_held_without_push():
    """Overlap under LINEAR_SLOP: the biased pass adds no velocity."""
    world, ball = ball_on_plane(z=0.5 - 0.5 * LINEAR_SLOP)
    bodies, contacts = prepared(world)
    solver = solver_of(world)
    solver.solve(bodies, contacts, DT, use_bias=True)
    np.testing.assert_allclose(ball.velocity, 0.0, atol=1e-15)


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_impact_of_two_spheres_is_the_one_dimensional_collision(e):
    """Head-on, masses 1 and 3: the velocities after `impacts` are the textbook ones for restitution e (e = 0
    too: touching, they land together at the common velocity, the collision pass's as any impact's)."""
    world = tumble.World(dt=DT, substeps=1, gravity=(0.0, 0.0, 0.0))
    m1, m2, v1, v2 = 1.0, 3.0, 2.0, -1.0
    a = world.add_sphere(position=(0.0, 0.0, 0.0), radius=0.5, mass=m1, velocity=(v1, 0, 0), restitution=e)
    b = world.add_sphere(position=(1.0, 0.0, 0.0), radius=0.5, mass=m2, velocity=(v2, 0, 0), restitution=e)
    bodies, contacts = prepared(world)
    solver = solver_of(world)
    solver.impacts(bodies, contacts, ZERO_G, DT, threshold=0.5)
    u1 = ((m1 - e * m2) * v1 + (1 + e) * m2 * v2) / (m1 + m2)
    u2 = ((m2 - e * m1) * v2 + (1 + e) * m1 * v1) / (m1 + m2)
    assert a.velocity[0] == pytest.approx(u1, rel=1e-12)
    assert b.velocity[0] == pytest.approx(u2, rel=1e-12)
    assert m1 * a.velocity[0] + m2 * b.velocity[0] == pytest.approx(m1 * v1 + m2 * v2, rel=1e-12)
    assert contacts.row_values("relative_velocity")[0] == pytest.approx(v2 - v1, rel=1e-12)


def test_impact_slower_than_the_threshold_of_a_loaded_contact_does_not_bounce():
    """A contact that already carries load (jn > 0) and closes below the threshold is left to the solve."""
    world, ball = ball_on_plane(velocity=(0.0, 0.0, -0.3), restitution=0.8)
    bodies, contacts = prepared(world)
    solver = solver_of(world)
    solver.solve(bodies, contacts, DT, use_bias=False)  # carries load now, at rest
    ball.velocity = (0.0, 0.0, -0.3)
    solver.impacts(bodies, contacts, ZERO_G, DT, threshold=1.0)
    assert ball.velocity[2] == pytest.approx(-0.3)
    solver.impacts(bodies, contacts, ZERO_G, DT, threshold=0.1)
    # e v from the stored restitution and speed: a few ulps
    assert ball.velocity[2] == pytest.approx(0.8 * 0.3, rel=resolution(1e-12, 1.0, 4))
