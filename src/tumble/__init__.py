"""Tumble: particles, rigid bodies and cloth, simulated with Warp kernels.

Public API::

    world = tumble.World(gravity=(0, 0, -9.81))
    world.add_plane()
    world.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    world.run(duration=1.0)

    world = tumble.load_scene("samples/sphere_pile.toml")
"""

import warp as _wp

_wp.config.log_level = _wp.LOG_WARNING  # no banner; the CLI says when kernels compile

# `tumble.wedge` is the function below; the names of its module import as usual (from tumble.wedge import ...)
from .cloth import ClothSystem, Wind
from .emitters import Emitter
from .errors import HandleError, SceneError, SimulationError, TumbleError
from .shapes import ShapeType
from .state import BodyId, BodyKind, ClothId
from .wedge import wedge
from .world import BodyState, World

__all__ = [
    "BodyId",
    "BodyKind",
    "BodyState",
    "ClothId",
    "ClothSystem",
    "Emitter",
    "HandleError",
    "SceneError",
    "ShapeType",
    "SimulationError",
    "TumbleError",
    "Wind",
    "World",
    "load_scene",
    "wedge",
]
__version__ = "0.1.0"


def load_scene(path, **overrides):
    """Build a `World` from a TOML scene file; see docs/scenes.md. Raises `SceneError` on bad input."""
    from .io.scene import load_scene as _load

    return _load(path, **overrides)
