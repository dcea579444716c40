"""state.py: ArraySet and RowGroup storage (growth, rows, views, reordering, loading), read-only views and handles."""

from __future__ import annotations

import gc
import pickle

import numpy as np
import pytest
import warp as wp

import tumble
from tumble.state import (
    ArraySet,
    BodyId,
    ClothId,
    Handle,
    JointId,
    RowGroup,
    float_t,
    host_view,
    mat33,
    numpy_dtype,
    quat,
    readonly,
    vec3,
)

FIELDS = {"mass": float_t, "position": vec3, "orientation": quat, "frame": mat33, "tag": wp.int32}


def rows(k: int, start: int = 0) -> dict[str, np.ndarray]:
    """k rows whose values tell their number (start, start + 1, ...)."""
    i = np.arange(start, start + k, dtype=np.float64)
    return {
        "mass": i + 0.5,
        "position": np.stack([i, 2 * i, 3 * i], axis=1),
        "orientation": np.tile([0.0, 0.0, 0.0, 1.0], (k, 1)) * (i[:, None] + 1),
        "tag": np.arange(start, start + k, dtype=np.int32),
    }


def test_numpy_dtype_gives_scalar_type_and_row_shape():
    """Each Warp row type maps to a NumPy scalar type and the trailing shape of one row."""
    assert numpy_dtype(float_t) == (np.float64, ())
    assert numpy_dtype(vec3) == (np.float64, (3,))
    assert numpy_dtype(quat) == (np.float64, (4,))
    assert numpy_dtype(mat33) == (np.float64, (3, 3))
    assert numpy_dtype(wp.int32) == (np.int32, ())


def test_append_returns_the_new_rows_and_zeroes_missing_fields():
    """Rows land after the existing ones; a field not given is zero (frame here)."""
    s = ArraySet(FIELDS, device="cpu", capacity=8)
    assert (s.count, s.capacity) == (0, 8)
    assert s.append(rows(3)) == range(0, 3)
    assert s.append(rows(2, start=3)) == range(3, 5)
    assert s.count == 5
    np.testing.assert_array_equal(s.numpy("tag"), np.arange(5))
    np.testing.assert_array_equal(s.numpy("position")[4], [4.0, 8.0, 12.0])
    assert s.numpy("frame").shape == (5, 3, 3) and not s.numpy("frame").any()
    assert s.numpy("mass", count=2).shape == (2,)


def test_growth_doubles_the_capacity_and_keeps_every_row():
    """Appending past the capacity reallocates at max(needed, 2 x old) with the old rows intact."""
    s = ArraySet(FIELDS, device="cpu", capacity=4)
    s.append(rows(3))
    old = s.arrays["position"]
    s.append(rows(2, start=3))  # 5 rows > 4: doubled to 8
    assert s.capacity == 8 and s.arrays["position"] is not old
    s.append(rows(20, start=5))  # 25 rows > 2 x 8: exactly what is needed
    assert (s.count, s.capacity) == (25, 25)
    expected = rows(25)
    for name in ("mass", "position", "orientation", "tag"):
        np.testing.assert_array_equal(s.numpy(name), expected[name])
    assert all(arr.shape == (25,) for arr in s.arrays.values())


def test_reserve_reallocates_only_when_it_must():
    """reserve below the capacity keeps the arrays (same objects); above it reallocates."""
    s = ArraySet(FIELDS, device="cpu", capacity=16)
    s.append(rows(4))
    arrays = dict(s.arrays)
    assert s.reserve(16) is False
    assert all(s.arrays[name] is arrays[name] for name in FIELDS)
    assert s.reserve(17) is True
    assert s.capacity == 32
    np.testing.assert_array_equal(s.numpy("tag"), np.arange(4))


def test_attribute_access_and_unknown_names():
    """A field reads as an attribute; any other name is an AttributeError."""
    s = ArraySet(FIELDS, device="cpu")
    assert s.tag is s.arrays["tag"]
    with pytest.raises(AttributeError):
        _ = s.velocity


