"""Contact solver: sequential impulses with soft contacts, Coulomb friction and restitution.

Reads contacts from the narrow phase and body poses and velocities; writes body velocities and
the per-contact accumulated impulses. One pass costs O(contacts).

The scheme is the "soft step" of Catto (Solver2D, 2024; Box2D v3), in 3D:
- per step, `prepare` fixes each contact's anchors r_a, r_b, tangents, effective masses
  m_n = 1 / (1/m_a + 1/m_b + (r_a x n) . I_a^-1 (r_a x n) + (r_b x n) . I_b^-1 (r_b x n)),
  the combined friction mu = sqrt(mu_a mu_b) and restitution e = max(e_a, e_b);
- per substep: warm start (the first substep applies last step's matched impulses in a pass of
  its own; later ones get the previous substep's, summed per body by its relax pass, through
  `integrate_velocities`), `solve` (a manifold's rows friction first, then the normal, since
  non-penetration matters more; a lone contact's normal row first, so that its friction is
  bounded by the pass's own load, then friction, and a lever's normal row once more) with bias
  (the soft constraint pushes overlapping bodies apart at a bounded speed), integrate positions,
  then `solve` again without bias ("relax"), which removes the push-out velocity again, so
  penetration recovery adds no kinetic energy -- the role split impulses play in older solvers;
- the normal impulse is clamped to >= 0, the friction impulse to the disc |jt| <= mu jn;
- a manifold (a pair's consecutive contacts sharing one normal, up to `MANIFOLD_ROWS`: a face's corners) is solved
  as one block: its rows are swept forward and backward in turn until no impulse changes by
  `MANIFOLD_SWEEP_TOLERANCE` of the block's load, at most `MANIFOLD_SWEEPS` times (the collision pass: until they converge to `MANIFOLD_TOLERANCE`), because its normal rows are coupled and rank-deficient (four coplanar
  corners, three degrees of freedom) and one sweep leaves each corner a different impulse;
  a patch (a manifold whose rows share the normal) takes its friction at its centre, on the
  disc |jt| <= mu sum jn, with a twist row about n, |j_twist| <= mu sum jn_i arm_i, so that no
  order of its corners enters the friction (a box landing flat or on one edge never turns
  about the vertical; tests/regression/test_issue_16_flat_landing_spins_a_box.py);
- contacts with a static body are twice as stiff (they carry whole piles), as in Box2D;
- a lone contact's overlap up to `LINEAR_SLOP` is held rigidly (no push-out), so resting spheres
  do not jitter; a manifold's rows have no slop (their corners share the load evenly, see
  `_normal_target`): a resting row under load F settles at F / (m_n omega^2)
  (tests/physics/test_stacks.py);
- restitution is a collision pass at the start of every substep, before its gravity kick and the solve (`impacts`,
  as in the collision/contact split of Guendelman, Bridson & Fedkiw, SIGGRAPH 2003): every
  contact that closes within the substep faster than the threshold collides once, as a
  two-body collision with its own impact speed (normal impulse to -e v_impact, then Coulomb
  friction of at most mu times it); a manifold's rows collide together (their normal impulses
  swept to convergence, a patch's friction at its centre). The sweep runs forward then backward, so a collision
  travels along a chain of touching bodies in either direction within the substep; each
  impulse alone cannot add energy, so no sequence of them can. The contact is then
  separating, and the inelastic solve that follows leaves it alone; resting contacts
  (approach below the threshold) never bounce. An inelastic contact (e = 0) faster than the
  threshold collides too, landing: to the approach that closes its gap within the next substep
  (a stack struck from above, a ball squeezed between others, is stopped in the pass's sweeps at
  once, instead of by the soft rows a pass a substep, which pushed its bodies apart again); so
  does, at any speed, one whose body another contact's collision changed earlier in the pass
  (`struck`), with up to INELASTIC_IMPACT_SWEEPS sweeps, so that such a collision runs along a row
  of touching bodies or down a stack into the floor.

Soft constraint coefficients for stiffness f [Hz] and damping ratio zeta at substep h:
omega = 2 pi f, a1 = 2 zeta + h omega, a2 = h omega a1, a3 = 1 / (1 + a2);
bias rate = omega / a1, mass scale = a2 a3, impulse scale = a3.

Layout: the narrow phase's contacts are arrays (`CONTACT_FIELDS`); `prepare` turns each into a
`ContactRow` record (`ContactSet.rows`), which every pass reads and updates in place, field by
field. On the CPU each pass is one thread looping over the rows in order (`_make_solve`,
`_make_impacts`): a true Gauss-Seidel sweep, deterministic, with no per-thread start-up for
each contact. Records and the loop made the passes of a 5,000-sphere pile 1.6 to 1.9 times
faster in float32 than thirty arrays read by one thread per contact. On CUDA a pass is one
thread per contact, a Jacobi iteration; each contact's impulse is then scaled by 1 / (largest
contact count of its two bodies) so that a body touched by many contacts is not over-corrected.

Warm starting: contacts are matched to the previous step's by body pair and by the distance
between their anchors on the pair's first dynamic body (the "owner"); previous contacts are
bucketed per owner by counting sort, so matching costs O(contacts x contacts per body).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import warp as wp

from ..collision.narrowphase import CONTACT_FIELDS, Contacts
from ..launch import LaunchCache, each_in_use, launch, launch_each
from ..model import body_arrays
from ..real import TYPES, BodyArrays, float_t, mat33, vec3
from ..shapes import ShapeType
from ..state import ArraySet, host_values
from ..structs import array_struct, fill_struct
from .rigid import add_to_velocity, inv_inertia_times, inv_inertia_world, safe_inverse

# no adjoint code: nothing differentiates through Tumble's kernels, and it doubles the compile time
wp.set_module_options({"enable_backward": False})

vec4 = wp.types.vector(length=4, dtype=float_t)

#: contact stiffness as a fraction of the substep rate (1/8: stiff, yet calm in tall stacks;
#: contacts with static bodies, which carry whole piles, are twice as stiff, as in Box2D),
#: and the damping ratio of the soft constraint
CONTACT_HERTZ_PER_SUBSTEP_RATE = 0.125
CONTACT_DAMPING_RATIO = 10.0
#: overlap [m] tolerated without push-out: resting contacts stay still
LINEAR_SLOP = 2.0e-5
#: largest speed [m/s] at which overlapping bodies are pushed apart
MAX_PUSH_VELOCITY = 3.0
#: Where a biased pass changed a manifold's body's velocity by more than RELAX_TRIGGER [m/s], or pushed
#: its overlap apart faster (CPU), the relax pass first sweeps without bias, up to RELAX_SWEEPS times,
#: over the manifolds of the bodies so marked, until a sweep changes none of their velocities by
#: RELAX_TOLERANCE [m/s]; then its one sweep over all. One relax sweep took back too little: of the push
#: in a knot of overlapping bodies (placed so: every body touches several), and the knot flew apart
#: (200 cubes of 0.2 m placed at random in a 1 m box: 36 kJ of kinetic energy, 15 m/s); and of a warm
#: start's excess between a heavy body and the floor (a heavy ball landing on a light one left the light
#: one's floor contact 224 times its weight, put back by the next step's warm start: random drops
#: gained up to 0.21 J in a step). docs/design.md, "Mass ratios".
RELAX_TRIGGER = wp.constant(float_t(0.1))
RELAX_SWEEPS = wp.constant(8)
RELAX_TOLERANCE = wp.constant(float_t(0.01))
#: most collision sweeps per pass (CPU); a resting scene takes one, a cluster of impacts a few
IMPACT_SWEEPS = wp.constant(16)
#: most collision sweeps per pass while inelastic contacts still collide: a collision passing along a
#: row of touching bodies converges slowly under Gauss-Seidel (a row of ten balls: 0.92 of the error
#: left after each sweep), and what is left goes to the soft rows, which spread the row apart
INELASTIC_IMPACT_SWEEPS = wp.constant(256)
#: a patch's collision: rounds of its friction and twist, then its normal rows, at most (`_patch_impact_friction`).
#: Each round leaves ~0.6 of the last's sliding at a cube's face centre (the turn that friction's moment
#: gives, which the corners take back): 2 m/s stops to MANIFOLD_TOLERANCE in ~25 rounds
PATCH_IMPACT_ROUNDS = wp.constant(64)
#: `_rebound`'s answer for a contact that does not collide (its speeds may be negative: a landing)
NO_IMPACT = wp.constant(float_t(-1.0e30))
#: anchors on the owner closer than this fraction of its bound radius are the same contact
MATCH_TOLERANCE = 0.5
#: a manifold: a pair's consecutive contacts (the narrow phase writes a pair's points together),
#: in runs of up to this many, whose normal rows are solved together (see `_solve`)
MANIFOLD_ROWS = wp.constant(4)
#: Gauss-Seidel sweeps over one manifold's rows in each solve and relax pass, at most (six: with
#: four, a cube landing flat at 10 m/s kept 1.2e-8 m/s of sideways speed from the corners' order,
#: against 1e-8 in tests/regression/test_issue_16_*); a block stops sweeping once a sweep changed
#: none of its impulses by more than MANIFOLD_SWEEP_TOLERANCE times the block's load (the sum of its
#: normal impulses; the twist row: times sum_i jn_i arm_i), as the warm-started blocks of a resting
#: stack do after one. In the collision pass, sweeps until no row changes its velocity by
#: MANIFOLD_TOLERANCE [m/s] (at most IMPACT_SWEEPS)
MANIFOLD_SWEEPS = wp.constant(6)
#: In float32 a sweep's rounding alone changes a resting block's impulses by ~1e-4..3e-4 of its
#: load (box_pyramid: 1e-6 was never met, every block swept MANIFOLD_SWEEPS times, 5.8 on average
#: against 1.0 in float64); so the tolerance is at least 8192 ulps of the load (float32: 9.8e-4,
#: 1.02 sweeps a block, the pyramid's top as far off; float64: 1e-6)
MANIFOLD_SWEEP_TOLERANCE = wp.constant(float_t(max(1.0e-6, 8192.0 * TYPES.eps)))
MANIFOLD_TOLERANCE = wp.constant(float_t(1.0e-5))
#: a dynamic body's friction anchor turns with it within the step (as a kinematic body's always does)
#: when it is more than this many times as far from its centre as the other body's: a turntable's
#: under a rider. Then the contact moves with the rider, and so with the table's turn; the rider's
#: own anchor, near its centre, barely moves. (Without it a rider on a motor-driven table crept
#: outwards at w^2 r dt / 2.) Not for bodies of a size (a sphere rolling on a sphere: its contact
#: point does not turn with it), so not every anchor
FAR_ANCHOR_RATIO = wp.constant(float_t(2.0))


@wp.struct
class ContactRow:
    """One contact as the solver's passes read it: prepared once per step (`_prepare`) from the
    narrow phase's contact and last step's impulses, then read and updated by every pass.

    Solver scratch, one record per contact (`ContactSet.rows`): a pass reads a contact's data
    from one contiguous record rather than from a row of thirty arrays (on the CPU the contact
    passes ran 1.6 to 1.9 times faster so, pile_5k in float32).
    """

    # (fields in the order the passes read them: the collision pass's test reads the first line or two)
    body_a: wp.int32
    body_b: wp.int32
    # rows of the manifold that starts here (its pair's next contacts, up to MANIFOLD_ROWS), 0 inside one
    manifold: wp.int32
    # friction anchors that turn with their body within the step (`_turned`, `_turns`): 1 a's, 2 b's,
    # 3 both; set on every row, read on a manifold's first (in the record's padding: no cost)
    turning: wp.int32
    restitution: float_t
    impulse_n: float_t  # accumulated impulses of one substep [N s]
    separation: float_t  # [m] at the step's start, negative when overlapping
    # where the anchors were moved to meet (`_impact_anchors`): the gap still follows the surface
    # points, s += gap_turn . (gap_share dtheta_a + (1 - gap_share) dtheta_b) (0 for other contacts)
    gap_share: float_t
    gap_turn: vec3
    # two spheres: the sum of their radii [m], and their gap follows their centres exactly
    # (`_gap`); 0 for other pairs
    radii: float_t
    normal: vec3  # unit, a -> b
    r_a: vec3  # anchor offsets from the centres, world frame at step start [m]
    r_b: vec3
    impulse_t1: float_t
    impulse_t2: float_t
    friction: float_t
    scale: float_t  # 1 on the CPU; Jacobi relaxation on CUDA
    mass_n: float_t  # effective masses [kg]
    mass_t1: float_t
    mass_t2: float_t
    tangent1: vec3
    tangent2: vec3
    # angular velocity change per unit impulse along n, t1, t2: I^-1 (r x d), world frame
    angular_a_n: vec3
    angular_b_n: vec3
    angular_a_t1: vec3
    angular_b_t1: vec3
    angular_a_t2: vec3
    angular_b_t2: vec3
    relative_velocity: float_t  # normal speed at this step's last impact [m/s] (< 0), else 0
    # a patch (a manifold whose rows share the normal) has its friction at its centre: anchors of
    # the centre (world frame, from the centres [m]), the twist row about n on its first row
    # (I^-1 n, effective mass [kg m^2]), each point's arm [m] from the centre across n
    impulse_twist: float_t  # [N m s]
    mass_twist: float_t
    twist_arm: float_t
    centre_a: vec3
    centre_b: vec3
    angular_a_twist: vec3
    angular_b_twist: vec3


PREVIOUS_FIELDS = {
    "previous_body_a": wp.int32,
    "previous_body_b": wp.int32,
    "previous_local_owner": vec3,
    "previous_impulse_n": float_t,
    "previous_impulse_t": vec3,  # friction impulse as a world vector (tangents change), plus the twist along n
}


#: last step's contacts as the kernels take them: `previous_body_a` is `p.body_a`
Previous = array_struct("Previous", PREVIOUS_FIELDS, "previous_", __name__)


@wp.func(inline=True)
def _speed_along(b: BodyArrays, ia: int, ib: int, ra: vec3, rb: vec3, d: vec3):
    """Relative velocity of the anchors along d: d . (v_b + w_b x r_b - v_a - w_a x r_a)."""
    return (
        wp.dot(b.velocity[ib] - b.velocity[ia], d)
        + wp.dot(b.angular_velocity[ib], wp.cross(rb, d))
        - wp.dot(b.angular_velocity[ia], wp.cross(ra, d))
    )


# ---------------------------------------------------------------------------- manifolds


@wp.func
def _manifold_first(c: Contacts, k: int):
    """The first row of the manifold contact k belongs to: a pair's consecutive contacts (the
    narrow phase writes a pair's points together), cut into pieces of MANIFOLD_ROWS."""
    before = int(0)
    j = k - 1
    while j >= 0:
        if c.body_a[j] != c.body_a[k] or c.body_b[j] != c.body_b[k]:
            break
        before += 1
        j -= 1
    return k - before % MANIFOLD_ROWS


@wp.func
def _manifold_rows(c: Contacts, first: int, count: int):
    """Rows of the manifold that starts at `first`."""
    rows = int(1)
    while rows < MANIFOLD_ROWS and first + rows < count:
        if c.body_a[first + rows] != c.body_a[first] or c.body_b[first + rows] != c.body_b[first]:
            break
        rows += 1
    return rows


# ---------------------------------------------------------------------------- warm-start matching


