"""World API: adding bodies, views, bad input, growth, state validation."""

from __future__ import annotations

import time

import numpy as np
import pytest

import tumble
from tumble.shapes import ShapeType


def test_bodies_get_ids_and_views_in_creation_order():
    """add_* return ids in creation order; views show shapes, sizes and masses."""
    w = tumble.World()
    p = w.add_plane(normal=(0, 0, 2), offset=0.5)
    s = w.add_sphere(position=(0, 0, 1), radius=0.1, density=1000.0)
    b = w.add_box(position=(1, 0, 1), half_extents=(0.1, 0.2, 0.3), mass=2.0)
    f = w.add_body("sphere", position=(2, 0, 1), radius=0.2, mass=1.0)
    assert [p.index, s.index, b.index, f.index] == [0, 1, 2, 3]
    np.testing.assert_array_equal(w.body_shape, [ShapeType.PLANE, ShapeType.SPHERE, ShapeType.BOX, ShapeType.SPHERE])
    np.testing.assert_allclose(w.body_plane_normal[0], [0, 0, 1])
    np.testing.assert_allclose(w.body_position[0], [0, 0, 0.5])
    assert w.body_mass[1] == pytest.approx(1000.0 * 4 / 3 * np.pi * 0.1**3)
    assert w.body_mass[0] == 0.0 and w.body_inv_mass[0] == 0.0
    np.testing.assert_allclose(w.body_half_extents[2], [0.1, 0.2, 0.3])


def test_views_are_read_only():
    """Writing to a state view raises instead of corrupting the engine's arrays."""
    w = tumble.World()
    w.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    with pytest.raises(ValueError):
        w.body_position[0, 2] = 5.0


def test_static_bodies_do_not_move():
    """static=True gives inverse mass 0: gravity and contacts leave the body where it is."""
    w = tumble.World()
    w.add_box(position=(0, 0, 0), half_extents=(1, 1, 0.1), static=True)
    w.add_sphere(position=(0, 0, 0.5), radius=0.1, mass=1.0)
    w.run(1.0)
    np.testing.assert_array_equal(w.body_position[0], [0, 0, 0])
    assert w.body_position[1, 2] == pytest.approx(0.2, abs=1e-3)


def test_arrays_grow_past_their_capacity():
    """Adding many bodies one by one keeps earlier ones intact."""
    w = tumble.World(gravity=(0, 0, 0))
    for i in range(100):
        w.add_sphere(position=(i, 0, 0), radius=0.1, mass=1.0 + i)
    assert w.body_count == 100
    np.testing.assert_allclose(w.body_position[:, 0], np.arange(100))
    np.testing.assert_allclose(w.body_mass, 1.0 + np.arange(100))
    w.step()


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda w: w.add_sphere(position=(0, 0, 0), radius=-1.0), "radius must be a positive number"),
        (lambda w: w.add_sphere(position=(0, 0, 0), radius=0.0), "radius"),
        (lambda w: w.add_sphere(position=(0, 0, 0), radius=0.1, mass=-2.0), "mass must be a positive number"),
        (lambda w: w.add_sphere(position=(0, 0, 0), radius=0.1, mass=1, density=1), "mass or density"),
        (lambda w: w.add_sphere(position=(0, float("nan"), 0), radius=0.1), "position must be finite"),
        (lambda w: w.add_sphere(position=(0, 0), radius=0.1), "position must have 3 components"),
        (lambda w: w.add_sphere(position=(0, 0, 0), radius=0.1, restitution=1.5), "restitution must be in"),
        (lambda w: w.add_sphere(position=(0, 0, 0), radius=0.1, friction=-1), "friction"),
        (lambda w: w.add_box(position=(0, 0, 0), half_extents=(1, 0, 1)), "half_extents must all be > 0"),
        (
            lambda w: w.add_box(position=(0, 0, 0), half_extents=(1, 1, 1), orientation=(0, 0, 0, 0)),
            "non-zero quaternion",
        ),
        (lambda w: w.add_plane(normal=(0, 0, 0)), "normal must not be zero"),
        (lambda w: w.add_plane(offset=float("inf")), "offset must be finite"),
        (lambda w: w.add_body("cylinder", position=(0, 0, 0)), "unknown shape 'cylinder'"),
    ],
)
def test_bad_input_is_named(call, message):
    """Each bad argument raises a ValueError that names it, and nothing is added."""
    w = tumble.World()
    with pytest.raises(ValueError, match=message):
        call(w)
    assert w.body_count == 0


@pytest.mark.parametrize("kwargs", [dict(dt=0), dict(dt=float("nan")), dict(substeps=0), dict(gravity=(0, 0))])
def test_bad_world_settings(kwargs):
    """World settings are checked when the world is made."""
    with pytest.raises(ValueError):
        tumble.World(**kwargs)


@pytest.mark.parametrize("count", [2, 40])  # (under and over VALIDATE_SUM_BODIES: two ways of checking)
@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_nan_in_state_is_reported_with_the_body(count, value):
    """A NaN or an infinity that reaches the state stops the step with a SimulationError naming the body."""
    w = tumble.World()
    w.add_spheres(position=[(k, 0, 1) for k in range(count)], radius=0.1, mass=1.0)
    w.step()
    w.bodies.write("body_velocity", count - 1, [0, value, 0])
    with pytest.raises(tumble.SimulationError, match=f"body_velocity of body {count - 1} is not finite"):
        w.step()


