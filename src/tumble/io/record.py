"""Trajectory recording: sample a world at a fixed rate of simulated time, save as .npz.

Typical use::

    recorder = Recorder(world, fps=60)          # records the first frame now
    world.run(2.0, callback=recorder)           # records a frame every 1/60 s of simulated time
    recorder.save("pile.npz")

The per-body and per-particle arrays are the declared ones (`model.BODY_FIELDS`,
`cloth.arrays.PARTICLE_FIELDS`), named without their entity: each state array every frame
(`body_position` -> position (F, N, 3), `particle_velocity` -> cloth_velocity (F, P, 3)), each
model array once (`body_mass` -> mass (N,), `particle_mass` -> cloth_mass (P,)); scratch and
control arrays are not recorded. A new declared array is recorded without a line here.

The file format (documented in docs/scenes.md, "Recordings"), with F frames and N bodies (the
final body count, in creation order; rows of bodies that did not exist yet at a frame are NaN):

    time (F,), position (F, N, 3), velocity (F, N, 3), orientation (F, N, 4) as (x, y, z, w),
    angular_velocity (F, N, 3), shape (N,) int32 indexing shape_names, shape_names (6,) (ShapeType order),
    radius (N,), half_extents (N, 3), mass (N,), geometry (N,) int32, and the other model arrays
    (id, kind, bound_radius, inv_mass, inv_inertia), gravity (3,), dt (), fps (),
    contact_count (F,) int32, kinetic_energy (F,), momentum (F, 3) [kg m/s] (bodies and cloth)
    with cloth: cloth_position (F, P, 3), cloth_velocity (F, P, 3), cloth_pin_target (F, P, 3),
    cloth_triangles (T, 3) int32, cloth_rest_position (P, 3), cloth_mass (P,) [kg], and the other
    particle model arrays, cloth_max_strain (F,) (largest structural-spring strain per frame)
    since version 2: restitution (N,), friction (N,); with a scene [camera]: camera_position (3,),
    camera_target (3,), camera_up (3,), camera_fov () [degrees]
    with joints (J of them, in creation order): joint_force (F, J, 3) [N] and joint_torque (F, J, 3)
    [N m] on each joint's body b, joint_broken (F, J) bool, joint_bodies (J, 2) int32 (-1 = the world),
    and the joints' model (what USD export writes as UsdPhysics joints): joint_kind (J,) int32
    (JointKind), joint_local (J, 2, 3) [m] anchors in each body's frame (the world's: world
    points), joint_frame (J, 2, 4) joint frames in each body's frame (x = hinge / slider axis),
    joint_limit (J,) int32, joint_lower / joint_upper (J,) [rad or m], joint_break_force (J,) [N],
    joint_collide (J,) int32
    with convex bodies or static meshes, per kind K in (hull, mesh) (`geometry` is a body's row): K_points (V, 3) [m] in the body / mesh frame, K_triangles (T, 3)
    int32 indexing K_points, K_point_start and K_triangle_start (rows + 1,) int64 (row i is
    points [start[i], start[i + 1]) ...); hull triangles are the faces fanned, counter-clockwise outside

Cost: one host copy of the body state per frame (~100 bytes per body per frame in memory).
Files written before the model arrays were all recorded (no id, kind, ... nor cloth_velocity;
geometry only with hulls or meshes) read the same: readers use what is there.
"""

from __future__ import annotations

import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from .. import limits, validate
from ..cloth.arrays import PARTICLE_FIELDS
from ..errors import TumbleError
from ..model import BODY_FIELDS, Field, Role
from ..shapes import SHAPE_NAMES

#: format version written as `format_version` in every recording
FORMAT_VERSION = 2


def recorded_name(field: Field) -> str:
    """The name a declared array has in a recording: `body_position` -> "position",
    `particle_position` -> "cloth_position"."""
    entity, _, rest = field.name.partition("_")
    return rest if entity == "body" else f"cloth_{rest}"


def _recorded(declaration: tuple[Field, ...], role: Role) -> dict[str, Field]:
    return {recorded_name(f): f for f in declaration if f.role is role}


