"""Shared helpers of the benchmarks: timing (medians of repeats), validation (:func:`check`,
:func:`max_rel_error`), machine description and load averages, atomic output.

Benchmarks never assert timings; they validate a small slice against the float64 reference
before timing anything (raising :class:`BenchValidationError` when it is wrong), and report
ratios against the reference setting or the baseline run in the same process.
"""

from __future__ import annotations

import datetime as _dt
import math
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
ROOT = Path(__file__).resolve().parent.parent


class BenchValidationError(AssertionError):
    """A benchmark's result disagrees with its float64 reference: nothing is timed."""


def check(ok: bool, what: str) -> None:
    """Fail loudly (not with ``assert``, which ``python -O`` drops) when a validation fails."""
    if not ok:
        raise BenchValidationError(what)


def max_rel_error(got: Any, want: Any) -> float:
    """Largest pointwise relative error ``max(|got - want| / |want|)``: every validation's "max rel"."""
    import numpy as np

    want = np.asarray(want, dtype=np.float64)
    return float(np.max(np.abs(np.asarray(got, dtype=np.float64) - want) / np.abs(want)))


def fmt_number(v: Any, digits: int = 3) -> str:
    """A table cell: ``digits`` significant digits (scientific below 1e-3 and from 1e5), integers
    with thousands separators, booleans as "yes" or empty, None as "–", NaN as "n/a"."""
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else ""
    if isinstance(v, int):
        return f"{v:,}"
    if isinstance(v, float):
        if math.isnan(v):
            return "n/a"
        if v == 0:
            return "0"
        if abs(v) >= 1e5 or abs(v) < 1e-3:
            return f"{v:.{digits - 1}e}"
        return f"{v:.{digits}g}"
    return str(v)


def comparison_rows(rates: dict[str, float], baseline: str, extra: dict[str, dict[str, Any]] | None = None
                    ) -> list[dict[str, Any]]:
    """Rows of a side-by-side comparison (the first of ``rates`` is s2cl's): ``method``, ``per_s``,
    ``ratio_s2cl_over_this``, ``baseline`` (the method a user would otherwise run) and ``extra[method]``."""
    first = rates[next(iter(rates))]
    return [{"method": k, "per_s": v, "ratio_s2cl_over_this": first / v, "baseline": k == baseline,
             **(extra or {}).get(k, {})} for k, v in rates.items()]


def print_comparison(result: dict[str, Any]) -> None:
    """A comparison's rows on the terminal (the standalone scripts)."""
    print(f"--- {result['title']} ({result['n']:,} items)")
    for r in result["rows"]:
        mark = " (baseline)" if r["baseline"] else ""
        print(f"{r['method'] + mark:68s} {r['per_s']:14,.0f} {result['unit']}"
              f"  s2cl ÷ this {r['ratio_s2cl_over_this']:8.3g}")


def load_average() -> tuple[float, float, float]:
    """The 1-, 5- and 15-minute load averages now (zeros where the platform has none)."""
    try:
        return os.getloadavg()
    except OSError:
        return (0.0, 0.0, 0.0)


def machine_busy(before: Any, after: Any, cores: int | None = None) -> bool:
    """Did other jobs share the machine? The 1-minute load average around a run above 1.25 × the
    cores (a benchmark that keeps every core busy alone loads about the core count)."""
    cores = cores or os.cpu_count() or 1
    return max(float(before[0]), float(after[0])) > 1.25 * cores


def load_note(before: Any, after: Any, cores: int | None = None) -> str:
    """One sentence from the 1-minute load averages before and after a run: shared or quiet."""
    cores = cores or os.cpu_count() or 1
    measured = (f"the 1-minute load average was {float(before[0]):.1f} before and {float(after[0]):.1f} after the "
                f"run on {cores} cores (the benchmark alone loads about {cores})")
    if machine_busy(before, after, cores):
        return (f"{measured}: other jobs shared the machine, so the times are upper bounds of a quiet machine's; "
                "read ratios, not absolute numbers")
    return f"{measured}: the machine was otherwise quiet"


