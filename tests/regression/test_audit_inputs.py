"""Inputs a hostile audit of the command line and the API found mishandled (2026-12-07).

Each was a traceback line ("internal error"), a run that saved what diverged, a user's file lost,
or a check that passed what `run` refuses; each now gets one line naming the problem and exit 2
(or a clear exception from the API), and nothing of the user's is written over.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import tumble
import tumble.io.record
from tumble import limits
from tumble.cli import main
from tumble.io.scene import build_world, parse_scene

BALL = "[[plane]]\n[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\nmass = 1.0\n"
HUGE = "1" + "0" * 400  # an integer literal no float holds


def _one_line_error(capsys, *fragments: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and "internal error" not in err, err
    for fragment in fragments:
        assert fragment in err, err
    return err


@pytest.mark.parametrize(
    "text, key",
    [
        (f"[[sphere]]\nposition = [0, 0, 1]\nradius = {HUGE}\n", "radius"),
        (f"[[sphere]]\nposition = [0, 0, {HUGE}]\nradius = 1\n", "position"),
        (f"[world]\ndt = {HUGE}\n[[sphere]]\nposition = [0, 0, 1]\nradius = 1\n", "dt"),
        (f"[world]\nseed = {HUGE}\n[[sphere]]\nposition = [0, 0, 1]\nradius = 1\n", "seed"),
        (f"[[sphere]]\nposition = [0, 0, 1]\nradius = -{HUGE}\n", "radius"),
    ],
)
@pytest.mark.parametrize("command", ["check", "run"])
def test_an_integer_too_large_for_a_float_is_refused_by_its_key(write_scene, capsys, text, key, command):
    """A 400-digit integer made `float()` raise OverflowError: "internal error", exit 1 (and a seed that
    large passed `check`, then failed `run`)."""
    path = write_scene(text)
    argv = [command, str(path)] + (["--duration", "0.01"] if command == "run" else [])
    assert main(argv) == 2
    _one_line_error(capsys, str(path), key)


def test_an_integer_past_pythons_digit_limit_is_refused_with_its_line(write_scene, capsys):
    path = write_scene(BALL + "[[sphere]]\nposition = [0, 0, 2]\nradius = 1" + "0" * 5000 + "\n")
    assert main(["check", str(path)]) == 2
    _one_line_error(capsys, str(path), "line 8")


def test_a_seed_from_the_api_is_an_integer_in_the_int64_range():
    assert tumble.World(seed=limits.MAX_SEED).seed == limits.MAX_SEED
    with pytest.raises(ValueError, match="seed must be an integer in"):
        tumble.World(seed=limits.MAX_SEED + 1)
    with pytest.raises(TypeError, match="position must be 3 finite numbers"):
        tumble.World().add_sphere(position=(0, 0, 10**400), radius=1.0)


DIVERGES_LAST = "[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\nvelocity = [1e308, 0, 0]\n"


def test_a_run_that_diverges_in_its_last_step_saves_nothing(write_scene, tmp_path, capsys):
    """Each step checks the state it starts from, so a state made infinite by the last step was saved
    (exit 0, "kinetic energy inf J"), and `run --resume` of it then failed."""
    path = write_scene(DIVERGES_LAST)
    state, record = tmp_path / "s.npz", tmp_path / "r.npz"
    argv = ["run", str(path), "--duration", "1.8", "--save-state", str(state), "--record", str(record)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "is not finite" in err and "Traceback" not in err, err
    assert not state.exists() and not record.exists()
    world = build_world(parse_scene(DIVERGES_LAST))
    with pytest.raises(tumble.SimulationError, match="is not finite"):
        world.run(1.8)


def test_an_export_that_diverges_in_its_last_step_writes_nothing(write_scene, tmp_path, capsys):
    pytest.importorskip("pxr")
    path = write_scene(DIVERGES_LAST)
    out = tmp_path / "x.usda"
    assert main(["export", str(path), "--duration", "1.8", "--fps", "240", "-o", str(out), "--no-progress"]) == 2
    assert "is not finite" in capsys.readouterr().err
    assert not out.exists()


def _ball_recording(tmp_path):
    world = build_world(parse_scene(BALL))
    recorder = tumble.io.record.Recorder(world, fps=60.0)
    for _ in range(30):
        world.step()
        recorder(world)
    recorder.save(tmp_path / "ball.npz")
    return tumble.io.record.load_recording(tmp_path / "ball.npz")


@pytest.mark.parametrize(
    "name, value, message",
    [
        ("position", np.inf, "'position' holds an infinity"),
        ("dt", 0.0, "'dt' holds 0, not a positive number"),
        ("fps", -1.0, "'fps' holds -1, not a positive number"),
    ],
)
def test_an_edited_recording_with_an_infinite_state_or_no_rate_is_refused(tmp_path, capsys, name, value, message):
    """Infinite positions were exported into the USD stage and plotted, dt = 0 was taken, and fps = -1 was
    reported as if the user's --fps were wrong, naming no file."""
    arrays = _ball_recording(tmp_path)
    arrays[name] = np.full_like(arrays[name], value)
    path = tmp_path / "edited.npz"
    np.savez(path, **arrays)
    with pytest.raises(tumble.io.record.RecordingError, match=message):
        tumble.io.record.load_recording(path)
    assert main(["plot", str(path), "-o", str(tmp_path / "p.png")]) == 2
    _one_line_error(capsys, str(path), message)
    assert not (tmp_path / "p.png").exists()


