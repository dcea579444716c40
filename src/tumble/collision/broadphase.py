"""Broad phase: a spatial hash built by counting sort -> candidate pairs, kept over steps.

Reads body positions, velocities and bounding radii; writes `pair_a`, `pair_b` (int32, one row
per candidate pair). Expected cost O(n) for bodies of similar size: each body is hashed into
one cell of a uniform grid, cells are sorted by counting sort (count, exclusive scan,
scatter), and each body scans the cells its swept bound can reach.

Rules that keep it exact and duplicate-free:
- a body's swept radius R = bound radius + dt * (|v| + |w| * bound) + margin, so fast bodies
  find their partners before they arrive (speculative contacts, no tunnelling); a pair is a
  candidate when the two swept spheres overlap (a plane: when the body's centre is within R of it);
- a pair is emitted by its body with the larger R (ties: the lower row), which scans
  the cells overlapping its position +- 2 R; a body that would scan more than `MAX_RANGE` cells each way
  (planes, huge static boxes, very fast bodies) tests every body directly instead;
- pairs of two static bodies are dropped;
- a pair is stored lower body id first, so it keeps its order (and warm start) when the world
  renumbers its rows.

Kept over steps (a Verlet list): the grid is searched with fattened radii, R + `SKIN` x bound +
dt (|v| + |w| bound), and that "fat" list is kept, sorted by body rows, for as long as every body
stays inside its fattened sphere: R now + its distance from where it was then <= its fat radius
(planes: not moved or turned at all). Then every pair whose swept spheres overlap now was in the
fat list (|x_a - x_b| < R_a + R_b implies the same at the build within the distances moved), and
each step keeps the fat pairs that pass the candidate test above, in the fat list's order: the
same pairs, in the same order (by rows), as a search of this step's state alone would give, so
trajectories do not depend on when the list was built. A resting pile searches its grid once
every many steps; the test of every body and pair costs a few percent of a search. The
decision is made on the device, so a recorded step runs it without the host.

Tuning: the cell edge is twice the largest fat radius among ordinary bodies (bound radius no
more than 4x the median, fat radius no more than `1.5 + SKIN` times the largest such bound), which
is the typical shape diameter plus its motion in one step. Outliers scan more cells rather than
make every cell bigger.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..launch import LaunchCache, each_end, each_in_use, launch, launch_each
from ..model import body_struct
from ..real import BodyArrays, float_t, quat, vec3
from ..shapes import ShapeType
from ..state import host_values, host_view
from .hashgrid import Grid, HashGrid, cell_hash, cell_of

# no adjoint code: nothing differentiates through Tumble's kernels, and it doubles the compile time
wp.set_module_options({"enable_backward": False})

#: extra swept radius [m] so that resting neighbours stay paired
MARGIN = 0.002
#: the fat list's slack, as a fraction of each body's bound radius (besides another step's motion):
#: a body may move this far before the grid is searched again
SKIN = 0.25
#: cells scanned each way before a body switches to testing all bodies
MAX_RANGE = 6
_HALF_RANGE = wp.constant(float_t(0.5 * MAX_RANGE))


@wp.struct
class PairList:
    """The candidate pairs as kernels write them: `count[0]` pairs (body rows `a[k]`, `b[k]`); a
    query counts past the capacity when it overflows, and the host grows the buffers."""

    count: wp.array(dtype=wp.int32)
    a: wp.array(dtype=wp.int32)
    b: wp.array(dtype=wp.int32)


@wp.struct
class Built:
    """The fat list's build as the kernels take it: where each body row was and how far it may go."""

    stale: wp.array(dtype=wp.int32)  # one value: 1 when the grid must be searched again this step
    radius: wp.array(dtype=float_t)  # per body row: its fat radius [m] (planes: inf)
    position: wp.array(dtype=vec3)  # per body row: its centre at the build [m]
    orientation: wp.array(dtype=quat)  # per body row: its orientation at the build


