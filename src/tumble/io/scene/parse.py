"""Reading scene files: TOML text -> checked values (`Scene`), and the limits a scene may ask for.

`parse_scene(text)` checks every table against `schema.SCHEMA`, fills in the defaults and
returns a `Scene` of plain Python values (no Warp, no World); `check_limits` then refuses a
scene asking for more than Tumble can do or the machine can hold. Every problem raises
`SceneError` naming the file, the table (e.g. `sphere[2]` for the third `[[sphere]]`) and the key.
"""

from __future__ import annotations

import difflib
import importlib.resources
import os
import re
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ... import limits
from ...errors import SceneError
from ...limits import show_bytes
from .checks import Bad, KeyBad, show
from .schema import BODY_TABLES, REQUIRED, SCHEMA, TableSpec

#: directory of the bundled sample scenes, installed with the package (`tumble/samples`, which the
#: repository's `samples/` links to); override with $TUMBLE_SAMPLES
SAMPLES_DIR = Path(os.environ.get("TUMBLE_SAMPLES") or os.fspath(importlib.resources.files("tumble") / "samples"))  # type: ignore[call-overload]  # a Path here; typeshed: a Traversable


# ---------------------------------------------------------------------------------------- parsing


@dataclass
class Scene:
    """A validated scene: for each table its converted values (defaults filled in).

    `tables[name]` is a dict for a single table (absent tables are missing) and a list of
    dicts for an array table (possibly empty).
    """

    path: str | None
    tables: dict[str, Any] = field(default_factory=dict)  # a dict, or a list of dicts for an array table
    text: str | None = None  # the TOML it was parsed from (kept so that snapshots can rebuild the world)

    def items(self, name: str) -> list[dict]:
        """The entries of an array table (empty when absent)."""
        return list(self.tables.get(name, []))

    def table(self, name: str) -> dict | None:
        """A single table's values, or None when the file does not have it."""
        return self.tables.get(name)

    @property
    def dt(self) -> float:
        """The time step the scene runs at: its [world] dt, or the default."""
        return float((self.table("world") or {}).get("dt", SCHEMA["world"].fields["dt"].default))

    def counts(self) -> dict[str, int]:
        """Number of entries per table present in the file."""
        return {
            name: (len(value) if isinstance(value, list) else 1)
            for name, value in self.tables.items()
            if not isinstance(value, list) or value
        }

    def summary(self) -> str:
        """One line: counts per table, e.g. "[world], 5 planes, 1 emitter (1000 bodies)"."""
        parts = []
        for name, n in self.counts().items():
            label = name if n == 1 else name + ("es" if name.endswith(("x", "s", "sh")) else "s")
            if not SCHEMA[name].array:
                parts.append(f"[{name}]")
                continue
            text = f"{n} {label}"
            if name == "emitter":
                text += f" ({sum(e['count'] for e in self.items('emitter'))} bodies)"
            if name == "cloth":
                text += f" ({sum(c['resolution'][0] * c['resolution'][1] for c in self.items('cloth'))} particles)"
            parts.append(text)
        return ", ".join(parts) if parts else "empty scene"


def table_label(name: str, index: int | None) -> str:
    return name if index is None else f"{name}[{index}]"