@wp.func
def _owner(a: int, b: int, inv_mass: wp.array(dtype=float_t)):
    """The contact's first dynamic body: the one whose anchor identifies the contact next step."""
    if inv_mass[a] == float_t(0.0):
        return b
    return a


@wp.struct
class Owners:
    """Last step's contacts bucketed by owner (counting sort): the contacts of body o are
    `entries[start[o] : start[o] + count[o]]`; `fill` counts them in while scattering."""

    start: wp.array(dtype=wp.int32)
    count: wp.array(dtype=wp.int32)
    fill: wp.array(dtype=wp.int32)
    entries: wp.array(dtype=wp.int32)


@wp.kernel
def _owner_count(p: Previous, b: BodyArrays, o: Owners, counts: wp.array(dtype=wp.int32), serial: int):
    for c in range(wp.tid(), each_in_use(wp.tid(), serial, counts[1], p.body_a.shape[0])):
        wp.atomic_add(o.count, _owner(p.body_a[c], p.body_b[c], b.inv_mass), 1)


@wp.kernel
def _owner_scatter(p: Previous, b: BodyArrays, o: Owners, counts: wp.array(dtype=wp.int32), serial: int):
    for c in range(wp.tid(), each_in_use(wp.tid(), serial, counts[1], p.body_a.shape[0])):
        owner = _owner(p.body_a[c], p.body_b[c], b.inv_mass)
        o.entries[o.start[owner] + wp.atomic_add(o.fill, owner, 1)] = c


@wp.kernel
def _match(
    c: Contacts,
    b: BodyArrays,
    tolerance: float_t,
    owners: Owners,
    p: Previous,
    jn_warm: wp.array(dtype=float_t),
    jt_world: wp.array(dtype=vec3),
    counts: wp.array(dtype=wp.int32),
    serial: int,
):
    for k in range(wp.tid(), each_in_use(wp.tid(), serial, counts[0], c.body_a.shape[0])):
        ia = c.body_a[k]
        ib = c.body_b[k]
        o = ia
        local = c.local_a[k]
        if b.inv_mass[ia] == float_t(0.0):
            o = ib
            local = c.local_b[k]
        best = int(-1)
        best_d = (tolerance * b.bound_radius[o]) * (tolerance * b.bound_radius[o])
        start = owners.start[o]
        for e in range(start, start + owners.count[o]):
            j = owners.entries[e]
            if p.body_a[j] == ia and p.body_b[j] == ib:
                d = wp.length_sq(p.local_owner[j] - local)
                if d < best_d:
                    best_d = d
                    best = j
        if best >= 0:
            jn_warm[k] = p.impulse_n[best]
            jt_world[k] = p.impulse_t[best]
        else:
            jn_warm[k] = float_t(0.0)
            jt_world[k] = vec3()


@wp.kernel
def _store(
    c: Contacts,
    rows: wp.array(dtype=ContactRow),
    b: BodyArrays,
    p: Previous,
    counts: wp.array(dtype=wp.int32),
    serial: int,
):
    for k in range(wp.tid(), each_in_use(wp.tid(), serial, counts[0], rows.shape[0])):
        r = rows[k]
        p.body_a[k] = r.body_a
        p.body_b[k] = r.body_b
        if b.inv_mass[r.body_a] == float_t(0.0):
            p.local_owner[k] = c.local_b[k]
        else:
            p.local_owner[k] = c.local_a[k]
        p.impulse_n[k] = r.impulse_n
        # friction as a world vector, the twist along n; a patch's (on its first row) spread over its rows
        first = k
        while rows[first].manifold == 0:
            first -= 1
        f = r
        share = float_t(1.0)
        head = rows[first]
        if head.mass_twist > float_t(0.0):
            f = head
            share = float_t(1.0) / float_t(head.manifold)
        p.impulse_t[k] = (f.tangent1 * f.impulse_t1 + f.tangent2 * f.impulse_t2 + f.normal * f.impulse_twist) * share


# ---------------------------------------------------------------------------- prepare / solve


@wp.kernel
def _body_contact_count(c: Contacts, count: wp.array(dtype=wp.int32), counts: wp.array(dtype=wp.int32), serial: int):
    for k in range(wp.tid(), each_in_use(wp.tid(), serial, counts[0], c.body_a.shape[0])):
        wp.atomic_add(count, c.body_a[k], 1)
        wp.atomic_add(count, c.body_b[k], 1)


# ---------------------------------------------------------------------------- anchors of a collision


@wp.func
def _meeting_share(b: BodyArrays, ia: int, ib: int):
    """How the gap between a contact's two anchors is closed when they are made to meet (`_impact_anchors`,
    `_impact`): the part a's anchor moves (b's moves the rest); -1 where they are left as they are.

    Only between two dynamic bodies (a static or kinematic body takes any angular momentum). A
    sphere's anchor, its support point towards the other body, stays (so a frictionless hit gives a
    sphere no spin) and the other anchor moves the whole way; two other bodies' meet halfway; two
    spheres' anchors lie on the line of centres already.
    """
    if b.inv_mass[ia] == float_t(0.0) or b.inv_mass[ib] == float_t(0.0):
        return float_t(-1.0)
    sa = b.shape[ia] == int(ShapeType.SPHERE)
    sb = b.shape[ib] == int(ShapeType.SPHERE)
    if sa and sb:
        return float_t(-1.0)
    if sa:
        return float_t(0.0)
    if sb:
        return float_t(1.0)
    return float_t(0.5)


@wp.func
def _impact_anchors(
    b: BodyArrays, ia: int, ib: int, n: vec3, ra: vec3, rb: vec3, s0: float_t, load: float_t, dt: float_t
):
    """(r_a, r_b, share, turn) of a speculative contact between two dynamic bodies: its anchors made to
    meet where the bodies will be when it collides, rather than where they were at the step's start.

    An impulse P whose anchors are apart by g changes the pair's angular momentum by g x P, and
    the anchors' offsets stay fixed through the step while the bodies move. A speculative
    contact (s0 > 0, closing at v_n < 0) is found up to a step's approach early and collides
    later in the step: with its anchors at their start offsets, an off-centre hit of two boxes
    at dt = 1/240 s lost 1.4 % of the pair's angular momentum. So its anchors are made to meet
    (`_meeting_share`) at the bodies' centres predicted at the moment t = min(s0 / -v_n, dt) (at
    the step start's velocities; gravity moves both bodies alike). The impulses act at the moved
    anchors; the gap still follows the surface points found by the narrow phase, through `share`
    and `turn` = d x n, d the move (`ContactRow.gap_turn`): moved anchors turning with their
    bodies would misjudge it (a rain of boxes overlapped up to 12 mm, against 8). A contact that
    touches at the start, or carried load last step (`load`, its warm-start impulse: a resting or
    rolling contact that opened a little), keeps its anchors (share and turn 0): its bodies barely
    slide within a step, and its impulses act all through it. (Moved, such contacts kept a
    capsule rolling in a hollow for seconds: the gap follows the surface points while the
    impulses act at the anchors, and under rolling the two part.)
    """
    none = vec3()
    share = _meeting_share(b, ia, ib)
    if share < float_t(0.0) or s0 <= float_t(0.0) or load > float_t(0.0):
        return ra, rb, float_t(0.0), none
    vn = _speed_along(b, ia, ib, ra, rb, n)
    if vn >= float_t(0.0):
        return ra, rb, float_t(0.0), none  # opening: no impulse expected
    t = wp.min(s0 / -vn, dt)
    # the anchors' gap at the centres predicted for t, closed as `_met` closes it now
    g = (b.position[ib] + b.velocity[ib] * t) - (b.position[ia] + b.velocity[ia] * t) + rb - ra
    ra_t, rb_t = _closed(share, ra, rb, g)
    return ra_t, rb_t, share, wp.cross(g, n)


@wp.func
def _gap_turn(rows: wp.array(dtype=ContactRow), k: int, dtha: vec3, dthb: vec3):
    """The part of row k's gap [m] that its moved anchors leave out (`_impact_anchors`), at the turns dtha, dthb."""
    return wp.dot(rows[k].gap_turn, dtha * rows[k].gap_share + dthb * (float_t(1.0) - rows[k].gap_share))


@wp.func
def _gap(
    rows: wp.array(dtype=ContactRow), k: int, b: BodyArrays, dxa: vec3, dtha: vec3, dxb: vec3, dthb: vec3, curved: int
):
    """Row k's gap [m] now, its bodies moved by dxa, dtha and dxb, dthb since the step began.

    Linearised in that motion along the step start's normal, from the anchors:
    s = s0 + n . ((dx_b + dtheta_b x r_b) - (dx_a + dtheta_a x r_a)) (plus `_gap_turn`). Between
    two spheres it is exact from their centres instead, |x_b - x_a| - R (R the sum of their radii):
    a ball moving along another's surface moves along the start's tangent plane, which the sphere
    curves away from, and the linearised contact held it there, pushing it out a little every
    substep; a ball sliding off the top of a sphere so left it early, bouncing along a gap of a few
    tenths of a millimetre. For a speculative contact whose normal is the line of centres at impact
    (`collide_sphere_sphere`) both reach 0 at that moment.

    (The spheres' gap is written as the part the linear one leaves out, added to it: the same value
    but for rounding, and the rounding the trajectories of piles and samples have.)

    The exact gap is the solve passes' (`curved` 1); the collision pass takes the linear one
    (`curved` 0), whose closing test then matches the approach speed it measures along the step
    start's normal. With the exact gap there too, a ball sliding past another along the floor was
    found not to close within the substep, its approach was left to the solve, and the impulse
    the solve kept for the next step's warm start pushed the pair apart again: a frictionless
    settling gas (e = 0.3 and 0.7, six seeds, 480 steps each) gained up to 6.4e-4 J in a step;
    with the linear gap there, 2.3e-6 J at most (the linear gap in every pass: 7e-7 J).
    """
    n = rows[k].normal
    s0 = rows[k].separation + _gap_turn(rows, k, dtha, dthb)
    radii = rows[k].radii
    if curved != 0 and radii != float_t(0.0):
        exact = wp.length(b.position[rows[k].body_b] - b.position[rows[k].body_a]) - radii
        s0 = s0 + (exact - rows[k].separation - wp.dot(n, dxb - dxa))
    return s0 + wp.dot(n, dxb + wp.cross(dthb, rows[k].r_b) - dxa - wp.cross(dtha, rows[k].r_a))


@wp.func
def _met(share: float_t, ra: vec3, rb: vec3, centres: vec3):
    """The anchors ra, rb [m] moved to meet, a's by `share` of the way (`_meeting_share`; < 0: left as
    they are), with b's centre at `centres` [m] from a's."""
    if share < float_t(0.0):
        return ra, rb
    return _closed(share, ra, rb, centres + rb - ra)


@wp.func
def _closed(share: float_t, ra: vec3, rb: vec3, g: vec3):
    """The anchors ra, rb [m], b's apart from a's by g [m], moved to meet: a's by `share` of g, b's by the rest."""
    return ra + g * share, rb - g * (float_t(1.0) - share)


@wp.kernel
def _prepare(
    c: Contacts,
    b: BodyArrays,
    jn_warm: wp.array(dtype=float_t),
    jt_world: wp.array(dtype=vec3),
    jacobi: int,
    body_count: wp.array(dtype=wp.int32),
    counts: wp.array(dtype=wp.int32),
    rows: wp.array(dtype=ContactRow),
    dt: float_t,
    serial: int,
):
    for k in range(wp.tid(), each_in_use(wp.tid(), serial, counts[0], rows.shape[0])):
        r = ContactRow()
        ia = c.body_a[k]
        ib = c.body_b[k]
        n = c.normal[k]
        r.body_a = ia
        r.body_b = ib
        r.normal = n
        qa = b.orientation[ia]
        qb = b.orientation[ib]
        # anchors in the world frame, where the contact collides if it is ahead (`_impact_anchors`)
        ra, rb, share, turn = _impact_anchors(
            b,
            ia,
            ib,
            n,
            wp.quat_rotate(qa, c.local_a[k]),
            wp.quat_rotate(qb, c.local_b[k]),
            c.separation[k],
            jn_warm[k],
            dt,
        )
        r.separation = c.separation[k]
        r.gap_share = share
        r.gap_turn = turn
        r.radii = float_t(0.0)
        if b.shape[ia] == int(ShapeType.SPHERE) and b.shape[ib] == int(ShapeType.SPHERE):
            r.radii = b.radius[ia] + b.radius[ib]
        r.r_a = ra
        r.r_b = rb
        # manifold: the first row holds its row count, the others 0. It is a patch when its rows
        # share one normal (a face on a plane or a face: up to 4 points, one normal); a patch takes
        # its friction at its centre (the mean of its anchors), as two tangent rows and a twist row
        # about n held on its first row, instead of one friction row per point (see `_solve_manifold`)
        first = _manifold_first(c, k)
        size = _manifold_rows(c, first, counts[0])
        r.manifold = wp.int32(0)
        if first == k:
            r.manifold = wp.int32(size)
        patch = int(0)
        fa = ra
        fb = rb
        if size > 1:
            patch = int(1)
            fa = vec3()
            fb = vec3()
            for i in range(size):
                kk = first + i
                if wp.dot(c.normal[kk], c.normal[first]) < float_t(1.0) - float_t(1.0e-12):
                    patch = int(0)
                pa, pb, _share, _turn = _impact_anchors(
                    b,
                    ia,
                    ib,
                    c.normal[kk],
                    wp.quat_rotate(qa, c.local_a[kk]),
                    wp.quat_rotate(qb, c.local_b[kk]),
                    c.separation[kk],
                    jn_warm[kk],
                    dt,
                )
                fa = fa + pa
                fb = fb + pb
            fa = fa / float_t(size)
            fb = fb / float_t(size)
        if patch == 0:
            # rows with differing normals (a box or hull on a mesh, a capsule) are not coupled by a
            # shared face: each is its own manifold of one row, as a lone contact
            fa = ra
            fb = rb
            r.manifold = wp.int32(1)
        # twist arm: the point's distance from the patch centre across n (the twist row's limit is
        # mu sum_i jn_i arm_i, the most torque the points' friction can give)
        arm = ra - fa
        r.twist_arm = float_t(patch) * wp.length(arm - n * wp.dot(arm, n))
        r.centre_a = fa
        r.centre_b = fb
        r.turning = wp.int32(0)
        if _turns(b, ia, fa, fb):
            r.turning = wp.int32(1)
        if _turns(b, ib, fb, fa):
            r.turning = r.turning + wp.int32(2)
        # tangent basis orthogonal to n
        t1 = wp.cross(n, vec3(float_t(1.0), float_t(0.0), float_t(0.0)))
        if wp.length_sq(t1) < float_t(0.01):
            t1 = wp.cross(n, vec3(float_t(0.0), float_t(1.0), float_t(0.0)))
        t1 = wp.normalize(t1)
        t2 = wp.cross(n, t1)
        r.tangent1 = t1
        r.tangent2 = t2
        # world inverse inertia I^-1 = R diag(1/I) R^T once per body, then per direction d:
        # angular response I^-1 (r x d) and effective mass 1 / (1/m_a + 1/m_b + (r_a x d) . I_a^-1 (r_a x d) + ...)
        Ia = inv_inertia_world(qa, b.inv_inertia[ia])
        Ib = inv_inertia_world(qb, b.inv_inertia[ib])
        im = b.inv_mass[ia] + b.inv_mass[ib]
        ca = wp.cross(ra, n)
        cb = wp.cross(rb, n)
        r.angular_a_n = Ia * ca
        r.angular_b_n = Ib * cb
        r.mass_n = safe_inverse(im + wp.dot(ca, Ia * ca) + wp.dot(cb, Ib * cb))
        # friction rows at the anchors (the patch centre for a patch); a patch's other rows have none
        on = float_t(1.0)
        if patch != 0 and first != k:
            on = float_t(0.0)
        ca = wp.cross(fa, t1)
        cb = wp.cross(fb, t1)
        r.angular_a_t1 = Ia * ca * on
        r.angular_b_t1 = Ib * cb * on
        r.mass_t1 = safe_inverse(im + wp.dot(ca, Ia * ca) + wp.dot(cb, Ib * cb)) * on
        ca = wp.cross(fa, t2)
        cb = wp.cross(fb, t2)
        r.angular_a_t2 = Ia * ca * on
        r.angular_b_t2 = Ib * cb * on
        r.mass_t2 = safe_inverse(im + wp.dot(ca, Ia * ca) + wp.dot(cb, Ib * cb)) * on
        # twist about n: angular response I^-1 n, effective mass 1 / (n . I_a^-1 n + n . I_b^-1 n)
        tw = float_t(0.0)
        if patch != 0 and first == k:
            tw = float_t(1.0)
        r.angular_a_twist = Ia * n * tw
        r.angular_b_twist = Ib * n * tw
        r.mass_twist = safe_inverse(wp.dot(n, Ia * n) + wp.dot(n, Ib * n)) * tw
        # combination rules: mu = sqrt(mu_a mu_b), e = max(e_a, e_b)
        r.friction = wp.sqrt(b.friction[ia] * b.friction[ib])
        r.restitution = wp.max(b.restitution[ia], b.restitution[ib])
        r.relative_velocity = float_t(0.0)  # set by _impact when the contact collides
        # warm start values arrive as a world friction vector (tangent) plus the twist impulse along
        # n; project on the new tangents. A patch's friction was stored spread over its rows (so it
        # survives a change of which row comes first): its first row sums its rows' shares
        r.impulse_n = jn_warm[k]
        jt = jt_world[k]
        if patch != 0:
            jt = vec3()
            if first == k:
                for i in range(size):
                    jt = jt + jt_world[k + i]
        r.impulse_t1 = wp.dot(jt, t1)
        r.impulse_t2 = wp.dot(jt, t2)
        r.impulse_twist = wp.dot(jt, n) * tw
        r.scale = float_t(1.0)
        if jacobi != 0:
            r.scale = float_t(1.0) / float_t(wp.max(body_count[ia], body_count[ib]))
        rows[k] = r


