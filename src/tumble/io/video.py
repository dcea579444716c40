"""Headless export: render a `World` over simulated time to images, an MP4, a GIF or PNG frames.

Uses the same `tumble.render.Renderer` as the viewer, on an EGL context (no display needed)::

    from tumble.io.video import export, render_frames

    export(world, "drop.mp4", duration=2.0, fps=30, size=(1280, 720))
    for image in render_frames(world, duration=1.0, fps=10, size=(320, 240)):
        ...  # np.ndarray (240, 320, 3) uint8

Frame k shows the world at simulated time t0 + k / fps (t0 = the world's time when export
starts); between frames the world steps at its own `dt`. `duration * fps` frames are made.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Self

import numpy as np

from .. import validate
from ..progress import progress_bar

#: output kinds `export` understands, by suffix (no suffix or an existing folder: PNG frames)
FORMATS = {".mp4": "mp4", ".gif": "gif"}


def output_kind(out) -> str:
    """ "mp4", "gif" or "png" (a folder of numbered PNG frames) for an output path.

    Raises:
        ValueError: for any other suffix, naming the ones supported.
    """
    path = Path(out)
    if path.is_dir() or path.suffix == "" or str(out).endswith(os.sep):
        return "png"
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise ValueError(
            f"cannot write {str(out)!r}: the output must end in .mp4 or .gif, or be a folder for PNG frames"
        )
    return kind


def frame_count(duration: float, fps: float) -> int:
    """Number of frames for `duration` seconds at `fps` (at least 1)."""
    duration, fps = validate.positive(duration, "duration"), validate.positive(fps, "fps")
    return max(1, int(round(duration * fps)))


def parse_size(size) -> tuple[int, int]:
    """(width, height) from "1280x720" or a pair of positive integers (`tumble.validate.image_size`)."""
    return validate.image_size(size)


def render_frames(
    world,
    *,
    duration: float,
    fps: float = 30,
    size: Sequence[int] | str = (1280, 720),
    camera=None,
    renderer=None,
    dither: bool = True,
    joints: bool | None = None,
) -> Iterator[np.ndarray]:
    """Step `world` and yield one RGB image (height, width, 3) uint8 every 1/fps simulated seconds.

    Args:
        world: the World to simulate (it is advanced in place).
        duration: simulated seconds to cover; `round(duration * fps)` frames are yielded.
        fps: frames per simulated second.
        size: (width, height) in pixels, or "WxH".
        camera: a `tumble.render.Camera`; default the scene's `[camera]`, else automatic framing
            of the first frame (kept fixed afterwards, so the view does not jump).
        renderer: a `tumble.render.Renderer` to reuse (its size is set to `size`); default a new
            one on a new headless context, 4x multisampled (smooth edges, ~1.3-1.8x the time).
        dither: add the renderer's +-1/255 output noise (no banding); GIFs leave it off.
        joints: draw the joints (`renderer.show_joints`) for these frames; None keeps the renderer's setting.

    Raises:
        TumbleError: no OpenGL context could be made.
    """
    from ..render import Camera, Renderer, create_context

    n = frame_count(duration, fps)
    width, height = parse_size(size)
    own = renderer is None
    if own:
        renderer = Renderer(create_context(), width, height, samples=4)
    else:
        renderer.resize(width, height)
    if camera is None:
        camera = Camera.for_world(world, aspect=width / height)
    elif isinstance(camera, dict):
        camera = Camera.from_dict(camera)
    start = float(world.time)
    dt = float(world.dt)
    dither_before, renderer.dither = renderer.dither, bool(dither)
    joints_before = renderer.show_joints
    if joints is not None:
        renderer.show_joints = bool(joints)
    try:
        for k in range(n):
            # step until the world reaches this frame's time (within half a step)
            target = start + k / float(fps)
            while world.time < target - 0.5 * dt:
                world.step()
            world.check_finite()  # (a step checks the state it starts from, not the one it leaves)
            yield renderer.render(world, camera)
    finally:
        renderer.dither = dither_before
        renderer.show_joints = joints_before
        if own:  # the context made here goes with the renderer
            ctx = renderer.ctx
            renderer.release()
            ctx.release()


def export(
    world,
    out,
    *,
    duration: float,
    fps: float = 30,
    size: Sequence[int] | str = (1280, 720),
    camera=None,
    progress: bool = True,
    renderer=None,
    joints: bool | None = None,
) -> Path:
    """Render `world` over `duration` simulated seconds into `out` and return its path.

    The kind of output follows `out`: `.mp4` (H.264 through imageio-ffmpeg), `.gif` (Pillow,
    looping), or a folder (an existing one, or a path with no suffix) of `frame_00000.png`, ...

    Args:
        world, duration, fps, size, camera, renderer, joints: as for `render_frames`.
        progress: show a progress bar on stderr (frames done, estimated time left).

    The output is checked before the first frame and written beside `out`, then renamed into
    place when complete (`tumble.io.atomic`): a failure leaves an existing `out` as it was.

    Raises:
        ValueError: an unsupported suffix, or bad duration / fps / size.
        OutputError: `out` cannot be written (checked first), or writing it failed.
        TumbleError: no OpenGL context could be made.
    """
    from .atomic import atomic_folder, atomic_path, check_output

    out = Path(out)
    kind = output_kind(out)
    n = frame_count(duration, fps)
    width, height = parse_size(size)
    # the output is checked before the first frame is simulated (OutputError names it)
    check_output(out, suffixes=tuple(FORMATS), folder=kind == "png", option="")
    if kind == "gif":
        gif_delays_ms(n, fps)  # (refuses a rate a GIF cannot play before rendering anything)
    elif kind == "mp4" and fps < MP4_MIN_FPS:
        raise ValueError(
            f"an MP4 frame lasts at most {1.0 / MP4_MIN_FPS:,.0f} s (ffmpeg refuses slower rates), got --fps {fps:g} "
            f"(a frame every {1.0 / fps:g} s); use a higher fps or a folder of PNG frames"
        )
    frames = render_frames(
        world,
        duration=duration,
        fps=fps,
        size=(width, height),
        camera=camera,
        renderer=renderer,
        dither=kind != "gif",
        joints=joints,
    )
    label = f"rendering {out.name or out}"

    # every kind is written beside `out` and renamed into place when complete (tumble.io.atomic)
    with progress_bar(n, label, enabled=progress) as advance:
        if kind == "png":
            from PIL import Image

            with atomic_folder(out) as tmp:
                for k, image in enumerate(frames):
                    Image.fromarray(image).save(tmp / f"frame_{k:05d}.png")
                    advance()
        elif kind == "mp4":
            with atomic_path(out) as tmp, FfmpegWriter(tmp, (width, height), fps) as writer:
                for image in frames:
                    writer.append(image)
                    advance()
        else:  # gif
            from PIL import Image

            images = []
            for image in frames:
                images.append(
                    Image.fromarray(image).quantize(
                        colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE
                    )
                )
                advance()
            with atomic_path(out) as tmp:
                images[0].save(
                    tmp,
                    format="GIF",
                    save_all=True,
                    append_images=images[1:],
                    duration=gif_delays_ms(len(images), fps),
                    loop=0,
                    optimize=False,
                    disposal=1,
                )
    return out


#: the slowest frame rate written to an MP4: ffmpeg's muxer fails on time bases finer than about
#: 1/100,000 s (measured with imageio-ffmpeg's ffmpeg: 1e-5 fps writes, 5e-6 fails)
MP4_MIN_FPS = 1e-5
#: the fastest frame rate a GIF plays: browsers slow delays under 2/100 s down to 1/10 s
GIF_MAX_FPS = 50.0
#: the longest delay a GIF frame can have [1/100 s]: the format stores it in 16 bits
GIF_MAX_DELAY_CS = 65535


def gif_delays_ms(n: int, fps: float) -> list[int]:
    """Per-frame GIF delays [ms] (whole hundredths of a second) that keep time at `fps`.

    A GIF stores each delay in centiseconds, so 30 fps (33.3 ms) cannot be one delay: frame k
    lasts round(100 (k + 1) / fps) - round(100 k / fps) cs (3, 3, 4, 3, 3, 4, ... at 30 fps),
    and frame k starts within 5 ms of k / fps; the n frames last round(100 n / fps) cs in all.

    Raises:
        ValueError: `fps` above `GIF_MAX_FPS` (delays under 2 cs are not honoured by viewers).
    """
    fps = float(fps)
    if fps > GIF_MAX_FPS:
        raise ValueError(
            f"a GIF plays at most {GIF_MAX_FPS:g} frames per second, got --fps {fps:g}; use a lower fps or an .mp4"
        )
    ends = np.round(100.0 * np.arange(n + 1) / fps).astype(np.int64)
    delays = np.diff(ends)
    if delays.size and delays.max() > GIF_MAX_DELAY_CS:
        raise ValueError(
            f"a GIF frame lasts at most {GIF_MAX_DELAY_CS / 100:g} s (a 16-bit delay in 1/100 s), "
            f"got --fps {fps:g} (a frame every {1.0 / fps:g} s); use a higher fps or an .mp4"
        )
    return [int(10 * d) for d in delays]


class FfmpegWriter:
    """H.264 MP4 through the ffmpeg binary of imageio-ffmpeg, its output summarized in one line.

    Frames go to ffmpeg's stdin as raw RGB; ffmpeg's own messages go to a temporary file, not
    to the terminal, and a failure (ffmpeg missing, exiting early, a full disk) raises
    OSError with ffmpeg's last message as one line (`atomic_path` names the target). The encoding matches imageio's
    `quality=8` (CRF 10), yuv420p, odd sizes scaled up to even ones.

    Args:
        path: the .mp4 file to write (a temporary path from `atomic_path`).
        size: (width, height) of every frame in pixels.
        fps: frames per second of the video.
    """

    def __init__(self, path, size: tuple[int, int], fps: float):
        import subprocess
        import tempfile
        from fractions import Fraction

        import imageio_ffmpeg

        self.path = Path(path)
        self.size = (int(size[0]), int(size[1]))
        w, h = self.size
        try:
            exe = imageio_ffmpeg.get_ffmpeg_exe()
        except RuntimeError as exc:
            raise OSError(f"no ffmpeg binary found ({exc}); install it with: pip install imageio-ffmpeg") from None
        cmd = [
            exe,
            "-y",
            "-v",
            "error",
            "-f",
            "rawvideo",
            "-vcodec",
            "rawvideo",
            "-s",
            f"{w}x{h}",
            "-pix_fmt",
            "rgb24",
            "-r",
            str(Fraction(float(fps)).limit_denominator()),
            "-i",
            "-",
            "-an",
            "-vcodec",
            "libx264",
            "-pix_fmt",
            "yuv420p",
            "-crf",
            "10",
        ]
        if w % 2 or h % 2:
            cmd += ["-vf", f"scale={w + w % 2}:{h + h % 2}"]
        cmd += ["-f", "mp4", str(self.path)]
        self._log = tempfile.TemporaryFile()  # noqa: SIM115 (open while ffmpeg runs; closed in close/__exit__)
        try:
            self._process = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=self._log)
        except OSError as exc:
            self._log.close()
            raise self._error(f"cannot start ffmpeg ({exc.strerror or exc})") from None

    def append(self, image: np.ndarray) -> None:
        """Encode one frame, shape (height, width, 3) uint8."""
        w, h = self.size
        if image.shape != (h, w, 3):
            raise ValueError(f"frame of shape {image.shape}, expected {(h, w, 3)}")
        assert self._process.stdin is not None  # opened with stdin=PIPE
        try:
            self._process.stdin.write(np.ascontiguousarray(image, dtype=np.uint8).tobytes())
        except (BrokenPipeError, OSError):
            self._process.wait()
            raise self._error(self._summary()) from None

    def close(self) -> None:
        """Finish the file; raises OSError if ffmpeg failed."""
        assert self._process.stdin is not None  # opened with stdin=PIPE
        try:
            self._process.stdin.close()
        except OSError:
            pass
        code = self._process.wait()
        summary = self._summary() if code else ""
        self._log.close()
        if code:
            raise self._error(summary)

    def _summary(self) -> str:
        """ffmpeg's last message, one line."""
        self._log.seek(0)
        lines = [line.strip() for line in self._log.read().decode(errors="replace").splitlines() if line.strip()]
        code = self._process.poll()
        why = lines[-1] if lines else "no message"
        if code is not None and code < 0:
            import signal

            name = signal.Signals(-code).name
            hint = {"SIGXFSZ": ": the file size limit was reached"}.get(name, "")
            return f"ffmpeg was killed by {name}{hint}" + (f" ({why})" if lines else "")
        return f"ffmpeg failed (exit status {code}): {why}" if code else f"ffmpeg stopped reading frames: {why}"

    def _error(self, message: str) -> OSError:
        # an OSError: `atomic_path` reports it as "cannot write OUT: <message>", naming the target
        return OSError(message)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, kind, exc, tb) -> None:
        if exc is None:
            self.close()
            return
        # the block failed: stop ffmpeg without waiting for it to finish the file
        if self._process.poll() is None:
            self._process.kill()
        self._process.wait()
        self._log.close()
