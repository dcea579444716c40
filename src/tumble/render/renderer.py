"""The moderngl renderer: sky, checkered ground planes, impostor spheres, instanced boxes,
capsules, convex hulls and static meshes, cloth, and (on demand) the joints.

Per frame it reads the world's array views once, packs one float32 instance array per shape
kind (spheres, boxes, capsules; hulls and meshes: one per prototype, `tumble.render.solids`) and
the cloth's vertices, and uploads each with a single buffer write; no Python loop runs over
bodies (hulls loop over their distinct prototypes). Passes, in order:

1. sun shadow map (optional): every shape and the cloth rendered depth-only from the sun;
2. sky: one screen-covering triangle, gradient from the view direction;
3. planes: one screen-covering ray-cast pass per plane (exact to the horizon, checkered,
   fading into the sky with distance, drawn only from the front side);
4. spheres: one quad per sphere, ray-cast against the sphere, true depth written;
5. boxes: one instanced 36-vertex cube per box, darkened edges;
6. capsules: one instanced draw of impostors (each ray cast inside its bounding box); hulls and
   static meshes: one instanced draw per prototype (a vertex buffer each, made once and cached);
7. cloth: one indexed, two-sided triangle mesh with per-vertex normals;
8. joints (`show_joints`): rods from each body's centre to its anchor and dots on the anchors,
   opaque where in view and faint where hidden inside or behind bodies;
9. glass: walls seen from behind (a container's near walls), blended, no depth written.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import TumbleError
from ..shapes import ShapeType
from . import shaders, solids
from .camera import Camera, scene_bounds, scene_box
from .colors import CLOTH_COLOR, body_colors
from .solids import CAPSULE_FLOATS, SOLID_FLOATS, vertex_normals
from .supports import cloth_supports

#: OpenGL enum of alpha-to-coverage (moderngl has no named flag for it)
GL_SAMPLE_ALPHA_TO_COVERAGE = 0x809E
#: floats per instance: centre 3, radius 1, orientation 4, colour 3
SPHERE_FLOATS = 11
#: floats per instance: centre 3, orientation 4, half extents 3, colour 3
BOX_FLOATS = 13
#: hull and mesh vertex buffers kept between frames (beyond it, those not drawn now are freed)
SOLID_CACHE_SIZE = 512


def create_context(*, require: tuple[int, int] = (3, 3)):
    """A headless moderngl context (EGL, no display needed; Mesa llvmpipe works without a GPU).

    Raises:
        TumbleError: "no OpenGL context: ..." when neither EGL nor the default backend gives one.
    """
    try:
        import moderngl
    except ImportError:  # pragma: no cover - moderngl is a declared dependency
        raise TumbleError(
            "no OpenGL context: the Python package 'moderngl' is not installed; install it with: "
            'pip install "tumble[viewer]"'
        ) from None
    version = require[0] * 100 + require[1] * 10
    errors = []
    for kwargs in ({"backend": "egl"}, {}):
        try:
            ctx = moderngl.create_standalone_context(require=version, **kwargs)  # type: ignore[arg-type]  # backend only
        except Exception as exc:  # moderngl raises plain Exceptions from its loaders
            errors.append(
                f"{kwargs.get('backend', 'default')}: {str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__}"
            )
            continue
        return ctx
    raise TumbleError(
        "no OpenGL context: "
        + "; ".join(errors)
        + " (headless rendering needs EGL and Mesa: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1)"
    )


@dataclass
class SceneArrays:
    """What the renderer draws, packed from a world's views.

    Attributes:
        spheres: instance data, shape (n_spheres, 11), float32: centre, radius, quaternion, colour.
        sphere_body: body index of each sphere, shape (n_spheres,).
        boxes: instance data, shape (n_boxes, 13), float32: centre, quaternion, half extents, colour.
        box_body: body index of each box, shape (n_boxes,); -1 for the supports drawn under
            pinned cloth (`tumble.render.supports`).
        planes: unit normal and offset of each plane, shape (n_planes, 4), float64.
        cloth_position: cloth particle positions [m], shape (P, 3), or None.
        cloth_triangles: cloth triangles, shape (T, 3), int, or None.
        capsules: instance data, shape (n_capsules, 12), float32: centre, quaternion, radius,
            half height, colour.
        capsule_body: body index of each capsule, shape (n_capsules,).
        solids: one `SolidBatch` per hull prototype and per static mesh drawn.
        joints: (centre a, anchor a, anchor b, centre b) of each unbroken joint [m], shape (J, 4, 3).
    """

    spheres: np.ndarray
    sphere_body: np.ndarray
    boxes: np.ndarray
    box_body: np.ndarray
    planes: np.ndarray
    cloth_position: np.ndarray | None = None
    cloth_triangles: np.ndarray | None = None
    capsules: np.ndarray = field(default_factory=lambda: np.zeros((0, CAPSULE_FLOATS), np.float32))
    capsule_body: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    solids: list = field(default_factory=list)
    joints: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 3)))


@dataclass
class SolidBatch:
    """The bodies drawn with one hull prototype or one static mesh.

    Attributes:
        key: what identifies the geometry for the renderer's vertex-buffer cache.
        source: the object the geometry comes from (kept alive while cached, so `key` stays unique).
        build: returns the triangles, (V, 6) float32 rows (position, normal) in the body frame.
        instances: shape (k, 10), float32: centre, quaternion, colour.
        body: body index of each instance, shape (k,).
    """

    key: tuple
    source: object
    build: Callable[..., np.ndarray]  # called with no arguments
    instances: np.ndarray
    body: np.ndarray


class _ColorCache:
    """Body colours by index, computed once per body and grown as bodies appear."""

    def __init__(self):
        self.colors = np.zeros((0, 3), dtype=np.float32)

    def get(self, n: int) -> np.ndarray:
        if len(self.colors) < n:
            grown = max(n, 2 * len(self.colors), 64)
            self.colors = body_colors(np.arange(grown))
        return self.colors[:n]


_color_cache = _ColorCache()


def scene_arrays(world) -> SceneArrays:
    """Pack a world's bodies and cloth into the renderer's arrays (no GL needed)."""
    n = int(world.body_count)
    shape = np.asarray(world.body_shape)[:n]
    pos = np.asarray(world.body_position)[:n]
    quat = np.asarray(world.body_orientation)[:n]
    colors = _color_cache.get(n)
    finite = np.isfinite(pos).all(axis=1) & np.isfinite(quat).all(axis=1)

    sphere_body = np.flatnonzero((shape == ShapeType.SPHERE) & finite)
    spheres = np.empty((len(sphere_body), SPHERE_FLOATS), dtype=np.float32)
    spheres[:, 0:3] = pos[sphere_body]
    spheres[:, 3] = np.asarray(world.body_radius)[sphere_body]
    spheres[:, 4:8] = quat[sphere_body]
    spheres[:, 8:11] = colors[sphere_body]

    box_body = np.flatnonzero((shape == ShapeType.BOX) & finite)
    boxes = np.empty((len(box_body), BOX_FLOATS), dtype=np.float32)
    boxes[:, 0:3] = pos[box_body]
    boxes[:, 3:7] = quat[box_body]
    boxes[:, 7:10] = np.asarray(world.body_half_extents)[box_body]
    boxes[:, 10:13] = colors[box_body]

    plane_body = np.flatnonzero((shape == ShapeType.PLANE) & finite)
    planes = np.empty((len(plane_body), 4))
    if len(plane_body):
        normal = np.asarray(world.body_plane_normal)[plane_body]
        planes[:, 0:3] = normal
        planes[:, 3] = np.einsum("ij,ij->i", normal, pos[plane_body])

    cloth_position = cloth_triangles = None
    if world.has_cloth:
        cloth = world.cloth
        p = np.asarray(cloth.particle_position, dtype=np.float64).reshape(-1, 3)
        t = np.asarray(cloth.triangles).reshape(-1, 3)
        if len(p) and len(t):
            cloth_position, cloth_triangles = p, t
        # posts and rails under pinned cloth: drawn as boxes of no body (index -1)
        supports = cloth_supports(world, BOX_FLOATS)
        if len(supports):
            boxes = np.concatenate([boxes, supports])
            box_body = np.concatenate([box_body, np.full(len(supports), -1, dtype=box_body.dtype)])

    capsule_body = np.flatnonzero((shape == ShapeType.CAPSULE) & finite)
    capsules = np.empty((len(capsule_body), CAPSULE_FLOATS), dtype=np.float32)
    capsules[:, 0:3] = pos[capsule_body]
    capsules[:, 3:7] = quat[capsule_body]
    capsules[:, 7] = np.asarray(world.body_radius)[capsule_body]
    # the body-frame half extents are (r, r, a + r): the segment's half length is h_z - r
    capsules[:, 8] = np.asarray(world.body_half_extents)[capsule_body, 2] - capsules[:, 7]
    capsules[:, 9:12] = colors[capsule_body]
    batches = _solid_batches(world, shape, pos, quat, colors, finite)
    return SceneArrays(
        spheres,
        sphere_body,
        boxes,
        box_body,
        planes,
        cloth_position,
        cloth_triangles,
        capsules,
        capsule_body,
        batches,
        solids.joint_segments(world),
    )


def _solid_batches(world, shape, pos, quat, colors, finite) -> list[SolidBatch]:
    """One batch per hull prototype in use (its bodies as instances) and one per static mesh."""
    out: list[SolidBatch] = []
    picked = np.flatnonzero(((shape == ShapeType.CONVEX) | (shape == ShapeType.MESH)) & finite)
    if not len(picked):
        return out
    geometry = np.asarray(world.body_geometry)[picked]
    hulls, meshes = getattr(world, "hulls", None), getattr(world, "meshes", None)
    is_hull = shape[picked] == ShapeType.CONVEX
    for index in np.unique(geometry[is_hull]):
        if hulls is None or not 0 <= index < len(hulls.prototypes):
            continue
        proto = hulls.prototypes[int(index)]
        body = picked[is_hull & (geometry == index)]
        out.append(
            SolidBatch(
                ("hull", id(proto)),
                proto,
                lambda p=proto: solids.hull_vertices(p),
                _solid_instances(pos, quat, colors[body], body),
                body,
            )
        )
    for body in picked[~is_hull]:
        index = int(np.asarray(world.body_geometry)[body])
        if meshes is None or not 0 <= index < len(meshes.vertices):
            continue
        v, t = meshes.vertices[index], meshes.triangles[index]
        color = np.asarray(solids.MESH_COLOR, dtype=np.float32)[None]
        out.append(
            SolidBatch(
                ("mesh", id(v)),
                v,
                lambda v=v, t=t: solids.mesh_vertices(v, t),
                _solid_instances(pos, quat, color, np.array([body])),
                np.array([body]),
            )
        )
    return out


def _solid_instances(pos, quat, color, body) -> np.ndarray:
    out = np.empty((len(body), SOLID_FLOATS), dtype=np.float32)
    out[:, 0:3] = pos[body]
    out[:, 3:7] = quat[body]
    out[:, 7:10] = color
    return out


def _container_width(planes: np.ndarray) -> float | None:
    """Largest gap [m] between two upright walls facing each other (n_i . n_j < -0.99), or None.

    Planes are rows (unit normal, offset) with the inside at n . x >= offset, so two opposite
    walls enclose -(offset_i + offset_j) of space between them.
    """
    upright = planes[np.abs(planes[:, 2]) < 0.1]
    if len(upright) < 2:
        return None
    facing = upright[:, :3] @ upright[:, :3].T < -0.99
    gap = -(upright[:, 3][:, None] + upright[:, 3][None, :])
    gaps = gap[facing & (gap > 0.0)]
    return float(gaps.max()) if len(gaps) else None


def _cube() -> np.ndarray:
    """Unit cube [-1, 1]^3 as 36 vertices (position, outward normal), counter-clockwise outside."""
    rows = []
    eye = np.eye(3)
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = sign * eye[axis]
            u, v = eye[(axis + 1) % 3], eye[(axis + 2) % 3]
            if sign < 0:
                u, v = v, u  # keep u x v = n so the winding stays counter-clockwise from outside
            quad = [n - u - v, n + u - v, n + u + v, n - u + v]
            for i in (0, 1, 2, 0, 2, 3):
                rows.append(np.r_[quad[i], n])
    return np.array(rows, dtype=np.float32)


def _mat(m: np.ndarray) -> bytes:
    """A row-major (4, 4) float64 matrix as the column-major float32 bytes GLSL expects."""
    return np.ascontiguousarray(m.T, dtype=np.float32).tobytes()


def _ortho(half: float, near: float, far: float) -> np.ndarray:
    m = np.eye(4)
    m[0, 0] = m[1, 1] = 1.0 / half
    m[2, 2] = -2.0 / (far - near)
    m[2, 3] = -(far + near) / (far - near)
    return m


def _perpendicular(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (t, b) with (t, b, n) right-handed; t follows world x where it can."""
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = a - n * np.dot(n, a)
    t /= np.linalg.norm(t)
    return t, np.cross(n, t)


