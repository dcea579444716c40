"""Snapshots: the whole simulation state of a world, to restore in place or save and resume later.

A snapshot holds everything a step reads and later steps depend on: body rows (bodies emitted
since the start included), the contact and joint rows with their warm-start impulses, the cloth
particles and its collision lists, the emitters' counters and random generators, the world's
clock and random generator. Restoring it and stepping gives the same trajectory, bit for bit,
as the run it was taken from, in the same process or in a new one.

What is not in it: recorded kernel launches and other caches (rebuilt on demand), Warp BVHs of
static meshes (built from the scene), and `world.metadata`.

The state is found by walking the world's attributes: Warp and NumPy arrays, `ArraySet`s, random
generators and plain values, inside every object of Tumble's own classes that the world holds.
So a new stage's arrays are in snapshots without being listed here. A value of a type the walk
does not know is an error (`SnapshotError`), never silently left out.

File format (`.npz`): one array per state array under its path ("state/bodies/body_position", ...)
and a JSON manifest under "manifest" with the plain values, the format version and, for a world
built from a scene file, the scene's text, so that `tumble.load_snapshot` (`io.scene.load_snapshot`) can rebuild the world first.
"""

from __future__ import annotations

import enum
import hashlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import warp as wp

from .errors import TumbleError

if TYPE_CHECKING:
    from .world import World
from .launch import LaunchCache
from .limits import LimitError
from .precision import PRECISIONS
from .state import ArraySet, Handle, RowGroup

FORMAT = 10  # 2: the body rows saved by part (model, state, control); 3: the joint and cloth rows too;
# 4: the joints' geometric load is a body state array; 5: the cloth self-collision pairs are cloth state;
# 6: the world's precision (a format 5 file is float64); 7: the contact solver's per-step quantities are
# scratch rows (`ContactSet.rows`), no longer contact arrays (`_upgrade_contacts` reads formats 5 and 6);
# 8: the hinges' angle counting whole turns is joint state (`_upgrade_joints` reads formats 5 to 7);
# 9: the broad phase's grid is a cache (its last search: `_upgrade_broadphase` reads formats 5 to 8);
# 10: the cloth's substeps of the last step are cloth state (`_upgrade_cloth` reads formats 5 to 9)
# formats read, and the precision of those that did not save one
_READS = {5: "float64", 6: None, 7: None, 8: None, 9: None, 10: None}

# World attributes that are not simulation state: identity, bookkeeping of the user's session,
# diagnostics, the Warp device (a snapshot can be restored on another device of the same world),
# and the stages' table of the body rows, whose sets the model, state and control parts hold
# (the solver's scratch rows are reset every step)
# and the precision (saved as `Snapshot.precision`) with its kernel modules, and the views of the
# state that the step's finiteness check keeps
_WORLD_SKIP = frozenset(
    {
        "_key",
        "metadata",
        "profile",
        "_lap",
        "device",
        "_launch_sizes",
        "bodies",
        "_precision",
        "_k",
        "_finite_held",
        "_issued_generation",  # the world's own history of handles: a restore must not lower it
    }
)


# what a stage keeps of the world it belongs to (`World.key`, which handles carry): the identity of the
# world that holds it, as the world's own `_key`, never state; a restore into another world keeps its own
_IDENTITY = frozenset({"world_key"})

# the World's parts (tumble.model), walked first in this order
_PARTS = {"model": 0, "state": 1, "control": 2}

# what `ArraySet` itself keeps beside its arrays (captured through its markers)
_ARRAYSET_OWN = frozenset({"fields", "numpy_types", "arrays", "count", "capacity", "device"})
# what a `RowGroup` keeps: its sets are saved where the world's parts (model, state, control) hold
# them; the rest (the solver's scratch sets) is grown back to their rows by `RowGroup.sync`
_ROWGROUP_OWN = frozenset({"parts", "arrays", "fields", "_part", "device"})


class SnapshotError(TumbleError):
    """A snapshot that cannot be taken, written, read or restored into this world."""


