"""`ViewerWindow`: the 3D view in the centre, live controls on the right, status along the bottom.

Mouse (on the view):
    left drag on a body or cloth particle   pull it with a spring
    left drag elsewhere                     orbit
    right or middle drag, shift + left      pan
    wheel                                   zoom

Keys: space play/pause, . step, R reset, F frame the scene, Home reset the view,
1 drop a sphere, 2 drop a box, J show joints, S screenshot, V record video.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path

import numpy as np
from PySide6 import QtCore, QtGui, QtWidgets

from ..errors import TumbleError
from . import picking
from .controls import ControlsPanel
from .recorder import VideoRecorder, output_path, save_png
from .sim import SimulationClock, SimulationThread, WorldSnapshot
from .views import GLSceneView, ImageSceneView, is_software_name, probe_gl_window

#: timer period [ms]: the simulation and the view are updated at most this often (~60 Hz)
TICK_MS = 16
#: width of the controls panel [px]
PANEL_WIDTH = 290
#: frames per second of recorded video (one frame per 1/fps of simulated time)
VIDEO_FPS = 30.0
#: the simulation waits while this many recorded frames are waiting to be drawn
VIDEO_FRAMES_AHEAD = 8

_STYLE = """
QLabel#note { color: palette(mid); font-size: 9pt; font-style: italic; }
QLabel#stats { background: #23262e; color: #e6e6e6; padding: 3px 8px; }
QGroupBox { font-weight: bold; margin-top: 10px; }
QGroupBox::title { subcontrol-origin: margin; left: 6px; padding: 0 3px; }
QGroupBox QLabel { font-weight: normal; }
"""


HELP_HTML = """
<table cellspacing="4">
<tr><td colspan="2"><b>Mouse on the view</b></td></tr>
<tr><td>left drag on a body / cloth</td><td>pull it with a spring</td></tr>
<tr><td>left drag elsewhere</td><td>orbit</td></tr>
<tr><td>right or middle drag, shift + left drag</td><td>pan</td></tr>
<tr><td>wheel</td><td>zoom</td></tr>
<tr><td colspan="2"><b>Keys</b></td></tr>
<tr><td>space</td><td>play / pause</td></tr>
<tr><td>. (period)</td><td>one step</td></tr>
<tr><td>R</td><td>reset: rebuild the world from the scene</td></tr>
<tr><td>F / Home</td><td>frame the scene / starting view</td></tr>
<tr><td>1 / 2</td><td>drop a sphere / a box</td></tr>
<tr><td>J</td><td>show / hide the joints</td></tr>
<tr><td>S / V</td><td>screenshot (PNG) / record video (MP4)</td></tr>
</table>
"""


class ViewerUnavailable(TumbleError):
    """Neither an OpenGL window nor an offscreen EGL context can be made on this machine."""


def make_scene_view(kind: str = "auto", *, size: tuple[int, int] = (960, 640)):
    """Make the 3D view: an OpenGL window where that works well, else the offscreen image view.

    With "auto", OpenGL that runs on the CPU (Mesa llvmpipe: no GPU) also picks the image view:
    measured under Xvfb it drew 2-5x more frames per second than a software QOpenGLWidget, and
    it lowers its resolution while frames are slow.

    Args:
        kind: "auto", "gl" (OpenGL window only) or "image" (offscreen EGL image only).
        size: preferred size of the view in pixels (width, height).

    Raises:
        ViewerUnavailable: when the requested view (or, for "auto", either view) cannot be made.
    """
    if kind not in ("auto", "gl", "image"):
        raise ValueError(f'view kind must be "auto", "gl" or "image", got {kind!r}')
    problem = None
    if kind in ("auto", "gl"):
        problem, renderer = probe_gl_window()
        if problem is None and (kind == "gl" or not is_software_name(renderer)):
            return GLSceneView(size=size)
        if kind == "gl":
            raise ViewerUnavailable(f"cannot open an OpenGL window: {problem}")
        if problem is None:
            problem = f"OpenGL windows draw in software here ({renderer.split('(')[0].strip()})"
    try:
        from ..render import create_context

        context = create_context()
    except Exception as exc:  # noqa: BLE001 (turned into one clear line)
        why = f"no OpenGL window ({problem}) and " if problem else ""
        raise ViewerUnavailable(f"cannot start the viewer: {why}no offscreen EGL context ({exc})") from exc
    view = ImageSceneView(context, size=size)
    view.reason = problem or ""
    return view


#: room left around the window on the screen for the window manager's frame and title [px]
SCREEN_MARGIN = (16, 48)


def fit_on_screen(size: tuple[int, int], chrome: tuple[int, int], screen: QtCore.QRect) -> tuple[int, int]:
    """The view size, scaled down (same aspect) so that view + `chrome` fits in `screen`."""
    room_w = screen.width() - chrome[0] - SCREEN_MARGIN[0]
    room_h = screen.height() - chrome[1] - SCREEN_MARGIN[1]
    scale = min(1.0, room_w / size[0], room_h / size[1])
    if scale >= 1.0 or room_w <= 0 or room_h <= 0:
        return size
    return max(160, int(size[0] * scale)), max(120, int(size[1] * scale))


class ViewerWindow(QtWidgets.QMainWindow):
    """The interactive viewer around one world.

    Args:
        world: the world to show; None to build it with `factory`.
        factory: callable returning a fresh world, used by Reset (R). A scene file's viewer
            passes `lambda: tumble.load_scene(path)`; None disables Reset.
        title: window title (e.g. the scene's name).
        size: size of the 3D view in pixels (width, height).
        paused: start paused (else the simulation runs at once).
        view: "auto", "gl" or "image" (see `make_scene_view`).
        output_dir: folder for screenshots and videos.
    """

    def __init__(
        self,
        world=None,
        *,
        factory: Callable[[], object] | None = None,
        title: str = "Tumble",
        size: tuple[int, int] = (960, 640),
        paused: bool = False,
        view: str = "auto",
        output_dir=".",
        parent=None,
    ):
        super().__init__(parent)
        if world is None:
            if factory is None:
                raise ValueError("give a world or a factory that builds one")
            world = factory()
        from ..render import Camera
        from ..render.camera import ground_level

        self.title = title
        self.output_dir = Path(output_dir)
        self.clock = SimulationClock(world, factory=factory, before_step=self._before_step, after_step=self._after_step)
        # the world steps on this worker thread; the window draws its snapshots
        self.sim = SimulationThread(
            self.clock, period=TICK_MS / 1000.0, ready=lambda: len(self._video_frames) < VIDEO_FRAMES_AHEAD
        )
        self._drawn_version = self.sim.version
        self.held: picking.Grab | None = None
        self.recorder: VideoRecorder | None = None
        self._next_frame_time = 0.0
        self._video_frames: deque[WorldSnapshot] = deque()  # taken by the simulation, drawn by the window
        self._video_start = 0.0
        self._mouse_mode: str | None = None
        self._mouse_last = QtCore.QPointF()
        self._dirty = True
        self._drop_rng = np.random.default_rng(12345)
        self._fps = 0.0
        self._frames_seen = 0
        self._stats_time = time.perf_counter()
        self._sim_seen = world.time
        self._realtime = 0.0  # simulated seconds per real second over the last statistics period
        self.last_saved: Path | None = None

        self.setWindowTitle(f"{title} — Tumble viewer")
        self.setStyleSheet(_STYLE)

        # the 3D view, with the live statistics line right under it
        self.central = QtWidgets.QWidget()
        central_layout = QtWidgets.QVBoxLayout(self.central)
        central_layout.setContentsMargins(0, 0, 0, 0)
        central_layout.setSpacing(0)
        self.status_label = QtWidgets.QLabel()
        self.status_label.setObjectName("stats")
        self.status_label.setTextInteractionFlags(QtCore.Qt.TextInteractionFlag.TextSelectableByMouse)
        # a narrow window clips the line rather than growing to fit it
        self.status_label.setSizePolicy(QtWidgets.QSizePolicy.Policy.Ignored, QtWidgets.QSizePolicy.Policy.Minimum)
        central_layout.addWidget(self.status_label)
        self.setCentralWidget(self.central)
        self.view = make_scene_view(view, size=size)
        self._install_view(self.view)
        aspect = size[0] / size[1]
        self.camera = Camera.for_world(self.scene, aspect=aspect)
        self.camera.floor = ground_level(self.scene)  # orbit, pan and zoom stay above the ground
        self.home_camera = self.camera.copy()
        self.view.camera = self.camera

        # controls on the right
        self.controls = ControlsPanel()
        self.controls.bind(world)
        self.controls.apply = self.sim.submit
        self.controls.changed.connect(self._on_control_changed)
        self.controls.timeScaleChanged.connect(self._on_time_scale)
        self.controls.shadowsToggled.connect(self._on_shadows)
        self.controls.jointsToggled.connect(self._on_joints)
        scroll = QtWidgets.QScrollArea()
        scroll.setWidget(self.controls)
        scroll.setWidgetResizable(True)
        scroll.setHorizontalScrollBarPolicy(QtCore.Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        scroll.setFixedWidth(PANEL_WIDTH)
        self.dock = QtWidgets.QDockWidget("Controls", self)
        self.dock.setObjectName("controls")
        self.dock.setWidget(scroll)
        self.dock.setFeatures(
            QtWidgets.QDockWidget.DockWidgetFeature.DockWidgetMovable
            | QtWidgets.QDockWidget.DockWidgetFeature.DockWidgetFloatable
        )
        self.addDockWidget(QtCore.Qt.DockWidgetArea.RightDockWidgetArea, self.dock)

        self._build_actions()
        self._build_status()
        # make the 3D view itself `size`, with the toolbar, panel and status bar around it,
        # shrunk (keeping its shape) where that window would not fit on the screen
        chrome = (PANEL_WIDTH + 8, self.toolbar.sizeHint().height() + 2 * self.statusBar().sizeHint().height() + 4)
        size = fit_on_screen(size, chrome, self.screen().availableGeometry())
        self._view_size = size
        self.resize(size[0] + chrome[0], size[1] + chrome[1])
        self._fit_view()

        # one timer drives both the simulation and the repaints
        self.timer = QtCore.QTimer(self)
        self.timer.setTimerType(QtCore.Qt.TimerType.PreciseTimer)
        self.timer.timeout.connect(self.on_tick)
        self.timer.start(TICK_MS)
        self.sim.start()
        if not paused:
            self.play()
        self._update_play_action()
        self._update_status()
        self._view_ready()

    # ------------------------------------------------------------------ construction

    def _install_view(self, view) -> None:
        view.world = self.scene
        if hasattr(self, "controls"):
            view.shadows = self.controls.shadows.isChecked()
            view.show_joints = self.controls.joints.isChecked()
        view.installEventFilter(self)
        view.failed.connect(self.on_view_failed)
        if hasattr(view, "ready"):
            view.ready.connect(self._view_ready)
        layout = self.central.layout()
        assert isinstance(layout, QtWidgets.QBoxLayout)  # made with the window
        layout.insertWidget(0, view, 1)
        view.setFocus()

    def _action(self, text: str, key: str | None, slot, tip: str, *, checkable: bool = False) -> QtGui.QAction:
        action = QtGui.QAction(text, self)
        if key:
            action.setShortcut(QtGui.QKeySequence(key))
            action.setShortcutContext(QtCore.Qt.ShortcutContext.WindowShortcut)
            tip = f"{tip} ({QtGui.QKeySequence(key).toString(QtGui.QKeySequence.SequenceFormat.NativeText)})"
        action.setToolTip(tip)
        action.setCheckable(checkable)
        action.triggered.connect(slot)
        self.addAction(action)
        return action

    def _build_actions(self) -> None:
        self.play_action = self._action("Play", "Space", self.toggle_play, "Play or pause the simulation")
        self.step_action = self._action("Step", ".", self.step, "Advance exactly one step")
        self.reset_action = self._action("Reset", "R", self.reset, "Rebuild the world from the scene")
        self.reset_action.setEnabled(self.clock.factory is not None)
        self.frame_action = self._action("Frame", "F", self.frame_scene, "Fit the whole scene in view")
        self.home_action = self._action("Reset view", "Home", self.reset_view, "Back to the starting camera")
        self.sphere_action = self._action("Drop sphere", "1", self.drop_sphere, "Drop a sphere from above the scene")
        self.box_action = self._action("Drop box", "2", self.drop_box, "Drop a box from above the scene")
        self.joints_action = self._action("Joints", "J", self.toggle_joints, "Show or hide the joints")
        # (triggered(bool) would pass its `checked` flag as the path)
        self.shot_action = self._action("Screenshot", "S", lambda: self.screenshot(), "Save the view as a PNG")
        self.record_action = self._action(
            "Record", "V", self.toggle_recording, "Record the view to an MP4 while playing", checkable=True
        )
        self.help_action = self._action("Help", "F1", self.show_help, "Mouse and keyboard controls")

        bar = QtWidgets.QToolBar("Simulation", self)
        bar.setObjectName("toolbar")
        bar.setMovable(False)
        bar.setToolButtonStyle(QtCore.Qt.ToolButtonStyle.ToolButtonTextOnly)
        for group in (
            (self.play_action, self.step_action, self.reset_action),
            (self.frame_action, self.home_action),
            (self.sphere_action, self.box_action),
            (self.shot_action, self.record_action),
            (self.help_action,),
        ):
            for action in group:
                bar.addAction(action)
            bar.addSeparator()
        self.addToolBar(QtCore.Qt.ToolBarArea.TopToolBarArea, bar)
        self.toolbar = bar

    def _build_status(self) -> None:
        self.message_label = QtWidgets.QLabel()
        self.backend_label = QtWidgets.QLabel(self.view.backend_name)
        self.backend_label.setObjectName("note")
        status = self.statusBar()
        status.addWidget(self.message_label, 1)
        status.addPermanentWidget(self.backend_label)

    # ------------------------------------------------------------------ world and time

    @property
    def world(self):
        """The world being shown (replaced by Reset). It steps on the worker thread: read `scene`."""
        return self.clock.world

    @property
    def scene(self) -> WorldSnapshot:
        """The latest snapshot of the world, taken between steps: what is drawn and picked."""
        return self.sim.snapshot

    def play(self) -> None:
        """Run the simulation in real time (× the time scale), on the worker thread."""
        self.clock.play()
        self.sim.wake()
        self._update_play_action()

    def pause(self) -> None:
        """Stop the simulation; the view stays live."""
        self.clock.pause()
        self._update_play_action()

    def toggle_play(self) -> None:
        """Play if paused, pause if playing (space)."""
        self.pause() if self.clock.playing else self.play()

    def step(self) -> None:
        """Advance the world by exactly one step (period), pausing first."""
        if self.clock.playing:
            self.pause()
        self._guarded(self.clock.step)
        self.sim.publish()
        self._show_snapshot()

    def reset(self) -> None:
        """Rebuild the world from its scene (R); the camera, the play state and changed controls stay."""
        if self.clock.factory is None:
            self.show_message("This world was built in Python without a factory: it cannot be reset.", error=True)
            return
        self.held = None
        with self.clock.lock:
            try:
                world = self.clock.reset()
            except (TumbleError, ValueError, OSError) as exc:
                self.show_message(f"Reset failed, the old world stays: {exc}", error=True)
                return
            self.controls.bind(world, keep_user_values=True)
            self._next_frame_time = world.time
            self.sim.publish()
        self.view.world = self.scene
        self._sim_seen = world.time
        self.show_message("World reset.")
        self._mark_dirty()

    def _before_step(self, world) -> None:
        held = self.held  # (read once: the window may let go meanwhile)
        if held is not None:
            picking.apply_drag(world, held)

    def _guarded(self, action) -> bool:
        """Run a stepping action; on a simulation error pause and show it instead of crashing."""
        try:
            action()
            return True
        except TumbleError as exc:
            self.pause()
            self.show_message(f"Simulation stopped: {exc}", error=True)
            return False

    def on_tick(self) -> None:
        error, self.sim.error = self.sim.error, None
        if error is not None:
            self.pause()
            self.show_message(f"Simulation stopped: {error}", error=True)
        self._draw_video_frames(limit=2)
        if self.sim.version != self._drawn_version:
            self._show_snapshot()
        elif self._dirty:
            self._update_spring_line()
            self.view.update()
            self._dirty = False
        now = time.perf_counter()
        if now - self._stats_time >= 0.5:
            period = now - self._stats_time
            self._fps = (self.view.frame_count - self._frames_seen) / period
            self._realtime = max(0.0, self.scene.time - self._sim_seen) / period
            self._frames_seen, self._sim_seen = self.view.frame_count, self.scene.time
            self._stats_time = now
            self._update_status()

    def _update_spring_line(self) -> None:
        """Where the mouse spring is drawn: from the held point (as it moves) to the cursor."""
        line = None
        held = self.held
        if held is not None:
            w, h = self.view.width(), self.view.height()
            anchor = picking.held_point(self.scene, held)
            if anchor is not None:
                a = self.camera.project(anchor, w, h)
                c = self.camera.project(held.target, w, h)
                if a[2] > 0 and c[2] > 0:
                    line = ((float(a[0]), float(a[1])), (float(c[0]), float(c[1])))
        self.view.spring_line = line

    def _show_snapshot(self) -> None:
        """Draw the latest snapshot of the world."""
        self._drawn_version = self.sim.version
        self.view.world = self.scene
        self._update_spring_line()
        self.view.update()
        self._dirty = False
        if not self.clock.playing:
            self._update_status()

    def _mark_dirty(self) -> None:
        self._dirty = True
        if not self.timer.isActive():
            self.view.update()

    # ------------------------------------------------------------------ live controls

    def _on_control_changed(self, key: str, value: float) -> None:
        self._mark_dirty()

    def toggle_joints(self) -> None:
        """Show or hide the joints (J); the Display group's checkbox follows."""
        self.controls.joints.setChecked(not self.controls.joints.isChecked())

    def _on_joints(self, on: bool) -> None:
        self.view.show_joints = bool(on)
        self._mark_dirty()

    def _on_shadows(self, on: bool) -> None:
        self.view.shadows = bool(on)
        self._shadows_touched = True
        self._mark_dirty()

    def _view_ready(self) -> None:
        """Once the view's GL context exists: without a GPU, start with the cheaper settings."""
        if not hasattr(self, "backend_label"):
            return
        software = self.view.software
        self.backend_label.setText(self.view.backend_name + (", software" if software else ""))
        self.backend_label.setToolTip(getattr(self.view, "reason", ""))
        if software and not getattr(self, "_shadows_touched", False) and self.controls.shadows.isChecked():
            self.controls.shadows.setChecked(False)
            self._shadows_touched = False
            self.show_message("No GPU: sun shadows are off for speed (Display).")

    def _on_time_scale(self, value: float) -> None:
        self.clock.time_scale = float(value)

    # ------------------------------------------------------------------ camera

    def frame_scene(self) -> None:
        """Fit the whole scene in view, keeping the viewing direction (F)."""
        w, h = self.view.pixel_size()
        self.camera.frame(self.scene, aspect=w / h)
        self._mark_dirty()

    def reset_view(self) -> None:
        """Go back to the camera the window started with (Home)."""
        home = self.home_camera
        self.camera.position, self.camera.target = home.position.copy(), home.target.copy()
        self.camera.up, self.camera.fov_deg = home.up.copy(), home.fov_deg
        self._mark_dirty()

    def eventFilter(self, obj, event) -> bool:  # noqa: N802 (Qt name)
        if obj is not self.view:
            return super().eventFilter(obj, event)
        kind = event.type()
        Type = QtCore.QEvent.Type
        if kind == Type.MouseButtonPress:
            return self._mouse_press(event)
        if kind == Type.MouseMove:
            return self._mouse_move(event)
        if kind == Type.MouseButtonRelease:
            self._mouse_mode = None
            if self.held is not None:
                self.held = None
                self.show_message("")
                self._mark_dirty()
            return True
        if kind == Type.KeyPress:
            # shortcuts fire only in the active window; a key that reaches the view unhandled
            # (e.g. under a bare X server without a window manager) triggers its action here
            pressed = QtGui.QKeySequence(event.keyCombination())
            for action in self.actions():
                if action.isEnabled() and not action.shortcut().isEmpty() and action.shortcut() == pressed:
                    action.trigger()
                    return True
            return False
        if kind == Type.Wheel:
            steps = event.angleDelta().y() / 120.0
            if steps:
                self.camera.zoom(1.15**steps)
                self._mark_dirty()
            return True
        return False

    def _mouse_press(self, event) -> bool:
        buttons = QtCore.Qt.MouseButton
        shift = bool(event.modifiers() & QtCore.Qt.KeyboardModifier.ShiftModifier)
        self._mouse_last = event.position()
        self.view.setFocus()
        if event.button() == buttons.LeftButton and not shift:
            origin, direction = self._ray(event.position())
            grab = picking.pick(self.scene, origin, direction, self.camera.basis()[2])
            if grab is not None:
                self.held = grab
                self._mouse_mode = "drag"
                what = {"body": "body", "particle": "cloth particle", "pin": "pinned cloth particle"}[grab.kind]
                hint = "" if self.clock.playing else " (paused: press space to let it move)"
                self.show_message(f"Pulling {what} {grab.index}{hint}")
                self._mark_dirty()
                return True
            self._mouse_mode = "orbit"
        elif event.button() in (buttons.RightButton, buttons.MiddleButton) or (
            event.button() == buttons.LeftButton and shift
        ):
            self._mouse_mode = "pan"
        return True

    def _mouse_move(self, event) -> bool:
        if self._mouse_mode is None:
            return False
        pos = event.position()
        dx, dy = pos.x() - self._mouse_last.x(), pos.y() - self._mouse_last.y()
        self._mouse_last = pos
        h = max(1.0, float(self.view.height()))
        if self._mouse_mode == "orbit":
            self.camera.orbit(-dx * 0.01, dy * 0.01)
        elif self._mouse_mode == "pan":
            self.camera.pan(-dx / h, dy / h)
        elif self._mouse_mode == "drag" and self.held is not None:
            origin, direction = self._ray(pos)
            self.held.target = picking.drag_target(self.held, origin, direction, self.camera.basis()[2])
        self._mark_dirty()
        return True

    def _ray(self, pos: QtCore.QPointF):
        return self.camera.ray(pos.x(), pos.y(), max(1, self.view.width()), max(1, self.view.height()))

    # ------------------------------------------------------------------ dropping bodies

    def _drop_spot(self) -> tuple[np.ndarray, float, float]:
        """Where to drop a new body: above the scene's top, near its centre. (position, size, density)"""
        world = self.scene
        dynamic = np.asarray(world.body_inv_mass) > 0.0
        size, density = 0.1, 1000.0
        top = 0.0
        xy_centre, spread = np.zeros(2), 0.5
        if dynamic.any():
            pos = np.asarray(world.body_position)[dynamic]
            bound = np.maximum(world.body_radius, np.linalg.norm(world.body_half_extents, axis=1))[dynamic]
            size = float(np.clip(np.median(bound), 0.02, 1.0))
            top = float(np.max(pos[:, 2] + bound))
            xy_centre = 0.5 * (pos[:, :2].min(axis=0) + pos[:, :2].max(axis=0))
            spread = max(size, 0.3 * float(np.max(pos[:, :2].max(axis=0) - pos[:, :2].min(axis=0))))
            volume = np.where(
                np.asarray(world.body_shape)[dynamic] == 1,
                4.0 / 3.0 * math.pi * np.asarray(world.body_radius)[dynamic] ** 3,
                8.0 * np.prod(np.asarray(world.body_half_extents)[dynamic], axis=1),
            )
            density = float(np.median(np.asarray(world.body_mass)[dynamic] / np.maximum(volume, 1e-12)))
        cloth = picking.cloth_of(world)
        if cloth is not None:
            top = max(top, float(np.max(np.asarray(cloth.particle_position)[:, 2])))
        xy = xy_centre + self._drop_rng.uniform(-spread, spread, size=2)
        return np.array([xy[0], xy[1], top + 4.0 * size + 0.2]), size, density

    def _material_kwargs(self) -> dict:
        c = self.controls.controls
        return {"restitution": c["restitution"].value(), "friction": c["friction"].value()}

    def drop_sphere(self) -> None:
        """Drop a sphere (typical size of the scene's bodies) from above the scene (1)."""
        position, size, density = self._drop_spot()
        material = self._material_kwargs()
        self._drop(lambda: self.world.add_sphere(position=position, radius=size, density=density, **material), "sphere")

    def drop_box(self) -> None:
        """Drop a box (typical size of the scene's bodies), turned a little, from above the scene (2)."""
        position, size, density = self._drop_spot()
        half = size / math.sqrt(3.0)
        axis = self._drop_rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = self._drop_rng.uniform(0.2, 0.8)
        q = np.r_[axis * math.sin(angle / 2), math.cos(angle / 2)]
        material = self._material_kwargs()
        self._drop(
            lambda: self.world.add_box(
                position=position, half_extents=(half, half, half), density=density, orientation=q, **material
            ),
            "box",
        )

    def _drop(self, add: Callable[[], int], what: str) -> None:
        """Add a body between two steps (at once when no step is running)."""
        added = []
        now = self.sim.submit(lambda: added.append(add()))
        self.show_message(f"Dropped {what} {int(added[0])}." if now else f"Dropping a {what}...")
        self._mark_dirty()

    # ------------------------------------------------------------------ output

    def _file_stem(self) -> str:
        stem = "".join(ch if ch.isalnum() or ch in "-_" else "-" for ch in self.title).strip("-")
        return stem or "tumble"

    def screenshot(self, path=None) -> Path:
        """Save the current view as a PNG (S) in the output folder (or at `path`). Returns the path."""
        path = Path(path) if path is not None else output_path(self.output_dir, self._file_stem(), ".png")
        save_png(self.view.render_image(), path)
        self.last_saved = path
        self.show_message(f"Saved {path}")
        return path

    def toggle_recording(self) -> None:
        """Start or stop recording an MP4 (V); frames are taken while the simulation plays."""
        if self.recorder is None:
            self.start_recording()
        else:
            self.stop_recording()

    def start_recording(self, path=None) -> Path:
        """Start recording the view to an MP4 (one frame per 1/30 s of simulated time)."""
        if self.recorder is not None:
            return self.recorder.path
        path = Path(path) if path is not None else output_path(self.output_dir, self._file_stem(), ".mp4")
        with self.clock.lock:
            # frame 0 is the world now; frame k is taken by the step that reaches t0 + k / fps
            self._video_frames.clear()
            self._video_frames.append(WorldSnapshot(self.world))
            self._next_frame_time = self.world.time + 1.0 / VIDEO_FPS
            self._video_start = self.world.time
            self.recorder = VideoRecorder(path, fps=VIDEO_FPS)
        if hasattr(self.view, "adaptive"):
            # draw at full size while recording, so frames are not rendered twice at two sizes
            self.view.adaptive, self.view.render_scale = False, 1.0
        self.record_action.setChecked(True)
        self.record_action.setText("Stop")
        self.show_message(f"Recording to {path}: one frame per 1/{VIDEO_FPS:g} s of simulated time, while playing")
        return path

    def stop_recording(self) -> Path | None:
        """Finish the MP4. Returns its path (None when no frame was taken)."""
        with self.clock.lock:
            recorder, self.recorder = self.recorder, None
        if recorder is not None:
            self._draw_video_frames(recorder=recorder)
        self.record_action.setChecked(False)
        if hasattr(self.view, "adaptive"):
            self.view.adaptive = True
        self.record_action.setText("Record")
        if recorder is None:
            return None
        try:
            path = recorder.close()
        except Exception as exc:  # noqa: BLE001 (an encoder failure is shown, not raised into Qt)
            self.show_message(f"Video failed: {exc}", error=True)
            return None
        if path is None:
            self.show_message("Recording stopped: no frames were taken (the simulation was paused).")
        else:
            self.last_saved = path
            self.show_message(f"Saved {path} ({recorder.frame_count} frames)")
        return path

    def _after_step(self, world) -> None:
        """After each step (on the simulation's thread): keep a snapshot for every video frame now due."""
        if self.recorder is None:
            return
        snapshot = None
        while world.time + 1e-9 >= self._next_frame_time:
            # a step longer than a frame gives that frame twice, so the video keeps time
            snapshot = snapshot or WorldSnapshot(world)
            self._video_frames.append(snapshot)
            self._next_frame_time += 1.0 / VIDEO_FPS

    def _draw_video_frames(self, *, limit: int | None = None, recorder: VideoRecorder | None = None) -> None:
        """Draw the waiting video frames (at most `limit`) into the recorder, as the current camera sees them."""
        recorder = recorder or self.recorder
        if recorder is None:
            return
        drawn = 0
        shown = self.view.world
        try:
            while self._video_frames and (limit is None or drawn < limit):
                self.view.world = self._video_frames.popleft()
                recorder.add(self.view.render_image())
                drawn += 1
        except Exception as exc:  # noqa: BLE001 (an encoder failure is shown, not raised into Qt)
            self.show_message(f"Recording stopped: {exc}", error=True)
            self.recorder = None
            self._video_frames.clear()
            self.record_action.setChecked(False)
        finally:
            self.view.world = shown
        self.sim.wake()

    # ------------------------------------------------------------------ status and errors

    def show_help(self) -> None:
        """Show the mouse and keyboard controls (F1) in a non-blocking box."""
        box = QtWidgets.QMessageBox(self)
        box.setWindowTitle("Tumble viewer controls")
        box.setTextFormat(QtCore.Qt.TextFormat.RichText)
        box.setText(HELP_HTML)
        box.setModal(False)
        box.open()
        self._help_box = box

    def show_message(self, text: str, *, error: bool = False) -> None:
        """Show a line in the status bar (red for errors)."""
        self.message_label.setStyleSheet("color: #c0392b;" if error else "")
        self.message_label.setText(text)

    def status_text(self) -> str:
        """The status line: bodies, particles, contacts, time, steps/s and fps."""
        world = self.scene
        cloth = picking.cloth_of(world)
        particles = cloth.particle_count if cloth is not None else 0
        if self.clock.playing:
            # how fast simulated time actually runs, against the time scale asked for
            state = f"playing, {self._realtime:.2f}× real time"
            if self.clock.time_scale != 1.0:
                state += f" (asked {self.clock.time_scale:g}×)"
        else:
            state = "paused"
        if self.recorder is not None:
            state += f", recording {max(0.0, world.time - self._video_start):.2f} s"
        return "   ".join(
            [
                f"bodies {world.body_count:,}",
                f"particles {particles:,}",
                f"contacts {world.contact_count:,}",
                f"t = {world.time:.3f} s (step {world.step_count:,})",
                f"{self.clock.steps_per_second():.0f} steps/s",
                f"{self._fps:.0f} fps",
                state,
            ]
        )

    def _update_status(self) -> None:
        self.status_label.setText(self.status_text())

    def _update_play_action(self) -> None:
        if hasattr(self, "play_action"):
            self.play_action.setText("Pause" if self.clock.playing else "Play")

    def on_view_failed(self, reason: str) -> None:
        """The GL view could not draw: switch to the offscreen image view, or explain and stop."""
        if isinstance(self.view, ImageSceneView):
            self.pause()
            self.show_message(f"Cannot draw: {reason}", error=True)
            return
        try:
            view = make_scene_view("image", size=(self.view.width(), self.view.height()))
        except ViewerUnavailable as exc:
            self.pause()
            self.show_message(f"{reason}; {exc}", error=True)
            return
        old = self.view
        layout = self.central.layout()
        assert layout is not None  # made with the window
        layout.removeWidget(old)
        old.hide()
        old.deleteLater()
        self.view = view
        view.camera = self.camera
        self._frames_seen = 0
        self._install_view(view)
        self.backend_label.setText(view.backend_name)
        self.show_message(f"{reason}; drawing offscreen instead.", error=True)

    def _fit_view(self) -> None:
        """Resize the window so that the 3D view gets exactly the requested size."""
        layout = self.layout()
        assert layout is not None  # a main window always has one
        layout.activate()
        w, h = self._view_size
        dw, dh = w - self.view.width(), h - self.view.height()
        if dw or dh:
            self.resize(self.width() + dw, self.height() + dh)

    def showEvent(self, event) -> None:  # noqa: N802 (Qt name)
        super().showEvent(event)
        if not getattr(self, "_shown_once", False):
            self._shown_once = True
            self._fit_view()

    def closeEvent(self, event) -> None:  # noqa: N802 (Qt name)
        self.timer.stop()
        self.sim.stop()
        if self.recorder is not None:
            self.stop_recording()
        super().closeEvent(event)
