"""Peak memory of one piece of work in a child process (Linux): the growth of the resident set (``VmHWM`` reset
through ``/proc/self/clear_refs``, over the resident set before the work) and numpy's traced peak (tracemalloc).

The footprint tests run their work in a fresh ``python -c`` child with the tests folder on ``PYTHONPATH`` and print
:func:`peak`'s figures as JSON (:func:`env` sets both)."""

from __future__ import annotations

import os
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent


def _status(key: str) -> int:
    """A ``/proc/self/status`` figure in bytes."""
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith(key))


def peak(work: Callable[[], Any], *, traced: bool = True) -> dict[str, int]:
    """``{"rss": growth of the peak resident set during work (bytes), "traced": numpy's peak (bytes; 0 untraced)}``."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    base = _status("VmRSS:")
    if traced:
        tracemalloc.start()
    work()
    top = tracemalloc.get_traced_memory()[1] if traced else 0
    if traced:
        tracemalloc.stop()
    return {"rss": _status("VmHWM:") - base, "traced": top}


def env(**more: str) -> dict[str, str]:
    """The child's environment: the repository and the tests folder first on ``PYTHONPATH``, plus ``more``."""
    path = os.pathsep.join([str(ROOT), str(ROOT / "tests"), os.environ.get("PYTHONPATH", "")])
    return {**os.environ, "PYTHONPATH": path, **more}
