"""The viewer's simulation clock, world snapshots and simulation thread (tumble.viewer.sim), without a window."""

import threading

import numpy as np
import pytest

import tumble
from tumble.viewer.sim import SimulationClock, SimulationThread, WorldSnapshot


class FakeWorld:
    """Just what the clock touches: dt, time, step_count and step()."""

    def __init__(self, dt=0.01):
        self.dt, self.time, self.step_count = dt, 0.0, 0

    def step(self):
        self.time += self.dt
        self.step_count += 1


class FakeClock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_clock_paces_steps_by_real_time_and_time_scale():
    """Elapsed real time x time scale becomes whole steps; the remainder carries over."""
    world, clock = FakeWorld(dt=0.01), FakeClock()
    sim = SimulationClock(world, clock=clock, playing=True)
    clock.now += 0.105
    assert sim.tick() == 10  # 0.105 s -> 10 steps, 0.005 s carried
    clock.now += 0.005
    assert sim.tick() == 1
    sim.time_scale = 0.5
    clock.now += 0.1
    assert sim.tick() == 5
    assert world.step_count == 16


def test_clock_caps_a_backlog_and_drops_it():
    """A long stall takes at most max_steps_per_tick steps, and the backlog is dropped."""
    world, clock = FakeWorld(dt=0.01), FakeClock()
    sim = SimulationClock(world, clock=clock, playing=True)
    sim.max_steps_per_tick = 8
    clock.now += 10.0
    assert sim.tick() == 8
    assert sim.dropped == pytest.approx(10.0 - 0.08)
    clock.now += 0.02
    assert sim.tick() == 2


def test_paused_clock_does_not_step_but_step_does():
    """tick() does nothing while paused; step() advances exactly one step and calls before_step."""
    world, clock = FakeWorld(), FakeClock()
    seen = []
    sim = SimulationClock(world, clock=clock, before_step=seen.append)
    clock.now += 1.0
    assert sim.tick() == 0
    sim.step()
    assert world.step_count == 1 and seen == [world]


def test_reset_uses_the_factory():
    """reset() replaces the world with a fresh one from the factory; without one it refuses."""
    sim = SimulationClock(FakeWorld(), factory=FakeWorld)
    sim.step()
    new = sim.reset()
    assert new is sim.world and new.step_count == 0
    with pytest.raises(RuntimeError, match="factory"):
        SimulationClock(FakeWorld()).reset()


def test_steps_due_carries_the_remainder_and_time_scale_slows_it():
    """steps_due(elapsed): whole steps of dt in elapsed x time_scale, the rest carried to the next call."""
    sim = SimulationClock(FakeWorld(dt=0.25), clock=FakeClock())
    assert [sim.steps_due(0.3) for _ in range(4)] == [1, 1, 1, 1]  # 0.3, 0.35, 0.4, 0.45 owed: one each
    assert sim.steps_due(0.3) == 2  # 0.2 carried + 0.3 = 0.5
    sim.time_scale = 0.5
    assert sim.steps_due(1.0) == 2  # 1 s of real time is 0.5 s simulated


def _ball_world():
    world = tumble.World(dt=1.0 / 120.0)
    world.add_plane()
    world.add_sphere(position=(0.0, 0.0, 1.0), radius=0.1, mass=1.0)
    return world


def test_a_snapshot_is_a_copy_taken_between_steps():
    """A WorldSnapshot keeps the positions, time and counts of when it was taken while the world steps on."""
    world = _ball_world()
    for _ in range(3):
        world.step()
    snap = WorldSnapshot(world)
    z, t = float(world.body_position[1, 2]), world.time
    for _ in range(10):
        world.step()
    assert world.body_position[1, 2] < z  # the world fell on
    assert snap.body_position[1, 2] == z and snap.time == t and snap.step_count == 3
    assert snap.body_count == 2 and snap.source is world
    np.testing.assert_array_equal(snap.body_shape, [tumble.ShapeType.PLANE, tumble.ShapeType.SPHERE])
    np.testing.assert_allclose(snap.gravity, world.gravity)
    assert not snap.has_cloth and snap.cloth is None
    assert snap.joint_lines.shape == (0, 4, 3)


