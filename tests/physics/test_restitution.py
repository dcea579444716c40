"""Restitution against classical collision results: chains, an elastic gas, energy per step, bounce apexes.

Every contact collides with its own impact speed in the substep it closes (solver/contacts.py,
`impacts`): a two-body collision whose impulse cannot add energy for e <= 1.
"""

from __future__ import annotations

import numpy as np
import pytest

import tumble
from tolerances import in_float32, ulps

G = 9.81


def total_energy(world):
    """Kinetic plus potential energy m g z [J] of every body."""
    g = -world.gravity[2]
    return world.kinetic_energy() + float(np.sum(world.body_mass * g * world.body_position[:, 2]))


def chain(count, *, from_end, v=1.0, gap=0.0):
    """A row of touching e = 1 frictionless balls (r 5 cm, 1 kg), the first or last moving at v into the rest."""
    world = tumble.World(gravity=(0, 0, 0))
    r = 0.05
    for i in range(count):
        velocity = (0.0, 0.0, 0.0)
        if i == 0 and not from_end:
            velocity = (v, 0.0, 0.0)
        if i == count - 1 and from_end:
            velocity = (-v, 0.0, 0.0)
        world.add_sphere(
            position=((2 * r + gap) * i, 0, 0), radius=r, mass=1.0, velocity=velocity, restitution=1.0, friction=0.0
        )
    return world


@pytest.mark.parametrize("from_end", [False, True], ids=["struck first", "struck last"])
@pytest.mark.parametrize("count", [2, 5, 8])
def test_newtons_cradle_passes_the_whole_velocity_along(count, from_end):
    """A row of touching elastic balls struck at one end: the far ball leaves at v, the rest stay (KE within 1 %)."""
    world = chain(count, from_end=from_end)
    e0 = world.kinetic_energy()
    world.run(0.5)
    v = world.body_velocity[:, 0]
    assert world.kinetic_energy() == pytest.approx(e0, rel=0.01)
    assert v.sum() == pytest.approx(1.0 if not from_end else -1.0, abs=1e-12)  # momentum
    # sequential two-body collisions: the ideal (0, ..., 0, v), to rounding
    ideal = np.zeros(count)
    ideal[-1 if not from_end else 0] = 1.0 if not from_end else -1.0
    np.testing.assert_allclose(v, ideal, atol=1e-9)


def test_spaced_chain_of_unequal_balls_keeps_energy():
    """A row of balls of different masses, 1 mm apart, hit at 3 m/s: momentum exact, KE within 1 %."""
    world = tumble.World(gravity=(0, 0, 0))
    masses = [1.0, 2.0, 0.5, 1.5, 1.0, 3.0]
    for i, m in enumerate(masses):
        world.add_sphere(
            position=(0.101 * i, 0, 0),
            radius=0.05,
            mass=m,
            velocity=(3.0 if i == 0 else 0.0, 0, 0),
            restitution=1.0,
            friction=0.0,
        )
    e0, p0 = world.kinetic_energy(), 3.0
    world.run(1.0)
    assert float(np.dot(world.body_mass, world.body_velocity[:, 0])) == pytest.approx(p0, abs=1e-12)
    assert world.kinetic_energy() == pytest.approx(e0, rel=0.01)


def gas(n, *, seed=1, gravity=(0, 0, 0)):
    """n^3 elastic frictionless balls (r 5 cm) with random velocities (2 m/s per axis) in a closed 1 m box."""
    world = tumble.World(gravity=gravity)
    for normal, offset in [
        ((0, 0, 1), 0),
        ((0, 0, -1), -1),
        ((1, 0, 0), 0),
        ((-1, 0, 0), -1),
        ((0, 1, 0), 0),
        ((0, -1, 0), -1),
    ]:
        world.add_plane(normal=normal, offset=offset, restitution=1.0, friction=0.0)
    rng = np.random.default_rng(seed)
    grid = np.linspace(0.15, 0.85, n)
    for x in grid:
        for y in grid:
            for z in grid:
                world.add_sphere(
                    position=(x, y, z),
                    radius=0.05,
                    mass=rng.uniform(0.5, 2.0),
                    velocity=tuple(rng.normal(size=3) * 2.0),
                    restitution=1.0,
                    friction=0.0,
                )
    return world


def energy_per_step(world, steps):
    e = [total_energy(world)]
    for _ in range(steps):
        world.step()
        e.append(total_energy(world))
    return np.array(e)


def test_elastic_gas_keeps_its_energy():
    """27 elastic balls in a closed box for 10 s at the default settings: KE within 1 %, no step gains energy."""
    world = gas(3)
    e = energy_per_step(world, 2400)
    assert abs(e[-1] / e[0] - 1.0) < 0.01
    # float32 (no gravity: the energy is kinetic): each substep rounds a colliding ball's velocity by up to an
    # ulp, its energy by 2 ulps: 2 ulps of the total per substep (measured: 3.1e-5 J, 2.1e-7 of it, in a step,
    # against 2.8e-4 J allowed)
    assert np.diff(e).max() <= in_float32(1e-12 * e[0], ulps(e[0], 2 * world.substeps))


