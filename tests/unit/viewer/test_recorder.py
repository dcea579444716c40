"""The viewer's screenshots and videos (tumble.viewer.recorder): new names that never overwrite, PNGs and
MP4s written atomically, frames fitted to the first one's even size."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from tumble.viewer.recorder import VideoRecorder, output_path, save_png


def _leftovers(folder: Path) -> list[str]:
    return [p.name for p in folder.iterdir() if ".tmp" in p.name or p.name.startswith(".tumble-probe")]


def test_viewer_screenshots_and_videos_are_written_atomically(tmp_path):
    """The viewer's PNG and MP4 land whole: nothing at the target until the video is closed."""
    pixels = np.zeros((49, 65, 3), dtype=np.uint8)
    pixels[10:20, 10:30] = 255
    shot = save_png(pixels, tmp_path / "shot.png")
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    video = VideoRecorder(tmp_path / "clip.mp4", fps=30)
    for k in range(10):
        video.add(np.roll(pixels, k, axis=1))
    assert not (tmp_path / "clip.mp4").exists()  # still being written beside it
    assert video.close() == tmp_path / "clip.mp4"
    data = (tmp_path / "clip.mp4").read_bytes()
    assert data[4:8] == b"ftyp" and video.frame_count == 10
    assert _leftovers(tmp_path) == []


def test_output_paths_are_dated_and_never_overwrite(tmp_path, monkeypatch):
    """<stem>-<YYYYmmdd>-<HHMMSS><suffix> in a folder it makes; a name taken gets -1, then -2."""
    import tumble.viewer.recorder as recorder

    folder = tmp_path / "shots" / "today"
    dated = output_path(folder, "ball", ".png")
    assert folder.is_dir() and dated.parent == folder and not dated.exists()
    assert re.fullmatch(r"ball-\d{8}-\d{6}\.png", dated.name)
    monkeypatch.setattr(recorder.time, "strftime", lambda fmt: "20261202-154500")  # one second, three files
    names = []
    for _ in range(3):
        path = output_path(folder, "ball", ".png")
        path.write_bytes(b"x")
        names.append(path.name)
    assert names == ["ball-20261202-154500.png", "ball-20261202-154500-1.png", "ball-20261202-154500-2.png"]


def test_a_png_reads_back_pixel_for_pixel(tmp_path):
    """save_png writes the (H, W, 3) pixels losslessly."""
    import imageio.v3 as iio

    pixels = np.random.default_rng(1).integers(0, 256, size=(9, 14, 3), dtype=np.uint8)
    path = save_png(pixels, tmp_path / "shot.png")
    np.testing.assert_array_equal(iio.imread(path)[..., :3], pixels)


def test_frames_are_fitted_to_the_first_frames_even_size(tmp_path):
    """A 49 x 65 first frame makes a 48 x 64 video; later larger or smaller frames are cropped or padded to it."""
    import imageio.v3 as iio

    video = VideoRecorder(tmp_path / "clip.mp4", fps=10)
    video.add(np.full((49, 65, 3), 200, dtype=np.uint8))
    video.add(np.full((80, 90, 3), 200, dtype=np.uint8))
    video.add(np.full((20, 30, 3), 200, dtype=np.uint8))
    assert video.close() == tmp_path / "clip.mp4" and video.frame_count == 3
    frames = np.stack(list(iio.imiter(tmp_path / "clip.mp4")))
    assert frames.shape == (3, 48, 64, 3)
    # the small last frame is padded with black beyond its 20 x 30 corner
    assert frames[2, :16, :26].mean() > 150 and frames[2, 28:, 40:].mean() < 30


def test_closing_a_video_without_frames_writes_nothing(tmp_path):
    """No frame added: close() returns None and leaves no file."""
    video = VideoRecorder(tmp_path / "empty.mp4")
    assert video.close() is None
    assert list(tmp_path.iterdir()) == []