def test_numpy_is_a_view_of_the_array_and_write_changes_it():
    """On the CPU `numpy` shares memory with the Warp array; `write` sets rows by index or slice."""
    s = ArraySet(FIELDS, device="cpu")
    s.append(rows(4))
    s.write("mass", [1, 3], [10.0, 30.0])
    s.write("position", slice(0, 2), np.zeros((2, 3)))
    np.testing.assert_array_equal(s.arrays["mass"].numpy()[:4], [0.5, 10.0, 2.5, 30.0])
    np.testing.assert_array_equal(s.numpy("position")[:2], np.zeros((2, 3)))
    view = host_view(s.arrays["mass"])
    assert host_view(s.arrays["mass"]) is view  # made once per array
    view[0] = -1.0
    assert s.arrays["mass"].numpy()[0] == -1.0


def test_take_reorders_and_drops_rows_of_every_field():
    """take(rows): new row k is old row rows[k], in every field; rows left out are gone."""
    s = ArraySet(FIELDS, device="cpu")
    s.append(rows(5))
    s.take(np.array([4, 0, 2]))
    assert s.count == 3
    np.testing.assert_array_equal(s.numpy("tag"), [4, 0, 2])
    np.testing.assert_array_equal(s.numpy("position")[:, 0], [4.0, 0.0, 2.0])
    np.testing.assert_array_equal(s.numpy("mass"), [4.5, 0.5, 2.5])
    s.permute(np.array([2, 1, 0]))
    np.testing.assert_array_equal(s.numpy("tag"), [2, 0, 4])


def test_load_keeps_the_arrays_at_the_same_capacity_and_reallocates_otherwise():
    """load puts saved arrays back; same capacity: the same array objects (recorded launches stay valid)."""
    s = ArraySet(FIELDS, device="cpu", capacity=8)
    s.append(rows(6))
    saved = {name: arr.numpy().copy() for name, arr in s.arrays.items()}
    s.write("tag", slice(0, 6), np.zeros(6))
    same = s.arrays["tag"]
    s.load(saved, count=6, capacity=8)
    assert s.arrays["tag"] is same
    np.testing.assert_array_equal(s.numpy("tag"), np.arange(6))
    bigger = {name: np.concatenate([a, np.zeros_like(a)]) for name, a in saved.items()}
    s.load(bigger, count=6, capacity=16)
    assert s.capacity == 16 and s.arrays["tag"] is not same and s.arrays["tag"].shape == (16,)
    np.testing.assert_array_equal(s.numpy("position"), rows(6)["position"])


def test_readonly_view_refuses_writes_and_follows_the_data():
    """readonly(a) cannot be written, and shows later changes made to a."""
    a = np.arange(4.0)
    v = readonly(a)
    with pytest.raises(ValueError):
        v[0] = 9.0
    a[1] = 7.0
    assert v[1] == 7.0 and a.flags.writeable


def test_handles_compare_by_index_generation_and_world():
    """Equal handles match in index, generation, world and kind; a handle equals its plain index."""
    assert BodyId(3, 1, 7) == BodyId(3, 1, 7)
    assert BodyId(3, 1, 7) != BodyId(3, 2, 7)
    assert BodyId(3, 1, 7) != BodyId(3, 1, 8)
    assert BodyId(3) != ClothId(3)
    assert BodyId(3, 5, 7) == 3 and hash(BodyId(3, 5, 7)) == hash(3)
    assert [10, 11, 12, 13][BodyId(2)] == 12  # indexes like an int
    assert repr(BodyId(3, 2)) == "BodyId(3, generation=2)" and str(BodyId(3)) == "3"


def test_handles_are_immutable_and_pickle_whole():
    """Setting or deleting an attribute raises; a pickled handle keeps generation and world key."""
    h = BodyId(4, 2, 9)
    with pytest.raises(AttributeError, match="immutable"):
        h.generation = 3
    with pytest.raises(AttributeError, match="immutable"):
        del h.world_key
    back = pickle.loads(pickle.dumps(h))
    assert type(back) is BodyId and back == h and (back.generation, back.world_key) == (2, 9)


def test_a_handle_finds_its_world_only_while_it_lives():
    """handle.world is the world that made it; a bare id, or one whose world is gone, raises HandleError."""
    world = tumble.World()
    ball = world.add_sphere(position=(0.0, 0.0, 1.0), radius=0.1)
    assert ball.world is world
    np.testing.assert_array_equal(ball.position, [0.0, 0.0, 1.0])
    with pytest.raises(tumble.HandleError, match="bare id"):
        _ = Handle(0).world
    del world
    gc.collect()
    with pytest.raises(tumble.HandleError, match="no longer exists"):
        _ = ball.world


