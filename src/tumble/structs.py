"""Warp structs of arrays derived from a field table, so that a set of arrays is declared once.

A table such as `JOINT_FIELDS` (name -> Warp dtype of one row) declares the arrays of an
`ArraySet` (a table may also name a Warp array type, such as `wp.array2d(dtype=wp.int32)` for
rows of index pairs). `array_struct` makes from it the Warp struct that kernels take instead of one
argument per array (one array field per entry, named without the table's prefix:
`joint_body_a` -> `body_a`), and `fill_struct` points one at an ArraySet's arrays. Build a
struct once per set of arrays and keep it: setting each array field costs a few microseconds of
Python, and a recorded launch (`launch.LaunchCache`) re-packs a struct argument only when it is
another struct.
"""

from __future__ import annotations

from typing import Any

import warp as wp


def array_struct(name: str, fields: dict[str, Any], prefix: str, module: str) -> Any:
    """The Warp struct `name` with an array of each dtype of `fields`, named without `prefix`.

    Args:
        name: the struct's name (its C++ type carries it).
        fields: field table, name -> Warp dtype of one row (a one-dimensional array of it) or a Warp
            array type (`wp.array2d(dtype=wp.int32)`); every name starts with `prefix`.
        prefix: the table's entity prefix, dropped from the struct's field names.
        module: the Python module the struct belongs to (the kernels' module: `__name__`).

    Returns:
        The struct class (typed Any: its fields are made here, which no checker can see).
    """
    annotations: dict[str, Any] = {}
    for field, dtype in fields.items():
        if not field.startswith(prefix):
            raise ValueError(f"field {field!r} does not start with {prefix!r}")
        annotations[field.removeprefix(prefix)] = dtype if isinstance(dtype, wp.array) else wp.array(dtype=dtype)
    doc = f"The arrays of {', '.join(fields)}, as kernels take them."
    cls = type(name, (), {"__annotations__": annotations, "__module__": module, "__qualname__": name, "__doc__": doc})
    return wp.struct(cls)


def fill_struct(struct, arrays: dict[str, Any], prefix: str) -> Any:
    """An instance of `struct` (from `array_struct`) whose fields are the arrays `arrays[prefix + field]`."""
    s = struct()
    for field in struct.vars:
        setattr(s, field, arrays[prefix + field])
    return s


def cached_struct(struct, arrays: dict[str, Any], prefix: str, cached: tuple | None = None) -> tuple:
    """`fill_struct`'s instance with what it holds, as (instance, [values]); `cached` (a previous return)
    comes back while those are the same objects (arrays, and any scalar field of the struct), so that
    callers keep it as a cache that a replaced array (a grown set, a restored snapshot) rebuilds, and a
    recorded launch re-packs nothing."""
    held = [arrays[prefix + field] for field in struct.vars]
    if cached is not None and all(a is b for a, b in zip(cached[1], held)):
        return cached
    return fill_struct(struct, arrays, prefix), held
