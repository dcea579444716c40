"""Cloth pinned to bodies: pins that follow a body's motion, and pull on it (two-way).

Reads body poses and the cloth's forces on its pinned particles; writes those particles'
positions and pin targets, and body velocities. Costs O(body pins) per cloth substep.

A body pin is a pinned particle (inverse mass 0) with a point fixed in a body's frame. Each
cloth substep, after the spring and air forces are summed and before integration:
- reaction: the force F the cloth exerts on the pin, plus the pin particle's own weight m g,
  acts on the body for the cloth substep: v += F h / m, w += I^-1 (r x F) h (as the cloth's
  contacts push bodies);
and after integration:
- follow: the particle is put on the body point x_b + R_b r (its target too), so its velocity
  (x - x_prev) / h is the point's.
The body's response to the pins comes one cloth substep late, which is stable while the cloth
is much lighter than the body (a flag on a pole).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..launch import LaunchCache, launch
from ..model import body_arrays
from ..real import BodyArrays, float_t, vec3
from ..solver.joints import add_velocity
from ..solver.rigid import inv_inertia_times


@wp.kernel
def _reaction(
    pin_particle: wp.array(dtype=wp.int32),
    pin_body: wp.array(dtype=wp.int32),
    pin_local: wp.array(dtype=vec3),
    particle_force: wp.array(dtype=vec3),
    particle_mass: wp.array(dtype=float_t),
    gravity: vec3,
    h: float_t,
    bodies: BodyArrays,
    serial: int,
):
    k = wp.tid()
    b = pin_body[k]
    im = bodies.inv_mass[b]
    if im == float_t(0.0):
        return
    p = pin_particle[k]
    F = particle_force[p] + gravity * particle_mass[p]
    r = wp.quat_rotate(bodies.orientation[b], pin_local[k])
    dv = F * (im * h)
    dw = inv_inertia_times(bodies.orientation[b], bodies.inv_inertia[b], wp.cross(r, F)) * h
    add_velocity(b, dv, dw, bodies.velocity, bodies.angular_velocity, bodies.inv_mass, serial)


@wp.kernel
def _follow(
    pin_particle: wp.array(dtype=wp.int32),
    pin_body: wp.array(dtype=wp.int32),
    pin_local: wp.array(dtype=vec3),
    bodies: BodyArrays,
    particle_position: wp.array(dtype=vec3),
    particle_pin_target: wp.array(dtype=vec3),
):
    k = wp.tid()
    b = pin_body[k]
    p = pin_particle[k]
    point = bodies.position[b] + wp.quat_rotate(bodies.orientation[b], pin_local[k])
    particle_position[p] = point
    particle_pin_target[p] = point


@wp.kernel
def _sum_pin_load(
    pins: wp.array(dtype=wp.int32),
    force: wp.array(dtype=vec3),
    mass: wp.array(dtype=float_t),
    gravity: vec3,
    h: float_t,
    total: wp.array(dtype=vec3),
):
    p = pins[wp.tid()]
    wp.atomic_add(total, 0, (force[p] + gravity * mass[p]) * h)


def sum_pin_load(pins, force, mass, gravity, total, h, *, cache: LaunchCache | None = None) -> None:
    """Add to total[0] the impulse over h of a force on every pinned particle, plus its weight.

    Args:
        pins: the pinned particles, shape (k,) int32.
        force: per-particle force [N], shape (P,) vec3 (springs and air; or a pull in kg m with
            h the inverse substep and zero gravity).
        mass: particle masses [kg], shape (P,).
        gravity: [m/s^2], shape (3,).
        total: accumulator [N s], shape (1,) vec3.
        h: substep [s].
    """
    if pins.shape[0]:
        launch(_sum_pin_load, pins.shape[0], [pins, force, mass, vec3(*gravity), float(h), total], pins.device, cache)


class BodyPins:
    """Particles pinned to points of bodies (rows of the world's body arrays)."""

    def __init__(self, device: str):
        self.device = device
        self.count = 0
        self._particle = np.zeros(0, dtype=np.int32)
        self._body = np.zeros(0, dtype=np.int32)
        self._local = np.zeros((0, 3))
        self._bodies: tuple | None = None  # the body arrays as the kernels take them (`_body_struct`)
        self._upload()

    def add(self, particles: np.ndarray, body_row: int, local: np.ndarray) -> None:
        """Pin `particles` (indices) to body row `body_row` at body-frame points `local` (k, 3)."""
        keep = ~np.isin(self._particle, particles)  # a particle follows one body: the last given
        self._particle = np.concatenate([self._particle[keep], particles.astype(np.int32)])
        self._body = np.concatenate([self._body[keep], np.full(len(particles), body_row, dtype=np.int32)])
        self._local = np.vstack([self._local[keep], local])
        self._upload()

    def remove(self, particles) -> None:
        keep = ~np.isin(self._particle, np.asarray(particles))
        self._particle, self._body, self._local = self._particle[keep], self._body[keep], self._local[keep]
        self._upload()

    def remap_bodies(self, slot: np.ndarray) -> None:
        self._body = slot[self._body].astype(np.int32)
        self._upload()

    def _upload(self) -> None:
        self.count = len(self._particle)
        n = max(1, self.count)
        self.particle: wp.array = wp.array(np.resize(self._particle, n), dtype=wp.int32, device=self.device)
        self.body: wp.array = wp.array(np.resize(self._body, n), dtype=wp.int32, device=self.device)
        self.local: wp.array = wp.array(np.resize(self._local, (n, 3)), dtype=vec3, device=self.device)

    def _body_struct(self, bodies) -> BodyArrays:
        """The body arrays as the kernels take them, built again only when the arrays were."""
        self._bodies = body_arrays(bodies, self._bodies)
        return self._bodies[0]

    def _react(self, force: wp.array, mass: wp.array, bodies, gravity: vec3, h: float) -> None:
        """`force` on the pin particles, plus `gravity` times their `mass`, acts on the bodies for `h` seconds."""
        if self.count == 0:
            return
        inputs = [self.particle, self.body, self.local, force, mass, gravity, h, self._body_struct(bodies)]
        wp.launch(_reaction, dim=self.count, device=self.device, inputs=[*inputs, 1 if self.device == "cpu" else 0])

    def react(self, arrays: dict, bodies, gravity, h: float) -> None:
        """The cloth's pull on the pins (and their weight) acts on the bodies for `h` seconds."""
        self._react(arrays["particle_force"], arrays["particle_mass"], bodies, vec3(*gravity), h)

    def react_constraints(self, arrays: dict, bodies, h: float) -> None:
        """The stretch limit's and tethers' pull on the pins this substep (`particle_pin_load`,
        lambda u [kg m]) acts on their bodies as the impulse lambda u / h."""
        self._react(arrays["particle_pin_load"], arrays["particle_mass"], bodies, vec3(0.0, 0.0, 0.0), 1.0 / h)

    def follow(self, arrays: dict, bodies) -> None:
        """Put the pinned particles on their body points."""
        if self.count == 0:
            return
        wp.launch(
            _follow,
            dim=self.count,
            device=self.device,
            inputs=[
                self.particle,
                self.body,
                self.local,
                self._body_struct(bodies),
                arrays["particle_position"],
                arrays["particle_pin_target"],
            ],
        )