def test_a_recording_of_a_plane_keeps_its_infinite_bound():
    """A plane's bound radius is infinite in every recording: not state, and not refused."""
    world = tumble.World()
    world.add_plane()
    world.add_sphere(position=(0, 0, 1), radius=0.1)
    recorder = tumble.io.record.Recorder(world, fps=60.0)
    world.step()
    recorder(world)
    assert math.isinf(recorder.arrays()["bound_radius"][0])


def test_run_refuses_to_record_over_the_state_it_resumes(write_scene, tmp_path, capsys):
    path = write_scene(BALL)
    state = tmp_path / "s.npz"
    assert main(["run", str(path), "--duration", "0.05", "--save-state", str(state)]) == 0
    saved = state.read_bytes()
    capsys.readouterr()
    assert main(["run", "--resume", str(state), "--duration", "0.05", "--record", str(state)]) == 2
    _one_line_error(capsys, "--record and --resume name the same file")
    assert state.read_bytes() == saved


def test_check_refuses_what_only_the_built_world_refuses(write_scene, capsys):
    """`check` passed scenes that `run` then refused: here a hinge motor without a torque."""
    text = (
        "[[box]]\nposition = [0, 0, 1]\nhalf_extents = [0.1, 0.1, 0.1]\n"
        '[[joint]]\ntype = "hinge"\nbody_a = "world"\nbody_b = "box[0]"\nanchor = [0, 0, 1.2]\n'
        "axis = [1, 0, 0]\nmotor_speed = 1.0\n"
    )
    path = write_scene(text)
    assert main(["check", str(path)]) == 2
    _one_line_error(capsys, str(path), "max_torque")


def test_a_kinematic_body_in_a_scene_moves_by_its_velocity(write_scene, capsys):
    """The message refusing a static body's velocity said "set kinematic = true", and docs/scenes.md too,
    but the scene schema had no such key."""
    text = "[[box]]\nposition = [0, 0, 0.5]\nhalf_extents = [1, 1, 0.05]\nkinematic = true\nvelocity = [0.5, 0, 0]\n"
    world = build_world(parse_scene(text))
    world.run(1.0)
    assert world.body_position[0] == pytest.approx([0.5, 0.0, 0.5], abs=1e-12)
    assert world.body_velocity[0] == pytest.approx([0.5, 0.0, 0.0], abs=0)


def test_bodies_beyond_the_memory_are_refused_before_they_are_copied():
    """A broadcast of 10^9 positions was copied to float64 until the system ended the process."""
    world = tumble.World()
    with pytest.raises(limits.LimitError, match="bodies need about"):
        world.add_spheres(position=np.broadcast_to(np.zeros(3), (10**9, 3)), radius=0.1)
    assert world.body_count == 0


def test_a_scene_saved_with_a_byte_order_mark_reads_as_without(write_scene, capsys):
    """Notepad saves UTF-8 with a byte-order mark, which made every scene "Invalid statement (at line 1)"."""
    path = write_scene("\ufeff" + BALL)
    assert main(["check", str(path)]) == 0
    assert "ok: 1 plane, 1 sphere" in capsys.readouterr().out


def test_a_named_pipe_or_an_empty_name_is_not_read_as_a_scene(tmp_path, capsys):
    """A pipe with no writer made `check` wait for ever; an empty name was called "a directory"."""
    import os

    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)
    assert main(["check", str(fifo)]) == 2
    _one_line_error(capsys, str(fifo), "not a regular file")
    assert main(["check", ""]) == 2
    _one_line_error(capsys, "no scene file given")
    with pytest.raises(ValueError, match="neither was given"):
        tumble.World().add_convex(position=(0, 0, 0))


def test_a_float32_world_refuses_a_gravity_its_floats_cannot_hold():
    """Positions and masses beyond float32 were refused when given; gravity of 1e39 was taken, and the run
    later failed as if it had diverged."""
    with pytest.raises(ValueError, match="gravity: -1e\\+39 does not fit a float32 world"):
        tumble.World(gravity=(0, 0, -1e39), precision="float32")
    world = tumble.World(precision="float32")
    with pytest.raises(ValueError, match="gravity: 1e\\+40 does not fit a float32 world"):
        world.gravity = (0, 0, 1e40)
    assert tumble.World(gravity=(0, 0, -1e39), precision="float64").gravity[2] == -1e39


def test_export_names_a_rate_above_the_steps_before_the_memory_it_would_take(write_scene, tmp_path, capsys):
    """--fps 1e9 was refused as "duration: 100,000,001 frames need about 51 GB", not for its rate."""
    pytest.importorskip("pxr")
    path = write_scene(BALL)
    out = tmp_path / "e.usda"
    assert main(["export", str(path), "-o", str(out), "--fps", "1e9", "--duration", "0.1", "--no-progress"]) == 2
    _one_line_error(capsys, "fps 1e+09 is more than the world's 240 steps per second")
    assert not out.exists()


