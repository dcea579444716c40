"""io/scene/schema.py: every table's keys, defaults and the defaults shared with the World API."""

from __future__ import annotations

import inspect

import pytest

import tumble
from tumble.cloth.system import ClothSystem
from tumble.io.scene import schema


@pytest.mark.parametrize("name", list(schema.SCHEMA))
def test_every_default_passes_its_own_check(name):
    """Give each key a default its own check accepts unchanged (or REQUIRED, or None for the engine's)."""
    for key, f in schema.SCHEMA[name].fields.items():
        if f.default is schema.REQUIRED or f.default is None:
            continue
        assert f.check(f.default) == f.default, f"{name}.{key}"


def test_cloth_and_wind_defaults_are_the_api_defaults():
    """Read the cloth's and the wind's defaults from the World API, so that the two cannot drift apart."""
    cloth, wind = schema.SCHEMA["cloth"].fields, schema.SCHEMA["wind"].fields
    add = inspect.signature(ClothSystem.add_cloth).parameters
    assert cloth["max_stretch"].default == add["max_stretch"].default
    assert cloth["thickness"].shown_default == f"{add['thickness'].default:g}"
    for key, parameter in inspect.signature(ClothSystem.set_wind).parameters.items():
        if key in wind:
            default = parameter.default
            assert wind[key].default == (list(default) if isinstance(default, tuple) else default), key


def test_world_defaults_are_the_world_defaults():
    """Give [world] the defaults a World made without arguments has."""
    world, fields = tumble.World(), schema.SCHEMA["world"].fields
    assert list(world.gravity) == fields["gravity"].default
    assert world.dt == fields["dt"].default and world.substeps == fields["substeps"].default


def test_body_tables_are_tables_and_body_ref_names_them():
    """Accept "box[2]" and "world" as body references, and nothing that is not a body table."""
    assert set(schema.BODY_TABLES) <= set(schema.SCHEMA)
    check = schema.body_ref()
    assert check("box[2]") == "box[2]" and check("world") == "world"
    for bad in ("emitter[0]", "box[x]", "box", 3):
        with pytest.raises(schema.Bad):
            check(bad)