def time_repeats(fn: Callable[[], Any], repeat: int = 3, warmup: int = 0) -> list[float]:
    """Wall times of ``repeat`` calls of ``fn`` after ``warmup`` untimed calls (seconds)."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return times


def median_time(fn: Callable[[], Any], repeat: int = 3, warmup: int = 0) -> float:
    """Median wall time of ``repeat`` calls of ``fn`` (seconds); the machine is shared, so medians."""
    return statistics.median(time_repeats(fn, repeat, warmup))


def median_and_times(fn: Callable[[], Any], repeat: int = 3, warmup: int = 0) -> tuple[float, list[float]]:
    """Median wall time (seconds) and every timed run, for results that keep the spread."""
    times = time_repeats(fn, repeat, warmup)
    return statistics.median(times), times


def interleaved_medians(fns: list[Callable[[], Any]], repeat: int = 3, warmup: int = 0) -> list[float]:
    """Median wall time of each of ``fns``, timed in interleaved rounds (a, b, c, a, b, c, ...) so
    that drift in the machine's load (other users) hits every setting alike; after ``warmup``
    untimed rounds."""
    for _ in range(warmup):
        for fn in fns:
            fn()
    times: list[list[float]] = [[] for _ in fns]
    for _ in range(repeat):
        for k, fn in enumerate(fns):
            t0 = time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - t0)
    return [statistics.median(t) for t in times]


def cpu_model() -> str:
    try:
        m = re.search(r"model name\s*:\s*(.+)", Path("/proc/cpuinfo").read_text())
        if m:
            return m.group(1).strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_name() -> str:
    """A short label for result files: CPU model words and core count (``amd-epyc-9r14-2c``)."""
    words = re.sub(r"\(R\)|\(TM\)|CPU|Processor|\d+-Core|@.*", "", cpu_model())
    label = "-".join(w for w in re.split(r"[^A-Za-z0-9]+", words) if w)[:40] or platform.machine()
    return f"{label}-{os.cpu_count()}c".lower()


def cpu_vector_flags() -> list[str]:
    """The CPU's SIMD feature flags that decide the kernels' vector width (Linux; else empty)."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return []
    flags = next((line.split(":", 1)[1].split() for line in text.splitlines() if line.startswith("flags")), [])
    return sorted(f for f in flags if f in ("avx", "avx2", "fma", "avx512f", "avx512vl", "avx512bw"))


def machine_info(rt: Any | None = None) -> dict[str, Any]:
    """What the numbers were measured on: CPU, cores, OpenCL device and lanes, library versions."""
    import numpy as np

    info: dict[str, Any] = {
        "machine": machine_name(),
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "numpy": np.__version__,
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "load_average": load_average(),  # when the description was taken: the start of a run
    }
    try:
        import pyopencl

        info["pyopencl"] = pyopencl.VERSION_TEXT
    except ImportError:
        pass
    if rt is not None:
        info["opencl_device"] = rt.name
        info["lanes"] = {r: rt.lanes(r) for r in ("float32", "float64")}
        info["native_vector_width"] = {r: rt.reported_lanes(r) for r in ("float32", "float64")}  # as reported
        info["clean_vector_width"] = {r: rt.native_lanes(r) for r in ("float32", "float64")}  # as built
        info["opencl_driver"] = str(rt.device.driver_version).strip()
        info["cpu_flags"] = cpu_vector_flags()
    return info


def write_json(name: str | Path, data: dict[str, Any]) -> Path:
    """Write JSON atomically: ``name`` relative to ``bench/results/`` or a path."""
    from s2cl.io.output import write_json as _write

    path = Path(name)
    return _write(path if path.is_absolute() or path.parent != Path() else RESULTS / path, data)


def write_result(name: str, data: dict[str, Any]) -> Path:
    """Write ``bench/results/<name>-<machine>-<date>.json`` atomically; return the path."""
    date = _dt.date.today().isoformat()
    return write_json(RESULTS / f"{name}-{machine_name()}-{date}.json", data)


def save_figure(fig: Any, path: Path, dpi: int = 110) -> Path:
    """Save a matplotlib figure atomically (temporary file in the same folder + rename)."""
    from s2cl.io.output import write_atomic

    return write_atomic(path, lambda p: fig.savefig(p, dpi=dpi, format="png"))