def _suggest(word: str, options) -> str:
    close = difflib.get_close_matches(word, list(options), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def parse_table(spec: TableSpec, raw, path, index: int | None) -> dict:
    label = table_label(spec.name, index)
    if not isinstance(raw, dict):
        raise SceneError(f"must be a table, got {show(raw)}", path=path, table=label)
    values = {}
    for key, value in raw.items():
        if key not in spec.fields:
            raise SceneError(
                f"unknown key {key!r}{_suggest(key, spec.fields)}; "
                f"[{'[' if spec.array else ''}{spec.name}{']' if spec.array else ''}] takes: {', '.join(spec.fields)}",
                path=path,
                table=label,
                key=key,
            )
        try:
            values[key] = spec.fields[key].check(value)
        except Bad as exc:
            raise SceneError(str(exc), path=path, table=label, key=key) from None
    for key, f in spec.fields.items():
        if key not in values:
            if f.default is REQUIRED:
                raise SceneError("missing required key", path=path, table=label, key=key)
            values[key] = copy_default(f.default)
    if spec.rules is not None:
        try:
            spec.rules(values)
        except KeyBad as exc:
            raise SceneError(str(exc), path=path, table=label, key=exc.key) from None
    return values


def copy_default(value):
    return list(value) if isinstance(value, list) else value


def parse_scene(text: str, path=None) -> Scene:
    """Validate scene-file text and return a `Scene` with every default filled in.

    Args:
        text: the TOML document.
        path: the file it came from, used in error messages.

    Raises:
        SceneError: malformed TOML (with the line), an unknown table or key, a value of the
            wrong type, length or range; the message names the file, the table and the key.
    """
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"invalid TOML: {exc}", path=path) from None
    except RecursionError:
        raise SceneError("invalid TOML: arrays or tables nested too deeply", path=path) from None
    except ValueError:  # Python's limit on the digits of an integer it converts from text
        raise SceneError(f"invalid TOML: {_long_number(text)}", path=path) from None
    scene = Scene(path=None if path is None else str(path), text=text)
    for name, raw in doc.items():
        spec = SCHEMA.get(name)
        if spec is None:
            kind = "table" if isinstance(raw, (dict, list)) else "top-level key"
            raise SceneError(
                f"unknown {kind} {name!r}{_suggest(name, SCHEMA)}; tables are: "
                + ", ".join(f"[[{s.name}]]" if s.array else f"[{s.name}]" for s in SCHEMA.values()),
                path=path,
                table=name,
            )
        if spec.array:
            if isinstance(raw, dict):
                raise SceneError(f"write [[{name}]] (an array of tables), not [{name}]", path=path, table=name)
            if not isinstance(raw, list):
                raise SceneError(f"must be an array of tables [[{name}]], got {show(raw)}", path=path, table=name)
            scene.tables[name] = [parse_table(spec, item, path, i) for i, item in enumerate(raw)]
        else:
            if isinstance(raw, list):
                raise SceneError(f"write [{name}] (one table), not [[{name}]]", path=path, table=name)
            scene.tables[name] = parse_table(spec, raw, path, None)
    check_limits(scene)
    return scene


def _long_number(text: str) -> str:
    """Where the first integer too long for Python to read (over `sys.get_int_max_str_digits()` digits) is."""
    limit = sys.get_int_max_str_digits()
    digits = text.replace("_", "")
    found = re.search(rf"\d{{{limit + 1},}}", digits) if limit else None
    where = "" if found is None else f" (at line {digits.count(chr(10), 0, found.start()) + 1})"
    return f"an integer of more than {limit:,} digits{where}"


def check_limits(scene: Scene, *, dt: float | None = None) -> None:
    """Refuse a scene asking for more than Tumble can do or this machine can hold (docs/scenes.md#limits).

    Checked before anything is allocated: bodies released per emitter step, steps of the
    [check] duration, cloth indices (int32), and the memory of every body and cloth particle
    the scene will hold against `limits.available_memory()`.

    Args:
        dt: the time step the scene will run at (default its [world] dt).

    Raises:
        SceneError: naming the table and key asking too much, the request and the limit.
    """
    path = scene.path
    dt = scene.dt if dt is None else float(dt)

    # solver limits: bodies released in one step, steps of the check run
    for i, e in enumerate(scene.items("emitter")):
        per_step = min(e["rate"] * dt, e["count"])
        if per_step > limits.MAX_RELEASE_PER_STEP:
            raise SceneError(
                f"{e['rate']:g} bodies/s at dt {dt:g} s releases {per_step:,.0f} bodies in one step; "
                f"the limit is {limits.MAX_RELEASE_PER_STEP:,} a step (docs/scenes.md#limits)",
                path=path,
                table=table_label("emitter", i),
                key="rate",
            )
    check = scene.table("check")
    if check is not None:
        try:
            limits.check_steps("duration", check["duration"], dt)
        except limits.LimitError as exc:
            raise SceneError(str(exc), path=path, table="check") from None

    # memory: every body (listed and emitted) and every cloth particle, blamed on the largest request
    requests: list[tuple[int, str, str | None, int, str, int]] = []  # (bytes, table, key, count, what, bytes each)
    for name in BODY_TABLES:
        n = len(scene.items(name))
        if n:
            requests.append((n * limits.BYTES_PER_BODY, name, None, n, f"{name} bodies", limits.BYTES_PER_BODY))
    for i, e in enumerate(scene.items("emitter")):
        requests.append(
            (
                e["count"] * limits.BYTES_PER_BODY,
                table_label("emitter", i),
                "count",
                e["count"],
                "bodies",
                limits.BYTES_PER_BODY,
            )
        )
    particles = 0
    for i, c in enumerate(scene.items("cloth")):
        n = c["resolution"][0] * c["resolution"][1]
        particles += n
        if particles > limits.MAX_PARTICLES_INT32:
            raise SceneError(
                f"{c['resolution'][0]:,} x {c['resolution'][1]:,} = {n:,} particles; cloth indices are int32, "
                f"which allows at most {limits.MAX_PARTICLES_INT32:,} particles in all (docs/scenes.md#limits)",
                path=path,
                table=table_label("cloth", i),
                key="resolution",
            )
        requests.append(
            (
                n * limits.BYTES_PER_PARTICLE,
                table_label("cloth", i),
                "resolution",
                n,
                "particles",
                limits.BYTES_PER_PARTICLE,
            )
        )
    need = sum(r[0] for r in requests)
    if requests:
        have = limits.available_memory()
        if need > have:
            _, table, key, count, what, each = max(requests, key=lambda r: r[0])
            others = need - count * each
            try:
                limits.check_memory(key or f"[[{table}]]", what, count, each, available=max(0, have - others))
            except limits.LimitError as exc:
                message = str(exc).split(": ", 1)[1] if key is not None else str(exc)
                if others > 0.01 * have:
                    message += f" beside the {show_bytes(others)} the rest of the scene needs"
                raise SceneError(message, path=path, table=table if key is not None else None, key=key) from None


