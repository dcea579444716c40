"""Errors Tumble raises for bad input. Each names what was wrong and where."""

from __future__ import annotations


class TumbleError(Exception):
    """Base class of all errors Tumble raises on purpose."""


class SceneError(TumbleError, ValueError):
    """A scene file (or table in it) is malformed.

    Args:
        message: what is wrong, in one line.
        path: the scene file, if any.
        table: the table, e.g. "sphere[2]" for the third `[[sphere]]`.
        key: the offending key inside that table.
    """

    def __init__(self, message: str, *, path=None, table: str | None = None, key: str | None = None):
        self.path = None if path is None else str(path)
        self.table = table
        self.key = key
        where = ": ".join(
            part
            for part in (
                self.path,
                None if table is None else f"[{table}]" + ("" if key is None else f" {key}"),
            )
            if part
        )
        super().__init__(f"{where}: {message}" if where else message)


class SimulationError(TumbleError, RuntimeError):
    """The simulation state became invalid (NaN or infinite values)."""


class HandleError(TumbleError, ValueError):
    """A handle (BodyId, ClothId, Emitter) that belongs to another World, or to a removed entity."""


class NoSuchIdError(HandleError, IndexError):
    """An int id past the ones a World has given out (also an IndexError, as an index out of range is)."""
