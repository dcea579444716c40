"""The interactive viewer: a PySide6 window around the shared renderer (`tumble.render`).

    from tumble.viewer import run_viewer
    run_viewer(world)                                  # a world built in Python
    run_viewer(factory=lambda: build_my_world())       # Reset (R) rebuilds it with the factory

`tumble view SCENE` opens a scene file the same way. See docs/viewer.md for the controls.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from collections.abc import Callable

from .. import signals

__all__ = ["ViewerUnavailable", "ViewerWindow", "run_viewer"]


def __getattr__(name: str):
    # import Qt only when the viewer is actually used
    if name in ("ViewerWindow", "ViewerUnavailable"):
        from . import window

        return getattr(window, name)
    raise AttributeError(name)


def run_viewer(
    world=None,
    *,
    factory: Callable[[], object] | None = None,
    title: str = "Tumble",
    size: tuple[int, int] = (1280, 720),
    paused: bool = False,
    view: str = "auto",
    output_dir=".",
) -> int:
    """Open the viewer window on a world and run the Qt event loop until it is closed.

    Args:
        world: the world to show (or None with `factory`).
        factory: callable returning a fresh world, for Reset (R).
        title: window title.
        size: size of the 3D view in pixels (width, height).
        paused: start paused.
        view: "auto" (OpenGL window where possible, else offscreen), "gl" or "image".
        output_dir: folder for screenshots and videos.

    Returns:
        The exit status of the event loop (0).

    Raises:
        ViewerUnavailable: when no window can be shown (no Qt, no OpenGL window and no EGL).
    """
    app = make_application()
    from PySide6 import QtCore

    from .window import ViewerWindow

    # Ctrl-C, SIGTERM and SIGHUP close the window: a handler that raised (KeyboardInterrupt, tumble.cli's
    # Terminated) inside a Qt slot only printed a traceback, and the viewer ran on. Caught from
    # before the window is made, whose setup (seconds on a loaded machine) runs Qt callbacks too
    received: list[int] = []
    previous: dict[int, object] = {}
    if threading.current_thread() is threading.main_thread():

        def stop(signum: int, frame: object) -> None:
            received.append(signum)
            app.quit()  # (nothing before the event loop runs: the timer below quits it then)

        previous = signals.replace(signals.ENDING, stop)
    try:
        window = ViewerWindow(
            world, factory=factory, title=title, size=size, paused=paused, view=view, output_dir=output_dir
        )
        window.show()
        if app.platformName() not in ("offscreen", "minimal"):
            window.raise_()
        QtCore.QTimer.singleShot(0, lambda: app.quit() if received else None)
        status = int(app.exec())
    finally:
        signals.restore(previous)
    if received:  # unwind as the signal would have outside Qt
        handler = previous[received[0]]
        if callable(handler):
            handler(received[0], None)
        raise KeyboardInterrupt
    return status


def make_application():
    """The QApplication (made once), with the OpenGL 3.3 core format the views need as default."""
    from .window import ViewerUnavailable

    try:
        from PySide6 import QtGui, QtWidgets
    except ImportError as exc:
        raise ViewerUnavailable(f"the viewer needs PySide6 (pip install 'tumble[viewer]'): {exc}") from exc
    app = QtWidgets.QApplication.instance()
    if app is None:
        from .views import gl_surface_format

        problem = gui_platform_problem()
        if problem:
            raise ViewerUnavailable(problem)
        QtGui.QSurfaceFormat.setDefaultFormat(gl_surface_format())
        app = QtWidgets.QApplication(sys.argv[:1])
        app.setApplicationName("Tumble")
    return app


def gui_platform_problem() -> str | None:
    """Why Qt cannot open windows here, or None. Qt aborts the process when its platform fails to
    start (e.g. no display), so that is tried in a child process first."""
    platform = os.environ.get("QT_QPA_PLATFORM", "")
    if platform.split(":")[0] in ("offscreen", "minimal"):
        return None
    if sys.platform.startswith("linux") and not platform:
        if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
            return (
                "cannot open a window: there is no display (DISPLAY and WAYLAND_DISPLAY are unset); "
                "run it on a desktop or under xvfb-run, or use `tumble render` for headless video"
            )
    probe = "from PySide6.QtWidgets import QApplication; QApplication([]).platformName()"
    try:
        result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"cannot open a window: starting Qt failed ({exc})"
    if result.returncode != 0:
        lines = [line.strip() for line in result.stderr.splitlines() if line.strip()]
        reason = next((line for line in lines if "could not" in line.lower() or "needed" in line), None)
        reason = reason or (lines[-1] if lines else f"exit status {result.returncode}")
        return f"cannot open a window: Qt's platform plugin did not start ({reason})"
    return None
