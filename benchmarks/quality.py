"""Quality figures of a benchmark state, computed the same way for every engine from plain arrays.

* largest overlap: max over pairs of bodies of their penetration depth [m] (spheres: 2 r - d;
  cubes: the smallest overlap over the 15 separating axes of the two oriented boxes);
* largest ground / wall penetration: max depth of any body below the ground plane or beyond a
  wall plane [m] (sphere: r - signed distance; box: its lowest corner);
* total kinetic energy [J]: sum 1/2 m v^2 + 1/2 I w^2 (spheres and cubes have isotropic inertia,
  so the frame of w does not matter);
* cloth: largest strain of a structural edge, |x_i - x_j| / L0 - 1.

Neighbours are found with a hashed uniform grid in NumPy (cell = cut-off distance, 27 cells),
so the figures cost O(n) and need no extra package.
"""

from __future__ import annotations

import numpy as np

_HASH = np.array([73856093, 19349663, 83492791], dtype=np.int64)
_OFFSETS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)], dtype=np.int64)


def neighbour_pairs(position: np.ndarray, cutoff: float) -> np.ndarray:
    """Pairs (i, j), i < j, of points closer than `cutoff`, shape (p, 2), int64.

    Args:
        position: points [m], shape (n, 3), finite.
        cutoff: distance [m] > 0.
    """
    n = len(position)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    cell = np.floor(position / cutoff).astype(np.int64)
    key = np.bitwise_xor.reduce(cell * _HASH, axis=1)
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    found = []
    for offset in _OFFSETS:
        # the points of the neighbouring cell, via its hash (hash collisions only add candidates)
        k = np.bitwise_xor.reduce((cell + offset) * _HASH, axis=1)
        start = np.searchsorted(sorted_key, k, side="left")
        end = np.searchsorted(sorted_key, k, side="right")
        for t in range(int(np.max(end - start))):
            i = np.nonzero(start + t < end)[0]
            j = order[start[i] + t]
            keep = i < j
            i, j = i[keep], j[keep]
            d2 = np.einsum("ij,ij->i", position[i] - position[j], position[i] - position[j])
            close = d2 < cutoff * cutoff
            found.append(np.stack([i[close], j[close]], axis=1))
    pairs = np.concatenate(found) if found else np.zeros((0, 2), dtype=np.int64)
    # the same pair can come through two offsets only on a hash collision
    return np.unique(pairs, axis=0)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (columns = body axes in world) of unit quaternions (x, y, z, w), (n, 4) -> (n, 3, 3)."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=1),
        ],
        axis=1,
    )


def sphere_max_overlap(position: np.ndarray, radius: float) -> float:
    """Largest overlap 2 r - |x_i - x_j| of equal spheres [m], 0 if none touch."""
    pairs = neighbour_pairs(position, 2.0 * radius)
    if len(pairs) == 0:
        return 0.0
    d = np.linalg.norm(position[pairs[:, 0]] - position[pairs[:, 1]], axis=1)
    return float(np.max(2.0 * radius - d))


def box_max_overlap(position: np.ndarray, orientation: np.ndarray, half_extents: np.ndarray) -> float:
    """Largest penetration depth between equal oriented boxes [m], 0 if none overlap.

    Separating axis test: for axes L (3 face normals of each box, 9 edge-edge cross products),
    overlap(L) = r_a(L) + r_b(L) - |d . L| with r(L) = sum_k h_k |axis_k . L|; the boxes
    intersect when every overlap is positive, and the smallest one is the penetration depth.
    """
    bound = float(np.linalg.norm(half_extents))
    pairs = neighbour_pairs(position, 2.0 * bound)
    if len(pairs) == 0:
        return 0.0
    rot = quat_to_matrix(orientation)
    a_axes = np.swapaxes(rot[pairs[:, 0]], 1, 2)  # (p, 3 axes, 3 components)
    b_axes = np.swapaxes(rot[pairs[:, 1]], 1, 2)
    cross = np.cross(a_axes[:, :, None, :], b_axes[:, None, :, :]).reshape(-1, 9, 3)
    axes = np.concatenate([a_axes, b_axes, cross], axis=1)  # (p, 15, 3)
    length = np.linalg.norm(axes, axis=2)
    usable = length > 1e-9  # parallel edges give no axis
    axes = axes / np.where(usable, length, 1.0)[:, :, None]
    d = position[pairs[:, 1]] - position[pairs[:, 0]]
    r_a = np.abs(np.einsum("pak,pjk->paj", axes, a_axes)) @ half_extents
    r_b = np.abs(np.einsum("pak,pjk->paj", axes, b_axes)) @ half_extents
    overlap = r_a + r_b - np.abs(np.einsum("pak,pk->pa", axes, d))
    depth = np.min(np.where(usable, overlap, np.inf), axis=1)
    return float(max(0.0, np.max(depth)))


def plane_penetration(
    position: np.ndarray,
    planes: list[tuple[np.ndarray, float]],
    *,
    radius: float = 0.0,
    orientation: np.ndarray | None = None,
    half_extents: np.ndarray | None = None,
) -> np.ndarray:
    """Largest depth of any body behind each plane [m], shape (len(planes),); 0 where none is.

    A body's depth behind plane (n, c) is c - (n . x - s), with support s = r for a sphere and
    s = sum_k h_k |n . axis_k| for a box.
    """
    depths = []
    rot = None if orientation is None else quat_to_matrix(orientation)
    for normal, offset in planes:
        support = radius if rot is None else np.abs(np.einsum("k,nkj->nj", normal, rot)) @ half_extents
        depth = offset - (position @ normal - support)
        depths.append(max(0.0, float(np.max(depth))) if len(position) else 0.0)
    return np.array(depths)


def kinetic_energy(velocity: np.ndarray, angular_velocity: np.ndarray, mass: float, inertia: float) -> float:
    """Total kinetic energy [J] of bodies with equal mass [kg] and isotropic inertia [kg m^2]."""
    return float(0.5 * mass * np.sum(velocity * velocity) + 0.5 * inertia * np.sum(angular_velocity**2))


def cloth_max_strain(position: np.ndarray, edges: np.ndarray, rest_length: float) -> float:
    """Largest stretch |x_i - x_j| / L0 - 1 over the given edges (dimensionless)."""
    d = np.linalg.norm(position[edges[:, 0]] - position[edges[:, 1]], axis=1)
    return float(np.max(d / rest_length - 1.0))
