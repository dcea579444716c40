"""cloth/collide.py: particles pushed out of bodies, the candidate bodies, self-collision between cloths."""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

import tumble
from tumble.cloth import attach, collide
from tumble.cloth.arrays import PARTICLE_FIELDS, Particles
from tumble.model import fields_of
from tumble.state import ArraySet
from tumble.structs import fill_struct


def make_world(**kwargs):
    return tumble.World(dt=1.0 / 240.0, substeps=4, **kwargs)


def particles(**columns) -> Particles:
    """Particles with the given arrays (`position=...`: `particle_position`), the rest zero, as the kernels take them."""
    n = len(next(iter(columns.values())))
    arrays = ArraySet(fields_of(PARTICLE_FIELDS), device="cpu", capacity=n).arrays
    for name, values in columns.items():
        arrays["particle_" + name].assign(np.asarray(values, dtype=arrays["particle_" + name].numpy().dtype))
    return fill_struct(Particles, arrays, "particle_")


def test_body_collision_pushes_particle_out_of_static_shapes():
    """Particles inside a plane, sphere or box end up at the thickness outside its surface."""
    world = make_world(gravity=(0, 0, 0))
    world.add_plane(offset=-1.0)
    world.add_sphere(position=(5.0, 0.0, 0.0), radius=0.5, static=True)
    world.add_box(
        position=(-5.0, 0.0, 0.0),
        half_extents=(0.5, 0.5, 0.5),
        static=True,
        orientation=(0.0, 0.0, math.sin(0.3), math.cos(0.3)),
    )
    world.add_cloth(size=(0.01, 0.01), resolution=(3, 1), thickness=0.05, max_stretch=None, stiffness=0.0, damping=0.0)
    cloth = world.cloth
    cloth.set_state(position=np.array([[0.0, 0.0, -1.02], [5.1, 0.1, 0.0], [-5.0, 0.0, 0.4]]))
    world.step()
    x = cloth.particle_position
    assert x[0, 2] == pytest.approx(-1.0 + 0.05)
    assert np.linalg.norm(x[1] - [5.0, 0.0, 0.0]) == pytest.approx(0.5 + 0.05)
    assert x[2, 2] == pytest.approx(0.5 + 0.05)


def test_candidate_bodies_skip_far_spheres():
    """Only bodies whose bounds can reach the cloth's box this step are tested."""
    world = make_world()
    world.add_plane()
    near = world.add_sphere(position=(0.0, 0.0, 0.3), radius=0.1)
    world.add_sphere(position=(50.0, 0.0, 0.3), radius=0.1)
    got = collide.candidate_bodies(world.bodies, np.array([-0.5, -0.5, 0.0]), np.array([0.5, 0.5, 0.5]), 0.01, world.dt)
    assert list(got) == [0, near.index]


def test_self_collision_separates_two_cloths():
    """Particles of two cloths closer than the thickness are pushed apart to it."""
    world = make_world(gravity=(0, 0, 0))
    for z in (0.0, 0.02):
        world.add_cloth(size=(0.2, 0.2), resolution=(3, 3), position=(0, 0, z), thickness=0.05)
    world.step()
    x = world.cloth.particle_position
    gap = x[9:, 2] - x[:9, 2]
    assert gap.min() >= 0.05 * 0.99


def _brute_force_pairs(x, inv_m, thickness, cloth, gi, gj, margin):
    """Every pair p < q within its mean thickness + margin, not grid neighbours (|di|, |dj| <= 2 in one
    cloth) and not two pins, found by checking all pairs."""
    found = set()
    for p in range(len(x)):
        for q in range(p + 1, len(x)):
            if cloth[p] == cloth[q] and abs(gi[p] - gi[q]) <= 2 and abs(gj[p] - gj[q]) <= 2:
                continue
            near = 0.5 * (thickness[p] + thickness[q]) + margin
            if np.sum((x[p] - x[q]) ** 2) < near * near and inv_m[p] + inv_m[q] > 0:
                found.add((p, q))
    return found


