"""`tumble render` (tumble.commands.render) from the command line, in process: the files it writes, the
camera it uses, its one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

import tumble
import tumble.cli
from tumble.io.scene import SAMPLES_DIR


@pytest.fixture
def cli(monkeypatch):
    """tumble.cli.main with only the render command (the others' imports are not needed)."""
    monkeypatch.setattr(tumble.cli, "COMMANDS", {"render": "render"})
    return tumble.cli.main


@pytest.fixture
def scene(monkeypatch, make_falling_world):
    """A scene path whose loading gives a falling-spheres world (records the worlds it made)."""
    made = []

    def load_scene(path, **overrides):
        world = make_falling_world()
        world.metadata["path"] = str(path)
        made.append(world)
        return world

    monkeypatch.setattr(tumble, "load_scene", load_scene)
    return made


def test_render_writes_an_mp4(tmp_path, cli, scene):
    """tumble render SCENE -o OUT.mp4 --duration --fps --size writes that many frames of that size."""
    import imageio.v3 as iio

    out = tmp_path / "drop.mp4"
    rc = cli(
        ["render", "drop.toml", "-o", str(out), "--duration", "0.3", "--fps", "10", "--size", "96x64", "--no-progress"]
    )
    assert rc == 0
    assert iio.imread(out).shape == (3, 64, 96, 3)
    assert scene[0].time == pytest.approx(0.2, abs=scene[0].dt)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_render_precision_replaces_the_scenes(tmp_path, cli, monkeypatch, precision):
    """--precision builds the rendered world in that precision (as `tumble run --precision`)."""
    load = tumble.load_scene
    made = []
    monkeypatch.setattr(
        tumble, "load_scene", lambda path, **overrides: made.append(load(path, **overrides)) or made[-1]
    )
    out = tmp_path / "ball.gif"
    argv = ["render", "bouncing_ball", "-o", str(out), "--duration", "0.1", "--fps", "10", "--size", "32x24"]
    assert cli([*argv, "--no-progress", "--precision", precision]) == 0
    assert out.is_file() and [w.precision for w in made] == [precision]


def test_render_camera_options_override_the_scene(tmp_path, cli, scene, monkeypatch):
    """--camera-position/--camera-target/--fov win over the scene's [camera] table."""
    import tumble.io.video as video

    seen = []
    original = video.export

    def spy(world, out, **kwargs):
        seen.append(kwargs["camera"])
        return original(world, out, **kwargs)

    monkeypatch.setattr(video, "export", spy)
    rc = cli(
        [
            "render",
            "s.toml",
            "-o",
            str(tmp_path / "f"),
            "--duration",
            "0.1",
            "--fps",
            "10",
            "--size",
            "32x24",
            "--camera-position",
            "1,2,3",
            "--camera-target",
            "0,0,0.5",
            "--fov",
            "35",
            "--no-progress",
        ]
    )
    assert rc == 0
    cam = seen[0]
    assert np.allclose(cam.position, [1, 2, 3]) and np.allclose(cam.target, [0, 0, 0.5])
    assert cam.fov_deg == 35


def test_render_without_opengl_exits_2_with_one_line(tmp_path, cli, scene, monkeypatch, capsys):
    """No OpenGL context: one line on stderr and exit status 2."""
    import moderngl

    def fail(*args, **kwargs):
        raise Exception("libEGL.so.1: cannot open shared object file")

    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    rc = cli(["render", "s.toml", "-o", str(tmp_path / "x.mp4"), "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1
    assert err.startswith("tumble render: error: no OpenGL context:")


def test_render_rejects_an_unknown_format(tmp_path, cli, scene, capsys):
    """An OUT with an unsupported suffix is refused before anything runs."""
    rc = cli(["render", "s.toml", "-o", str(tmp_path / "x.avi")])
    assert rc == 2
    assert ".mp4 or .gif" in capsys.readouterr().err
    assert scene == []


def test_render_a_sample_scene_file(tmp_path, monkeypatch):
    """tumble render on a real sample file writes a GIF with the scene's camera."""
    from PIL import Image

    monkeypatch.setattr(tumble.cli, "COMMANDS", {"render": "render"})
    out = tmp_path / "ball.gif"
    rc = tumble.cli.main(
        [
            "render",
            str(SAMPLES_DIR / "bouncing_ball.toml"),
            "-o",
            str(out),
            "--duration",
            "0.3",
            "--fps",
            "10",
            "--size",
            "64x48",
            "--no-progress",
        ]
    )
    assert rc == 0
    with Image.open(out) as im:
        assert im.size == (64, 48) and im.n_frames == 3


def test_render_joints_option_draws_the_joints(tmp_path, cli, monkeypatch):
    """--joints draws the joint overlay: a hanging ball's rope changes the frame; without it, it does not show."""
    from PIL import Image

    def load_scene(path, **overrides):
        world = tumble.World(dt=1.0 / 120.0)
        world.add_plane()
        ball = world.add_sphere(position=(0.0, 0.0, 0.5), radius=0.08)
        world.add_joint("rope", None, ball, anchor_a=(0.0, 0.0, 1.1))
        world.metadata["camera"] = {"position": [0.0, -2.5, 0.8], "target": [0.0, 0.0, 0.8], "fov": 40}
        return world

    monkeypatch.setattr(tumble, "load_scene", load_scene)
    frames = {}
    for flag in ([], ["--joints"]):
        out = tmp_path / ("with" if flag else "without")
        rc = cli(
            [
                "render",
                "rope.toml",
                "-o",
                str(out),
                "--duration",
                "0.1",
                "--fps",
                "10",
                "--size",
                "96x96",
                "--no-progress",
                *flag,
            ]
        )
        assert rc == 0
        frames[bool(flag)] = np.asarray(Image.open(out / "frame_00000.png"), dtype=int)
    # the rope runs up the middle of the image from the ball (below the centre) to its anchor (above)
    column = np.abs(frames[True] - frames[False]).max(axis=2)[:, 44:52]
    assert (column.max(axis=1) > 40).sum() >= 10  # ten or more rows of the rope


def test_camera_options_leave_the_scene_camera_as_it_was(make_falling_world):
    """camera_for: options override the [camera] table for this camera only; the world's metadata is unchanged."""
    import argparse

    from tumble.commands.render import camera_for

    world = make_falling_world()
    world.metadata["camera"] = {"position": [1.0, -4.0, 2.0], "target": [0.0, 0.0, 0.5], "fov": 30}
    before = dict(world.metadata["camera"])
    args = argparse.Namespace(camera_position=None, camera_target=(0.0, 0.0, 1.0), fov=None)
    cam = camera_for(world, args, 4 / 3)
    np.testing.assert_allclose(cam.position, [1.0, -4.0, 2.0])
    np.testing.assert_allclose(cam.target, [0.0, 0.0, 1.0])
    assert cam.fov_deg == 30
    assert world.metadata["camera"] == before
    bare = make_falling_world()  # no [camera]: framed automatically, and no [camera] is left behind
    camera_for(bare, argparse.Namespace(camera_position=None, camera_target=None, fov=45.0), 1.0)
    assert "camera" not in bare.metadata


@pytest.mark.parametrize(
    "option, value, fragment",
    [("--camera-position", "1,2", "expected three numbers x,y,z"), ("--fps", "fast", "--fps")],
)
def test_bad_option_values_exit_2_with_one_line(tmp_path, cli, scene, capsys, option, value, fragment):
    """A malformed option value: argparse's exit 2, one line naming it, nothing loaded."""
    with pytest.raises(SystemExit) as exit_:
        cli(["render", "s.toml", "-o", str(tmp_path / "x.mp4"), option, value])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tumble render: error:") and fragment in err[0]
    assert scene == []


def test_a_render_beyond_the_frame_limit_is_refused_before_its_first_frame(tmp_path, cli, scene, capsys):
    """More frames than limits.MAX_FRAMES: exit 2, one line giving the count and the limit, no file."""
    from tumble import limits

    fps = 1000.0
    duration = (limits.MAX_FRAMES + 10) / fps
    rc = cli(["render", "s.toml", "-o", str(tmp_path / "x.mp4"), "--duration", str(duration), "--fps", str(fps)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert err[0].startswith("tumble render: error: --duration")  # (1,000,010 frames, 120,001 steps: under MAX_STEPS)
    assert f"is {limits.MAX_FRAMES + 10:,} frames; the limit is {limits.MAX_FRAMES:,} frames" in err[0]
    assert not (tmp_path / "x.mp4").exists()
    assert scene[0].time == 0.0  # loaded, never stepped


@pytest.mark.parametrize(
    "option, value",
    [("--duration", "nan"), ("--duration", "-1"), ("--duration", "inf"), ("--fps", "nan"), ("--fps", "0")],
)
def test_a_duration_or_rate_that_is_not_a_positive_number_is_refused_first(tmp_path, cli, scene, capsys, option, value):
    """--duration nan was reported as "nan steps" against the step limit, and -1 as "duration"
    without its dashes, after loading the scene: now one line naming the option, before loading."""
    rc = cli(["render", "s.toml", "-o", str(tmp_path / "x.mp4"), option, value])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert err[0].startswith(f"tumble render: error: {option} must be a positive number, got "), err
    assert scene == [] and list(tmp_path.iterdir()) == []
