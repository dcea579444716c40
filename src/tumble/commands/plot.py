"""`tumble plot RECORD.npz -o OUT.png`: energy, momentum, contacts and cloth strain over time."""

from __future__ import annotations

import argparse

HELP = "plot energy, momentum, contact count and cloth strain of a recording (.npz) to an image"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("record", metavar="RECORD", help="recording written by `tumble run --record` (.npz)")
    parser.add_argument("-o", "--output", required=True, metavar="OUT", help="image to write (.png, .svg, .pdf)")
    parser.add_argument("--dpi", type=int, default=100, help="resolution of raster images (default 100)")


def main(args: argparse.Namespace) -> int:
    import sys

    from ..io.plot import plot_record

    out = plot_record(args.record, args.output, dpi=args.dpi)
    print(f"wrote {out}", file=sys.stderr)
    return 0