#: the declared arrays recorded every frame (state) and once (model), by their names in a recording
BODY_STATE = _recorded(BODY_FIELDS, Role.STATE)
BODY_MODEL = _recorded(BODY_FIELDS, Role.MODEL)
PARTICLE_STATE = _recorded(PARTICLE_FIELDS, Role.STATE)
PARTICLE_MODEL = _recorded(PARTICLE_FIELDS, Role.MODEL)


class Recorder:
    """Samples a world every 1/fps seconds of simulated time.

    Use it as the `callback` of `World.run`, or call it after each `World.step`; it records a
    frame whenever the world's time has reached the next sample time. The frame at the current
    time is recorded on construction.

    Args:
        world: the world to record.
        fps: frames per second of simulated time (> 0).
    """

    def __init__(self, world, fps: float = 60.0):
        fps = check_rate(world, validate.positive(fps, "fps"))
        self.world = world
        self.fps = fps
        self.start_time = float(world.time)
        # the scene's [camera] as resolved at the first frame (the USD export's Camera prim)
        self.camera = None
        if getattr(world, "metadata", {}).get("camera"):
            from ..render.camera import Camera

            self.camera = Camera.for_world(world)
        self.frames: list[dict[str, Any]] = []  # per frame: name -> array or NumPy scalar
        # each body id's model (shape, sizes, mass, ...) as last seen alive, so that a body removed
        # during the recording keeps the shape it had in the frames before (the views show -1 for it)
        self._model: dict[str, np.ndarray] = {}
        self._model_seen: tuple[int, int] | None = None
        self.capture()

    @property
    def frame_count(self) -> int:
        """Number of frames recorded so far."""
        return len(self.frames)

    def __call__(self, world=None) -> None:
        """Record a frame if the world's time has reached the next sample time."""
        world = self.world if world is None else world
        # frame k is due at start + k / fps; half a step of slack absorbs rounding in world.time
        due = self.start_time + len(self.frames) / self.fps
        if world.time + 0.5 * world.dt >= due:
            self.capture()

    def capture(self) -> None:
        """Record the world's current state as the next frame, whatever the time."""
        w = self.world
        frame: dict[str, Any] = {name: np.array(w.body_values(f.name)) for name, f in BODY_STATE.items()}
        frame["time"] = np.float64(w.time)
        frame["contact_count"] = np.int32(w.contact_count)
        frame["kinetic_energy"] = np.float64(w.kinetic_energy())
        frame["momentum"] = np.array(w.momentum(), dtype=np.float64)
        cloth = w.cloth if w.has_cloth else None
        if cloth is not None:
            frame["momentum"] = frame["momentum"] + cloth.momentum()
            for name, f in PARTICLE_STATE.items():
                frame[name] = np.array(cloth.particle_values(f.name))
            frame["cloth_max_strain"] = np.float64(cloth.max_strain())
        if getattr(w, "joint_count", 0):
            frame["joint_force"] = np.array(w.joint_force, dtype=np.float64)
            frame["joint_torque"] = np.array(w.joint_torque, dtype=np.float64)
            frame["joint_broken"] = np.array(w.joint_broken, dtype=bool)
        self.frames.append(frame)
        self._note_model()

    def _note_model(self) -> None:
        """Keep the model of every live body id, when bodies were added or removed since the last look
        (an id freed and given to a new body within one frame keeps the new body's)."""
        w = self.world
        alive = np.asarray(w.body_alive)
        seen = (len(alive), int(np.count_nonzero(alive)))
        if seen == self._model_seen:
            return
        self._model_seen = seen
        for name, decl in BODY_MODEL.items():
            now = np.array(w.body_values(decl.name))
            old = self._model.get(name)
            if old is None:
                self._model[name] = now
                continue
            rows = max(len(old), len(now))
            kept = np.concatenate([old, now[len(old) :]]) if len(now) > len(old) else old.copy()
            kept[: len(now)][alive] = now[alive]
            self._model[name] = kept[:rows]

    def arrays(self) -> dict[str, np.ndarray | np.generic]:
        """The recording as named arrays (what `save` writes)."""
        w = self.world
        self._note_model()
        n = max(w.body_count, len(self._model[next(iter(BODY_MODEL))]))
        f = len(self.frames)
        out: dict[str, np.ndarray | np.generic] = {
            "format_version": np.int32(FORMAT_VERSION),
            "time": np.array([fr["time"] for fr in self.frames], dtype=np.float64),
            "contact_count": np.array([fr["contact_count"] for fr in self.frames], dtype=np.int32),
            "kinetic_energy": np.array([fr["kinetic_energy"] for fr in self.frames], dtype=np.float64),
            "momentum": np.array([fr["momentum"] for fr in self.frames], dtype=np.float64).reshape(f, 3),
        }
        # per-body state, padded with NaN for bodies created after the frame; the model once
        for name, decl in BODY_STATE.items():
            out[name] = _frames(self.frames, name, n, decl.shape)
        for name in BODY_MODEL:
            out[name] = self._model[name]
        out["shape_names"] = np.array(SHAPE_NAMES)
        if self.camera is not None:
            out["camera_position"] = np.array(self.camera.position, dtype=np.float64)
            out["camera_target"] = np.array(self.camera.target, dtype=np.float64)
            out["camera_up"] = np.array(self.camera.up, dtype=np.float64)
            out["camera_fov"] = np.float64(self.camera.fov_deg)
        out["gravity"] = np.array(w.gravity, dtype=np.float64)
        out["dt"] = np.float64(w.dt)
        out["fps"] = np.float64(self.fps)

        cloth = w.cloth if w.has_cloth else None
        if cloth is not None:
            for name, decl in PARTICLE_STATE.items():
                out[name] = _frames(self.frames, name, cloth.particle_count, decl.shape)
            for name, decl in PARTICLE_MODEL.items():
                out[name] = np.array(cloth.particle_values(decl.name))
            out["cloth_triangles"] = np.array(cloth.triangles, dtype=np.int32)
            out["cloth_max_strain"] = np.array([fr.get("cloth_max_strain", np.nan) for fr in self.frames])
        if getattr(w, "joint_count", 0):
            j = w.joint_count
            out["joint_force"] = _frames(self.frames, "joint_force", j, (3,))
            out["joint_torque"] = _frames(self.frames, "joint_torque", j, (3,))
            out["joint_broken"] = _frames(self.frames, "joint_broken", j, fill=False)
            bodies = np.stack([w.joints.numpy("joint_body_a"), w.joints.numpy("joint_body_b")], axis=1)
            ids = np.asarray(w.bodies.numpy("body_id"))
            out["joint_bodies"] = np.where(bodies >= 0, ids[np.maximum(bodies, 0)], -1).astype(np.int32)
            out.update(_joint_model(w.joints))
        out.update(_geometry(w))
        return out

    def save(self, path) -> Path:
        """Write the recording to `path` (.npz, compressed), atomically. Returns the path written.

        The file is written beside `path` and renamed into place (`tumble.io.atomic`): a failure
        (a full disk, Ctrl-C) leaves an existing `path` as it was and no partial file.

        Raises:
            OutputError: `path` does not end in .npz, its folder is missing or unwritable, or the
                write failed (an OSError).
        """
        from .atomic import atomic_path, check_output

        path = check_output(path, suffixes=(".npz",), option="")
        arrays = self.arrays()
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays)  # type: ignore[arg-type]  # numpy's stub: a key could be allow_pickle
        return path


