"""collision/hashgrid.py: the counting-sort grid against brute force, and the Morton order.

A small query kernel here walks the 27 cells around each point through the grid's public
arrays (`cell_of`, `cell_hash`, `cell_start`, `cell_count`, `entries`, `sorted_coord`); the
pairs it finds within one cell edge must be exactly the brute-force list of all pairs.
"""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from tumble.collision.hashgrid import HashGrid, cell_hash, cell_of, spatial_order
from tumble.state import float_t, vec3

DEVICE = "cpu"


@wp.kernel
def _pairs_within(
    x: wp.array(dtype=vec3),
    inv_cell: float_t,
    mask: int,
    distance: float_t,
    cell_start: wp.array(dtype=wp.int32),
    cell_count: wp.array(dtype=wp.int32),
    entries: wp.array(dtype=wp.int32),
    sorted_coord: wp.array(dtype=wp.vec3i),
    pair_count: wp.array(dtype=wp.int32),
    pairs: wp.array(dtype=wp.vec2i),
):
    i = wp.tid()
    c = cell_of(x[i], inv_cell)
    for dz in range(-1, 2):
        for dy in range(-1, 2):
            for dx in range(-1, 2):
                cell = wp.vec3i(c[0] + dx, c[1] + dy, c[2] + dz)
                h = cell_hash(cell, mask)
                start = cell_start[h]
                for e in range(start, start + cell_count[h]):
                    j = entries[e]
                    other = sorted_coord[e]
                    # another cell may share the slot: keep only this cell's points
                    same = other[0] == cell[0] and other[1] == cell[1] and other[2] == cell[2]
                    if same and j > i and wp.length(x[j] - x[i]) < distance:
                        k = wp.atomic_add(pair_count, 0, 1)
                        if k < pairs.shape[0]:
                            pairs[k] = wp.vec2i(i, j)


def brute_force_pairs(x: np.ndarray, distance: float) -> set[tuple[int, int]]:
    d = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=2)
    i, j = np.nonzero(np.triu(d < distance, k=1))
    return set(zip(i.tolist(), j.tolist()))


def grid_pairs(grid: HashGrid, xs: wp.array, n: int, distance: float) -> set[tuple[int, int]]:
    count = wp.zeros(1, dtype=wp.int32, device=DEVICE)
    out = wp.zeros(64 * n, dtype=wp.vec2i, device=DEVICE)
    wp.launch(
        _pairs_within,
        dim=n,
        inputs=[
            xs,
            grid.inv_cell,
            grid.mask,
            distance,
            grid.cell_start,
            grid.cell_count,
            grid.entries,
            grid.sorted_coord,
            count,
            out,
        ],
        device=DEVICE,
    )
    k = int(count.numpy()[0])
    assert k <= out.shape[0], "more pairs than the test's buffer holds"
    found = [tuple(p) for p in out.numpy()[:k].tolist()]
    assert len(found) == len(set(found)), "a pair was found twice"
    return set(found)


@pytest.mark.parametrize(("n", "spread", "cell", "seed"), [(300, 2.0, 0.25, 0), (500, 0.6, 0.1, 1), (200, 4.0, 1.5, 2)])
def test_pairs_found_through_the_grid_equal_brute_force(n, spread, cell, seed):
    """Every pair closer than the cell edge is found once, and no other (random points, negative coordinates too)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-spread, spread, size=(n, 3))
    xs = wp.array(x, dtype=vec3, device=DEVICE)
    grid = HashGrid(DEVICE).build(xs, n, cell)
    expected = brute_force_pairs(x, cell)
    assert len(expected) > 10  # the scene has pairs to find
    assert grid_pairs(grid, xs, n, cell) == expected


def test_cells_partition_the_points_in_index_order():
    """Each slot's entries are the points hashed to it, in index order; the sorted copies match them."""
    rng = np.random.default_rng(3)
    n, cell = 400, 0.3
    x = rng.normal(size=(n, 3))
    xs = wp.array(x, dtype=vec3, device=DEVICE)
    grid = HashGrid(DEVICE).build(xs, n, cell)
    assert (grid.mask + 1) & grid.mask == 0 and grid.mask + 1 >= 4 * n  # a power of two, load 1/4 or less
    coord = np.floor(x / cell).astype(np.int32)
    np.testing.assert_array_equal(grid.point_cell_coord.numpy()[:n], coord)
    slot = grid.point_cell.numpy()[:n]
    start, count, entries = grid.cell_start.numpy(), grid.cell_count.numpy(), grid.entries.numpy()[:n]
    assert count.sum() == n
    for h in np.unique(slot):
        members = entries[start[h] : start[h] + count[h]]
        np.testing.assert_array_equal(members, np.flatnonzero(slot == h))
    np.testing.assert_array_equal(grid.sorted_x.numpy()[:n], x[entries])
    np.testing.assert_array_equal(grid.sorted_coord.numpy()[:n], coord[entries])


