"""Broad phase: every pair that can touch within the step is found, once, and far pairs are not.

Reference by brute force over all pairs: two spheres moving linearly over one step touch if
their closest approach in [0, dt] is under the sum of their radii (planes: the lowest point of
the sphere over the step reaches the plane). The broad phase may report more pairs (its bounds
are conservative), but never misses one of these and never reports a pair twice.
"""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import tumble

DT = 1.0 / 240.0


def _world(seed: int, n: int, speed: float, spread: float):
    rng = np.random.default_rng(seed)
    w = tumble.World(dt=DT)
    w.add_plane()
    x = rng.uniform(-spread, spread, (n, 3)) + (0.0, 0.0, spread + 0.2)
    x[: n // 4, 2] = rng.uniform(0.0, 0.15, n // 4)  # some near the ground
    r = rng.uniform(0.02, 0.08, n)
    r[0] = 0.5  # one big body, which tests every other body itself
    v = rng.normal(size=(n, 3)) * speed
    w.add_spheres(position=x, radius=r, mass=1.0, velocity=v)
    return w


def _pairs_found(w) -> list[tuple[int, int]]:
    bp = w.broadphase.find_pairs(w.bodies, w.dt)
    a = bp.pair_a.numpy()[: bp.pair_count]
    b = bp.pair_b.numpy()[: bp.pair_count]
    return [tuple(sorted(p)) for p in zip(a.tolist(), b.tolist())]


def _must_find(w) -> set[tuple[int, int]]:
    x, v, r = w.body_position, w.body_velocity, w.body_radius
    n = w.body_count
    need = set()
    for j in range(1, n):  # the ground plane (body 0): lowest point over the step
        if min(x[j, 2], x[j, 2] + v[j, 2] * DT) - r[j] < 0.0:
            need.add((0, j))
    for i, j in itertools.combinations(range(1, n), 2):
        d, u = x[j] - x[i], v[j] - v[i]
        t = np.clip(-np.dot(d, u) / max(np.dot(u, u), 1e-300), 0.0, DT)
        if np.linalg.norm(d + u * t) < r[i] + r[j]:
            need.add((i, j))
    return need


@settings(max_examples=12, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1), speed=st.sampled_from([0.0, 1.0, 20.0, 200.0]), spread=st.sampled_from([0.3, 1.0])
)
def test_finds_every_pair_that_can_touch_once(seed, speed, spread):
    w = _world(seed, 120, speed, spread)
    found = _pairs_found(w)
    assert len(found) == len(set(found)), "a pair was reported twice"
    missing = _must_find(w) - set(found)
    assert not missing, f"pairs that touch within the step were missed: {sorted(missing)[:5]}"


def test_far_apart_bodies_make_no_pairs():
    w = tumble.World(dt=DT)
    grid = np.stack(np.meshgrid(*[np.arange(8)] * 3, indexing="ij"), -1).reshape(-1, 3) * 1.0
    w.add_spheres(position=grid + 5.0, radius=0.1, mass=1.0)
    assert _pairs_found(w) == []


def test_pairs_grow_linearly_with_bodies():
    """Resting spheres on a lattice: about three pairs a body, whatever the count (not n^2)."""
    for side in (6, 12):
        w = tumble.World(dt=DT)
        g = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3) * 0.101
        w.add_spheres(position=g, radius=0.05, mass=1.0)
        pairs = len(_pairs_found(w))
        assert pairs == 3 * side * side * (side - 1)  # face neighbours only
