"""The viewer window (tumble.viewer.window), driven with pytest-qt on the offscreen platform."""

import math

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6 import QtCore, QtGui, QtWidgets  # noqa: E402

import tumble  # noqa: E402
from tumble.render import body_colors  # noqa: E402
from tumble.viewer.views import ImageSceneView  # noqa: E402

from . import make_cloth_world  # noqa: E402

Qt = QtCore.Qt

DT = 1.0 / 240.0
SPHERES = [(-0.4, 0.0, 0.3), (0.0, 0.0, 0.6), (0.4, 0.0, 0.3)]


def make_world():
    """A ground plane and three spheres at rest in the air, 0.1 m radius."""
    world = tumble.World(gravity=(0.0, 0.0, -9.81), dt=DT, substeps=2)
    world.add_plane(restitution=0.3, friction=0.5)
    for p in SPHERES:
        world.add_sphere(position=p, radius=0.1, mass=1.0, restitution=0.3, friction=0.5)
    return world


@pytest.fixture
def window(open_viewer):
    """A paused 320x240 viewer on `make_world`, saving into tmp_path."""
    return open_viewer(make_world)


def test_window_opens_the_scene(window):
    """Open a world: the offscreen view shows it and the status line counts its bodies."""
    assert isinstance(window.view, ImageSceneView)
    assert window.world.body_count == 1 + len(SPHERES)
    assert "bodies 4" in window.status_text()
    assert window.view.width() == 320 and window.view.height() == 240


def test_play_advances_time_and_pause_stops_it(window, qtbot):
    """Play (space) makes simulated time run; pause (space again) freezes it."""
    assert not window.clock.playing
    qtbot.keyClick(window.view, Qt.Key.Key_Space)
    assert window.clock.playing
    qtbot.waitUntil(lambda: window.world.step_count >= 3, timeout=10000)
    qtbot.keyClick(window.view, Qt.Key.Key_Space)
    assert not window.clock.playing
    steps, t = window.world.step_count, window.world.time
    qtbot.wait(100)  # timer ticks keep coming while paused
    assert window.world.step_count == steps and window.world.time == t
    assert t > 0.0


def test_step_advances_exactly_one_step(window, qtbot):
    """Period steps once: step_count + 1 and time + dt, by key and by the toolbar action."""
    steps, t = window.world.step_count, window.world.time
    qtbot.keyClick(window.view, Qt.Key.Key_Period)
    assert window.world.step_count == steps + 1
    assert window.world.time == pytest.approx(t + DT, abs=1e-12)
    window.step_action.trigger()
    assert window.world.step_count == steps + 2
    assert window.world.time == pytest.approx(t + 2 * DT, abs=1e-12)
    assert not window.clock.playing


def test_reset_rebuilds_the_world_and_keeps_changed_controls(window, qtbot):
    """R rebuilds the world from its factory; a control the user changed is applied to the new world."""
    for _ in range(3):
        window.step()
    window.controls.controls["gravity_z"].spin.setValue(-3.0)
    old = window.world
    qtbot.keyClick(window.view, Qt.Key.Key_R)
    assert window.world is not old
    assert window.world.step_count == 0 and window.world.time == 0.0
    assert window.world.gravity[2] == pytest.approx(-3.0)
    assert window.view.world.source is window.world


def test_drag_on_empty_view_orbits_and_right_drag_pans(window, qtbot):
    """A left drag on the sky orbits the camera, a right drag pans it, the wheel zooms."""
    view, cam = window.view, window.camera
    start = cam.position.copy()
    qtbot.mousePress(view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(5, 5))
    qtbot.mouseMove(view, QtCore.QPoint(60, 30))
    qtbot.mouseRelease(view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(60, 30))
    assert window.held is None
    assert np.linalg.norm(cam.position - start) > 1e-3
    assert cam.distance == pytest.approx(np.linalg.norm(start - cam.target), rel=1e-9)  # orbit keeps distance

    target = cam.target.copy()
    qtbot.mousePress(view, Qt.MouseButton.RightButton, pos=QtCore.QPoint(5, 5))
    qtbot.mouseMove(view, QtCore.QPoint(40, 5))
    qtbot.mouseRelease(view, Qt.MouseButton.RightButton, pos=QtCore.QPoint(40, 5))
    assert np.linalg.norm(cam.target - target) > 1e-3

    distance = cam.distance
    wheel = QtGui.QWheelEvent(
        QtCore.QPointF(100, 100),
        QtCore.QPointF(view.mapToGlobal(QtCore.QPoint(100, 100))),
        QtCore.QPoint(0, 0),
        QtCore.QPoint(0, 120),
        Qt.MouseButton.NoButton,
        Qt.KeyboardModifier.NoModifier,
        Qt.ScrollPhase.NoScrollPhase,
        False,
    )
    QtWidgets.QApplication.sendEvent(view, wheel)
    assert cam.distance < distance

    qtbot.keyClick(view, Qt.Key.Key_Home)
    np.testing.assert_allclose(cam.position, window.home_camera.position)


