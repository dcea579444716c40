"""Picking and dragging in the viewer (tumble.viewer.picking): rays against particles, boxes, capsules,
hulls and spheres, and the drag that follows the cursor."""

import math

import numpy as np
import pytest

import tumble
from tolerances import resolution
from tumble.viewer import picking

TETRA = np.array([[0.0, 0.0, 0.0], [0.4, 0.0, 0.0], [0.0, 0.4, 0.0], [0.0, 0.0, 0.4]])
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def test_ray_points_finds_the_nearest_particle_within_reach():
    """Particles within reach of the ray are candidates; the nearest along the ray wins."""
    points = np.array([[3.0, 0.05, 0.0], [1.0, 0.5, 0.0], [2.0, -0.02, 0.0]])
    i, t = picking.ray_points(np.zeros(3), np.array([1.0, 0.0, 0.0]), points, reach=0.1)
    assert i == 2 and t == pytest.approx(2.0)


def test_ray_box_hits_the_face_of_a_turned_box():
    """A ray along +x meets a unit cube turned 45 degrees about z at its edge, sqrt(2)/2 from the centre."""
    q = np.array([0.0, 0.0, math.sin(math.pi / 8), math.cos(math.pi / 8)])
    t = picking.ray_box(np.array([-5.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.zeros(3), q, np.full(3, 0.5))
    assert t == pytest.approx(5.0 - math.sqrt(0.5))
    miss = picking.ray_box(np.array([-5.0, 0.9, 0.0]), np.array([1.0, 0.0, 0.0]), np.zeros(3), q, np.full(3, 0.5))
    assert math.isinf(miss)


class FakeCloth:
    """The ClothSystem surface the viewer uses: positions, velocities, masses, forces, pins."""

    def __init__(self):
        self.particle_position = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [2.0, 0.0, 1.0]])
        self.particle_velocity = np.zeros((3, 3))
        self.particle_mass = np.full(3, 0.5)
        self.particle_inv_mass = np.array([2.0, 2.0, 0.0])  # the last one is pinned
        self.particle_count = 3
        self.forces, self.pins = [], []

    def apply_force(self, i, force):
        self.forces.append((i, np.asarray(force)))

    def set_pin_target(self, i, position):
        self.pins.append((i, np.asarray(position)))


class FakeClothWorld:
    body_count = 0
    gravity = np.array([0.0, 0.0, -9.81])
    dt = 0.25

    has_cloth = True

    def __init__(self):
        self.cloth = FakeCloth()


def test_drag_pulls_a_free_cloth_particle_and_moves_a_pinned_one():
    """A ray through a free particle grabs it (spring force, weight held); through a pin, moves the pin."""
    world = FakeClothWorld()
    down = np.array([0.0, 0.0, -1.0])
    grab = picking.pick(world, np.array([1.0, 0.0, 5.0]), down)
    assert grab.kind == "particle" and grab.index == 1 and grab.distance == pytest.approx(4.0)
    grab.target = np.array([1.0, 0.0, 1.0])  # at the particle: only the weight is carried
    picking.apply_drag(world, grab)
    i, force = world.cloth.forces[-1]
    assert i == 1
    np.testing.assert_allclose(force, [0.0, 0.0, 0.5 * 9.81], atol=1e-9)

    pin = picking.pick(world, np.array([2.0, 0.0, 5.0]), down)
    assert pin.kind == "pin" and pin.index == 2
    pin.target = np.array([2.0, 0.3, 1.4])  # 0.5 m away: reached in one step of 0.25 s at 3 m/s
    picking.apply_drag(world, pin)
    assert world.cloth.pins[-1][0] == 2
    np.testing.assert_allclose(world.cloth.pins[-1][1], [2.0, 0.3, 1.4])
    pin.target = np.array([2.0, 0.0, 3.0])  # 2 m away: moves 0.75 m towards it
    picking.apply_drag(world, pin)
    np.testing.assert_allclose(world.cloth.pins[-1][1], [2.0, 0.0, 1.75])


def test_drag_target_stays_in_the_camera_facing_plane():
    """Moving the cursor keeps the target at the grab depth along the view axis."""
    grab = picking.Grab("body", 0, np.zeros(3), distance=5.0, target=np.zeros(3), depth=5.0)
    forward = np.array([0.0, 1.0, 0.0])
    d = np.array([0.6, 0.8, 0.0])
    target = picking.drag_target(grab, np.zeros(3), d, forward)
    assert target @ forward == pytest.approx(5.0)


def test_ray_capsule_hits_the_side_and_the_caps_at_their_distances():
    """An upright capsule (r 0.5, segment half length 1): the side at 5 - r, a cap's top at 5 - (1 + r), misses inf."""
    centre = np.zeros(3)
    side = picking.ray_capsule(np.array([-5.0, 0.0, 0.3]), np.array([1.0, 0.0, 0.0]), centre, IDENTITY, 0.5, 1.0)
    assert side == pytest.approx(4.5)
    top = picking.ray_capsule(np.array([0.0, 0.0, 5.0]), np.array([0.0, 0.0, -1.0]), centre, IDENTITY, 0.5, 1.0)
    assert top == pytest.approx(3.5)
    # off the axis by 0.3 over the cap: the sphere of radius 0.5 at z = 1 is met at z = 1 + 0.4
    off = picking.ray_capsule(np.array([0.3, 0.0, 5.0]), np.array([0.0, 0.0, -1.0]), centre, IDENTITY, 0.5, 1.0)
    assert off == pytest.approx(5.0 - 1.4)
    miss = picking.ray_capsule(np.array([-5.0, 0.6, 0.0]), np.array([1.0, 0.0, 0.0]), centre, IDENTITY, 0.5, 1.0)
    assert math.isinf(miss)
    behind = picking.ray_capsule(np.array([-5.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0]), centre, IDENTITY, 0.5, 1.0)
    assert math.isinf(behind)