def _frames(frames: list[dict[str, Any]], name: str, rows: int, tail: tuple[int, ...] = (), fill=np.nan) -> np.ndarray:
    """The per-frame array `name` stacked over frames, `rows` rows of shape `tail` each; `fill` in
    the rows of a frame that did not have them yet (a body emitted later, a cloth added later)."""
    a = np.full((len(frames), rows, *tail), fill)
    for k, fr in enumerate(frames):
        got = fr.get(name)
        if got is not None:
            a[k, : len(got)] = got
    return a


def _joint_model(joints) -> dict[str, np.ndarray]:
    """The joints' fixed description (anchors, frames, limits), in creation order."""
    get = joints.numpy
    return {
        "joint_kind": np.array(get("joint_kind"), dtype=np.int32),
        "joint_local": np.stack([get("joint_local_a"), get("joint_local_b")], axis=1).astype(np.float64),
        "joint_frame": np.stack([get("joint_frame_a"), get("joint_frame_b")], axis=1).astype(np.float64),
        "joint_limit": np.array(get("joint_limit"), dtype=np.int32),
        "joint_lower": np.array(get("joint_lower"), dtype=np.float64),
        "joint_upper": np.array(get("joint_upper"), dtype=np.float64),
        "joint_break_force": np.array(get("joint_break_force"), dtype=np.float64),
        "joint_collide": np.array(get("joint_collide"), dtype=np.int32),
    }


