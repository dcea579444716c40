"""Building a `World` from a checked `Scene`: every table's values passed to the World API.

Bodies are made in `schema.BODY_TABLES` order, each table in file order; then emitters, cloths
(with the bodies their pins follow), the wind and the joints. An error of the World API becomes
a `SceneError` naming the file and the table.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict, Unpack

import numpy as np

from ... import snapshot, validate
from ...errors import SceneError
from ...world import World
from ..meshfile import read_mesh_file
from .parse import Scene, parse_scene, parse_table, read_scene, table_label
from .schema import BODY_TABLES, SCHEMA

if TYPE_CHECKING:
    from ...state import BodyId

# ---------------------------------------------------------------------------------------- building


class WorldOverrides(TypedDict, total=False):
    """World settings that replace a scene file's [world] values (`load_scene`); None keeps the file's."""

    gravity: Sequence[float] | None
    dt: float | None
    substeps: int | None
    seed: int | None
    restitution_threshold: float | None
    device: str | None
    precision: str | None


WORLD_OVERRIDES = tuple(WorldOverrides.__annotations__)


def build_world(scene: Scene, **overrides: Unpack[WorldOverrides]) -> World:
    """Make a `World` from a validated `Scene`.

    Args:
        scene: from `parse_scene` / `read_scene`.
        **overrides: World settings replacing the file's [world] values
            (gravity, dt, substeps, seed, restitution_threshold, device, precision).

    Raises:
        SceneError: when the World API rejects a value (named by table).
    """
    unknown = set(overrides) - set(WORLD_OVERRIDES)
    if unknown:
        raise TypeError(f"unknown override(s) {', '.join(sorted(unknown))}; expected {', '.join(WORLD_OVERRIDES)}")
    path = scene.path
    settings = dict(scene.table("world") or parse_table(SCHEMA["world"], {}, path, None))
    settings.update({k: v for k, v in overrides.items() if v is not None})

    with _api_errors(path, "world"):
        world = World(**settings)
    world.metadata["path"] = path
    world.metadata["overrides"] = {k: v for k, v in overrides.items() if v is not None}
    world.metadata["scene"] = scene
    world.metadata["check"] = scene.table("check") or parse_table(SCHEMA["check"], {}, path, None)
    if (camera := scene.table("camera")) is not None:
        world.metadata["camera"] = dict(camera)

    # bodies: planes, spheres, boxes, capsules, convex bodies, meshes, each in file order
    made: dict[str, list[BodyId]] = {}
    for name, add in (
        ("plane", world.add_plane),
        ("sphere", world.add_sphere),
        ("box", world.add_box),
        ("capsule", world.add_capsule),
        ("convex", world.add_convex),
        ("mesh", world.add_mesh),
    ):
        made[name] = []
        for i, values in enumerate(scene.items(name)):
            values = dict(values)
            if values.get("file") is not None:
                values["file"] = _file_path(path, values["file"])
            if values.get("points") is not None:
                values["points"] = np.asarray(values["points"], dtype=np.float64)
            with _api_errors(path, table_label(name, i)):
                made[name].append(add(**_given(values)))
    for i, values in enumerate(scene.items("emitter")):
        values = dict(values)
        if values.get("file") is not None:
            values["file"] = _file_path(path, values["file"])
        if values.get("points") is not None:
            values["points"] = np.asarray(values["points"], dtype=np.float64)
        with _api_errors(path, table_label("emitter", i)):
            world.add_emitter(**_given(values))
    for i, values in enumerate(scene.items("cloth")):
        label = table_label("cloth", i)
        args = _given(values)
        pin_body = args.pop("pin_body", None)
        with _api_errors(path, label):
            cloth = world.cloth.cloths[world.add_cloth(**args)]
        if pin_body is not None:
            body = _named_body(made, pin_body, path, label, "pin_body")
            start = cloth.particle_start
            pinned = start + np.nonzero(world.cloth.particle_inv_mass[start : start + cloth.nx * cloth.ny] == 0.0)[0]
            with _api_errors(path, label):
                world.cloth.pin_to_body(pinned, body)
    if (wind := scene.table("wind")) is not None:
        with _api_errors(path, "wind"):
            world.set_wind(**wind)
    for i, values in enumerate(scene.items("joint")):
        _add_joint(world, made, values, path, table_label("joint", i))
    return world


def _named_body(made: dict, ref: str, path, label: str, key: str):
    """The BodyId of "box[2]" among the bodies the file made, or a SceneError at `key`."""
    name, index = _body_ref(ref, {name: len(ids) for name, ids in made.items()}, path, label, key)
    return made[name][index]


def _body_ref(ref: str, counts: dict[str, int], path, label: str, key: str) -> tuple[str, int]:
    """("box", 2) for "box[2]" when the file has `counts["box"]` > 2 boxes; else a SceneError at `key`."""
    if ref == "world":
        raise SceneError(
            "'world' is not a body here: leave pin_body out to pin in place", path=path, table=label, key=key
        )
    name, index = ref[:-1].split("[")
    if int(index) >= counts.get(name, 0):
        raise SceneError(
            f"no body {ref!r}: the file has {counts.get(name, 0)} [[{name}]]", path=path, table=label, key=key
        )
    return name, int(index)


def _file_path(scene_path, file: str) -> str:
    """A mesh file named in a scene: relative names are taken from the scene file's folder."""
    return file if scene_path is None else str(Path(scene_path).parent / Path(file).expanduser())


