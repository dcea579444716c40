"""Rotations in NumPy, for setup, I/O, picking and plots (the kernels have Warp's own).

Quaternions are (x, y, z, w) arrays, the layout of `wp.quat`. Every function takes one value or a
stack of them (leading axes broadcast) unless its docstring says otherwise, and returns float64.
"""

from __future__ import annotations

import numpy as np


def quat_mul(p, q) -> np.ndarray:
    """Hamilton products p q, shapes (..., 4): rotate by q, then by p."""
    p, q = np.asarray(p, dtype=np.float64), np.asarray(q, dtype=np.float64)
    pv, pw, qv, qw = p[..., :3], p[..., 3:], q[..., :3], q[..., 3:]
    vector = pw * qv + qw * pv + np.cross(pv, qv)
    scalar = pw * qw - np.sum(pv * qv, axis=-1, keepdims=True)
    return np.concatenate([vector, scalar], axis=-1)


def quat_conj(q) -> np.ndarray:
    """Conjugates of quaternions, shape (..., 4): the inverse rotations of unit ones."""
    q = np.array(q, dtype=np.float64)
    q[..., :3] *= -1.0
    return q


def quat_rotate(q, v) -> np.ndarray:
    """Vectors v (..., 3) rotated by unit quaternions q (..., 4): v + 2 w (u x v) + 2 u x (u x v)."""
    q, v = np.asarray(q, dtype=np.float64), np.asarray(v, dtype=np.float64)
    u, w = q[..., :3], q[..., 3:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def quat_rotate_inverse(q, v) -> np.ndarray:
    """Vectors v (..., 3) rotated by the inverses of unit quaternions q (..., 4)."""
    return quat_rotate(quat_conj(q), v)


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrices of unit quaternions, shape (..., 4) -> (..., 3, 3)."""
    q = np.asarray(q, dtype=np.float64)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def matrix_to_quat(m) -> np.ndarray:
    """Unit quaternion of one proper rotation matrix (3, 3), by Shepperd's method (the largest pivot)."""
    m = np.asarray(m, dtype=np.float64)
    t = np.trace(m)
    if t > 0:
        s = 2.0 * np.sqrt(1.0 + t)
        q = np.array([(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s])
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = np.zeros(4)
        q[i] = 0.25 * s
        q[j] = (m[j, i] + m[i, j]) / s
        q[k] = (m[k, i] + m[i, k]) / s
        q[3] = (m[k, j] - m[j, k]) / s
    return q / np.linalg.norm(q)


def _shortest_arc(cross: np.ndarray, cos: float, half_turn: tuple[float, float, float, float]) -> np.ndarray:
    """The rotation (cross, 1 + cos) normalised; `half_turn` when the two directions are opposite."""
    if cos < -1.0 + 1e-12:
        return np.array(half_turn, dtype=np.float64)
    q = np.array([cross[0], cross[1], cross[2], 1.0 + cos])
    return q / np.linalg.norm(q)


def quat_from_z(direction) -> np.ndarray:
    """Unit quaternion turning +z onto the unit vector `direction` (3,) the shortest way (-z: a half turn about x)."""
    d = np.asarray(direction, dtype=np.float64)
    return _shortest_arc(np.cross([0.0, 0.0, 1.0], d), float(d[2]), (1.0, 0.0, 0.0, 0.0))


def quat_from_x(direction) -> np.ndarray:
    """Unit quaternion turning +x onto the unit vector `direction` (3,) the shortest way (-x: a half turn about z)."""
    d = np.asarray(direction, dtype=np.float64)
    return _shortest_arc(np.array([0.0, -d[2], d[1]]), float(d[0]), (0.0, 0.0, 1.0, 0.0))


def rotation_vector(q_to, q_from) -> np.ndarray:
    """Rotation vectors (axis * angle [rad]) of the rotations q_to q_from^-1, the shorter way, shape (k, 3)."""
    d = quat_mul(q_to, quat_conj(q_from))
    d = np.where(d[:, 3:] < 0.0, -d, d)  # q and -q are one rotation: take the one of angle <= pi
    s = np.linalg.norm(d[:, :3], axis=1)
    angle = 2.0 * np.arctan2(s, d[:, 3])
    with np.errstate(invalid="ignore", divide="ignore"):
        axis = np.where(s[:, None] > 1e-300, d[:, :3] / s[:, None], 0.0)
    return axis * angle[:, None]


def inertia_world(inv_inertia, q) -> np.ndarray:
    """World-frame inertia tensors R diag(I) R^T [kg m^2], shape (n, 3, 3), from principal inverse moments (n, 3)."""
    inv_inertia = np.asarray(inv_inertia, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        inertia = np.where(inv_inertia > 0.0, 1.0 / np.where(inv_inertia > 0.0, inv_inertia, 1.0), 0.0)
    rot = quat_to_matrix(q)
    return np.einsum("nij,nj,nkj->nik", rot, inertia, rot)
