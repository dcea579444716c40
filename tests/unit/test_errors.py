"""errors.py: one hierarchy for errors raised on purpose; SceneError says where (file, table, key)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tumble import HandleError, SceneError, SimulationError, TumbleError


@pytest.mark.parametrize(
    ("kwargs", "text"),
    [
        ({}, "radius must be positive"),
        ({"path": Path("pile.toml")}, "pile.toml: radius must be positive"),
        ({"path": "pile.toml", "table": "sphere[2]"}, "pile.toml: [sphere[2]]: radius must be positive"),
        (
            {"path": "pile.toml", "table": "sphere[2]", "key": "radius"},
            "pile.toml: [sphere[2]] radius: radius must be positive",
        ),
        ({"table": "world", "key": "dt"}, "[world] dt: radius must be positive"),
    ],
)
def test_scene_error_names_file_table_and_key(kwargs, text):
    """The message is "<file>: [<table>] <key>: <what>", with the parts that are known; they stay readable."""
    error = SceneError("radius must be positive", **kwargs)
    assert str(error) == text
    assert error.path == (None if "path" not in kwargs else str(kwargs["path"]))
    assert (error.table, error.key) == (kwargs.get("table"), kwargs.get("key"))


def test_every_error_is_a_tumble_error_and_a_builtin_one():
    """Callers can catch TumbleError for all, or the builtin they expect (ValueError, RuntimeError)."""
    assert issubclass(SceneError, TumbleError) and issubclass(SceneError, ValueError)
    assert issubclass(HandleError, TumbleError) and issubclass(HandleError, ValueError)
    assert issubclass(SimulationError, TumbleError) and issubclass(SimulationError, RuntimeError)
    assert not issubclass(SimulationError, ValueError)
