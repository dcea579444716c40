"""Viewer tests run on Qt's offscreen platform (no display, no GPU): the window uses the EGL image view."""

import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

import pytest  # noqa: E402

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")