def _pixel_of(window, point):
    x, y, depth = window.camera.project(np.asarray(point, dtype=float), window.view.width(), window.view.height())
    assert depth > 0
    return int(x), int(y)


def test_drag_on_a_body_pulls_it_towards_the_cursor(window, qtbot):
    """Pressing on a sphere grabs it; moving the mouse up and stepping pulls it up."""
    i = 2  # the sphere at (0, 0, 0.6)
    x, y = _pixel_of(window, SPHERES[1])
    qtbot.mousePress(window.view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(x, y))
    assert window.held is not None and window.held.kind == "body" and window.held.index == i
    qtbot.mouseMove(window.view, QtCore.QPoint(x, y - 40))
    assert window.held.target[2] > SPHERES[1][2] + 0.05
    z0 = window.world.body_position[i, 2]
    for _ in range(20):
        window.step()
    assert window.world.body_position[i, 2] > z0 + 0.01  # pulled up against gravity
    (x0, y0), (x1, y1) = window.view.spring_line  # the spring is drawn from the body to the cursor
    assert (x1, y1) == pytest.approx((x, y - 40), abs=2.0)
    qtbot.mouseRelease(window.view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(x, y - 40))
    assert window.held is None
    window.on_tick()
    assert window.view.spring_line is None


def test_screenshot_shows_spheres_and_ground(window, tmp_path):
    """A screenshot has the spheres' colours at their centres and the bare ground elsewhere."""
    import imageio.v3 as iio

    path = window.screenshot(tmp_path / "shot.png")
    image = iio.imread(path)[..., :3].astype(float)
    h, w = image.shape[:2]
    assert (w, h) == (320, 240)

    # the same view without the spheres: the ground and sky alone
    from tumble.render import Renderer, create_context

    bare = tumble.World(dt=DT)
    bare.add_plane()
    renderer = Renderer(create_context(), w, h)
    empty = renderer.render(bare, window.camera).astype(float)

    colors = body_colors(np.arange(window.world.body_count)) * 255.0
    for k, centre in enumerate(SPHERES):
        x, y = _pixel_of(window, centre)
        pixel = image[y, x]
        assert np.abs(pixel - empty[y, x]).sum() > 60.0, f"sphere {k} is not drawn"
        # sphere-coloured: the same hue as the body's colour (shading scales brightness)
        c = colors[k + 1]
        cos = pixel @ c / (np.linalg.norm(pixel) * np.linalg.norm(c))
        assert cos > 0.97, f"sphere {k} pixel {pixel} is not the colour {c}"

    # ground where no sphere is: bottom corners match the bare scene
    for x, y in ((5, h - 5), (w - 5, h - 5)):
        assert np.abs(image[y, x] - empty[y, x]).max() <= 12.0


def test_record_writes_an_mp4(window, tmp_path):
    """Recording while stepping writes an MP4 with one frame per 1/30 s of simulated time."""
    import imageio.v3 as iio

    path = window.start_recording(tmp_path / "clip.mp4")
    for _ in range(20):  # t = 1/240 ... 1/12 s: frames at the first step, then t >= 1/30 and 2/30
        window.step()
    saved = window.stop_recording()
    assert saved == path and path.stat().st_size > 0
    frames = list(iio.imiter(path))
    assert len(frames) == 3
    assert frames[0].shape[:2] == (240, 320)


def test_drop_buttons_add_bodies(window):
    """Drop sphere and drop box add a body above the scene."""
    n = window.world.body_count
    window.sphere_action.trigger()
    window.box_action.trigger()
    assert window.world.body_count == n + 2
    assert list(window.world.body_shape[-2:]) == [1, 2]
    top = max(p[2] for p in SPHERES) + 0.1
    assert np.all(window.world.body_position[-2:, 2] > top)
    window.step()  # the world steps with the new bodies
    assert np.isfinite(window.world.body_position).all()


def test_status_shows_counts_and_rates(window):
    """The status line shows bodies, particles, contacts, time, steps/s and fps."""
    window.step()
    text = window.status_label.text()
    for word in ("bodies", "particles", "contacts", "t = 0.004 s", "steps/s", "fps"):
        assert word in text


