"""tumble.model: the one declaration of the body arrays, and the Model / State / Control parts of a World."""

from __future__ import annotations

import numpy as np
import pytest

import tumble
from tumble.model import (
    BODY_FIELDS,
    Control,
    Model,
    Role,
    State,
    body_arrays,
    body_arrays_struct,
    body_struct,
    fields_of,
)
from tumble.precision import specialize


@pytest.fixture
def world() -> tumble.World:
    w = tumble.World(dt=1 / 240, substeps=2)
    w.add_plane()
    w.add_sphere(position=(0, 0, 0.5), radius=0.1)
    w.add_box(position=(0.5, 0, 0.5), half_extents=(0.1, 0.1, 0.1))
    return w


def test_each_body_field_is_declared_once_with_a_role_and_a_unit_string():
    names = [f.name for f in BODY_FIELDS]
    assert len(names) == len(set(names))
    assert all(n.startswith("body_") for n in names)
    assert all(isinstance(f.role, Role) and isinstance(f.unit, str) and f.doc for f in BODY_FIELDS)
    # what the issue places where: poses and velocities are state, user forces control, masses model
    role = {f.name: f.role for f in BODY_FIELDS}
    assert role["body_position"] is role["body_angular_velocity"] is Role.STATE
    assert role["body_force"] is role["body_torque"] is Role.CONTROL
    assert role["body_mass"] is role["body_inv_inertia"] is role["body_shape"] is Role.MODEL
    assert role["body_warm_velocity"] is role["body_delta_position"] is Role.SCRATCH


def test_the_world_is_built_from_parts_that_split_the_fields_between_them(world):
    assert isinstance(world.model, Model) and isinstance(world.state, State) and isinstance(world.control, Control)
    parts = {
        Role.MODEL: world.model.bodies,
        Role.STATE: world.state.bodies,
        Role.CONTROL: world.control.bodies,
    }
    for role, part in parts.items():
        assert set(part.fields) == set(fields_of(BODY_FIELDS, role))
        assert part.count == world.body_count == 3
    # the stages' table holds every field once, scratch included, over the same arrays
    assert set(world.bodies.fields) == {f.name for f in BODY_FIELDS}
    assert world.bodies.arrays["body_position"] is world.state.bodies.arrays["body_position"]
    assert world.hulls is world.model.hulls and world.meshes is world.model.meshes
    # the state's warm-start contacts are the contact solver's
    assert world.state.contacts is world.contacts.previous


def test_state_step_count_and_pose_change_while_the_model_does_not(world):
    model_before = {n: world.model.bodies.numpy(n).copy() for n in world.model.bodies.fields}
    pose_before = world.state.bodies.numpy("body_position").copy()
    world.run(0.1)
    assert world.state.step_count == world.step_count == 24
    for n, values in model_before.items():
        np.testing.assert_array_equal(world.model.bodies.numpy(n), values, err_msg=n)
    assert not np.array_equal(world.state.bodies.numpy("body_position"), pose_before)


def test_control_is_cleared_after_the_step_that_used_it(world):
    world.apply_force(world.body(1), (1.0, 0.0, 0.0))
    assert world.control.bodies.numpy("body_force")[1, 0] == 1.0
    world.step()
    np.testing.assert_array_equal(world.control.bodies.numpy("body_force"), 0.0)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_kernel_struct_derives_from_the_declaration(precision):
    world = tumble.World(precision=precision)
    world.add_plane(normal=(0, 0, 1))
    world.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    kernel = [f for f in BODY_FIELDS if f.kernel]
    short = [f.name.removeprefix("body_") for f in kernel]
    struct = body_arrays_struct(precision)
    assert list(struct.vars) == short
    # each array field in the precision's types: float64 as declared, float32 specialised
    for f, name in zip(kernel, short):
        assert struct.vars[name].type.dtype is specialize(f.dtype, precision)
    s, arrays = body_arrays(world.bodies)
    assert isinstance(s, struct.cls)
    for f, name, a in zip(kernel, short, arrays):
        assert getattr(s, name) is world.bodies.arrays[f.name] is a
    # cached while the arrays are the same, rebuilt when they were reallocated
    assert body_arrays(world.bodies, (s, arrays))[0] is s
    world.add_spheres(position=np.zeros((40, 3)) + (0, 0, 2), radius=0.01)
    assert body_arrays(world.bodies, (s, arrays))[0] is not s


def test_views_are_documented_from_the_declaration():
    doc = tumble.World.body_position.__doc__
    assert "[m]" in doc and "(n, 3)" in doc
    assert "int32" in tumble.World.body_shape.__doc__
    assert "[kg]" in tumble.World.body_mass.__doc__


def test_snapshots_hold_state_not_scratch_and_each_array_once(world):
    world.run(0.05)
    snap = world.snapshot()
    saved = set(snap.arrays)
    assert not any("body_warm_velocity" in p or "body_delta_position" in p for p in saved)
    assert any(p.endswith("state/bodies/body_position") for p in saved)
    assert any(p.endswith("model/bodies/body_mass") for p in saved)
    assert any(p.endswith("control/bodies/body_force") for p in saved)
    # the warm-start contacts are held by the state and by the contact solver: saved under one path
    prev = [p for p in saved if p.endswith("previous_impulse_n")]
    assert len(prev) == 1, prev


def test_a_restore_into_a_smaller_world_grows_the_solver_scratch(world):
    big = tumble.World(dt=1 / 240, substeps=2)
    big.add_plane()
    big.add_sphere(position=(0, 0, 0.5), radius=0.1)
    big.add_box(position=(0.5, 0, 0.5), half_extents=(0.1, 0.1, 0.1))
    big.bodies.reserve(100)
    snap = big.snapshot()
    world.restore(snap)
    for name in fields_of(BODY_FIELDS, Role.SCRATCH):
        assert world.bodies.arrays[name].shape[0] >= world.bodies.capacity == 100
    world.run(0.05)
    big.run(0.05)
    assert world.state_hash() == big.state_hash()