def _geometry(w) -> dict[str, np.ndarray]:
    """Hull prototypes and static meshes as flat arrays, when the world has convex bodies or meshes."""
    shape = np.asarray(w.body_shape)
    out: dict[str, np.ndarray] = {}
    has_hull = bool(np.any(shape == SHAPE_NAMES.index("convex")))
    meshes = getattr(w, "meshes", None)
    has_mesh = meshes is not None and len(meshes.vertices) > 0
    if not (has_hull or has_mesh):
        return out
    if has_hull:
        tris = []
        for p in w.hulls.prototypes:
            tris.append(
                np.array(
                    [(f[0], f[k], f[k + 1]) for f in p.faces for k in range(1, len(f) - 1)], dtype=np.int64
                ).reshape(-1, 3)
            )
        out.update(_flat("hull", [p.vertex for p in w.hulls.prototypes], tris))
    if has_mesh:
        assert meshes is not None
        out.update(_flat("mesh", meshes.vertices, meshes.triangles))
    return out


def _flat(kind: str, points: list, triangles: list) -> dict[str, np.ndarray]:
    """Lists of (V_i, 3) points and (T_i, 3) triangles as concatenated arrays with row starts."""
    point_start = np.concatenate([[0], np.cumsum([len(p) for p in points])]).astype(np.int64)
    triangle_start = np.concatenate([[0], np.cumsum([len(t) for t in triangles])]).astype(np.int64)
    return {
        f"{kind}_points": np.concatenate([np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in points]),
        f"{kind}_triangles": np.concatenate([np.asarray(t, dtype=np.int64).reshape(-1, 3) for t in triangles]).astype(
            np.int32
        ),
        f"{kind}_point_start": point_start,
        f"{kind}_triangle_start": triangle_start,
    }


class RecordingError(TumbleError, ValueError):
    """A file that is not a readable recording; the message names the file and what is wrong."""


#: the first bytes of a zip archive (an .npz), of an empty one, and of a single .npy array
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")
_NPY_MAGIC = b"\x93NUMPY"


#: memory a reader needs per byte of an archive's arrays: the arrays, and what is made of them (a
#: recording's padded rows, the USD or plot values, a snapshot's digest and world)
READ_COPIES = 2


class ArchiveError(ValueError):
    """An .npz archive whose arrays cannot be what they declare (see `check_archive`)."""


