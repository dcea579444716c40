"""`tumble export SCENE.toml|RECORDING.npz -o shot.usd`: write a USD stage for Blender, Houdini, usdview."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import add_precision_argument

HELP = "simulate a scene (or convert a recording .npz) and write a USD stage (.usd, .usda, .usdc, .usdz)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("source", metavar="SOURCE", help="scene file (.toml), bundled sample name, or recording (.npz)")
    parser.add_argument(
        "-o", "--output", required=True, metavar="OUT", help="stage to write: .usd, .usda, .usdc or .usdz"
    )
    parser.add_argument(
        "--fps",
        type=float,
        default=None,
        metavar="F",
        help="frames per second (default 60 for a scene, the recorded rate for a recording)",
    )
    length = parser.add_mutually_exclusive_group()
    length.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="seconds to export (default 2; all of a recording)",
    )
    length.add_argument("--frames", type=int, default=None, metavar="N", help="number of frames, instead of --duration")
    parser.add_argument(
        "--bodies",
        choices=("instancer", "xforms"),
        default="instancer",
        help="instancer: one PointInstancer (default); xforms: one animated Xform per body",
    )
    parser.add_argument(
        "--physics",
        action="store_true",
        help="also write UsdPhysics schemas (scene, colliders, rigid bodies, masses, materials)",
    )
    parser.add_argument("--seed", type=int, default=None, metavar="N", help="replace the scene's [world] seed")
    parser.add_argument("--no-progress", action="store_true", help="do not show the progress bars")
    add_precision_argument(parser)


def main(args: argparse.Namespace) -> int:
    from ..io import usd

    # cheap checks first, before any simulating: pxr, the output's suffix and folder
    usd.require_pxr()
    usd.check_output(args.output)
    source = args.source
    if Path(source).suffix == ".npz":
        for option, value in (("--seed", args.seed), ("--precision", args.precision)):
            if value is not None:
                raise ValueError(f"{option} applies to scenes, not to recordings")
    else:
        from ..io.scene import load_scene

        source = load_scene(source, seed=args.seed, precision=args.precision)
    out = usd.export(
        source,
        args.output,
        fps=args.fps,
        duration=args.duration,
        frames=args.frames,
        bodies=args.bodies,
        physics=args.physics,
        progress=not args.no_progress,
    )
    print(f"wrote {out}", file=sys.stderr)
    return 0
