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
  (x - x_prev) / h is the point's; the momentum m (v_point - v_last) that gives it is taken from
  the body at the point (J = -m (v_point - v_last): dv = J / m_b, dw = I^-1 (r x J)). The pin
  rides on the body, so the body carries its inertia as well as its weight: at rest
  v_point = v_last and the body holds m g; in free fall the two cancel, and bar and
  cloth fall together at g, keeping p = p0 + M g t (with the weight alone they fell at
  (1 + m_pins / m_body) g, momentum gained m_pins g t).
The body's response to the pins comes one cloth substep late, which is stable while the cloth
is much lighter than the body (a flag on a pole).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..launch import LaunchCache, each_end, launch_each, vector
from ..model import body_arrays
from ..real import BodyArrays, float_t, vec3
from ..solver.joints import add_velocity
from ..solver.rigid import inv_inertia_times
from ..structs import array_struct, cached_struct
from .arrays import Particles

#: the arrays of the body pins, one row per pin (`BodyPins.particle`, `.body`, `.local`)
PIN_FIELDS = {
    "particle": wp.int32,  # the pinned particle
    "body": wp.int32,  # the row of the body it follows
    "local": vec3,  # its point in the body's frame [m]
}
#: the body pins as the kernels take them
Pins = array_struct("Pins", PIN_FIELDS, "", __name__)


@wp.kernel
def _reaction(
    pins: Pins,
    force: wp.array(dtype=vec3),
    particles: Particles,
    gravity: vec3,
    h: float_t,
    bodies: BodyArrays,
    serial: int,
):
    for k in range(wp.tid(), each_end(wp.tid(), serial, pins.particle.shape[0])):
        b = pins.body[k]
        im = bodies.inv_mass[b]
        if im == float_t(0.0):
            continue
        p = pins.particle[k]
        F = force[p] + gravity * particles.mass[p]
        r = wp.quat_rotate(bodies.orientation[b], pins.local[k])
        dv = F * (im * h)
        dw = inv_inertia_times(bodies.orientation[b], bodies.inv_inertia[b], wp.cross(r, F)) * h
        add_velocity(b, dv, dw, bodies.velocity, bodies.angular_velocity, bodies.inv_mass, serial)


@wp.kernel
def _follow(pins: Pins, bodies: BodyArrays, particles: Particles, h: float_t, serial: int):
    for k in range(wp.tid(), each_end(wp.tid(), serial, pins.particle.shape[0])):
        b = pins.body[k]
        p = pins.particle[k]
        r = wp.quat_rotate(bodies.orientation[b], pins.local[k])
        point = bodies.position[b] + r
        # the particle's velocity over this substep will be the point's: the momentum it gains, the
        # body gives (its inertia, as its weight in `_reaction`, is the body's to carry)
        im = bodies.inv_mass[b]
        if im != float_t(0.0):
            J = (particles.velocity[p] - (point - particles.position_prev[p]) / h) * particles.mass[p]
            dw = inv_inertia_times(bodies.orientation[b], bodies.inv_inertia[b], wp.cross(r, J))
            add_velocity(b, J * im, dw, bodies.velocity, bodies.angular_velocity, bodies.inv_mass, serial)
        particles.position[p] = point
        particles.pin_target[p] = point


@wp.kernel
def _sum_pin_load(
    pins: wp.array(dtype=wp.int32),
    force: wp.array(dtype=vec3),
    particles: Particles,
    gravity: vec3,
    h: float_t,
    total: wp.array(dtype=vec3),
    serial: int,
):
    for k in range(wp.tid(), each_end(wp.tid(), serial, pins.shape[0])):
        p = pins[k]
        wp.atomic_add(total, 0, (force[p] + gravity * particles.mass[p]) * h)


def sum_pin_load(pins, force, particles: Particles, gravity, total, h, *, cache: LaunchCache | None = None) -> None:
    """Add to total[0] the impulse over h of a force on every pinned particle, plus its weight.

    Args:
        pins: the pinned particles, shape (k,) int32.
        force: per-particle force [N], shape (P,) vec3 (springs and air; or a pull in kg m with
            h the inverse substep and zero gravity).
        particles: the particle arrays (reads `mass` [kg]).
        gravity: [m/s^2], shape (3,).
        total: accumulator [N s], shape (1,) vec3.
        h: substep [s].
    """
    if pins.shape[0]:
        launch_each(
            _sum_pin_load, pins.shape[0], [pins, force, particles, vector(gravity), float(h), total], pins.device, cache
        )


class BodyPins:
    """Particles pinned to points of bodies (rows of the world's body arrays).

    Attributes:
        count: the number of pins.
        particle, body, local: the arrays of `PIN_FIELDS`, at least one row (the first `count` are pins).
    """

    # the pin arrays as the kernels take them (`_struct`), built on first use and again when the arrays
    # change; a class default, so that pins restored from a snapshot older than it have it too
    _pins: tuple | None = None

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

    def _struct(self) -> Pins:
        """The pin arrays as the kernels take them, built again only when the arrays were."""
        self._pins = cached_struct(Pins, vars(self), "", self._pins)
        return self._pins[0]

    def _body_struct(self, bodies) -> BodyArrays:
        """The body arrays as the kernels take them, built again only when the arrays were."""
        self._bodies = body_arrays(bodies, self._bodies)
        return self._bodies[0]

    def _react(self, force: wp.array, particles: Particles, bodies, gravity: tuple[float, ...], h: float) -> None:
        """`force` on the pin particles, plus `gravity` times their mass, acts on the bodies for `h` seconds."""
        if self.count == 0:
            return
        inputs = [self._struct(), force, particles, gravity, h, self._body_struct(bodies)]
        launch_each(_reaction, self.count, inputs, self.device)

    def react(self, particles: Particles, bodies, gravity, h: float) -> None:
        """The cloth's pull on the pins (and their weight) acts on the bodies for `h` seconds."""
        self._react(particles.force, particles, bodies, vector(gravity), h)

    def react_constraints(self, particles: Particles, bodies, h: float) -> None:
        """The stretch limit's and tethers' pull on the pins this substep (`particle_pin_load`,
        lambda u [kg m]) acts on their bodies as the impulse lambda u / h."""
        self._react(particles.pin_load, particles, bodies, (0.0, 0.0, 0.0), 1.0 / h)

    def follow(self, particles: Particles, bodies, h: float) -> None:
        """Put the pinned particles (and their targets) on their body points, at the end of a cloth
        substep of `h` seconds; the momentum that takes from each particle's last velocity to the
        point's over the substep is taken from its body."""
        if self.count == 0:
            return
        launch_each(_follow, self.count, [self._struct(), self._body_struct(bodies), particles, h], self.device)
