"""Tumble: particles, rigid bodies and cloth, simulated with Warp kernels.

Public API::

    world = tumble.World(gravity=(0, 0, -9.81))
    world.add_plane()
    world.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    world.run(duration=1.0)

    world = tumble.load_scene("samples/sphere_pile.toml")
"""

import os as _os
import sys as _sys
from pathlib import Path as _Path
from typing import TYPE_CHECKING as _TYPE_CHECKING


def _started_as_command() -> bool:
    """Whether this process is the `tumble` command: its console script, or `python -m tumble`
    (while a `-m` module is being found, `sys.argv[0]` is "-m" and `sys.orig_argv` names it)."""
    argv0 = _sys.argv[0] if _sys.argv else ""
    if argv0 != "-m":
        return _os.path.basename(argv0).removesuffix(".exe").removesuffix("-script.py") == "tumble"
    orig = list(getattr(_sys, "orig_argv", ()))
    for i, arg in enumerate(orig[1:], 1):
        if arg.startswith("-m"):
            module = arg[2:] or (orig[i + 1] if i + 1 < len(orig) else "")
            return module in ("tumble", "tumble.__main__", "tumble.cli")
    return False


def _quiet_startup_interrupts() -> None:
    """In the `tumble` command, a Ctrl-C that `tumble.cli.main` cannot catch yet (while Tumble,
    Warp and NumPy import, a second or two, or while the arguments are parsed) ends it with one
    line, "tumble: interrupted", and exit status 130, not a traceback; a SIGTERM then ends it with
    "tumble: terminated" and status 143 (before this, Python's default ended it silently; nothing
    is written before the command's own handlers take over). A program that imports Tumble as a
    library keeps Python's own handling."""
    if not _started_as_command():
        return
    import threading

    from . import signals

    def terminated(signum, frame) -> None:
        _sys.stderr.write("tumble: terminated\n")
        _sys.stderr.flush()
        _os._exit(128 + signum)

    if threading.current_thread() is threading.main_thread():
        signals.replace(signals.TERMINATING, terminated)
    previous = _sys.excepthook

    def hook(kind, value, traceback) -> None:
        if not issubclass(kind, KeyboardInterrupt):
            previous(kind, value, traceback)
            return
        print(f"tumble: {'terminated' if kind.__name__ == 'Terminated' else 'interrupted'}", file=_sys.stderr)

    _sys.excepthook = hook


_quiet_startup_interrupts()  # before the imports that take the time

import warp as _wp

_wp.config.log_level = _wp.LOG_WARNING  # no banner; the CLI says when kernels compile

# `tumble.wedge` is the function below; the names of its module import as usual (from tumble.wedge import ...)
from .cloth import ClothSystem, Wind
from .emitters import Emitter
from .errors import HandleError, SceneError, SimulationError, TumbleError
from .model import Control, Model, State
from .shapes import ShapeType, SolidOptions
from .snapshot import Snapshot, SnapshotError
from .state import BodyId, BodyKind, ClothId, JointId
from .wedge import wedge
from .world import BodyState, World

if _TYPE_CHECKING:
    from typing import Unpack

    from .io.scene import WorldOverrides

__all__ = [
    "BodyId",
    "BodyKind",
    "BodyState",
    "ClothId",
    "ClothSystem",
    "Control",
    "Emitter",
    "HandleError",
    "JointId",
    "Model",
    "SceneError",
    "ShapeType",
    "SimulationError",
    "Snapshot",
    "SnapshotError",
    "SolidOptions",
    "State",
    "TumbleError",
    "Wind",
    "World",
    "load_scene",
    "load_snapshot",
    "read_snapshot",
    "save_snapshot",
    "wedge",
]
__version__ = "0.1.0"


def load_scene(path: str | _os.PathLike[str], **overrides: "Unpack[WorldOverrides]") -> World:
    """Build a `World` from a TOML scene file; see docs/scenes.md. Raises `SceneError` on bad input."""
    from .io.scene import load_scene as _load

    return _load(path, **overrides)


def save_snapshot(state: Snapshot, path: str | _os.PathLike[str]) -> _Path:
    """Write a `world.snapshot()` to `path` (.npz), atomically; returns the path. See `load_snapshot`."""
    from . import snapshot

    return snapshot.save(state, path)


def read_snapshot(path: str | _os.PathLike[str]) -> Snapshot:
    """Read a snapshot file, for `world.restore` into a world built the same way (raises `SnapshotError`)."""
    from . import snapshot

    return snapshot.read(path)


def load_snapshot(path: str | _os.PathLike[str], **overrides: "Unpack[WorldOverrides]") -> World:
    """Rebuild the world a snapshot file of a scene was taken from, at the saved moment; stepping it
    continues the saved run bit for bit (`tumble run --resume FILE`). Overrides as in `load_scene` (device)."""
    from .io.scene import load_snapshot as _load

    return _load(path, **overrides)
