"""`tumble render` and `tumble plot` from the command line (in process)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import tumble
import tumble.cli


@pytest.fixture
def cli(monkeypatch):
    """tumble.cli.main limited to this part's commands (the others are built elsewhere)."""
    monkeypatch.setattr(tumble.cli, "COMMANDS", {"render": "render", "plot": "plot"})
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


def test_plot_command_writes_png(tmp_path, cli):
    """tumble plot RECORD.npz -o OUT.png writes a PNG."""
    t = np.linspace(0.0, 1.0, 11)
    np.savez(
        tmp_path / "r.npz",
        time=t,
        position=np.zeros((11, 1, 3)),
        velocity=np.zeros((11, 1, 3)),
        mass=np.ones(1),
        gravity=np.array([0, 0, -9.81]),
        contact_count=np.zeros(11),
    )
    rc = cli(["plot", str(tmp_path / "r.npz"), "-o", str(tmp_path / "p.png")])
    assert rc == 0
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_command_missing_file_exits_2(tmp_path, cli, capsys):
    """A missing recording: exit status 2 and the path in the message."""
    rc = cli(["plot", str(tmp_path / "nope.npz"), "-o", str(tmp_path / "p.png")])
    assert rc == 2
    assert "nope.npz" in capsys.readouterr().err


SAMPLES = Path(__file__).resolve().parents[2] / "samples"


def test_render_a_sample_scene_file(tmp_path, monkeypatch):
    """tumble render on a real sample file writes a GIF with the scene's camera."""
    from PIL import Image

    monkeypatch.setattr(tumble.cli, "COMMANDS", {"render": "render"})
    out = tmp_path / "ball.gif"
    rc = tumble.cli.main(
        [
            "render",
            str(SAMPLES / "bouncing_ball.toml"),
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


def test_run_record_then_plot(tmp_path, monkeypatch):
    """A recording from tumble run --record plots with every body panel filled in."""
    from tumble.io.plot import build_figure
    from tumble.io.record import load_recording

    monkeypatch.setattr(tumble.cli, "COMMANDS", {"run": "run", "plot": "plot"})
    record = tmp_path / "ball.npz"
    assert (
        tumble.cli.main(
            ["run", str(SAMPLES / "bouncing_ball.toml"), "--duration", "0.25", "--record", str(record), "--fps", "20"]
        )
        == 0
    )
    assert tumble.cli.main(["plot", str(record), "-o", str(tmp_path / "ball.png")]) == 0
    fig = build_figure(load_recording(record))
    titles = [ax.get_title(loc="left") for ax in fig.axes]
    assert titles == ["Kinetic energy", "Potential energy", "Linear momentum", "Contact count"]


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
