"""Static triangle meshes against analytic references: a bowl, a ramp like a plane, no tunnelling."""

from __future__ import annotations

import numpy as np
import pytest

import tumble

G = 9.81


def quat_axis_angle(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.r_[axis * np.sin(angle / 2), np.cos(angle / 2)]


def grid_mesh(height, n=41, half=1.0):
    """A height field z = height(x, y) on an n x n grid over [-half, half]^2, wound upwards."""
    xs = np.linspace(-half, half, n)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), height(X, Y).ravel()], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return v, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def energy_and_x(w, duration):
    """Run `w` for `duration` seconds; its total energy and body 1's x after every step."""
    energy, xs = [], []

    def record(world):
        energy.append(world.kinetic_energy() + world.potential_energy())
        xs.append(world.body_position[1, 0])

    w.run(duration, callback=record)
    return np.array(energy), np.array(xs)


def slab_mesh(hx, hy, hz):
    """A closed box mesh (12 triangles, outward) of half sizes hx, hy, hz."""
    v = np.array([[x, y, z] for z in (-hz, hz) for y in (-hy, hy) for x in (-hx, hx)])
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3]]
    return v, np.array([t for q in quads for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])])


def test_sphere_settles_at_the_lowest_point_of_a_bowl():
    """A sphere dropped into a paraboloid bowl comes to rest on its lowest face, the flat middle cell.

    On a 40 x 40 grid over [-1, 1]^2 the middle cell's corners are all at x, y = +-1/39, so it is
    flat at z = (1/39)^2 and the lowest part of the mesh; the sphere's centre rests r above it.
    """
    v, t = grid_mesh(lambda x, y: 0.5 * (x * x + y * y), n=40)
    w = tumble.World()
    w.add_mesh(vertices=v, triangles=t, restitution=0.0)
    r = 0.05
    w.add_sphere(position=(0.01, -0.005, 0.3), radius=r, restitution=0.0)
    w.run(2.0)
    x = w.body_position[1]
    assert abs(x[0]) < 1 / 39 and abs(x[1]) < 1 / 39
    assert x[2] == pytest.approx((1 / 39) ** 2 + r, abs=1e-4)
    assert np.linalg.norm(w.body_velocity[1]) < 1e-3


def test_sphere_released_on_a_bowl_side_oscillates_about_the_lowest_point():
    """A sphere released on the bowl's side rolls to and fro about the bottom, gaining no energy.

    Rolling in a bowl of curvature radius R = 1 / (2 k) its centre swings with
    omega^2 = g / ((R - r)(1 + 2/5)) for small amplitudes: period 2.31 s for R = 1 m, r = 5 cm.
    """
    v, t = grid_mesh(lambda x, y: 0.5 * (x * x + y * y))
    w = tumble.World()
    w.add_mesh(vertices=v, triangles=t, restitution=0.0, friction=0.8)
    r, x0 = 0.05, 0.2
    z0 = 0.5 * x0 * x0 + r  # near the surface (the centre rides r above it)
    w.add_sphere(position=(x0, 0.0, z0 + 0.002), radius=r, restitution=0.0, friction=0.8)
    e0 = w.kinetic_energy() + w.potential_energy()
    xs = []
    w.run(4.62, callback=lambda world: xs.append(world.body_position[1, 0]))
    xs = np.array(xs)
    # two periods: the swing is centred on the lowest point and returns near its start
    assert abs(xs.mean()) < 0.02
    assert xs.min() < -0.15
    assert w.kinetic_energy() + w.potential_energy() <= e0 + 1e-9
    period = 2 * np.pi * np.sqrt((1.0 - r) * 1.4 / G)
    crossings = np.flatnonzero(np.diff(np.sign(xs)) != 0) * w.dt
    assert np.diff(crossings[:3]).sum() == pytest.approx(period, rel=0.05)


