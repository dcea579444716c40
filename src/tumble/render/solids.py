"""Geometry of the shapes the renderer draws beyond spheres and boxes: capsules, convex hulls,
static triangle meshes, and the joint overlay (rods and anchor dots, drawn as thin capsules).

- **Capsules** need no geometry: the renderer ray casts each one inside its bounding box (see
  `shaders.CAPSULE_RAY`), so every capsule of any size is one instanced draw of a cube, exact at any
  zoom; here only their instance layout (`CAPSULE_FLOATS`).
- **Convex hulls** get one vertex buffer per prototype (`world.hulls.prototypes[i]`, in the body
  frame: origin at the centre of mass), flat-shaded: each polygon face is fanned into triangles
  with the face's normal. Bodies using a prototype are its instances (centre, quaternion, colour).
- **Static meshes** get one vertex buffer per mesh (`world.meshes`, in the mesh's frame), with
  smooth normals except across creases sharper than `CREASE_DEGREES` (a stair's edge stays sharp,
  a bowl stays round).
- **Joints** (`joint_segments`): body a's centre -> anchor on a -> anchor on b -> body b's centre,
  one row per joint that has not broken; `segment_capsules` turns those into capsule instances.

Everything here is NumPy, computed once per prototype (the renderer caches the vertex buffers);
per frame only the instance arrays are packed.
"""

from __future__ import annotations

import math

import numpy as np

#: floats per capsule instance: centre 3, orientation 4, radius 1, half height 1, colour 3
CAPSULE_FLOATS = 12
#: floats per hull or mesh instance: centre 3, orientation 4, colour 3
SOLID_FLOATS = 10
#: colour (sRGB) of static triangle meshes: a light stone, apart from the body palette and the ground
MESH_COLOR = (0.74, 0.70, 0.63)
#: colours (sRGB) of the joint overlay: rods between centres and anchors, and the anchors' dots
JOINT_COLOR = (0.98, 0.80, 0.18)
ANCHOR_COLOR = (0.95, 0.95, 0.95)
#: creases sharper than this between two triangles of a mesh keep their flat normals [degrees]
CREASE_DEGREES = 40.0


def hull_vertices(proto) -> np.ndarray:
    """Flat-shaded triangles of a hull prototype: (V, 6) float32 rows (position, normal) in the body frame."""
    rows = []
    for face, normal in zip(proto.faces, proto.normal):
        face = np.asarray(face)
        fan = np.stack([np.full(len(face) - 2, face[0]), face[1:-1], face[2:]], axis=1).reshape(-1)
        rows.append(np.concatenate([proto.vertex[fan], np.broadcast_to(normal, (len(fan), 3))], axis=1))
    return np.ascontiguousarray(np.concatenate(rows), dtype=np.float32)


def vertex_normals(position: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals of a triangle mesh, shape (P, 3), float64.

    Each triangle adds its un-normalised face normal (b - a) x (c - a), whose length is twice
    its area, to its three corners; sums are then normalised (zero stays zero).
    """
    a, b, c = (position[triangles[:, k]] for k in range(3))
    face = np.cross(b - a, c - a)
    corners = triangles.reshape(-1)
    weights = np.repeat(face, 3, axis=0)
    n = len(position)
    normal = np.stack([np.bincount(corners, weights=weights[:, k], minlength=n) for k in range(3)], axis=1)
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    return np.divide(normal, length, out=np.zeros_like(normal), where=length > 1e-20)


def mesh_vertices(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Triangles of a static mesh: (3 T, 6) float32 rows (position, normal) in the mesh's frame.

    A corner takes the area-weighted vertex normal where it is within `CREASE_DEGREES` of its
    triangle's own normal, else the triangle's normal.
    """
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    smooth = vertex_normals(v, t)
    face = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    face /= np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-30)
    corner = smooth[t.reshape(-1)]
    flat = np.repeat(face, 3, axis=0)
    sharp = np.einsum("ij,ij->i", corner, flat) < math.cos(math.radians(CREASE_DEGREES))
    normal = np.where(sharp[:, None], flat, corner)
    return np.ascontiguousarray(np.concatenate([v[t.reshape(-1)], normal], axis=1), dtype=np.float32)


