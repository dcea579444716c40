"""Static triangle meshes: cleaned NumPy triangles -> Warp BVHs (`wp.Mesh`) the narrow phase queries.

Each mesh is stored in its own frame (scaled, float32 as `wp.Mesh` requires: ~1e-7 of its size),
placed by its static body's position and orientation. Queries (`mesh_query_point_sign_normal`,
`mesh_query_aabb`, `mesh_query_ray`) walk the BVH in O(log triangles) on the CPU and on CUDA.
Triangles are one-sided by winding: counter-clockwise seen from the side bodies stay on (a closed
mesh: outward), since the sign of a distance comes from the angle-weighted pseudo-normal.

`MeshSet.struct()` adds, for cloth (`cloth/collide.py`), whether each mesh is closed (a solid,
every edge shared by two triangles of opposite winding) and its sharp features: each triangle
flags the vertices and edges it owns (the first triangle holding them) that can poke between
cloth particles: boundary edges and convex edges, and vertices on a boundary or where the
faces around them are not all coplanar. Built once per mesh, O(triangles log triangles).
"""

from __future__ import annotations

import numpy as np
import warp as wp


@wp.struct
class Meshes:
    """The static meshes of one world for kernels, by row (`body_geometry`)."""

    id: wp.array(dtype=wp.uint64)  # BVH (`wp.Mesh.id`)
    closed: wp.array(dtype=wp.int32)  # 1 for a closed mesh (a solid), 0 for an open one (a terrain, a plate)
    feature_start: wp.array(dtype=wp.int32)  # the row in `feature` of each mesh's first triangle
    feature: wp.array(dtype=wp.int32)  # per triangle: bit k, it owns sharp vertex k; bit 3 + k, sharp edge (k, k + 1)


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The point of each triangle (a[i], b[i], c[i]), shapes (T, 3), closest to the point p (3,), shape
    (T, 3): by the Voronoi region of p (a corner, an edge or the face; Ericson, Real-Time Collision
    Detection, 5.1.5), in NumPy (host side: where an emitter may place a body)."""
    ab, ac = b - a, c - a
    ap, bp, cp = p - a, p - b, p - c
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):  # (each quotient is used only where its region holds)
        on_ab = a + (d1 / (d1 - d3))[:, None] * ab
        on_ac = a + (d2 / (d2 - d6))[:, None] * ac
        on_bc = b + ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None] * (c - b)
        total = va + vb + vc
        on_face = a + (vb / total)[:, None] * ab + (vc / total)[:, None] * ac
    regions = (
        ((d1 <= 0) & (d2 <= 0), a),
        ((d3 >= 0) & (d4 <= d3), b),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), on_ab),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), on_ac),
        ((va <= 0) & (d4 >= d3) & (d5 >= d6), on_bc),
    )
    closest = on_face
    for holds, point in reversed(regions):  # the first region that holds wins
        closest = np.where(holds[:, None], point, closest)
    return closest


def winding_number(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    """The winding number of the closed surface of triangles (a, b, c) about the point p: +-1 inside
    (by the triangles' winding), 0 outside. The sum of the triangles' solid angles seen from p over
    4 pi, each by van Oosterom and Strackee's formula."""
    x, y, z = a - p, b - p, c - p
    lx, ly, lz = np.linalg.norm(x, axis=1), np.linalg.norm(y, axis=1), np.linalg.norm(z, axis=1)
    det = np.einsum("ij,ij->i", x, np.cross(y, z))
    den = (
        lx * ly * lz
        + np.einsum("ij,ij->i", x, y) * lz
        + np.einsum("ij,ij->i", y, z) * lx
        + np.einsum("ij,ij->i", z, x) * ly
    )
    return float(np.sum(np.arctan2(det, den)) / (2.0 * np.pi))


def edge_table(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct edges of a triangle list: edge k of triangle f, from corner k to k + 1, is entry 3 f + k.

    Returns (first, other, uses), one row per distinct edge: the entry of the first triangle that
    holds it, of the second (first again where fewer or more than two hold it), and how many do.
    """
    t = np.asarray(triangles, dtype=np.int64)
    a = t.reshape(-1)
    b = t[:, [1, 2, 0]].reshape(-1)
    key = np.minimum(a, b) * (int(t.max(initial=0)) + 1) + np.maximum(a, b)
    _unique, first, inverse, uses = np.unique(key, return_index=True, return_inverse=True, return_counts=True)
    order = np.argsort(inverse, kind="stable")  # the triangles of an edge side by side
    start = np.concatenate([[0], np.cumsum(uses)[:-1]]).astype(np.int64)
    other = np.where(uses == 2, order[np.minimum(start + 1, len(order) - 1)], first)
    return first, other, uses


def sharp_features(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, bool]:
    """The sharp features of a mesh, as per-triangle flags (T,) int32 (see `Meshes.feature`), and whether it is closed.

    Each vertex and each edge is flagged on one triangle only, the first that holds it, so a query
    that finds every triangle near a point finds each feature once.
    """
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    count = len(t)
    if count == 0:
        return np.zeros(0, dtype=np.int32), False
    normal = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    a = t.reshape(-1)
    b = t[:, [1, 2, 0]].reshape(-1)
    first, other, uses = edge_table(t)
    # a shared edge is convex where the other triangle's third vertex lies behind this one's plane
    f0, f1 = first // 3, other // 3
    third = t[f1, (other % 3 + 2) % 3]
    size = np.linalg.norm(v[b[first]] - v[a[first]], axis=1)
    behind = np.einsum("ij,ij->i", v[third] - v[a[first]], normal[f0])
    coplanar = np.einsum("ij,ij->i", normal[f0], normal[f1]) > 1.0 - 1e-9
    sharp_edge = (uses != 2) | ((behind < -1e-9 * size) & ~coplanar)
    closed = bool(np.all(uses == 2)) and bool(np.all(a[other] == b[first]))
    flags = np.zeros(count, dtype=np.int64)
    np.bitwise_or.at(flags, f0[sharp_edge], 8 << (first[sharp_edge] % 3))
    # vertices: on a boundary edge, or where the faces around them are not all coplanar
    edge_sharp_vertex = np.zeros(len(v), dtype=bool)
    boundary = uses != 2
    edge_sharp_vertex[a[first[boundary]]] = True
    edge_sharp_vertex[b[first[boundary]]] = True
    corner = np.repeat(normal, 3, axis=0)
    reference = np.zeros((len(v), 3))
    reference[a[::-1]] = corner[::-1]  # the normal of the first triangle holding each vertex
    lowest = np.ones(len(v))
    np.minimum.at(lowest, a, np.einsum("ij,ij->i", corner, reference[a]))
    used, owner = np.unique(a, return_index=True)
    sharp_vertex = edge_sharp_vertex[used] | (lowest[used] < 1.0 - 1e-9)
    np.bitwise_or.at(flags, owner[sharp_vertex] // 3, 1 << (owner[sharp_vertex] % 3))
    return flags.astype(np.int32), closed


class MeshSet:
    """The triangle meshes of one world; row i is the `body_geometry` of a mesh body."""

    #: what snapshots keep by name only: the BVH ids are pointers, valid in the process that made them
    #: (a resume in another process crashed on the saved ones); the world the snapshot is restored into
    #: has its own, built from the same meshes
    SNAPSHOT_CACHES = frozenset({"_ids", "_struct"})

    def __init__(self, device: str):
        self.device = device
        self.meshes: list[wp.Mesh] = []
        self.vertices: list[np.ndarray] = []
        self.triangles: list[np.ndarray] = []
        self._ids: wp.array | None = None
        self.features: list[np.ndarray] = []  # per-triangle sharp-feature flags (`sharp_features`)
        self.closed: list[bool] = []
        self._struct: Meshes | None = None

    def add(self, vertices: np.ndarray, triangles: np.ndarray) -> int:
        """Build the BVH of a cleaned mesh (vertices (V, 3) in its frame, triangles (T, 3)); returns its row."""
        points: wp.array = wp.array(
            np.ascontiguousarray(vertices, dtype=np.float32), dtype=wp.vec3f, device=self.device
        )
        indices: wp.array = wp.array(
            np.ascontiguousarray(triangles, dtype=np.int32).reshape(-1), dtype=wp.int32, device=self.device
        )
        self.meshes.append(wp.Mesh(points=points, indices=indices))
        self.vertices.append(np.asarray(vertices, dtype=np.float64))
        self.triangles.append(np.asarray(triangles, dtype=np.int32))
        flags, closed = sharp_features(vertices, triangles)
        self.features.append(flags)
        self.closed.append(closed)
        self._ids = None
        self._struct = None
        return len(self.meshes) - 1

    def ids(self) -> wp.array:
        """Mesh ids (uint64) by row, for kernels; one zero entry when there is no mesh."""
        if self._ids is None:
            values = [m.id for m in self.meshes] or [0]
            self._ids = wp.array(np.array(values, dtype=np.uint64), dtype=wp.uint64, device=self.device)
        return self._ids

    def struct(self) -> Meshes:
        """The meshes' BVH ids, closed flags and sharp features for kernels (rebuilt after an `add`)."""
        if self._struct is None:
            s = Meshes()
            s.id = self.ids()
            dev = self.device
            s.closed = wp.array(np.array([int(c) for c in self.closed] or [0], dtype=np.int32), device=dev)
            sizes = [len(f) for f in self.features]
            s.feature_start = wp.array(np.concatenate([[0], np.cumsum(sizes)]).astype(np.int32), device=dev)
            s.feature = wp.array(np.concatenate([*self.features, np.zeros(1, np.int32)]).astype(np.int32), device=dev)
            self._struct = s
        return self._struct

    def corners(self, row: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The corners (a, b, c), each (T, 3), of mesh `row`'s triangles, in its frame [m]."""
        v, t = self.vertices[row], self.triangles[row]
        return v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]

    @property
    def triangle_count(self) -> int:
        return int(sum(len(t) for t in self.triangles))
