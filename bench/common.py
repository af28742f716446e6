"""Shared helpers for the benchmarks: timing (medians of repeats), machine description, JSON output.

Benchmarks never assert timings; they validate a small slice against the float64 reference
before timing anything, and report ratios against the baseline run in the same process.
"""

from __future__ import annotations

import datetime as _dt
import os
import platform
import re
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

RESULTS = Path(__file__).resolve().parent / "results"


def median_time(fn: Callable[[], Any], repeat: int = 5, warmup: int = 1) -> tuple[float, list[float]]:
    """Median wall time of ``fn()`` over ``repeat`` runs after ``warmup`` runs (seconds)."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times


def cpu_model() -> str:
    try:
        text = Path("/proc/cpuinfo").read_text()
        m = re.search(r"model name\s*:\s*(.+)", text)
        if m:
            return m.group(1).strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_info(rt: Any | None = None) -> dict[str, Any]:
    """What ran the benchmark: CPU, cores, OpenCL device, library versions."""
    import numpy as np

    info: dict[str, Any] = {
        "machine": machine_name(),
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
    }
    try:
        import pyopencl

        info["pyopencl"] = pyopencl.VERSION_TEXT
    except ImportError:
        pass
    if rt is not None:
        info["device"] = rt.name
    return info


def machine_name() -> str:
    """A short label for result files: cpu model words and core count."""
    words = re.sub(r"\(R\)|\(TM\)|CPU|Processor|@.*", "", cpu_model())
    label = "-".join(w for w in re.split(r"[^A-Za-z0-9]+", words) if w)[:40] or platform.machine()
    return f"{label}-{os.cpu_count()}c".lower()


def write_result(name: str, data: dict[str, Any]) -> Path:
    """Write ``bench/results/<name>-<machine>-<date>.json`` atomically; return the path."""
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
    from s2cl.output import write_json

    date = _dt.date.today().isoformat()
    return write_json(RESULTS / f"{name}-{machine_name()}-{date}.json", data)
