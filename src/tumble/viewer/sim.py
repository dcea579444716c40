"""Simulation clock for the viewer: a fixed world dt paced against real time.

The viewer never changes `world.dt`. Each timer tick it converts the real time elapsed since the
last tick (times the time scale) into a whole number of world steps, carrying the remainder over
to the next tick, so simulated time tracks real time on average. When the machine cannot keep up,
the number of steps per tick is capped and the backlog dropped (the simulation then runs slower
than real time instead of freezing the window).

Reads `world.dt`, `world.time`, `world.step_count`; calls `world.step()` and, before every step,
the `before_step(world)` hook (the viewer's mouse spring uses it, since `world.apply_force` lasts
one step only), after it the `after_step(world)` hook (the video recorder's).

`SimulationThread` runs the clock on a worker thread, so that a slow step never blocks the
window: the window draws, picks and shows statistics from a `WorldSnapshot` (a copy of the few
arrays it reads, taken between steps), and every change it makes to the world (controls, dropped
bodies) goes through `SimulationThread.submit`, which runs it between two steps.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable

import numpy as np

from ..errors import TumbleError

#: the most world steps one tick may take, whatever the backlog
MAX_STEPS_PER_TICK = 64
#: the most wall time [s] one tick may spend stepping, so that painting and input keep up
MAX_STEP_SECONDS_PER_TICK = 0.030


class SimulationClock:
    """Steps a world at a fixed dt so that simulated time follows real time × `time_scale`.

    Args:
        world: the `tumble.World` to step.
        factory: callable returning a fresh world, used by `reset()`; None disables reset.
        time_scale: simulated seconds per real second (1 = real time).
        playing: start running at once.
        before_step: called with the world just before each `world.step()`.
        after_step: called with the world just after each `world.step()`.
        clock: returns the current real time [s]; `time.perf_counter` by default.

    Each step runs holding `lock` (re-entrant), so that another thread can change the world
    between steps; `pause()` waits for a step in progress to end.
    """

    def __init__(
        self,
        world,
        *,
        factory: Callable[[], object] | None = None,
        time_scale: float = 1.0,
        playing: bool = False,
        before_step: Callable[[object], None] | None = None,
        after_step: Callable[[object], None] | None = None,
        clock: Callable[[], float] = time.perf_counter,
    ):
        self.world = world
        self.lock = threading.RLock()
        self.after_step = after_step
        self.factory = factory
        self.time_scale = float(time_scale)
        self.before_step = before_step
        self.clock = clock
        self.max_steps_per_tick = MAX_STEPS_PER_TICK
        self.max_step_seconds = MAX_STEP_SECONDS_PER_TICK
        self._playing = False
        self._last: float | None = None
        self._backlog = 0.0  # simulated seconds owed to the world, < one dt after each tick
        self._step_times: deque[float] = deque()  # wall times of recent steps, for steps_per_second
        self.dropped = 0.0  # simulated seconds given up because the machine could not keep up
        if playing:
            self.play()

    # ------------------------------------------------------------------ state

    @property
    def playing(self) -> bool:
        """True while the clock advances the world on `tick()`."""
        return self._playing

    def play(self) -> None:
        """Start (or continue) running in real time."""
        if not self._playing:
            self._playing = True
            self._last = self.clock()
            self._backlog = 0.0

    def pause(self) -> None:
        """Stop advancing the world; `step()` still works. Returns once no step is in progress."""
        self._playing = False
        with self.lock:
            self._last = None
            self._backlog = 0.0

    def toggle(self) -> bool:
        """Play if paused, pause if playing. Returns the new `playing`."""
        if self._playing:
            self.pause()
        else:
            self.play()
        return self._playing

    # ------------------------------------------------------------------ stepping

    def step(self) -> None:
        """Advance the world by exactly one step of `world.dt` (whether playing or not)."""
        with self.lock:
            if self.before_step is not None:
                self.before_step(self.world)
            self.world.step()
            if self.after_step is not None:
                self.after_step(self.world)
        self._step_times.append(self.clock())

    def steps_due(self, elapsed: float) -> int:
        """Add `elapsed` real seconds to the backlog; return the whole steps now owed (uncapped)."""
        self._backlog += max(0.0, float(elapsed)) * self.time_scale
        dt = float(self.world.dt)
        # a tiny tolerance so that e.g. 10 x dt of elapsed time gives 10 steps despite rounding
        n = int(math.floor(self._backlog / dt + 1e-9))
        self._backlog = max(0.0, self._backlog - n * dt)
        return n

    def tick(self) -> int:
        """Called by the viewer's timer: take the steps owed since the last tick. Returns how many.

        At most `max_steps_per_tick` steps, and no new step once `max_step_seconds` of wall time
        has gone into this tick (at least one step is always taken when one is owed).
        """
        if not self._playing:
            return 0
        now = self.clock()
        elapsed = 0.0 if self._last is None else now - self._last
        self._last = now
        owed = self.steps_due(elapsed)
        budget_end = now + self.max_step_seconds
        taken = 0
        while taken < min(owed, self.max_steps_per_tick) and self._playing:
            self.step()
            taken += 1
            if self.clock() > budget_end:
                break
        if taken < owed:
            # behind real time: drop the backlog rather than let it grow without bound
            self.dropped += (owed - taken) * float(self.world.dt)
            self._backlog = 0.0
        return taken

    def reset(self):
        """Replace the world by a fresh one from `factory`. Returns the new world.

        Raises:
            RuntimeError: when the clock has no factory.
        """
        if self.factory is None:
            raise RuntimeError("this world was not given a factory, so it cannot be reset")
        world = self.factory()
        with self.lock:
            self.world = world
        self._backlog = 0.0
        self._last = self.clock() if self._playing else None
        self._step_times.clear()
        self.dropped = 0.0
        return self.world

    # ------------------------------------------------------------------ statistics

    def steps_per_second(self, window: float = 1.0) -> float:
        """World steps taken per real second over the last `window` seconds."""
        now = self.clock()
        while self._step_times and self._step_times[0] < now - window:
            self._step_times.popleft()
        return len(self._step_times) / window


# ---------------------------------------------------------------------- the worker thread

#: world attributes a snapshot copies (what the renderer, the camera's framing and picking read)
SNAPSHOT_ARRAYS = (
    "body_shape",
    "body_position",
    "body_orientation",
    "body_radius",
    "body_half_extents",
    "body_plane_normal",
    "body_inv_mass",
    "body_mass",
    "body_geometry",
)
SNAPSHOT_VALUES = ("body_count", "time", "step_count", "contact_count", "dt", "substeps")


class ClothSnapshot:
    """Copies of a cloth's particle positions, masses and triangles (what is drawn and picked)."""

    def __init__(self, cloth):
        self.source = cloth
        self.particle_count = int(cloth.particle_count)
        self.particle_position = np.array(cloth.particle_position)
        self.particle_inv_mass = np.array(cloth.particle_inv_mass)
        self.particle_mass = np.array(cloth.particle_mass)
        self.triangles = np.asarray(cloth.triangles)  # fixed at creation


