"""Narrow phase, per shape pair: separated, touching, overlapping, deep, coincident, swapped."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import tumble
from tolerances import resolution, stored

from ..reference import quat_axis_angle, rotate

DT = 1.0 / 240.0
# contacts are reported up to the speculative margin when bodies are at rest
MARGIN = 0.002


def contacts(world):
    """Run broad + narrow phase and return (pairs, normals, depths, points)."""
    world.collide()
    return world.contact_pair, world.contact_normal, world.contact_depth, world.contact_point


# ------------------------------------------------------------------ sphere-sphere


@pytest.mark.parametrize(
    "gap, expect",
    [(0.5, 0), (MARGIN / 2, 1), (0.0, 1), (-0.01, 1), (-0.15, 1)],
    ids=["separated", "speculative", "touching", "overlapping", "deep"],
)
@pytest.mark.parametrize("swapped", [False, True])
def test_sphere_sphere_depth_and_normal(gap, expect, swapped):
    """Report depth r1 + r2 - |d| along the centre line, normal from the first body to the second."""
    w = tumble.World(gravity=(0, 0, 0))
    r1, r2 = 0.1, 0.2
    p1, p2 = np.zeros(3), np.array([r1 + r2 + gap, 0, 0])
    if swapped:
        w.add_sphere(position=p2, radius=r2, mass=1)
        w.add_sphere(position=p1, radius=r1, mass=1)
    else:
        w.add_sphere(position=p1, radius=r1, mass=1)
        w.add_sphere(position=p2, radius=r2, mass=1)
    pairs, normals, depths, _ = contacts(w)
    assert len(depths) == expect
    if expect:
        # r1 + r2 - |x2 - x1| from rounded inputs: a few ulps of the centres' distance
        assert depths[0] == pytest.approx(-gap, abs=resolution(1e-12, r1 + r2, 4))
        a = pairs[0, 0]
        # normal points from body a to body b
        expected = np.array([1.0, 0, 0]) if (a == 0) != swapped else np.array([-1.0, 0, 0])
        np.testing.assert_allclose(normals[0], expected, atol=resolution(1e-12, 1.0, 4))


def test_sphere_sphere_coincident_centres():
    """Give coincident spheres a valid unit normal and full depth."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_sphere(position=(0, 0, 0), radius=0.1, mass=1)
    w.add_sphere(position=(0, 0, 0), radius=0.1, mass=1)
    _, normals, depths, _ = contacts(w)
    assert len(depths) == 1
    assert np.linalg.norm(normals[0]) == pytest.approx(1.0)
    assert depths[0] == pytest.approx(0.2)


def test_coincident_sphere_pairs_get_different_normals():
    """Each pair of coincident spheres has its own normal (from its ids), so a knot placed at one point
    parts in every direction instead of along one axis; the same pair gets the same normal every time."""
    w = tumble.World(gravity=(0, 0, 0))
    for _ in range(4):
        w.add_sphere(position=(1, 2, 3), radius=0.1, mass=1)
    pairs, normals, depths, _ = contacts(w)
    assert len(depths) == 6
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=resolution(1e-12, 1.0, 4))
    # no two of the six normals parallel, and they span space (the knot spreads in all three axes)
    cos = np.abs(normals @ normals.T) - np.eye(6)
    assert cos.max() < 0.99
    assert np.linalg.svd(normals, compute_uv=False).min() > 0.1
    again, normals_again, _, _ = contacts(w)
    np.testing.assert_array_equal(again, pairs)
    np.testing.assert_array_equal(normals_again, normals)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-1, 1), min_size=3, max_size=3),
    st.floats(0.01, 0.5),
    st.floats(0.01, 0.5),
)
def test_sphere_sphere_matches_distance(offset, r1, r2):
    """Depth equals r1 + r2 - |x2 - x1| for any placement that is near enough to report."""
    d, r1, r2 = stored(offset), float(stored(r1)), float(stored(r2))
    w = tumble.World(gravity=(0, 0, 0))
    w.add_sphere(position=(0, 0, 0), radius=r1, mass=1)
    w.add_sphere(position=d, radius=r2, mass=1)
    _, normals, depths, _ = contacts(w)
    depth = r1 + r2 - np.linalg.norm(d)
    scale = r1 + r2 + np.linalg.norm(d)  # one formula: a few ulps of the lengths it subtracts
    band = resolution(1e-9, scale, 4)
    if depth < -MARGIN - band:
        assert len(depths) == 0
    elif depth > -MARGIN + band and np.linalg.norm(d) > 1e-9:
        assert len(depths) == 1
        assert depths[0] == pytest.approx(depth, abs=resolution(1e-12, scale, 4))
        np.testing.assert_allclose(normals[0], d / np.linalg.norm(d), atol=resolution(1e-12, 1.0, 4))


