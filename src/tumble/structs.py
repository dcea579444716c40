"""Warp structs of arrays derived from a field table, so that a set of arrays is declared once.

A table such as `JOINT_FIELDS` (name -> Warp dtype of one row) declares the arrays of an
`ArraySet`. `array_struct` makes from it the Warp struct that kernels take instead of one
argument per array (one array field per entry, named without the table's prefix:
`joint_body_a` -> `body_a`), and `fill_struct` points one at an ArraySet's arrays. Build a
struct once per set of arrays and keep it: setting each array field costs a few microseconds of
Python, and a recorded launch (`launch.LaunchCache`) re-packs a struct argument only when it is
another struct.
"""

from __future__ import annotations

from typing import Any

import warp as wp


def array_struct(name: str, fields: dict[str, type], prefix: str, module: str) -> Any:
    """The Warp struct `name` with an array of each dtype of `fields`, named without `prefix`.

    Args:
        name: the struct's name (its C++ type carries it).
        fields: field table, name -> Warp dtype of one row; every name starts with `prefix`.
        prefix: the table's entity prefix, dropped from the struct's field names.
        module: the Python module the struct belongs to (the kernels' module: `__name__`).

    Returns:
        The struct class (typed Any: its fields are made here, which no checker can see).
    """
    annotations: dict[str, Any] = {}
    for field, dtype in fields.items():
        if not field.startswith(prefix):
            raise ValueError(f"field {field!r} does not start with {prefix!r}")
        annotations[field.removeprefix(prefix)] = wp.array(dtype=dtype)
    doc = f"The arrays of {', '.join(fields)}, as kernels take them."
    cls = type(name, (), {"__annotations__": annotations, "__module__": module, "__qualname__": name, "__doc__": doc})
    return wp.struct(cls)


def fill_struct(struct, arrays: dict[str, wp.array], prefix: str) -> Any:
    """An instance of `struct` (from `array_struct`) whose fields are the arrays `arrays[prefix + field]`."""
    s = struct()
    for field in struct.vars:
        setattr(s, field, arrays[prefix + field])
    return s
