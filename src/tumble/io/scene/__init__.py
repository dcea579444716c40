"""Scene files: TOML -> validated tables -> `World`.

A scene file is a TOML document with the tables described in docs/scenes.md::

    [world]
    gravity = [0, 0, -9.81]

    [[plane]]
    normal = [0, 0, 1]

    [[sphere]]
    position = [0, 0, 1]
    radius = 0.1
    mass = 1.0

The schema is data (`SCHEMA`: one `TableSpec` per table, one `Field` per key), so the
validator, the defaults and the reference tables in docs/scenes.md (`reference_markdown()`)
come from one place. Every problem raises `SceneError` naming the file, the table (e.g.
`sphere[2]` for the third `[[sphere]]`) and the key.

Loading is two steps: `parse_scene(text)` checks everything and returns a `Scene` of plain
Python values (no Warp, no World); `build_world(scene)` passes those values to the World API.
`load_scene(path)` does both.

One module per job, each importing only from those before it:

- `checks`: the rule framework: value checks (`Check`), cross-key rules, the error `Bad`;
- `schema`: the tables, their keys and defaults (`SCHEMA`);
- `parse`: TOML text -> checked values (`Scene`), and the limits a scene may ask for;
- `build`: checked values -> `World`;
- `verify`: a stepped world against the `[check]` table (`check_world`);
- `docs`: the scene reference of docs/scenes.md (`reference_markdown`).
"""

from __future__ import annotations

from . import checks  # the value checks (`checks.vector`, ...) and cross-key rules
from .build import WORLD_OVERRIDES, WorldOverrides, build_world, load_scene, load_snapshot, validate_scene
from .checks import PIN_NAMES, SPRING_KINDS, Bad, Check, KeyBad
from .docs import reference_markdown
from .parse import (
    SAMPLES_DIR,
    Scene,
    check_limits,
    copy_default,
    list_samples,
    parse_scene,
    read_scene,
    resolve_scene_path,
)
from .schema import BODY_TABLES, JOINT_KINDS, REQUIRED, SCHEMA, Field, TableSpec, body_ref
from .verify import check_world

__all__ = [
    "BODY_TABLES",
    "JOINT_KINDS",
    "PIN_NAMES",
    "REQUIRED",
    "SAMPLES_DIR",
    "SCHEMA",
    "SPRING_KINDS",
    "WORLD_OVERRIDES",
    "Bad",
    "Check",
    "Field",
    "KeyBad",
    "Scene",
    "TableSpec",
    "WorldOverrides",
    "body_ref",
    "build_world",
    "check_limits",
    "check_world",
    "checks",
    "copy_default",
    "list_samples",
    "load_scene",
    "load_snapshot",
    "parse_scene",
    "read_scene",
    "reference_markdown",
    "resolve_scene_path",
    "validate_scene",
]