# ------------------------------------------------------------------ plane-sphere, plane-box


@pytest.mark.parametrize(
    "height, expect", [(1.0, 0), (0.1, 1), (0.05, 1), (-0.2, 1)], ids=["separated", "touching", "overlapping", "deep"]
)
def test_plane_sphere(height, expect):
    """Depth of a sphere on a tilted plane is r - signed distance of its centre."""
    n = np.array([0.0, 0.6, 0.8])
    w = tumble.World(gravity=(0, 0, 0))
    w.add_plane(normal=n, offset=0.5)
    w.add_sphere(position=n * (0.5 + height), radius=0.1, mass=1)
    _, normals, depths, points = contacts(w)
    assert len(depths) == expect
    if expect:
        # r - (n . x - offset): a few ulps of the offset and the centre's distance it subtracts
        scale = 0.5 + abs(0.5 + height)
        assert depths[0] == pytest.approx(0.1 - height, abs=resolution(1e-12, scale, 8))
        np.testing.assert_allclose(normals[0], n, atol=resolution(1e-12, 1.0, 4))


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1), st.floats(-0.1, 0.3)
)
def test_plane_box_deepest_corners(q, z):
    """Report up to four corners, the deepest ones, each at its true depth below the plane."""
    q = stored(np.asarray(q) / np.linalg.norm(q))
    z = float(stored(z))
    h = np.array([0.1, 0.2, 0.05])
    w = tumble.World(gravity=(0, 0, 0))
    w.add_plane()
    w.add_box(position=(0, 0, z), half_extents=h, orientation=q, mass=1)
    _, normals, depths, _ = contacts(w)
    corners = np.array([[sx, sy, sz] for sz in (1, -1) for sy in (1, -1) for sx in (1, -1)]) * h
    heights = np.sort([z + rotate(q, c)[2] for c in corners])
    expected = -heights[heights <= MARGIN][:4]
    assert len(depths) == len(expected)
    # corners turned by the (normalised) quaternion's matrix: 16 ulps of the corner's reach
    atol = resolution(1e-12, abs(z) + np.linalg.norm(h), 16)
    np.testing.assert_allclose(np.sort(depths)[::-1], np.sort(expected)[::-1], atol=atol)
    if len(depths):
        np.testing.assert_allclose(normals, np.tile([0, 0, 1.0], (len(depths), 1)), atol=resolution(1e-12, 1.0, 4))


# ------------------------------------------------------------------ sphere-box


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3),
    st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1),
)
def test_sphere_box_closest_point(centre, q):
    """Depth is r minus the distance to the box's closest point (or plus the depth inside)."""
    q = stored(np.asarray(q) / np.linalg.norm(q))
    h = np.array([0.2, 0.1, 0.15])
    r = 0.1
    c = stored(centre)
    w = tumble.World(gravity=(0, 0, 0))
    w.add_box(position=(0, 0, 0), half_extents=h, orientation=q, mass=1)
    w.add_sphere(position=c, radius=r, mass=1)
    pairs, normals, depths, _ = contacts(w)
    local = rotate(q * [-1, -1, -1, 1], c)
    inside = np.all(np.abs(local) <= h)
    if inside:
        expected = r + np.min(h - np.abs(local))
    else:
        expected = r - np.linalg.norm(local - np.clip(local, -h, h))
    # the centre turned into the box's frame, clipped, measured: 16 ulps of the lengths involved
    atol = resolution(1e-9, np.linalg.norm(c) + np.linalg.norm(h) + r, 16)
    if expected < -MARGIN - atol:
        assert len(depths) == 0
        return
    if expected > -MARGIN + atol:
        assert len(depths) == 1
        assert depths[0] == pytest.approx(expected, abs=atol)
        # sphere is body a (SPHERE < BOX): the normal points from the sphere into the box
        assert tuple(pairs[0]) == (1, 0)
        if not inside:
            out = local - np.clip(local, -h, h)
            np.testing.assert_allclose(normals[0], -rotate(q, out / np.linalg.norm(out)), atol=atol)


