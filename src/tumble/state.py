"""Struct-of-arrays storage: one float type a set, entity-first names, growable capacity.

All engine state lives in Warp arrays with the entity index on the first axis
(`body_position (n, 3)`, `contact_normal (k, 3)`, ...). An `ArraySet` owns a group of such
arrays that share one row count and one capacity; it grows them by doubling outside any
kernel, so kernels never allocate.
"""

from __future__ import annotations

import enum
import itertools
import operator
import weakref

import numpy as np
import warp as wp

from .precision import FLOAT, MAT33, QUAT, TYPES, VEC3, precision_of_dtype, specialize

# the declared float types (float64): tables outside the kernel modules name these, and an
# `ArraySet` allocates them in its precision. Kernel modules take theirs from `tumble.real`, of
# which each precision's copy of them has its own.
float_t, vec3, quat, mat33 = FLOAT, VEC3, QUAT, MAT33

_NUMPY_DTYPE: dict[type, type] = {wp.int32: np.int32, wp.uint32: np.uint32, wp.int64: np.int64}


def host_view(arr: wp.array) -> np.ndarray:
    """NumPy view of a Warp array: on the CPU the array's own memory, made once per array (a
    `wp.array.numpy()` costs ~5 us, much of a small world's step); on other devices a copy."""
    view = arr.__dict__.get("_tumble_host_view")  # (only a CPU array has one: looked up first, it is cheaper)
    if view is None:
        assert arr.device is not None  # Warp's stubs allow None; an allocated array always has a device
        if not arr.device.is_cpu:
            return arr.numpy()
        view = arr._tumble_host_view = arr.numpy()  # type: ignore[attr-defined]  # cached on the array itself
    return view


def host_values(arr: wp.array) -> memoryview:
    """The values of a Warp array as one flat memoryview: on the CPU of the array's own memory (made
    once per array), elsewhere of a copy. Python's `sum` over a few dozen of them takes well under a
    microsecond, where a NumPy reduction costs ~2.5 us whatever its size, and an element read is a
    Python number at once (`int(host_view(a)[0])` costs ~0.4 us more)."""
    values = arr.__dict__.get("_tumble_host_values")  # (as in host_view, only a CPU array has one)
    if values is None:
        assert arr.device is not None
        if not arr.device.is_cpu:
            return memoryview(arr.numpy().reshape(-1))
        values = arr._tumble_host_values = memoryview(host_view(arr).reshape(-1))  # type: ignore[attr-defined,arg-type]
    return values


def numpy_dtype(dtype: type) -> tuple[type, tuple[int, ...]]:
    """NumPy scalar type and trailing shape of one element of a Warp `dtype` (either precision)."""
    precision = precision_of_dtype(dtype)
    if precision is None:
        return _NUMPY_DTYPE[dtype], ()
    t = TYPES[precision]
    shape: tuple[int, ...] = {t.float_t: (), t.vec3: (3,), t.quat: (4,), t.mat33: (3, 3)}[dtype]
    return t.numpy, shape


def cast(values, np_type: type, name: str) -> np.ndarray:
    """`values` as an array of `np_type`; ValueError naming `name` for a finite value the type cannot
    hold (beyond float32's 3.4e38, or a nonzero one below its 1.2e-38, which would become 0 or inf)."""
    if np_type is np.float64:  # nothing to lose, nothing to warn of (and no errstate, ~3 us a call)
        return np.asarray(values, dtype=np.float64)
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        out: np.ndarray = np.asarray(values, dtype=np_type)
    if np_type is np.float32:
        given = np.asarray(values, dtype=np.float64)
        lost = (np.isfinite(given) & ~np.isfinite(out)) | ((given != 0) & (np.abs(out) < np.finfo(np.float32).tiny))
        if lost.any():
            bad = float(given[lost].flat[0])
            raise ValueError(
                f"{name}: {bad:g} does not fit a float32 world (its floats hold magnitudes from 1.2e-38 to "
                "3.4e38); use World(precision='float64') or [world] precision = \"float64\""
            )
    return out