def test_numpy_views_match_declared_shapes(world):
    for f in BODY_FIELDS:
        assert world.bodies.numpy(f.name).shape == (3, *f.shape), f.name
        # the declared (float64) types, in the world's precision
        assert world.bodies.arrays[f.name].dtype == specialize(f.dtype, world.precision), f.name


def _flag_on_a_hinge() -> tumble.World:
    """A cloth in the wind beside a hinged box: every part has cloth and joint rows."""
    w = tumble.World(dt=1 / 240, substeps=2)
    box = w.add_box(position=(0, 0, 1), half_extents=(0.1, 0.1, 0.1), mass=1.0)
    w.add_joint("hinge", None, box, anchor=(0, 0, 1.2), axis=(1, 0, 0))
    w.add_cloth(size=(0.4, 0.3), resolution=(5, 4), position=(1, 0, 1), pins="top-edge")
    w.set_wind(velocity=(0.0, 2.0, 0.0))
    return w


def test_joint_fields_split_between_model_state_and_the_solver():
    """JOINT_FIELDS: definitions to the model, impulses and broken flags to the state, the step's sums are scratch."""
    from tumble.solver.joints import JOINT_FIELDS, Joints

    role = {f.name: f.role for f in JOINT_FIELDS}
    assert role["joint_kind"] is role["joint_local_a"] is role["joint_break_force"] is Role.MODEL
    assert role["joint_enabled"] is role["joint_impulse_linear"] is role["joint_force"] is Role.STATE
    assert role["joint_sum_linear"] is Role.SCRATCH
    # the kernels' one struct has every field, in declaration order
    assert list(Joints.vars) == [f.name.removeprefix("joint_") for f in JOINT_FIELDS]  # type: ignore[attr-defined]
    w = _flag_on_a_hinge()
    assert set(w.model.joints.fields) == set(fields_of(JOINT_FIELDS, Role.MODEL))
    assert set(w.state.joints.fields) == set(fields_of(JOINT_FIELDS, Role.STATE))
    assert w.model.joints.count == w.state.joints.count == w.joint_count == 1
    definitions = {n: w.model.joints.numpy(n).copy() for n in w.model.joints.fields}
    w.run(0.1)
    for n, values in definitions.items():
        np.testing.assert_array_equal(w.model.joints.numpy(n), values, err_msg=n)
    assert np.abs(w.state.joints.numpy("joint_impulse_linear")).max() > 0.0


def test_cloth_particles_split_between_model_state_and_control():
    """PARTICLE_FIELDS: masses and pins to the model, positions to the state, drags to the control; wind too."""
    from tumble.cloth.system import PARTICLE_FIELDS

    w = _flag_on_a_hinge()
    assert (w.model.cloth, w.state.cloth, w.control.cloth) == w.cloth.parts
    for role, part in ((Role.MODEL, w.model.cloth), (Role.STATE, w.state.cloth), (Role.CONTROL, w.control.cloth)):
        assert set(part.particles.fields) == set(fields_of(PARTICLE_FIELDS, role))
        assert part.particles.count == w.cloth.particle_count == 20
    # one table over the parts' arrays and the stage's scratch rows
    assert set(w.cloth.particles.fields) == {f.name for f in PARTICLE_FIELDS}
    assert w.cloth.particles.arrays["particle_position"] is w.state.cloth.particles.arrays["particle_position"]
    assert "spring_ids" in w.model.cloth.topology and len(w.model.cloth.cloths) == 1
    assert w.control.wind is w.cloth.wind and w.control.wind.velocity[1] == 2.0
    mass = w.model.cloth.particles.numpy("particle_mass").copy()
    x = w.state.cloth.particles.numpy("particle_position").copy()
    w.cloth.apply_force(7, (0.0, 0.0, 1.0))
    assert w.control.cloth.forces
    w.step()
    assert not w.control.cloth.forces
    assert w.control.cloth.particles.numpy("particle_external_force")[7, 2] == 1.0  # during that step
    w.step()
    np.testing.assert_array_equal(w.control.cloth.particles.numpy("particle_external_force"), 0.0)
    np.testing.assert_array_equal(w.model.cloth.particles.numpy("particle_mass"), mass)
    assert not np.array_equal(w.state.cloth.particles.numpy("particle_position"), x)


def test_snapshots_hold_cloth_and_joint_state_once_and_no_scratch():
    w = _flag_on_a_hinge()
    w.run(0.05)
    saved = set(w.snapshot().arrays)
    for name in ("particle_position", "particle_mass", "particle_external_force", "joint_kind", "joint_impulse_linear"):
        assert len([p for p in saved if p.endswith("/" + name)]) == 1, name
    for name in ("particle_force", "particle_position_prev", "particle_wind", "joint_sum_linear"):
        assert not any(p.endswith("/" + name) for p in saved), name


def test_body_struct_is_kept_per_row_group_while_its_arrays_stay(world):
    """body_struct gives one struct per row group, over its arrays, and a new one once they were reallocated."""
    s = body_struct(world.bodies)
    assert (
        s.velocity is world.bodies.arrays["body_velocity"]
        and s.bound_radius is world.bodies.arrays["body_bound_radius"]
    )
    assert body_struct(world.bodies) is s
    other = tumble.World()
    other.add_plane()
    assert body_struct(other.bodies) is not s
    world.add_spheres(position=np.zeros((40, 3)) + (0, 0, 2), radius=0.01)
    t = body_struct(world.bodies)
    assert t is not s and t.position is world.bodies.arrays["body_position"]