def test_a_cloth_a_hundred_times_thicker_than_it_is_wide_is_refused(write_scene, capsys):
    """thickness = 1e300 was taken, and the cloth diverged in its first step with advice to lower its
    stiffness."""
    path = write_scene("[[cloth]]\nsize = [1, 1]\nposition = [0, 0, 1]\nresolution = [10, 10]\nthickness = 1e300\n")
    assert main(["check", str(path)]) == 2
    _one_line_error(capsys, str(path), "thickness 1e+300 m is more than 100 times the cloth's size 1 x 1 m")
    world = tumble.World()
    world.add_cloth(size=(0.5, 0.2), resolution=(4, 4), thickness=50.0)  # up to 100 times its larger side
    with pytest.raises(ValueError, match="thickness 51 m is more than 100 times"):
        world.add_cloth(size=(0.5, 0.2), resolution=(4, 4), thickness=51.0)


def test_a_cloth_blown_apart_by_its_wind_is_told_to_check_the_wind(write_scene, capsys):
    path = write_scene(
        "[[cloth]]\nsize = [1, 1]\nposition = [0, 0, 1]\nresolution = [10, 10]\n[wind]\nvelocity = [1e308, 0, 0]\n"
    )
    assert main(["run", str(path), "--duration", "0.1"]) == 2
    err = capsys.readouterr().err.splitlines()  # (after run's "first step done" line)
    assert "the cloth diverged" in err[-1] and "check the wind's speed and turbulence" in err[-1], err


# ------------------------------------------------------------------------------ the API's lifecycle (a second audit)


def test_a_step_too_short_for_the_solver_is_refused():
    """step(dt=5e-324) raised ZeroDivisionError inside the solver; a float32 cloth stepped by 1e-300 s went
    NaN. Steps are at least limits.MIN_DT (1 ns), everywhere a step length is taken."""
    world = tumble.World()
    world.add_plane()
    world.add_sphere(position=(0, 0, 0.1), radius=0.1)
    for call in (lambda: world.step(dt=5e-324), lambda: setattr(world, "dt", 1e-300)):
        with pytest.raises(ValueError, match=r"dt must be in \[1e-09, 0.1\]"):
            call()
    kinematic = world.add_box(position=(1, 0, 1), half_extents=(0.1, 0.1, 0.1), kinematic=True)
    with pytest.raises(ValueError, match=r"dt must be in \[1e-09, 0.1\]"):
        world.set_kinematic_target(kinematic, position=(2, 0, 1), dt=5e-324)
    world.step(dt=limits.MIN_DT)
    assert world.time == limits.MIN_DT


def test_an_int_id_past_the_worlds_is_a_tumble_error_and_an_index_error():
    """body(999) raised a bare IndexError, which `except tumble.TumbleError` missed."""
    world = tumble.World()
    world.add_sphere(position=(0, 0, 1), radius=0.1)
    for call in (lambda: world.body(999), lambda: world.remove_body(999), lambda: world.body_state(999)):
        with pytest.raises(tumble.HandleError, match="body 999 does not exist") as info:
            call()
        assert isinstance(info.value, IndexError)


def test_a_joint_to_another_worlds_body_is_a_tumble_error():
    world, other = tumble.World(), tumble.World()
    body = other.add_sphere(position=(0, 0, 1), radius=0.1)
    with pytest.raises(tumble.TumbleError, match="body_b: body 0 belongs to another World"):
        world.add_joint("ball", None, body)


def test_save_snapshot_names_a_wrong_argument_or_path(tmp_path):
    """save_snapshot("x", path) raised AttributeError; a missing folder was reported by the temporary file's
    name; a .txt path was written as an npz."""
    from tumble.io.atomic import OutputError

    world = tumble.World()
    world.add_sphere(position=(0, 0, 1), radius=0.1)
    with pytest.raises(TypeError, match="must be a Snapshot"):
        tumble.save_snapshot("x", tmp_path / "s.npz")
    with pytest.raises(OutputError, match=f"no such directory '{tmp_path / 'nope'}'"):
        tumble.save_snapshot(world.snapshot(), tmp_path / "nope" / "s.npz")
    with pytest.raises(OutputError, match="must end in .npz"):
        tumble.save_snapshot(world.snapshot(), tmp_path / "s.txt")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_gravity_made_nan_in_place_is_named_by_the_next_step():
    """World.gravity may be changed in place; a NaN put there was reported as the bodies' divergence (with
    cloth: "lower its stiffness")."""
    world = tumble.World()
    world.add_sphere(position=(0, 0, 1), radius=0.1)
    world.add_cloth(size=(0.2, 0.2), resolution=(3, 3), position=(1, 0, 1))
    world.step()
    world.gravity[2] = np.nan
    with pytest.raises(ValueError, match=r"gravity must be finite, got \[0.0, 0.0, nan\]"):
        world.step()
    world.gravity[2] = -9.81
    world.step()
    assert world.step_count == 2