def test_submit_runs_at_once_when_no_step_is_running_and_publishes():
    """With the clock idle, submit runs the change here and returns True; the new snapshot shows it."""
    world = _ball_world()
    thread = SimulationThread(SimulationClock(world))
    version = thread.version
    assert thread.submit(lambda: world.add_sphere(position=(1.0, 0.0, 1.0), radius=0.1)) is True
    assert world.body_count == 3
    assert thread.version == version + 1 and thread.snapshot.body_count == 3


def test_submit_during_a_step_is_run_by_the_worker_after_it():
    """While another thread holds the step lock, submit queues the change; the worker runs it afterwards."""
    world = _ball_world()
    clock = SimulationClock(world)
    thread = SimulationThread(clock, period=0.005)
    held, release = threading.Event(), threading.Event()

    def hold_the_lock():
        with clock.lock:
            held.set()
            release.wait(10.0)

    holder = threading.Thread(target=hold_the_lock)
    holder.start()
    held.wait(10.0)
    thread.start()
    try:
        assert thread.submit(lambda: world.add_sphere(position=(1.0, 0.0, 1.0), radius=0.1)) is False
        assert world.body_count == 2  # not run yet: a step (here, the holder) has the world
        release.set()
        holder.join(10.0)
        for _ in range(1000):
            if thread.snapshot.body_count == 3:
                break
            threading.Event().wait(0.01)
        assert world.body_count == 3 and thread.snapshot.body_count == 3
        assert thread.error is None
    finally:
        release.set()
        thread.stop()
    assert not thread.running


def _hold(lock):
    """Hold `lock` from another thread; returns (release, thread): call release.set() to let it go."""
    held, release = threading.Event(), threading.Event()

    def run():
        with lock:
            held.set()
            release.wait(10.0)

    holder = threading.Thread(target=run)
    holder.start()
    assert held.wait(10.0)
    return release, holder


def test_changes_apply_in_the_order_they_were_made():
    """A change queued during a step, then one run at once after it: the later change is the one that stays."""
    world = _ball_world()
    clock = SimulationClock(world)
    thread = SimulationThread(clock, period=0.005)
    release, holder = _hold(clock.lock)
    assert thread.submit(lambda: setattr(world, "gravity", (0.0, 0.0, -5.0))) is False  # queued: a step holds the world
    release.set()
    holder.join(10.0)
    assert thread.submit(lambda: setattr(world, "gravity", (0.0, 0.0, -7.0))) is True
    thread.start()  # the worker would run anything still queued
    thread.stop()
    np.testing.assert_allclose(world.gravity, [0.0, 0.0, -7.0])


class CountingLock:
    """A re-entrant lock that counts acquisitions by threads other than the one that made it."""

    def __init__(self):
        self._lock, self._owner, self.foreign = threading.RLock(), threading.get_ident(), 0

    def acquire(self, blocking=True, timeout=-1):
        got = self._lock.acquire(blocking, timeout)
        if got and threading.get_ident() != self._owner:
            self.foreign += 1
        return got

    def release(self):
        self._lock.release()

    __enter__ = acquire

    def __exit__(self, *exc):
        self.release()


def test_a_paused_worker_leaves_the_world_to_the_window():
    """Paused with nothing queued, the worker never takes the step lock, so the window's changes run at once."""
    world = _ball_world()
    clock = SimulationClock(world)
    clock.lock = lock = CountingLock()
    thread = SimulationThread(clock, period=0.002)
    thread.start()
    try:
        threading.Event().wait(0.1)  # about 50 idle periods
        assert thread.running and lock.foreign == 0
        assert thread.submit(lambda: setattr(world, "gravity", (0.0, 0.0, -3.0))) is True
        clock.play()
        for _ in range(1000):  # playing, the worker steps under the lock
            if lock.foreign:
                break
            threading.Event().wait(0.01)
        assert lock.foreign > 0
    finally:
        thread.stop()
