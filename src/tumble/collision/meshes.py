"""Static triangle meshes: cleaned NumPy triangles -> Warp BVHs (`wp.Mesh`) the narrow phase queries.

Each mesh is stored in its own frame (scaled, float32 as `wp.Mesh` requires: ~1e-7 of its size),
placed by its static body's position and orientation. Queries (`mesh_query_point_sign_normal`,
`mesh_query_aabb`, `mesh_query_ray`) walk the BVH in O(log triangles) on the CPU and on CUDA.
Triangles are one-sided by winding: counter-clockwise seen from the side bodies stay on (a closed
mesh: outward), since the sign of a distance comes from the angle-weighted pseudo-normal.
"""

from __future__ import annotations

import numpy as np
import warp as wp


class MeshSet:
    """The triangle meshes of one world; row i is the `body_geometry` of a mesh body."""

    def __init__(self, device: str):
        self.device = device
        self.meshes: list[wp.Mesh] = []
        self.vertices: list[np.ndarray] = []
        self.triangles: list[np.ndarray] = []
        self._ids: wp.array | None = None

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
        self._ids = None
        return len(self.meshes) - 1

    def ids(self) -> wp.array:
        """Mesh ids (uint64) by row, for kernels; one zero entry when there is no mesh."""
        if self._ids is None:
            values = [m.id for m in self.meshes] or [0]
            self._ids = wp.array(np.array(values, dtype=np.uint64), dtype=wp.uint64, device=self.device)
        return self._ids

    @property
    def triangle_count(self) -> int:
        return int(sum(len(t) for t in self.triangles))
