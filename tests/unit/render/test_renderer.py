"""The renderer (tumble.render.renderer) draws spheres, boxes, planes and cloth where the camera says they are."""

from __future__ import annotations

import numpy as np
import pytest

import tumble
from tumble.errors import TumbleError
from tumble.render import Camera, body_colors, scene_arrays

W, H = 160, 120


def _scene_one_sphere(world=None):
    world = tumble.World() if world is None else world
    world.add_plane()
    world.add_sphere(position=(0.0, 0.0, 0.5), radius=0.3)  # body 1
    return world


def _camera():
    return Camera(position=(0.0, -3.0, 1.2), target=(0.0, 0.0, 0.4), fov_deg=45)


def _like(pixel, colour, chromaticity) -> bool:
    """Whether a shaded pixel has the hue of `colour`: its chromaticity is near the colour's
    and clearly nearer to it than to neutral grey (shading changes brightness, not hue)."""
    p, c = chromaticity(pixel)[0], chromaticity(colour)[0]
    return np.abs(p - c).max() < 0.1 and np.abs(p - c).max() < 0.7 * np.abs(p - 1 / 3).max()


def _pixel(image, camera, point):
    x, y, _ = camera.project(point, image.shape[1], image.shape[0])
    return image[int(y), int(x)].astype(float)


def test_image_shape_and_dtype(small_renderer):
    """Render returns an RGB uint8 image of the renderer's size."""
    image = small_renderer.render(_scene_one_sphere(), _camera())
    assert image.shape == (H, W, 3)
    assert image.dtype == np.uint8


