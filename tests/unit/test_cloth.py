"""Unit tests of the cloth package: grid builder, pins, validation, wind, stages on plain inputs."""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

import tumble
from tumble.cloth import Wind, collide, grid, springs
from tumble.cloth.wind import accumulate_air_forces
from tumble.state import float_t, vec3

FACING_X = (0.5, 0.5, 0.5, 0.5)  # i -> +y, j -> +z, normal +x


def make_world(**kwargs):
    return tumble.World(dt=1.0 / 240.0, substeps=4, **kwargs)


# ---------------------------------------------------------------- grid builder


def test_grid_positions_row_major_in_xy_plane():
    """Particle j * nx + i sits at grid point (i, j) of an xy-plane grid centred on the position."""
    x = grid.grid_positions((2.0, 1.0), (5, 3), (1.0, 2.0, 3.0), np.array([0.0, 0.0, 0.0, 1.0]))
    assert x.shape == (15, 3)
    assert x[0] == pytest.approx([0.0, 1.5, 3.0])
    assert x[1] == pytest.approx([0.5, 1.5, 3.0])  # i fastest, along x
    assert x[5] == pytest.approx([0.0, 2.0, 3.0])  # next row, along y
    assert x.mean(axis=0) == pytest.approx([1.0, 2.0, 3.0])


def test_grid_orientation_rotates_the_grid():
    """The quaternion (0.5, 0.5, 0.5, 0.5) maps grid i to +y, j to +z, the normal to +x."""
    x = grid.grid_positions((1.0, 1.0), (2, 2), (0, 0, 0), np.array(FACING_X))
    assert x[1] - x[0] == pytest.approx([0.0, 1.0, 0.0])
    assert x[2] - x[0] == pytest.approx([0.0, 0.0, 1.0])


@pytest.mark.parametrize("nx, ny", [(2, 2), (4, 3), (7, 5)])
def test_spring_and_triangle_counts(nx, ny):
    """Structural, shear and bend springs and triangles number as the grid dictates."""
    s = grid.grid_springs(nx, ny)
    assert len(s["structural"]) == (nx - 1) * ny + nx * (ny - 1)
    assert len(s["shear"]) == 2 * (nx - 1) * (ny - 1)
    assert len(s["bend"]) == max(nx - 2, 0) * ny + nx * max(ny - 2, 0)
    assert len(grid.grid_triangles(nx, ny)) == 2 * (nx - 1) * (ny - 1)


def test_triangles_face_plus_z():
    """Every triangle of an unrotated cloth is counter-clockwise seen from +z."""
    x = grid.grid_positions((1.0, 1.0), (6, 4), (0, 0, 0), np.array([0.0, 0.0, 0.0, 1.0]))
    t = grid.grid_triangles(6, 4)
    normal = np.cross(x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]])
    assert np.all(normal[:, 2] > 0.0)
    assert t.dtype == np.int32


def test_pin_names_and_lists():
    """Named pins pick the right grid points; explicit [i, j] lists are honoured."""
    nx, ny = 4, 3
    assert list(grid.pin_indices("corners", nx, ny)) == [0, 3, 8, 11]
    assert list(grid.pin_indices("top-corners", nx, ny)) == [8, 11]
    assert list(grid.pin_indices("top-edge", nx, ny)) == [8, 9, 10, 11]
    assert list(grid.pin_indices([[1, 0], [2, 2]], nx, ny)) == [1, 10]
    assert len(grid.pin_indices(None, nx, ny)) == 0


@pytest.mark.parametrize("pins", ["sides", [[4, 0]], [[0, -1]], [[1]], [[0.5, 1]]])
def test_bad_pins_raise(pins):
    """Unknown names and grid points outside the cloth raise ValueError."""
    with pytest.raises(ValueError):
        grid.pin_indices(pins, 4, 3)


