"""Export to USD: a simulation or a recording as a stage that Blender, Houdini and usdview open.

Typical use::

    from tumble.io import usd

    usd.export(world, "shot.usdc", duration=2.0, fps=60)       # simulates, then writes
    usd.export("pile.npz", "pile.usda")                       # converts a recording (or its dict)

What the stage holds (Z up, metres, `timeCodesPerSecond` = fps, frame k at time code k):

    /Root                       Xform, the default prim
      Static/plane_0, ...       Mesh: planes as finite quads around everything that moves;
                                static spheres, boxes, capsules, hulls; static triangle meshes
      Bodies                    PointInstancer: one instance per moving body, `ids` = body index,
                                time-sampled positions, orientations (quath), scales, and
                                `invisibleIds` listing the bodies not released yet (or removed)
        Prototypes/sphere, box  Mesh: unit sphere (radius 1), cube [-1, 1]^3
        Prototypes/capsule_K    Capsule (axis Z): one per distinct radius and half height
        Prototypes/hull_R       Mesh: hull prototype R's triangles, flat normals, in the body frame
      JointedBodies             with `physics=True` and joints: Xforms of the jointed moving bodies
      Joints                    with `physics=True`: UsdPhysics joints naming those Xforms
      Cloth                     Mesh: every cloth's triangles, time-sampled points and normals
      Camera                    the scene's [camera], when it has one
      PhysicsScene, Materials   with `physics=True`: UsdPhysics colliders, rigid bodies, masses

With `bodies="xforms"`, `Bodies` holds one animated Xform per body instead (`body_000042`,
translate + orient time-sampled, visibility off and geom scale 0 until release), for tools that take instancers
poorly. Colours are the viewer's (`tumble.render.colors`), as `primvars:displayColor`, turned
from sRGB into the linear values USD colours are (so that a renderer shows the viewer's shade).

Cost: one pass over the frames, NumPy throughout; pxr copies each frame's arrays once. A 2 s,
60 fps recording of 5,000 bodies writes in ~2.6 s to a 15.8 MB .usdc (benchmarks/export_usd.py);
`bodies="xforms"` costs ~25 us per body per frame (one pxr call per sample), for small scenes.

The shape of a body picks its prototype through `PROTOTYPES` (shape name -> builder), so a new
shape kind adds one builder returning its meshes, which bodies use them and at what scale.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import TumbleError
from ..npmath import quat_mul, quat_rotate
from ..render.colors import CLOTH_COLOR, body_colors
from ..render.solids import vertex_normals
from .atomic import atomic_path, probe_folder

#: file types `export` writes, chosen by the suffix (".usd" is binary crate, like ".usdc")
EXTENSIONS = (".usd", ".usda", ".usdc", ".usdz")
#: how moving bodies are written
BODY_MODES = ("instancer", "xforms")
#: the pip command that brings pxr
PIP_HINT = "pip install 'tumble[usd]' (or: pip install usd-core)"
#: colour of planes, sRGB (the viewer's ground is a light grey checker)
PLANE_COLOR = (0.80, 0.81, 0.83)
#: default seconds to simulate when neither the call nor the scene says
DEFAULT_DURATION = 2.0
#: joint limits and break forces at or above this are "none" (the solver stores infinity as 1e30)
UNLIMITED = 1e29


def require_pxr() -> None:
    """Check that pxr imports, else raise TumbleError naming the pip command."""
    try:
        from pxr import Usd, UsdGeom, UsdPhysics, UsdUtils  # noqa: F401
    except ImportError:
        raise TumbleError(f"USD export needs Pixar's usd-core, which is not installed: {PIP_HINT}") from None


def check_output(path) -> Path:
    """The output path, after checking its suffix and that its folder exists and is writable.

    Raises:
        TumbleError: a suffix other than .usd/.usda/.usdc/.usdz, a missing folder or one where no
            file can be created, an existing directory.
    """
    path = Path(path)
    if path.suffix.lower() not in EXTENSIONS:
        raise TumbleError(f"cannot write {str(path)!r}: a USD file must end in .usd, .usda, .usdc or .usdz")
    folder = path.parent
    if not folder.is_dir():
        raise TumbleError(f"cannot write {str(path)!r}: folder {str(folder)!r} does not exist")
    if path.is_dir():
        # (the stage was authored, then renaming the temporary file over the folder failed)
        raise TumbleError(f"cannot write {str(path)!r}: is a directory, not a file")
    # a probe file, as for every output (permission bits say little when running as root); an existing
    # read-only file is replaced by the rename, as `run --record` and `render` replace theirs
    probe_folder(folder, f"cannot write {str(path)!r}")
    return path


# ---------------------------------------------------------------------------------------------- frames


def frame_times(
    fps: float | None, duration: float | None, frames: int | None, *, default_fps: float, default_duration: float
) -> tuple[float, int]:
    """(fps, frame count) from the options; frame 0 is the start, so `duration` s give fps * duration + 1.

    Raises:
        TumbleError: a non-positive or non-finite value, or both `duration` and `frames`.
    """
    fps = default_fps if fps is None else float(fps)
    if not (math.isfinite(fps) and fps > 0):
        raise TumbleError(f"fps must be a positive number, got {fps:g}")
    if duration is not None and frames is not None:
        raise TumbleError("give the duration or the number of frames, not both")
    if frames is not None:
        if int(frames) != frames or frames < 1:
            raise TumbleError(f"frames must be a whole number >= 1, got {frames!r}")
        return fps, int(frames)
    duration = default_duration if duration is None else float(duration)
    if not (math.isfinite(duration) and duration > 0):
        raise TumbleError(f"duration must be a positive number of seconds, got {duration:g}")
    return fps, round(duration * fps) + 1


def simulate(
    world,
    *,
    fps: float | None = None,
    duration: float | None = None,
    frames: int | None = None,
    advance: Callable[[], None] = lambda: None,
) -> dict[str, np.ndarray | np.generic]:
    """Step `world` and record it (`tumble.io.record.Recorder`); return the recording's arrays.

    Frame k is the world at its start time + k / fps. `duration` defaults to
    `DEFAULT_DURATION` (2 s); `advance` is called once per frame recorded (a progress bar).
    """
    from .record import Recorder

    fps, n = _world_frames(world, fps, duration, frames)
    recorder = Recorder(world, fps=fps)  # refuses a rate above the world's steps a second
    advance()
    while recorder.frame_count < n:
        before = recorder.frame_count
        world.step()
        recorder(world)
        if recorder.frame_count > before:
            advance()
    world.check_finite()  # (each step checks the state it starts from: this is what the last one left)
    return recorder.arrays()


def _world_frames(world, fps, duration, frames) -> tuple[float, int]:
    """`frame_times` with the export's defaults: 60 fps (at most one frame a step of `world`) for
    `DEFAULT_DURATION` s."""
    default_fps = min(60.0, 1.0 / world.dt)
    return frame_times(fps, duration, frames, default_fps=default_fps, default_duration=DEFAULT_DURATION)


def _check_world_frames(world, fps: float, n: int, *, key: str) -> None:
    """Refuse `n` frames at `fps` past the step limit or the memory their recording needs
    (docs/scenes.md#limits), before anything is simulated."""
    from .. import limits
    from .record import check_rate, frame_bytes

    check_rate(world, fps)  # (first: a rate of 1e9 fps would be refused as 51 GB of frames)
    limits.check_steps(key, (n - 1) / fps, world.dt)
    limits.check_memory(key, "frames", n, frame_bytes(world)[0])


def select_frames(
    rec: dict, *, fps: float | None = None, duration: float | None = None, frames: int | None = None
) -> tuple[np.ndarray, float]:
    """Which recorded frames to export: (indices, fps). Fewer fps than recorded takes the nearest frames.

    Raises:
        TumbleError: more fps than recorded, or more frames or seconds than the recording holds.
    """
    times = np.asarray(rec["time"], dtype=np.float64)
    rec_fps = float(rec["fps"])
    total = len(times)
    length = (times[-1] - times[0]) if total else 0.0
    fps, n = frame_times(
        fps, duration, frames, default_fps=rec_fps, default_duration=length if length > 0 else 1.0 / rec_fps
    )
    if duration is None and frames is None:
        # every output frame that falls within the recording (0.5 s at 15 fps: 8 frames, not
        # round(7.5) + 1 = 9); the 1e-6 absorbs a clock that falls short by a rounding
        n = math.floor(length * fps + 1e-6) + 1
    if fps > rec_fps * (1 + 1e-9):
        raise TumbleError(f"fps {fps:g} is more than the recording's {rec_fps:g}")
    # the last frame's time is checked before the n times are made (frames = 10^11 held 800 GB)
    if times[0] + (n - 1) / fps > times[-1] + 0.5 / rec_fps:
        count = f"{n:,}" if n < 10**15 else f"{float(n):.3g}"
        raise TumbleError(
            f"the recording holds {length:g} s ({total} frames at {rec_fps:g} fps); "
            f"{count} frames at {fps:g} fps need {(n - 1) / fps:g} s"
        )
    want = times[0] + np.arange(n) / fps
    index = np.clip(np.rint((want - times[0]) * rec_fps).astype(np.int64), 0, total - 1)
    return index, fps


# ---------------------------------------------------------------------------------------------- geometry


@dataclass
class Prototype:
    """A mesh that bodies are drawn with, in the body's frame, before scaling.

    Attributes:
        name: prim name, e.g. "sphere".
        points: vertices, shape (V, 3), float32.
        counts: vertices per face, shape (F,), int32.
        indices: vertex index of each face corner, shape (sum(counts),), int32.
        normals: unit normals, shape (V, 3) per vertex, or (sum(counts), 3) per face corner, float32.
        collision: UsdPhysics mesh approximation of the collider ("boundingSphere", "boundingCube", ...).
        normals_interpolation: "vertex" (smooth) or "faceVarying" (one normal per face corner: flat hulls).
        capsule: (radius, half height) [m] of a capsule, written as a `UsdGeom.Capsule` (axis Z) instead of a mesh.
        volume: volume at scale 1 [m^3] (0: not known), for the density of `--physics`.
        color: sRGB colour of the prototype's own prims (static meshes), else None (the body's colour).
    """

    name: str
    points: np.ndarray
    counts: np.ndarray
    indices: np.ndarray
    normals: np.ndarray
    collision: str = "convexHull"
    normals_interpolation: str = "vertex"
    capsule: tuple[float, float] | None = None
    volume: float = 0.0
    color: tuple[float, float, float] | None = None


@dataclass
class PrototypeUse:
    """Bodies drawn with one prototype: their indices (K,) and per-body scales (K, 3)."""

    prototype: Prototype
    bodies: np.ndarray
    scales: np.ndarray


def unit_sphere(segments: int = 32, rings: int = 16) -> Prototype:
    """UV sphere of radius 1: quads, triangles at the poles, smooth normals."""
    theta = np.linspace(0.0, np.pi, rings + 1)[1:-1]  # inner rings, from +z down
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    points = np.vstack([[0.0, 0.0, 1.0], ring, [0.0, 0.0, -1.0]]).astype(np.float32)
    south = len(points) - 1
    s = np.arange(segments)
    s1 = (s + 1) % segments
    faces = [np.stack([np.zeros(segments, int), 1 + s, 1 + s1], axis=1)]  # north cap, counter-clockwise outside
    quads = []
    for r in range(rings - 2):
        a, b = 1 + r * segments, 1 + (r + 1) * segments
        quads.append(np.stack([a + s, b + s, b + s1, a + s1], axis=1))
    last = 1 + (rings - 2) * segments
    faces.append(np.stack([last + s, np.full(segments, south), last + s1], axis=1))  # south cap
    tri_n, tri_s = faces
    counts = np.concatenate([np.full(segments, 3), np.full(len(quads) * segments, 4), np.full(segments, 3)])
    indices = np.concatenate([tri_n.ravel(), np.concatenate(quads).ravel(), tri_s.ravel()])
    return Prototype(
        "sphere", points, counts.astype(np.int32), indices.astype(np.int32), points.copy(), collision="boundingSphere"
    )


def unit_cube() -> Prototype:
    """Cube [-1, 1]^3: six quads with four vertices each, so that normals stay flat."""
    points, normals = [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = np.zeros(3)
            n[axis] = sign
            u, v = np.eye(3)[(axis + 1) % 3], np.eye(3)[(axis + 2) % 3]
            if sign < 0:
                u, v = v, u  # keep the corners counter-clockwise seen from outside
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                points.append(n + a * u + b * v)
                normals.append(n)
    counts = np.full(6, 4, dtype=np.int32)
    indices = np.arange(24, dtype=np.int32)
    return Prototype(
        "box", np.array(points, np.float32), counts, indices, np.array(normals, np.float32), collision="boundingCube"
    )


def _sphere_prototypes(rec: dict, bodies: np.ndarray) -> list[PrototypeUse]:
    r = np.asarray(rec["radius"], dtype=np.float64)[bodies]
    return [PrototypeUse(unit_sphere(), bodies, np.repeat(r[:, None], 3, axis=1))]


def _box_prototypes(rec: dict, bodies: np.ndarray) -> list[PrototypeUse]:
    return [PrototypeUse(unit_cube(), bodies, np.asarray(rec["half_extents"], dtype=np.float64)[bodies])]


def capsule_prototype(radius: float, half_height: float, name: str = "capsule") -> Prototype:
    """A capsule along z (Tumble's axis): a `UsdGeom.Capsule` of that radius and spine length 2 a.

    `points` etc. hold the capsule's bounding box corners only (its extent); the prim is a Capsule.
    """
    r, a = float(radius), float(half_height)
    corners = np.array([[-r, -r, -a - r], [r, r, a + r]], dtype=np.float32)
    volume = math.pi * r * r * (2.0 * a + 4.0 / 3.0 * r)
    return Prototype(
        name,
        corners,
        np.zeros(0, np.int32),
        np.zeros(0, np.int32),
        np.zeros((0, 3), np.float32),
        collision="none",
        capsule=(r, a),
        volume=volume,
    )


def triangle_prototype(
    name: str, points: np.ndarray, triangles: np.ndarray, *, flat: bool, collision: str, color=None
) -> Prototype:
    """A triangle mesh prototype: flat (one normal per face corner: hulls) or smooth (vertex normals: meshes)."""
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    face = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    # volume by the divergence theorem: the sum of the signed tetrahedra (origin, a, b, c)
    volume = float(np.einsum("ij,ij->i", p[t[:, 0]], face).sum() / 6.0)
    if flat:
        unit = face / np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-30)
        normals, interpolation = np.repeat(unit, 3, axis=0), "faceVarying"
    else:
        normals, interpolation = vertex_normals(p, t), "vertex"
    return Prototype(
        name,
        p.astype(np.float32),
        np.full(len(t), 3, np.int32),
        t.reshape(-1).astype(np.int32),
        normals.astype(np.float32),
        collision=collision,
        normals_interpolation=interpolation,
        volume=max(volume, 0.0),
        color=color,
    )


def _capsule_prototypes(rec: dict, bodies: np.ndarray) -> list[PrototypeUse]:
    """One Capsule prototype per distinct (radius, half height); the body-frame half extents are (r, r, a + r)."""
    r = np.asarray(rec["radius"], dtype=np.float64)[bodies]
    a = np.asarray(rec["half_extents"], dtype=np.float64)[bodies, 2] - r
    pairs, which = np.unique(np.stack([r, a], axis=1), axis=0, return_inverse=True)
    which = which.reshape(-1)
    return [
        PrototypeUse(capsule_prototype(ri, ai, f"capsule_{k}"), bodies[which == k], np.ones(((which == k).sum(), 3)))
        for k, (ri, ai) in enumerate(pairs)
    ]


def _rows(rec: dict, kind: str, row: int) -> tuple[np.ndarray, np.ndarray]:
    """Points and triangles (local indices) of hull or mesh `row` of a recording."""
    ps, ts = rec[f"{kind}_point_start"], rec[f"{kind}_triangle_start"]
    points = np.asarray(rec[f"{kind}_points"])[ps[row] : ps[row + 1]]
    triangles = np.asarray(rec[f"{kind}_triangles"])[ts[row] : ts[row + 1]]
    return points, triangles


def _geometry_rows(rec: dict, bodies: np.ndarray, kind: str) -> np.ndarray:
    if "geometry" not in rec or f"{kind}_points" not in rec:
        raise TumbleError(f"this recording has {kind} bodies but not their geometry (recorded by an older Tumble)")
    return np.asarray(rec["geometry"], dtype=np.int64)[bodies]


def _convex_prototypes(rec: dict, bodies: np.ndarray) -> list[PrototypeUse]:
    """One flat-shaded Mesh prototype per distinct hull, in the body frame (origin at the centre of mass)."""
    rows = _geometry_rows(rec, bodies, "hull")
    uses = []
    for row in np.unique(rows):
        points, triangles = _rows(rec, "hull", int(row))
        proto = triangle_prototype(f"hull_{int(row)}", points, triangles, flat=True, collision="convexHull")
        uses.append(PrototypeUse(proto, bodies[rows == row], np.ones(((rows == row).sum(), 3))))
    return uses


def _mesh_prototypes(rec: dict, bodies: np.ndarray) -> list[PrototypeUse]:
    """One smooth Mesh per static triangle mesh, in its frame; collider approximation "none" (the triangles)."""
    from ..render.solids import MESH_COLOR

    rows = _geometry_rows(rec, bodies, "mesh")
    uses = []
    for row in np.unique(rows):
        points, triangles = _rows(rec, "mesh", int(row))
        proto = triangle_prototype(
            f"mesh_{int(row)}", points, triangles, flat=False, collision="none", color=MESH_COLOR
        )
        uses.append(PrototypeUse(proto, bodies[rows == row], np.ones(((rows == row).sum(), 3))))
    return uses


#: shape name -> builder(recording, body indices of that shape) -> the prototypes those bodies use
PROTOTYPES: dict[str, Callable[[dict, np.ndarray], list[PrototypeUse]]] = {
    "sphere": _sphere_prototypes,
    "box": _box_prototypes,
    "capsule": _capsule_prototypes,
    "convex": _convex_prototypes,
    "mesh": _mesh_prototypes,
}


def prototype_uses(rec: dict, bodies: np.ndarray) -> list[PrototypeUse]:
    """The prototypes `bodies` (indices) are drawn with, one builder per shape kind, in shape order.

    Raises:
        TumbleError: a shape kind with no builder in `PROTOTYPES`.
    """
    names = np.asarray(rec["shape_names"]).astype(str)[np.asarray(rec["shape"])[bodies]]
    uses: list[PrototypeUse] = []
    for name in dict.fromkeys(names.tolist()):
        builder = PROTOTYPES.get(name)
        if builder is None:
            raise TumbleError(f"USD export does not know how to draw {name!r} bodies yet")
        uses += builder(rec, bodies[names == name])
    return uses


def srgb_to_linear(c) -> np.ndarray:
    """sRGB colour values in [0, 1] to linear ones (IEC 61966-2-1), float32."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


# ---------------------------------------------------------------------------------------------- the take


@dataclass
class Take:
    """A recording prepared for writing: which bodies go where, per-frame arrays, bounds.

    Attributes:
        rec: the recording's arrays (`tumble.io.record` format, version 1 or 2).
        frames: recorded frame of each exported frame, shape (F,), int.
        fps: exported frames per second.
        planes, static, moving: body indices of planes, of bodies that never move, of the others.
        visible: whether each moving body exists at each exported frame, shape (F, M), bool.
        position: moving bodies' positions with gaps filled by the nearest known one, (F, M, 3).
        orientation: the same for orientations (x, y, z, w), (F, M, 4).
        lo, hi: box around everything that moves and every static body over all frames [m].
    """

    rec: dict
    frames: np.ndarray
    fps: float
    planes: np.ndarray
    static: np.ndarray
    moving: np.ndarray
    visible: np.ndarray
    position: np.ndarray
    orientation: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    @property
    def frame_count(self) -> int:
        return len(self.frames)

    @property
    def cloth(self) -> bool:
        return "cloth_position" in self.rec and "cloth_triangles" in self.rec

    def jointed_moving(self) -> np.ndarray:
        """Moving bodies that take part in a joint (sorted body indices)."""
        if "joint_bodies" not in self.rec:
            return np.zeros(0, np.int64)
        ends = np.asarray(self.rec["joint_bodies"], dtype=np.int64).reshape(-1)
        return np.intersect1d(self.moving, ends[ends >= 0])

    @classmethod
    def from_recording(cls, rec: dict, frames: np.ndarray, fps: float) -> Take:
        names = np.asarray(rec["shape_names"]).astype(str)
        kind = np.asarray(rec["shape"], dtype=np.int64)
        # a removed body's row has shape -1 (and no state): it is left out ("" matches no shape)
        shape = np.where(kind >= 0, names[np.clip(kind, 0, None)], "")
        pos = np.asarray(rec["position"], dtype=np.float64)[frames]
        quat = np.asarray(rec["orientation"], dtype=np.float64)[frames]
        mass = np.asarray(rec["mass"], dtype=np.float64)
        n = len(shape)
        finite = np.isfinite(pos).all(axis=2) & np.isfinite(quat).all(axis=2)  # (F, N)
        planes = np.flatnonzero(shape == "plane")
        # a body is static when it has no mass and neither moves nor turns over the frames exported
        # (a kinematic turntable turning in place was written as static before)
        ever = finite.any(axis=0)
        first = np.where(ever, finite.argmax(axis=0), 0)
        p0 = pos[first, np.arange(n)]
        q0 = quat[first, np.arange(n)]
        absent = ~finite[..., None]
        still = np.all((pos == p0[None]) | absent, axis=(0, 2)) & np.all((quat == q0[None]) | absent, axis=(0, 2))
        static = np.flatnonzero((shape != "plane") & (shape != "") & (mass <= 0.0) & still & ever)
        moving = np.setdiff1d(np.flatnonzero(shape != ""), np.union1d(planes, static))
        visible = finite[:, moving]
        # fill the frames where a body does not exist with its nearest known state (hidden there)
        f = len(frames)
        last_seen = np.where(visible, np.arange(f)[:, None], -1)
        np.maximum.accumulate(last_seen, axis=0, out=last_seen)
        src = np.where(last_seen >= 0, last_seen, first[moving][None, :])
        cols = np.arange(len(moving))[None, :]
        position = pos[:, moving][src, cols]
        orientation = quat[:, moving][src, cols]
        position = np.nan_to_num(position)
        orientation = np.where(np.isfinite(orientation), orientation, [0.0, 0.0, 0.0, 1.0])
        # unit quaternions: pxr turns an orient op into a rotation through acos of the real part, so
        # one 1e-5 too long (a pebble just released) lost a rotation of a few mrad (0.3 degrees)
        orientation = orientation / np.linalg.norm(orientation, axis=2, keepdims=True)
        lo, hi = cls._bounds(rec, frames, pos, finite, moving, static)
        return cls(rec, np.asarray(frames), float(fps), planes, static, moving, visible, position, orientation, lo, hi)

    @staticmethod
    def _bounds(rec, frames, pos, finite, moving, static) -> tuple[np.ndarray, np.ndarray]:
        """Box [m] around moving and static bodies (grown by their size) and cloth, over all frames."""
        lo, hi = [], []
        size = np.maximum(
            np.asarray(rec["radius"], dtype=np.float64),
            np.linalg.norm(np.asarray(rec["half_extents"], dtype=np.float64), axis=1),
        )
        for bodies in (moving, static):
            if len(bodies):
                p = pos[:, bodies]
                ok = finite[:, bodies]
                if ok.any():
                    s = np.broadcast_to(size[bodies], ok.shape)[ok]
                    lo.append((p[ok] - s[:, None]).min(axis=0))
                    hi.append((p[ok] + s[:, None]).max(axis=0))
        if "cloth_position" in rec:
            c = np.asarray(rec["cloth_position"], dtype=np.float64)[frames].reshape(-1, 3)
            c = c[np.isfinite(c).all(axis=1)]
            if len(c):
                lo.append(c.min(axis=0))
                hi.append(c.max(axis=0))
        if not lo:
            return np.array([-1.0, -1.0, 0.0]), np.array([1.0, 1.0, 1.0])
        return np.min(lo, axis=0), np.max(hi, axis=0)


# ---------------------------------------------------------------------------------------------- writing


class _Writer:
    """Authors a Take onto a stage; one method per part of the stage."""

    def __init__(self, stage, take: Take, *, bodies: str, physics: bool, advance: Callable[[], None]):
        from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, UsdShade, Vt

        self.Gf, self.Sdf, self.Usd, self.UsdGeom, self.UsdPhysics, self.UsdShade, self.Vt = (
            Gf,
            Sdf,
            Usd,
            UsdGeom,
            UsdPhysics,
            UsdShade,
            Vt,
        )
        self.stage, self.take, self.bodies, self.physics, self.advance = stage, take, bodies, physics, advance
        self.colors = srgb_to_linear(body_colors(np.arange(len(take.rec["shape"]))))
        self._materials: dict[tuple[float, float], object] = {}
        self._body_prims: dict[int, object] = {}  # body index -> path of its Xform (xforms, jointed bodies)

    def write(self) -> None:
        UsdGeom, take = self.UsdGeom, self.take
        stage = self.stage
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        stage.SetTimeCodesPerSecond(take.fps)
        stage.SetFramesPerSecond(take.fps)
        stage.SetStartTimeCode(0)
        stage.SetEndTimeCode(take.frame_count - 1)
        root = UsdGeom.Xform.Define(stage, "/Root")
        stage.SetDefaultPrim(root.GetPrim())
        stage.GetRootLayer().customLayerData = {"creator": "tumble", "tumble:fps": take.fps}
        if self.physics:
            self._physics_scene()
        self._static()
        if "camera_position" in take.rec:
            self._camera()
        # the animated parts set up their prims, then author one frame at a time
        # with --physics, jointed bodies must be prims a UsdPhysics joint can name: in the default
        # instancer mode they leave the instancer and become Xforms under /Root/JointedBodies
        jointed = take.jointed_moving() if self.physics else np.zeros(0, np.int64)
        if self.bodies == "xforms":
            parts = [self._xforms(take.moving)]
        else:
            parts = [self._instancer(np.setdiff1d(take.moving, jointed)), self._xforms(jointed, "/Root/JointedBodies")]
        if self.physics and "joint_kind" in take.rec:
            self._joints()
        if take.cloth:
            parts.append(self._cloth())
        animate = [frame for frame in parts if frame is not None]
        for k in range(take.frame_count):
            t = self.Usd.TimeCode(k)
            for frame in animate:
                frame(k, t)
            self.advance()

    # -------------------------------------------------------------------- helpers

    def _f3(self, a):
        return self.Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32))

    def _mesh(self, path: str, proto: Prototype, *, color=None):
        """The prototype's prim at `path`: a Mesh, or a Capsule (axis Z) for a capsule prototype."""
        UsdGeom = self.UsdGeom
        if color is None and proto.color is not None:
            color = srgb_to_linear(proto.color)
        if proto.capsule is not None:
            capsule = UsdGeom.Capsule.Define(self.stage, path)
            capsule.CreateAxisAttr(UsdGeom.Tokens.z)
            capsule.CreateRadiusAttr(proto.capsule[0])
            capsule.CreateHeightAttr(2.0 * proto.capsule[1])  # the spine, without the two caps
            capsule.CreateExtentAttr(self._f3(proto.points))
            if color is not None:
                capsule.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(self._f3(np.reshape(color, (1, 3))))
            return capsule
        mesh = UsdGeom.Mesh.Define(self.stage, path)
        mesh.CreatePointsAttr(self._f3(proto.points))
        mesh.CreateFaceVertexCountsAttr(self.Vt.IntArray.FromNumpy(proto.counts))
        mesh.CreateFaceVertexIndicesAttr(self.Vt.IntArray.FromNumpy(proto.indices))
        mesh.CreateNormalsAttr(self._f3(proto.normals))
        mesh.SetNormalsInterpolation(getattr(UsdGeom.Tokens, proto.normals_interpolation))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateExtentAttr(self._f3(np.stack([proto.points.min(axis=0), proto.points.max(axis=0)])))
        if color is not None:
            mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(self._f3(np.reshape(color, (1, 3))))
        return mesh

    def _orient_op(self, xformable):
        """An orient op of double precision: pxr takes the rotation angle from acos of the real part,
        which in float loses rotations of a few mrad (1e-4 rad came out as none at all)."""
        return xformable.AddOrientOp(self.UsdGeom.XformOp.PrecisionDouble)

    def _quat(self, xyzw):
        """A unit Gf.Quatd from Tumble's (x, y, z, w)."""
        q = np.asarray(xyzw, dtype=np.float64)
        x, y, z, w = (q / np.linalg.norm(q)).tolist()
        return self.Gf.Quatd(w, x, y, z)

    def _place(self, xformable, position, orientation, scale=None) -> None:
        """Constant translate, orient (x, y, z, w) and scale ops."""
        Gf = self.Gf
        xformable.AddTranslateOp().Set(Gf.Vec3d(*map(float, position)))
        self._orient_op(xformable).Set(self._quat(orientation))
        if scale is not None:
            xformable.AddScaleOp().Set(Gf.Vec3f(*map(float, scale)))

    def _collider(self, prim, proto: Prototype | None, body: int) -> None:
        """Static collider: CollisionAPI, the mesh approximation, and the body's material."""
        UsdPhysics = self.UsdPhysics
        UsdPhysics.CollisionAPI.Apply(prim)
        if proto is None or proto.capsule is None:  # a Capsule is its own collider shape
            UsdPhysics.MeshCollisionAPI.Apply(prim).CreateApproximationAttr(proto.collision if proto else "none")
        self._bind_material(prim, body)

    def _bind_material(self, prim, body: int) -> None:
        rec = self.take.rec
        if "restitution" not in rec:
            return  # a version-1 recording has no materials
        key = (float(rec["restitution"][body]), float(rec["friction"][body]))
        material = self._materials.get(key)
        if material is None:
            if not self._materials:
                self.UsdGeom.Scope.Define(self.stage, "/Root/Materials")
            path = f"/Root/Materials/physics_{len(self._materials)}"
            material = self.UsdShade.Material.Define(self.stage, path)
            api = self.UsdPhysics.MaterialAPI.Apply(material.GetPrim())
            api.CreateRestitutionAttr(key[0])
            api.CreateStaticFrictionAttr(key[1])
            api.CreateDynamicFrictionAttr(key[1])
            self._materials[key] = material
        self.UsdShade.MaterialBindingAPI.Apply(prim).Bind(
            material, self.UsdShade.Tokens.weakerThanDescendants, "physics"
        )

    # -------------------------------------------------------------------- parts

    def _physics_scene(self) -> None:
        g = np.asarray(self.take.rec.get("gravity", (0.0, 0.0, -9.81)), dtype=np.float64)
        scene = self.UsdPhysics.Scene.Define(self.stage, "/Root/PhysicsScene")
        magnitude = float(np.linalg.norm(g))
        if magnitude > 0:
            scene.CreateGravityDirectionAttr(self.Gf.Vec3f(*map(float, g / magnitude)))
        scene.CreateGravityMagnitudeAttr(magnitude)

    def _static(self) -> None:
        take, rec = self.take, self.take.rec
        if not (len(take.planes) or len(take.static)):
            return
        self.UsdGeom.Xform.Define(self.stage, "/Root/Static")
        frame0 = take.frames[0]
        centre = 0.5 * (take.lo + take.hi)
        half = 0.75 * float(np.linalg.norm(take.hi - take.lo)) + 0.5
        for b in take.planes:
            q = np.asarray(rec["orientation"][frame0, b], dtype=np.float64)
            p = np.asarray(rec["position"][frame0, b], dtype=np.float64)
            if not (np.isfinite(q).all() and np.isfinite(p).all()):
                continue
            # the quad: centred where the action's centre projects onto the plane, in the plane's frame
            n = quat_rotate(q, np.array([0.0, 0.0, 1.0]))
            c = centre - float(np.dot(centre - p, n)) * n
            quad = Prototype(
                "plane",
                np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]], np.float32),
                np.array([4], np.int32),
                np.arange(4, dtype=np.int32),
                np.tile(np.float32([0, 0, 1]), (4, 1)),  # type: ignore[arg-type]  # an array; numpy's stub: scalars only
                collision="none",
            )
            mesh = self._mesh(f"/Root/Static/plane_{b}", quad, color=srgb_to_linear(PLANE_COLOR))
            self._place(mesh, c, q)
            if self.physics:
                self._collider(mesh.GetPrim(), None, b)
        for use in prototype_uses(rec, take.static):
            for b, s in zip(use.bodies, use.scales):
                mesh = self._mesh(f"/Root/Static/{use.prototype.name}_{b}", use.prototype, color=self.colors[b])
                self._place(mesh, rec["position"][frame0, b], rec["orientation"][frame0, b], s)
                if self.physics:
                    self._collider(mesh.GetPrim(), use.prototype, b)

    def _instancer(self, bodies: np.ndarray) -> Callable | None:
        """The PointInstancer of `bodies` (moving body indices, in `take.moving` order)."""
        UsdGeom, Vt, take = self.UsdGeom, self.Vt, self.take
        if not len(bodies):
            return None
        columns = np.searchsorted(take.moving, bodies)  # their columns in take.position / visible
        inst = UsdGeom.PointInstancer.Define(self.stage, "/Root/Bodies")
        self.UsdGeom.Scope.Define(self.stage, "/Root/Bodies/Prototypes")
        uses = prototype_uses(take.rec, bodies)
        # instance k is body k of `bodies`; protoIndices and scales in that order
        slot = {int(b): k for k, b in enumerate(bodies)}
        proto_index = np.empty(len(bodies), np.int32)
        scales = np.empty((len(bodies), 3))
        targets = []
        for j, use in enumerate(uses):
            path = f"/Root/Bodies/Prototypes/{use.prototype.name}"
            if len(uses) > 1 and any(u.prototype.name == use.prototype.name for u in uses[:j]):
                path += f"_{j}"
            mesh = self._mesh(path, use.prototype)
            if self.physics:
                self._rigid_prototype(mesh.GetPrim(), use)
            targets.append(mesh.GetPath())
            rows = np.array([slot[int(b)] for b in use.bodies], dtype=np.int64)
            proto_index[rows] = j
            scales[rows] = use.scales
        inst.CreatePrototypesRel().SetTargets(targets)
        inst.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(proto_index))
        ids = bodies.astype(np.int64)
        inst.CreateIdsAttr(Vt.Int64Array.FromNumpy(ids))
        colors = self.UsdGeom.PrimvarsAPI(inst.GetPrim()).CreatePrimvar(
            "displayColor", self.Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex
        )
        colors.Set(self._f3(self.colors[bodies]))

        positions = inst.CreatePositionsAttr()
        orientations = inst.CreateOrientationsAttr()
        scale_attr = inst.CreateScalesAttr()
        invisible = inst.CreateInvisibleIdsAttr()
        extent = inst.CreateExtentAttr()
        # a body not yet released also gets scale 0, for tools that ignore invisibleIds
        visible = take.visible[:, columns]
        births = not visible.all()
        if not births:
            scale_attr.Set(self._f3(scales))
        # bounds of the prototypes at their scales: unit sphere and cube (the cube reaches sqrt 3), or
        # the capsule's, hull's or mesh's own points
        bound = {
            id(u.prototype): float(np.linalg.norm(u.prototype.points, axis=1).max())
            for u in uses
            if u.prototype.name not in ("sphere", "box")
        }
        radius = np.linalg.norm(scales, axis=1)
        for use in uses:
            if id(use.prototype) in bound:
                radius[[slot[int(b)] for b in use.bodies]] = bound[id(use.prototype)]
        position = take.position[:, columns]
        pos32 = position.astype(np.float32)
        quat16 = take.orientation[:, columns].astype(np.float16)
        previous = None

        def frame(k: int, t) -> None:
            nonlocal previous
            positions.Set(Vt.Vec3fArray.FromNumpy(pos32[k]), t)
            orientations.Set(Vt.QuathArray.FromNumpy(quat16[k]), t)
            seen = visible[k]
            if births:
                scale_attr.Set(self._f3(np.where(seen[:, None], scales, 0.0)), t)
            hidden = ids[~seen]
            if previous is None or not np.array_equal(hidden, previous):
                invisible.Set(Vt.Int64Array.FromNumpy(hidden), t)
                previous = hidden
            if seen.any():
                p = position[k][seen]
                r = radius[seen][:, None]
                extent.Set(self._f3(np.stack([(p - r).min(axis=0), (p + r).max(axis=0)])), t)
            else:
                extent.Set(self._f3(np.zeros((2, 3))), t)

        return frame

    def _rigid_prototype(self, prim, use: PrototypeUse) -> None:
        """RigidBodyAPI and a collider on an instancer's prototype; density from its bodies' masses."""
        UsdPhysics = self.UsdPhysics
        UsdPhysics.RigidBodyAPI.Apply(prim)
        UsdPhysics.CollisionAPI.Apply(prim)
        if use.prototype.capsule is None:
            UsdPhysics.MeshCollisionAPI.Apply(prim).CreateApproximationAttr(use.prototype.collision)
        mass = np.asarray(self.take.rec["mass"], dtype=np.float64)[use.bodies]
        volume = _volume(use.prototype, use.scales)
        if np.all(volume > 0):
            UsdPhysics.MassAPI.Apply(prim).CreateDensityAttr(float(np.median(mass / volume)))
        self._bind_material(prim, int(use.bodies[0]))

    def _xforms(self, bodies: np.ndarray, root: str = "/Root/Bodies") -> Callable | None:
        """One animated Xform per body of `bodies` under `root`; its unscaled frame is the body frame
        (centre of mass, principal axes), the scale sits on its `geom` child."""
        UsdGeom, take, rec = self.UsdGeom, self.take, self.take.rec
        if not len(bodies):
            return None
        UsdGeom.Xform.Define(self.stage, root)
        Gf = self.Gf
        slot = {int(b): k for k, b in enumerate(take.moving)}
        prims = []
        for use in prototype_uses(rec, bodies):
            # the prototype once, as an `over` (not drawn by itself); each body references it
            proto_path = f"/Root/Prototypes/{use.prototype.name}"
            if not self.stage.GetPrimAtPath(proto_path):
                self._mesh(proto_path, use.prototype)
                self.stage.GetPrimAtPath(proto_path).SetSpecifier(self.Sdf.SpecifierOver)
                self.stage.GetPrimAtPath("/Root/Prototypes").SetSpecifier(self.Sdf.SpecifierOver)
            for b, s in zip(use.bodies, use.scales):
                xf = UsdGeom.Xform.Define(self.stage, f"{root}/body_{b:06d}")
                ops = (xf.AddTranslateOp(), self._orient_op(xf))
                geom = self.stage.DefinePrim(f"{root}/body_{b:06d}/geom")
                geom.GetReferences().AddInternalReference(proto_path)
                # a body that does not exist at some frame (not released yet, or removed) also gets
                # scale 0 there, for tools that ignore visibility (Blender draws it all the same)
                hides = not take.visible[:, slot[int(b)]].all()
                scale = None
                if hides:
                    scale = UsdGeom.Xformable(geom).AddScaleOp()
                elif np.any(s != 1.0):
                    UsdGeom.Xformable(geom).AddScaleOp().Set(Gf.Vec3f(*map(float, s)))
                self._body_prims[int(b)] = xf.GetPath()
                UsdGeom.Gprim(geom).CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(
                    self._f3(self.colors[b][None])
                )
                if self.physics:
                    UsdPhysics = self.UsdPhysics
                    UsdPhysics.RigidBodyAPI.Apply(xf.GetPrim())
                    UsdPhysics.MassAPI.Apply(xf.GetPrim()).CreateMassAttr(float(rec["mass"][b]))
                    UsdPhysics.CollisionAPI.Apply(geom)
                    if use.prototype.capsule is None:
                        UsdPhysics.MeshCollisionAPI.Apply(geom).CreateApproximationAttr(use.prototype.collision)
                    self._bind_material(geom, int(b))
                size = Gf.Vec3f(*map(float, s))
                prims.append((slot[int(b)], xf, ops, None if scale is None else (scale, size)))
        vis_tokens = (UsdGeom.Tokens.invisible, UsdGeom.Tokens.inherited)
        nothing = Gf.Vec3f(0.0, 0.0, 0.0)

        def frame(k: int, t) -> None:
            pos = take.position[k]
            quat = take.orientation[k]
            for row, xf, (translate, orient), scaling in prims:
                translate.Set(Gf.Vec3d(*pos[row].tolist()), t)
                x, y, z, w = quat[row].tolist()
                orient.Set(Gf.Quatd(w, x, y, z), t)
                seen = bool(take.visible[k, row])
                if k == 0 or seen != bool(take.visible[k - 1, row]):
                    xf.CreateVisibilityAttr().Set(vis_tokens[seen], t)
                if scaling is not None:  # every frame, as the instancer's scales: no ramp over frames
                    scaling[0].Set(scaling[1] if seen else nothing, t)

        return frame

    def _joints(self) -> None:
        """UsdPhysics joints under /Root/Joints, one per recorded joint, in creation order.

        body0 / body1 name the bodies' Xforms; a joint end at the world, or at a static body (which
        never moves), names no body and gives its anchor and frame in world coordinates. Tumble's
        joint frame has the hinge / slider axis along x, so revolute and prismatic joints have
        axis X; their limits are degrees and metres, a distance joint's min / max its lower /
        upper lengths (a spring's stiffness has no UsdPhysics attribute and is not written).
        """
        from ..solver.joints import JointKind

        UsdPhysics, Gf, rec, take = self.UsdPhysics, self.Gf, self.take.rec, self.take
        kinds = {
            JointKind.BALL: UsdPhysics.SphericalJoint,
            JointKind.HINGE: UsdPhysics.RevoluteJoint,
            JointKind.SLIDER: UsdPhysics.PrismaticJoint,
            JointKind.FIXED: UsdPhysics.FixedJoint,
            JointKind.DISTANCE: UsdPhysics.DistanceJoint,
        }
        self.UsdGeom.Scope.Define(self.stage, "/Root/Joints")
        frame0 = take.frames[0]
        ends = np.asarray(rec["joint_bodies"], dtype=np.int64)
        local = np.asarray(rec["joint_local"], dtype=np.float64)
        frames = np.asarray(rec["joint_frame"], dtype=np.float64)
        for j, kind in enumerate(np.asarray(rec["joint_kind"])):
            joint = kinds[JointKind(int(kind))].Define(self.stage, f"/Root/Joints/joint_{j:04d}")
            for side in (0, 1):
                body = int(ends[j, side])
                pos, rot = local[j, side], frames[j, side]
                path = self._body_prims.get(body)
                if path is None and body >= 0:
                    # a static body: the anchor and frame in world coordinates, attached to the world
                    p, q = rec["position"][frame0, body], rec["orientation"][frame0, body]
                    pos, rot = np.asarray(p) + quat_rotate(q, pos), quat_mul(q, rot)
                rel = joint.CreateBody0Rel() if side == 0 else joint.CreateBody1Rel()
                if path is not None:
                    rel.SetTargets([path])
                x, y, z, w = map(float, rot / np.linalg.norm(rot))
                (joint.CreateLocalPos0Attr if side == 0 else joint.CreateLocalPos1Attr)(Gf.Vec3f(*map(float, pos)))
                (joint.CreateLocalRot0Attr if side == 0 else joint.CreateLocalRot1Attr)(Gf.Quatf(w, x, y, z))
            limited = bool(rec["joint_limit"][j])
            lower, upper = float(rec["joint_lower"][j]), float(rec["joint_upper"][j])
            if kind in (JointKind.HINGE, JointKind.SLIDER):
                joint.CreateAxisAttr("X")
                scale = math.degrees(1.0) if kind == JointKind.HINGE else 1.0
                if limited and abs(lower) < UNLIMITED:
                    joint.CreateLowerLimitAttr(lower * scale)
                if limited and abs(upper) < UNLIMITED:
                    joint.CreateUpperLimitAttr(upper * scale)
            elif kind == JointKind.DISTANCE:
                if lower > 0.0:
                    joint.CreateMinDistanceAttr(lower)
                if upper < UNLIMITED:
                    joint.CreateMaxDistanceAttr(upper)
            force = float(rec["joint_break_force"][j])
            if force < UNLIMITED:
                joint.CreateBreakForceAttr(force)
            joint.CreateCollisionEnabledAttr(bool(rec["joint_collide"][j]))

    def _cloth(self) -> Callable:
        UsdGeom, take, rec = self.UsdGeom, self.take, self.take.rec
        tri = np.asarray(rec["cloth_triangles"], dtype=np.int32)
        pts = np.asarray(rec["cloth_position"], dtype=np.float64)[take.frames]
        mesh = UsdGeom.Mesh.Define(self.stage, "/Root/Cloth")
        mesh.CreateFaceVertexCountsAttr(self.Vt.IntArray.FromNumpy(np.full(len(tri), 3, np.int32)))
        mesh.CreateFaceVertexIndicesAttr(self.Vt.IntArray.FromNumpy(tri.reshape(-1)))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateDoubleSidedAttr(True)
        mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
        mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(self._f3(srgb_to_linear(CLOTH_COLOR[None])))
        points, normals, extent = mesh.CreatePointsAttr(), mesh.CreateNormalsAttr(), mesh.CreateExtentAttr()

        def frame(k: int, t) -> None:
            p = np.nan_to_num(pts[k])
            points.Set(self._f3(p), t)
            normals.Set(self._f3(vertex_normals(p, tri)), t)
            extent.Set(self._f3(np.stack([p.min(axis=0), p.max(axis=0)])), t)

        return frame

    def _camera(self) -> None:
        rec = self.take.rec
        from ..render.camera import Camera

        cam = Camera(rec["camera_position"], rec["camera_target"], rec["camera_up"], float(rec["camera_fov"]))
        right, up, forward = cam.basis()
        # USD cameras look down their -z with +y up: the columns of the rotation are right, up, -forward
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, -forward, cam.position
        prim = self.UsdGeom.Camera.Define(self.stage, "/Root/Camera")
        prim.AddTransformOp().Set(self.Gf.Matrix4d(m.T.tolist()))  # Gf matrices act on row vectors
        # apertures in tenths of a scene unit, as USD asks; only their ratio to the focal length matters
        vertical = 20.25
        prim.CreateVerticalApertureAttr(vertical)
        prim.CreateHorizontalApertureAttr(vertical * 16.0 / 9.0)
        prim.CreateFocalLengthAttr(0.5 * vertical / math.tan(math.radians(cam.fov_deg) / 2.0))
        near, far = cam.clip_range()
        prim.CreateClippingRangeAttr(self.Gf.Vec2f(near, far))


