"""World.add_joint and [[joint]] tables: arguments, bad input (one line naming table and key), pair filter."""

from __future__ import annotations

import itertools
import math
import warnings

import numpy as np
import pytest

import tumble
from tolerances import dtype, resolution
from tumble.io.scene import build_world, parse_scene
from tumble.launch import LaunchCache
from tumble.solver.joints import JointArgumentError, JointKind, ball_chains


def _world():
    world = tumble.World(gravity=(0, 0, -9.81))
    a = world.add_box(position=(0, 0, 1), half_extents=(0.1, 0.1, 0.1))
    b = world.add_box(position=(0.3, 0, 1), half_extents=(0.1, 0.1, 0.1))
    return world, a, b


def test_an_axis_of_huge_components_is_its_direction():
    """A hinge axis (1e300, 0, 1e300) is the unit axis along it, with no overflow warning (its
    squared length overflowed float64 before)."""
    world, a, b = _world()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        huge = world.add_joint("hinge", a, b, anchor=(0.15, 0, 1), axis=(1e300, 0, 1e300))
        unit = world.add_joint("hinge", a, b, anchor=(0.15, 0, 1), axis=(1, 0, 1))
    frames = world.joints.numpy("joint_frame_a")
    np.testing.assert_allclose(frames[huge.index], frames[unit.index], rtol=0, atol=1e-15)


def test_add_joint_stores_anchors_in_body_frames():
    """Give a world anchor: each body keeps it in its own frame, and the joint starts with no error."""
    world, a, b = _world()
    joint = world.add_joint("hinge", a, b, anchor=(0.15, 0, 1), axis=(0, 1, 0), lower=-1.0, upper=1.0)
    j = world.joints
    assert joint.index == 0 and world.joint_count == 1
    assert j.numpy("joint_kind")[0] == JointKind.HINGE
    assert j.numpy("joint_local_a")[0] == pytest.approx([0.15, 0, 0])
    assert j.numpy("joint_local_b")[0] == pytest.approx([-0.15, 0, 0])
    assert world.joint_error[0] == pytest.approx(0.0, abs=1e-15)
    assert (j.numpy("joint_lower")[0], j.numpy("joint_upper")[0]) == (-1.0, 1.0)


def test_distance_and_rope_defaults():
    """A distance joint defaults to a rod of the current length; a rope to slack up to it."""
    world, a, b = _world()
    world.add_joint("distance", a, b)
    world.add_joint("rope", None, b, anchor_a=(0.3, 0, 2))
    lower, upper = world.joints.numpy("joint_lower"), world.joints.numpy("joint_upper")
    assert (lower[0], upper[0]) == pytest.approx((0.3, 0.3))
    assert (lower[1], upper[1]) == pytest.approx((0.0, 1.0))


@pytest.mark.parametrize(
    ("args", "kwargs", "key"),
    [
        (("ball", 0, 7), {}, "body_b"),
        (("ball", 0, 0), {}, "body_b"),
        (("hinge", 0, 1), {"axis": (0, 0, 0)}, "axis"),
        (("hinge", 0, 1), {"lower": 1.0, "upper": -1.0}, "lower"),
        (("distance", 0, 1), {"min_length": 2.0, "max_length": 1.0}, "min_length"),
        (("twist", 0, 1), {}, "kind"),
        (("ball", 0, 1), {"lower": 0.0}, "lower"),
        (("hinge", 0, 1), {"motor_speed": 1.0}, "max_torque"),
        (("ball", 0, 1), {"anchor": (0, float("nan"), 0)}, "anchor"),
        # a joint that breaks at any force (the scene loader refused it already)
        (("ball", 0, 1), {"break_force": 0.0}, "break_force"),
    ],
)
def test_add_joint_rejects_bad_arguments(args, kwargs, key):
    """Reject a bad joint argument with a ValueError naming it."""
    world, _, _ = _world()
    with pytest.raises(JointArgumentError) as info:
        world.add_joint(*args, **kwargs)
    assert info.value.key == key
    assert str(info.value).startswith(f"{key}: ")
    assert world.joint_count == 0


