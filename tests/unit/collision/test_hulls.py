"""Convex bodies: hull mass properties against formulas, and contacts against a brute-force reference."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import tumble
from tolerances import resolution
from tumble import shapes
from tumble.collision.hulls import hull_from_points
from tumble.collision.narrowphase import SPECULATIVE_MARGIN

from ..reference import quat_axis_angle, rotate

CUBE = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])


def fibonacci_sphere(n):
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5**0.5) * k
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


# ------------------------------------------------------------------ mass properties


def test_hull_of_a_box_has_the_box_mass_properties():
    """Give the hull of a box's corners the box's volume and principal moments, centred."""
    h = np.array([0.3, 0.2, 0.1])
    proto = hull_from_points(CUBE * h + [1.0, 2.0, 3.0])
    assert proto.volume == pytest.approx(float(shapes.box_volume(h)), rel=1e-12)
    np.testing.assert_allclose(proto.offset_com, [1.0, 2.0, 3.0], atol=1e-12)
    expected = shapes.box_inertia(proto.volume, h)
    np.testing.assert_allclose(np.sort(proto.inertia), np.sort(expected), rtol=1e-12)
    assert len(proto.faces) == 6 and all(len(f) == 4 for f in proto.faces)


def test_hull_of_a_tetrahedron():
    """Give the corner tetrahedron (0, e1, e2, e3) V = 1/6, centroid 1/4 and moments 1/60, 1/96 (x2)."""
    # second moments of unit density: int x^2 = 1/60, int xy = 1/120; about the centroid
    # C_xx = 1/60 - V/16 = 1/160, C_xy = 1/120 - V/16 = -1/480, so I = tr(C) - C has
    # I_xx = 1/80, I_xy = 1/480 and eigenvalues 1/80 + 2/480 = 1/60 and 1/80 - 1/480 = 1/96
    proto = hull_from_points(np.vstack([np.zeros(3), np.eye(3)]))
    assert proto.volume == pytest.approx(1 / 6, rel=1e-12)
    np.testing.assert_allclose(proto.offset_com, [0.25] * 3, atol=1e-12)
    np.testing.assert_allclose(np.sort(proto.inertia), [1 / 96, 1 / 96, 1 / 60], rtol=1e-10)


def test_hull_of_a_sampled_sphere_approaches_the_sphere():
    """Give the hull of 250 points on a sphere the sphere's volume and moments, less the chord error."""
    r = 0.5
    proto = hull_from_points(fibonacci_sphere(250) * r)
    # the inscribed hull falls short of the sphere by O(edge^2 / r^2): ~1.6 % for 250 points
    assert proto.volume == pytest.approx(float(shapes.sphere_volume(r)), rel=0.025)
    assert proto.volume < float(shapes.sphere_volume(r))
    moments = proto.inertia / proto.volume  # per unit mass
    np.testing.assert_allclose(moments, 0.4 * r * r, rtol=0.03)
    assert np.ptp(moments) / moments.mean() < 0.01  # nearly isotropic
    np.testing.assert_allclose(proto.offset_com, 0.0, atol=1e-3)


def test_add_convex_puts_the_body_frame_at_the_centre_of_mass():
    """Place a convex body's frame at its centre of mass and keep the user frame in its prototype."""
    w = tumble.World()
    q = quat_axis_angle((0, 0, 1), 0.5)
    pts = np.vstack([np.zeros(3), np.eye(3)])
    c = w.add_convex(points=pts, position=(1, 0, 2), orientation=q, density=600)
    proto = w.hulls.prototypes[w.body_geometry[c]]
    # the centre of mass turned into place and stored: a few ulps of the position (~2.3)
    atol = resolution(1e-12, 2.3, 4)
    np.testing.assert_allclose(w.body_position[c], np.array([1, 0, 2]) + rotate(q, np.full(3, 0.25)), atol=atol)
    assert w.body_mass[c] == pytest.approx(600 / 6)
    # the world inertia, rotated back into the user frame, is the tetrahedron's (the stored
    # inverse moments turned and inverted: 8 ulps)
    inertia = w.body_inertia_world[c]
    moments = [600 / 96, 600 / 96, 600 / 60]
    assert sorted(np.linalg.eigvalsh(inertia)) == pytest.approx(moments, rel=resolution(1e-9, 1.0, 8))
    # user-frame vertex 0 (the origin) lands at the body's mapped vertex
    world_vertices = w.body_position[c] + np.array([rotate(w.body_orientation[c], v) for v in proto.vertex])
    assert np.min(np.linalg.norm(world_vertices - [1, 0, 2], axis=1)) < atol


@pytest.mark.parametrize(
    "points, message",
    [
        (np.zeros((3, 3)), "at least 4"),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float), "no volume"),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, np.nan]]), "not finite"),
    ],
)
def test_add_convex_rejects_bad_points(points, message):
    """Reject too few, coplanar or non-finite points with one line."""
    with pytest.raises(ValueError, match=message):
        tumble.World().add_convex(points=points)


