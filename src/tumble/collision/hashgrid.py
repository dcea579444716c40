"""A spatial hash built by counting sort, shared by the bodies' broad phase and cloth self-collision.

Reads point positions (and optionally a radius per point); writes, per hashed cell, the range
`cell_start[h] .. cell_start[h] + cell_count[h]` of `entries`, the points sorted by cell.
Cost O(n) per build, allocation-free once sized: count points per cell (atomic add), exclusive
scan, scatter (Ten Minute Physics, "Spatial hashing"). On the CPU, Warp runs threads in order,
so points within a cell stay in index order and the build is deterministic.

Queries walk the cells around a point (`cell_of`, `cell_hash`) and, since different cells can
hash to one slot, compare the entry's cell coordinates with the cell being walked. Positions,
radii and coordinates are copied in cell order during the scatter, so each cell is one
contiguous read.

Tuning: a cell edge of about the largest interaction distance keeps each query to 2-3 cells a
side; the table has four times as many slots as points (see `cell_hash`).
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ..launch import LaunchCache, launch
from ..real import float_t, vec3
from ..structs import cached_struct

# no adjoint code: nothing differentiates through Tumble's kernels, and it doubles the compile time
wp.set_module_options({"enable_backward": False})

#: hash table slots per point (a power of two): flat point sets fill a quarter of each block's slots
TABLE_LOAD = 4


@wp.func
def cell_of(x: vec3, inv_cell: float_t):
    """Integer cell coordinates of a point."""
    return wp.vec3i(int(wp.floor(x[0] * inv_cell)), int(wp.floor(x[1] * inv_cell)), int(wp.floor(x[2] * inv_cell)))


@wp.func
def cell_hash(c: wp.vec3i, mask: int):
    """Table slot of a cell.

    Blocks of 4 x 4 x 4 cells are hashed (coordinates mixed by large primes, Teschner et al.
    2003) to runs of 64 consecutive slots, one slot per cell of the block: a query's
    neighbouring cells then mostly sit in one or two cache lines of the table (1.6x faster
    broad phase at 100k bodies than hashing each cell on its own).
    """
    hx = wp.uint32(c[0] >> 2) * wp.uint32(73856093)
    hy = wp.uint32(c[1] >> 2) * wp.uint32(19349663)
    hz = wp.uint32(c[2] >> 2) * wp.uint32(83492791)
    local = wp.uint32((c[0] & 3) | ((c[1] & 3) << 2) | ((c[2] & 3) << 4))
    return int((((hx ^ hy ^ hz) << wp.uint32(6)) | local) & wp.uint32(mask))


@wp.struct
class Grid:
    """A `HashGrid`'s arrays as kernels take them (`HashGrid.struct`; its fields are the grid's
    attributes of those names, `params` aside: see `struct`)."""

    params: wp.array(dtype=float_t)  # (cell edge [m], its inverse [1/m], largest radius kept in the grid)
    mask: int  # table size - 1
    cell_start: wp.array(dtype=wp.int32)  # per slot: its first row of `entries`
    cell_count: wp.array(dtype=wp.int32)  # per slot: its number of points
    cell_fill: wp.array(dtype=wp.int32)  # per slot: points scattered so far (during a build)
    entries: wp.array(dtype=wp.int32)  # the point indices, sorted by slot
    sorted_x: wp.array(dtype=vec3)  # row e: the position, radius and cell coordinates of entries[e]
    sorted_radius: wp.array(dtype=float_t)
    sorted_coord: wp.array(dtype=wp.vec3i)
    point_cell: wp.array(dtype=wp.int32)  # per point: its slot, -1 when left out
    point_cell_coord: wp.array(dtype=wp.vec3i)  # per point: its cell's coordinates


@wp.kernel
def _count(x: wp.array(dtype=vec3), radius: wp.array(dtype=float_t), g: Grid, when: wp.array(dtype=wp.int32)):
    i = wp.tid()
    if when[0] == 0:
        return  # (a build skipped on the device: see `build_from`)
    if radius[i] > g.params[2]:
        g.point_cell[i] = -1  # left out of the grid (its owner queries it some other way)
        return
    c = cell_of(x[i], g.params[1])
    h = cell_hash(c, g.mask)
    g.point_cell[i] = h
    g.point_cell_coord[i] = c
    wp.atomic_add(g.cell_count, h, 1)


@wp.kernel
def _scatter(x: wp.array(dtype=vec3), radius: wp.array(dtype=float_t), g: Grid, when: wp.array(dtype=wp.int32)):
    i = wp.tid()
    if when[0] == 0:
        return
    h = g.point_cell[i]
    if h >= 0:
        e = g.cell_start[h] + wp.atomic_add(g.cell_fill, h, 1)
        g.entries[e] = i
        # copies in cell order, so a query reads each cell's points from contiguous memory
        g.sorted_x[e] = x[i]
        g.sorted_radius[e] = radius[i]
        g.sorted_coord[e] = g.point_cell_coord[i]


_ALWAYS: dict[str, wp.array] = {}


def _always(device) -> wp.array:
    """A flag that is always set, on `device`: `HashGrid.build_from`'s default `when` (one per device,
    not per grid, so that a grid restored from an older snapshot needs no array it lacks)."""
    key = str(device)
    flag = _ALWAYS.get(key)
    if flag is None:
        flag = _ALWAYS[key] = wp.ones(1, dtype=wp.int32, device=device)
    return flag


class HashGrid:
    """Points sorted into hashed cells.

    Attributes:
        cell_size: cell edge of the last build [m]; `inv_cell` its inverse.
        mask: table size - 1 (the table size is a power of two).
        cell_start, cell_count: per slot, where its points start in `entries` and how many.
        entries: point indices sorted by slot, int32.
        sorted_x, sorted_radius, sorted_coord: position, radius and cell coordinates of
            `entries[e]` at row e, so queries read each cell contiguously.
        point_cell: slot of each point (-1 when left out), int32.
        point_cell_coord: integer cell coordinates of each point, vec3i.
    """

    # the grid as kernels take it (`struct`), made on first use and again when an array changes; a class
    # default, so that a grid restored from a snapshot older than it has it too
    _grid: tuple | None = None

    def __init__(self, device: str):
        self.device = device
        self.cell_size = 1.0
        self.inv_cell = 1.0
        self.mask = 0
        self._points = 0
        self.params = wp.zeros(3, dtype=float_t, device=device)  # what `build` was given, for the kernels

    def reserve(self, count: int) -> None:
        """Size the table and the point buffers for `count` points (allocates only when they grow)."""
        self._reserve(count)

    def _reserve(self, count: int) -> None:
        table = 1 << max(10, math.ceil(math.log2(max(TABLE_LOAD * count, 1))))
        if table != self.mask + 1:
            self.mask = table - 1
            self.cell_count = wp.zeros(table, dtype=wp.int32, device=self.device)
            self.cell_start = wp.zeros(table, dtype=wp.int32, device=self.device)
            self.cell_fill = wp.zeros(table, dtype=wp.int32, device=self.device)
        if count > self._points:
            self._points = max(count, 2 * self._points)
            self.point_cell = wp.zeros(self._points, dtype=wp.int32, device=self.device)
            self.point_cell_coord = wp.zeros(self._points, dtype=wp.vec3i, device=self.device)
            self.entries = wp.zeros(self._points, dtype=wp.int32, device=self.device)
            self._no_radius = wp.zeros(self._points, dtype=float_t, device=self.device)
            self.sorted_x = wp.zeros(self._points, dtype=vec3, device=self.device)
            self.sorted_radius = wp.zeros(self._points, dtype=float_t, device=self.device)
            self.sorted_coord = wp.zeros(self._points, dtype=wp.vec3i, device=self.device)

    def build(
        self,
        x: wp.array,
        count: int,
        cell_size: float,
        radius: wp.array | None = None,
        max_radius: float = np.inf,
        cache: LaunchCache | None = None,
    ) -> HashGrid:
        """Sort the first `count` points of `x` into cells of edge `cell_size` [m].

        Points whose `radius` exceeds `max_radius` are left out (`point_cell` = -1). With
        `cache`, the launches are recorded once and replayed (see tumble.launch).
        """
        self._reserve(count)
        self.cell_size = float(cell_size)
        self.inv_cell = 1.0 / self.cell_size
        if radius is None:
            radius, max_radius = self._no_radius, np.inf
        params = np.array([self.cell_size, self.inv_cell, float(max_radius)])
        if self.device == "cpu":
            self.params.numpy()[:] = params  # the host view is the array
        else:
            self.params.assign(params)
        return self.build_from(x, count, self.params, radius, cache)

    def build_from(
        self,
        x: wp.array,
        count: int,
        params: wp.array,
        radius: wp.array,
        cache: LaunchCache | None = None,
        when: wp.array | None = None,
    ) -> HashGrid:
        """`build` with the cell edge, its inverse and `max_radius` read by the kernels from the
        device array `params` (so that they may be computed there); `cell_size` and `inv_cell`
        are then not updated. Call `reserve(count)` first.

        `when` (int32, one value, read on the device): the points are sorted into the cells only
        where it is not 0; else the table is left empty (a recorded build that runs only on the
        steps that need it, `BroadPhase`)."""
        self.cell_count.zero_()
        self.cell_fill.zero_()
        if count == 0:
            return self
        grid = self.struct(params)
        when = _always(self.device) if when is None else when
        launch(_count, count, [x, radius, grid, when], self.device, cache)
        wp.utils.array_scan(self.cell_count, self.cell_start, inclusive=False)
        launch(_scatter, count, [x, radius, grid, when], self.device, cache)
        return self

    def struct(self, params: wp.array | None = None) -> Grid:
        """The grid's arrays as kernels take them, with `params` (default: `self.params`, what `build`
        was given) as the cell edge, its inverse and the largest radius kept in the grid.

        The same struct comes back while the arrays are the same ones (a recorded launch then re-packs
        nothing); a struct is never changed once made, since recorded launches hold copies of it."""
        held = {**vars(self), "params": self.params if params is None else params}
        self._grid = cached_struct(Grid, held, "", self._grid)
        return self._grid[0]


def _spread_bits(v: np.ndarray) -> np.ndarray:
    """Spread the low 21 bits of each value so that two zero bits follow each bit."""
    v = v & 0x1FFFFF
    v = (v | (v << 32)) & 0x1F00000000FFFF
    v = (v | (v << 16)) & 0x1F0000FF0000FF
    v = (v | (v << 8)) & 0x100F00F00F00F00F
    v = (v | (v << 4)) & 0x10C30C30C30C30C3
    v = (v | (v << 2)) & 0x1249249249249249
    return v


def spatial_order(x: np.ndarray, cell_size: float) -> np.ndarray:
    """Indices that sort points along a Morton (Z-order) curve over cells of edge `cell_size`.

    Points close in space mostly end up close in the order; ties keep their index order, so
    the result is deterministic. Cost O(n log n) on the host.
    """
    n = len(x)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    finite = np.isfinite(x).all(axis=1)
    lo = x[finite].min(axis=0) if finite.any() else np.zeros(3)
    c = np.floor((np.where(finite[:, None], x, lo) - lo) / max(float(cell_size), 1e-9))
    c = np.clip(c, 0, (1 << 21) - 1).astype(np.int64)
    key = _spread_bits(c[:, 0]) | (_spread_bits(c[:, 1]) << 1) | (_spread_bits(c[:, 2]) << 2)
    return np.argsort(key, kind="stable")