def test_a_per_body_anchor_wins_over_the_shared_one_for_its_body():
    """anchor with anchor_b: a's anchor is `anchor`, b's is `anchor_b` (a rope from a world point to a body point)."""
    world, a, b = _world()
    world.add_joint("rope", a, b, anchor=(0.0, 0.0, 2.0), anchor_b=(0.3, 0.0, 1.0))
    pa = world.body_position[a.index] + world.joints.numpy("joint_local_a")[0]  # the bodies start unrotated
    pb = world.body_position[b.index] + world.joints.numpy("joint_local_b")[0]
    assert pa == pytest.approx([0.0, 0.0, 2.0])
    assert pb == pytest.approx([0.3, 0.0, 1.0])


def test_infinite_hinge_limits_are_no_limit_on_that_side():
    """lower=-inf (or None, or upper=inf) on a hinge is no limit on that side (kept as -1e30: no inf
    in the kernels); a finite limit may lie beyond half a turn (the angle counts turns)."""
    world, a, b = _world()
    world.add_joint("hinge", a, b, lower=-math.inf, upper=0.5)
    world.add_joint("hinge", a, b, upper=4.0 * math.pi)
    none = float(dtype()(-1e30))  # -1e30 as the world's floats hold it (-1.0000000150e30 in float32)
    assert world.joints.numpy("joint_lower").tolist() == [none, none]
    assert world.joints.numpy("joint_upper").tolist() == [0.5, pytest.approx(4.0 * math.pi)]


def test_add_joint_rejects_two_static_bodies():
    """Refuse a joint between two static bodies, or a static body and the world."""
    world = tumble.World()
    ground = world.add_plane()
    block = world.add_box(position=(0, 0, 1), half_extents=(0.1, 0.1, 0.1), static=True)
    for a, b in ((ground, block), (None, block)):
        with pytest.raises(JointArgumentError, match="static"):
            world.add_joint("ball", a, b)


SCENE = """
[[plane]]
[[sphere]]
position = [0, 0, 1]
radius = 0.1
[[box]]
position = [0.5, 0, 1]
half_extents = [0.1, 0.1, 0.1]
[[joint]]
kind = "hinge"
body_a = "sphere[0]"
body_b = "box[0]"
anchor = [0.25, 0, 1]
axis = [0, 1, 0]
lower = -45
upper = 90
[[joint]]
kind = "rope"
body_b = "sphere[0]"
anchor_a = [0, 0, 2]
"""


def test_scene_joint_table_builds_joints():
    """Build [[joint]] tables: bodies by table and index, hinge limits in degrees, the world by default."""
    world = build_world(parse_scene(SCENE))
    j = world.joints
    assert world.joint_count == 2
    assert list(j.numpy("joint_body_a")) == [1, -1]
    assert list(j.numpy("joint_body_b")) == [2, 1]
    assert j.numpy("joint_lower")[0] == pytest.approx(math.radians(-45))
    assert j.numpy("joint_upper")[0] == pytest.approx(math.radians(90))
    world.run(duration=0.1)
    assert np.isfinite(world.joint_force).all()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (('body_b = "box[0]"', 'body_b = "box[3]"'), "[joint[0]] body_b: no body 'box[3]'"),
        (('body_b = "box[0]"', 'body_b = "sphere[0]"'), "[joint[0]] body_b: a joint needs two different bodies"),
        (("axis = [0, 1, 0]", "axis = [0, 0, 0]"), "[joint[0]] axis: must not be the zero vector"),
        (("upper = 90", "upper = -90"), "[joint[0]] lower: lower -45 > upper -90"),
        (('body_b = "box[0]"', 'body_b = "cube[0]"'), "[joint[0]] body_b: must name a body"),
        (('body_a = "sphere[0]"', 'body_a = "plane[0]"\nbody_b = "world"'), None),
    ],
)
def test_scene_joint_errors_name_table_and_key(change, message):
    """Report a bad [[joint]] in one line naming the table and the key."""
    text = SCENE.replace(*change)
    if message is None:  # the plane and the world: both static
        text = text.replace('body_b = "box[0]"\n', "", 1)
        message = "[joint[0]] body_b: neither body is dynamic (each is static, kinematic or the world)"
    with pytest.raises(tumble.SceneError) as info:
        build_world(parse_scene(text, path="s.toml"))
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_a_joint_between_a_static_and_a_kinematic_body_is_refused_as_such():
    """A joint that would move nothing is refused, naming what each body is: a kinematic body is not static."""
    world = tumble.World()
    ground = world.add_box(position=(0, 0, 0), half_extents=(1, 1, 0.1), static=True)
    lift = world.add_box(position=(0, 0, 1), half_extents=(0.1, 0.1, 0.1), kinematic=True)
    with pytest.raises(ValueError, match=r"body_b: neither body is dynamic \(each is static, kinematic or the world\)"):
        world.add_joint("ball", ground, lift, anchor=(0, 0, 0.5))
    assert world.joint_count == 0


