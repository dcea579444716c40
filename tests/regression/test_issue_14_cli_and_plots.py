"""The command line and the plots as a new user meets them.

Issue 14 (a new user's first hour), items 5 (CLI: --version, help, what each command accepts)
and 7 (plots: momentum includes the cloth, emitted bodies marked, empty panels say so).
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import tumble
from tumble.cli import COMMANDS, build_parser, main
from tumble.io.plot import build_figure, compute_series, emission_span
from tumble.io.record import Recorder

# ------------------------------------------------------------------------------ CLI


@pytest.mark.parametrize("flag", ["--version", "-V"])
def test_version(flag, capsys):
    """tumble --version and -V print "tumble X.Y.Z" and exit 0."""
    with pytest.raises(SystemExit) as info:
        main([flag])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"tumble {tumble.__version__}"


def test_no_arguments_prints_help(tumble_subprocess_env):
    """`tumble` alone prints the help (every command listed) and exits 0."""
    result = subprocess.run(
        [sys.executable, "-m", "tumble"], capture_output=True, text=True, env=tumble_subprocess_env, timeout=120
    )
    assert result.returncode == 0 and result.stderr == ""
    assert result.stdout.startswith("usage: tumble")
    for name in COMMANDS:
        assert name in result.stdout


def _subparsers():
    return build_parser().commands


def test_every_scene_argument_says_it_takes_sample_names():
    """run, check, view and render help: SCENE is a .toml file or a bundled sample's name."""
    for name in ("run", "check", "view", "render"):
        help_text = _subparsers()[name].format_help()
        assert "SCENE" in help_text and ".toml" in help_text and "bundled sample" in help_text, name


def test_plot_help_says_it_takes_a_recording():
    """plot's help names the .npz recording and the image suffixes."""
    text = " ".join(_subparsers()["plot"].format_help().split())
    assert "RECORD" in text and "--record" in text and ".png" in text and "not a scene file" in text


def test_help_strings_share_one_style():
    """Every command and option help starts in lower case and ends without a full stop."""
    from importlib import import_module

    for name, module in COMMANDS.items():
        summary = import_module(f"tumble.commands.{module}").HELP
        assert summary[0].islower() and not summary.endswith("."), name
        for action in _subparsers()[name].options:
            if action.help and action.help != "==SUPPRESS==":
                assert action.help[0].islower() or action.help[0] in "`-", (name, action.help)
                assert not action.help.endswith("."), (name, action.help)


def test_a_bad_option_is_one_line(capsys):
    """argparse's usage errors are one line pointing at --help, exit 2."""
    with pytest.raises(SystemExit) as info:
        main(["run", "bouncing_ball", "--duration", "soon"])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--duration" in err and "tumble run --help" in err


def test_plot_of_a_scene_file_says_what_to_do(capsys):
    """`tumble plot samples/rain.toml` says it is a scene and how to record one, not "pickled data"."""
    from tumble.io.scene import SAMPLES_DIR

    assert main(["plot", str(SAMPLES_DIR / "rain.toml"), "-o", "/tmp/unused-robust.png"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "pickled" not in err
    assert "rain.toml" in err and "tumble run" in err and "--record" in err


# ------------------------------------------------------------------------------ plots


def _flag_recording(seconds: float = 0.5):
    """A hanging flag in wind: bodies at rest, the cloth moving."""
    world = tumble.World(seed=1)
    world.add_plane()
    world.add_cloth(
        size=(1.0, 0.6),
        resolution=(8, 5),
        position=(0, 0, 1.5),
        orientation=(0.7071068, 0, 0, 0.7071068),
        pins="top-edge",
    )
    world.set_wind(velocity=(4.0, 0.0, 0.0), turbulence=1.0)
    recorder = Recorder(world, fps=30)
    world.run(seconds, callback=recorder)
    return world, recorder.arrays()


def test_momentum_includes_the_cloth():
    """The recorded and plotted momentum is bodies plus cloth: sum m v over the particles."""
    world, rec = _flag_recording()
    cloth = world.cloth
    expected = np.asarray(cloth.particle_mass) @ np.asarray(cloth.particle_velocity)
    np.testing.assert_allclose(rec["momentum"][-1], expected + world.momentum(), rtol=1e-12, atol=1e-15)
    assert np.linalg.norm(rec["momentum"][-1]) > 1e-6  # the flag moves, so the panel is not flat zero
    s = compute_series(rec)
    np.testing.assert_array_equal(s.momentum, rec["momentum"])


def test_momentum_without_a_recorded_total_is_the_bodies_and_says_so():
    """Without a recorded total (cloth velocities are never recorded), the panel sums the bodies' m v and says so."""
    f, p = 4, 3
    rec = {
        "time": np.arange(f) / 10.0,
        "position": np.zeros((f, 1, 3)),
        "velocity": np.ones((f, 1, 3)),
        "mass": np.array([2.0]),
        "cloth_position": np.zeros((f, p, 3)),
        "cloth_mass": np.full(p, 0.5),
        "gravity": np.array([0.0, 0.0, -9.81]),
    }
    s = compute_series(rec)
    np.testing.assert_allclose(s.momentum, np.full((f, 3), 2.0))
    assert "bodies only" in s.notes["momentum"]


def test_emitted_bodies_are_marked():
    """While bodies appear, every panel shades the span and the potential panel says how many."""
    f = 20
    t = np.arange(f) / 10.0
    pos = np.zeros((f, 6, 3))
    pos[:, :, 2] = 1.0
    for k in range(5):  # body k + 1 appears at frame 5 + 2k
        pos[: 5 + 2 * k, k + 1] = np.nan
    rec = {
        "time": t,
        "position": pos,
        "velocity": np.zeros_like(pos),
        "mass": np.ones(6),
        "gravity": np.array([0.0, 0.0, -9.81]),
        "contact_count": np.arange(f),
    }
    assert emission_span(t, np.isfinite(pos[..., 0]).sum(axis=1)) == pytest.approx((0.4, 1.3))
    fig = build_figure(rec)
    title = fig.axes[1].get_title(loc="left")
    assert "emitted" in title and "1 to 6 bodies" in title
    for ax in fig.axes:
        spans = [p for p in ax.patches if p.get_label() == "_emitting"]
        assert len(spans) == 1, ax.get_title(loc="left")
        bbox = spans[0].get_bbox()  # in data x (axes y) coordinates
        assert (bbox.x0, bbox.x1) == pytest.approx((0.4, 1.3))


def test_empty_panels_say_so():
    """A quantity zero throughout says so, on an axis with whole ticks -1, 0, 1."""
    f = 10
    rec = {
        "time": np.arange(f) / 10.0,
        "position": np.ones((f, 1, 3)),
        "velocity": np.zeros((f, 1, 3)),
        "mass": np.ones(1),
        "gravity": np.array([0.0, 0.0, -9.81]),
        "contact_count": np.zeros(f),
        "kinetic_energy": np.zeros(f),
    }
    fig = build_figure(rec)
    by_title = {ax.get_title(loc="left").split(" (")[0]: ax for ax in fig.axes}
    for name, words in (
        ("Kinetic energy", "zero throughout"),
        ("Linear momentum", "zero throughout"),
        ("Contact count", "no contacts at the recorded frames"),
    ):
        ax = by_title[name]
        assert words in [t.get_text() for t in ax.texts], name
        assert list(ax.get_yticks()) == [-1.0, 0.0, 1.0], name
    # a panel with data draws it and has no such note
    assert not by_title["Potential energy"].texts
