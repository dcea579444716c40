"""Issue 16: a box landing flat and fast picked up sideways speed and spin from nothing.

Found with the thin-mesh tunnelling test (tests/physics/test_meshes.py): a 4 cm cube dropped
flat at 50 m/s onto a 5 mm mesh slab was caught on top, then slid off the slab's edge. The same
happened on a plane, so it was the contact solver, not the mesh query. Measured before the fix
(dt 1/240, 8 substeps, mu 0.5, e 0), after 0.1 s: landing at 10 m/s left 0.70 m/s sideways and
73 rad/s, at 20 m/s 1.5 m/s and 156 rad/s.

Cause: the four corner contacts of a face share one body pair, so their rows are coupled, and
their normal rows are rank-deficient (four rows, three degrees of freedom: v_n and the two
tilts). One Gauss-Seidel sweep a pass, corner after corner, leaves each corner a different
impulse and the box rocking (a quarter of the impact speed at the corners); the next substep's
warm start re-applies the impact impulse, which the next sweep takes back as unevenly; and
friction, one row per corner bounded by mu times that corner's impulse, turns the rocking
into spin and slide. Fixed in solver/contacts.py: a manifold's rows are swept together until
converged (the solve and the collision pass), and a patch (rows sharing one normal) takes
its friction at its centre with a twist row, so the result no longer depends on the order of
the corners.

Tolerances. The setups below are mirror-symmetric (x -> -x, and y -> -y for the flat ones), so
in exact arithmetic the yaw rate, the sideways speed and the turn are 0 for any solver whose
result does not depend on the order of the corners. Normal rows cannot turn a body about n at all
(r x n is across n), and a patch's friction and twist are single rows whose bounds depend only on
the total load, so what is left of the order of the corners is rounding (1e-16 relative): the
bounds are ROUNDING, a billionth of the speeds and rates in play (10 m/s, and 10 m/s over the
half extent), far above double rounding, far below anything seen. One figure is not rounding:
the 4 sweeps a pass after an impact leave a remainder of the corners' normal rows, which rocks the box a little
about x and y while it slaps down: two such rocks compose into a turn about z (their product),
and while it rocks on an edge the box walks along it. A tilted landing at 10 m/s ends turned up
to 1.3e-5 rad (TURN bounds it) and shifted up to 2.9 mm along the edge (SHIFT, H / 4); five
boxes dropped on each other shift up to 0.5 mm (SHIFT / 2; on main 2.5 mm, and turned 4e-4 rad).
Resting and sliding manifolds take one sweep a pass (their changes are far below an impact's), so
their normal rows keep an order: a 2 m/s slide leaves its line by 1.2e-7 m (DRIFT, 1 um) and turns
at up to 2.3e-6 rad/s, as does a tilted box settling on the hull (SPIN, 1e-5 rad/s; main: 0.04
rad/s for the slide, 13-62 rad/s for the tilted landings); the
dropped stack ends turned up to 1.3e-4 rad (10 TURN; main 4.4e-4).
"""

from __future__ import annotations

import numpy as np
import pytest

import tumble
from tolerances import resolution

G = 9.81
H = 0.02  # half extent of the cube [m]
DT = 1.0 / 240.0
SUBSTEPS = 8


ROUNDING = 1e-9 * 10.0  # [m/s], see above
TURN = 1e-4  # [rad], see above
SHIFT = H / 4  # [m], see above
DRIFT = 1e-6  # [m], see above
SPIN = 1e-5  # [rad/s], see above


def _yaw(q) -> float:
    """Turn [rad] of the body's x axis about the vertical, from an (x, y, z, w) quaternion."""
    x, y, z, w = q
    return float(np.arctan2(2 * (x * y + w * z), 1 - 2 * (y * y + z * z)))


def _world(ground: str, *, restitution: float = 0.0, friction: float = 0.5) -> tumble.World:
    """A world with a ground whose top is at z = 0: a plane, a static box or a static convex hull."""
    w = tumble.World(gravity=(0, 0, -G), dt=DT, substeps=SUBSTEPS)
    material = {"restitution": restitution, "friction": friction}
    half = np.array([0.2, 0.2, 0.05])
    if ground == "plane":
        w.add_plane(**material)
    elif ground == "box":
        w.add_box(half_extents=half, position=(0, 0, -half[2]), static=True, **material)
    else:
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
        w.add_convex(points=corners, position=(0, 0, -half[2]), static=True, **material)
    return w


def _drop(ground: str, *, tilt: float, speed: float, duration: float):
    """Drop the cube at `speed` from 6 cm up, turned `tilt` rad about x; returns the world and the
    largest |w_z| seen after any step."""
    w = _world(ground)
    q = (np.sin(tilt / 2), 0.0, 0.0, np.cos(tilt / 2))
    w.add_box(half_extents=(H,) * 3, position=(0, 0, 0.0825), velocity=(0, 0, -speed), orientation=q, restitution=0.0)
    spin = [0.0]

    def watch(world):
        spin[0] = max(spin[0], abs(world.body_angular_velocity[1, 2]))

    w.run(duration, callback=watch)
    return w, spin[0]