@pytest.mark.parametrize("corner", ["on mesh vertices", "on mesh edges"])
@pytest.mark.float64(
    "mirror-symmetric test of an amplifier: in float32 the manifold sweeps' rounding (they stop at "
    "MANIFOLD_SWEEP_TOLERANCE, 9.8e-4 of the load) tilts the box by ~3e-6 rad at its first landing, the four "
    "corner rows being swept in a diagonal order on the mesh, and the second, e = 0.5 landing turns that tilt "
    "into 0.045 rad/s of spin (one side's corners close a substep before the other's); it checks that the mesh "
    "matches the plane, in float64"
)
def test_box_landing_flat_on_a_flat_grid_mesh_bounces_as_on_a_plane(corner):
    """A box dropped flat (e = 0.5, mu = 0.5) onto a flat grid mesh of 0.02 m cells bounces and comes
    to rest as on a plane, its corners landing on the mesh's vertices or on its edges.

    There the closest point's direction, the contact normal at an edge or a vertex, came out of the
    float32 mesh query tilted by 4e-5; the four corners' normals differed, so they were not solved
    as one face's patch but one by one, and the second bounce threw the box off spinning at 0.84
    rad/s, 16 mm from where it rests on a plane. Mirror-symmetric, it must not turn: the bound is
    0.01 rad/s (its corners moving 1 mm/s), and 1 mm from the plane's path.
    """
    x0 = 0.0 if corner == "on mesh vertices" else 0.01  # half extents 0.1 and 0.06: grid lines

    def path(as_mesh):
        w = tumble.World()
        if as_mesh:
            v, t = grid_mesh(lambda x, y: 0.0 * x, n=101)
            w.add_mesh(vertices=v, triangles=t, restitution=0.5, friction=0.5)
        else:
            w.add_plane(restitution=0.5, friction=0.5)
        w.add_box(position=(x0, 0.0, 0.3), half_extents=(0.1, 0.06, 0.05), restitution=0.5, friction=0.5)
        out = []
        w.run(1.5, callback=lambda world: out.append(np.r_[world.body_position[1], world.body_angular_velocity[1]]))
        return np.array(out)

    mesh, plane = path(True), path(False)
    assert np.abs(mesh[:, 3:]).max() <= 0.01
    assert np.abs(mesh[:, :3] - plane[:, :3]).max() <= 1e-3


def test_box_lying_across_a_tessellated_ridge_rests_level():
    """A box lowered flat onto a roof's ridge (z = -0.3 |x|, a grid of 0.02 m cells: the ridge is 100
    collinear mesh edges) rests on the whole ridge line under it, level.

    The ridge presses into the box's bottom face between its corners (the mesh-edge contact). Its
    stretch under the face was one mesh edge's, the first found of equals: the box stood on the
    2 cm of the ridge under one end, tipped about the ridge at up to 4.3 rad/s and came to rest
    11 mm aside and tilted. Mirror-symmetric about its own mid-plane, it must not turn at all: the
    bound is a tilt speed of 1e-3 rad/s (its ends moving 0.05 mm/s) and 1e-4 of its start aside.
    In both precisions: in float32 a grid diagonal ending on the ridge came out a hair deeper than
    the ridge's own edges, the line contact shrank to that end, and the box tipped at 1.09 rad/s.
    """
    v, t = grid_mesh(lambda x, y: -0.3 * np.abs(x), n=101)
    w = tumble.World()
    w.add_mesh(vertices=v, triangles=t, restitution=0.0, friction=0.5)
    h, y0 = 0.05, 0.003  # (its ends off the mesh's vertices)
    w.add_box(position=(0.0, y0, h + 0.001), half_extents=(h, h, h), restitution=0.0, friction=0.5)
    spin = []
    w.run(1.0, callback=lambda world: spin.append(world.body_angular_velocity[1].copy()))
    assert np.abs(spin).max() <= 1e-3
    assert abs(w.body_position[1, 1] - y0) <= 1e-4
    assert w.body_position[1, 2] == pytest.approx(h, abs=1e-4)  # on the ridge, not tipped onto a side


