"""Simulation clock for the viewer: a fixed world dt paced against real time.

The viewer never changes `world.dt`. Each timer tick it converts the real time elapsed since the
last tick (times the time scale) into a whole number of world steps, carrying the remainder over
to the next tick, so simulated time tracks real time on average. When the machine cannot keep up,
the number of steps per tick is capped and the backlog dropped (the simulation then runs slower
than real time instead of freezing the window).

Reads `world.dt`, `world.time`, `world.step_count`; calls `world.step()` and, before every step,
the `before_step(world)` hook (the viewer's mouse spring uses it, since `world.apply_force` lasts
one step only).
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable

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
        clock: returns the current real time [s]; `time.perf_counter` by default.
    """

    def __init__(
        self,
        world,
        *,
        factory: Callable[[], object] | None = None,
        time_scale: float = 1.0,
        playing: bool = False,
        before_step: Callable[[object], None] | None = None,
        clock: Callable[[], float] = time.perf_counter,
    ):
        self.world = world
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
        """Stop advancing the world; `step()` still works."""
        self._playing = False
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
        if self.before_step is not None:
            self.before_step(self.world)
        self.world.step()
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
        while taken < min(owed, self.max_steps_per_tick):
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
        self.world = self.factory()
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
