"""Solid geometry (tumble.render.solids): hull, mesh and joint vertex rows, and the renderer drawing capsules,
convex hulls and static meshes with their real geometry, and joints on demand."""

from __future__ import annotations

import math

import numpy as np
import pytest

import tumble
from tumble.render import Camera, body_colors, scene_arrays, solids, vertex_normals

pytest.importorskip("scipy")  # convex hulls are taken with SciPy

W, H = 160, 120
TETRA = np.array([[0.0, 0.0, 0.0], [0.4, 0.0, 0.0], [0.0, 0.4, 0.0], [0.0, 0.0, 0.4]])


def _front_camera(target=(0.0, 0.0, 0.5), distance=3.0):
    """Looking along +y at `target`, level: world x to the right, z up on screen."""
    t = np.asarray(target, dtype=float)
    return Camera(position=t - (0.0, distance, 0.0), target=t, fov_deg=30)


def _pixel(image, camera, point):
    x, y, _ = camera.project(np.asarray(point, dtype=float), image.shape[1], image.shape[0])
    return image[int(y), int(x)].astype(float)


def _like(pixel, colour, chromaticity) -> bool:
    p, c = chromaticity(pixel)[0], chromaticity(colour)[0]
    return np.abs(p - c).max() < 0.1 and np.abs(p - c).max() < 0.7 * np.abs(p - 1 / 3).max()


def _grid_mesh(n=9, size=1.0, bump=0.0):
    x, y = np.meshgrid(np.linspace(-0.5, 0.5, n) * size, np.linspace(-0.5, 0.5, n) * size)
    v = np.stack([x.ravel(), y.ravel(), bump * (x.ravel() ** 2 + y.ravel() ** 2)], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return v, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def _mixed_world():
    """Plane, sphere, box, two capsules, two bodies of one hull, one of another, a static mesh."""
    world = tumble.World()
    world.add_plane()
    world.add_sphere(position=(-1.0, 0.0, 0.5), radius=0.1)
    world.add_box(position=(-0.6, 0.0, 0.5), half_extents=(0.1, 0.1, 0.1))
    world.add_capsule(position=(-0.2, 0.0, 0.5), radius=0.05, half_height=0.1)
    world.add_capsule(position=(0.0, 0.0, 0.5), radius=0.08, half_height=0.2)
    world.add_convex(points=TETRA, position=(0.3, 0.0, 0.5))
    world.add_convex(points=TETRA, position=(0.6, 0.0, 0.5))
    world.add_convex(points=TETRA * 0.5, position=(0.9, 0.0, 0.5))
    v, t = _grid_mesh()
    world.add_mesh(vertices=v, triangles=t, position=(0.0, 0.0, 0.01))
    return world


def test_every_body_is_packed_once_by_its_shape():
    """Each non-plane body is in exactly one instance array (nothing drawn twice, nothing left out)."""
    world = _mixed_world()
    arrays = scene_arrays(world)
    drawn = np.concatenate(
        [
            arrays.sphere_body,
            arrays.box_body[arrays.box_body >= 0],
            arrays.capsule_body,
            *[batch.body for batch in arrays.solids],
        ]
    )
    assert sorted(drawn.tolist()) == list(range(1, world.body_count))
    np.testing.assert_allclose(arrays.capsules[:, 7], [0.05, 0.08])  # radius
    np.testing.assert_allclose(arrays.capsules[:, 8], [0.1, 0.2], atol=1e-7)  # half height
    # the three hull bodies use two prototypes (hull_from_points makes one per call, so three here)
    hull_batches = [b for b in arrays.solids if b.key[0] == "hull"]
    mesh_batches = [b for b in arrays.solids if b.key[0] == "mesh"]
    assert sum(len(b.body) for b in hull_batches) == 3 and len(mesh_batches) == 1


def test_bodies_sharing_a_hull_prototype_are_one_batch():
    """Two bodies with one prototype row are two instances of one vertex buffer."""
    world = _mixed_world()
    hull_rows = np.asarray(world.body_geometry)[np.asarray(world.body_shape) == tumble.ShapeType.CONVEX]
    # point two bodies at one prototype, as an emitter of one hull would
    world.bodies.write("body_geometry", world.body_row(world.body(7)), int(hull_rows[0]))
    batches = [b for b in scene_arrays(world).solids if b.key[0] == "hull"]
    assert sorted(len(b.body) for b in batches) == [1, 2]


def test_vertex_normals_of_a_flat_grid(make_cloth):
    """A flat counter-clockwise grid has unit normals along +z at every vertex."""
    cloth = make_cloth(5, 4)
    p = cloth.particle_position.copy()
    p[:, 2] = 0.0
    n = vertex_normals(p, cloth.triangles)
    assert np.allclose(n, [0.0, 0.0, 1.0])


def test_hull_triangles_cover_each_face_with_its_normal():
    """The hull's triangles have the face normals, wind outward and add up to the hull's surface."""
    from tumble.collision.hulls import hull_from_points

    cube = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float) * 0.5
    proto = hull_from_points(cube)
    v = solids.hull_vertices(proto)
    assert len(v) == 6 * 2 * 3  # six square faces, two triangles each
    tri = v[:, :3].reshape(-1, 3, 3)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    np.testing.assert_allclose(0.5 * np.linalg.norm(cross, axis=1).sum(), 6.0, rtol=1e-6)
    n = v[::3, 3:]
    np.testing.assert_allclose(cross / np.linalg.norm(cross, axis=1, keepdims=True), n, atol=1e-6)


