"""`tumble view SCENE`: open a scene in the interactive viewer window."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .. import validate
from . import add_precision_argument

HELP = "open a scene in the interactive viewer (orbit, play, tune parameters live, record)"


def parse_size(text: str) -> tuple[int, int]:
    """Parse "WxH" (e.g. "1280x720") into (width, height) in pixels, at least 16 a side, for argparse."""
    try:
        return validate.image_size(text, low=16)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from .run import SCENE_HELP

    parser.add_argument("scene", metavar="SCENE", help=SCENE_HELP)
    parser.add_argument("--paused", action="store_true", help="start paused (space plays)")
    parser.add_argument(
        "--size",
        type=parse_size,
        default=(1280, 720),
        metavar="WxH",
        help="size of the 3D view in pixels (default 1280x720)",
    )
    parser.add_argument(
        "--view",
        choices=("auto", "gl", "image"),
        default="auto",
        help="auto: an OpenGL window where possible, else offscreen rendering shown as "
        "an image; gl or image to force one",
    )
    parser.add_argument(
        "--out-dir", default=".", metavar="DIR", help="folder for screenshots and videos (default: the current folder)"
    )
    add_precision_argument(parser)


def main(args: argparse.Namespace) -> int:
    import tumble

    from ..io.atomic import check_folder

    check_folder(args.out_dir, option="--out-dir")
    scene = args.scene
    # load once before opening any window, so that a missing or broken scene is one line on
    # stderr (from the CLI), not a window that opens and fails
    world = tumble.load_scene(scene, precision=args.precision)
    # compile any kernel not yet cached now, saying so, rather than in the window's first step
    from ..runtime import prepare_kernels

    prepare_kernels(world.device, report=lambda line: print(line, file=sys.stderr, flush=True))

    from tumble.viewer import run_viewer

    return run_viewer(
        world,
        factory=lambda: tumble.load_scene(scene, precision=args.precision),
        title=Path(scene).stem,
        size=args.size,
        paused=args.paused,
        view=args.view,
        output_dir=args.out_dir,
    )
