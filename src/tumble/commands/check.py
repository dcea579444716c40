"""`tumble check SCENE`: validate a scene file without running it."""

from __future__ import annotations

import argparse

HELP = "validate a scene file (keys, values, limits, body references, mesh files, the built world) without running it"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from .run import SCENE_HELP

    parser.add_argument("scene", metavar="SCENE", help=SCENE_HELP)


def main(args: argparse.Namespace) -> int:
    from ..io.scene import build_world, validate_scene

    scene = validate_scene(args.scene)
    # then built, not stepped: what only the World's own checks see (a mesh whose triangles all have no
    # area, a hinge motor without a torque, a float32 world's range) is refused here as `run` refuses it
    build_world(scene)
    print(f"{scene.path}: ok: {scene.summary()}")
    return 0