def _volume(proto: Prototype, scales: np.ndarray) -> np.ndarray:
    """Volume [m^3] of prototypes scaled by `scales` (K, 3); 0 where the shape is not known."""
    if proto.name == "sphere":
        return 4.0 / 3.0 * np.pi * np.prod(scales, axis=1)
    if proto.name == "box":
        return 8.0 * np.prod(scales, axis=1)
    return proto.volume * np.prod(scales, axis=1)


# ---------------------------------------------------------------------------------------------- export


#: what a recording must hold for an export (`tumble.io.record` writes more)
RECORDING_KEYS = ("time", "fps", "position", "orientation", "shape", "shape_names", "radius", "half_extents", "mass")


def _recording(source) -> dict:
    """A recording's arrays from a dict or an .npz path."""
    if isinstance(source, dict):
        missing = [k for k in RECORDING_KEYS if k not in source]
        if missing:  # (a bare KeyError before)
            raise TumbleError(f"the recording given has no {', '.join(missing)}: it is not a Tumble recording")
        return source
    from .record import load_recording

    path = Path(source)
    if path.suffix != ".npz":
        raise TumbleError(f"{str(path)!r}: a recording is an .npz file written by `tumble run --record`")
    if not path.is_file():
        raise TumbleError(f"{str(path)!r}: no such recording")
    try:
        rec = load_recording(path)
    except TumbleError:
        raise
    except Exception as exc:  # noqa: BLE001 - a broken archive, whatever numpy makes of it
        raise TumbleError(f"{str(path)!r}: not a readable recording ({type(exc).__name__}: {exc})") from None
    missing = [k for k in RECORDING_KEYS if k not in rec]
    if missing:
        raise TumbleError(f"{str(path)!r}: not a Tumble recording (no {', '.join(missing)})")
    return rec