def validate_scene(path) -> Scene:
    """Check a scene file as far as can be done without building it; returns the validated `Scene`.

    Beyond `read_scene` (keys, values, limits): every body a joint or a cloth's `pin_body` names
    is in the file, every mesh file reads as a mesh, and every convex body's or convex emitter's
    points (or file's vertices) make a hull (a volume, few enough vertices), so `tumble check`
    passes no scene that `tumble run` refuses for these. What only the built world shows (bodies
    released on top of each other, say) is left to `build_world` and `check_world`.

    Raises:
        SceneError: naming the file, the table and the key.
    """
    scene = read_scene(path)
    counts = {name: len(scene.items(name)) for name in BODY_TABLES}
    for i, values in enumerate(scene.items("cloth")):
        if values.get("pin_body") is not None:
            _body_ref(values["pin_body"], counts, scene.path, table_label("cloth", i), "pin_body")
    for i, values in enumerate(scene.items("joint")):
        for key in ("body_a", "body_b"):
            if values[key] != "world":
                _body_ref(values[key], counts, scene.path, table_label("joint", i), key)
    for name in (*BODY_TABLES, "emitter"):
        for i, values in enumerate(scene.items(name)):
            vertices = None
            if values.get("file") is not None:
                try:
                    vertices = read_mesh_file(_file_path(scene.path, values["file"]))[0]
                except ValueError as exc:
                    raise SceneError(str(exc), path=scene.path, table=table_label(name, i), key="file") from None
            _check_hull(scene.path, name, i, values, vertices)
    return scene


def _check_hull(path, name: str, i: int, values: dict, vertices) -> None:
    """The hull that a [[convex]] or a convex [[emitter]] makes of its points or its file's `vertices` (read
    by the caller), made as `build_world` makes it (the convex body's at its scale, the emitter's at scale
    1), or a SceneError in its words."""
    from ...collision.hulls import hull_from_points

    shapes = values.get("shape") or ()
    convex = name == "convex" or (name == "emitter" and "convex" in ([shapes] if isinstance(shapes, str) else shapes))
    points, file = values.get("points"), values.get("file")
    if not convex or (points is None) == (file is None):
        return  # not a hull, or one that the World API refuses for its arguments when the scene is built
    # named as `meshfile.hull_points` names them, for the World API's words
    p, label = (points, "points") if file is None else (vertices, str(_file_path(path, file)))
    try:
        scale = values.get("scale")
        factor = validate.scale(1.0 if scale is None else scale) if name == "convex" else 1.0
        hull_from_points(np.asarray(p, dtype=np.float64) * factor, name=label)
    except ValueError as exc:
        raise SceneError(str(exc), path=path, table=table_label(name, i)) from None


def _add_joint(world, made: dict, values: dict, path, label: str) -> None:
    """One [[joint]]: body names to ids (checked against the file's bodies), hinge degrees to radians."""
    from ...solver.joints import JointArgumentError

    args = _given(values)
    ends: list[BodyId | None] = []
    for key in ("body_a", "body_b"):
        ref = args.pop(key)
        if ref == "world":
            ends.append(None)
            continue
        ends.append(_named_body(made, ref, path, label, key))
    if args["kind"] == "hinge":
        for key in ("lower", "upper", "motor_speed"):
            if key in args:
                args[key] = math.radians(args[key])
    try:
        world.add_joint(args.pop("kind"), *ends, **args)
    except JointArgumentError as exc:
        raise SceneError(exc.reason, path=path, table=label, key=exc.key) from None


def load_scene(path: str | os.PathLike[str], **overrides: Unpack[WorldOverrides]) -> World:
    """Read, validate and build a scene file into a `World` (see docs/scenes.md).

    Args:
        path: the .toml file, or the name of a bundled sample ("sphere_pile").
        **overrides: World settings replacing the file's [world] values, e.g. seed=3, device="cuda".
    """
    return build_world(read_scene(path), **overrides)


def load_snapshot(path: str | os.PathLike[str], **overrides: Unpack[WorldOverrides]) -> World:
    """Rebuild the world a snapshot file was taken from (it must come from a scene) and restore it.

    Keyword overrides are those of `load_scene` (e.g. device) and replace the saved ones. Lives
    here, above `World`, so that `tumble.snapshot` (which World imports) never imports the scene
    loader.
    """
    snap = snapshot.read(path)
    if snap.scene is None:
        raise snapshot.SnapshotError(
            f"{path}: this snapshot was taken from a world built in Python, not from a scene file; "
            "build the same world and call world.restore(tumble.snapshot.read(path))"
        )
    world = build_world(
        parse_scene(snap.scene, snap.scene_path), **{"precision": snap.precision, **snap.overrides, **overrides}
    )
    world.restore(snap)
    return world


def _given(values: dict) -> dict:
    """Keyword arguments for the World API: keys left to the engine (None) are not passed."""
    return {
        k: (tuple(v) if isinstance(v, list) and all(validate.is_real(x) for x in v) else v)
        for k, v in values.items()
        if v is not None
    }


class _api_errors:
    """Turn a ValueError/TypeError from the World API into a SceneError naming file and table."""

    def __init__(self, path, table: str):
        self.path, self.table = path, table

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if exc is not None and isinstance(exc, (ValueError, TypeError)) and not isinstance(exc, SceneError):
            raise SceneError(str(exc), path=self.path, table=self.table) from exc
        return False