class ArraySet:
    """Named Warp arrays sharing a row count, grown by doubling.

    Args:
        fields: name -> Warp dtype of one row.
        device: Warp device the arrays live on.
        capacity: initial number of rows allocated.
        arrays: a dict to keep the arrays in, shared with the other sets of a `RowGroup` (default: its own).
        precision: "float32" or "float64": the declared (float64) float types of `fields` are
            allocated in it (`tumble.precision.specialize`); None: the types as given.

    Attributes:
        precision: the precision of its float arrays ("float64" for a set without any).
    """

    def __init__(
        self,
        fields: dict[str, type],
        *,
        device: str,
        capacity: int = 16,
        arrays: dict[str, wp.array] | None = None,
        precision: str | None = None,
    ):
        self.fields = {
            name: dtype if precision is None else specialize(dtype, precision) for name, dtype in fields.items()
        }
        found = sorted({p for p in map(precision_of_dtype, self.fields.values()) if p is not None})
        if len(found) > 1:
            raise ValueError(f"an ArraySet holds one precision, got {found}")
        self.precision: str = found[0] if found else (precision or "float64")
        #: NumPy scalar type and trailing shape of each field's rows (`numpy_dtype`)
        self.numpy_types = {name: numpy_dtype(dtype) for name, dtype in self.fields.items()}
        self.device = device
        self.count = 0
        self.capacity = 0
        self.arrays: dict[str, wp.array] = {} if arrays is None else arrays
        self.reserve(max(1, capacity))

    def __getattr__(self, name: str) -> wp.array:
        fields = self.__dict__.get("fields")
        if fields is not None and name in fields:
            return self.__dict__["arrays"][name]
        raise AttributeError(name)

    def reserve(self, capacity: int) -> bool:
        """Make room for `capacity` rows, keeping the first `count`. Returns True if reallocated."""
        if capacity <= self.capacity:
            return False
        new_capacity = max(capacity, 2 * self.capacity)
        for name, dtype in self.fields.items():
            new = wp.zeros(new_capacity, dtype=dtype, device=self.device)
            old = self.arrays.get(name)
            if old is not None and self.count:
                wp.copy(new, old, count=self.count)
            self.arrays[name] = new
        self.capacity = new_capacity
        return True

    def append(self, rows: dict[str, np.ndarray], *, count: int | None = None) -> range:
        """Append rows given as NumPy arrays (first axis = rows). Returns the new row range.

        Fields missing from `rows` are zero; `count` gives the number of rows when `rows` has none
        of this set's fields.
        """
        k = len(next(iter(rows.values()))) if count is None else count
        start = self.count
        self.reserve(start + k)
        # rows that `take` dropped may hold old values: zero the fields not given
        types = self.numpy_types
        zeros: dict[str, np.ndarray] = {
            name: np.zeros((k,) + tail, np_type) for name, (np_type, tail) in types.items() if name not in rows
        }
        converted = {}  # every field first, so that a value the precision cannot hold changes nothing
        for name, values in {**rows, **zeros}.items():
            np_type, tail = types[name]
            converted[name] = cast(values, np_type, name).reshape((k,) + tail)
        for name, src in converted.items():
            dtype = self.fields[name]
            if self.device == "cpu":
                host_view(self.arrays[name])[start : start + k] = src  # the host view is the array
            else:
                staged: wp.array = wp.array(np.ascontiguousarray(src), dtype=dtype, device=self.device)
                wp.copy(self.arrays[name], staged, dest_offset=start, count=k)
        self.count = start + k
        return range(start, start + k)

    def numpy(self, name: str, *, count: int | None = None) -> np.ndarray:
        """Host view of the first `count` rows of one array (zero-copy on the CPU)."""
        n = self.count if count is None else count
        arr = self.arrays[name]
        host = host_view(arr) if n else np.zeros((0,) + self.numpy_types[name][1], self.numpy_types[name][0])
        return host[:n]

    def permute(self, order: np.ndarray) -> None:
        """Reorder the first `count` rows of every array: new row k is old row `order[k]`."""
        self.take(order)

    def take(self, rows: np.ndarray) -> None:
        """Keep only the rows `rows` of the first `count`, in that order: new row k is old row `rows[k]`.

        A permutation of all rows reorders them; a shorter list also drops the rows it leaves out.
        """
        k = len(rows)
        for name in self.fields:
            arr = self.arrays[name]
            host = host_view(arr)
            host[:k] = host[rows]
            if self.device != "cpu":
                arr.assign(host)
        self.count = k

    def write(self, name: str, rows, values) -> None:
        """Overwrite the rows `rows` (an index array or slice) of one array from host values."""
        host = host_view(self.arrays[name])
        host[rows] = cast(values, host.dtype.type, name)
        if self.device != "cpu":
            self.arrays[name].assign(host)

    def load(self, arrays: dict[str, np.ndarray], *, count: int, capacity: int) -> None:
        """Replace every row, capacity included, with whole arrays saved earlier (snapshots).

        Arrays keep their identity when the capacity is unchanged (so recorded launches stay
        valid); otherwise they are reallocated at exactly `capacity`, as after a `reserve`.
        """
        if capacity != self.capacity:
            for name, dtype in self.fields.items():  # in place: a RowGroup's sets share one dict
                self.arrays[name] = wp.zeros(capacity, dtype=dtype, device=self.device)
            self.capacity = capacity
        for name in self.fields:
            self.arrays[name].assign(arrays[name])
        self.count = count


