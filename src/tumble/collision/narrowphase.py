"""Narrow phase: candidate pairs -> contact points, through one pair table.

Reads the broad phase's pairs and the bodies' poses and shapes; writes contact rows
(`contact_body_a/b`, `contact_normal`, `contact_point`, `contact_separation`, and the two
surface points in each body's frame, `contact_local_a/b`). Cost: O(pairs), at most four
contacts per pair.

Conventions:
- `collide_<a>_<b>` handles shapes a <= b in `ShapeType` order (PLANE < SPHERE < BOX < CAPSULE <
  CONVEX < MESH; `hull` in a name stands for CONVEX, and for a box meeting one); the
  dispatch kernel swaps a pair into that order, so the normal always points from body a to b;
- each contact carries one surface point on each body; their separation along the normal is
  s = n . (p_b - p_a) (negative when overlapping); contacts with s below the pair's
  speculative distance are kept, so bodies approaching within one step are caught before
  they overlap (no tunnelling);
- box-box uses the separating axis test over 15 axes; a face axis gives a manifold by
  clipping the incident face against the reference face (Sutherland-Hodgman), reduced to
  four points; an edge axis gives the closest points of the two edges.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..launch import LaunchCache, each_in_use, launch_each
from ..model import body_struct
from ..real import TYPES, BodyArrays, float_t, quat, vec3
from ..shapes import ShapeType
from ..state import host_values, host_view
from ..structs import array_struct
from .hulls import Hulls, HullSet
from .meshes import MeshSet

# forward code only: nothing differentiates through contacts, and the adjoint of the dispatch
# kernel (every pair function inlined) made NVRTC take over 15 minutes for sm_90 (65 s without)
wp.set_module_options({"enable_backward": False})

#: speculative distance added to the relative motion of a pair in one step [m]
SPECULATIVE_MARGIN = 0.002
#: a step lower than this part of the smaller body's inner half size is flush (`_ghost_step`)
GHOST_STEP = 0.01

vec8 = wp.types.vector(length=8, dtype=float_t)

_ZERO = wp.constant(float_t(0.0))
_ONE = wp.constant(float_t(1.0))
_HALF_SQRT2 = wp.constant(float_t(0.7071067811865476))  # cos 45 degrees
# a sphere's further mesh faces: a face whose normal is within 1.4 mrad of the nearest contact's
# is that contact's plane again; a concave neighbour's plane is as far as the mesh within float32's
# position error (relative 6e-8, a margin of 16 times it)
_COPLANAR = wp.constant(float_t(1.0 - 1.0e-6))
#: depths of mesh edges this close (relative to the body's bound) are equals: rounding, not geometry
#: (64 ulps of the precision: a ridge's edge and a diagonal ending on it, `collide_mesh_edges`)
_EDGE_TIE = wp.constant(float_t(64.0 * TYPES.eps))
#: a distance computed from coordinates of size s is known to about 16 ulps of s: what `_first_touch`
#: counts as touching (a ball resting at overlap 0 on one block touches the flush block it rolls onto)
_TOUCH_ROUNDING = wp.constant(float_t(16.0 * TYPES.eps))
_CONCAVE_TOLERANCE = wp.constant(float_t(1.0e-6))
_GHOST_STEP = wp.constant(float_t(GHOST_STEP))


#: the contact arrays the narrow phase appends to, one row a contact point (the solver's `ContactSet`
#: holds them; capacity = length of the arrays)
CONTACT_FIELDS = {
    "contact_body_a": wp.int32,
    "contact_body_b": wp.int32,
    "contact_normal": vec3,  # unit, a -> b
    "contact_point": vec3,  # [m]
    "contact_separation": float_t,  # [m], negative when overlapping
    "contact_local_a": vec3,  # surface point on a, body frame [m]
    "contact_local_b": vec3,
}

#: the contact arrays as kernels take them, with the count of the rows written (`count[0]`, an array of one):
#: `contact_normal` is `c.normal`
Contacts = array_struct("Contacts", {"contact_count": wp.int32, **CONTACT_FIELDS}, "contact_", __name__)


@wp.struct
class Pose:
    x: vec3
    q: quat


@wp.func
def emit(c: Contacts, a: int, b: int, pa_: Pose, pb_: Pose, n: vec3, p_a: vec3, p_b: vec3, max_sep: float_t):
    """Append one contact from surface points p_a (on a) and p_b (on b) and normal n (a -> b)."""
    s = wp.dot(n, p_b - p_a)
    if s > max_sep:
        return
    k = wp.atomic_add(c.count, 0, 1)
    if k < c.body_a.shape[0]:
        c.body_a[k] = a
        c.body_b[k] = b
        c.normal[k] = n
        c.point[k] = (p_a + p_b) * float_t(0.5)
        c.separation[k] = s
        c.local_a[k] = wp.quat_rotate_inv(pa_.q, p_a - pa_.x)
        c.local_b[k] = wp.quat_rotate_inv(pb_.q, p_b - pb_.x)


@wp.func
def _axis(q: quat, k: int):
    e = vec3(_ZERO, _ZERO, _ZERO)
    e[k] = _ONE
    return wp.quat_rotate(q, e)


# ---------------------------------------------------------------------------- pair functions


@wp.func
def collide_plane_sphere(c: Contacts, a: int, b: int, A: Pose, B: Pose, r: float_t, max_sep: float_t):
    # signed distance of the centre: d = n . (x_b - x_plane); separation = d - r
    n = _axis(A.q, 2)
    d = wp.dot(n, B.x - A.x)
    emit(c, a, b, A, B, n, B.x - n * d, B.x - n * r, max_sep)


@wp.func
def _box_corner(h: vec3, k: int):
    """Corner k (0-7) of a box of half extents h in its own frame: bit i of k negates axis i."""
    corner = vec3(h[0], h[1], h[2])
    if k & 1:
        corner[0] = -h[0]
    if k & 2:
        corner[1] = -h[1]
    if k & 4:
        corner[2] = -h[2]
    return corner


@wp.func
def collide_plane_box(c: Contacts, a: int, b: int, A: Pose, B: Pose, h: vec3, max_sep: float_t):
    # the (up to) four deepest of the eight corners
    n = _axis(A.q, 2)
    depth = vec8()
    for k in range(8):
        depth[k] = wp.dot(n, B.x + wp.quat_rotate(B.q, _box_corner(h, k)) - A.x)
    taken = int(0)
    for _pick in range(4):
        best = int(-1)
        for k in range(8):
            if (taken & (1 << k)) == 0:
                if best < 0 or depth[k] < depth[best]:
                    best = k
        taken = taken | (1 << best)
        if depth[best] <= max_sep:
            p = B.x + wp.quat_rotate(B.q, _box_corner(h, best))
            emit(c, a, b, A, B, n, p - n * depth[best], p, max_sep)


# the R2 sequence's two steps (Roberts 2018: 1/g and 1/g^2, g^3 = g + 1) in units of 2^-32
_R2_STEP_1 = wp.constant(wp.uint32(3242174889))
_R2_STEP_2 = wp.constant(wp.uint32(2447445413))


@wp.func
def _pair_direction(a: int, b: int):
    """A unit vector that differs from pair to pair, for the normal of two coincident centres.

    The pair's number m (over all pairs of ids) picks point m of the R2 low-discrepancy sequence,
    mapped to the sphere by equal areas: pairs of neighbouring ids point apart, so a knot of bodies
    placed at one point spreads out in every direction rather than stacking along one axis, where
    each pair's push-out would add to the next. Integer arithmetic (the sequence's fractions to
    24 bits, exact in float32): the same pair gets the same direction in both precisions, on
    every device.
    """
    lo = wp.uint32(wp.min(a, b))
    hi = wp.uint32(wp.max(a, b))
    m = ((hi * (hi - wp.uint32(1))) >> wp.uint32(1)) + lo
    scale = float_t(1.0 / 16777216.0)
    u = float_t((m * _R2_STEP_1) >> wp.uint32(8)) * scale
    v = float_t((m * _R2_STEP_2) >> wp.uint32(8)) * scale
    z = _ONE - float_t(2.0) * u
    r = wp.sqrt(wp.max(_ONE - z * z, _ZERO))
    phi = float_t(6.283185307179586) * v
    return vec3(r * wp.cos(phi), r * wp.sin(phi), z)


@wp.func
def collide_sphere_sphere(
    c: Contacts,
    a: int,
    b: int,
    A: Pose,
    B: Pose,
    ra: float_t,
    rb: float_t,
    dv: vec3,
    dt: float_t,
    max_sep: float_t,
):
    """Two spheres; `dv` = v_b - v_a [m/s], the relative velocity over the step of `dt` [s].

    The normal is the line of centres at the moment of impact when the spheres, apart now, meet
    within the step: with dv held (gravity moves both alike), the centres are ra + rb apart at the
    first root t* of |d + dv t| = ra + rb. The contact keeps its normal for every substep, so the
    line of centres now would push an oblique hit off its true direction by about the angle the
    pair turns until impact (0.025 rad at 3 m/s, dt = 1/240 s, r = 0.1 m). Its gap along that
    normal is then t* times the closing speed, so the speculative contact lets them meet at t*.
    """
    d = B.x - A.x
    dist = wp.length(d)
    n = _pair_direction(a, b)
    if dist > float_t(1e-12):
        n = d / dist
    reach = ra + rb
    closing = wp.dot(d, dv)
    speed2 = wp.dot(dv, dv)
    if dist > reach and closing < _ZERO:
        # |d + dv t|^2 = reach^2: speed2 t^2 + 2 closing t + excess = 0, first root
        excess = dist * dist - reach * reach
        disc = closing * closing - speed2 * excess
        if disc >= _ZERO:
            t = excess / (-closing + wp.sqrt(disc))  # the smaller root, stably
            if t <= dt:
                hit = d + dv * t
                length = wp.length(hit)
                if length > float_t(1e-12):
                    n = hit / length
    emit(c, a, b, A, B, n, A.x + n * ra, B.x - n * rb, max_sep)


@wp.func
def box_closest(p: vec3, h: vec3):
    """Signed distance of a point from a box's surface, box frame (half extents h).

    Returns (closest surface point, outward unit normal there, signed distance d). Outside,
    d > 0 is the distance to the clamped point; inside, d < 0 and the point leaves through the
    nearest face.
    """
    q = vec3(wp.clamp(p[0], -h[0], h[0]), wp.clamp(p[1], -h[1], h[1]), wp.clamp(p[2], -h[2], h[2]))
    delta = p - q
    dist = wp.length(delta)
    if dist > float_t(1e-12):
        return q, delta / dist, dist
    best = int(0)
    gap = h[0] - wp.abs(p[0])
    for k in range(1, 3):
        g = h[k] - wp.abs(p[k])
        if g < gap:
            gap = g
            best = k
    out = vec3(_ZERO, _ZERO, _ZERO)
    if p[best] >= _ZERO:
        out[best] = _ONE
        q[best] = h[best]
    else:
        out[best] = -_ONE
        q[best] = -h[best]
    return q, out, -gap


@wp.func
def collide_sphere_box(
    c: Contacts, a: int, b: int, A: Pose, B: Pose, r: float_t, h: vec3, dv: vec3, dt: float_t, max_sep: float_t
):
    """A sphere (a) and a box (b); `dv` = v_b - v_a. The normal is the box's at the moment of impact
    when the sphere, apart now, touches it within the step (`_first_touch`)."""
    # closest point of the box to the sphere centre (at impact), in the box frame
    p = wp.quat_rotate_inv(B.q, A.x - B.x)
    u = wp.quat_rotate_inv(B.q, -dv)
    t = _first_touch(p, u, dt, r, Hulls(), -1, vec3(), h, max_sep)
    q, out, d = box_closest(p + u * t, h)  # out: box -> sphere, box frame
    n = -wp.quat_rotate(B.q, out)  # sphere (a) -> box (b)
    emit(c, a, b, A, B, n, A.x + n * r, B.x + wp.quat_rotate(B.q, q), max_sep)


@wp.func
def _box_projection(q: quat, h: vec3, axis: vec3):
    # half-width of an oriented box along a unit axis: sum_k h_k |axis . e_k|
    return (
        h[0] * wp.abs(wp.dot(axis, _axis(q, 0)))
        + h[1] * wp.abs(wp.dot(axis, _axis(q, 1)))
        + h[2] * wp.abs(wp.dot(axis, _axis(q, 2)))
    )


@wp.struct
class Polygon:
    """Up to eight points in reference-face coordinates: (u, v) in the face, d along its normal."""

    u: vec8
    v: vec8
    d: vec8
    count: int


@wp.func
def _clip(p: Polygon, axis: int, sign: float_t, limit: float_t):
    """Clip polygon p against sign * coordinate(axis) <= limit (Sutherland-Hodgman)."""
    out = Polygon()
    m = int(0)
    for k in range(p.count):
        k2 = (k + 1) % p.count
        c1 = sign * p.u[k]
        c2 = sign * p.u[k2]
        if axis == 1:
            c1 = sign * p.v[k]
            c2 = sign * p.v[k2]
        in1 = c1 <= limit
        in2 = c2 <= limit
        if in1:
            out.u[m] = p.u[k]
            out.v[m] = p.v[k]
            out.d[m] = p.d[k]
            m += 1
        if in1 != in2:
            t = (limit - c1) / (c2 - c1)
            out.u[m] = p.u[k] + t * (p.u[k2] - p.u[k])
            out.v[m] = p.v[k] + t * (p.v[k2] - p.v[k])
            out.d[m] = p.d[k] + t * (p.d[k2] - p.d[k])
            m += 1
    out.count = m
    return out


@wp.func
def _reduce_manifold(u2: vec8, v2: vec8, d2: vec8, m: int):
    """Bit mask of at most four of m points (u, v, depth d): the deepest, the farthest from it,
    then the largest triangles on either side of the line through those two."""
    chosen = int(0)
    if m <= 4:
        chosen = (1 << m) - 1
    else:
        i0 = int(0)
        for k in range(1, m):
            if d2[k] < d2[i0]:
                i0 = k
        i1 = int(0)
        far = float_t(-1.0)
        for k in range(m):
            dd = (u2[k] - u2[i0]) * (u2[k] - u2[i0]) + (v2[k] - v2[i0]) * (v2[k] - v2[i0])
            if dd > far:
                far = dd
                i1 = k
        i2 = int(-1)
        i3 = int(-1)
        amax = _ZERO
        amin = _ZERO
        for k in range(m):
            area = (u2[i1] - u2[i0]) * (v2[k] - v2[i0]) - (v2[i1] - v2[i0]) * (u2[k] - u2[i0])
            if area > amax:
                amax = area
                i2 = k
            if area < amin:
                amin = area
                i3 = k
        chosen = (1 << i0) | (1 << i1)
        if i2 >= 0:
            chosen = chosen | (1 << i2)
        if i3 >= 0:
            chosen = chosen | (1 << i3)
    return chosen


@wp.func
def _emit_manifold(
    c: Contacts,
    a: int,
    b: int,
    A: Pose,
    B: Pose,
    n: vec3,
    origin: vec3,
    U: vec3,
    V: vec3,
    u2: vec8,
    v2: vec8,
    d2: vec8,
    m: int,
    ref_is_a: bool,
    max_sep: float_t,
):
    """Emit the points of a face clip (m points at origin + u U + v V + d n on the incident side,
    d their depth along the reference face's normal n), reduced to at most four (`_reduce_manifold`)."""
    chosen = _reduce_manifold(u2, v2, d2, m)
    for k in range(m):
        if chosen & (1 << k):
            on_inc = origin + U * u2[k] + V * v2[k] + n * d2[k]
            on_ref = on_inc - n * d2[k]
            if ref_is_a:
                emit(c, a, b, A, B, n, on_ref, on_inc, max_sep)
            else:
                emit(c, a, b, A, B, -n, on_inc, on_ref, max_sep)


@wp.func
def _face_contacts(
    c: Contacts, a: int, b: int, A: Pose, B: Pose, ha: vec3, hb: vec3, ref_is_a: bool, axis: int, max_sep: float_t
):
    """Manifold for a face axis: `axis` of the reference box (A if ref_is_a) against the other box;
    returns the number of points kept (0: the incident face clips to nothing within reach)."""
    R = A
    I = B
    hr = ha
    hi = hb
    if not ref_is_a:
        R = B
        I = A
        hr = hb
        hi = ha
    n = _axis(R.q, axis)
    if wp.dot(n, I.x - R.x) < _ZERO:
        n = -n  # reference face normal, towards the incident box
    iu = (axis + 1) % 3
    iv = (axis + 2) % 3
    U = _axis(R.q, iu)
    V = _axis(R.q, iv)
    face = R.x + n * hr[axis]
    # incident face: the face of I most anti-parallel to n
    best = int(0)
    best_dot = wp.dot(_axis(I.q, 0), n)
    for k in range(1, 3):
        dk = wp.dot(_axis(I.q, k), n)
        if wp.abs(dk) > wp.abs(best_dot):
            best = k
            best_dot = dk
    out = _axis(I.q, best)
    if best_dot > _ZERO:
        out = -out
    j1 = (best + 1) % 3
    j2 = (best + 2) % 3
    e1 = _axis(I.q, j1) * hi[j1]
    e2 = _axis(I.q, j2) * hi[j2]
    centre = I.x + out * hi[best]
    # the incident quad in reference-face coordinates (u, v, depth along n)
    quad = Polygon()
    for k in range(4):
        s1 = _ONE
        s2 = _ONE
        if k == 1 or k == 2:
            s1 = -_ONE
        if k >= 2:
            s2 = -_ONE
        p = centre + e1 * s1 + e2 * s2 - face
        quad.u[k] = wp.dot(p, U)
        quad.v[k] = wp.dot(p, V)
        quad.d[k] = wp.dot(p, n)
    quad.count = 4
    # clip against the four sides of the reference face
    poly = _clip(quad, 0, _ONE, hr[iu])
    poly = _clip(poly, 0, -_ONE, hr[iu])
    poly = _clip(poly, 1, _ONE, hr[iv])
    poly = _clip(poly, 1, -_ONE, hr[iv])
    count = poly.count
    u = poly.u
    v = poly.v
    d = poly.d
    u2 = vec8()
    v2 = vec8()
    d2 = vec8()
    # keep the points within the speculative distance, merging near-duplicates (nearly aligned
    # faces clip to pairs of almost equal corners; merging keeps the manifold the same each step)
    merge = float_t(0.02) * wp.min(wp.min(hr[iu], hr[iv]), wp.min(hi[j1], hi[j2]))
    m = int(0)
    for k in range(count):
        if d[k] <= max_sep:
            fresh = bool(True)
            for e in range(m):
                if wp.abs(u2[e] - u[k]) < merge and wp.abs(v2[e] - v[k]) < merge:
                    fresh = False
                    if d[k] < d2[e]:
                        d2[e] = d[k]
            if fresh:
                u2[m] = u[k]
                v2[m] = v[k]
                d2[m] = d[k]
                m += 1
    if m > 0:
        # reduce to at most four: deepest, farthest from it, then the largest triangles either side
        _emit_manifold(c, a, b, A, B, n, face, U, V, u2, v2, d2, m, ref_is_a, max_sep)
    return m


@wp.func
def _lines_closest(pa: vec3, ua: vec3, ha: float_t, pb: vec3, ub: vec3):
    """(e, f, g, s) for the closest points pa + s ua, pb + t ub of two lines (unit directions):
    e = ua.ub, f = ua.r, g = ub.r with r = pa - pb, and s the free optimum clamped to |s| <= ha
    (0 for parallel lines); `_segment_closest` and the box edge pairs go on from there."""
    r = pa - pb
    e = wp.dot(ua, ub)
    f = wp.dot(ua, r)
    g = wp.dot(ub, r)
    den = _ONE - e * e
    s = _ZERO
    if den > float_t(1e-12):
        s = wp.clamp((e * g - f) / den, -ha, ha)
    return e, f, g, s


@wp.func
def _edge_contact(
    c: Contacts, a: int, b: int, A: Pose, B: Pose, ha: vec3, hb: vec3, i: int, j: int, L: vec3, max_sep: float_t
):
    """Closest points of edge i of A and edge j of B for the cross axis L (oriented A -> B)."""
    pa = A.x
    pb = B.x
    for k in range(3):
        if k != i:
            ak = _axis(A.q, k)
            sa = _ONE
            if wp.dot(ak, L) < _ZERO:
                sa = -_ONE
            pa = pa + ak * (sa * ha[k])
        if k != j:
            bk = _axis(B.q, k)
            sb = _ONE
            if wp.dot(bk, L) > _ZERO:
                sb = -_ONE
            pb = pb + bk * (sb * hb[k])
    da = _axis(A.q, i)
    db = _axis(B.q, j)
    # closest points of the lines pa + s da, pb + t db (|da| = |db| = 1), clamped to the edges
    e, f, g, s = _lines_closest(pa, da, ha[i], pb, db)
    t = wp.clamp(e * s + g, -hb[j], hb[j])
    s = wp.clamp(e * t - f, -ha[i], ha[i])
    emit(c, a, b, A, B, L, pa + da * s, pb + db * t, max_sep)


#: face normals within this cosine of each other are one axis (`_ghost_step`)
_PARALLEL = wp.constant(float_t(0.99))


@wp.func
def _ghost_step(apart: float_t, thinnest: float_t, inner: float_t):
    """Whether two bodies meet only at an edge where a step no higher than their contact's give
    begins, to be passed over: no contact this step.

    `apart` is the largest separation over the two bodies' face axes (> 0: apart along it, a
    speculative contact), `thinnest` their smallest overlap along another face axis, not parallel
    to that one (the largest separation <= 0 there), `inner` the smaller body's least half size.
    Bodies that overlap along both axes by less than GHOST_STEP of `inner` (or are apart along the
    first) meet on a sliver at most that thin: a body resting on a face sinks by its contact's give
    (1 um at dt = 1/240 s and 8 substeps, 0.3 mm at 1/30 s and 4), so sliding across the seam of
    two coplanar boxes it met the next box's side as a wall of that height, face to face (as a
    speculative contact, or once it touched, as the axis of least overlap) and stopped: a cube at
    2 m/s lost 1.3 m/s and hopped 4 cm. Once the body is over the next face by more than the give,
    that face's manifold carries it (its axis then separates least). Only pairs with a static or
    kinematic body (`seams`, the blocks a level is built of) take the rule: a moving body's corner
    landing on a sliver of another's edge would go a step deep (the rain of 1,000 boxes overlapped
    12.5 mm during its impacts with the rule on every pair, against 9.1 mm without).
    """
    tol = _GHOST_STEP * inner
    return apart > -tol and thinnest > -tol


@wp.func
def collide_box_box(c: Contacts, a: int, b: int, A: Pose, B: Pose, ha: vec3, hb: vec3, max_sep: float_t, seams: bool):
    T = B.x - A.x
    apart = float_t(-1.0e30)  # the largest separation over the face axes, and its axis
    apart_axis = vec3()
    best_sep = float_t(-1.0e30)
    best_kind = int(-1)  # 0: face of A, 1: face of B, 2: edge-edge
    best_i = int(0)
    face_seps = vec8()  # each face axis's separation, for the seam rule
    # face axes of A then of B
    for k in range(6):
        axis = vec3()
        if k < 3:
            axis = _axis(A.q, k)
        else:
            axis = _axis(B.q, k - 3)
        s = wp.abs(wp.dot(T, axis)) - _box_projection(A.q, ha, axis) - _box_projection(B.q, hb, axis)
        if s > max_sep:
            return
        face_seps[k] = s
        if s > apart:
            apart = s
            apart_axis = axis
        # B's faces must beat A's clearly, so the reference face does not flip between steps
        better = s > best_sep
        if k >= 3:
            better = s > float_t(0.98) * best_sep + float_t(0.0005)
        if better:
            best_sep = s
            best_kind = 0
            if k >= 3:
                best_kind = 1
            best_i = k % 3
    face_sep = best_sep
    inner = wp.min(wp.min(wp.min(ha[0], ha[1]), ha[2]), wp.min(wp.min(hb[0], hb[1]), hb[2]))
    if seams and apart > -_GHOST_STEP * inner:
        # the smallest overlap along a face axis across the largest separation's
        thinnest = float_t(-1.0e30)
        for k in range(6):
            axis = vec3()
            if k < 3:
                axis = _axis(A.q, k)
            else:
                axis = _axis(B.q, k - 3)
            if wp.abs(wp.dot(axis, apart_axis)) < _PARALLEL and face_seps[k] <= _ZERO:
                thinnest = wp.max(thinnest, face_seps[k])
        if _ghost_step(apart, thinnest, inner):
            return
    # edge-edge axes; prefer faces unless an edge axis separates clearly more (stable manifolds)
    edge_sep = float_t(-1.0e30)
    edge_i = int(-1)
    edge_j = int(0)
    edge_axis = vec3()
    for i in range(3):
        for j in range(3):
            axis = wp.cross(_axis(A.q, i), _axis(B.q, j))
            length = wp.length(axis)
            if length > float_t(1e-6):
                axis = axis / length
                s = wp.abs(wp.dot(T, axis)) - _box_projection(A.q, ha, axis) - _box_projection(B.q, hb, axis)
                if s > max_sep:
                    return
                if s > edge_sep:
                    edge_sep = s
                    edge_i = i
                    edge_j = j
                    edge_axis = axis
    if edge_i >= 0 and edge_sep > float_t(0.95) * face_sep + float_t(0.001) and edge_sep > face_sep:
        best_kind = 2
    if best_kind != 2:
        kept = _face_contacts(c, a, b, A, B, ha, hb, best_kind == 0, best_i, max_sep)
        if kept == 0 and edge_i >= 0:
            # the face preferred for a steady manifold clips to nothing within reach: the boxes
            # meet edge to edge (a crossed edge sunk 0.74 mm into a resting box had no contact)
            best_kind = 2
    if best_kind == 2:
        if wp.dot(edge_axis, T) < _ZERO:
            edge_axis = -edge_axis
        _edge_contact(c, a, b, A, B, ha, hb, edge_i, edge_j, edge_axis, max_sep)


# ---------------------------------------------------------------------------- capsules
# A capsule of radius r and half height a is the set of points within r of the segment
# x + t u, t in [-a, a], u = the body's z axis; it is stored with body_radius = r and
# body_half_extents = (r, r, a + r), the half extents of its bounding box.


@wp.func
def _capsule_half_height(r: float_t, h: vec3):
    return h[2] - r


@wp.func
def _perpendicular(u: vec3):
    """A unit vector perpendicular to the unit vector u."""
    t = vec3(_ONE, _ZERO, _ZERO)
    if wp.abs(u[0]) > float_t(0.9):
        t = vec3(_ZERO, _ONE, _ZERO)
    t = t - u * wp.dot(u, t)
    return wp.normalize(t)


@wp.func
def _sphere_pair(
    c: Contacts,
    a: int,
    b: int,
    A: Pose,
    B: Pose,
    ca: vec3,
    ra: float_t,
    cb: vec3,
    rb: float_t,
    fallback: vec3,
    max_sep: float_t,
):
    """Contact of two spheres (centres ca on a, cb on b); `fallback` is the normal for coincident centres."""
    d = cb - ca
    dist = wp.length(d)
    n = fallback
    if dist > float_t(1e-12):
        n = d / dist
    emit(c, a, b, A, B, n, ca + n * ra, cb - n * rb, max_sep)


@wp.func
def collide_plane_capsule(c: Contacts, a: int, b: int, A: Pose, B: Pose, r: float_t, h: vec3, max_sep: float_t):
    # the two end spheres against the plane: at most two contacts, a line contact when lying flat
    n = _axis(A.q, 2)
    u = _axis(B.q, 2)
    hh = _capsule_half_height(r, h)
    for k in range(2):
        e = B.x + u * hh
        if k == 1:
            e = B.x - u * hh
        d = wp.dot(n, e - A.x)
        emit(c, a, b, A, B, n, e - n * d, e - n * r, max_sep)


@wp.func
def collide_sphere_capsule(
    c: Contacts, a: int, b: int, A: Pose, B: Pose, ra: float_t, rb: float_t, h: vec3, max_sep: float_t
):
    # the sphere against the nearest point of the capsule's segment
    u = _axis(B.q, 2)
    hh = _capsule_half_height(rb, h)
    t = wp.clamp(wp.dot(A.x - B.x, u), -hh, hh)
    _sphere_pair(c, a, b, A, B, A.x, ra, B.x + u * t, rb, _perpendicular(u), max_sep)


def _golden_section(objective):
    """A Warp function that narrows [lo, hi] around the minimum over t of `objective` at p0 + t u, a
    convex function of t, by `steps` steps of golden-section search (each shrinks the interval by
    0.618); it returns the final (lo, hi). `objective(p, H, i, j, a, b)` takes the point and hands
    the rest through (a hull's rows and sizes, as each objective names them)."""

    @wp.func
    def search(p0: vec3, u: vec3, lo: float_t, hi: float_t, steps: int, H: Hulls, i: int, j: int, a: vec3, b: vec3):
        g = float_t(0.6180339887498949)
        x1 = hi - g * (hi - lo)
        x2 = lo + g * (hi - lo)
        f1 = objective(p0 + u * x1, H, i, j, a, b)
        f2 = objective(p0 + u * x2, H, i, j, a, b)
        for _it in range(steps):
            if f1 <= f2:
                hi = x2
                x2 = x1
                f2 = f1
                x1 = hi - g * (hi - lo)
                f1 = objective(p0 + u * x1, H, i, j, a, b)
            else:
                lo = x1
                x1 = x2
                f1 = f2
                x2 = lo + g * (hi - lo)
                f2 = objective(p0 + u * x2, H, i, j, a, b)
        return lo, hi

    return search


@wp.func
def _convex_distance(p: vec3, H: Hulls, h: int, _unused: int, one: vec3, hb: vec3):
    """Signed distance of p from a box (h < 0: half extents hb) or from hull h (scaled by `one`)."""
    if h < 0:
        _q, _o, f = box_closest(p, hb)
        return f
    _q, _o, f = hull_closest(H, h, one, p)
    return f


#: the signed distance from a convex set is a convex function, and so is its restriction to a line:
#: 40 steps shrink [lo, hi] by 0.618^40 ~ 4e-9
_nearest_along = _golden_section(_convex_distance)


@wp.func
def _golden_min(p0: vec3, u: vec3, lo: float_t, hi: float_t, H: Hulls, h: int, one: vec3, hb: vec3):
    """Parameter t in [lo, hi] minimising the signed distance of p0 + t u from a box or a hull
    (`_convex_distance`)."""
    lo, hi = _nearest_along(p0, u, lo, hi, 40, H, h, 0, one, hb)
    return (lo + hi) * float_t(0.5)


@wp.func
def _first_touch(p0: vec3, u: vec3, dt: float_t, r: float_t, H: Hulls, h: int, one: vec3, hb: vec3, max_sep: float_t):
    """The time t in [0, 2 dt] [s] at which a sphere of radius r, its centre moving as p0 + t u (the
    frame of a box, h < 0, half extents hb, or of hull h), first touches it within two steps; 0 when
    it touches now, will not within them, or is out of the speculative reach `max_sep`.

    A speculative contact keeps its normal for every substep, so the normal at the start pushes a
    sphere off its true path by the angle it turns about the feature it meets: rolling at 2 m/s
    (r = 0.1 m) over the seam of two flush blocks, the next block's edge, met at the step's start
    8 mm ahead, kicked it up at 0.3 m/s (a 4.7 mm hop; 2 cm at dt = 1/60 s). At the moment of
    impact the sphere meets that block's face (or the edge at the tilt where the sphere's give
    would let it touch). The distance from a convex set along a line is convex in t, so its
    minimum over the step (golden section) tells whether the sphere touches, and bisection
    between 0 and that minimum finds the first touch, to 1e-9 of the step. The search looks two
    steps ahead: the last substep's relax pass holds the contact for the next substep's motion.
    """
    gap = _convex_distance(p0, H, h, 0, one, hb) - r
    ahead = float_t(2.0) * dt
    if gap <= _ZERO or gap > max_sep or wp.length(u) * ahead < gap:
        return _ZERO
    target = r
    end = ahead
    if _convex_distance(p0 + u * ahead, H, h, 0, one, hb) > r:
        lo, hi = _nearest_along(p0, u, _ZERO, ahead, 30, H, h, 0, one, hb)
        end = (lo + hi) * float_t(0.5)
        nearest = _convex_distance(p0 + u * end, H, h, 0, one, hb)
        # touching: within the rounding of the distances, which are worked from coordinates of |p0|
        # (a ball resting at overlap 0 rolls onto a flush block at distance r from it: in float32 the
        # block frame's 2.5 m put it 2.4e-8 over, it passed by, and the edge's normal made it hop
        # 4.7 mm); then the first point as near as the path comes (on the face, not before the edge)
        if nearest > r + _TOUCH_ROUNDING * (wp.length(p0) + wp.length(u) * ahead + r):
            return _ZERO  # passes by
        target = wp.max(r, nearest)
    lo = _ZERO
    hi = end
    for _k in range(30):
        mid = (lo + hi) * float_t(0.5)
        if _convex_distance(p0 + u * mid, H, h, 0, one, hb) > target:
            lo = mid
        else:
            hi = mid
    return lo


@wp.func
def _nearest_on_segment(p0: vec3, u: vec3, hh: float_t, h: vec3):
    """The t in [-hh, hh] of the segment point p0 + t u nearest a box (half extents h): golden
    section (`_golden_min`), then, while the point is outside the box, moved to the segment's point
    nearest the box's point nearest it, twice (alternating projections, which never move the pair apart).

    Where a segment's distance from the box is flat (a capsule lying along an edge), golden section
    stops anywhere within sqrt(eps) of the distance past the flat part: the box point there is the
    edge's end, and the normal tilted along the segment by as much, 4e-4 rad in float32 (2e-8 in
    float64). Projected back, the segment point lies over the edge and the normal is square to it."""
    t = _golden_min(p0, u, -hh, hh, Hulls(), -1, vec3(), h)  # a box: no hull
    for _k in range(2):
        q, _n, d = box_closest(p0 + u * t, h)
        if d <= _ZERO:
            return t
        t = wp.clamp(wp.dot(q - p0, u) / wp.dot(u, u), -hh, hh)
    return t


@wp.func
def collide_box_capsule(
    c: Contacts,
    a: int,
    b: int,
    A: Pose,
    B: Pose,
    ha: vec3,
    rb: float_t,
    hb: vec3,
    dv: vec3,
    dt: float_t,
    max_sep: float_t,
):
    """A box (a) and a capsule (b); `dv` = v_b - v_a. Found where the capsule's deepest point first
    touches the box within the step, when it is apart now (`_first_touch`), and its points on the
    capsule moved back to now."""
    # the capsule's segment in the box frame: p(t) = p0 + t u, t in [-a, a]
    hh = _capsule_half_height(rb, hb)
    p0 = wp.quat_rotate_inv(A.q, B.x - A.x)
    u = wp.quat_rotate_inv(A.q, _axis(B.q, 2))
    t = _nearest_on_segment(p0, u, hh, ha)
    motion = wp.quat_rotate_inv(A.q, dv)
    shift = motion * _first_touch(p0 + u * t, motion, dt, rb, Hulls(), -1, vec3(), ha, max_sep)
    back = wp.quat_rotate(A.q, shift)  # world frame, from the capsule's place at impact to now
    if wp.length_sq(shift) > _ZERO:
        p0 = p0 + shift
        t = _nearest_on_segment(p0, u, hh, ha)
    q, out, d = box_closest(p0 + u * t, ha)
    # the box face nearest the contact normal; a segment nearly parallel to it (within ~11 deg)
    # is clipped to the face rectangle, and its two ends are the manifold (a line contact)
    k = int(0)
    for j in range(1, 3):
        if wp.abs(out[j]) > wp.abs(out[k]):
            k = j
    side = _ONE
    if out[k] < _ZERO:
        side = -_ONE
    if wp.abs(u[k]) < float_t(0.2):
        lo = -hh
        hi = hh
        for j in range(3):
            if j != k:
                # |p0_j + t u_j| <= ha_j
                if wp.abs(u[j]) > float_t(1e-12):
                    t1 = (-ha[j] - p0[j]) / u[j]
                    t2 = (ha[j] - p0[j]) / u[j]
                    lo = wp.max(lo, wp.min(t1, t2))
                    hi = wp.min(hi, wp.max(t1, t2))
                elif wp.abs(p0[j]) > ha[j]:
                    hi = lo - _ONE
        # (when the deepest point is beyond the face, over an edge, it is added as a third contact)
        tol = float_t(1e-6) * (_ONE + hh)
        if hi - lo > float_t(1e-9) * (_ONE + hh):
            f = vec3(_ZERO, _ZERO, _ZERO)
            f[k] = side
            n = wp.quat_rotate(A.q, f)
            for e in range(2):
                te = lo
                if e == 1:
                    te = hi
                p = p0 + u * te
                on_box = vec3(p[0], p[1], p[2])
                on_box[k] = side * ha[k]
                pw = A.x + wp.quat_rotate(A.q, p) - back
                emit(c, a, b, A, B, n, A.x + wp.quat_rotate(A.q, on_box), pw - n * rb, max_sep)
            if t >= lo - tol and t <= hi + tol:
                return
    n = wp.quat_rotate(A.q, out)
    pb = A.x + wp.quat_rotate(A.q, p0 + u * t) - back - n * rb
    emit(c, a, b, A, B, n, A.x + wp.quat_rotate(A.q, q), pb, max_sep)


@wp.func
def _segment_closest(pa: vec3, ua: vec3, ha: float_t, pb: vec3, ub: vec3, hb: float_t):
    """Parameters (s, t) of the closest points pa + s ua, pb + t ub of two segments, |s| <= ha, |t| <= hb.

    Unit directions; minimise |r + s ua - t ub|^2 with r = pa - pb: the free optimum solves
    s = e t - f, t = e s + g (e = ua.ub, f = ua.r, g = ub.r); clamp s, take the best t for it,
    and if t clamps, the best s for that t (Ericson, Real-Time Collision Detection, 5.1.9).
    """
    e, f, g, s = _lines_closest(pa, ua, ha, pb, ub)
    t = e * s + g
    if t < -hb:
        t = -hb
        s = wp.clamp(e * t - f, -ha, ha)
    elif t > hb:
        t = hb
        s = wp.clamp(e * t - f, -ha, ha)
    return s, t


segment_closest = _segment_closest  # for cloth edges against mesh edges (cloth/collide.py)


@wp.func
def collide_capsule_capsule(
    c: Contacts, a: int, b: int, A: Pose, B: Pose, ra: float_t, ha: vec3, rb: float_t, hb: vec3, max_sep: float_t
):
    la = _capsule_half_height(ra, ha)
    lb = _capsule_half_height(rb, hb)
    ua = _axis(A.q, 2)
    ub = _axis(B.q, 2)
    s, t = _segment_closest(A.x, ua, la, B.x, ub, lb)
    d = B.x + ub * t - (A.x + ua * s)
    dist = wp.length(d)
    n = wp.cross(ua, ub)
    if wp.length(n) > float_t(1e-9):
        n = wp.normalize(n)
        if wp.dot(n, B.x - A.x) < _ZERO:
            n = -n
    else:
        n = _perpendicular(ua)
    if dist > float_t(1e-12):
        n = d / dist
    # nearly parallel segments (within ~11 deg) that overlap along A's axis: a contact at each end
    # of the overlap, each with the closest point of B's segment, so a capsule lies still on another
    e = wp.dot(ua, ub)
    if _ONE - e * e < float_t(0.04):
        c0 = wp.dot(B.x - A.x, ua)
        lo = wp.max(-la, c0 - wp.abs(e) * lb)
        hi = wp.min(la, c0 + wp.abs(e) * lb)
        if hi - lo > float_t(1e-9) * (_ONE + la):
            nearest = float_t(1.0e30)
            for k in range(2):
                sk = lo
                if k == 1:
                    sk = hi
                pa = A.x + ua * sk
                tk = wp.clamp(wp.dot(pa - B.x, ub), -lb, lb)
                nearest = wp.min(nearest, wp.length(B.x + ub * tk - pa))
                _sphere_pair(c, a, b, A, B, pa, ra, B.x + ub * tk, rb, n, max_sep)
            # crossing segments are nearest between the ends: that point is a third contact
            if dist >= nearest - float_t(1e-9) * (_ONE + la):
                return
    _sphere_pair(c, a, b, A, B, A.x + ua * s, ra, B.x + ub * t, rb, n, max_sep)


# ---------------------------------------------------------------------------- convex hulls
# A hull is a slice of the `Hulls` arrays (see collision.hulls) in its body frame; `sc` scales
# its vertices per axis, so the unit-cube prototype 0 stands for any box that meets a hull.

vec16 = wp.types.vector(length=16, dtype=float_t)


@wp.func
def _hull_vertex(H: Hulls, i: int, sc: vec3):
    return wp.cw_mul(H.vertex[i], sc)


@wp.func
def _hull_face(H: Hulls, f: int, sc: vec3):
    """Outward unit normal and offset (n . x = d) of face f, scaled: n ~ n0 / sc."""
    n = wp.normalize(wp.cw_div(H.face_normal[f], sc))
    return n, wp.dot(n, _hull_vertex(H, H.face_vertex[H.face_start[f]], sc))


@wp.func
def _face_depth(H: Hulls, f0: int, nf: int, sc: vec3, p: vec3):
    """Largest face-plane distance max_f (n_f . p - d_f) of a point from a hull (its signed distance
    inside, a lower bound outside), and that face's outward normal; hull frame."""
    best = float_t(-1.0e30)
    normal = vec3(_ZERO, _ZERO, _ONE)
    for f in range(f0, f0 + nf):
        n, d = _hull_face(H, f, sc)
        if wp.dot(n, p) - d > best:
            best = wp.dot(n, p) - d
            normal = n
    return best, normal


@wp.func
def _face_depth_at(p: vec3, H: Hulls, f0: int, nf: int, sc: vec3, _unused: vec3):
    """`_face_depth`'s depth alone, as `_golden_section` calls its objective."""
    depth, _n = _face_depth(H, f0, nf, sc, p)
    return depth


_deepest_along = _golden_section(_face_depth_at)


@wp.func
def hull_closest(H: Hulls, h: int, sc: vec3, p: vec3):
    """Signed distance of a point from a hull's surface, hull frame; as `box_closest`.

    Returns (closest surface point, outward unit normal there, signed distance d). Inside, d < 0
    is the largest face-plane distance (the point leaves through that face). Outside, the
    nearest point lies inside a face the point is in front of, or on an edge: all are tried.
    Cost O(faces x face vertices + edges).
    """
    f0 = H.hull_face_start[h]
    nf = H.hull_face_count[h]
    dmax, nmax = _face_depth(H, f0, nf, sc, p)
    if dmax <= _ZERO:
        return p - nmax * dmax, nmax, dmax
    best = float_t(1.0e30)
    q = p
    out = nmax
    for f in range(f0, f0 + nf):
        n, d = _hull_face(H, f, sc)
        dist = wp.dot(n, p) - d
        if dist > _ZERO and dist < best:
            proj = p - n * dist
            inside = bool(True)
            start = H.face_start[f]
            count = H.face_count[f]
            for k in range(count):
                v0 = _hull_vertex(H, H.face_vertex[start + k], sc)
                v1 = _hull_vertex(H, H.face_vertex[start + (k + 1) % count], sc)
                if wp.dot(wp.cross(v1 - v0, proj - v0), n) < _ZERO:
                    inside = False
            if inside:
                best = dist
                q = proj
                out = n
    e0 = H.edge_start[h]
    for e in range(e0, e0 + H.edge_count[h]):
        ed = H.edge[e]
        v0 = _hull_vertex(H, ed[0], sc)
        v1 = _hull_vertex(H, ed[1], sc)
        seg = v1 - v0
        t = wp.clamp(wp.dot(p - v0, seg) / wp.max(wp.dot(seg, seg), float_t(1e-30)), _ZERO, _ONE)
        cp = v0 + seg * t
        dd = wp.length(p - cp)
        if dd < best:
            best = dd
            q = cp
            out = (p - cp) / wp.max(dd, float_t(1e-30))
    return q, out, best


@wp.struct
class Motion:
    """The velocities of a solid (vs, ws) and of the plane or mesh it meets (vm, wm), and the step."""

    vs: vec3
    ws: vec3
    vm: vec3
    wm: vec3
    dt: float_t


@wp.func
def _point_velocity(m: Motion, S: Pose, M: Pose, p: vec3):
    """Velocity of the solid's point p relative to the plane's or mesh's point there."""
    return (m.vs + wp.cross(m.ws, p - S.x)) - (m.vm + wp.cross(m.wm, p - M.x))


@wp.func
def _crosses(m: Motion, S: Pose, M: Pose, p: vec3, n: vec3, d: float_t):
    """Whether the solid's point p, a distance d > 0 outside the surface (normal n there), would pass
    through it within the step at the bodies' velocities."""
    return d > _ZERO and d + m.dt * wp.dot(n, _point_velocity(m, S, M, p)) < _ZERO


@wp.func
def collide_plane_hull(
    c: Contacts,
    a: int,
    b: int,
    A: Pose,
    B: Pose,
    H: Hulls,
    h: int,
    bound: float_t,
    max_sep: float_t,
    motion: Motion,
):
    # up to four of the vertices within the speculative distance (`_four_vertices`), and any other
    # that would pass through the plane this step
    n = _axis(A.q, 2)
    one = vec3(_ONE, _ONE, _ONE)
    nv = H.vertex_count[h]
    i0, i1, i2, i3, crossing, n0, d0 = _four_vertices(
        B, int(ShapeType.CONVEX), H, h, one, nv, bound, A, wp.uint64(0), n, max_sep, motion
    )
    if i0 < 0 or d0 > max_sep:
        return
    for k in range(4):
        i = _pick(k, i0, i1, i2, i3)
        if i >= 0 and (k == 0 or i != i0):
            pi = B.x + wp.quat_rotate(B.q, _solid_vertex(int(ShapeType.CONVEX), H, h, one, i))
            emit(c, a, b, A, B, n, pi - n * wp.dot(n, pi - A.x), pi, max_sep)
    if crossing > 0:
        for i in range(nv):
            if i != i0 and i != i1 and i != i2 and i != i3:
                pi = B.x + wp.quat_rotate(B.q, _solid_vertex(int(ShapeType.CONVEX), H, h, one, i))
                d = wp.dot(n, pi - A.x)
                if _crosses(motion, B, A, pi, n, d):
                    emit(c, a, b, A, B, n, pi - n * d, pi, max_sep)


@wp.func
def collide_sphere_hull(
    c: Contacts, a: int, b: int, A: Pose, B: Pose, r: float_t, H: Hulls, h: int, dv: vec3, dt: float_t, max_sep: float_t
):
    """A sphere (a) and a hull (b), as `collide_sphere_box`."""
    # nearest point of the hull to the sphere centre (at impact), in the hull frame
    one = vec3(_ONE, _ONE, _ONE)
    p = wp.quat_rotate_inv(B.q, A.x - B.x)
    u = wp.quat_rotate_inv(B.q, -dv)
    t = _first_touch(p, u, dt, r, H, h, one, vec3(), max_sep)
    q, out, _d = hull_closest(H, h, one, p + u * t)
    n = -wp.quat_rotate(B.q, out)  # sphere (a) -> hull (b)
    emit(c, a, b, A, B, n, A.x + n * r, B.x + wp.quat_rotate(B.q, q), max_sep)


@wp.func
def _clip_interval(lo: float_t, hi: float_t, c0: float_t, cu: float_t, eps: float_t):
    """[lo, hi] cut to the t with c0 + t cu <= 0 (a segment's points p0 + t u inside a plane):
    (lo, hi), empty (hi < lo) when the plane is parallel to the segment (|cu| <= eps) and c0 > 0."""
    if wp.abs(cu) > eps:
        if cu > _ZERO:
            hi = wp.min(hi, -c0 / cu)
        else:
            lo = wp.max(lo, -c0 / cu)
    elif c0 > _ZERO:
        hi = lo - _ONE
    return lo, hi


@wp.func
def collide_capsule_hull(
    c: Contacts,
    a: int,
    b: int,
    A: Pose,
    B: Pose,
    ra: float_t,
    ha: vec3,
    H: Hulls,
    h: int,
    dv: vec3,
    dt: float_t,
    max_sep: float_t,
):
    """A capsule (a) and a hull (b), as `collide_box_capsule`."""
    # the capsule's segment in the hull frame, its deepest point by golden-section search
    hh = _capsule_half_height(ra, ha)
    one = vec3(_ONE, _ONE, _ONE)
    p0 = wp.quat_rotate_inv(B.q, A.x - B.x)
    u = wp.quat_rotate_inv(B.q, _axis(A.q, 2))
    t = _golden_min(p0, u, -hh, hh, H, h, one, vec3())
    motion = wp.quat_rotate_inv(B.q, -dv)
    shift = motion * _first_touch(p0 + u * t, motion, dt, ra, H, h, one, vec3(), max_sep)
    back = wp.quat_rotate(B.q, shift)  # world frame, from the capsule's place at impact to now
    if wp.length_sq(shift) > _ZERO:
        p0 = p0 + shift
        t = _golden_min(p0, u, -hh, hh, H, h, one, vec3())
    q, out, _d = hull_closest(H, h, one, p0 + u * t)
    # a segment nearly parallel to the face nearest the normal is clipped to that face's prism
    # (side planes through its edges): the two ends are the manifold, as for boxes
    f0 = H.hull_face_start[h]
    fb = f0
    for f in range(f0, f0 + H.hull_face_count[h]):
        if wp.dot(H.face_normal[f], out) > wp.dot(H.face_normal[fb], out):
            fb = f
    nf, df = _hull_face(H, fb, one)
    if wp.abs(wp.dot(u, nf)) < float_t(0.2):
        lo = -hh
        hi = hh
        start = H.face_start[fb]
        count = H.face_count[fb]
        for k in range(count):
            v0 = H.vertex[H.face_vertex[start + k]]
            v1 = H.vertex[H.face_vertex[start + (k + 1) % count]]
            m = wp.cross(v1 - v0, nf)  # outward side normal (counter-clockwise face)
            # keep m . (p0 + t u - v0) <= 0
            lo, hi = _clip_interval(lo, hi, wp.dot(m, p0 - v0), wp.dot(m, u), float_t(1e-12))
        tol = float_t(1e-6) * (_ONE + hh)
        if hi - lo > float_t(1e-9) * (_ONE + hh):
            n = -wp.quat_rotate(B.q, nf)  # capsule (a) -> hull (b)
            for e in range(2):
                te = lo
                if e == 1:
                    te = hi
                pe = p0 + u * te
                dist = wp.dot(nf, pe) - df
                emit(
                    c,
                    a,
                    b,
                    A,
                    B,
                    n,
                    B.x + wp.quat_rotate(B.q, pe - nf * ra) - back,
                    B.x + wp.quat_rotate(B.q, pe - nf * dist),
                    max_sep,
                )
            if t >= lo - tol and t <= hi + tol:
                return  # else the deepest point, over an edge, is a third contact
    n = -wp.quat_rotate(B.q, out)
    pa = B.x + wp.quat_rotate(B.q, p0 + u * t) - back + n * ra
    emit(c, a, b, A, B, n, pa, B.x + wp.quat_rotate(B.q, q), max_sep)


@wp.struct
class Polygon3:
    """Up to sixteen points in the world frame (a clipped incident face)."""

    x: vec16
    y: vec16
    z: vec16
    count: int


@wp.func
def _poly_point(p: Polygon3, k: int):
    return vec3(p.x[k], p.y[k], p.z[k])


@wp.func
def _clip3(p: Polygon3, m: vec3, o: float_t):
    """Clip polygon p against the half space m . x <= o (Sutherland-Hodgman), at most 16 points."""
    out = Polygon3()
    k2 = int(0)
    for k in range(p.count):
        a = _poly_point(p, k)
        b = _poly_point(p, (k + 1) % p.count)
        ca = wp.dot(m, a) - o
        cb = wp.dot(m, b) - o
        if ca <= _ZERO and k2 < 16:
            out.x[k2] = a[0]
            out.y[k2] = a[1]
            out.z[k2] = a[2]
            k2 += 1
        if (ca <= _ZERO) != (cb <= _ZERO) and k2 < 16:
            x = a + (b - a) * (ca / (ca - cb))
            out.x[k2] = x[0]
            out.y[k2] = x[1]
            out.z[k2] = x[2]
            k2 += 1
    out.count = k2
    return out


@wp.func
def _hull_face_contacts(
    c: Contacts,
    a: int,
    b: int,
    A: Pose,
    B: Pose,
    H: Hulls,
    ha: int,
    sa: vec3,
    hb: int,
    sb: vec3,
    ref_is_a: bool,
    fref: int,
    max_sep: float_t,
):
    """Manifold for a face axis: face `fref` of the reference hull clips the other hull's incident face."""
    R = A
    I = B
    sr = sa
    hi = hb
    si = sb
    if not ref_is_a:
        R = B
        I = A
        sr = sb
        hi = ha
        si = sa
    nl, dl = _hull_face(H, fref, sr)
    n = wp.quat_rotate(R.q, nl)
    # incident face: the face of I most anti-parallel to n
    fi0 = H.hull_face_start[hi]
    finc = fi0
    best = float_t(2.0)
    for f in range(fi0, fi0 + H.hull_face_count[hi]):
        nf, _df = _hull_face(H, f, si)
        dn = wp.dot(wp.quat_rotate(I.q, nf), n)
        if dn < best:
            best = dn
            finc = f
    poly = Polygon3()
    start = H.face_start[finc]
    count = wp.min(H.face_count[finc], 16)
    for k in range(count):
        x = I.x + wp.quat_rotate(I.q, _hull_vertex(H, H.face_vertex[start + k], si))
        poly.x[k] = x[0]
        poly.y[k] = x[1]
        poly.z[k] = x[2]
    poly.count = count
    # clip against the side planes through the reference face's edges
    rstart = H.face_start[fref]
    rcount = H.face_count[fref]
    for k in range(rcount):
        v0 = R.x + wp.quat_rotate(R.q, _hull_vertex(H, H.face_vertex[rstart + k], sr))
        v1 = R.x + wp.quat_rotate(R.q, _hull_vertex(H, H.face_vertex[rstart + (k + 1) % rcount], sr))
        side = wp.cross(v1 - v0, n)
        if poly.count > 0:
            poly = _clip3(poly, side, wp.dot(side, v0))
    origin = R.x + wp.quat_rotate(R.q, _hull_vertex(H, H.face_vertex[rstart], sr))
    U = _perpendicular(n)
    V = wp.cross(n, U)
    # keep points within the speculative distance, merging near-duplicates, at most eight
    u2 = vec8()
    v2 = vec8()
    d2 = vec8()
    merge = float_t(1e-4) * wp.max(wp.length(sr), wp.length(si))
    m = int(0)
    # the incident hull's deepest vertex first: the clipped face need not hold it (a small or
    # tilted incident face), and without it the manifold would miss the axis' full depth
    deepest = I.x
    dmin = float_t(1.0e30)
    for i in range(H.vertex_start[hi], H.vertex_start[hi] + H.vertex_count[hi]):
        x = I.x + wp.quat_rotate(I.q, _hull_vertex(H, i, si))
        if wp.dot(x - origin, n) < dmin:
            dmin = wp.dot(x - origin, n)
            deepest = x
    for k in range(-1, poly.count):
        x = deepest - origin
        if k >= 0:
            x = _poly_point(poly, k) - origin
        d = wp.dot(x, n)
        if d <= max_sep:
            uk = wp.dot(x, U)
            vk = wp.dot(x, V)
            fresh = bool(True)
            for e in range(m):
                if wp.abs(u2[e] - uk) < merge and wp.abs(v2[e] - vk) < merge:
                    fresh = False
                    d2[e] = wp.min(d2[e], d)
            if fresh and m < 8:
                u2[m] = uk
                v2[m] = vk
                d2[m] = d
                m += 1
    _emit_manifold(c, a, b, A, B, n, origin, U, V, u2, v2, d2, m, ref_is_a, max_sep)


@wp.func
def _face_separation(H: Hulls, n: vec3, dl: float_t, P: Pose, Q: Pose, hq: int, sq: vec3):
    """Separation of hull hq (pose Q, scale sq) from a face of P's with world normal n at offset dl
    from P's centre: the least of its vertices' heights over the face's plane."""
    nq = wp.quat_rotate_inv(Q.q, n)
    lowest = float_t(1.0e30)
    for i in range(H.vertex_start[hq], H.vertex_start[hq] + H.vertex_count[hq]):
        lowest = wp.min(lowest, wp.dot(nq, _hull_vertex(H, i, sq)))
    return lowest + wp.dot(n, Q.x - P.x) - dl


@wp.func
def _hull_face_query(H: Hulls, P: Pose, hp: int, sp: vec3, Q: Pose, hq: int, sq: vec3):
    """Largest separation over P's face normals of Q from P, and that face: min over Q's vertices.
    Also P's least face offset from its centre (its inner half size, for `_ghost_step`)."""
    best = float_t(-1.0e30)
    fbest = H.hull_face_start[hp]
    inner = float_t(1.0e30)
    for f in range(H.hull_face_start[hp], H.hull_face_start[hp] + H.hull_face_count[hp]):
        nl, dl = _hull_face(H, f, sp)
        inner = wp.min(inner, dl)
        s = _face_separation(H, wp.quat_rotate(P.q, nl), dl, P, Q, hq, sq)
        if s > best:
            best = s
            fbest = f
    return best, fbest, inner


@wp.func
def _hull_thinnest(H: Hulls, P: Pose, hp: int, sp: vec3, Q: Pose, hq: int, sq: vec3, across: vec3):
    """The largest separation <= 0 of Q from P over P's face normals not parallel to `across` (world):
    the thinnest overlap along another axis, for `_ghost_step`."""
    thinnest = float_t(-1.0e30)
    for f in range(H.hull_face_start[hp], H.hull_face_start[hp] + H.hull_face_count[hp]):
        nl, dl = _hull_face(H, f, sp)
        n = wp.quat_rotate(P.q, nl)
        if wp.abs(wp.dot(n, across)) < _PARALLEL:
            s = _face_separation(H, n, dl, P, Q, hq, sq)
            if s <= _ZERO:
                thinnest = wp.max(thinnest, s)
    return thinnest


@wp.func
def collide_hulls(
    c: Contacts,
    a: int,
    b: int,
    A: Pose,
    B: Pose,
    H: Hulls,
    ha: int,
    sa: vec3,
    hb: int,
    sb: vec3,
    max_sep: float_t,
    seams: bool,
):
    """Separating axis test over both hulls' face normals and their Minkowski-face edge pairs
    (Gregorius, "The Separating Axis Test between Convex Polyhedra", GDC 2013), then face
    clipping (up to four points) or the closest points of two edges."""
    sep_a, fa, inner_a = _hull_face_query(H, A, ha, sa, B, hb, sb)
    if sep_a > max_sep:
        return
    sep_b, fb, inner_b = _hull_face_query(H, B, hb, sb, A, ha, sa)
    if sep_b > max_sep:
        return
    inner = wp.min(inner_a, inner_b)
    apart = wp.max(sep_a, sep_b)
    if seams and apart > -_GHOST_STEP * inner:
        na, _da = _hull_face(H, fa, sa)
        nb, _db = _hull_face(H, fb, sb)
        across = wp.quat_rotate(A.q, na)
        if sep_b > sep_a:
            across = wp.quat_rotate(B.q, nb)
        thinnest = wp.max(
            _hull_thinnest(H, A, ha, sa, B, hb, sb, across), _hull_thinnest(H, B, hb, sb, A, ha, sa, across)
        )
        if _ghost_step(apart, thinnest, inner):
            return
    # B's faces must beat A's clearly, so the reference face does not flip between steps
    ref_is_a = bool(True)
    face_sep = sep_a
    if sep_b > float_t(0.98) * sep_a + float_t(0.0005):
        ref_is_a = False
        face_sep = sep_b
    # edge pairs whose arcs cross on the Gauss map (the others cannot give a separating axis)
    best_sep = face_sep
    best_ea = int(-1)
    best_eb = int(-1)
    best_axis = vec3()
    for ea in range(H.edge_start[ha], H.edge_start[ha] + H.edge_count[ha]):
        ia = H.edge[ea]
        pa0 = A.x + wp.quat_rotate(A.q, _hull_vertex(H, ia[0], sa))
        pa1 = A.x + wp.quat_rotate(A.q, _hull_vertex(H, ia[1], sa))
        fa_ = H.edge_face[ea]
        na1, _d1 = _hull_face(H, fa_[0], sa)
        na2, _d2 = _hull_face(H, fa_[1], sa)
        n1 = wp.quat_rotate(A.q, na1)
        n2 = wp.quat_rotate(A.q, na2)
        bxa = wp.cross(n2, n1)
        for eb in range(H.edge_start[hb], H.edge_start[hb] + H.edge_count[hb]):
            ib = H.edge[eb]
            fb_ = H.edge_face[eb]
            nb1, _d3 = _hull_face(H, fb_[0], sb)
            nb2, _d4 = _hull_face(H, fb_[1], sb)
            m1 = -wp.quat_rotate(B.q, nb1)
            m2 = -wp.quat_rotate(B.q, nb2)
            dxc = wp.cross(m2, m1)
            cba = wp.dot(m1, bxa)
            dba = wp.dot(m2, bxa)
            adc = wp.dot(n1, dxc)
            bdc = wp.dot(n2, dxc)
            if cba * dba < _ZERO and adc * bdc < _ZERO and cba * bdc > _ZERO:
                pb0 = B.x + wp.quat_rotate(B.q, _hull_vertex(H, ib[0], sb))
                pb1 = B.x + wp.quat_rotate(B.q, _hull_vertex(H, ib[1], sb))
                axis = wp.cross(pa1 - pa0, pb1 - pb0)
                length = wp.length(axis)
                if length > float_t(1e-6) * wp.length(pa1 - pa0) * wp.length(pb1 - pb0):
                    axis = axis / length
                    if wp.dot(axis, pa0 - A.x) < _ZERO:
                        axis = -axis
                    s = wp.dot(axis, pb0 - pa0)
                    if s > max_sep:
                        return
                    # prefer faces unless an edge axis separates clearly more (stable manifolds)
                    if s > float_t(0.95) * face_sep + float_t(0.001) and s > best_sep:
                        best_sep = s
                        best_ea = ea
                        best_eb = eb
                        best_axis = axis
    if best_ea >= 0:
        ia = H.edge[best_ea]
        ib = H.edge[best_eb]
        pa0 = A.x + wp.quat_rotate(A.q, _hull_vertex(H, ia[0], sa))
        pa1 = A.x + wp.quat_rotate(A.q, _hull_vertex(H, ia[1], sa))
        pb0 = B.x + wp.quat_rotate(B.q, _hull_vertex(H, ib[0], sb))
        pb1 = B.x + wp.quat_rotate(B.q, _hull_vertex(H, ib[1], sb))
        la = wp.length(pa1 - pa0) * float_t(0.5)
        lb = wp.length(pb1 - pb0) * float_t(0.5)
        ua = (pa1 - pa0) / (float_t(2.0) * la)
        ub = (pb1 - pb0) / (float_t(2.0) * lb)
        ca = (pa0 + pa1) * float_t(0.5)
        cb = (pb0 + pb1) * float_t(0.5)
        s, t = _segment_closest(ca, ua, la, cb, ub, lb)
        emit(c, a, b, A, B, best_axis, ca + ua * s, cb + ub * t, max_sep)
    elif ref_is_a:
        _hull_face_contacts(c, a, b, A, B, H, ha, sa, hb, sb, True, fa, max_sep)
    else:
        _hull_face_contacts(c, a, b, A, B, H, ha, sa, hb, sb, False, fb, max_sep)


# ---------------------------------------------------------------------------- triangle meshes
# A static mesh body (always b: MESH is last in the table) is a `wp.Mesh` in the body's frame.
# Points of the other body are queried against its BVH: the nearest surface point, signed by the
# angle-weighted pseudo-normal (inside a closed mesh, or below a terrain's upward-wound faces).


@wp.func
def _mesh_point(mesh: wp.uint64, M: Pose, p: vec3, max_dist: float_t):
    """Nearest point of a mesh to the world point p within max_dist.

    Returns (found, surface point [world], outward unit normal [world], signed distance).
    """
    pl = wp.quat_rotate_inv(M.q, p - M.x)
    pf = wp.vec3f(wp.float32(pl[0]), wp.float32(pl[1]), wp.float32(pl[2]))
    query = wp.mesh_query_point_sign_normal(mesh, pf, wp.float32(max_dist))
    zero3 = vec3(_ZERO, _ZERO, _ZERO)
    if not query.result:
        return False, zero3, zero3, _ZERO
    cf = wp.mesh_eval_position(mesh, query.face, query.u, query.v)
    cl = vec3(float_t(cf[0]), float_t(cf[1]), float_t(cf[2]))
    d = pl - cl
    nf = wp.mesh_eval_face_normal(mesh, query.face)
    n = wp.normalize(vec3(float_t(nf[0]), float_t(nf[1]), float_t(nf[2])))
    # inside a face the face normal is exact (the direction to a float32 closest point is not,
    # for a point nearly on the surface); at an edge or a corner the direction to it is the normal,
    # unless that direction is the face's normal but for rounding (within 1.4e-3 rad: a point over
    # a vertex or an edge of a flat region). A box's corners landing on a flat grid mesh's vertices
    # got normals tilted 4e-5 by the float32 closest point, differing, so not one patch: the corners
    # were solved one by one and the box bounced off spinning at 0.84 rad/s
    bw = wp.float32(1.0) - query.u - query.v
    dist = wp.dot(d, n)
    if wp.min(wp.min(query.u, query.v), bw) < wp.float32(1e-4):
        length = wp.length(d)
        if length > float_t(1e-6) * (_ONE + wp.length(pl)) and wp.abs(dist) < (_ONE - float_t(1e-6)) * length:
            face = n
            n = d / length
            dist = length
            # behind the face (the sign), the point is inside, pushed out back through the edge;
            # unless it is more beside the edge than behind the face: past an open mesh's boundary
            # edge, where a body's corner sliding off a ledge dips as far as its resting contact
            # sinks, a push back through the edge stopped it (2 m/s to 0.73 and a 4 cm hop)
            if query.sign < wp.float32(0.0) and -wp.dot(d, face) > _HALF_SQRT2 * length:
                n = -n
                dist = -length
    return True, M.x + wp.quat_rotate(M.q, cl), wp.quat_rotate(M.q, n), dist


@wp.func
def _mesh_vertex(mesh: wp.uint64, i: int):
    p = wp.mesh_get_point(mesh, i)
    return vec3(float_t(p[0]), float_t(p[1]), float_t(p[2]))


@wp.func
def _sphere_mesh(
    c: Contacts, a: int, b: int, A: Pose, B: Pose, centre: vec3, r: float_t, mesh: wp.uint64, max_sep: float_t
):
    """A sphere of body a at `centre` against a mesh: the nearest mesh point, then every other face
    the sphere nearly touches or rolls onto this step.

    A sphere in a crease (a V-groove, a concave corner) rests on two or three faces at once: a
    face of the triangles near it (BVH AABB query) is a further contact, along its own normal,
    when the centre is in front of it within r + max_sep of its plane and projects inside it.
    A concave neighbour (its plane no nearer the centre than the mesh is: a plane nearer than
    the nearest surface point runs through free space, as at a convex edge) is one also where
    the centre projects outside it by less than max_sep, the distance the sphere can travel in
    the step: rolling across a concave edge onto it, the sphere is stopped by its plane at the
    edge instead of sinking into it along the face it left and being pushed out after (a push-out
    that raised it without slowing it: a ball rolling in a finely tessellated bowl swung ever
    higher, +23 % energy in 20 s; a capsule, whose ends and middle are such spheres, too).
    Contacts on edges and vertices are left to the nearest point, so a sphere on a flat or
    convex part of a mesh keeps one contact (neighbours of the touched face meet it on their edges).
    With r = 0 it is a point: a box's or a hull's vertex (`collide_vertices_mesh`), which takes
    its concave neighbours also when it is inside the surface, as a resting vertex is by its
    contact's give (a sphere's centre never is).
    """
    found, q, n, d = _mesh_point(mesh, B, centre, r + max_sep)
    if not found:
        return
    emit(c, a, b, A, B, -n, centre - n * r, q, max_sep)
    p = wp.quat_rotate_inv(B.q, centre - B.x)  # the centre in the mesh frame
    reach = r + max_sep
    lower = wp.vec3f(wp.float32(p[0] - reach), wp.float32(p[1] - reach), wp.float32(p[2] - reach))
    upper = wp.vec3f(wp.float32(p[0] + reach), wp.float32(p[1] + reach), wp.float32(p[2] + reach))
    nq = wp.quat_rotate_inv(B.q, n)
    query = wp.mesh_query_aabb(mesh, lower, upper)
    tri = int(0)
    while wp.mesh_query_aabb_next(query, tri):
        p0 = _mesh_vertex(mesh, tri * 3)
        p1 = _mesh_vertex(mesh, tri * 3 + 1)
        p2 = _mesh_vertex(mesh, tri * 3 + 2)
        e1 = p1 - p0
        e2 = p2 - p0
        m = wp.cross(e1, e2)
        area2 = wp.length(m)
        if area2 > float_t(0.0):
            nf = m / area2
            dist = wp.dot(nf, p - p0)
            # in front, within reach, not the face (or a coplanar neighbour) already taken
            if dist > _ZERO and dist <= reach and wp.dot(nf, nq) < _COPLANAR:
                # barycentric coordinates of the projection, each times its altitude: the
                # projection's distance inside each edge (negative outside)
                w = p - nf * dist - p0
                l1 = wp.dot(wp.cross(w, e2), m) / (area2 * area2)
                l2 = wp.dot(wp.cross(e1, w), m) / (area2 * area2)
                l0 = _ONE - l1 - l2
                inside = wp.min(
                    wp.min(l0 * area2 / wp.length(p2 - p1), l1 * area2 / wp.length(e2)), l2 * area2 / wp.length(e1)
                )
                # strictly inside (by 1e-4 of each altitude), or concave and within the step's reach of it
                take = wp.min(wp.min(l1, l2), l0) > float_t(1e-4)
                if not take and (d > _ZERO or r == _ZERO) and inside > -max_sep:
                    take = dist >= d - _CONCAVE_TOLERANCE * (_ONE + wp.length(p))
                if take:
                    nw = wp.quat_rotate(B.q, nf)
                    emit(c, a, b, A, B, -nw, centre - nw * r, centre - nw * dist, max_sep)


@wp.func
def collide_sphere_mesh(c: Contacts, a: int, b: int, A: Pose, B: Pose, r: float_t, mesh: wp.uint64, max_sep: float_t):
    """A sphere against a mesh (`_sphere_mesh` at its centre)."""
    _sphere_mesh(c, a, b, A, B, A.x, r, mesh, max_sep)


@wp.func
def collide_capsule_mesh(
    c: Contacts, a: int, b: int, A: Pose, B: Pose, r: float_t, h: vec3, mesh: wp.uint64, max_sep: float_t
):
    # spheres at both ends and the middle of the segment (a line contact on a slope; a capsule
    # lying across a ridge rests on its middle)
    u = _axis(A.q, 2)
    hh = _capsule_half_height(r, h)
    for k in range(3):
        t = float_t(k - 1) * hh
        _sphere_mesh(c, a, b, A, B, A.x + u * t, r, mesh, max_sep)


@wp.func
def _solid_vertex(shape: int, H: Hulls, g: int, h: vec3, i: int):
    """Vertex i of a box (corner i of half extents h) or of hull g, body frame."""
    if shape == int(ShapeType.BOX):
        return _box_corner(h, i)
    return H.vertex[H.vertex_start[g] + i]


@wp.func
def _vertex_depth(mesh: wp.uint64, M: Pose, n_plane: vec3, p: vec3, max_sep: float_t):
    """World point p against the other surface: a mesh (`mesh` not 0) through its BVH, else the plane
    through M.x with normal `n_plane`. Returns (found, surface point, outward normal, signed distance)."""
    if mesh != wp.uint64(0):
        return _mesh_point(mesh, M, p, max_sep)
    d = wp.dot(n_plane, p - M.x)
    return True, p - n_plane * d, n_plane, d


@wp.func
def _four_vertices(
    S: Pose,
    shape: int,
    H: Hulls,
    g: int,
    h: vec3,
    nv: int,
    bound: float_t,
    M: Pose,
    mesh: wp.uint64,
    n_plane: vec3,
    max_sep: float_t,
    motion: Motion,
):
    """Up to four vertices of a box or hull (pose S, `_solid_vertex(shape, H, g, h, i)`, i < nv)
    to touch a plane or a mesh (`_vertex_depth`): the deepest; the one farthest from it across
    its normal; the largest triangles either side of that line. Only vertices within half the
    bound radius of the deepest count: a fast body's far side, though within the speculative
    distance, must not displace the near side's vertices. It counts, too, the vertices that
    would pass through the surface this step (`_crosses`), which the caller adds.

    Returns (i0, i1, i2, i3, crossing count, normal at the deepest, its depth); i0 < 0 when no vertex
    is within `max_sep`, i2 or i3 < 0 when no vertex lies on that side; i1 == i0 when all are at one point.
    """
    i0 = int(-1)
    d0 = float_t(1.0e30)
    n0 = vec3()
    crossing = int(0)
    for i in range(nv):
        pi = S.x + wp.quat_rotate(S.q, _solid_vertex(shape, H, g, h, i))
        found, q, n, d = _vertex_depth(mesh, M, n_plane, pi, max_sep)
        if found and d < d0:
            d0 = d
            i0 = i
            n0 = n
        if found and _crosses(motion, S, M, pi, n, d):
            crossing += 1
    i1 = i0
    i2 = int(-1)
    i3 = int(-1)
    if i0 < 0 or d0 > max_sep:
        return i0, i1, i2, i3, crossing, n0, d0
    p0 = S.x + wp.quat_rotate(S.q, _solid_vertex(shape, H, g, h, i0))
    limit = wp.min(max_sep, d0 + float_t(0.5) * bound)
    far = float_t(1e-12) * bound * bound
    for i in range(nv):
        pi = S.x + wp.quat_rotate(S.q, _solid_vertex(shape, H, g, h, i))
        found, q, n, d = _vertex_depth(mesh, M, n_plane, pi, max_sep)
        if found and d <= limit:
            t = (pi - p0) - n0 * wp.dot(n0, pi - p0)
            if wp.dot(t, t) > far:
                far = wp.dot(t, t)
                i1 = i
    p1 = S.x + wp.quat_rotate(S.q, _solid_vertex(shape, H, g, h, i1))
    amax = float_t(1e-12) * far
    amin = -amax
    for i in range(nv):
        pi = S.x + wp.quat_rotate(S.q, _solid_vertex(shape, H, g, h, i))
        found, q, n, d = _vertex_depth(mesh, M, n_plane, pi, max_sep)
        if found and d <= limit:
            area = wp.dot(n0, wp.cross(p1 - p0, pi - p0))
            if area > amax:
                amax = area
                i2 = i
            if area < amin:
                amin = area
                i3 = i
    return i0, i1, i2, i3, crossing, n0, d0


@wp.func
def _pick(k: int, i0: int, i1: int, i2: int, i3: int):
    """The k-th of four indices."""
    if k == 1:
        return i1
    if k == 2:
        return i2
    if k == 3:
        return i3
    return i0


@wp.func
def _mesh_edge_in(A: Pose, B: Pose, mesh: wp.uint64, tri: int, k: int):
    """Edge k of mesh triangle `tri` (mesh B), from vertex k to the next, in the frame of body A."""
    s0 = wp.quat_rotate_inv(A.q, B.x + wp.quat_rotate(B.q, _mesh_vertex(mesh, tri * 3 + k)) - A.x)
    s1 = wp.quat_rotate_inv(A.q, B.x + wp.quat_rotate(B.q, _mesh_vertex(mesh, tri * 3 + (k + 1) % 3)) - A.x)
    return s0, s1


@wp.func
def _edge_face(H: Hulls, f0: int, nf: int, sc: vec3, p: vec3, u: vec3, tol: float_t):
    """`_face_depth` of a point p on an edge of direction u, the face chosen among those within tol
    of the largest distance as the one the edge runs most along (least |n . u|): a ridge lying in a
    box's bottom face, near a side face, is under the bottom face (taken as under the side face, its
    contact pushed the box sideways). Returns (that face's distance, its outward normal)."""
    depth, normal = _face_depth(H, f0, nf, sc, p)
    along = wp.normalize(u)
    least = float_t(2.0)
    dist = depth
    for f in range(f0, f0 + nf):
        n, d = _hull_face(H, f, sc)
        df = wp.dot(n, p) - d
        if df >= depth - tol and wp.abs(wp.dot(n, along)) < least:
            least = wp.abs(wp.dot(n, along))
            normal = n
            dist = df
    return dist, normal


@wp.func
def _over_face(H: Hulls, f0: int, nf: int, sc: vec3, s0: vec3, u: vec3, t: float_t, tol: float_t):
    """The point of the edge s0 + t' u nearest t that lies over the face it is deepest from: within
    tol of every other face plane of the hull (hull frame). Returns (whether there is one, the
    point, and its `_edge_face` distance and normal there).

    Outside the body the face-plane depth is a lower bound, least where two planes cross beyond
    the body's rim: a mesh rising past a box's bottom edge (an incline, a hill) looked nearer than
    the box's own corners there, and one edge of the many under the box, in BVH order, took a
    contact beside the rim that spun the box as it landed (7.6 rad/s about the vertical, from a
    frictionless landing on a hill). Over the face the depth is exact; a point inside the body is
    within every plane and stays where it is.
    """
    p = s0 + u * t
    depth, face = _edge_face(H, f0, nf, sc, p, u, tol)
    lo = _ZERO
    hi = _ONE
    for f in range(f0, f0 + nf):
        n, d = _hull_face(H, f, sc)
        if wp.dot(n, face) < _COPLANAR:
            lo, hi = _clip_interval(lo, hi, wp.dot(n, s0) - d - tol, wp.dot(n, u), float_t(1e-30))
    tc = wp.clamp(t, lo, wp.max(lo, hi))
    if tc != t:  # moved over the face: its depth there
        p = s0 + u * tc
        depth, face = _edge_face(H, f0, nf, sc, p, u, tol)
    return hi >= lo, p, depth, face


@wp.func
def _mesh_edges_into_solid(
    c: Contacts,
    a: int,
    b: int,
    A: Pose,
    B: Pose,
    H: Hulls,
    hp: int,
    sc: vec3,
    bound: float_t,
    mesh: wp.uint64,
    max_sep: float_t,
    d0: float_t,
):
    """The deepest point of the mesh's triangle edges inside a box or hull, when deeper than its vertices.

    A ridge or a spike of the mesh pressing into a face between the body's vertices is missed by
    the vertex queries. Every triangle edge near the body (BVH query over its bounding sphere) is
    clipped to the body's face planes pushed out by max_sep (Cyrus-Beck); along what is left, the
    largest face-plane distance f(t) = max_f f_f(p(t)), f_f = n_f . p - d_f (the signed distance
    inside, a lower bound outside, whose face gives the normal: the true distance's direction
    off an edge or a corner would tip a body lying across a ridge), convex and piecewise linear,
    is minimised by golden-section search. An edge is skipped unless max_f min(f_f(lo), f_f(hi)),
    a lower bound of f on the stretch, is below the best so far (an edge lying flat under a face
    costs no search).
    Kept when deeper than the deepest vertex d0 by a tolerance: one contact on the deepest face,
    or two, at the ends of the stretch of that edge within the tolerance of the deepest (a ridge
    lying along a face is a line contact: one point anywhere on it would tip the body).
    """
    f0 = H.hull_face_start[hp]
    nf = H.hull_face_count[hp]
    tol = float_t(1e-3) * bound + float_t(1e-5)
    best = wp.min(d0 - tol, max_sep)
    tie = _EDGE_TIE * bound
    found = bool(False)
    best_flat = float_t(1.0e30)  # the best edge's |n . u| / |u| (0: it lies along the face)
    best_p = vec3()
    best_n = vec3()
    best_s0 = vec3()
    best_u = vec3()
    centre = wp.quat_rotate_inv(B.q, A.x - B.x)
    reach = bound + max_sep
    lower = wp.vec3f(wp.float32(centre[0] - reach), wp.float32(centre[1] - reach), wp.float32(centre[2] - reach))
    upper = wp.vec3f(wp.float32(centre[0] + reach), wp.float32(centre[1] + reach), wp.float32(centre[2] + reach))
    query = wp.mesh_query_aabb(mesh, lower, upper)
    tri = int(0)
    while wp.mesh_query_aabb_next(query, tri):
        for k in range(3):
            s0, s1 = _mesh_edge_in(A, B, mesh, tri, k)
            u = s1 - s0
            lo = _ZERO
            hi = _ONE
            for f in range(f0, f0 + nf):
                n, d = _hull_face(H, f, sc)
                lo, hi = _clip_interval(lo, hi, wp.dot(n, s0) - d - max_sep, wp.dot(n, u), float_t(1e-30))
            if hi >= lo:
                bound_lo = float_t(-1.0e30)
                for f in range(f0, f0 + nf):
                    n, d = _hull_face(H, f, sc)
                    bound_lo = wp.max(bound_lo, wp.min(wp.dot(n, s0 + u * lo), wp.dot(n, s0 + u * hi)) - d)
                if bound_lo < best + tie:
                    # golden-section search of the depth along the edge (convex, piecewise linear)
                    lo, hi = _deepest_along(s0, u, lo, hi, 30, H, f0, nf, sc, vec3())
                    over, pt, depth, normal = _over_face(H, f0, nf, sc, s0, u, (lo + hi) * float_t(0.5), tol)
                    # of equal depths (within rounding) the edge lying flattest along the face: a grid's
                    # diagonal ending on a ridge is as deep at its end as the ridge's edges, and in float32
                    # was found a hair deeper, so the line contact shrank to that end and tipped the box
                    flat = wp.abs(wp.dot(normal, u)) / wp.length(u)
                    if over and (depth < best - tie or (depth < best + tie and flat < best_flat)):
                        best = depth
                        best_flat = flat
                        best_p = pt
                        best_n = normal
                        best_s0 = s0
                        best_u = u
                        found = True
    if not found:
        return
    # the stretch within tol of the deepest point along the deepest edge's line: the line clipped to
    # the face planes pushed out by best + tol (the others, outside the body, by tol: over the face,
    # as above), then what the mesh edges on that line cover of it. A ridge is often many collinear
    # edges (a grid's line): the deepest one, the first found of equals, held a stretch of a third
    # of a box's width and tipped the box sideways as it lay across the ridge
    lo = float_t(-1.0e30)
    hi = float_t(1.0e30)
    for f in range(f0, f0 + nf):
        n, d = _hull_face(H, f, sc)
        reach_f = wp.min(best, _ZERO) + tol
        if wp.dot(n, best_n) >= _COPLANAR:
            reach_f = best + tol
            # and no deeper than best - tol: an edge running into the face is deepest at one point
            lo, hi = _clip_interval(lo, hi, best - tol - (wp.dot(n, best_s0) - d), -wp.dot(n, best_u), float_t(1e-30))
        lo, hi = _clip_interval(lo, hi, wp.dot(n, best_s0) - d - reach_f, wp.dot(n, best_u), float_t(1e-30))
    uu = wp.dot(best_u, best_u)
    off = tol * wp.sqrt(uu)  # an edge on the line: |r x u| / |u| <= tol at both ends
    first = float_t(1.0e30)
    last = float_t(-1.0e30)
    query = wp.mesh_query_aabb(mesh, lower, upper)
    tri = int(0)
    while wp.mesh_query_aabb_next(query, tri):
        for k in range(3):
            s0, s1 = _mesh_edge_in(A, B, mesh, tri, k)
            r0 = s0 - best_s0
            r1 = s1 - best_s0
            if wp.length(wp.cross(r0, best_u)) <= off and wp.length(wp.cross(r1, best_u)) <= off:
                t0 = wp.dot(r0, best_u) / uu
                t1 = wp.dot(r1, best_u) / uu
                ta = wp.max(wp.min(t0, t1), lo)
                tb = wp.min(wp.max(t0, t1), hi)
                if tb >= ta:
                    first = wp.min(first, ta)
                    last = wp.max(last, tb)
    lo = first
    hi = last
    d_best = wp.dot(best_n, best_p) - best
    # normal a -> b: the face's outward normal; a's surface point is the mesh point moved onto the face
    n = wp.quat_rotate(A.q, best_n)
    if (hi - lo) * wp.length(best_u) > float_t(1e-3) * bound:
        for e in range(2):
            te = lo
            if e == 1:
                te = hi
            pt = best_s0 + best_u * te
            p_b = A.x + wp.quat_rotate(A.q, pt)
            emit(c, a, b, A, B, n, p_b - n * (wp.dot(best_n, pt) - d_best), p_b, max_sep)
    else:
        p_b = A.x + wp.quat_rotate(A.q, best_p)
        emit(c, a, b, A, B, n, p_b - n * best, p_b, max_sep)


@wp.func
def collide_vertices_mesh(
    c: Contacts,
    a: int,
    b: int,
    A: Pose,
    B: Pose,
    shape: int,
    H: Hulls,
    g: int,
    h: vec3,
    bound: float_t,
    mesh: wp.uint64,
    max_sep: float_t,
    motion: Motion,
):
    """A box's or hull's vertices against a mesh: up to four, chosen as against a plane, and any other
    that would pass through the mesh within the step; then the mesh's own edges, for a ridge or a
    spike pressing into a face between the vertices.

    The deepest vertex, the one farthest from it across the normal, then the largest triangles
    either side (`_four_vertices`); then one contact at the deepest point of the mesh edges inside
    the body, when that is deeper than the deepest vertex (`_mesh_edges_into_solid`). Each vertex
    touches as a sphere of radius 0 (`_sphere_mesh`): its nearest mesh point, and the concave faces
    next to it that it can reach within the step. With the nearest point alone, a box sliding in a
    finely tessellated half-pipe sank its edges into each next face along the one they left and
    was pushed out after, raised without being slowed: it gained 1 % of its energy in 4 s.
    """
    nv = int(8)
    if shape != int(ShapeType.BOX):
        nv = H.vertex_count[g]
    i0, i1, i2, i3, crossing, n0, d0 = _four_vertices(A, shape, H, g, h, nv, bound, B, mesh, vec3(), max_sep, motion)
    # the box as the unit-cube hull (prototype 0) scaled by its half extents
    hp = g
    sc = vec3(_ONE, _ONE, _ONE)
    if shape == int(ShapeType.BOX):
        hp = 0
        sc = h
    _mesh_edges_into_solid(c, a, b, A, B, H, hp, sc, bound, mesh, max_sep, d0)
    if i0 < 0 or d0 > max_sep:
        return
    for k in range(4):
        i = _pick(k, i0, i1, i2, i3)
        if i >= 0 and (k == 0 or i != i0):
            pi = A.x + wp.quat_rotate(A.q, _solid_vertex(shape, H, g, h, i))
            _sphere_mesh(c, a, b, A, B, pi, _ZERO, mesh, max_sep)  # the vertex as a point, creases included
    if crossing > 0:
        for i in range(nv):
            if i != i0 and i != i1 and i != i2 and i != i3:
                pi = A.x + wp.quat_rotate(A.q, _solid_vertex(shape, H, g, h, i))
                found, q, n, d = _mesh_point(mesh, B, pi, max_sep)
                if found and _crosses(motion, A, B, pi, n, d):
                    _sphere_mesh(c, a, b, A, B, pi, _ZERO, mesh, max_sep)


# ---------------------------------------------------------------------------- dispatch


@wp.func
def _motion(body: BodyArrays, solid: int, other: int, dt: float_t):
    m = Motion()
    m.vs = body.velocity[solid]
    m.ws = body.angular_velocity[solid]
    m.vm = body.velocity[other]
    m.wm = body.angular_velocity[other]
    m.dt = dt
    return m


@wp.kernel
def _collide_pairs(
    pair_a: wp.array(dtype=wp.int32),
    pair_b: wp.array(dtype=wp.int32),
    body: BodyArrays,
    hulls: Hulls,
    mesh_ids: wp.array(dtype=wp.uint64),
    dt: float_t,
    margin: float_t,
    c: Contacts,
    pair_count: wp.array(dtype=wp.int32),
    serial: int,
):
    # launched over the pair capacity, the count on the device (see tumble.launch.launch_each)
    for p in range(wp.tid(), each_in_use(wp.tid(), serial, pair_count[0], pair_a.shape[0])):
        a = pair_a[p]
        b = pair_b[p]
        shape = body.shape
        radius = body.radius
        half_extents = body.half_extents
        bound = body.bound_radius
        geometry = body.geometry
        # swap into pair-table order: shape[a] <= shape[b]; the normal then points a -> b
        if shape[a] > shape[b]:
            t = a
            a = b
            b = t
        sa = shape[a]
        sb = shape[b]
        A = Pose()
        A.x = body.position[a]
        A.q = body.orientation[a]
        B = Pose()
        B.x = body.position[b]
        B.q = body.orientation[b]
        # speculative distance: how far the surfaces can approach in one step, plus a margin
        w = body.angular_velocity
        reach = wp.length(body.velocity[b] - body.velocity[a])
        if sa != int(ShapeType.PLANE):
            reach += wp.length(w[a]) * bound[a]
        reach += wp.length(w[b]) * bound[b]
        max_sep = dt * reach + margin
        # a pair with a static or kinematic body may meet at a seam of the level's blocks (`_ghost_step`)
        seams = body.inv_mass[a] == float_t(0.0) or body.inv_mass[b] == float_t(0.0)
        one = vec3(_ONE, _ONE, _ONE)
        if sa == int(ShapeType.PLANE):
            if sb == int(ShapeType.SPHERE):
                collide_plane_sphere(c, a, b, A, B, radius[b], max_sep)
            elif sb == int(ShapeType.BOX):
                collide_plane_box(c, a, b, A, B, half_extents[b], max_sep)
            elif sb == int(ShapeType.CAPSULE):
                collide_plane_capsule(c, a, b, A, B, radius[b], half_extents[b], max_sep)
            elif sb == int(ShapeType.CONVEX):
                collide_plane_hull(c, a, b, A, B, hulls, geometry[b], bound[b], max_sep, _motion(body, b, a, dt))
        elif sa == int(ShapeType.SPHERE):
            if sb == int(ShapeType.SPHERE):
                collide_sphere_sphere(
                    c, a, b, A, B, radius[a], radius[b], body.velocity[b] - body.velocity[a], dt, max_sep
                )
            elif sb == int(ShapeType.BOX):
                collide_sphere_box(
                    c, a, b, A, B, radius[a], half_extents[b], body.velocity[b] - body.velocity[a], dt, max_sep
                )
            elif sb == int(ShapeType.CAPSULE):
                collide_sphere_capsule(c, a, b, A, B, radius[a], radius[b], half_extents[b], max_sep)
            elif sb == int(ShapeType.CONVEX):
                collide_sphere_hull(
                    c, a, b, A, B, radius[a], hulls, geometry[b], body.velocity[b] - body.velocity[a], dt, max_sep
                )
        elif sa == int(ShapeType.BOX):
            if sb == int(ShapeType.BOX):
                collide_box_box(c, a, b, A, B, half_extents[a], half_extents[b], max_sep, seams)
            elif sb == int(ShapeType.CAPSULE):
                collide_box_capsule(
                    c,
                    a,
                    b,
                    A,
                    B,
                    half_extents[a],
                    radius[b],
                    half_extents[b],
                    body.velocity[b] - body.velocity[a],
                    dt,
                    max_sep,
                )
            elif sb == int(ShapeType.CONVEX):
                # the box as the unit-cube hull (prototype 0) scaled by its half extents
                collide_hulls(c, a, b, A, B, hulls, 0, half_extents[a], geometry[b], one, max_sep, seams)
        elif sa == int(ShapeType.CAPSULE):
            if sb == int(ShapeType.CAPSULE):
                collide_capsule_capsule(c, a, b, A, B, radius[a], half_extents[a], radius[b], half_extents[b], max_sep)
            elif sb == int(ShapeType.CONVEX):
                collide_capsule_hull(
                    c,
                    a,
                    b,
                    A,
                    B,
                    radius[a],
                    half_extents[a],
                    hulls,
                    geometry[b],
                    body.velocity[b] - body.velocity[a],
                    dt,
                    max_sep,
                )
        elif sa == int(ShapeType.CONVEX):
            if sb == int(ShapeType.CONVEX):
                collide_hulls(c, a, b, A, B, hulls, geometry[a], one, geometry[b], one, max_sep, seams)
        if sb == int(ShapeType.MESH):
            mesh = mesh_ids[geometry[b]]
            if sa == int(ShapeType.SPHERE):
                collide_sphere_mesh(c, a, b, A, B, radius[a], mesh, max_sep)
            elif sa == int(ShapeType.CAPSULE):
                collide_capsule_mesh(c, a, b, A, B, radius[a], half_extents[a], mesh, max_sep)
            elif sa == int(ShapeType.BOX) or sa == int(ShapeType.CONVEX):
                collide_vertices_mesh(
                    c,
                    a,
                    b,
                    A,
                    B,
                    sa,
                    hulls,
                    geometry[a],
                    half_extents[a],
                    bound[a],
                    mesh,
                    max_sep,
                    _motion(body, a, b, dt),
                )


_default_hulls: dict[str, HullSet] = {}
_default_meshes: dict[str, MeshSet] = {}


def collide(
    bodies,
    pairs,
    contacts,
    dt: float,
    hulls: HullSet | None = None,
    meshes: MeshSet | None = None,
    cache: LaunchCache | None = None,
) -> None:
    """Run the pair table over the broad phase's pairs, filling `contacts` (grown as needed).

    `hulls` and `meshes` hold the convex prototypes and triangle meshes that the bodies'
    `body_geometry` rows name (default: the unit box only, no mesh). With `cache`, the launch
    is recorded once and replayed (see tumble.launch).
    """
    contacts.begin_step()
    if pairs.pair_count == 0:
        contacts.count = 0
        return
    launch_pairs(bodies, pairs, contacts, dt, hulls, meshes, cache)
    while not collected(contacts):
        launch_pairs(bodies, pairs, contacts, dt, hulls, meshes, cache)


def launch_pairs(
    bodies, pairs, contacts, dt: float, hulls: HullSet | None, meshes: MeshSet | None, cache: LaunchCache | None = None
) -> None:
    """The launch of `collide` (no host decision, so it can be recorded): over the pair capacity,
    the pair count read on the device from `pairs.pair_count_array` (when `pairs` has none, its
    `pair_count` is put there first)."""
    if hulls is None:
        hulls = _default_hulls.setdefault(bodies.device, HullSet(bodies.device))
    if meshes is None:
        meshes = _default_meshes.setdefault(bodies.device, MeshSet(bodies.device))
    count = getattr(pairs, "pair_count_array", None)
    if count is None:
        count = contacts.pair_count_array
        if bodies.device == "cpu":
            host_view(count)[0] = pairs.pair_count
        else:
            count.assign(np.array([pairs.pair_count], dtype=np.int32))
    args = [
        pairs.pair_a,
        pairs.pair_b,
        body_struct(bodies),
        hulls.struct(),
        meshes.ids(),
        dt,
        SPECULATIVE_MARGIN,
        contacts.writer(),
        count,
    ]
    launch_each(_collide_pairs, pairs.pair_a.shape[0], args, bodies.device, cache)


def collected(contacts) -> bool:
    """Host side after `launch_pairs`: the contact count; False (contacts grown) if they overflowed."""
    count = host_values(contacts.count_array)[0]
    if count > contacts.capacity:
        contacts.grow(count)
        return False
    contacts.count = count
    return True
