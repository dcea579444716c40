"""Wedges: one scene run over a grid of parameter values, each combination its own simulation.

An artist's "wedge" is the same shot at five frictions or ten seeds, side by side, to pick one;
a study or a dataset is the same thing at a larger scale. Tumble runs one world on one core
(Warp's CPU kernels are serial), so a wedge runs its variants in parallel on a Dask
distributed cluster: by default a local one with one single-threaded worker process per core,
or an existing one (`address=`), on several machines or under SLURM (docs/wedge.md)::

    table = tumble.wedge("samples/sphere_pile.toml",
                         vary={"plane[*].friction": [0.2, 0.5, 0.8], "world.seed": "0..3"},
                         out="pile_wedge", duration=2.0)
    for row in table:
        print(row["variant"], row["status"], row["kinetic_energy_J"])

Stages, each a plain function:

1. keys and values: `parse_key` resolves "emitter[0].rate" against the scene file and the
   scene schema (`tumble.io.scene.SCHEMA`); `parse_values` reads "a,b,c", "start:stop:count"
   or "a..b";
2. variants: the cartesian product, each variant's scene written out as TOML
   (`variant_text`) and validated by the same loader as `tumble run` (`parse_scene`), so a
   bad value names its table and key before anything runs;
3. run: `run_variant` on the workers (build, step `round(duration / dt)` times as
   `tumble run` does, measure, render the final frame, write the files asked for);
4. results: `OUTDIR/<variant>/result.json` per variant, `OUTDIR/manifest.csv` and `.json`
   (one row per variant), `OUTDIR/contact_sheet.png`; `plot_wedge` draws the figures.

A variant's folder is named after its values, and a variant whose `result.json` says "ok" for
the same scene text and settings is not run again, so re-running the same command resumes.
Every file is written to a temporary name beside its target and renamed into place.
"""

from __future__ import annotations

import contextlib
import copy
import csv
import difflib
import hashlib
import io
import itertools
import json
import math
import os
import re
import sys
import time
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, TypeGuard

from . import limits, validate
from .errors import TumbleError
from .io.atomic import atomic_path
from .progress import new_bar

if TYPE_CHECKING:
    from rich.progress import Progress

#: most variants a wedge runs without `yes=True` / `--yes`
MAX_VARIANTS = 1000
#: most variants (and values of one key) a wedge takes even with `--yes`: checked before a range is
#: expanded, so that 0..1000000000 is refused at once rather than after building a billion values
MAX_VARIANTS_EVER = 100_000
#: seconds to wait for an existing cluster at `address` to answer
CONNECT_TIMEOUT = 5.0
#: what a variant can keep besides result.json, scene.toml and final.png
KEEP = ("record", "video", "usd", "figures")
#: short names for common key paths
KEY_ALIASES = {"seed": "world.seed", "gravity": "world.gravity", "dt": "world.dt", "substeps": "world.substeps"}
#: summary figures of a variant, in manifest order (name -> meaning)
METRICS = {
    "kinetic_energy_J": "final kinetic energy [J]",
    "max_overlap_m": "largest overlap between two bodies [m]",
    "max_penetration_m": "largest penetration of a body into a plane [m]",
    "max_strain": "largest cloth strain",
    "body_count": "bodies at the end (planes included)",
    "contact_count": "contacts at the end",
}
#: columns of manifest.csv after the varied keys
COLUMNS = ("status", "error", "wall_s", "steps", "steps_per_s", *METRICS, "state_hash", "worker")

_KEY_RE = re.compile(r"^([A-Za-z_]+)(?:\[(\d+|\*)\])?\.([A-Za-z_]+)(?:\[(\d+)\])?$")


class WedgeError(TumbleError, ValueError):
    """A wedge request is malformed (key path, values, limit, cluster address); one line."""


# ---------------------------------------------------------------------------------------- key paths


@dataclass(frozen=True)
class KeyPath:
    """Where a varied value goes: `table[index].key[component]`.

    Attributes:
        table: scene table name ("emitter").
        index: entry of an array table, "*" for every entry, None for a single table.
        key: key inside the table ("rate").
        component: index into a list value (wind.velocity[0]), or None for the whole value.
    """

    table: str
    index: int | str | None
    key: str
    component: int | None = None

    @property
    def label(self) -> str:
        """Canonical text, e.g. "emitter[0].rate" or "plane[*].friction"."""
        head = self.table if self.index is None else f"{self.table}[{self.index}]"
        tail = "" if self.component is None else f"[{self.component}]"
        return f"{head}.{self.key}{tail}"


def _key_paths(doc: Mapping) -> list[str]:
    """Every key path the scene `doc` can take, for 'did you mean' suggestions."""
    from .io.scene import SCHEMA

    out = []
    for spec in SCHEMA.values():
        if spec.array:
            entries = len(doc.get(spec.name, []) or [])
            heads = [f"{spec.name}[{i}]" for i in range(entries)] + ([f"{spec.name}[*]"] if entries else [])
        else:
            heads = [spec.name]
        out += [f"{head}.{key}" for head in heads for key in spec.fields]
    return out


def parse_key(text: str, doc: Mapping) -> KeyPath:
    """Resolve a key path against the scene schema and the scene's own tables.

    Args:
        text: "world.gravity", "plane[0].friction", "plane[*].friction" (every plane),
            "wind.velocity[0]" (one component of a list), or an alias such as "seed".
        doc: the scene file as read by `tomllib` (to know how many entries each array has).

    Raises:
        WedgeError: an unknown table or key (naming the nearest key path), a missing or
            out-of-range index.
    """
    from .io.scene import SCHEMA

    text = KEY_ALIASES.get(text.strip(), text.strip())
    match = _KEY_RE.match(text)
    if match is None:
        raise WedgeError(
            f"key path {text!r} should look like table.key or table[i].key, "
            f"e.g. world.gravity or plane[0].friction{_nearest(text, doc)}"
        )
    table, index, key, component = match.groups()
    spec = SCHEMA.get(table)
    if spec is None or key not in spec.fields:
        what = (
            f"table {table!r}"
            if spec is None
            else f"key {key!r} in [{'[' if spec.array else ''}{table}{']' if spec.array else ''}]"
        )
        raise WedgeError(f"unknown key path {text!r}: no {what}{_nearest(text, doc)}")
    entries = len(doc.get(table, []) or []) if spec.array else None
    if spec.array:
        if entries == 0:
            raise WedgeError(f"key path {text!r}: the scene has no [[{table}]] table")
        if index is None:
            raise WedgeError(
                f"key path {text!r}: [[{table}]] is an array of tables; write {table}[0].{key} "
                f"(or {table}[*].{key} for every one; the scene has {entries})"
            )
        assert entries is not None  # counted for an array of tables
        if index != "*" and int(index) >= entries:
            raise WedgeError(
                f"key path {text!r}: the scene has {entries} [[{table}]] "
                f"table{'' if entries == 1 else 's'}{_nearest(text, doc)}"
            )
    elif index is not None:
        raise WedgeError(f"key path {text!r}: [{table}] is a single table; write {table}.{key}")
    return KeyPath(
        table, index if index in (None, "*") else int(index), key, None if component is None else int(component)
    )


