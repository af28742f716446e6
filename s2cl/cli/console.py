"""What the commands print through: a rich console and a progress bar (rate, ETA) on stderr."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from typing import Any


def rich_console(stderr: bool = False) -> Any:
    """A rich console on stdout (or stderr); 160 columns wide when it writes to a file or a pipe."""
    from rich.console import Console

    console = Console(stderr=stderr)
    if not console.is_terminal:
        console = Console(stderr=stderr, width=160)
    return console


class _Advance:
    """``advance(n)`` for a progress bar; the bar appears at :meth:`start` (or at the first ``advance`` when its
    size was given up front), so a run refused before its work prints no bar."""

    def __init__(self, enabled: bool, stack: ExitStack, label: str, total: int | None, unit: str, per_item: int):
        self.enabled, self.stack, self.label, self.total = enabled, stack, label, total
        self.unit, self.per_item = unit, per_item
        self.bar: Any = None
        self.closed = False  # set when the progress_bar block ends: a late call shows nothing
        self.t0, self.first = time.perf_counter(), 0

    def start(self, total: int, done: int = 0, per_item: int | None = None, label: str | None = None) -> None:
        """Show the bar, ``total`` items of which ``done`` are already done."""
        self.per_item = self.per_item if per_item is None else per_item
        self.label, self.total = label or self.label, total
        if not self.enabled or self.closed:
            return
        if self.bar is None:
            from rich.progress import Progress

            self.bar = self.stack.enter_context(Progress(*_columns(), transient=False,
                                                         console=rich_console(stderr=True)))
            self.task = self.bar.add_task(self.label, total=total, rate="")
        self.bar.update(self.task, total=total, completed=done, description=self.label)
        self.t0, self.first = time.perf_counter(), done

    def __call__(self, n: int) -> None:
        if not self.enabled or self.closed:
            return
        if self.bar is None:
            self.start(self.total or 0)
        self.bar.advance(self.task, n)
        done = self.bar.tasks[0].completed - self.first
        elapsed = max(time.perf_counter() - self.t0, 1e-9)
        rate = f"{done / elapsed:,.0f} {self.unit}/s"
        if self.per_item:
            rate += f" ({done * self.per_item / elapsed / 1e6:,.2f} M evaluations/s)"
        self.bar.update(self.task, rate=rate)


@contextmanager
def progress_bar(total: int | None, label: str, enabled: bool = True, unit: str = "px",
                 per_item: int = 0) -> Iterator[_Advance]:
    """A rich progress bar with rate and ETA on stderr; yields ``advance(n)`` (``advance.start(total, done)`` sets a
    size known only later). Nothing shows until the work starts.

    :param unit: what one item is, for the rate (``px``: pixels, ``configs``: configurations).
    :param per_item: evaluations per item; when given, the rate also shows millions of evaluations/s.
    """
    with ExitStack() as stack:
        advance = _Advance(enabled, stack, label, total, unit, per_item)
        try:
            yield advance
        finally:
            advance.closed = True


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
