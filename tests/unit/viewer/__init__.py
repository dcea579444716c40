"""Unit tests of tumble.viewer, one file per module."""

import tumble


def make_cloth_world():
    """A 12 x 12 cloth hanging from two corners in a light wind."""
    world = tumble.World(dt=1.0 / 240.0, substeps=2)
    world.add_plane()
    world.add_cloth(size=(1.0, 1.0), resolution=(12, 12), position=(0.0, 0.0, 1.0), mass=0.2, pins="top-corners")
    world.set_wind(velocity=(1.0, 0.0, 0.0), turbulence=0.5, scale=0.5, seed=1, drag=1.0, lift=0.2)
    return world
