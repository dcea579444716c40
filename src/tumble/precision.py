"""Floating-point precision: float32 or float64, chosen per world, one kernel source for both.

Every kernel module (the solver, the collision stages, the cloth) is written once against the
names of `tumble.real`: `float_t`, `vec3`, `quat`, `mat33`. Warp fixes a kernel's types when the
module is imported, so each precision gets its own copy of those modules:

- `tumble.solver.contacts` (the modules as they are imported normally) is the float64 copy;
- `tumble._float32.solver.contacts` is the float32 copy: the same file, loaded a second time
  under that name by the import hook below, whose `tumble._float32.real` says float32.

Inside a copy, relative imports reach the same precision's copy of the other kernel modules
(`KERNEL_MODULES`); every other module (`tumble.state`, `tumble.launch`, `tumble.errors`, ...) is
shared, the very same module object, so handles, errors and array sets are one type in both.
A world finds its stages through `kernels(precision)`.

Declarations outside the kernel modules (the body fields of `tumble.model`) name the float64
types (`FLOAT`, `VEC3`, `QUAT`, `MAT33`); `specialize` maps them to a precision's types where
the arrays are allocated.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import types
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import warp as wp

Precision = Literal["float32", "float64"]

#: the precisions a world can run in
PRECISIONS: tuple[Precision, ...] = ("float32", "float64")
#: what `World()` and scene files use when they name no precision; read at each `World()`, so a
#: program may set it once (`tumble.precision.DEFAULT_PRECISION = "float64"`) for all its worlds
DEFAULT_PRECISION: Precision = "float64"


@dataclass(frozen=True)
class Types:
    """The Warp and NumPy types of one precision."""

    name: Precision
    float_t: type  #: scalar
    vec3: type
    quat: type  #: (x, y, z, w)
    mat33: type
    vec2: type
    mat22: type
    numpy: type  #: NumPy scalar type of every float array
    eps: float  #: machine epsilon, the spacing of floats at 1


TYPES: dict[str, Types] = {
    "float64": Types(
        "float64",
        wp.float64,
        wp.vec3d,
        wp.quatd,
        wp.mat33d,
        wp.vec2d,
        wp.mat22d,
        np.float64,
        float(np.finfo(np.float64).eps),
    ),
    "float32": Types(
        "float32",
        wp.float32,
        wp.vec3f,
        wp.quatf,
        wp.mat33f,
        wp.vec2f,
        wp.mat22f,
        np.float32,
        float(np.finfo(np.float32).eps),
    ),
}

#: the declared (float64) types, as tables outside the kernel modules name them
FLOAT, VEC3, QUAT, MAT33 = wp.float64, wp.vec3d, wp.quatd, wp.mat33d
_ROLE = {FLOAT: "float_t", VEC3: "vec3", QUAT: "quat", MAT33: "mat33"}

#: the modules loaded once per precision: path below `tumble` -> name in `kernels(precision)`
KERNEL_MODULES: dict[str, str] = {
    "real": "real",
    "solver.rigid": "rigid",
    "solver.integrate": "integrate",
    "solver.contacts": "contacts",
    "solver.joints": "joints",
    "collision.hashgrid": "hashgrid",
    "collision.hulls": "hulls",
    "collision.meshes": "meshes",
    "collision.broadphase": "broadphase",
    "collision.narrowphase": "narrowphase",
    "cloth.arrays": "cloth_arrays",
    "cloth.springs": "springs",
    "cloth.attach": "attach",
    "cloth.wind": "wind",
    "cloth.collide": "cloth_collide",
    "cloth.system": "cloth",
}

_ROOT = "tumble"
#: package of each precision's copy of the kernel modules (float64's is the package itself)
PACKAGE = {"float64": _ROOT, "float32": f"{_ROOT}._float32"}


def check(precision: object, key: str = "precision") -> Precision:
    """`precision` if it names one of `PRECISIONS`, else ValueError naming `key`."""
    if precision not in PRECISIONS:
        raise ValueError(f"{key} must be one of {', '.join(map(repr, PRECISIONS))}, got {precision!r}")
    return precision


def types_of(precision: str) -> Types:
    """The types of `precision` ("float32" or "float64")."""
    return TYPES[check(precision)]


def precision_of_module(name: str) -> Precision:
    """The precision of the copy that the module `name` belongs to."""
    return "float32" if name.startswith(PACKAGE["float32"] + ".") or name == PACKAGE["float32"] else "float64"


def precision_of_dtype(dtype: type) -> Precision | None:
    """The precision of a Warp float type (scalar, vec3, quat, mat33), None for other types."""
    for t in TYPES.values():
        if dtype in (t.float_t, t.vec3, t.quat, t.mat33):
            return t.name
    return None


def specialize(dtype: type, precision: str) -> type:
    """`dtype` in `precision`: a declared (float64) float type becomes that precision's, others stay."""
    role = _ROLE.get(dtype)
    return dtype if role is None else getattr(types_of(precision), role)