def test_tethers_tie_free_particles_to_nearest_pins():
    """Tethers join every free particle to its nearest pins with limit (1 + s) x rest distance."""
    rest = grid.grid_positions((1.0, 1.0), (3, 3), (0, 0, 0), np.array([0.0, 0.0, 0.0, 1.0]))
    pinned = np.array([6, 8])
    particle, pin, limit = grid.tethers(rest, pinned, 0.1)
    assert set(particle) == set(range(9)) - {6, 8}
    assert len(particle) == 2 * 7
    k = np.nonzero((particle == 0) & (pin == 6))[0][0]
    assert limit[k] == pytest.approx(1.1 * 1.0)


# ---------------------------------------------------------------- add_cloth


def test_add_cloth_layout_and_mass():
    """add_cloth fills the particle arrays in creation order with the given total mass."""
    world = make_world()
    first = world.add_cloth(size=(1.0, 1.0), resolution=(4, 3), mass=0.6)
    second = world.add_cloth(size=(2.0, 1.0), resolution=(3, 3), areal_density=0.5, position=(0, 0, 1))
    cloth = world.cloth
    assert (first, second) == (0, 1)
    assert cloth.particle_count == 12 + 9
    assert cloth.triangle_count == 2 * 3 * 2 + 2 * 2 * 2
    assert cloth.particle_mass[:12].sum() == pytest.approx(0.6)
    assert cloth.particle_mass[12:].sum() == pytest.approx(0.5 * 2.0)
    # the second cloth's triangles index its own particles
    assert cloth.triangles[12:].min() >= 12
    assert cloth.triangles.dtype == np.int32
    assert cloth.particle_position[12:, 2] == pytest.approx(np.ones(9))


def test_pinned_particles_have_zero_inverse_mass():
    """Pins are particles of inverse mass 0."""
    world = make_world()
    world.add_cloth(resolution=(3, 3), pins="top-corners")
    inv = world.cloth.particle_inv_mass
    assert list(np.nonzero(inv == 0.0)[0]) == [6, 8]


@pytest.mark.parametrize(
    "kwargs",
    [
        {"size": (-1.0, 1.0)},
        {"size": (1.0,)},
        {"resolution": (1, 1)},
        {"resolution": (2.5, 3)},
        {"mass": 1.0, "areal_density": 1.0},
        {"mass": -1.0},
        {"stiffness": {"stretch": 1.0}},
        {"stiffness": -1.0},
        {"damping": float("nan")},
        {"thickness": 0.0},
        {"friction": -0.1},
        {"max_stretch": -0.1},
        {"orientation": (0, 0, 0, 0)},
        {"position": (0, 0)},
        {"pins": "everywhere"},
    ],
)
def test_bad_cloth_arguments_raise_value_error(kwargs):
    """Bad add_cloth arguments raise ValueError naming the problem, before any kernel runs."""
    world = make_world()
    with pytest.raises(ValueError):
        world.add_cloth(**kwargs)


def test_bad_wind_arguments_raise_value_error():
    """Bad wind arguments raise ValueError."""
    world = make_world()
    with pytest.raises(ValueError):
        world.set_wind(scale=0.0)
    with pytest.raises(ValueError):
        world.set_wind(velocity=(1.0, 2.0))
    with pytest.raises(ValueError):
        world.set_wind(turbulence=-1.0)


def test_views_are_read_only():
    """Particle views cannot be written by users."""
    world = make_world()
    world.add_cloth(resolution=(3, 3))
    with pytest.raises(ValueError):
        world.cloth.particle_position[0, 0] = 1.0
    with pytest.raises(ValueError):
        world.cloth.triangles[0, 0] = 1


# ---------------------------------------------------------------- stages


def test_stable_substep_single_spring():
    """Undamped: h = 0.9 * 2 / sqrt(2 K w), the Gershgorin bound of symplectic Euler."""
    h = springs.stable_substep(np.array([10.0]), np.array([0.0]), np.array([100.0]))
    assert h == pytest.approx(0.9 * 2.0 / math.sqrt(2.0 * 10.0 * 100.0))
    assert springs.stable_substep(np.zeros(3), np.zeros(3), np.ones(3)) == math.inf


