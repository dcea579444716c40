"""Triangle meshes from files (OBJ, STL, PLY, glTF/GLB, ... through trimesh) or from arrays, cleaned.

`load_mesh` returns float64 vertices (V, 3) and int32 triangles (T, 3), with NaN vertices and
the triangles using them, out-of-range indices and degenerate (zero-area) triangles dropped;
each drop is told in one line on the "tumble" logger (stderr by default). A problem that leaves
nothing to simulate raises `ValueError` with one line naming the file.

trimesh (the `tumble[mesh]` extra) is imported only when a file is read.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

log = logging.getLogger("tumble")

#: largest mesh accepted [triangles]: 4 M triangles take ~0.3 GB as float64 vertices + BVH
MAX_TRIANGLES = 4_000_000
#: the formats trimesh reads without extra packages
FORMATS = ("obj", "stl", "ply", "off", "glb", "gltf")


def notice(message: str) -> None:
    """Tell the user one line about their geometry (dropped triangles, a hull taken)."""
    log.warning("notice: %s", message)


def read_mesh_file(path) -> tuple[np.ndarray, np.ndarray, object]:
    """Vertices, triangles and the trimesh object of a mesh file (all its geometry, transforms applied).

    Raises:
        ValueError: one line naming the file: missing, a directory, an unknown format, unreadable,
            or holding no triangles.
    """
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{path}: no such mesh file")
    if p.is_dir():
        raise ValueError(f"{path}: is a directory, not a mesh file")
    if not p.is_file():  # a device or a pipe: its size says nothing, and /dev/zero never ends
        raise ValueError(f"{path}: not a regular file (a device or a pipe), not a mesh file")
    ext = p.suffix.lower().lstrip(".")
    if ext not in FORMATS:
        raise ValueError(
            f"{path}: unknown mesh format {p.suffix or '(no extension)'!r}; "
            f"expected one of {', '.join('.' + f for f in FORMATS)}"
        )
    if p.stat().st_size > 64 * MAX_TRIANGLES:
        raise ValueError(
            f"{path}: {p.stat().st_size / 1e6:.0f} MB is too large a mesh file (at most {MAX_TRIANGLES:,} triangles)"
        )
    try:
        import trimesh
    except ImportError:
        raise ValueError(f"{path}: reading mesh files needs trimesh (pip install 'tumble[mesh]')") from None
    try:
        mesh = trimesh.load(str(p), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds on a broken file
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"{path}: cannot read the mesh ({first})") from None
    vertices = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0:
        raise ValueError(f"{path}: the mesh has no triangles")
    return vertices, faces, mesh


def clean_triangles(vertices, triangles, *, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Drop NaN vertices' triangles, bad indices and zero-area triangles, with a one-line count each.

    Raises:
        ValueError: when no triangle is left, or there are more than `MAX_TRIANGLES`.
    """
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"{name}: vertices must have shape (n, 3), got {v.shape}")
    if t.ndim != 2 or t.shape[1] != 3 or (len(t) and not np.issubdtype(t.dtype, np.integer)):
        raise ValueError(f"{name}: triangles must be integer vertex indices of shape (m, 3), got {t.shape}")
    t = t.astype(np.int64)
    if len(t) == 0:
        raise ValueError(f"{name}: the mesh has no triangles")
    if len(t) > MAX_TRIANGLES:
        raise ValueError(f"{name}: {len(t):,} triangles is too large a mesh (at most {MAX_TRIANGLES:,})")
    bad_index = np.any((t < 0) | (t >= len(v)), axis=1)
    if bad_index.any():
        notice(f"{name}: dropped {int(bad_index.sum())} triangles with vertex indices out of range")
        t = t[~bad_index]
    finite = np.isfinite(v).all(axis=1)
    nan_tri = ~finite[t].all(axis=1)  # type: ignore[index]  # finite is an array; numpy's stub: maybe a scalar
    if nan_tri.any():
        notice(
            f"{name}: dropped {int(nan_tri.sum())} triangles with non-finite vertices ({int((~finite).sum())} vertices)"
        )
        t = t[~nan_tri]
    if len(t):
        a, b, c = (v[t[:, k]] for k in range(3))
        area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
        scale = float(np.ptp(v[finite], axis=0).max()) if finite.any() else 0.0
        degenerate = area2 <= 1e-12 * scale * scale
        if degenerate.any():
            notice(f"{name}: dropped {int(degenerate.sum())} degenerate (zero-area) triangles")
            t = t[~degenerate]
    if len(t) == 0:
        raise ValueError(f"{name}: the mesh has no usable triangles left")
    # keep only the vertices that triangles use, renumbered
    used = np.unique(t)
    remap = np.full(len(v), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return np.ascontiguousarray(v[used]), remap[t].astype(np.int32)


def load_mesh(*, file=None, vertices=None, triangles=None, name: str | None = None):
    """A cleaned triangle mesh from `file`, or from `vertices` (n, 3) and `triangles` (m, 3).

    Returns:
        (vertices (V, 3) float64, triangles (T, 3) int32, watertight: bool or None when unknown).
    """
    if (file is None) == (vertices is None):
        raise ValueError("give a mesh file, or vertices (and triangles), not both")
    watertight = None
    if file is not None:
        v, t, mesh = read_mesh_file(file)
        name = name or str(file)
        watertight = bool(getattr(mesh, "is_watertight", False))
    else:
        v = np.asarray(vertices, dtype=np.float64)
        t = np.zeros((0, 3), dtype=np.int64) if triangles is None else np.asarray(triangles)
        name = name or "mesh"
    v, t = clean_triangles(v, t, name=name)
    return v, t, watertight


def hull_points(points, file) -> tuple[np.ndarray, str]:
    """The points whose convex hull a convex body is, and the name errors give them.

    From `points` as given, or the vertices of the mesh `file` (with a one-line notice when the
    mesh is not watertight: its hull is used all the same). Exactly one of them must be given;
    the caller says so in its own words first.
    """
    if file is None:
        return np.asarray(points, dtype=np.float64), "points"
    vertices, _triangles, mesh = read_mesh_file(file)
    if not getattr(mesh, "is_watertight", False):
        notice(f"{file}: the mesh is not watertight; its convex hull is used")
    return np.asarray(vertices, dtype=np.float64), str(file)