@wp.kernel
def _check(n: int, b: BodyArrays, dt: float_t, margin: float_t, radius: wp.array(dtype=float_t), f: Built, serial: int):
    # every body's swept radius R now; the list is stale when a body left its fat sphere, or a plane moved
    for i in range(wp.tid(), each_end(wp.tid(), serial, n)):
        bound = b.bound_radius[i]
        if b.shape[i] == int(ShapeType.PLANE):
            radius[i] = bound  # inf
            if f.stale[0] == 0:
                q = b.orientation[i]
                q0 = f.orientation[i]
                turned = q[0] != q0[0] or q[1] != q0[1] or q[2] != q0[2] or q[3] != q0[3]
                if turned or wp.length_sq(b.position[i] - f.position[i]) != float_t(0.0):
                    f.stale[0] = 1
        else:
            r = bound + dt * (wp.length(b.velocity[i]) + wp.length(b.angular_velocity[i]) * bound) + margin
            radius[i] = r
            if f.stale[0] == 0:
                if r + wp.length(b.position[i] - f.position[i]) > f.radius[i]:
                    f.stale[0] = 1


@wp.kernel
def _fatten(
    n: int, b: BodyArrays, skin: float_t, radius: wp.array(dtype=float_t), f: Built, fat: PairList, serial: int
):
    # a stale list: every body's fat radius, R + skin x bound + (R - bound: its motion in one more step and
    # the margin), and its place now
    if f.stale[0] == 0:
        return
    if wp.tid() == 0:
        fat.count[0] = 0
    for i in range(wp.tid(), each_end(wp.tid(), serial, n)):
        r = radius[i]
        if b.shape[i] != int(ShapeType.PLANE):
            bound = b.bound_radius[i]
            r = r + (r - bound) + skin * bound
        f.radius[i] = r
        f.position[i] = b.position[i]
        f.orientation[i] = b.orientation[i]


@wp.kernel
def _cell_size(radius: wp.array(dtype=float_t), n: int, limit: float_t, params: wp.array(dtype=float_t), f: Built):
    # one thread: cell edge = twice the largest swept radius up to `limit` (ordinary bodies),
    # else the last one (params[0]); then its inverse and the largest radius kept in the grid
    if f.stale[0] == 0:
        return
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


@wp.func
def _above(b: BodyArrays, plane: int, j: int, rj: float_t):
    """Whether body j's centre is within rj of the plane (its signed distance along the plane's normal)."""
    nrm = wp.quat_rotate(b.orientation[plane], vec3(float_t(0.0), float_t(0.0), float_t(1.0)))
    return wp.dot(nrm, b.position[j] - b.position[plane]) < rj


@wp.func
def _near(b: BodyArrays, i: int, j: int, ri: float_t, rj: float_t):
    """The candidate test of bodies i and j with swept (or fat) radii ri, rj: their spheres overlap, or
    the one that is not a plane has its centre within its radius of the plane. The search with fat radii
    and each step's test of the kept pairs with swept ones take the same test, so that the kept list
    holds every pair a fresh search would find."""
    if b.shape[i] == int(ShapeType.PLANE):
        return _above(b, i, j, rj)
    if b.shape[j] == int(ShapeType.PLANE):
        return _above(b, j, i, ri)
    reach = ri + rj
    return wp.length_sq(b.position[j] - b.position[i]) < reach * reach


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
def _query_large(n: int, b: BodyArrays, radius: wp.array(dtype=float_t), g: Grid, pairs: PairList, f: Built):
    # bodies too big for the grid (planes, huge static boxes, very fast bodies) test every body
    i = wp.tid()
    if f.stale[0] == 0 or g.point_cell[i] >= 0:
        return
    ri = radius[i]
    for j in range(n):
        if j != i and _emits(i, j, ri, radius[j], b.inv_mass):
            if _near(b, i, j, ri, radius[j]):
                _push_pair(i, j, b.id, pairs)


@wp.func
def _query_body(i: int, b: BodyArrays, radius: wp.array(dtype=float_t), g: Grid, pairs: PairList):
    """The pairs body i emits: every body in the cells its reach covers whose swept bound overlaps its own."""
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


@wp.kernel
def _query_grid(
    n: int, b: BodyArrays, radius: wp.array(dtype=float_t), g: Grid, pairs: PairList, f: Built, serial: int
):
    # bodies in index order (one thread looping over them on the CPU, `launch_each`; one thread per body elsewhere)
    if f.stale[0] == 0:
        return
    for i in range(wp.tid(), each_end(wp.tid(), serial, n)):
        if g.point_cell[i] >= 0:
            _query_body(i, b, radius, g, pairs)