def _nearest(text: str, doc: Mapping) -> str:
    close = difflib.get_close_matches(text, _key_paths(doc), n=1, cutoff=0.5)
    return f" (did you mean {close[0]!r}?)" if close else ""


# ---------------------------------------------------------------------------------------- values


def _round(x: float) -> float:
    """x to 12 significant digits, so that 0:1:11 gives 0.3 rather than 0.30000000000000004."""
    return float(f"{x:.12g}")


def _scalar(text: str):
    """One value as TOML reads it (3, 0.5, true, "box", [0, 0, -9.81]); a bare word is a string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _split_top(text: str) -> list[str]:
    """Split on commas outside brackets and quotes."""
    parts, depth, quote, start = [], 0, None, 0
    for i, ch in enumerate(text):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return [p.strip() for p in parts]


def parse_values(text) -> list:
    """The values of one varied key.

    Args:
        text: "a,b,c" (TOML values: numbers, true/false, strings, [x, y, z] lists),
            "start:stop:count" (`count` evenly spaced numbers, both ends included; integers
            when start and stop are integers and every value is whole), "a..b" (the integers
            a, a+1, ..., b), or already a list of values.

    Raises:
        WedgeError: an empty list or range, a malformed range, a value given twice.
    """
    if isinstance(text, (list, tuple, range)):
        values = list(text)
    elif not isinstance(text, str):
        values = [text]
    else:
        s = text.strip()
        if not s:
            raise WedgeError("no values given")
        if re.fullmatch(r"[+-]?\d+\s*\.\.\s*[+-]?\d+", s):
            a, b = (int(p) for p in s.split(".."))
            if b < a:
                raise WedgeError(f"empty range {s!r}: the end {b} is below the start {a}")
            _at_most(b - a + 1, s)
            values = list(range(a, b + 1))
        elif ".." in s and not s.startswith(("[", '"', "'")):
            raise WedgeError(f"range {s!r}: a..b takes two integers, e.g. 0..99")
        elif ":" in s and not s.startswith(("[", '"', "'")):
            values = _linspace(s)
        else:
            values = [_scalar(p) for p in _split_top(s)]
            if any(p == "" for p in _split_top(s)):
                raise WedgeError(f"values {s!r}: an empty value between commas")
    if not values:
        raise WedgeError("empty list of values")
    seen = set()
    for v in values:
        k = json.dumps(v, sort_keys=True)
        if k in seen:
            raise WedgeError(f"value {format_value(v)} is given twice")
        seen.add(k)
    return values


def _at_most(count: int, s: str) -> None:
    if count > MAX_VARIANTS_EVER:
        raise WedgeError(f"range {s!r} gives {count:,} values; a wedge takes at most {MAX_VARIANTS_EVER:,}")


def _linspace(s: str) -> list:
    parts = s.split(":")
    if len(parts) != 3:
        raise WedgeError(f"range {s!r} should be start:stop:count, e.g. 0.1:0.9:5")
    start, stop, count = (_scalar(p.strip()) for p in parts)
    for name, v in (("start", start), ("stop", stop)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise WedgeError(f"range {s!r}: {name} must be a finite number, got {parts[0 if name == 'start' else 1]!r}")
    if isinstance(count, bool) or not isinstance(count, int):
        raise WedgeError(f"range {s!r}: count must be a whole number, got {parts[2].strip()!r}")
    if count < 1:
        raise WedgeError(f"empty range {s!r}: count must be at least 1")
    _at_most(count, s)
    if count == 1:
        return [start]
    values = [_round(start + (stop - start) * k / (count - 1)) for k in range(count)]
    if isinstance(start, int) and isinstance(stop, int) and all(v == int(v) for v in values):
        return [int(v) for v in values]
    return values


def parse_vary(spec: str) -> tuple[str, list]:
    """Split "KEY=VALUES" (one --vary) into the key text and its values (`parse_values`)."""
    if "=" not in spec:
        raise WedgeError(f"--vary {spec!r} should be KEY=VALUES, e.g. plane[0].friction=0.2,0.5,0.8")
    key, _, values = spec.partition("=")
    if not key.strip():
        raise WedgeError(f"--vary {spec!r}: no key before '='")
    try:
        return key.strip(), parse_values(values)
    except WedgeError as exc:
        raise WedgeError(f"--vary {spec}: {exc}") from None


def format_value(value, *, digits: int | None = None) -> str:
    """A value as text: 0.5, 3, [0, 0, -9.81], box (digits: significant digits of floats)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.{digits}g}" if digits else repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(format_value(v, digits=digits) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {format_value(v, digits=digits)}" for k, v in value.items()) + "}"
    return str(value)


# ---------------------------------------------------------------------------------------- scene text


def _toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise WedgeError(f"cannot write {value!r} ({type(value).__name__}) into a scene file")


def scene_text(doc: Mapping, header: str = "") -> str:
    """A scene document (tables as `tomllib` reads them) written back as TOML text."""
    lines = [f"# {line}" for line in header.splitlines()]
    for name, table in doc.items():
        entries = table if isinstance(table, list) else [table]
        for entry in entries:
            lines += ["", f"[[{name}]]" if isinstance(table, list) else f"[{name}]"]
            lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in entry.items()]
    return "\n".join(lines).lstrip("\n") + "\n"


def apply_value(doc: dict, key: KeyPath, value) -> None:
    """Set `value` at `key` in the scene document `doc` (in place; a missing single table is added)."""
    from .io.scene import SCHEMA, copy_default

    spec = SCHEMA[key.table]
    if spec.array:
        rows = doc[key.table]
        targets = rows if key.index == "*" else [rows[key.index]]
    else:
        targets = [doc.setdefault(key.table, {})]
    for row in targets:
        if key.component is None:
            row[key.key] = value
            continue
        current = row.get(key.key, copy_default(spec.fields[key.key].default))
        if not isinstance(current, list) or key.component >= len(current):
            size = len(current) if isinstance(current, list) else 0
            raise WedgeError(f"key path {key.label!r}: {key.key} has {size} component{'' if size == 1 else 's'}")
        current = list(current)
        current[key.component] = value
        row[key.key] = current


# ---------------------------------------------------------------------------------------- variants


@dataclass
class Variant:
    """One combination of values: its folder name, its values by key label, its scene text."""

    name: str
    values: dict[str, object]
    text: str
    dt: float  # the variant's time step (its steps are checked against limits.MAX_STEPS)

    @property
    def scene_sha(self) -> str:
        return hashlib.sha256(self.text.encode()).hexdigest()


