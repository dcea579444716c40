"""Argument checks for the public Python API: each names the argument and the value it got.

A wrong type (a string for a radius, a float for a count, 1 for a flag) raises `TypeError`;
a value of the right type out of its range (a negative radius, NaN, 2.5 substeps) raises
`ValueError`. Both messages read "<name> must be <what>, got <value>", so a caller (the scene
loader, a CLI) can pass them on as one line. Every check returns the value in the engine's
own type (float, int, bool or a float64 array).
"""

from __future__ import annotations

import math
import numbers
import operator

import numpy as np

from . import limits
from .limits import MAX_IMAGE_SIDE

#: longest repr of a bad value quoted in a message
_SHOWN = 60


def show(value) -> str:
    """`repr(value)`, shortened for messages (arrays of a million rows stay one line)."""
    if isinstance(value, np.ndarray) and value.size > 8:
        return f"an array of shape {value.shape}"
    if isinstance(value, np.generic):
        value = value.item()  # 2.0, not np.float64(2.0)
    text = " ".join(repr(value).split())  # one line: a small 2-d array's repr has several
    return text if len(text) <= _SHOWN else text[: _SHOWN - 3] + "..."


#: shortest vector taken as non-zero (a direction, an axis, a quaternion to normalise)
ZERO_LENGTH = 1e-12


def is_real(value) -> bool:
    """True for a real number (int, float, a NumPy scalar or 0-d array); False for bools, strings and the rest."""
    if isinstance(value, (bool, np.bool_)):
        return False
    return isinstance(value, numbers.Real) or (
        isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf"
    )


def within(
    v: float, *, low: float | None = None, high: float | None = None, above: bool = False, below: bool = False
) -> bool:
    """True if v is finite and in [low, high]: (low, ... with `above`, ..., high) with `below`; None is no bound."""
    return (
        math.isfinite(v)
        and (low is None or (v > low if above else v >= low))
        and (high is None or (v < high if below else v <= high))
    )


def is_zero(v) -> bool:
    """True if the vector `v` is shorter than `ZERO_LENGTH`: it has no direction."""
    return bool(np.linalg.norm(scaled_down(v)) < ZERO_LENGTH)


#: largest component whose square and the squares of three more stay finite in float64
_SQUARE_SAFE = 1e150


def scaled_down(v) -> np.ndarray:
    """`v` (a finite vector, or rows of them) with each row whose squared length would overflow
    divided by its largest magnitude: the same direction, a norm that is finite. Other rows are
    returned unchanged, bit for bit."""
    v = np.asarray(v, dtype=np.float64)
    big = np.max(np.abs(v), axis=-1, keepdims=True)
    return np.where(big > _SQUARE_SAFE, v / np.where(big > _SQUARE_SAFE, big, 1.0), v)


def unit(v) -> np.ndarray:
    """`v` (a finite vector, or rows of them, none zero) divided by its length, row by row; a vector
    as long as 1e200 too, whose squared length overflows float64."""
    v = scaled_down(v)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def as_float(value) -> float:
    """A real number as a float: an integer too large for one (10**400) is infinite, with its sign, so
    that the finiteness checks refuse it by name instead of `float` raising OverflowError."""
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def _real(value, name: str, what: str) -> float:
    """`value` as a float if it is a real number (not a bool, not a string), else TypeError."""
    if not is_real(value):
        raise TypeError(f"{name} must be {what}, got {show(value)}")
    return as_float(value)


def number(
    value,
    name: str,
    *,
    low: float | None = None,
    high: float | None = None,
    above: bool = False,
    below: bool = False,
) -> float:
    """A finite real number in [low, high]; (low, ... with `above`, ..., high) with `below`."""
    if low is None:
        what = "finite"
    elif above:
        what = "a positive number" if low == 0.0 else f"a number > {low:g}"
    else:
        what = f"a number >= {low:g}"
    if high is not None:
        what = f"in {'(' if above else '['}{low:g}, {high:g}{')' if below else ']'}"
    v = _real(value, name, "a number")
    if not within(v, low=low, high=high, above=above, below=below):
        raise ValueError(f"{name} must be {what}, got {show(value)}")
    return v


def positive(value, name: str) -> float:
    """A finite number > 0."""
    return number(value, name, low=0.0, above=True)


