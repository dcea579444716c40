"""cloth/wind.py: the wind arguments, the air force on triangles and the seeded turbulent field."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import tumble
from tumble.cloth import Wind
from tumble.cloth.arrays import PARTICLE_FIELDS, Particles
from tumble.cloth.wind import accumulate_air_forces
from tumble.model import fields_of
from tumble.state import ArraySet
from tumble.structs import fill_struct


def make_world(**kwargs):
    return tumble.World(dt=1.0 / 240.0, substeps=4, **kwargs)


def test_bad_wind_arguments_raise_value_error():
    """Bad wind arguments raise ValueError."""
    world = make_world()
    with pytest.raises(ValueError):
        world.set_wind(scale=0.0)
    with pytest.raises(ValueError):
        world.set_wind(velocity=(1.0, 2.0))
    with pytest.raises(ValueError):
        world.set_wind(turbulence=-1.0)


def test_air_force_face_on_and_edge_on():
    """Drag on a face-on triangle is 1/2 rho Cd A u^2 along the normal; edge-on it is zero."""
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    tris = wp.array(np.array([[0, 1, 2]], dtype=np.int32), dtype=wp.int32)
    arrays = ArraySet(fields_of(PARTICLE_FIELDS), device="cpu", capacity=3).arrays  # at rest
    arrays["particle_position"].assign(pts)
    particles = fill_struct(Particles, arrays, "particle_")
    for wind, expected in (((0.0, 0.0, 2.0), 0.5 * 1.2 * 1.0 * 0.5 * 4.0), ((2.0, 1.0, 0.0), 0.0)):
        arrays["particle_wind"].assign(np.tile(wind, (3, 1)))
        arrays["particle_force"].zero_()
        accumulate_air_forces(particles, tris, 1.0, 0.0, 1.2)
        total = arrays["particle_force"].numpy().sum(axis=0)
        assert total == pytest.approx([0.0, 0.0, expected], abs=1e-12)


def test_wind_field_seeded_smooth_and_time_varying():
    """Turbulence is reproducible per seed, smooth in space, varies in time, with RMS = strength."""
    wind = Wind(velocity=(1.0, 0.0, 0.0), turbulence=2.0, scale=0.5, seed=4, modes=64)
    rng = np.random.default_rng(0)
    pts = rng.uniform(-20, 20, size=(20000, 3))
    u = wind.sample(pts, 0.0)
    assert np.array_equal(
        u, Wind(velocity=(1.0, 0.0, 0.0), turbulence=2.0, scale=0.5, seed=4, modes=64).sample(pts, 0.0)
    )
    assert not np.allclose(
        u, Wind(velocity=(1.0, 0.0, 0.0), turbulence=2.0, scale=0.5, seed=5, modes=64).sample(pts, 0.0)
    )
    # mean = U, RMS per component = turbulence (to sampling error)
    assert u.mean(axis=0) == pytest.approx([1.0, 0.0, 0.0], abs=0.1)
    assert (u - [1.0, 0.0, 0.0]).std(axis=0) == pytest.approx([2.0, 2.0, 2.0], rel=0.1)
    # smooth: Lipschitz, |u(x + d) - u(x)| <= sum_k |a_k| |kappa_k| |d|; 1 s later the field has moved on
    wave, amplitude, _, _ = wind.mode_arrays()
    lipschitz = float(np.sum(np.linalg.norm(amplitude, axis=1) * np.linalg.norm(wave, axis=1)))
    step = np.full(3, 1e-3)
    near = wind.sample(pts[:100] + step, 0.0)
    assert np.linalg.norm(near - u[:100], axis=1).max() <= lipschitz * np.linalg.norm(step)
    later = wind.sample(pts[:100], 1.0)
    assert np.abs(later - u[:100]).max() > 0.5
