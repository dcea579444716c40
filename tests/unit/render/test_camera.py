"""Camera maths: projection, orbit, pan, zoom, framing, scene-file cameras."""

from __future__ import annotations

import math

import numpy as np
import pytest

import tumble
from tumble.render import Camera


def test_target_projects_to_the_image_centre():
    """The target lands in the middle of the image at its distance."""
    cam = Camera(position=(1.0, -4.0, 2.0), target=(0.2, 0.3, 0.1))
    x, y, depth = cam.project(cam.target, 200, 100)
    assert x == pytest.approx(100.0) and y == pytest.approx(50.0)
    assert depth == pytest.approx(cam.distance)


def test_up_is_up_on_screen_and_right_is_right():
    """A point above the target is higher in the image (smaller y); one to the right has larger x."""
    cam = Camera(position=(0.0, -5.0, 0.0), target=(0.0, 0.0, 0.0))
    _, y_up, _ = cam.project((0.0, 0.0, 1.0), 100, 100)
    x_right, _, _ = cam.project((1.0, 0.0, 0.0), 100, 100)
    assert y_up < 50 and x_right > 50


def test_ray_through_a_projected_point_hits_it():
    """camera.ray inverts camera.project."""
    cam = Camera(position=(2.0, -3.0, 1.5), target=(0.0, 0.0, 0.5), fov_deg=50)
    p = np.array([0.4, -0.2, 0.9])
    x, y, _ = cam.project(p, 320, 240)
    origin, direction = cam.ray(x, y, 320, 240)
    to_p = p - origin
    assert np.allclose(direction, to_p / np.linalg.norm(to_p), atol=1e-9)


def test_orbit_keeps_distance_and_target():
    """Orbiting turns the eye around the target at a constant distance."""
    cam = Camera(position=(0.0, -4.0, 1.0), target=(0.0, 0.0, 0.0))
    d0 = cam.distance
    cam.orbit(math.pi / 2, 0.0)
    assert cam.distance == pytest.approx(d0)
    assert np.allclose(cam.target, 0.0)
    assert cam.position[2] == pytest.approx(1.0)  # yaw keeps the height
    assert cam.position[0] == pytest.approx(4.0)  # a quarter turn to the right


def test_orbit_elevation_is_clamped():
    """Large elevation changes stop just short of straight overhead."""
    cam = Camera(position=(0.0, -4.0, 0.0), target=(0.0, 0.0, 0.0))
    cam.orbit(0.0, 10.0)
    elevation = math.degrees(math.asin(cam.position[2] / cam.distance))
    assert elevation == pytest.approx(89.0)
    assert np.isfinite(cam.view_matrix()).all()


def test_pan_moves_eye_and_target_together():
    """Panning shifts both points by the same vector, perpendicular to the view."""
    cam = Camera(position=(0.0, -4.0, 0.0), target=(0.0, 0.0, 0.0))
    before = cam.position - cam.target
    cam.pan(0.5, 0.0)
    assert np.allclose(cam.position - cam.target, before)
    assert cam.target[0] > 0.0 and cam.target[1] == pytest.approx(0.0)


def test_zoom_divides_the_distance():
    """zoom(2) halves the distance to the target; bad factors are refused."""
    cam = Camera(position=(0.0, -4.0, 0.0), target=(0.0, 0.0, 0.0))
    cam.zoom(2.0)
    assert cam.distance == pytest.approx(2.0)
    with pytest.raises(ValueError, match="zoom"):
        cam.zoom(0.0)


def test_frame_puts_every_body_in_view():
    """After frame(), every sphere and box corner projects inside the image."""
    world = tumble.World()
    world.add_plane()
    world.add_sphere(position=(5.0, 0.0, 1.0), radius=0.5)
    world.add_sphere(position=(-3.0, 2.0, 4.0), radius=0.2)
    world.add_box(position=(0.0, -6.0, 0.5), half_extents=(0.5, 0.5, 0.5))
    cam = Camera()
    cam.frame(world, aspect=16 / 9)
    pts = np.array([[5.5, 0, 1], [4.5, 0, 1], [-3.2, 2, 4.2], [0.5, -6.5, 1.0], [-0.5, -5.5, 0.0]])
    xy = cam.project(pts, 160, 90)
    assert np.all((xy[:, 0] > 0) & (xy[:, 0] < 160) & (xy[:, 1] > 0) & (xy[:, 1] < 90))
    assert np.all(xy[:, 2] > 0)


def test_scene_camera_from_metadata():
    """A world's metadata camera (position, target, fov in degrees) is used as given."""
    world = tumble.World()
    world.metadata["camera"] = {"position": [1, 2, 3], "target": [0, 0, 1], "fov": 30}
    cam = Camera.for_world(world)
    assert np.allclose(cam.position, [1, 2, 3]) and np.allclose(cam.target, [0, 0, 1])
    assert cam.fov_deg == 30


def test_bad_camera_values_are_refused():
    """A field of view out of range or a degenerate camera raises ValueError naming the problem."""
    with pytest.raises(ValueError, match="field of view"):
        Camera(fov_deg=0)
    with pytest.raises(ValueError, match="position"):
        Camera(position=(1, 2))
    with pytest.raises(ValueError, match="differ"):
        Camera(position=(0, 0, 0), target=(0, 0, 0))
    # beyond what the float32 matrices hold (1e300 ended in "Singular matrix", naming nothing)
    with pytest.raises(
        ValueError, match=r"camera position must be within 1e\+12 m of the origin, got \[1e\+300, 0.0, 0.0\]"
    ):
        Camera(position=(1e300, 0, 0))
    with pytest.raises(ValueError, match="camera target must be within"):
        Camera(target=(0, -1e13, 0))
    assert Camera(position=(1e12, 0, 0), target=(0, 0, 0)).position[0] == 1e12


def test_scene_camera_with_position_only_looks_at_the_scene():
    """A [camera] table with a position but no target aims at the framed scene's centre."""
    world = tumble.World()
    world.add_sphere(position=(2.0, 1.0, 0.5), radius=0.5)
    world.metadata["camera"] = {"position": [6, -4, 3], "fov": 50}
    cam = Camera.for_world(world)
    assert np.allclose(cam.position, [6, -4, 3])
    assert np.allclose(cam.target, [2.0, 1.0, 0.5])
    assert cam.fov_deg == 50


def test_frame_includes_cloth_and_emitters(cloth_world, make_cloth):
    """Cloth particles and emitter regions count when framing a scene."""
    world = cloth_world(make_cloth(centre=(10.0, 0.0, 1.0)))
    world.add_emitter(shape="sphere", rate=10, count=5, position=(-10.0, 0.0, 2.0), radius=0.1)
    cam = Camera()
    cam.frame(world, aspect=1.0)
    xy = cam.project([[10.0, 0.0, 1.0], [-10.0, 0.0, 2.0]], 100, 100)
    assert np.all((xy[:, :2] > 0) & (xy[:, :2] < 100))
