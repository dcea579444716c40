"""closest_on_triangle (cloth triangles against small spheres): the nearest point, as barycentric weights."""

from __future__ import annotations

import numpy as np
import warp as wp
from hypothesis import given, settings
from hypothesis import strategies as st

from tumble.cloth.collide import closest_on_triangle
from tumble.state import vec3


@wp.kernel
def _closest(
    p: wp.array(dtype=vec3),
    a: wp.array(dtype=vec3),
    b: wp.array(dtype=vec3),
    c: wp.array(dtype=vec3),
    out: wp.array(dtype=vec3),
):
    i = wp.tid()
    out[i] = closest_on_triangle(p[i], a[i], b[i], c[i])


def _weights(p, a, b, c) -> np.ndarray:
    arrays = [wp.array(np.asarray(v, dtype=np.float64), dtype=vec3) for v in (p, a, b, c)]
    out = wp.zeros(len(p), dtype=vec3)
    wp.launch(_closest, dim=len(p), inputs=[*arrays, out])
    return out.numpy()


coord = st.floats(-2.0, 2.0, allow_nan=False)
point = st.tuples(coord, coord, coord)


@settings(max_examples=60, deadline=None)
@given(p=point, a=point, b=point, c=point)
def test_weights_give_the_nearest_point_of_the_triangle(p, a, b, c):
    p, a, b, c = (np.array(v) for v in (p, a, b, c))
    w = _weights([p], [a], [b], [c])[0]
    assert np.all(np.isfinite(w))
    assert np.all(w >= -1e-9) and abs(w.sum() - 1.0) < 1e-9
    q = w[0] * a + w[1] * b + w[2] * c
    if np.linalg.norm(np.cross(b - a, c - a)) < 1e-6 * max(1.0, np.linalg.norm(b - a) * np.linalg.norm(c - a)):
        return  # a collapsed triangle: some point of it (above), not necessarily the nearest
    # no point of the triangle (dense barycentric samples) is nearer than q
    u, v = np.meshgrid(np.linspace(0, 1, 41), np.linspace(0, 1, 41))
    keep = u + v <= 1
    samples = a + u[keep, None] * (b - a) + v[keep, None] * (c - a)
    assert np.linalg.norm(q - p) <= np.linalg.norm(samples - p, axis=1).min() + 1e-9


def test_points_over_the_face_edges_and_corners():
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    cases = {
        (0.25, 0.25, 0.5): (0.5, 0.25, 0.25),  # above the face: its projection
        (-1.0, -1.0, 0.0): (1.0, 0.0, 0.0),  # beyond corner a
        (0.5, -1.0, 0.3): (0.5, 0.5, 0.0),  # beyond edge ab: its midpoint
        (2.0, 2.0, 0.0): (0.0, 0.5, 0.5),  # beyond edge bc
    }
    got = _weights(list(cases), [a] * 4, [b] * 4, [c] * 4)
    np.testing.assert_allclose(got, np.array(list(cases.values())), atol=1e-12)


def test_a_collapsed_triangle_gives_a_vertex_not_nan():
    a = np.array([0.0, 0.0, 0.0])
    w = _weights([[0.3, 0.2, 1.0], [5.0, 5.0, 5.0]], [a, a], [a, a], [a, a])
    assert np.all(np.isfinite(w))
    line = _weights([[0.5, 1.0, 0.0]], [[0.0, 0, 0]], [[1.0, 0, 0]], [[2.0, 0, 0]])[0]
    assert np.all(np.isfinite(line)) and abs(line.sum() - 1.0) < 1e-9
