"""Semi-implicit (symplectic) Euler integration of bodies, one substep at a time.

Reads and writes body positions, orientations and velocities; costs O(bodies).

- velocities first: v += (g + F / m) h, w += I^-1 tau h (static bodies, inverse mass 0, skip);
- then positions with the new velocities: x += v h (kinematic bodies too: inverse mass 0, moved
  only by the velocity the user gives them), and the orientation by the exponential
  of the rotation vector w h, q' = exp(w h / 2) q, which keeps |q| = 1 to rounding (we also
  renormalise);
- torque-free rotation: the world angular momentum L = I_world(q) w is carried across the
  rotation, w' = I_world(q')^-1 L, so a spinning box conserves L exactly and precesses
  (Euler's equations dL/dt = 0) instead of gaining energy as explicit gyroscopic terms would.
"""

from __future__ import annotations

import warp as wp

from ..launch import LaunchCache, launch
from ..state import float_t, quat, vec3
from .contacts import inv_inertia_times


@wp.kernel
def _integrate_velocities(
    inv_mass: wp.array(dtype=float_t),
    inv_inertia: wp.array(dtype=vec3),
    q: wp.array(dtype=quat),
    force: wp.array(dtype=vec3),
    torque: wp.array(dtype=vec3),
    gravity: vec3,
    h: float_t,
    use_warm: int,
    v: wp.array(dtype=vec3),
    w: wp.array(dtype=vec3),
    warm_v: wp.array(dtype=vec3),
    warm_w: wp.array(dtype=vec3),
    count: int,
):
    i = wp.tid()
    if i >= count:
        return  # launched over the capacity (see tumble.launch)
    im = inv_mass[i]
    if im == float_t(0.0):
        return
    if use_warm != 0:
        # warm start: the contact impulses of the previous substep, summed by its relax pass
        v[i] = v[i] + warm_v[i]
        w[i] = w[i] + warm_w[i]
    warm_v[i] = vec3()
    warm_w[i] = vec3()
    v[i] = v[i] + (gravity + force[i] * im) * h
    tau = torque[i]
    if tau[0] != float_t(0.0) or tau[1] != float_t(0.0) or tau[2] != float_t(0.0):
        w[i] = w[i] + inv_inertia_times(q[i], inv_inertia[i], tau) * h


@wp.func
def _inertia_times(q: quat, inv_i: vec3, x: vec3):
    local = wp.quat_rotate_inv(q, x)
    return wp.quat_rotate(q, vec3(local[0] / inv_i[0], local[1] / inv_i[1], local[2] / inv_i[2]))


@wp.kernel
def _integrate_positions(
    inv_mass: wp.array(dtype=float_t),
    inv_inertia: wp.array(dtype=vec3),
    h: float_t,
    x: wp.array(dtype=vec3),
    q: wp.array(dtype=quat),
    v: wp.array(dtype=vec3),
    w: wp.array(dtype=vec3),
    dx: wp.array(dtype=vec3),
    dtheta: wp.array(dtype=vec3),
    count: int,
):
    i = wp.tid()
    if i >= count:
        return
    if inv_mass[i] == float_t(0.0) and wp.length_sq(v[i]) == float_t(0.0) and wp.length_sq(w[i]) == float_t(0.0):
        return  # static (a kinematic body, inverse mass 0 too, moves with the velocity it was given)
    x[i] = x[i] + v[i] * h
    dx[i] = dx[i] + v[i] * h
    wi = w[i]
    dtheta[i] = dtheta[i] + wi * h
    speed = wp.length(wi)
    if speed > float_t(0.0):
        # q' = exp(w h / 2) q: rotation by |w| h about w / |w|
        angle = speed * h
        axis = wi / speed
        half = float_t(0.5) * angle
        s = wp.sin(half)
        dq = quat(axis[0] * s, axis[1] * s, axis[2] * s, wp.cos(half))
        q0 = q[i]
        q1 = wp.normalize(dq * q0)
        q[i] = q1
        ii = inv_inertia[i]
        if ii[0] != ii[1] or ii[1] != ii[2]:
            # carry the angular momentum L = I(q0) w over the rotation: w' = I(q1)^-1 L
            w[i] = inv_inertia_times(q1, ii, _inertia_times(q0, ii, wi))


@wp.kernel
def _clear(force: wp.array(dtype=vec3), torque: wp.array(dtype=vec3)):
    i = wp.tid()
    force[i] = vec3()
    torque[i] = vec3()


def integrate_velocities(bodies, gravity, h: float, *, warm: bool, cache: LaunchCache | None = None) -> None:
    """v += (g + F/m) h and w += I^-1 tau h for every dynamic body.

    With `warm`, first add the warm start the last relax pass summed per body; either way clear it.
    """
    if bodies.count == 0:
        return  # a cloth-only world: no launch over an empty capacity
    a = bodies.arrays
    launch(_integrate_velocities, bodies.capacity,
           [a["body_inv_mass"], a["body_inv_inertia"], a["body_orientation"], a["body_force"], a["body_torque"],
            vec3(*gravity), h, int(warm), a["body_velocity"], a["body_angular_velocity"], a["body_warm_velocity"],
            a["body_warm_angular_velocity"], bodies.count], bodies.device, cache)


def integrate_positions(bodies, h: float, *, cache: LaunchCache | None = None) -> None:
    """x += v h and q' = exp(w h / 2) q for every dynamic or kinematic body, conserving angular momentum."""
    if bodies.count == 0:
        return
    a = bodies.arrays
    launch(_integrate_positions, bodies.capacity,
           [a["body_inv_mass"], a["body_inv_inertia"], h, a["body_position"], a["body_orientation"],
            a["body_velocity"], a["body_angular_velocity"], a["body_delta_position"], a["body_delta_rotation"],
            bodies.count], bodies.device, cache)


def begin_step(bodies) -> None:
    """Zero the motion accumulated since the step began (read by the contact solver)."""
    if bodies.count == 0:
        return
    bodies.arrays["body_delta_position"].zero_()
    bodies.arrays["body_delta_rotation"].zero_()


def clear_forces(bodies) -> None:
    """Forget the user forces and torques applied for the step just taken."""
    if bodies.count == 0:
        return
    a = bodies.arrays
    wp.launch(_clear, dim=bodies.count, device=bodies.device, inputs=[a["body_force"], a["body_torque"]])