@pytest.mark.slow
def test_dense_elastic_gas_keeps_its_energy():
    """125 elastic balls in a closed box for 10 s at the default settings: KE within 1 %."""
    world = gas(5)
    e = energy_per_step(world, 2400)
    assert abs(e[-1] / e[0] - 1.0) < 0.01
    # float32 (no gravity: the energy is kinetic): each substep rounds a colliding ball's velocity by up to an
    # ulp, its energy by 2 ulps: 2 ulps of the total per substep (measured: 3.1e-5 J, 2.1e-7 of it, in a step,
    # against 2.8e-4 J allowed)
    assert np.diff(e).max() <= in_float32(1e-12 * e[0], ulps(e[0], 2 * world.substeps))


def falling_balls(e, mu):
    world = tumble.World()
    world.add_plane(restitution=e, friction=mu)
    rng = np.random.default_rng(3)
    for i in range(20):
        world.add_sphere(
            position=(rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), 0.2 + 0.15 * i),
            radius=0.05,
            mass=rng.uniform(0.5, 2.0),
            velocity=tuple(rng.normal(size=3)),
            restitution=e,
            friction=mu,
        )
    return world


def falling_boxes(e, mu):
    world = tumble.World()
    world.add_plane(restitution=e, friction=mu)
    rng = np.random.default_rng(4)
    for i in range(8):
        q = rng.normal(size=4)
        world.add_box(
            position=(rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), 0.3 + 0.3 * i),
            half_extents=(0.1, 0.07, 0.04),
            mass=1.0,
            orientation=tuple(q / np.linalg.norm(q)),
            angular_velocity=tuple(rng.normal(size=3)),
            restitution=e,
            friction=mu,
        )
    return world


def gas_with_gravity(e, mu):
    world = gas(3, gravity=(0, 0, -G))
    world.set_material(restitution=e, friction=mu)
    return world


@pytest.mark.parametrize("scene", [falling_balls, falling_boxes, gas_with_gravity])
@pytest.mark.parametrize("e, mu", [(1.0, 0.0), (0.7, 0.5), (1.0, 0.5), (0.3, 0.0)])
def test_no_step_raises_total_energy(scene, e, mu):
    """Kinetic plus potential energy never grows from one step to the next for e <= 1 (balls, boxes, a gas)."""
    world = scene(e, mu)
    energy = energy_per_step(world, 480)
    # rounding of the sums only (the boxes' bounded rotation error is ~1e-9 of E at these spins)
    assert np.diff(energy).max() <= 1e-7 * abs(energy[0])


@pytest.mark.parametrize("seed", [2, 3])
def test_a_settling_frictionless_gas_gains_no_energy_in_any_step(seed):
    """More draws of the gas with gravity at e = 0.3: balls settling on the floor slide past one another,
    and their contacts must not push them apart again (seed 3 gained 6.4e-4 J in one step when the
    collision pass took two spheres' exact gap: `contacts._gap`)."""
    world = gas(3, seed=seed, gravity=(0, 0, -G))
    world.set_material(restitution=0.3, friction=0.0)
    energy = energy_per_step(world, 480)
    assert np.diff(energy).max() <= 1e-7 * abs(energy[0])


def test_a_corner_that_strikes_in_the_first_substep_adds_no_energy():
    """A box spinning at 55 rad/s whose corner strikes an elastic plane within the first substep of a
    step (a contact the last step could not foresee) bounces without gaining energy.

    Gravity's kick and the position update of a substep keep energy only if no impulse falls between
    them; the first substep's collisions are therefore taken before its kick, as every later
    substep's are. (Taken after it, this bounce gained 3.7 mJ, 3e-4 of the box's energy.)
    """
    world = tumble.World()
    world.add_plane(restitution=1.0, friction=0.0)
    q = np.array([0.521741, 0.534781, 0.442317, -0.496136])
    box = world.add_box(
        position=(0.170769, -0.258519, 0.107717),
        half_extents=(0.1, 0.07, 0.04),
        orientation=q / np.linalg.norm(q),
        velocity=(0.748844, -0.404525, 0.753475),
        angular_velocity=(20.937560, 46.646946, -24.592815),
        mass=1.0,
        restitution=1.0,
        friction=0.0,
    )
    e0 = total_energy(world)
    world.step()
    assert world.body_state(box).velocity[2] > 1.5  # the corner struck: the centre rises at 2.2 m/s, not 0.75
    energy = np.concatenate([[e0], energy_per_step(world, 23)])
    # as test_no_step_raises_total_energy: rounding, and the spinning box's bounded rotation error
    assert np.diff(energy).max() <= 1e-7 * abs(energy[0])


@pytest.mark.parametrize("substeps, tolerance", [(8, 0.01), (4, 0.02), (16, 0.01)])
@pytest.mark.parametrize("e", [0.5, 0.8])
def test_bounce_apexes_are_e_squared_times_the_last(substeps, tolerance, e):
    """A ball dropped from 1 m rises to e^(2k) m after bounce k, within 1 % (2 % at 4 substeps), k = 1, 2, 3."""
    r = 0.1
    world = tumble.World(substeps=substeps)
    world.add_plane(restitution=e)
    world.add_sphere(position=(0, 0, 1.0 + r), radius=r, mass=1.0, restitution=e)
    z = []
    world.run(3.0, callback=lambda w: z.append(w.body_position[1, 2] - r))
    z = np.array(z)
    apex = [z[i] for i in range(1, len(z) - 1) if z[i - 1] < z[i] >= z[i + 1] and z[i] > 1e-3]
    assert len(apex) >= 3
    for k, measured in enumerate(apex[:3], start=1):
        assert measured == pytest.approx(e ** (2 * k), rel=tolerance), k