def test_scene_rope_min_over_max():
    """Report min_length > max_length on the min_length key."""
    text = SCENE + "min_length = 2.0\nmax_length = 1.0\n"
    with pytest.raises(tumble.SceneError, match=r"\[joint\[1\]\] min_length: min_length 2 > max_length 1"):
        parse_scene(text, path="s.toml")


def test_broken_joint_lets_its_pair_collide_again():
    """Break a joint between overlapping boxes: from the next step on they make contacts."""
    world = tumble.World(gravity=(0, 0, 0))
    a = world.add_box(position=(0, 0, 1), half_extents=(0.1, 0.1, 0.1))
    b = world.add_box(position=(0.15, 0, 1), half_extents=(0.1, 0.1, 0.1))
    world.add_joint("ball", a, b, anchor=(0.075, 0, 1), break_force=1.0)
    world.apply_force(b, (100.0, 0, 0))
    world.step()
    assert world.contact_count == 0 and world.joint_broken[0]
    world.step()
    assert world.contact_count > 0


def test_recording_holds_joint_forces(tmp_path):
    """Record a pendulum: the file has each frame's joint force, which balances the bob's weight at rest."""
    from tumble.io.record import Recorder, load_recording

    world = tumble.World(gravity=(0, 0, -9.81))
    bob = world.add_sphere(position=(0, 0, 1), radius=0.05, mass=2.0)
    world.add_joint("rope", None, bob, anchor_a=(0, 0, 2))
    recorder = Recorder(world, fps=30)
    world.run(duration=0.5, callback=recorder)
    rec = load_recording(recorder.save(tmp_path / "pendulum.npz"))
    assert rec["joint_force"].shape == (recorder.frame_count, 1, 3)
    assert rec["joint_force"][-1, 0] == pytest.approx([0, 0, 2.0 * 9.81], rel=1e-6)
    assert rec["joint_bodies"].tolist() == [[-1, bob.index]]
    assert not rec["joint_broken"].any()


def test_removing_another_body_keeps_joints_on_their_bodies():
    """Remove a body with a lower row than two jointed ones: the joints follow their bodies' new rows."""
    world = tumble.World(gravity=(0, 0, -9.81), dt=1 / 240)
    loose = world.add_sphere(position=(5, 0, 0), radius=0.1, mass=1.0)
    a = world.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    b = world.add_sphere(position=(0, 0, 0.5), radius=0.1, mass=1.0)
    world.add_joint("ball", None, a, anchor=(0, 0, 1.2))
    world.add_joint("distance", a, b)
    world.step()
    world.remove_body(loose)
    world.run(duration=0.5)
    assert world.body_position[a.index] == pytest.approx([0, 0, 1], abs=1e-4)
    assert world.body_position[b.index] == pytest.approx([0, 0, 0.5], abs=1e-4)
    assert world.joint_error.max() < 1e-4


def _chains(body_a, body_b) -> list[list[int]]:
    order, starts = ball_chains(np.array(body_a), np.array(body_b))
    return [order[s:e].tolist() for s, e in itertools.pairwise(starts)]