def _slug(values: Mapping[str, object]) -> str:
    parts = []
    for label, v in values.items():
        k = label.replace("[*]", "").replace("[", "").replace("]", "")
        text = ",".join(format_value(x) for x in v) if isinstance(v, (list, tuple)) else format_value(v)
        parts.append(f"{k}={text}".replace(", ", ","))
    name = re.sub(r"[^A-Za-z0-9._=,+-]", "_", "__".join(parts)) or "base"
    if len(name) > 100:
        name = name[:80] + "-" + hashlib.sha1(name.encode()).hexdigest()[:8]
    return name


@dataclass
class Plan:
    """A wedge checked and expanded: the base scene, the varied keys and every variant."""

    source: Path
    doc: dict
    keys: list[KeyPath]
    values: list[list]
    variants: list[Variant] = field(default_factory=list)

    @property
    def labels(self) -> list[str]:
        return [k.label for k in self.keys]


def plan_wedge(
    scene: str | os.PathLike[str],
    vary: Mapping[str, object] | Sequence[tuple[str, object]],
    *,
    yes: bool = False,
    limit: int = MAX_VARIANTS,
) -> Plan:
    """Check a wedge request and expand it into variants, each validated as a scene file.

    Args:
        scene: a scene file (or a bundled sample's name).
        vary: key path -> values (a list, or text for `parse_values`), in the order to nest
            them (the last key varies fastest).
        yes: allow more than `limit` variants.

    Raises:
        WedgeError, SceneError: one line naming the problem; nothing has run yet.
    """
    from .errors import SceneError
    from .io.scene import parse_scene, read_scene, resolve_scene_path

    source = resolve_scene_path(scene)
    doc = tomllib.loads(read_scene(source).text or "")  # the unchanged file must load first, with its own errors
    items = list(vary.items()) if isinstance(vary, Mapping) else list(vary)
    if not items:
        raise WedgeError("nothing to vary: give at least one --vary KEY=VALUES")
    keys: list[KeyPath] = []
    values: list[list] = []
    for key_text, vals in items:
        key = parse_key(key_text, doc)
        if key.label in [k.label for k in keys]:
            raise WedgeError(f"key path {key.label!r} is varied twice")
        try:
            vals = parse_values(vals)
        except WedgeError as exc:
            raise WedgeError(f"--vary {key.label}: {exc}") from None
        keys.append(key)
        values.append(vals)
    total = math.prod(len(v) for v in values)
    if total > MAX_VARIANTS_EVER:
        raise WedgeError(
            f"{total:,} variants ({' x '.join(str(len(v)) for v in values)}) is more than a wedge runs, "
            f"{MAX_VARIANTS_EVER:,} even with --yes"
        )
    if total > limit and not yes:
        raise WedgeError(
            f"{total:,} variants is more than the limit of {limit:,} "
            f"({' x '.join(str(len(v)) for v in values)}); pass --yes (yes=True) to run them all"
        )
    plan = Plan(source=source, doc=doc, keys=keys, values=values)

    # each value alone first, so that a bad one is named by itself
    for key, vals in zip(keys, values):
        for v in vals:
            trial = copy.deepcopy(doc)
            apply_value(trial, key, v)
            try:
                parse_scene(scene_text(trial), path=source)
            except SceneError as exc:
                raise WedgeError(f"--vary {key.label}={format_value(v)}: {exc}") from None

    names = set()
    for combo in itertools.product(*values):
        chosen = dict(zip(plan.labels, combo))
        trial = copy.deepcopy(doc)
        for key, v in zip(keys, combo):
            apply_value(trial, key, v)
        header = f"variant of {source} with " + ", ".join(f"{k} = {format_value(v)}" for k, v in chosen.items())
        text = scene_text(trial, header)
        try:
            dt = parse_scene(text, path=source).dt
        except SceneError as exc:
            raise WedgeError(
                f"variant {', '.join(f'{k}={format_value(v)}' for k, v in chosen.items())}: {exc}"
            ) from None
        name = _slug(chosen)
        if name in names:
            name += "-" + hashlib.sha1(json.dumps(combo).encode()).hexdigest()[:8]
        names.add(name)
        plan.variants.append(Variant(name, chosen, text, dt))
    return plan


# ---------------------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class Settings:
    """How each variant runs and what it keeps (part of a variant's identity for resuming)."""

    duration: float = 2.0
    fps: float = 30.0
    keep: tuple[str, ...] = ()
    image_size: tuple[int, int] = (320, 180)
    device: str = "cpu"

    def identity(self) -> dict:
        return {
            "duration": self.duration,
            "fps": self.fps,
            "keep": sorted(self.keep),
            "image_size": list(self.image_size),
            "device": self.device,
        }


def check_settings(settings: Settings) -> Settings:
    """Reject a bad duration, fps, keep or image size (WedgeError, one line)."""
    if not (math.isfinite(settings.duration) and settings.duration > 0):
        raise WedgeError(f"duration must be a positive number of seconds, got {settings.duration:g}")
    if not (math.isfinite(settings.fps) and settings.fps > 0):
        raise WedgeError(f"fps must be a positive number, got {settings.fps:g}")
    for k in settings.keep:
        if k not in KEEP:
            raise WedgeError(f"unknown --keep {k!r}{_suggest(k, KEEP)}; choose from {', '.join(KEEP)}")
    if "usd" in settings.keep:
        if usd_exporter() is None:
            raise WedgeError("--keep usd: this Tumble has no USD exporter (tumble.io.usd.export)")
        from .io.usd import require_pxr

        require_pxr()  # one line naming the pip command when usd-core is missing
    w, h = settings.image_size
    if not (16 <= w <= 4096 and 16 <= h <= 4096):
        raise WedgeError(f"image size must be between 16x16 and 4096x4096, got {w}x{h}")
    return settings


def _suggest(word: str, options) -> str:
    close = difflib.get_close_matches(word, list(options), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def usd_exporter():
    """`tumble.io.usd.export` (issue 17), else None: the hook of --keep usd, given the variant's recording."""
    try:
        from .io import usd
    except ImportError:
        return None
    return getattr(usd, "export", None)


def step_count(duration: float, dt: float) -> int:
    """Steps a run of `duration` takes at `dt`: the same count as `tumble run --duration`."""
    return max(1, round(duration / dt))


# ---------------------------------------------------------------------------------------- files


def atomic_write(path, data: bytes | str) -> Path:
    """Write `data` to `path` through `tumble.io.atomic.atomic_path` (a temporary file beside it, renamed)."""
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(data.encode() if isinstance(data, str) else data)
    return Path(path)


# ---------------------------------------------------------------------------------------- on a worker

_worker: dict = {}  # per worker process: the renderer (or why there is none)


def _renderer(size: tuple[int, int]):
    """This process's headless renderer at `size`, made once; None (and the reason) without EGL."""
    if "renderer" not in _worker:
        from .render import Renderer, create_context

        try:
            _worker["renderer"] = Renderer(create_context(), *size, samples=4)
            _worker["render_error"] = None
        except Exception as exc:  # noqa: BLE001 - no EGL / GL on this worker: the variant runs, without images
            _worker["renderer"] = None
            _worker["render_error"] = _one_line(exc)
    renderer = _worker["renderer"]
    if renderer is not None:
        renderer.resize(*size)
    return renderer, _worker["render_error"]


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    name = "out of memory" if isinstance(exc, MemoryError) else type(exc).__name__
    return f"{name}: {text[0]}" if text else name


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().name)
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