def _group(capacity: int = 4) -> tuple[RowGroup, ArraySet, ArraySet]:
    shared: dict = {}
    a = ArraySet({"mass": float_t, "tag": wp.int32}, device="cpu", capacity=capacity, arrays=shared)
    b = ArraySet({"position": vec3, "orientation": quat}, device="cpu", capacity=capacity, arrays=shared)
    return RowGroup(a, b), a, b


def test_a_row_group_adds_reorders_and_grows_its_sets_together():
    group, a, b = _group()
    r = rows(6)
    added = group.append({k: r[k] for k in ("mass", "tag", "position")})
    assert added == range(0, 6) and a.count == b.count == group.count == 6
    assert a.capacity == b.capacity == group.capacity >= 6
    assert set(group.fields) == {"mass", "tag", "position", "orientation"} == set(group.arrays)
    np.testing.assert_array_equal(group.numpy("orientation"), 0.0)  # not given: zero
    group.take(np.array([5, 0, 3]))
    np.testing.assert_array_equal(group.numpy("tag"), [5, 0, 3])
    np.testing.assert_array_equal(group.numpy("position")[:, 0], [5.0, 0.0, 3.0])
    # each set holds its own fields only
    assert set(a.fields) == {"mass", "tag"} and not hasattr(a, "position") and a.tag is group.tag


def test_rows_dropped_by_take_are_zero_when_added_again():
    """A field not given for new rows is zero even where a dropped row left its values."""
    group, a, b = _group()
    r = rows(4, start=1)
    group.append(r | {"position": r["position"]})
    group.take(np.array([0]))
    group.append({"mass": np.ones(3)})
    np.testing.assert_array_equal(group.numpy("tag"), [1, 0, 0, 0])
    np.testing.assert_array_equal(group.numpy("position")[1:], 0.0)


def test_sync_grows_a_set_that_a_load_left_behind():
    group, a, b = _group()
    group.append({"mass": np.ones(2)})
    saved = {n: a.arrays[n].numpy().copy() for n in a.fields}
    a.load({n: np.resize(v, 64) for n, v in saved.items()}, count=2, capacity=64)
    assert b.capacity < 64
    group.sync()
    assert b.capacity >= 64 and b.count == 2 and group.capacity == 64


def test_a_row_group_needs_one_shared_dict():
    with pytest.raises(ValueError, match="share one arrays dict"):
        RowGroup(ArraySet({"x": float_t}, device="cpu"), ArraySet({"y": float_t}, device="cpu"))


def test_joint_handles_carry_their_world():
    w = tumble.World()
    a = w.add_sphere(position=(0, 0, 1), radius=0.1)
    joint = w.add_joint("ball", a, None, anchor=(0, 0, 1.2))
    assert isinstance(joint, JointId) and joint.index == 0 and joint.world is w


def test_a_value_a_float32_set_cannot_hold_is_refused_and_changes_nothing():
    """Cast to float32, 1e39 would become inf and 1e-40 zero: the set refuses both, naming the field,
    before it writes any row."""
    import pytest

    from tumble.state import ArraySet, float_t, vec3

    s = ArraySet({"a_x": float_t, "a_v": vec3}, device="cpu", precision="float32")
    s.append({"a_x": np.array([1.0]), "a_v": np.zeros((1, 3))})
    for bad in (1e39, 1e-40, -1e39):
        with pytest.raises(ValueError, match="a_v: .* does not fit a float32 world"):
            s.append({"a_x": np.array([2.0]), "a_v": np.array([[0.0, bad, 0.0]])})
        with pytest.raises(ValueError, match="a_x: .* does not fit a float32 world"):
            s.write("a_x", slice(0, 1), [bad])
    assert s.count == 1 and s.numpy("a_x")[0] == 1.0
    # inf and nan are not "lost" (they are the same in float32) and zero stays zero
    s.append({"a_x": np.array([np.inf]), "a_v": np.zeros((1, 3))})
    assert s.count == 2
    # float64 holds them
    d = ArraySet({"a_x": float_t}, device="cpu")
    d.append({"a_x": np.array([1e39, 1e-40])})
    assert d.numpy("a_x").tolist() == [1e39, 1e-40]
