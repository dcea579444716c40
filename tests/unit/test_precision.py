"""tumble.precision: one kernel source, a copy of the kernel modules per precision, worlds of either."""

from __future__ import annotations

import ast
import importlib
import math
from pathlib import Path

import numpy as np
import pytest
import warp as wp

import tumble
from tumble import precision, snapshot
from tumble.errors import SceneError
from tumble.io.scene import load_scene, parse_scene
from tumble.io.scene.build import build_world

SRC = Path(tumble.__file__).parent
BOTH = pytest.mark.parametrize("p", ["float32", "float64"])


def test_each_precision_has_its_own_copy_of_the_kernel_modules():
    k32, k64 = precision.kernels("float32"), precision.kernels("float64")
    assert k64.contacts is importlib.import_module("tumble.solver.contacts")
    assert k32.contacts is not k64.contacts
    assert k32.contacts.__name__ == "tumble._float32.solver.contacts"
    assert k32.real.float_t is wp.float32 and k32.real.vec3 is wp.vec3f and k32.real.quat is wp.quatf
    assert k64.real.float_t is wp.float64 and k64.real.vec3 is wp.vec3d and k64.real.mat33 is wp.mat33d
    # a copy reaches the other kernel modules of its own precision ...
    assert k32.contacts.Contacts is k32.narrowphase.Contacts
    assert k32.cloth.springs is k32.springs
    # ... and shares every other module, and the classes listed as shared
    assert importlib.import_module("tumble._float32.state") is tumble.state
    assert importlib.import_module("tumble._float32.launch") is tumble.launch
    assert k32.wind.Wind is tumble.Wind
    assert precision.kernels("float32") is k32  # imported once


