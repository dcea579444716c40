"""cloth/collide.py: particles pushed out of bodies, the candidate bodies, self-collision between cloths."""

from __future__ import annotations

import math

import numpy as np
import pytest

import tumble
from tumble.cloth import collide


def make_world(**kwargs):
    return tumble.World(dt=1.0 / 240.0, substeps=4, **kwargs)


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
