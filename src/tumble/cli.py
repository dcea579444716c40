"""The `tumble` command line: one subcommand per module under `tumble.commands`.

Each command module defines `HELP` (one line, lower case, no full stop), `add_arguments(parser)`
and `main(args) -> int`.

Exit status and what is printed on stderr, for every command:

- 0: done.
- 2: bad input (a missing or malformed scene, a bad option, an output that cannot be written,
  a request beyond a limit, a broken recording, a missing optional package, out of memory):
  one line, "tumble COMMAND: error: ...".
- 1: an unexpected error (a bug): one line naming it and how to see the traceback.
- 130: interrupted (Ctrl-C).
- 143: terminated (SIGTERM, `kill`), unwound as on Ctrl-C; 129 on SIGHUP (its terminal closed).

A traceback is printed only with `--debug` (before or after the command) or with the
environment variable TUMBLE_DEBUG=1.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading
import warnings

from . import signals
from .errors import TumbleError

#: subcommand -> module under tumble.commands
COMMANDS = {
    "run": "run",
    "check": "check",
    "view": "view",
    "render": "render",
    "plot": "plot",
    "export": "export",
    "wedge": "wedge",
}

#: environment variable that turns on tracebacks (as --debug does)
DEBUG_ENV = "TUMBLE_DEBUG"

#: optional packages -> the pip command that installs them (the [viewer] extra holds them all)
OPTIONAL = {
    name: 'pip install "tumble[viewer]"'
    for name in ("PySide6", "moderngl", "glcontext", "matplotlib", "imageio", "imageio_ffmpeg", "PIL")
}
OPTIONAL["pxr"] = 'pip install "tumble[usd]"'  # tumble export


def _version() -> str:
    try:
        from importlib.metadata import PackageNotFoundError, version

        return version("tumble")
    except (ImportError, PackageNotFoundError):
        from . import __version__

        return __version__


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors: "tumble run: error: ... (see tumble run --help)", exit 2; it
    keeps what it is built of in public attributes, for the help texts' checks and docs.

    Attributes:
        options: every argument added (`argparse.Action`: flags, help, default), in order, `-h` first,
            those of argument groups included.
        commands: the subcommands' parsers by name (`build_parser` fills it).
    """

    def __init__(self, *args, **kwargs):
        self.options: list[argparse.Action] = []  # before argparse's __init__, which adds -h
        self.commands: dict[str, Parser] = {}
        super().__init__(*args, **kwargs)

    def add_argument(self, *args, **kwargs) -> argparse.Action:
        action = super().add_argument(*args, **kwargs)
        self.options.append(action)
        return action

    def add_mutually_exclusive_group(self, **kwargs):
        group = super().add_mutually_exclusive_group(**kwargs)
        add = group.add_argument

        def add_argument(*args, **kw) -> argparse.Action:
            action = add(*args, **kw)
            self.options.append(action)
            return action

        group.add_argument = add_argument  # type: ignore[method-assign]  # recorded as the parser's own
        return group

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> Parser:
    """The `tumble` parser: its subcommands' parsers are in `parser.commands`, each one's arguments in `options`."""
    parser = Parser(
        prog="tumble",
        description="Tumble: particles, rigid bodies and cloth, simulated headless, viewed, rendered and plotted.",
        epilog="Scenes are TOML files (docs/scenes.md) or the names of bundled samples, e.g. sphere_pile. "
        f"Errors are one line on stderr; --debug or {DEBUG_ENV}=1 adds the traceback.",
    )
    parser.add_argument(
        "-V", "--version", action="version", version=f"tumble {_version()}", help="print the version and exit"
    )
    parser.add_argument("--debug", action="store_true", help="print the traceback of an error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for name, module_name in COMMANDS.items():
        module = importlib.import_module(f"tumble.commands.{module_name}")
        p = sub.add_parser(name, help=module.HELP, description=module.HELP[0].upper() + module.HELP[1:] + ".")
        module.add_arguments(p)
        p.add_argument(
            "--debug", action="store_true", default=argparse.SUPPRESS, help="print the traceback of an error"
        )
        p.set_defaults(command_main=module.main)
        parser.commands[name] = p
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM (`kill`, a job's time limit) or SIGHUP (its terminal closed), raised where the command is
    so that it unwinds as Ctrl-C does: every output still being written is removed, and what the user
    had is left as it was. The command then exits with status 128 + `signum` (143, 129)."""

    def __init__(self, signum: int = signal.SIGTERM) -> None:
        super().__init__(signum)
        self.signum = int(signum)


#: seconds between raising an interruption (SIGTERM, Ctrl-C) again while it is not seen unwinding.
#: C code that looks an attribute up may clear whatever was raised meanwhile, the signal's exception
#: too: NumPy, comparing an array with an enum member, asks the enum class for its special methods,
#: and 3 of 60 renders sent `kill` at a random frame rendered on to the end
INTERRUPT_RETRY_S = 0.5


class _Interrupts:
    """Handlers that raise KeyboardInterrupt on Ctrl-C and Terminated on SIGTERM or SIGHUP, and raise
    it again every INTERRUPT_RETRY_S until it unwinds (an exception being handled, or what one raised
    meanwhile). A signal the command was started ignoring (`nohup`, a script's background job) stays ignored."""

    def __init__(self) -> None:
        self.pending: KeyboardInterrupt | None = None
        self.previous: dict[int, object] = {}

    def install(self) -> None:
        self.previous = signals.replace(signals.ENDING, self.received)
        if hasattr(signal, "setitimer"):
            self.previous.update(signals.replace([signal.SIGALRM], self.again))

    def restore(self) -> None:
        self.pending = None
        if hasattr(signal, "setitimer"):
            signal.setitimer(signal.ITIMER_REAL, 0)
        signals.restore(self.previous)
        self.previous = {}

    def received(self, signum: int, frame: object) -> None:
        self.pending = KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)
        if hasattr(signal, "setitimer"):
            signal.setitimer(signal.ITIMER_REAL, INTERRUPT_RETRY_S, INTERRUPT_RETRY_S)
        raise self.pending

    def again(self, signum: int, frame: object) -> None:
        if self.pending is None or _unwinding():
            return
        raise self.pending


def _unwinding() -> bool:
    """Whether an interruption is being handled here or further up (a `finally`, an `__exit__`),
    or an exception raised meanwhile has one as its context."""
    exc, seen = sys.exc_info()[1], 0
    while exc is not None and seen < 100:
        if isinstance(exc, KeyboardInterrupt):
            return True
        exc, seen = exc.__context__, seen + 1
    return False


def main(argv: list[str] | None = None) -> int:
    interrupts = _Interrupts()
    if threading.current_thread() is threading.main_thread():
        interrupts.install()
    try:
        return _run(argv, interrupts)
    finally:
        interrupts.restore()


def _run(argv: list[str] | None, interrupts: _Interrupts) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    debug = bool(getattr(args, "debug", False)) or os.environ.get(DEBUG_ENV, "") not in ("", "0")
    if not debug:  # NumPy's overflow warnings on absurd (but valid) values are not a user's business
        warnings.filterwarnings("ignore", category=RuntimeWarning)
    prefix = f"tumble {args.command}: error:"
    try:
        return int(args.command_main(args) or 0)
    except Terminated as exc:
        interrupts.restore()  # (here, where it is being handled, so that it is not raised again)
        print(f"tumble {args.command}: terminated", file=sys.stderr)
        return 128 + exc.signum
    except KeyboardInterrupt:
        interrupts.restore()
        print(f"tumble {args.command}: interrupted", file=sys.stderr)
        return 130
    except ModuleNotFoundError as exc:
        top = (exc.name or "").split(".")[0]
        if top not in OPTIONAL or debug:
            return _unexpected(args.command, exc, debug)
        print(
            f"{prefix} `tumble {args.command}` needs the Python package {top!r}, which is not installed; "
            f"install it with: {OPTIONAL[top]}",
            file=sys.stderr,
        )
        return 2
    except MemoryError as exc:
        if debug:
            raise
        detail = f" ({exc})" if str(exc) else ""
        print(
            f"{prefix} out of memory{detail}; reduce the number of bodies (emitter count), the cloth "
            "resolution, or the recorded duration and --fps",
            file=sys.stderr,
        )
        return 2
    except RecursionError as exc:
        return _unexpected(args.command, exc, debug)
    except (TumbleError, ValueError, OSError) as exc:
        if debug:
            raise
        print(f"{prefix} {_one_line(exc)}", file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 (the last resort: one line, not a traceback)
        return _unexpected(args.command, exc, debug)


def _one_line(exc: BaseException) -> str:
    """The message of `exc` on one line (an OSError without a message shows its strerror and file)."""
    text = str(exc)
    if isinstance(exc, OSError) and exc.strerror and exc.filename and not isinstance(exc, TumbleError):
        text = f"{exc.filename}: {exc.strerror}"
    return " ".join(part.strip() for part in text.splitlines() if part.strip()) or type(exc).__name__


def _unexpected(command: str, exc: BaseException, debug: bool) -> int:
    if debug:
        raise exc
    print(
        f"tumble {command}: internal error: {type(exc).__name__}: {_one_line(exc)} "
        f"(run again with --debug or {DEBUG_ENV}=1 for the traceback, and please report it)",
        file=sys.stderr,
    )
    return 1


if __name__ == "__main__":
    sys.exit(main())
