"""io/scene/build.py: building the World from a scene's values, overrides."""

from __future__ import annotations

import math

import numpy as np
import pytest

import tumble
from tolerances import stored

from . import BALL


def test_load_scene_builds_the_world(write_scene):
    """Build planes and spheres with the file's values and keep path and camera in metadata."""
    path = write_scene(
        "[world]\ngravity = [0, 0, -1.62]\ndt = 0.01\nsubsteps = 2\nseed = 5\n"
        + BALL
        + "\n[[box]]\nposition = [1, 0, 1]\nhalf_extents = [0.1, 0.2, 0.3]\ndensity = 500\nstatic = true\n"
        "[camera]\nfov = 60\n"
    )
    world = tumble.load_scene(path)
    assert world.body_count == 3
    np.testing.assert_array_equal(world.gravity, [0.0, 0.0, -1.62])
    assert world.dt == 0.01 and world.substeps == 2 and world.seed == 5
    assert list(world.body_shape) == [tumble.ShapeType.PLANE, tumble.ShapeType.SPHERE, tumble.ShapeType.BOX]
    assert world.body_mass[1] == 1.0
    assert world.body_inv_mass[2] == 0.0  # static box
    np.testing.assert_array_equal(world.body_half_extents[2], stored([0.1, 0.2, 0.3]))  # as the world holds them
    assert world.metadata["path"] == str(path)
    assert world.metadata["camera"] == {"position": [3.0, -3.0, 2.0], "target": [0.0, 0.0, 0.5], "fov": 60.0}


def test_overrides_replace_world_settings(write_scene):
    """Let load_scene keywords (as the CLI's --seed) replace [world] values."""
    world = tumble.load_scene(write_scene("[world]\nseed = 5\n" + BALL), seed=9, dt=0.002)
    assert world.seed == 9 and world.dt == 0.002
    with pytest.raises(TypeError, match="unknown override"):
        tumble.load_scene(write_scene(BALL), colour="red")


def test_plane_offset_follows_the_normal(write_scene):
    """Place a plane so that dot(normal, x) = offset, with the normal normalised."""
    world = tumble.load_scene(write_scene("[[plane]]\nnormal = [0, 0, 2]\noffset = 0.5\n"))
    np.testing.assert_allclose(world.body_plane_normal[0], [0.0, 0.0, 1.0])
    assert math.isclose(float(world.body_position[0] @ world.body_plane_normal[0]), 0.5)
