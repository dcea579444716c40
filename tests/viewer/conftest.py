"""Viewer tests run on Qt's offscreen platform (no display, no GPU): the window uses the EGL image view."""

import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

import pytest  # noqa: E402

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")


@pytest.fixture
def open_viewer(qtbot, tmp_path):
    """open_viewer(factory): a paused 320x240 viewer (offscreen image view) saving into tmp_path."""
    from tumble.viewer import make_application
    from tumble.viewer.window import ViewerWindow

    make_application()
    windows = []

    def open_(factory):
        win = ViewerWindow(factory=factory, size=(320, 240), paused=True, view="image", output_dir=tmp_path)
        qtbot.addWidget(win)
        win.show()
        qtbot.waitExposed(win)
        windows.append(win)
        return win

    yield open_
    for win in windows:
        win.close()