@wp.struct
class Delta:
    """A contact's velocity changes to its two bodies, accumulated over its rows."""

    va: vec3
    wa: vec3
    vb: vec3
    wb: vec3


@wp.func
def _delta(va: vec3, wa: vec3, vb: vec3, wb: vec3):
    """A Delta of the given changes."""
    d = Delta()
    d.va = va
    d.wa = wa
    d.vb = vb
    d.wb = wb
    return d


@wp.func
def _add_pair(b: BodyArrays, ia: int, ib: int, d: Delta, serial: int):
    """Add one contact's changes d to the velocities of its two bodies (static bodies never change):
    plain updates on the CPU (`serial`), one contact after another (Gauss-Seidel); else atomics (CUDA)."""
    if b.inv_mass[ia] > float_t(0.0):
        add_to_velocity(b.velocity, b.angular_velocity, ia, d.va, d.wa, serial)
    if b.inv_mass[ib] > float_t(0.0):
        add_to_velocity(b.velocity, b.angular_velocity, ib, d.vb, d.wb, serial)


@wp.kernel
def _warm_start(rows: wp.array(dtype=ContactRow), b: BodyArrays, counts: wp.array(dtype=wp.int32), serial: int):
    for k in range(wp.tid(), each_in_use(wp.tid(), serial, counts[0], rows.shape[0])):
        r = rows[k]
        jn = r.impulse_n
        j1 = r.impulse_t1
        j2 = r.impulse_t2
        P = r.normal * jn + r.tangent1 * j1 + r.tangent2 * j2
        dwa = r.angular_a_n * jn + r.angular_a_t1 * j1 + r.angular_a_t2 * j2 + r.angular_a_twist * r.impulse_twist
        dwb = r.angular_b_n * jn + r.angular_b_t1 * j1 + r.angular_b_t2 * j2 + r.angular_b_twist * r.impulse_twist
        ia = r.body_a
        ib = r.body_b
        _add_pair(b, ia, ib, _delta(-P * b.inv_mass[ia], -dwa, P * b.inv_mass[ib], dwb), serial)


@wp.struct
class Pair:
    """A contact's two bodies as its rows see them: velocities at the start of the pass, inverse masses."""

    va: vec3
    wa: vec3
    vb: vec3
    wb: vec3
    ima: float_t
    imb: float_t


@wp.func(inline=True)
def _turns(b: BodyArrays, i: int, own: vec3, other: vec3):
    """Whether body i's friction anchor `own` (from its centre; `other` the other body's) turns with
    it within the step: the body turns, and it is kinematic, or its anchor is more than
    FAR_ANCHOR_RATIO times as far from its centre as the other's (a turntable under a rider)."""
    if wp.length_sq(b.angular_velocity[i]) == float_t(0.0):
        return False
    if b.inv_mass[i] == float_t(0.0):
        return True
    return wp.length_sq(own) > FAR_ANCHOR_RATIO * FAR_ANCHOR_RATIO * wp.length_sq(other)


@wp.func(inline=True)
def _turned(dtheta: vec3, r: vec3):
    """An anchor offset r [m] turned with its body by the rotation dtheta [rad] since the step began (to first order)."""
    return r + wp.cross(dtheta, r)


@wp.func
def _friction_row(rows: wp.array(dtype=ContactRow), k: int, ra: vec3, rb: vec3, limit: float_t, pair: Pair, dv: Delta):
    """Coulomb friction of row k at the anchors ra, rb: |jt| <= limit, clamped on the disc.

    Updates the row's impulses; returns the pair's changes and the largest change of an impulse.
    (Rows are read field by field: a whole record copied to a local costs more than the fields used.)
    """
    t1 = rows[k].tangent1
    t2 = rows[k].tangent2
    relax = rows[k].scale
    j1_old = rows[k].impulse_t1
    j2_old = rows[k].impulse_t2
    v = pair.vb + dv.vb - pair.va - dv.va
    vt1 = wp.dot(v, t1) + wp.dot(pair.wb + dv.wb, wp.cross(rb, t1)) - wp.dot(pair.wa + dv.wa, wp.cross(ra, t1))
    vt2 = wp.dot(v, t2) + wp.dot(pair.wb + dv.wb, wp.cross(rb, t2)) - wp.dot(pair.wa + dv.wa, wp.cross(ra, t2))
    j1 = j1_old - rows[k].mass_t1 * vt1 * relax
    j2 = j2_old - rows[k].mass_t2 * vt2 * relax
    norm = wp.sqrt(j1 * j1 + j2 * j2)
    if norm > limit:
        f = limit / norm
        j1 = j1 * f
        j2 = j2 * f
    rows[k].impulse_t1 = j1
    rows[k].impulse_t2 = j2
    d1 = j1 - j1_old
    d2 = j2 - j2_old
    P = t1 * d1 + t2 * d2
    out = Delta()
    out.va = dv.va - P * pair.ima
    out.vb = dv.vb + P * pair.imb
    out.wa = dv.wa - rows[k].angular_a_t1 * d1 - rows[k].angular_a_t2 * d2
    out.wb = dv.wb + rows[k].angular_b_t1 * d1 + rows[k].angular_b_t2 * d2
    return out, wp.max(wp.abs(d1), wp.abs(d2))


@wp.struct
class SolvePass:
    """The parameters of one contact solve pass (`solve`), for the normal rows: the soft constraint's at this substep."""

    inv_h: float_t  # 1 / substep [1/s]
    use_bias: int  # 1: the pass with bias (overlap pushed out softly); 0: the relax pass
    bias_rate: float_t  # soft constraint (see `softness`)
    mass_scale: float_t
    impulse_scale: float_t
    static_bias_rate: float_t  # the same, twice as stiff, against a static body
    static_mass_scale: float_t
    static_impulse_scale: float_t
    max_push: float_t  # largest push-out speed [m/s]
    slop: float_t  # overlap not pushed out [m]


@wp.func
def _normal_target(s: float_t, p: SolvePass, static: bool, block: bool):
    """(bias, mass scale, impulse scale) of a normal row for this pass at its current gap s [m] (`_gap`;
    `block`: a row of a manifold).

    Speculative (s > 0) lets the gap close in one substep; overlap beyond the slop is pushed out
    softly (bias) and only in the biased pass; against a static body twice as stiff (it carries the
    whole pile).
    """
    bias = float_t(0.0)
    ms = float_t(1.0)
    isc = float_t(0.0)
    if s > float_t(0.0):
        bias = s * p.inv_h
    # a manifold's rows have no slop: soft from s = 0, as in Box2D v3 and Box3D. A rigid row in
    # the slop carries any load at no overlap, so a face's corner that sat at s = 0 took up to a
    # third of a cube's load while the soft corners sank, and the box tilted (0.8 mm across a
    # cube in a tower of ten at dt = 1/60 s, 4 substeps, whose top then leaned 11 mm). The four
    # rows then settle evenly, each at F_i / (m_n omega^2), micrometres under a few bodies' weight.
    # A lone contact has no such freedom and keeps its rigid slop
    slop = p.slop
    if block:
        slop = float_t(0.0)
    if p.use_bias != 0 and s < -slop:
        ms = p.mass_scale
        isc = p.impulse_scale
        bias = wp.max(p.bias_rate * (s + slop), -p.max_push)
        if static:
            ms = p.static_mass_scale
            isc = p.static_impulse_scale
            bias = wp.max(p.static_bias_rate * (s + slop), -p.max_push)
    return bias, ms, isc


@wp.func
def _normal_row(
    rows: wp.array(dtype=ContactRow), k: int, bias: float_t, ms: float_t, isc: float_t, pair: Pair, dv: Delta
):
    """The normal row k, the soft step dj = -m_n ms (v_n + bias) - isc j, clamped to j >= 0.

    Updates the row's impulse; returns the pair's changes and |dj|. Its fixed point is
    v_n + bias + (isc / ms) j / m_n = 0, so sweeping it again solves the same soft row.
    """
    n = rows[k].normal
    vn = wp.dot(pair.vb + dv.vb - pair.va - dv.va, n) + wp.dot(pair.wb + dv.wb, wp.cross(rows[k].r_b, n))
    vn = vn - wp.dot(pair.wa + dv.wa, wp.cross(rows[k].r_a, n))
    jn_old = rows[k].impulse_n
    jn = wp.max(jn_old + (-rows[k].mass_n * ms * (vn + bias) - isc * jn_old) * rows[k].scale, float_t(0.0))
    rows[k].impulse_n = jn
    dj = jn - jn_old
    out = Delta()
    out.va = dv.va - n * (dj * pair.ima)
    out.vb = dv.vb + n * (dj * pair.imb)
    out.wa = dv.wa - rows[k].angular_a_n * dj
    out.wb = dv.wb + rows[k].angular_b_n * dj
    return out, wp.abs(dj)


@wp.func
def _block_load(rows: wp.array(dtype=ContactRow), k: int, size: int):
    """The load sum_i jn_i [N s] of the manifold block of `size` rows at k, and its twist limit's sum_i jn_i arm_i [N m s]."""
    load = float_t(0.0)
    torque = float_t(0.0)
    for i in range(size):
        load += rows[k + i].impulse_n
        torque += rows[k + i].impulse_n * rows[k + i].twist_arm
    return load, torque


@wp.func
def _sticking_point(
    rows: wp.array(dtype=ContactRow), k: int, bias: float_t, ms: float_t, isc: float_t, pair: Pair, dv: Delta
):
    """A lone contact whose normal and friction rows are coupled (an anchor off the line of the
    normal through a body's centre: a corner, a rod's end) held sticking, its three rows solved
    together: the impulse change dj with (K + diag(c, 0, 0)) dj = -(v_n + bias + c j_n, v_t1, v_t2),
    K the point's 3x3 inverse mass along (n, t1, t2), c = (isc / ms) / m_n the normal row's
    softness (as `_normal_row`'s fixed point). Kept (1) when the new impulses push (j_n >= 0) and lie
    in the friction cone (|j_t| <= mu j_n); else (0) nothing is changed and the rows are swept.

    A friction row then a normal row, once a pass, leave a coupled point slipping: the normal
    impulse turns the body and moves the point sideways, and the friction row saw only the last
    pass's load. A 1 m capsule (r = 1 cm) striking the floor with its end at 2 m/s, 45 degrees,
    e = 0, mu = 5 (sticking: |j_t| / j_n = 0.78) left the floor with its end slipping at 0.12 m/s
    and lifting at 0.025 m/s, v_x 0.828 m/s against the sticking impulse's 0.750; a box's corner
    likewise. A sphere's anchor is on the normal through its centre: no coupling, no block.
    """
    n = rows[k].normal
    ra = rows[k].r_a
    rb = rows[k].r_b
    im = pair.ima + pair.imb
    can = wp.cross(ra, n)
    cbn = wp.cross(rb, n)
    knn = im + wp.dot(can, rows[k].angular_a_n) + wp.dot(cbn, rows[k].angular_b_n)
    k1n = wp.dot(can, rows[k].angular_a_t1) + wp.dot(cbn, rows[k].angular_b_t1)
    k2n = wp.dot(can, rows[k].angular_a_t2) + wp.dot(cbn, rows[k].angular_b_t2)
    out = dv
    if k1n * k1n + k2n * k2n <= float_t(1.0e-12) * knn * knn:
        return out, 0  # uncoupled (a sphere): the rows one after the other are exact
    t1 = rows[k].tangent1
    t2 = rows[k].tangent2
    ca1 = wp.cross(ra, t1)
    cb1 = wp.cross(rb, t1)
    k11 = im + wp.dot(ca1, rows[k].angular_a_t1) + wp.dot(cb1, rows[k].angular_b_t1)
    k12 = wp.dot(ca1, rows[k].angular_a_t2) + wp.dot(cb1, rows[k].angular_b_t2)
    k22 = im + wp.dot(wp.cross(ra, t2), rows[k].angular_a_t2) + wp.dot(wp.cross(rb, t2), rows[k].angular_b_t2)
    c = float_t(0.0)
    if ms > float_t(0.0):
        c = isc / ms * knn
    a = mat33(knn + c, k1n, k2n, k1n, k11, k12, k2n, k12, k22)
    det = wp.determinant(a)
    if not (det > float_t(1.0e-12) * (knn + c) * k11 * k22):
        return out, 0
    v = pair.vb + dv.vb - pair.va - dv.va
    wa = pair.wa + dv.wa
    wb = pair.wb + dv.wb
    vn = wp.dot(v, n) + wp.dot(wb, cbn) - wp.dot(wa, can)
    v1 = wp.dot(v, t1) + wp.dot(wb, cb1) - wp.dot(wa, ca1)
    v2 = wp.dot(v, t2) + wp.dot(wb, wp.cross(rb, t2)) - wp.dot(wa, wp.cross(ra, t2))
    jn_old = rows[k].impulse_n
    j1_old = rows[k].impulse_t1
    j2_old = rows[k].impulse_t2
    d = wp.inverse(a) * vec3(-(vn + bias + c * jn_old), -v1, -v2)
    jn = jn_old + d[0]
    j1 = j1_old + d[1]
    j2 = j2_old + d[2]
    if jn < float_t(0.0):
        # it would have to pull: released instead (no impulse at all) if it then opens. Row by row
        # the warm-started friction of last step's impact outlived its normal impulse (cleared
        # first), and the friction row's removal, coupled, drove the normal row to push
        d = vec3(-jn_old, -j1_old, -j2_old)
        if vn + knn * d[0] + k1n * d[1] + k2n * d[2] + bias < float_t(0.0):
            return out, 0
        jn = float_t(0.0)
        j1 = float_t(0.0)
        j2 = float_t(0.0)
    elif j1 * j1 + j2 * j2 > rows[k].friction * rows[k].friction * jn * jn:
        return out, 0
    rows[k].impulse_n = jn
    rows[k].impulse_t1 = j1
    rows[k].impulse_t2 = j2
    P = n * d[0] + t1 * d[1] + t2 * d[2]
    out.va = dv.va - P * pair.ima
    out.vb = dv.vb + P * pair.imb
    out.wa = dv.wa - rows[k].angular_a_n * d[0] - rows[k].angular_a_t1 * d[1] - rows[k].angular_a_t2 * d[2]
    out.wb = dv.wb + rows[k].angular_b_n * d[0] + rows[k].angular_b_t1 * d[1] + rows[k].angular_b_t2 * d[2]
    return out, 1