@wp.func
def _sort_key(i: int, j: int, by: int, inv_mass: wp.array(dtype=float_t)):
    """A pair's key for `_count_sort`: its lower row (`by` 0), its higher row (1), or 1 if it holds a
    static or kinematic body, else 0 (2)."""
    if by == 0:
        return wp.min(i, j)
    if by == 1:
        return wp.max(i, j)
    if inv_mass[i] == float_t(0.0) or inv_mass[j] == float_t(0.0):
        return 1
    return 0


@wp.func
def _count_sort(
    a: wp.array(dtype=wp.int32),
    b: wp.array(dtype=wp.int32),
    count: int,
    keys: int,
    by: int,
    inv_mass: wp.array(dtype=float_t),
    bucket: wp.array(dtype=wp.int32),
    out_a: wp.array(dtype=wp.int32),
    out_b: wp.array(dtype=wp.int32),
):
    """Rows 0..count of (a, b) into (out_a, out_b), stably by `_sort_key` (by `by`; keys 0 <= key < keys)."""
    for k in range(keys + 1):
        bucket[k] = 0
    for p in range(count):
        bucket[_sort_key(a[p], b[p], by, inv_mass) + 1] += 1
    for k in range(keys):
        bucket[k + 1] += bucket[k]
    for p in range(count):
        key = _sort_key(a[p], b[p], by, inv_mass)
        q = bucket[key]
        bucket[key] = q + 1
        out_a[q] = a[p]
        out_b[q] = b[p]


@wp.kernel
def _sort_pairs(
    n: int,
    b: BodyArrays,
    fat: PairList,
    f: Built,
    bucket: wp.array(dtype=wp.int32),
    scratch_a: wp.array(dtype=wp.int32),
    scratch_b: wp.array(dtype=wp.int32),
):
    # one thread (the CPU): a fresh fat list in an order of the pairs alone, not of the cells and threads
    # that found them: the pairs of two moving bodies first, then those with a static or kinematic body
    # (a plane's, a wall's), each part by its lower row, then its higher (three stable counting sorts
    # through the scratch rows). So the solver's passes take the ground's contacts after the pile's, as
    # the search's order had them (planes test every body after the grid's pairs): with the grounds'
    # contacts first, the largest overlaps of four 2,000-sphere piles were 13 % deeper, the ground's 34 %
    if f.stale[0] == 0:
        return
    count = wp.min(fat.count[0], fat.a.shape[0])  # (an overflowed list is searched again, bigger)
    _count_sort(fat.a, fat.b, count, n, 1, b.inv_mass, bucket, scratch_a, scratch_b)
    _count_sort(scratch_a, scratch_b, count, n, 0, b.inv_mass, bucket, fat.a, fat.b)
    _count_sort(fat.a, fat.b, count, 2, 2, b.inv_mass, bucket, scratch_a, scratch_b)
    for p in range(count):
        fat.a[p] = scratch_a[p]
        fat.b[p] = scratch_b[p]


@wp.kernel
def _keep_pairs(b: BodyArrays, radius: wp.array(dtype=float_t), fat: PairList, pairs: PairList, serial: int):
    # this step's candidates: the fat pairs whose swept spheres overlap now (a plane: the other body's
    # centre within its R of it), in the fat list's order (on the CPU; in any order elsewhere)
    for k in range(wp.tid(), each_in_use(wp.tid(), serial, fat.count[0], fat.a.shape[0])):
        i = fat.a[k]
        j = fat.b[k]
        if _near(b, i, j, radius[i], radius[j]):
            q = wp.atomic_add(pairs.count, 0, 1)
            if q < pairs.a.shape[0]:  # (as large as the fat list: `BroadPhase._grow`)
                pairs.a[q] = i
                pairs.b[q] = j


