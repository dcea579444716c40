"""collision/meshes.py: MeshSet rows, ids for the kernels, and a BVH that answers point queries."""

from __future__ import annotations

import numpy as np
import warp as wp

from tumble.collision.meshes import MeshSet

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
