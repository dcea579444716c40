"""World API: handles, setting and reading body state, removal, time, argument checks, views."""

from __future__ import annotations

import inspect
import math
import pickle

import numpy as np
import pytest

import tumble
import tumble.world as world_module
from tolerances import resolution
from tumble import BodyId, BodyKind, ClothId, HandleError
from tumble.cloth import ClothSystem
from tumble.errors import NoSuchIdError


def _free_world() -> tumble.World:
    """No gravity, three spheres far apart (no contacts)."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_spheres(position=[(0, 0, 0), (1, 0, 0), (2, 0, 0)], radius=0.1, mass=1.0)
    return w


# ---------------------------------------------------------------- handles


def test_body_handles_are_ints_with_generation_and_world():
    """A BodyId indexes the views like an int and carries its generation and world."""
    w = _free_world()
    ball = w.add_sphere(position=(3, 0, 0), radius=0.1, mass=1.0)
    assert isinstance(ball, BodyId) and isinstance(ball, int)
    assert ball == 3 and ball.index == 3 and ball.generation == 0 and ball.world is w
    assert w.body_position[ball][0] == 3.0 and w.body_position[ball.index][0] == 3.0
    assert str(ball) == "3" and repr(ball) == "BodyId(3, generation=0)"
    assert pickle.loads(pickle.dumps(ball)) == ball
    with pytest.raises(AttributeError, match="immutable"):
        ball.generation = 5


def test_a_handle_from_another_world_is_refused():
    """A handle names its world: another world refuses it instead of moving its own body 1."""
    a, b = _free_world(), _free_world()
    ball = a.add_sphere(position=(5, 0, 0), radius=0.1, mass=1.0)
    other = b.add_sphere(position=(5, 0, 0), radius=0.1, mass=1.0)
    assert ball == 3 and other == 3 and ball != other
    for call in (
        lambda: b.set_body_state(ball, position=(0, 0, 1)),
        lambda: b.apply_force(ball, (1, 0, 0)),
        lambda: b.remove_body(ball),
        lambda: b.body_state(ball),
    ):
        with pytest.raises(HandleError, match="body 3 belongs to another World"):
            call()
    assert not b.has_body(ball) and a.has_body(ball)


def test_a_removed_handle_is_refused_even_after_its_id_is_reused():
    """A reused id gets a new generation: the old handle raises, the new body gets the id."""
    w = _free_world()
    w.remove_body(1)
    with pytest.raises(HandleError, match="body 1 was removed"):
        w.set_body_state(1, velocity=(1, 0, 0))
    old = BodyId(1, 0, w.key)
    new = w.add_sphere(position=(7, 0, 0), radius=0.2, mass=2.0)
    assert int(new) == 1 and new.generation == 1 and new != old
    with pytest.raises(HandleError, match="now names a newer body"):
        w.set_body_state(old, position=(0, 0, 0))
    np.testing.assert_array_equal(w.body_position[new], (7, 0, 0))
    assert w.body_radius[1] == 0.2 and w.body_mass[1] == 2.0


def test_the_handle_of_the_last_body_removed_is_refused_as_removed():
    """Removing the newest body frees its id, so the world holds fewer ids than the handle names: its
    handle still gets HandleError (as documented), a plain int that was never an id IndexError."""
    w = tumble.World()
    w.add_sphere(position=(0, 0, 1), radius=0.1)
    last = w.add_sphere(position=(1, 0, 1), radius=0.1)
    w.remove_body(last)
    for call in (
        lambda: last.position,
        lambda: w.set_body_state(last, position=(0, 0, 0)),
        lambda: w.remove_body(last),
    ):
        with pytest.raises(HandleError, match="body 1 was removed from this World"):
            call()
    with pytest.raises(IndexError, match="body 5 does not exist"):
        w.body_state(5)


def test_a_joint_to_another_worlds_body_names_the_other_world():
    w, other = tumble.World(), tumble.World()
    a = w.add_sphere(position=(0, 0, 1), radius=0.1)
    foreign = other.add_sphere(position=(0, 0, 1), radius=0.1)
    with pytest.raises(ValueError, match="body_b: body 0 belongs to another World"):
        w.add_joint("ball", a, foreign)


@pytest.mark.parametrize(
    "bad, error",
    [(1.0, TypeError), ("1", TypeError), (True, TypeError), (None, TypeError), (17, IndexError), (-1, IndexError)],
)
def test_bad_body_arguments_are_named(bad, error):
    """Anything but a live body's handle or int id is refused, naming the body."""
    w = _free_world()
    with pytest.raises(error, match="body"):
        w.set_body_state(bad, position=(0, 0, 0))


