"""tumble.npmath against rotation matrices built independently (Rodrigues' formula)."""

import numpy as np
import pytest

from tumble import npmath


def _rodrigues(axis, angle):
    """Rotation matrix of `angle` about the unit `axis`: I + sin K + (1 - cos) K^2."""
    x, y, z = axis
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * k @ k


def _quat(axis, angle):
    return np.r_[np.sin(angle / 2) * np.asarray(axis), np.cos(angle / 2)]


@pytest.fixture
def rotations():
    rng = np.random.default_rng(3)
    axes = rng.normal(size=(6, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = rng.uniform(-np.pi, np.pi, size=6)
    q = np.array([_quat(a, t) for a, t in zip(axes, angles)])
    m = np.array([_rodrigues(a, t) for a, t in zip(axes, angles)])
    return q, m, rng.normal(size=(6, 3))


def test_matrices_and_rotation_agree_with_rodrigues(rotations):
    q, m, v = rotations
    np.testing.assert_allclose(npmath.quat_to_matrix(q), m, atol=1e-14)
    np.testing.assert_allclose(npmath.quat_rotate(q, v), np.einsum("nij,nj->ni", m, v), atol=1e-14)
    np.testing.assert_allclose(npmath.quat_rotate_inverse(q, v), np.einsum("nji,nj->ni", m, v), atol=1e-14)


def test_product_composes_rotations_right_to_left(rotations):
    q, m, _ = rotations
    pq = npmath.quat_mul(q[:3], q[3:])
    np.testing.assert_allclose(npmath.quat_to_matrix(pq), m[:3] @ m[3:], atol=1e-14)
    np.testing.assert_allclose(npmath.quat_mul(q[0], npmath.quat_conj(q[0])), [0, 0, 0, 1], atol=1e-15)


def test_matrix_to_quat_inverts_quat_to_matrix_up_to_sign(rotations):
    q, m, _ = rotations
    for qi, mi in zip(q, m):
        back = npmath.matrix_to_quat(mi)
        assert min(np.abs(back - qi).max(), np.abs(back + qi).max()) < 1e-14


def test_shortest_arcs_turn_their_axis_onto_the_direction():
    d = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    np.testing.assert_allclose(npmath.quat_rotate(npmath.quat_from_z(d), [0, 0, 1]), d, atol=1e-15)
    np.testing.assert_allclose(npmath.quat_rotate(npmath.quat_from_x(d), [1, 0, 0]), d, atol=1e-15)
    # opposite directions: a half turn (about x for +z, about z for +x)
    np.testing.assert_array_equal(npmath.quat_from_z([0, 0, -1]), [1, 0, 0, 0])
    np.testing.assert_array_equal(npmath.quat_from_x([-1, 0, 0]), [0, 0, 1, 0])


def test_rotation_vector_is_axis_times_angle_the_short_way():
    axis = np.array([0.0, 0.6, 0.8])
    q0 = _quat([1.0, 0.0, 0.0], 0.4)
    for angle in (0.0, 0.7, 3.0, -2.5):
        q1 = npmath.quat_mul(_quat(axis, angle), q0)
        np.testing.assert_allclose(npmath.rotation_vector(q1[None], q0[None])[0], axis * angle, atol=1e-13)
    # a turn of 3.5 rad one way is 2 pi - 3.5 the other
    q1 = npmath.quat_mul(_quat(axis, 3.5), q0)
    np.testing.assert_allclose(npmath.rotation_vector(q1[None], q0[None])[0], -axis * (2 * np.pi - 3.5), atol=1e-13)


def test_inertia_world_is_r_diag_rt(rotations):
    q, m, _ = rotations
    moments = np.array([1.0, 2.0, 4.0])
    inv = np.tile(1.0 / moments, (6, 1))
    inv[0, 2] = 0.0  # an infinite moment stays out (static axis): its entry is 0
    expected = np.einsum("nij,nj,nkj->nik", m, np.where(inv > 0, 1.0 / np.where(inv > 0, inv, 1), 0.0), m)
    np.testing.assert_allclose(npmath.inertia_world(inv, q), expected, atol=1e-13)
    np.testing.assert_allclose(np.linalg.eigvalsh(npmath.inertia_world(inv, q)[1]), moments, atol=1e-13)