def test_ball_chains_follow_shared_bodies_and_cut_at_branches_loops_and_paired_ties():
    # a hanging chain, given in any order, is one chain walked end to end
    assert _chains([-1, 0, 1, 2], [0, 1, 2, 3]) == [[0, 1, 2, 3]]
    assert _chains([2, 1, 0, -1], [3, 2, 1, 0]) == [[0, 1, 2, 3]]
    # a bridge: the world at both ends
    assert _chains([-1, 0, 1], [0, 1, -1]) == [[0, 1, 2]]
    # a torso (body 0) with three two-joint limbs: the limbs, cut at the branch
    assert _chains([0, 1, 0, 3, 0, 5], [1, 2, 3, 4, 5, 6]) == [[0, 1], [2, 3], [4, 5]]
    # a ring of four bodies: cut open, its last joint on its own
    assert sorted(map(len, _chains([0, 1, 2, 3], [1, 2, 3, 0]))) == [1, 3]
    # two joints on the same two bodies (paired ties): redundant rows, never one chain
    assert _chains([0, 0], [1, 1]) == [[0], [1]]


def test_ball_chain_solve_leaves_no_joint_velocity():
    """One pass with bias solves a chain's point rows exactly: at zero error every anchor pair moves
    together after it.

    Six boxes of masses 0.1 to 10 kg (1:100) hang in a chain from the world, with random velocities;
    a Gauss-Seidel sweep would leave the rows coupled through their shared bodies unsolved.
    """
    world = tumble.World(gravity=(0, 0, 0))
    rng = np.random.default_rng(7)
    n = 6
    links = [
        world.add_box(position=(0.3 * i, 0, 0), half_extents=(0.1, 0.05, 0.05), mass=m)
        for i, m in enumerate([0.1, 10.0, 1.0, 0.1, 5.0, 0.3][:n])
    ]
    world.add_joint("ball", None, links[0], anchor=(-0.15, 0, 0))
    for i in range(1, n):
        world.add_joint("ball", links[i - 1], links[i], anchor=(0.3 * i - 0.15, 0.02 * i, 0))
    world.bodies.write("body_velocity", slice(0, n), rng.normal(size=(n, 3)))
    world.bodies.write("body_angular_velocity", slice(0, n), rng.normal(size=(n, 3)) * 5)
    world.joints.refresh(world.bodies.count)
    assert world.joint_error.max() < 1e-15  # no error to feed back: the pass only solves Cdot = 0
    world.joints.solve(world.bodies, world.dt / world.substeps, use_bias=True)
    v, w = world.body_velocity, world.body_angular_velocity
    la, lb = world.joints.numpy("joint_local_a"), world.joints.numpy("joint_local_b")  # unrotated bodies: world arms
    ia, ib = world.joints.numpy("joint_body_a"), world.joints.numpy("joint_body_b")
    # rounding, amplified by the 1:100 masses: 1e-9 in float64 (~26 ulps seen), 400 ulps (100 times a
    # few) in float32 (~40 seen)
    speed = max(1.0, np.abs(v).max())
    bound = resolution(1e-9 * speed, speed, 400)
    for k in range(n):
        va = np.zeros(3) if ia[k] < 0 else v[ia[k]] + np.cross(w[ia[k]], la[k])
        vb = v[ib[k]] + np.cross(w[ib[k]], lb[k])
        assert np.abs(vb - va).max() < bound


