"""Convex hulls: built from points in NumPy, stored flat for the narrow phase.

A hull prototype is the convex hull of a point set, with coplanar triangles merged into
polygon faces. Its mass properties come from exact polyhedron integrals (a tetrahedron from an
interior point to every triangle of every face); its vertices are then stored in the body
frame, whose origin is the centre of mass and whose axes are the principal axes of inertia.
The frame the points were given in (the "user frame") is kept as `offset` and `rotation`, so
that a display or an export can place the original geometry.

Layout (all prototypes of a world in one set of arrays, each prototype a slice):
- `vertex (V, 3)`: body-frame vertices [m];
- `face_normal (F, 3)`, `face_offset (F,)`: outward unit normals n and offsets d, n . x = d;
- `face_start (F,)`, `face_count (F,)` into `face_vertex (FV,)`: each face's vertices
  (global rows of `vertex`), counter-clockwise seen from outside;
- `edge (E, 2)`: each undirected edge once, global vertex rows; `edge_face (E, 2)` its two faces;
- `hull_vertex_start/count`, `hull_face_start/count`, `hull_edge_start/count (H,)`.

Costs: building a hull of n points is O(n log n) (Qhull, through SciPy); a query against a hull
reads all its vertices, faces or edges, so keep hulls small (tens of vertices).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import warp as wp

from ..npmath import matrix_to_quat
from ..real import float_t, vec3

#: most vertices a hull may keep (more make every contact query against it slow)
MAX_HULL_VERTICES = 256


@dataclass
class HullPrototype:
    """One convex hull in its body frame, with its mass properties at density 1.

    Attributes:
        vertex: body-frame vertices [m], shape (V, 3).
        faces: vertex rows of each face, counter-clockwise seen from outside (list of int arrays).
        normal, offset: outward unit face normals, shape (F, 3), and offsets [m], shape (F,).
        volume: [m^3].
        inertia: principal moments at density 1 [m^5], shape (3,).
        offset_com: the centre of mass in the user frame [m], shape (3,).
        rotation: the body frame's axes in the user frame as a quaternion (x, y, z, w).
    """

    vertex: np.ndarray
    faces: list
    normal: np.ndarray
    offset: np.ndarray
    volume: float
    inertia: np.ndarray
    offset_com: np.ndarray
    rotation: np.ndarray

    def scaled(self, s: float) -> HullPrototype:
        """The same hull scaled by s about its centre of mass (volume s^3, unit-density moments s^5;
        inf where they overflow float64, as at s = 1e100, not an OverflowError)."""
        s = np.float64(s)
        with np.errstate(over="ignore"):
            return replace(
                self,
                vertex=self.vertex * s,
                offset=self.offset * s,
                volume=float(self.volume * s**3),
                inertia=self.inertia * s**5,
                offset_com=self.offset_com * s,
            )

    @property
    def bound_radius(self) -> float:
        """Radius of the bounding sphere about the centre of mass [m]."""
        return float(np.linalg.norm(self.vertex, axis=1).max())

    @property
    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """Unique edges (E, 2) as vertex rows, and the two faces of each (E, 2)."""
        seen: dict[tuple[int, int], list[int]] = {}
        for f, face in enumerate(self.faces):
            for k in range(len(face)):
                i, j = int(face[k]), int(face[(k + 1) % len(face)])
                seen.setdefault((min(i, j), max(i, j)), []).append(f)
        edge = np.array(list(seen), dtype=np.int32).reshape(-1, 2)
        faces = np.array([(v + v)[:2] for v in seen.values()], dtype=np.int32).reshape(-1, 2)
        return edge, faces


def polyhedron_mass_properties(vertex: np.ndarray, faces) -> tuple[float, np.ndarray, np.ndarray]:
    """Volume, centre of mass and inertia tensor (about the centre, density 1) of a closed polyhedron.

    Each face is fanned into triangles (a, b, c); with an interior apex o, each tetrahedron
    (o, a, b, c) of signed volume V = det[a-o, b-o, c-o] / 6 adds V to the volume, V (o+a+b+c)/4
    to the first moment, and V / 20 (sum_i u_i u_i^T + (sum_i u_i)(sum_i u_i)^T) (u_i = vertices
    less o) to the second moment about o (Tonon 2004: the covariance of a tetrahedron). The inertia
    tensor is then I = tr(C) 1 - C for the covariance C about the centre of mass.
    """
    o = vertex.mean(axis=0)
    tris = np.array([(f[0], f[k], f[k + 1]) for f in faces for k in range(1, len(f) - 1)], dtype=np.int64)
    a, b, c = (vertex[tris[:, k]] - o for k in range(3))
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    volume = float(vol.sum())
    com_o = (vol[:, None] * (a + b + c)).sum(axis=0) / 4.0 / volume
    s = a + b + c
    cov = (
        vol[:, None, None]
        / 20.0
        * (
            np.einsum("ni,nj->nij", a, a)
            + np.einsum("ni,nj->nij", b, b)
            + np.einsum("ni,nj->nij", c, c)
            + np.einsum("ni,nj->nij", s, s)
        )
    ).sum(axis=0)
    cov -= volume * np.outer(com_o, com_o)  # parallel-axis shift from o to the centre of mass
    inertia = np.trace(cov) * np.eye(3) - cov
    return volume, o + com_o, inertia


def _merge_faces(points: np.ndarray, simplices: np.ndarray, equations: np.ndarray, tol: float):
    """Group the hull's triangles by plane and order each group's vertices counter-clockwise."""
    groups: list[list[int]] = []
    planes: list[np.ndarray] = []
    for t, eq in enumerate(equations):
        for g, plane in enumerate(planes):
            if np.abs(plane[:3] - eq[:3]).max() < 1e-6 and abs(plane[3] - eq[3]) < tol:
                groups[g].append(t)
                break
        else:
            groups.append([t])
            planes.append(eq)
    faces, normals, offsets = [], [], []
    for group, plane in zip(groups, planes):
        n = plane[:3] / np.linalg.norm(plane[:3])
        ids = np.unique(simplices[group].reshape(-1))
        p = points[ids]
        centre = p.mean(axis=0)
        u = p[0] - centre if np.linalg.norm(p[0] - centre) > 0 else np.cross(n, [1.0, 0.0, 0.0])
        u = u - n * (u @ n)
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        angle = np.arctan2((p - centre) @ v, (p - centre) @ u)
        faces.append(ids[np.argsort(angle)])
        normals.append(n)
        offsets.append(float(n @ centre))
    return faces, np.array(normals), np.array(offsets)


def hull_from_points(points, *, name: str = "points") -> HullPrototype:
    """The convex hull of `points` (shape (n, 3), any frame) as a prototype in its body frame.

    Raises:
        ValueError: one line naming `name`, for non-finite points, fewer than four points, points
            spanning no volume, or a hull with more than `MAX_HULL_VERTICES` vertices.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{name}: points must have shape (n, 3), got {p.shape}")
    if not np.isfinite(p).all():
        raise ValueError(f"{name}: {int((~np.isfinite(p).all(axis=1)).sum())} points are not finite")
    if len(p) < 4:
        raise ValueError(f"{name}: a convex hull needs at least 4 points, got {len(p)}")
    try:
        from scipy.spatial import ConvexHull, QhullError
    except ImportError:  # pragma: no cover - scipy comes with the mesh extra
        raise ValueError(f"{name}: convex hulls need SciPy (pip install 'tumble[mesh]')") from None
    size = float(np.ptp(p, axis=0).max())
    try:
        hull = ConvexHull(p)
    except QhullError:
        raise ValueError(f"{name}: the points span no volume (they are coplanar or collinear)") from None
    if hull.volume <= 1e-12 * size**3:
        raise ValueError(f"{name}: the points span no volume (they are coplanar or collinear)")
    used = hull.vertices
    if len(used) > MAX_HULL_VERTICES:
        raise ValueError(
            f"{name}: the hull has {len(used)} vertices, more than {MAX_HULL_VERTICES}; simplify the mesh first"
        )
    remap = np.full(len(p), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    verts = p[used]
    faces, _normals, _offsets = _merge_faces(verts, remap[hull.simplices], hull.equations, 1e-9 * size)
    volume, com, inertia = polyhedron_mass_properties(verts, faces)
    moments, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    body = (verts - com) @ axes  # rows: R^T (v - com)
    normals = _normals @ axes
    offsets = np.einsum("ij,ij->i", normals, np.array([body[f[0]] for f in faces]))
    return HullPrototype(
        vertex=body,
        faces=faces,
        normal=normals,
        offset=offsets,
        volume=volume,
        inertia=moments,
        offset_com=com,
        rotation=matrix_to_quat(axes),
    )


def box_prototype() -> HullPrototype:
    """The cube [-1, 1]^3 as a hull (no SciPy needed), scaled by half extents when a box meets a convex body."""
    corners = np.array([[x, y, z] for z in (-1.0, 1.0) for y in (-1.0, 1.0) for x in (-1.0, 1.0)])
    # corner k has bit i set when coordinate i is +1; each face counter-clockwise from outside
    faces = [np.array(f) for f in ([0, 2, 3, 1], [4, 5, 7, 6], [0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3])]
    normal = np.array([[0, 0, -1], [0, 0, 1], [-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0]], dtype=np.float64)
    volume, com, inertia = polyhedron_mass_properties(corners, faces)
    return HullPrototype(
        vertex=corners,
        faces=faces,
        normal=normal,
        offset=np.ones(6),
        volume=volume,
        inertia=np.diag(inertia).copy(),
        offset_com=com,
        rotation=np.array([0.0, 0.0, 0.0, 1.0]),
    )


@wp.struct
class Hulls:
    """Every hull prototype of a world, flat (see the module docstring)."""

    vertex: wp.array(dtype=vec3)
    face_normal: wp.array(dtype=vec3)
    face_offset: wp.array(dtype=float_t)
    face_start: wp.array(dtype=wp.int32)
    face_count: wp.array(dtype=wp.int32)
    face_vertex: wp.array(dtype=wp.int32)
    edge: wp.array(dtype=wp.vec2i)
    edge_face: wp.array(dtype=wp.vec2i)
    vertex_start: wp.array(dtype=wp.int32)
    vertex_count: wp.array(dtype=wp.int32)
    hull_face_start: wp.array(dtype=wp.int32)
    hull_face_count: wp.array(dtype=wp.int32)
    edge_start: wp.array(dtype=wp.int32)
    edge_count: wp.array(dtype=wp.int32)


class HullSet:
    """The prototypes of one world; prototype 0 is the unit box (boxes meeting hulls use it)."""

    def __init__(self, device: str):
        self.device = device
        self.prototypes: list[HullPrototype] = []
        self._struct: Hulls | None = None
        self.add(box_prototype())

    def add(self, proto: HullPrototype) -> int:
        """Store a prototype; returns its index (the body's `body_geometry`)."""
        self.prototypes.append(proto)
        self._struct = None
        return len(self.prototypes) - 1

    def struct(self) -> Hulls:
        """The flat arrays as a Warp struct (rebuilt after an `add`)."""
        if self._struct is None:
            self._struct = self._build()
        return self._struct

    def _build(self) -> Hulls:
        dev = self.device
        vertex, normal, offset, fstart, fcount, fvert, edge, eface = [], [], [], [], [], [], [], []
        vstart, vcount, hfs, hfc, estart, ecount = [], [], [], [], [], []
        nv = nf = nfv = ne = 0
        for p in self.prototypes:
            vstart.append(nv)
            vcount.append(len(p.vertex))
            hfs.append(nf)
            hfc.append(len(p.faces))
            vertex.append(p.vertex)
            normal.append(p.normal)
            offset.append(p.offset)
            for f in p.faces:
                fstart.append(nfv)
                fcount.append(len(f))
                fvert.append(np.asarray(f) + nv)
                nfv += len(f)
            e, ef = p.edges
            estart.append(ne)
            ecount.append(len(e))
            edge.append(e + nv)
            eface.append(ef + nf)
            nv += len(p.vertex)
            nf += len(p.faces)
            ne += len(e)
        s = Hulls()

        def arr(values, dtype):
            return wp.array(np.ascontiguousarray(values), dtype=dtype, device=dev)

        s.vertex = arr(np.concatenate(vertex), vec3)
        s.face_normal = arr(np.concatenate(normal), vec3)
        s.face_offset = arr(np.concatenate(offset), float_t)
        s.face_start = arr(np.array(fstart, dtype=np.int32), wp.int32)
        s.face_count = arr(np.array(fcount, dtype=np.int32), wp.int32)
        s.face_vertex = arr(np.concatenate(fvert).astype(np.int32), wp.int32)
        s.edge = arr(np.concatenate(edge).astype(np.int32), wp.vec2i)
        s.edge_face = arr(np.concatenate(eface).astype(np.int32), wp.vec2i)
        s.vertex_start = arr(np.array(vstart, dtype=np.int32), wp.int32)
        s.vertex_count = arr(np.array(vcount, dtype=np.int32), wp.int32)
        s.hull_face_start = arr(np.array(hfs, dtype=np.int32), wp.int32)
        s.hull_face_count = arr(np.array(hfc, dtype=np.int32), wp.int32)
        s.edge_start = arr(np.array(estart, dtype=np.int32), wp.int32)
        s.edge_count = arr(np.array(ecount, dtype=np.int32), wp.int32)
        return s