def test_box_landing_on_a_mesh_incline_turns_as_on_the_plane():
    """A frictionless box dropped square onto an incline (slope 0.3) made of a grid mesh of 0.02 m
    cells lands and slides as on the same incline as a plane: it tips onto the slope about y only.

    The mesh beyond the box's leading bottom edge, rising with the slope, looked nearer than the
    box's corners to the edge contact's lower bound on the distance outside the box: one mesh
    edge of the many there took a contact beside the box, which rolled it at 0.1 rad/s and spun it
    about the vertical at 0.03 (on a curved hill, 6.6 and 9.2 rad/s). Mirror-symmetric about its
    own mid-plane, it must not turn about x or z; the bound, 0.01 rad/s, is 1/500 of its 5 rad/s
    landing turn about y, which must match the plane's to the same 0.01 rad/s.
    """
    slope, h = 0.3, 0.05

    def spins(as_mesh):
        # the plane, the reference, in float64 (the mesh in the test's precision): in float32 the landing's
        # impact falls a substep earlier or later by rounding, and the spin sampled at the step it falls in
        # (step 13) moves by 0.95 rad/s on the plane itself; the float32 mesh matches float64's to 4e-4 rad/s
        w = tumble.World() if as_mesh else tumble.World(precision="float64")
        if as_mesh:
            v, t = grid_mesh(lambda x, y: slope * x, n=101)
            w.add_mesh(vertices=v, triangles=t, restitution=0.0, friction=0.0)
        else:
            w.add_plane(normal=(-slope, 0.0, 1.0), restitution=0.0, friction=0.0)
        # its lower corners 6 mm above the incline, its sides off the mesh's vertices
        w.add_box(
            position=(-0.3, 0.003, -0.25 * slope + h + 0.006),
            half_extents=(h, h, h),
            velocity=(0.8, 0.0, -0.041),
            restitution=0.0,
            friction=0.0,
        )
        out = []
        w.run(0.5, callback=lambda world: out.append(world.body_angular_velocity[1].copy()))
        return np.array(out)

    mesh, plane = spins(True), spins(False)
    assert np.abs(plane[:, 1]).max() > 4.0  # it did tip onto the slope
    assert np.abs(mesh[:, [0, 2]]).max() <= 0.01
    assert np.abs(mesh[:, 1] - plane[:, 1]).max() <= 0.01


@pytest.mark.parametrize("yaw_deg", [0.0, 30.0])
def test_box_sliding_in_a_finely_tessellated_half_pipe_gains_no_energy(yaw_deg):
    """A frictionless box (0.1 m, e = 0) sliding across a half-pipe z = x^2 / 2 of 0.02 m cells
    loses energy, never gains it.

    Its bottom edges cross a concave edge of the mesh every 2 cm. With each vertex touching only
    the nearest face, they sank into the next face along the one they left and were pushed out
    after, raised without being slowed: +6.7 mJ (1 % of its energy, 0.7 mm of height) in 4 s,
    more the finer the mesh. Each crossing is an inelastic impact on the new face, so the energy
    can only fall. The bound is the sphere's: the energy of 100 um of height. Turned 30 degrees
    about the vertical, its corners cross the edges one after another.
    """
    v, t = grid_mesh(lambda x, y: 0.5 * x * x, n=101)
    w = tumble.World()
    w.add_mesh(vertices=v, triangles=t, restitution=0.0, friction=0.0)
    h, yaw = 0.05, np.radians(yaw_deg)
    reach = h * (abs(np.cos(yaw)) + abs(np.sin(yaw)))  # the farthest corner's |x|
    # released with its lowest corners 0.3 mm above the faces under them (the analytic z = x^2 / 2
    # there, which the faceted mesh lies at most 50 um above), sliding at 0.6 m/s along x
    w.add_box(
        position=(0.0, 0.0, h + 0.5 * reach * reach + 3.5e-4),
        half_extents=(h, h, h),
        orientation=quat_axis_angle((0, 0, 1), yaw),
        velocity=(0.6, 0.0, 0.0),
        restitution=0.0,
        friction=0.0,
    )
    m, e0 = w.body_mass[1], w.kinetic_energy() + w.potential_energy()
    energy, xs = energy_and_x(w, 4.0)
    assert max(energy) <= e0 + m * G * 1e-4
    assert max(xs) > 0.15 and min(xs) < -0.15  # it swung up both sides (to 0.19 m without losses)


