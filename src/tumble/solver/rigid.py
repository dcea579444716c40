"""Rigid-body algebra shared by the solver's stages (contacts, joints, integration) and the cloth coupling.

Warp functions only: each reads a body's orientation and principal inverse inertia, as the body
arrays hold them (`model.BodyArrays`), and works in the world frame.
"""

from __future__ import annotations

import warp as wp

from ..real import float_t, quat, vec3


@wp.func
def inv_inertia_times(q: quat, inv_i: vec3, x: vec3):
    """World-frame I^-1 x = R diag(inv_i) R^T x."""
    local = wp.quat_rotate_inv(q, x)
    return wp.quat_rotate(q, vec3(local[0] * inv_i[0], local[1] * inv_i[1], local[2] * inv_i[2]))


@wp.func
def inv_inertia_world(q: quat, inv_i: vec3):
    """World-frame inverse inertia tensor R diag(inv_i) R^T."""
    R = wp.quat_to_matrix(q)
    return R * wp.diag(inv_i) * wp.transpose(R)


@wp.func
def safe_inverse(k: float_t):
    """1 / k, or 0 for k <= 0 (an effective mass of a row with no mobility)."""
    if k > float_t(0.0):
        return float_t(1.0) / k
    return float_t(0.0)


@wp.func
def add_to_velocity(v: wp.array(dtype=vec3), w: wp.array(dtype=vec3), i: int, dv: vec3, dw: vec3, serial: int):
    """Add dv, dw to row i of the velocities v, w: `serial` (the CPU) plain updates, one after another
    in the thread's order (Gauss-Seidel); else atomics (CUDA)."""
    if serial != 0:
        v[i] = v[i] + dv
        w[i] = w[i] + dw
    else:
        wp.atomic_add(v, i, dv)
        wp.atomic_add(w, i, dw)
