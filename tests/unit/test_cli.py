"""The `tumble run` and `tumble check` commands: summaries, recordings, exit codes on bad input."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import numpy as np
import pytest

import tumble
from tumble.cli import COMMANDS, build_parser, main
from tumble.io.scene import SAMPLES_DIR

from .io.scene import BALL

# a ground plane, one sphere and an emitter releasing 4 spheres at 40 per second from t = 0
EMITTING = (
    BALL
    + """
[[emitter]]
rate = 40
count = 4
position = [0, 0, 2]
region = "box"
extent = [0.5, 0.5, 0.1]
radius = 0.05
mass = 0.1
seed = 3
"""
)


def test_run_prints_a_summary(write_scene, capsys):
    """Run a scene headless, exit 0 and print bodies, steps, speed, energy and contacts."""
    assert main(["run", str(write_scene(BALL)), "--duration", "0.25"]) == 0
    out = capsys.readouterr().out
    for label in ("bodies", "steps", "steps/s", "kinetic energy", "contacts"):
        assert label in out
    assert "2 (1 plane, 1 sphere, 0 boxes)" in out
    assert "60 (0.250 s simulated" in out  # 0.25 s at dt = 1/240


def test_run_profile_lists_the_stages(write_scene, capsys):
    """Print the time per stage with --profile."""
    assert main(["run", str(write_scene(BALL)), "--duration", "0.05", "--profile"]) == 0
    out = capsys.readouterr().out
    assert "stage" in out and "ms/step" in out and "total" in out


def test_record_writes_the_documented_arrays(write_scene, tmp_path, capsys):
    """Write every documented array with its shape, and NaN rows for bodies not yet emitted."""
    out = tmp_path / "rec.npz"
    assert main(["run", str(write_scene(EMITTING)), "--duration", "0.5", "--record", str(out), "--fps", "30"]) == 0
    rec = np.load(out)
    f = 16  # frames at t = 0, 1/30, ..., 15/30 = 0.5 s
    n = 2 + 4  # plane, sphere, 4 emitted spheres
    expected = {
        "time": (f,),
        "position": (f, n, 3),
        "velocity": (f, n, 3),
        "orientation": (f, n, 4),
        "angular_velocity": (f, n, 3),
        "shape": (n,),
        "shape_names": (len(tumble.ShapeType),),
        "radius": (n,),
        "half_extents": (n, 3),
        "mass": (n,),
        "gravity": (3,),
        "dt": (),
        "contact_count": (f,),
        "kinetic_energy": (f,),
    }
    for name, shape in expected.items():
        assert rec[name].shape == shape, name
    np.testing.assert_allclose(rec["time"], np.arange(f) / 30.0, atol=0.5 / 240)
    assert rec["shape"].dtype == np.int32
    assert list(rec["shape_names"][rec["shape"]]) == ["plane", "sphere"] + ["sphere"] * 4
    np.testing.assert_array_equal(rec["radius"], [0.0, 0.1] + [0.05] * 4)
    # at t = 0 only the plane and the ball exist; at the end every body does
    assert np.isfinite(rec["position"][0, :2]).all()
    assert np.isnan(rec["position"][0, 2:]).all() and np.isnan(rec["orientation"][0, 2:]).all()
    assert np.isfinite(rec["position"][-1]).all()
    # once a body appears it stays: its NaN frames come first
    present = np.isfinite(rec["position"][:, :, 0])
    assert (np.diff(present.astype(int), axis=0) >= 0).all()
    # the free ball falls as z0 - g t^2 / 2 until it reaches the ground (z0 = 1 m, it lands after ~0.43 s)
    t = rec["time"][:6]
    np.testing.assert_allclose(rec["position"][:6, 1, 2], 1.0 - 0.5 * 9.81 * t**2, atol=9.81 * t.max() / 240 + 1e-9)
    assert "recorded" in capsys.readouterr().out


def test_check_accepts_a_good_file(capsys):
    """Validate a bundled sample without running it and print one summary line."""
    assert main(["check", str(SAMPLES_DIR / "sphere_pile.toml")]) == 0
    out = capsys.readouterr().out.strip()
    assert out.count("\n") == 0
    assert "ok" in out and "5 planes" in out and "1 emitter (1000 bodies)" in out


def test_check_finds_a_sample_by_name(capsys):
    """Accept the bare name of a bundled sample."""
    assert main(["check", "bouncing_ball"]) == 0
    assert "1 sphere" in capsys.readouterr().out


BAD_FILES = {
    "unknown key": ("[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\ncolour = 'red'\n", "colour"),
    "negative radius": ("[[sphere]]\nposition = [0, 0, 1]\nradius = -1\n", "radius"),
    "zero normal": ("[[plane]]\nnormal = [0, 0, 0]\n", "normal"),
    "nan": ("[[box]]\nposition = [0, 0, nan]\nhalf_extents = [1, 1, 1]\n", "position"),
    "malformed toml": ("[[sphere]\nposition = [0, 0, 1]\n", "line 1"),
}


@pytest.mark.parametrize(
    "command, case",
    [("check", case) for case in BAD_FILES] + [("run", "unknown key"), ("run", "malformed toml")],
    ids=[f"check-{case}" for case in BAD_FILES] + ["run-unknown key", "run-malformed toml"],
)
def test_bad_file_exits_2_with_one_line(write_scene, tumble_subprocess_env, command, case):
    """Exit with status 2 and one line on stderr naming file and key, without a traceback."""
    text, fragment = BAD_FILES[case]
    path = write_scene(text, "bad.toml")
    result = subprocess.run(
        [sys.executable, "-m", "tumble", command, str(path)],
        capture_output=True,
        text=True,
        env=tumble_subprocess_env,
        timeout=120,
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    assert lines[0].startswith(f"tumble {command}: error: ")
    assert "bad.toml" in lines[0] and fragment in lines[0]
    assert result.stdout == ""


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["run", "missing.toml"], "no such scene file"),
        (["run", "SCENE", "--duration", "-1"], "--duration"),
        (["run", "SCENE", "--fps", "0"], "--fps"),
        (["run", "SCENE", "--record", "out.csv"], ".npz"),
        (["run", "SCENE", "--record", "no/such/dir/out.npz"], "no such directory"),
        (["check", "missing.toml"], "no such scene file"),
    ],
)
def test_bad_arguments_exit_2(write_scene, capsys, argv, fragment):
    """Reject a missing file or a bad option with exit status 2 and one line on stderr."""
    path = str(write_scene(BALL))
    assert main([path if a == "SCENE" else a for a in argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and fragment in err


CLOTH_READY = importlib.util.find_spec("tumble.cloth") is not None


@pytest.mark.skipif(not CLOTH_READY, reason="the cloth engine (tumble.cloth) is not merged yet")
def test_record_writes_cloth_arrays(write_scene, tmp_path):
    """Add cloth_position, cloth_triangles, cloth_rest_position, cloth_mass and strain to cloth recordings."""
    out = tmp_path / "cloth.npz"
    scene = write_scene(
        "[[plane]]\n[[cloth]]\nsize = [1, 0.5]\nresolution = [6, 4]\nposition = [0, 0, 1]\npins = 'top-edge'\n"
    )
    assert main(["run", str(scene), "--duration", "0.25", "--record", str(out)]) == 0
    rec = np.load(out)
    f, p = 16, 6 * 4
    assert rec["cloth_position"].shape == (f, p, 3)
    assert rec["cloth_triangles"].shape == (2 * 5 * 3, 3) and rec["cloth_triangles"].dtype == np.int32
    np.testing.assert_allclose(rec["cloth_rest_position"], rec["cloth_position"][0])
    # row-major, i fastest: particle j * nx + i sits at x = -0.5 + i * 0.2, y = -0.25 + j * 0.5 / 3 at rest
    np.testing.assert_allclose(rec["cloth_rest_position"][7, :2], [-0.3, -0.25 + 0.5 / 3], atol=1e-12)
    # the pinned top edge (j = 3) stays; the rest falls
    np.testing.assert_allclose(rec["cloth_position"][-1, 18:, 2], 1.0, atol=1e-9)
    assert rec["cloth_position"][-1, :6, 2].max() < 1.0
    # masses add up to the cloth's; strain starts at zero and stays within the 10 % limit
    assert rec["cloth_mass"].shape == (p,) and rec["cloth_mass"].sum() > 0
    assert rec["cloth_max_strain"].shape == (f,)
    assert rec["cloth_max_strain"][0] == 0.0
    assert 0.0 < rec["cloth_max_strain"].max() <= 0.1 + 1e-6


def test_recorder_samples_at_the_nearest_step(write_scene):
    """Record one frame per 1/fps of simulated time, at the step nearest to it, when dt does not divide it."""
    import tumble
    from tumble.io.record import Recorder

    world = tumble.load_scene(write_scene("[world]\ndt = 0.01\n" + BALL))
    recorder = Recorder(world, fps=30)
    world.run(1.0, callback=recorder)
    time = recorder.arrays()["time"]
    assert len(time) == 31  # t = 0, 1/30, ..., 1
    assert np.all(np.abs(time - np.arange(31) / 30) <= 0.5 * world.dt + 1e-12)
    with pytest.raises(ValueError, match="fps"):
        Recorder(world, fps=0)


def test_the_parser_lists_its_commands_and_every_option():
    """build_parser() keeps one parser per command in `commands`, each with every argument it takes in `options`."""
    parser = build_parser()
    assert list(parser.commands) == list(COMMANDS)
    flags = {name: [f for a in p.options for f in a.option_strings] for name, p in parser.commands.items()}
    for name, listed in flags.items():
        assert listed[:2] == ["-h", "--help"] and "--debug" in listed, name
        assert len(listed) == len(set(listed)), name
    assert {"--duration", "--record", "--fps", "--resume"} <= set(flags["run"])
    # the arguments of a mutually exclusive group are listed as the parser's own
    assert {"--duration", "--frames"} <= set(flags["export"])
    # and what is listed is what the parser takes: each option's value lands under its dest
    export = {a.dest: a for a in parser.commands["export"].options}
    args = parser.parse_args(["export", "sphere_pile", "-o", "x.usda", "--frames", "12"])
    assert args.frames == 12 and export["frames"].type is int and args.output == "x.usda"
    # the positional SCENE argument is an option too, with no flags
    assert [a.dest for a in parser.commands["check"].options if not a.option_strings] == ["scene"]