def test_cloth_substeps_follow_stiffness():
    """Stiffer springs on the same particles need more cloth substeps per world step."""
    soft, stiff = make_world(), make_world()
    soft.add_cloth(resolution=(16, 16), stiffness=1.0)
    stiff.add_cloth(resolution=(16, 16), stiffness=1000.0)
    assert soft.cloth.substeps_for(soft.dt) == 1
    assert stiff.cloth.substeps_for(stiff.dt) > 4


def test_spring_force_on_plain_arrays():
    """One stretched spring pulls its ends together with ks (|d| - l0)."""
    x = wp.array(np.array([[0.0, 0.0, 0.0], [1.5, 0.0, 0.0]]), dtype=vec3)
    v = wp.zeros(2, dtype=vec3)
    f = wp.zeros(2, dtype=vec3)
    ids = wp.array(np.array([[0, 1]], dtype=np.int32), dtype=wp.int32)
    one = lambda value: wp.array(np.array([value]), dtype=float_t)  # noqa: E731
    springs.accumulate_spring_forces(x, v, ids, one(1.0), one(4.0), one(0.0), f)
    assert f.numpy() == pytest.approx(np.array([[2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]]))


def test_stretch_limit_on_plain_arrays():
    """A spring stretched to 2 l0 is brought back to at most (1 + s) l0, pinned end fixed."""
    x = wp.array(np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]]), dtype=vec3)
    inv_m = wp.array(np.array([0.0, 1.0]), dtype=float_t)
    ids = wp.array(np.array([[0, 1]], dtype=np.int32), dtype=wp.int32)
    limit = wp.array(np.array([1.1]), dtype=float_t)
    flag = wp.zeros(1, dtype=wp.int32)
    springs.limit_stretch(x, inv_m, ids, limit, flag)
    out = x.numpy()
    assert out[0] == pytest.approx([0.0, 0.0, 0.0])
    assert 1.0 < out[1, 0] <= 1.1


def test_tethers_on_plain_arrays():
    """A particle tethered to two pins ends within margin x limit of each; a released pin holds nothing."""
    x = wp.array(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, -3.0, 0.0], [9.0, 9.0, 9.0]]), dtype=vec3)
    inv_m = wp.array(np.array([0.0, 0.0, 1.0, 1.0]), dtype=float_t)
    # particle 2 has tethers to pins 0 and 1 (limit 1.2 each); particle 3 none
    first = wp.array(np.array([0, 0, 0, 2], dtype=np.int32), dtype=wp.int32)
    count = wp.array(np.array([0, 0, 2, 0], dtype=np.int32), dtype=wp.int32)
    pin = wp.array(np.array([0, 1], dtype=np.int32), dtype=wp.int32)
    limit = wp.array(np.array([1.2, 1.2]), dtype=float_t)
    tethers = springs.tether_arrays(first, count, pin, limit)
    for _ in range(20):  # alternating projections onto two balls converge into their overlap
        springs.limit_tethers(x, inv_m, tethers)
    out = x.numpy()
    assert np.linalg.norm(out[2] - out[0]) <= 0.99 * 1.2 + 1e-9
    assert np.linalg.norm(out[2] - out[1]) <= 0.99 * 1.2 + 1e-9
    assert out[0] == pytest.approx([0.0, 0.0, 0.0]) and out[1] == pytest.approx([1.0, 0.0, 0.0])
    assert out[3] == pytest.approx([9.0, 9.0, 9.0])
    # pin 1 released (inverse mass > 0): its tether no longer acts
    x = wp.array(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [9.0, 9.0, 9.0]]), dtype=vec3)
    released = wp.array(np.array([0.0, 1.0, 1.0, 1.0]), dtype=float_t)
    springs.limit_tethers(x, released, tethers)
    assert x.numpy()[2] == pytest.approx([0.0, -1.0, 0.0])


