"""Fixtures for the renderer tests: one headless GL context (EGL, Mesa llvmpipe) per session."""

from __future__ import annotations

import numpy as np
import pytest

import tumble
from tumble.render import Renderer, create_context


@pytest.fixture(scope="session")
def gl_context():
    """A headless moderngl context shared by the session's tests."""
    return create_context()


@pytest.fixture(scope="session")
def renderer(gl_context):
    """A small renderer (160 x 120); tests resize it as they need."""
    r = Renderer(gl_context, 160, 120)
    yield r
    r.release()


@pytest.fixture
def small_renderer(renderer):
    """The session renderer reset to 160 x 120 with default settings."""
    renderer.resize(160, 120)
    renderer.shadows = True
    renderer.ground_cell_size = 1.0
    return renderer


class GridCloth:
    """Stand-in for a ClothSystem: a bent nx x ny grid with the views the renderer reads."""

    def __init__(self, nx: int = 12, ny: int = 10, *, centre=(0.0, 0.0, 0.8), size=1.2):
        x, y = np.meshgrid(np.linspace(-0.5, 0.5, nx) * size, np.linspace(-0.5, 0.5, ny) * size)
        z = 0.15 * np.sin(3.0 * x) * np.cos(2.0 * y)
        self.particle_position = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1) + np.asarray(centre)
        idx = np.arange(nx * ny).reshape(ny, nx)
        a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
        self.triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int32)
        self.particle_count = nx * ny


class WorldWithCloth(tumble.World):
    """A World whose cloth is a stand-in (`GridCloth`): the renderer reads only `has_cloth` and `cloth`."""

    def __init__(self, cloth, **settings):
        super().__init__(**settings)
        self.stand_in = cloth

    @property
    def has_cloth(self) -> bool:
        return True

    @property
    def cloth(self):
        return self.stand_in


@pytest.fixture
def cloth_world():
    """Factory of `WorldWithCloth`: cloth_world(make_cloth(...)) is an empty World showing that cloth."""
    return WorldWithCloth


def falling_world(n: int = 3) -> tumble.World:
    """A ground plane and `n` spheres side by side, dropped from different heights."""
    world = tumble.World(dt=1.0 / 120.0)
    world.add_plane()
    for i in range(n):
        world.add_sphere(position=(0.4 * (i - (n - 1) / 2), 0.0, 0.6 + 0.2 * i), radius=0.12, mass=1.0)
    return world


@pytest.fixture
def make_falling_world():
    """Factory of `falling_world` scenes."""
    return falling_world


@pytest.fixture
def make_cloth():
    """Factory of `GridCloth` stand-ins."""
    return GridCloth


def chroma(rgb) -> np.ndarray:
    """Chromaticity r, g, b / (r + g + b): colour without brightness, so shading does not change it."""
    c = np.asarray(rgb, dtype=np.float64).reshape(-1, 3)
    return c / np.maximum(c.sum(axis=1, keepdims=True), 1e-9)


@pytest.fixture
def chromaticity():
    return chroma
