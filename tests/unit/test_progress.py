"""progress.py: one progress bar for run, render, export and wedge."""

from __future__ import annotations

import io

from rich.console import Console

from tumble.progress import new_bar, progress_bar


def _console() -> tuple[Console, io.StringIO]:
    out = io.StringIO()
    return Console(file=out, force_terminal=True, width=100, color_system=None), out


def test_the_bar_counts_in_the_jobs_unit():
    """Three advances of five frames, then two more at once: the last line reads 5/5 frames."""
    console, out = _console()
    with progress_bar(5, "writing clip.mp4", console=console) as advance:
        for _ in range(3):
            advance()
        advance(completed=5)
    last = out.getvalue().rstrip().split("\r")[-1]  # the bar's last redraw
    assert "writing clip.mp4" in last and "5/5 frames" in last


def test_a_disabled_bar_writes_nothing():
    console, out = _console()
    with progress_bar(5, "simulating", unit="steps", enabled=False, console=console) as advance:
        advance()
        advance(completed=4)
    assert out.getvalue() == ""


def test_extra_columns_sit_between_the_count_and_the_time_left():
    from rich.progress import TextColumn

    console, out = _console()
    with new_bar(console, "variants", extra=(TextColumn("{task.fields[failed]}"),)) as bar:
        task = bar.add_task("wedge", total=4, failed="1 failed")
        bar.update(task, completed=2)
    last = out.getvalue().rstrip().split("\r")[-1]  # the bar's last redraw
    assert "2/4 variants" in last and last.index("2/4 variants") < last.index("1 failed")
