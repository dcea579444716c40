"""The Python API reference, docs/api.md, generated from the public signatures and docstrings.

    python -m tumble.apidoc            # rewrites docs/api.md (atomically)

`tests/unit/test_apidoc.py` checks that the page equals `render()` and, independently of how
`render` picks members, that every public name of `tumble` and of each class below (from
`dir()`) has its entry, so the page cannot fall behind the code.
"""

from __future__ import annotations

import dataclasses
import enum
import inspect
import os
import re
import tempfile
import typing
from pathlib import Path

import tumble
from tumble.keywords import defaults_of

#: classes of the reference, in page order
CLASSES = (
    tumble.World,
    tumble.BodyId,
    tumble.ClothId,
    tumble.JointId,
    tumble.Model,
    tumble.State,
    tumble.Control,
    tumble.BodyKind,
    tumble.BodyState,
    tumble.Emitter,
    tumble.ClothSystem,
    tumble.Wind,
    tumble.ShapeType,
    tumble.SolidOptions,
    tumble.TumbleError,
    tumble.SceneError,
    tumble.SimulationError,
    tumble.HandleError,
    tumble.Snapshot,
    tumble.SnapshotError,
)
#: functions of the package itself
FUNCTIONS = (tumble.load_scene, tumble.wedge, tumble.save_snapshot, tumble.read_snapshot, tumble.load_snapshot)
#: attributes every World instance has (set in __init__, so not found on the class)
WORLD_ATTRIBUTES = {
    "seed": "Seed of the world's random generator (int, as given).",
    "rng": "The world's `numpy.random.Generator` (emitters without a seed draw theirs from it).",
    "device": 'Warp device the arrays live on ("cpu", "cuda:0").',
    "profile": "Stage name -> cumulative seconds spent in it (validate, emit, layout, broad_phase, ...).",
    "metadata": 'Scene-file extras, e.g. `metadata["camera"]`, `metadata["path"]`.',
    "emitters": "The world's `Emitter`s, in the order added.",
    "model": "The `Model`: what does not change while stepping (body shapes, masses, materials; hulls, meshes).",
    "state": "The `State`: what changes (body poses and velocities, the warm-start contacts, `step_count`).",
    "control": "The `Control`: this step's inputs (user forces and torques).",
    "bodies": (
        "Engine internals: every body array as one table (`RowGroup` over the model's, state's, control's and "
        "the solver's sets; rows in storage order, `body_rows` maps ids to them). Not a stable API."
    ),
    "contacts": "Engine internals: the contact arrays (`ContactSet`). Not a stable API; read `contact_*` views.",
    "broadphase": "Engine internals: the broad phase's grid and pair buffers. Not a stable API.",
    "joints": "The joint arrays (`tumble.solver.joints.JointSet`); add joints with `add_joint`.",
}
INTRO = """\
# Python API reference

Generated from the code by `python -m tumble.apidoc`; a test keeps it in step with `dir()` of every
class below. [README.md](../README.md) shows the API in use; [design.md](design.md) the data layout.

Conventions:

- **Units** are SI: metres, kilograms, seconds, radians (degrees only for an emitter's `cone_angle`).
  Orientations are unit quaternions (x, y, z, w).
- **Arguments** are keyword-only and checked by name: a wrong type raises `TypeError`, a value out
  of range `ValueError`, both as "`<name> must be <what>, got <value>`".
- **Handles.** `add_plane`, `add_sphere`, `add_box` return a `BodyId`, `add_cloth` a `ClothId`,
  `add_emitter` the `Emitter`. A `BodyId` is an `int` (the body's id, so `world.body_position[ball]`
  works) that also carries its world and a generation: a world refuses a handle of another world
  or of a removed body with `HandleError`. Plain int ids are accepted too (checked only for being live).
- **Views** (`world.body_position`, `world.contact_pair`, `world.cloth.particle_position`, ...) are
  read afresh on every access: each is a read-only copy of that moment's state, one row per id.
  An array kept from an earlier access is a snapshot and never changes; read the property again
  after `step()`. Write state with `set_body_state` (or `ball.position = ...`), never into a view.
- **Removal.** `remove_body` frees the id; its rows in the views read NaN (shape and kind -1) and
  `body_alive` is False there until the next body added takes the id, with a new generation.
"""


