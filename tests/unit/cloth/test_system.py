"""cloth/system.py: add_cloth (layout, mass, pins, bad arguments), read-only views, forces, pins, energies."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import tumble
from tolerances import is_float32, resolution
from tumble.precision import kernels


def make_world(**kwargs):
    return tumble.World(dt=1.0 / 240.0, substeps=4, **kwargs)


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


def test_views_are_read_only():
    """Particle views cannot be written by users."""
    world = make_world()
    world.add_cloth(resolution=(3, 3))
    with pytest.raises(ValueError):
        world.cloth.particle_position[0, 0] = 1.0
    with pytest.raises(ValueError):
        world.cloth.triangles[0, 0] = 1


def test_cloth_substeps_follow_stiffness():
    """Stiffer springs on the same particles need more cloth substeps per world step."""
    soft, stiff = make_world(), make_world()
    soft.add_cloth(resolution=(16, 16), stiffness=1.0)
    stiff.add_cloth(resolution=(16, 16), stiffness=1000.0)
    assert soft.cloth.substeps_for(soft.dt) == 1
    assert stiff.cloth.substeps_for(stiff.dt) > 4


@pytest.mark.parametrize("springs", [{"stiffness": "huge"}, {"damping": "huge"}, {"stiffness": 1e12}])
def test_springs_too_stiff_for_any_substep_are_refused_when_the_step_starts(springs):
    """Springs needing more than limits.MAX_CLOTH_SUBSTEPS cloth substeps in a step are a LimitError
    naming the count and the limit (stiffness 1e300 asked for 1e150 substeps: the step never ended).
    "huge" is 1e300 in float64 and 1e37 in float32, the largest a world of each precision holds."""
    huge = 1e37 if is_float32() else 1e300
    springs = {key: huge if value == "huge" else value for key, value in springs.items()}
    world = make_world()
    world.add_cloth(resolution=(8, 8), **springs)
    with pytest.raises(tumble.limits.LimitError, match=r"^cloth stiffness and damping: .* the limit is 10,000"):
        world.step()
    world.cloth.substeps = 10**9
    with pytest.raises(tumble.limits.LimitError, match=r"^cloth substeps: 1,000,000,000 is too large"):
        world.step()
    world.cloth.substeps = 4
    world.step()
    assert world.step_count == 1


@pytest.mark.parametrize(
    "keywords", [{"size": (1e-300, 1e-300)}, {"mass": 1e-310}, {"areal_density": 1e300, "size": (1e10, 1e10)}]
)
def test_a_particle_mass_that_vanishes_or_overflows_is_refused(keywords):
    """A cloth whose particles would weigh 0 or inf kg in float64 is a ValueError naming the mass;
    before, a tiny size gave inverse masses of inf with a NumPy divide-by-zero warning."""
    world = make_world()
    with pytest.raises(ValueError, match=r"^cloth mass: .* kg each; the mass or areal_density and size"):
        world.add_cloth(resolution=(4, 4), **keywords)
    assert not world.has_cloth


def test_a_spring_constant_a_float32_world_cannot_hold_is_refused_by_name():
    """Stiffness or damping beyond float32's 3.4e38 is a ValueError naming the spring array and the
    precision, as for bodies; before, NumPy warned of an overflow in the cast and the springs held inf."""
    world = tumble.World(precision="float32")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for springs in ({"stiffness": 1e39}, {"damping": {"bend": 1e300}}):
            with pytest.raises(ValueError, match=r"^spring_(stiffness|damping): .* does not fit a float32 world"):
                world.add_cloth(resolution=(4, 4), **springs)
            assert not world.has_cloth
    world.add_cloth(resolution=(4, 4), stiffness=1e30)  # large, but held
    assert world.has_cloth


def test_apply_force_lasts_one_step():
    """A force given with apply_force acts during the next step only: dv = F dt / m, then none."""
    world = make_world(gravity=(0, 0, 0))
    world.add_cloth(size=(0.1, 0.1), resolution=(2, 1), mass=2.0, stiffness=0.0, damping=0.0)
    world.cloth.apply_force(1, (4.0, 0.0, 0.0))
    world.step()
    v1 = world.cloth.particle_velocity[1, 0]
    world.step()
    # a velocity is (x - x_prev) / h: a few ulps of the positions (0.05 m), divided by the substep
    h = world.dt / (world.substeps * world.cloth.substeps_for(world.dt))
    rounding = resolution(1e-12, np.abs(world.cloth.particle_position).max() / h, 4)
    assert v1 == pytest.approx(4.0 * world.dt / 1.0, rel=1e-6, abs=rounding)
    assert world.cloth.particle_velocity[1, 0] == pytest.approx(v1, rel=1e-6, abs=rounding)
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


@pytest.mark.parametrize("body_pin", [False, True])
def test_diverging_cloth_raises_simulation_error(body_pin):
    """Springs far too stiff for forced substeps blow up: a SimulationError names the particle. With a
    body pinned to the cloth the remedy adds spreading its load over more pins (a jointed body light at
    its pins can still diverge whatever the substeps: docs/design.md, "Cloth with bodies")."""
    world = make_world()
    world.add_cloth(resolution=(8, 8), stiffness=1.0e7, max_stretch=None, pins="top-edge")
    world.cloth.substeps = 1
    world.cloth.self_collision = False
    if body_pin:
        box = world.add_box(position=(0.0, 0.0, -0.1), half_extents=(0.05, 0.05, 0.05), mass=1.0)
        world.pin_cloth_to_body([0], box)
    with pytest.raises(tumble.SimulationError, match="cloth 0 particle") as info:
        world.run(2.0)
    message = str(info.value)
    assert ("pinned" in message) == body_pin
    assert not body_pin or "spread the load of bodies pinned to it over more pins" in message


def test_cloth_stages_run_without_a_world():
    """The cloth keeps no reference to its world: driven through its stages by hand, it moves as in World.step."""
    kwargs = {"size": (1.0, 1.0), "resolution": (6, 6), "position": (0.0, 0.0, 1.0), "pins": "top-edge"}
    world = make_world()
    world.add_cloth(**kwargs)
    assert not any(isinstance(v, tumble.World) for v in vars(world.cloth).values())
    free = kernels(world.precision).cloth.ClothSystem("cpu", gravity=world.gravity)  # the world's precision
    free.add_cloth(**kwargs)
    bodies = make_world().bodies  # an empty world's body arrays
    stages = {"bodies": bodies, "hulls": world.hulls.struct(), "meshes": world.meshes.struct()}
    h = world.dt / world.substeps
    for step in range(10):
        free.begin_step(h, world.substeps, bodies=bodies, gravity=world.gravity, time=world.time, step=step)
        for _ in range(world.substeps):
            free.substep(h, **stages)
        free.end_step(**stages)
        world.step()
    assert np.array_equal(free.particle_position, world.cloth.particle_position)
    assert free.particle_position[:, 2].min() < 1.0 - 1e-3  # it fell
