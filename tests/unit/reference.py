"""Reference rotations for the unit tests, written out in NumPy apart from the engine's own helpers.

Quaternions are (x, y, z, w), unit length.
"""

from __future__ import annotations

import numpy as np


def quat_axis_angle(axis, angle: float) -> np.ndarray:
    """The rotation by `angle` [rad] about `axis` (any length)."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.r_[axis * np.sin(angle / 2), np.cos(angle / 2)]


def rotate(q, v) -> np.ndarray:
    """v rotated by q: v + 2 u x (u x v + w v)."""
    x, y, z, w = q
    u = np.array([x, y, z])
    return v + 2 * np.cross(u, np.cross(u, v) + w * v)


def quat_matrix(q) -> np.ndarray:
    """The rotation matrix R of q (R v = rotate(q, v))."""
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