def check_archive(path: Path) -> None:
    """Check an .npz archive's arrays before loading any: each member's .npy header must declare
    exactly the bytes the member holds, and twice their bytes must fit in the memory available
    (`READ_COPIES`).

    Reading a damaged header (one declaring 10^12 rows) asked NumPy for terabytes, and an archive
    of well-compressed zeros expanded to tens of gigabytes before anything was checked.

    Raises:
        ArchiveError: one line (without the path): the member and what is wrong.
        limits.LimitError: the arrays need more memory than is available.
        zipfile.BadZipFile: the archive itself is damaged.
    """
    total = 0
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            name = info.filename.removesuffix(".npy")
            with archive.open(info) as f:
                try:
                    version = np.lib.format.read_magic(f)
                    if version == (1, 0):
                        shape, _, dtype = np.lib.format.read_array_header_1_0(f)
                    elif version == (2, 0):
                        shape, _, dtype = np.lib.format.read_array_header_2_0(f)
                    else:
                        raise ValueError(f"unsupported .npy version {version}")
                except (ValueError, SyntaxError, EOFError) as exc:
                    raise ArchiveError(f"member {name!r} is not a valid .npy array ({exc})") from None
                header = f.tell()
            if dtype.hasobject:
                raise ArchiveError("it holds object (pickled) arrays, which Tumble never loads")
            declared = dtype.itemsize
            for n in shape:
                declared *= int(n)
            if header + declared != info.file_size:
                raise ArchiveError(
                    f"array {name!r} declares {limits.show_bytes(declared)} of data but holds "
                    f"{limits.show_bytes(info.file_size - header)}: the file is damaged or was edited"
                )
            total += declared
    have = limits.available_memory()
    if READ_COPIES * total > have:
        raise limits.LimitError(
            f"its arrays hold {limits.show_bytes(total)}, and reading them needs about "
            f"{limits.show_bytes(READ_COPIES * total)} of memory; {limits.show_bytes(have)} is available"
        )


def load_recording(path) -> dict[str, np.ndarray]:
    """Read a recording written by `Recorder.save` into a dict of arrays.

    Object (pickled) arrays are never loaded.

    Raises:
        RecordingError: a missing, empty, truncated or corrupt file, a file of another kind (a
            scene file, a single .npy array), or one without a non-empty 1-D `time` array of
            finite, increasing times.
        TumbleError: the file was written by a newer format version than this Tumble reads.
    """
    p = Path(path)

    def bad(why: str) -> RecordingError:
        return RecordingError(f"{p}: not a readable recording (.npz): {why}")

    if not p.exists():
        raise RecordingError(f"{p}: no such recording")
    if p.is_dir():
        raise bad("it is a directory")
    try:
        with open(p, "rb") as f:
            head = f.read(512)
    except OSError as exc:
        raise bad(f"cannot read it ({exc.strerror or exc})") from None
    kind = file_kind(p, head)
    if kind != "zip":
        raise bad(_NOT_A_RECORDING[kind].format(path=p))
    try:
        check_archive(p)
        with np.load(p, allow_pickle=False) as data:
            if not hasattr(data, "files"):
                raise bad("it holds a single array, not named arrays")
            out = {name: data[name] for name in data.files}
    except zipfile.BadZipFile as exc:
        raise bad(
            f"corrupt ({exc})" if "CRC" in str(exc) else "truncated or corrupt (not a complete zip archive)"
        ) from None
    except limits.LimitError as exc:
        raise RecordingError(f"{p}: {exc}") from None
    except ArchiveError as exc:
        raise bad(str(exc)) from None
    except ValueError as exc:  # (object arrays are refused by check_archive before NumPy sees them)
        raise bad(f"corrupt ({exc})") from None
    except (OSError, EOFError, KeyError, zlib.error) as exc:
        raise bad(f"truncated or corrupt ({type(exc).__name__}: {exc})") from None
    time = out.get("time")
    if "manifest" in out and time is None:  # what tumble.snapshot.write makes
        raise RecordingError(
            f"{p}: a saved state (run --save-state), not a recording; resume it with tumble run --resume, "
            "or make a recording with tumble run --record"
        )
    if time is None or time.ndim != 1 or len(time) == 0:
        raise RecordingError(f"{p}: a recording needs a non-empty 1-D 'time' array")
    _check_rows(out, p)
    version = out.get("format_version", np.int32(1))
    if version.shape != () or version.dtype.kind not in "iu":
        raise RecordingError(
            f"{p}: recording array 'format_version' is not an integer: the file is damaged or was edited"
        )
    if int(version) > FORMAT_VERSION:
        raise TumbleError(
            f"{path}: recording format version {int(version)} is newer than this Tumble reads "
            f"(up to {FORMAT_VERSION}); upgrade Tumble"
        )
    _check_tables(out, p)
    if not (np.all(np.isfinite(time)) and np.all(np.diff(time) > 0)):  # readers search it and divide by it
        raise RecordingError(
            f"{p}: recording array 'time' is not finite and increasing: the file is damaged or was edited"
        )
    return out


