"""What the commands print through: a rich console and a progress bar (rate, ETA) on stderr."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any


def rich_console(stderr: bool = False) -> Any:
    """A rich console on stdout (or stderr); 160 columns wide when it writes to a file or a pipe."""
    from rich.console import Console

    console = Console(stderr=stderr)
    if not console.is_terminal:
        console = Console(stderr=stderr, width=160)
    return console


@contextmanager
def progress_bar(total: int, label: str, enabled: bool = True, unit: str = "px",
                 per_item: int = 0) -> Iterator[Callable[[int], None]]:
    """A rich progress bar with rate and ETA; yields ``advance(n)``.

    :param unit: what one item is, for the rate (``px``: pixels, ``configs``: configurations).
    :param per_item: evaluations per item; when given, the rate also shows millions of evaluations/s.
    """
    if not enabled:
        yield lambda n: None
        return
    from rich.progress import Progress

    with Progress(*_columns(), transient=False, console=rich_console(stderr=True)) as bar:
        task = bar.add_task(label, total=total, rate="")
        start = time.perf_counter()

        def advance(n: int) -> None:
            bar.advance(task, n)
            done = bar.tasks[0].completed
            elapsed = max(time.perf_counter() - start, 1e-9)
            rate = f"{done / elapsed:,.0f} {unit}/s"
            if per_item:
                rate += f" ({done * per_item / elapsed / 1e6:,.2f} M evaluations/s)"
            bar.update(task, rate=rate)

        yield advance


def _columns() -> list[Any]:
    """The bar's columns: label, bar, percent, done/total, rate, elapsed, remaining."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        TaskProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return [TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(), MofNCompleteColumn(),
            TextColumn("[cyan]{task.fields[rate]}"), TimeElapsedColumn(), TimeRemainingColumn()]
