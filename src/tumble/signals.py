"""The signals that end a command, and handlers set over them for a while.

Ctrl-C (SIGINT) raises KeyboardInterrupt; the others end a command as `tumble.cli.Terminated`
(status 128 + the signal). A signal the process was started ignoring (SIGHUP under `nohup`, SIGINT
in a script's background job) stays ignored: `replace` leaves it alone.
"""

from __future__ import annotations

import signal
from collections.abc import Callable, Iterable

#: the signals that end a command besides Ctrl-C: `kill` and a closed terminal, where the platform has them
TERMINATING: tuple[int, ...] = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))
#: Ctrl-C and the signals above
ENDING: tuple[int, ...] = (signal.SIGINT, *TERMINATING)


def replace(numbers: Iterable[int], handler: Callable[[int, object], None]) -> dict[int, object]:
    """Set `handler` for each signal of `numbers` that is not ignored; returns the handlers it replaced
    (for `restore`). Only in the main thread, as `signal.signal` itself."""
    previous: dict[int, object] = {}
    for number in numbers:
        if number not in previous and signal.getsignal(number) is not signal.SIG_IGN:
            previous[number] = signal.signal(number, handler)
    return previous


def restore(previous: dict[int, object]) -> None:
    """Put back the handlers `replace` returned."""
    for number, handler in previous.items():
        signal.signal(number, handler)  # type: ignore[arg-type]
