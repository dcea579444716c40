"""Mass-spring cloth: grid builder, springs, Provot stretch limit, wind, collisions.

`World.cloth` is the world's `ClothSystem`; `World.add_cloth` and `World.set_wind` forward to it.
"""

from .system import Cloth, ClothSystem
from .wind import Wind

__all__ = ["Cloth", "ClothSystem", "Wind"]