#: what a scene path holding a recording or a saved state (.npz, a zip archive) is told
_NOT_A_SCENE = (
    "a .npz archive (a recording or a saved state), not a scene file: tumble plot and export read "
    "recordings, tumble run --resume a saved state"
)


def read_scene(path) -> Scene:
    """Read and validate a scene file (see `parse_scene`). Raises `SceneError`, or `OSError` if unreadable."""
    path = resolve_scene_path(path)
    if path.suffix.lower() == ".npz":  # even an empty or broken one: never read as an (empty) scene
        raise SceneError(_NOT_A_SCENE, path=path)
    with open(path, "rb") as f:  # at most the limit and one byte: a device or a huge file is not read to its end
        data = f.read(limits.MAX_SCENE_BYTES + 1)
    if len(data) > limits.MAX_SCENE_BYTES:
        raise SceneError(
            f"larger than {show_bytes(limits.MAX_SCENE_BYTES)}, too large for a scene file (a scene is text; "
            "meshes go in their own files, docs/scenes.md#limits)",
            path=path,
        )
    try:
        # newlines as text mode reads them; a byte-order mark (Notepad writes one) is not TOML
        text = data.decode("utf-8").removeprefix("\ufeff").replace("\r\n", "\n").replace("\r", "\n")
    except UnicodeDecodeError as exc:
        if data[:4] == b"PK\x03\x04":  # a zip: what --record and --save-state write
            raise SceneError(_NOT_A_SCENE, path=path) from None
        raise SceneError(f"not a UTF-8 text file ({exc.reason})", path=path) from None
    scene = parse_scene(text, path=path)
    if not scene.tables:  # a zero-byte file (cut short, or never written) would run as an empty world
        what = "empty" if not text.strip() else "only comments"
        raise SceneError(
            f"the file is {what}, not a scene: a scene has at least one table, such as [world] or [[sphere]] "
            "(docs/scenes.md)",
            path=path,
        )
    return scene


def resolve_scene_path(path) -> Path:
    """`path` itself, or, for a bare name like "sphere_pile", the bundled sample of that name."""
    if str(path) == "":  # (Path("") is the current folder)
        raise FileNotFoundError("no scene file given: the name is empty")
    p = Path(path)
    if not p.exists() and p.parent == Path(".") and (SAMPLES_DIR / p.with_suffix(".toml").name).exists():
        return SAMPLES_DIR / p.with_suffix(".toml").name
    if not p.exists():
        raise FileNotFoundError(f"{path}: no such scene file")
    if p.is_dir():
        raise IsADirectoryError(f"{path}: is a directory, not a scene file")
    if not p.is_file():  # a named pipe waits for a writer, a device never ends: neither is read
        raise SceneError("not a regular file (a pipe or a device), not a scene file", path=path)
    return p


def list_samples() -> list[Path]:
    """The bundled sample scenes (`SAMPLES_DIR/*.toml`), sorted by name."""
    return sorted(SAMPLES_DIR.glob("*.toml"))