def test_points_with_a_radius_over_the_limit_are_left_out():
    """Points whose radius exceeds max_radius get slot -1 and appear in no cell."""
    x = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.2, 0.0, 0.0], [5.0, 5.0, 5.0]])
    radius = wp.array(np.array([0.05, 2.0, 0.05, 3.0]), dtype=float_t, device=DEVICE)
    grid = HashGrid(DEVICE).build(wp.array(x, dtype=vec3, device=DEVICE), 4, 0.5, radius=radius, max_radius=1.0)
    slot = grid.point_cell.numpy()[:4]
    assert slot[1] == -1 and slot[3] == -1 and slot[0] >= 0 and slot[2] >= 0
    assert grid.cell_count.numpy().sum() == 2
    np.testing.assert_array_equal(np.sort(grid.entries.numpy()[:2]), [0, 2])


def test_rebuild_after_the_points_move_and_grow():
    """A second build of more, moved points (the buffers grow) is again complete."""
    rng = np.random.default_rng(4)
    grid = HashGrid(DEVICE)
    for n in (50, 700):
        x = rng.uniform(-1.0, 1.0, size=(n, 3))
        xs = wp.array(x, dtype=vec3, device=DEVICE)
        grid.build(xs, n, 0.2)
        assert grid_pairs(grid, xs, n, 0.2) == brute_force_pairs(x, 0.2)


def test_struct_is_the_grid_as_kernels_take_it_and_kept_while_its_buffers_are():
    """struct() holds the grid's table and buffers and the last build's cell edge (in `params`); it is the
    same struct until the buffers are reallocated, and another one for other params."""
    rng = np.random.default_rng(6)
    grid = HashGrid(DEVICE)
    x = wp.array(rng.uniform(-1.0, 1.0, size=(50, 3)), dtype=vec3, device=DEVICE)
    cells = grid.build(x, 50, 0.2).struct()
    assert cells.cell_start is grid.cell_start and cells.entries is grid.entries and cells.mask == grid.mask
    assert cells.point_cell_coord is grid.point_cell_coord and cells.params.numpy()[1] == pytest.approx(5.0)
    assert grid.struct() is cells
    assert grid.build(x, 50, 0.25).struct() is cells and cells.params.numpy()[1] == pytest.approx(4.0)
    more = wp.array(rng.uniform(-1.0, 1.0, size=(700, 3)), dtype=vec3, device=DEVICE)
    grown = grid.build(more, 700, 0.25).struct()
    assert grown is not cells and grown.entries is grid.entries and grown.mask == grid.mask
    params = wp.zeros(3, dtype=float_t, device=DEVICE)
    assert grid.struct(params).params is params and grid.struct() is not grown


def morton_key(c: np.ndarray) -> int:
    """Bit k of x, y, z goes to bit 3k, 3k + 1, 3k + 2 of the key (written bit by bit)."""
    key = 0
    for bit in range(21):
        for axis in range(3):
            key |= ((int(c[axis]) >> bit) & 1) << (3 * bit + axis)
    return key


def test_spatial_order_is_the_stable_morton_order():
    """The order sorts cells by their interleaved bits, ties in index order; a permutation."""
    rng = np.random.default_rng(5)
    x = rng.uniform(0.0, 10.0, size=(300, 3))
    x[50] = x[10]  # a tie: the lower index first
    order = spatial_order(x, 0.5)
    np.testing.assert_array_equal(np.sort(order), np.arange(300))
    cells = np.floor((x - x.min(axis=0)) / 0.5).astype(np.int64)
    keys = np.array([morton_key(c) for c in cells])
    np.testing.assert_array_equal(order, np.argsort(keys, kind="stable"))
    assert list(order).index(10) < list(order).index(50)


def test_spatial_order_of_the_2x2x2_block_and_of_non_finite_points():
    """Unit cells of one block come x first, then y, then z; NaN rows are placed, not lost."""
    corners = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=float) + 0.5
    shuffled = corners[[7, 2, 5, 0, 3, 6, 1, 4]]
    order = spatial_order(shuffled, 1.0)
    np.testing.assert_array_equal(shuffled[order], corners)
    with_nan = np.vstack([corners, [np.nan, 0.0, 0.0]])
    assert sorted(spatial_order(with_nan, 1.0)) == list(range(9))
    assert len(spatial_order(np.zeros((0, 3)), 1.0)) == 0