def export(
    source,
    path,
    *,
    fps: float | None = None,
    duration: float | None = None,
    frames: int | None = None,
    bodies: str = "instancer",
    physics: bool = False,
    progress: bool = False,
) -> Path:
    """Write a simulation or a recording to a USD stage at `path`; return the path.

    Args:
        source: a `World` (simulated here from its current state), a recording's arrays (the dict
            `tumble.io.record.load_recording` returns), or the path of a recording (.npz).
        path: .usd or .usdc (binary), .usda (text) or .usdz (zipped package).
        fps: frames per second; a world's default is 60, a recording's the rate it was recorded at
            (a lower rate takes the nearest recorded frames).
        duration: seconds to cover (frame 0 is the start, so duration * fps + 1 frames); default
            2 s for a world, all of it for a recording.
        frames: number of frames, instead of `duration`.
        bodies: "instancer" (one PointInstancer) or "xforms" (one animated Xform per body).
        physics: also write UsdPhysics schemas (scene, colliders, rigid bodies, masses, materials).
        progress: show progress bars on stderr.

    Raises:
        TumbleError: no pxr, a bad suffix or folder, bad options, an unreadable or newer recording.
    """
    from ..progress import progress_bar

    require_pxr()
    path = check_output(path)
    if bodies not in BODY_MODES:
        raise TumbleError(f"bodies must be one of {', '.join(BODY_MODES)}, got {bodies!r}")

    if hasattr(source, "step") and hasattr(source, "body_position"):
        out_fps, n = _world_frames(source, fps, duration, frames)
        _check_world_frames(source, out_fps, n, key=f"frames {n:,} at {out_fps:g} fps" if frames else "duration")
        with progress_bar(n, "simulating", enabled=progress) as advance:
            rec = simulate(source, fps=out_fps, frames=n, advance=advance)
        index = np.arange(n)
    else:
        rec = _recording(source)
        index, out_fps = select_frames(rec, fps=fps, duration=duration, frames=frames)
    take = Take.from_recording(rec, index, out_fps)
    with progress_bar(take.frame_count, f"writing {path.name}", enabled=progress) as advance:
        _write_atomic(take, path, bodies=bodies, physics=physics, advance=advance)
    return path