class Renderer:
    """Draws a `World` with moderngl, into an offscreen image or a given framebuffer.

    Args:
        ctx: a moderngl context (`create_context()` headless, or the viewer's widget context).
        width, height: size in pixels of the images `render()` returns.
        samples: multisampling of `render()`'s offscreen framebuffer (0 = off; 4 smooths edges).
        shadows: draw sun shadows (a depth map of the scene from the sun).
        shadow_size: shadow map size in texels.

    Attributes you may change between frames: `ground_cell_size` [m] (checker square size),
    `light_direction` (unit vector towards the sun), `shadows`, `cloth_color` (sRGB), `dither`,
    `show_joints` (draw the joints: rods and anchor dots, about 1.5 and 3.5 pixels wide at the
    camera's target).
    """

    def __init__(
        self,
        ctx,
        width: int = 1280,
        height: int = 720,
        *,
        samples: int = 0,
        shadows: bool = True,
        shadow_size: int = 1024,
    ):
        import moderngl

        self._mgl = moderngl
        self.ctx = ctx
        self.width, self.height = self._check_size(width, height)
        self.samples = int(samples)
        self.shadows = bool(shadows)
        self.ground_cell_size = 1.0
        self.light_direction = np.array([0.6, -0.15, 1.0]) / np.linalg.norm([0.6, -0.15, 1.0])
        self.cloth_color = CLOTH_COLOR
        # +-1/255 of noise on every output colour, so gradients show no 8-bit bands; GIF export
        # turns it off (its 256-colour palette quantises anyway, and noise costs it 3-4x the size)
        self.dither = True
        self.show_joints = False
        self._fbo = self._resolve = None
        self._fbo_size: tuple[int, int, int] | None = None
        # box that walls are cut to: the union of the scene's bounds over the frames drawn of
        # one world, so walls keep their size while bodies fall or fly out
        self._wall_world = None
        self._wall_box: tuple[np.ndarray, np.ndarray] | None = None
        with ctx:  # create the GL objects in this context, whichever is current now
            self._create_gl_objects(int(shadow_size))

    def _create_gl_objects(self, shadow_size: int) -> None:
        ctx, moderngl = self.ctx, self._mgl
        prog = ctx.program
        self._sky = prog(vertex_shader=shaders.SKY_VERTEX, fragment_shader=shaders.SKY_FRAGMENT)
        self._plane = prog(vertex_shader=shaders.SKY_VERTEX, fragment_shader=shaders.PLANE_FRAGMENT)
        self._sphere = prog(vertex_shader=shaders.SPHERE_VERTEX, fragment_shader=shaders.SPHERE_FRAGMENT)
        self._box = prog(vertex_shader=shaders.BOX_VERTEX, fragment_shader=shaders.BOX_FRAGMENT)
        self._cloth = prog(vertex_shader=shaders.CLOTH_VERTEX, fragment_shader=shaders.CLOTH_FRAGMENT)
        self._shadow_sphere = prog(
            vertex_shader=shaders.SHADOW_SPHERE_VERTEX, fragment_shader=shaders.SHADOW_SPHERE_FRAGMENT
        )
        self._shadow_box = prog(vertex_shader=shaders.SHADOW_BOX_VERTEX, fragment_shader=shaders.EMPTY_FRAGMENT)
        self._shadow_mesh = prog(vertex_shader=shaders.SHADOW_MESH_VERTEX, fragment_shader=shaders.EMPTY_FRAGMENT)
        self._solid = prog(vertex_shader=shaders.SOLID_VERTEX, fragment_shader=shaders.SOLID_FRAGMENT)
        self._capsule = prog(vertex_shader=shaders.CAPSULE_VERTEX, fragment_shader=shaders.CAPSULE_FRAGMENT)
        self._shadow_solid = prog(vertex_shader=shaders.SHADOW_SOLID_VERTEX, fragment_shader=shaders.EMPTY_FRAGMENT)
        self._shadow_capsule = prog(
            vertex_shader=shaders.CAPSULE_VERTEX, fragment_shader=shaders.SHADOW_CAPSULE_FRAGMENT
        )
        self._lit = (self._sky, self._plane, self._sphere, self._box, self._cloth, self._solid, self._capsule)

        # static geometry
        corners = np.array([[-1, -1], [1, -1], [-1, 1], [1, 1]], dtype=np.float32)
        self._quad_vbo = ctx.buffer(corners.tobytes())
        self._cube_vbo = ctx.buffer(_cube().tobytes())
        # per-frame instance and cloth buffers, grown by orphaning (the VAOs stay valid)
        self._sphere_buf = ctx.buffer(reserve=64 * SPHERE_FLOATS * 4, dynamic=True)
        self._box_buf = ctx.buffer(reserve=64 * BOX_FLOATS * 4, dynamic=True)
        self._cloth_vbo = ctx.buffer(reserve=1024 * 24, dynamic=True)
        self._cloth_ibo = ctx.buffer(reserve=1024 * 12, dynamic=True)
        self._cloth_tris: np.ndarray | None = None
        self._capsule_buf = ctx.buffer(reserve=64 * CAPSULE_FLOATS * 4, dynamic=True)
        self._joint_buf = ctx.buffer(reserve=64 * CAPSULE_FLOATS * 4, dynamic=True)
        # hull and mesh vertex buffers by SolidBatch.key: (source, vbo, instance buffer, vao, shadow vao, count)
        self._solid_cache: dict[tuple, tuple] = {}  # batch key -> its GPU buffers (`cached_batches`)

        va = ctx.vertex_array
        self._sky_vao = va(self._sky, [])
        self._plane_vao = va(self._plane, [])
        self._sphere_vao = va(
            self._sphere,
            [
                (self._quad_vbo, "2f", "in_corner"),
                (self._sphere_buf, "3f 1f 4f 3f/i", "in_center", "in_radius", "in_quat", "in_color"),
            ],
        )
        self._box_vao = va(
            self._box,
            [
                (self._cube_vbo, "3f 3f", "in_position", "in_normal"),
                (self._box_buf, "3f 4f 3f 3f/i", "in_center", "in_quat", "in_half", "in_color"),
            ],
        )
        self._cloth_vao = va(
            self._cloth,
            [(self._cloth_vbo, "3f 3f", "in_position", "in_normal")],
            index_buffer=self._cloth_ibo,
            index_element_size=4,
        )
        self._shadow_sphere_vao = va(
            self._shadow_sphere,
            [
                (self._quad_vbo, "2f", "in_corner"),
                (self._sphere_buf, "3f 1f 28x/i", "in_center", "in_radius"),
            ],
        )
        self._shadow_box_vao = va(
            self._shadow_box,
            [
                (self._cube_vbo, "3f 12x", "in_position"),
                (self._box_buf, "3f 4f 3f 12x/i", "in_center", "in_quat", "in_half"),
            ],
        )
        self._shadow_cloth_vao = va(
            self._shadow_mesh,
            [(self._cloth_vbo, "3f 12x", "in_position")],
            index_buffer=self._cloth_ibo,
            index_element_size=4,
        )
        # capsules are ray cast inside their bounding boxes: the cube's corners, no normals
        capsule_layout = ("3f 4f 1f 1f 3f/i", "in_center", "in_quat", "in_radius", "in_half", "in_color")
        self._capsule_vao = va(
            self._capsule, [(self._cube_vbo, "3f 12x", "in_position"), (self._capsule_buf, *capsule_layout)]
        )
        self._joint_vao = va(
            self._capsule, [(self._cube_vbo, "3f 12x", "in_position"), (self._joint_buf, *capsule_layout)]
        )
        self._shadow_capsule_vao = va(
            self._shadow_capsule,
            [
                (self._cube_vbo, "3f 12x", "in_position"),
                (self._capsule_buf, "3f 4f 1f 1f 12x/i", "in_center", "in_quat", "in_radius", "in_half"),
            ],
        )

        # sun shadow map: a depth texture read as plain values (no hardware comparison)
        self._shadow_tex = ctx.depth_texture((shadow_size, shadow_size))
        self._shadow_tex.compare_func = ""
        self._shadow_tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._shadow_tex.repeat_x = self._shadow_tex.repeat_y = False
        self._shadow_fbo = ctx.framebuffer(depth_attachment=self._shadow_tex)

    # ------------------------------------------------------------------ public API

    def resize(self, width: int, height: int) -> None:
        """Change the size of the images `render()` returns."""
        self.width, self.height = self._check_size(width, height)

    def render(self, world, camera: Camera | None = None) -> np.ndarray:
        """Draw `world` offscreen and read it back: RGB image, shape (height, width, 3), uint8.

        With no camera, uses `Camera.for_world(world)` (the scene's camera or automatic framing).
        """
        if camera is None:
            camera = Camera.for_world(world, aspect=self.width / self.height)
        # make this renderer's context current (another one may have been made or released
        # since), and restore the previous one afterwards
        with self.ctx:
            fbo = self._offscreen()
            self.draw(world, camera, fbo)
            if self._resolve is not None:
                self.ctx.copy_framebuffer(self._resolve, fbo)
                fbo = self._resolve
            data = fbo.read(components=3, alignment=1)
        image = np.frombuffer(data, dtype=np.uint8).reshape(self.height, self.width, 3)
        return np.ascontiguousarray(image[::-1])

    def draw(self, world, camera: Camera, framebuffer=None, *, viewport=None) -> None:
        """Draw `world` seen by `camera` into `framebuffer` (None: the currently bound one).

        Uses the current GL context (a widget's, in its paint method); with a standalone context
        that may not be current, call this inside `with renderer.ctx:`.

        Args:
            framebuffer: a moderngl Framebuffer; None detects the one bound now (a new wrapper
                each call, so for a widget drawn every frame prefer passing
                `ctx.detect_framebuffer(widget.defaultFramebufferObject())` once per resize).
            viewport: (x, y, width, height) in pixels; default the whole framebuffer.
        """
        ctx, mgl = self.ctx, self._mgl
        fbo = framebuffer if framebuffer is not None else ctx.detect_framebuffer()
        if viewport is None:
            w, h = fbo.size if fbo.size[0] > 0 else (self.width, self.height)
            viewport = (0, 0, w, h)
        vw, vh = max(int(viewport[2]), 1), max(int(viewport[3]), 1)
        aspect = vw / vh
        arrays = scene_arrays(world)

        # upload: one write per buffer, grown by orphaning when too small
        self._upload(self._sphere_buf, arrays.spheres)
        self._upload(self._box_buf, arrays.boxes)
        self._upload(self._capsule_buf, arrays.capsules)
        self._evict_solids({batch.key for batch in arrays.solids})
        batches = [(self._solid_entry(batch), len(batch.instances)) for batch in arrays.solids]
        for (entry, _), batch in zip(batches, arrays.solids):
            self._upload(entry[2], batch.instances)
        n_cloth_idx = self._upload_cloth(arrays)

        view = camera.view_matrix()
        proj = camera.projection_matrix(aspect)
        vp = proj @ view
        inv_view = np.linalg.inv(view)
        inv_vp = np.linalg.inv(vp)
        light = np.asarray(self.light_direction, dtype=np.float64)
        light = light / np.linalg.norm(light)

        # shadow map: depth of the scene seen from the sun, orthographic around its bounds
        shadow_on = self.shadows and (
            len(arrays.spheres) or len(arrays.boxes) or len(arrays.capsules) or batches or n_cloth_idx
        )
        light_vp = np.eye(4)
        if shadow_on:
            light_vp = self._draw_shadow_map(world, arrays, light, n_cloth_idx, batches)

        fbo.use()
        fbo.viewport = tuple(int(v) for v in viewport)
        fbo.clear(0.0, 0.0, 0.0, 1.0, depth=1.0, viewport=fbo.viewport)
        ctx.disable(mgl.BLEND)
        ctx.disable(mgl.CULL_FACE)

        for prog in self._lit:
            self._set(prog, "u_eye", camera.position)
            self._set(prog, "u_up", camera.up)
            self._set(prog, "u_light_dir", light)
            self._set_mat(prog, "u_light_vp", light_vp)
            self._set(prog, "u_shadow_on", 1.0 if shadow_on else 0.0)
            self._set(prog, "u_dither", 1.0 if self.dither else 0.0)
            if "u_shadow_map" in prog:
                prog["u_shadow_map"].value = 0
        self._shadow_tex.use(location=0)

        # sky: no depth test, so no depth written (skipped when a level floor paints it)
        walls = [self._is_wall(plane, camera) for plane in arrays.planes]
        first_floor = walls.index(False) if False in walls else -1
        if first_floor < 0:
            ctx.disable(mgl.DEPTH_TEST)
            self._set_mat(self._sky, "u_inv_vp", inv_vp)
            self._sky_vao.render(mgl.TRIANGLES, vertices=3)

        ctx.enable(mgl.DEPTH_TEST)
        # planes: a handful at most, one full-screen pass each, the sky-painting floor first
        if len(arrays.planes):
            p = self._plane
            self._set_mat(p, "u_inv_vp", inv_vp)
            self._set_mat(p, "u_vp", vp)
            self._set(p, "u_cell", float(self.ground_cell_size))
            self._set(p, "u_fade", max(40.0 * camera.distance, 10.0))
            clip_min, clip_max = self._wall_clip_box(world, arrays.planes)
            self._set(p, "u_clip_min", clip_min)
            self._set(p, "u_clip_max", clip_max)
            self._set(p, "u_glass", 0.0)
            order = list(range(len(arrays.planes)))
            if first_floor >= 0:
                order.remove(first_floor)
                order.insert(0, first_floor)
            for k in order:
                sky = k == first_floor
                ctx.depth_func = "<=" if sky else "<"  # the sky sits at depth 1, the cleared value
                self._set(p, "u_sky_on_miss", 1.0 if sky else 0.0)
                self._set_plane(arrays.planes, k, wall=walls[k])
                self._plane_vao.render(mgl.TRIANGLES, vertices=3)
            self._set(p, "u_sky_on_miss", 0.0)
        ctx.depth_func = "<"

        if len(arrays.spheres):
            s = self._sphere
            self._set_mat(s, "u_view", view)
            self._set_mat(s, "u_proj", proj)
            self._set_mat(s, "u_inv_view", inv_view)
            # multisampled target: the fragment's coverage of the disc becomes its sample mask
            msaa = int(getattr(fbo, "samples", 0) or 0) > 1
            self._set(s, "u_coverage", 1.0 if msaa else 0.0)
            # (alpha itself is not written: the sky left 1 everywhere, so a widget stays opaque)
            if msaa:
                ctx.enable_direct(GL_SAMPLE_ALPHA_TO_COVERAGE)
                fbo.color_mask = (True, True, True, False)
                fbo.use()  # moderngl applies a framebuffer's masks when it is bound
            self._sphere_vao.render(mgl.TRIANGLE_STRIP, vertices=4, instances=len(arrays.spheres))
            if msaa:
                fbo.color_mask = (True, True, True, True)
                fbo.use()
                ctx.disable_direct(GL_SAMPLE_ALPHA_TO_COVERAGE)

        if len(arrays.boxes):
            ctx.enable(mgl.CULL_FACE)
            self._set_mat(self._box, "u_vp", vp)
            self._box_vao.render(mgl.TRIANGLES, vertices=36, instances=len(arrays.boxes))
            ctx.disable(mgl.CULL_FACE)

        # capsules, hulls and static meshes (not culled: open meshes are seen from both sides)
        self._set_mat(self._solid, "u_vp", vp)
        self._set(self._solid, "u_alpha", 1.0)
        c = self._capsule
        self._set_mat(c, "u_clip", vp)
        self._set(c, "u_ray_dir", np.zeros(3))
        self._set(c, "u_alpha", 1.0)
        if len(arrays.capsules):
            self._render_capsules(self._capsule_vao, len(arrays.capsules))
        for (_, _, _, vao, _, count), instances in batches:
            vao.render(mgl.TRIANGLES, vertices=count, instances=instances)

        if n_cloth_idx:
            c = self._cloth
            self._set_mat(c, "u_vp", vp)
            self._set(c, "u_front", self.cloth_color)
            self._set(c, "u_back", np.clip(np.asarray(self.cloth_color) * 0.6 + 0.4, 0, 1))
            self._cloth_vao.render(mgl.TRIANGLES, vertices=n_cloth_idx)

        if self.show_joints and len(arrays.joints):
            self._draw_joints(fbo, arrays.joints, camera, vh)

        # glass: walls seen from behind (a container's near walls), blended over everything
        near_walls = [
            k
            for k, plane in enumerate(arrays.planes)
            if self._is_wall(plane, camera) and float(np.dot(plane[:3], camera.position)) < plane[3]
        ]
        if near_walls:
            p = self._plane
            self._set(p, "u_glass", 1.0)
            ctx.enable(mgl.BLEND)
            ctx.blend_func = mgl.SRC_ALPHA, mgl.ONE_MINUS_SRC_ALPHA
            fbo.depth_mask = False  # glass hides nothing, not even other glass
            fbo.color_mask = (True, True, True, False)  # and leaves the target opaque
            fbo.use()
            for k in near_walls:
                self._set_plane(arrays.planes, k)
                self._plane_vao.render(mgl.TRIANGLES, vertices=3)
            fbo.depth_mask = True
            fbo.color_mask = (True, True, True, True)
            fbo.use()
            ctx.disable(mgl.BLEND)
            self._set(p, "u_glass", 0.0)

    @property
    def cached_batches(self) -> int:
        """Instanced batches whose buffers are kept on the GPU (at most `SOLID_CACHE_SIZE` after a frame)."""
        return len(self._solid_cache)

    def release(self) -> None:
        """Free the GL objects this renderer made (not the context); the renderer is unusable after."""
        objects = [v for k, v in vars(self).items() if k not in ("ctx", "_mgl") and hasattr(v, "release")]
        for entry in self._solid_cache.values():
            objects += list(entry[1:5])
        self._solid_cache = {}
        for fbo in (self._fbo, self._resolve):
            if fbo is not None:
                objects += [*fbo.color_attachments, fbo.depth_attachment]
        with self.ctx:
            for obj in objects:
                try:
                    obj.release()
                except Exception:  # already released
                    pass
        self._fbo = self._resolve = self._fbo_size = None

    # ------------------------------------------------------------------ internals

    @staticmethod
    def _check_size(width, height) -> tuple[int, int]:
        w, h = int(width), int(height)
        if w < 1 or h < 1 or w > 16384 or h > 16384:
            raise ValueError(f"image size must be between 1x1 and 16384x16384 pixels, got {width}x{height}")
        return w, h

    def _offscreen(self):
        size = (self.width, self.height, self.samples)
        if self._fbo_size != size:
            for fbo in (self._fbo, self._resolve):
                if fbo is not None:
                    for att in (*fbo.color_attachments, fbo.depth_attachment):
                        att.release()
                    fbo.release()
            ctx, wh = self.ctx, (self.width, self.height)
            samples = min(self.samples, ctx.max_samples) if self.samples > 0 else 0
            self._fbo = ctx.framebuffer(
                color_attachments=[ctx.renderbuffer(wh, 4, samples=samples)],
                depth_attachment=ctx.depth_renderbuffer(wh, samples=samples),
            )
            self._resolve = None
            if samples:
                self._resolve = ctx.framebuffer(
                    color_attachments=[ctx.renderbuffer(wh, 4)], depth_attachment=ctx.depth_renderbuffer(wh)
                )
            self._fbo_size = size
        return self._fbo

    @staticmethod
    def _upload(buf, data: np.ndarray) -> None:
        if not len(data):
            return
        raw = data.tobytes()
        if buf.size < len(raw):
            buf.orphan(max(len(raw), 2 * buf.size))
        buf.write(raw)

    def _upload_cloth(self, arrays: SceneArrays) -> int:
        """Upload cloth vertices (position, normal) and, when changed, triangles; return index count."""
        if arrays.cloth_position is None:
            return 0
        p, tri = arrays.cloth_position, arrays.cloth_triangles
        assert tri is not None  # given with the positions
        if tri.min() < 0 or tri.max() >= len(p):
            raise TumbleError(f"cloth triangles index particles outside 0..{len(p) - 1}")
        vertices = np.empty((len(p), 6), dtype=np.float32)
        vertices[:, :3] = p
        vertices[:, 3:] = vertex_normals(p, tri)
        self._upload(self._cloth_vbo, vertices)
        if self._cloth_tris is None or self._cloth_tris.shape != tri.shape or not np.array_equal(self._cloth_tris, tri):
            self._cloth_tris = np.array(tri, copy=True)
            self._upload(self._cloth_ibo, np.ascontiguousarray(tri, dtype=np.uint32))
        return tri.size

    @staticmethod
    def _is_wall(plane: np.ndarray, camera: Camera) -> bool:
        """Only level planes facing up stretch to the horizon; walls and ramps are cut."""
        return float(np.dot(plane[:3], camera.up)) < 0.99

    def _set_plane(self, planes: np.ndarray, k: int, *, wall: bool = True) -> None:
        """Uniforms of the plane pass for plane k (normal, offset, tangents; the others for walls)."""
        p = self._plane
        n = planes[k, :3]
        t, b = _perpendicular(n)
        self._set(p, "u_wall", 1.0 if wall else 0.0)
        if wall:
            others = np.zeros((8, 4), dtype=np.float32)
            rest = np.delete(planes, k, axis=0)[:8]
            others[: len(rest)] = rest
            if "u_others" in p:
                p["u_others"].write(others.tobytes())
            self._set(p, "u_other_count", len(rest))
        self._set(p, "u_normal", n)
        self._set(p, "u_offset", float(planes[k, 3]))
        self._set(p, "u_tangent", t)
        self._set(p, "u_bitangent", b)

    def _wall_clip_box(self, world, planes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Box [m] that walls and ramps are cut to: the scene's bounds (grown over the frames drawn),
        widened sideways, a little higher on top, and down to the highest level floor."""
        box = scene_box(world)
        source = getattr(world, "source", world)  # a viewer's snapshot stands for its world
        if self._wall_world is not source:
            self._wall_world, self._wall_box = source, None
        if box is not None:
            if self._wall_box is None:
                self._wall_box = (box[0].copy(), box[1].copy())
            else:
                self._wall_box = (np.minimum(self._wall_box[0], box[0]), np.maximum(self._wall_box[1], box[1]))
        if self._wall_box is None:
            return np.full(3, -1.0), np.full(3, 1.0)
        lo, hi = self._wall_box
        size = float(np.linalg.norm(hi - lo))
        side, top = 0.2 * size + 0.3, 0.05 * size + 0.05
        lo = lo - np.array([side, side, top])
        hi = hi + np.array([side, side, top])
        floors = planes[planes[:, 2] > 0.99]  # level floors: z = offset
        if len(floors):
            lo[2] = min(lo[2], float(floors[:, 3].max()) - 1e-3)
            # a container's walls stand about as high as it is wide, not as high as the bodies
            # dropped into it came from (its emitter, above it)
            width = _container_width(planes)
            if width is not None:
                hi[2] = max(lo[2] + 0.05, min(hi[2], float(floors[:, 3].max()) + 1.25 * width))
        return lo, hi

    def _solid_entry(self, batch: SolidBatch) -> tuple:
        """The cached (source, vbo, instance buffer, vao, shadow vao, vertex count) of a batch's geometry."""
        entry = self._solid_cache.get(batch.key)
        if entry is not None and entry[0] is batch.source:
            return entry
        if entry is not None:
            self._release_solid(batch.key)
        ctx = self.ctx
        vertices = batch.build()
        vbo = ctx.buffer(vertices.tobytes())
        inst = ctx.buffer(reserve=max(1, len(batch.instances)) * SOLID_FLOATS * 4, dynamic=True)
        vao = ctx.vertex_array(
            self._solid,
            [(vbo, "3f 3f", "in_position", "in_normal"), (inst, "3f 4f 3f/i", "in_center", "in_quat", "in_color")],
        )
        shadow = ctx.vertex_array(
            self._shadow_solid, [(vbo, "3f 12x", "in_position"), (inst, "3f 4f 12x/i", "in_center", "in_quat")]
        )
        entry = (batch.source, vbo, inst, vao, shadow, len(vertices))
        self._solid_cache[batch.key] = entry
        return entry

    def _render_capsules(self, vao, instances: int) -> None:
        """Draw capsule impostors: the back faces of their boxes, so a box around the eye still draws."""
        mgl = self._mgl
        self.ctx.enable(mgl.CULL_FACE)
        self.ctx.cull_face = "front"
        vao.render(mgl.TRIANGLES, vertices=36, instances=instances)
        self.ctx.cull_face = "back"
        self.ctx.disable(mgl.CULL_FACE)

    def _evict_solids(self, keep: set) -> None:
        """Past `SOLID_CACHE_SIZE` cached vertex buffers, free those this frame does not draw."""
        if len(self._solid_cache) + len(keep) > SOLID_CACHE_SIZE:
            for key in [k for k in self._solid_cache if k not in keep]:
                self._release_solid(key)

    def _release_solid(self, key: tuple) -> None:
        for obj in self._solid_cache.pop(key)[1:5]:
            obj.release()

    def _draw_joints(self, fbo, lines: np.ndarray, camera: Camera, height: int) -> None:
        """The joint overlay: opaque where in view, then faint (blended, depth kept) where hidden."""
        ctx, mgl = self.ctx, self._mgl
        # a pixel's size at the camera's target [m]: rods ~1.5 px wide, dots ~3.5 px
        pixel = 2.0 * camera.distance * math.tan(math.radians(camera.fov_deg) / 2.0) / max(height, 1)
        instances = solids.joint_capsules(lines, 0.75 * pixel, 1.75 * pixel)
        self._upload(self._joint_buf, instances)
        c = self._capsule
        self._set(c, "u_alpha", 1.0)
        self._render_capsules(self._joint_vao, len(instances))
        ctx.enable(mgl.BLEND)
        ctx.blend_func = mgl.SRC_ALPHA, mgl.ONE_MINUS_SRC_ALPHA
        ctx.depth_func = ">"
        fbo.depth_mask = False
        fbo.color_mask = (True, True, True, False)
        fbo.use()
        self._set(c, "u_alpha", 0.35)
        self._render_capsules(self._joint_vao, len(instances))
        self._set(c, "u_alpha", 1.0)
        fbo.depth_mask = True
        fbo.color_mask = (True, True, True, True)
        fbo.use()
        ctx.depth_func = "<"
        ctx.disable(mgl.BLEND)

    def _draw_shadow_map(
        self, world, arrays: SceneArrays, light: np.ndarray, n_cloth_idx: int, batches=()
    ) -> np.ndarray:
        """Render depth from the sun into the shadow map; return the world -> sun clip matrix."""
        ctx, mgl = self.ctx, self._mgl
        centre, radius = scene_bounds(world)
        radius *= 1.05
        # sun frame: looking along -light, from 2 radii out
        forward = -light
        side = np.cross(forward, [0.0, 0.0, 1.0] if abs(forward[2]) < 0.99 else [1.0, 0.0, 0.0])
        side /= np.linalg.norm(side)
        up = np.cross(side, forward)
        eye = centre + light * 2.0 * radius
        view = np.eye(4)
        view[0, :3], view[1, :3], view[2, :3] = side, up, -forward
        view[:3, 3] = -view[:3, :3] @ eye
        light_vp = _ortho(radius, 0.0, 4.0 * radius) @ view

        self._shadow_fbo.use()
        self._shadow_fbo.clear(depth=1.0)
        ctx.enable(mgl.DEPTH_TEST)
        ctx.depth_func = "<"
        ctx.disable(mgl.CULL_FACE)
        if len(arrays.spheres):
            s = self._shadow_sphere
            self._set_mat(s, "u_light_vp", light_vp)
            self._set(s, "u_light_right", side)
            self._set(s, "u_light_up", up)
            self._set(s, "u_light_dir", light)
            self._shadow_sphere_vao.render(mgl.TRIANGLE_STRIP, vertices=4, instances=len(arrays.spheres))
        if len(arrays.boxes):
            self._set_mat(self._shadow_box, "u_light_vp", light_vp)
            self._shadow_box_vao.render(mgl.TRIANGLES, vertices=36, instances=len(arrays.boxes))
        self._set_mat(self._shadow_solid, "u_light_vp", light_vp)
        if len(arrays.capsules):
            self._set_mat(self._shadow_capsule, "u_clip", light_vp)
            self._set(self._shadow_capsule, "u_ray_dir", -light)
            self._render_capsules(self._shadow_capsule_vao, len(arrays.capsules))
        for (_, _, _, _, shadow, count), instances in batches:
            shadow.render(mgl.TRIANGLES, vertices=count, instances=instances)
        if n_cloth_idx:
            self._set_mat(self._shadow_mesh, "u_light_vp", light_vp)
            self._shadow_cloth_vao.render(mgl.TRIANGLES, vertices=n_cloth_idx)
        return light_vp

    @staticmethod
    def _set(prog, name: str, value) -> None:
        if name in prog:
            if isinstance(value, np.ndarray):
                value = tuple(float(v) for v in value.reshape(-1))
            prog[name].value = value

    @staticmethod
    def _set_mat(prog, name: str, m: np.ndarray) -> None:
        if name in prog:
            prog[name].write(_mat(m))
