"""Cloth collisions: particles against the world's bodies (two-way) and against each other.

Stages:

- `candidate_bodies` (host, once per world step) keeps only the bodies whose bounding sphere,
  or plane, comes within reach of the cloth's bounding box this step, so a cloth next to a
  pile of 10,000 spheres does not test every particle against every sphere. Cost O(bodies).
- `collide_bodies` (one thread per particle, looping over the candidates) pushes particles
  that are closer than their thickness to a plane, sphere, box, capsule, convex hull or static
  mesh surface back out (hulls through the narrow phase's `hull_closest`, meshes through their
  BVH, one-sided), applies
  Coulomb friction on the tangential motion of the substep, and gives dynamic bodies the
  equal and opposite impulse on their velocity and angular velocity. Cost O(P x candidates).
- `catch_small_spheres` (one thread per triangle) does the same for spheres small enough to
  pass between particles, against the closest point of each triangle. Cost O(T x candidates).
- `SelfCollisionGrid.find_pairs` (once per world step) sorts particles into the counting-sort
  spatial hash shared with the bodies' broad phase (`collision/hashgrid.py`) and lists the particle pairs closer than their thickness plus a margin, except
  near neighbours on the same grid (|di| <= 2 and |dj| <= 2), which are held by springs.
  Cost O(P). `SelfCollisionGrid.separate` (every substep) pushes listed pairs closer than
  their thickness apart; cost O(pairs), small unless the cloth is folded. For cloth that does
  not pass through itself, choose a thickness close to the grid spacing: particles farther
  apart than the thickness can slip between each other.

The kernels take the particle arrays as one struct (`arrays.Particles`) and the bodies near the
cloth, with the pass's settings, as another (`Near`, from `near_bodies`); "one thread per
particle" is the CUDA launch: on the CPU one thread loops over the particles (triangles, pairs)
in index order (`launch.launch_each`), which is the order Warp runs a launch's threads in there.

Contacts are resolved on positions, as in position-based dynamics (Mueller et al. 2007), with
inverse-mass weighting: for penetration depth d along normal n, with particle and body inverse
masses w_p and w_b (w_b = 1/m + (r x n) . I^-1 (r x n) at the contact point), the particle
moves by lambda w_p n with lambda = d / (w_p + c w_b) and the body receives the impulse
-lambda n / h. c is the number of particles that touched this body in the previous pass
("mass splitting"), so that many particles pressing on one light body do not overshoot; at a
body's first touch it is the particles within their thickness of it now, whose pushes are then
applied together when the pass ends (`count_first_touches`, `apply_pushes`).
With `strict` (`ClothSystem.strict_limit`) a particle moves at most its slack along n, the
distance before one of its limited springs or tethers reaches its limit, and the body takes the
rest: lambda_b = (d - slack) / (c w_b).

Where the particle gives way less than its own mass asks (its tethers near their limit, or the
strict slack), the body's push lambda_b n exceeds the particle's momentum change m_p dx: the
difference is held by the taut cloth and goes on to the pins of the particle's tethers that the
push lengthens (`particle_pin_load`, as the stretch limit's pull does), so that a body resting on
pinned cloth hangs its weight on the pins and momentum is kept.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..collision.hashgrid import Grid, HashGrid, cell_hash, cell_of
from ..collision.hulls import Hulls
from ..collision.meshes import Meshes, edge_table
from ..collision.narrowphase import box_closest, hull_closest, segment_closest
from ..launch import LaunchCache, each_end, launch_each
from ..real import BodyArrays, float_t, quat, vec3
from ..shapes import ShapeType
from ..solver.rigid import inv_inertia_times
from ..structs import cached_struct
from .arrays import Limits, Particles, Tethers, corners
from .attach import Carried, carried_inverse_mass, carried_pin

# no adjoint code: nothing differentiates through Tumble's kernels, and it doubles the compile time
wp.set_module_options({"enable_backward": False})

PLANE = wp.constant(int(ShapeType.PLANE))
SPHERE = wp.constant(int(ShapeType.SPHERE))
BOX = wp.constant(int(ShapeType.BOX))
CAPSULE = wp.constant(int(ShapeType.CAPSULE))
CONVEX = wp.constant(int(ShapeType.CONVEX))
MESH = wp.constant(int(ShapeType.MESH))
#: most a particle moves in one triangle or edge contact, in units of the contact's depth: pushed at a
#: point by its particles' weights (barycentric weight times inverse mass), each moves in proportion to its
#: weight, which for a point near a particle that cannot move (a pin, a taut tether) is the depth over a
#: tiny weight; a kinematic sphere between a pin and a free particle threw that particle 15 m. Where
#: every particle gives way the most is 1.37 x depth, so the cap leaves those contacts as they were
LEVER_LIMIT = wp.constant(float_t(2.0))


@wp.struct
class Near:
    """The bodies the cloth may touch this step, as its contact kernels take them (`near_bodies`)."""

    bodies: BodyArrays  # the world's body arrays (dynamic bodies get the cloth's pushes)
    hulls: Hulls  # the world's convex hulls
    meshes: Meshes  # the world's static meshes
    candidates: wp.array(dtype=wp.int32)  # the body rows that can reach the cloth this step
    contacts_prev: wp.array(dtype=wp.int32)  # per body row: the particles that touched it in the last pass
    contacts_next: wp.array(dtype=wp.int32)  # per body row: this pass's count (zeroed before the pass)
    h: float_t  # the substep [s]
    taut: float_t  # a tether holds its particle from taut x its limit on (`collide_bodies`)
    strict: int  # 1: particles give way only within their slack (`collide_bodies`)
    # per body row: the pushes of this pass, applied together after it (`apply_pushes`): position and
    # rotation [m, rad], velocity and angular velocity [m/s, rad/s]
    push_position: wp.array(dtype=vec3)
    push_rotation: wp.array(dtype=vec3)
    push_velocity: wp.array(dtype=vec3)
    push_spin: wp.array(dtype=vec3)
    # per body row: the particles on it at the substep's start if none touched it in the last pass (a first
    # touch, `count_first_touches`), else 0: such a body's pushes wait for the pass's end (`_push_later`)
    fresh: wp.array(dtype=wp.int32)
    # per particle: the body row it does not touch (-1: none; empty: no body pins): its pin's, or that
    # of a pin one structural spring away (`attach.shielded_bodies`)
    shield: wp.array(dtype=wp.int32)
    # per particle: the body row it is pinned to (-1: none; empty: no body pins)
    pinned: wp.array(dtype=wp.int32)


@wp.func
def _shielded(near: Near, p: int, b: int):
    """Whether particle p skips body row b: it is pinned to b, or next to a particle pinned to b."""
    return near.shield.shape[0] > 0 and near.shield[p] == b


@wp.func
def _pinned_to(near: Near, pin: int, b: int):
    """Whether particle `pin` is pinned to body row b."""
    return near.pinned.shape[0] > 0 and near.pinned[pin] == b


@wp.func
def _holding(near: Near, carried: Carried, particles: Particles, pin: int, b: int, w_b: float_t, n: vec3):
    """Whether a taut tether to particle `pin` holds its particle against the push along n of body row b,
    whose inverse mass at the contact is w_b: `pin` is pinned, and not to a body that the stretch limit
    moves (`carried_pin`: a free dynamic body, or one turned about a pivot) and that is lighter at the
    pin along n than b is at the contact (`carried_inverse_mass`, about the pivot for a pivoted one).
    Such a body gives way with its pins, and the stretch limit then pulls it along by its own inverse
    mass. (Held fast, a heavy box's push on cloth tethered to a light capsule's pins went to the capsule
    whole, as an impulse: 700 times the box's mass, it spun up to 7,000 rad/s in one step.) A fixed pin
    holds, as do a pin on a body that other joints hold (they take the load), on a heavier one, and on
    b itself (b cannot push its own cloth away from itself, `_route_to_pins`)."""
    if particles.inv_mass[pin] > float_t(0.0):
        return False
    if _pinned_to(near, pin, b):
        return True
    k = carried_pin(carried, pin, float_t(0.0))
    if k < 0:
        return True
    return carried_inverse_mass(carried, k, n) <= w_b


@wp.func
def _give_way(
    p: int,
    xp: vec3,
    n: vec3,
    w_p: float_t,
    particles: Particles,
    tethers: Tethers,
    near: Near,
    carried: Carried,
    b: int,
    w_b: float_t,
):
    """Inverse mass with which particle p at xp yields to body row b's push along n: less the tauter its tethers.

    A tether that the push would stretch holds its particle (`_holding`): free below taut x its
    limit, fixed at the limit, linear in between (a sudden switch made bodies resting on cloth chatter).
    """
    w = w_p
    t = particles.tether_first[p]
    t_end = t + particles.tether_count[p]
    while t < t_end:
        pin = tethers.pin[t]
        arm = xp - particles.position[pin]
        if wp.dot(arm, n) > float_t(0.0) and _holding(near, carried, particles, pin, b, w_b, n):
            lim = tethers.limit[t]
            slack = (lim - wp.length(arm)) / (lim * (float_t(1.0) - near.taut))
            w = wp.min(w, w_p * wp.clamp(slack, float_t(0.0), float_t(1.0)))
        t += 1
    return w


@wp.func
def _tether_hold(
    t: int,
    xp: vec3,
    u: vec3,
    particles: Particles,
    tethers: Tethers,
    near: Near,
    carried: Carried,
    b: int,
    w_b: float_t,
):
    """How tether t of a particle at xp resists body row b's push along u: (pull, tight), pull = cos of the
    angle between u and the tether (0 when the push does not lengthen it or it does not hold the particle,
    `_holding`) and tight its tautness, 0 below taut x its limit, 1 at the limit (the `_give_way` ramp)."""
    zero = float_t(0.0)
    pull = zero
    tight = zero
    pin = tethers.pin[t]
    taut = near.taut
    if _holding(near, carried, particles, pin, b, w_b, u):
        arm = xp - particles.position[pin]
        length = wp.length(arm)
        if length > float_t(1.0e-12):
            pull = wp.max(wp.dot(arm, u) / length, zero)
            lim = tethers.limit[t]
            tight = float_t(1.0) - wp.clamp((lim - length) / (lim * (float_t(1.0) - taut)), zero, float_t(1.0))
    return pull, tight


@wp.func
def _route_to_pins(
    p: int,
    xp: vec3,
    held: vec3,
    particles: Particles,
    tethers: Tethers,
    near: Near,
    carried: Carried,
    b: int,
    w_b: float_t,
):
    """A push `held` [kg m] of body row b on particle p that the cloth took without moving p (its tethers
    or limited springs held it) goes on to the pins that hold it: shared among p's tethers that the push
    lengthens, each in proportion to its tautness (as `_give_way` ramps it) and to how straight the
    push pulls on it; by pull alone when none is near its limit. The pins' loads then sum to
    `held`, so the body's push ends on the pins (`particles.pin_load`) and momentum is kept.

    Returns the part of `held` that fell on pins of b itself, which is not passed on: the caller takes it
    off b's push instead, since a body cannot push on itself through its own cloth (passed on to its
    pins, the push and its return acted at different points of b and turned it).
    """
    own = vec3()
    size = wp.length(held)
    if size <= float_t(0.0):
        return own
    u = held / size
    zero = float_t(0.0)
    total = zero
    along = zero
    t0 = particles.tether_first[p]
    t_end = t0 + particles.tether_count[p]
    for t in range(t0, t_end):
        pull, tight = _tether_hold(t, xp, u, particles, tethers, near, carried, b, w_b)
        total += pull * tight
        along += pull
    if along <= zero:
        return own
    for t in range(t0, t_end):
        pull, tight = _tether_hold(t, xp, u, particles, tethers, near, carried, b, w_b)
        share = pull / along
        if total > zero:
            share = pull * tight / total
        if share > zero:
            pin = tethers.pin[t]
            if _pinned_to(near, pin, b):
                own += held * share
            else:
                wp.atomic_add(particles.pin_load, pin, held * share)
    return own


@wp.func
def _coulomb(
    dx: vec3,
    n: vec3,
    r_b: vec3,
    w_point: float_t,
    w_lin: float_t,
    split: float_t,
    mu: float_t,
    lam: float_t,
    q: quat,
    inv_i: vec3,
):
    """Friction against a cloth point's tangential motion dx relative to the body surface this substep.

    Returns the direction of that motion and the size lambda_t of the friction displacement:
    all of it if a static-friction impulse <= mu lambda can stop it, else mu lambda. The cloth
    point moves by -lambda_t w_point along the direction and the body receives +lambda_t.
    """
    dxt = dx - n * wp.dot(dx, n)
    slip = wp.length(dxt)
    tdir = vec3(float_t(0.0), float_t(0.0), float_t(0.0))
    lam_t = float_t(0.0)
    if slip > float_t(1.0e-14) and mu > float_t(0.0):
        tdir = dxt / slip
        rt = wp.cross(r_b, tdir)
        w_bt = w_lin + wp.dot(rt, inv_inertia_times(q, inv_i, rt))
        if w_point + split * w_bt > float_t(0.0):
            lam_t = wp.min(slip / (w_point + split * w_bt), mu * lam)
    return tdir, lam_t


@wp.func
def _move_body(bodies: BodyArrays, b: int, q: quat, dx_b: vec3, dtheta: vec3, dv: vec3, dw: vec3):
    """Body row b moves by dx_b, turns by dtheta from orientation q, and its velocities change by dv, dw."""
    wp.atomic_add(bodies.position, b, dx_b)
    wp.atomic_add(bodies.velocity, b, dv)
    # q' = q + 1/2 (dtheta, 0) q (small angle; the rigid integrator renormalises), else the
    # rotational part of the overlap is never undone
    wp.atomic_add(bodies.orientation, b, float_t(0.5) * (quat(dtheta[0], dtheta[1], dtheta[2], float_t(0.0)) * q))
    wp.atomic_add(bodies.angular_velocity, b, dw)
    # the rigid contact solver tracks each body's motion over the step
    wp.atomic_add(bodies.delta_position, b, dx_b)
    wp.atomic_add(bodies.delta_rotation, b, dtheta)


@wp.func
def _push_parts(impulse: vec3, still: float_t, r_b: vec3, q: quat, inv_i: vec3, w_lin: float_t, h: float_t):
    """What `impulse` (a displacement times mass) at r_b from a body's centre does to it: its move, its turn,
    and its velocity changes, those for all but the fraction `still` (see `_push_body`)."""
    dx_b = impulse * w_lin
    dtheta = inv_inertia_times(q, inv_i, wp.cross(r_b, impulse))
    moving = float_t(1.0) - still
    return dx_b, dtheta, dx_b * moving / h, dtheta * moving / h


@wp.func
def _push_body(
    b: int,
    impulse: vec3,
    still: float_t,
    r_b: vec3,
    q: quat,
    inv_i: vec3,
    w_lin: float_t,
    h: float_t,
    bodies: BodyArrays,
):
    """Two-way coupling: a dynamic body gets `impulse` (a displacement times mass) at r_b from its centre.

    As in position-based dynamics it moves and turns by it, and its velocities change by it / h
    (so that cloth held by its stretch limit can hold the body up instead of the two trading
    ever larger pushes over the substeps), but for the fraction `still` of it, which only moves it
    (the part that undoes an overlap the contact began the substep in, `_collide_bodies`).
    """
    if w_lin > float_t(0.0):
        dx_b, dtheta, dv, dw = _push_parts(impulse, still, r_b, q, inv_i, w_lin, h)
        _move_body(bodies, b, q, dx_b, dtheta, dv, dw)


@wp.func
def _first_touch(near: Near, b: int):
    """Whether this pass is body row b's first touch: no particle touched it in the last pass, and some are on
    it now (`count_first_touches`). Its pushes then share `near.fresh[b]` and wait for the pass's end."""
    return near.contacts_prev[b] == 0 and near.fresh[b] > 0