class RowGroup:
    """Several `ArraySet`s over one row space, used as one: rows are added, reordered, dropped and
    grown in all of them together, and `arrays` holds every set's arrays by name.

    The world's body rows are one: the model's, the state's, the control's and the solver's
    scratch sets (`tumble.model`), which kernels see as one table.

    Args:
        parts: the sets, made with one shared `arrays` dict, each with its own fields.
    """

    def __init__(self, *parts: ArraySet):
        self.parts = parts
        self.arrays = parts[0].arrays
        if any(p.arrays is not self.arrays for p in parts):
            raise ValueError("the sets of a RowGroup must share one arrays dict")
        self.fields = {name: dtype for p in parts for name, dtype in p.fields.items()}
        self._part = {name: p for p in parts for name in p.fields}
        self.device = parts[0].device
        self.precision = parts[0].precision
        if any(p.precision != self.precision for p in parts):
            raise ValueError("the sets of a RowGroup must share one precision")
        self.sync()

    def __getattr__(self, name: str) -> wp.array:
        fields = self.__dict__.get("fields")
        if fields is not None and name in fields:
            return self.__dict__["arrays"][name]
        raise AttributeError(name)

    @property
    def count(self) -> int:
        """Rows in use."""
        return self.parts[0].count

    @property
    def capacity(self) -> int:
        """Rows allocated (in every part at least this many)."""
        return self.parts[0].capacity

    def sync(self) -> None:
        """Give every part the first part's row count, and a capacity at least the first part's
        (after a part was loaded alone, as a snapshot restore does)."""
        first = self.parts[0]
        for p in self.parts[1:]:
            p.reserve(first.capacity)
            p.count = first.count

    def reserve(self, capacity: int) -> bool:
        """Make room for `capacity` rows in every part. Returns True if any was reallocated."""
        grown = [p.reserve(capacity) for p in self.parts]
        return any(grown)

    def append(self, rows: dict[str, np.ndarray]) -> range:
        """Append rows given as NumPy arrays (first axis = rows) to every part; missing fields are zero."""
        k = len(next(iter(rows.values())))
        # cast before any part changes (a value its precision cannot hold changes nothing); the parts
        # then take the cast arrays as they are
        rows = {name: cast(values, self._part[name].numpy_types[name][0], name) for name, values in rows.items()}
        self.reserve(self.count + k)
        added = [p.append({name: v for name, v in rows.items() if name in p.fields}, count=k) for p in self.parts]
        return added[0]

    def numpy(self, name: str, *, count: int | None = None) -> np.ndarray:
        """Host view of the first `count` rows of one array (zero-copy on the CPU)."""
        return self._part[name].numpy(name, count=count)

    def write(self, name: str, rows, values) -> None:
        """Overwrite the rows `rows` of one array from host values."""
        self._part[name].write(name, rows, values)

    def permute(self, order: np.ndarray) -> None:
        """Reorder the rows of every part: new row k is old row `order[k]`."""
        self.take(order)

    def take(self, rows: np.ndarray) -> None:
        """Keep only the rows `rows`, in that order, in every part."""
        for p in self.parts:
            p.take(rows)


