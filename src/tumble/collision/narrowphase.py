"""Narrow phase: candidate pairs -> contact points, through one pair table.

Reads the broad phase's pairs and the bodies' poses and shapes; writes contact rows
(`contact_body_a/b`, `contact_normal`, `contact_point`, `contact_separation`, and the two
surface points in each body's frame, `contact_local_a/b`). Cost: O(pairs), at most four
contacts per pair.

Conventions:
- `collide_<a>_<b>` handles shapes a <= b in `ShapeType` order (PLANE < SPHERE < BOX < CAPSULE); the
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

import warp as wp

from ..shapes import ShapeType
from ..state import float_t, quat, vec3

#: speculative distance added to the relative motion of a pair in one step [m]
SPECULATIVE_MARGIN = 0.002

vec8 = wp.types.vector(length=8, dtype=float_t)

_ZERO = wp.constant(float_t(0.0))
_ONE = wp.constant(float_t(1.0))


@wp.struct
class ContactWriter:
    """The contact arrays the narrow phase appends to (capacity = length of the arrays)."""

    count: wp.array(dtype=wp.int32)
    body_a: wp.array(dtype=wp.int32)
    body_b: wp.array(dtype=wp.int32)
    normal: wp.array(dtype=vec3)
    point: wp.array(dtype=vec3)
    separation: wp.array(dtype=float_t)
    local_a: wp.array(dtype=vec3)
    local_b: wp.array(dtype=vec3)


@wp.struct
class Pose:
    x: vec3
    q: quat


@wp.func
def emit(c: ContactWriter, a: int, b: int, pa_: Pose, pb_: Pose, n: vec3, p_a: vec3, p_b: vec3, max_sep: float_t):
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
def collide_plane_sphere(c: ContactWriter, a: int, b: int, A: Pose, B: Pose, r: float_t, max_sep: float_t):
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
def collide_plane_box(c: ContactWriter, a: int, b: int, A: Pose, B: Pose, h: vec3, max_sep: float_t):
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


@wp.func
def collide_sphere_sphere(
    c: ContactWriter, a: int, b: int, A: Pose, B: Pose, ra: float_t, rb: float_t, max_sep: float_t
):
    d = B.x - A.x
    dist = wp.length(d)
    n = vec3(_ZERO, _ZERO, _ONE)
    if dist > float_t(1e-12):
        n = d / dist
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
def collide_sphere_box(c: ContactWriter, a: int, b: int, A: Pose, B: Pose, r: float_t, h: vec3, max_sep: float_t):
    # closest point of the box to the sphere centre, in the box frame
    p = wp.quat_rotate_inv(B.q, A.x - B.x)
    q, out, d = box_closest(p, h)  # out: box -> sphere, box frame
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
def _face_contacts(c: ContactWriter, a: int, b: int, A: Pose, B: Pose, ha: vec3, hb: vec3, ref_is_a: bool,
                   axis: int, max_sep: float_t):
    """Manifold for a face axis: `axis` of the reference box (A if ref_is_a) against the other box."""
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
    if m == 0:
        return
    # reduce to at most four: deepest, farthest from it, then the largest triangles either side
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
    for k in range(m):
        if chosen & (1 << k):
            on_inc = face + U * u2[k] + V * v2[k] + n * d2[k]
            on_ref = on_inc - n * d2[k]
            if ref_is_a:
                emit(c, a, b, A, B, n, on_ref, on_inc, max_sep)
            else:
                emit(c, a, b, A, B, -n, on_inc, on_ref, max_sep)


@wp.func
def _edge_contact(c: ContactWriter, a: int, b: int, A: Pose, B: Pose, ha: vec3, hb: vec3, i: int, j: int,
                  L: vec3, max_sep: float_t):
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
    r = pa - pb
    e = wp.dot(da, db)
    f = wp.dot(da, r)
    g = wp.dot(db, r)
    den = _ONE - e * e
    s = _ZERO
    t = _ZERO
    if den > float_t(1e-12):
        s = wp.clamp((e * g - f) / den, -ha[i], ha[i])
    t = wp.clamp(e * s + g, -hb[j], hb[j])
    s = wp.clamp(e * t - f, -ha[i], ha[i])
    emit(c, a, b, A, B, L, pa + da * s, pb + db * t, max_sep)


@wp.func
def collide_box_box(c: ContactWriter, a: int, b: int, A: Pose, B: Pose, ha: vec3, hb: vec3, max_sep: float_t):
    T = B.x - A.x
    best_sep = float_t(-1.0e30)
    best_kind = int(-1)  # 0: face of A, 1: face of B, 2: edge-edge
    best_i = int(0)
    best_j = int(0)
    best_axis = vec3()
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
            best_axis = axis
    face_sep = best_sep
    # edge-edge axes; prefer faces unless an edge axis separates clearly more (stable manifolds)
    for i in range(3):
        for j in range(3):
            axis = wp.cross(_axis(A.q, i), _axis(B.q, j))
            length = wp.length(axis)
            if length > float_t(1e-6):
                axis = axis / length
                s = wp.abs(wp.dot(T, axis)) - _box_projection(A.q, ha, axis) - _box_projection(B.q, hb, axis)
                if s > max_sep:
                    return
                if s > float_t(0.95) * face_sep + float_t(0.001) and s > best_sep:
                    best_sep = s
                    best_kind = 2
                    best_i = i
                    best_j = j
                    best_axis = axis
    if best_kind == 2:
        if wp.dot(best_axis, T) < _ZERO:
            best_axis = -best_axis
        _edge_contact(c, a, b, A, B, ha, hb, best_i, best_j, best_axis, max_sep)
    else:
        _face_contacts(c, a, b, A, B, ha, hb, best_kind == 0, best_i, max_sep)


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
def _sphere_pair(c: ContactWriter, a: int, b: int, A: Pose, B: Pose, ca: vec3, ra: float_t, cb: vec3, rb: float_t,
                 fallback: vec3, max_sep: float_t):
    """Contact of two spheres (centres ca on a, cb on b); `fallback` is the normal for coincident centres."""
    d = cb - ca
    dist = wp.length(d)
    n = fallback
    if dist > float_t(1e-12):
        n = d / dist
    emit(c, a, b, A, B, n, ca + n * ra, cb - n * rb, max_sep)


@wp.func
def collide_plane_capsule(c: ContactWriter, a: int, b: int, A: Pose, B: Pose, r: float_t, h: vec3, max_sep: float_t):
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
def collide_sphere_capsule(c: ContactWriter, a: int, b: int, A: Pose, B: Pose, ra: float_t, rb: float_t, h: vec3,
                           max_sep: float_t):
    # the sphere against the nearest point of the capsule's segment
    u = _axis(B.q, 2)
    hh = _capsule_half_height(rb, h)
    t = wp.clamp(wp.dot(A.x - B.x, u), -hh, hh)
    _sphere_pair(c, a, b, A, B, A.x, ra, B.x + u * t, rb, _perpendicular(u), max_sep)


@wp.func
def _golden_min_box(p0: vec3, u: vec3, lo: float_t, hi: float_t, hb: vec3):
    """Parameter t in [lo, hi] minimising the signed distance of p0 + t u from a box (half extents hb).

    The signed distance from a convex set is a convex function, and so is its restriction to a
    line, so golden-section search finds the minimum: 40 steps shrink [lo, hi] by 0.618^40 ~ 4e-9.
    """
    g = float_t(0.6180339887498949)
    x1 = hi - g * (hi - lo)
    x2 = lo + g * (hi - lo)
    _q1, _o1, f1 = box_closest(p0 + u * x1, hb)
    _q2, _o2, f2 = box_closest(p0 + u * x2, hb)
    for _it in range(40):
        if f1 <= f2:
            hi = x2
            x2 = x1
            f2 = f1
            x1 = hi - g * (hi - lo)
            _q1, _o1, f1 = box_closest(p0 + u * x1, hb)
        else:
            lo = x1
            x1 = x2
            f1 = f2
            x2 = lo + g * (hi - lo)
            _q2, _o2, f2 = box_closest(p0 + u * x2, hb)
    return (lo + hi) * float_t(0.5)


@wp.func
def collide_box_capsule(c: ContactWriter, a: int, b: int, A: Pose, B: Pose, ha: vec3, rb: float_t, hb: vec3,
                        max_sep: float_t):
    # the capsule's segment in the box frame: p(t) = p0 + t u, t in [-a, a]
    hh = _capsule_half_height(rb, hb)
    p0 = wp.quat_rotate_inv(A.q, B.x - A.x)
    u = wp.quat_rotate_inv(A.q, _axis(B.q, 2))
    t = _golden_min_box(p0, u, -hh, hh, ha)
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
        # (only when the deepest point is over the face: f is linear there, so an end is deepest)
        tol = float_t(1e-6) * (_ONE + hh)
        if hi - lo > float_t(1e-9) * (_ONE + hh) and t >= lo - tol and t <= hi + tol:
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
                pw = A.x + wp.quat_rotate(A.q, p)
                emit(c, a, b, A, B, n, A.x + wp.quat_rotate(A.q, on_box), pw - n * rb, max_sep)
            return
    n = wp.quat_rotate(A.q, out)
    emit(c, a, b, A, B, n, A.x + wp.quat_rotate(A.q, q), A.x + wp.quat_rotate(A.q, p0 + u * t) - n * rb, max_sep)


@wp.func
def _segment_closest(pa: vec3, ua: vec3, ha: float_t, pb: vec3, ub: vec3, hb: float_t):
    """Parameters (s, t) of the closest points pa + s ua, pb + t ub of two segments, |s| <= ha, |t| <= hb.

    Unit directions; minimise |r + s ua - t ub|^2 with r = pa - pb: the free optimum solves
    s = e t - f, t = e s + g (e = ua.ub, f = ua.r, g = ub.r); clamp s, take the best t for it,
    and if t clamps, the best s for that t (Ericson, Real-Time Collision Detection, 5.1.9).
    """
    r = pa - pb
    e = wp.dot(ua, ub)
    f = wp.dot(ua, r)
    g = wp.dot(ub, r)
    den = _ONE - e * e
    s = _ZERO
    if den > float_t(1e-12):
        s = wp.clamp((e * g - f) / den, -ha, ha)
    t = e * s + g
    if t < -hb:
        t = -hb
        s = wp.clamp(e * t - f, -ha, ha)
    elif t > hb:
        t = hb
        s = wp.clamp(e * t - f, -ha, ha)
    return s, t


@wp.func
def collide_capsule_capsule(c: ContactWriter, a: int, b: int, A: Pose, B: Pose, ra: float_t, ha: vec3, rb: float_t,
                            hb: vec3, max_sep: float_t):
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
            for k in range(2):
                sk = lo
                if k == 1:
                    sk = hi
                pa = A.x + ua * sk
                tk = wp.clamp(wp.dot(pa - B.x, ub), -lb, lb)
                _sphere_pair(c, a, b, A, B, pa, ra, B.x + ub * tk, rb, n, max_sep)
            return
    _sphere_pair(c, a, b, A, B, A.x + ua * s, ra, B.x + ub * t, rb, n, max_sep)


# ---------------------------------------------------------------------------- dispatch


@wp.kernel
def _collide_pairs(
    pair_a: wp.array(dtype=wp.int32),
    pair_b: wp.array(dtype=wp.int32),
    shape: wp.array(dtype=wp.int32),
    radius: wp.array(dtype=float_t),
    half_extents: wp.array(dtype=vec3),
    bound: wp.array(dtype=float_t),
    x: wp.array(dtype=vec3),
    q: wp.array(dtype=quat),
    v: wp.array(dtype=vec3),
    w: wp.array(dtype=vec3),
    dt: float_t,
    margin: float_t,
    c: ContactWriter,
):
    p = wp.tid()
    a = pair_a[p]
    b = pair_b[p]
    # swap into pair-table order: shape[a] <= shape[b]; the normal then points a -> b
    if shape[a] > shape[b]:
        t = a
        a = b
        b = t
    sa = shape[a]
    sb = shape[b]
    A = Pose()
    A.x = x[a]
    A.q = q[a]
    B = Pose()
    B.x = x[b]
    B.q = q[b]
    # speculative distance: how far the surfaces can approach in one step, plus a margin
    reach = wp.length(v[b] - v[a])
    if sa != int(ShapeType.PLANE):
        reach += wp.length(w[a]) * bound[a]
    reach += wp.length(w[b]) * bound[b]
    max_sep = dt * reach + margin
    if sa == int(ShapeType.PLANE):
        if sb == int(ShapeType.SPHERE):
            collide_plane_sphere(c, a, b, A, B, radius[b], max_sep)
        elif sb == int(ShapeType.BOX):
            collide_plane_box(c, a, b, A, B, half_extents[b], max_sep)
        elif sb == int(ShapeType.CAPSULE):
            collide_plane_capsule(c, a, b, A, B, radius[b], half_extents[b], max_sep)
    elif sa == int(ShapeType.SPHERE):
        if sb == int(ShapeType.SPHERE):
            collide_sphere_sphere(c, a, b, A, B, radius[a], radius[b], max_sep)
        elif sb == int(ShapeType.BOX):
            collide_sphere_box(c, a, b, A, B, radius[a], half_extents[b], max_sep)
        elif sb == int(ShapeType.CAPSULE):
            collide_sphere_capsule(c, a, b, A, B, radius[a], radius[b], half_extents[b], max_sep)
    elif sa == int(ShapeType.BOX):
        if sb == int(ShapeType.BOX):
            collide_box_box(c, a, b, A, B, half_extents[a], half_extents[b], max_sep)
        elif sb == int(ShapeType.CAPSULE):
            collide_box_capsule(c, a, b, A, B, half_extents[a], radius[b], half_extents[b], max_sep)
    elif sa == int(ShapeType.CAPSULE):
        collide_capsule_capsule(c, a, b, A, B, radius[a], half_extents[a], radius[b], half_extents[b], max_sep)


def collide(bodies, pairs, contacts, dt: float) -> None:
    """Run the pair table over the broad phase's pairs, filling `contacts` (grown as needed)."""
    contacts.begin_step()
    if pairs.pair_count == 0:
        contacts.count = 0
        return
    b = bodies.arrays
    while True:
        writer = contacts.writer()
        wp.launch(
            _collide_pairs,
            dim=pairs.pair_count,
            device=bodies.device,
            inputs=[pairs.pair_a, pairs.pair_b, b["body_shape"], b["body_radius"], b["body_half_extents"],
                    b["body_bound_radius"], b["body_position"], b["body_orientation"], b["body_velocity"],
                    b["body_angular_velocity"], dt, SPECULATIVE_MARGIN, writer],
        )
        count = int(writer.count.numpy()[0])
        if count <= contacts.capacity:
            break
        contacts.grow(count)
    contacts.count = count
