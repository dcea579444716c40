"""Screenshots (PNG) and video recording (MP4, H.264 through imageio-ffmpeg) of the view."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..io.video import FfmpegWriter


def output_path(directory, stem: str, suffix: str) -> Path:
    """A new file name in `directory`: `<stem>-<date>-<time><suffix>`, never overwriting a file."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    base = f"{stem}-{time.strftime('%Y%m%d-%H%M%S')}"
    path = directory / f"{base}{suffix}"
    n = 1
    while path.exists():
        path = directory / f"{base}-{n}{suffix}"
        n += 1
    return path


def save_png(pixels: np.ndarray, path) -> Path:
    """Write (H, W, 3) uint8 pixels to a PNG file. Returns the path."""
    import imageio.v3 as iio

    from ..io.atomic import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:  # written beside, renamed into place (tumble.io.atomic)
        iio.imwrite(tmp, np.ascontiguousarray(pixels, dtype=np.uint8), extension=".png")
    return path


class VideoRecorder:
    """Writes frames to an MP4 file as they come; every frame is fitted to the first one's size.

    Args:
        path: the .mp4 file to write.
        fps: frames per second of the video (frames are taken every 1/fps of simulated time).
    """

    def __init__(self, path, *, fps: float = 30.0):
        self.path = Path(path)
        self.fps = float(fps)
        self.frame_count = 0
        self._writer: FfmpegWriter | None = None
        self._shape: tuple[int, int] | None = None

    def add(self, pixels: np.ndarray) -> None:
        """Append one (H, W, 3) uint8 frame."""
        pixels = np.asarray(pixels, dtype=np.uint8)
        if self._writer is None:
            from ..io.atomic import AtomicFile
            from ..io.video import FfmpegWriter

            # even width and height, as H.264 in yuv420p needs
            h, w = pixels.shape[0] // 2 * 2, pixels.shape[1] // 2 * 2
            self._shape = (h, w)
            # written beside the target and renamed into place on close (tumble.io.atomic)
            self._file = AtomicFile(self.path)
            try:
                self._writer = FfmpegWriter(self._file.tmp, (w, h), self.fps)
            except BaseException:
                self._file.discard()
                raise
        assert self._shape is not None  # set with the writer
        h, w = self._shape
        frame = np.zeros((h, w, 3), dtype=np.uint8)
        ph, pw = min(h, pixels.shape[0]), min(w, pixels.shape[1])
        frame[:ph, :pw] = pixels[:ph, :pw, :3]
        try:
            self._writer.append(frame)
        except BaseException:
            self._abandon()
            raise
        self.frame_count += 1

    def close(self) -> Path | None:
        """Finish the file. Returns its path, or None when no frame was written."""
        if self._writer is None:
            return None
        writer, self._writer = self._writer, None
        try:
            writer.close()
        except BaseException:
            self._file.discard()
            raise
        return self._file.commit()

    def _abandon(self) -> None:
        """Stop ffmpeg and remove the partial file (an existing `path` stays as it was)."""
        writer, self._writer = self._writer, None
        assert writer is not None  # abandoned only while writing
        writer.__exit__(RuntimeError, RuntimeError("abandoned"), None)
        self._file.discard()