def readonly(a: np.ndarray) -> np.ndarray:
    """A read-only view of `a`, so users cannot write engine state behind its back."""
    v = a.view()
    v.flags.writeable = False
    return v


class BodyKind(enum.IntEnum):
    """How a body moves. Static and kinematic bodies both have inverse mass 0 (infinite mass to contacts)."""

    DYNAMIC = 0  # moved by gravity, forces and contacts
    STATIC = 1  # never moves (planes; static=True)
    KINEMATIC = 2  # moved only by its velocity, which the user's script sets (kinematic=True)


# ---------------------------------------------------------------------------- handles

#: every live World by its key, so that a handle can find its world without keeping it alive
_worlds: weakref.WeakValueDictionary = weakref.WeakValueDictionary()
_world_keys = itertools.count(1)


def register_world(world) -> int:
    """A new key for `world`, carried by every handle it gives out."""
    key = next(_world_keys)
    _worlds[key] = world
    return key


class Handle(int):
    """Public handle: an int (the entity's index, so it indexes the views) carrying a generation and its world.

    Two handles are equal when index, generation and world all match; a handle equals a plain
    int with its index. Handles are immutable and picklable; the world checks each one it is
    given and raises `tumble.HandleError` for one from another world or of a removed entity.

    Args:
        index: the entity's index (body id, cloth index).
        generation: how many handles its world made at this index before (a restore never lowers it).
        world_key: key of the world that made the handle; None: any world (a bare id).
    """

    _noun = "entity"
    generation: int
    world_key: int | None

    def __new__(cls, index, generation: int = 0, world_key: int | None = None):
        self = super().__new__(cls, operator.index(index))
        object.__setattr__(self, "generation", int(generation))
        object.__setattr__(self, "world_key", None if world_key is None else int(world_key))
        return self

    @property
    def index(self) -> int:
        """The index as a plain int (rows of the views are in index order)."""
        return int(self)

    @property
    def world(self):
        """The `World` this handle belongs to."""
        from .errors import HandleError

        world = None if self.world_key is None else _worlds.get(self.world_key)
        if world is None:
            raise HandleError(f"{self._noun} {int(self)}: its World no longer exists (or it is a bare id)")
        return world

    @classmethod
    def checked_index(cls, handle, count: int, world_key: int | None) -> int:
        """The index that `handle`, one of this class or a plain int index, names among the `count` a
        world with key `world_key` has: TypeError for anything else, `HandleError` for another world's
        handle, `NoSuchIdError` for an index out of range (for kinds whose indices are never reused)."""
        from . import validate
        from .errors import HandleError, NoSuchIdError

        noun, kind = cls._noun, cls.__name__
        if isinstance(handle, (bool, np.bool_)) or not isinstance(handle, (int, np.integer)):
            raise TypeError(f"{noun} must be a {kind} (or an int index), got {validate.show(handle)}")
        if isinstance(handle, Handle):
            if not isinstance(handle, cls):
                raise TypeError(f"{noun} must be a {kind}, got the {type(handle).__name__} {handle!r}")
            if handle.world_key is not None and world_key is not None and handle.world_key != world_key:
                raise HandleError(f"{noun} {int(handle)} belongs to another World")
        index = int(handle)
        if not 0 <= index < count:
            raise NoSuchIdError(f"{noun} {index} does not exist (the world has {count} {noun}s)")
        return index

    def __setattr__(self, name, value):
        attr = getattr(type(self), name, None)
        if isinstance(attr, property) and attr.fset is not None:
            attr.fset(self, value)
            return
        raise AttributeError(f"{type(self).__name__} is immutable: {name!r} cannot be set")

    def __delattr__(self, name):
        raise AttributeError(f"{type(self).__name__} is immutable: {name!r} cannot be deleted")

    def __eq__(self, other):
        if isinstance(other, Handle):
            return (
                type(self) is type(other)
                and int(self) == int(other)
                and self.generation == other.generation
                and self.world_key == other.world_key
            )
        return int.__eq__(self, other)

    def __ne__(self, other):
        equal = self.__eq__(other)
        return equal if equal is NotImplemented else not equal

    __hash__ = int.__hash__

    def __repr__(self) -> str:
        return f"{type(self).__name__}({int(self)}, generation={self.generation})"

    def __str__(self) -> str:
        return str(int(self))