@pytest.mark.parametrize("shape", ["sphere", "capsule"])
@pytest.mark.parametrize("friction", [0.0, 0.8])
def test_ball_in_a_finely_tessellated_bowl_gains_no_energy(friction, shape):
    """A ball in a bowl of cells smaller than itself (0.02 m, r = 0.05 m) loses energy, never gains it.

    Rolling or sliding from face to face it crosses a concave edge every few steps. With only the
    nearest face as its contact it sank into the next face along the one it left and was pushed out
    after, raised without being slowed: its swing grew from 0.2 to 0.207 m in 5 s (+23 % energy in
    20 s). Each crossing is an inelastic impact on the new face, so the swing can only shrink. The
    bound: the energy of 100 um of height (five times the ball's resting sink under its weight).
    A capsule lying across the swing (its ends and middle are such balls) swung from 0.2 to 0.213 m
    in 10 s.
    """
    v, t = grid_mesh(lambda x, y: 0.5 * (x * x + y * y), n=101)
    w = tumble.World()
    w.add_mesh(vertices=v, triangles=t, restitution=0.0, friction=friction)
    r, x0 = 0.05, 0.2
    # released 4 mm above the analytic bowl, clear of it along its normal (the bowl rises 11 degrees
    # there, and 1.25 mm more under a capsule's ends; the faceted bowl lies up to 50 um above it)
    start = (x0, 0.0, 0.5 * x0 * x0 + r + 0.004)
    if shape == "sphere":
        w.add_sphere(position=start, radius=r, restitution=0.0, friction=friction)
    else:  # its axis along y, across the swing
        q = (np.sin(np.pi / 4), 0.0, 0.0, np.cos(np.pi / 4))
        w.add_capsule(position=start, radius=r, half_height=0.05, orientation=q, restitution=0.0, friction=friction)
    m, e0 = w.body_mass[1], w.kinetic_energy() + w.potential_energy()
    energy, xs = energy_and_x(w, 5.0)
    assert max(energy) <= e0 + m * G * 1e-4
    assert np.abs(xs[-round(2.0 / w.dt) :]).max() <= x0 + 5e-4  # the last 2 s hold a turning point
    assert np.abs(xs).min() < 0.01  # it did swing through the middle


@pytest.mark.parametrize("alpha_deg", [5.0, 20.0])
def test_ball_sliding_onto_a_rising_face_keeps_the_speed_along_it(alpha_deg):
    """A frictionless ball sliding at 2 m/s onto a face rising at alpha keeps v cos(alpha) (e = 0).

    The crease is an inelastic impact: the speed into the new face is lost, the speed along it
    kept, so the centre then rises (v cos alpha)^2 / (2 g) above where it slid. Bound: one step's
    rise along the face, v dt sin(alpha) (the crease is met within a step); a crease passed
    without loss would rise 1.5 mm (5 degrees) and 24 mm (20 degrees) higher.
    """
    alpha, v0, r = np.radians(alpha_deg), 2.0, 0.05
    length = 12.0
    xb, zb = length * np.cos(alpha), length * np.sin(alpha)
    vertices = np.array([[-1, -1, 0], [0, -1, 0], [0, 1, 0], [-1, 1, 0], [xb, -1, zb], [xb, 1, zb]], float)
    w = tumble.World()
    w.add_mesh(vertices=vertices, triangles=[[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]], restitution=0.0, friction=0.0)
    w.add_sphere(position=(-0.5, 0.0, r), radius=r, restitution=0.0, friction=0.0, velocity=(v0, 0.0, 0.0))
    heights = []
    w.run(1.2 * v0 / (G * np.sin(alpha)) + 0.3, callback=lambda world: heights.append(world.body_position[1, 2]))
    rise = (v0 * np.cos(alpha)) ** 2 / (2 * G)
    assert max(heights) - r == pytest.approx(rise, abs=v0 * w.dt * np.sin(alpha))