@wp.func(inline=True)
def _has_lever(rows: wp.array(dtype=ContactRow), k: int, inv_masses: float_t):
    """Whether row k's anchor has a lever (r x n not 0 on a dynamic body), read from its normal mass:
    then 1 / m_n > 1/m_a + 1/m_b (`inv_masses`), beyond rounding."""
    return rows[k].mass_n * inv_masses < float_t(1.0) - float_t(1.0e-6)


@wp.func(inline=False)
def _lone_lever(k: int, rows: wp.array(dtype=ContactRow), bias: float_t, ms: float_t, isc: float_t, pair: Pair):
    """One pass over the lone contact k whose anchor has a lever (a corner, a capsule's end; its
    anchors not turning within the step), its normal row's target `bias, ms, isc`
    (`_normal_target`): the sticking block of its three rows (`_sticking_point`), or where that
    would leave the friction cone, its rows swept: normal, friction, normal. Friction is bounded by
    this pass's load, as a lone sphere's is (an inelastic impact's friction, else one pass late),
    and the normal row has the last word, since a friction impulse at a lever moves the normal
    speed. Returns the pair's velocity changes."""
    ra = rows[k].r_a
    rb = rows[k].r_b
    dv, held = _sticking_point(rows, k, bias, ms, isc, pair, Delta())
    if held == 0:
        dv, _ = _normal_row(rows, k, bias, ms, isc, pair, dv)
        dv, _ = _friction_row(rows, k, ra, rb, rows[k].friction * rows[k].impulse_n, pair, dv)
        dv, _ = _normal_row(rows, k, bias, ms, isc, pair, dv)
    return dv


@wp.func
def _lcp2(a00: float_t, a01: float_t, a11: float_t, b0: float_t, b1: float_t):
    """The two impulses j >= 0 with A j - b >= 0 and j . (A j - b) = 0, A = [[a00, a01], [a01, a11]]
    positive definite: a two-row block solved exactly, by its four cases (Box2D's block solver);
    the third value is 0 where none of them holds to rounding (A singular: two rows at one point),
    and the caller sweeps instead.

    Two rows of one pair (a box's edge, a rod's end, a capsule lying on a face) are coupled by
    the tilt they share, and Gauss-Seidel converges on them by (a01^2 / (a00 a11)) a sweep pair
    only: a 1 m x 2 cm rod landing on its end at 60 degrees, 0.41; after the six sweeps of a solve
    pass its two corners' impulses still differed by 0.8 %, which spun the frictionless rod at
    0.68 rad/s about its own axis.
    """
    det = a00 * a11 - a01 * a01
    tiny = float_t(1.0e-9) * a00 * a11
    if det > tiny:
        j0 = (a11 * b0 - a01 * b1) / det
        j1 = (a00 * b1 - a01 * b0) / det
        if j0 >= float_t(0.0) and j1 >= float_t(0.0):
            return j0, j1, 1
    if a00 > float_t(0.0):
        j0 = wp.max(b0, float_t(0.0)) / a00
        if a01 * j0 - b1 >= float_t(0.0):
            return j0, float_t(0.0), 1
    if a11 > float_t(0.0):
        j1 = wp.max(b1, float_t(0.0)) / a11
        if a01 * j1 - b0 >= float_t(0.0):
            return float_t(0.0), j1, 1
    return float_t(0.0), float_t(0.0), 0


@wp.func(inline=False)
def _normal_pair(rows: wp.array(dtype=ContactRow), k: int, bias4: vec4, ms4: vec4, isc4: vec4, pair: Pair, dv: Delta):
    """The two normal rows of the manifold at k solved together, exactly (`_lcp2`): each row at the
    fixed point of its soft step (`_normal_row`), v_n + bias + (isc / ms) j / m_n = 0, or at j = 0
    and separating. Returns the pair's changes, 1 (0 where the block is singular and nothing was
    done: sweep it) and the largest |dj|.
    """
    n = rows[k].normal  # a manifold's rows share their normal (a patch)
    ca0 = wp.cross(rows[k].r_a, n)
    cb0 = wp.cross(rows[k].r_b, n)
    ca1 = wp.cross(rows[k + 1].r_a, n)
    cb1 = wp.cross(rows[k + 1].r_b, n)
    v = pair.vb + dv.vb - pair.va - dv.va
    wa = pair.wa + dv.wa
    wb = pair.wb + dv.wb
    v0 = wp.dot(v, n) + wp.dot(wb, cb0) - wp.dot(wa, ca0)
    v1 = wp.dot(v, n) + wp.dot(wb, cb1) - wp.dot(wa, ca1)
    im = pair.ima + pair.imb
    k00 = im + wp.dot(ca0, rows[k].angular_a_n) + wp.dot(cb0, rows[k].angular_b_n)
    k11 = im + wp.dot(ca1, rows[k + 1].angular_a_n) + wp.dot(cb1, rows[k + 1].angular_b_n)
    k01 = im + wp.dot(ca0, rows[k + 1].angular_a_n) + wp.dot(cb0, rows[k + 1].angular_b_n)
    # softness: v_n + bias + c j = 0 with c = (isc / ms) / m_n (0 in the relax pass and when speculative)
    c0 = float_t(0.0)
    c1 = float_t(0.0)
    if ms4[0] > float_t(0.0):
        c0 = isc4[0] / ms4[0] * k00
    if ms4[1] > float_t(0.0):
        c1 = isc4[1] / ms4[1] * k11
    j0_old = rows[k].impulse_n
    j1_old = rows[k + 1].impulse_n
    b0 = -(v0 + bias4[0]) + k00 * j0_old + k01 * j1_old
    b1 = -(v1 + bias4[1]) + k01 * j0_old + k11 * j1_old
    j0, j1, ok = _lcp2(k00 + c0, k01, k11 + c1, b0, b1)
    out = dv
    if ok == 0:
        return out, 0, float_t(0.0)
    rows[k].impulse_n = j0
    rows[k + 1].impulse_n = j1
    d0 = j0 - j0_old
    d1 = j1 - j1_old
    out.va = dv.va - n * ((d0 + d1) * pair.ima)
    out.vb = dv.vb + n * ((d0 + d1) * pair.imb)
    out.wa = dv.wa - rows[k].angular_a_n * d0 - rows[k + 1].angular_a_n * d1
    out.wb = dv.wb + rows[k].angular_b_n * d0 + rows[k + 1].angular_b_n * d1
    return out, 1, wp.max(wp.abs(d0), wp.abs(d1))


@wp.func
def _two_row_patch(rows: wp.array(dtype=ContactRow), k: int):
    """Whether the manifold at row k is a patch of two rows (an edge, a rod's end): the one the
    passes give to `_solve_manifold_pair` and `_impact_pair_first`."""
    return rows[k].manifold == 2 and rows[k].mass_twist > float_t(0.0)


def _make_solve_manifold(exact_pair: bool):
    """`_solve_manifold`, or with `exact_pair` `_solve_manifold_pair`: the same pass over a manifold,
    where a two-row patch has its normal rows solved exactly (`_normal_pair`) instead of swept. Two
    functions from one source, so that the one every contact runs compiles as it did (with the
    block inside it, the solve of a pile of spheres and a rain of boxes ran 10 to 17 % slower), and
    the other is called for two-row patches alone."""

    @wp.func
    def _solve_manifold(
        k: int, rows: wp.array(dtype=ContactRow), b: BodyArrays, p: SolvePass, serial: int, last: int
    ) -> float_t:
        """One pass over the manifold that starts at row k (nothing at a row inside one): friction then
        normal rows, with bias or without (`p.use_bias`); the relax pass's `last` sweep also sums the
        rows' final impulses per body for the next substep's warm start.

        Returns, but for the relax pass's `last` sweep, the largest change this pass made to a body's
        velocity, squared [m^2/s^2]; with bias, at least the square of its fastest push-out.
        """
        size = rows[k].manifold
        if size == 0:
            return float_t(0.0)  # solved with the first row of its manifold
        ia = rows[k].body_a
        ib = rows[k].body_b
        # the two bodies' velocities and this manifold's changes to them, accumulated locally, stored once
        pair = Pair()
        pair.va = b.velocity[ia]
        pair.wa = b.angular_velocity[ia]
        pair.vb = b.velocity[ib]
        pair.wb = b.angular_velocity[ib]
        pair.ima = b.inv_mass[ia]
        pair.imb = b.inv_mass[ib]
        dxa = b.delta_position[ia]
        dtha = b.delta_rotation[ia]
        dxb = b.delta_position[ib]
        dthb = b.delta_rotation[ib]
        dv = Delta()
        push = float_t(0.0)  # the fastest push-out (-bias) of an overlapping normal row [m/s]
        static = pair.ima == float_t(0.0) or pair.imb == float_t(0.0)
        # friction's anchors on a turning kinematic body, or on a turning dynamic one far from the contact
        # beside the other, turn with it within the step (a turntable's surface velocity at the contact
        # turns with the table); other anchors stay as prepared. Only such pairs pay for it, flagged by
        # `_prepare` (deciding it here, and the turns made always, cost pile_1k 5 %)
        turning = rows[k].turning != 0
        turn_a = vec3()
        turn_b = vec3()
        if turning:
            if rows[k].turning % 2 == 1:
                turn_a = dtha
            if rows[k].turning >= 2:
                turn_b = dthb

        if size == 1:
            # a lone contact: its normal row, then its friction row (below)
            ra = rows[k].r_a
            rb = rows[k].r_b
            fa = ra
            fb = rb
            if turning:
                fa = _turned(turn_a, ra)
                fb = _turned(turn_b, rb)
            # a point with a lever (r x n not 0 on a dynamic body, so 1 / m_n > 1/m_a + 1/m_b) may stick
            # only as a block of its three rows (`_lone_lever`, a function of its own, not inlined, so
            # that the loop a sphere's contact runs stays as it was: its anchor is on the normal through
            # its centre, no lever but for rounding); the test is one product of fields read anyway
            lever = _has_lever(rows, k, pair.ima + pair.imb)
            # (the normal row's target depends on the positions only, not on the friction row's impulse)
            bias, ms, isc = _normal_target(_gap(rows, k, b, dxa, dtha, dxb, dthb, 1), p, static, False)
            push = -bias
            if serial == 0 or not lever or turning or rows[k].friction == float_t(0.0):
                # the normal row first, then friction bounded by this pass's load. Friction first saw the
                # last pass's, none at an inelastic impact (e = 0, no collision pass): a ball landing at
                # 3 m/s with 2 m/s across a rough floor slid on (zero g: for good; in gravity for 14
                # steps, at mu m g) instead of rolling off at 5/7 of it. A sphere's friction impulse moves
                # no normal speed (its anchor is on the normal through its centre), so its normal row
                # ends the same either way
                dv, _ = _normal_row(rows, k, bias, ms, isc, pair, dv)
                dv, _ = _friction_row(rows, k, fa, fb, rows[k].friction * rows[k].impulse_n, pair, dv)
            else:
                dv = _lone_lever(k, rows, bias, ms, isc, pair)
        else:
            # each normal row's target, fixed for the pass
            bias4 = vec4()
            ms4 = vec4()
            isc4 = vec4()
            for i in range(size):
                kk = k + i
                bias, ms, isc = _normal_target(_gap(rows, kk, b, dxa, dtha, dxb, dthb, 1), p, static, True)
                bias4[i] = bias
                ms4[i] = ms
                isc4[i] = isc
                push = wp.max(push, -bias)
            # The rows of a manifold share the body pair, so they are coupled (a corner's impulse also
            # moves the others) and the normal rows are rank-deficient (four coplanar corners, three
            # degrees of freedom): one sweep leaves each corner a different impulse and the body
            # rocking (after a fast flat landing, a quarter of the impact speed at the corners), and
            # friction bounded by those impulses, corner after corner, turns it into spin. So the
            # manifold's rows are swept forward and backward in turn, up to MANIFOLD_SWEEPS times:
            # projected Gauss-Seidel on the manifold's own block, whose velocities converge whatever
            # the order of the corners. Resting manifolds too: one forward sweep a pass at rest gave the
            # first corners more of the load every substep, and the remainder, held by friction, leaned
            # stacks over (a tower of ten 1 m cubes at dt = 1/60 s, 4 substeps: its top 11 mm off its
            # start after 4 s; Box3D's 4,095-cube pyramid at 32 substeps: 24 mm). A block stops once a
            # sweep changed no impulse by MANIFOLD_SWEEP_TOLERANCE of its load: a tolerance relative to
            # the load each row carries, so the remainder left to the next pass is that small a part of
            # it however deep in the stack (an absolute one, 1e-5 m/s, left a resting stack rocking at
            # 2.5e-4 rad/s). Warm-started resting blocks stop after one sweep, blocks that take a load
            # change sweep on (the tower of ten: its top 0.05 mm off; 0.02 mm at six sweeps always).
            # A patch (rows sharing the normal) has its friction at its centre, on the disc
            # |jt| <= mu sum_i jn_i, and a twist row about n, |j_twist| <= mu sum_i jn_i arm_i, so no
            # order of corners enters it either.
            patch = rows[k].mass_twist > float_t(0.0)
            mu = rows[k].friction
            load, torque = _block_load(rows, k, size)
            sweep = int(0)
            while sweep < MANIFOLD_SWEEPS:
                change = float_t(0.0)  # the largest impulse change of this sweep [N s]
                change_twist = float_t(0.0)  # the twist row's [N m s]
                if patch:
                    ca = rows[k].centre_a
                    cb = rows[k].centre_b
                    if turning:
                        ca = _turned(turn_a, ca)
                        cb = _turned(turn_b, cb)
                    dv, change = _friction_row(rows, k, ca, cb, mu * load, pair, dv)
                    jw_old = rows[k].impulse_twist
                    wn = wp.dot(pair.wb + dv.wb - pair.wa - dv.wa, rows[k].normal)
                    jw = wp.clamp(jw_old - rows[k].mass_twist * wn * rows[k].scale, -mu * torque, mu * torque)
                    rows[k].impulse_twist = jw
                    dw = jw - jw_old
                    change_twist = wp.abs(dw)
                    dv.wa = dv.wa - rows[k].angular_a_twist * dw
                    dv.wb = dv.wb + rows[k].angular_b_twist * dw
                swept = size
                if wp.static(exact_pair):  # (the caller's two-row patch: one normal)
                    dv, solved, moved = _normal_pair(rows, k, bias4, ms4, isc4, pair, dv)
                    change = wp.max(change, moved)
                    swept = size * (1 - solved)
                for j in range(swept):
                    i = j
                    if sweep % 2 == 1:
                        i = size - 1 - j
                    kk = k + i
                    if not patch:
                        ra = rows[kk].r_a
                        rb = rows[kk].r_b
                        if turning:
                            ra = _turned(turn_a, ra)
                            rb = _turned(turn_b, rb)
                        dv, moved = _friction_row(rows, kk, ra, rb, mu * rows[kk].impulse_n, pair, dv)
                        change = wp.max(change, moved)
                    dv, moved = _normal_row(rows, kk, bias4[i], ms4[i], isc4[i], pair, dv)
                    change = wp.max(change, moved)
                sweep += 1
                load, torque = _block_load(rows, k, size)
                if change <= MANIFOLD_SWEEP_TOLERANCE * load and change_twist <= MANIFOLD_SWEEP_TOLERANCE * torque:
                    break  # converged: another sweep would change no impulse by more
        _add_pair(b, ia, ib, dv, serial)
        if p.use_bias == 0 and last != 0:
            # relax: these impulses are final for this substep, and the next substep starts from them
            # (warm start), so sum their velocity changes per body now instead of in another pass
            # (a twist row is a patch's, on its first row: the other rows' twist fields are zero, so they are
            # neither read nor summed)
            twist = rows[k].mass_twist > float_t(0.0)
            P = vec3()
            wa_ = vec3()
            wb_ = vec3()
            for i in range(size):
                kk = k + i
                jn = rows[kk].impulse_n
                j1 = rows[kk].impulse_t1
                j2 = rows[kk].impulse_t2
                P = P + rows[kk].normal * jn + rows[kk].tangent1 * j1 + rows[kk].tangent2 * j2
                wa_ = wa_ + rows[kk].angular_a_n * jn + rows[kk].angular_a_t1 * j1 + rows[kk].angular_a_t2 * j2
                wb_ = wb_ + rows[kk].angular_b_n * jn + rows[kk].angular_b_t1 * j1 + rows[kk].angular_b_t2 * j2
                if i == 0 and twist:
                    jw = rows[kk].impulse_twist
                    wa_ = wa_ + rows[kk].angular_a_twist * jw
                    wb_ = wb_ + rows[kk].angular_b_twist * jw
            if pair.ima > float_t(0.0):
                add_to_velocity(b.warm_velocity, b.warm_angular_velocity, ia, -P * pair.ima, -wa_, serial)
            if pair.imb > float_t(0.0):
                add_to_velocity(b.warm_velocity, b.warm_angular_velocity, ib, P * pair.imb, wb_, serial)
        if p.use_bias == 0 and last != 0:
            return float_t(0.0)
        change = wp.max(wp.length_sq(dv.va), wp.length_sq(dv.vb))
        if push > float_t(0.0):
            change = wp.max(change, push * push)
        return change

    return _solve_manifold