def _contact_extremes(world) -> tuple[float, float]:
    """Largest body-body overlap and largest body-plane penetration [m] among the current contacts."""
    import numpy as np

    from .shapes import ShapeType

    if world.contact_count == 0:
        return 0.0, 0.0
    depth = np.asarray(world.contact_depth)
    pair = np.asarray(world.contact_pair)
    plane = np.asarray(world.body_shape) == ShapeType.PLANE
    touches_plane = plane[pair[:, 0]] | plane[pair[:, 1]]
    overlap = depth[~touches_plane]
    penetration = depth[touches_plane]
    return (
        max(0.0, float(overlap.max())) if len(overlap) else 0.0,
        max(0.0, float(penetration.max())) if len(penetration) else 0.0,
    )


def run_variant(task: dict) -> dict:
    """Run one variant (on a worker) and return its manifest row; never raises.

    Args:
        task: {"name", "text" (scene TOML), "path" (for messages), "folder" (for kept files),
            "settings" (Settings.identity())}.

    Returns:
        The row: status "ok" or "failed" with a one-line `error`, wall time, steps/s, the
        summary figures, the state hash, and `final_png` (bytes of the final frame, or None).
    """
    start = time.perf_counter()
    s = task["settings"]
    keep = set(s["keep"])
    folder = Path(task["folder"])
    row: dict = {"status": "failed", "error": "", "worker": _worker_name(), "final_png": None}
    try:
        import numpy as np

        from .io.record import Recorder
        from .io.scene import build_world, parse_scene
        from .runtime import init_warp

        init_warp()
        world = build_world(parse_scene(task["text"], path=task["path"]), device=s["device"])
        steps = step_count(s["duration"], world.dt)
        size = tuple(s["image_size"])
        renderer, render_error = _renderer(size)
        camera = None
        if renderer is not None:
            from .render import Camera

            camera = Camera.for_world(world, aspect=size[0] / size[1])
        if keep & {"record", "usd", "figures"}:
            recorder = Recorder(world, fps=min(s["fps"], 1.0 / world.dt))  # at most a frame a step
        else:
            recorder = None
        frames: list[np.ndarray] | None = [] if "video" in keep and renderer is not None else None
        if frames is not None:
            frames.append(renderer.render(world, camera))

        # step as `tumble run` does; sample the contacts and the strain at the recording rate
        overlap = penetration = strain = 0.0
        cloth = world.cloth if world.has_cloth else None
        due, stepping = 0, time.perf_counter()
        for k in range(steps):
            world.step()
            if recorder is not None:
                recorder(world)
            if world.time + 0.5 * world.dt >= (due + 1) / s["fps"] or k == steps - 1:
                due += 1
                o, p = _contact_extremes(world)
                overlap, penetration = max(overlap, o), max(penetration, p)
                if cloth is not None:
                    strain = max(strain, float(cloth.max_strain()))
                if frames is not None:
                    frames.append(renderer.render(world, camera))
        world.check_finite()  # (each step checks the state it starts from: this is what the last one left)
        stepping = time.perf_counter() - stepping

        row.update(
            {
                "steps": steps,
                "steps_per_s": steps / stepping if stepping > 0 else None,
                "kinetic_energy_J": world.kinetic_energy(),
                "max_overlap_m": overlap,
                "max_penetration_m": penetration,
                "max_strain": strain if cloth is not None else None,  # JSON null, an empty CSV cell
                "body_count": int(world.body_count),
                "contact_count": int(world.contact_count),
                "state_hash": world.state_hash(),
            }
        )
        if not np.isfinite(row["kinetic_energy_J"]):
            raise FloatingPointError("the kinetic energy is not finite at the end (the simulation diverged)")

        # the files asked for; then the final frame for the contact sheet
        files = _write_kept(world, folder, keep, recorder, frames, s["fps"])
        row["files"] = files
        if renderer is not None:
            from PIL import Image

            buffer = io.BytesIO()
            Image.fromarray(renderer.render(world, camera)).save(buffer, format="PNG")
            row["final_png"] = buffer.getvalue()
        else:
            row["image_error"] = render_error
        row["status"] = "ok"
    except BaseException as exc:  # a failed variant is a row, never a lost wedge
        if isinstance(exc, KeyboardInterrupt):
            raise
        row["error"] = _one_line(exc)
    row["wall_s"] = time.perf_counter() - start
    return row


def _write_kept(world, folder: Path, keep: set, recorder, frames, fps: float) -> list[str]:
    """Write the recording, video, USD stage and figures a variant keeps; returns their names."""
    written: list[str] = []
    if not keep:
        return written
    folder.mkdir(parents=True, exist_ok=True)
    record = folder / "record.npz"
    if recorder is not None:
        with atomic_path(record) as tmp:
            recorder.save(tmp)
        if "record" in keep:
            written.append(record.name)
    try:
        if "video" in keep and frames:
            from .io.video import FfmpegWriter

            # (`tumble render`'s writer: ffmpeg's failures, a full disk among them, raise one line, and the
            # short file is not renamed into place)
            size = (frames[0].shape[1], frames[0].shape[0])
            with atomic_path(folder / "video.mp4") as tmp, FfmpegWriter(tmp, size, fps) as writer:
                for image in frames:
                    writer.append(image)
            written.append("video.mp4")
        if "usd" in keep:
            usd_exporter()(record, folder / "scene.usdc")  # the recording, at its fps; written atomically
            written.append("scene.usdc")
        if "figures" in keep:
            from .io.plot import plot_record

            with atomic_path(folder / "plot.png") as tmp:
                plot_record(record, tmp)
            written.append("plot.png")
    finally:
        if "record" not in keep:
            with contextlib.suppress(FileNotFoundError):
                record.unlink()
    return written


# ---------------------------------------------------------------------------------------- the cluster