@pytest.mark.parametrize("ground", ["plane", "box", "hull"])
def test_a_box_landing_flat_at_10_m_s_keeps_no_sideways_speed_or_spin(ground):
    """Drop a cube flat at 10 m/s onto a plane, a box and a hull: by symmetry it lands without sliding or spinning."""
    w, _ = _drop(ground, tilt=0.0, speed=10.0, duration=0.1)
    # in float32, 8 ulps of the speeds in play: its manifold sweeps stop at 8192 ulps of the load
    # (MANIFOLD_SWEEP_TOLERANCE, 1e-6 in float64), and what they leave of the corners' order shows
    # at ~0.1 ulp of 10 m/s (2e-7 m/s, 1.3e-5 rad/s on the hull; 8e-9 m/s and 1.5e-8 rad/s in float64)
    assert np.linalg.norm(w.body_velocity[1, :2]) < resolution(ROUNDING, 10.0, 8)
    assert np.linalg.norm(w.body_angular_velocity[1]) < resolution(ROUNDING / H, 10.0 / H, 8)


@pytest.mark.parametrize("ground", ["plane", "box", "hull"])
def test_a_box_landing_on_one_edge_comes_to_rest_flat_without_turning(ground):
    """Drop a cube at 10 m/s tilted 0.05 rad about x: it slaps down on its face and rests, never turning about z."""
    w, spin = _drop(ground, tilt=0.05, speed=10.0, duration=1.0)
    # mirror symmetry x -> -x: no yaw rate, no x motion; the normal rows cannot add any about n
    assert spin < SPIN
    assert abs(_yaw(w.body_orientation[1])) < TURN
    assert abs(w.body_position[1, 0]) < SHIFT
    # at rest, flat on its face (within the soft contact's settling overlap, micrometres)
    assert np.linalg.norm(w.body_velocity[1]) < 1e-6
    assert np.linalg.norm(w.body_angular_velocity[1]) < 1e-6 / H
    q = w.body_orientation[1]
    assert 2 * np.arcsin(min(1.0, np.linalg.norm(q[:3]))) < 1e-4
    assert abs(w.body_position[1, 2] - H) < 2e-5


def test_a_box_sliding_flat_stops_straight_at_v2_over_2_mu_g():
    """Slide a resting cube at 2 m/s with mu 0.5: it stops at v^2 / (2 mu g) without leaving its line or turning."""
    v0, mu = 2.0, 0.5
    w = _world("plane", friction=mu)
    w.add_box(half_extents=(H,) * 3, position=(0, 0, H), friction=mu, restitution=0.0)
    w.run(0.25)  # settle
    start = w.body_position[1].copy()
    w.set_body_state(w.body(1), velocity=(v0, 0.0, 0.0))
    spin = [0.0]

    def watch(world):
        spin[0] = max(spin[0], abs(world.body_angular_velocity[1, 2]))

    w.run(0.5, callback=watch)  # it stops after v0 / (mu g) = 0.41 s
    travel = w.body_position[1] - start
    # Coulomb friction decelerates at mu g: d = v0^2 / (2 mu g). Semi-implicit Euler moves with the
    # velocity after each substep's friction, which puts it v0 h / 2 short: allow one substep of travel.
    h = DT / SUBSTEPS
    assert travel[0] == pytest.approx(v0**2 / (2 * mu * G), abs=v0 * h)
    assert np.linalg.norm(w.body_velocity[1]) < 1e-6
    assert abs(travel[1]) < DRIFT
    assert spin[0] < SPIN
    assert abs(_yaw(w.body_orientation[1])) < SPIN * 0.5  # the rate bound over the 0.5 s slide


def test_a_dropped_stack_of_boxes_lands_and_stands_unturned():
    """Drop five cubes 2 cm apart onto each other: they land and stand in a column, none moved sideways or turned."""
    w = _world("plane")
    for i in range(5):
        w.add_box(half_extents=(H,) * 3, position=(0, 0, H + i * (2 * H + 0.02)), restitution=0.0)
    duration = 2.0
    w.run(duration)
    # the flat landings' remainders rock the boxes a little (see TURN); none may drift or turn visibly
    assert np.abs(w.body_position[1:, :2]).max() < SHIFT / 2
    assert max(abs(_yaw(q)) for q in w.body_orientation[1:]) < 10 * TURN
    assert np.abs(w.body_angular_velocity[1:]).max() < 1e-6 / H
    # heights: each contact settles about 4 micrometres per body it carries (softness), 60 um summed down the column
    z = w.body_position[1:, 2]
    assert np.allclose(z, H + 2 * H * np.arange(5), atol=1e-4)