def _rotate_rows(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (n, 3) by unit quaternions q (n, 4) as (x, y, z, w): v + 2 w (u x v) + 2 u x (u x v)."""
    u, w = q[:, :3], q[:, 3:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def joint_segments(world) -> np.ndarray:
    """Where each unbroken joint is drawn: shape (J, 4, 3) [m], rows (centre of a, anchor on a, anchor on b, centre of b).

    The world's end of a joint (body -1) has its anchor as its centre. A `WorldSnapshot` carries
    the array it copied (`joint_lines`), which is returned as it is.
    """
    copied = getattr(world, "joint_lines", None)
    if copied is not None:
        return copied
    joints = getattr(world, "joints", None)
    if joints is None or not getattr(joints, "count", 0) or not hasattr(world, "bodies"):
        return np.zeros((0, 4, 3))
    bodies = world.bodies
    x = np.vstack([bodies.numpy("body_position"), np.zeros((1, 3))])  # row -1: the world
    q = np.vstack([bodies.numpy("body_orientation"), [[0.0, 0.0, 0.0, 1.0]]])
    ia = joints.numpy("joint_body_a").astype(np.int64)
    ib = joints.numpy("joint_body_b").astype(np.int64)
    pa = x[ia] + _rotate_rows(q[ia], joints.numpy("joint_local_a"))
    pb = x[ib] + _rotate_rows(q[ib], joints.numpy("joint_local_b"))
    ca = np.where((ia >= 0)[:, None], x[ia], pa)
    cb = np.where((ib >= 0)[:, None], x[ib], pb)
    keep = joints.numpy("joint_enabled") != 0
    out = np.stack([ca, pa, pb, cb], axis=1)[keep]
    return out[np.isfinite(out).all(axis=(1, 2))]


def segment_capsules(segments: np.ndarray, radius: float, color) -> np.ndarray:
    """Capsule instances (k, 12) float32 for segments (k, 2, 3) [m]: rods of `radius` from end to end.

    A zero-length segment gives a sphere (half height 0).
    """
    p, q = segments[:, 0], segments[:, 1]
    d = q - p
    length = np.linalg.norm(d, axis=1)
    u = np.divide(d, length[:, None], out=np.tile([0.0, 0.0, 1.0], (len(d), 1)), where=length[:, None] > 1e-12)
    # the rotation taking +z to u: quaternion (z x u, 1 + z . u), normalised; u = -z is half a turn about x
    rot = np.stack([-u[:, 1], u[:, 0], np.zeros(len(u)), 1.0 + u[:, 2]], axis=1)
    rot[rot[:, 3] < 1e-9] = (1.0, 0.0, 0.0, 0.0)
    rot /= np.linalg.norm(rot, axis=1, keepdims=True)
    out = np.empty((len(d), CAPSULE_FLOATS), dtype=np.float32)
    out[:, 0:3] = 0.5 * (p + q)
    out[:, 3:7] = rot
    out[:, 7] = radius
    out[:, 8] = 0.5 * length
    out[:, 9:12] = color
    return out


def joint_capsules(lines: np.ndarray, rod_radius: float, dot_radius: float) -> np.ndarray:
    """The joint overlay as capsule instances: three rods per joint (centre a -> anchor a -> anchor b ->
    centre b; zero-length ones dropped) and a dot on each anchor (one where the two coincide)."""
    if not len(lines):
        return np.zeros((0, CAPSULE_FLOATS), dtype=np.float32)
    rods = np.concatenate([lines[:, 0:2], lines[:, 1:3], lines[:, 2:4]])
    rods = rods[np.linalg.norm(rods[:, 1] - rods[:, 0], axis=1) > 1e-9]
    apart = np.linalg.norm(lines[:, 2] - lines[:, 1], axis=1) > 1e-6
    dots = np.concatenate([lines[:, 1], lines[apart, 2]])
    return np.concatenate(
        [
            segment_capsules(rods, rod_radius, JOINT_COLOR),
            segment_capsules(np.stack([dots, dots], axis=1), dot_radius, ANCHOR_COLOR),
        ]
    )