def test_add_convex_file_errors(tmp_path):
    """Name the file when it is missing or of an unknown format."""
    w = tumble.World()
    with pytest.raises(ValueError, match="no such mesh file"):
        w.add_convex(file=tmp_path / "missing.obj")
    bad = tmp_path / "rock.xyz"
    bad.write_text("1 2 3\n")
    with pytest.raises(ValueError, match=r"rock\.xyz: unknown mesh format"):
        w.add_convex(file=bad)


def test_add_convex_from_an_open_mesh_takes_the_hull_with_a_notice(tmp_path, caplog):
    """Take the hull of a non-watertight mesh file's vertices and say so in one line."""
    path = tmp_path / "open_box.obj"
    lines = [f"v {x} {y} {z}" for x, y, z in CUBE * 0.1]
    lines += ["f 1 2 4", "f 1 4 3", "f 5 7 8", "f 5 8 6"]  # two faces only: not closed
    path.write_text("\n".join(lines) + "\n")
    w = tumble.World()
    with caplog.at_level(logging.WARNING, logger="tumble"):
        c = w.add_convex(file=path)
    assert any("not watertight" in r.getMessage() and "open_box.obj" in r.getMessage() for r in caplog.records)
    assert w.body_mass[c] == pytest.approx(1000 * 0.2**3)


# ------------------------------------------------------------------ contacts


def gap_reference(va, vb, normals):
    """Support gap min_b n.b - max_a n.a for each direction: the brute-force SAT."""
    return (vb @ normals.T).min(axis=0) - (va @ normals.T).max(axis=0)


def candidate_directions(va, vb):
    """Face normals of both hulls, every edge-pair cross product and 4,000 sampled directions."""
    from scipy.spatial import ConvexHull

    dirs = [fibonacci_sphere(4000)]
    edges = []
    for v in (va, vb):
        h = ConvexHull(v)
        dirs.append(h.equations[:, :3])
        dirs.append(-h.equations[:, :3])
        e = np.concatenate([v[h.simplices[:, k]] - v[h.simplices[:, (k + 1) % 3]] for k in range(3)])
        edges.append(e)
    cross = np.cross(edges[0][:, None], edges[1][None]).reshape(-1, 3)
    length = np.linalg.norm(cross, axis=1)
    cross = cross[length > 1e-9] / length[length > 1e-9, None]
    dirs += [cross, -cross]
    return np.concatenate(dirs)


def world_vertices(w, i):
    proto = w.hulls.prototypes[w.body_geometry[i]]
    return w.body_position[i] + np.array([rotate(w.body_orientation[i], v) for v in proto.vertex])


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    gap=st.floats(-0.02, 0.004),
    direction=st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 0.3),
)
def test_convex_convex_depth_and_normal_match_brute_force(seed, gap, direction):
    """Make the deepest convex-convex contact the brute-force SAT gap, along a normal that achieves it."""
    rng = np.random.default_rng(seed)
    pa = rng.uniform(-0.1, 0.1, (10, 3))
    pb = rng.uniform(-0.1, 0.1, (10, 3))
    w = tumble.World(gravity=(0, 0, 0))
    w.add_convex(points=pa, orientation=rng.normal(size=4))
    b = w.add_convex(points=pb, orientation=rng.normal(size=4))
    # slide B along `direction` until the brute-force gap is `gap`
    u = np.asarray(direction) / np.linalg.norm(direction)
    va = world_vertices(w, 0)
    vb0 = world_vertices(w, b)
    dirs = candidate_directions(va, vb0)
    lo, hi = -0.5, 0.5
    for _ in range(60):  # bisection: the gap grows with the offset along u
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap_reference(va, vb0 + mid * u, dirs).max() < gap else (lo, mid)
    shift = 0.5 * (lo + hi)
    w.bodies.write("body_position", 1, w.body_position[b] + shift * u)
    vb = vb0 + shift * u
    reference = gap_reference(va, vb, candidate_directions(va, vb)).max()
    w.collide()
    depths, normals, pairs = w.contact_depth, w.contact_normal, w.contact_pair
    if reference > SPECULATIVE_MARGIN - resolution(1e-12, 0.5, 16):
        # beyond the speculative distance of bodies at rest (2 mm): no contact is due (this was
        # 3 mm, so a gap of 2.3 mm, found by hypothesis with seed 0 along z, failed on main too).
        # At the margin itself rounding decides: hypothesis found gap = 2 mm exactly (seed
        # 722284510 along z), a reference 9e-18 m inside it and the engine's gap as far outside;
        # in float32, within 16 ulps of the hulls' reach (0.5)
        return
    assert len(depths) >= 1
    sign = 1.0 if pairs[0, 0] == 0 else -1.0  # normals point from the pair's first body to its second
    n = normals[0] * sign
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=resolution(1e-12, 1.0, 4))
    # the normal is (nearly) a separating direction of largest gap: faces are preferred within
    # 5 % + 1 mm of an edge axis, so the reported axis may fall short of the best by that much
    along = gap_reference(va, vb, n[None])[0]
    assert along == pytest.approx(reference, abs=0.05 * abs(reference) + 1.2e-3)
    # and the deepest clipped contact measures the same gap, within that preference
    assert -depths.max() == pytest.approx(reference, abs=0.05 * abs(reference) + 1.2e-3)