def _public_members(cls) -> list[tuple[str, object]]:
    """(name, attribute) of the public members a class defines itself or inherits from Tumble classes."""
    seen: dict[str, object] = {}
    for base in reversed(cls.__mro__):
        if not base.__module__.startswith("tumble"):
            continue
        for name, value in vars(base).items():
            if name.startswith("_"):
                continue
            if isinstance(value, (staticmethod, classmethod)):
                value = value.__func__
            if callable(value) or isinstance(value, property):
                seen[name] = value
    return list(seen.items())


def _signature(name: str, func) -> str:
    """`name(arg: type = default, ...) -> type`, one argument a line when it is long."""
    try:
        sig = inspect.signature(func)
    except (TypeError, ValueError):
        return f"{name}(...)"
    params, star = [], False
    for p in sig.parameters.values():
        if p.name == "self":
            continue
        if p.kind == p.KEYWORD_ONLY and not star:
            params.append("*")
            star = True
        prefixes: dict[object, str] = {p.VAR_POSITIONAL: "*", p.VAR_KEYWORD: "**"}
        prefix = prefixes.get(p.kind, "")
        text = prefix + p.name
        if p.kind == p.VAR_POSITIONAL:
            star = True
        if p.annotation is not p.empty:
            text += f": {_annotation(p.annotation)}"
        if p.default is not p.empty:
            text += (" = " if p.annotation is not p.empty else "=") + repr(p.default)
        params.append(text)
    returns = "" if sig.return_annotation is sig.empty else f" -> {_annotation(sig.return_annotation)}"
    one_line = f"{name}({', '.join(params)}){returns}"
    if len(one_line) <= 100:
        return one_line
    return f"{name}(\n" + "".join(f"    {p},\n" for p in params) + f"){returns}"


def _annotation(annotation) -> str:
    return annotation if isinstance(annotation, str) else inspect.formatannotation(annotation)


_SECTION = re.compile(r"^(Args|Arguments|Keys|Returns|Raises|Attributes|Yields|Tuning attributes.*):$")
_ITEM = re.compile(r"^(\*{0,2}[A-Za-z_][\w, .*]*):\s*(.*)$")


def _markdown(doc: str | None) -> str:
    """A Google-style docstring as Markdown: sections bold, their items as a list, `::` blocks as code."""
    if not doc:
        return "(no docstring)"
    out: list[str] = []
    lines = inspect.cleandoc(doc).splitlines()
    in_section = code = False
    for line in lines:
        if code:
            if line.startswith("    ") or not line.strip():
                out.append(line[4:])
                continue
            while out and not out[-1].strip():
                out.pop()
            out.append("```")
            out.append("")
            code = False
        if line.rstrip().endswith("::") and not _SECTION.match(line):
            out.append(line.rstrip()[:-1])
            out.append("")
            out.append("```python")
            code = True
            continue
        match = _SECTION.match(line.strip()) if not line.startswith(" ") else None
        if match:
            out.append(f"**{match.group(1)}:**")
            out.append("")
            in_section = True
            continue
        if in_section and line.startswith("    "):
            body = line[4:]
            item = _ITEM.match(body) if not body.startswith(" ") else None
            if item:
                out.append(f"- `{item.group(1)}`: {item.group(2)}".rstrip())
            elif out and out[-1].strip() and not out[-1].startswith("**"):
                out[-1] += " " + body.strip()
            else:
                out.append(body.strip())
            continue
        if not line.strip():
            in_section = False
        out.append(line)
    if code:
        while out and not out[-1].strip():
            out.pop()
        out.append("```")
    return "\n".join(out).strip()


