"""Headless export: frames over simulated time, MP4, GIF and PNG folders."""

from __future__ import annotations

import numpy as np
import pytest

from tumble.io.video import MP4_MIN_FPS, export, frame_count, gif_delays_ms, output_kind, parse_size, render_frames
from tumble.render import Camera

CAMERA = Camera(position=(0.0, -3.0, 0.8), target=(0.0, 0.0, 0.4), fov_deg=45)


def _export(make_falling_world, renderer, path, *, progress=False, **options):
    """`export` of a new falling world through CAMERA with the shared renderer."""
    return export(make_falling_world(), path, camera=CAMERA, progress=progress, renderer=renderer, **options)


def test_frames_step_the_world_at_the_frame_rate(make_falling_world, renderer):
    """Frame k shows the world at time k / fps; frames are not blank and change as bodies fall."""
    world = make_falling_world()
    times, frames = [], []
    for image in render_frames(world, duration=0.25, fps=20, size=(96, 64), camera=CAMERA, renderer=renderer):
        times.append(world.time)
        frames.append(image)
    assert len(frames) == 5
    assert np.allclose(times, np.arange(5) / 20, atol=0.5 * world.dt)
    for image in frames:
        assert image.shape == (64, 96, 3)
        assert image.std() > 10  # not one flat colour
    diffs = [np.abs(a.astype(int) - b.astype(int)).sum() for a, b in zip(frames, frames[1:])]
    assert min(diffs) > 0


def test_mp4_has_n_frames_of_the_given_size(tmp_path, make_falling_world, renderer):
    """An MP4 of N frames at W x H reads back with N frames of W x H."""
    import imageio.v3 as iio

    out = _export(make_falling_world, renderer, tmp_path / "drop.mp4", duration=0.4, fps=15, size=(160, 120))
    frames = iio.imread(out)
    assert frames.shape == (6, 120, 160, 3)
    assert frames[0].std() > 10


def test_odd_sizes_are_kept_in_mp4(tmp_path, make_falling_world, renderer):
    """A 161 x 121 MP4 is padded to even size only, never to multiples of 16."""
    import imageio.v3 as iio

    out = _export(make_falling_world, renderer, tmp_path / "odd.mp4", duration=0.1, fps=20, size=(161, 121))
    frames = iio.imread(out)
    assert frames.shape[0] == 2
    assert frames.shape[1:3] in ((121, 161), (122, 162))


def test_same_scene_gives_identical_png_frames(tmp_path, make_falling_world):
    """Rendering one scene twice (each time a new context, multisampled) writes identical PNG frames."""
    a = export(make_falling_world(), tmp_path / "a", duration=0.3, fps=10, size=(96, 72), progress=False)
    b = export(make_falling_world(), tmp_path / "b", duration=0.3, fps=10, size=(96, 72), progress=False)
    names = sorted(p.name for p in a.iterdir())
    assert names == ["frame_00000.png", "frame_00001.png", "frame_00002.png"]
    assert names == sorted(p.name for p in b.iterdir())
    for name in names:
        assert (a / name).read_bytes() == (b / name).read_bytes()
    assert (a / names[0]).read_bytes() != (a / names[-1]).read_bytes()


def test_gif_and_png_folder_are_written(tmp_path, make_falling_world, renderer):
    """A .gif path gives a looping GIF; a path with no suffix gives a folder of PNGs."""
    from PIL import Image

    gif = _export(make_falling_world, renderer, tmp_path / "drop.gif", duration=0.3, fps=10, size=(80, 60))
    with Image.open(gif) as im:
        assert im.format == "GIF" and im.size == (80, 60)
        assert im.n_frames == 3
    folder = _export(make_falling_world, renderer, tmp_path / "frames", duration=0.2, fps=10, size=(80, 60))
    pngs = sorted(folder.glob("*.png"))
    assert len(pngs) == 2
    with Image.open(pngs[0]) as im:
        assert im.format == "PNG" and im.size == (80, 60)


def test_progress_bar_reports_frames(tmp_path, make_falling_world, renderer, capsys):
    """With progress on, the bar on stderr counts frames."""
    _export(make_falling_world, renderer, tmp_path / "p", duration=0.2, fps=10, size=(32, 24), progress=True)
    assert "2/2" in capsys.readouterr().err


def test_output_kinds_and_bad_arguments(tmp_path):
    """The suffix picks the format; unknown suffixes and bad numbers raise ValueError."""
    assert output_kind(tmp_path / "x.mp4") == "mp4"
    assert output_kind(tmp_path / "x.GIF") == "gif"
    assert output_kind(tmp_path / "frames") == "png"
    assert output_kind(tmp_path) == "png"
    with pytest.raises(ValueError, match=r"\.mp4 or \.gif"):
        output_kind(tmp_path / "x.avi")
    assert frame_count(2.0, 30) == 60
    with pytest.raises(ValueError, match="duration"):
        frame_count(0.0, 30)
    with pytest.raises(ValueError, match="fps"):
        frame_count(1.0, -1)
    assert parse_size("1280x720") == (1280, 720)
    with pytest.raises(ValueError, match="size"):
        parse_size("big")


def test_gif_refuses_a_frame_longer_than_its_16_bit_delay(tmp_path, make_falling_world):
    """A GIF stores each frame's delay in 16 bits of 1/100 s: --fps 0.001 (100,000 cs a frame)
    raises ValueError naming --fps before any frame is rendered, and writes nothing (it was an
    OverflowError from Pillow, an internal error, after rendering); the slowest rate that fits works."""
    out = tmp_path / "slow.gif"
    with pytest.raises(ValueError, match=r"at most 655\.35 s.*--fps 0\.001"):
        export(make_falling_world(), out, duration=0.1, fps=0.001, size=(16, 9), progress=False)
    assert list(tmp_path.iterdir()) == []
    assert gif_delays_ms(2, 100 / 65535) == [655350, 655350]


def test_mp4_refuses_a_rate_ffmpeg_cannot_mux_and_writes_the_slowest_it_can(tmp_path, make_falling_world):
    """--fps 1e-6 rendered every frame and then failed inside ffmpeg ("Invalid argument"); it is
    refused naming --fps before rendering, and the slowest rate allowed (MP4_MIN_FPS) writes a file."""
    out = tmp_path / "slow.mp4"
    with pytest.raises(ValueError, match=r"MP4 frame lasts at most 100,000 s.*--fps 1e-06"):
        export(make_falling_world(), out, duration=0.1, fps=1e-6, size=(16, 10), progress=False)
    assert list(tmp_path.iterdir()) == []
    export(make_falling_world(), out, duration=0.1, fps=MP4_MIN_FPS, size=(16, 10), progress=False)
    assert out.stat().st_size > 0