_solve_manifold = _make_solve_manifold(False)
_solve_manifold_pair = _make_solve_manifold(True)


@wp.struct
class Relax:
    """Scratch of the serial solve passes: the bodies the biased pass marked, for its relax pass to sweep
    their manifolds on (RELAX_SWEEPS); zero again after every relax pass."""

    # [0]: 1 when some body is marked; [1]: the manifolds the last collision pass listed in `order`
    marked: wp.array(dtype=wp.int32)
    body: wp.array(dtype=wp.int32)  # per body: 1 when marked
    listed: wp.array(dtype=wp.int32)  # per contact: the first rows of the marked bodies' manifolds
    order: wp.array(dtype=wp.vec3i)  # `Ticks.order`: each manifold's first row and bodies, in row order


@wp.func
def _mark(rows: wp.array(dtype=ContactRow), k: int, b: BodyArrays, relax: Relax):
    """Mark the dynamic bodies of the manifold at k (a static body's other manifolds need no sweep)."""
    if b.inv_mass[rows[k].body_a] > float_t(0.0):
        relax.body[rows[k].body_a] = 1
    if b.inv_mass[rows[k].body_b] > float_t(0.0):
        relax.body[rows[k].body_b] = 1


def _make_solve(serial: int):
    """The solve pass's kernel: one thread sweeping every contact in order (`serial`, the CPU: a
    Gauss-Seidel sweep, and no per-thread start-up for each contact), or one thread per contact
    (CUDA: a Jacobi iteration with atomics); the other branch is left out when Warp compiles it."""

    # a name of its own: a recorded CPU graph finds a kernel by its name
    @wp.kernel(name="_solve_serial" if serial else "_solve_parallel")
    def solve(
        rows: wp.array(dtype=ContactRow),
        b: BodyArrays,
        p: SolvePass,
        counts: wp.array(dtype=wp.int32),
        relax: Relax,
    ):
        if wp.static(serial == 0):
            k = wp.tid()
            if k < counts[0]:  # launched over the capacity, the count on the device
                _solve_manifold(k, rows, b, p, 0, 1)
        else:
            count = counts[0]
            trigger = RELAX_TRIGGER * RELAX_TRIGGER
            if p.use_bias != 0:
                # the biased pass marks the dynamic bodies of the manifolds it changed fast (the two-row
                # dispatch is written out in each loop below: a wp.func wrapping it made box_pyramid's
                # and pile_5k's steps 1.4 times as long)
                marked = int(0)
                for k in range(count):
                    change = float_t(0.0)
                    if _two_row_patch(rows, k):
                        change = _solve_manifold_pair(k, rows, b, p, 1, 1)  # an edge, a rod's end
                    else:
                        change = _solve_manifold(k, rows, b, p, 1, 1)
                    if change > trigger:
                        _mark(rows, k, b, relax)
                        marked = 1
                relax.marked[0] = marked
            else:
                listed = int(0)
                if relax.marked[0] != 0:
                    # the manifolds of the marked bodies (from the collision pass's list of them all, which
                    # ran just before: 12 bytes a manifold, not a row's cache line), swept without bias
                    # while they change the velocities
                    for m in range(relax.marked[1]):
                        e = relax.order[m]
                        if relax.body[e[1]] != 0 or relax.body[e[2]] != 0:
                            relax.listed[listed] = e[0]
                            listed += 1
                    sweep = int(0)
                    fastest = trigger
                    while sweep < RELAX_SWEEPS and fastest > RELAX_TOLERANCE * RELAX_TOLERANCE:
                        fastest = float_t(0.0)
                        for i in range(listed):
                            k = relax.listed[i]
                            if _two_row_patch(rows, k):
                                fastest = wp.max(fastest, _solve_manifold_pair(k, rows, b, p, 1, 0))
                            else:
                                fastest = wp.max(fastest, _solve_manifold(k, rows, b, p, 1, 0))
                        sweep += 1
                # the relax sweep over all, which keeps the impulses for the next substep's warm start
                for k in range(count):
                    if _two_row_patch(rows, k):
                        _solve_manifold_pair(k, rows, b, p, 1, 1)
                    else:
                        _solve_manifold(k, rows, b, p, 1, 1)
                # unmark (every mark is on a listed manifold's body)
                for i in range(listed):
                    k = relax.listed[i]
                    relax.body[rows[k].body_a] = 0
                    relax.body[rows[k].body_b] = 0
                relax.marked[0] = 0

    return solve


#: the solve pass, by `_serial`
_SOLVES = {serial: _make_solve(serial) for serial in (0, 1)}


@wp.struct
class ImpactPass:
    """The parameters of one collision pass (`impacts`)."""

    gravity: vec3  # [m/s^2]
    h: float_t  # substep [s]
    threshold: float_t  # approach speed [m/s] below which a contact carrying load does not bounce
    floor: float_t  # the same for a contact carrying none: the approach gravity gives in two substeps


@wp.struct
class Ticks:
    """When the serial collision pass last tested each contact and last changed each body, in ticks of
    `clock` (which only grows): a contact neither of whose bodies changed since its last test is skipped."""

    tested: wp.array(dtype=wp.int64)  # per contact
    listed: wp.array(dtype=wp.int32)  # scratch, per contact: the contacts the inelastic sweeps go on with
    # scratch, per manifold: its first row and its two bodies, in row order, listed by a pass's first
    # sweep, so that the later sweeps' test of which manifolds to skip reads 12 bytes a manifold
    # instead of a row's cache line (`ContactRow` is 528 bytes in float64)
    order: wp.array(dtype=wp.vec3i)
    changed: wp.array(dtype=wp.int64)  # per body
    clock: wp.array(dtype=wp.int64)  # one value


@wp.func(inline=True)
def _rebound(
    k: int, rows: wp.array(dtype=ContactRow), b: BodyArrays, p: ImpactPass, share: float_t, centres: vec3, struck: int
):
    """The normal speed u [m/s] contact k collides to now, if it closes within the substep faster than
    `threshold` [m/s]; else NO_IMPACT. u >= 0 separates (the bounce); a landing's u may be negative,
    the approach that closes its gap by the end of the next substep. An inelastic contact (e = 0)
    whose body was `struck` by another contact's collision earlier in this pass closes as part of
    that collision, at any approach above 2 |g| h (MANIFOLD_TOLERANCE without gravity). Speeds are measured at the
    anchors the collision acts at (`_met` with `share` and `centres`, as in `_impact`), so that u
    never exceeds the approach there; the gap at the row's own (`_gap`).

    The velocities are those of the next substep but for its gravity kick (the pass runs before
    the kick, so that no impulse falls between a substep's kick and its position update).
    """
    e = rows[k].restitution
    ia = rows[k].body_a
    ib = rows[k].body_b
    n = rows[k].normal
    ra = rows[k].r_a
    rb = rows[k].r_b
    ma, mb = _met(share, ra, rb, centres)
    vn = _speed_along(b, ia, ib, ma, mb, n)
    if vn >= float_t(0.0):
        return NO_IMPACT
    # relative acceleration along n from gravity on the dynamic bodies (< 0: closing)
    ga = float_t(0.0)
    gb = float_t(0.0)
    if b.inv_mass[ia] > float_t(0.0):
        ga = float_t(1.0)
    if b.inv_mass[ib] > float_t(0.0):
        gb = float_t(1.0)
    gn = wp.min((gb - ga) * wp.dot(p.gravity, n), float_t(0.0))
    # the threshold keeps contacts that carry load (an impulse this substep) from bouncing; a
    # contact that carries none is a fresh impact and bounces down to `floor`, the approach
    # speed gravity alone gives in two substeps (0 without gravity: a gas stays elastic)
    # (an inelastic contact only lands faster than the threshold: below it the soft rows stop it, as
    # they stopped every e = 0 contact before; with the fresh floor a box pivoting on a mesh's edge
    # landed its corners one by one every substep and turned about the other axes in float32)
    limit = p.threshold
    if rows[k].impulse_n == float_t(0.0) and e > float_t(0.0):
        limit = wp.min(p.threshold, p.floor)
    if e == float_t(0.0) and struck != 0:
        # a collision passing along touching bodies (a row of balls struck at one end): each contact it
        # reaches closes now, at any speed, so that the row moves off as one body. Left to the soft
        # rows below the threshold, a struck row of six balls spread apart as if springs joined them
        # (the front one at 0.21 m/s, the common speed 1/6 m/s), its kinetic energy 4.6 % above
        limit = wp.max(p.floor, MANIFOLD_TOLERANCE)
    if e == float_t(0.0) and rows[k].radii != float_t(0.0):
        # two spheres landing: closing along their line of centres now, not only along the step start's
        # normal, which a ball sliding over a sphere's curve drops below (it would be held to the
        # tangent plane and thrown off early)
        centres_now = b.position[ib] - b.position[ia]
        if wp.dot(b.velocity[ib] - b.velocity[ia], centres_now) > -limit * wp.length(centres_now):
            return NO_IMPACT
    # cheap exit, before the gap: the impact speed^2 below (vi2) grows with the gap s (by -2 g_n
    # s), and a contact that collides has s <= -(v_n + g_n h) h (the closing test), so a
    # contact whose bound at that largest gap is well under the limit would return 0 there too
    # (resting contacts under load; the factor 2 is far beyond any rounding)
    gap = -(vn + gn * p.h) * p.h
    if vn * vn - float_t(2.0) * gn * gap + gn * p.h * vn < float_t(0.5) * limit * limit:
        return NO_IMPACT
    # current gap, linearised along the step start's normal (`_gap`: not the exact one of two spheres)
    s = _gap(rows, k, b, b.delta_position[ia], b.delta_rotation[ia], b.delta_position[ib], b.delta_rotation[ib], 0)
    if s + (vn + gn * p.h) * p.h > float_t(0.0):
        return NO_IMPACT  # still apart at the end of the substep: a later pass collides it
    # the bounce, in the energy the substeps conserve: semi-implicit Euler under a constant
    # acceleration g_n (v' = v + g_n h, then s' = s + v' h) keeps E = v^2 / 2 - g_n s + g_n h v / 2
    # exactly (not v^2 / 2 - g_n s), taken over (s, v) at the end of a substep. A contact at gap
    # s arriving with v_n (< 0) rebounds with the u that makes E after e^2 times E before
    # (both measured from the contact, s = 0), so the next apex of the discrete flight is e^2
    # times the last, wherever in the substep the impact falls and whatever h is:
    #   u^2 / 2 + g_n h u / 2 = e^2 E_b + g_n s,   E_b = v^2 / 2 - g_n s + g_n h v / 2,
    # and never faster than the elastic rebound |v_n| (no kinetic energy gain). Without
    # gravity along n this is u = e |v_n|.
    eb = float_t(0.5) * vn * vn - gn * s + float_t(0.5) * gn * p.h * vn
    vi2 = float_t(2.0) * eb  # the impact speed^2 of the discrete flight (v_n^2 - 2 g_n s as h -> 0)
    if vi2 <= limit * limit:
        return NO_IMPACT
    rhs = e * e * eb + gn * s
    # where the bounce's energy is below the gap's (e^2 E_b + g_n s <= 0: e = 0, or a small e met
    # while still apart), the contact lands instead: the approach that closes the gap s exactly at
    # the end of the next substep (s + (u + g_n h) h = 0), never faster than it comes. Stopped where
    # it was, it hung up to a substep's travel above the surface (4 mm at 8.5 m/s) and fell again.
    # An overlap (s < 0) is not pushed out here but left to the soft rows, whose push is bounded: struck
    # (above), every resting contact of a tower lands, and at -s / h a 10 kg box landing at 8 m/s on a
    # tower of ten 1 kg boxes threw the tower's boxes up at up to 1.5 m/s, and the tower fell
    u = wp.max(-wp.max(s, float_t(0.0)) / p.h - gn * p.h, vn)
    if rhs > float_t(0.0):
        gh = gn * p.h
        u = wp.max(float_t(0.5) * (-gh + wp.sqrt(gh * gh + float_t(8.0) * rhs)), float_t(0.0))
    u = wp.min(u, -vn)
    rows[k].relative_velocity = -wp.sqrt(vi2)
    return u