def test_mesh_normals_are_smooth_on_a_bowl_and_sharp_on_a_step():
    """A gently curved mesh gets shared vertex normals; a right-angled crease keeps each face's own."""
    v, t = _grid_mesh(bump=0.3)
    rows = solids.mesh_vertices(v, t)
    corner = t.reshape(-1)
    # corners at the same vertex share one normal on the bowl
    first = {}
    for k, i in enumerate(corner):
        first.setdefault(int(i), rows[k, 3:])
        np.testing.assert_allclose(rows[k, 3:], first[int(i)], atol=1e-6)
    # a step: two triangles meeting at 90 degrees keep their flat normals
    rows = solids.mesh_vertices(
        np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float), np.array([[0, 1, 2], [0, 2, 3]])
    )
    np.testing.assert_allclose(rows[:3, 3:], np.tile([0, 0, 1], (3, 1)), atol=1e-6)
    np.testing.assert_allclose(rows[3:, 3:], np.tile([1, 0, 0], (3, 1)), atol=1e-6)


def test_capsule_is_drawn_with_its_rounded_length(small_renderer, chromaticity):
    """A lying capsule covers its segment and caps (a + 0.8 r from the centre) but not beyond (a + 1.3 r)."""
    world = tumble.World()
    world.add_plane()
    r, a = 0.1, 0.3
    # lying along x: a quarter turn about y takes the body's z to world x
    q = (0.0, math.sin(math.pi / 4), 0.0, math.cos(math.pi / 4))
    world.add_capsule(position=(0.0, 0.0, 0.5), radius=r, half_height=a, orientation=q)
    camera = _front_camera()
    image = small_renderer.render(world, camera)
    colour = body_colors([1])
    for x in (0.0, a, -(a + 0.8 * r)):
        assert _like(_pixel(image, camera, (x, 0.0, 0.5)), colour, chromaticity), x
    for x in (a + 1.3 * r, -(a + 1.3 * r)):
        assert not _like(_pixel(image, camera, (x, 0.0, 0.5)), colour, chromaticity), x
    # and its height is 2 r, not 2 (a + r): above the segment's middle by 1.3 r is sky
    assert not _like(_pixel(image, camera, (0.0, 0.0, 0.5 + 1.3 * r)), colour, chromaticity)


def test_hull_is_drawn_as_the_hull_not_its_bounding_sphere(small_renderer, chromaticity):
    """A tetrahedron shows inside its outline and not in the corner of its bounding box it leaves empty."""
    world = tumble.World()
    world.add_plane()
    world.add_convex(points=TETRA * 2.0, position=(0.0, 0.0, 0.2), static=True)
    camera = _front_camera(target=(0.4, 0.0, 0.6), distance=4.0)
    image = small_renderer.render(world, camera)
    colour = body_colors([1])
    # seen along +y the tetrahedron is the triangle (0, 0), (0.8, 0), (0, 0.8) in x, z above z = 0.2
    assert _like(_pixel(image, camera, (0.2, -0.1, 0.2 + 0.2)), colour, chromaticity)
    assert not _like(_pixel(image, camera, (0.65, -0.1, 0.2 + 0.65)), colour, chromaticity)


def test_static_mesh_is_drawn_in_the_mesh_colour(small_renderer, chromaticity):
    """A static mesh floor raised above the plane shows in the mesh colour where it is, the ground beyond."""
    world = tumble.World()
    world.add_plane()
    v, t = _grid_mesh(size=0.8)
    world.add_mesh(vertices=v, triangles=t, position=(0.0, 0.0, 0.3))
    camera = Camera(position=(0.0, -2.0, 2.0), target=(0.0, 0.0, 0.3), fov_deg=40)
    small_renderer.shadows = False
    image = small_renderer.render(world, camera)
    assert _like(_pixel(image, camera, (0.0, 0.0, 0.3)), solids.MESH_COLOR, chromaticity)
    ground = _pixel(image, camera, (1.2, 0.0, 0.0))
    assert not _like(ground, solids.MESH_COLOR, chromaticity)