def warp_cache_dir() -> str:
    """The value of WARP_CACHE_PATH that gives workers this process's kernel cache.

    Warp keeps its kernels in WARP_CACHE_PATH/<warp version> (default ~/.cache/warp/<version>),
    so the workers get the base folder, not the versioned one.
    """
    if os.environ.get("WARP_CACHE_PATH"):
        return os.environ["WARP_CACHE_PATH"]
    import warp as wp

    from .runtime import init_warp

    init_warp()
    resolved = Path(str(wp.config.kernel_cache_dir))
    return str(resolved.parent if resolved.name == wp.config.version else resolved)


#: seconds to wait for a local cluster's workers to shut down after a wedge
CLOSE_TIMEOUT = 60.0


@contextlib.contextmanager
def cluster(address=None, *, workers: int | None = None, timeout: float = CONNECT_TIMEOUT):
    """A Dask client: on an existing scheduler (`address`, or a scheduler file .json), the
    `distributed.Client` given as `address` itself (left open), or on a new local cluster of
    `workers` single-threaded processes (default: one per core) sharing this process's Warp
    kernel cache.

    Raises:
        WedgeError: no scheduler answered at `address` within `timeout` seconds.
    """
    import logging

    from distributed import Client, LocalCluster

    if address is not None and not isinstance(address, str):  # a distributed.Client made by the caller
        yield address
        return
    if address:
        try:
            if address.endswith(".json"):
                client = Client(scheduler_file=address, timeout=timeout)
            else:
                client = Client(address, timeout=timeout)
        except (OSError, TimeoutError, ValueError) as exc:
            raise WedgeError(
                f"--address {address}: no Dask scheduler answered within {timeout:g} s ({_one_line(exc)})"
            ) from None
        try:
            yield client
        finally:
            client.close()
        return
    n = workers or os.cpu_count() or 1
    local: LocalCluster | None = None
    local_client: Client | None = None
    interrupted = False
    try:
        # a Ctrl-C stopping a cluster half started left it to fail at exit; one reaching a worker
        # still importing printed its traceback
        with interrupt_after(), _spawned_without_sigint():
            local = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
                env={"WARP_CACHE_PATH": warp_cache_dir()},
                preload=[__name__],  # dask_setup: a Ctrl-C is this process's to handle, not the workers'
            )
        local_client = Client(local)
        yield local_client
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        # the results are in by now: a slow shutdown on a busy machine is waited for, then let go
        # (Dask's own 5 s would raise TimeoutError after a finished wedge); after a Ctrl-C, what
        # Dask logs of the tasks it cancels is not the user's business (a traceback of CancelledError)
        from distributed.utils import silence_logging_cmgr

        with silence_logging_cmgr(logging.CRITICAL) if interrupted else contextlib.nullcontext():
            if local_client is not None:
                with contextlib.suppress(TimeoutError):
                    local_client.close(timeout=CLOSE_TIMEOUT)
            if local is not None:
                with contextlib.suppress(TimeoutError):
                    local.close(timeout=CLOSE_TIMEOUT)


@contextlib.contextmanager
def interrupt_after():
    """Hold back a Ctrl-C or a SIGTERM until the block has run, then handle it as the handler in place
    before the block does (KeyboardInterrupt; the command's Terminated), also in place of an error
    the block raised meanwhile. A SIGTERM reaching a local cluster half started left Dask's exit
    handler to close it, which failed with a traceback.

    Outside the main thread (where signals cannot be caught) nothing changes.
    """
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    from . import signals

    received: list[int] = []
    previous = signals.replace(signals.ENDING, lambda signum, frame: received.append(signum))
    try:
        yield
    except Exception:
        if received:  # what the signal broke (a worker it stopped as it started)
            signals.restore(previous)
            try:
                _deliver(received[0])
            except BaseException as exc:
                raise exc from None
        raise
    finally:
        signals.restore(previous)
    if received:
        _deliver(received[0])


def _deliver(number: int) -> None:
    """Handle the signal `number` as its handler now does: call it, or take the default action."""
    import signal

    handler = signal.getsignal(number)
    if callable(handler):
        handler(number, None)
    elif handler == signal.SIG_DFL:
        signal.raise_signal(number)
    if number == signal.SIGINT:  # a handler that returned: a Ctrl-C still ends the block
        raise KeyboardInterrupt


@contextlib.contextmanager
def _spawned_without_sigint():
    """Processes that multiprocessing spawns in the block start with SIGINT blocked, for good.

    A terminal sends a Ctrl-C to every process of the command. A local cluster's worker that got it
    while still importing (about 2 s, before its preload `dask_setup` ignores it) printed a
    KeyboardInterrupt traceback. The mask a thread has when it starts a process is the new process's
    (and stays through exec, where a handler would not), so the spawning call blocks SIGINT in its
    own thread around the start (Dask starts workers from threads of its own, where no handler can be
    set). The wedge's own process still gets the Ctrl-C, stops, and closes the cluster.
    """
    import multiprocessing.util as mp_util
    import signal

    spawn = getattr(mp_util, "spawnv_passfds", None)
    mask = getattr(signal, "pthread_sigmask", None)
    if spawn is None or mask is None:  # (not POSIX)
        yield
        return

    def spawn_blocked(*args, **kwargs):
        before = mask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            return spawn(*args, **kwargs)
        finally:
            mask(signal.SIG_SETMASK, before)

    mp_util.spawnv_passfds = spawn_blocked
    try:
        yield
    finally:
        mp_util.spawnv_passfds = spawn


def dask_setup(worker) -> None:
    """Dask's preload hook, run in each worker of a local cluster as it starts: ignore SIGINT.

    A terminal sends a Ctrl-C to every process of the command: each worker printed a
    KeyboardInterrupt traceback. The wedge's own process stops it and closes the cluster.
    """
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def check_address(address: str | None) -> None:
    """Reject a malformed --address before connecting (WedgeError)."""
    if address is None or not isinstance(address, str):
        return
    if address.endswith(".json"):
        if not Path(address).is_file():
            raise WedgeError(f"--address {address}: no such scheduler file")
        return
    if not re.fullmatch(r"(tcp|tls|ucx|inproc|ws|wss)://\S+|[^\s/:]+:\d+", address):
        raise WedgeError(
            f"--address {address!r} should be a scheduler address like tcp://host:8786 or a scheduler file (.json)"
        )


# ---------------------------------------------------------------------------------------- the wedge


