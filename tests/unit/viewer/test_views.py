"""The viewer's scene views (tumble.viewer.views): the offscreen image view, the pixel conversions, and
the real OpenGL window (QOpenGLWidget) under a virtual X server, where xvfb-run is installed.

The other viewer tests use Qt's offscreen platform, which has no OpenGL windows; the GL window test
checks the desktop path in a child process: `xvfb-run python -c SCRIPT`.
"""

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from tumble.viewer import views  # noqa: E402

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
    src = Path(__file__).resolve().parents[3] / "src"
    env = dict(os.environ, PYTHONPATH=str(src), QT_QPA_PLATFORM="xcb")
    result = subprocess.run(
        ["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", sys.executable, "-c", SCRIPT],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert result.returncode == 0 and "GL window OK" in result.stdout, result.stdout + result.stderr[-2000:]


def test_image_view_lowers_its_resolution_on_slow_frames_and_shadows_toggle(open_viewer):
    """The image view draws smaller while frames are slow, back up when fast; shadows can be switched."""
    import tumble

    def make_world():
        world = tumble.World(dt=1.0 / 240.0)
        world.add_plane()
        world.add_sphere(position=(0.0, 0.0, 0.5), radius=0.1)
        return world

    window = open_viewer(make_world)
    view = window.view
    assert isinstance(view, views.ImageSceneView)
    view.render_scale = 1.0  # (a slow first paint on a busy machine may already have lowered it)
    view.adapt_scale(0.5)
    assert view.render_scale == 0.75
    view.adapt_scale(0.5)
    view.adapt_scale(0.5)
    assert view.render_scale == views.MIN_RENDER_SCALE == 0.5  # never below it
    view.adapt_scale(0.001)
    assert view.render_scale == 0.75
    # shadows start off when drawing in software (Mesa llvmpipe on the test machine), else on
    assert view.shadows is (not view.software)
    assert window.controls.shadows.isChecked() is view.shadows
    window.controls.shadows.setChecked(not view.shadows)
    assert view.shadows is window.controls.shadows.isChecked()
    assert window.view.render_image().shape == (240, 320, 3)  # screenshots stay full size


def test_pixels_round_trip_through_a_qimage():
    """array_to_qimage then qimage_to_array gives back the same pixels, for a width whose rows are padded."""
    rng = np.random.default_rng(5)
    pixels = rng.integers(0, 256, size=(7, 13, 3), dtype=np.uint8)  # 39 bytes a row: Qt pads rows to 40
    image = views.array_to_qimage(pixels)
    assert (image.width(), image.height()) == (13, 7)
    assert image.pixelColor(4, 2).getRgb()[:3] == tuple(int(v) for v in pixels[2, 4])  # x = 4, y = 2
    np.testing.assert_array_equal(views.qimage_to_array(image), pixels)
    before = pixels[0, 0].tolist()
    pixels[0, 0] = 255 - pixels[0, 0]  # the image owns its pixels: changing the array leaves it as it was
    assert views.qimage_to_array(image)[0, 0].tolist() == before


@pytest.mark.parametrize(
    "name, software",
    [
        ("llvmpipe (LLVM 15.0.7, 256 bits)", True),
        ("softpipe", True),
        ("Google SwiftShader", True),
        ("Microsoft Basic Render Driver (Software)", True),
        ("NVIDIA GeForce RTX 3080/PCIe/SSE2", False),
        ("AMD Radeon RX 6800 (radeonsi, navi21, LLVM 15.0.7)", False),
    ],
)
def test_software_rasterisers_are_told_from_gpus(name, software):
    """GL_RENDERER names of CPU rasterisers count as software; a GPU's name (even one naming LLVM) does not."""
    assert views.is_software_name(name) is software
