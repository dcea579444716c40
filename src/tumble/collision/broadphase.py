"""Broad phase: a spatial hash built by counting sort -> candidate pairs.

Reads body positions, velocities and bounding radii; writes `pair_a`, `pair_b` (int32, one row
per candidate pair). Expected cost O(n) for bodies of similar size: each body is hashed into
one cell of a uniform grid, cells are sorted by counting sort (count, exclusive scan,
scatter), and each body scans the cells its swept bound can reach.

Rules that keep it exact and duplicate-free:
- a body's swept radius R = bound radius + dt * (|v| + |w| * bound) + margin, so fast bodies
  find their partners before they arrive (speculative contacts, no tunnelling);
- a pair is emitted by its body with the larger R (ties: the lower index), which scans
  the cells overlapping its position +- 2 R; a body that would scan more than `MAX_RANGE` cells each way
  (planes, huge static boxes, very fast bodies) tests every body directly instead;
- pairs of two static bodies are dropped.

Tuning: the cell size is twice the largest bound radius among ordinary bodies (those no more
than 4x the median), which is the typical shape diameter.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..shapes import ShapeType
from ..state import float_t, vec3

#: extra swept radius [m] so that resting neighbours stay paired
MARGIN = 0.002
#: cells scanned each way before a body switches to testing all bodies
MAX_RANGE = 6


@wp.func
def _cell_of(x: vec3, inv_cell: float_t):
    return wp.vec3i(
        int(wp.floor(x[0] * inv_cell)), int(wp.floor(x[1] * inv_cell)), int(wp.floor(x[2] * inv_cell))
    )


@wp.func
def _hash(c: wp.vec3i, mask: int):
    # large odd primes, XOR-folded (Teschner et al. 2003)
    h = (c[0] * 92837111) ^ (c[1] * 689287499) ^ (c[2] * 283923481)
    return h & mask


@wp.kernel
def _swept_radius(
    shape: wp.array(dtype=wp.int32),
    bound: wp.array(dtype=float_t),
    v: wp.array(dtype=vec3),
    w: wp.array(dtype=vec3),
    dt: float_t,
    margin: float_t,
    radius: wp.array(dtype=float_t),
):
    i = wp.tid()
    if shape[i] == int(ShapeType.PLANE):
        radius[i] = bound[i]  # inf
    else:
        radius[i] = bound[i] + dt * (wp.length(v[i]) + wp.length(w[i]) * bound[i]) + margin


@wp.kernel
def _count_cells(
    x: wp.array(dtype=vec3),
    radius: wp.array(dtype=float_t),
    inv_cell: float_t,
    mask: int,
    max_radius: float_t,
    body_cell: wp.array(dtype=wp.int32),
    cell_count: wp.array(dtype=wp.int32),
):
    i = wp.tid()
    if radius[i] > max_radius:
        body_cell[i] = -1  # scans everything itself, nobody needs to find it in the grid
        return
    h = _hash(_cell_of(x[i], inv_cell), mask)
    body_cell[i] = h
    wp.atomic_add(cell_count, h, 1)


@wp.kernel
def _scatter_cells(
    body_cell: wp.array(dtype=wp.int32),
    cell_start: wp.array(dtype=wp.int32),
    cell_fill: wp.array(dtype=wp.int32),
    cell_entries: wp.array(dtype=wp.int32),
):
    i = wp.tid()
    h = body_cell[i]
    if h >= 0:
        cell_entries[cell_start[h] + wp.atomic_add(cell_fill, h, 1)] = i


@wp.func
def _emits(i: int, j: int, ri: float_t, rj: float_t, inv_mass: wp.array(dtype=float_t)):
    # the body with the larger swept radius (ties: lower index) emits; static-static never
    if inv_mass[i] == float_t(0.0) and inv_mass[j] == float_t(0.0):
        return False
    return rj < ri or (rj == ri and j > i)


@wp.func
def _push_pair(i: int, j: int, pair_count: wp.array(dtype=wp.int32), pair_a: wp.array(dtype=wp.int32),
               pair_b: wp.array(dtype=wp.int32)):
    # stored lower index first, so a pair keeps its order (and its warm start) from step to step
    k = wp.atomic_add(pair_count, 0, 1)
    if k < pair_a.shape[0]:
        pair_a[k] = wp.min(i, j)
        pair_b[k] = wp.max(i, j)


@wp.kernel
def _query(
    n: int,
    shape: wp.array(dtype=wp.int32),
    x: wp.array(dtype=vec3),
    q: wp.array(dtype=wp.quatd),
    radius: wp.array(dtype=float_t),
    inv_mass: wp.array(dtype=float_t),
    inv_cell: float_t,
    cell: float_t,
    mask: int,
    max_radius: float_t,
    cell_start: wp.array(dtype=wp.int32),
    cell_count: wp.array(dtype=wp.int32),
    cell_entries: wp.array(dtype=wp.int32),
    pair_count: wp.array(dtype=wp.int32),
    pair_a: wp.array(dtype=wp.int32),
    pair_b: wp.array(dtype=wp.int32),
):
    i = wp.tid()
    ri = radius[i]
    xi = x[i]
    if ri > max_radius:
        # too big for the grid: test every body directly (planes test signed distance)
        for j in range(n):
            if j != i and _emits(i, j, ri, radius[j], inv_mass):
                near = False
                if shape[i] == int(ShapeType.PLANE):
                    nrm = wp.quat_rotate(q[i], vec3(float_t(0.0), float_t(0.0), float_t(1.0)))
                    near = wp.dot(nrm, x[j] - xi) < radius[j]
                else:
                    near = wp.length(x[j] - xi) < ri + radius[j]
                if near:
                    _push_pair(i, j, pair_count, pair_a, pair_b)
        return
    # scan the cells the swept bound can reach
    # partners have R_j <= R_i, so they lie within 2 R_i along each axis
    reach = vec3(float_t(2.0) * ri, float_t(2.0) * ri, float_t(2.0) * ri)
    lo = _cell_of(xi - reach, inv_cell)
    hi = _cell_of(xi + reach, inv_cell)
    for cz in range(lo[2], hi[2] + 1):
        for cy in range(lo[1], hi[1] + 1):
            for cx in range(lo[0], hi[0] + 1):
                cc = wp.vec3i(cx, cy, cz)
                h = _hash(cc, mask)
                start = cell_start[h]
                for e in range(start, start + cell_count[h]):
                    j = cell_entries[e]
                    if j != i and _emits(i, j, ri, radius[j], inv_mass):
                        cj = _cell_of(x[j], inv_cell)
                        # hash collisions: only take j from the cell it really lives in
                        if cj[0] == cc[0] and cj[1] == cc[1] and cj[2] == cc[2]:
                            if wp.length(x[j] - xi) < ri + radius[j]:
                                _push_pair(i, j, pair_count, pair_a, pair_b)


class BroadPhase:
    """Owns the grid and pair buffers; `find_pairs` fills them for the current state.

    Attributes:
        pair_a, pair_b: candidate pairs, int32 arrays; the first `pair_count` rows are valid.
        cell_size: grid cell edge [m] used by the last call.
    """

    def __init__(self, device: str):
        self.device = device
        self.pair_capacity = 1024
        self.pair_a = wp.zeros(self.pair_capacity, dtype=wp.int32, device=device)
        self.pair_b = wp.zeros(self.pair_capacity, dtype=wp.int32, device=device)
        self.pair_count_array = wp.zeros(1, dtype=wp.int32, device=device)
        self.pair_count = 0
        self.cell_size = 1.0
        self._sized_for = -1
        self._table = 0
        self._body_capacity = 0

    def _resize(self, bodies) -> None:
        """Choose the cell size and table size when the body count changed (not every step)."""
        n = bodies.count
        shape = bodies.numpy("body_shape")
        bound = bodies.numpy("body_bound_radius")
        finite = bound[(shape != ShapeType.PLANE) & np.isfinite(bound)]
        if len(finite):
            ordinary = finite[finite <= 4.0 * np.median(finite)]
            self.cell_size = 2.0 * float(ordinary.max()) + 2.0 * MARGIN
        table = 1 << max(10, int(np.ceil(np.log2(max(2 * n, 1)))))
        if table != self._table:
            self._table = table
            self.cell_count = wp.zeros(table, dtype=wp.int32, device=self.device)
            self.cell_start = wp.zeros(table, dtype=wp.int32, device=self.device)
            self.cell_fill = wp.zeros(table, dtype=wp.int32, device=self.device)
        if bodies.capacity != self._body_capacity:
            self._body_capacity = bodies.capacity
            self.swept_radius = wp.zeros(bodies.capacity, dtype=float_t, device=self.device)
            self.body_cell = wp.zeros(bodies.capacity, dtype=wp.int32, device=self.device)
            self.cell_entries = wp.zeros(bodies.capacity, dtype=wp.int32, device=self.device)
        self._sized_for = n

    def find_pairs(self, bodies, dt: float) -> BroadPhase:
        """Fill `pair_a`/`pair_b` with every pair whose swept bounds overlap; returns self."""
        n = bodies.count
        if n != self._sized_for:
            self._resize(bodies)
        if n < 2:
            self.pair_count = 0
            return self
        b = bodies.arrays
        dev = self.device
        wp.launch(_swept_radius, dim=n, device=dev,
                  inputs=[b["body_shape"], b["body_bound_radius"], b["body_velocity"], b["body_angular_velocity"],
                          dt, MARGIN, self.swept_radius])
        inv_cell = 1.0 / self.cell_size
        max_radius = 0.5 * MAX_RANGE * self.cell_size
        mask = self._table - 1

        # counting sort of bodies into hashed cells
        self.cell_count.zero_()
        self.cell_fill.zero_()
        wp.launch(_count_cells, dim=n, device=dev,
                  inputs=[b["body_position"], self.swept_radius, inv_cell, mask, max_radius, self.body_cell,
                          self.cell_count])
        wp.utils.array_scan(self.cell_count, self.cell_start, inclusive=False)
        wp.launch(_scatter_cells, dim=n, device=dev,
                  inputs=[self.body_cell, self.cell_start, self.cell_fill, self.cell_entries])

        # query; grow the pair buffers and query again if they overflowed
        while True:
            self.pair_count_array.zero_()
            wp.launch(_query, dim=n, device=dev,
                      inputs=[n, b["body_shape"], b["body_position"], b["body_orientation"], self.swept_radius,
                              b["body_inv_mass"], inv_cell, self.cell_size, mask, max_radius, self.cell_start,
                              self.cell_count, self.cell_entries, self.pair_count_array, self.pair_a, self.pair_b])
            count = int(self.pair_count_array.numpy()[0])
            if count <= self.pair_capacity:
                break
            self.pair_capacity = max(count, 2 * self.pair_capacity)
            self.pair_a = wp.zeros(self.pair_capacity, dtype=wp.int32, device=dev)
            self.pair_b = wp.zeros(self.pair_capacity, dtype=wp.int32, device=dev)
        self.pair_count = count
        return self
