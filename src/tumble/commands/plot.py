"""`tumble plot RECORD.npz -o OUT.png`: energy, momentum, contacts and cloth strain over time."""

from __future__ import annotations

import argparse

HELP = "plot energy, momentum, contact count and cloth strain of a recording (.npz) to an image"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "record",
        metavar="RECORD",
        help="recording written by `tumble run SCENE --record RECORD.npz` (not a scene file), "
        "or a wedge's output folder",
    )
    parser.add_argument(
        "-o",
        "--output",
        default=None,
        metavar="OUT",
        help="image to write: OUT.png, OUT.svg or OUT.pdf (checked before the recording is read); "
        "for a wedge folder default OUTDIR/summary.png",
    )
    parser.add_argument(
        "--dpi", type=int, default=100, metavar="N", help="resolution of raster images in dots per inch (default 100)"
    )


def main(args: argparse.Namespace) -> int:
    import sys
    from pathlib import Path

    from ..io.atomic import check_output
    from ..io.plot import PLOT_SUFFIXES, plot_record

    if args.output is not None:
        check_output(args.output, suffixes=PLOT_SUFFIXES, option="-o")

    if not 10 <= args.dpi <= 2000:
        raise ValueError(f"--dpi must be between 10 and 2000, got {args.dpi}")

    if (Path(args.record) / "manifest.json").is_file():  # a wedge's folder: its summary figures (tumble.wedge)
        from ..wedge import plot_wedge

        out = plot_wedge(args.record, args.output, dpi=args.dpi)
    elif args.output is None:
        raise ValueError("-o OUT is required when plotting a recording")
    else:
        out = plot_record(args.record, args.output, dpi=args.dpi)
    print(f"wrote {out}", file=sys.stderr)
    return 0
