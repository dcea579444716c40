"""Viewer tests run on Qt's offscreen platform (tests/conftest.py sets it, and has `open_viewer`)."""

import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")