@dataclass
class Snapshot:
    """The state of a world at one moment; `World.snapshot()` makes one, `World.restore` puts it back.

    Two snapshots compare equal when every value and array is identical (caches are not compared).

    Attributes:
        arrays: path -> NumPy array of every state array.
        values: path -> plain value (numbers, strings, generator states, ...).
        step_count: the world's step count when it was taken.
        time: the world's simulated time [s] when it was taken.
        scene: the scene file's text, when the world was built from one.
        scene_path: that file's path (meshes and other files named in it are found beside it).
        overrides: keyword overrides the scene was loaded with (seed, device, ...).
        precision: the world's precision, "float32" or "float64"; it restores only into a world of it.
    """

    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    values: dict[str, Any] = field(default_factory=dict)  # what each value is depends on its path
    step_count: int = 0
    time: float = 0.0
    scene: str | None = None
    scene_path: str | None = None
    overrides: dict = field(default_factory=dict)
    precision: str = "float64"

    def __eq__(self, other) -> bool:
        if not isinstance(other, Snapshot):
            return NotImplemented
        return not self.differences(other)

    def differences(self, other: Snapshot) -> list[str]:
        """Paths whose value differs between two snapshots (empty when equal); caches are not compared."""
        derived = {p.rpartition("/:")[0] for p in self.values.keys() | other.values.keys() if p.endswith("/:derived")}
        out = sorted(
            k
            for k in self.values.keys() | other.values.keys()
            if self.values.get(k, _MISSING) != other.values.get(k, _MISSING)
            and k.rpartition("/:")[0] not in derived
            and k not in derived
        )
        out += sorted(
            k
            for k in self.arrays.keys() | other.arrays.keys()
            if k not in self.arrays or k not in other.arrays or not _same_array(self.arrays[k], other.arrays[k])
        )
        return out

    def copy(self) -> Snapshot:
        """A deep copy (arrays copied), so that restoring one snapshot twice is safe."""
        return Snapshot(
            {k: a.copy() for k, a in self.arrays.items()},
            json.loads(json.dumps(self.values)),
            self.step_count,
            self.time,
            self.scene,
            self.scene_path,
            dict(self.overrides),
            self.precision,
        )


_MISSING = object()