def test_a_cloth_handle_is_not_a_body_handle():
    """ClothId and BodyId are different kinds: a cloth handle does not name body 0."""
    w = _free_world()
    cloth = w.add_cloth(size=(0.2, 0.2), resolution=(3, 3), position=(0, 0, 5))
    with pytest.raises(TypeError, match="must be a BodyId, got the ClothId"):
        w.set_body_state(cloth, position=(0, 0, 0))


def test_add_cloth_returns_a_cloth_handle():
    """add_cloth gives a ClothId: the cloth's index, its world and where its particles are."""
    w = tumble.World()
    first = w.add_cloth(size=(1.0, 1.0), resolution=(4, 3))
    second = w.add_cloth(size=(1.0, 1.0), resolution=(3, 3), position=(0, 0, 1))
    assert isinstance(second, ClothId) and second == 1 and second.world is w
    assert first.particle_start == 0 and second.particle_start == 12 and second.particle_count == 9
    assert second.resolution == (3, 3) and second.particle(2, 1) == 12 + 1 * 3 + 2
    np.testing.assert_array_equal(second.particle_position, w.cloth.particle_position[12:21])
    with pytest.raises(IndexError, match=r"grid point \(3, 0\) is outside cloth 1"):
        second.particle(3, 0)
    with pytest.raises(HandleError, match="cloth 1 belongs to another World"):
        tumble.World().cloth.cloth(second)


def test_emitters_belong_to_their_world():
    """add_emitter returns the Emitter, its handle; another world cannot remove it."""
    w, other = tumble.World(), tumble.World()
    em = w.add_emitter(rate=10.0, count=5)
    assert isinstance(em, tumble.Emitter) and em.world_key == w.key
    with pytest.raises(HandleError, match="does not belong to this World"):
        other.remove_emitter(em)
    w.remove_emitter(em)
    w.run(1.0)
    assert w.body_count == 0 and em.world_key is None
    with pytest.raises(TypeError, match="emitter must be an Emitter"):
        w.remove_emitter(3)


# ---------------------------------------------------------------- setting state


def test_set_body_state_moves_and_launches_a_body():
    """set_body_state writes pose and velocities at once; the next step starts from them (free flight)."""
    w = _free_world()
    q = np.array([0.0, 0.0, math.sin(0.3), math.cos(0.3)])
    w.set_body_state(1, position=(1, 2, 3), orientation=2 * q, velocity=(4, 0, 0), angular_velocity=(0, 0, 1))
    state = w.body_state(1)
    np.testing.assert_array_equal(state.position, (1, 2, 3))
    # normalised and stored: an ulp or two
    np.testing.assert_allclose(state.orientation, q, rtol=0, atol=resolution(1e-15, 1.0, 2))
    assert state.kind == BodyKind.DYNAMIC
    w.step()
    # no forces: x = x0 + v dt (exact in binary for dt = 1/240 to rounding: a few ulps of x)
    np.testing.assert_allclose(w.body_position[1], (1 + 4 * w.dt, 2, 3), rtol=0, atol=resolution(1e-14, 3.0, 4))
    np.testing.assert_array_equal(w.body_position[0], (0, 0, 0))


def test_handle_properties_read_and_write_like_pymunk():
    """ball.position = ... is set_body_state; ball.velocity reads a copy."""
    w = _free_world()
    ball = w.add_sphere(position=(5, 0, 0), radius=0.1, mass=1.0)
    ball.position = (0, 0, 9)
    ball.velocity = (1, 2, 3)
    ball.angular_velocity = (0, 0, 4)
    ball.orientation = (0, 0, 1, 0)
    np.testing.assert_array_equal(w.body_position[ball], (0, 0, 9))
    np.testing.assert_array_equal(ball.velocity, (1, 2, 3))
    np.testing.assert_array_equal(ball.angular_velocity, (0, 0, 4))
    np.testing.assert_array_equal(ball.orientation, (0, 0, 1, 0))
    v = ball.velocity
    v[0] = 100.0  # a copy: the world does not change
    assert ball.velocity[0] == 1.0 and ball.kind == BodyKind.DYNAMIC