def test_sphere_coloured_where_the_sphere_is(small_renderer, chromaticity):
    """The sphere's pixel has the sphere's colour; sky above and ground below do not."""
    world, camera = _scene_one_sphere(), _camera()
    image = small_renderer.render(world, camera)

    centre = _pixel(image, camera, (0.0, 0.0, 0.5))
    assert _like(centre, body_colors([1]), chromaticity)

    # sky: the top row is bluish (more blue than red) and brighter than mid grey
    sky = image[2, W // 2].astype(float)
    assert sky[2] > sky[0] and sky.mean() > 150
    # ground: beside the sphere on the plane, close to grey
    ground = _pixel(image, camera, (1.0, 0.0, 0.0))
    assert np.abs(chromaticity(ground)[0] - 1 / 3).max() < 0.03
    assert not _like(ground, body_colors([1]), chromaticity)


def test_sphere_silhouette_matches_its_radius(small_renderer, chromaticity):
    """Just inside the projected radius is sphere, just outside is not (impostor is exact)."""
    world, camera = _scene_one_sphere(), _camera()
    small_renderer.shadows = False
    image = small_renderer.render(world, camera)
    right = np.cross(camera.target - camera.position, camera.up)
    right /= np.linalg.norm(right)
    inside = _pixel(image, camera, np.array([0.0, 0.0, 0.5]) + 0.85 * 0.3 * right)
    outside = _pixel(image, camera, np.array([0.0, 0.0, 0.5]) + 1.25 * 0.3 * right)
    assert _like(inside, body_colors([1]), chromaticity)
    assert not _like(outside, body_colors([1]), chromaticity)


def test_depth_order_sphere_in_front_of_box(small_renderer, chromaticity):
    """A sphere between the camera and a box hides the box; the box shows beside it."""
    world = tumble.World()
    world.add_plane()
    world.add_box(position=(0.0, 1.0, 0.5), half_extents=(0.6, 0.2, 0.5))  # body 1, behind
    world.add_sphere(position=(0.0, 0.0, 0.5), radius=0.25)  # body 2, in front
    camera = _camera()
    image = small_renderer.render(world, camera)
    box_c, sphere_c = body_colors([1, 2])
    assert _like(_pixel(image, camera, (0.0, 0.0, 0.5)), sphere_c, chromaticity)
    beside = _pixel(image, camera, (0.45, 0.8, 0.5))  # front face of the box, right of the sphere
    assert _like(beside, box_c, chromaticity)


def test_rotated_box_follows_its_orientation(small_renderer, chromaticity):
    """A long thin box turned 90 degrees about z covers pixels along y, not along x."""
    world = tumble.World()
    world.add_plane()
    s = np.sqrt(0.5)
    world.add_box(position=(0.0, 0.0, 0.1), half_extents=(0.8, 0.1, 0.1), orientation=(0.0, 0.0, s, s))
    camera = Camera(position=(0.0, -3.0, 3.0), target=(0.0, 0.0, 0.0), fov_deg=40)
    small_renderer.shadows = False
    image = small_renderer.render(world, camera)
    box_c = body_colors([1])
    along_y = _pixel(image, camera, (0.0, 0.6, 0.2))
    along_x = _pixel(image, camera, (0.6, 0.0, 0.2))
    assert _like(along_y, box_c, chromaticity)
    assert not _like(along_x, box_c, chromaticity)


def test_plane_not_drawn_from_behind(small_renderer):
    """A camera below the ground sees no checker: every pixel is sky."""
    world = tumble.World()
    world.add_plane()
    camera = Camera(position=(0.0, -3.0, -1.0), target=(0.0, 0.0, -1.5), fov_deg=45)
    image = small_renderer.render(world, camera).astype(float)
    sky_only = small_renderer.render(tumble.World(), camera).astype(float)
    assert np.array_equal(image, sky_only)


def test_cloth_is_drawn_two_sided(cloth_world, small_renderer, make_cloth, chromaticity):
    """Cloth shows its colour seen from above and from below (two-sided)."""
    world = cloth_world(make_cloth(centre=(0.0, 0.0, 1.0)))
    small_renderer.shadows = False
    front = small_renderer.cloth_color
    back = np.clip(front * 0.6 + 0.4, 0.0, 1.0)  # the back side's lighter tint
    for z, colour in ((4.0, front), (-2.0, back)):
        camera = Camera(position=(0.0, -0.5, z), target=(0.0, 0.0, 1.0), fov_deg=40)
        image = small_renderer.render(world, camera)
        pixel = _pixel(image, camera, (0.05, 0.05, 1.0))
        assert _like(pixel, colour, chromaticity), f"no cloth colour seen from z = {z}: {pixel}"


def test_same_scene_renders_identically(cloth_world, small_renderer, make_cloth):
    """Two renders of one scene give the same bytes."""
    world = _scene_one_sphere(cloth_world(make_cloth(centre=(-0.5, 0.5, 1.2), size=0.8)))
    world.add_box(position=(0.6, 0.3, 0.3), half_extents=(0.2, 0.2, 0.2), orientation=(0.1, 0.2, 0.3, 0.9))
    a = small_renderer.render(world, _camera())
    b = small_renderer.render(world, _camera())
    assert np.array_equal(a, b)


def test_draw_into_a_given_framebuffer(gl_context, small_renderer):
    """draw() into a caller's framebuffer gives the same picture as render()."""
    world, camera = _scene_one_sphere(), _camera()
    with gl_context:  # draw() uses the current context, as a widget's paint method would
        fbo = gl_context.simple_framebuffer((W, H))
        fbo.use()
        small_renderer.draw(world, camera)  # the bound framebuffer
        bound = np.frombuffer(fbo.read(components=3, alignment=1), np.uint8).reshape(H, W, 3)[::-1]
        small_renderer.draw(world, camera, fbo)
        given = np.frombuffer(fbo.read(components=3, alignment=1), np.uint8).reshape(H, W, 3)[::-1]
        fbo.release()
    assert np.array_equal(bound, small_renderer.render(world, camera))
    assert np.array_equal(given, bound)


def test_resize_changes_image_size(small_renderer):
    """resize() changes the size render() returns; bad sizes are refused."""
    small_renderer.resize(64, 48)
    assert small_renderer.render(_scene_one_sphere(), _camera()).shape == (48, 64, 3)
    with pytest.raises(ValueError, match="size"):
        small_renderer.resize(0, 10)


def test_multisampled_render(gl_context):
    """A multisampled renderer resolves to a plain RGB image with the sphere in it."""
    from tumble.render import Renderer

    r = Renderer(gl_context, 80, 60, samples=4, shadow_size=256)
    image = r.render(_scene_one_sphere(), _camera())
    r.release()
    assert image.shape == (60, 80, 3)
    assert image.std() > 5


def test_scene_arrays_pack_each_shape():
    """scene_arrays splits bodies by shape with positions, sizes and colours by body index."""
    world = tumble.World()
    world.add_plane(normal=(0, 0, 2), offset=0.5)
    world.add_sphere(position=(1, 2, 3), radius=0.25)
    world.add_box(position=(4, 5, 6), half_extents=(0.1, 0.2, 0.3))
    arrays = scene_arrays(world)
    assert arrays.spheres.dtype == np.float32 and arrays.spheres.shape == (1, 11)
    assert np.allclose(arrays.spheres[0, :4], [1, 2, 3, 0.25])
    assert np.allclose(arrays.spheres[0, 8:], body_colors([1])[0])
    assert np.allclose(arrays.boxes[0, :3], [4, 5, 6]) and np.allclose(arrays.boxes[0, 7:10], [0.1, 0.2, 0.3])
    assert np.allclose(arrays.boxes[0, 10:], body_colors([2])[0])
    assert np.allclose(arrays.planes, [[0, 0, 1, 0.5]])
    assert arrays.cloth_position is None


def test_cloth_triangles_out_of_range_are_refused(cloth_world, small_renderer, make_cloth):
    """Cloth triangles naming missing particles raise a clear error, not a GL crash."""
    cloth = make_cloth(3, 3)
    cloth.triangles = cloth.triangles.copy()
    cloth.triangles[0, 0] = 99
    world = cloth_world(cloth)
    with pytest.raises(TumbleError, match="cloth triangles"):
        small_renderer.render(world, _camera())


def test_no_context_is_a_clear_error(monkeypatch):
    """Without any OpenGL context, create_context raises TumbleError('no OpenGL context: ...')."""
    import moderngl

    from tumble.render import create_context

    def fail(*args, **kwargs):
        raise Exception("eglGetDisplay failed")

    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    with pytest.raises(TumbleError, match="^no OpenGL context: .*eglGetDisplay failed"):
        create_context()


def test_walls_are_cut_to_the_scene(small_renderer, chromaticity):
    """A container's far wall shows near the bodies but not far above them; its near wall is glass."""

    def world_with(walls: bool):
        world = tumble.World()
        world.add_plane()
        if walls:
            world.add_plane(normal=(1, 0, 0), offset=-0.5)  # far wall, facing the camera
            world.add_plane(normal=(-1, 0, 0), offset=-0.5)  # near wall, seen from behind
        world.add_sphere(position=(0.0, 0.0, 0.3), radius=0.2)
        return world

    camera = Camera(position=(3.0, 0.0, 1.0), target=(0.0, 0.0, 0.5), fov_deg=60)
    small_renderer.shadows = False
    walled = small_renderer.render(world_with(True), camera)
    open_ = small_renderer.render(world_with(False), camera)
    on_wall = (-0.5, 0.4, 0.4)
    high_above = (-0.5, 0.0, 2.2)
    assert not np.array_equal(_pixel(walled, camera, on_wall), _pixel(open_, camera, on_wall))
    assert np.array_equal(_pixel(walled, camera, high_above), _pixel(open_, camera, high_above))
    # the near wall is faint glass: the sphere behind it is tinted but keeps its colour
    sphere = body_colors([3])
    behind_glass = _pixel(walled, camera, (0.0, 0.0, 0.3))
    assert _like(behind_glass, sphere, chromaticity)
    assert not np.array_equal(behind_glass, _pixel(open_, camera, (0.0, 0.0, 0.3)))


def test_multisampling_smooths_only_the_sphere_silhouette(gl_context):
    """With 4x MSAA, pixels change only in a thin ring at the sphere's outline (edge coverage)."""
    from tumble.render import Renderer

    world = tumble.World()
    world.add_sphere(position=(0.0, 0.0, 0.5), radius=0.3)
    camera = _camera()
    plain = Renderer(gl_context, W, H, shadows=False)
    smooth = Renderer(gl_context, W, H, shadows=False, samples=4)
    a = plain.render(world, camera).astype(int)
    b = smooth.render(world, camera).astype(int)
    plain.release()
    smooth.release()
    changed = np.argwhere(np.abs(a - b).max(axis=2) > 8)
    assert len(changed) > 10  # the outline did change
    x, y, depth = camera.project((0.0, 0.0, 0.5), W, H)
    f = H / 2 / np.tan(np.radians(camera.fov_deg) / 2)
    radius_px = 0.3 * f / np.sqrt(depth**2 - 0.3**2)
    dist = np.hypot(changed[:, 1] + 0.5 - x, changed[:, 0] + 0.5 - y)
    assert np.all(np.abs(dist - radius_px) < 2.0)


def test_multisampled_widget_framebuffer_stays_opaque(gl_context):
    """Drawing into a multisampled framebuffer (as a viewer widget may have) leaves alpha at 1."""
    world = tumble.World()
    world.add_plane(normal=(1, 0, 0), offset=-0.5)  # walls, so the glass pass runs too
    world.add_plane(normal=(-1, 0, 0), offset=-0.5)
    world.add_sphere(position=(0.0, 0.0, 0.5), radius=0.3)
    from tumble.render import Renderer

    r = Renderer(gl_context, W, H, shadow_size=256)
    with gl_context:
        msaa = gl_context.framebuffer(
            color_attachments=[gl_context.renderbuffer((W, H), 4, samples=4)],
            depth_attachment=gl_context.depth_renderbuffer((W, H), samples=4),
        )
        plain = gl_context.simple_framebuffer((W, H), components=4)
        r.draw(world, Camera(position=(3.0, 0.0, 1.0), target=(0.0, 0.0, 0.5)), msaa)
        gl_context.copy_framebuffer(plain, msaa)
        rgba = np.frombuffer(plain.read(components=4, alignment=1), np.uint8).reshape(H, W, 4)
        for obj in (*msaa.color_attachments, msaa.depth_attachment, msaa, plain):
            obj.release()
    r.release()
    assert rgba[..., 3].min() == 255


def test_renderers_on_two_contexts_stay_apart():
    """A renderer keeps drawing in its own context after another context is made and released."""
    from tumble.render import Renderer, create_context

    world, camera = _scene_one_sphere(), _camera()
    first_ctx, second_ctx = create_context(), create_context()
    first = Renderer(first_ctx, W, H, shadow_size=256)  # made while the second context is current
    before = first.render(world, camera)
    second = Renderer(second_ctx, W, H, shadow_size=256)
    assert np.array_equal(second.render(world, camera), before)
    second.release()
    second_ctx.release()
    assert np.array_equal(first.render(world, camera), before)
    first.release()
    first_ctx.release()
