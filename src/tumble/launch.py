"""Recorded kernel launches: on the CPU a `wp.launch` costs ~20 us of Python, a replay ~4 us.

(Where a whole stage has no host decision between its launches, the world records it as a
graph instead, `wp.capture_begin`, replayed in C++ for well under a microsecond a launch: see
`World._solver_graph`. This cache serves the launches that run outside a graph.)

A world substep launches a handful of kernels (and a cloth substep about ten), so for small
scenes the launch overhead alone would cost more than the arithmetic. `LaunchCache` records
each launch once per set of arrays and dimension and replays it, updating only the scalar
arguments that changed. Callers launch over an array's capacity (which changes rarely) and
pass the live count as a scalar, so a changing count does not record a new launch.
"""

from __future__ import annotations

import operator
from collections.abc import Callable

import warp as wp


class LaunchCache:
    """Recorded launches keyed by kernel, dimension and the identity of the array arguments.

    Holds references to the arrays it recorded, so their ids cannot be reused while cached;
    call `clear` when the arrays are replaced (stale entries are only memory, never wrong).
    """

    def __init__(self):
        self._commands: dict = {}
        self._arrays_of: dict = {}  # kernel -> (getter of its array arguments, scalar positions)
        self._graphs: dict = {}  # (kind, *key) -> (graph, the arrays it launches with)
        self._graph_seen: dict = {}  # kind -> the key asked for last

    def clear(self) -> None:
        """Forget every recorded launch and graph."""
        self._commands.clear()
        self._graphs.clear()
        self._graph_seen.clear()

    def graph(self, kind: str, key: tuple, record, arrays, device):
        """The graph (`wp.capture_begin`) of the launches `record()` makes, recorded for `key`, or
        None: then the caller runs them directly.

        A graph is recorded the second call running that asks for the same `key` of a `kind` (a
        key that changes every call never pays for a recording) and kept for later calls with
        that key (the last eight graphs). `key` must name everything the launches bake in; the
        entry holds `arrays()` (every array they may use), so that array ids in keys stay theirs.
        """
        key = (kind, *key)
        entry = self._graphs.get(key)
        if entry is None:
            seen, self._graph_seen[kind] = self._graph_seen.get(kind), key
            if key != seen:
                return None
            wp.capture_begin(device=device)
            try:
                record()
            finally:
                graph = wp.capture_end(device=device)
            if len(self._graphs) >= 8:
                self._graphs.pop(next(iter(self._graphs)))
            entry = self._graphs[key] = (graph, list(arrays()))
        return entry[0]

    def launch(self, kernel, dim: int, inputs: list, device) -> None:
        """Launch `kernel` over `dim` threads with `inputs`, replaying a recorded launch when possible."""
        layout = self._arrays_of.get(kernel)
        if layout is None:
            arrays = [i for i, a in enumerate(inputs) if isinstance(a, wp.array)]
            scalars = tuple(i for i, a in enumerate(inputs) if not isinstance(a, wp.array))
            getter: Callable[[list], tuple]
            if len(arrays) > 1:
                getter = operator.itemgetter(*arrays)
            else:  # one array, or none (arrays in structs: a new struct is a changed scalar)

                def getter(xs, i=tuple(arrays)):
                    return tuple(xs[k] for k in i)

            layout = self._arrays_of[kernel] = (getter, scalars)
        getter, scalars = layout
        key = (kernel, dim, *map(id, getter(inputs)))
        entry = self._commands.get(key)
        if entry is None:
            command = wp.launch(kernel, dim=dim, inputs=inputs, device=device, record_cmd=True)
            entry = (command, [inputs[i] for i in scalars], list(inputs))
            self._commands[key] = entry
        else:
            command, last, _ = entry
            # re-pack only the scalars that changed (packing costs a few microseconds each)
            for k, i in enumerate(scalars):
                value = inputs[i]
                if value != last[k]:
                    command.set_param_at_index(i, value)
                    last[k] = value
        entry[0].launch()


def vector(values) -> tuple[float, ...]:
    """A vector argument of a launch (gravity, a wind velocity) as a tuple of floats, which Warp packs as
    the kernel's vector type: `LaunchCache` compares a tuple with the last one in well under a
    microsecond, where comparing two Warp vec3 takes ~12 us (and making one ~5 us) at every launch."""
    return tuple(map(float, values))


def launch(kernel, dim: int, inputs: list, device, cache: LaunchCache | None = None) -> None:
    """`wp.launch`, or a replay through `cache` when one is given."""
    if cache is None:
        wp.launch(kernel, dim=dim, inputs=inputs, device=device)
    else:
        cache.launch(kernel, dim, inputs, device)


@wp.func
def each_end(thread: int, serial: int, count: int):
    """Where the elements of thread `thread` of a `launch_each` kernel end: its loop is
    `for k in range(wp.tid(), each_end(wp.tid(), serial, count))`, over all `count` for the one
    thread of a serial launch, else over the thread's own element if it is one of the `count`
    (a launch over a buffer's capacity whose kernel reads the count in use on the device)."""
    if serial != 0:
        return count
    return wp.min(thread + 1, count)


@wp.func
def each_in_use(thread: int, serial: int, count: int, capacity: int):
    """`each_end` for a kernel launched over a buffer's `capacity` of which the first `count` (read
    on the device) are in use: a count beyond the capacity (the buffer overflowed; it is grown and
    filled again before it is read) stops at the capacity."""
    return each_end(thread, serial, wp.min(count, capacity))


def launch_each(kernel, count: int, inputs: list, device, cache: LaunchCache | None = None) -> None:
    """`kernel` over `count` elements, whose last argument is `serial` (see `each_end`).

    On the CPU, where Warp runs the threads of a launch one after another in index order, one
    thread loops over the elements in that order (`serial` 1): the same arithmetic in the same
    order, without each element's thread start-up. Elsewhere one thread per element (`serial` 0).
    A kernel that reads its count on the device is launched with `count` its buffer's capacity:
    on the CPU its one thread then loops over the elements in use only (a thread's start-up in a
    large kernel, the narrow phase's, costs ~0.13 us even when it returns at once).
    """
    serial = 1 if (device == "cpu" if isinstance(device, str) else device.is_cpu) else 0
    launch(kernel, 1 if serial else count, [*inputs, serial], device, cache)
