"""io/scene/schema.py: every table's keys, defaults and the defaults shared with the World API."""

from __future__ import annotations

import inspect
import math
import typing

import pytest

import tumble
from tumble.cloth.system import ClothSystem
from tumble.io.scene import schema
from tumble.keywords import defaults_of


@pytest.mark.parametrize("name", list(schema.SCHEMA))
def test_every_default_passes_its_own_check(name):
    """Give each key a default its own check accepts unchanged (or REQUIRED, or None for the engine's)."""
    for key, f in schema.SCHEMA[name].fields.items():
        if f.default is schema.REQUIRED or f.default is None:
            continue
        assert f.check(f.default) == f.default, f"{name}.{key}"


#: the World API call each table's keys are passed to
API = {
    "world": tumble.World.__init__,
    "plane": tumble.World.add_plane,
    "sphere": tumble.World.add_sphere,
    "box": tumble.World.add_box,
    "capsule": tumble.World.add_capsule,
    "convex": tumble.World.add_convex,
    "mesh": tumble.World.add_mesh,
    "emitter": tumble.World.add_emitter,
    "cloth": ClothSystem.add_cloth,
    "wind": ClothSystem.set_wind,
    "joint": tumble.World.add_joint,
}


def api_defaults(function) -> dict[str, object]:
    """The defaults of the keywords `function` takes: its own parameters', and those of the keyword set
    (a TypedDict) it takes as `**options: Unpack[...]`, found from the annotation."""
    out = {}
    for name, p in inspect.signature(function).parameters.items():
        if p.kind is p.VAR_KEYWORD:
            (options,) = typing.get_args(typing.get_type_hints(function)[name])
            out |= defaults_of(options)
        else:
            out[name] = p.default
    return out


def test_the_solid_adders_defaults_come_from_their_keyword_set():
    """add_sphere's mass, velocity, ... defaults are SolidOptions' (what the scene tables are checked against)."""
    d = api_defaults(tumble.World.add_sphere)
    assert d["velocity"] == (0.0, 0.0, 0.0) and d["restitution"] == 0.5 and d["kinematic"] is False
    assert d["radius"] is inspect.Parameter.empty


@pytest.mark.parametrize("name", list(API))
def test_defaults_are_the_api_defaults(name):
    """Give each key the default of the API keyword it is passed to, so that the file and the API cannot drift.

    A key the file requires, or leaves to the engine (None), shows the API's default in the reference instead.
    """
    parameters = api_defaults(API[name])
    shared = 0
    for key, f in schema.SCHEMA[name].fields.items():
        api = parameters.get(key, inspect.Parameter.empty)
        if api is inspect.Parameter.empty or f.default is schema.REQUIRED:
            continue
        api = [float(v) for v in api] if isinstance(api, tuple) else api
        if f.default is None:
            if isinstance(api, (int, float)) and math.isfinite(api) and f.shown_default not in (None, "none"):
                assert f.shown_default == (str(api).lower() if isinstance(api, bool) else f"{api:g}"), key
            continue
        assert f.default == api and type(f.default) is type(api), key
        shared += 1
    assert shared >= 1


def test_reference_shows_the_api_defaults_of_keys_left_to_the_engine():
    """Show the API's defaults for the cloth's springs, the density and the camera's field of view."""
    from tumble.render.camera import DEFAULT_FOV
    from tumble.shapes import DEFAULT_DENSITY

    assert schema.SCHEMA["sphere"].fields["density"].shown_default == f"{DEFAULT_DENSITY:g}"
    assert schema.SCHEMA["emitter"].fields["density"].shown_default == f"{DEFAULT_DENSITY:g}"
    assert schema.SCHEMA["camera"].fields["fov"].default == DEFAULT_FOV
    assert schema.SCHEMA["cloth"].fields["stiffness"].shown_default.startswith("{ structural = ")


def test_body_tables_are_tables_and_body_ref_names_them():
    """Accept "box[2]" and "world" as body references, and nothing that is not a body table."""
    assert set(schema.BODY_TABLES) <= set(schema.SCHEMA)
    check = schema.body_ref()
    assert check("box[2]") == "box[2]" and check("world") == "world"
    for bad in ("emitter[0]", "box[x]", "box", 3):
        with pytest.raises(schema.Bad):
            check(bad)