def test_air_force_face_on_and_edge_on():
    """Drag on a face-on triangle is 1/2 rho Cd A u^2 along the normal; edge-on it is zero."""
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    tris = wp.array(np.array([[0, 1, 2]], dtype=np.int32), dtype=wp.int32)
    x = wp.array(pts, dtype=vec3)
    v = wp.zeros(3, dtype=vec3)
    for wind, expected in (((0.0, 0.0, 2.0), 0.5 * 1.2 * 1.0 * 0.5 * 4.0), ((2.0, 1.0, 0.0), 0.0)):
        u = wp.array(np.tile(wind, (3, 1)), dtype=vec3)
        f = wp.zeros(3, dtype=vec3)
        accumulate_air_forces(x, v, u, tris, 1.0, 0.0, 1.2, f)
        total = f.numpy().sum(axis=0)
        assert total == pytest.approx([0.0, 0.0, expected], abs=1e-12)


def test_wind_field_seeded_smooth_and_time_varying():
    """Turbulence is reproducible per seed, smooth in space, varies in time, with RMS = strength."""
    wind = Wind(velocity=(1.0, 0.0, 0.0), turbulence=2.0, scale=0.5, seed=4, modes=64)
    rng = np.random.default_rng(0)
    pts = rng.uniform(-20, 20, size=(20000, 3))
    u = wind.sample(pts, 0.0)
    assert np.array_equal(
        u, Wind(velocity=(1.0, 0.0, 0.0), turbulence=2.0, scale=0.5, seed=4, modes=64).sample(pts, 0.0)
    )
    assert not np.allclose(
        u, Wind(velocity=(1.0, 0.0, 0.0), turbulence=2.0, scale=0.5, seed=5, modes=64).sample(pts, 0.0)
    )
    # mean = U, RMS per component = turbulence (to sampling error)
    assert u.mean(axis=0) == pytest.approx([1.0, 0.0, 0.0], abs=0.1)
    assert (u - [1.0, 0.0, 0.0]).std(axis=0) == pytest.approx([2.0, 2.0, 2.0], rel=0.1)
    # smooth: Lipschitz, |u(x + d) - u(x)| <= sum_k |a_k| |kappa_k| |d|; 1 s later the field has moved on
    wave, amplitude, _, _ = wind.mode_arrays()
    lipschitz = float(np.sum(np.linalg.norm(amplitude, axis=1) * np.linalg.norm(wave, axis=1)))
    step = np.full(3, 1e-3)
    near = wind.sample(pts[:100] + step, 0.0)
    assert np.linalg.norm(near - u[:100], axis=1).max() <= lipschitz * np.linalg.norm(step)
    later = wind.sample(pts[:100], 1.0)
    assert np.abs(later - u[:100]).max() > 0.5


def test_body_collision_pushes_particle_out_of_static_shapes():
    """Particles inside a plane, sphere or box end up at the thickness outside its surface."""
    world = make_world(gravity=(0, 0, 0))
    world.add_plane(offset=-1.0)
    world.add_sphere(position=(5.0, 0.0, 0.0), radius=0.5, static=True)
    world.add_box(
        position=(-5.0, 0.0, 0.0),
        half_extents=(0.5, 0.5, 0.5),
        static=True,
        orientation=(0.0, 0.0, math.sin(0.3), math.cos(0.3)),
    )
    world.add_cloth(size=(0.01, 0.01), resolution=(3, 1), thickness=0.05, max_stretch=None, stiffness=0.0, damping=0.0)
    cloth = world.cloth
    cloth.set_state(position=np.array([[0.0, 0.0, -1.02], [5.1, 0.1, 0.0], [-5.0, 0.0, 0.4]]))
    world.step()
    x = cloth.particle_position
    assert x[0, 2] == pytest.approx(-1.0 + 0.05)
    assert np.linalg.norm(x[1] - [5.0, 0.0, 0.0]) == pytest.approx(0.5 + 0.05)
    assert x[2, 2] == pytest.approx(0.5 + 0.05)