def _same_array(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


# --- taking a snapshot -------------------------------------------------------------------------
# Paths name attributes ("state/cloth/body_contacts"), list items ("emitters/0") and dict entries; a
# segment starting with ":" is a marker of the walk itself (":class", ":dtype", ...), never a name.


def take(world: World, *, arrays: bool = True) -> Snapshot:
    """Capture `world`'s state (see `World.snapshot`); with `arrays=False` only its layout (no array is copied)."""
    snap = Snapshot(step_count=world.step_count, time=world.time, precision=world.precision)
    seen: set[int] = {id(world)}
    for name, value in _world_order(world):
        if name not in _WORLD_SKIP:
            _capture(value, name, snap, seen, arrays)
    scene = world.metadata.get("scene")
    if scene is not None and getattr(scene, "text", None) is not None:
        snap.scene = scene.text
        snap.scene_path = None if scene.path is None else str(Path(scene.path).resolve())
        snap.overrides = dict(world.metadata.get("overrides", {}))
    return snap


def _world_order(world) -> list[tuple[str, Any]]:
    """The world's attributes in the walk's order: its parts first, so that what the stages share with
    them is saved under the part ("state/cloth/particles/..."), then the rest by name."""
    return sorted(vars(world).items(), key=lambda item: (_PARTS.get(item[0], len(_PARTS)), item[0]))


def _capture(value, path: str, snap: Snapshot, seen: set[int], arrays: bool) -> None:
    if _is_plain(value):
        snap.values[path] = _plain(value)
    elif _is_derived(value):
        snap.values[path + "/:derived"] = True  # kept by name only: a restore leaves it to be rebuilt
    elif isinstance(value, ArraySet):
        if id(value) in seen:  # held twice (the state's warm-start contacts are the contact solver's): saved once
            snap.values[path + "/:same"] = True
            return
        seen.add(id(value))
        snap.values[path + "/:fields"] = list(value.fields)
        snap.values[path + "/:count"] = value.count
        snap.values[path + "/:capacity"] = value.capacity
        for name in value.fields:
            if arrays:
                snap.arrays[f"{path}/{name}"] = value.arrays[name].numpy().copy()
        for name, item in sorted(vars(value).items()):  # a subclass's own attributes (ContactSet's matching data)
            if name not in _ARRAYSET_OWN:
                _capture_member(value, name, item, path, snap, seen, arrays)
    elif isinstance(value, wp.array):
        if arrays:
            snap.arrays[path] = value.numpy().copy()
        snap.values[path + "/:dtype"] = _dtype_name(value.dtype)
    elif isinstance(value, np.ndarray):
        if arrays:
            snap.arrays[path] = value.copy()
    elif isinstance(value, np.random.Generator):
        snap.values[path + "/:rng"] = value.bit_generator.state
    elif isinstance(value, (list, tuple)):
        snap.values[path + "/:len"] = len(value)
        for i, item in enumerate(value):
            _capture(item, f"{path}/{i}", snap, seen, arrays)
    elif isinstance(value, dict):
        keys = list(value)
        if not all(isinstance(k, (str, int)) and not isinstance(k, bool) for k in keys):
            raise SnapshotError(f"cannot snapshot {path}: a dict with keys of type {type(keys[0]).__name__}")
        snap.values[path + "/:keys"] = keys
        for k in keys:
            _capture(value[k], f"{path}/{k}", snap, seen, arrays)
    elif _is_ours(value):
        if id(value) in seen:  # a back-reference (cloth -> world) or an object reached twice
            return
        seen.add(id(value))
        snap.values[path + "/:class"] = type(value).__qualname__
        skip = _ROWGROUP_OWN if isinstance(value, RowGroup) else frozenset()
        for name, item in sorted(vars(value).items()):
            if name not in skip:
                _capture_member(value, name, item, path, snap, seen, arrays)
    else:
        raise SnapshotError(
            f"cannot snapshot {path}: a value of type {type(value).__module__}.{type(value).__qualname__}"
        )


def _capture_member(owner, name: str, item, path: str, snap: Snapshot, seen: set[int], arrays: bool) -> None:
    """One attribute of an object of ours; those its class names in `SNAPSHOT_CACHES` (caches
    rebuilt when needed, such as keys of array identities) are kept by name only, as derived; the
    world's identity (`_IDENTITY`) is left out."""
    if name in _IDENTITY:
        return
    if name in getattr(type(owner), "SNAPSHOT_CACHES", ()):
        snap.values[f"{path}/{name}/:derived"] = True
    else:
        _capture(item, f"{path}/{name}", snap, seen, arrays)


def _is_plain(value) -> bool:
    if isinstance(value, Handle):
        return False
    if isinstance(value, (bool, int, float, str, type(None), np.integer, np.floating, np.bool_)):
        return True
    return isinstance(value, tuple) and type(value) is tuple and all(_is_plain(v) for v in value)


def _plain(value):
    """A JSON-safe copy of a plain value (tuples and floats tagged, so they come back exactly)."""
    if isinstance(value, enum.Enum):
        return {"enum": value.value}
    if isinstance(value, (np.integer, np.bool_)):
        return value.item()
    if isinstance(value, (float, np.floating)):
        return {"float": float(value).hex()}  # exact, and inf/nan safe
    if isinstance(value, tuple):
        return {"tuple": [_plain(v) for v in value]}
    return value


def _unplain(value, current=None):
    if isinstance(value, dict):
        if "float" in value:
            return float.fromhex(value["float"])
        if "tuple" in value:
            return tuple(_unplain(v) for v in value["tuple"])
        if "enum" in value:
            return type(current)(value["enum"]) if isinstance(current, enum.Enum) else value["enum"]
    return value


def _is_ours(value) -> bool:
    module = type(value).__module__ or ""
    return module == "tumble" or module.startswith("tumble.")


def _is_derived(value) -> bool:
    """Derived data or code, rebuilt when needed: recorded launches, Warp structs, BVHs, kernels, functions,
    and caches holding any of them (a tuple of a struct and the arrays it was built from)."""
    if isinstance(value, LaunchCache):
        return True
    if isinstance(value, (tuple, list)):
        return any(_is_derived(v) for v in value)
    module = type(value).__module__ or ""
    return module.startswith("warp") and not isinstance(value, wp.array) or callable(value) and not _is_ours(value)


def _refers_to(value, replaced: dict[int, wp.array]) -> bool:
    """True for a derived value (a Warp struct, or a cache holding one) that holds an array in `replaced`."""
    if isinstance(value, (tuple, list)):
        return any(_refers_to(v, replaced) for v in value)
    if isinstance(value, wp.array):
        return replaced.get(id(value)) is value
    if _is_warp_struct(value):
        return any(_refers_to(getattr(value, name), replaced) for name in value._cls.vars)
    return False


def _is_warp_struct(value) -> bool:
    return any(c.__name__ == "StructInstance" and c.__module__.startswith("warp") for c in type(value).__mro__)


def _dtype_name(dtype) -> str:
    name = getattr(dtype, "__name__", "")
    if getattr(wp, name, None) is not dtype:
        raise SnapshotError(f"cannot snapshot a Warp array of dtype {dtype}")
    return name


# --- restoring ---------------------------------------------------------------------------------


def restore(world: World, snap: Snapshot) -> None:
    """Put `snap` back into `world` (see `World.restore`, which then forgets what it derived from the old arrays).

    Raises `SnapshotError` when they do not match.
    """
    if snap.precision != world.precision:
        raise SnapshotError(
            f"the snapshot is of a {snap.precision} world and this world is {world.precision}: "
            f"restore it into a World(precision={snap.precision!r})"
        )
    _check_layout(world, snap)
    children: dict[str, set[str]] = {}
    for p in snap.values.keys() | snap.arrays.keys():
        parts = p.split("/")
        for depth, leaf in enumerate(parts):
            if not leaf.startswith(":"):
                children.setdefault("/".join(parts[:depth]), set()).add(leaf)
    walk = _Restore(snap, children, world)
    walk.seen.add(id(world))
    walk.members(world, "", skip=_WORLD_SKIP)
    for group in walk.groups:
        group.sync()  # its scratch sets, which snapshots leave out, to the restored rows
    for owner, name, value in walk.derived:
        if isinstance(value, LaunchCache):
            value.clear()
        elif _refers_to(value, walk.replaced):
            _assign(owner, name, None)  # a struct over arrays the restore replaced: rebuilt on first use


def _check_layout(world, snap: Snapshot) -> None:
    """Refuse a snapshot of another kind of world (other stages, emitters, cloth) before changing anything."""

    def layout(s: Snapshot) -> dict[str, object]:
        return {p: v for p, v in s.values.items() if p.endswith(("/:class", "/:fields", "/:len"))}

    have, want = layout(take(world, arrays=False)), layout(snap)
    if have != want:
        diff = sorted(p.rpartition("/")[0] for p in have.keys() | want.keys() if have.get(p) != want.get(p))
        raise SnapshotError(
            f"the snapshot does not match this world: {_few(diff)} differ (restore into a world "
            "built the same way as the one it was taken from)"
        )


def _few(paths: list[str]) -> str:
    return ", ".join(paths[:3]) + (f" and {len(paths) - 3} more" if len(paths) > 3 else "")


class _Restore:
    """Writes a snapshot back along the same walk that took it."""

    def __init__(self, snap: Snapshot, children: dict[str, set[str]], world: World):
        self.snap, self.children, self.world, self.device = snap, children, world, world.device
        self.derived: list[tuple] = []  # (owner, name, value) of every cache met on the way
        self.replaced: dict[int, wp.array] = {}  # arrays this restore replaced by new ones (kept alive here)
        self.seen: set[int] = set()
        self.groups: list[RowGroup] = []  # row groups met, synced once their parts are restored

    def members(self, obj, path: str, skip=frozenset()) -> None:
        """Restore the attributes of `obj`: those the snapshot has, and none that it lacks."""
        prefix = path + "/" if path else ""
        saved = self.children.get(path, set()) - skip
        caches = getattr(type(obj), "SNAPSHOT_CACHES", ())
        for name, value in _world_order(obj) if obj is self.world else sorted(vars(obj).items()):
            if name in skip or name in _IDENTITY:  # (an older file holds the saving world's key)
                continue
            if name in caches:
                # never taken from the file, whatever it holds (an older file may hold one: mesh BVH ids are
                # pointers into the process that saved it); kept, unless it refers to arrays the restore replaces
                self.derived.append((obj, name, value))
            elif name in saved:
                self.value(obj, name, value, prefix + name)
            elif _is_plain(value) or isinstance(value, (np.ndarray, wp.array)):
                delattr(obj, name)  # made after the snapshot was taken (a lazily sized buffer)
        for name in sorted(saved - set(vars(obj))):
            if prefix + name + "/:derived" not in self.snap.values:  # a cache is rebuilt, not restored
                object.__setattr__(obj, name, self.new(prefix + name))

    def new(self, path: str):
        """A value the object does not hold now: a plain value or an array, made from the snapshot."""
        snap = self.snap
        if path in snap.values:
            return _unplain(snap.values[path])
        if path in snap.arrays:
            data = snap.arrays[path].copy()
            dtype = snap.values.get(path + "/:dtype")
            return data if dtype is None else wp.array(data, dtype=getattr(wp, dtype), device=self.device)
        raise SnapshotError(f"cannot restore {path}: this world has nothing there to restore it into")

    def value(self, owner, name, value, path: str) -> None:
        """Write the snapshot's data at `path` into `value`, the attribute (or item) `name` of `owner`.

        What the snapshot holds at `path` decides, so that an attribute that was None then and is an
        array now (or the other way round) comes back as it was.
        """
        snap = self.snap
        if path + "/:same" in snap.values:
            return  # an ArraySet restored where the walk met it first
        if path + "/:derived" in snap.values or _is_derived(value):
            self.derived.append((owner, name, value))
        elif path in snap.values:
            _assign(owner, name, _unplain(snap.values[path], value))
        elif path in snap.arrays and not isinstance(value, ArraySet):
            data = snap.arrays[path]
            if isinstance(value, wp.array) and tuple(value.shape) == data.shape and value.numpy().dtype == data.dtype:
                value.assign(data)  # in place: recorded launches that hold this array stay valid
            elif (
                isinstance(value, np.ndarray)
                and value.shape == data.shape
                and value.dtype == data.dtype
                and value.flags.writeable
            ):
                value[...] = data
            else:
                if isinstance(value, wp.array):
                    self.replaced[id(value)] = value
                _assign(owner, name, self.new(path))
        elif isinstance(value, ArraySet):
            before = dict(value.arrays)
            value.load(
                {n: snap.arrays[f"{path}/{n}"] for n in value.fields},
                count=snap.values[path + "/:count"],
                capacity=snap.values[path + "/:capacity"],
            )
            self.replaced.update((id(a), a) for n, a in before.items() if value.arrays[n] is not a)
            self.seen.add(id(value))
            self.members(value, path, skip=_ARRAYSET_OWN | set(value.fields))
        elif isinstance(value, np.random.Generator):
            value.bit_generator.state = snap.values[path + "/:rng"]
        elif isinstance(value, (list, tuple)):
            items = list(value)
            for i, item in enumerate(items):
                self.value(items, i, item, f"{path}/{i}")
            if isinstance(value, list):
                value[:] = items
            elif type(value) is tuple and any(a is not b for a, b in zip(items, value)):
                _assign(owner, name, tuple(items))
        elif isinstance(value, dict):
            saved = snap.values[path + "/:keys"]
            for k in [k for k in value if k not in saved]:
                del value[k]
            for k in saved:
                if k in value:
                    self.value(value, k, value[k], f"{path}/{k}")
                else:
                    value[k] = self.new(f"{path}/{k}")
        elif _is_ours(value):
            if id(value) not in self.seen:
                self.seen.add(id(value))
                if isinstance(value, RowGroup):
                    self.groups.append(value)
                self.members(value, path, skip=_ROWGROUP_OWN if isinstance(value, RowGroup) else frozenset())
        else:
            raise SnapshotError(f"cannot restore {path}: a value of type {type(value).__qualname__}")


def _assign(owner, name, value) -> None:
    if isinstance(owner, (list, dict)):
        owner[name] = value
    else:
        object.__setattr__(owner, name, value)


# --- files -------------------------------------------------------------------------------------


def save(snap: Snapshot, path: str | os.PathLike[str]) -> Path:
    """Write `snap` to `path` (.npz), atomically (OutputError, naming `path`, if it cannot be written)."""
    from .io.atomic import atomic_path, check_output

    if not isinstance(snap, Snapshot):
        raise TypeError(f"a snapshot to save must be a Snapshot (world.snapshot()), got {type(snap).__name__}")
    path = check_output(path, suffixes=(".npz",), option="")
    manifest: dict[str, Any] = {
        "format": FORMAT,
        "values": snap.values,
        "step_count": snap.step_count,
        "time": float(snap.time).hex(),
        "scene": snap.scene,
        "scene_path": snap.scene_path,
        "overrides": snap.overrides,
        "precision": snap.precision,
        "arrays": sorted(snap.arrays),
    }
    payload = {f"a{i}": a for i, a in enumerate(snap.arrays[k] for k in manifest["arrays"])}
    manifest["digest"] = _digest(manifest, payload)
    payload["manifest"] = np.frombuffer(json.dumps(manifest).encode(), dtype=np.uint8)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **payload)  # type: ignore[arg-type]  # numpy's stub: a key could be allow_pickle
    return path


