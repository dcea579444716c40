"""Cloth pinned to bodies: pins that follow a body's motion, and pull on it (two-way).

Reads body poses and the cloth's forces on its pinned particles; writes those particles'
positions, velocities and pin targets, and body velocities. Costs O(body pins) per cloth substep.

A body pin is a pinned particle (inverse mass 0) with a point fixed in a body's frame: it rides
on the body, so the body carries its weight and its inertia. Each cloth substep:
- reaction (after the spring and air forces are summed, and again after the stretch limit):
  the force F the cloth exerts on the pin, plus the pin particle's own weight m g, acts on the
  body for the cloth substep: v += F h / m, w += I^-1 (r x F) h (as the cloth's contacts push
  bodies); the stretch limit's pull on the pin acts as its impulse;
- follow (after integration): the particle is put on the body point x_b + R_b r (its target too);
- weld (at the end, before the velocities from positions): each body and the pins on it take
  the one rigid motion (v, w) that has their linear momentum and their angular momentum about
  the body's centre (the pins' at their velocities u_i, as the last weld left them): a 6 x 6
  solve (3 x 3 once the linear part is eliminated), whose (v, w) the body keeps; then the pins
  take their points' velocities v + w x r_i (`ride`).
So the pins' weight, the cloth's pull and whatever the body met in between (contacts, joints,
its own weight) are shared by body and pins as by one rigid body, and momentum is kept to
rounding (p = p0 + (m_body + m_cloth) g t for a bar carrying a cloth in free fall). Handing
each pin's momentum change to the body one substep late instead (as before the weld)
multiplied every velocity error by -m_pins / m_body a substep (about a thin rod's own axis,
-I_pins / I_rod): a 1 kg curtain hung 0.1 m below the axis of a 0.5 kg hinged rod flew off.
The stretch limit's and tethers' pull is not explicit: within their sweeps a pin on a free dynamic
body is a point of that body (`Carried`). A correction between a free particle and such a pin is
shared by the particle's inverse mass and the body's at the pin along the correction, 1/m +
(r x u) . I^-1 (r x u); the body's share is a pending shift and turn of the body, which every later
correction of the substep sees at all of its pins (Gauss-Seidel on the CPU); the same impulse goes
to the pin load. After the constraints the body is moved by its shift and turn (`move_bodies`), its
pins with it, and `react_constraints` hands it the impulse as a velocity change: the step a free
particle takes. A body light at its pin (a small box hung far below it, turning about its centre)
so takes its share of the correction, where the whole impulse computed as if the pin could not
move made it overshoot (such a box diverged at 0.05 and 0.2 kg). A body that its joints turn about
a pivot fixed in the world (`hold`) is turned about it, with inverse mass 0 and its inertia about the
pivot (about the pivot's axis alone, for a line). Other bodies a joint holds keep that explicit
pull: the limit cannot know what the joint lets them do.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from ..launch import LaunchCache, each_end, launch_each, vector
from ..model import body_arrays
from ..real import BodyArrays, float_t, mat33, vec3
from ..solver.joints import add_velocity
from ..solver.rigid import inv_inertia_times, inv_inertia_world
from ..structs import array_struct, cached_struct
from .arrays import Particles

if TYPE_CHECKING:
    from ..solver.joints import JointSet

# no adjoint code: nothing differentiates through Tumble's kernels, and it doubles the compile time
wp.set_module_options({"enable_backward": False})

#: the arrays of the body pins, one row per pin (`BodyPins.particle`, `.body`, `.local`)
PIN_FIELDS = {
    "particle": wp.int32,  # the pinned particle
    "body": wp.int32,  # the row of the body it follows
    "local": vec3,  # its point in the body's frame [m]
}
#: the body pins as the kernels take them
Pins = array_struct("Pins", PIN_FIELDS, "", __name__)
#: the pins grouped by body: `order` lists the pin rows body after body, `start` (one more row than
#: there are bodies) where each body's begin
PinGroups = array_struct("PinGroups", {"order": wp.int32, "start": wp.int32}, "", __name__)


@wp.struct
class Carried:
    """The pins of the stretch limit and tethers that a dynamic body carries (`BodyPins.carried`):
    their corrections move the body and its pins as one rigid body, as the weld then moves them (a
    pending shift of their centre of mass and turn about it, this substep's)."""

    count: int  # particles `pin` covers (0: no body pins, and `pin` is not read)
    pin: wp.array(dtype=wp.int32)  # per particle: its body pin's row, -1 for none
    group: wp.array(dtype=wp.int32)  # per pin: its body's group (the rows of the arrays below)
    group_body: wp.array(dtype=wp.int32)  # per group: its body's row
    order: wp.array(dtype=wp.int32)  # the pin rows group after group (`BodyPins.order`)
    start: wp.array(dtype=wp.int32)  # where each group's pins begin in `order` (one more row than groups)
    particle: wp.array(dtype=wp.int32)  # per pin: its particle
    body: wp.array(dtype=wp.int32)  # per pin: its body's row
    local: wp.array(dtype=vec3)  # per pin: its point in the body's frame [m]
    # per group, a pivot its joints hold the body about (`BodyPins.hold`): 1 if one, its point [m] and unit
    # axis (zero: a point) in the world
    pivoted: wp.array(dtype=wp.int32)
    pivot: wp.array(dtype=vec3)
    axis: wp.array(dtype=vec3)
    # per group, the body and its pins as one rigid body (`_composite`, at the substep's start): inverse mass
    # [1/kg], the point it turns about from the body's centre (world frame) [m]: its centre of mass, or
    # its pivot (inverse mass 0); world inverse inertia about that point (about a pivot's axis alone)
    inv_mass: wp.array(dtype=float_t)
    centre: wp.array(dtype=vec3)
    inv_inertia: wp.array(dtype=mat33)
    shift: wp.array(dtype=vec3)  # per group: the corrections' translation of the centre of mass so far [m]
    turn: wp.array(dtype=vec3)  # per group: their rotation about it so far [rad]
    bodies: BodyArrays


#: no body turns about a pivot (`BodyPins.hold`)
_NO_PIVOTS = (np.zeros(0, dtype=np.int32), np.zeros((0, 3)), np.zeros((0, 3)))


def no_carried_pins(device) -> Carried:
    """A `Carried` with no pins on bodies (for the stretch limit of a cloth alone)."""
    c = Carried()
    c.count = 0
    ints = wp.full(1, -1, dtype=wp.int32, device=device)
    c.pin = c.group = c.group_body = c.order = c.start = c.particle = c.body = c.pivoted = ints
    c.local = c.centre = c.shift = c.turn = c.pivot = c.axis = wp.zeros(1, dtype=vec3, device=device)
    c.inv_mass = wp.zeros(1, dtype=float_t, device=device)
    c.inv_inertia = wp.zeros(1, dtype=mat33, device=device)
    return c


@wp.func
def carried_pin(c: Carried, p: int, w: float_t):
    """Particle p's pin row if a dynamic body carries it (its inverse mass `w` is 0), else -1."""
    if w != float_t(0.0) or p >= c.count:
        return -1
    k = c.pin[p]
    if k < 0:
        return -1
    if c.bodies.inv_mass[c.body[k]] == float_t(0.0):
        return -1  # a static or kinematic body: its pins do not give way
    return k


@wp.func
def _arm(c: Carried, k: int):
    """Pin k's offset from the centre of mass of its body and pins, world frame [m]."""
    return wp.quat_rotate(c.bodies.orientation[c.body[k]], c.local[k]) - c.centre[c.group[k]]


@wp.func
def carried_position(c: Carried, k: int, x: vec3):
    """Where pin k (its particle at `x`) is with its body moved by the corrections so far."""
    g = c.group[k]
    return x + c.shift[g] + wp.cross(c.turn[g], _arm(c, k))


@wp.func
def carried_inverse_mass(c: Carried, k: int, u: vec3):
    """The inverse mass [1/kg] of pin k's body with its pins at the pin along the unit vector u:
    1/M + (r x u) . I^-1 (r x u), r from their centre of mass."""
    g = c.group[k]
    ru = wp.cross(_arm(c, k), u)
    return c.inv_mass[g] + wp.dot(ru, c.inv_inertia[g] * ru)


@wp.func
def carry(c: Carried, k: int, impulse: vec3):
    """Pin k's body with its pins takes the position-level impulse J [kg m] at the pin: shift += J / M,
    turn += I^-1 (r x J)."""
    g = c.group[k]
    wp.atomic_add(c.shift, g, impulse * c.inv_mass[g])
    wp.atomic_add(c.turn, g, c.inv_inertia[g] * wp.cross(_arm(c, k), impulse))


@wp.kernel
def _composite(c: Carried, particles: Particles, serial: int):
    # one thread a body with pins: it and its pins as one rigid body (as `_weld` moves them), no correction yet
    for g in range(wp.tid(), each_end(wp.tid(), serial, c.shift.shape[0])):
        c.shift[g] = vec3()
        c.turn[g] = vec3()
        b = c.group_body[g]
        im = c.bodies.inv_mass[b]
        if im == float_t(0.0):
            continue  # a static or kinematic body: its pins are not carried
        q = c.bodies.orientation[b]
        eye = wp.identity(n=3, dtype=float_t)
        total = float_t(1.0) / im
        s = vec3()  # first moment of the pins about the body's centre
        for e in range(c.start[g], c.start[g + 1]):
            k = c.order[e]
            m = particles.mass[c.particle[k]]
            total += m
            s += wp.quat_rotate(q, c.local[k]) * m
        # the point they turn about: their centre of mass, or the pivot their joints hold them at
        centre = s / total
        c.inv_mass[g] = float_t(1.0) / total
        if c.pivoted[g] != 0:
            centre = c.pivot[g] - c.bodies.position[b]
            c.inv_mass[g] = float_t(0.0)
        # X: what the body's own inertia lacks about that point, its mass at -centre and the pins';
        # I^-1 = (I_b + X)^-1 = (1 + W X)^-1 W with W = I_b^-1, which holds where W has no inverse (as `_weld`)
        X = (eye * wp.dot(centre, centre) - wp.outer(centre, centre)) / im
        for e in range(c.start[g], c.start[g + 1]):
            k = c.order[e]
            r = wp.quat_rotate(q, c.local[k]) - centre
            X += (eye * wp.dot(r, r) - wp.outer(r, r)) * particles.mass[c.particle[k]]
        W = inv_inertia_world(q, c.bodies.inv_inertia[b])
        inv_inertia = wp.inverse(eye + W * X) * W
        a = c.axis[g]
        if c.pivoted[g] != 0 and wp.length_sq(a) > float_t(0.0):
            # about the pivot's axis alone: a a^T / (a . I a), with a . I_b a from the body's principal moments
            # (a locked one, inverse moment 0, holds the axis still)
            ab = wp.quat_rotate_inv(q, a)
            inv_i = c.bodies.inv_inertia[b]
            locked = int(0)
            moment = wp.dot(a, X * a)
            for i in range(3):
                if inv_i[i] > float_t(0.0):
                    moment += ab[i] * ab[i] / inv_i[i]
                elif ab[i] != float_t(0.0):
                    locked = 1
            inv_inertia = mat33()
            if locked == 0 and moment > float_t(0.0):
                inv_inertia = wp.outer(a, a) / moment
        c.centre[g] = centre
        c.inv_inertia[g] = inv_inertia


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
def _move_bodies(c: Carried, serial: int):
    # one thread a body with pins: the shift and the turn its pins' corrections gave it with its pins
    for g in range(wp.tid(), each_end(wp.tid(), serial, c.shift.shape[0])):
        b = c.group_body[g]
        dtheta = c.turn[g]
        if wp.length_sq(c.shift[g]) == float_t(0.0) and wp.length_sq(dtheta) == float_t(0.0):
            continue  # no correction moved it (a static or kinematic body, or one joints hold: its pins stayed put)
        # the body's centre, at -centre from the centre of mass, moves with the turn about it
        dx = c.shift[g] - wp.cross(dtheta, c.centre[g])
        c.bodies.position[b] = c.bodies.position[b] + dx
        c.bodies.delta_position[b] = c.bodies.delta_position[b] + dx
        c.bodies.delta_rotation[b] = c.bodies.delta_rotation[b] + dtheta
        angle = wp.length(dtheta)
        if angle > float_t(0.0):
            turn = wp.quat_from_axis_angle(dtheta / angle, angle)
            c.bodies.orientation[b] = wp.normalize(turn * c.bodies.orientation[b])


@wp.kernel
def _follow(pins: Pins, bodies: BodyArrays, particles: Particles, serial: int):
    for k in range(wp.tid(), each_end(wp.tid(), serial, pins.particle.shape[0])):
        b = pins.body[k]
        p = pins.particle[k]
        point = bodies.position[b] + wp.quat_rotate(bodies.orientation[b], pins.local[k])
        particles.position[p] = point
        particles.pin_target[p] = point


@wp.kernel
def _weld(pins: Pins, groups: PinGroups, bodies: BodyArrays, particles: Particles, serial: int):
    # one thread a body: its pins are groups.order[groups.start[g]:groups.start[g + 1]]
    for g in range(wp.tid(), each_end(wp.tid(), serial, groups.start.shape[0] - 1)):
        first = groups.start[g]
        last = groups.start[g + 1]
        b = pins.body[groups.order[first]]
        im = bodies.inv_mass[b]
        if im == float_t(0.0):
            continue  # a static or kinematic body: its pins move with it, it does not feel them
        q = bodies.orientation[b]
        eye = wp.identity(n=3, dtype=float_t)
        # the pins' mass M, first moment s, inertia about the body's centre Ip, momentum P and
        # angular momentum Lp about the centre
        M = float_t(0.0)
        s = vec3()
        P = vec3()
        Lp = vec3()
        Ip = mat33()
        for e in range(first, last):
            k = groups.order[e]
            p = pins.particle[k]
            m = particles.mass[p]
            r = wp.quat_rotate(q, pins.local[k])
            u = particles.velocity[p]
            M += m
            s += r * m
            P += u * m
            Lp += wp.cross(r, u) * m
            Ip += (eye * wp.dot(r, r) - wp.outer(r, r)) * m
        total = float_t(1.0) / im + M
        P0 = bodies.velocity[b] / im + P  # the linear momentum of body and pins
        # with v = (P0 + s x w) / total, the angular momentum I w_b + Lp about the centre gives
        # (I + Ip - (|s|^2 - s s^T) / total) w = I w_b + Lp - s x P0 / total; times I^-1:
        W = inv_inertia_world(q, bodies.inv_inertia[b])
        X = Ip - (eye * wp.dot(s, s) - wp.outer(s, s)) / total
        w = wp.inverse(eye + W * X) * (bodies.angular_velocity[b] + W * (Lp - wp.cross(s, P0) / total))
        v = (P0 + wp.cross(s, w)) / total
        bodies.velocity[b] = v
        bodies.angular_velocity[b] = w


@wp.kernel
def _ride(pins: Pins, bodies: BodyArrays, particles: Particles, serial: int):
    for k in range(wp.tid(), each_end(wp.tid(), serial, pins.particle.shape[0])):
        b = pins.body[k]
        r = wp.quat_rotate(bodies.orientation[b], pins.local[k])
        particles.velocity[pins.particle[k]] = bodies.velocity[b] + wp.cross(bodies.angular_velocity[b], r)


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


def pinned_rows(count: int, pin_particle: np.ndarray, pin_body: np.ndarray) -> np.ndarray:
    """Per particle of `count`, the body row it is pinned to, (count,) int32, -1 for none (`pin_particle`,
    `pin_body`: the body pins' particles and body rows, (k,) each)."""
    pinned = np.full(count, -1, dtype=np.int32)
    pinned[pin_particle] = pin_body
    return pinned


def shielded_bodies(pinned: np.ndarray, limited: np.ndarray) -> np.ndarray:
    """Per particle, the body row whose contacts it skips, (count,) int32, -1 for none.

    A body pin holds its particle on (or in) its body, and the stretch limit holds the particle's
    grid neighbours within a structural spring of it: pushed out of that body they would fight the pin
    every substep, which made a sphere hung from a cloth's corner diverge (the triangles round the
    pin cannot leave a sphere whose centre holds it) and a box pinned by the middle of its top
    face gain joules. So a pinned particle and the particles one structural spring from it do not
    touch the pin's body (as bodies joined by a joint do not collide); every other particle does.

    Args:
        pinned: per particle, the body row it is pinned to, -1 for none (`pinned_rows`), (count,).
        limited: the structural springs' particles, (s, 2).
    """
    shield = np.full(len(pinned), -1, dtype=np.int32)
    for end in (0, 1):
        a, other = limited[:, end], limited[:, 1 - end]
        shield[other[pinned[a] >= 0]] = pinned[a[pinned[a] >= 0]]
    at_pin = pinned >= 0
    shield[at_pin] = pinned[at_pin]
    return shield


def _by_body(body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pins grouped by body, groups in the order of their body rows: (order, start), the pin rows
    group after group and where each group begins (one more entry than groups)."""
    order = np.argsort(body, kind="stable")
    rows = body[order]
    start = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]]) if len(order) else np.zeros(0, np.int64)
    return order, np.r_[start, len(order)]


class BodyPins:
    """Particles pinned to points of bodies (rows of the world's body arrays).

    Attributes:
        count: the number of pins.
        particle, body, local: the arrays of `PIN_FIELDS`, at least one row (the first `count` are pins).
    """

    # the pin arrays as the kernels take them (`_struct`), built on first use and again when the arrays
    # change; a class default, so that pins restored from a snapshot older than it have it too
    _pins: tuple | None = None
    # the pins grouped by body (`PinGroups`), made with the arrays; None in pins restored from an older
    # snapshot, made on first use
    order: wp.array | None = None
    start: wp.array | None = None
    _groups: tuple | None = None
    # per particle, the body row it does not touch, and the pins it was made from (`shielded`); left out of
    # snapshots (`snapshot.py`), made again from the pins
    _shield: tuple | None = None
    # the pins as the stretch limit and tethers take them (`carried`): (struct, key, its arrays); left out
    # of snapshots, made again from the pins
    _carry: tuple | None = None
    # of the bodies with pins, those joints hold this step and the limit leaves to them (`hold`), and those
    # it turns about a pivot: (rows, points, axes); set every step
    _held: np.ndarray = np.zeros(0, dtype=np.int32)
    _pivots: tuple = (np.zeros(0, dtype=np.int32), np.zeros((0, 3)), np.zeros((0, 3)))
    SNAPSHOT_CACHES = frozenset({"_shield", "_carry", "_held", "_pivots"})

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
        self._group()

    def _group(self) -> None:
        """The pins grouped by body (`order`, `start`), from the host arrays."""
        order, start = _by_body(self._body)
        self.order = wp.array(order.astype(np.int32), dtype=wp.int32, device=self.device)
        self.start = wp.array(start.astype(np.int32), dtype=wp.int32, device=self.device)

    def shielded(self, count: int, structural) -> tuple[wp.array, wp.array]:
        """Per particle of `count`: the body row it does not touch (`shielded_bodies`, from the structural
        springs' particles (s, 2) `structural`) and the body row it is pinned to (`pinned_rows`), (count,)
        int32 each, -1 for none; both empty without pins. Made again only when the pins, their body rows
        or the particle count changed."""
        key = (count, self._particle.tobytes(), self._body.tobytes())
        if self._shield is None or self._shield[1] != key:
            shield = pinned = np.zeros(0, dtype=np.int32)
            if self.count:
                pinned = pinned_rows(count, self._particle, self._body)
                shield = shielded_bodies(pinned, structural)
            arrays: tuple[wp.array, wp.array] = (
                wp.array(shield, dtype=wp.int32, device=self.device),
                wp.array(pinned, dtype=wp.int32, device=self.device),
            )
            self._shield = (arrays, key)
        return self._shield[0]

    def hold(self, joints: JointSet | None) -> None:
        """Once a step: which bodies with pins the world's `joints` hold (`JointSet.held_bodies`), and of
        them which turn about a point or a line fixed in the world (`JointSet.pivots`). The stretch limit
        turns a pivoted body about its pivot; the pins of the other held bodies stay put in it, and it hands
        them its pull as an impulse, as it cannot know what their joints let them do (moved as if free, a
        hinged rod was pulled off its hinge by up to 3 cm)."""
        self._held, self._pivots = np.zeros(0, dtype=np.int32), _NO_PIVOTS
        if joints is None or joints.count == 0 or self.count == 0:
            return
        held = np.intersect1d(joints.held_bodies(), self._body).astype(np.int32)
        self._pivots = joints.pivots(held)
        self._held = np.setdiff1d(held, self._pivots[0]).astype(np.int32)

    def carried(self, count: int, bodies) -> Carried:
        """The pins as the stretch limit and tethers take them (`Carried`), for `count` particles and the
        world's body rows `bodies`, but for those on bodies joints hold (`hold`); made again only when the
        pins, the particle count, the held bodies or the body arrays changed. Its shifts and turns are
        this substep's (`begin_constraints` clears them)."""
        if self.count == 0:  # a cloth without body pins: nothing to look up in every sweep
            if self._carry is None or self._carry[1] is not None:
                self._carry = (no_carried_pins(self.device), None, ())
            return self._carry[0]
        pivot_rows, pivot_points, pivot_axes = self._pivots
        body_struct = self._body_struct(bodies)
        if self.start is None:
            self._group()
        key = (
            count,
            self._particle.tobytes(),
            self._body.tobytes(),
            self._held.tobytes(),
            *(a.tobytes() for a in self._pivots),
        )
        arrays = (self.particle, self.body, self.local, self.order, self.start, body_struct)
        cached = self._carry
        if cached is None or cached[1] != key or any(a is not b for a, b in zip(cached[2], arrays, strict=True)):
            c = Carried()
            c.count = count
            pin = np.full(max(1, count), -1, dtype=np.int32)
            free = ~np.isin(self._body, self._held)
            pin[self._particle[free]] = np.flatnonzero(free).astype(np.int32)
            # the groups of `order` and `start` (`_group`), which `_composite` walks
            order, start = _by_body(self._body)
            groups = len(start) - 1
            bodies_of = self._body[order[start[:-1]]]
            group = np.empty(self.count, dtype=np.int32)
            group[order] = np.repeat(np.arange(groups, dtype=np.int32), np.diff(start))
            c.pin = wp.array(pin, dtype=wp.int32, device=self.device)
            c.group = wp.array(group, dtype=wp.int32, device=self.device)
            c.group_body = wp.array(bodies_of.astype(np.int32), dtype=wp.int32, device=self.device)
            at = np.searchsorted(bodies_of, pivot_rows)
            mine = (at < groups) & (bodies_of[np.minimum(at, groups - 1)] == pivot_rows)
            pivoted = np.zeros(groups, dtype=np.int32)
            pivot, axis = np.zeros((groups, 3)), np.zeros((groups, 3))
            pivoted[at[mine]], pivot[at[mine]], axis[at[mine]] = 1, pivot_points[mine], pivot_axes[mine]
            c.pivoted = wp.array(pivoted, dtype=wp.int32, device=self.device)
            c.pivot = wp.array(pivot, dtype=vec3, device=self.device)
            c.axis = wp.array(axis, dtype=vec3, device=self.device)
            c.particle, c.body, c.local, c.order, c.start = self.particle, self.body, self.local, self.order, self.start
            c.inv_mass = wp.zeros(groups, dtype=float_t, device=self.device)
            c.inv_inertia = wp.zeros(groups, dtype=mat33, device=self.device)
            c.centre = wp.zeros(groups, dtype=vec3, device=self.device)
            c.shift = wp.zeros(groups, dtype=vec3, device=self.device)
            c.turn = wp.zeros(groups, dtype=vec3, device=self.device)
            c.bodies = body_struct
            cached = self._carry = (c, key, arrays)
        return cached[0]

    def begin_constraints(self, particles: Particles, count: int, bodies) -> Carried:
        """The `carried` pins with no correction yet, each body with its pins (their masses from
        `particles`) as one rigid body: once a cloth substep, before its stretch limit."""
        c = self.carried(count, bodies)
        if self.count:
            launch_each(_composite, c.shift.shape[0], [c, particles], self.device)
        return c

    def move_bodies(self, carried: Carried, bodies) -> None:
        """Move each dynamic body carrying pins by its corrections of this substep (`carried`'s shift and
        turn), as the stretch limit moved the particles, and put its pins on it again: a body's position
        is then where its velocity change (`react_constraints`) says, as a free particle's is."""
        if self.count == 0:
            return
        launch_each(_move_bodies, carried.shift.shape[0], [carried], self.device)

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

    def follow(self, particles: Particles, bodies) -> None:
        """Put the pinned particles (and their targets) on their body points."""
        if self.count == 0:
            return
        launch_each(_follow, self.count, [self._struct(), self._body_struct(bodies), particles], self.device)

    def weld(self, particles: Particles, bodies) -> None:
        """Give every dynamic body with pins the rigid motion that it and its pins (at their velocities, as the
        last `ride` left them or as given) have together: their momentum and angular momentum."""
        if self.count == 0:
            return
        if self.start is None:
            self._group()
        assert self.order is not None and self.start is not None
        self._groups = cached_struct(PinGroups, {"order": self.order, "start": self.start}, "", self._groups)
        inputs = [self._struct(), self._groups[0], self._body_struct(bodies), particles]
        launch_each(_weld, self.start.shape[0] - 1, inputs, self.device)

    def ride(self, particles: Particles, bodies) -> None:
        """Set the pinned particles' velocities to their body points' (after the velocities from positions)."""
        if self.count == 0:
            return
        launch_each(_ride, self.count, [self._struct(), self._body_struct(bodies), particles], self.device)
