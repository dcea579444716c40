"""Issue 14 (a new user's first hour), viewer items: screenshot, recording length, the camera
under the ground, controls out of reach, and a window frozen by a slow step."""

import math
import time

import numpy as np
import pytest
from PySide6 import QtCore, QtWidgets

import tumble

Qt = QtCore.Qt

DT = 1.0 / 240.0


def make_world():
    """A ground plane and two spheres resting on it."""
    world = tumble.World(gravity=(0.0, 0.0, -9.81), dt=DT, substeps=2)
    world.add_plane()
    world.add_sphere(position=(-0.3, 0.0, 0.1), radius=0.1, mass=1.0)
    world.add_sphere(position=(0.3, 0.0, 0.1), radius=0.1, mass=1.0)
    return world


@pytest.fixture
def window(open_viewer):
    return open_viewer(make_world)


def test_screenshot_key_and_toolbar_button_save_pngs(window, qtbot):
    """S and the toolbar's Screenshot each save a PNG of the view (the button once passed False as the path)."""
    import imageio.v3 as iio

    qtbot.keyClick(window.view, Qt.Key.Key_S)
    first = window.last_saved
    assert first is not None and first.suffix == ".png"
    assert iio.imread(first).shape[:2] == (240, 320)
    button = window.toolbar.widgetForAction(window.shot_action)
    qtbot.mouseClick(button, Qt.MouseButton.LeftButton)
    assert window.last_saved != first and window.last_saved.is_file()
    assert "Saved" in window.message_label.text()


def test_a_recording_plays_as_long_as_the_simulated_time_it_covers(window, qtbot, tmp_path):
    """Record while playing at 4x: the MP4 has a frame per 1/30 s of simulated time, none skipped."""
    import imageio.v3 as iio

    window.controls.time_scale.set_value(4.0, user=True)  # ~15 steps (2 frames) in each tick
    path = window.start_recording(tmp_path / "clip.mp4")
    t0 = window.world.time
    window.play()
    qtbot.waitUntil(lambda: window.world.time >= t0 + 1.0, timeout=60000)
    window.pause()
    span = window.world.time - t0
    saved = window.stop_recording()
    assert saved == path
    frames = len(list(iio.imiter(path)))
    fps = iio.immeta(path)["fps"]
    assert fps == pytest.approx(30.0)
    # frame k shows t0 + k/30: frames 0 .. floor(span * 30), so it plays span within one frame
    assert frames == math.floor(span * 30.0 + 1e-6) + 1
    assert abs(frames / fps - span) <= 1.0 / 30.0 + 1e-9


def test_the_camera_cannot_pass_below_the_ground(window, qtbot):
    """Dragging up (orbit), panning down and zooming out all keep the eye above the ground plane."""
    view, cam = window.view, window.camera
    for _ in range(5):  # drag up: the eye goes down towards (and once below) the ground
        qtbot.mousePress(view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(160, 235))
        qtbot.mouseMove(view, QtCore.QPoint(160, 5))
        qtbot.mouseRelease(view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(160, 5))
        assert cam.position[2] > 0.0
    assert cam.position[2] < 0.2  # it did get down to the ground
    for _ in range(5):  # pan: drag down moves the camera down
        qtbot.mousePress(view, Qt.MouseButton.RightButton, pos=QtCore.QPoint(160, 5))
        qtbot.mouseMove(view, QtCore.QPoint(160, 235))
        qtbot.mouseRelease(view, Qt.MouseButton.RightButton, pos=QtCore.QPoint(160, 235))
        assert cam.position[2] > 0.0
    for _ in range(20):
        cam.zoom(0.5)
        assert cam.position[2] > 0.0
    image = window.view.render_image()
    assert image.shape == (240, 320, 3)


def test_every_control_is_reachable_at_the_default_size(qtbot, tmp_path):
    """At `tumble view`'s default 1280x720 the window fits the screen and every control scrolls into view."""
    from tumble.viewer import make_application
    from tumble.viewer.window import ViewerWindow

    make_application()
    win = ViewerWindow(factory=make_world, size=(1280, 720), paused=True, view="image", output_dir=tmp_path)
    qtbot.addWidget(win)
    win.show()
    qtbot.waitExposed(win)
    screen = win.screen().availableGeometry()
    assert win.frameGeometry().width() <= screen.width() and win.frameGeometry().height() <= screen.height()
    scroll = win.dock.widget()
    widgets = [c for c in win.controls.controls.values()] + [win.controls.shadows]
    for widget in widgets:
        scroll.ensureWidgetVisible(widget)
        QtWidgets.QApplication.processEvents()
        top_left = widget.mapTo(win, QtCore.QPoint(0, 0))
        box = QtCore.QRect(top_left, widget.size())
        assert win.rect().contains(box), f"{widget} at {box} is outside the window {win.rect()}"
        assert not widget.visibleRegion().isEmpty()
    win.close()


def _orbit_until(qtbot, view, done, timeout: float) -> None:
    """Drag across the view (a mouse move every 5 ms) until `done()` or `timeout` seconds."""
    qtbot.mousePress(view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(5, 60))
    start, x = time.monotonic(), 5
    while not done() and time.monotonic() - start < timeout:
        x = 5 + (x + 3) % 150
        qtbot.mouseMove(view, QtCore.QPoint(x, 60))
        qtbot.wait(5)
    qtbot.mouseRelease(view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(x, 60))


def test_the_window_keeps_drawing_while_a_step_runs(qtbot, tmp_path):
    """The world steps on a worker thread: while a step is held inside `world.step`, orbiting the
    camera still redraws the window (stepping on the UI thread froze it: no frame until the step
    ended). No speed is asserted: the step is held until ten frames were drawn, or 20 s passed.
    """
    import threading

    from tumble.viewer import make_application
    from tumble.viewer.window import ViewerWindow

    world = make_world()
    real_step = world.step
    in_step, release = threading.Event(), threading.Event()

    def held_step(dt=None):
        in_step.set()
        release.wait(timeout=30.0)
        real_step(dt)

    world.step = held_step
    make_application()
    win = ViewerWindow(world, size=(160, 120), paused=True, view="image", output_dir=tmp_path)
    qtbot.addWidget(win)
    win.show()
    qtbot.waitExposed(win)
    view = win.view
    win.play()
    qtbot.waitUntil(in_step.is_set, timeout=10000)
    start_position, frames = win.camera.position.copy(), view.frame_count
    try:
        _orbit_until(qtbot, view, lambda: view.frame_count >= frames + 10, timeout=20.0)
        drawn = view.frame_count - frames  # all while the step was held: `release` is set below
    finally:
        release.set()
    win.pause()
    assert drawn >= 10, f"{drawn} frames drawn in 20 s while a step was running"
    assert np.linalg.norm(win.camera.position - start_position) > 1e-3
    win.close()


def test_an_error_in_the_simulation_thread_pauses_with_a_message(window, qtbot):
    """A step that fails on the worker thread pauses the viewer and shows the error; the window goes on."""
    from tumble.errors import SimulationError

    def failing_step(dt=None):
        raise SimulationError("body 1 position is NaN")

    window.world.step = failing_step
    window.play()
    qtbot.waitUntil(lambda: not window.clock.playing, timeout=10000)
    qtbot.waitUntil(lambda: "NaN" in window.message_label.text(), timeout=10000)
    assert "Simulation stopped" in window.message_label.text()
    assert window.sim.running