@pytest.mark.parametrize("seed", [0, 1])
def test_self_collision_pairs_equal_brute_force_and_the_buffer_grows(seed):
    """find_pairs lists exactly the brute-force pairs; from a buffer too small it keeps the first K and
    returns a larger buffer that holds the whole list on the next call."""
    rng = np.random.default_rng(seed)
    n = 400
    x = rng.uniform(0.0, 0.4, size=(n, 3))
    inv_m = np.where(rng.uniform(size=n) < 0.1, 0.0, 1.0)
    thickness = rng.uniform(0.01, 0.03, size=n)
    cloth = rng.integers(0, 2, size=n).astype(np.int32)
    gi, gj = rng.integers(0, 30, size=n).astype(np.int32), rng.integers(0, 30, size=n).astype(np.int32)
    margin = 0.01
    expected = _brute_force_pairs(x, inv_m, thickness, cloth, gi, gj, margin)
    assert len(expected) > 64  # more than the smallest buffer holds

    columns = {"position": x, "inv_mass": inv_m, "thickness": thickness, "cloth": cloth, "i": gi, "j": gj}
    args = (particles(**columns), float(thickness.max()), margin)
    finder = collide.SelfCollisionGrid("cpu")
    small = collide.pair_buffer(0, "cpu")
    grown, count = finder.find_pairs(small, *args)
    assert count == small.shape[0] == 64 and grown.shape[0] >= len(expected)
    assert {tuple(r) for r in grown.numpy()[:count]} <= expected  # the truncated list: true pairs
    again, count = finder.find_pairs(grown, *args)
    assert again is grown and count == len(expected)
    assert {tuple(r) for r in again.numpy()[:count]} == expected


def test_separate_pairs_pushes_a_listed_pair_to_its_thickness_by_inverse_mass():
    """Two particles 0.01 m apart with thickness 0.03: pushed to 0.03 apart, the light one three times as far."""
    x = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [5.0, 0.0, 0.0]])
    p = particles(position=x, inv_mass=[1.0, 3.0, 1.0], thickness=[0.03, 0.03, 0.03])
    pairs = wp.array([[0, 1], [0, 2]], dtype=wp.int32, device="cpu")
    collide.separate_pairs(p, pairs, 1)
    out = p.position.numpy()
    assert out[1, 0] - out[0, 0] == pytest.approx(0.03, abs=1e-15)
    assert -out[0, 0] == pytest.approx(0.005, abs=1e-15) and out[1, 0] - 0.01 == pytest.approx(0.015, abs=1e-15)
    assert np.array_equal(out[2], [5.0, 0.0, 0.0])  # past the count: not read


def test_shielded_bodies_are_the_pins_bodies_at_and_next_to_the_pins():
    """A 4 x 3 grid (rows of 4) with particle 5 pinned to body row 7 and particle 11 to body row 2: 5 and its
    four grid neighbours skip body 7, 11 and its two skip body 2, the rest touch everything (-1)."""
    nx, ny = 4, 3
    index = np.arange(nx * ny).reshape(ny, nx)
    springs = np.vstack([np.column_stack([index[:, :-1].ravel(), index[:, 1:].ravel()]),
                         np.column_stack([index[:-1, :].ravel(), index[1:, :].ravel()])])  # fmt: skip
    shield = attach.shielded_bodies(attach.pinned_rows(nx * ny, np.array([5, 11]), np.array([7, 2])), springs)
    expected = np.full(nx * ny, -1)
    expected[[5, 4, 6, 1, 9]] = 7
    expected[[11, 10, 7]] = 2
    assert shield.dtype == np.int32 and shield.tolist() == expected.tolist()
    no_pins = attach.pinned_rows(3, np.zeros(0, np.int32), np.zeros(0, np.int32))
    assert attach.shielded_bodies(no_pins, springs[:0]).tolist() == [-1] * 3