def kernels(precision: str) -> types.SimpleNamespace:
    """The kernel modules of `precision` by their names in `KERNEL_MODULES` (`kernels("float32").contacts`
    is `tumble._float32.solver.contacts`), imported on first use."""
    package = PACKAGE[check(precision)]
    cached = _KERNELS.get(precision)
    if cached is None:
        modules = {short: importlib.import_module(f"{package}.{path}") for path, short in KERNEL_MODULES.items()}
        cached = _KERNELS[precision] = types.SimpleNamespace(**modules)
    return cached


_KERNELS: dict[str, types.SimpleNamespace] = {}


# ---------------------------------------------------------------------------- the import hook


class _Alias(importlib.abc.Loader):
    """Loads `tumble._float32.X` for a shared module X as the module `tumble.X` itself."""

    def __init__(self, target: str):
        self.target = target

    def create_module(self, spec):
        return None  # a fresh module, replaced in `sys.modules` by `exec_module`

    def exec_module(self, module) -> None:
        # the import system returns whatever `sys.modules` holds under the name after this
        sys.modules[module.__name__] = importlib.import_module(self.target)


class _Copy(importlib.machinery.SourceFileLoader):
    """Loads a kernel module's file again under its float32 name; the names it lists in
    `__shared__` (classes without kernels, such as `Wind`) are then the float64 copy's objects,
    so that both precisions hand out one type."""

    def exec_module(self, module) -> None:
        super().exec_module(module)
        shared = getattr(module, "__shared__", ())
        if shared:
            base = importlib.import_module(_ROOT + module.__name__[len(PACKAGE["float32"]) :])
            for name in shared:
                setattr(module, name, getattr(base, name))


class _Package(importlib.abc.Loader):
    """An empty package (`tumble._float32`, `tumble._float32.solver`, ...) for the copies to live in."""

    def create_module(self, spec):
        return None

    def exec_module(self, module) -> None:
        module.__doc__ = (
            f"The {precision_of_module(module.__name__)} copy of Tumble's kernel modules (tumble.precision)."
        )


class _Finder(importlib.abc.MetaPathFinder):
    """Finds the modules below `tumble._float32`: kernel modules are the same files loaded again
    under that name, packages are empty, anything else is the shared module."""

    def find_spec(self, fullname, path=None, target=None):
        prefix = PACKAGE["float32"]
        if fullname != prefix and not fullname.startswith(prefix + "."):
            return None
        inner = fullname[len(prefix) + 1 :]
        base = Path(__file__).parent.joinpath(*inner.split(".")) if inner else Path(__file__).parent
        if not inner or (base.is_dir() and any(m.startswith(inner + ".") for m in KERNEL_MODULES)):
            spec = importlib.machinery.ModuleSpec(fullname, _Package(), is_package=True)
            spec.submodule_search_locations = []
            return spec
        if inner in KERNEL_MODULES:
            source = str(base.with_suffix(".py"))
            return importlib.util.spec_from_file_location(fullname, source, loader=_Copy(fullname, source))
        return importlib.machinery.ModuleSpec(fullname, _Alias(f"{_ROOT}.{inner}"))


def _install() -> None:
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())


_install()