def test_recorded_solver_graph_runs_each_joint_kinds_own_kernel(monkeypatch):
    """A world of hinge, slider and distance joints steps the same with its solver graph as without.

    The solve kernels of the kinds come from one factory; a recorded CPU graph finds a kernel by
    its name, so each needs a name of its own (with one shared name the replay ran one kind's
    kernel for all: a hinge about y drifted off y by 6e-10 m in 0.5 s).
    """

    def build():
        world = tumble.World(gravity=(0, 0, -9.81), dt=1 / 240, substeps=4)
        a = world.add_box(position=(0.3, 0, 1), half_extents=(0.1, 0.05, 0.05))
        b = world.add_box(position=(0.6, 0, 1), half_extents=(0.1, 0.05, 0.05))
        c = world.add_box(position=(0.6, 0, 0.5), half_extents=(0.05, 0.05, 0.05))
        world.add_joint("hinge", None, a, anchor=(0.15, 0, 1), axis=(0, 1, 0))
        world.add_joint("distance", a, b)
        world.add_joint("slider", b, c, axis=(0, 0, 1))
        return world

    replays = []
    record = LaunchCache.graph

    def spy(self, *args):
        graph = record(self, *args)
        replays.append(graph is not None)
        return graph

    monkeypatch.setattr(LaunchCache, "graph", spy)
    recorded = build()
    recorded.run(0.25)
    assert sum(replays) > 50  # the solver stages ran as a recorded graph
    monkeypatch.setattr(LaunchCache, "graph", lambda *args: None)
    direct = build()
    direct.run(0.25)
    assert recorded.state_hash() == direct.state_hash()
    # nothing drives them off y: what they show is the rounding of the joints' frames, well under an ulp
    # of the positions (~1 m; 1e-17 in float64, 6e-9 in float32) in the 0.25 s, bounded by 16 of them
    assert np.abs(recorded.bodies.numpy("body_position")[:, 1]).max() < resolution(1e-12, 1.0, 16)


@pytest.mark.parametrize("kind", [None, 0, 3.5, True, ["ball"]])
def test_a_kind_that_is_not_a_name_is_refused_naming_kind(kind):
    """add_joint's kind is a name ("ball", ...) or a JointKind; None, numbers and True get a
    JointArgumentError at `kind` listing the names (None gave "None is not a valid JointKind")."""
    world = tumble.World()
    a = world.add_sphere(position=(0, 0, 1), radius=0.1)
    with pytest.raises(JointArgumentError, match=r"^kind: must be one of 'ball', 'hinge', .*, got ") as error:
        world.add_joint(kind, a, None, anchor=(0, 0, 2))
    assert error.value.key == "kind"
    assert world.add_joint(JointKind.BALL, a, None, anchor=(0, 0, 2)) is not None


def test_pivots_are_the_points_and_lines_world_joints_turn_a_body_about():
    """`JointSet.pivots`: a rod on two coaxial hinges turns about their axis, a ball on one ball joint about
    its anchor, three balls in a row about their line; three balls off one line hold a body still, and a
    hinge with a limit, or a joint to another body, leaves the body out."""
    world = tumble.World()
    rod = world.add_box(position=(0, 0, 2.1), half_extents=(0.55, 0.02, 0.02), mass=0.1)
    for end in (-0.55, 0.55):
        world.add_joint("hinge", rod, None, anchor=(end, 0, 2.1), axis=(1, 0, 0))
    ball = world.add_sphere(position=(1, 1, 1), radius=0.1, mass=1)
    world.add_joint("ball", ball, None, anchor=(1, 1, 1.5))
    row = world.add_sphere(position=(3, 1, 1), radius=0.1, mass=1)
    for y in (1.0, 1.5, 2.0):
        world.add_joint("ball", row, None, anchor=(3, y, 1.5))
    still = world.add_sphere(position=(5, 1, 1), radius=0.1, mass=1)
    for anchor in ((5, 1, 1.5), (5.5, 1, 1.5), (5, 2, 1.5)):
        world.add_joint("ball", still, None, anchor=anchor)
    limited = world.add_sphere(position=(7, 1, 1), radius=0.1, mass=1)
    world.add_joint("hinge", limited, None, anchor=(7, 1, 1.5), axis=(0, 1, 0), lower=-1.0, upper=1.0)
    pair = [world.add_sphere(position=(9 + k, 1, 1), radius=0.1, mass=1) for k in range(2)]
    world.add_joint("ball", pair[0], pair[1], anchor=(9.5, 1, 1))

    rows, points, axes = world.joints.pivots(world.joints.held_bodies())
    assert rows.tolist() == [world.body_row(b) for b in (rod, ball, row)]
    np.testing.assert_allclose(points, [(-0.55, 0, 2.1), (1, 1, 1.5), (3, 1, 1.5)])
    np.testing.assert_allclose(axes, [(1, 0, 0), (0, 0, 0), (0, 1, 0)], atol=1e-12)
