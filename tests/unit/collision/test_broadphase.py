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
    # the reference in float64 whatever the world's precision
    x, v, r = (np.asarray(a, np.float64) for a in (w.body_position, w.body_velocity, w.body_radius))
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


def _searched(w) -> bool:
    """Whether the last step searched the grid (a step that kept its list leaves the table empty)."""
    return int(w.broadphase.grid.cell_count.numpy().sum()) > 0


def _pouring_world():
    """Spheres and boxes falling into a walled box, a kinematic paddle sweeping through them."""
    rng = np.random.default_rng(7)
    w = tumble.World(dt=DT)
    w.add_plane()
    for normal in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)):
        w.add_plane(normal=normal, offset=-0.4)
    g = np.stack(np.meshgrid(np.arange(5), np.arange(5), np.arange(4), indexing="ij"), -1).reshape(-1, 3)
    x = (g - (2, 2, 0)) * 0.13 + (0.0, 0.0, 0.08) + rng.uniform(-0.01, 0.01, g.shape)
    w.add_spheres(position=x[::2], radius=0.05, mass=0.1, velocity=rng.normal(size=(len(x[::2]), 3)))
    w.add_boxes(position=x[1::2], half_extents=(0.04, 0.04, 0.04), mass=0.1)
    paddle = w.add_box(position=(-0.3, 0.0, 0.1), half_extents=(0.02, 0.3, 0.1), mass=1.0, kinematic=True)
    w.set_body_state(paddle, velocity=(0.5, 0.0, 0.0))
    return w


def test_a_kept_list_gives_the_pairs_and_the_run_a_fresh_search_gives():
    """The broad phase keeps its fat list while every body stays within its slack; the pairs kept from it
    each step must be exactly those (in the same order) that a search of that step's state alone gives,
    so that the run is bit for bit the same as one that searches the grid at every step."""
    kept, fresh = _pouring_world(), _pouring_world()
    kept_steps = 0
    for step in range(300):
        fresh.broadphase.rows_changed()  # search again, whatever the bodies did
        kept.step()
        fresh.step()
        kept_steps += not _searched(kept)
        assert _searched(fresh)
        a, b = kept.broadphase, fresh.broadphase
        assert a.pair_count == b.pair_count, f"step {step}"
        np.testing.assert_array_equal(a.pair_a.numpy()[: a.pair_count], b.pair_a.numpy()[: b.pair_count])
        np.testing.assert_array_equal(a.pair_b.numpy()[: a.pair_count], b.pair_b.numpy()[: b.pair_count])
    assert kept.state_hash() == fresh.state_hash()
    assert kept_steps > 150  # (else this test would not test the kept list) the settling pile keeps it


def test_a_body_moved_by_hand_or_a_moved_plane_finds_its_pairs_at_once():
    """Setting a body's place, or moving a plane, between steps: the kept list is searched again."""
    w = tumble.World(dt=DT, gravity=(0.0, 0.0, 0.0))
    plane = w.add_plane()
    a, b = w.add_spheres(position=[(0.0, 0.0, 1.0), (2.0, 0.0, 1.0)], radius=0.1, mass=1.0)
    for _ in range(3):
        w.step()
    assert w.broadphase.pair_count == 0 and not _searched(w)
    w.set_body_state(b, position=(0.15, 0.0, 1.0))  # now overlapping a
    w.step()
    assert _pairs_found(w) == [(int(a), int(b))] and w.contact_count == 1
    w.set_body_state(plane, position=(0.0, 0.0, 0.95))  # the floor rises into both
    w.step()
    assert sorted(_pairs_found(w)) == [(0, int(a)), (0, int(b)), (int(a), int(b))]