@wp.func(inline=False)
def _impact_pair(
    k: int,
    rows: wp.array(dtype=ContactRow),
    b: BodyArrays,
    share: float_t,
    centres: vec3,
    u0: float_t,
    u1: float_t,
    serial: int,
):
    """The collision of the two-row manifold at k, both rows colliding (to u0, u1 [m/s]), solved
    exactly (`_lcp2`: K j = u - v, j >= 0) and applied; the impulses and 1, or 0 where the block is
    singular (nothing applied: swept instead). Gauss-Seidel converges on two coupled rows by
    a01^2 / (a00 a11) a sweep pair only: a 1 m x 2 cm rod landing on its end at 60 degrees, e = 1,
    was left after the sixteen sweeps with its corners' impulses 0.1 % apart, spinning at 0.11 rad/s
    about its own axis. (Called by `_impact_pair_first` alone, the collision of two-row patches.)
    """
    ia = rows[k].body_a
    ib = rows[k].body_b
    ima = b.inv_mass[ia]
    imb = b.inv_mass[ib]
    qa = b.orientation[ia]
    qb = b.orientation[ib]
    n = rows[k].normal  # a manifold's rows share their normal (a patch)
    ra0, rb0 = _met(share, rows[k].r_a, rows[k].r_b, centres)
    ra1, rb1 = _met(share, rows[k + 1].r_a, rows[k + 1].r_b, centres)
    ca0 = wp.cross(ra0, n)
    cb0 = wp.cross(rb0, n)
    ca1 = wp.cross(ra1, n)
    cb1 = wp.cross(rb1, n)
    dwa0 = inv_inertia_times(qa, b.inv_inertia[ia], ca0)
    dwb0 = inv_inertia_times(qb, b.inv_inertia[ib], cb0)
    dwa1 = inv_inertia_times(qa, b.inv_inertia[ia], ca1)
    dwb1 = inv_inertia_times(qb, b.inv_inertia[ib], cb1)
    k00 = ima + imb + wp.dot(ca0, dwa0) + wp.dot(cb0, dwb0)
    k11 = ima + imb + wp.dot(ca1, dwa1) + wp.dot(cb1, dwb1)
    k01 = ima + imb + wp.dot(ca0, dwa1) + wp.dot(cb0, dwb1)
    b0 = u0 - _speed_along(b, ia, ib, ra0, rb0, n)
    b1 = u1 - _speed_along(b, ia, ib, ra1, rb1, n)
    j0, j1, ok = _lcp2(k00, k01, k11, b0, b1)
    if ok != 0:
        _add_pair(
            b,
            ia,
            ib,
            _delta(-n * ((j0 + j1) * ima), -dwa0 * j0 - dwa1 * j1, n * ((j0 + j1) * imb), dwb0 * j0 + dwb1 * j1),
            serial,
        )
    return j0, j1, ok


@wp.func
def _sum(x: Delta, y: Delta):
    """Two Deltas' changes together."""
    return _delta(x.va + y.va, x.wa + y.wa, x.vb + y.vb, x.wb + y.wb)


@wp.func
def _apply(b: BodyArrays, ia: int, ib: int, d: Delta, total: Delta, serial: int):
    """Add d to the pair's velocities (`_add_pair`); returns the running total of the changes, with d."""
    _add_pair(b, ia, ib, d, serial)
    return _sum(total, d)


@wp.func
def _energy_change(b: BodyArrays, i: int, v: vec3, w: vec3, dv: vec3, dw: vec3):
    """The kinetic energy [J] body i gains when its velocities v, w change by dv, dw (0 for a static body)."""
    if b.inv_mass[i] == float_t(0.0):
        return float_t(0.0)
    gain = (wp.dot(v, dv) + float_t(0.5) * wp.dot(dv, dv)) / b.inv_mass[i]
    q = b.orientation[i]
    wl = wp.quat_rotate_inv(q, w)
    dl = wp.quat_rotate_inv(q, dw)
    inv_i = b.inv_inertia[i]
    for axis in range(3):
        if inv_i[axis] > float_t(0.0):
            gain += (wl[axis] * dl[axis] + float_t(0.5) * dl[axis] * dl[axis]) / inv_i[axis]
    return gain


@wp.func
def _impact_sweeps(
    k: int,
    size: int,
    rows: wp.array(dtype=ContactRow),
    b: BodyArrays,
    u4: vec4,
    j4: vec4,
    hits: int,
    share: float_t,
    centres: vec3,
    serial: int,
):
    """The collision's normal rows of the manifold at k swept, forward and backward in turn, until none
    changes its velocity by MANIFOLD_TOLERANCE (at most IMPACT_SWEEPS; one sweep for a lone colliding
    row, which it leaves exact): each colliding row i (u4[i] > NO_IMPACT) to its normal speed u4[i]
    (`_rebound`), its accumulated impulse j4[i] >= 0, inertia at the current orientations. Returns j4, 1 if any
    impulse changed, and the velocity changes made."""
    ia = rows[k].body_a
    ib = rows[k].body_b
    ima = b.inv_mass[ia]
    imb = b.inv_mass[ib]
    qa = b.orientation[ia]
    qb = b.orientation[ib]
    out = j4
    total = Delta()
    changed = int(0)
    sweep = int(0)
    moving = int(1)
    while moving != 0 and sweep < IMPACT_SWEEPS:
        moving = int(0)
        for m in range(size):
            i = m
            if sweep % 2 == 1:
                i = size - 1 - m
            if u4[i] > NO_IMPACT:
                kk = k + i
                n = rows[kk].normal
                ra, rb = _met(share, rows[kk].r_a, rows[kk].r_b, centres)
                vn = _speed_along(b, ia, ib, ra, rb, n)
                ca = wp.cross(ra, n)
                cb = wp.cross(rb, n)
                dwa = inv_inertia_times(qa, b.inv_inertia[ia], ca)
                dwb = inv_inertia_times(qb, b.inv_inertia[ib], cb)
                kn = ima + imb + wp.dot(ca, dwa) + wp.dot(cb, dwb)
                j_old = out[i]
                j = wp.max(j_old + (u4[i] - vn) / kn * rows[kk].scale, float_t(0.0))
                dj = j - j_old
                out[i] = j
                total = _apply(b, ia, ib, _delta(-n * (dj * ima), -dwa * dj, n * (dj * imb), dwb * dj), total, serial)
                if wp.abs(dj) * kn > MANIFOLD_TOLERANCE:
                    moving = int(1)
                    changed = int(1)
        sweep += 1
        if hits == 1:
            moving = int(0)
    return out, changed, total


@wp.func
def _impact_load(rows: wp.array(dtype=ContactRow), k: int, size: int, j4: vec4):
    """The load sum_i j_i [N s] of a collision's normal impulses j4 on the manifold at k, and its twist
    limit's sum_i j_i arm_i [N m s] (as `_block_load` for the solve's accumulated impulses)."""
    load = float_t(0.0)
    torque = float_t(0.0)
    for i in range(size):
        load += j4[i]
        torque += j4[i] * rows[k + i].twist_arm
    return load, torque


@wp.func
def _centre_friction(
    b: BodyArrays, ia: int, ib: int, ca: vec3, cb: vec3, n: vec3, jt: vec3, limit: float_t, relax: float_t, whole: int
):
    """A friction step at a patch's centre (anchors ca, cb [m]): along the sliding direction d, the
    impulse that stops the sliding there added to the accumulated jt [N s] (`whole` 0) and clamped to
    |jt| <= limit, or (`whole` 1) one impulse alone, at most limit and at most the one that stops
    the motion along d. Returns the new jt, the velocity changes and the largest speed change [m/s]."""
    ima = b.inv_mass[ia]
    imb = b.inv_mass[ib]
    qa = b.orientation[ia]
    qb = b.orientation[ib]
    v = b.velocity[ib] + wp.cross(b.angular_velocity[ib], cb) - b.velocity[ia] - wp.cross(b.angular_velocity[ia], ca)
    vt = v - n * wp.dot(v, n)
    speed = wp.length(vt)
    if speed == float_t(0.0):
        return jt, Delta(), float_t(0.0)
    d = -vt / speed
    xa = wp.cross(ca, d)
    xb = wp.cross(cb, d)
    k_d = ima + imb + wp.dot(xa, inv_inertia_times(qa, b.inv_inertia[ia], xa))
    k_d = k_d + wp.dot(xb, inv_inertia_times(qb, b.inv_inertia[ib], xb))
    target = jt + d * (speed / k_d * relax)
    if whole != 0:
        target = d * (wp.min(speed / k_d, limit / relax) * relax)
    else:
        length = wp.length(target)
        if length > limit:
            target = target * (limit / length)
    dj = target - jt
    out = _delta(
        -dj * ima,
        -inv_inertia_times(qa, b.inv_inertia[ia], wp.cross(ca, dj)),
        dj * imb,
        inv_inertia_times(qb, b.inv_inertia[ib], wp.cross(cb, dj)),
    )
    return target, out, wp.length(dj) * k_d


@wp.func
def _twist_friction(b: BodyArrays, ia: int, ib: int, n: vec3, jw: float_t, limit: float_t, relax: float_t, whole: int):
    """A twist step about n: the impulse [N m s] that stops the relative spin about n, added to the
    accumulated jw and clamped to |jw| <= limit (`whole` 0), or alone, at most limit (`whole` 1).
    Returns the new jw, the velocity changes and the change of the relative spin about n [rad/s]."""
    twa = inv_inertia_times(b.orientation[ia], b.inv_inertia[ia], n)
    twb = inv_inertia_times(b.orientation[ib], b.inv_inertia[ib], n)
    k_w = wp.dot(n, twa) + wp.dot(n, twb)
    if k_w == float_t(0.0):
        return jw, Delta(), float_t(0.0)
    wn = wp.dot(b.angular_velocity[ib] - b.angular_velocity[ia], n)
    target = wp.clamp(jw - wn / k_w * relax, -limit, limit)
    if whole != 0:
        target = -wp.sign(wn) * wp.min(wp.abs(wn) / k_w, limit / relax) * relax
    dw = target - jw
    return target, _delta(vec3(), -twa * dw, vec3(), twb * dw), wp.abs(dw) * k_w


@wp.func(inline=False)
def _patch_impact_friction(
    k: int,
    size: int,
    rows: wp.array(dtype=ContactRow),
    b: BodyArrays,
    u4: vec4,
    j4: vec4,
    hits: int,
    share: float_t,
    centres: vec3,
    serial: int,
):
    """The friction of a patch's collision, its rows' normal impulses j4 found (`_impact_sweeps`):
    at its centre, |j_t| <= mu sum_i j_i, and its twist about n, |j_w| <= mu sum_i j_i arm_i, each
    accumulated and stepped towards stopping its motion, then the normal rows swept again, in
    turn until none changes (at most PATCH_IMPACT_ROUNDS rounds; projected Gauss-Seidel on the
    whole block).

    A friction impulse at the face turns the body, which moves the corners' normal speeds: the
    corners that dip must take more of the load, so that the box slows without tipping. Friction
    applied once after the normal rows left that turn in: a cube landing flat at 4.4 m/s with
    2 m/s across a floor (e = 0.5, mu = 0.5) left spinning at 12 rad/s, bounced off its leading
    edge and flipped over, where the impulse-momentum solution stops its sliding (mu j_n = 3.3 N s
    against the 2 N s that stops it; its friction's moment about the centre, 0.1 m x 2 N s, within
    the corners' most, 0.1 m x 6.6 N s) and sends it straight up at e v_n.

    The normal rows' targets are the separating speeds decided before the collision, and sweeping
    them again after friction has turned the body can add energy where e is near 1 (a random test
    of boxes striking a floor: up to 24 % at e = 1). So the rounds' velocity changes are summed,
    and where they gained the pair kinetic energy they are taken back, and friction acts once
    instead, along the sliding direction and about n, each at most the impulse that stops that
    motion (no energy gained, as in `_impact`).
    """
    ia = rows[k].body_a
    ib = rows[k].body_b
    n = rows[k].normal
    mu = rows[k].friction
    relax = rows[k].scale
    ca, cb = _met(share, rows[k].centre_a, rows[k].centre_b, centres)
    va = b.velocity[ia]
    wa = b.angular_velocity[ia]
    vb = b.velocity[ib]
    wb = b.angular_velocity[ib]
    load0, torque0 = _impact_load(rows, k, size, j4)
    normals = j4
    total = Delta()
    jt = vec3()  # accumulated friction impulse on b [N s], in the plane of the patch
    jw = float_t(0.0)  # accumulated twist impulse on b about n [N m s]
    load = load0
    torque = torque0
    arm = float_t(0.0)  # the patch's widest point from its centre [m]: a spin change moves it by arm times as much
    for i in range(size):
        arm = wp.max(arm, rows[k + i].twist_arm)
    rounds = int(0)
    while rounds < PATCH_IMPACT_ROUNDS:
        jt, d, moved = _centre_friction(b, ia, ib, ca, cb, n, jt, mu * load, relax, 0)
        total = _apply(b, ia, ib, d, total, serial)
        jw, d, turned = _twist_friction(b, ia, ib, n, jw, mu * torque, relax, 0)
        total = _apply(b, ia, ib, d, total, serial)
        # the normal rows again: the friction's moment moved the corners
        normals, changed, d = _impact_sweeps(k, size, rows, b, u4, normals, hits, share, centres, serial)
        total = _sum(total, d)
        load, torque = _impact_load(rows, k, size, normals)
        rounds += 1
        if changed == 0 and moved <= MANIFOLD_TOLERANCE and turned * arm <= MANIFOLD_TOLERANCE:
            break
    gain = _energy_change(b, ia, va, wa, total.va, total.wa) + _energy_change(b, ib, vb, wb, total.vb, total.wb)
    if gain > float_t(0.0):
        # taken back; friction once, at the normal rows' first impulses
        _add_pair(b, ia, ib, _delta(-total.va, -total.wa, -total.vb, -total.wb), serial)
        no_jt = vec3()
        jt, d, moved = _centre_friction(b, ia, ib, ca, cb, n, no_jt, mu * load0, relax, 1)
        _add_pair(b, ia, ib, d, serial)
        jw, d, turned = _twist_friction(b, ia, ib, n, float_t(0.0), mu * torque0, relax, 1)
        _add_pair(b, ia, ib, d, serial)


