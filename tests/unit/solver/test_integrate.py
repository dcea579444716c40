"""solver/integrate.py on plain body arrays: free flight, forces, torques, kinematic and static bodies,
warm start, and the torque-free rotation (|L| and L carried, energy bounded, spheres exact).

Semi-implicit Euler with substep h: v_k = v_0 + k g h and x_n = x_0 + h sum_{k=1..n} v_k
= x_0 + n h v_0 + g h^2 n (n + 1) / 2 (explicit Euler would give n (n - 1) / 2). With
h = 2^-k the sums are exact in float64, so the tolerances are a few ulps.
"""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from tumble.model import BODY_FIELDS, fields_of
from tumble.solver import integrate
from tumble.state import ArraySet

from ..reference import quat_axis_angle, quat_matrix

#: the body arrays (all of them: the integrator takes the kernels' struct of body arrays)
FIELDS = fields_of(BODY_FIELDS)
G = np.array([0.0, 0.0, -9.81])
H = 2.0**-10


def bodies(**rows) -> ArraySet:
    """Bodies from rows given as arrays (first axis = body); orientation defaults to identity."""
    n = len(next(iter(rows.values())))
    rows.setdefault("body_orientation", np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)))
    rows.setdefault("body_inv_inertia", np.ones((n, 3)))
    s = ArraySet(FIELDS, device="cpu", capacity=4)
    s.append(rows)
    return s


def substep(b: ArraySet, h: float = H, gravity=G, *, warm: bool = False) -> None:
    integrate.integrate_velocities(b, gravity, h, warm=warm)
    integrate.integrate_positions(b, h)


def test_free_flight_follows_the_semi_implicit_euler_sums():
    """After n substeps: v = v0 + n g h, x = x0 + n h v0 + g h^2 n (n + 1) / 2, for every body."""
    x0 = np.array([[0.0, 0.0, 10.0], [1.0, -2.0, 0.5]])
    v0 = np.array([[3.0, 0.0, 4.0], [-0.5, 0.25, 0.0]])
    b = bodies(body_position=x0, body_velocity=v0, body_inv_mass=np.array([1.0, 0.25]))
    n = 64
    for _ in range(n):
        substep(b)
    np.testing.assert_allclose(b.numpy("body_velocity"), v0 + n * G * H, rtol=0, atol=1e-13)
    expected = x0 + n * H * v0 + G * H * H * n * (n + 1) / 2
    np.testing.assert_allclose(b.numpy("body_position"), expected, rtol=0, atol=1e-13)
    # the displacement since the step began is kept for the contact solver; begin_step zeroes it
    np.testing.assert_allclose(b.numpy("body_delta_position"), expected - x0, rtol=0, atol=1e-13)
    integrate.begin_step(b)
    assert not b.numpy("body_delta_position").any() and not b.numpy("body_delta_rotation").any()


def test_force_accelerates_by_f_over_m_and_clear_forces_forgets_it():
    """v += (g + F / m) h; after clear_forces only gravity acts."""
    b = bodies(
        body_position=np.zeros((1, 3)),
        body_velocity=np.zeros((1, 3)),
        body_inv_mass=np.array([0.5]),
        body_force=np.array([[4.0, 0.0, 2.0]]),
        body_torque=np.array([[0.0, 0.0, 1.0]]),
    )
    substep(b)
    np.testing.assert_allclose(b.numpy("body_velocity")[0], (G + [2.0, 0.0, 1.0]) * H, rtol=0, atol=1e-15)
    integrate.clear_forces(b)
    assert not b.numpy("body_force").any() and not b.numpy("body_torque").any()
    v = b.numpy("body_velocity")[0].copy()
    substep(b)
    np.testing.assert_allclose(b.numpy("body_velocity")[0], v + G * H, rtol=0, atol=1e-15)


def test_torque_turns_through_the_world_inverse_inertia():
    """w += R diag(1 / I) R^T tau h for a rotated body with unequal moments."""
    q = quat_axis_angle([1.0, 2.0, -0.5], 0.8)
    inv_i = np.array([1.0, 0.5, 0.25])
    tau = np.array([0.3, -1.0, 2.0])
    b = bodies(
        body_position=np.zeros((1, 3)),
        body_orientation=q[None],
        body_velocity=np.zeros((1, 3)),
        body_inv_mass=np.array([1.0]),
        body_inv_inertia=inv_i[None],
        body_torque=tau[None],
    )
    integrate.integrate_velocities(b, np.zeros(3), H, warm=False)
    R = quat_matrix(q)
    np.testing.assert_allclose(b.numpy("body_angular_velocity")[0], R @ np.diag(inv_i) @ R.T @ tau * H, atol=1e-15)


def test_static_bodies_stay_and_kinematic_bodies_move_only_with_their_velocity():
    """Inverse mass 0: no gravity or force; at rest it stays, with a velocity it moves x += v h."""
    x0 = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    v0 = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, -0.25]])
    b = bodies(
        body_position=x0,
        body_velocity=v0,
        body_inv_mass=np.zeros(2),
        body_force=np.ones((2, 3)),
        body_angular_velocity=np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 2.0]]),
    )
    for _ in range(8):
        substep(b)
    np.testing.assert_array_equal(b.numpy("body_velocity"), v0)
    np.testing.assert_array_equal(b.numpy("body_position")[0], x0[0])
    np.testing.assert_allclose(b.numpy("body_position")[1], x0[1] + 8 * H * v0[1], rtol=0, atol=1e-15)
    # the kinematic body turned by |w| t about z
    expected = quat_axis_angle([0.0, 0.0, 1.0], 2.0 * 8 * H)
    np.testing.assert_allclose(b.numpy("body_orientation")[1], expected, atol=1e-14)