@wp.func
def _push_later(b: int, impulse: vec3, still: float_t, r_b: vec3, q: quat, inv_i: vec3, w_lin: float_t, near: Near):
    """`_push_body` (substep `near.h`), but for a body's first touch (no particle on it in the last pass,
    `near.fresh`) the push is kept in `near`'s push arrays until the pass ends (`apply_pushes`), so that
    every particle meets the body where it began the pass: pushed at once, the first particle a body
    touched pushed it alone, by its whole depth, and a ball landing square between four particles of a
    cloth on the floor left sideways at 0.5 m/s. Bodies in touch since the last pass are pushed at once,
    as before (pushes averaged in every pass left such a ball resting 4.4 mm deep in the cloth's 10 mm
    layer)."""
    if w_lin > float_t(0.0):
        dx_b, dtheta, dv, dw = _push_parts(impulse, still, r_b, q, inv_i, w_lin, near.h)
        if _first_touch(near, b):
            wp.atomic_add(near.push_position, b, dx_b)
            wp.atomic_add(near.push_rotation, b, dtheta)
            wp.atomic_add(near.push_velocity, b, dv)
            wp.atomic_add(near.push_spin, b, dw)
        else:
            _move_body(near.bodies, b, q, dx_b, dtheta, dv, dw)


@wp.kernel
def _apply_pushes(near: Near, serial: int):
    bodies = near.bodies
    zero = vec3()
    for k in range(wp.tid(), each_end(wp.tid(), serial, near.candidates.shape[0])):
        b = near.candidates[k]
        if near.fresh[b] == 0:
            continue  # nothing kept
        q = bodies.orientation[b]
        _move_body(bodies, b, q, near.push_position[b], near.push_rotation[b], near.push_velocity[b], near.push_spin[b])
        near.push_position[b] = zero
        near.push_rotation[b] = zero
        near.push_velocity[b] = zero
        near.push_spin[b] = zero


def apply_pushes(near: Near, *, cache: LaunchCache | None = None):
    """Move the near bodies by the pushes the pass kept (`_push_later`), and clear them."""
    count = near.candidates.shape[0]
    if count:
        launch_each(_apply_pushes, count, [near], near.candidates.device, cache)


@wp.func
def _slack_along(a: vec3, n: vec3, limit: float_t):
    """Largest s >= 0 with |a + s n| <= limit: how far a particle at arm a from a fixed point may move along n."""
    an = wp.dot(a, n)
    disc = an * an - wp.dot(a, a) + limit * limit
    return wp.max(-an + wp.sqrt(wp.max(disc, float_t(0.0))), float_t(0.0))