class Table:
    """Rows of a wedge's results, in grid order: `table[i]` is a row (dict), `table["col"]` a column.

    Attributes:
        rows: one dict per variant (the manifest's columns).
        columns: column names, varied keys first.
        out: the wedge's output folder.
    """

    def __init__(self, rows: list[dict], columns: list[str], out: Path):
        self.rows, self.columns, self.out = rows, columns, out

    def __len__(self) -> int:
        return len(self.rows)

    def __iter__(self):
        return iter(self.rows)

    def __getitem__(self, item):
        if isinstance(item, str):
            return [row.get(item) for row in self.rows]
        return self.rows[item]

    @property
    def failed(self) -> list[dict]:
        return [row for row in self.rows if row.get("status") != "ok"]

    def to_pandas(self):
        """The table as a pandas DataFrame (needs pandas)."""
        import pandas as pd

        return pd.DataFrame(self.rows, columns=self.columns)

    def __repr__(self) -> str:
        done = sum(row.get("status") == "ok" for row in self.rows)
        return f"<wedge Table: {len(self.rows)} variants, {done} ok, {len(self.failed)} failed, in {self.out}>"


def _read_result(folder: Path) -> dict | None:
    try:
        return json.loads((folder / "result.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _is_done(result: dict | None, variant: Variant, settings: Settings, retry_failed: bool) -> TypeGuard[dict]:
    """Whether a variant's earlier result stands: same scene text and settings, and ok, or failed
    in the simulation itself (Tumble is deterministic, so it would fail the same way again)
    unless `retry_failed`; a variant that never finished on a worker (`lost`) is run again."""
    if result is None or result.get("scene_sha") != variant.scene_sha or result.get("settings") != settings.identity():
        return False
    if result.get("status") == "ok":
        return True
    return result.get("status") == "failed" and not retry_failed and not result.get("lost")


def wedge(
    scene: str | os.PathLike[str],
    vary: Mapping[str, object] | Sequence[tuple[str, object]],
    *,
    out: str | os.PathLike[str],
    duration: float = 2.0,
    fps: float = 30.0,
    keep: Iterable[str] = (),
    address: str | None = None,
    workers: int | None = None,
    yes: bool = False,
    image_size: tuple[int, int] = (320, 180),
    device: str = "cpu",
    progress: bool | None = None,
    retry_failed: bool = False,
    connect_timeout: float = CONNECT_TIMEOUT,
    contact_sheet: bool = True,
    summary_figure: bool | None = None,
) -> Table:
    """Run `scene` over every combination of the values in `vary`, each variant its own simulation.

    Args:
        scene: a scene file (.toml) or a bundled sample's name.
        vary: key path -> values, e.g. {"plane[*].friction": [0.2, 0.5], "world.seed": "0..9"}
            (see `parse_key`, `parse_values`); the last key varies fastest.
        out: output folder (created); OUTDIR/manifest.csv, manifest.json, contact_sheet.png and
            one folder per variant (scene.toml, result.json, final.png, and what `keep` asks).
        duration: simulated seconds per variant (as `tumble run --duration`).
        fps: rate of the recording, the video and the sampling of overlaps and strain.
        keep: any of "record" (record.npz), "video" (video.mp4), "usd" (scene.usdc, needs
            tumble.io.usd), "figures" (plot.png per variant and OUTDIR/summary.png).
        address: an existing Dask scheduler ("tcp://host:8786" or a scheduler file .json), or
            a `distributed.Client` (e.g. of a dask-jobqueue SLURMCluster); default a local
            cluster of `workers` processes (default one per core).
        yes: allow more than `MAX_VARIANTS` variants.
        image_size: (width, height) of each variant's final frame on the contact sheet.
        device: Warp device of every variant ("cpu" or "cuda").
        progress: show progress on stderr (default: a bar when stderr is a terminal; True
            off a terminal prints one line per finished variant).
        retry_failed: run variants that failed before again (by default only those whose
            worker was lost are).
        connect_timeout: seconds to wait for the scheduler at `address`.
        contact_sheet: write OUTDIR/contact_sheet.png.
        summary_figure: write OUTDIR/summary.png (default: when `keep` has "figures").

    Returns:
        A `Table` of one row per variant, in grid order. Variants already done (same scene
        text and settings) are read back, not run again; failures are rows with an error.

    Raises:
        WedgeError, SceneError: bad input, before anything runs or is written.
    """
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise WedgeError(
            "wedges run on Dask distributed, which is not installed: pip install 'tumble[wedge]'"
        ) from None
    settings = check_settings(
        Settings(
            duration=float(duration),
            fps=float(fps),
            keep=tuple(sorted(set(keep))),
            image_size=tuple(int(v) for v in image_size),  # type: ignore[arg-type]  # check_settings checks the length
            device=device,
        )
    )
    check_address(address)
    if not (math.isfinite(connect_timeout) and connect_timeout > 0):
        raise WedgeError(f"connect timeout must be a positive number of seconds, got {connect_timeout:g}")
    plan = plan_wedge(scene, vary, yes=yes)
    smallest = min(plan.variants, key=lambda v: v.dt)  # the most steps
    try:
        limits.check_steps("duration", settings.duration, smallest.dt)
    except limits.LimitError as exc:
        where = f" (variant {smallest.name})" if len(plan.variants) > 1 else ""
        raise WedgeError(f"{exc}{where}") from None
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise WedgeError(f"-o {out}: exists and is not a folder")
    if not out.parent.exists() and not out.exists():
        raise WedgeError(f"-o {out}: no such folder {str(out.parent)!r}")

    results: dict[str, dict] = {}
    for v in plan.variants:
        r = _read_result(out / v.name)
        if _is_done(r, v, settings, retry_failed):
            results[v.name] = r
    todo = [v for v in plan.variants if v.name not in results]
    if address is None and todo:  # a local cluster: no more processes than variants to run, each in memory
        if workers is not None:
            workers = validate.integer(workers, "workers", low=1)
        workers = min(workers or os.cpu_count() or 1, len(todo))
        limits.check_memory("--workers", "worker processes", workers, limits.BYTES_PER_WORKER)

    report = _Progress(len(plan.variants), len(results), progress)
    write = _ManifestWriter(plan, settings, out)
    runner = cluster(address, workers=workers, timeout=connect_timeout) if todo else contextlib.nullcontext()
    try:
        with runner as client:
            out.mkdir(exist_ok=True)
            try:
                if client is not None:
                    report.start(engine=_describe(client))
                    _run_all(client, plan, todo, settings, out, results, report, write)
            finally:
                report.stop()
                rows = write(results, force=True)
    finally:
        # a worker stopped in the middle of a write (Ctrl-C closes the cluster; a worker killed
        # for memory) left its temporary file: the folders hold only whole files
        for v in todo:
            remove_partial_writes(out / v.name)
    if contact_sheet:
        message = write_contact_sheet(plan, rows, out)
        if message:
            print(f"tumble wedge: {message}", file=sys.stderr)
    if summary_figure or (summary_figure is None and "figures" in settings.keep):
        plot_wedge(out)
    return Table(rows, write.columns, out)


#: the files of a variant's folder: its scene, its result and final frame, and those `keep` asks for
VARIANT_FILES = ("scene.toml", "result.json", "final.png", "record.npz", "video.mp4", "scene.usdc", "plot.png")
#: the temporary names they are written under (`tumble.io.atomic`, which the USD export uses too):
#: .NAME.XXXXXXXX.tmpSUFFIX, XXXXXXXX being `tempfile`'s random letters
_PARTIAL = re.compile(
    "|".join(rf"\.{re.escape(name)}\.[a-z0-9_]{{8}}\.tmp{re.escape(Path(name).suffix)}" for name in VARIANT_FILES)
)


def remove_partial_writes(folder: Path) -> list[str]:
    """Remove from a variant's `folder` the temporary files of writes that never finished; returns their names.

    Only names `VARIANT_FILES` are written under are touched; anything else in the folder is left.
    """
    removed = []
    with contextlib.suppress(OSError):
        for path in folder.iterdir():
            if _PARTIAL.fullmatch(path.name) and path.is_file():
                with contextlib.suppress(OSError):
                    path.unlink()
                    removed.append(path.name)
    return removed


def _describe(client) -> str:
    info = client.scheduler_info()
    workers = info.get("workers", {})
    threads = sum(w.get("nthreads", 1) for w in workers.values())
    return f"{len(workers)} worker{'' if len(workers) == 1 else 's'} ({threads} threads) at {info.get('address', '?')}"


def _run_all(
    client, plan: Plan, todo: list[Variant], settings: Settings, out: Path, results: dict, report, write
) -> None:
    from distributed import as_completed

    futures = {}
    for v in todo:
        folder = out / v.name
        folder.mkdir(exist_ok=True)
        atomic_write(folder / "scene.toml", v.text)
        task = {
            "name": v.name,
            "text": v.text,
            "path": str(folder / "scene.toml"),
            "folder": str(folder.resolve()),
            "settings": settings.identity(),
        }
        future = client.submit(run_variant, task, key=f"tumble-wedge-{v.name}-{v.scene_sha[:12]}", pure=False)
        futures[future] = v
    for future in as_completed(futures):
        v = futures[future]
        try:
            row = future.result()
        except Exception as exc:  # noqa: BLE001 - the worker died (killed, out of memory) or the task could not run
            row = {"status": "failed", "error": _lost(exc), "lost": True, "final_png": None}
        png = row.pop("final_png", None)
        if png:
            atomic_write(out / v.name / "final.png", png)
        row.update({"variant": v.name, **v.values, "scene_sha": v.scene_sha, "settings": settings.identity()})
        atomic_write(out / v.name / "result.json", json.dumps(_finite(row), indent=1, default=_json_default))
        results[v.name] = row
        future.release()
        report.advance(v, row)
        write(results)


def _lost(exc: BaseException) -> str:
    """One line for a variant that never finished on a worker (killed, or an environment problem)."""
    from distributed.scheduler import KilledWorker

    text = " ".join(str(exc).split())
    text = text if len(text) <= 240 else text[:237] + "..."
    if isinstance(exc, KilledWorker):
        return f"worker lost (killed, e.g. out of memory): {text}"
    return f"not run: {type(exc).__name__}: {text}"


def _finite(value):
    """`value` with every NaN or infinite float replaced by None (JSON has neither)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def _json_default(value):
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


class _ManifestWriter:
    """Writes OUTDIR/manifest.csv and .json: one row per variant in grid order (pending ones too)."""

    def __init__(self, plan: Plan, settings: Settings, out: Path, every: float = 1.0):
        self.plan, self.settings, self.out, self.every = plan, settings, out, every
        self.columns = ["variant", *plan.labels, *COLUMNS]
        self.last = 0.0

    def __call__(self, results: dict, *, force: bool = False) -> list[dict]:
        rows = []
        for v in self.plan.variants:
            r = results.get(v.name) or {"status": "pending"}
            row = {"variant": v.name, **v.values}
            row.update({c: r.get(c, "") for c in COLUMNS})
            rows.append(row)
        now = time.monotonic()
        if not force and now - self.last < self.every:
            return rows
        self.last = now
        meta = {
            "scene": str(self.plan.source),
            "vary": {k: v for k, v in zip(self.plan.labels, self.plan.values)},
            "settings": self.settings.identity(),
            "engine": "dask.distributed",
            "columns": self.columns,
            "variants": rows,
        }
        atomic_write(self.out / "manifest.json", json.dumps(_finite(meta), indent=1, default=_json_default))
        text = io.StringIO()
        w = csv.writer(text, lineterminator="\n")
        w.writerow(self.columns)
        for row in rows:
            w.writerow([_csv_cell(row.get(c, "")) for c in self.columns])
        atomic_write(self.out / "manifest.csv", text.getvalue())
        return rows


def _csv_cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    if isinstance(value, (list, tuple, dict, bool)):
        return format_value(value)
    return str(value)


class _Progress:
    """Variants done and left, failures, elapsed time and time left, on stderr (rich)."""

    def __init__(self, total: int, done: int, enabled: bool | None):
        from rich.console import Console

        self.console = Console(stderr=True)
        self.total, self.done, self.failed = total, done, 0
        self.live = self.console.is_terminal if enabled is None else enabled
        self.lines = enabled is True and not self.console.is_terminal
        self.bar: Progress | None = None

    def start(self, engine: str) -> None:
        from rich.progress import TextColumn, TimeElapsedColumn

        if self.live or self.lines:
            skipped = f", {self.done} already done" if self.done else ""
            self.console.print(f"wedge: {self.total} variants{skipped}, on {engine}", highlight=False)
        if self.live and not self.lines:
            extra = (TextColumn("{task.fields[failed]}"), TimeElapsedColumn(), TextColumn("left"))
            self.bar = new_bar(self.console, "variants", extra=extra)
            self.bar.start()
            self.task = self.bar.add_task("wedge", total=self.total, completed=self.done, failed="")

    def advance(self, variant: Variant, row: dict) -> None:
        self.done += 1
        if row.get("status") != "ok":
            self.failed += 1
        if self.bar is not None:
            failed = f"[red]{self.failed} failed[/red]" if self.failed else ""
            self.bar.update(self.task, completed=self.done, failed=failed)
            if row.get("status") != "ok":
                self.bar.console.print(f"failed {variant.name}: {row.get('error')}", highlight=False, markup=False)
        elif self.lines:
            status = "ok" if row.get("status") == "ok" else f"failed: {row.get('error')}"
            print(
                f"[{self.done}/{self.total}] {variant.name} {status} ({row.get('wall_s', 0):.1f} s)",
                file=sys.stderr,
                flush=True,
            )

    def stop(self) -> None:
        if self.bar is not None:
            self.bar.stop()
            self.bar = None


# ---------------------------------------------------------------------------------------- pictures


def _labels(plan: Plan) -> list[str]:
    """Short names of the varied keys: the key alone unless two varied keys share it."""
    short = [k.key if k.component is None else f"{k.key}[{k.component}]" for k in plan.keys]
    return [s if short.count(s) == 1 else k.label for s, k in zip(short, plan.keys)]


def _font(size: int):
    from PIL import ImageFont

    for name in ("DejaVuSans.ttf", "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"):
        with contextlib.suppress(OSError):
            return ImageFont.truetype(name, size)
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1
        return ImageFont.load_default()


def write_contact_sheet(plan: Plan, rows: list[dict], out: Path, *, max_width: int = 4096) -> str | None:
    """OUTDIR/contact_sheet.png: every variant's final frame in a grid, labelled with its values.

    Returns:
        None when written, else why not (no variant has a final frame: no EGL on the workers).
    """
    from PIL import Image, ImageDraw

    images = {}
    for row in rows:
        path = out / row["variant"] / "final.png"
        if path.is_file():
            with contextlib.suppress(OSError):
                images[row["variant"]] = Image.open(path).convert("RGB")
    if not images:
        reasons = {r.get("image_error") for v in plan.variants if (r := _read_result(out / v.name))} - {None}
        why = f" ({reasons.pop()})" if reasons else ""
        return f"no contact sheet: no variant has a final frame{why}"
    tile_w, tile_h = next(iter(images.values())).size
    cols = min(len(rows), max(1, math.ceil(math.sqrt(len(rows)))), 16)
    scale = min(1.0, max_width / (cols * tile_w))
    tile_w, tile_h = max(16, int(tile_w * scale)), max(16, int(tile_h * scale))
    names = _labels(plan)
    font = _font(max(9, min(14, tile_w // 22)))
    line_h = font.size + 3 if hasattr(font, "size") else 14
    label_h = line_h * (len(names) + 1) + 4
    grid_rows = math.ceil(len(rows) / cols)
    sheet = Image.new("RGB", (cols * tile_w, grid_rows * (tile_h + label_h)), (24, 24, 28))
    draw = ImageDraw.Draw(sheet)
    for i, row in enumerate(rows):
        x, y = (i % cols) * tile_w, (i // cols) * (tile_h + label_h)
        image = images.get(row["variant"])
        if image is not None:
            sheet.paste(image.resize((tile_w, tile_h)), (x, y))
        else:
            draw.rectangle([x + 1, y + 1, x + tile_w - 2, y + tile_h - 2], fill=(60, 30, 30))
            draw.text((x + 6, y + 6), str(row.get("status", "")), fill=(255, 160, 160), font=font)
            draw.text((x + 6, y + 6 + line_h), str(row.get("error", ""))[:60], fill=(255, 200, 200), font=font)
        texts = [f"{n} = {format_value(row.get(k), digits=4)}" for n, k in zip(names, plan.labels)]
        texts.append(
            str(row.get("status"))
            if row.get("status") != "ok"
            else f"KE {_num(row.get('kinetic_energy_J'))} J  {_num(row.get('steps_per_s'))} steps/s"
        )
        for j, text in enumerate(texts):
            draw.text(
                (x + 5, y + tile_h + 3 + j * line_h),
                text,
                fill=(235, 235, 235) if j < len(names) else (150, 150, 160),
                font=font,
            )
    buffer = io.BytesIO()
    sheet.save(buffer, format="PNG")
    atomic_write(out / "contact_sheet.png", buffer.getvalue())
    return None


def _num(value) -> str:
    return f"{value:.3g}" if isinstance(value, (int, float)) else "?"


def read_manifest(outdir) -> dict:
    """OUTDIR/manifest.json of a wedge (WedgeError when it is missing or unreadable)."""
    path = Path(outdir) / "manifest.json"
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise WedgeError(f"{outdir}: no manifest.json (not a wedge's output folder)") from None
    except (OSError, ValueError) as exc:
        raise WedgeError(f"{path}: unreadable ({exc})") from None
    if not isinstance(meta, dict) or "variants" not in meta or "vary" not in meta:
        raise WedgeError(f"{path}: not a wedge manifest")
    return meta


def plot_wedge(outdir, out=None, *, dpi: int = 100) -> Path:
    """Draw each summary figure of a wedge against its varied values, to OUTDIR/summary.png (or `out`).

    The x axis is the first varied key with more than one number; each combination of the other
    keys' values is one line (the legend names them). Failed variants are left out and counted.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    meta = read_manifest(outdir)
    out = Path(outdir) / "summary.png" if out is None else Path(out)
    if not out.parent.exists():
        raise WedgeError(f"cannot write {str(out)!r}: folder {str(out.parent)!r} does not exist")
    labels = list(meta["vary"])
    rows = meta["variants"]
    ok = [r for r in rows if r.get("status") == "ok"]
    numeric = [
        k
        for k in labels
        if len({json.dumps(r[k]) for r in rows}) > 1
        and all(isinstance(r[k], (int, float)) and not isinstance(r[k], bool) for r in rows)
    ]
    xkey = numeric[0] if numeric else None
    others = [k for k in labels if k != xkey]
    metrics = [
        m
        for m in (*METRICS, "steps_per_s", "wall_s")
        if any(isinstance(r.get(m), (int, float)) and math.isfinite(r[m]) for r in ok)
    ]
    cols = 2 if len(metrics) > 1 else 1
    fig, axes = plt.subplots(
        math.ceil(len(metrics) / cols) or 1,
        cols,
        figsize=(5.5 * cols, 3.2 * math.ceil(max(len(metrics), 1) / cols)),
        squeeze=False,
    )
    groups: dict[str, list[dict]] = {}
    for r in ok:
        groups.setdefault(", ".join(f"{k}={format_value(r[k], digits=4)}" for k in others), []).append(r)
    for ax, metric in zip(axes.flat, metrics):
        for name, members in list(groups.items())[:12]:
            if xkey is None:
                xs = [rows.index(r) for r in members]
            else:
                members = sorted(members, key=lambda r: r[xkey])
                xs = [r[xkey] for r in members]
            ys = [r.get(metric) if isinstance(r.get(metric), (int, float)) else math.nan for r in members]
            ax.plot(xs, ys, "o-", ms=3, label=name or None)
        ax.set_title(
            METRICS.get(metric, {"steps_per_s": "steps per second", "wall_s": "wall time [s]"}.get(metric)), fontsize=9
        )
        ax.set_xlabel(xkey or "variant", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(metrics) :]:
        ax.axis("off")
    if others and len(groups) > 1:
        axes.flat[0].legend(fontsize=6, loc="best")
    failed = len(rows) - len(ok)
    fig.suptitle(
        f"wedge of {Path(meta['scene']).name}: {len(ok)} variants"
        + (f", {failed} failed or pending (not shown)" if failed else ""),
        fontsize=10,
    )
    fig.tight_layout()
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=dpi, format=out.suffix.lstrip(".") or "png")
    plt.close(fig)
    return out