def test_kernel_modules_take_their_float_types_from_real_only():
    """A kernel module that named a float type from anywhere else would compile float64 in both copies."""
    floats = {"float_t", "vec3", "quat", "mat33", "vec2", "mat22"}
    # float64 types named outright would stay float64 in the float32 copy (float32 ones are how
    # both copies talk to Warp's meshes, whose points and queries are float32)
    fixed = {"float64", "vec3d", "quatd", "mat33d", "vec2d", "mat22d"}
    for path in precision.KERNEL_MODULES:
        if path == "real":
            continue
        tree = ast.parse((SRC / (path.replace(".", "/") + ".py")).read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module != "real":
                named = {a.name for a in node.names} & floats
                assert not named, f"{path} imports {named} from {node.module}"
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "wp":
                assert node.attr not in fixed, f"{path} names wp.{node.attr}"


def test_a_bad_precision_is_refused_by_name():
    with pytest.raises(ValueError, match="precision must be one of 'float32', 'float64', got 'float16'"):
        tumble.World(precision="float16")  # type: ignore[arg-type]
    with pytest.raises(SceneError, match="precision"):
        build_world(parse_scene('[world]\nprecision = "double"\n'))


@BOTH
def test_every_array_of_a_world_is_in_its_precision(p):
    world = load_scene("hammock", precision=p)
    world.step()
    want = precision.types_of(p).numpy
    assert world.precision == p
    assert world.body_position.dtype == want and world.body_velocity.dtype == want
    assert world.cloth.particle_position.dtype == want
    for group in (world.bodies, world.contacts, world.cloth.particles):
        for name, a in group.arrays.items():
            if a.dtype in (wp.int32, wp.uint32, wp.int64):
                continue
            assert precision.precision_of_dtype(a.dtype) == p, name


def test_scene_files_choose_the_precision():
    world = build_world(parse_scene('[world]\nprecision = "float32"\n[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\n'))
    assert world.precision == "float32"
    assert build_world(parse_scene("[world]\n")).precision == precision.DEFAULT_PRECISION


@BOTH
def test_free_fall_follows_the_scheme_to_the_precision(p):
    """Semi-implicit Euler over N substeps of h from rest: z_N = z0 - g h^2 N (N + 1) / 2.

    Each substep rounds v and z once, so the error is at most ~N eps (|z| + |v| h) summed: the bound
    below is that with a factor 4, float64's ~1e-12 m, float32's ~1e-3 m.
    """
    world = tumble.World(gravity=(0, 0, -9.81), precision=p)
    ball = world.add_sphere(position=(0.0, 0.0, 10.0), radius=0.1, mass=1.0)
    steps = 240
    world.run(steps * world.dt)
    h = world.dt / world.substeps
    n = steps * world.substeps
    expected = 10.0 - 9.81 * h * h * n * (n + 1) / 2
    eps = precision.types_of(p).eps
    bound = 4 * n * eps * (10.0 + 9.81 * steps * world.dt * h)
    assert abs(float(ball.position[2]) - expected) <= bound
    assert abs(float(ball.velocity[2]) + 9.81 * h * n) <= 4 * n * eps * 9.81 * steps * world.dt


@BOTH
def test_a_dropped_ball_bounces_to_e_squared_h_in_either_precision(p):
    """Dropped from H = 1 m onto a plane, e = 0.5: the apex is e^2 H (the impact pass gives the analytic
    bounce at any substep count, to 1e-4 of H in float64), and float32 adds its rounding: one eps of the
    height a substep, ~1920 substeps to the first apex."""
    world = tumble.World(precision=p)
    world.add_plane(normal=(0, 0, 1), restitution=0.5)
    ball = world.add_sphere(position=(0.0, 0.0, 1.1), radius=0.1, mass=1.0, restitution=0.5)
    apex, falling_again = 0.0, False
    was_rising = False
    for _ in range(int(1.2 / world.dt)):
        world.step()
        vz, z = float(ball.velocity[2]), float(ball.position[2]) - 0.1
        if vz > 0:
            was_rising = True
            apex = max(apex, z)
        elif was_rising:
            falling_again = True
            break
    assert falling_again
    # the apex is sampled once a step: within |v| dt of the true one, where v ~ g dt near the top
    sampled = 9.81 * world.dt**2
    rounding = 2 * world.substeps * (1.2 / world.dt) * precision.types_of(p).eps
    assert abs(apex - 0.25) <= 1e-4 + sampled + rounding


@BOTH
def test_float32_and_float64_agree_to_float32_rounding_on_an_incline(p):
    """A ball rolling without slipping down a 20 degree slope accelerates at 5/7 g sin(theta)."""
    theta = math.radians(20.0)
    n = (0.0, -math.sin(theta), math.cos(theta))
    world = tumble.World(precision=p)
    world.add_plane(normal=n, friction=1.0)
    r = 0.1
    ball = world.add_sphere(position=np.array(n) * r, radius=r, mass=1.0, friction=1.0)
    world.run(60 * world.dt)
    v0 = np.array(ball.velocity, dtype=np.float64)
    world.run(120 * world.dt)
    dv = np.linalg.norm(np.array(ball.velocity, dtype=np.float64) - v0)
    expected = 5.0 / 7.0 * 9.81 * math.sin(theta) * 120 * world.dt
    # float64's test tolerance for this scheme (physics tests) plus float32's rounding over the substeps
    tol = 2e-3 * expected + 180 * world.substeps * precision.types_of(p).eps * 9.81 * world.dt
    assert abs(dv - expected) <= tol


@BOTH
def test_the_same_scene_gives_the_same_trajectory_bit_for_bit(p):
    hashes = []
    for _ in range(2):
        world = load_scene("rain", precision=p)  # an emitter with its random generator, boxes and spheres
        world.run(0.5)
        hashes.append(world.state_hash())
    assert hashes[0] == hashes[1]


def test_a_float32_snapshot_resumes_bit_for_bit(tmp_path):
    straight = load_scene("box_tower", precision="float32")
    straight.run(1.0)
    straight.run(0.5)
    resumed = load_scene("box_tower", precision="float32")
    resumed.run(1.0)
    snapshot.save(resumed.snapshot(), tmp_path / "s.npz")
    loaded = tumble.load_snapshot(tmp_path / "s.npz")
    assert loaded.precision == "float32"
    loaded.run(0.5)
    assert loaded.state_hash() == straight.state_hash()


def test_a_snapshot_restores_only_into_a_world_of_its_precision():
    w32, w64 = load_scene("bouncing_ball", precision="float32"), load_scene("bouncing_ball", precision="float64")
    with pytest.raises(snapshot.SnapshotError, match="float64 world and this world is float32"):
        w32.restore(w64.snapshot())
    with pytest.raises(snapshot.SnapshotError, match="float32 world and this world is float64"):
        w64.restore(w32.snapshot())


def test_the_default_is_read_at_each_world(monkeypatch):
    for p in precision.PRECISIONS:
        monkeypatch.setattr(precision, "DEFAULT_PRECISION", p)
        assert tumble.World().precision == p
        assert build_world(parse_scene("[world]\n")).precision == p


@pytest.mark.float64("checks the marker itself")
def test_the_float64_marker_makes_worlds_float64():
    assert tumble.World().precision == "float64"


def test_a_scene_whose_sizes_do_not_fit_float32_is_refused_by_table():
    text = '[world]\nprecision = "float32"\n[[box]]\nposition = [0, 0, 1]\nhalf_extents = [1e-20, 1e-20, 1e-20]\nmass = 1e-30\n'
    with pytest.raises(SceneError, match=r"box\[0\].*does not fit a float32 world"):
        build_world(parse_scene(text))
    assert build_world(parse_scene(text.replace("float32", "float64"))).body_count == 1