@wp.func
def _slack(
    p: int,
    xp: vec3,
    n: vec3,
    particles: Particles,
    limits: Limits,
    tethers: Tethers,
    near: Near,
    carried: Carried,
    b: int,
    w_b: float_t,
):
    """How far particle p may move along n before one of its limited springs or its tethers that hold it
    (`_holding`) reaches its limit (the other ends held where they are)."""
    x = particles.position
    s = float_t(1.0e30)
    k = limits.first[p]
    k_end = k + limits.count[p]
    while k < k_end:
        s = wp.min(s, _slack_along(xp - x[limits.other[k]], n, limits.length[k]))
        k += 1
    t = particles.tether_first[p]
    t_end = t + particles.tether_count[p]
    while t < t_end:
        pin = tethers.pin[t]
        if _holding(near, carried, particles, pin, b, w_b, n):
            s = wp.min(s, _slack_along(xp - x[pin], n, tethers.limit[t]))
        t += 1
    return s


@wp.func
def _mesh_distance(mesh: wp.uint64, closed: int, c: vec3, q: quat, xp: vec3, x_start: vec3, reach: float_t):
    """Signed distance of xp from a static mesh placed at (c, q), and the outward normal.

    Faces are one-sided on a closed mesh (a solid): a point is inside only behind a face's
    interior and less than half the reach deep; near an edge or a corner (where the
    pseudo-normal's sign is unreliable) only in front. An open mesh (a terrain, a plate) has no
    inside, and a cloth may lie on either side of it: the side is the one x_start (the point at
    the start of the substep) was on, so that a point which crossed the sheet during the substep
    is sent back, and one that lies behind it is kept behind, not pushed through to the front
    (pushed through a zero-thickness plate, a particle was thrown out at up to 2 reach / h).
    A point that begins less than a quarter of the reach behind still counts as in front.
    """
    zero = float_t(0.0)
    pl = wp.quat_rotate_inv(q, xp - c)
    query = wp.mesh_query_point_sign_normal(
        mesh, wp.vec3f(wp.float32(pl[0]), wp.float32(pl[1]), wp.float32(pl[2])), wp.float32(reach)
    )
    n = vec3(zero, zero, float_t(1.0))
    if not query.result:
        return False, zero, n
    cf = wp.mesh_eval_position(mesh, query.face, query.u, query.v)
    closest = vec3(float_t(cf[0]), float_t(cf[1]), float_t(cf[2]))
    rel = pl - closest
    nf = wp.mesh_eval_face_normal(mesh, query.face)
    n = wp.normalize(vec3(float_t(nf[0]), float_t(nf[1]), float_t(nf[2])))
    d = wp.dot(rel, n)
    bw = wp.float32(1.0) - query.u - query.v
    at_border = wp.min(wp.min(query.u, query.v), bw) < wp.float32(1e-4)
    length = wp.length(rel)
    if closed == 0:
        # open: the side x_start was on; at an edge or a corner the direction to it is the normal
        if wp.dot(wp.quat_rotate_inv(q, x_start - c) - closest, n) < float_t(-0.25) * reach:
            n = -n
            d = -d
        if at_border:
            if length <= float_t(1.0e-9):
                return False, zero, n
            n = rel / length
            d = length
        return True, d, wp.quat_rotate(q, n)
    if at_border:
        # at an edge or a corner: the direction to it is the normal, and only the front side counts
        if d <= zero or length <= float_t(1.0e-9):
            return False, zero, n
        n = rel / length
        d = length
    elif d < float_t(-0.5) * reach:
        return False, zero, n
    return True, d, wp.quat_rotate(q, n)


@wp.func
def _surface(
    shape: int, b: int, xp: vec3, x_start: vec3, bodies: BodyArrays, hulls: Hulls, meshes: Meshes, reach: float_t
):
    """Signed distance d of point xp from body b's surface and the outward normal n there; found is
    False where the body cannot be near (a mesh with no triangle within `reach`). x_start is the
    point at the start of the substep (the side of an open mesh it is kept on)."""
    zero = float_t(0.0)
    one = float_t(1.0)
    c = bodies.position[b]
    q = bodies.orientation[b]
    d = zero
    n = vec3(zero, zero, one)
    found = bool(True)
    if shape == PLANE:
        n = wp.quat_rotate(q, vec3(zero, zero, one))
        d = wp.dot(xp - c, n)
    elif shape == SPHERE:
        r = xp - c
        length = wp.length(r)
        d = length - bodies.radius[b]
        if length > float_t(1.0e-12):
            n = r / length
    elif shape == BOX:
        _surface_point, nl, d = box_closest(wp.quat_rotate_inv(q, xp - c), bodies.half_extents[b])
        n = wp.quat_rotate(q, nl)
    elif shape == CAPSULE:
        # the nearest point of the segment c + t u, |t| <= h_z - r, then as a sphere
        u = wp.quat_rotate(q, vec3(zero, zero, one))
        hh = bodies.half_extents[b][2] - bodies.radius[b]
        r = xp - (c + u * wp.clamp(wp.dot(xp - c, u), -hh, hh))
        length = wp.length(r)
        d = length - bodies.radius[b]
        if length > float_t(1.0e-12):
            n = r / length
    elif shape == CONVEX:
        _hull_point, nl, d = hull_closest(hulls, bodies.geometry[b], vec3(one, one, one), wp.quat_rotate_inv(q, xp - c))
        n = wp.quat_rotate(q, nl)
    elif shape == MESH:
        g = bodies.geometry[b]
        found, d, n = _mesh_distance(meshes.id[g], meshes.closed[g], c, q, xp, x_start, reach)
    else:
        found = False
    return found, d, n


@wp.func
def _start_overlap(near: Near, b: int, start: vec3, thickness: float_t):
    """How deep [m] into its `thickness` from body row b a particle at `start` was (0 or less: clear of it);
    with `start` where it began the substep, the overlap a contact began the substep in."""
    found, d, n = _surface(
        near.bodies.shape[b], b, start, start, near.bodies, near.hulls, near.meshes, float_t(2.0) * thickness
    )
    if not found:
        return float_t(0.0)
    return thickness - d


@wp.kernel
def _collide_bodies(particles: Particles, tethers: Tethers, limits: Limits, near: Near, carried: Carried, serial: int):
    x = particles.position
    x_prev = particles.position_prev
    thickness = particles.thickness
    bodies = near.bodies
    count = near.candidates.shape[0]
    for p in range(wp.tid(), each_end(wp.tid(), serial, x.shape[0])):
        w_p = particles.inv_mass[p]
        if w_p <= float_t(0.0):
            continue
        xp = x[p]
        zero = float_t(0.0)
        # static bodies first (pass 0), then dynamic ones (pass 1), so that a particle pressed
        # against a static body by a dynamic one knows it cannot give way
        support = vec3(zero, zero, zero)
        k = int(0)
        while k < 2 * count:
            b = near.candidates[k % count]
            dynamic_pass = k >= count
            k += 1
            if (bodies.inv_mass[b] > zero) != dynamic_pass or _shielded(near, p, b):
                continue
            c = bodies.position[b]
            q = bodies.orientation[b]
            # signed distance d from the body's surface and outward normal n
            found, d, n = _surface(
                bodies.shape[b], b, xp, x_prev[p], bodies, near.hulls, near.meshes, float_t(2.0) * thickness[p]
            )
            depth = thickness[p] - d
            if not found or depth <= zero:
                continue

            # the body's inverse mass at the contact point along n: w_b = 1/m + (r x n) . I^-1 (r x n)
            split = float_t(wp.max(near.contacts_prev[b], 1))
            if _first_touch(near, b):
                split = float_t(near.fresh[b])  # all the particles on it now (`_push_later`)
            wp.atomic_add(near.contacts_next, b, 1)
            r_b = (xp - n * d) - c
            w_lin = bodies.inv_mass[b]
            inv_i = bodies.inv_inertia[b]
            rn = wp.cross(r_b, n)
            w_b = w_lin + wp.dot(rn, inv_inertia_times(q, inv_i, rn))
            # a particle which a static body holds from the other side cannot give way to a dynamic
            # one; nor can one whose tethers are taut in the direction of the push (between taut x
            # limit and the limit a tether stiffens gradually: an on/off switch made bodies resting
            # on cloth chatter)
            w_c = w_p
            if w_b == zero:
                support = support + n
            elif wp.dot(support, n) < zero:
                w_c = zero
            if w_b > zero and w_c > zero:
                w_c = wp.min(w_c, _give_way(p, xp, n, w_p, particles, tethers, near, carried, b, w_b))
            if w_c + w_b <= zero:
                continue
            # normal, mass-weighted: lambda = depth / (w_c + c w_b) moves the particle lambda w_c along n
            # and gives the body -lambda n (c: particles on this body in the last pass, "mass splitting");
            # strict: the cloth gives way only as far as its stretch limit lets it, a particle moves at
            # most its slack along n (before one of its limited springs or tethers reaches its limit),
            # and the body is pushed out the rest of the way, lambda_b = (depth - slack) / (c w_b)
            lam = depth / (w_c + split * w_b)
            move = lam * w_c
            lam_b = lam
            if near.strict != 0 and w_b > zero and move > zero:
                slack = _slack(p, xp, n, particles, limits, tethers, near, carried, b, w_b)
                if move > slack:
                    move = slack
                    lam_b = (depth - slack) / (split * w_b)
            xp = xp + n * move

            # friction on the particle's tangential motion relative to the body surface this substep
            mu = wp.sqrt(particles.friction[p] * bodies.friction[b])
            vb = bodies.velocity[b] + wp.cross(bodies.angular_velocity[b], r_b)
            tdir, lam_t = _coulomb((xp - x_prev[p]) - vb * near.h, n, r_b, w_c, w_lin, split, mu, lam, q, inv_i)
            move_t = lam_t * w_c
            if near.strict != 0 and w_b > zero and move_t > zero:
                move_t = wp.min(move_t, _slack(p, xp, -tdir, particles, limits, tethers, near, carried, b, w_b))
            xp = xp - tdir * move_t
            # a body at rest (static, or kinematic and still) pushes the particle out of an overlap it
            # began the substep in (made inside a surface) without making that push speed: the velocity
            # update takes (x - x_prev) / h, so x_prev moves out with it by that overlap, at most the
            # push (the relax pass does this for rigid contacts). A cloth made lying in the ground left
            # it at overlap / h (2.4 m/s and a 0.3 m leap for 1 cm at dt = 1/240 s). A particle that
            # landed (its start outside) keeps the inelastic stop; one sliding over an edge keeps its
            # speed (the overlap is its start's own distance from the surface, not its motion along n)
            if w_b == zero and wp.length_sq(vb) == zero and wp.dot(n, xp - x_prev[p]) > zero:
                overlap = _start_overlap(near, b, x_prev[p], thickness[p])
                if overlap > zero:
                    x_prev[p] = x_prev[p] + n * wp.min(overlap, move)
            # a dynamic body pressing a particle against a static one (which cannot give way) undoes an
            # overlap the particle began the substep in without making it speed (the particle's start
            # taken where the body then was, v h back): that part of the push only moves the body (the
            # relax pass of rigid contacts does the same). A 1 kg ball placed on a cloth lying on the
            # floor, the cloth's thickness (1 cm) inside the ball, was thrown 14 m up at 19 m/s
            still = zero
            if w_b > zero and wp.dot(support, n) < zero:
                overlap = _start_overlap(near, b, x_prev[p] + bodies.velocity[b] * near.h, thickness[p])
                if overlap > zero:
                    still = wp.min(overlap / depth, float_t(1.0))
                    x_prev[p] = x_prev[p] + n * (move * still)
            # what the body gave the particle beyond the particle's own momentum change, m_p times its
            # move, the cloth held (taut tethers, the strict slack): it goes on to the pins, but for the
            # part held by the body's own pins, which the body does not give (`_route_to_pins`); a
            # particle pressed against a static body passes it to that body instead
            own = vec3()
            if w_b > zero and wp.dot(support, n) >= zero:
                m_p = float_t(1.0) / w_p
                held = n * (lam_b - move * m_p) - tdir * (lam_t - move_t * m_p)
                own = _route_to_pins(p, xp, held, particles, tethers, near, carried, b, w_b)
            _push_later(b, tdir * lam_t - n * lam_b + own, still, r_b, q, inv_i, w_lin, near)

        x[p] = xp
        particles.support[p] = support  # for the triangles' contacts (`_catch_small_spheres`)