def check_rate(world, fps: float) -> float:
    """`fps`, refused (LimitError) above the world's steps a second: one frame a step at most. A higher
    rate would be stored as the recording's fps while its frames are a step apart, and exports would
    time them by the false rate."""
    if fps > 1.0 / float(world.dt) * (1 + 1e-9):
        raise limits.LimitError(f"fps {fps:g} is more than the world's {1.0 / float(world.dt):g} steps per second")
    return fps


def frame_bytes(world) -> tuple[int, int, int]:
    """Memory a recording of `world` holds per frame [bytes] (docs/scenes.md#limits), with the bodies
    it counts (those its emitters have still to release included) and its cloth particles."""
    bodies = world.body_count + sum(e.count - e.emitted for e in world.emitters)
    particles = world.cloth.particle_count if world.has_cloth else 0
    return bodies * limits.BYTES_PER_BODY_FRAME + particles * limits.BYTES_PER_PARTICLE_FRAME, bodies, particles


#: the joints' arrays in a recording, per frame and once, with the trailing shape of one joint's row
JOINT_STATE = {"joint_force": (3,), "joint_torque": (3,), "joint_broken": ()}
JOINT_MODEL = {
    "joint_bodies": (2,),
    "joint_kind": (),
    "joint_local": (2, 3),
    "joint_frame": (2, 4),
    "joint_limit": (),
    "joint_lower": (),
    "joint_upper": (),
    "joint_break_force": (),
    "joint_collide": (),
}
#: arrays of one value or one vector (the trailing shape), when present
_FIXED = {
    "dt": (),
    "fps": (),
    "gravity": (3,),
    "camera_position": (3,),
    "camera_target": (3,),
    "camera_up": (3,),
    "camera_fov": (),
}
#: arrays written together: a file holding one of a group holds all of them (readers take them as one)
_TOGETHER = (
    ("camera_position", "camera_target", "camera_up", "camera_fov"),
    ("restitution", "friction"),
    (*JOINT_STATE, "joint_bodies"),
    tuple(name for name in JOINT_MODEL if name != "joint_bodies"),  # (written since later than the rest)
    *((f"{k}_points", f"{k}_triangles", f"{k}_point_start", f"{k}_triangle_start") for k in ("hull", "mesh")),
)
#: arrays of indices (NumPy integer types only)
_INDICES = (
    "shape",
    "geometry",
    "joint_bodies",
    "joint_kind",
    "cloth_triangles",
    *(f"{k}_{a}" for k in ("hull", "mesh") for a in ("triangles", "point_start", "triangle_start")),
)


def _check_rows(rec: dict[str, np.ndarray], path: Path) -> None:
    """Refuse a recording whose declared arrays disagree on the frame, body, particle or joint count
    (an edited or damaged file), or whose `shape` names no shape, before a reader indexes one by another."""
    frames = len(rec["time"])
    body_state = {name: f.shape for name, f in BODY_STATE.items()}
    body_model = {name: f.shape for name, f in BODY_MODEL.items()}
    particle_state = {name: f.shape for name, f in PARTICLE_STATE.items()}
    particle_model = {name: f.shape for name, f in PARTICLE_MODEL.items()}
    for entity, state, model in (
        ("bodies", body_state, body_model),
        ("particles", particle_state, particle_model),
        ("joints", JOINT_STATE, JOINT_MODEL),
    ):
        count, first = None, ""  # rows of this entity, from the first array found
        for per_frame, fields in ((True, state), (False, model)):
            for name, tail in fields.items():
                a = rec.get(name)
                if a is None:
                    continue
                lead = (frames,) if per_frame else ()
                rows = a.shape[len(lead)] if a.ndim > len(lead) else -1
                if count is None:
                    count, first = rows, name
                want = (*lead, count, *tail)
                if a.shape != want:
                    raise RecordingError(
                        f"{path}: recording array {name!r} has shape {a.shape}, expected {want} ({frames} "
                        f"frames, {count} {entity} as {first!r} has): the file is damaged or was edited"
                    )
    shape = rec.get("shape")
    if shape is not None and shape.size and shape.dtype.kind in "iu":  # -1: a body removed (`World.remove_body`)
        odd = shape[(shape < -1) | (shape >= len(SHAPE_NAMES))]
        if odd.size:
            raise RecordingError(f"{path}: recording array 'shape' holds {int(odd[0])}, which names no shape")


