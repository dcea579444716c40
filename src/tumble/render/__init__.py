"""Tumble's one renderer, shared by the interactive viewer and headless export (moderngl).

Headless, one call per image::

    from tumble.render import Camera, Renderer, create_context

    ctx = create_context()                      # EGL; TumbleError("no OpenGL context: ...") if none
    renderer = Renderer(ctx, 1280, 720)
    camera = Camera.for_world(world)            # the scene's [camera], else automatic framing
    image = renderer.render(world, camera)      # np.ndarray (720, 1280, 3) uint8, top row first

Inside a QOpenGLWidget (the viewer), with the widget's context current::

    ctx = moderngl.create_context()             # in initializeGL
    renderer = Renderer(ctx, w, h)
    renderer.draw(world, camera)                # in paintGL: draws into the bound framebuffer
    renderer.draw(world, camera, ctx.detect_framebuffer(self.defaultFramebufferObject()))

`render()` makes the renderer's context current for the call (and restores the previous one), so
several standalone contexts can live in one process. `draw()` uses whatever context is current,
as a widget's paint method expects; with a standalone context call it inside `with ctx:`.

Camera moves (all in place)::

    camera.orbit(dx, dy)      # radians: yaw about camera.up, elevation (clamped at +-89 deg)
    camera.pan(dx, dy)        # fractions of the view height at the target
    camera.zoom(factor)       # distance to target divided by factor (> 1 zooms in)
    camera.frame(world, aspect=w / h)   # fit all non-plane bodies, cloth and emitters
    camera.copy(); Camera.from_dict({"position": ..., "target": ..., "fov": deg})
    camera.project(points, w, h) -> (n, 3) pixel x, y (from the top left) and depth
    camera.ray(x, y, w, h) -> (origin, direction) for picking

`Renderer` attributes that may change between frames: `ground_cell_size` [m], `light_direction`,
`shadows`, `cloth_color`, `show_joints` (draw the joints); `resize(w, h)` changes the size
`render()` returns. Spheres, boxes, capsules, convex hulls and static meshes are drawn with their
real geometry (`tumble.render.solids`). Colours of bodies
come from `body_colors(indices)` (a stable hash of the body index), identical in viewer and video.
"""

from .camera import Camera, scene_bounds
from .colors import CLOTH_COLOR, PALETTE, body_colors
from .renderer import Renderer, SceneArrays, create_context, scene_arrays, vertex_normals

__all__ = [
    "CLOTH_COLOR",
    "PALETTE",
    "Camera",
    "Renderer",
    "SceneArrays",
    "body_colors",
    "create_context",
    "scene_arrays",
    "scene_bounds",
    "vertex_normals",
]
