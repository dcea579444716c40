"""solver/rigid.py: the Warp rigid-body algebra against NumPy (rotation matrices from tumble.npmath's tested ones)."""

import numpy as np
import warp as wp

from tumble.npmath import quat_to_matrix
from tumble.runtime import init_warp
from tumble.solver import rigid
from tumble.state import float_t, mat33, quat, vec3


@wp.kernel
def _apply(
    q: wp.array(dtype=quat),
    inv_i: wp.array(dtype=vec3),
    x: wp.array(dtype=vec3),
    k: wp.array(dtype=float_t),
    times: wp.array(dtype=vec3),
    tensor: wp.array(dtype=mat33),
    inverse: wp.array(dtype=float_t),
):
    i = wp.tid()
    times[i] = rigid.inv_inertia_times(q[i], inv_i[i], x[i])
    tensor[i] = rigid.inv_inertia_world(q[i], inv_i[i])
    inverse[i] = rigid.safe_inverse(k[i])


def test_world_inverse_inertia_and_safe_inverse_match_numpy():
    init_warp()
    rng = np.random.default_rng(5)
    n = 8
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    inv_i = rng.uniform(0.1, 3.0, size=(n, 3))
    inv_i[0] = 0.0  # a static body: no rotation at all
    x = rng.normal(size=(n, 3))
    k = np.array([2.0, 0.5, 0.0, -1.0, 1e-300, 4.0, 1.0, 8.0])
    out = [wp.zeros(n, dtype=t, device="cpu") for t in (vec3, mat33, float_t)]
    args = [wp.array(a, dtype=t, device="cpu") for a, t in ((q, quat), (inv_i, vec3), (x, vec3), (k, float_t))]
    wp.launch(_apply, dim=n, inputs=[*args, *out], device="cpu")
    r = quat_to_matrix(q)
    expected = np.einsum("nij,nj,nkj->nik", r, inv_i, r)  # R diag(inv_i) R^T
    np.testing.assert_allclose(out[1].numpy(), expected, atol=1e-13)
    np.testing.assert_allclose(out[0].numpy(), np.einsum("nij,nj->ni", expected, x), atol=1e-13)
    np.testing.assert_array_equal(out[0].numpy()[0], 0.0)
    np.testing.assert_array_equal(out[2].numpy(), np.where(k > 0, 1.0 / np.where(k > 0, k, 1.0), 0.0))
