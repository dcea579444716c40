"""launch.py: a recorded launch replays with new scalars and new arrays; a recorded graph repeats the launches exactly."""

from __future__ import annotations

import numpy as np
import warp as wp

from tumble.launch import LaunchCache, each_end, launch, launch_each
from tumble.state import float_t

DEVICE = "cpu"


@wp.kernel
def _axpb(x: wp.array(dtype=float_t), a: float_t, b: float_t, y: wp.array(dtype=float_t), count: int):
    """y = a x + b for the first `count` rows (launched over the capacity)."""
    i = wp.tid()
    if i >= count:
        return
    y[i] = a * x[i] + b


@wp.kernel
def _accumulate(x: wp.array(dtype=float_t), y: wp.array(dtype=float_t)):
    """y += x (so that a repeated graph shows every replay)."""
    i = wp.tid()
    y[i] = y[i] + x[i]


def arrays(n: int = 8):
    x = wp.array(np.arange(n, dtype=np.float64), dtype=float_t, device=DEVICE)
    return x, wp.zeros(n, dtype=float_t, device=DEVICE)


def test_without_a_cache_it_is_a_plain_launch():
    """launch(..., cache=None) runs the kernel once with the given inputs."""
    x, y = arrays()
    launch(_axpb, 8, [x, 2.0, 1.0, y, 8], DEVICE)
    np.testing.assert_array_equal(y.numpy(), 2.0 * np.arange(8) + 1.0)


def test_a_replay_uses_the_new_scalar_values():
    """The second launch with the same arrays replays the recording with the scalars changed."""
    cache = LaunchCache()
    x, y = arrays()
    expected = np.zeros(8)
    for a, b, count in ((2.0, 1.0, 8), (2.0, 1.0, 8), (-3.0, 0.5, 8), (-3.0, 4.0, 5), (7.0, 4.0, 3)):
        cache.launch(_axpb, 8, [x, a, b, y, count], DEVICE)
        expected[:count] = a * np.arange(count) + b
        np.testing.assert_array_equal(y.numpy(), expected)


def test_new_arrays_are_launched_with_those_arrays():
    """Other arrays (a new set of ids) give a new recording: the old arrays are left alone."""
    cache = LaunchCache()
    x, y = arrays()
    cache.launch(_axpb, 8, [x, 1.0, 0.0, y, 8], DEVICE)
    x2, y2 = arrays()
    x2.assign(np.full(8, 10.0))
    cache.launch(_axpb, 8, [x2, 1.0, 0.0, y2, 8], DEVICE)
    np.testing.assert_array_equal(y.numpy(), np.arange(8.0))
    np.testing.assert_array_equal(y2.numpy(), np.full(8, 10.0))
    # and after clear, the same arrays are recorded again, with the scalars of this call
    cache.clear()
    cache.launch(_axpb, 8, [x, 0.0, 5.0, y, 8], DEVICE)
    np.testing.assert_array_equal(y.numpy(), np.full(8, 5.0))


def test_a_graph_is_recorded_on_the_second_ask_and_replays_the_launches():
    """graph(kind, key) is None the first time, a graph the second; each replay adds x once more."""
    cache = LaunchCache()
    x, y = arrays()

    def record():
        wp.launch(_accumulate, dim=8, inputs=[x, y], device=DEVICE)

    direct = np.zeros(8)
    for call in range(4):
        graph = cache.graph("sum", (8,), record, lambda: [x, y], DEVICE)
        if call == 0:
            assert graph is None  # first ask of this key: the caller runs the launches directly
            record()
        else:
            assert graph is not None
            if call == 1:
                record()  # recording did not run the launches: the caller replays once
            wp.capture_launch(graph)
        direct += np.arange(8.0)
        if call == 1:
            direct += np.arange(8.0)
        np.testing.assert_array_equal(y.numpy(), direct)
    # the same key asks again: the same graph, kept
    assert cache.graph("sum", (8,), record, lambda: [x, y], DEVICE) is graph


def test_a_key_that_changes_every_call_never_records():
    """Alternating keys are never seen twice running, so no graph is recorded for them."""
    cache = LaunchCache()
    x, y = arrays()
    recorded = []
    for call in range(6):
        assert cache.graph("sum", (call % 2,), lambda: recorded.append(1), lambda: [x, y], DEVICE) is None
    assert not recorded


def test_graph_replay_gives_the_results_of_direct_launches():
    """The same three launches, replayed from a graph and run directly, give identical arrays."""
    x, y = arrays(16)
    x.assign(np.linspace(-1.0, 1.0, 16) ** 3)
    ref_x, ref_y = arrays(16)
    ref_x.assign(x.numpy())

    def stages(xs, ys, cache=None):
        launch(_axpb, 16, [xs, 1.5, -0.25, ys, 16], DEVICE, cache)
        launch(_accumulate, 16, [xs, ys], DEVICE, cache)
        launch(_axpb, 16, [ys, 0.5, 0.125, xs, 16], DEVICE, cache)

    cache = LaunchCache()
    for _ in range(2):
        graph = cache.graph("stages", (16,), lambda: stages(x, y), lambda: [x, y], DEVICE)
    assert graph is not None
    for _ in range(5):
        wp.capture_launch(graph)
        stages(ref_x, ref_y)
    np.testing.assert_array_equal(x.numpy(), ref_x.numpy())
    np.testing.assert_array_equal(y.numpy(), ref_y.numpy())


@wp.kernel
def _running_sum(x: wp.array(dtype=float_t), y: wp.array(dtype=float_t), serial: int):
    """y[i] = x[i] + y[i - 1]: each element reads the one before it, so the order of the elements shows."""
    for i in range(wp.tid(), each_end(wp.tid(), serial, x.shape[0])):
        if i > 0:
            y[i] = x[i] + y[i - 1]
        else:
            y[i] = x[i]


def test_launch_each_loops_in_one_thread_on_the_cpu_in_index_order():
    """launch_each on the CPU is one thread over the elements in order (the running sum comes out whole),
    the same as one thread per element there, where Warp runs the threads in index order."""
    x, y = arrays()
    launch_each(_running_sum, 8, [x, y], DEVICE)
    np.testing.assert_array_equal(y.numpy(), np.cumsum(np.arange(8.0)))
    y_threads = wp.zeros(8, dtype=float_t, device=DEVICE)
    wp.launch(_running_sum, dim=8, inputs=[x, y_threads, 0], device=DEVICE)
    np.testing.assert_array_equal(y_threads.numpy(), y.numpy())
    cache = LaunchCache()
    for _ in range(2):  # recorded, then replayed
        y.zero_()
        launch_each(_running_sum, 8, [x, y], wp.get_device(DEVICE), cache)
        np.testing.assert_array_equal(y.numpy(), np.cumsum(np.arange(8.0)))