class WorldSnapshot:
    """What the window reads of a world, copied between two steps; drawn in place of the world.

    Has the world's `body_*` arrays that the renderer and picking read (copies), its counts and
    time, `gravity`, `metadata`, `emitters` (their regions), and `cloth` as a `ClothSnapshot`;
    `hulls` and `meshes` are the world's own (prototypes are never changed once added, only
    appended), `joint_lines` a copy of where the joints are (`tumble.render.solids.joint_segments`).
    `source` is the world it was taken from.
    """

    # set by __init__ from SNAPSHOT_ARRAYS (copies) and SNAPSHOT_VALUES
    body_shape: np.ndarray
    body_position: np.ndarray
    body_orientation: np.ndarray
    body_radius: np.ndarray
    body_half_extents: np.ndarray
    body_plane_normal: np.ndarray
    body_inv_mass: np.ndarray
    body_mass: np.ndarray
    body_geometry: np.ndarray
    body_count: int
    time: float
    step_count: int
    contact_count: int
    dt: float
    substeps: int

    def __init__(self, world):
        self.source = world
        for name in SNAPSHOT_ARRAYS:
            setattr(self, name, np.array(getattr(world, name)))
        for name in SNAPSHOT_VALUES:
            setattr(self, name, getattr(world, name))
        self.gravity = np.array(world.gravity, dtype=np.float64)
        self.metadata = getattr(world, "metadata", {})
        self.emitters = list(getattr(world, "emitters", None) or [])
        self.hulls = getattr(world, "hulls", None)
        self.meshes = getattr(world, "meshes", None)
        from ..render.solids import joint_segments

        self.joint_lines = joint_segments(world)
        self._cloth = ClothSnapshot(world.cloth) if world.has_cloth else None

    @property
    def has_cloth(self) -> bool:
        """Whether the world had cloth particles."""
        return self._cloth is not None

    @property
    def cloth(self):
        """The cloth's `ClothSnapshot`, or None."""
        return self._cloth