def _digest(manifest: dict[str, Any], payload: dict[str, np.ndarray]) -> str:
    """A hash of a snapshot file's contents (the manifest without its digest, each array's name,
    type, shape and bytes): `read` refuses a file whose contents were damaged or edited since."""
    h = hashlib.blake2b(digest_size=16)
    h.update(json.dumps({k: v for k, v in manifest.items() if k != "digest"}, sort_keys=True).encode())
    for name in sorted(payload):
        a = np.ascontiguousarray(payload[name])
        h.update(f"{name}:{a.dtype.str}:{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def read(path: str | os.PathLike[str]) -> Snapshot:
    """Read a snapshot file written by `save`. Raises `SnapshotError` naming the file on any problem."""
    path = Path(path)
    try:
        from .io.record import ArchiveError, check_archive, file_kind

        with open(path, "rb") as f:
            kind = file_kind(path, f.read(512))
        if kind != "zip":  # NumPy would try it as a pickle, and say so
            raise SnapshotError(f"{path}: not a Tumble snapshot file ({_NOT_A_SNAPSHOT[kind]})")
        try:
            check_archive(path)
        except LimitError as exc:
            raise SnapshotError(f"{path}: {exc}") from None
        except ArchiveError as exc:
            raise SnapshotError(f"{path}: not a Tumble snapshot file ({exc})") from None
        with np.load(path, allow_pickle=False) as data:
            if "manifest" not in data.files and "time" in data.files:
                raise SnapshotError(
                    f"{path}: a recording (tumble run --record), not a saved state: resume from a file "
                    "written by tumble run --save-state (or tumble.save_snapshot)"
                )
            manifest = json.loads(bytes(data["manifest"]).decode())
            if not isinstance(manifest, dict) or "format" not in manifest:
                raise ValueError("no manifest")
            if manifest["format"] not in _READS:
                raise SnapshotError(
                    f"{path}: snapshot format {manifest['format']} is not the format {FORMAT} "
                    "this version of Tumble reads"
                )
            payload = {f"a{i}": data[f"a{i}"] for i in range(len(manifest["arrays"]))}
            if "digest" in manifest and manifest["digest"] != _digest(manifest, payload):  # (files before it have none)
                raise SnapshotError(
                    f"{path}: the snapshot is damaged or was edited (its contents do not match its digest)"
                )
            arrays = {k: payload[f"a{i}"] for i, k in enumerate(manifest["arrays"])}
        time = float.fromhex(manifest["time"]) if isinstance(manifest.get("time"), str) else math.nan
        if manifest["format"] < 7:
            _upgrade_contacts(manifest["values"], arrays)
        if manifest["format"] < 8:
            _upgrade_joints(manifest["values"], arrays)
        if manifest["format"] < 9:
            _upgrade_broadphase(manifest["values"], arrays)
        if manifest["format"] < 10:
            _upgrade_cloth(manifest["values"])
        return Snapshot(
            arrays,
            manifest["values"],
            int(manifest["step_count"]),
            time,
            manifest.get("scene"),
            manifest.get("scene_path"),
            dict(manifest.get("overrides") or {}),
            _READS[manifest["format"]] or _saved_precision(manifest, path),
        )
    except SnapshotError:
        raise
    except FileNotFoundError:
        raise SnapshotError(f"{path}: no such snapshot file") from None
    except IsADirectoryError:
        raise SnapshotError(f"{path}: is a directory, not a snapshot file") from None
    except Exception as exc:  # whatever the zip, zlib, NumPy or JSON readers raise on a damaged file, or a bad manifest
        raise SnapshotError(f"{path}: not a Tumble snapshot file ({type(exc).__name__}: {exc})") from None


def _upgrade_contacts(values: dict, arrays: dict[str, np.ndarray]) -> None:
    """A format 5 or 6 file as format 7 reads it: its contacts held the solver's per-step quantities
    (anchors, effective masses, impulses, ...) as contact arrays, which `prepare` now writes to the
    scratch rows every step; they are dropped, and the rows and the matched normal impulses are added
    as a step leaves them (rebuilt by the next step, as in a format 7 file)."""
    from .solver.contacts import CONTACT_FIELDS

    fields = values.get("contacts/:fields")
    if not isinstance(fields, list):
        return
    for name in fields:
        if name not in CONTACT_FIELDS:
            arrays.pop(f"contacts/{name}", None)
    values["contacts/:fields"] = [name for name in fields if name in CONTACT_FIELDS]
    values["contacts/rows/:derived"] = True
    values["contacts/_passes/:derived"] = True
    jt = arrays.get("contacts/jt_world")
    if jt is not None:
        arrays["contacts/jn_warm"] = np.zeros(len(jt), dtype=jt.dtype)
        values["contacts/jn_warm/:dtype"] = "float32" if jt.dtype == np.float32 else "float64"


_TEXT = "it is a text file (a scene? run it with tumble run SCENE); a snapshot is written by tumble run --save-state"
_BINARY = "unknown binary content; a snapshot is a zip archive written by tumble run --save-state"
#: what `read` says of a file that is not a zip archive, by `tumble.io.record.file_kind`
_NOT_A_SNAPSHOT = {"empty": "the file is empty", "npy": _BINARY, "binary": _BINARY, "scene": _TEXT, "text": _TEXT}


def _upgrade_joints(values: dict, arrays: dict[str, np.ndarray]) -> None:
    """A format 5 to 7 file as format 8 reads it: its joints had no `joint_angle` (a hinge's angle
    counting whole turns); it starts at 0, so each hinge counts on from its angle in (-pi, pi], the
    angle those formats' limits were on."""
    fields = values.get("state/joints/:fields")
    upper = arrays.get("state/joints/joint_impulse_upper")
    if not isinstance(fields, list) or upper is None or "joint_angle" in fields:
        return
    at = fields.index("joint_impulse_upper") + 1 if "joint_impulse_upper" in fields else len(fields)
    values["state/joints/:fields"] = [*fields[:at], "joint_angle", *fields[at:]]
    arrays["state/joints/joint_angle"] = np.zeros_like(upper)


def _upgrade_broadphase(values: dict, arrays: dict[str, np.ndarray]) -> None:
    """A format 5 to 8 file as format 9 reads it: it holds the broad phase's grid and cell edge as its
    last search left them, which are caches now (`BroadPhase.SNAPSHOT_CACHES`: a restored world
    searches afresh, with the same pairs); they are dropped and marked as caches."""
    from .collision.broadphase import BroadPhase

    for name in BroadPhase.SNAPSHOT_CACHES:
        path = f"broadphase/{name}"
        for held in (values, arrays):
            for key in [k for k in held if k == path or k.startswith(path + "/")]:
                del held[key]
        values[path + "/:derived"] = True


def _upgrade_cloth(values: dict) -> None:
    """A format 5 to 9 file as format 10 reads it: a cloth's state had no `substeps_last`; 0 (as on a
    world's first step) takes the world's substeps at once when a body approaches, as those versions did."""
    if "state/cloth/pair_count" in values:
        values["state/cloth/substeps_last"] = 0


def _saved_precision(manifest: dict, path: Path) -> str:
    precision = manifest.get("precision")
    if precision not in PRECISIONS:
        raise SnapshotError(f"{path}: not a Tumble snapshot file (precision {precision!r})")
    return precision
