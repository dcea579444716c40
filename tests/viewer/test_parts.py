"""Parts of the viewer that need no window: the pacing clock, picking, the command line."""

import math

import numpy as np
import pytest

from tumble.viewer import picking
from tumble.viewer.sim import SimulationClock


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


def test_ray_points_finds_the_nearest_particle_within_reach():
    """Particles within reach of the ray are candidates; the nearest along the ray wins."""
    points = np.array([[3.0, 0.05, 0.0], [1.0, 0.5, 0.0], [2.0, -0.02, 0.0]])
    i, t = picking.ray_points(np.zeros(3), np.array([1.0, 0.0, 0.0]), points, reach=0.1)
    assert i == 2 and t == pytest.approx(2.0)


def _view_only(monkeypatch):
    """The CLI with just the view command (the test needs no other command's imports)."""
    from tumble import cli

    monkeypatch.setattr(cli, "COMMANDS", {"view": "view"})
    return cli.main


def test_view_command_missing_scene_exits_2(capsys, tmp_path, monkeypatch):
    """`tumble view` on a missing file exits 2 with one line naming it."""
    pytest.importorskip("tumble.io.scene")  # the scene loader lives on its own branch until merged
    main = _view_only(monkeypatch)

    missing = tmp_path / "nope.toml"
    assert main(["view", str(missing)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope.toml" in err[0] and "no such scene file" in err[0]


def test_view_command_rejects_a_bad_size():
    """--size must look like WxH."""
    from tumble.commands.view import parse_size

    assert parse_size("320x240") == (320, 240)
    with pytest.raises(Exception, match="1280x720"):
        parse_size("big")


def test_view_command_broken_scene_exits_2(capsys, tmp_path, monkeypatch):
    """`tumble view` on a malformed scene exits 2 with one line naming the file, before any window."""
    pytest.importorskip("tumble.io.scene")  # the scene loader lives on its own branch until merged
    main = _view_only(monkeypatch)

    broken = tmp_path / "broken.toml"
    broken.write_text("[[sphere]]\nposition = [0, 0, 1]\nradius = 'big'\n")
    assert main(["view", str(broken)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "broken.toml" in err[0]


def test_no_display_is_reported_plainly(monkeypatch):
    """Without a display (and no offscreen platform asked for) the viewer says so instead of aborting."""
    import sys

    from tumble.viewer import gui_platform_problem

    monkeypatch.setenv("QT_QPA_PLATFORM", "offscreen")
    assert gui_platform_problem() is None
    if sys.platform.startswith("linux"):
        monkeypatch.delenv("QT_QPA_PLATFORM")
        monkeypatch.delenv("DISPLAY", raising=False)
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        assert "no display" in gui_platform_problem()


def test_ray_box_hits_the_face_of_a_turned_box():
    """A ray along +x meets a unit cube turned 45 degrees about z at its edge, sqrt(2)/2 from the centre."""
    q = np.array([0.0, 0.0, math.sin(math.pi / 8), math.cos(math.pi / 8)])
    t = picking.ray_box(np.array([-5.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.zeros(3), q, np.full(3, 0.5))
    assert t == pytest.approx(5.0 - math.sqrt(0.5))
    miss = picking.ray_box(np.array([-5.0, 0.9, 0.0]), np.array([1.0, 0.0, 0.0]), np.zeros(3), q, np.full(3, 0.5))
    assert math.isinf(miss)


class FakeCloth:
    """The ClothSystem surface the viewer uses: positions, velocities, masses, forces, pins."""

    def __init__(self):
        self.particle_position = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [2.0, 0.0, 1.0]])
        self.particle_velocity = np.zeros((3, 3))
        self.particle_mass = np.full(3, 0.5)
        self.particle_inv_mass = np.array([2.0, 2.0, 0.0])  # the last one is pinned
        self.particle_count = 3
        self.forces, self.pins = [], []

    def apply_force(self, i, force):
        self.forces.append((i, np.asarray(force)))

    def set_pin_target(self, i, position):
        self.pins.append((i, np.asarray(position)))


class FakeClothWorld:
    body_count = 0
    gravity = np.array([0.0, 0.0, -9.81])
    dt = 0.25

    has_cloth = True

    def __init__(self):
        self.cloth = FakeCloth()


def test_drag_pulls_a_free_cloth_particle_and_moves_a_pinned_one():
    """A ray through a free particle grabs it (spring force, weight held); through a pin, moves the pin."""
    world = FakeClothWorld()
    down = np.array([0.0, 0.0, -1.0])
    grab = picking.pick(world, np.array([1.0, 0.0, 5.0]), down)
    assert grab.kind == "particle" and grab.index == 1 and grab.distance == pytest.approx(4.0)
    grab.target = np.array([1.0, 0.0, 1.0])  # at the particle: only the weight is carried
    picking.apply_drag(world, grab)
    i, force = world.cloth.forces[-1]
    assert i == 1
    np.testing.assert_allclose(force, [0.0, 0.0, 0.5 * 9.81], atol=1e-9)

    pin = picking.pick(world, np.array([2.0, 0.0, 5.0]), down)
    assert pin.kind == "pin" and pin.index == 2
    pin.target = np.array([2.0, 0.3, 1.4])  # 0.5 m away: reached in one step of 0.25 s at 3 m/s
    picking.apply_drag(world, pin)
    assert world.cloth.pins[-1][0] == 2
    np.testing.assert_allclose(world.cloth.pins[-1][1], [2.0, 0.3, 1.4])
    pin.target = np.array([2.0, 0.0, 3.0])  # 2 m away: moves 0.75 m towards it
    picking.apply_drag(world, pin)
    np.testing.assert_allclose(world.cloth.pins[-1][1], [2.0, 0.0, 1.75])


def test_drag_target_stays_in_the_camera_facing_plane():
    """Moving the cursor keeps the target at the grab depth along the view axis."""
    grab = picking.Grab("body", 0, np.zeros(3), distance=5.0, target=np.zeros(3), depth=5.0)
    forward = np.array([0.0, 1.0, 0.0])
    d = np.array([0.6, 0.8, 0.0])
    target = picking.drag_target(grab, np.zeros(3), d, forward)
    assert target @ forward == pytest.approx(5.0)