class SimulationThread:
    """Ticks a `SimulationClock` on a worker thread, about every `period` seconds.

    The window reads `snapshot` (the latest `WorldSnapshot`, replaced after every tick that
    stepped) and never the world itself while the thread runs. Changes to the world go through
    `submit`. Warp's CPU kernels release Python's lock while they run, so the window keeps
    drawing during a long step.

    Args:
        clock: the clock to tick (its `lock` guards every step).
        period: seconds between ticks.
        ready: called before each tick; the tick is skipped while it returns False (the video
            recorder uses it to hold the simulation until its frames are drawn).
    """

    def __init__(self, clock: SimulationClock, *, period: float = 0.016, ready: Callable[[], bool] | None = None):
        self.clock = clock
        self.period = float(period)
        self.ready = ready
        self.error: Exception | None = None  # a simulation error from the thread, for the window to show
        self.snapshot = WorldSnapshot(clock.world)
        self.version = 0  # counts snapshots taken
        self._posted: deque[Callable[[], None]] = deque()
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start the worker thread (once)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="tumble-simulation", daemon=True)
            self._thread.start()

    def stop(self) -> None:
        """Stop the worker thread and wait for it (at most one step)."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=30.0)
            self._thread = None

    @property
    def running(self) -> bool:
        """Whether the worker thread is running."""
        return self._thread is not None and self._thread.is_alive()

    def wake(self) -> None:
        """Tick now rather than at the end of the current period (e.g. after play)."""
        self._wake.set()

    def submit(self, change: Callable[[], None]) -> bool:
        """Run `change()` (which may change the world) between two steps. Returns True if it ran now.

        When no step is in progress it runs at once, here, after any changes still posted (so changes
        apply in the order they were made); else the worker runs it after that step.
        """
        if self.clock.lock.acquire(blocking=False):
            try:
                self._run_posted()
                change()
                self.publish()
            finally:
                self.clock.lock.release()
            return True
        self._posted.append(change)
        self._wake.set()
        return False

    def publish(self) -> None:
        """Take a new snapshot of the world now (between steps)."""
        with self.clock.lock:
            self.snapshot = WorldSnapshot(self.clock.world)
            self.version += 1

    def _run_posted(self) -> bool:
        ran = False
        while self._posted:
            change = self._posted.popleft()
            try:
                change()
            except (TumbleError, ValueError) as exc:  # e.g. a dropped body the world refuses
                self.error = exc
            ran = True
        return ran

    def _run(self) -> None:
        while not self._stop.is_set():
            start = time.perf_counter()
            changed = False
            if self._posted:  # the lock is left free while paused, so the window's changes run at once
                with self.clock.lock:
                    changed = self._run_posted()
            if self.clock.playing and (self.ready is None or self.ready()):
                try:
                    changed |= self.clock.tick() > 0
                except Exception as exc:  # noqa: BLE001 (shown by the window; the thread keeps going)
                    self.clock.pause()
                    self.error = exc
                    changed = True
            if changed:
                self.publish()
            self._wake.wait(max(0.0, self.period - (time.perf_counter() - start)))
            self._wake.clear()