def _keyword_set(cls) -> list[str]:
    """A keyword set (a TypedDict taken as `**options`): its docstring, then a table of its keys."""
    name, default = cls.__name__, defaults_of(cls)
    parts = [f"## `tumble.{name}` (keywords)", "", _markdown(cls.__doc__), ""]
    parts += ["| key | type | default |", "|---|---|---|"]
    for key, annotation in cls.__annotations__.items():
        shown = getattr(
            annotation, "__forward_arg__", annotation
        )  # a TypedDict keeps its keys' annotations as ForwardRefs
        cells = (key, _annotation(shown), repr(default[key]))
        parts.append("| " + " | ".join(f"`{c}`".replace("|", "\\|") for c in cells) + " |")
    return [*parts, ""]


def _class_section(cls) -> list[str]:
    if typing.is_typeddict(cls):
        return _keyword_set(cls)
    name = cls.__name__
    kind = "exception" if issubclass(cls, BaseException) else "enum" if issubclass(cls, enum.Enum) else "class"
    parts = [f"## `tumble.{name}` ({kind})", ""]
    if kind == "class" and not issubclass(cls, tuple) and not dataclasses.is_dataclass(cls):
        parts += ["```python", _signature(name, cls), "```", ""]
    parts += [_markdown(cls.__doc__), ""]
    if issubclass(cls, enum.Enum):
        parts += ["| member | value |", "|---|---|"]
        parts += [f"| `{name}.{m.name}` | {m.value} |" for m in cls]
        parts.append("")
        return parts
    fields: tuple[str, ...] = ()
    if issubclass(cls, tuple) and hasattr(cls, "_fields"):
        fields = cls._fields  # a NamedTuple
    elif dataclasses.is_dataclass(cls):
        parts += ["```python", _signature(name, cls), "```", ""]
        fields = tuple(f.name for f in dataclasses.fields(cls))
    if fields:
        parts += ["**Fields:** " + ", ".join(f"`{name}.{f}`" for f in fields) + ".", ""]
    if cls is tumble.World:
        for attr, text in WORLD_ATTRIBUTES.items():
            parts += [f"### `World.{attr}` (attribute)", "", text, ""]
    for member, value in _public_members(cls):
        if isinstance(value, property):
            note = "property, settable" if value.fset is not None else "property"
            parts += [f"### `{name}.{member}` ({note})", "", _markdown(value.__doc__), ""]
        else:
            parts += [
                f"### `{name}.{member}`",
                "",
                "```python",
                _signature(member, value),
                "```",
                "",
                _markdown(value.__doc__),
                "",
            ]
    return parts


def render() -> str:
    """The whole page, as Markdown."""
    parts = [INTRO, "## Contents", ""]
    parts += [f"- [`tumble.{f.__name__}`](#tumble{f.__name__.lower()})" for f in FUNCTIONS]
    parts += [f"- `tumble.{c.__name__}`" for c in CLASSES]
    parts.append("")
    for func in FUNCTIONS:
        parts += [
            f"## `tumble.{func.__name__}`",
            "",
            "```python",
            _signature(func.__name__, func),
            "```",
            "",
            _markdown(func.__doc__),
            "",
        ]
    for cls in CLASSES:
        parts += _class_section(cls)
    text = "\n".join(parts)
    return re.sub(r"\n{3,}", "\n\n", text).rstrip() + "\n"


def write(path: Path) -> None:
    """Write the page to `path` atomically (a temporary file beside it, then renamed)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(render())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(prog="python -m tumble.apidoc", description="Rewrite the API reference page.")
    parser.add_argument("target", nargs="?", type=Path, help="the page to write (default: docs/api.md)")
    target = parser.parse_args().target or Path(__file__).resolve().parents[2] / "docs" / "api.md"
    write(target)
    print(f"wrote {target}")