def test_a_drawing_failure_pauses_with_a_message(window):
    """When the view cannot draw, the window pauses and says why instead of crashing."""
    window.play()
    window.on_view_failed("drawing failed: test")
    assert not window.clock.playing
    assert "drawing failed: test" in window.message_label.text()


def test_reset_with_a_broken_scene_keeps_the_old_world(qtbot, tmp_path):
    """If the scene cannot be rebuilt (e.g. the file was broken meanwhile), Reset says so and keeps going."""
    from tumble.errors import SceneError
    from tumble.viewer import make_application
    from tumble.viewer.window import ViewerWindow

    calls = []

    def factory():
        calls.append(1)
        if len(calls) > 1:
            raise SceneError("expected a number", path="broken.toml", table="sphere[0]", key="radius")
        return make_world()

    make_application()
    win = ViewerWindow(factory=factory, size=(320, 240), paused=True, view="image", output_dir=tmp_path)
    qtbot.addWidget(win)
    win.step()
    old = win.world
    win.reset()
    assert win.world is old and old.step_count == 1
    assert "broken.toml" in win.message_label.text() and "radius" in win.message_label.text()
    win.close()


def test_offscreen_platform_picks_the_image_view_and_refuses_gl(qtbot):
    """On the offscreen platform "auto" gives the EGL image view (saying why); "gl" fails in one line."""
    from tumble.viewer import make_application
    from tumble.viewer.window import ViewerUnavailable, make_scene_view

    make_application()
    view = make_scene_view("auto", size=(64, 48))
    qtbot.addWidget(view)
    assert isinstance(view, ImageSceneView)
    assert "offscreen" in view.reason
    with pytest.raises(ViewerUnavailable, match='platform "offscreen" has no OpenGL windows'):
        make_scene_view("gl")
    with pytest.raises(ValueError, match="view kind"):
        make_scene_view("vulkan")


def test_no_gl_window_and_no_egl_is_one_clear_error(qtbot, monkeypatch):
    """Where neither an OpenGL window nor an EGL context can be made, the error says both reasons."""
    import tumble.render
    from tumble.errors import TumbleError
    from tumble.viewer import make_application
    from tumble.viewer.window import ViewerUnavailable, make_scene_view

    def no_egl():
        raise TumbleError("no OpenGL context: egl: eglGetDisplay failed")

    make_application()
    monkeypatch.setattr(tumble.render, "create_context", no_egl)
    with pytest.raises(ViewerUnavailable) as info:
        make_scene_view("auto")
    message = str(info.value)
    assert "\n" not in message
    assert 'no OpenGL window (the Qt platform "offscreen" has no OpenGL windows)' in message
    assert "eglGetDisplay failed" in message


def test_drag_pulls_a_cloth_particle(open_viewer, qtbot):
    """Pressing on a free cloth particle grabs it; pulling towards the camera moves it that way."""
    pytest.importorskip("tumble.cloth.system")
    window = open_viewer(make_cloth_world)
    cloth = window.world.cloth
    free = np.flatnonzero(np.asarray(cloth.particle_inv_mass) > 0)
    i = int(free[len(free) // 2])
    w, h = window.view.width(), window.view.height()
    x, y, depth = window.camera.project(cloth.particle_position[i], w, h)
    qtbot.mousePress(window.view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(int(x), int(y)))
    held = window.held
    assert held is not None and held.kind == "particle"
    qtbot.mouseMove(window.view, QtCore.QPoint(int(x), int(y) - 60))
    start = np.array(cloth.particle_position[held.index])
    for _ in range(30):
        window.step()
    moved = np.array(window.world.cloth.particle_position[held.index]) - start
    toward = held.target - start
    assert moved @ toward / np.linalg.norm(toward) > 0.02  # at least 2 cm towards the cursor
    assert math.isfinite(float(np.abs(window.world.cloth.particle_position).max()))


def test_no_display_is_reported_plainly(monkeypatch):
    """Without a display (and no offscreen platform asked for) the viewer says so instead of aborting."""
    import sys

    from tumble.viewer import gui_platform_problem

    monkeypatch.setenv("QT_QPA_PLATFORM", "offscreen")
    assert gui_platform_problem() is None
    if sys.platform.startswith("linux"):
        monkeypatch.delenv("QT_QPA_PLATFORM")
        monkeypatch.delenv("DISPLAY", raising=False)
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        assert "no display" in gui_platform_problem()