@wp.func
def _fraction(num: float_t, den: float_t):
    """num / den for a point's position along an edge; 0 on an edge of zero length."""
    if den > float_t(0.0):
        return num / den
    return float_t(0.0)


@wp.func
def closest_on_triangle(p: vec3, a: vec3, b: vec3, c: vec3):
    """Barycentric weights (of a, b, c) of the point of triangle abc closest to p (Ericson 2005, 5.1.5).

    For a collapsed triangle (zero area) the weights still give a point of it, not always the nearest.
    """
    zero = float_t(0.0)
    one = float_t(1.0)
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = wp.dot(ab, ap)
    d2 = wp.dot(ac, ap)
    if d1 <= zero and d2 <= zero:
        return vec3(one, zero, zero)
    bp = p - b
    d3 = wp.dot(ab, bp)
    d4 = wp.dot(ac, bp)
    if d3 >= zero and d4 <= d3:
        return vec3(zero, one, zero)
    vc = d1 * d4 - d3 * d2
    if vc <= zero and d1 >= zero and d3 <= zero:
        t = _fraction(d1, d1 - d3)
        return vec3(one - t, t, zero)
    cp = p - c
    d5 = wp.dot(ab, cp)
    d6 = wp.dot(ac, cp)
    if d6 >= zero and d5 <= d6:
        return vec3(zero, zero, one)
    vb = d5 * d2 - d1 * d6
    if vb <= zero and d2 >= zero and d6 <= zero:
        t = _fraction(d2, d2 - d6)
        return vec3(one - t, zero, t)
    va = d3 * d6 - d5 * d4
    if va <= zero and (d4 - d3) >= zero and (d5 - d6) >= zero:
        t = _fraction(d4 - d3, (d4 - d3) + (d5 - d6))
        return vec3(zero, one - t, t)
    area2 = va + vb + vc  # proportional to the squared area: zero only for a collapsed triangle
    if area2 <= zero:
        return vec3(one, zero, zero)
    denom = one / area2
    v = vb * denom
    w = vc * denom
    return vec3(one - v - w, v, w)


@wp.func
def _off_triangle(c: vec3, c_start: vec3, a0: vec3, a1: vec3, a2: vec3, s0: vec3, s1: vec3, s2: vec3, reach: float_t):
    """Whether point c is closer than `reach` to triangle (a0, a1, a2), which was at (s0, s1, s2)
    when the substep began (c at c_start): (hit, beta, n, depth).

    beta are the barycentric weights of the triangle's closest point, n the direction from it
    towards c and depth how far the triangle must move along -n (c along +n) to leave `reach`
    between them. The side c_start was on decides n, so a point that got past the triangle's
    plane during the substep is pushed back rather than through.
    """
    zero = float_t(0.0)
    beta = closest_on_triangle(c, a0, a1, a2)
    d = c - (a0 * beta[0] + a1 * beta[1] + a2 * beta[2])
    dist = wp.length(d)
    n = vec3(zero, zero, float_t(1.0))
    if dist >= reach:
        return False, beta, n, zero
    face = wp.cross(a1 - a0, a2 - a0)
    p_start = s0 * beta[0] + s1 * beta[1] + s2 * beta[2]
    if wp.dot(c_start - p_start, face) < zero:
        face = -face
    face_len = wp.length(face)
    if face_len <= float_t(1.0e-14):
        return False, beta, n, zero  # a collapsed triangle: its particles' own contacts handle it
    n = face / face_len
    depth = reach - dist
    if wp.dot(d, n) < zero:
        depth = reach + dist  # the point is past the triangle: all the way back
    elif dist > float_t(1.0e-12):
        n = d / dist
    return True, beta, n, depth


