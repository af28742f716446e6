"""Which emulated machines ran here: ``tests/test_machines.py`` under pytest, each set-up's outcome (passed,
skipped and why, failed), its time, and the CPU and OpenCL drivers it ran on, into ``bench/results/machines.json``
(docs/devices.md shows it: ``python -m bench.doc_blocks machines``).

    python -m bench.machines             # all set-ups, the valgrind one included (about 5 minutes on 2 cores)
    python -m bench.machines --quick     # without the valgrind one (marker slow)
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from bench.common import ROOT, load_average, machine_info, write_json

RESULTS_JSON = Path("machines.json")


def cpu_identity() -> str:
    """The CPU as ``/proc/cpuinfo`` names it: model name, family, model and its widest SIMD (Linux; else '?')."""
    try:
        info = Path("/proc/cpuinfo").read_text()
    except OSError:
        return "?"

    def field(name: str) -> str:
        match = re.search(rf"^{name}\s*:\s*(.*)$", info, re.M)
        return match.group(1).strip() if match else "?"

    flags = field("flags").split()
    simd = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "no AVX2"
    return f"{field('model name')} (CPU family {field('cpu family')}, model {field('model')}, {simd})"


def drivers() -> list[str]:
    """The OpenCL devices here as ``s2cl devices --json`` lists them, one line each."""
    out = subprocess.run([sys.executable, "-m", "s2cl", "devices", "--json"], capture_output=True, text=True,
                         cwd=ROOT, timeout=600)
    rows = json.loads(out.stdout or "[]")
    return [f"{r['spec']} {r['platform']} {r['driver']} ({r['target'] or '?'})"
            + ("" if r["builds"] else f": cannot compile ({r['why_not']})") for r in rows]


def cases(junit: Path) -> list[dict[str, Any]]:
    """Each test of the module: name, outcome, seconds, and the reason of a skip or the first line of a failure."""
    out = []
    for case in ET.parse(junit).getroot().iter("testcase"):
        outcome, why = "passed", ""
        for child in case:
            if child.tag in ("skipped", "failure", "error"):
                outcome = {"skipped": "skipped", "failure": "failed", "error": "failed"}[child.tag]
                why = (child.get("message") or "").splitlines()[0] if child.get("message") else ""
                why = re.sub(r"^Skipped: ", "", why)
        out.append({"test": case.get("name"), "outcome": outcome, "seconds": round(float(case.get("time", 0)), 1),
                    "why": why})
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.machines", description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="leave out the valgrind set-up (marker slow)")
    args = ap.parse_args(argv)
    before = load_average()
    with tempfile.TemporaryDirectory() as tmp:
        junit = Path(tmp) / "machines.xml"
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={junit}",
               "tests/test_machines.py"] + (["-m", "not slow"] if args.quick else [])
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, env=os.environ | {"PYTHONPATH": str(ROOT)})
        seconds = time.perf_counter() - t0
        rows = cases(junit)
    data = {"command": "python -m bench.machines" + (" --quick" if args.quick else ""), "cpu": cpu_identity(),
            "drivers": drivers(), "cases": rows, "seconds": round(seconds, 1), "status": proc.returncode,
            "machine": machine_info() | {"load_average_after": load_average(), "load_average_before": before}}
    path = write_json(RESULTS_JSON, data)
    print(f"wrote {path.relative_to(ROOT)}: " + ", ".join(f"{r['test']} {r['outcome']}" for r in rows))
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