@pytest.mark.parametrize("theta_deg, mu", [(30.0, 0.3), (40.0, 0.5)])
def test_box_slides_down_a_mesh_ramp_as_down_a_plane(theta_deg, mu):
    """A box on a two-triangle mesh ramp slides with the acceleration it has on an equal plane, within 1 %."""
    theta = np.radians(theta_deg)
    n = np.array([0.0, -np.sin(theta), np.cos(theta)])
    down = np.array([0.0, -np.cos(theta), -np.sin(theta)])
    q = quat_axis_angle((1, 0, 0), theta)
    result = {}
    for kind in ("plane", "mesh"):
        w = tumble.World()
        if kind == "plane":
            w.add_plane(normal=n, friction=mu, restitution=0.0)
        else:
            v = np.array([[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], float)
            w.add_mesh(vertices=v, triangles=[[0, 1, 2], [0, 2, 3]], orientation=q, friction=mu, restitution=0.0)
        w.add_box(
            position=n * 0.1 + 1.5 * np.cross(n, [1, 0, 0]) * 0,
            half_extents=(0.1,) * 3,
            orientation=q,
            mass=1.0,
            friction=mu,
            restitution=0.0,
        )
        w.run(0.25)
        v1 = np.dot(w.body_velocity[1], down)
        w.run(1.0)
        result[kind] = (np.dot(w.body_velocity[1], down) - v1) / 1.0
    a = G * (np.sin(theta) - mu * np.cos(theta))
    assert result["mesh"] == pytest.approx(result["plane"], rel=0.01)
    assert result["mesh"] == pytest.approx(a, rel=0.01)


@pytest.mark.parametrize("shape", ["sphere", "box", "capsule"])
def test_no_tunnelling_through_a_thin_mesh_at_50_m_s(shape):
    """A body hitting a 5 mm thick mesh slab at 50 m/s is stopped on top of it (speculative contacts).

    While its centre is over the slab (one bound radius inside the edges), the body never sinks
    below resting height by more than 1 mm. The box lands flat and then slides off the 1 m slab
    with the ~2 m/s and ~20 rad/s that the solver gives any box landing flat that fast, on a plane
    too (tests/regression/test_issue_16_flat_landing_spins_a_box.py): that is not tunnelling,
    so it is judged on top only, the sphere and the capsule also at rest after 0.5 s.
    """
    v, t = slab_mesh(0.5, 0.5, 0.0025)
    w = tumble.World(gravity=(0, 0, -9.81))
    w.add_mesh(vertices=v, triangles=t, restitution=0.0)
    kwargs = dict(position=(0, 0, 0.5), velocity=(0, 0, -50.0), restitution=0.0)
    if shape == "sphere":
        w.add_sphere(radius=0.02, **kwargs)
    elif shape == "box":
        w.add_box(half_extents=(0.02,) * 3, **kwargs)
    else:
        w.add_capsule(radius=0.02, half_height=0.05, orientation=quat_axis_angle((1, 0, 0), np.pi / 2), **kwargs)
    rest = 0.0025 + 0.02
    inside = 0.5 - float(w.bodies.numpy("body_bound_radius")[1])
    heights = []
    for _ in range(round(0.5 / w.dt)):
        w.step()
        x = w.body_position[1]
        if x[2] < 0.1 and max(abs(x[0]), abs(x[1])) < inside:
            heights.append(x[2])
    assert len(heights) > 20  # it was caught on top and stayed there a while (20 steps: 83 ms)
    assert min(heights) > rest - 1e-3
    if shape != "box":
        assert w.body_position[1, 2] == pytest.approx(rest, abs=1e-3)


# a pebble of the pebble_bowl sample (the hull of ten points, 8 cm across)
PEBBLE = 0.08 * np.array(
    [
        [-0.280, 0.223, 0.220],
        [0.486, 0.643, -0.082],
        [0.256, -0.129, -0.302],
        [-0.332, 0.048, -0.194],
        [-0.090, 0.396, 0.121],
        [0.270, 0.122, -0.037],
        [-0.880, 0.350, -0.320],
        [0.102, -0.038, 0.029],
        [0.119, -0.118, 0.191],
        [-0.606, 0.280, -0.359],
    ]
)


def quat_rotate(q, v):
    """Rotate the rows of v by the unit quaternion q = (x, y, z, w)."""
    u, s = np.asarray(q[:3]), q[3]
    return v + 2 * s * np.cross(u, v) + 2 * np.cross(u, np.cross(u, v))


@pytest.mark.parametrize("floor", ["plane", "mesh"])
def test_a_spinning_pebble_puts_no_vertex_through_the_floor_that_it_swings_down(floor):
    """A pebble tumbling at 23 rad/s, one vertex 1.2 mm above the floor, swings another from 1.95 mm
    above to 5.6 mm below within the step (at its velocities now), a vertex that is not among the
    four a resting contact keeps (the deepest, the farthest from it, and the largest triangles).
    That vertex gets a contact as well, and stays out of the floor: 3.8 mm into it before, in the
    pebble_bowl sample 7 mm into the bowl. Bound: the distance gravity moves a body in one step
    (g dt^2, 0.17 mm), less than which the contact, stopping it at the surface, leaves.
    """
    w = tumble.World(gravity=(0, 0, -G))
    if floor == "plane":
        w.add_plane(restitution=0.1, friction=0.6)
    else:
        v, t = slab_mesh(1.0, 1.0, 0.005)
        w.add_mesh(vertices=v, triangles=t, position=(0, 0, -0.005), restitution=0.1, friction=0.6)
    i = w.add_convex(points=PEBBLE, position=(0, 0, 1), density=2600, restitution=0.1, friction=0.6)
    # a state of a pebble dropped at 3 m/s spinning (principal frame: the orientation is the body's)
    q = np.array([0.545393, -0.822651, -0.133903, 0.088667])
    w.set_body_state(
        i,
        position=(0.013728, 0.003286, 0.016192),
        orientation=q / np.linalg.norm(q),
        velocity=(0.107484, -0.316346, -0.747502),
        angular_velocity=(-23.13876, 4.323552, 0.0),
    )
    vertices = np.asarray(w.hulls.prototypes[int(w.bodies.numpy("body_geometry")[i])].vertex)

    def heights():
        return (w.body_position[i] + quat_rotate(w.body_orientation[i], vertices))[:, 2]

    world_vertices = w.body_position[i] + quat_rotate(w.body_orientation[i], vertices)
    point_velocity = w.body_velocity[i] + np.cross(w.body_angular_velocity[i], world_vertices - w.body_position[i])
    ahead = world_vertices[:, 2] + w.dt * point_velocity[:, 2]
    crossing = np.flatnonzero((world_vertices[:, 2] > 0) & (ahead < 0))
    assert len(crossing) >= 1  # the case: a vertex above the floor that would end the step below it
    w.collide()
    for k in crossing:  # a contact at it (the point midway to the floor is right below it)
        offsets = np.linalg.norm(w.contact_point[:, :2] - world_vertices[k, :2], axis=1)
        assert offsets.min() < 1e-6, (k, w.contact_point)
    w.step()
    assert heights().min() > -G * w.dt**2


def ridge_mesh(height=0.2, half=1.0):
    """A tent: two 45 degree slopes meeting at a sharp ridge along y at z = height, wound upwards."""
    v = np.array(
        [
            [-half, -half, height - half],
            [0, -half, height],
            [half, -half, height - half],
            [-half, half, height - half],
            [0, half, height],
            [half, half, height - half],
        ],
        float,
    )
    t = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]])
    return v, t