def test_warm_start_adds_the_stored_impulse_once_and_clears_it():
    """With warm, v += warm_v before gravity; either way the warm buffers are zero afterwards."""
    b = bodies(
        body_position=np.zeros((1, 3)),
        body_velocity=np.zeros((1, 3)),
        body_inv_mass=np.array([1.0]),
        body_warm_velocity=np.array([[1.0, 0.0, 0.0]]),
        body_warm_angular_velocity=np.array([[0.0, 2.0, 0.0]]),
    )
    integrate.integrate_velocities(b, G, H, warm=True)
    np.testing.assert_allclose(b.numpy("body_velocity")[0], [1.0, 0.0, 0.0] + G * H, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(b.numpy("body_angular_velocity")[0], [0.0, 2.0, 0.0])
    assert not b.numpy("body_warm_velocity").any() and not b.numpy("body_warm_angular_velocity").any()
    b.write("body_warm_velocity", 0, [5.0, 5.0, 5.0])
    integrate.integrate_velocities(b, G, H, warm=False)  # not warm: dropped, not added
    np.testing.assert_allclose(b.numpy("body_velocity")[0], [1.0, 0.0, 0.0] + 2 * G * H, rtol=0, atol=1e-15)
    assert not b.numpy("body_warm_velocity").any()


def test_sphere_rotation_is_exact():
    """Equal moments: q(t) = exp(w t / 2) q0, the exact rotation by |w| t about w, at any step count."""
    w = np.array([1.0, -2.0, 0.5])
    q0 = quat_axis_angle([0.0, 1.0, 1.0], 0.3)
    b = bodies(
        body_position=np.zeros((1, 3)),
        body_orientation=q0[None],
        body_velocity=np.zeros((1, 3)),
        body_angular_velocity=w[None],
        body_inv_mass=np.array([1.0]),
        body_inv_inertia=np.full((1, 3), 2.5),
    )
    n, h = 200, 2.0**-7
    for _ in range(n):
        substep(b, h, gravity=np.zeros(3))
    turn = quat_axis_angle(w, np.linalg.norm(w) * n * h)
    expected = quat_matrix(turn) @ quat_matrix(q0)
    np.testing.assert_allclose(quat_matrix(b.numpy("body_orientation")[0]), expected, atol=1e-12)
    np.testing.assert_allclose(b.numpy("body_angular_velocity")[0], w, atol=0)
    np.testing.assert_allclose(b.numpy("body_delta_rotation")[0], w * n * h, atol=1e-12)


@pytest.mark.parametrize("w0", [(0.3, 4.0, 0.2), (2.0, -1.0, 3.0)])
def test_torque_free_rotation_carries_the_angular_momentum(w0):
    """Unequal moments (1, 2, 3): L = R I R^T w stays fixed (to rounding); the energy error is second order in h.

    Over 2 s (several tumbles about the unstable middle axis for the first w0), the largest
    energy error at h and at h / 2 must shrink by 2^2 = 4 (a first-order method: by 2). Both steps
    turn the body by less than MAX_SPLIT_TURN, so each takes its splitting in one part.
    """
    inertia = np.array([1.0, 2.0, 3.0])
    w0 = np.array(w0)
    worst = []
    for h in (2.0**-7, 2.0**-8):
        assert np.linalg.norm(w0) * h < float(integrate.MAX_SPLIT_TURN)
        b = bodies(
            body_position=np.zeros((1, 3)),
            body_velocity=np.zeros((1, 3)),
            body_angular_velocity=w0[None],
            body_inv_mass=np.array([1.0]),
            body_inv_inertia=(1.0 / inertia)[None],
        )

        def momentum_and_energy(b=b):
            R = quat_matrix(b.numpy("body_orientation")[0])
            w = b.numpy("body_angular_velocity")[0]
            I_world = R @ np.diag(inertia) @ R.T
            return I_world @ w, 0.5 * w @ I_world @ w

        L0, E0 = momentum_and_energy()
        error = 0.0
        for _ in range(round(2.0 / h)):
            substep(b, h, gravity=np.zeros(3))
            L, E = momentum_and_energy()
            np.testing.assert_allclose(L, L0, rtol=0, atol=1e-11 * np.linalg.norm(L0))
            error = max(error, abs(E - E0) / E0)
        assert np.linalg.norm(b.numpy("body_orientation")[0]) == pytest.approx(1.0, abs=1e-14)
        assert 0.0 < error <= (h * np.linalg.norm(w0)) ** 2  # bounded by (h |w|)^2, and the body did tumble
        worst.append(error)
    assert worst[0] / worst[1] == pytest.approx(4.0, rel=0.1)


def test_empty_body_set_launches_nothing():
    """A world without bodies (cloth only): every stage returns without touching the arrays."""
    b = ArraySet(FIELDS, device="cpu", capacity=4)
    b.arrays["body_velocity"].fill_(wp.vec3d(1.0, 1.0, 1.0))  # rows beyond the count are not bodies
    substep(b)
    integrate.begin_step(b)
    integrate.clear_forces(b)
    assert (b.arrays["body_velocity"].numpy() == 1.0).all()