def restitution(value, name: str = "restitution") -> float:
    """A coefficient of restitution, in [0, 1]."""
    return number(value, name, low=0.0, high=1.0)


def friction(value, name: str = "friction") -> float:
    """A Coulomb friction coefficient, >= 0."""
    return number(value, name, low=0.0)


def integer(value, name: str, *, low: int | None = None, high: int | None = None) -> int:
    """An integer in [low, high]; an integral float (8.0) is taken, 2.5 is refused rather than truncated."""
    what = "an integer" if low is None else f"an integer >= {low}"
    if high is not None:
        what = f"an integer <= {high}" if low is None else f"an integer in [{low}, {high}]"
    v = _real(value, name, what)
    if isinstance(value, numbers.Integral):
        i = int(value)  # exact, however large (not through a float)
    elif not math.isfinite(v) or v != math.floor(v):
        raise ValueError(f"{name} must be {what}, got {show(value)}")
    else:
        i = int(v)
    if (low is not None and i < low) or (high is not None and i > high):
        raise ValueError(f"{name} must be {what}, got {show(value)}")
    return i


def seed(value, name: str = "seed") -> int:
    """A random generator's seed: an integer in [0, limits.MAX_SEED]."""
    return integer(value, name, low=0, high=limits.MAX_SEED)


def integers(value, name: str, n: int, *, low: int | None = None) -> tuple[int, ...]:
    """n integers, each as `integer` takes it (>= low), e.g. a grid's resolution (nx, ny)."""
    what = f"{n} integers"
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
        raise TypeError(f"{name} must be {what}, got {show(value)}")
    if len(value) != n:
        raise ValueError(f"{name} must be {what}, got {show(value)}")
    return tuple(integer(v, name, low=low) for v in value)


