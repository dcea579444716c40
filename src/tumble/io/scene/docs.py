"""The scene reference of docs/scenes.md, generated from `schema.SCHEMA` (`python -m tumble.io.scene`)."""

from __future__ import annotations

from .schema import REQUIRED, SCHEMA

# ---------------------------------------------------------------------------------------- docs


def reference_markdown() -> str:
    """The key reference of every table, as Markdown (pasted into docs/scenes.md; a test compares)."""
    lines = []
    for spec in SCHEMA.values():
        header = f"[[{spec.name}]]" if spec.array else f"[{spec.name}]"
        lines += [
            f"### `{header}`",
            "",
            spec.doc,
            "",
            "| key | type | default | units | meaning |",
            "|---|---|---|---|---|",
        ]
        for key, f in spec.fields.items():
            if f.default is REQUIRED:
                default = "required"
            elif f.default is None:
                default = f.shown_default or "none"
            elif f.shown_default is not None:
                default = f.shown_default
            else:
                default = _toml_value(f.default)
            lines.append(f"| `{key}` | {f.check.kind} | {default} | {f.units} | {f.doc} |")
        lines.append("")
    return "\n".join(lines)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "`true`" if value else "`false`"
    if isinstance(value, str):
        return f'`"{value}"`'
    if isinstance(value, list):
        return "`[" + ", ".join(f"{v:g}" for v in value) + "]`"
    if isinstance(value, float):
        return f"`{value:g}`"
    return f"`{value}`"