def test_set_body_state_for_many_bodies():
    """One call sets k bodies from (k, 3) arrays, or all of them from one row."""
    w = _free_world()
    w.set_body_state([0, 2], position=[(0, 0, 1), (0, 0, 2)], velocity=(0, 0, 1))
    np.testing.assert_array_equal(w.body_position[:, 2], (1, 0, 2))
    np.testing.assert_array_equal(w.body_velocity[:, 2], (1, 0, 1))
    with pytest.raises(ValueError, match=r"position must have 3 components \(or shape \(2, 3\)\)"):
        w.set_body_state([0, 2], position=np.zeros((3, 3)))


def test_static_bodies_refuse_velocities_but_may_be_moved():
    """A static body never moves by itself: a velocity is refused, a new position is taken."""
    w = tumble.World()
    floor = w.add_plane()
    block = w.add_box(position=(0, 0, 0), half_extents=(1, 1, 0.1), static=True)
    with pytest.raises(ValueError, match="body 1 is static"):
        w.set_body_state(block, velocity=(1, 0, 0))
    w.set_body_state(block, position=(0, 0, 0.5))
    w.run(0.1)
    np.testing.assert_array_equal(w.body_position[block], (0, 0, 0.5))
    assert floor.kind == BodyKind.STATIC and block.kind == BodyKind.STATIC


@pytest.mark.parametrize(
    "adder, size",
    [
        ("add_box", {"half_extents": (1, 1, 0.1)}),
        ("add_sphere", {"radius": 0.1}),
        ("add_capsule", {"radius": 0.1, "half_height": 0.2}),
        ("add_convex", {"points": np.eye(3).tolist() + [[0, 0, 0]]}),
    ],
)
def test_a_static_body_is_refused_a_velocity_when_it_is_added_too(adder, size):
    """As set_body_state refuses it: a static body added with a velocity or a spin other than 0 is an
    error naming the key (before, the velocity was dropped and the body stood still); zeros are taken."""
    w = tumble.World()
    add = getattr(w, adder)
    for key in ("velocity", "angular_velocity"):
        with pytest.raises(ValueError, match=rf"^{key}: a static body never moves.*kinematic=True"):
            add(position=(0, 0, 0), static=True, **{key: (0, 0.5, 0)}, **size)
    assert w.body_count == 0  # nothing half-added
    body = add(position=(0, 0, 0), static=True, velocity=(0, 0, 0), angular_velocity=(0, 0, 0), **size)
    assert body.kind == BodyKind.STATIC
    moving = add(position=(3, 0, 0), kinematic=True, velocity=(0, 0.5, 0), **size)  # what was meant
    y0 = w.body_position[moving][1]
    w.step()
    assert w.body_velocity[moving][1] == 0.5 and w.body_position[moving][1] > y0


def test_moving_a_resting_body_keeps_the_others_resting():
    """Teleporting the top box of a resting stack away leaves the lower box at rest on the floor."""
    w = tumble.World()
    w.add_plane()
    low = w.add_box(position=(0, 0, 0.1), half_extents=(0.1, 0.1, 0.1), mass=1.0)
    top = w.add_box(position=(0, 0, 0.3), half_extents=(0.1, 0.1, 0.1), mass=1.0)
    w.run(0.5)
    top.position = (3, 0, 0.1)
    w.run(0.5)
    assert abs(w.body_position[low][2] - 0.1) < 1e-3 and abs(w.body_position[top][2] - 0.1) < 1e-3
    assert np.abs(w.body_velocity[[low, top]]).max() < 1e-2


# ---------------------------------------------------------------- removal


def test_remove_body_frees_its_id_and_keeps_the_others():
    """Other bodies keep their ids and values; the removed id reads NaN until reused."""
    w = _free_world()
    w.set_body_state([0, 1, 2], velocity=[(1, 0, 0), (2, 0, 0), (3, 0, 0)])
    w.remove_body(1)
    assert w.body_count == 3 and not w.has_body(1)
    np.testing.assert_array_equal(w.body_alive, (True, False, True))
    assert np.isnan(w.body_position[1]).all() and w.body_shape[1] == -1 and w.body_kind[1] == -1
    w.step()
    # x0 + v dt: a few ulps of x
    np.testing.assert_allclose(w.body_position[[0, 2], 0], (w.dt, 2 + 3 * w.dt), rtol=0, atol=resolution(1e-15, 2.0, 4))
    w.remove_body(2)  # the highest id: the views get shorter
    assert w.body_count == 1 and w.body_position.shape == (1, 3)
    w.remove_body(0)
    assert w.body_count == 0
    w.step()