class _FatList:
    """The kept list (see the module's docstring): the fat pairs, where each body row was when they
    were found and how far it may go, and the sort's scratch rows."""

    def __init__(self, device: str, bodies: int, pairs: int):
        self.body_capacity, self.capacity = bodies, pairs
        self.built = Built()
        self.built.stale = wp.ones(1, dtype=wp.int32, device=device)
        self.built.radius = wp.zeros(bodies, dtype=float_t, device=device)
        self.built.position = wp.zeros(bodies, dtype=vec3, device=device)
        self.built.orientation = wp.zeros(bodies, dtype=quat, device=device)
        self.pairs = PairList()
        self.pairs.count = wp.zeros(1, dtype=wp.int32, device=device)
        self.pairs.a = wp.zeros(pairs, dtype=wp.int32, device=device)
        self.pairs.b = wp.zeros(pairs, dtype=wp.int32, device=device)
        self.bucket = wp.zeros(bodies + 1, dtype=wp.int32, device=device)
        self.scratch_a = wp.zeros(pairs, dtype=wp.int32, device=device)
        self.scratch_b = wp.zeros(pairs, dtype=wp.int32, device=device)

    def arrays(self) -> list[wp.array]:
        b, p = self.built, self.pairs
        return [
            b.stale,
            b.radius,
            b.position,
            b.orientation,
            p.count,
            p.a,
            p.b,
            self.bucket,
            self.scratch_a,
            self.scratch_b,
        ]

    def mark_stale(self) -> None:
        """Search the grid at the next step, whatever the bodies did."""
        stale = self.built.stale
        if stale.device.is_cpu:
            host_view(stale)[0] = 1
        else:
            stale.fill_(1)


