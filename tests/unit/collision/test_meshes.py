"""collision/meshes.py: MeshSet rows, ids for the kernels, and a BVH that answers point queries."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from tumble.collision.meshes import MeshSet, closest_on_triangles, sharp_features, winding_number

#: a unit square in z = 0, counter-clockwise seen from +z (two triangles)
SQUARE = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
SQUARE_TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]])


@wp.kernel
def _closest(mesh: wp.uint64, points: wp.array(dtype=wp.vec3f), out: wp.array(dtype=wp.vec3f)):
    i = wp.tid()
    q = wp.mesh_query_point_no_sign(mesh, points[i], 10.0)
    if q.result:
        out[i] = wp.mesh_eval_position(mesh, q.face, q.u, q.v)


def test_rows_ids_and_triangle_count():
    """Each add returns the next row; ids() has one id per row (a single 0 with none); counts add up."""
    meshes = MeshSet("cpu")
    assert meshes.ids().numpy().tolist() == [0] and meshes.triangle_count == 0
    assert meshes.add(SQUARE, SQUARE_TRIANGLES) == 0
    tetra = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    assert meshes.add(tetra, np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])) == 1
    ids = meshes.ids().numpy()
    assert ids.dtype == np.uint64 and len(ids) == 2 and ids[0] != ids[1] and (ids > 0).all()
    assert meshes.triangle_count == 6
    np.testing.assert_array_equal(meshes.vertices[1], tetra)
    assert meshes.triangles[0].dtype == np.int32


def test_the_bvh_finds_the_closest_point_of_the_mesh():
    """A point above the square projects onto it; one beside it onto the nearest edge."""
    meshes = MeshSet("cpu")
    row = meshes.add(SQUARE, SQUARE_TRIANGLES)
    points = np.array([[0.25, 0.75, 0.5], [2.0, 0.5, 0.0], [-1.0, -1.0, 1.0]], dtype=np.float32)
    out = wp.zeros(3, dtype=wp.vec3f)
    wp.launch(_closest, dim=3, inputs=[wp.uint64(meshes.ids().numpy()[row]), wp.array(points, dtype=wp.vec3f), out])
    expected = np.array([[0.25, 0.75, 0.0], [1.0, 0.5, 0.0], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(out.numpy(), expected, atol=1e-6)


def _count(flags, shift):
    return sum(int(f >> shift & 7).bit_count() for f in flags)


def test_sharp_features_are_the_corners_and_edges_each_flagged_once():
    """A box mesh: closed, its 8 corners and 12 edges (not the face diagonals); the open square: its
    4 corners and 4 border edges; a flat grid's inner vertices and edges are not sharp."""
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    flags, closed = sharp_features(box.vertices, box.faces)
    assert closed and _count(flags, 0) == 8 and _count(flags, 3) == 12
    flags, closed = sharp_features(SQUARE, SQUARE_TRIANGLES)
    assert not closed and _count(flags, 0) == 4 and _count(flags, 3) == 4
    # a 3 x 3 flat grid of 2 x 2 quads: the middle vertex and the 8 inner edges are not sharp
    v = np.array([[i, j, 0.0] for j in range(3) for i in range(3)])
    t = np.array([[a, a + 1, a + 4] for a in (0, 1, 3, 4)] + [[a, a + 4, a + 3] for a in (0, 1, 3, 4)])
    flags, closed = sharp_features(v, t)
    assert not closed and _count(flags, 0) == 8 and _count(flags, 3) == 8
    # a convex solid: every vertex and edge is sharp, a concave edge is not
    ico = trimesh.creation.icosphere(1)
    flags, closed = sharp_features(ico.vertices, ico.faces)
    assert closed and _count(flags, 0) == len(ico.vertices) and _count(flags, 3) == len(ico.edges_unique)


def test_struct_holds_the_features_of_every_row():
    """MeshSet.struct(): ids, closed flags and feature rows concatenated with their starts."""
    meshes = MeshSet("cpu")
    meshes.add(SQUARE, SQUARE_TRIANGLES)
    tetra = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    meshes.add(tetra, np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))
    s = meshes.struct()
    assert s.closed.numpy().tolist() == [0, 1]
    assert s.feature_start.numpy().tolist() == [0, 2, 6]
    assert _count(s.feature.numpy()[2:6], 0) == 4 and _count(s.feature.numpy()[2:6], 3) == 6
    np.testing.assert_array_equal(s.id.numpy(), meshes.ids().numpy())


def test_closest_on_triangles_matches_the_bvh_query():
    """The host-side closest point (NumPy, by Voronoi regions) is as near as Warp's BVH query finds,
    for points near and far from a soup of random triangles, to float32 rounding (the BVH's points)."""
    rng = np.random.default_rng(4)
    vertices = rng.normal(size=(90, 3))
    triangles = np.arange(90).reshape(30, 3)
    meshes = MeshSet("cpu")
    meshes.add(vertices, triangles)
    points = rng.normal(size=(200, 3)) * 1.5
    out = wp.zeros(len(points), dtype=wp.vec3f)
    wp.launch(_closest, len(points), [meshes.meshes[0].id, wp.array(points, dtype=wp.vec3f), out])
    bvh = np.linalg.norm(out.numpy() - points, axis=1)
    a, b, c = meshes.corners(0)
    ours = np.array([np.linalg.norm(closest_on_triangles(p, a, b, c) - p, axis=1).min() for p in points])
    np.testing.assert_allclose(ours, bvh, atol=2e-6)


def test_closest_on_triangles_picks_each_region():
    """A point beyond a corner, beside an edge and above the face of the triangle (0,0,0) (1,0,0) (0,1,0)."""
    a, b, c = np.array([[0.0, 0, 0]]), np.array([[1.0, 0, 0]]), np.array([[0.0, 1, 0]])
    cases = {
        (-1.0, -1.0, 0.5): (0, 0, 0),
        (2.0, -0.5, 0.0): (1, 0, 0),
        (-0.5, 3.0, 0.0): (0, 1, 0),
        (0.5, -2.0, 1.0): (0.5, 0, 0),
        (-2.0, 0.25, 0.0): (0, 0.25, 0),
        (1.0, 1.0, -1.0): (0.5, 0.5, 0),
        (0.2, 0.3, 2.0): (0.2, 0.3, 0),
    }
    for p, want in cases.items():
        np.testing.assert_allclose(closest_on_triangles(np.array(p), a, b, c)[0], want, atol=1e-15)


def test_winding_number_is_one_inside_a_closed_mesh_and_zero_outside():
    """+1 inside a tetrahedron wound outward, -1 with its winding flipped, 0 outside."""
    tetra = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    outward = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    a, b, c = (tetra[outward[:, k]] for k in range(3))
    inside, outside = np.array([0.1, 0.2, 0.3]), np.array([0.6, 0.6, 0.6])
    assert winding_number(inside, a, b, c) == pytest.approx(1.0, abs=1e-12)
    assert winding_number(inside, a, c, b) == pytest.approx(-1.0, abs=1e-12)
    assert winding_number(outside, a, b, c) == pytest.approx(0.0, abs=1e-12)
