"""Body rows renumbered along a space-filling curve (World._sort_bodies): ids and results must not notice.

Large worlds reorder their body rows now and then so that neighbours in space are neighbours in
memory. Here the threshold and interval are lowered so that small worlds reorder every few steps.
"""

from __future__ import annotations

import numpy as np
import pytest

import tumble
import tumble.world as world_module
from tolerances import resolution
from tumble.collision.hashgrid import spatial_order


@pytest.fixture
def sort_often(monkeypatch):
    monkeypatch.setattr(world_module, "SORT_MIN_BODIES", 2)
    monkeypatch.setattr(world_module, "SORT_INTERVAL", 3)


def _scattered_world(seed: int = 0) -> tuple[tumble.World, np.ndarray]:
    """Spheres far apart (no contacts), added in random order, with random velocities and spins."""
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(np.arange(6), np.arange(6), np.arange(6), indexing="ij"), -1).reshape(-1, 3)
    x = grid[rng.permutation(len(grid))] * 2.0 + rng.uniform(-0.1, 0.1, (len(grid), 3))
    w = tumble.World()
    w.add_spheres(
        position=x,
        radius=0.1,
        mass=rng.uniform(0.5, 2.0, len(x)),
        velocity=rng.normal(size=(len(x), 3)),
        angular_velocity=rng.normal(size=(len(x), 3)),
    )
    return w, x


def test_spatial_order_is_a_permutation_that_groups_neighbours():
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 10, (5000, 3))
    order = spatial_order(x, 0.5)
    assert sorted(order.tolist()) == list(range(len(x)))
    # consecutive points in the order are much closer than consecutive points in random order
    step = np.linalg.norm(np.diff(x[order], axis=0), axis=1)
    random_step = np.linalg.norm(np.diff(x, axis=0), axis=1)
    assert np.median(step) < 0.2 * np.median(random_step)


def test_free_bodies_move_the_same_with_and_without_reordering(sort_often, monkeypatch):
    """Rows change, ids do not: every view is in id order and bit-identical to an unsorted run."""
    sorted_world, _ = _scattered_world()
    sorted_world.run(0.1)
    assert not np.array_equal(sorted_world.body_rows, np.arange(sorted_world.body_count)), (
        "the world never reordered its rows"
    )

    monkeypatch.setattr(world_module, "SORT_MIN_BODIES", 10**9)
    plain_world, _ = _scattered_world()
    plain_world.run(0.1)
    np.testing.assert_array_equal(plain_world.body_rows, np.arange(plain_world.body_count))
    for name in ("body_position", "body_velocity", "body_orientation", "body_angular_velocity", "body_mass"):
        np.testing.assert_array_equal(getattr(sorted_world, name), getattr(plain_world, name), err_msg=name)
    assert sorted_world.state_hash() == plain_world.state_hash()


def test_apply_force_reaches_the_body_with_that_id(sort_often):
    w, _ = _scattered_world()
    w.gravity = np.zeros(3)
    w.run(0.05)
    body = 17
    before = w.body_velocity.copy()
    mass = w.body_mass[body]
    w.apply_force(body, (10.0, 0.0, 0.0))
    w.step()
    dv = w.body_velocity - before
    # the force is added in each of the step's substeps: an ulp or two of the velocity each
    atol = resolution(1e-12, np.abs(w.body_velocity[body]).max(), 2 * w.substeps)
    np.testing.assert_allclose(dv[body], (10.0 / mass * w.dt, 0.0, 0.0), rtol=1e-9, atol=atol)
    others = np.delete(dv, body, axis=0)
    assert np.abs(others).max() == 0.0


def test_new_bodies_get_the_next_ids_after_a_reorder(sort_often):
    w, _ = _scattered_world()
    w.run(0.05)
    n = w.body_count
    new = w.add_sphere(position=(50.0, 50.0, 50.0), radius=0.2, mass=1.0)
    assert int(new) == n
    np.testing.assert_array_equal(w.body_position[n], (50.0, 50.0, 50.0))
    assert w.body_radius[n] == 0.2
    w.run(0.05)  # and they survive the next reorder
    assert w.body_radius[n] == 0.2


def _pile(seed: int) -> tumble.World:
    rng = np.random.default_rng(seed)
    w = tumble.World()
    w.add_plane()
    for normal in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)):
        w.add_plane(normal=normal, offset=-0.3)
    grid = np.stack(np.meshgrid(np.arange(5), np.arange(5), np.arange(8), indexing="ij"), -1).reshape(-1, 3)
    x = (grid - (2, 2, 0)) * 0.11 + (0, 0, 0.1) + rng.uniform(-0.004, 0.004, (len(grid), 3))
    w.add_spheres(position=x[rng.permutation(len(x))], radius=0.05, mass=0.1)
    return w


def test_a_pile_settles_through_reorders_and_contacts_name_ids(sort_often):
    """Warm starts follow the renumbered rows: the pile comes to rest as it does without reordering."""
    w = _pile(3)
    w.run(2.0)
    assert not np.array_equal(w.body_rows, np.arange(w.body_count)), "the world never reordered its rows"
    assert w.kinetic_energy() < 1e-3
    x = w.body_position[5:]
    gaps = np.linalg.norm(x[:, None] - x[None], axis=-1) + np.eye(len(x))
    assert gaps.min() > 0.1 - 1e-3  # overlap under 1 mm
    # contact pairs are body ids: every sphere resting on the ground (id 0) appears with it
    pairs = w.contact_pair
    on_ground = 5 + np.nonzero(w.body_position[5:, 2] < 0.051)[0]  # spheres (ids 0-4 are the planes)
    ground_partners = set(pairs[pairs[:, 0] == 0, 1].tolist()) | set(pairs[pairs[:, 1] == 0, 0].tolist())
    assert len(on_ground) > 0 and set(on_ground.tolist()) <= ground_partners


def test_reordering_is_deterministic(sort_often):
    a, b = _pile(4), _pile(4)
    a.run(0.5)
    b.run(0.5)
    assert a.state_hash() == b.state_hash()


def test_cloth_catches_a_ball_through_reorders(sort_often):
    w = tumble.World()
    w.add_plane()
    w.add_cloth(size=(1.0, 1.0), resolution=(16, 16), position=(0.0, 0.0, 1.0), pins="corners")
    ball = w.add_sphere(position=(0.0, 0.0, 1.4), radius=0.1, mass=0.2)
    w.add_sphere(position=(-2.0, -2.0, 0.1), radius=0.1, mass=0.2)  # sorts before the others
    w.run(2.0)
    assert not np.array_equal(w.body_rows, np.arange(w.body_count)), "the world never reordered its rows"
    assert 0.5 < w.body_position[int(ball)][2] < 1.0  # in the sagging cloth, not on the ground