@wp.func
def _point_mass_matrix(b: BodyArrays, ia: int, ib: int, ra: vec3, rb: vec3, n: vec3, t1: vec3, t2: vec3):
    """K, the velocity change per unit impulse at anchors ra, rb [m] along (n, t1, t2), at the bodies'
    current orientations: K_ij = d_i . d_j (1/m_a + 1/m_b) + (r_a x d_i) . I_a^-1 (r_a x d_j) + (b's)."""
    qa = b.orientation[ia]
    qb = b.orientation[ib]
    ia_inv = b.inv_inertia[ia]
    ib_inv = b.inv_inertia[ib]
    im = b.inv_mass[ia] + b.inv_mass[ib]
    an = wp.cross(ra, n)
    a1 = wp.cross(ra, t1)
    a2 = wp.cross(ra, t2)
    bn = wp.cross(rb, n)
    b1 = wp.cross(rb, t1)
    b2 = wp.cross(rb, t2)
    ian = inv_inertia_times(qa, ia_inv, an)
    ia1 = inv_inertia_times(qa, ia_inv, a1)
    ia2 = inv_inertia_times(qa, ia_inv, a2)
    ibn = inv_inertia_times(qb, ib_inv, bn)
    ib1 = inv_inertia_times(qb, ib_inv, b1)
    ib2 = inv_inertia_times(qb, ib_inv, b2)
    knn = im + wp.dot(an, ian) + wp.dot(bn, ibn)
    kn1 = wp.dot(an, ia1) + wp.dot(bn, ib1)
    kn2 = wp.dot(an, ia2) + wp.dot(bn, ib2)
    k11 = im + wp.dot(a1, ia1) + wp.dot(b1, ib1)
    k12 = wp.dot(a1, ia2) + wp.dot(b1, ib2)
    k22 = im + wp.dot(a2, ia2) + wp.dot(b2, ib2)
    return mat33(knn, kn1, kn2, kn1, k11, k12, kn2, k12, k22)


@wp.func(inline=False)
def _lone_impact_sticking(
    k: int,
    rows: wp.array(dtype=ContactRow),
    b: BodyArrays,
    u: float_t,
    jn: float_t,
    applied: Delta,
    share: float_t,
    centres: vec3,
    serial: int,
):
    """The collision of a lone point with a lever (a corner, a rod's end), its normal impulse jn [N s]
    applied (`applied`, which brought its normal speed to u [m/s]), made to stick where it can: the
    impulse change dJ with K dJ = (0, -v_t1, -v_t2) at the point (`_point_mass_matrix`), kept (1) when
    the whole impulse pushes and lies in the friction cone, |J_t| <= mu J_n, and the collision then
    gains the pair no energy; else nothing is changed (0) and friction acts once (`_impact`).

    Friction applied once after the normal impulse moved the point's normal speed through the
    body's turn, and the bounce was lost: a 1 m rod striking a mu = 5 floor on its end at 2 m/s,
    45 degrees, e = 0.5, left at (0.745, 0, -0.735) m/s, about what e = 0 gives, against the
    sticking impulse's (1.125, 0, -0.093), where J = (1 + e) times the e = 0 impulse (a point that
    sticks throughout: Newton's and Poisson's restitution agree) and the energy lost is 1 - e^2 of
    the e = 0 impact's.
    """
    ia = rows[k].body_a
    ib = rows[k].body_b
    n = rows[k].normal
    t1 = rows[k].tangent1
    t2 = rows[k].tangent2
    mu = rows[k].friction
    ra, rb = _met(share, rows[k].r_a, rows[k].r_b, centres)
    kmat = _point_mass_matrix(b, ia, ib, ra, rb, n, t1, t2)
    det = wp.determinant(kmat)
    if not (det > float_t(1.0e-12) * kmat[0, 0] * kmat[1, 1] * kmat[2, 2]):
        return 0
    va = b.velocity[ia]
    wa = b.angular_velocity[ia]
    vb = b.velocity[ib]
    wb = b.angular_velocity[ib]
    v = vb + wp.cross(wb, rb) - va - wp.cross(wa, ra)
    d = wp.inverse(kmat) * vec3(u - wp.dot(v, n), -wp.dot(v, t1), -wp.dot(v, t2))
    total_n = jn + d[0]
    if total_n < float_t(0.0) or d[1] * d[1] + d[2] * d[2] > mu * mu * total_n * total_n:
        return 0  # it would pull or slide: friction once instead
    P = n * d[0] + t1 * d[1] + t2 * d[2]
    ima = b.inv_mass[ia]
    imb = b.inv_mass[ib]
    change = _delta(
        -P * ima,
        -inv_inertia_times(b.orientation[ia], b.inv_inertia[ia], wp.cross(ra, P)),
        P * imb,
        inv_inertia_times(b.orientation[ib], b.inv_inertia[ib], wp.cross(rb, P)),
    )
    # the whole collision's energy change, from the velocities before its normal impulse
    whole = _sum(applied, change)
    gain = _energy_change(b, ia, va - applied.va, wa - applied.wa, whole.va, whole.wa)
    gain = gain + _energy_change(b, ib, vb - applied.vb, wb - applied.wb, whole.vb, whole.wb)
    if gain > float_t(0.0):
        return 0
    _add_pair(b, ia, ib, change, serial)
    return 1


def _make_impact(exact_pair: bool):
    """`_impact`, or with `exact_pair` `_impact_pair_first`: the same collision, where a two-row patch
    whose rows both collide first has its normal impulses solved exactly (`_impact_pair`). Two
    functions from one source, so that the one inlined into every contact's test of the collision
    pass stays as small as it was (the block inside it slowed a pile of spheres' collision pass
    by 15 %), and the other is called for two-row patches alone."""

    @wp.func(inline=True if not exact_pair else None)
    def _impact(
        k: int, size: int, rows: wp.array(dtype=ContactRow), b: BodyArrays, p: ImpactPass, struck: int, serial: int
    ):
        """Collide the rows of the manifold at k (`size` contacts) that close within the substep
        faster than `threshold` [m/s] (inelastic ones at any speed if a body was `struck` earlier in
        the pass: `_rebound`); 1 if any did.

        One collision of the two bodies at every such row at once: normal impulses j_i >= 0 that
        turn each row's approach speed v_i into its separating speed u_i (`_rebound`), then at each
        row a Coulomb friction impulse of at most mu j_i along its sliding direction. The rows
        share the body pair, so their normal impulses are found together, by projected
        Gauss-Seidel sweeps over them (forward and backward in turn) to MANIFOLD_TOLERANCE: a box
        landing flat bounces flat. Each row is decided before any impulse, so j_i v_i < 0, and at
        the solution K j = u - v on the rows that push, so the collision's energy change
        j . v + j . K j / 2 = j . (u + v) / 2 <= 0 (u_i <= -v_i). Each friction impulse acts alone
        along one direction d with at most the impulse that stops the motion along d, so it cannot
        add kinetic energy either: dKE = j v_d + j^2 / (2 m_d) <= 0 for 0 <= j <= -2 m_d v_d. A
        patch's friction (at its centre, and its twist) is solved with its normal rows in turn
        instead, since its moment shifts the load between the corners (`_patch_impact_friction`,
        which keeps the rule where that would add energy); so is a lone point with a lever, after
        trying it as one sticking block (`_lone_impact_sticking`), since its friction moves its
        normal speed.
        """
        ia = rows[k].body_a
        ib = rows[k].body_b
        # the impulses act now: anchors that meet at the bodies' present places (`_meeting_share`), so
        # that the pair's angular momentum is kept
        share = _meeting_share(b, ia, ib)
        centres = b.position[ib] - b.position[ia]
        u4 = vec4()
        hits = int(0)
        for i in range(size):
            u4[i] = _rebound(k + i, rows, b, p, share, centres, struck)
            if u4[i] > NO_IMPACT:
                hits += 1
        if hits == 0:
            return 0
        # normal: v_n -> u, j = m_n (u - v_n), 1 / m_n = 1/m_a + 1/m_b + (r_a x n) . I_a^-1 (r_a x n) + ...,
        # with the inertia at the current orientations (a fast-spinning box turns far in a step; with
        # the step start's, the impulse would not keep the energy exactly); a lone row is exact in one sweep
        j4 = vec4()
        if wp.static(exact_pair):  # (the caller's two-row patch: one normal)
            if hits == 2:
                # both rows collide (an edge, a rod's end): solved exactly (`_impact_pair`); the sweeps
                # below then find nothing left to do
                j0, j1, ok = _impact_pair(k, rows, b, share, centres, u4[0], u4[1], serial)
                if ok != 0:
                    j4[0] = j0
                    j4[1] = j1
        j4, swept, applied = _impact_sweeps(k, size, rows, b, u4, j4, hits, share, centres, serial)
        if rows[k].mass_twist > float_t(0.0):
            # a patch: its friction at its centre and its twist, with the normal rows in turn
            if rows[k].friction > float_t(0.0):
                _patch_impact_friction(k, size, rows, b, u4, j4, hits, share, centres, serial)
            return 1
        if size == 1 and j4[0] > float_t(0.0) and rows[k].friction > float_t(0.0):
            # a lone point with a lever (a corner, a rod's end): its friction moves its normal speed.
            # It sticks as one block where it can, else its rows are solved in turn, as a patch's
            if _has_lever(rows, k, b.inv_mass[ia] + b.inv_mass[ib]):
                if _lone_impact_sticking(k, rows, b, u4[0], j4[0], applied, share, centres, serial) == 0:
                    _patch_impact_friction(k, size, rows, b, u4, j4, hits, share, centres, serial)
                return 1
        # friction: along the sliding velocity d = -v_t / |v_t|, at most mu j and at most the
        # impulse m_d |v_t| that stops the sliding, 1 / m_d = 1/m_a + 1/m_b + (r_a x d) . I_a^-1 (r_a x d) + ...
        ima = b.inv_mass[ia]
        imb = b.inv_mass[ib]
        qa = b.orientation[ia]
        qb = b.orientation[ib]
        for i in range(size):
            kk = k + i
            j = j4[i]
            if j > float_t(0.0) and rows[kk].friction > float_t(0.0):
                ra, rb = _met(share, rows[kk].r_a, rows[kk].r_b, centres)
                relax = rows[kk].scale
                t1 = rows[kk].tangent1
                t2 = rows[kk].tangent2
                v1 = _speed_along(b, ia, ib, ra, rb, t1)
                v2 = _speed_along(b, ia, ib, ra, rb, t2)
                vt = wp.sqrt(v1 * v1 + v2 * v2)
                if vt > float_t(0.0):
                    a1 = -v1 / vt
                    a2 = -v2 / vt
                    d = t1 * a1 + t2 * a2
                    ca = wp.cross(ra, d)
                    cb = wp.cross(rb, d)
                    dwa = inv_inertia_times(qa, b.inv_inertia[ia], ca)
                    dwb = inv_inertia_times(qb, b.inv_inertia[ib], cb)
                    k_d = ima + imb + wp.dot(ca, dwa) + wp.dot(cb, dwb)
                    jt = wp.min(vt / k_d, rows[kk].friction * j / relax) * relax
                    _add_pair(b, ia, ib, _delta(-d * (jt * ima), -dwa * jt, d * (jt * imb), dwb * jt), serial)
        return 1

    return _impact


_impact = _make_impact(False)
_impact_pair_first = _make_impact(True)


def _make_impacts(serial: int):
    """The collision pass's kernel: one thread sweeping every contact (`serial`, the CPU), or one
    thread per contact (CUDA); the other branch is left out when Warp compiles it."""

    # a name of its own: a recorded CPU graph finds a kernel by its name
    @wp.kernel(name="_impacts_serial" if serial else "_impacts_parallel")
    def impacts(
        rows: wp.array(dtype=ContactRow),
        b: BodyArrays,
        p: ImpactPass,
        ticks: Ticks,
        counts: wp.array(dtype=wp.int32),
        relax: Relax,
    ):
        if wp.static(serial == 0):
            # one thread per contact (CUDA): atomics and the Jacobi scale
            thread = wp.tid()
            if thread < counts[0]:
                size = rows[thread].manifold
                if size > 0:
                    _impact(thread, size, rows, b, p, 0, 0)
        else:
            # one thread: Gauss-Seidel sweeps, forward and backward in turn, until one collides nothing
            # (a collision passes along a chain of touching bodies in either direction within a sweep;
            # a body caught between two others needs several); at most IMPACT_SWEEPS, INELASTIC_IMPACT_SWEEPS
            # while inelastic contacts still collide.
            # Whether a contact collides, and how, depends only on the velocities of its two bodies:
            # everything else _impact reads is fixed during the pass. So after the first sweep a contact
            # is tested again only if one of its bodies changed since its last test (`changed` and
            # `tested` hold ticks of `clock`, which only grows); the ones skipped would collide nothing
            # again, and the result is the same as sweeping them all.
            count = counts[0]
            t = ticks.clock[0]
            start = t  # a body changed after this was struck in this pass
            one = wp.int64(1)
            sweep = int(0)
            hits = int(1)
            inelastic = int(0)  # of the hits, inelastic manifolds' (e = 0), which may sweep on
            firsts = int(0)  # the manifolds, listed in `ticks.order` by the first sweep
            swept = count  # the rows a sweep goes over: all, then the manifolds, from IMPACT_SWEEPS those listed
            while hits > 0 and (sweep < IMPACT_SWEEPS or (inelastic > 0 and sweep < INELASTIC_IMPACT_SWEEPS)):
                if sweep == 1:
                    swept = firsts
                if sweep == IMPACT_SWEEPS:
                    # the inelastic sweeps beyond: over the contacts of the bodies this pass changed, listed
                    # once (a sweep over all of them to find these took a pouring pile of 1,000 balls, e = 0,
                    # 45 % longer over its first 2 s); the collision goes on within them
                    swept = int(0)
                    for m in range(firsts):
                        e = ticks.order[m]
                        if ticks.changed[e[1]] > start or ticks.changed[e[2]] > start:
                            ticks.listed[swept] = e[0]
                            swept += 1
                hits = int(0)
                inelastic = int(0)
                for i in range(swept):
                    m = i
                    if sweep % 2 == 1:
                        m = swept - 1 - i
                    k = m
                    ia = int(0)
                    ib = int(0)
                    if sweep == 0:
                        if rows[k].manifold == 0:
                            continue  # collided with the first row of its manifold
                        ia = rows[k].body_a
                        ib = rows[k].body_b
                        ticks.order[firsts] = wp.vec3i(k, ia, ib)
                        firsts += 1
                    elif sweep < IMPACT_SWEEPS:
                        e = ticks.order[m]
                        k = e[0]
                        ia = e[1]
                        ib = e[2]
                    else:
                        k = ticks.listed[m]
                        ia = rows[k].body_a
                        ib = rows[k].body_b
                    last = ticks.tested[k]
                    if sweep > 0:
                        if ticks.changed[ia] < last and ticks.changed[ib] < last:
                            continue
                    size = rows[k].manifold
                    # struck: a body changed in this pass by another contact's collision (its own last
                    # collision's tick is its `tested` tick: it leaves its rows closing at up to the
                    # manifold's tolerance, which must not strike it again)
                    struck = int(0)
                    if (ticks.changed[ia] > start and ticks.changed[ia] != last) or (
                        ticks.changed[ib] > start and ticks.changed[ib] != last
                    ):
                        struck = 1
                    t = t + one
                    ticks.tested[k] = t
                    if _two_row_patch(rows, k):
                        hit = _impact_pair_first(k, size, rows, b, p, struck, 1)  # an edge, a rod's end
                    else:
                        hit = _impact(k, size, rows, b, p, struck, 1)
                    if hit > 0:
                        t = t + one
                        ticks.tested[k] = t  # (still tested before its bodies' change: see `struck`)
                        if b.inv_mass[ia] > float_t(0.0):
                            ticks.changed[ia] = t
                        if b.inv_mass[ib] > float_t(0.0):
                            ticks.changed[ib] = t
                        hits += hit
                        if rows[k].restitution == float_t(0.0):
                            inelastic += hit
                sweep += 1
            ticks.clock[0] = t
            relax.marked[1] = firsts  # (the relax pass after it finds the marked bodies' manifolds there)

    return impacts