def _body_state(field: str, doc: str) -> property:
    """A `BodyId` property: reads `world.body_state(body).<field>`, sets by `world.set_body_state(body, <field>=...)`."""
    return property(
        lambda self: self._get(field), lambda self, v: self.world.set_body_state(self, **{field: v}), doc=doc
    )


class BodyId(Handle):
    """Handle to one body (planes, spheres and boxes share the index space).

    Read and set the body's state through it, as in Pymunk and Rapier::

        ball.position = (0, 0, 2)      # same as world.set_body_state(ball, position=(0, 0, 2))
        print(ball.velocity)           # same as world.body_state(ball).velocity

    Each read is a copy of that moment's value.
    """

    _noun = "body"

    def _get(self, field: str) -> np.ndarray:
        return getattr(self.world.body_state(self), field)

    position = _body_state("position", "Centre of mass [m], shape (3,).")
    orientation = _body_state("orientation", "Body-to-world rotation, unit quaternion (x, y, z, w), shape (4,).")
    velocity = _body_state("velocity", "Linear velocity [m/s], shape (3,).")
    angular_velocity = _body_state("angular_velocity", "Angular velocity, world frame [rad/s], shape (3,).")

    @property
    def kind(self) -> BodyKind:
        """DYNAMIC, STATIC or KINEMATIC."""
        return self.world.body_state(self).kind


class JointId(Handle):
    """Handle to one joint: its index in creation order (`world.joint_force[joint.index]` is its force).

    A joint keeps its index for good: a broken one, and one `World.remove_joint` removed, stay as
    broken rows (`joint_broken`), so the generation stays 0.
    """

    _noun = "joint"


class ClothId(Handle):
    """Handle to one cloth: its index (creation order) and where its particles are.

    `world.cloth` holds every cloth's particles in one set of arrays; a cloth's particles are
    rows `particle_start` to `particle_start + particle_count` of them, grid point (i, j) at
    `particle(i, j)`.
    """

    _noun = "cloth"

    def _record(self):
        return self.world.cloth.cloth(self)

    @property
    def particle_start(self) -> int:
        """First particle of this cloth in `world.cloth`'s arrays."""
        return self._record().particle_start

    @property
    def particle_count(self) -> int:
        """nx * ny."""
        return self._record().particle_count

    @property
    def resolution(self) -> tuple[int, int]:
        """(nx, ny) particles."""
        record = self._record()
        return record.nx, record.ny

    def particle(self, i: int, j: int) -> int:
        """Index in `world.cloth`'s arrays of grid point (i, j) of this cloth (i along its width)."""
        record = self._record()
        from .validate import integer

        i, j = integer(i, "i", low=0), integer(j, "j", low=0)
        if i >= record.nx or j >= record.ny:
            raise IndexError(f"grid point ({i}, {j}) is outside cloth {int(self)} of {record.nx} x {record.ny}")
        return record.particle(i, j)

    @property
    def particle_position(self) -> np.ndarray:
        """Positions of this cloth's particles [m], shape (nx * ny, 3), a copy."""
        record = self._record()
        return self.world.cloth.particle_position[record.particle_start : record.particle_start + record.particle_count]

    @property
    def particle_velocity(self) -> np.ndarray:
        """Velocities of this cloth's particles [m/s], shape (nx * ny, 3), a copy."""
        record = self._record()
        return self.world.cloth.particle_velocity[record.particle_start : record.particle_start + record.particle_count]