@pytest.mark.parametrize("shape", ["box", "convex"])
def test_a_block_sliding_off_an_open_mesh_ledge_keeps_its_speed(shape):
    """A frictionless 0.2 m block sliding at 2 m/s off the boundary edge of a flat open mesh (a
    ledge 0.5 m up) leaves it as off a static box: no slower by more than one step of gravity's
    impulse, g dt, and no higher than tipping over the edge lifts its centre, (sqrt 2 - 1) h for
    half height h. Its corners past the edge, dipping as deep as its resting contact, were pushed
    back through the edge: it slowed to 0.73 m/s and hopped 4 cm (found by an outside audit)."""
    v, t = np.array([[-1, -1, 0.5], [1, -1, 0.5], [1, 1, 0.5], [-1, 1, 0.5]]), np.array([[0, 1, 2], [0, 2, 3]])
    w = tumble.World(gravity=(0, 0, -9.81))
    w.add_plane()
    w.add_mesh(vertices=v, triangles=t, friction=0.0, restitution=0.0)
    half = 0.1
    start = (0.6, 0.0, 0.5 + half)
    if shape == "box":
        block = w.add_box(position=start, half_extents=(half,) * 3, velocity=(2, 0, 0), friction=0.0, restitution=0.0)
    else:
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
        block = w.add_convex(points=corners, position=start, velocity=(2, 0, 0), friction=0.0, restitution=0.0)
    slowest, highest = np.inf, -np.inf
    for _ in range(round(0.5 / w.dt)):  # over the edge at 0.2 s, falling past the ledge by 0.5 s
        w.step()
        slowest = min(slowest, w.body_velocity[block][0])
        highest = max(highest, w.body_position[block][2])
    assert w.body_position[block][0] > 1.0 + half  # it left the ledge
    assert slowest >= 2.0 - 9.81 * w.dt
    assert highest <= start[2] + (np.sqrt(2.0) - 1.0) * half