class BroadPhase:
    """Owns the grid and pair buffers; `find_pairs` fills them for the current state.

    Attributes:
        pair_a, pair_b: candidate pairs, int32 arrays; the first `pair_count` rows are valid.
        cell_size: grid cell edge [m] used by the last search.
    """

    #: caches that snapshots keep by name only: the pair buffers as the queries take them, and what the
    #: last search left (the kept fat list, the grid, its cell edge, the body count it was sized for).
    #: A restored world searches afresh (`World.restore` calls `bodies_changed`), and finds the same
    #: pairs, in the same order, as the run it was taken from: so a snapshot holds none of it
    SNAPSHOT_CACHES = frozenset({"_pair_list", "_fat", "grid", "cell_params", "cell_size", "_sized_for"})

    def __init__(self, device: str):
        self.device = device
        self.grid = HashGrid(device)
        self.pair_capacity = 64
        self.pair_a = wp.zeros(self.pair_capacity, dtype=wp.int32, device=device)
        self.pair_b = wp.zeros(self.pair_capacity, dtype=wp.int32, device=device)
        self.pair_count_array = wp.zeros(1, dtype=wp.int32, device=device)
        self._pair_list: PairList | None = None
        self._fat: _FatList | None = None
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
        fat = self._fat
        return (
            self._ordinary_limit,
            self.pair_capacity,
            id(self.pair_a),
            id(self.swept_radius),
            grid.mask,
            id(grid.cell_count),
            id(grid.entries),
            id(fat),
            None if fat is None else fat.capacity,
        )

    def graph_arrays(self) -> list[wp.array]:
        """The arrays of the fat list, which recorded launches use besides this object's own."""
        return [] if self._fat is None else self._fat.arrays()

    def bodies_changed(self) -> None:
        """Bodies were removed, renumbered or restored: size the grid afresh and search it at the next `find_pairs`."""
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
            self.cell_size = 2.0 * (1.0 + SKIN) * float(ordinary.max()) + 2.0 * MARGIN
            # fat radii up to this size set the cell; faster or bigger bodies scan more cells
            self._ordinary_limit = (1.5 + SKIN) * float(ordinary.max()) + MARGIN
        if bodies.capacity != self._body_capacity:
            self._body_capacity = bodies.capacity
            self.swept_radius = wp.zeros(bodies.capacity, dtype=float_t, device=self.device)
        self.rows_changed()
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
        fat = self._fat
        if fat is None or fat.body_capacity != bodies.capacity:  # (made stale: searched at this step)
            capacity = self.pair_capacity if fat is None else fat.capacity
            self._fat = fat = _FatList(self.device, bodies.capacity, capacity)
        if self.pair_a.shape[0] < fat.capacity:  # (a restore brought back smaller buffers)
            self._grow(fat.capacity)
        if n < 2:
            self.pair_count = 0
            return False
        return True

    def _kept(self) -> _FatList:
        """The kept list (made by `begin`)."""
        fat = self._fat
        assert fat is not None, "BroadPhase.begin makes the kept list"
        return fat

    def rows_changed(self) -> None:
        """The body rows were renumbered, or the world restored: search the grid again at the next step
        (the fat list names rows, and holds where they were)."""
        if self._fat is not None:
            self._fat.mark_stale()

    def launch(self, bodies, dt: float, cache: LaunchCache | None = None) -> None:
        """Every launch of the pair search, with no host decision between them (so it can be recorded):
        the test of the kept list, the search where it failed, then this step's pairs from the list."""
        n = bodies.count
        launch_each(
            _check, n, [n, body_struct(bodies), dt, MARGIN, self.swept_radius, self._kept().built], self.device, cache
        )
        self._search(bodies, cache)

    def _search(self, bodies, cache: LaunchCache | None) -> None:
        """The fat list found again where it is stale (every launch returns at once where it is not),
        then this step's pairs kept from it."""
        n = bodies.count
        dev = self.device
        fat = self._kept()
        built = fat.built
        body = body_struct(bodies)
        launch_each(_fatten, n, [n, body, SKIN, self.swept_radius, built, fat.pairs], dev, cache)
        # cell edge: twice the largest fat radius among ordinary bodies, so most scan 2-3 cells a side
        launch(_cell_size, 1, [built.radius, n, self._ordinary_limit, self.cell_params, built], dev, cache)
        # counting sort of bodies into hashed cells; the biggest stay out and test everything
        position = bodies.arrays["body_position"]
        self.grid.build_from(position, n, self.cell_params, built.radius, cache, when=built.stale)
        args = [body, built.radius, self.grid.struct(self.cell_params), fat.pairs, built]
        launch_each(_query_grid, n, [n, *args], dev, cache)
        launch(_query_large, n, [n, *args], dev, cache)
        if dev == "cpu":  # (elsewhere the pairs keep the order the threads found them in)
            launch(_sort_pairs, 1, [n, body, fat.pairs, built, fat.bucket, fat.scratch_a, fat.scratch_b], dev, cache)
        self.pair_count_array.zero_()
        launch_each(_keep_pairs, fat.capacity, [body, self.swept_radius, fat.pairs, self._pairs()], dev, cache)
        built.stale.zero_()

    def _pairs(self) -> PairList:
        """The pair buffers as the queries write them (the same struct while the buffers are)."""
        p = self._pair_list
        if p is None or p.a is not self.pair_a:
            p = self._pair_list = PairList()
            p.count, p.a, p.b = self.pair_count_array, self.pair_a, self.pair_b
        return p

    def _grow(self, capacity: int) -> None:
        """Room for `capacity` pairs in the fat list and in this step's."""
        fat = self._kept()
        if fat.capacity < capacity:
            fat.capacity = capacity
            pairs = PairList()
            pairs.count = fat.pairs.count
            pairs.a, pairs.b, fat.scratch_a, fat.scratch_b = (
                wp.zeros(capacity, dtype=wp.int32, device=self.device) for _ in range(4)
            )
            fat.pairs = pairs
        if self.pair_a.shape[0] < capacity:
            self.pair_capacity = capacity
            self.pair_a = wp.zeros(capacity, dtype=wp.int32, device=self.device)
            self.pair_b = wp.zeros(capacity, dtype=wp.int32, device=self.device)

    def end(self, bodies, cache: LaunchCache | None = None) -> bool:
        """Host side after `launch`: read the pair count; grow the pair buffers and search again if
        they overflowed. Returns True if it searched again (pairs found by a recorded narrow phase
        that followed the first search are then incomplete)."""
        fat = self._kept()
        found = host_values(fat.pairs.count)[0]
        again = False
        while found > fat.capacity:
            again = True
            self._grow(max(found, 2 * fat.capacity))
            fat.mark_stale()
            self._search(bodies, cache)
            found = host_values(fat.pairs.count)[0]
        self.pair_count = host_values(self.pair_count_array)[0]
        self.cell_size = float(host_values(self.cell_params)[0])
        return again
