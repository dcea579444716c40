"""The real OpenGL window (QOpenGLWidget) under a virtual X server, where xvfb-run is installed.

The other viewer tests use Qt's offscreen platform, which has no OpenGL windows; this one checks
the desktop path in a child process: `xvfb-run python -c SCRIPT`.
"""

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

SCRIPT = textwrap.dedent(
    """
    import numpy as np
    import tumble
    from PySide6 import QtTest
    from tumble.render import body_colors
    from tumble.viewer import make_application
    from tumble.viewer.views import GLSceneView
    from tumble.viewer.window import ViewerWindow

    def build():
        world = tumble.World(dt=1 / 240)
        world.add_plane()
        world.add_sphere(position=(0.0, 0.0, 0.5), radius=0.2)
        return world

    app = make_application()
    win = ViewerWindow(factory=build, size=(320, 240), paused=True, view="gl")
    win.show()
    QtTest.QTest.qWaitForWindowExposed(win)
    QtTest.QTest.qWait(200)
    assert isinstance(win.view, GLSceneView), type(win.view)
    assert win.view.renderer is not None, win.message_label.text()
    image = win.view.render_image().astype(float)
    assert image.shape == (240, 320, 3), image.shape
    x, y, _ = win.camera.project(np.array([0.0, 0.0, 0.5]), 320, 240)
    pixel, color = image[int(y), int(x)], body_colors([1])[0] * 255
    cos = pixel @ color / (np.linalg.norm(pixel) * np.linalg.norm(color))
    assert cos > 0.97, (pixel, color)
    win.step()
    assert win.world.step_count == 1
    print("GL window OK", win.view.software)
    """
)


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="needs xvfb-run (apt: xvfb xauth)")
def test_gl_window_draws_under_xvfb():
    """Under Xvfb the viewer opens a QOpenGLWidget that draws the scene (sphere colour at its centre)."""
    src = Path(__file__).resolve().parents[2] / "src"
    env = dict(os.environ, PYTHONPATH=str(src), QT_QPA_PLATFORM="xcb")
    result = subprocess.run(
        ["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", sys.executable, "-c", SCRIPT],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert result.returncode == 0 and "GL window OK" in result.stdout, result.stdout + result.stderr[-2000:]