@wp.kernel
def _catch_small_spheres(
    particles: Particles,
    tethers: Tethers,
    triangles: wp.array2d(dtype=wp.int32),
    near: Near,
    carried: Carried,
    serial: int,
):
    x = particles.position
    x_prev = particles.position_prev
    rest = particles.rest_position
    bodies = near.bodies
    for t in range(wp.tid(), each_end(wp.tid(), serial, triangles.shape[0])):
        i0, i1, i2 = corners(triangles, t)
        w0 = particles.inv_mass[i0]
        w1 = particles.inv_mass[i1]
        w2 = particles.inv_mass[i2]
        zero = float_t(0.0)
        # spheres that fit between this triangle's particles: no wider than its longest rest edge
        edge = wp.max(
            wp.length(rest[i1] - rest[i0]), wp.max(wp.length(rest[i2] - rest[i1]), wp.length(rest[i0] - rest[i2]))
        )
        gap = float_t(0.5) * wp.min(particles.thickness[i0], wp.min(particles.thickness[i1], particles.thickness[i2]))
        for k in range(near.candidates.shape[0]):
            b = near.candidates[k]
            r = bodies.radius[b]
            if bodies.shape[b] != SPHERE or r >= edge:
                continue
            if _shielded(near, i0, b) or _shielded(near, i1, b) or _shielded(near, i2, b):
                continue
            c = bodies.position[b]
            a0 = x[i0]
            a1 = x[i1]
            a2 = x[i2]
            hit, beta, n, depth = _off_triangle(
                c, c - bodies.velocity[b] * near.h, a0, a1, a2, x_prev[i0], x_prev[i1], x_prev[i2], r + gap
            )
            if not hit:
                continue
            p_prev = x_prev[i0] * beta[0] + x_prev[i1] * beta[1] + x_prev[i2] * beta[2]
            # lambda moves the closest point by -lambda sum(beta_i^2 w_i) n and the centre by lambda w_b n;
            # particles held by taut tethers give way less, as against any body
            w_b = bodies.inv_mass[b]
            split = float_t(wp.max(near.contacts_prev[b], 1))
            g0 = _give_way(i0, a0, -n, w0, particles, tethers, near, carried, b, w_b)
            g1 = _give_way(i1, a1, -n, w1, particles, tethers, near, carried, b, w_b)
            g2 = _give_way(i2, a2, -n, w2, particles, tethers, near, carried, b, w_b)
            # nor do particles that a static body holds from the other side (this pass's particle contacts)
            supported = False
            if wp.dot(particles.support[i0], n) > zero:
                g0 = zero
                supported = True
            if wp.dot(particles.support[i1], n) > zero:
                g1 = zero
                supported = True
            if wp.dot(particles.support[i2], n) > zero:
                g2 = zero
                supported = True
            w_tri = beta[0] * beta[0] * g0 + beta[1] * beta[1] * g1 + beta[2] * beta[2] * g2
            if w_tri + split * w_b <= zero:
                continue
            wp.atomic_add(near.contacts_next, b, 1)
            lam = depth / (w_tri + split * w_b)
            lam = lam * _lever_scale(lam, depth, beta[0] * g0, beta[1] * g1, beta[2] * g2)
            wp.atomic_sub(x, i0, n * (lam * beta[0] * g0))
            wp.atomic_sub(x, i1, n * (lam * beta[1] * g1))
            wp.atomic_sub(x, i2, n * (lam * beta[2] * g2))
            # a sphere at rest (static, or kinematic and still) pushes the triangle out of an overlap it
            # began the substep in (made through the sphere) without making that push speed, as it does a
            # particle (`_collide_bodies`): the start positions move with it by the part of the push that
            # the start's overlap asks. A 4 x 4 cloth made through a ball of 0.12 m left it at 23 m/s
            if w_b == zero and wp.length_sq(bodies.velocity[b]) == zero:
                was_in, beta_start, n_start, overlap = _off_triangle(
                    c, c, x_prev[i0], x_prev[i1], x_prev[i2], x_prev[i0], x_prev[i1], x_prev[i2], r + gap
                )
                if was_in:
                    undo = n * (lam * wp.min(overlap / depth, float_t(1.0)))
                    wp.atomic_sub(x_prev, i0, undo * (beta[0] * g0))
                    wp.atomic_sub(x_prev, i1, undo * (beta[1] * g1))
                    wp.atomic_sub(x_prev, i2, undo * (beta[2] * g2))

            # friction on the triangle point's tangential motion relative to the sphere's surface
            q = bodies.orientation[b]
            inv_i = bodies.inv_inertia[b]
            r_b = -n * r
            mu = wp.sqrt(
                (particles.friction[i0] + particles.friction[i1] + particles.friction[i2])
                / float_t(3.0)
                * bodies.friction[b]
            )
            p_moved = x[i0] * beta[0] + x[i1] * beta[1] + x[i2] * beta[2] - p_prev
            vb = bodies.velocity[b] + wp.cross(bodies.angular_velocity[b], r_b)
            tdir, lam_t = _coulomb(p_moved - vb * near.h, n, r_b, w_tri, w_b, split, mu, lam, q, inv_i)
            wp.atomic_sub(x, i0, tdir * (lam_t * beta[0] * g0))
            wp.atomic_sub(x, i1, tdir * (lam_t * beta[1] * g1))
            wp.atomic_sub(x, i2, tdir * (lam_t * beta[2] * g2))
            # a dynamic sphere pressing the triangle against a static body undoes an overlap it began the
            # substep in without making it speed, as for a particle (`_collide_bodies`; its start v h back)
            still = zero
            if supported and w_b > zero:
                c_start = c - bodies.velocity[b] * near.h
                was_in, beta_start, n_start, overlap = _off_triangle(
                    c_start, c_start, x_prev[i0], x_prev[i1], x_prev[i2], x_prev[i0], x_prev[i1], x_prev[i2], r + gap
                )
                if was_in:
                    still = wp.min(overlap / depth, float_t(1.0))
            _push_body(b, tdir * lam_t + n * lam, still, r_b, q, inv_i, w_b, near.h, bodies)


@wp.func
def _lever_scale(lam: float_t, depth: float_t, m0: float_t, m1: float_t, m2: float_t):
    """The factor (at most 1) on a contact's lambda, which moves particle i by lam * m_i (m_i its weight at
    the contact, >= 0), that keeps every particle's move within LEVER_LIMIT x depth; 1 where it is."""
    most = lam * wp.max(m0, wp.max(m1, m2))
    cap = LEVER_LIMIT * depth
    if most > cap:
        return cap / most
    return float_t(1.0)


@wp.func
def _mesh_vertex(points: wp.array(dtype=wp.vec3f), indices: wp.array(dtype=wp.int32), corner: int):
    """Vertex `corner` (3 f + k: corner k of triangle f) of a mesh, in its frame, as vec3."""
    v = points[indices[corner]]
    return vec3(float_t(v[0]), float_t(v[1]), float_t(v[2]))


@wp.func
def _to_frame(q: quat, c: vec3, x: vec3):
    """A world point in the frame at (c, q)."""
    return wp.quat_rotate_inv(q, x - c)


@wp.func
def _overlaps(a_lo: vec3, a_hi: vec3, b_lo: vec3, b_hi: vec3):
    """Whether the boxes [a_lo, a_hi] and [b_lo, b_hi] overlap."""
    return (
        a_lo[0] <= b_hi[0]
        and a_lo[1] <= b_hi[1]
        and a_lo[2] <= b_hi[2]
        and b_lo[0] <= a_hi[0]
        and b_lo[1] <= a_hi[1]
        and b_lo[2] <= a_hi[2]
    )