def _check_tables(rec: dict[str, np.ndarray], path: Path) -> None:
    """Refuse a recording whose other arrays an exporter or a plot reads are damaged or edited: a
    value of the wrong type or shape, one of a group of arrays missing, or an index (a shape, a hull or
    mesh row, a triangle's corner, a joint's body) out of its table, before a reader indexes by it."""

    def bad(name: str, why: str) -> RecordingError:
        return RecordingError(f"{path}: recording array {name!r} {why}: the file is damaged or was edited")

    for group in _TOGETHER:
        if "joint_kind" in group and "joint_kind" in rec:  # the joints' model came later, never without these
            group = (*group, *JOINT_STATE, "joint_bodies")
        held = [name for name in group if name in rec]
        if held and len(held) < len(group):
            missing = next(name for name in group if name not in rec)
            raise RecordingError(
                f"{path}: recording array {missing!r} is missing (the file has {held[0]!r}): "
                "the file is damaged or was edited"
            )
    for name, a in rec.items():
        if name == "shape_names":
            if a.ndim != 1 or a.dtype.kind != "U":
                raise bad(name, f"has shape {a.shape} and type {a.dtype}, expected strings")
        elif name in _INDICES:
            if a.dtype.kind not in "iu":
                raise bad(name, f"has type {a.dtype}, expected integers")
        elif a.dtype.kind not in "biuf":
            raise bad(name, f"has type {a.dtype}, expected numbers")
    for name, tail in _FIXED.items():
        if name in rec and rec[name].shape != tail:
            raise bad(name, f"has shape {rec[name].shape}, expected {tail}")
    for name in (*BODY_STATE, *PARTICLE_STATE, *JOINT_STATE, "gravity", "camera_position", "camera_target"):
        # the state a run left (`World.check_finite`): NaN marks the rows of removed bodies, an infinity
        # is never written (a plane's bound radius is infinite, and is not state)
        state = rec.get(name)
        if state is not None and state.dtype.kind == "f" and np.isinf(state).any():
            raise bad(name, "holds an infinity")
    for name in ("dt", "fps"):  # readers divide by them
        if name in rec and not float(rec[name]) > 0.0:
            raise bad(name, f"holds {float(rec[name]):g}, not a positive number")
    if "shape" in rec and "shape_names" in rec and rec["shape"].size:
        if rec["shape"].max() >= len(rec["shape_names"]):
            raise bad("shape", f"holds {int(rec['shape'].max())}, past the {len(rec['shape_names'])} shape names")
    tables = {}
    for kind in ("hull", "mesh"):
        if f"{kind}_points" in rec:
            tables[kind] = _check_table(rec, kind, bad)
    bodies = len(rec["shape"]) if "shape" in rec else None
    if "geometry" in rec and "shape" in rec:
        for kind, rows in tables.items():
            row = rec["geometry"][rec["shape"] == SHAPE_NAMES.index("convex" if kind == "hull" else "mesh")]
            if row.size and (row.min() < 0 or row.max() >= rows):
                raise bad("geometry", f"names {kind} row {int(row.min() if row.min() < 0 else row.max())} of {rows}")
    if "cloth_triangles" in rec:
        tri = rec["cloth_triangles"]
        particles = rec["cloth_position"].shape[1] if "cloth_position" in rec else 0
        if tri.ndim != 2 or tri.shape[1] != 3 or (particles and not len(tri)):
            raise bad("cloth_triangles", f"has shape {tri.shape}, expected (T, 3) with T > 0")
        if tri.size and (tri.min() < 0 or tri.max() >= particles):
            raise bad("cloth_triangles", f"names particles outside the {particles} recorded")
    if "joint_bodies" in rec and bodies is not None:
        ends = rec["joint_bodies"]
        if ends.size and (ends.min() < -1 or ends.max() >= bodies):
            raise bad("joint_bodies", f"names bodies outside the {bodies} recorded (-1 is the world)")
    if "joint_kind" in rec:
        from ..solver.joints import JointKind

        kinds = rec["joint_kind"]
        if kinds.size and (kinds.min() < 0 or kinds.max() > max(JointKind)):
            raise bad(
                "joint_kind", f"holds {int(kinds.min() if kinds.min() < 0 else kinds.max())}, which names no joint"
            )


