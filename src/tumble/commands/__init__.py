"""Implementations of the `tumble` subcommands (see `tumble.cli`)."""

from __future__ import annotations

import argparse


def add_precision_argument(parser: argparse.ArgumentParser) -> None:
    """`--precision float32|float64`: replace the scene's [world] precision (run, render, view, export)."""
    from ..precision import DEFAULT_PRECISION, PRECISIONS

    parser.add_argument(
        "--precision",
        choices=PRECISIONS,
        default=None,
        help=f"replace the scene's [world] precision, the float type of the arrays and kernels (default {DEFAULT_PRECISION})",
    )