@pytest.mark.parametrize("shape", ["capsule", "hull", "mesh"])
def test_each_shape_casts_a_shadow(small_renderer, shape):
    """The ground under the shape, along the sun, is darker with shadows on than off."""
    world = tumble.World()
    world.add_plane()
    centre = np.array([0.0, 0.0, 0.4])
    if shape == "capsule":
        world.add_capsule(position=centre, radius=0.15, half_height=0.1, static=True)
    elif shape == "hull":
        world.add_convex(points=(TETRA - 0.1) * 1.2, position=centre, static=True)
    else:
        v, t = _grid_mesh(size=0.4)
        world.add_mesh(vertices=v, triangles=t, position=centre)
    light = np.asarray(small_renderer.light_direction)
    ground = centre - light * (centre[2] / light[2])  # where the sun's ray through the centre meets z = 0
    camera = Camera(position=(0.0, -2.5, 2.5), target=(ground[0], ground[1], 0.0), fov_deg=40)
    small_renderer.shadows = False
    lit = _pixel(small_renderer.render(world, camera), camera, ground)
    small_renderer.shadows = True
    shaded = _pixel(small_renderer.render(world, camera), camera, ground)
    assert shaded.sum() < 0.8 * lit.sum()


def _pendulum(hinged_box=True):
    """A ball hung on a rope from a world point, and a box on a hinge from it."""
    world = tumble.World()
    world.add_plane()
    ball = world.add_sphere(position=(0.0, 0.0, 0.6), radius=0.05)
    world.add_joint("rope", None, ball, anchor_a=(0.0, 0.0, 1.2))
    if hinged_box:
        box = world.add_box(position=(0.3, 0.0, 0.6), half_extents=(0.05, 0.05, 0.05))
        world.add_joint("hinge", ball, box, anchor=(0.15, 0.0, 0.6), axis=(0, 1, 0))
    return world


def test_joint_segments_run_centre_anchor_anchor_centre():
    """One row per joint: a's centre, a's anchor, b's anchor, b's centre (the world's end at its anchor)."""
    world = _pendulum()
    lines = solids.joint_segments(world)
    assert lines.shape == (2, 4, 3)
    np.testing.assert_allclose(lines[0], [[0, 0, 1.2], [0, 0, 1.2], [0, 0, 0.6], [0, 0, 0.6]], atol=1e-12)
    np.testing.assert_allclose(lines[1], [[0, 0, 0.6], [0.15, 0, 0.6], [0.15, 0, 0.6], [0.3, 0, 0.6]], atol=1e-12)
    # rods: the rope's string, the ball's arm and the box's arm; dots: the rope's two anchors, the hinge's one
    capsules = solids.joint_capsules(lines, 0.01, 0.02)
    rods, dots = capsules[capsules[:, 7] == 0.01], capsules[capsules[:, 7] == 0.02]
    assert len(rods) == 3 and len(dots) == 3
    np.testing.assert_allclose(sorted(2 * rods[:, 8]), [0.15, 0.15, 0.6], rtol=1e-6)


def test_joints_are_drawn_only_when_asked(small_renderer):
    """With show_joints the rope shows between the ball and its anchor; without, that pixel is sky."""
    world = _pendulum(hinged_box=False)
    camera = _front_camera(target=(0.0, 0.0, 0.9), distance=2.5)
    small_renderer.show_joints = False
    try:
        plain = small_renderer.render(world, camera)
        small_renderer.show_joints = True
        shown = small_renderer.render(world, camera)
    finally:
        small_renderer.show_joints = False
    rope = (0.0, 0.0, 0.95)  # halfway up the string
    assert np.abs(_pixel(shown, camera, rope) - _pixel(plain, camera, rope)).max() > 40
    changed = np.abs(shown.astype(int) - plain.astype(int)).max(axis=2) > 20
    assert 5 < changed.sum() < 0.05 * W * H  # a thin line and two dots, not a smear
    np.testing.assert_array_equal(small_renderer.render(world, camera), plain)  # and off again


def test_capsule_seen_from_inside_its_bounding_box(small_renderer, chromaticity):
    """An eye between a capsule's cap and the corner of its box still sees the capsule (back faces are cast)."""
    world = tumble.World()
    world.add_capsule(position=(0.0, 0.0, 0.0), radius=0.5, half_height=0.5, static=True)
    camera = Camera(position=(0.45, -0.45, 0.98), target=(0.0, 0.0, 0.0), fov_deg=40)
    image = small_renderer.render(world, camera)
    assert _like(image[H // 2, W // 2].astype(float), body_colors([0]), chromaticity)


def test_hull_buffers_past_the_cache_size_are_freed_but_not_while_drawn(small_renderer, monkeypatch):
    """With room for two cached hulls, a frame of three still draws all three, the same as a fresh cache."""
    import tumble.render.renderer as renderer_module

    world = tumble.World()
    world.add_plane()
    for k in range(3):
        world.add_convex(points=TETRA * (1.0 + 0.2 * k), position=(0.5 * (k - 1), 0.0, 0.3), static=True)
    camera = _front_camera(target=(0.0, 0.0, 0.4))
    full = small_renderer.render(world, camera)
    monkeypatch.setattr(renderer_module, "SOLID_CACHE_SIZE", 2)
    np.testing.assert_array_equal(small_renderer.render(world, camera), full)
    assert small_renderer.cached_batches == 3  # all drawn now; older ones go when the next frame needs room