#: the collision pass, by `_serial`
_IMPACTS = {serial: _make_impacts(serial) for serial in (0, 1)}


# ---------------------------------------------------------------------------- host side


class SolverStructs(NamedTuple):
    """The structs the solver's kernels take, built once per set of arrays (`ContactSet.begin_solve`)."""

    contacts: Contacts
    bodies: BodyArrays
    previous: Previous
    owners: Owners
    ticks: Ticks
    relax: Relax


class ContactSet(ArraySet):
    """Contact arrays (see CONTACT_FIELDS) plus last step's contacts for warm starting, and the
    solver's rows (`rows`, one `ContactRow` per contact, scratch prepared every step)."""

    #: caches that snapshots keep by name only: `_sized` holds the identities of the arrays the
    #: solver structs were built from, so it differs in a restored world while meaning the same;
    #: `rows`, `impact_order`, the `relax_` arrays and `_passes` are solver scratch and parameters, made
    #: anew by every step (`impact_order` by every collision pass; the `relax_` arrays are zero again
    #: after every relax pass)
    SNAPSHOT_CACHES = frozenset(
        {"_sized", "rows", "_passes", "_struct", "impact_order", "relax_marked", "relax_body", "relax_listed"}
    )

    def __init__(self, device: str):
        super().__init__(CONTACT_FIELDS, device=device, capacity=64)
        self.count_array = wp.zeros(1, dtype=wp.int32, device=device)
        self.pair_count_array = wp.zeros(1, dtype=wp.int32, device=device)  # of pairs that carry no count of their own
        self.previous = ArraySet(PREVIOUS_FIELDS, device=device, capacity=64)
        # per contact: last step's impulses matched to it (normal; friction as a world vector plus the twist),
        # and the rows the solver's passes read
        self.jn_warm = wp.zeros(0, dtype=float_t, device=device)
        self.jt_world = wp.zeros(0, dtype=vec3, device=device)
        self.rows = wp.zeros(0, dtype=ContactRow, device=device)
        # this step's and last step's contact counts, on the device, for kernels launched over the capacity
        self.counts = wp.zeros(2, dtype=wp.int32, device=device)
        self.impact_clock = wp.zeros(1, dtype=wp.int64, device=device)  # ticks of the impact passes
        self._owner_capacity = 0
        self._sized: tuple = ()
        self._structs: SolverStructs | None = None
        self._passes: dict[tuple, SolvePass | ImpactPass] = {}
        self._struct: Contacts | None = None

    def grow(self, count: int) -> None:
        self.count = 0
        self.reserve(count)

    def begin_step(self) -> None:
        self.count_array.zero_()

    def writer(self) -> Contacts:
        """The contact arrays as the narrow phase appends to them, count zeroed (`struct`)."""
        self.count_array.zero_()
        return self.struct()

    def row_values(self, field: str) -> np.ndarray:
        """One field of the solver's rows (`ContactRow`, filled by `prepare`) for this step's contacts, a host copy."""
        return self.rows.numpy()[field][: self.count].copy()

    def struct(self) -> Contacts:
        """The contact arrays and their count as the kernels take them: one struct while the arrays are the same."""
        c = self._struct
        if c is None or c.body_a is not self.arrays["contact_body_a"]:
            c = self._struct = fill_struct(Contacts, {"contact_count": self.count_array, **self.arrays}, "contact_")
        return c

    def begin_solve(self, bodies) -> tuple:
        """Host side of the solver stages, before any of them runs: size the scratch buffers, put
        the contact counts on the device and build the solver structs (once per set of arrays).

        Returns what the recorded launches of the stages depend on (see `World._solver_graph`).
        """
        p = self.previous
        if p.capacity < self.capacity:
            p.reserve(self.capacity)  # store_impulses keeps up to `capacity` contacts
        dev = self.device
        if self.rows.shape[0] != self.capacity:
            self.jn_warm = wp.zeros(self.capacity, dtype=float_t, device=dev)
            self.jt_world = wp.zeros(self.capacity, dtype=vec3, device=dev)
            self.rows = wp.zeros(self.capacity, dtype=ContactRow, device=dev)
        sized = (
            bodies.capacity,
            self.capacity,
            p.capacity,
            id(bodies.arrays["body_velocity"]),
            id(self.arrays["contact_normal"]),
            id(p.arrays["previous_body_a"]),
            id(self.jt_world),
            id(self.rows),
        )
        if sized != self._sized[: len(sized)] or self._structs is None:
            if bodies.capacity != self._owner_capacity:
                self._owner_capacity = bodies.capacity
                self.owner_count = wp.zeros(bodies.capacity, dtype=wp.int32, device=dev)
                self.owner_start = wp.zeros(bodies.capacity, dtype=wp.int32, device=dev)
                self.owner_fill = wp.zeros(bodies.capacity, dtype=wp.int32, device=dev)
                self.body_count = wp.zeros(bodies.capacity, dtype=wp.int32, device=dev)
                self.impact_changed = wp.zeros(bodies.capacity, dtype=wp.int64, device=dev)
            self.owner_entries = wp.zeros(p.capacity, dtype=wp.int32, device=dev)
            self.impact_tested = wp.zeros(self.capacity, dtype=wp.int64, device=dev)
            self.impact_listed = wp.zeros(self.capacity, dtype=wp.int32, device=dev)
            self.impact_order = wp.zeros(self.capacity, dtype=wp.vec3i, device=dev)
            # (zero between relax passes: made anew with the structs, kept by a restore as caches)
            self.relax_marked = wp.zeros(2, dtype=wp.int32, device=dev)
            self.relax_body = wp.zeros(bodies.capacity, dtype=wp.int32, device=dev)
            self.relax_listed = wp.zeros(self.capacity, dtype=wp.int32, device=dev)
            relax = Relax()
            relax.marked, relax.body, relax.listed = self.relax_marked, self.relax_body, self.relax_listed
            relax.order = self.impact_order
            owners = Owners()
            owners.start, owners.count = self.owner_start, self.owner_count
            owners.fill, owners.entries = self.owner_fill, self.owner_entries
            previous = fill_struct(Previous, p.arrays, "previous_")
            ticks = Ticks()
            ticks.tested, ticks.changed, ticks.clock = self.impact_tested, self.impact_changed, self.impact_clock
            ticks.listed = self.impact_listed
            ticks.order = self.impact_order
            self._structs = SolverStructs(self.struct(), body_arrays(bodies)[0], previous, owners, ticks, relax)
            self._sized = sized + (id(self.impact_changed), id(self.impact_tested), id(self.impact_listed))
        count = self.count
        if self.device == "cpu":
            values = host_values(self.counts)  # the array's own memory
            values[0], values[1] = count, p.count
        else:
            self.counts.assign(np.array((count, p.count), dtype=np.int32))
        return self._sized + (count > 0,)

    def match_previous(self, bodies) -> None:
        """Carry last step's impulses over to the contacts that persist (warm starting)."""
        if self.count == 0:
            return
        assert self._structs is not None  # built by begin_solve, which runs before every solver stage
        c, b, p, owners = self._structs.contacts, self._structs.bodies, self._structs.previous, self._structs.owners
        dev = self.device
        self.owner_count.zero_()
        self.owner_fill.zero_()
        # last step's contacts bucketed by owner (counting sort), over their capacity (one thread on the CPU)
        cap = self.previous.capacity
        launch_each(_owner_count, cap, [p, b, owners, self.counts], dev)
        wp.utils.array_scan(self.owner_count, self.owner_start, inclusive=False)
        launch_each(_owner_scatter, cap, [p, b, owners, self.counts], dev)
        args = [c, b, MATCH_TOLERANCE, owners, p, self.jn_warm, self.jt_world, self.counts]
        launch_each(_match, self.capacity, args, dev)

    def remap_bodies(self, slot: np.ndarray, *, current: bool = False) -> None:
        """The body rows were renumbered (row i is now `slot[i]`, -1 if removed): follow them in
        last step's contacts, and with `current` in this step's too (what the views show).

        Contacts of a removed body are dropped. Pairs are ordered by body id, not row, so a
        renumbering never swaps a pair's bodies and every other contact keeps its warm start.
        """
        for contacts, a, b in ((self.previous, "previous_body_a", "previous_body_b"),) + (
            ((self, "contact_body_a", "contact_body_b"),) if current else ()
        ):
            if slot.min(initial=0) < 0:
                kept = np.flatnonzero((slot[contacts.numpy(a)] >= 0) & (slot[contacts.numpy(b)] >= 0))
                if len(kept) < contacts.count:
                    contacts.take(kept)
            for name in (a, b):
                rows = contacts.numpy(name)
                contacts.write(name, slice(0, contacts.count), slot[rows])

    def store_impulses(self, bodies) -> None:
        """Keep this step's contacts and impulses for the next step's warm start (`end_solve` then
        sets their count)."""
        if self.count == 0:
            return
        assert self._structs is not None  # built by begin_solve, which runs before every solver stage
        c, b, p = self._structs.contacts, self._structs.bodies, self._structs.previous
        launch_each(_store, self.capacity, [c, self.rows, b, p, self.counts], self.device)

    def end_solve(self) -> None:
        """Host side after the solver stages: the contacts stored for warm starting are this step's."""
        self.previous.count = self.count


def _serial(contacts: ContactSet) -> int:
    """1 where kernels run their threads one after another (the CPU): plain Gauss-Seidel updates."""
    return 1 if contacts.device == "cpu" else 0


def softness(h: float, *, stiffness: float = 1.0) -> tuple[float, float, float]:
    """(bias rate [1/s], mass scale, impulse scale) of the soft contact at substep h [s].

    A resting contact settles at an overlap of about g / omega^2 per body it carries
    (4 micrometres per body at the default 8 substeps of 1/240 s).
    """
    hertz = stiffness * CONTACT_HERTZ_PER_SUBSTEP_RATE / h
    omega = 2.0 * math.pi * hertz
    a1 = 2.0 * CONTACT_DAMPING_RATIO + h * omega
    a2 = h * omega * a1
    a3 = 1.0 / (1.0 + a2)
    return omega / a1, a2 * a3, a3


def prepare(bodies, contacts: ContactSet, dt: float) -> None:
    """Anchors, tangents, effective masses and combined materials, once per step of `dt` [s]: the solver's rows."""
    if contacts.count == 0:
        return
    assert contacts._structs is not None  # built by begin_solve, which runs before every solver stage
    jacobi = 0 if contacts.device == "cpu" else 1
    c, b = contacts._structs.contacts, contacts._structs.bodies
    if jacobi:
        contacts.body_count.zero_()
        launch_each(_body_contact_count, contacts.capacity, [c, contacts.body_count, contacts.counts], contacts.device)
    args = [c, b, contacts.jn_warm, contacts.jt_world, jacobi, contacts.body_count, contacts.counts, contacts.rows, dt]
    launch_each(_prepare, contacts.capacity, args, contacts.device)


def warm_start(bodies, contacts: ContactSet) -> None:
    """Apply last step's impulses of the matched contacts to the velocities (first substep only;
    later substeps get theirs from the relax pass, through `integrate_velocities`)."""
    if contacts.count:
        assert contacts._structs is not None  # built by begin_solve, which runs before every solver stage
        launch_each(
            _warm_start, contacts.capacity, [contacts.rows, contacts._structs.bodies, contacts.counts], contacts.device
        )


def solve(bodies, contacts: ContactSet, h: float, *, use_bias: bool, cache: LaunchCache | None = None) -> None:
    """One sweep of normal and friction impulses over all contacts at substep `h`."""
    if contacts.count == 0:
        return
    assert contacts._structs is not None  # built by begin_solve, which runs before every solver stage
    serial = _serial(contacts)
    args = [
        contacts.rows,
        contacts._structs.bodies,
        _solve_pass(contacts, h, use_bias),
        contacts.counts,
        contacts._structs.relax,
    ]
    launch(_SOLVES[serial], 1 if serial else contacts.capacity, args, contacts.device, cache)


def _solve_pass(contacts: ContactSet, h: float, use_bias: bool) -> SolvePass:
    """The parameters of a solve pass at substep h."""

    def parameters() -> SolvePass:
        p = SolvePass()
        p.inv_h = float_t(1.0 / h)
        p.use_bias = int(use_bias)
        p.bias_rate, p.mass_scale, p.impulse_scale = map(float_t, softness(h))
        p.static_bias_rate, p.static_mass_scale, p.static_impulse_scale = map(float_t, softness(h, stiffness=2.0))
        p.max_push = float_t(MAX_PUSH_VELOCITY)
        p.slop = float_t(LINEAR_SLOP)
        return p

    return _parameters(contacts, ("solve", h, use_bias), parameters)


def _parameters(contacts: ContactSet, key: tuple, make):
    """The struct of a pass's parameters that `make()` builds, one per key kept by the contact set: a
    recorded launch re-packs a struct argument only when it is another one."""
    p = contacts._passes.get(key)
    if p is None:
        if len(contacts._passes) >= 16:
            contacts._passes.clear()  # dt, substeps or gravity changed many times: keep only the passes in use
        p = contacts._passes[key] = make()
    return p


def impacts(
    bodies,
    contacts: ContactSet,
    gravity: np.ndarray,
    h: float,
    threshold: float,
    *,
    cache: LaunchCache | None = None,
) -> None:
    """Collide the contacts that close within the substep faster than `threshold` [m/s] (restitution).

    The step calls it before the first substep's gravity kick and before every relax pass, so
    with the velocities of the next substep but for its kick: the contacts that close within
    that substep, its kick included, collide. So no speculative clamp lands a bouncing contact
    first, and no impulse falls between a substep's kick and its position update (there, a
    box's corner striking in the first substep gained energy).

    On the CPU one thread sweeps the contacts forward then backward (Gauss-Seidel); on CUDA one
    thread per contact, with atomics and the Jacobi scale.
    """
    if contacts.count == 0:
        return
    assert contacts._structs is not None  # built by begin_solve, which runs before every solver stage

    def parameters() -> ImpactPass:
        p = ImpactPass()
        p.gravity, p.h, p.threshold = vec3(*gravity), float_t(h), float_t(threshold)
        p.floor = float_t(2.0 * float(np.linalg.norm(gravity)) * h)  # the approach speed gravity gives in two substeps
        return p

    p = _parameters(contacts, ("impacts", tuple(map(float, gravity)), h, threshold), parameters)
    serial = _serial(contacts)
    args = [
        contacts.rows,
        contacts._structs.bodies,
        p,
        contacts._structs.ticks,
        contacts.counts,
        contacts._structs.relax,
    ]
    launch(_IMPACTS[serial], 1 if serial else contacts.capacity, args, contacts.device, cache)
