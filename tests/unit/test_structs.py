"""structs.py: Warp structs of arrays derived from a field table, filled from named arrays."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from tumble.state import float_t, vec3
from tumble.structs import array_struct, cached_struct, fill_struct

FIELDS = {"thing_mass": float_t, "thing_position": vec3}
Things = array_struct("Things", FIELDS, "thing_", __name__)


@wp.kernel
def _lift(t: Things, dz: float_t):
    i = wp.tid()
    t.position[i] = t.position[i] + vec3(float_t(0.0), float_t(0.0), dz * t.mass[i])


def test_fields_are_the_table_without_its_prefix():
    """One array field per table entry, named without the prefix, with the entry's dtype."""
    assert list(Things.vars) == ["mass", "position"]
    assert Things.vars["position"].type.dtype is vec3
    assert Things.vars["mass"].type.dtype is float_t


def test_a_filled_struct_is_the_arrays_themselves():
    """fill_struct points the fields at the named arrays: a kernel's writes land in them."""
    arrays = {
        "thing_mass": wp.array(np.array([1.0, 2.0]), dtype=float_t),
        "thing_position": wp.zeros(2, dtype=vec3),
    }
    t = fill_struct(Things, arrays, "thing_")
    assert t.mass is arrays["thing_mass"] and t.position is arrays["thing_position"]
    wp.launch(_lift, dim=2, inputs=[t, 0.5], device="cpu")
    np.testing.assert_array_equal(arrays["thing_position"].numpy(), [[0.0, 0.0, 0.5], [0.0, 0.0, 1.0]])


def test_a_field_without_the_prefix_is_refused():
    """A table entry that does not start with the prefix is a ValueError naming it."""
    with pytest.raises(ValueError, match="body_mass"):
        array_struct("Bad", {"body_mass": float_t}, "thing_", __name__)


def test_a_table_may_name_an_array_type():
    """An entry that is a Warp array type (pairs of indices) is a field of that type."""
    Pairs = array_struct("Pairs", {"pair_ids": wp.array2d(dtype=wp.int32), "pair_length": float_t}, "pair_", __name__)
    assert Pairs.vars["ids"].type.ndim == 2 and Pairs.vars["ids"].type.dtype is wp.int32
    assert Pairs.vars["length"].type.ndim == 1


def test_a_cached_struct_is_kept_while_its_arrays_are_the_same():
    """cached_struct returns the cache while the table holds the same arrays, a new struct once one is replaced."""
    arrays = {"thing_mass": wp.zeros(2, dtype=float_t), "thing_position": wp.zeros(2, dtype=vec3)}
    first = cached_struct(Things, arrays, "thing_")
    assert cached_struct(Things, dict(arrays), "thing_", first) is first
    arrays["thing_mass"] = wp.zeros(4, dtype=float_t)
    second = cached_struct(Things, arrays, "thing_", first)
    assert second is not first and second[0].mass is arrays["thing_mass"]