def test_removing_bodies_from_a_pile_drops_their_contacts():
    """Contacts and warm starts of removed bodies go; the rest of the pile stays at rest."""
    w = tumble.World()
    w.add_plane()
    x = np.array([(i * 0.21, 0.0, 0.1 + 0.2 * k) for i in range(4) for k in range(3)])
    balls = w.add_spheres(position=x, radius=0.1, mass=1.0)
    w.run(1.0)
    top = [b for b in balls if w.body_position[b][2] > 0.45]
    assert len(top) == 4
    w.remove_bodies(top)
    pairs = w.contact_pair
    assert len(pairs) and not np.isin(pairs, [int(b) for b in top]).any()
    w.run(1.0)
    assert w.kinetic_energy() < 1e-6
    assert np.nanmax(w.body_position[:, 2]) < 0.31


def test_removal_through_reorders_and_with_cloth(monkeypatch):
    """Removal follows reordered rows, and the cloth's per-body data follows the removal."""
    monkeypatch.setattr(world_module, "SORT_MIN_BODIES", 2)
    monkeypatch.setattr(world_module, "SORT_INTERVAL", 3)
    w = tumble.World()
    w.add_plane()
    w.add_cloth(size=(1.0, 1.0), resolution=(12, 12), position=(0.0, 0.0, 1.0), pins="corners")
    rng = np.random.default_rng(0)
    x = np.column_stack([rng.uniform(1.5, 3.0, 30), rng.uniform(-1, 1, 30), rng.uniform(0.1, 1.0, 30)])
    balls = w.add_spheres(position=x[rng.permutation(30)], radius=0.05, mass=0.1)
    caught = w.add_sphere(position=(0.0, 0.0, 1.3), radius=0.1, mass=0.2)
    w.run(0.5)
    assert not np.array_equal(w.body_rows, np.arange(w.body_count))  # the rows were reordered
    gone = balls[::2]
    w.remove_bodies(gone)
    w.run(1.0)
    assert 0.5 < w.body_position[caught][2] < 1.0  # still in the cloth
    kept = [b for b in balls if b not in gone]
    assert np.all(w.body_position[kept, 2] > 0.05 - 1e-3)
    assert np.isnan(w.body_position[gone]).all() and w.has_body(caught)


