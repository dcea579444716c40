"""`tumble render SCENE -o OUT`: simulate a scene headless and write an MP4, a GIF or PNG frames."""

from __future__ import annotations

import argparse

from . import add_precision_argument

HELP = "render a scene to an MP4, a GIF or a folder of PNG frames, without a display"


def _triple(text: str) -> tuple[float, float, float]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected three numbers x,y,z, got {text!r}")
    return values


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from .run import SCENE_HELP

    parser.add_argument("scene", metavar="SCENE", help=SCENE_HELP)
    parser.add_argument(
        "-o",
        "--output",
        required=True,
        metavar="OUT",
        help="output: NAME.mp4, NAME.gif, or a folder for numbered PNG frames (checked before "
        "rendering, written atomically)",
    )
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="simulated seconds to render (default 5)",
    )
    parser.add_argument("--fps", type=float, default=30.0, metavar="F", help="frames per simulated second (default 30)")
    parser.add_argument("--size", default="1280x720", metavar="WxH", help="image size in pixels (default 1280x720)")
    parser.add_argument("--camera-position", type=_triple, metavar="X,Y,Z", help="camera position [m]")
    parser.add_argument("--camera-target", type=_triple, metavar="X,Y,Z", help="point the camera looks at [m]")
    parser.add_argument("--fov", type=float, metavar="DEG", help="vertical field of view [degrees]")
    parser.add_argument(
        "--joints",
        action="store_true",
        help="draw the joints: rods from each body's centre to its anchors, a dot on each anchor",
    )
    parser.add_argument("--no-progress", action="store_true", help="do not show the progress bar")
    add_precision_argument(parser)


def camera_for(world, args, aspect: float):
    """The camera: command-line values over the scene's `[camera]` table over automatic framing."""
    from ..render import Camera

    spec = dict(world.metadata.get("camera") or {})
    if args.camera_position is not None:
        spec["position"] = args.camera_position
    if args.camera_target is not None:
        spec["target"] = args.camera_target
    if args.fov is not None:
        spec["fov"] = args.fov
    saved = world.metadata.get("camera")
    world.metadata["camera"] = spec
    try:
        return Camera.for_world(world, aspect=aspect)
    finally:
        if saved is None:
            world.metadata.pop("camera", None)
        else:
            world.metadata["camera"] = saved


def _check_limits(args, world, duration: float, kind: str, width: int, height: int) -> None:
    """Refuse a render beyond the limits (docs/scenes.md#limits) before its first frame."""
    from .. import limits
    from ..io.video import frame_count

    limits.check_steps("--duration", duration, world.dt)
    n = frame_count(duration, args.fps)
    if n > limits.MAX_FRAMES:
        raise limits.LimitError(
            f"--duration {duration:g} s at --fps {args.fps:g} is {n:,} frames; "
            f"the limit is {limits.MAX_FRAMES:,} frames"
        )
    if kind == "gif":  # a GIF is assembled in memory: one byte per pixel per frame, and as much again
        try:
            limits.check_memory("--duration", "GIF frames", n, 2 * width * height)
        except limits.LimitError as exc:
            raise limits.LimitError(
                f"{exc} at {width}x{height}; lower --duration, --fps or --size, or write an .mp4"
            ) from None


def main(args: argparse.Namespace) -> int:
    import sys

    import tumble

    from .. import validate
    from ..io.atomic import check_output
    from ..io.video import FORMATS, export, output_kind, parse_size
    from ..render import Renderer, create_context
    from ..runtime import prepare_kernels

    # cheap checks first: the output kind and folder, the size, then an OpenGL context (TumbleError -> exit 2)
    kind = output_kind(args.output)
    duration = validate.positive(args.duration if args.duration is not None else 5.0, "--duration")
    validate.positive(args.fps, "--fps")
    check_output(args.output, suffixes=tuple(FORMATS), folder=kind == "png", option="-o")
    width, height = parse_size(args.size)
    ctx = create_context()
    renderer = Renderer(ctx, width, height, samples=4)
    try:
        world = tumble.load_scene(args.scene, precision=args.precision)
        prepare_kernels(world.device, report=lambda line: print(line, file=sys.stderr, flush=True))
        _check_limits(args, world, duration, kind, width, height)
        camera = camera_for(world, args, width / height)
        out = export(
            world,
            args.output,
            duration=duration,
            fps=args.fps,
            size=(width, height),
            camera=camera,
            progress=not args.no_progress,
            renderer=renderer,
            joints=args.joints,
        )
    finally:
        renderer.release()
        ctx.release()
    print(f"wrote {out}", file=sys.stderr)
    return 0
