"""The `tumble` command line: one subcommand per module under `tumble.commands`.

Each command module defines `HELP` (one line), `add_arguments(parser)` and `main(args) -> int`.
Bad input (a missing or malformed scene) exits with status 2 and one line on stderr.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from .errors import TumbleError

#: subcommand -> module under tumble.commands
COMMANDS = {
    "run": "run",
    "check": "check",
    "view": "view",
    "render": "render",
    "plot": "plot",
    "export": "export",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tumble", description="Tumble: particles, rigid bodies and cloth.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, module_name in COMMANDS.items():
        try:
            module = importlib.import_module(f"tumble.commands.{module_name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"tumble.commands.{module_name}":
                raise
            continue  # command not built yet in this checkout
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(_main=module.main)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args._main(args) or 0)
    except (TumbleError, ValueError, OSError) as exc:
        print(f"tumble {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"tumble {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