@wp.func
def _signs(j: int):
    """(+-1, +-1, +-1): the signs of corner j of a box, bit k of j set for -1 along axis k."""
    one = float_t(1.0)
    two = float_t(2.0)
    return vec3(one - two * float_t(j % 2), one - two * float_t((j // 2) % 2), one - two * float_t((j // 4) % 2))


@wp.func
def _keep_vertex_off(
    particles: Particles,
    i0: int,
    i1: int,
    i2: int,
    s0: vec3,
    s1: vec3,
    s2: vec3,
    v: vec3,
    c: vec3,
    q: quat,
    gap: float_t,
    mu: float_t,
):
    """Keep a static vertex v (in the frame at (c, q)) `gap` off the triangle (i0, i1, i2), which began
    the substep at (s0, s1, s2) in that frame: lambda = depth / sum(beta_i^2 w_i) moves particle i by
    -lambda beta_i w_i n (the closest point by -depth n), then Coulomb friction on the closest point's
    slip over the substep, bounded by mu lambda."""
    zero = float_t(0.0)
    one = float_t(1.0)
    x = particles.position
    a0 = _to_frame(q, c, x[i0])
    a1 = _to_frame(q, c, x[i1])
    a2 = _to_frame(q, c, x[i2])
    hit, beta, n, depth = _off_triangle(v, v, a0, a1, a2, s0, s1, s2, gap)
    if hit:
        w0 = particles.inv_mass[i0]
        w1 = particles.inv_mass[i1]
        w2 = particles.inv_mass[i2]
        w_tri = beta[0] * beta[0] * w0 + beta[1] * beta[1] * w1 + beta[2] * beta[2] * w2
        if w_tri > zero:
            lam = depth / w_tri
            scale = _lever_scale(lam, depth, beta[0] * w0, beta[1] * w1, beta[2] * w2)
            lam = lam * scale
            moved = a0 * beta[0] + a1 * beta[1] + a2 * beta[2] - n * (depth * scale)
            slip = moved - (s0 * beta[0] + s1 * beta[1] + s2 * beta[2])
            none = vec3(zero, zero, zero)
            tdir, lam_t = _coulomb(slip, n, none, w_tri, zero, one, mu, lam, quat(zero, zero, zero, one), none)
            move = wp.quat_rotate(q, n * lam + tdir * lam_t)
            wp.atomic_sub(x, i0, move * (beta[0] * w0))
            wp.atomic_sub(x, i1, move * (beta[1] * w1))
            wp.atomic_sub(x, i2, move * (beta[2] * w2))


@wp.func
def _keep_edge_off(
    particles: Particles,
    triangles: wp.array2d(dtype=wp.int32),
    t: int,
    owned: int,
    e0: vec3,
    e1: vec3,
    c: vec3,
    q: quat,
    gap: float_t,
    mu: float_t,
):
    """Keep a static edge (e0, e1) (in the frame at (c, q)) `gap` off the edges of triangle t that it
    owns (bit e of `owned`: corner e to e + 1): closest points inside both edges (at an end, a
    vertex or a particle contact holds it), on the side the cloth edge began the substep on; the
    cloth edge's ends move by weights (1 - s, s), with friction, as `_keep_vertex_off`."""
    zero = float_t(0.0)
    one = float_t(1.0)
    x = particles.position
    x_prev = particles.position_prev
    e_half = float_t(0.5) * wp.length(e1 - e0)
    if e_half > float_t(1.0e-12):
        e_dir = (e1 - e0) / (float_t(2.0) * e_half)
        e_mid = float_t(0.5) * (e0 + e1)
        for e in range(3):
            if (owned & (1 << e)) == 0:
                continue
            ia = triangles[t, e]
            ib = triangles[t, (e + 1) % 3]
            wa = particles.inv_mass[ia]
            wb = particles.inv_mass[ib]
            la = _to_frame(q, c, x[ia])
            lb = _to_frame(q, c, x[ib])
            c_half = float_t(0.5) * wp.length(lb - la)
            if c_half <= float_t(1.0e-12):
                continue
            sc, se = segment_closest(
                float_t(0.5) * (la + lb), (lb - la) / (float_t(2.0) * c_half), c_half, e_mid, e_dir, e_half
            )
            if wp.abs(sc) >= c_half or wp.abs(se) >= e_half:
                continue
            s = float_t(0.5) + float_t(0.5) * sc / c_half
            on_edge = e_mid + e_dir * se
            d = la * (one - s) + lb * s - on_edge
            d_start = _to_frame(q, c, x_prev[ia]) * (one - s) + _to_frame(q, c, x_prev[ib]) * s - on_edge
            # the side the cloth edge was on at the start of the substep
            start_len = wp.length(d_start)
            if start_len <= float_t(1.0e-12):
                continue
            n = d_start / start_len
            along = wp.dot(d, n)
            dist = wp.length(d)
            if along > zero and dist > float_t(1.0e-12):
                n = d / dist
                along = dist
            depth = gap - along
            w_edge = (one - s) * (one - s) * wa + s * s * wb
            if depth <= zero or w_edge <= zero:
                continue
            lam = depth / w_edge
            scale = _lever_scale(lam, depth, (one - s) * wa, s * wb, zero)
            lam = lam * scale
            slip = d + n * (depth * scale) - d_start
            none = vec3(zero, zero, zero)
            tdir, lam_t = _coulomb(slip, n, none, w_edge, zero, one, mu, lam, quat(zero, zero, zero, one), none)
            move = wp.quat_rotate(q, n * lam - tdir * lam_t)
            wp.atomic_add(x, ia, move * ((one - s) * wa))
            wp.atomic_add(x, ib, move * (s * wb))


@wp.kernel
def _collide_features(
    particles: Particles,
    triangles: wp.array2d(dtype=wp.int32),
    edge_owner: wp.array(dtype=wp.int32),
    near: Near,
    serial: int,
):
    x = particles.position
    x_prev = particles.position_prev
    bodies = near.bodies
    for t in range(wp.tid(), each_end(wp.tid(), serial, triangles.shape[0])):
        i0, i1, i2 = corners(triangles, t)
        zero = float_t(0.0)
        if particles.inv_mass[i0] + particles.inv_mass[i1] + particles.inv_mass[i2] <= zero:
            continue
        # the triangle keeps half the particles' thickness from the features, as from small spheres
        # (where the particles' own contacts hold the cloth, the triangles stay out of their way)
        gap = float_t(0.5) * wp.min(particles.thickness[i0], wp.min(particles.thickness[i1], particles.thickness[i2]))
        mu_cloth = (particles.friction[i0] + particles.friction[i1] + particles.friction[i2]) / float_t(3.0)
        owned = edge_owner[t]
        for k in range(near.candidates.shape[0]):
            b = near.candidates[k]
            shape = bodies.shape[b]
            if shape != MESH and (shape != BOX or bodies.inv_mass[b] > zero):
                continue
            if _shielded(near, i0, b) or _shielded(near, i1, b) or _shielded(near, i2, b):
                continue
            c = bodies.position[b]
            q = bodies.orientation[b]
            mu = wp.sqrt(mu_cloth * bodies.friction[b])
            # the triangle in the body's frame at the start of the substep and now, and its box widened by the gap
            s0 = _to_frame(q, c, x_prev[i0])
            s1 = _to_frame(q, c, x_prev[i1])
            s2 = _to_frame(q, c, x_prev[i2])
            a0 = _to_frame(q, c, x[i0])
            a1 = _to_frame(q, c, x[i1])
            a2 = _to_frame(q, c, x[i2])
            lo = wp.min(wp.min(wp.min(a0, a1), wp.min(a2, s0)), wp.min(s1, s2)) - vec3(gap, gap, gap)
            hi = wp.max(wp.max(wp.max(a0, a1), wp.max(a2, s0)), wp.max(s1, s2)) + vec3(gap, gap, gap)
            if shape == BOX:
                # a static box's 8 corners and 12 edges, where the triangle's box meets the box
                he = bodies.half_extents[b]
                if not _overlaps(-he, he, lo, hi):
                    continue
                for j in range(8):
                    corner = wp.cw_mul(he, _signs(j))
                    if _overlaps(corner, corner, lo, hi):
                        _keep_vertex_off(particles, i0, i1, i2, s0, s1, s2, corner, c, q, gap, mu)
                for j in range(12):
                    # edges along axis j // 4, at the signs (u, w) of the other two axes
                    axis = j // 4
                    sign = _signs(j % 4)
                    u = sign[0]
                    w = sign[1]
                    e0 = vec3(zero, zero, zero)
                    e1 = vec3(zero, zero, zero)
                    if axis == 0:
                        e0 = vec3(-he[0], u * he[1], w * he[2])
                        e1 = vec3(he[0], u * he[1], w * he[2])
                    elif axis == 1:
                        e0 = vec3(u * he[0], -he[1], w * he[2])
                        e1 = vec3(u * he[0], he[1], w * he[2])
                    else:
                        e0 = vec3(u * he[0], w * he[1], -he[2])
                        e1 = vec3(u * he[0], w * he[1], he[2])
                    if _overlaps(wp.min(e0, e1), wp.max(e0, e1), lo, hi):
                        _keep_edge_off(particles, triangles, t, owned, e0, e1, c, q, gap, mu)
                continue
            # a mesh: the triangles its BVH finds in the box, each with the sharp features it owns
            g = bodies.geometry[b]
            mesh = near.meshes.id[g]
            first = near.meshes.feature_start[g]
            query = wp.mesh_query_aabb(
                mesh,
                wp.vec3f(wp.float32(lo[0]), wp.float32(lo[1]), wp.float32(lo[2])),
                wp.vec3f(wp.float32(hi[0]), wp.float32(hi[1]), wp.float32(hi[2])),
            )
            m = wp.mesh_get(mesh)
            f = int(0)
            while wp.mesh_query_aabb_next(query, f):
                flags = near.meshes.feature[first + f]
                for j in range(3):
                    if (flags & (1 << j)) != 0:
                        v = _mesh_vertex(m.points, m.indices, 3 * f + j)
                        if _overlaps(v, v, lo, hi):
                            _keep_vertex_off(particles, i0, i1, i2, s0, s1, s2, v, c, q, gap, mu)
                for j in range(3):
                    if (flags & (8 << j)) != 0:
                        e0 = _mesh_vertex(m.points, m.indices, 3 * f + j)
                        e1 = _mesh_vertex(m.points, m.indices, 3 * f + (j + 1) % 3)
                        if _overlaps(wp.min(e0, e1), wp.max(e0, e1), lo, hi):
                            _keep_edge_off(particles, triangles, t, owned, e0, e1, c, q, gap, mu)


@wp.struct
class PairList:
    """The self-collision pair list as `_find_pairs` writes it."""

    rows: wp.array2d(dtype=wp.int32)  # the pairs (p, q), p < q, (K, 2)
    found: wp.array(dtype=wp.int32)  # (1,): how many pairs were found (more than K when the list is full)


@wp.kernel
def _find_pairs(particles: Particles, margin: float_t, reach: float_t, cells: Grid, out: PairList, serial: int):
    x = particles.position
    for p in range(wp.tid(), each_end(wp.tid(), serial, x.shape[0])):
        xp = x[p]
        # cells are 2 reach wide, so the ball of radius `reach` around x_p lies in the 2 x 2 x 2
        # cells from `lo` (loops with constant bounds: Warp unrolls them, much faster on the CPU)
        lo = cell_of(xp - vec3(reach, reach, reach), cells.params[1])
        cloth = particles.cloth[p]
        pi = particles.i[p]
        pj = particles.j[p]
        capacity = out.rows.shape[0]
        for dz in range(2):
            for dy in range(2):
                for dx in range(2):
                    cx = lo[0] + dx
                    cy = lo[1] + dy
                    cz = lo[2] + dz
                    slot = cell_hash(wp.vec3i(cx, cy, cz), cells.mask)
                    e = cells.cell_start[slot]
                    end = e + cells.cell_count[slot]
                    while e < end:
                        q = cells.entries[e]
                        e += 1
                        # each pair once (p < q)
                        if q <= p:
                            continue
                        # grid neighbours are held apart by springs, not by collisions
                        if particles.cloth[q] == cloth:
                            if wp.abs(particles.i[q] - pi) <= 2 and wp.abs(particles.j[q] - pj) <= 2:
                                continue
                        rel = xp - x[q]
                        near = float_t(0.5) * (particles.thickness[p] + particles.thickness[q]) + margin
                        if wp.dot(rel, rel) >= near * near:
                            continue
                        # the slot may hold other cells too (hash collisions): count each pair once;
                        # pairs of two pins never move
                        cq = cells.point_cell_coord[q]
                        if cq[0] != cx or cq[1] != cy or cq[2] != cz:
                            continue
                        if particles.inv_mass[p] + particles.inv_mass[q] <= float_t(0.0):
                            continue
                        k = wp.atomic_add(out.found, 0, 1)
                        if k < capacity:
                            out.rows[k, 0] = p
                            out.rows[k, 1] = q


@wp.kernel
def _separate_pairs(
    particles: Particles,
    pairs: wp.array2d(dtype=wp.int32),
    count: int,
    serial: int,
):
    x = particles.position
    for k in range(wp.tid(), each_end(wp.tid(), serial, count)):
        if k >= count:
            continue
        p = pairs[k, 0]
        q = pairs[k, 1]
        rel = x[p] - x[q]
        dist = wp.length(rel)
        target = float_t(0.5) * (particles.thickness[p] + particles.thickness[q])
        if dist >= target:
            continue
        w_p = particles.inv_mass[p]
        w_q = particles.inv_mass[q]
        n = vec3(float_t(0.0), float_t(0.0), float_t(1.0))
        if dist > float_t(1.0e-12):
            n = rel / dist
        # push both to distance `target`, in proportion to their inverse masses (Gauss-Seidel on
        # the CPU, where kernels run serially)
        c = n * ((target - dist) / (w_p + w_q))
        wp.atomic_add(x, p, c * w_p)
        wp.atomic_sub(x, q, c * w_q)


def candidate_bodies(world_bodies, lo: np.ndarray, hi: np.ndarray, reach: float, dt: float) -> np.ndarray:
    """Indices of the bodies that can touch the cloth's bounding box [lo, hi] this step, int32.

    Args:
        world_bodies: the world's body `ArraySet`.
        lo, hi: corners of the cloth's bounding box [m], shape (3,).
        reach: largest particle thickness plus the distance particles can travel this step [m].
        dt: step [s], for the distance bodies can travel.
    """
    n = world_bodies.count
    if n == 0:
        return np.zeros(0, dtype=np.int32)
    shape = world_bodies.numpy("body_shape")
    pos = world_bodies.numpy("body_position")
    bound = world_bodies.numpy("body_bound_radius")
    speed = np.linalg.norm(world_bodies.numpy("body_velocity"), axis=1)
    spin = np.linalg.norm(world_bodies.numpy("body_angular_velocity"), axis=1)
    finite = np.isfinite(bound)
    bound_f = np.where(finite, bound, 0.0)
    margin = reach + dt * (speed + spin * bound_f)
    # solids: distance from the centre to the box <= bounding radius + margin
    gap = np.linalg.norm(np.maximum(0.0, np.maximum(lo - pos, pos - hi)), axis=1)
    near = gap <= bound_f + margin
    # planes: the box's lowest corner along the normal is within margin of the plane
    planes = shape == int(ShapeType.PLANE)
    if np.any(planes):
        q = world_bodies.numpy("body_orientation")[planes]
        x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
        normal = np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)
        lowest = np.where(normal > 0.0, lo, hi)  # corner minimising n . x
        dist = np.einsum("ij,ij->i", lowest - pos[planes], normal)
        near[planes] = dist <= margin[planes]
    return np.nonzero(near)[0].astype(np.int32)


def near_bodies(
    candidates,
    bodies,
    hulls,
    meshes,
    counts,
    h,
    shield,
    pinned,
    pushes,
    fresh,
    *,
    taut: float = 0.97,
    strict: bool = False,
) -> Near:
    """The bodies the cloth may touch this step, as the contact kernels take them.

    Args:
        candidates: the body rows to test, shape (k,) int32 (`candidate_bodies`).
        bodies: the world's body arrays (`BodyArrays`, from `body_arrays`); positions and velocities of
            dynamic bodies are updated.
        hulls: the world's `Hulls` struct (convex bodies); meshes: its `Meshes` struct (`MeshSet.struct`).
        counts: per body row, the particles that touched it in the previous pass and (zeroed before
            each pass) in this one, two arrays of shape (n,) int32.
        h: substep [s].
        shield: per particle, the body row it does not touch, (P,) int32, or empty (`attach.shielded_bodies`).
        pinned: per particle, the body row it is pinned to, (P,) int32, or empty (`attach.pinned_rows`): a
            tether to a pin on a dynamic body does not hold its particle against a push (`_holding`).
        pushes: four (n,) vec3 arrays, zero, per body row: the pushes a pass keeps for bodies it touches
            first (position, rotation, velocity, angular velocity; `apply_pushes` applies and clears them).
        fresh: (n,) int32 per body row: the particles on it at the substep's start where no particle
            touched it in the last pass (`count_first_touches`), else 0.
        taut: a tether longer than taut x its limit starts to hold its particle against bodies,
            fully at the limit (a gradual ramp: an on/off switch made bodies resting on cloth
            chatter at ~0.2 m/s; with the ramp a box in a hammock settles to ~0.02 m/s).
        strict: particles give way to dynamic bodies only within the slack their limited springs
            and tethers leave them (the other ends held), and the bodies are pushed out the rest
            of the way, so contacts never stretch the cloth past its limit (`ClothSystem.strict_limit`).
    """
    near = Near()
    near.bodies, near.hulls, near.meshes, near.candidates = bodies, hulls, meshes, candidates
    near.contacts_prev, near.contacts_next = counts
    near.h, near.taut, near.strict = float_t(h), float_t(taut), int(strict)
    near.shield, near.pinned = shield, pinned
    near.push_position, near.push_rotation, near.push_velocity, near.push_spin = pushes
    near.fresh = fresh
    return near


def collide_bodies(
    particles: Particles,
    tethers: Tethers,
    limits: Limits,
    near: Near,
    carried: Carried,
    *,
    cache: LaunchCache | None = None,
):
    """Push particles out of the near bodies, with friction, and push the bodies back.

    Args:
        particles: the particle arrays: `position` after integration (corrected in place),
            `position_prev` at the start of the substep; pinned particles (`inv_mass` 0) are not
            moved; each keeps its `thickness` from surfaces; its `friction` is combined with a
            body's as sqrt(mu_p mu_b); `pin_load` [kg m] adds the part of the bodies' pushes that
            the cloth held without its particles moving, passed on to the pins holding them.
        tethers: each tether's pin and largest length (a particle's are `particles.tether_first`, ...).
        limits: each particle's limited springs.
        near: the bodies to test, the contact counts and the pass's settings (`near_bodies`).
        carried: the pins on free dynamic bodies with those bodies' inverse masses at them
            (`BodyPins.begin_constraints`): a tether to such a pin does not hold its particle against
            another body's push (`_holding`).
    """
    if near.candidates.shape[0]:
        x = particles.position
        launch_each(_collide_bodies, x.shape[0], [particles, tethers, limits, near, carried], x.device, cache)


@wp.func
def _inside_reach(near: Near, particles: Particles, p: int, xp: vec3, b: int, margin: float_t):
    """Particle p at xp against body row b for the passes after the contacts: (found, d, n) as `_surface`
    gives them, found False for a static body, the particle's own pin's (`_shielded`) and a particle
    farther than `margin` outside the body's bounding sphere."""
    bodies = near.bodies
    n = vec3()
    if bodies.inv_mass[b] <= float_t(0.0) or _shielded(near, p, b):
        return False, float_t(0.0), n
    reach = bodies.bound_radius[b] + margin
    if wp.length_sq(xp - bodies.position[b]) > reach * reach:
        return False, float_t(0.0), n
    thickness = particles.thickness[p]
    return _surface(
        bodies.shape[b], b, xp, particles.position_prev[p], bodies, near.hulls, near.meshes, float_t(2.0) * thickness
    )


@wp.kernel
def _count_first_touches(particles: Particles, near: Near, serial: int):
    """Per body that no particle touched in the last pass: the particles within their thickness of it now."""
    x = particles.position
    for p in range(wp.tid(), each_end(wp.tid(), serial, x.shape[0])):
        if particles.inv_mass[p] <= float_t(0.0):
            continue
        thickness = particles.thickness[p]
        for k in range(near.candidates.shape[0]):
            b = near.candidates[k]
            if near.contacts_prev[b] != 0:
                continue  # some particle touched it in the last pass
            found, d, n = _inside_reach(near, particles, p, x[p], b, thickness)
            if found and thickness - d > float_t(0.0):
                wp.atomic_add(near.fresh, b, 1)


def count_first_touches(particles: Particles, near: Near, *, cache: LaunchCache | None = None):
    """Count, per dynamic body that no particle touched in the last pass, the particles within their
    thickness of it now, into `near.fresh` (zeroed by the caller): the mass splitting of that body's
    first touch, whose pushes then wait for the pass's end (`_push_later`)."""
    if near.candidates.shape[0]:
        x = particles.position
        launch_each(_count_first_touches, x.shape[0], [particles, near], x.device, cache)


@wp.func
def _kick_body(b: int, impulse: vec3, r_b: vec3, q: quat, inv_i: vec3, w_lin: float_t, bodies: BodyArrays):
    """A dynamic body's velocities change by `impulse` [kg m/s] at r_b from its centre; its position does not."""
    if w_lin > float_t(0.0):
        wp.atomic_add(bodies.velocity, b, impulse * w_lin)
        wp.atomic_add(bodies.angular_velocity, b, inv_inertia_times(q, inv_i, wp.cross(r_b, impulse)))


@wp.kernel
def _hold_bodies(particles: Particles, tethers: Tethers, near: Near, carried: Carried, serial: int):
    """After the stretch limit's last word: a particle it left inside a dynamic body's surface (past its
    thickness layer), held by a tether to a pin against the body's push, marks what the cloth cannot
    give. The body is moved out by that depth, shared among its particles (`contacts_prev`), without
    making speed, and its approach to the particle along n is stopped, the impulse going on to the
    pins (`_route_to_pins`), so that momentum is kept. See `hold_bodies`."""
    x = particles.position
    x_prev = particles.position_prev
    bodies = near.bodies
    zero = float_t(0.0)
    for p in range(wp.tid(), each_end(wp.tid(), serial, x.shape[0])):
        if particles.inv_mass[p] <= zero:
            continue
        xp = x[p]
        for k in range(near.candidates.shape[0]):
            b = near.candidates[k]
            # (a particle outside the body's bounding sphere is not inside it)
            found, d, n = _inside_reach(near, particles, p, xp, b, zero)
            depth = -d  # inside the body's surface, not only within the particle's thickness of it
            if not found or depth <= zero:
                continue
            w_lin = bodies.inv_mass[b]
            c = bodies.position[b]
            q = bodies.orientation[b]
            split = float_t(wp.max(near.contacts_prev[b], 1))
            r_b = (xp - n * d) - c
            inv_i = bodies.inv_inertia[b]
            rn = wp.cross(r_b, n)
            w_b = w_lin + wp.dot(rn, inv_inertia_times(q, inv_i, rn))
            # only where a tether to a pin holds the particle against the push (free cloth: the body drags it)
            along = zero
            t0 = particles.tether_first[p]
            for t in range(t0, t0 + particles.tether_count[p]):
                pull, _tight = _tether_hold(t, xp, n, particles, tethers, near, carried, b, w_b)
                along += pull
            if along <= zero:
                continue
            # out by the depth, shared among the particles on it, without speed
            _push_body(b, -n * (depth / (split * w_b)), float_t(1.0), r_b, q, inv_i, w_lin, near.h, bodies)
            # its approach to the particle stopped
            vb = bodies.velocity[b] + wp.cross(bodies.angular_velocity[b], r_b)
            vp = (xp - x_prev[p]) / near.h
            approach = wp.dot(vb - vp, n)
            if approach > zero:
                j = approach / (split * w_b)
                own = _route_to_pins(p, xp, n * (j * near.h), particles, tethers, near, carried, b, w_b)
                _kick_body(b, -n * j + own / near.h, r_b, q, inv_i, w_lin, bodies)


def hold_bodies(
    particles: Particles, tethers: Tethers, near: Near, carried: Carried, *, cache: LaunchCache | None = None
):
    """Stop dynamic bodies that the taut cloth holds: run after the stretch limit's last word in a substep.

    A particle gives way to a body's push unless its tethers are near their limit (`_give_way`). Under
    a body much heavier than the cloth, the structural springs reach their limit first (a sheet sagging
    into a cone under a ball), so the body got only the particles' own momentum while the stretch limit
    pulled them back into it: a 14 kg ball fell through a 0.3 kg hammock, and a 20 kg one set on it
    was thrown up, 275 J over 3 s, by particles pushed out from 4 cm inside it. Here every particle left
    inside a body's surface (a depth the thickness layer, which the next substep's contacts settle,
    does not explain) moves the body out instead, without speed, and stops the body's approach to it;
    cloth without pins (no tether holds) is left to the contacts, which drag it along. Cost O(P x
    candidates), as one contact pass.
    """
    if near.candidates.shape[0]:
        x = particles.position
        launch_each(_hold_bodies, x.shape[0], [particles, tethers, near, carried], x.device, cache)


def catch_small_spheres(
    particles: Particles, tethers: Tethers, triangles, near: Near, carried: Carried, *, cache: LaunchCache | None = None
):
    """Keep spheres that fit between particles from passing through the cloth's triangles.

    Particles alone stop only bodies wider than the gaps between them. For each triangle and each
    candidate sphere narrower than the triangle's longest rest edge, the closest point of the
    triangle is kept at least radius + thickness / 2 from the centre, on the side the centre
    was on when the substep began: the triangle's particles and the sphere move apart, weighted
    by inverse masses, barycentric weights and tautness of the particles' tethers, with
    Coulomb friction at the sphere's surface (position-based, like `collide_bodies`, whose
    arguments these are; `triangles`: (T, 3) int32). Cost O(T x candidates).
    """
    count = triangles.shape[0]
    if near.candidates.shape[0] and count:
        launch_each(
            _catch_small_spheres, count, [particles, tethers, triangles, near, carried], triangles.device, cache
        )


def edge_owners(triangles: np.ndarray) -> np.ndarray:
    """Per triangle, bit k set where it is the first triangle holding its edge k (corner k to k + 1), (T,) int32:
    each cloth edge then meets a mesh edge once (`collide_features`)."""
    flags = np.zeros(len(triangles), dtype=np.int64)
    if len(triangles):
        first, _other, _uses = edge_table(triangles)
        np.bitwise_or.at(flags, first // 3, 1 << (first % 3))
    return flags.astype(np.int32)


def collide_features(particles: Particles, triangles, edge_owner, near: Near, *, cache: LaunchCache | None = None):
    """Keep the sharp features of static meshes and boxes (a cone's tip, a box's edge, a plate's border) out of the cloth's triangles.

    Particles alone keep out of a body's surface, but a feature narrower than the gaps between
    them pokes through a triangle. For each triangle and each static mesh, the mesh BVH is
    queried with the triangle's box (now and at the start of the substep, widened by half its
    thickness); each sharp vertex found (`meshes.sharp_features`) is kept half the thickness from
    the triangle, and each sharp edge from the triangle's own edges (closest points inside both),
    on the side the cloth was on when the substep began. A static box's 8 corners and 12 edges
    are treated alike (no BVH: one box test first), so a mesh box and the box primitive drape a
    cloth alike. The triangle's particles move by their barycentric weights times their inverse
    masses (position-based, as `catch_small_spheres`), with Coulomb friction as for particles.
    Serial on the CPU, so deterministic there. Dynamic boxes are left to the particle contacts.

    Args:
        particles: the particle arrays (`position` corrected in place; `position_prev` at the
            substep's start; `inv_mass`, `thickness`, `friction`).
        triangles: (T, 3) int32; edge_owner: `edge_owners(triangles)`, (T,) int32.
        near: the bodies that can reach the cloth (`near_bodies`; only its meshes and static boxes are read).
        cache: recorded launches to replay.

    Cost O(T x (log F + features near each triangle)) per call for a mesh of F triangles, O(T x 20)
    for a box near the triangle.
    """
    count = triangles.shape[0]
    if near.candidates.shape[0] and count:
        launch_each(_collide_features, count, [particles, triangles, edge_owner, near], triangles.device, cache)


def pair_buffer(particle_count: int, device: str) -> wp.array:
    """The first buffer of the self-collision pair list of P particles: (max(64, 4 P), 2) int32."""
    return wp.zeros((max(64, 4 * particle_count), 2), dtype=wp.int32, device=device)


class SelfCollisionGrid:
    """The self-collision pair finder: the particle spatial hash and the device-side pair counter.

    The pair list it fills is state (`ClothState.pairs`, kept from step to step while the particles
    stay within its margin); this object holds only scratch.

    Args:
        device: Warp device.
    """

    # the pair list as `_find_pairs` writes it (`PairList`), built again when the buffer grows; a class
    # default, so that a finder restored from a snapshot older than it has it too
    _out: tuple | None = None

    def __init__(self, device: str):
        self.grid = HashGrid(device)
        self.found = wp.zeros(1, dtype=wp.int32, device=device)

    def find_pairs(
        self,
        pairs: wp.array,
        particles: Particles,
        max_thickness: float,
        margin: float,
        *,
        cache: LaunchCache | None = None,
    ) -> tuple[wp.array, int]:
        """Every non-neighbour pair within its mean thickness + `margin`, written to `pairs`.

        Args:
            pairs: the pair buffer, (K, 2) int32 (`pair_buffer`).
            particles: the particle arrays (reads `position`, `inv_mass`, `thickness`, and the
                cloth and grid place `cloth`, `i`, `j`).
            max_thickness: the largest thickness [m].
            margin: how much closer two particles may come during the step [m].
            cache: recorded launches to replay.

        Returns:
            The buffer holding the list (`pairs`, or a larger one with the first K pairs when more than
            K were found: this step keeps the truncated list, the next finds room) and the number of
            pairs in it.
        """
        x = particles.position
        n, dev = x.shape[0], x.device
        reach = max_thickness + margin
        inv_cell = 0.5 / reach  # cells 2 reach wide: each query visits 2 x 2 x 2 cells
        # counting sort of the particles into hashed cells (shared with the bodies' broad phase)
        grid = self.grid.build(x, n, 1.0 / inv_cell)
        # candidate pairs
        self.found.zero_()
        self._out = cached_struct(PairList, {"rows": pairs, "found": self.found}, "", self._out)
        launch_each(_find_pairs, n, [particles, margin, reach, grid.struct(), self._out[0]], dev, cache)
        found = int(self.found.numpy()[0])
        count = min(found, pairs.shape[0])
        if found > count:
            # keep this step's truncated list; make room for the next step
            kept = pairs.numpy()[:count].copy()
            pairs = wp.zeros((2 * found, 2), dtype=wp.int32, device=dev)
            pairs.assign(np.concatenate([kept, np.zeros((2 * found - count, 2), np.int32)]))
        return pairs, count


def separate_pairs(particles: Particles, pairs, count: int, *, cache: LaunchCache | None = None) -> None:
    """Every substep: push the listed pairs that are closer than their mean thickness apart.

    Args:
        particles: the particle arrays (`position` corrected in place, weighted by `inv_mass`;
            `thickness`).
        pairs: the pair list, (K, 2) int32; count: how many of its rows are pairs.
        cache: recorded launches to replay.
    """
    if count:
        # on CUDA launched over the whole buffer (threads past `count` return), so the recorded
        # launch is reused whatever the count
        launch_each(_separate_pairs, pairs.shape[0], [particles, pairs, count], pairs.device, cache)