def test_apply_force_acts_for_one_step():
    """apply_force accelerates a body by F/m for exactly one step."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_sphere(position=(0, 0, 0), radius=0.1, mass=2.0)
    w.apply_force(0, (4.0, 0, 0))
    w.step()
    assert w.body_velocity[0, 0] == pytest.approx(2.0 * w.dt)
    w.step()
    assert w.body_velocity[0, 0] == pytest.approx(2.0 * w.dt)


def test_set_material_changes_every_body():
    """set_material updates restitution and friction of all bodies at once."""
    w = tumble.World()
    w.add_plane()
    w.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    w.set_material(restitution=0.9, friction=0.1)
    np.testing.assert_allclose(w.body_restitution, 0.9)
    np.testing.assert_allclose(w.body_friction, 0.1)
    with pytest.raises(ValueError):
        w.set_material(restitution=2.0)


def test_profile_times_every_stage():
    """world.profile sums seconds per stage: each step adds to it, and the stages add up to no more than the run took."""
    w = tumble.World()
    w.add_plane()
    w.add_sphere(position=(0, 0, 0.1), radius=0.1, mass=1.0)
    w.run(0.1)  # the first steps also record the solver's graph (timed inside "solver")
    assert {"validate", "broad_phase", "narrow_phase", "solver", "integrate"} <= set(w.profile)
    before = dict(w.profile)
    start = time.perf_counter()
    w.run(0.1)
    wall = time.perf_counter() - start
    added = {stage: w.profile[stage] - before.get(stage, 0.0) for stage in w.profile}
    for stage in ("validate", "broad_phase", "narrow_phase", "solver"):  # run on every step
        assert added[stage] > 0.0, stage
    assert sum(added.values()) <= wall  # seconds, each counted once


@pytest.mark.parametrize("shape", ["sphere", "box"])
def test_bulk_add_matches_one_by_one(shape):
    """add_spheres / add_boxes give the same body arrays as adding the bodies one at a time."""
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, (20, 3))
    size = dict(radius=rng.uniform(0.05, 0.1, 20)) if shape == "sphere" else dict(half_extents=(0.1, 0.2, 0.05))
    q = rng.normal(size=(20, 4))
    one, bulk = tumble.World(), tumble.World()
    for i in range(20):
        kw = dict(radius=size["radius"][i]) if shape == "sphere" else size
        one.add_body(shape, position=x[i], density=700.0, orientation=q[i], restitution=0.3, **kw)
    adder = bulk.add_spheres if shape == "sphere" else bulk.add_boxes
    ids = adder(position=x, density=700.0, orientation=q, restitution=0.3, **size)
    assert [b.index for b in ids] == list(range(20))
    for name in one.bodies.fields:
        np.testing.assert_array_equal(one.bodies.numpy(name), bulk.bodies.numpy(name), err_msg=name)


def test_bulk_add_names_bad_rows():
    """A wrong shape or a bad value in one row is reported with the argument's name."""
    w = tumble.World()
    with pytest.raises(ValueError, match="radius must be a positive number"):
        w.add_spheres(position=np.zeros((3, 3)), radius=[0.1, -0.1, 0.1])
    with pytest.raises(ValueError, match=r"velocity must have 3 components \(or shape \(3, 3\)\)"):
        w.add_spheres(position=np.zeros((3, 3)), radius=0.1, velocity=np.zeros((2, 3)))
    assert w.body_count == 0


def test_unknown_or_missing_device_is_named():
    """A device Warp cannot use is a ValueError naming it, not a crash inside Warp."""
    import warp as wp

    with pytest.raises(ValueError, match="device 'gpu7'"):
        tumble.World(device="gpu7")
    if not wp.is_cuda_available():
        with pytest.raises(ValueError, match="no CUDA device"):
            tumble.World(device="cuda")


def test_pairs_and_contacts_overflowing_a_recorded_step_are_all_found():
    """A step replayed from a recorded graph whose pair and contact buffers overflow (64 spheres far
    apart, then moved into one cluster) grows them and collides again, with the same result as a
    world made with that cluster: no pair read past the buffers' end (the narrow phase's and the
    solver's loops stop at the capacity, which the count on the device may pass)."""

    def world(position):
        w = tumble.World(gravity=(0, 0, 0))
        return w, w.add_spheres(position=position, radius=0.05, mass=0.1)

    apart = np.stack(np.meshgrid(*[np.arange(4.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    cluster = np.random.default_rng(1).uniform(-0.1, 0.1, (64, 3))
    w, ids = world(apart)
    for _ in range(5):  # the steps from the second on replay a recorded graph
        w.step()
    capacity = (w.broadphase.pair_capacity, w.contacts.capacity)
    w.set_body_state(ids, position=cluster, velocity=np.zeros((64, 3)))
    w.step()
    fresh, _ = world(cluster)
    fresh.step()
    assert w.broadphase.pair_count > capacity[0] and w.contacts.count > capacity[1]
    assert w.contacts.count == fresh.contacts.count
    assert w.state_hash() == fresh.state_hash()