# ------------------------------------------------------------------ box-box


@pytest.mark.parametrize(
    "gap, expect", [(0.3, 0), (0.0, 4), (-0.01, 4), (-0.08, 4)], ids=["separated", "touching", "overlapping", "deep"]
)
def test_box_box_face_manifold(gap, expect):
    """Stacked boxes give a four-point manifold at the overlap depth with an upward normal."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_box(position=(0, 0, 0), half_extents=(0.2, 0.2, 0.1), mass=1)
    w.add_box(position=(0.05, 0.02, 0.2 + gap), half_extents=(0.1, 0.1, 0.1), mass=1)
    pairs, normals, depths, points = contacts(w)
    assert len(depths) == expect
    if expect:
        # face clipping of axis-aligned boxes: a few ulps of the boxes' positions and sizes (~0.3)
        atol = resolution(1e-12, 0.3, 8)
        np.testing.assert_allclose(depths, -gap, atol=atol)
        np.testing.assert_allclose(normals, np.tile([0, 0, 1.0], (4, 1)), atol=resolution(1e-12, 1.0, 4))
        # the manifold spans the upper box's bottom face
        np.testing.assert_allclose(np.sort(points[:, 0]), [-0.05, -0.05, 0.15, 0.15], atol=atol)


def test_box_box_clipped_manifold_inside_both_faces():
    """A box turned 45 degrees on a larger box: contact points lie on both faces' overlap."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_box(position=(0, 0, 0), half_extents=(0.12, 0.12, 0.1), mass=1)
    q = quat_axis_angle((0, 0, 1), np.pi / 4)
    w.add_box(position=(0, 0, 0.199), half_extents=(0.1, 0.1, 0.1), orientation=q, mass=1)
    _, normals, depths, points = contacts(w)
    assert 1 <= len(depths) <= 4
    # a turned face clipped against another: 16 ulps of the boxes' positions and sizes (~0.3)
    atol = resolution(1e-9, 0.3, 16)
    np.testing.assert_allclose(depths, 0.001, atol=atol)
    assert np.all(np.abs(points[:, :2]) <= 0.12 + atol)
    local = np.array([rotate(q * [-1, -1, -1, 1], p - [0, 0, 0.199]) for p in points])
    assert np.all(np.abs(local[:, :2]) <= 0.1 + atol)


def test_box_box_edge_edge():
    """Two boxes crossed edge to edge touch at one point, normal along the cross axis."""
    w = tumble.World(gravity=(0, 0, 0))
    qa = quat_axis_angle((1, 0, 0), np.pi / 4)  # edge along x on top
    qb = quat_axis_angle((0, 1, 0), np.pi / 4)  # edge along y at the bottom
    e = 0.1 * np.sqrt(2)
    w.add_box(position=(0, 0, 0), half_extents=(0.1, 0.1, 0.1), orientation=qa, mass=1)
    w.add_box(position=(0, 0, 2 * e - 0.004), half_extents=(0.1, 0.1, 0.1), orientation=qb, mass=1)
    _, normals, depths, points = contacts(w)
    assert len(depths) == 1
    # closest points of two turned edges: 16 ulps of the boxes' reach (2e ~ 0.3)
    atol = resolution(1e-9, 2 * e, 16)
    assert depths[0] == pytest.approx(0.004, abs=atol)
    np.testing.assert_allclose(np.abs(normals[0]), [0, 0, 1], atol=resolution(1e-9, 1.0, 16))
    np.testing.assert_allclose(points[0], [0, 0, e - 0.002], atol=atol)


def _sat_depth(x, q, half):
    """Penetration depth of two equal boxes and its axis, by the 15 separating axes (independent of Tumble)."""
    frames = [np.array([rotate(qi, e) for e in np.eye(3)]).T for qi in q]
    axes = [f[:, k] for f in frames for k in range(3)]
    axes += [np.cross(frames[0][:, i], frames[1][:, j]) for i in range(3) for j in range(3)]
    d = x[1] - x[0]
    best = (np.inf, None)
    for axis in axes:
        if np.linalg.norm(axis) < 1e-6:
            continue
        axis = axis / np.linalg.norm(axis)
        reach = sum(half[k] * abs(f[:, k] @ axis) for f in frames for k in range(3))
        best = min(best, (reach - abs(d @ axis), tuple(axis)), key=lambda b: b[0])
    return best[0], np.array(best[1])


