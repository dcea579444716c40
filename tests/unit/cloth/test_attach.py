"""cloth/attach.py on plain arrays: body pins follow their body points and pull on their bodies.

References: the point of a body is x_b + R_b r; a force F on a pin (plus the pin's weight m g)
acting for h changes the body's velocities by dv = F h / m_b and dw = I_b^-1 (R_b r x F) h; a body
welded to its pins keeps their joint momentum and angular momentum.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from tumble.cloth.arrays import PARTICLE_FIELDS, Particles
from tumble.cloth.attach import BodyPins, sum_pin_load
from tumble.model import BODY_FIELDS, fields_of
from tumble.state import ArraySet, vec3
from tumble.structs import fill_struct

from ..reference import quat_matrix

#: the body arrays as a World holds them (the pins' kernels take the struct of every kernel field)
BODY_ARRAYS = fields_of(BODY_FIELDS)
G = np.array([0.0, 0.0, -9.81])


def two_bodies() -> ArraySet:
    """Row 0: a static body; row 1: a dynamic one, turned 0.6 rad about (1, 1, 0), mass 2, moments (1, 2, 4)."""
    q = np.append(np.array([1.0, 1.0, 0.0]) / math.sqrt(2) * math.sin(0.3), math.cos(0.3))
    b = ArraySet(BODY_ARRAYS, device="cpu", capacity=2)
    b.append(
        {
            "body_position": np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]]),
            "body_orientation": np.array([[0.0, 0.0, 0.0, 1.0], q]),
            "body_inv_mass": np.array([0.0, 0.5]),
            "body_inv_inertia": np.array([[0.0, 0.0, 0.0], [1.0, 0.5, 0.25]]),
        }
    )
    return b


def particles(n: int) -> dict[str, wp.array]:
    """Every particle array of n particles of 0.1 kg, the rest zero."""
    arrays = ArraySet(fields_of(PARTICLE_FIELDS), device="cpu", capacity=n).arrays
    arrays["particle_mass"].fill_(0.1)
    return arrays


def struct(arrays: dict[str, wp.array]) -> Particles:
    """The particle arrays as the kernels take them."""
    return fill_struct(Particles, arrays, "particle_")


def test_pinned_particles_sit_on_their_body_points():
    """follow puts each pin (and its target) at x_b + R_b r; particles not pinned stay."""
    bodies = two_bodies()
    pins = BodyPins("cpu")
    local = np.array([[0.5, 0.0, 0.0], [0.0, -0.2, 0.3]])
    pins.add(np.array([1, 3]), 1, local)
    assert pins.count == 2
    arrays = particles(4)
    arrays["particle_position"].assign(np.full((4, 3), 7.0))
    pins.follow(struct(arrays), bodies)
    x, R = bodies.numpy("body_position")[1], quat_matrix(bodies.numpy("body_orientation")[1])
    out = arrays["particle_position"].numpy()
    np.testing.assert_allclose(out[[1, 3]], x + local @ R.T, atol=1e-12)
    np.testing.assert_allclose(arrays["particle_pin_target"].numpy()[[1, 3]], out[[1, 3]], atol=0)
    np.testing.assert_array_equal(out[[0, 2]], np.full((2, 3), 7.0))


def test_weld_gives_a_body_and_its_pins_one_motion_with_their_momentum_and_angular_momentum():
    """weld: the dynamic body and its two pins (0.1 kg, moving apart from it) take the rigid motion (v, w)
    with their linear momentum m_b v_b + sum m u and their angular momentum I w_b + sum m r x u about the
    body's centre; ride then gives the pins their points' velocities v + w x r. A pin on the static body
    changes nothing. (Reference: the same balance written as one 6 x 6 system, solved by NumPy.)"""
    bodies = two_bodies()
    v_b, w_b = np.array([0.2, -0.4, 0.1]), np.array([1.0, 0.3, -0.5])
    bodies.arrays["body_velocity"].assign(np.array([[0.0, 0.0, 0.0], v_b]))
    bodies.arrays["body_angular_velocity"].assign(np.array([[0.0, 0.0, 0.0], w_b]))
    pins = BodyPins("cpu")
    local = np.array([[0.5, 0.0, 0.0], [0.0, -0.2, 0.3]])
    pins.add(np.array([0, 2]), 1, local)
    pins.add(np.array([1]), 0, np.array([[0.0, 0.0, 1.0]]))
    arrays = particles(3)
    u = np.array([[0.3, -0.1, 0.2], [5.0, 5.0, 5.0], [-1.0, 0.4, 0.0]])
    arrays["particle_velocity"].assign(u)
    pins.weld(struct(arrays), bodies)
    pins.ride(struct(arrays), bodies)

    R = quat_matrix(bodies.numpy("body_orientation")[1])
    inertia = R @ np.diag([1.0, 2.0, 4.0]) @ R.T
    r = local @ R.T
    m = 0.1
    # rows: linear momentum, angular momentum about the centre, of body and pins moving as (v, w)
    A = np.zeros((6, 6))
    A[:3, :3] = np.eye(3) * (2.0 + 2 * m)
    rhs = np.concatenate([2.0 * v_b + m * u[[0, 2]].sum(axis=0), inertia @ w_b])
    A[3:, 3:] = inertia
    for ri, ui in zip(r, u[[0, 2]]):
        cross = np.array([[0.0, -ri[2], ri[1]], [ri[2], 0.0, -ri[0]], [-ri[1], ri[0], 0.0]])
        A[:3, 3:] -= m * cross  # m (w x r) = -m [r]x w
        A[3:, :3] += m * cross  # m r x v
        A[3:, 3:] -= m * cross @ cross  # m r x (w x r)
        rhs[3:] += m * np.cross(ri, ui)
    expected = np.linalg.solve(A, rhs)
    np.testing.assert_allclose(bodies.numpy("body_velocity")[1], expected[:3], atol=1e-14)
    np.testing.assert_allclose(bodies.numpy("body_angular_velocity")[1], expected[3:], atol=1e-14)
    ride = expected[:3] + np.cross(expected[3:], r)
    np.testing.assert_allclose(arrays["particle_velocity"].numpy()[[0, 2]], ride, atol=1e-14)
    assert not bodies.numpy("body_velocity")[0].any() and not bodies.numpy("body_angular_velocity")[0].any()
    np.testing.assert_array_equal(arrays["particle_velocity"].numpy()[1], [0.0, 0.0, 0.0])  # the static body's


def test_the_pull_on_a_pin_moves_its_body_and_not_a_static_one():
    """react: dv = (F + m g) h / m_b, dw = I^-1 (R r x (F + m g)) h on the dynamic body; the static one stays."""
    bodies = two_bodies()
    pins = BodyPins("cpu")
    pins.add(np.array([0]), 1, np.array([[0.5, 0.0, 0.0]]))
    pins.add(np.array([1]), 0, np.array([[0.0, 0.0, 1.0]]))  # on the static body: no effect
    arrays = particles(2)
    force = np.array([[1.0, -2.0, 0.5], [100.0, 0.0, 0.0]])
    arrays["particle_force"].assign(force)
    h = 0.01
    pins.react(struct(arrays), bodies, G, h)
    F = force[0] + 0.1 * G
    R = quat_matrix(bodies.numpy("body_orientation")[1])
    inv_i_world = R @ np.diag([1.0, 0.5, 0.25]) @ R.T
    r = R @ np.array([0.5, 0.0, 0.0])
    np.testing.assert_allclose(bodies.numpy("body_velocity")[1], F * h * 0.5, atol=1e-14)
    np.testing.assert_allclose(bodies.numpy("body_angular_velocity")[1], inv_i_world @ np.cross(r, F) * h, atol=1e-14)
    assert not bodies.numpy("body_velocity")[0].any() and not bodies.numpy("body_angular_velocity")[0].any()


def test_a_particle_follows_the_body_it_was_pinned_to_last_and_remove_releases_it():
    """add of a pinned particle moves it to the new body; remove drops it; remap_bodies follows renumbered rows."""
    pins = BodyPins("cpu")
    pins.add(np.array([0, 1]), 0, np.zeros((2, 3)))
    pins.add(np.array([1]), 1, np.ones((1, 3)))
    assert pins.count == 2
    np.testing.assert_array_equal(np.sort(pins.particle.numpy()), [0, 1])
    body_of = dict(zip(pins.particle.numpy().tolist(), pins.body.numpy().tolist()))
    assert body_of == {0: 0, 1: 1}
    pins.remap_bodies(np.array([5, 4]))  # row 0 is now row 5, row 1 row 4
    assert dict(zip(pins.particle.numpy().tolist(), pins.body.numpy().tolist())) == {0: 5, 1: 4}
    pins.remove([0])
    assert pins.count == 1 and pins.particle.numpy()[0] == 1
    pins.remove([1])
    assert pins.count == 0
    bodies = two_bodies()
    pins.follow(struct(particles(2)), bodies)  # nothing pinned: no launch, nothing moves
    pins.weld(struct(particles(2)), bodies)
    pins.ride(struct(particles(2)), bodies)
    pins.react(struct(particles(2)), bodies, G, 0.01)
    assert not bodies.numpy("body_velocity").any()


def test_sum_pin_load_adds_the_impulse_of_force_and_weight():
    """total += sum over pins of (F + m g) h; other particles do not count."""
    arrays = particles(4)
    force = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [50.0, 50.0, 50.0], [0.0, 0.0, 3.0]])
    arrays["particle_force"].assign(force)
    total = wp.zeros(1, dtype=vec3)
    pins = wp.array(np.array([0, 1, 3], dtype=np.int32), dtype=wp.int32)
    sum_pin_load(pins, arrays["particle_force"], struct(arrays), G, total, 0.5)
    expected = (force[[0, 1, 3]].sum(axis=0) + 3 * 0.1 * G) * 0.5
    np.testing.assert_allclose(total.numpy()[0], expected, atol=1e-14)
    sum_pin_load(wp.zeros(0, dtype=wp.int32), arrays["particle_force"], struct(arrays), G, total, 0.5)
    np.testing.assert_allclose(total.numpy()[0], expected, atol=1e-14)  # no pins: nothing added
