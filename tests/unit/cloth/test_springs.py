"""cloth/springs.py: spring forces, the stretch limit, tethers and the stable substep, on plain arrays."""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

from tumble.cloth import springs
from tumble.state import float_t, vec3


def test_stable_substep_single_spring():
    """Undamped: h = 0.9 * 2 / sqrt(2 K w), the Gershgorin bound of symplectic Euler."""
    h = springs.stable_substep(np.array([10.0]), np.array([0.0]), np.array([100.0]))
    assert h == pytest.approx(0.9 * 2.0 / math.sqrt(2.0 * 10.0 * 100.0))
    assert springs.stable_substep(np.zeros(3), np.zeros(3), np.ones(3)) == math.inf


def test_spring_force_on_plain_arrays():
    """One stretched spring pulls its ends together with ks (|d| - l0)."""
    x = wp.array(np.array([[0.0, 0.0, 0.0], [1.5, 0.0, 0.0]]), dtype=vec3)
    v = wp.zeros(2, dtype=vec3)
    f = wp.zeros(2, dtype=vec3)
    ids = wp.array(np.array([[0, 1]], dtype=np.int32), dtype=wp.int32)
    one = lambda value: wp.array(np.array([value]), dtype=float_t)  # noqa: E731
    springs.accumulate_spring_forces(x, v, ids, one(1.0), one(4.0), one(0.0), f)
    assert f.numpy() == pytest.approx(np.array([[2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]]))


def test_stretch_limit_on_plain_arrays():
    """A spring stretched to 2 l0 is brought back to at most (1 + s) l0, pinned end fixed."""
    x = wp.array(np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]]), dtype=vec3)
    inv_m = wp.array(np.array([0.0, 1.0]), dtype=float_t)
    ids = wp.array(np.array([[0, 1]], dtype=np.int32), dtype=wp.int32)
    limit = wp.array(np.array([1.1]), dtype=float_t)
    flag = wp.zeros(1, dtype=wp.int32)
    springs.limit_stretch(x, inv_m, ids, limit, flag)
    out = x.numpy()
    assert out[0] == pytest.approx([0.0, 0.0, 0.0])
    assert 1.0 < out[1, 0] <= 1.1


def test_tethers_on_plain_arrays():
    """A particle tethered to two pins ends within margin x limit of each; a released pin holds nothing."""
    x = wp.array(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, -3.0, 0.0], [9.0, 9.0, 9.0]]), dtype=vec3)
    inv_m = wp.array(np.array([0.0, 0.0, 1.0, 1.0]), dtype=float_t)
    # particle 2 has tethers to pins 0 and 1 (limit 1.2 each); particle 3 none
    first = wp.array(np.array([0, 0, 0, 2], dtype=np.int32), dtype=wp.int32)
    count = wp.array(np.array([0, 0, 2, 0], dtype=np.int32), dtype=wp.int32)
    pin = wp.array(np.array([0, 1], dtype=np.int32), dtype=wp.int32)
    limit = wp.array(np.array([1.2, 1.2]), dtype=float_t)
    tethers = springs.tether_arrays(first, count, pin, limit)
    for _ in range(20):  # alternating projections onto two balls converge into their overlap
        springs.limit_tethers(x, inv_m, tethers)
    out = x.numpy()
    assert np.linalg.norm(out[2] - out[0]) <= 0.99 * 1.2 + 1e-9
    assert np.linalg.norm(out[2] - out[1]) <= 0.99 * 1.2 + 1e-9
    assert out[0] == pytest.approx([0.0, 0.0, 0.0]) and out[1] == pytest.approx([1.0, 0.0, 0.0])
    assert out[3] == pytest.approx([9.0, 9.0, 9.0])
    # pin 1 released (inverse mass > 0): its tether no longer acts
    x = wp.array(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [9.0, 9.0, 9.0]]), dtype=vec3)
    released = wp.array(np.array([0.0, 1.0, 1.0, 1.0]), dtype=float_t)
    springs.limit_tethers(x, released, tethers)
    assert x.numpy()[2] == pytest.approx([0.0, -1.0, 0.0])