def _check_table(rec: dict[str, np.ndarray], kind: str, bad) -> int:
    """Check the flat hull or mesh table `kind` (points, triangles and their row starts); return its rows."""
    points, triangles = rec[f"{kind}_points"], rec[f"{kind}_triangles"]
    ps, ts = rec[f"{kind}_point_start"], rec[f"{kind}_triangle_start"]
    if points.ndim != 2 or points.shape[1] != 3:
        raise bad(f"{kind}_points", f"has shape {points.shape}, expected (V, 3)")
    if triangles.ndim != 2 or triangles.shape[1] != 3:
        raise bad(f"{kind}_triangles", f"has shape {triangles.shape}, expected (T, 3)")
    if ps.ndim != 1:
        raise bad(f"{kind}_point_start", f"has shape {ps.shape}, expected (rows + 1,)")
    for name, start, total in (
        (f"{kind}_point_start", ps, len(points)),
        (f"{kind}_triangle_start", ts, len(triangles)),
    ):
        if start.ndim != 1 or len(start) != len(ps) or len(start) < 1:
            raise bad(name, f"has shape {start.shape}, expected ({len(ps)},) like {kind}_point_start")
        if start[0] != 0 or start[-1] != total or np.any(np.diff(start) < 0):
            raise bad(name, f"does not run from 0 up to {total}")
    for row in range(len(ps) - 1):
        corners = triangles[ts[row] : ts[row + 1]]
        if corners.size and (corners.min() < 0 or corners.max() >= ps[row + 1] - ps[row]):
            raise bad(f"{kind}_triangles", f"names points outside {kind} row {row}'s {ps[row + 1] - ps[row]}")
    return len(ps) - 1


def file_kind(path: Path, head: bytes) -> str:
    """What a file seems to be from its first bytes `head`: "zip" (an .npz archive, as recordings and
    snapshots are), "empty", "npy" (a single NumPy array), "binary", "scene" (a text whose suffix or
    first character says TOML) or "text"; for the messages of readers refusing it."""
    if head.startswith(_ZIP_MAGIC):
        return "zip"
    if not head:
        return "empty"
    if head.startswith(_NPY_MAGIC):
        return "npy"
    try:
        head.decode("utf-8")
    except UnicodeDecodeError:
        return "binary"
    if b"\x00" in head:  # valid UTF-8, but no text holds NUL (a file of zeros, /dev/zero)
        return "binary"
    if path.suffix.lower() == ".toml" or head.lstrip().startswith((b"[", b"#")):
        return "scene"
    return "text"


#: what `load_recording` says of a file that is not a zip archive, by `file_kind`
_NOT_A_RECORDING = {
    "empty": "the file is empty",
    "npy": "it is a single NumPy array (.npy), not a recording",
    "binary": "unknown binary content (a recording is a zip archive of arrays)",
    "scene": "it is a text file (a scene?); record a scene with `tumble run {path} --record FILE.npz`",
    "text": "it is a text file; a recording is written by `tumble run SCENE --record FILE.npz`",
}
