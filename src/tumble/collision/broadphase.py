"""Broad phase: a spatial hash built by counting sort -> candidate pairs.

Reads body positions, velocities and bounding radii; writes `pair_a`, `pair_b` (int32, one row
per candidate pair). Expected cost O(n) for bodies of similar size: each body is hashed into
one cell of a uniform grid, cells are sorted by counting sort (count, exclusive scan,
scatter), and each body scans the cells its swept bound can reach.

Rules that keep it exact and duplicate-free:
- a body's swept radius R = bound radius + dt * (|v| + |w| * bound) + margin, so fast bodies
  find their partners before they arrive (speculative contacts, no tunnelling);
- a pair is emitted by its body with the larger R (ties: the lower row), which scans
  the cells overlapping its position +- 2 R; a body that would scan more than `MAX_RANGE` cells each way
  (planes, huge static boxes, very fast bodies) tests every body directly instead;
- pairs of two static bodies are dropped;
- a pair is stored lower body id first, so it keeps its order (and warm start) when the world
  renumbers its rows; pairs come out in the row order of their emitting bodies.

Tuning: the cell edge is twice the largest swept radius among ordinary bodies (bound radius no
more than 4x the median, swept radius no more than 1.5x the largest such bound), which is the
typical shape diameter plus its motion in one step. Outliers scan more cells rather than make
every cell bigger.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..launch import LaunchCache, launch
from ..model import body_struct
from ..real import BodyArrays, float_t, vec3
from ..shapes import ShapeType
from ..state import host_values
from .hashgrid import Grid, HashGrid, cell_hash, cell_of

#: extra swept radius [m] so that resting neighbours stay paired
MARGIN = 0.002
#: cells scanned each way before a body switches to testing all bodies
MAX_RANGE = 6
_HALF_RANGE = wp.constant(float_t(0.5 * MAX_RANGE))


@wp.kernel
def _swept_radius(b: BodyArrays, dt: float_t, margin: float_t, radius: wp.array(dtype=float_t)):
    i = wp.tid()
    if b.shape[i] == int(ShapeType.PLANE):
        radius[i] = b.bound_radius[i]  # inf
    else:
        bound = b.bound_radius[i]
        radius[i] = bound + dt * (wp.length(b.velocity[i]) + wp.length(b.angular_velocity[i]) * bound) + margin


@wp.kernel
def _cell_size(radius: wp.array(dtype=float_t), n: int, limit: float_t, params: wp.array(dtype=float_t)):
    # one thread: cell edge = twice the largest swept radius up to `limit` (ordinary bodies),
    # else the last one (params[0]); then its inverse and the largest radius kept in the grid
    largest = float_t(0.0)
    found = int(0)
    for i in range(n):
        r = radius[i]
        if r <= limit:
            if found == 0 or r > largest:
                largest = r
            found = 1
    cell = params[0]
    if found != 0:
        cell = float_t(2.0) * largest
    params[0] = cell
    params[1] = float_t(1.0) / cell
    params[2] = _HALF_RANGE * cell


@wp.func
def _emits(i: int, j: int, ri: float_t, rj: float_t, inv_mass: wp.array(dtype=float_t)):
    # the body with the larger swept radius (ties: lower index) emits; static-static never
    if inv_mass[i] == float_t(0.0) and inv_mass[j] == float_t(0.0):
        return False
    return rj < ri or (rj == ri and j > i)


@wp.struct
class PairList:
    """The candidate pairs as kernels write them: `count[0]` pairs (body rows `a[k]`, `b[k]`); a
    query counts past the capacity when it overflows, and the host grows the buffers."""

    count: wp.array(dtype=wp.int32)
    a: wp.array(dtype=wp.int32)
    b: wp.array(dtype=wp.int32)


@wp.func
def _push_pair(i: int, j: int, body_id: wp.array(dtype=wp.int32), pairs: PairList):
    # stored lower id first, so a pair keeps its order (and its warm start) from step to step,
    # even when the world renumbers its body rows
    k = wp.atomic_add(pairs.count, 0, 1)
    if k < pairs.a.shape[0]:
        if body_id[i] < body_id[j]:
            pairs.a[k] = i
            pairs.b[k] = j
        else:
            pairs.a[k] = j
            pairs.b[k] = i


@wp.kernel
def _query_large(n: int, b: BodyArrays, radius: wp.array(dtype=float_t), g: Grid, pairs: PairList):
    # bodies too big for the grid (planes, huge static boxes, very fast bodies) test every body
    i = wp.tid()
    if g.point_cell[i] >= 0:
        return
    ri = radius[i]
    xi = b.position[i]
    nrm = wp.quat_rotate(b.orientation[i], vec3(float_t(0.0), float_t(0.0), float_t(1.0)))
    for j in range(n):
        if j != i and _emits(i, j, ri, radius[j], b.inv_mass):
            near = False
            if b.shape[i] == int(ShapeType.PLANE):
                near = wp.dot(nrm, b.position[j] - xi) < radius[j]  # signed distance to the plane
            else:
                near = wp.length(b.position[j] - xi) < ri + radius[j]
            if near:
                _push_pair(i, j, b.id, pairs)


@wp.kernel
def _query_grid(b: BodyArrays, radius: wp.array(dtype=float_t), g: Grid, pairs: PairList):
    # one thread per body, in index order, so that pairs (and the contacts made from them) come
    # out sorted by their emitting body: the solver then walks body memory nearly in order
    # (cell order, being hashed, would send it all over the body arrays: 3x slower at 100k)
    i = wp.tid()
    if g.point_cell[i] < 0:
        return
    inv_cell = g.params[1]
    ri = radius[i]
    xi = b.position[i]
    # partners have R_j <= R_i, so they lie within 2 R_i along each axis
    reach = vec3(float_t(2.0) * ri, float_t(2.0) * ri, float_t(2.0) * ri)
    lo = cell_of(xi - reach, inv_cell)
    hi = cell_of(xi + reach, inv_cell)
    for cz in range(lo[2], hi[2] + 1):
        for cy in range(lo[1], hi[1] + 1):
            for cx in range(lo[0], hi[0] + 1):
                h = cell_hash(wp.vec3i(cx, cy, cz), g.mask)
                start = g.cell_start[h]
                for e in range(start, start + g.cell_count[h]):
                    rj = g.sorted_radius[e]
                    reach_ij = ri + rj
                    if wp.length_sq(g.sorted_x[e] - xi) < reach_ij * reach_ij:
                        # hash collisions: only take j from the cell it really lives in
                        cj = g.sorted_coord[e]
                        if cj[0] == cx and cj[1] == cy and cj[2] == cz:
                            j = g.entries[e]
                            if j != i and _emits(i, j, ri, rj, b.inv_mass):
                                _push_pair(i, j, b.id, pairs)


class BroadPhase:
    """Owns the grid and pair buffers; `find_pairs` fills them for the current state.

    Attributes:
        pair_a, pair_b: candidate pairs, int32 arrays; the first `pair_count` rows are valid.
        cell_size: grid cell edge [m] used by the last call.
    """

    #: a cache that snapshots keep by name only: the pair buffers as the queries take them
    SNAPSHOT_CACHES = frozenset({"_pair_list"})

    def __init__(self, device: str):
        self.device = device
        self.grid = HashGrid(device)
        self.pair_capacity = 64
        self.pair_a = wp.zeros(self.pair_capacity, dtype=wp.int32, device=device)
        self.pair_b = wp.zeros(self.pair_capacity, dtype=wp.int32, device=device)
        self.pair_count_array = wp.zeros(1, dtype=wp.int32, device=device)
        self._pair_list: PairList | None = None
        self.pair_count = 0
        self.cell_size = 1.0
        self.cell_params = wp.zeros(3, dtype=float_t, device=device)  # cell edge, its inverse, max radius
        self._sized_for = -1
        self._body_capacity = 0
        self._ordinary_limit = np.inf

    def graph_key(self) -> tuple:
        """What the recorded launches of this stage bake in: its limits, capacities and the arrays it
        launches with (a recorded graph of `launch` is valid while this tuple is unchanged)."""
        grid = self.grid
        return (
            self._ordinary_limit,
            self.pair_capacity,
            id(self.pair_a),
            id(self.swept_radius),
            grid.mask,
            id(grid.cell_count),
            id(grid.entries),
        )

    def bodies_changed(self) -> None:
        """Bodies were removed (or replaced): size the grid afresh at the next `find_pairs`."""
        self._sized_for = -1

    def _resize(self, bodies) -> None:
        """Size the buffers and find the ordinary bodies when the body count changed (not every step)."""
        n = bodies.count
        shape = bodies.numpy("body_shape")
        bound = bodies.numpy("body_bound_radius")
        finite = bound[(shape != ShapeType.PLANE) & np.isfinite(bound)]
        self._ordinary_limit = np.inf
        if len(finite):
            ordinary = finite[finite <= 4.0 * np.median(finite)]
            self.cell_size = 2.0 * float(ordinary.max()) + 2.0 * MARGIN
            # swept radii up to this size set the cell; faster or bigger bodies scan more cells
            self._ordinary_limit = 1.5 * float(ordinary.max()) + MARGIN
        if bodies.capacity != self._body_capacity:
            self._body_capacity = bodies.capacity
            self.swept_radius = wp.zeros(bodies.capacity, dtype=float_t, device=self.device)
        self.grid.reserve(n)
        params = np.array([self.cell_size, 0.0, 0.0])  # the fallback cell edge (see _cell_size)
        if self.device == "cpu":
            self.cell_params.numpy()[:] = params
        else:
            self.cell_params.assign(params)
        self._sized_for = n

    def find_pairs(self, bodies, dt: float, cache: LaunchCache | None = None) -> BroadPhase:
        """Fill `pair_a`/`pair_b` with every pair whose swept bounds overlap; returns self.

        With `cache`, the launches are recorded once and replayed (see tumble.launch).
        """
        if self.begin(bodies):
            self.launch(bodies, dt, cache)
            self.end(bodies, cache)
        return self

    def begin(self, bodies) -> bool:
        """Host side before `launch`: size the buffers; False (and no pairs) for fewer than two bodies."""
        n = bodies.count
        if n != self._sized_for:
            self._resize(bodies)
        if n < 2:
            self.pair_count = 0
            return False
        return True

    def launch(self, bodies, dt: float, cache: LaunchCache | None = None) -> None:
        """Every launch of the pair search, with no host decision between them (so it can be recorded)."""
        n = bodies.count
        dev = self.device
        launch(_swept_radius, n, [body_struct(bodies), dt, MARGIN, self.swept_radius], dev, cache)
        # cell edge: twice the largest swept radius among ordinary bodies, so most scan 2-3 cells a side
        launch(_cell_size, 1, [self.swept_radius, n, self._ordinary_limit, self.cell_params], dev, cache)
        # counting sort of bodies into hashed cells; the biggest stay out and test everything
        self.grid.build_from(bodies.arrays["body_position"], n, self.cell_params, self.swept_radius, cache)
        self.pair_count_array.zero_()
        self._query(bodies, cache)

    def _query(self, bodies, cache: LaunchCache | None) -> None:
        n = bodies.count
        args = [body_struct(bodies), self.swept_radius, self.grid.struct(self.cell_params), self._pairs()]
        launch(_query_grid, n, args, self.device, cache)
        launch(_query_large, n, [n, *args], self.device, cache)

    def _pairs(self) -> PairList:
        """The pair buffers as the queries write them (the same struct while the buffers are)."""
        p = self._pair_list
        if p is None or p.a is not self.pair_a:
            p = self._pair_list = PairList()
            p.count, p.a, p.b = self.pair_count_array, self.pair_a, self.pair_b
        return p

    def end(self, bodies, cache: LaunchCache | None = None) -> bool:
        """Host side after `launch`: read the pair count; grow the pair buffers and query again if
        they overflowed. Returns True if it queried again (pairs found by a recorded narrow phase
        that followed the first query are then incomplete)."""
        count = host_values(self.pair_count_array)[0]
        again = False
        while count > self.pair_capacity:
            again = True
            self.pair_capacity = max(count, 2 * self.pair_capacity)
            self.pair_a = wp.zeros(self.pair_capacity, dtype=wp.int32, device=self.device)
            self.pair_b = wp.zeros(self.pair_capacity, dtype=wp.int32, device=self.device)
            self.pair_count_array.zero_()
            self._query(bodies, cache)
            count = host_values(self.pair_count_array)[0]
        self.pair_count = count
        self.cell_size = float(host_values(self.cell_params)[0])
        return again
