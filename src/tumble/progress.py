"""The progress bar of Tumble's long jobs (run, render, export, wedge), on stderr, from rich.

One look everywhere: the job's label, the bar, done/total in the job's unit (steps, frames,
variants), any columns the job adds, and the time left.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator


def new_bar(console, unit: str, *, extra: tuple = (), transient: bool = False):
    """A `rich.progress.Progress` with Tumble's columns (label, bar, done/total `unit`, `extra`, time left)."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn(unit),
        *extra,
        TimeRemainingColumn(),
        console=console,
        transient=transient,
    )


@contextlib.contextmanager
def progress_bar(
    total: int, label: str, *, unit: str = "frames", enabled: bool = True, transient: bool = False, console=None
) -> Iterator[Callable[..., None]]:
    """A progress bar of `total` `unit` while the block runs, or a no-op when not `enabled`.

    Yields `advance(completed=None)`: one more done, or `completed` done in all.
    """
    if not enabled:
        yield lambda completed=None: None
        return
    from rich.console import Console

    with new_bar(console or Console(stderr=True), unit, transient=transient) as bar:
        task = bar.add_task(label, total=total)

        def advance(completed: int | None = None) -> None:
            if completed is None:
                bar.advance(task)
            else:
                bar.update(task, completed=completed)

        yield advance
