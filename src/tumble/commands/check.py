"""`tumble check SCENE`: validate a scene file without running it."""

from __future__ import annotations

import argparse

HELP = "validate a scene file (keys, values, limits, body references and mesh files) without running it"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from .run import SCENE_HELP

    parser.add_argument("scene", metavar="SCENE", help=SCENE_HELP)


def main(args: argparse.Namespace) -> int:
    from ..io.scene import validate_scene

    scene = validate_scene(args.scene)
    print(f"{scene.path}: ok: {scene.summary()}")
    return 0
