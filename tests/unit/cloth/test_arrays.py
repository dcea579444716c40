"""cloth/arrays.py: the particle and topology tables, and the structs the kernels take, in both precisions."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import tumble
from tumble import precision
from tumble.cloth import arrays

BOTH = pytest.mark.parametrize("p", precision.PRECISIONS)


@BOTH
def test_each_struct_has_an_array_of_each_entry_of_its_table_in_the_precision(p):
    """Particles, Springs, ... have one field per table entry, named without its entity, of the entry's type."""
    a = precision.kernels(p).cloth_arrays
    types = precision.types_of(p)
    tables = (
        (a.Particles, {f.name: f.dtype for f in a.PARTICLE_FIELDS}, "particle_"),
        (a.Springs, a.SPRING_FIELDS, "spring_"),
        (a.Structural, a.STRUCTURAL_FIELDS, "structural_"),
        (a.Stretch, a.STRETCH_FIELDS, "stretch_"),
        (a.Limits, a.LIMIT_FIELDS, "limit_"),
        (a.Tethers, a.TETHER_FIELDS, "tether_"),
    )
    for struct, table, prefix in tables:
        assert list(struct.vars) == [name.removeprefix(prefix) for name in table]
        for name, row in table.items():
            field = struct.vars[name.removeprefix(prefix)].type
            want = row.dtype if isinstance(row, wp.array) else row
            assert field.dtype is want and field.ndim == (row.ndim if isinstance(row, wp.array) else 1), name
    assert a.Particles.vars["position"].type.dtype is types.vec3
    assert a.Springs.vars["stiffness"].type.dtype is types.float_t


@BOTH
def test_a_cloth_holds_the_topology_the_table_declares(p):
    """ClothModel.topology has exactly the arrays of TOPOLOGY, each of its type (index rows 2-D, int32)."""
    world = tumble.World(precision=p)
    world.add_cloth(resolution=(4, 3), pins="top-corners")
    a = precision.kernels(p).cloth_arrays
    top = world.model.cloth.topology
    assert set(top) == set(a.TOPOLOGY)
    for name, row in a.TOPOLOGY.items():
        want = row.dtype if isinstance(row, wp.array) else row
        assert top[name].dtype is want and top[name].ndim == (row.ndim if isinstance(row, wp.array) else 1), name


def test_corners_are_a_triangle_s_three_particles():
    """corners(triangles, t) reads row t."""

    @wp.kernel
    def read(triangles: wp.array2d(dtype=wp.int32), out: wp.array(dtype=wp.vec3i)):
        t = wp.tid()
        i, j, k = arrays.corners(triangles, t)
        out[t] = wp.vec3i(i, j, k)

    rows = np.array([[0, 1, 2], [7, 5, 3]], dtype=np.int32)
    out = wp.zeros(2, dtype=wp.vec3i)
    wp.launch(read, dim=2, inputs=[wp.array(rows, dtype=wp.int32), out], device="cpu")
    np.testing.assert_array_equal(out.numpy(), rows)