def test_candidate_bodies_skip_far_spheres():
    """Only bodies whose bounds can reach the cloth's box this step are tested."""
    world = make_world()
    world.add_plane()
    near = world.add_sphere(position=(0.0, 0.0, 0.3), radius=0.1)
    world.add_sphere(position=(50.0, 0.0, 0.3), radius=0.1)
    got = collide.candidate_bodies(world.bodies, np.array([-0.5, -0.5, 0.0]), np.array([0.5, 0.5, 0.5]), 0.01, world.dt)
    assert list(got) == [0, near.index]


def test_self_collision_separates_two_cloths():
    """Particles of two cloths closer than the thickness are pushed apart to it."""
    world = make_world(gravity=(0, 0, 0))
    for z in (0.0, 0.02):
        world.add_cloth(size=(0.2, 0.2), resolution=(3, 3), position=(0, 0, z), thickness=0.05)
    world.step()
    x = world.cloth.particle_position
    gap = x[9:, 2] - x[:9, 2]
    assert gap.min() >= 0.05 * 0.99


def test_apply_force_lasts_one_step():
    """A force given with apply_force acts during the next step only: dv = F dt / m, then none."""
    world = make_world(gravity=(0, 0, 0))
    world.add_cloth(size=(0.1, 0.1), resolution=(2, 1), mass=2.0, stiffness=0.0, damping=0.0)
    world.cloth.apply_force(1, (4.0, 0.0, 0.0))
    world.step()
    v1 = world.cloth.particle_velocity[1, 0]
    world.step()
    assert v1 == pytest.approx(4.0 * world.dt / 1.0)
    assert world.cloth.particle_velocity[1, 0] == pytest.approx(v1)
    assert world.cloth.particle_velocity[0, 0] == 0.0


def test_moving_pin_reaches_target_in_one_step():
    """set_pin_target moves a pin to its target by the end of the next step, and pins free particles."""
    world = make_world(gravity=(0, 0, 0))
    world.add_cloth(size=(1.0, 1.0), resolution=(3, 3), pins="corners")
    cloth = world.cloth
    target = cloth.particle_position[0] + [0.0, 0.0, 0.1]
    cloth.set_pin_target(0, target)
    cloth.set_pin_target(4, cloth.particle_position[4])
    world.step()
    assert cloth.particle_position[0] == pytest.approx(target)
    assert cloth.particle_inv_mass[4] == 0.0
    cloth.unpin(4)
    assert cloth.particle_inv_mass[4] > 0.0


def test_energies_and_strain():
    """kinetic = sum 1/2 m v^2, potential = -sum m g . x, strain = |d| / l0 - 1."""
    world = make_world()
    world.add_cloth(size=(1.0, 1.0), resolution=(2, 1), mass=2.0, position=(0.0, 0.0, 3.0), max_stretch=None)
    cloth = world.cloth
    cloth.set_state(position=np.array([[0.0, 0.0, 3.0], [1.2, 0.0, 3.0]]), velocity=np.array([[0, 0, 0], [3, 4, 0]]))
    assert cloth.kinetic_energy() == pytest.approx(0.5 * 1.0 * 25.0)
    assert cloth.potential_energy() == pytest.approx(2.0 * 9.81 * 3.0)
    assert cloth.max_strain() == pytest.approx(0.2)
    assert world.kinetic_energy() == pytest.approx(12.5)


def test_diverging_cloth_raises_simulation_error():
    """Springs far too stiff for forced substeps blow up: a SimulationError names the particle."""
    world = make_world()
    world.add_cloth(resolution=(8, 8), stiffness=1.0e7, max_stretch=None, pins="top-edge")
    world.cloth.substeps = 1
    world.cloth.self_collision = False
    with pytest.raises(tumble.SimulationError, match="cloth 0 particle"):
        world.run(2.0)
