"""Run s2cl's benchmark suite on this machine.

    python -m bench                    # full suite (its measured total is in each report), regenerates docs/bench.md
    python -m bench --quick            # reduced sizes (a few minutes on 2 cores); docs only with --docs
    python -m bench --only lm,grid     # some parts only (see --list); leaves the docs alone
    python -m bench --report bench/results/RESULT.json   # re-render Markdown/plots (and docs) from a JSON
    python -m bench --list

The parts are the families declared in :mod:`bench.registry` (name, sizes, columns, plot); this
command and :mod:`bench.report` only iterate over them. Writes
``bench/results/<machine>-<date>[-quick].json`` and ``.md`` with PNG plots beside them
(``-pareto.png``, ``-scaling.png``), atomically. Every part validates a slice against its float64
reference before timing and stops the suite (exit 1) if it disagrees; a part that fails otherwise
is recorded in the report and the exit code is 1. The docs are regenerated (unless ``--docs`` or
``--no-docs`` says otherwise) only from a full, complete run: every part, full sizes, none failed.
The 1-minute load averages before and after the run are recorded, and the report says from them
whether other jobs shared the machine.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import sys
import time
import traceback
from pathlib import Path
from typing import Any

from bench.common import RESULTS, BenchValidationError, load_average, machine_info, machine_name, write_json
from s2cl.errors import DependencyError

CONTEXT_KEYS = ("repeat", "spectra", "copies", "block", "loops", "time_pixels")


def _docs_default(results: dict[str, Any]) -> bool:
    """Whether a run's results regenerate docs/bench.md by default: a full, complete run (every
    part, full sizes, none failed)."""
    from bench.registry import FAMILIES, GROUPS

    return (not results.get("quick") and results.get("parts") == [f.name for f in FAMILIES]
            and not any("error" in part for g in GROUPS for part in results.get(g.key, {}).values()))


def _list() -> None:
    """Every part: name, group, title, the sizes of the full and the quick run, its columns."""
    from bench.registry import FAMILIES

    for f in FAMILIES:
        sizes = "".join(f"; {k}: {f.full[k]} (quick {f.quick.get(k)})" for k in f.full)
        print(f"{f.name:12s} {f.group.key:10s} {f.title}{sizes}")
        print(f"{'':23s} columns: {', '.join(c.key for c in f.columns)}")


def _run_part(f: Any, ctx: Any, results: dict[str, Any]) -> bool:
    """Run one family into ``results``; a validation failure stops the suite (exit 1). Returns
    whether it failed otherwise (recorded in the results)."""
    t0 = time.perf_counter()
    print(f"[bench] {f.name} ...", flush=True)
    failed = False
    try:
        results[f.group.key][f.key] = f.run(ctx, **results["sizes"][f.name])
    except BenchValidationError as err:
        print(f"[bench] {f.name}: VALIDATION FAILED: {err}", file=sys.stderr)
        raise SystemExit(1) from err
    except DependencyError as err:  # an optional extra this machine lacks: the part is not run, not failed
        print(f"[bench] {f.name}: not run: {err}", flush=True)
        results[f.group.key][f.key] = {"error": f"not run: {err}", "skipped": True}
    except Exception as err:
        failed = True
        traceback.print_exc()
        results[f.group.key][f.key] = {"error": f"{type(err).__name__}: {err}"}
    results["seconds"][f.name] = time.perf_counter() - t0
    print(f"[bench] {f.name}: {results['seconds'][f.name]:.1f} s", flush=True)
    return failed


def _validations(ctx: Any, results: dict[str, Any]) -> dict[str, Any]:
    """Every check run before timing: the chain's, and each part's ``validation*`` keys."""
    from bench.registry import GROUPS

    out = {f"chain: {k}": v for k, v in ctx.cache.get("validation", {}).items()}
    for g in GROUPS:
        for key, part in results[g.key].items():
            out.update({f"{key}: {k}": v for k, v in part.items() if k.startswith("validation")})
    return out


def _report(path: Path, docs: bool | None) -> int:
    """Re-render the Markdown, plots (and docs) of an earlier run's JSON."""
    import json

    from bench.report import write_reports

    results = json.loads(path.read_text(encoding="utf-8"))
    for p in write_reports(results, path.parent, path.stem, docs=docs if docs is not None else _docs_default(results)):
        print(f"[bench] wrote {p}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="reduced sizes and repeats (a few minutes on 2 cores)")
    parser.add_argument("--only", action="append", metavar="NAME[,NAME]",
                        help="parts or groups (knobs, scaling, baselines) to run; see --list")
    parser.add_argument("--list", action="store_true", help="list the parts and exit")
    parser.add_argument("--out", type=Path, default=RESULTS, help="results folder (default bench/results)")
    parser.add_argument("--docs", action=argparse.BooleanOptionalAction, default=None,
                        help="regenerate docs/bench.md and docs/bench/*.png (default: for a full, complete run: "
                             "every part, full sizes, none failed)")
    parser.add_argument("--report", type=Path, metavar="RESULT.json",
                        help="only rewrite the Markdown, plots (and docs) from an earlier run's JSON")
    args = parser.parse_args(argv)
    if args.report:
        return _report(args.report, args.docs)
    if args.list:
        _list()
        return 0
    from bench.chain import Context
    from bench.registry import GROUPS, select
    from s2cl.cl.runtime import get_runtime

    parts = select(args.only)
    ctx = Context.make(args.quick)
    t_start = time.perf_counter()
    machine = machine_info(get_runtime())
    results: dict[str, Any] = {"benchmark": "s2cl suite", "quick": args.quick, "parts": [f.name for f in parts],
                               "machine": machine, "load_average": {"before": machine["load_average"]},
                               "context": {k: getattr(ctx, k) for k in CONTEXT_KEYS},
                               "sizes": {f.name: f.sizes(args.quick) for f in parts},
                               **{g.key: {} for g in GROUPS}, "seconds": {}}
    failed = [f.name for f in parts if _run_part(f, ctx, results)]
    results["seconds_total"] = time.perf_counter() - t_start
    results["load_average"]["after"] = load_average()
    results["validation"] = _validations(ctx, results)

    from bench.report import write_reports

    stem = f"{machine_name()}-{_dt.date.today().isoformat()}" + ("-quick" if args.quick else "")
    if args.only:
        stem += "-" + "-".join(results["parts"])[:60]
    written = [write_json(args.out / f"{stem}.json", results)]
    docs = args.docs if args.docs is not None else _docs_default(results)
    written += write_reports(results, args.out, stem, docs=docs)
    for p in written:
        print(f"[bench] wrote {p}")
    print(f"[bench] total {results['seconds_total']:.0f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
