"""Struct-of-arrays storage: one float type, entity-first names, growable capacity.

All engine state lives in Warp arrays with the entity index on the first axis
(`body_position (n, 3)`, `contact_normal (k, 3)`, ...). An `ArraySet` owns a group of such
arrays that share one row count and one capacity; it grows them by doubling outside any
kernel, so kernels never allocate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

# the one float type of the engine: float64, so that momentum and energy bookkeeping is exact
# to ~1e-15 rather than ~1e-7
float_t = wp.float64
vec3 = wp.vec3d
quat = wp.quatd
mat33 = wp.mat33d
np_float = np.float64

_NUMPY_DTYPE = {float_t: np.float64, wp.int32: np.int32, wp.uint32: np.uint32, wp.int64: np.int64}
_WIDTH = {vec3: 3, quat: 4, mat33: 9}


def numpy_dtype(dtype) -> tuple[type, tuple[int, ...]]:
    """NumPy scalar type and trailing shape of one element of a Warp `dtype`."""
    if dtype in _WIDTH:
        return np.float64, ((3, 3) if dtype is mat33 else (_WIDTH[dtype],))
    return _NUMPY_DTYPE[dtype], ()


class ArraySet:
    """Named Warp arrays sharing a row count, grown by doubling.

    Args:
        fields: name -> Warp dtype of one row.
        device: Warp device the arrays live on.
        capacity: initial number of rows allocated.
    """

    def __init__(self, fields: dict[str, object], *, device: str, capacity: int = 16):
        self.fields = dict(fields)
        self.device = device
        self.count = 0
        self.capacity = 0
        self.arrays: dict[str, wp.array] = {}
        self.reserve(max(1, capacity))

    def __getattr__(self, name: str) -> wp.array:
        arrays = self.__dict__.get("arrays")
        if arrays is not None and name in arrays:
            return arrays[name]
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

    def append(self, rows: dict[str, np.ndarray]) -> range:
        """Append rows given as NumPy arrays (first axis = rows). Returns the new row range.

        Fields missing from `rows` are zero.
        """
        k = len(next(iter(rows.values())))
        start = self.count
        self.reserve(start + k)
        for name, values in rows.items():
            dtype = self.fields[name]
            np_type, tail = numpy_dtype(dtype)
            src = np.asarray(values, dtype=np_type).reshape((k,) + tail)
            if self.device == "cpu":
                self.arrays[name].numpy()[start:start + k] = src  # the host view is the array
            else:
                src = wp.array(np.ascontiguousarray(src), dtype=dtype, device=self.device)
                wp.copy(self.arrays[name], src, dest_offset=start, count=k)
        self.count = start + k
        return range(start, start + k)

    def numpy(self, name: str, *, count: int | None = None) -> np.ndarray:
        """Host view of the first `count` rows of one array (zero-copy on the CPU)."""
        n = self.count if count is None else count
        arr = self.arrays[name]
        host = arr.numpy() if n else np.zeros((0,) + numpy_dtype(self.fields[name])[1], numpy_dtype(self.fields[name])[0])
        return host[:n]

    def permute(self, order: np.ndarray) -> None:
        """Reorder the first `count` rows of every array: new row k is old row `order[k]`."""
        for name, arr in self.arrays.items():
            host = arr.numpy()
            host[: self.count] = host[order]
            if self.device != "cpu":
                arr.assign(host)

    def write(self, name: str, rows, values) -> None:
        """Overwrite the rows `rows` (an index array or slice) of one array from host values."""
        host = self.arrays[name].numpy()
        host[rows] = values
        if self.device != "cpu":
            self.arrays[name].assign(host)


def readonly(a: np.ndarray) -> np.ndarray:
    """A read-only view of `a`, so users cannot write engine state behind its back."""
    v = a.view()
    v.flags.writeable = False
    return v


@dataclass(frozen=True)
class BodyId:
    """Public handle to one body: its creation index. Planes, spheres and boxes share the index space."""

    index: int

    def __index__(self) -> int:
        return self.index

    def __int__(self) -> int:
        return self.index