@pytest.mark.parametrize("shape", ["box", "convex"])
def test_a_plank_dropped_across_a_sharp_ridge_is_held_by_it(shape):
    """A plank falling flat across a ridge rests on the ridge line, between its vertices.

    The ridge presses into the plank's bottom face far from any of its vertices, which the vertex
    queries alone never see (the plank would sink ~0.28 m into the tent until its ends met the
    slopes). Each step, every point of the ridge line under the plank stays outside it, within 1 mm.
    """
    v, t = ridge_mesh()
    w = tumble.World(gravity=(0, 0, -9.81))
    w.add_mesh(vertices=v, triangles=t, restitution=0.0, friction=0.5)
    h = np.array([0.3, 0.05, 0.02])
    pos = (0.0, 0.0, 0.2 + 0.02 + 0.05)
    if shape == "box":
        w.add_box(position=pos, half_extents=h, restitution=0.0)
    else:
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * h
        w.add_convex(points=corners, position=pos, restitution=0.0)
    ridge = np.stack([np.zeros(11), np.linspace(-1, 1, 11) * h[1], np.full(11, 0.2)], axis=1)
    worst = -np.inf
    for _ in range(round(1.0 / w.dt)):
        w.step()
        q = w.body_orientation[1]
        from tumble.npmath import quat_to_matrix

        R = quat_to_matrix(q[None])[0]
        local = (ridge - w.body_position[1]) @ R  # R^T (p - x)
        inside = np.min(h - np.abs(local), axis=1)  # > 0: the point is inside the plank
        worst = max(worst, inside.max())
    assert worst < 1e-3
    assert w.body_position[1, 2] > 0.2 - 0.05  # still on the ridge or its slopes, not through the tent


def test_a_sphere_in_a_v_groove_rests_on_both_faces():
    """A sphere dropped into a 90 degree V-groove rests touching both faces at once, at the analytic height.

    Faces at 45 degrees either side of the groove line: the centre rests at z = r / sin 45 = r sqrt 2
    above the groove, with the two contacts each carrying m g / sqrt 2 along its face normal.
    """
    v, t = ridge_mesh()
    v[:, 2] = 0.2 - v[:, 2]  # the tent mirrored in z: a groove along y at z = 0, the mirror winds it upwards
    w = tumble.World(gravity=(0, 0, -9.81))
    w.add_mesh(vertices=v, triangles=t, restitution=0.0, friction=0.5)
    r = 0.05
    w.add_sphere(position=(0.01, 0.0, 0.2), radius=r, restitution=0.0, mass=1.0)
    w.run(1.5)
    assert w.body_position[1, 0] == pytest.approx(0.0, abs=1e-4)
    assert w.body_position[1, 2] == pytest.approx(r * np.sqrt(2), abs=2e-4)
    assert np.linalg.norm(w.body_velocity[1]) < 1e-3
    n = w.contact_normal
    assert len(n) == 2 and n[0] @ n[1] == pytest.approx(0.0, abs=1e-6)  # both faces, at right angles