def test_box_box_crossed_edge_sunk_into_a_face_is_a_contact():
    """A tilted box whose edge has sunk 0.74 mm across a resting box's top edge (a pair from the rain
    of 1,000 boxes) touches it there: the face axis, preferred for a steady manifold, clips the
    incident face to nothing within reach, and the edge pair takes over, at the separating-axis depth."""
    x = np.array([[0.211061, 0.367465, 0.049996], [0.175925, 0.419842, 0.185327]])
    q = np.array([[5.95194e-06, -3.08525e-06, -0.0210845, 0.999778], [0.631580, 0.624097, -0.00569906, 0.459975]])
    q = q / np.linalg.norm(q, axis=1)[:, None]
    half = np.full(3, 0.05)
    w = tumble.World(gravity=(0, 0, 0))
    for k in range(2):
        w.add_box(position=x[k], orientation=q[k], half_extents=half, mass=1)
    depth, axis = _sat_depth(x, q, half)
    assert 0.0005 < depth < 0.001  # an edge-edge overlap, smaller than the face axes' (1.27 mm and more)
    _, normals, depths, _ = contacts(w)
    assert len(depths) == 1
    # two turned boxes' edge pair: 16 ulps of their positions (~0.5)
    assert depths[0] == pytest.approx(depth, abs=resolution(1e-9, 0.5, 16))
    np.testing.assert_allclose(np.abs(normals[0] @ axis), 1.0, atol=resolution(1e-9, 1.0, 16))


@pytest.mark.parametrize("swapped", [False, True])
def test_box_box_normal_points_from_a_to_b(swapped):
    """Whichever body comes first, the normal points from body a to body b."""
    w = tumble.World(gravity=(0, 0, 0))
    lower, upper = dict(position=(0, 0, 0)), dict(position=(0.19, 0.03, 0.02))
    for kw in (upper, lower) if swapped else (lower, upper):
        w.add_box(half_extents=(0.1, 0.1, 0.1), mass=1, **kw)
    pairs, normals, depths, _ = contacts(w)
    assert len(depths) == 4
    # face clipping of axis-aligned boxes: a few ulps of the boxes' positions and sizes (~0.2)
    np.testing.assert_allclose(depths, 0.01, atol=resolution(1e-12, 0.2, 8))
    x = w.body_position
    for (a, b), n in zip(pairs, normals):
        assert np.dot(n, x[b] - x[a]) > 0


def test_small_box_on_huge_box_keeps_four_corners():
    """A 10 cm box on a 10 m box gets its four corners (near-duplicate merging scales with the small face)."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_box(position=(0, 0, -0.5), half_extents=(5, 5, 0.5), static=True)
    w.add_box(position=(1, 2, 0.0499), half_extents=(0.05, 0.05, 0.05), mass=0.1)
    _, normals, depths, points = contacts(w)
    assert len(depths) == 4
    # face clipping of axis-aligned boxes: a few ulps of the positions involved (~1)
    atol = resolution(1e-12, 1.0, 8)
    np.testing.assert_allclose(depths, 1e-4, atol=atol)
    np.testing.assert_allclose(np.sort(points[:, 0]), [0.95, 0.95, 1.05, 1.05], atol=atol)


@pytest.mark.parametrize("static", [True, False])
def test_a_corner_over_a_sliver_of_an_edge_touches_only_a_moving_box(static):
    """A cube 1 mm above another's top, over its edge by 0.5 mm (under GHOST_STEP of its 0.1 m half
    size), falling at 1 m/s: against a static block that is a seam of flush blocks and passes
    (`_ghost_step`); against a moving box it is a contact, else the corner would go a step deep."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_box(position=(0, 0, 0), half_extents=(0.1, 0.1, 0.1), mass=1, static=static)
    w.add_box(position=(0.1995, 0, 0.201), half_extents=(0.1, 0.1, 0.1), mass=1, velocity=(0, 0, -1))
    _, normals, depths, _ = contacts(w)
    if static:
        assert len(depths) == 0
    else:
        assert len(depths) > 0
        # 16 ulps of the boxes' positions (~0.3)
        np.testing.assert_allclose(normals[:, 2], 1.0, atol=resolution(1e-9, 1.0, 16))
        np.testing.assert_allclose(depths, -0.001, atol=resolution(1e-9, 0.3, 16))
