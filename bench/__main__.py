"""Run s2cl's benchmark suite on this machine.

    python -m bench                    # full suite (its measured total is in each report), regenerates docs/bench.md
    python -m bench --quick            # reduced sizes (a few minutes on 2 cores); docs only with --docs
    python -m bench --only lm,grid     # some parts only (see --list); leaves the docs alone
    python -m bench --report bench/results/RESULT.json   # re-render Markdown/plots (and docs) from a JSON
    python -m bench --list

Writes ``bench/results/<machine>-<date>[-quick].json`` and ``.md`` with PNG plots beside them
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
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench.common import RESULTS, BenchValidationError, load_average, machine_info, machine_name, write_json

GROUPS = ("knobs", "scaling", "baselines")
CONTEXT_KEYS = ("repeat", "spectra", "copies", "block", "loops", "time_pixels")


def registry() -> dict[str, tuple[str, str, Callable[..., dict[str, Any]]]]:
    """name -> (group, key in the group, function)."""
    from bench.baselines import BASELINES
    from bench.knobs import KNOBS
    from bench.scaling import SCALING

    out: dict[str, tuple[str, str, Callable[..., dict[str, Any]]]] = {}
    out.update({k: ("knobs", k, f) for k, f in KNOBS.items()})
    out.update({k: ("scaling", k, f) for k, f in SCALING.items()})
    out.update({f"vs-{k}": ("baselines", k, f) for k, f in BASELINES.items()})
    return out


def select(only: list[str] | None, names: dict[str, tuple[str, str, Any]]) -> list[str]:
    if not only:
        return list(names)
    wanted: list[str] = []
    for item in (x.strip() for part in only for x in part.split(",")):
        if item in GROUPS:
            wanted += [n for n, (g, _, _) in names.items() if g == item]
        elif item in names:
            wanted.append(item)
        else:
            raise SystemExit(f"bench: unknown part {item!r}; choose from {', '.join((*GROUPS, *names))}")
    return list(dict.fromkeys(wanted))


def _docs_default(results: dict[str, Any]) -> bool:
    """Whether a run's results regenerate docs/bench.md by default: a full, complete run (every
    part, full sizes, none failed)."""
    return (not results.get("quick") and results.get("parts") == list(registry())
            and not any("error" in part for group in GROUPS for part in results.get(group, {}).values()))


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
        import json

        from bench.report import write_reports

        results = json.loads(args.report.read_text(encoding="utf-8"))
        docs = args.docs if args.docs is not None else _docs_default(results)
        for p in write_reports(results, args.report.parent, args.report.stem, docs=docs):
            print(f"[bench] wrote {p}")
        return 0

    names = registry()
    if args.list:
        for n, (g, _, f) in names.items():
            doc = " ".join((f.__doc__ or "").split())
            print(f"{n:12s} {g:10s} {doc[:100]}")
        return 0
    parts = select(args.only, names)

    from bench.chain import Context
    from s2cl.cl.runtime import get_runtime

    ctx = Context.make(args.quick)
    t_start = time.perf_counter()
    machine = machine_info(get_runtime())
    results: dict[str, Any] = {"benchmark": "s2cl suite", "quick": args.quick, "parts": parts, "machine": machine,
                               "load_average": {"before": machine["load_average"]},
                               "context": {k: getattr(ctx, k) for k in CONTEXT_KEYS},
                               "knobs": {}, "scaling": {}, "baselines": {}, "seconds": {}}
    failed = False
    for name in parts:
        group, key, fn = names[name]
        t0 = time.perf_counter()
        print(f"[bench] {name} ...", flush=True)
        try:
            results[group][key] = fn(ctx)
        except BenchValidationError as err:
            print(f"[bench] {name}: VALIDATION FAILED: {err}", file=sys.stderr)
            raise SystemExit(1) from err
        except Exception as err:
            failed = True
            traceback.print_exc()
            results[group][key] = {"name": name, "error": f"{type(err).__name__}: {err}"}
        results["seconds"][name] = time.perf_counter() - t0
        print(f"[bench] {name}: {results['seconds'][name]:.1f} s", flush=True)
    results["seconds_total"] = time.perf_counter() - t_start
    results["load_average"]["after"] = load_average()
    results["validation"] = {f"chain: {k}": v for k, v in ctx.cache.get("validation", {}).items()}
    for group in GROUPS:
        for key, part in results[group].items():
            results["validation"].update({f"{key}: {k}": v for k, v in part.items() if k.startswith("validation")})

    from bench.report import write_reports

    stem = f"{machine_name()}-{_dt.date.today().isoformat()}" + ("-quick" if args.quick else "")
    if args.only:
        stem += "-" + "-".join(parts)[:60]
    written = [write_json(args.out / f"{stem}.json", results)]
    docs = args.docs if args.docs is not None else _docs_default(results)
    written += write_reports(results, args.out, stem, docs=docs)
    for p in written:
        print(f"[bench] wrote {p}")
    print(f"[bench] total {results['seconds_total']:.0f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