def _write_atomic(take: Take, path: Path, *, bodies: str, physics: bool, advance) -> None:
    """Author the stage in memory, export it to a temporary file beside `path`, then rename it over
    (`tumble.io.atomic.atomic_path`: flushed to disk first, with the permissions of the file it replaces)."""
    from pxr import Sdf, Tf, Usd, UsdUtils

    stage = Usd.Stage.CreateInMemory()
    _Writer(stage, take, bodies=bodies, physics=physics, advance=advance).write()
    layer_dir = None
    try:
        # pxr picks the file format from the extension, which the temporary name ends in too
        with atomic_path(path) as tmp_path:
            tmp = str(tmp_path)
            if path.suffix.lower() == ".usdz":
                # the package's root layer is named after the output (`rain.usdc` in `rain.usdz`), so it
                # is written in a private folder beside it
                layer_dir = tempfile.mkdtemp(dir=path.parent, prefix=f".{path.stem}.")
                layer_tmp = os.path.join(layer_dir, f"{path.stem}.usdc")
                if not stage.GetRootLayer().Export(layer_tmp):
                    raise TumbleError(f"cannot write {str(path)!r}: pxr could not write the stage")
                os.remove(tmp)  # the packager refuses to overwrite
                if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(layer_tmp), tmp):
                    raise TumbleError(f"cannot write {str(path)!r}: pxr could not make the .usdz package")
            elif not stage.GetRootLayer().Export(tmp):
                raise TumbleError(f"cannot write {str(path)!r}: pxr could not write the stage")
    except (Tf.ErrorException, TumbleError) as exc:
        if _disk_full(path.parent):  # pxr's own words for it are about a corrupt asset
            raise TumbleError(f"cannot write {str(path)!r}: no space left on the device") from None
        if isinstance(exc, TumbleError):
            raise
        message = " ".join(str(exc).strip().splitlines()[-1].split()) if str(exc).strip() else "pxr error"
        raise TumbleError(f"cannot write {str(path)!r}: {message}") from None
    finally:
        if layer_dir is not None:
            shutil.rmtree(layer_dir, ignore_errors=True)


def _disk_full(folder: Path) -> bool:
    """Whether the file system of `folder` has (next to) no room left, after a failed write."""
    try:
        return shutil.disk_usage(folder).free < 2**20
    except OSError:
        return False