def test_emitters_keep_emitting_while_bodies_are_removed():
    """An emitter fills the ids freed by removals; nothing is born inside another body."""
    w = tumble.World()
    w.add_plane()
    em = w.add_emitter(
        rate=200.0, count=60, position=(0, 0, 0.5), region="disc", extent=0.3, radius=0.03, direction=(0, 0, 1)
    )
    for _ in range(6):
        w.run(0.1)
        alive = np.flatnonzero(w.body_alive)[1:]  # not the plane
        w.remove_bodies(alive[: len(alive) // 2].tolist())
    w.run(0.5)
    assert em.done and w.body_count < 61
    x = w.body_position[w.body_alive][1:]
    gaps = np.linalg.norm(x[:, None] - x[None], axis=-1) + np.eye(len(x))
    assert gaps.min() > 0.06 - 2e-3


def test_removal_is_deterministic():
    """The same removals give the same state, bit for bit."""

    def run():
        w = tumble.load_scene("rain")
        w.run(0.5)
        w.remove_bodies(np.flatnonzero(w.body_alive)[5::3].tolist())
        w.run(0.5)
        return w.state_hash()

    assert run() == run()


# ---------------------------------------------------------------- time


def test_time_is_steps_times_dt():
    """World.time is step_count * dt, not a running sum: 960 steps of 1/240 s read exactly 4 s."""
    w = tumble.World()
    w.run(4.0)
    assert w.step_count == 960 and w.time == 4.0


@pytest.mark.parametrize(
    ("value", "error"), [("abc", TypeError), (None, TypeError), (-1, ValueError), (1.5, ValueError)]
)
def test_step_count_takes_only_a_count(value, error):
    """world.step_count = "abc" is refused naming step_count; before it was taken, and the next
    step failed with TypeError: can only concatenate str (not "int") to str."""
    w = tumble.World()
    with pytest.raises(error, match=r"^step_count must be an integer >= 0, got "):
        w.step_count = value
    w.step_count = 7.0
    w.step()
    assert w.step_count == 8 and type(w.step_count) is int


def test_time_sums_runs_of_different_dt():
    """When dt changes, each run of equal steps counts as steps * dt."""
    w = tumble.World(dt=1 / 240)
    for _ in range(100):
        w.step()
    w.dt = 1 / 100
    for _ in range(50):
        w.step()
    for _ in range(3):
        w.step(0.1)
    assert w.time == 100 * (1 / 240) + 50 * (1 / 100) + 3 * 0.1
    assert abs(w.time - (100 / 240 + 0.5 + 0.3)) < 1e-15


# ---------------------------------------------------------------- argument checks


@pytest.mark.parametrize(
    "call, error, message",
    [
        (lambda: tumble.World(substeps=2.5), ValueError, r"substeps must be an integer >= 1, got 2.5"),
        (lambda: tumble.World(substeps="8"), TypeError, r"substeps must be an integer >= 1, got '8'"),
        (lambda: tumble.World(seed=-1), ValueError, r"seed must be an integer in \[0, 9223372036854775807\], got -1"),
        (lambda: tumble.World(restitution_threshold=float("nan")), ValueError, r"restitution_threshold must be"),
        (lambda: tumble.World(dt="fast"), TypeError, r"dt must be a number, got 'fast'"),
        (lambda: tumble.World(gravity="down"), TypeError, r"gravity must be 3 finite numbers, got 'down'"),
        (lambda: tumble.World(device=0), TypeError, r"device must be a string, got 0"),
    ],
)
def test_world_settings_are_checked_by_name(call, error, message):
    """Each bad World setting raises TypeError or ValueError naming it and its value."""
    with pytest.raises(error, match=message):
        call()


def _world_with_body():
    w = tumble.World()
    w.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    return w


@pytest.mark.parametrize(
    "call, error, message",
    [
        (
            lambda w: w.add_sphere(position=(0, 0, 0), radius=-1),
            ValueError,
            r"radius must be a positive number, got -1$",
        ),
        (lambda w: w.add_sphere(position=(0, 0, 0), radius="big"), TypeError, r"radius must be a .*got 'big'"),
        (lambda w: w.add_sphere(position="here", radius=0.1), TypeError, r"position must be 3 finite numbers"),
        (lambda w: w.add_sphere(position=(0, 0, 0), radius=0.1, static=1), TypeError, r"static must be True or False"),
        (
            lambda w: w.add_sphere(position=(0, 0, 0), radius=0.1, static=True, kinematic=True),
            ValueError,
            "static or kinematic, not both",
        ),
        (lambda w: w.add_box(position=(0, 0, 0), half_extents="big"), TypeError, r"half_extents must be 3"),
        (lambda w: w.add_spheres(position=[(0, 0, 0), (1, 0)], radius=0.1), ValueError, r"position must be"),
        (lambda w: w.add_plane(offset="low"), TypeError, r"offset must be a number, got 'low'"),
        (lambda w: w.add_body(3), TypeError, r"shape must be a string, got 3"),
        (lambda w: w.set_material(friction=-0.5), ValueError, r"friction must be a number >= 0, got -0.5"),
        (lambda w: w.apply_force(0, "up"), TypeError, r"force must be 3 finite numbers"),
        (lambda w: w.step(dt=-1), ValueError, r"dt must be in \[1e-09, 0.1\], got -1"),
        # a step longer than World(dt=...) takes (limits.MAX_DT)
        (lambda w: w.step(dt=0.5), ValueError, r"dt must be in \[1e-09, 0.1\], got 0.5"),
        (lambda w: w.run("long"), TypeError, r"duration must be a number, got 'long'"),
        (lambda w: w.run(0.1, callback=5), TypeError, r"callback must be a function or None, got 5"),
        (lambda w: w.collide(dt=float("inf")), ValueError, r"dt must be a positive number, got inf"),
        (lambda w: w.set_body_state(0, velocity=(0, 0, float("nan"))), ValueError, r"velocity must be finite"),
        (lambda w: w.set_body_state(0, orientation=(0, 0, 0, 0)), ValueError, "non-zero quaternion"),
        (lambda w: w.set_kinematic_target(0, position=(0, 0, 0)), ValueError, "body 0 is not kinematic"),
        (lambda w: w.remove_bodies([0, 0]), ValueError, "lists a body twice"),
        (lambda w: w.body("0"), TypeError, r"index must be an integer >= 0, got '0'"),
        (lambda w: w.add_emitter(rate="fast"), TypeError, r"rate must be a number, got 'fast'"),
        (lambda w: w.add_emitter(count=2.5), ValueError, r"count must be an integer >= 1, got 2.5"),
        (lambda w: w.add_emitter(region=3), TypeError, r"region must be a string, got 3"),
        (lambda w: w.add_emitter(radius="big"), TypeError, r"radius must be a number or a \[min, max\] pair"),
        (lambda w: w.add_emitter(random_orientation="yes"), TypeError, r"random_orientation must be True or False"),
        (lambda w: w.add_emitter(restitution=2), ValueError, r"restitution must be in \[0, 1\], got 2"),
        (lambda w: w.add_cloth(friction="x"), TypeError, r"friction must be a number, got 'x'"),
        (lambda w: w.add_cloth(max_stretch=-1), ValueError, r"max_stretch must be a number >= 0, got -1"),
        (lambda w: w.set_wind(turbulence="gusty"), TypeError, r"turbulence must be a number, got 'gusty'"),
        (lambda w: w.set_wind(seed=1.5), ValueError, r"seed must be an integer >= 0, got 1.5"),
        (lambda w: w.set_wind(velocity=(1, 0)), ValueError, r"velocity must have 3 components"),
        (lambda w: w.cloth.apply_force(2.5, (0, 0, 1)), ValueError, r"particle must be an integer >= 0, got 2.5"),
        (lambda w: w.cloth.pin("corner"), TypeError, r"particle must be an integer >= 0, got 'corner'"),
        (lambda w: w.cloth.set_state(position="flat"), TypeError, r"position must be finite numbers"),
    ],
)
def test_calls_check_their_arguments_by_name(call, error, message):
    """Each public call names the bad argument and its value, and changes nothing."""
    w = _world_with_body()
    before = w.state_hash()
    with pytest.raises(error, match=message):
        call(w)
    assert w.body_count == 1 and w.state_hash() == before


def test_settings_are_checked_when_changed():
    """dt, substeps, gravity and restitution_threshold are checked when set later, too."""
    w = tumble.World()
    with pytest.raises(ValueError, match="substeps must be an integer >= 1, got 0"):
        w.substeps = 0
    with pytest.raises(ValueError, match=r"dt must be in \[1e-09, 0.1\], got 0.0"):
        w.dt = 0.0
    with pytest.raises(ValueError, match="gravity must have 3 components"):
        w.gravity = (0, 0)
    with pytest.raises(ValueError, match="restitution_threshold"):
        w.restitution_threshold = -1
    w.substeps = 4.0  # an integral float is an integer
    assert w.substeps == 4 and isinstance(w.substeps, int)
    em = w.add_emitter()
    with pytest.raises(ValueError, match=r"rate must be a number >= 0, got -1"):
        em.rate = -1
    em.rate = 0  # pauses it, as the viewer's control does


def test_forwarding_calls_have_the_real_signatures():
    """add_emitter, add_cloth and set_wind list the same keywords, types and defaults as what they build."""
    pairs = [
        (tumble.World.add_emitter, tumble.Emitter.__init__),
        (tumble.World.add_cloth, ClothSystem.add_cloth),
        (tumble.World.set_wind, ClothSystem.set_wind),
    ]
    for front, back in pairs:
        a = [(p.name, p.default, p.kind, p.annotation) for p in inspect.signature(front).parameters.values()]
        b = [(p.name, p.default, p.kind, p.annotation) for p in inspect.signature(back).parameters.values()]
        assert a == b, front.__name__
        assert all(p.kind != p.VAR_KEYWORD for p in inspect.signature(front).parameters.values())


SOLID_ADDERS = {
    "add_sphere": dict(position=(0, 0, 1), radius=0.1),
    "add_box": dict(position=(0, 0, 1), half_extents=(0.1, 0.1, 0.1)),
    "add_capsule": dict(position=(0, 0, 1), radius=0.1, half_height=0.2),
    "add_convex": dict(points=np.eye(3).tolist() + [[0, 0, 0]]),
    "add_spheres": dict(position=[(0, 0, 1), (1, 0, 1)], radius=0.1),
    "add_boxes": dict(position=[(0, 0, 1), (1, 0, 1)], half_extents=(0.1, 0.1, 0.1)),
    "add_capsules": dict(position=[(0, 0, 1), (1, 0, 1)], radius=0.1, half_height=0.2),
}


@pytest.mark.parametrize("adder", list(SOLID_ADDERS))
def test_every_solid_adder_takes_the_solid_options(adder):
    """Each solid adder takes SolidOptions' keywords (a kinematic capsule or convex body too), and a
    misspelt keyword is refused naming the adder, before anything is added."""
    w = tumble.World()
    ids = getattr(w, adder)(**SOLID_ADDERS[adder], kinematic=True, velocity=(1.0, 0.0, 0.0), friction=0.2)
    for body in ids if isinstance(ids, list) else [ids]:
        assert w.body_state(body).kind == tumble.BodyKind.KINEMATIC
        assert w.body_state(body).velocity.tolist() == [1.0, 0.0, 0.0]
        assert w.body_friction[w.body_row(body)] == 0.2
    count = w.body_count
    with pytest.raises(TypeError, match=rf"^World.{adder}\(\) got an unexpected keyword argument 'frction'$"):
        getattr(w, adder)(**SOLID_ADDERS[adder], frction=0.2)
    assert w.body_count == count


def test_the_package_ships_its_type_hints():
    """py.typed sits in the package and pyproject.toml installs it."""
    from pathlib import Path

    package = Path(tumble.__file__).parent
    assert (package / "py.typed").is_file()
    pyproject = package.parents[1] / "pyproject.toml"
    if pyproject.is_file():
        assert '"py.typed"' in pyproject.read_text()


# ---------------------------------------------------------------- views


def test_views_are_fresh_copies_never_stale():
    """Each access reads the state of that moment; an array kept from before is a snapshot that
    does not change, not even when the world grows past its capacity and reallocates."""
    w = tumble.World()
    w.add_plane()
    ball = w.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    kept = w.body_position
    w.run(0.25)
    # free fall under semi-implicit Euler: z = z0 - g h^2 m (m + 1) / 2 after m substeps of h
    m, h = w.step_count * w.substeps, w.dt / w.substeps
    z = 1.0 - 9.81 * h * h * m * (m + 1) / 2
    # each substep rounds the velocity and the height: up to an ulp of z (~1 m) per substep
    fall = resolution(1e-12, 1.0, m)
    assert w.body_position[ball][2] == pytest.approx(z, abs=fall)
    assert kept[ball][2] == 1.0  # the snapshot
    before = w.body_position
    w.add_spheres(position=[(i, 5, 1) for i in range(100)], radius=0.1, mass=1.0)  # grows the arrays
    assert before.shape == (2, 3) and before[ball][2] == pytest.approx(z, abs=fall)
    w.step()
    now = w.body_position
    assert now.shape == (102, 3) and now[ball][2] < before[ball][2]
    assert not np.shares_memory(now, w.body_position)
    with pytest.raises(ValueError):
        now[0, 0] = 1.0  # read-only: write through set_body_state


def test_a_body_held_by_an_acting_joint_cannot_be_removed():
    """Removing a body held by an acting joint is refused (the joint would lose its body), and nothing
    changes; once the joint is removed (`remove_joint`), the body can be, and the joint keeps its index,
    broken, with the world (-1) in the removed body's place."""
    w = _free_world()
    j0 = w.add_joint("ball", 0, 1, anchor=(0.5, 0, 0))
    j1 = w.add_joint("ball", 0, 2, anchor=(0.5, 0, 0))
    with pytest.raises(ValueError, match=r"body 1 is held by joint 0; remove its joints first \(World.remove_joint\)"):
        w.remove_bodies([1, 2])
    assert w.body_alive.all() and w.body_count == 3
    w.remove_joint(j0)
    w.remove_joint(j0)  # again: nothing changes
    w.remove_body(1)
    assert w.joint_count == 2 and w.joint_broken.tolist() == [True, False]
    assert w.joints.numpy("joint_body_b").tolist() == [-1, w.body_row(2)]
    w.step()
    with pytest.raises(ValueError, match="body 2 is held by joint 1; "):
        w.remove_body(2)
    w.remove_joint(j1.index)  # an int index too
    w.remove_body(2)
    w.step()
    assert w.joint_broken.all()


def test_a_body_holding_cloth_pins_cannot_be_removed():
    """Removing a body that cloth particles are pinned to is refused, naming the pin, and nothing changes."""
    w = tumble.World(gravity=(0, 0, 0))
    pole = w.add_box(position=(0, 0, 1), half_extents=(0.05, 0.05, 1), mass=1.0)
    free = w.add_sphere(position=(3, 0, 0), radius=0.1, mass=1.0)
    w.add_cloth(size=(1, 1), resolution=(4, 4), position=(0.55, 0, 1.5))
    w.pin_cloth_to_body([0], pole)
    with pytest.raises(ValueError, match="body 0 is held by a cloth pin; pinned bodies cannot be removed"):
        w.remove_bodies([free, pole])
    assert w.body_alive.all()
    w.remove_body(free)
    assert w.body_alive.tolist() == [True]


def test_remove_joint_refuses_what_is_not_a_joint_of_this_world():
    """remove_joint takes a JointId of this world or an int index below joint_count; anything else is one clear error."""
    w = _free_world()
    joint = w.add_joint("ball", 0, 1, anchor=(0.5, 0, 0))
    other = _free_world()
    foreign = other.add_joint("ball", 0, 1, anchor=(0.5, 0, 0))
    with pytest.raises(HandleError, match="joint 0 belongs to another World"):
        w.remove_joint(foreign)
    with pytest.raises(NoSuchIdError, match=r"joint 1 does not exist \(the world has 1 joints\)"):
        w.remove_joint(1)
    with pytest.raises(NoSuchIdError, match="joint -1 does not exist"):
        w.remove_joint(-1)
    with pytest.raises(TypeError, match="joint must be a JointId, got the BodyId"):
        w.remove_joint(w.body(1))
    for bad in (True, 0.0, "0", None):
        with pytest.raises(TypeError, match="joint must be a JointId"):
            w.remove_joint(bad)
    assert not w.joint_broken.any()
    w.remove_joint(joint)
    assert w.joint_broken.all()


def test_python_api_refuses_requests_beyond_the_solver_limits():
    """World(dt=1e9), World(substeps=10**9) and run(duration=1e12) are refused by name, as the scene files are."""
    from tumble import limits

    with pytest.raises(ValueError, match=r"dt must be in \[1e-09, 0.1\], got 1000000000.0"):
        tumble.World(dt=1e9)
    with pytest.raises(ValueError, match=r"substeps must be an integer in \[1, 1000\], got 1000000000"):
        tumble.World(substeps=10**9)
    world = tumble.World(dt=limits.MAX_DT, substeps=limits.MAX_SUBSTEPS)  # the limits themselves are allowed
    with pytest.raises(limits.LimitError, match="duration: 1e\\+12 s .* the limit is 1,000,000,000 steps"):
        world.run(duration=1e12)
    assert world.step_count == 0
    with pytest.raises(ValueError, match="dt must be in"):
        world.dt = 0.5
    assert world.dt == limits.MAX_DT


def test_python_api_refuses_cloth_beyond_the_index_and_memory_limits(monkeypatch):
    """add_cloth refuses what the scene loader refuses, before allocating: a grid past the int32
    particle indices, and one that does not fit in the memory available ($TUMBLE_MEMORY caps it)."""
    from tumble import limits

    world = tumble.World()
    with pytest.raises(limits.LimitError, match="1,000,000 x 1,000,000 = 1,000,000,000,000 particles; .*int32"):
        world.add_cloth(resolution=(10**6, 10**6))
    monkeypatch.setenv(limits.MEMORY_ENV, "100M")
    most = 100 * 1024**2 // limits.BYTES_PER_PARTICLE
    with pytest.raises(
        limits.LimitError, match=f"cloth resolution: 40,000 particles need .* \\(at most {most:,} particles\\)"
    ):
        world.add_cloth(resolution=(200, 200))
    assert world.cloth.particles.count == 0
    world.add_cloth(resolution=(100, 100))  # 10,000 particles fit in 100 MB
    assert world.cloth.particles.count == 10_000


@pytest.mark.parametrize(
    "adder, keywords",
    [
        ("add_sphere", {"radius": 1e300}),
        ("add_sphere", {"radius": 1e-300}),
        ("add_sphere", {"radius": 1e-200, "mass": 1.0}),
        ("add_sphere", {"radius": 1e150, "density": 1e200}),
        ("add_box", {"half_extents": (1e200, 1e200, 1e-200), "mass": 1.0}),
        ("add_capsule", {"radius": 1e200, "half_height": 1e200}),
    ],
)
@pytest.mark.float64(
    "float64 overflow of mass and inertia: these sizes (1e300, 1e-200) lie outside float32's range, which a "
    "float32 world refuses before any mass is computed ('does not fit a float32 world')"
)
def test_sizes_whose_mass_or_inertia_overflow_are_refused(adder, keywords, recwarn):
    """A dynamic body whose mass or inertia (or their inverse) is inf, 0 or NaN in float64 is refused
    with one ValueError and no NumPy warning, as the scene loader refuses it; nothing is added."""
    world = tumble.World()
    with pytest.raises(ValueError, match="must give a mass and inertia that are finite and > 0"):
        getattr(world, adder)(position=(0, 0, 1), **keywords)
    assert world.body_count == 0
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
    getattr(world, adder)(position=(0, 0, 1), static=True, **keywords)  # a static body has no mass to overflow
    assert world.body_count == 1
