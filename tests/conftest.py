"""Shared fixtures: headless Qt, scene files written on the fly, a subprocess environment."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

SRC = Path(__file__).resolve().parents[1] / "src"


@pytest.fixture
def write_scene(tmp_path):
    """Write TOML text to a file under tmp_path and return its path: write_scene(text, name="scene.toml")."""

    def write(text: str, name: str = "scene.toml") -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path

    return write


@pytest.fixture
def tumble_subprocess_env():
    """Environment for `python -m tumble.cli` in a subprocess, importing this checkout's src."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env["PYTHONIOENCODING"] = "utf-8"
    env["COLUMNS"] = "120"
    return env
