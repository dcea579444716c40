"""`tumble wedge SCENE --vary KEY=VALUES ... -o OUTDIR`: run a scene over a grid of values, in parallel."""

from __future__ import annotations

import argparse
import sys

HELP = "run a scene over every combination of varied values (a wedge), on local cores or a Dask cluster"


def _keep(text: str) -> list[str]:
    return [k.strip() for k in text.split(",") if k.strip()]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..wedge import CONNECT_TIMEOUT, KEEP, MAX_VARIANTS

    parser.add_argument("scene", help="scene file (.toml) or the name of a bundled sample")
    parser.add_argument(
        "--vary",
        action="append",
        default=[],
        metavar="KEY=VALUES",
        required=True,
        help="a key path and its values: plane[0].friction=0.2,0.5,0.8 | emitter[0].rate=100:900:5 "
        "| world.seed=0..99 (repeat for a grid; the last varies fastest)",
    )
    parser.add_argument(
        "-o", "--output", required=True, metavar="OUTDIR", help="output folder (resumed when it exists)"
    )
    parser.add_argument(
        "--duration", type=float, default=2.0, metavar="S", help="simulated seconds per variant (default 2)"
    )
    parser.add_argument(
        "--fps",
        type=float,
        default=30.0,
        metavar="F",
        help="frames per simulated second of recordings and videos (default 30; recordings take at most one a step)",
    )
    parser.add_argument(
        "--keep",
        type=_keep,
        action="append",
        default=[],
        metavar="WHAT",
        help=f"files to keep per variant, comma-separated: {', '.join(KEEP)}",
    )
    parser.add_argument(
        "--address",
        default=None,
        metavar="ADDR",
        help="join an existing Dask cluster (tcp://host:8786, or a scheduler file .json) "
        "instead of starting one on this machine",
    )
    parser.add_argument(
        "--connect-timeout",
        type=float,
        default=CONNECT_TIMEOUT,
        metavar="S",
        help=f"seconds to wait for the scheduler at --address (default {CONNECT_TIMEOUT:g})",
    )
    parser.add_argument(
        "--retry-failed",
        action="store_true",
        help="run again the variants that failed before (resuming skips them otherwise)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="worker processes of the local cluster (default: one per core; at most one per variant)",
    )
    parser.add_argument("--size", default="320x180", metavar="WxH", help="size of each final frame (default 320x180)")
    parser.add_argument("--yes", action="store_true", help=f"run more than {MAX_VARIANTS:,} variants")
    parser.add_argument("--device", choices=("cpu", "cuda"), default="cpu", help="the Warp device (default cpu)")
    parser.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress display (on a terminal a bar, elsewhere one line per variant)",
    )


def main(args: argparse.Namespace) -> int:
    from ..io.video import parse_size
    from ..wedge import WedgeError, parse_vary, wedge

    if args.workers is not None and args.workers < 1:
        raise WedgeError(f"--workers must be at least 1, got {args.workers}")
    vary = [parse_vary(spec) for spec in args.vary]
    table = wedge(
        args.scene,
        vary,
        out=args.output,
        duration=args.duration,
        fps=args.fps,
        keep=[k for group in args.keep for k in group],
        address=args.address,
        workers=args.workers,
        yes=args.yes,
        image_size=parse_size(args.size),
        device=args.device,
        progress=not args.no_progress,
        retry_failed=args.retry_failed,
        connect_timeout=args.connect_timeout,
    )
    failed = table.failed
    print(
        f"{len(table)} variants, {len(table) - len(failed)} ok, {len(failed)} failed; "
        f"manifest in {table.out / 'manifest.csv'}"
    )
    for row in failed[:10]:
        print(f"  failed {row['variant']}: {row.get('error')}", file=sys.stderr)
    return 1 if failed else 0
