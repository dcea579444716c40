"""The 3D view of the window, with two backends behind one interface.

- `GLSceneView`: a `QOpenGLWidget`; moderngl wraps Qt's own GL context and the shared renderer
  draws straight into the widget's framebuffer. Used on real desktops (and under Xvfb).
- `ImageSceneView`: a plain widget; the renderer draws with a standalone (EGL) moderngl context
  into its own framebuffer and the pixels are painted as a QImage. Used where Qt cannot make a GL
  window: the "offscreen" and "minimal" platforms (tests, no display), or when GL setup fails.

Both draw with the one renderer, `tumble.render.Renderer`, and share this interface: `world`
and `camera` attributes, `render_image()` for screenshots and video, `frame_count` for the fps
counter, and the `failed(str)` signal when drawing is impossible. Mouse and keys are handled by
the window through an event filter, the same for both.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np
from PySide6 import QtCore, QtGui, QtWidgets
from PySide6.QtOpenGLWidgets import QOpenGLWidget

if TYPE_CHECKING:
    import moderngl

    from ..render import Renderer

    _ViewBase = QtWidgets.QWidget  # the views mix this into a widget
else:
    _ViewBase = object

#: Qt platforms on which a QOpenGLWidget cannot work (it aborts on "offscreen")
NO_GL_WINDOW_PLATFORMS = ("offscreen", "minimal", "vnc")


#: the image view draws at a lower resolution (down to MIN_RENDER_SCALE) while a frame takes longer
#: than SLOW_FRAME_SECONDS, and goes back up once frames take less than FAST_FRAME_SECONDS
SLOW_FRAME_SECONDS = 0.06
FAST_FRAME_SECONDS = 0.02
MIN_RENDER_SCALE = 0.5


def gl_surface_format() -> QtGui.QSurfaceFormat:
    """OpenGL 3.3 core with a depth buffer and 4x multisampling: what the renderer needs."""
    fmt = QtGui.QSurfaceFormat()
    fmt.setRenderableType(QtGui.QSurfaceFormat.RenderableType.OpenGL)
    fmt.setVersion(3, 3)
    fmt.setProfile(QtGui.QSurfaceFormat.OpenGLContextProfile.CoreProfile)
    fmt.setDepthBufferSize(24)
    fmt.setSamples(4)
    return fmt


def probe_gl_window() -> tuple[str | None, str]:
    """Can Qt make OpenGL windows here? Returns (problem or None, the GL renderer's name).

    A QApplication must exist. The probe makes a context with the viewer's format and reads
    GL_RENDERER (e.g. "llvmpipe ..." when OpenGL runs on the CPU).
    """
    platform = QtGui.QGuiApplication.platformName()
    if platform in NO_GL_WINDOW_PLATFORMS:
        return f'the Qt platform "{platform}" has no OpenGL windows', ""
    context = QtGui.QOpenGLContext()
    context.setFormat(gl_surface_format())
    if not context.create():
        return f'Qt could not create an OpenGL context on the "{platform}" platform', ""
    fmt = context.format()
    if (fmt.majorVersion(), fmt.minorVersion()) < (3, 3):
        return f"the OpenGL context is version {fmt.majorVersion()}.{fmt.minorVersion()}; 3.3 is needed", ""
    surface = QtGui.QOffscreenSurface()
    surface.setFormat(fmt)
    surface.create()
    name = ""
    if context.makeCurrent(surface):
        name = str(context.functions().glGetString(0x1F01) or "")  # GL_RENDERER
        context.doneCurrent()
    surface.destroy()
    return None, name


def is_software_renderer(context) -> bool:
    """True when a moderngl context draws on the CPU (Mesa llvmpipe/softpipe, SwiftShader)."""
    return is_software_name(str(context.info.get("GL_RENDERER", "")))


def is_software_name(renderer: str) -> bool:
    """True for the GL_RENDERER names of CPU rasterisers."""
    name = renderer.lower()
    return any(word in name for word in ("llvmpipe", "softpipe", "swiftshader", "software"))


def qimage_to_array(image: QtGui.QImage) -> np.ndarray:
    """RGB pixels of a QImage as a (H, W, 3) uint8 array."""
    image = image.convertToFormat(QtGui.QImage.Format.Format_RGB888)
    w, h = image.width(), image.height()
    ptr = image.constBits()
    rows = np.frombuffer(ptr, dtype=np.uint8, count=image.bytesPerLine() * h).reshape(h, image.bytesPerLine())
    return rows[:, : 3 * w].reshape(h, w, 3).copy()


def array_to_qimage(pixels: np.ndarray) -> QtGui.QImage:
    """A QImage (owning its pixels) from a (H, W, 3) uint8 array."""
    pixels = np.ascontiguousarray(pixels, dtype=np.uint8)
    h, w = pixels.shape[:2]
    return QtGui.QImage(pixels.data, w, h, 3 * w, QtGui.QImage.Format.Format_RGB888).copy()


class _SceneViewMixin(_ViewBase):
    """What both views share: the world and camera to draw, frame counting, a size hint."""

    def _init_view(self, size: tuple[int, int]) -> None:
        self.world = None
        self.camera = None
        self.frame_count = 0
        self.renderer: Renderer | None = None
        self.shadows = True  # sun shadows (a second pass; costly in software rendering)
        self.show_joints = False  # draw the joints (rods and anchor dots)
        self.software = False  # drawing on the CPU (known once the GL context exists)
        self.spring_line = None  # ((x, y) of the held point, (x, y) of the cursor), or None
        self._size_hint = QtCore.QSize(*size)
        self.setFocusPolicy(QtCore.Qt.FocusPolicy.StrongFocus)
        self.setMouseTracking(False)
        self.setMinimumSize(160, 120)
        self.setSizePolicy(QtWidgets.QSizePolicy.Policy.Expanding, QtWidgets.QSizePolicy.Policy.Expanding)

    def paint_overlay(self, painter: QtGui.QPainter) -> None:
        """Draw the mouse spring, if any: a line from the held point to the cursor (widget pixels)."""
        if self.spring_line is None:
            return
        (x0, y0), (x1, y1) = self.spring_line
        painter.setRenderHint(QtGui.QPainter.RenderHint.Antialiasing)
        pen = QtGui.QPen(QtGui.QColor(255, 255, 255, 220), 2.0, QtCore.Qt.PenStyle.DashLine)
        painter.setPen(pen)
        painter.drawLine(QtCore.QPointF(x0, y0), QtCore.QPointF(x1, y1))
        painter.setPen(QtGui.QPen(QtGui.QColor(30, 30, 30, 220), 1.5))
        painter.setBrush(QtGui.QColor(255, 214, 10))
        painter.drawEllipse(QtCore.QPointF(x0, y0), 4.0, 4.0)
        painter.setBrush(QtCore.Qt.BrushStyle.NoBrush)
        painter.drawEllipse(QtCore.QPointF(x1, y1), 6.0, 6.0)

    def sizeHint(self) -> QtCore.QSize:  # noqa: N802 (Qt name)
        return self._size_hint

    def pixel_size(self) -> tuple[int, int]:
        """Size of the drawing in device pixels (width, height)."""
        ratio = self.devicePixelRatioF()
        return max(1, round(self.width() * ratio)), max(1, round(self.height() * ratio))


class ImageSceneView(_SceneViewMixin, QtWidgets.QWidget):
    """Offscreen backend: render with a standalone EGL context, paint the pixels as a QImage.

    Args:
        context: a standalone moderngl context (`tumble.render.create_context()`).
        size: preferred size in pixels (width, height).
    """

    failed = QtCore.Signal(str)
    backend_name = "offscreen EGL image"
    renderer: Renderer  # made with the view

    def __init__(self, context, *, size: tuple[int, int] = (960, 640), parent=None):
        super().__init__(parent)
        self._init_view(size)
        from ..render import Renderer

        self.context = context
        self.software = is_software_renderer(context)
        self.renderer = Renderer(context, *size)
        self.render_scale = 1.0  # drawing size / widget size, lowered while frames are slow
        self.adaptive = True
        self.reason = ""  # why this view was chosen over an OpenGL window
        self.setAttribute(QtCore.Qt.WidgetAttribute.WA_OpaquePaintEvent)

    def render_image(self, scale: float = 1.0) -> np.ndarray:
        """Render the current view: (H, W, 3) uint8 at the view's pixel size (times `scale`)."""
        width, height = self.pixel_size()
        width, height = max(1, round(width * scale)), max(1, round(height * scale))
        if (self.renderer.width, self.renderer.height) != (width, height):
            self.renderer.resize(width, height)
        self.renderer.shadows = self.shadows
        self.renderer.show_joints = self.show_joints
        return self.renderer.render(self.world, self.camera)

    def paintEvent(self, event) -> None:  # noqa: N802 (Qt name)
        painter = QtGui.QPainter(self)
        if self.world is None or self.camera is None:
            painter.fillRect(self.rect(), QtGui.QColor(40, 44, 52))
            return
        start = time.perf_counter()
        try:
            image = array_to_qimage(self.render_image(self.render_scale))
        except Exception as exc:  # noqa: BLE001 (shown to the user, not swallowed)
            painter.fillRect(self.rect(), QtGui.QColor(40, 44, 52))
            painter.end()
            self.failed.emit(f"drawing failed: {exc}")
            return
        painter.setRenderHint(QtGui.QPainter.RenderHint.SmoothPixmapTransform)
        painter.drawImage(self.rect(), image)
        self.paint_overlay(painter)
        painter.end()
        self.frame_count += 1
        self.adapt_scale(time.perf_counter() - start)

    def adapt_scale(self, seconds: float) -> None:
        """Software rendering is slow at full size: draw smaller (scaled up) while frames are slow."""
        if not self.adaptive:
            return
        if seconds > SLOW_FRAME_SECONDS and self.render_scale > MIN_RENDER_SCALE:
            self.render_scale = max(MIN_RENDER_SCALE, self.render_scale - 0.25)
        elif seconds < FAST_FRAME_SECONDS and self.render_scale < 1.0:
            self.render_scale = min(1.0, self.render_scale + 0.25)


class GLSceneView(_SceneViewMixin, QOpenGLWidget):
    """Desktop backend: moderngl wraps the widget's own GL context; draws into its framebuffer.

    Args:
        size: preferred size in pixels (width, height).
    """

    failed = QtCore.Signal(str)
    ready = QtCore.Signal()  # the GL context exists (initializeGL ran)
    backend_name = "OpenGL window"
    # the moderngl context; it hides QOpenGLWidget.context(), which this class does not call
    context: moderngl.Context | None  # type: ignore[assignment]

    def __init__(self, *, size: tuple[int, int] = (960, 640), parent=None):
        super().__init__(parent)
        self._init_view(size)
        self.setFormat(gl_surface_format())
        self.context = None
        self.problem: str | None = None

    def initializeGL(self) -> None:  # noqa: N802 (Qt name)
        import moderngl

        from ..render import Renderer

        try:
            # wrap the context Qt made current for this widget
            self.context = moderngl.create_context()
            self.software = is_software_renderer(self.context)
            self.renderer = Renderer(self.context, *self.pixel_size())
            QtCore.QTimer.singleShot(0, self.ready.emit)
        except Exception as exc:  # noqa: BLE001 (reported; the window falls back to the image view)
            self.problem = f"OpenGL setup failed: {exc}"
            self.renderer = None
            QtCore.QTimer.singleShot(0, lambda: self.failed.emit(self.problem))

    def paintGL(self) -> None:  # noqa: N802 (Qt name)
        if self.renderer is None:
            return
        assert self.context is not None  # made with the renderer
        # Qt binds its own framebuffer object for the widget; draw into exactly that one
        framebuffer = self.context.detect_framebuffer(self.defaultFramebufferObject())
        if self.world is None or self.camera is None:
            framebuffer.use()
            framebuffer.clear(0.16, 0.17, 0.2, 1.0)
            return
        width, height = self.pixel_size()
        self.renderer.shadows = self.shadows
        self.renderer.show_joints = self.show_joints
        try:
            self.renderer.draw(self.world, self.camera, framebuffer, viewport=(0, 0, width, height))
        except Exception as exc:  # noqa: BLE001
            self.renderer = None
            message = f"drawing failed: {exc}"  # (`exc` is unbound once the except block ends)
            QtCore.QTimer.singleShot(0, lambda: self.failed.emit(message))
            return
        if self.spring_line is not None:
            # Qt's painter draws over the scene in the same framebuffer: hand it a plain GL state
            # (the renderer sets all the state it needs at the start of every draw)
            import moderngl

            self.context.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
            painter = QtGui.QPainter(self)
            self.paint_overlay(painter)
            painter.end()
        self.frame_count += 1

    def render_image(self) -> np.ndarray:
        """Render the current view: (H, W, 3) uint8 at the view's pixel size (without the mouse spring)."""
        line, self.spring_line = self.spring_line, None
        try:
            return qimage_to_array(self.grabFramebuffer())
        finally:
            self.spring_line = line