def test_convex_cube_on_box_face_gives_four_corners():
    """Give a convex cube resting on a box four contacts at its corners, depth and normal +z."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_box(position=(0, 0, 0), half_extents=(0.5, 0.5, 0.1), static=True)
    w.add_convex(points=CUBE * 0.1, position=(0, 0, 0.199))
    w.collide()
    assert w.contact_count == 4
    # a hull's face clipped against a box's: 8 ulps of the shapes' size (0.5)
    atol = resolution(1e-12, 0.5, 8)
    np.testing.assert_allclose(w.contact_depth, 0.001, atol=atol)
    np.testing.assert_allclose(w.contact_normal, [[0, 0, 1]] * 4, atol=resolution(1e-12, 1.0, 4))
    np.testing.assert_allclose(np.sort(np.abs(w.contact_point[:, :2]), axis=0), 0.1, atol=atol)


@pytest.mark.parametrize("where, depth", [("face", 0.01), ("edge", 0.005), ("inside", 0.1)])
def test_sphere_convex(where, depth):
    """Measure a sphere's depth in a convex cube on a face, at an edge and from inside."""
    r = 0.05
    p = {
        "face": [0.14, 0, 0],
        "edge": [0.1 + (r - depth) / 2**0.5, 0.1 + (r - depth) / 2**0.5, 0],
        "inside": [0.0, 0.0, 0.05],
    }[where]
    w = tumble.World(gravity=(0, 0, 0))
    w.add_sphere(position=p, radius=r)
    w.add_convex(points=CUBE * 0.1)
    w.collide()
    # the distance from the hull's nearest feature: 8 ulps of the positions (~0.15)
    assert w.contact_depth == pytest.approx([depth], abs=resolution(1e-12, 0.15, 8))
    expected = {"face": [-1, 0, 0], "edge": [-(2**-0.5), -(2**-0.5), 0], "inside": [0, 0, -1]}[where]
    np.testing.assert_allclose(w.contact_normal[0], expected, atol=resolution(1e-12, 1.0, 8))


def test_capsule_lying_on_convex_gives_a_line_contact():
    """Give a capsule lying across a convex slab two contacts clipped to the top face."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_convex(points=CUBE * [0.5, 0.2, 0.1], static=True)
    w.add_capsule(position=(0, 0, 0.19), radius=0.1, half_height=0.4, orientation=quat_axis_angle((1, 0, 0), np.pi / 2))
    w.collide()
    # the segment turned and clipped to the face: 8 ulps of the shapes' size (0.5)
    np.testing.assert_allclose(w.contact_depth, [0.01, 0.01], atol=resolution(1e-12, 0.5, 8))
    n = w.contact_normal * np.where(w.contact_pair[:, :1] == 0, 1, -1)  # from the slab to the capsule
    np.testing.assert_allclose(n, [[0, 0, 1]] * 2, atol=resolution(1e-12, 1.0, 4))
    np.testing.assert_allclose(sorted(w.contact_point[:, 1]), [-0.2, 0.2], atol=resolution(1e-9, 0.5, 8))


def test_convex_on_plane_keeps_four_deepest_vertices():
    """Give a many-vertex convex puck lying on a plane at most four contacts, spread over its base."""
    ring = np.array([[np.cos(a), np.sin(a)] for a in np.linspace(0, 2 * np.pi, 16, endpoint=False)]) * 0.2
    pts = np.vstack([np.c_[ring, np.full(16, -0.05)], np.c_[ring, np.full(16, 0.05)]])
    w = tumble.World(gravity=(0, 0, 0))
    w.add_plane()
    w.add_convex(points=pts, position=(0, 0, 0.0495))
    w.collide()
    assert w.contact_count == 4
    # the hull's vertices below the plane: 8 ulps of the puck's size (0.2)
    np.testing.assert_allclose(w.contact_depth, 0.0005, atol=resolution(1e-12, 0.2, 8))
    spread = np.linalg.norm(w.contact_point[:, :2], axis=1)
    np.testing.assert_allclose(spread, 0.2, atol=resolution(1e-9, 0.2, 8))  # the rim, not the middle