def test_ray_convex_of_a_cube_given_as_planes():
    """The cube |x|, |y|, |z| <= 0.5 as six half spaces: entered at 5 - 0.5, left at 0.5 from inside, missed beside."""
    normal = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    offset = np.full(6, 0.5)
    centre = np.array([1.0, 2.0, 3.0])
    along_x = np.array([1.0, 0.0, 0.0])
    assert picking.ray_convex(centre - (5.0, 0, 0), along_x, centre, IDENTITY, normal, offset) == pytest.approx(4.5)
    assert picking.ray_convex(centre, along_x, centre, IDENTITY, normal, offset) == pytest.approx(0.5)  # from inside
    beside = centre + (-5.0, 0.6, 0.0)
    assert math.isinf(picking.ray_convex(beside, along_x, centre, IDENTITY, normal, offset))
    # turned 45 degrees about z, the cube's edge is met sqrt(1/2) before its centre
    q = np.array([0.0, 0.0, math.sin(math.pi / 8), math.cos(math.pi / 8)])
    t = picking.ray_convex(centre - (5.0, 0, 0), along_x, centre, q, normal, offset)
    assert t == pytest.approx(5.0 - math.sqrt(0.5))


def test_pick_takes_the_nearest_movable_body_and_skips_static_ones():
    """Of two spheres on a ray the nearer is picked, at distance d - r; a static body in front is passed through."""
    world = tumble.World(gravity=(0, 0, 0))
    world.add_box(position=(0.0, -3.0, 0.0), half_extents=(0.5, 0.1, 0.5), static=True)  # body 0, in front
    far = world.add_sphere(position=(0.0, 2.0, 0.0), radius=0.3)
    near = world.add_sphere(position=(0.0, 0.0, 0.0), radius=0.2)
    grab = picking.pick(world, (0.0, -5.0, 0.0), (0.0, 1.0, 0.0))
    assert grab is not None and grab.kind == "body" and grab.index == near != far
    assert grab.distance == pytest.approx(5.0 - 0.2)
    np.testing.assert_allclose(grab.local_point, [0.0, -0.2, 0.0], atol=1e-12)  # the sphere's near pole
    assert grab.depth == pytest.approx(grab.distance)  # view axis = the ray
    assert picking.pick(world, (3.0, -5.0, 0.0), (0.0, 1.0, 0.0)) is None  # beside everything
    np.testing.assert_allclose(picking.held_point(world, grab), [0.0, -0.2, 0.0], atol=1e-12)


def test_drag_on_a_body_at_the_target_carries_its_weight():
    """A body held at rest exactly at the target gets the force m g upwards (the spring's pull is zero)."""
    world = tumble.World(gravity=(0.0, 0.0, -9.81))
    body = world.add_sphere(position=(0.0, 0.0, 1.0), radius=0.1, mass=2.0)
    grab = picking.pick(world, (0.0, -5.0, 1.0), (0.0, 1.0, 0.0))
    grab.target = picking.held_point(world, grab).copy()
    picking.apply_drag(world, grab)
    world.step()
    # one step with gravity balanced: the ball has not started to fall (free fall: g dt = 0.16 m/s)
    assert world.body_velocity[body][2] == pytest.approx(0.0, abs=1e-4)


def test_picking_hits_capsules_and_hulls_exactly():
    """Rays that pass inside the bounding sphere but miss the shape pick nothing; rays on the shape pick it."""
    pytest.importorskip("scipy")  # convex hulls are taken with SciPy
    world = tumble.World(gravity=(0, 0, 0))
    q = (0.0, math.sin(math.pi / 4), 0.0, math.cos(math.pi / 4))  # capsule lying along x
    capsule = world.add_capsule(position=(0.0, 0.0, 0.0), radius=0.1, half_height=0.4, orientation=q)
    hull = world.add_convex(points=TETRA * 2, position=(0.0, 0.0, 2.0))
    down = np.array([0.0, 0.0, -1.0])
    grab = picking.pick(world, (0.45, 0.0, 1.0), down)  # over the capsule's cap: hits its top at z = r
    assert grab is not None and grab.index == capsule
    centre = np.asarray(world.body_position)[capsule]
    # the ray against the capsule's turned segment, in the world's precision: 8 ulps of the ray's length (1 m)
    reach = 1.0 - (centre[2] + math.sqrt(0.1**2 - 0.05**2))
    assert grab.distance == pytest.approx(reach, abs=resolution(1e-9, 1.0, 8))
    assert picking.pick(world, (0.0, 0.3, 1.0), down) is None  # inside the bound (0.5), beside the capsule
    # the hull (tetrahedron of edge 0.8 at the origin of its user frame, moved to z = 2)
    along = np.array([0.0, 1.0, 0.0])
    grab = picking.pick(world, (0.1, -5.0, 2.1), along)
    assert grab is not None and grab.index == hull
    assert grab.distance == pytest.approx(5.0, abs=resolution(1e-9, 5.0, 8))  # 8 ulps of the ray's length
    assert picking.pick(world, (0.7, -5.0, 2.7), along) is None  # inside its bounding box, outside the hull