def flag(value, name: str) -> bool:
    """True or False (NumPy booleans too); 0, 1 and strings are refused."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {show(value)}")
    return bool(value)


def text(value, name: str, choices: tuple[str, ...] | None = None) -> str:
    """A string, one of `choices` when given."""
    if not isinstance(value, str):
        raise TypeError(f"{name} must be a string, got {show(value)}")
    if choices is not None and value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, choices))}, got {show(value)}")
    return value


def array(value, name: str, what: str) -> np.ndarray:
    """`value` as a float64 array; TypeError for strings, objects and booleans, ValueError for ragged lists."""
    try:
        a = np.asarray(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {what}, got {show(value)}") from None
    if a.dtype.kind not in "iuf":
        raise TypeError(f"{name} must be {what}, got {show(value)}")
    return a.astype(np.float64)


def vector(value, name: str, n: int = 3) -> np.ndarray:
    """n finite numbers, shape (n,)."""
    a = array(value, name, f"{n} finite numbers")
    if a.shape != (n,):
        raise ValueError(f"{name} must have {n} components, got {show(value)}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {show(value)}")
    return a


def positive_vector(value, name: str, n: int = 3) -> np.ndarray:
    """n finite numbers, each > 0 (sizes: half extents, a cloth's width and height), shape (n,)."""
    a = vector(value, name, n)
    if np.any(a <= 0.0):
        raise ValueError(f"{name} must all be > 0, got {show(value)}")
    return a


def direction(value, name: str) -> np.ndarray:
    """A non-zero 3-vector (a plane normal, a launch direction, an up axis), returned unit length."""
    d = vector(value, name)
    if is_zero(d):
        raise ValueError(f"{name} must not be zero, got {show(value)}")
    return unit(d)


def scale(value, name: str = "scale") -> np.ndarray:
    """One positive factor for every axis, or three (x, y, z), shape (3,)."""
    what = "one positive number or three"
    a = array(value, name, what)
    if a.shape not in ((), (3,)) or not np.all(np.isfinite(a)) or np.any(a <= 0.0):
        raise ValueError(f"{name} must be {what}, got {show(value)}")
    return np.full(3, float(a)) if a.ndim == 0 else a


def bounds(value, name: str, width: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) from a value or a [min, max] pair, low <= high; with `width`, of vectors of that many components.

    A number gives low = high; with `width`, a number is repeated in every component.
    """
    what = "a number or a [min, max] pair" if width is None else f"a {width}-vector or a pair of them [min, max]"
    a = array(value, name, what)
    if width is None:
        if a.shape == ():
            lo = hi = a
        elif a.shape == (2,):
            lo, hi = a
        else:
            raise ValueError(f"{name} must be {what}, got {show(value)}")
    else:
        if a.shape == (width,):
            lo = hi = a
        elif a.shape == (2, width):
            lo, hi = a
        elif a.shape == ():
            lo = hi = np.full(width, float(a))
        else:
            raise ValueError(f"{name} must be {what}, got {show(value)}")
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ValueError(f"{name} must be finite, got {show(value)}")
    if np.any(lo > hi):
        raise ValueError(f"{name}: min must not exceed max, got {show(value)}")
    return lo, hi


def rows(value, name: str, width: int, n: int | None = None) -> np.ndarray:
    """n rows of `width` finite numbers: one row is repeated n times; n rows are taken as they are."""
    a = array(value, name, f"{width} finite numbers per row")
    if a.ndim == 1 and a.shape[0] == width and n is not None:
        a = np.broadcast_to(a, (n, width))
    if a.ndim != 2 or a.shape[1] != width or (n is not None and a.shape[0] != n):
        count = "n" if n is None else str(n)
        raise ValueError(f"{name} must have {width} components (or shape ({count}, {width})), got {show(value)}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {show(value)}")
    return np.array(a)


def positive_rows(value, name: str, n: int) -> np.ndarray:
    """One positive number for all n rows, or n of them, shape (n,)."""
    a = array(value, name, "a positive number")
    if a.ndim == 0:
        return np.full(n, positive(value if isinstance(value, numbers.Real) else float(a), name))
    if a.shape != (n,):
        raise ValueError(f"{name} must be one positive number or {n} of them, got {show(value)}")
    if not np.all(np.isfinite(a) & (a > 0.0)):
        bad = a[~(np.isfinite(a) & (a > 0.0))][0]
        raise ValueError(f"{name} must be a positive number (each of the {n}), got {bad!r}")
    return a


def mass_properties_usable(mass, inertia) -> bool:
    """True when every mass and principal moment of inertia, and its inverse, is finite and > 0.

    The solver divides by both: a sphere of radius 1e300 weighs inf kg, one of 1e-300 nothing.
    """
    values = np.concatenate((np.ravel(mass), np.ravel(inertia)), dtype=np.float64)
    if not (np.isfinite(values).all() and (values > 0.0).all()):
        return False
    with np.errstate(over="ignore"):
        return bool(np.isfinite(1.0 / values).all())  # 1 / 1e-320 overflows


def quaternion(value, name: str = "orientation", n: int | None = None) -> np.ndarray:
    """Unit quaternions (x, y, z, w): shape (4,) when n is None, else (n, 4) (one row repeated)."""
    q = scaled_down(vector(value, name, 4)[None] if n is None else rows(value, name, 4, n))
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    if np.any(norm < ZERO_LENGTH):
        raise ValueError(f"{name} must be a non-zero quaternion (x, y, z, w), got {show(value)}")
    q = q / norm
    return q[0] if n is None else q


def callable_or_none(value, name: str):
    """A callable, or None."""
    if value is not None and not callable(value):
        raise TypeError(f"{name} must be a function or None, got {show(value)}")
    return value


def image_size(value, name: str = "size", *, low: int = 1) -> tuple[int, int]:
    """(width, height) in pixels from "1280x720" (x, X, * or the sign ×) or a pair of integers.

    Each side must lie in [low, `limits.MAX_IMAGE_SIDE`]; anything else raises ValueError.
    """
    if isinstance(value, str):
        parts = value.strip().lower().replace("*", "x").replace("\u00d7", "x").split("x")
        try:
            w, h = (int(p) for p in parts)
        except ValueError:
            raise ValueError(f"{name} must look like 1280x720, got {show(value)}") from None
    else:
        try:
            w, h = (operator.index(v) for v in value)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be (width, height) in pixels, got {show(value)}") from None
    if not (low <= w <= MAX_IMAGE_SIDE and low <= h <= MAX_IMAGE_SIDE):
        raise ValueError(
            f"{name} must be between {low}x{low} and {MAX_IMAGE_SIDE}x{MAX_IMAGE_SIDE} pixels, got {w}x{h}"
        )
    return w, h
