"""What a sweep with several applications (``[[application]]``, docs/applications.md) costs against the sum of
its applications' own single-application sweeps on the same designs (issue 35, item 8).

Two scenes, each run in the same process as a multi-application ``s2cl.optimise`` and as each of its applications'
own single-application scenes (:func:`s2cl.app.applications.application_sweep_scene`: the application's
``[analysis]``, library and copies, ``[sweep]`` restricted to its bands), in interleaved rounds (medians):

- ``different``: chlorophyll (IGRM Cab on B4-B7, Lib1) and leaf water (GVMI EWT on B8/B11, the leaf-water
  library): no library shared;
- ``shared``: three applications on Lib1 reading the same swept B5 and B6: chlorophyll (IGRM Cab), MTCI (a
  formula, Cab) and a red-edge NDVI (B5/B6, Cab).

Each run's time is split into phases by wrapping the functions that do them (exclusive times: a phase nested in
another is counted once, in itself): checks and planning, tables, kernel builds, sweep (the kernel over the
designs), joint table, reference rows, within noise, trade-off (margins, front, column, figure) and report. Before
each run the in-process kernel and program caches are emptied, as a new ``s2cl optimise`` process finds them. The
first round checks that each application's scores in the joint table equal its own run's bit for bit (nothing is
timed otherwise). The first round also pays each kernel's first compile into PoCL's disk cache (medians of 3
rounds or more leave it out). Nothing asserts a timing; the load averages are recorded.

    python -m bench.bench_applications              # 3 rounds, about 4 minutes on 2 cores
    python -m bench.bench_applications --rounds 5
    python -m bench.bench_applications --label before   # writes bench/results/applications-before.json

Writes bench/results/applications.json (or ``applications-LABEL.json``); its figures reach docs/applications.md
through ``python -m bench.doc_blocks applications.cost``.
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import RESULTS, BenchValidationError, check, load_average, load_note, machine_info, write_json

OUTPUT = RESULTS / "applications.json"

COMMON = """
[scene]
name = "{name}"
[surface]
library = "builtin:lib1"
quantity = "reflectance"
copies = 100
[effects]
atmosphere = true
correct = true
seed = 1
"""
RED_EDGE = """
[sweep.ranges]
B5 = { centres = [690, 695, 700, 705, 710, 715, 720], widths = [10, 15, 20, 25, 30] }
B6 = { centres = [725, 730, 735, 740, 745, 750, 755], widths = [10, 15, 20, 25, 30] }
"""
CHLOROPHYLL = """
[[application]]
name = "chlorophyll"
[application.analysis]
kind = "igrm"
parameter = "cab"
bands = ["B4", "B5", "B6", "B7"]
"""
#: the benchmark's scenes: name → (what, TOML)
SCENES: dict[str, tuple[str, str]] = {
    "different": (
        "chlorophyll (IGRM Cab, Lib1; B5 × B6, 1,225 designs) and leaf water (GVMI EWT, the leaf-water library; "
        "B11, 28 designs): no library shared, 34,300 joint designs",
        COMMON.format(name="cost-different") + CHLOROPHYLL + """
[[application]]
name = "leaf_water"
library = "builtin:leaf-water"
analysis = { kind = "gvmi", parameter = "ewt", nir = "B8", swir = "B11" }
[sweep]
bands = ["B5", "B6", "B11"]
""" + RED_EDGE + """B11 = { centres = [1580, 1595, 1610, 1625, 1640, 1655, 1670], widths = [50, 70, 90, 110] }
"""),
    "shared": (
        "chlorophyll (IGRM Cab), MTCI (formula, Cab) and a red-edge NDVI (B5/B6, Cab), all on Lib1 and all "
        "reading the swept B5 × B6: 1,225 joint designs, 1,225 per application",
        COMMON.format(name="cost-shared") + CHLOROPHYLL + """
[[application]]
name = "mtci"
[application.analysis]
kind = "formula"
expression = "(B6 - B5) / (B5 - B4)"
parameter = "cab"
[[application]]
name = "red_edge_ndvi"
analysis = { kind = "ndvi", parameter = "cab", nir = "B6", red = "B5" }
[sweep]
bands = ["B5", "B6"]
""" + RED_EDGE),
}

#: phase → the (module, attribute) names whose calls it counts (exclusive of the phases nested in them)
PHASES: dict[str, list[tuple[str, str]]] = {
    "checks and planning": [("s2cl.app.optimise", "prepare")],
    "tables": [("s2cl.app.plan", "build_tables")],
    "kernel builds": [("s2cl.sweep.kernel.SweepKernel", "__init__")],
    "sweep": [("s2cl.app.optimise", "run_designs")],
    "joint table": [("s2cl.app.multi_optimise", "run_joint")],
    "reference rows": [("s2cl.app.optimise", "reference_row"), ("s2cl.app.multi_optimise", "reference_row"),
                       ("s2cl.app.optimise", "reference_pixels"), ("s2cl.app.multi_optimise", "reference_pixels"),
                       ("s2cl.app.optimise", "own_design"), ("s2cl.app.multi_optimise", "own_design")],
    "within noise": [("s2cl.app.optimise", "within_noise"), ("s2cl.app.multi_optimise", "within_noise")],
    "trade-off": [("s2cl.app.multi_optimise", "trade_off")],
    "ranking": [("s2cl.app.optimise", "rank_against_reference")],
    "report": [("s2cl.app.optimise", "write_report")],
}


class PhaseTimer:
    """Exclusive seconds per phase of the wrapped calls: a call's time less that of the wrapped calls inside it."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {p: 0.0 for p in PHASES}
        self.calls: dict[str, int] = {p: 0 for p in PHASES}
        self._stack: list[float] = []  # per open call: the seconds of the calls nested in it

    def wrap(self, phase: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            self._stack.append(0.0)
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                spent = time.perf_counter() - t0
                nested = self._stack.pop()
                self.seconds[phase] += spent - nested
                self.calls[phase] += 1
                if self._stack:
                    self._stack[-1] += spent
        return timed


@contextlib.contextmanager
def timed_phases(timer: PhaseTimer) -> Iterator[None]:
    """Every function of :data:`PHASES` wrapped by ``timer`` while the block runs."""
    import importlib

    saved = []
    for phase, targets in PHASES.items():
        for module, attr in targets:
            parts = module.split(".")
            try:
                owner: Any = importlib.import_module(module)
            except ModuleNotFoundError:  # a class: module path then class name
                owner = getattr(importlib.import_module(".".join(parts[:-1])), parts[-1])
            if not hasattr(owner, attr):
                continue
            original = getattr(owner, attr)
            saved.append((owner, attr, original))
            setattr(owner, attr, timer.wrap(phase, original))
    try:
        yield
    finally:
        for owner, attr, original in reversed(saved):
            setattr(owner, attr, original)


def empty_kernel_caches() -> None:
    """The kernels a process keeps between calls, dropped (a new ``s2cl optimise`` process has none)."""
    import importlib

    import s2cl.sweep.designs as designs
    import s2cl.sweep.engine as engine
    from s2cl.cl.runtime import get_runtime

    engine._EVALUATORS.clear()
    designs._KERNELS.clear()
    for module, name in (("s2cl.sweep.within_noise", "_STATS"), ("s2cl.sweep.engine", "_TOGETHER")):
        cache = getattr(importlib.import_module(module), name, None)  # where the code has them
        if cache is not None:
            cache.clear()
    get_runtime()._programs.clear()  # built again (PoCL's own kernel cache on disk stays, as between processes)


def single_scenes(scene: Any) -> dict[str, Any]:
    """Each application's own single-application scene of the multi-application ``scene``: name → Scene."""
    from s2cl.app.applications import application_bands, application_sweep_scene
    from s2cl.scene.applications import scene_applications

    return {app.name: application_sweep_scene(scene, app, application_bands(scene, app))
            for app in scene_applications(scene)}


def timed_run(scene: Any, out: Path) -> dict[str, Any]:
    """One ``s2cl.optimise`` of ``scene`` into ``out`` (overwritten), cold kernel caches: wall seconds, s2cl's own
    ``summary["seconds"]`` and the exclusive seconds per phase."""
    import s2cl

    empty_kernel_caches()
    timer = PhaseTimer()
    t0 = time.perf_counter()
    with timed_phases(timer):
        result = s2cl.optimise(scene, out, overwrite=True)
    wall = time.perf_counter() - t0
    phases = dict(timer.seconds)
    phases["other"] = wall - sum(phases.values())
    return {"wall": wall, "s2cl_seconds": float(result.summary["seconds"]), "phases": phases,
            "calls": dict(timer.calls), "folder": str(out)}


def validate(multi: Path, singles: dict[str, Path], scene: Any) -> None:
    """Each application's joint column equals its own run's score bit for bit (NaN where it cannot fit the design),
    the designs matched by their band shapes."""
    import pandas as pd

    joint = pd.read_parquet(multi / "results.parquet")
    from s2cl.app.applications import application_bands
    from s2cl.scene.applications import scene_applications

    swept = [c[: -len("_centre_nm")] for c in joint.columns if c.endswith("_centre_nm")]
    for app in scene_applications(scene):
        own = pd.read_parquet(singles[app.name] / "results.parquet")
        keys = [f"{b}_{s}" for b in application_bands(scene, app) if b in swept for s in ("centre_nm", "width_nm")]
        column = next(c for c in joint.columns if c.startswith(app.name + "_") and c != "pareto")
        score = column[len(app.name) + 1:]
        merged = joint[[*keys, column]].merge(own[[*keys, score, "underdetermined"]], on=keys, how="left",
                                              validate="many_to_one")
        want = np.where(merged["underdetermined"].to_numpy(bool), np.nan, merged[score].to_numpy(np.float64))
        got = merged[column].to_numpy(np.float64)
        check(got.tobytes() == want.tobytes(), f"{app.name}: the joint {column} differs from its own run's {score}")


def bench_scene(name: str, text: str, rounds: int, tmp: Path) -> dict[str, Any]:
    """The multi-application run of scene ``text`` and each application's own run, ``rounds`` interleaved rounds."""
    from s2cl.scene.scene import Scene

    path = tmp / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    scene = Scene.load(str(path))
    singles = single_scenes(scene)
    runs: dict[str, list[dict[str, Any]]] = {"multi": [], **{a: [] for a in singles}}
    for r in range(rounds):
        runs["multi"].append(timed_run(scene, tmp / name / "multi"))
        for a, one in singles.items():
            runs[a].append(timed_run(one, tmp / name / a))
        if r == 0:
            validate(tmp / name / "multi", {a: tmp / name / a for a in singles}, scene)
        print(f"  {name} round {r + 1}: multi {runs['multi'][-1]['wall']:.2f} s, singles "
              + " + ".join(f"{runs[a][-1]['wall']:.2f}" for a in singles) + " s", flush=True)
    med = {k: _median(v) for k, v in runs.items()}
    total_single = sum(med[a]["wall"] for a in singles)
    total_single_s2cl = sum(med[a]["s2cl_seconds"] for a in singles)
    return {"what": SCENES[name][0], "scene": text, "applications": list(singles), "rounds": rounds,
            "median": med, "runs": runs,
            "sum_of_singles": {"wall": total_single, "s2cl_seconds": total_single_s2cl,
                               "phases": {p: sum(med[a]["phases"][p] for a in singles)
                                          for p in med["multi"]["phases"]}},
            "ratio": {"wall": med["multi"]["wall"] / total_single,
                      "s2cl_seconds": med["multi"]["s2cl_seconds"] / total_single_s2cl}}


def _median(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """The median of each figure over the rounds (each phase's on its own)."""
    return {"wall": statistics.median(r["wall"] for r in runs),
            "s2cl_seconds": statistics.median(r["s2cl_seconds"] for r in runs),
            "phases": {p: statistics.median(r["phases"][p] for r in runs) for p in runs[0]["phases"]},
            "calls": runs[0]["calls"]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (medians; default 3)")
    parser.add_argument("--scene", choices=list(SCENES), action="append", help="only these scenes")
    parser.add_argument("--label", default="", help="writes applications-LABEL.json instead")
    args = parser.parse_args(argv)
    from s2cl.cl.runtime import get_runtime

    info = machine_info(get_runtime())
    before = load_average()
    t0 = time.perf_counter()
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="s2cl-bench-applications-") as tmp:
        for name in args.scene or list(SCENES):
            print(f"scene {name}: {SCENES[name][0]}", flush=True)
            try:
                out[name] = bench_scene(name, SCENES[name][1], args.rounds, Path(tmp))
            except BenchValidationError as err:
                print(f"INVALID: {err}")
                return 1
            r = out[name]
            print(f"  multi / sum of singles: wall {r['ratio']['wall']:.3f}, s2cl timer "
                  f"{r['ratio']['s2cl_seconds']:.3f}", flush=True)
    after = load_average()
    path = RESULTS / (f"applications-{args.label}.json" if args.label else OUTPUT.name)
    write_json(path, {"machine": info, "command": "python -m bench.bench_applications"
                      + (f" --label {args.label}" if args.label else "") + f" --rounds {args.rounds}",
                      "seconds": time.perf_counter() - t0, "load_average_start": list(before),
                      "load_average_end": list(after), "load_note": load_note(before, after, info["cores"]),
                      "scenes": out})
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


# -- the generated block of docs/applications.md ------------------------------------------------------------------

#: the results file measured before the sharing: this benchmark run with ``--label before`` on the code of
#: :data:`BEFORE_COMMIT`, the commit before it
BEFORE = RESULTS / "applications-before.json"
BEFORE_COMMIT = "1ed1db1"


def cost_block() -> str:
    """``applications.cost``: per scene, each phase's median seconds in the multi-application run and summed over
    its applications' own runs, the totals and their ratio, and the ratio before the sharing."""
    import json

    from bench.doc_tables import md_table

    r = json.loads(OUTPUT.read_text(encoding="utf-8"))
    before = json.loads(BEFORE.read_text(encoding="utf-8")) if BEFORE.exists() else None
    names = list(r["scenes"])
    head = ["phase (median s)"]
    for n in names:
        k = len(r["scenes"][n]["applications"])
        head += [f"`{n}`: one run", f"`{n}`: {k} own runs"]
    phases = list(r["scenes"][names[0]]["median"]["multi"]["phases"])
    rows = []
    for p in phases:
        row = [p]
        for n in names:
            s = r["scenes"][n]
            row += [f"{s['median']['multi']['phases'][p]:.2f}", f"{s['sum_of_singles']['phases'][p]:.2f}"]
        rows.append(row)
    for label, key in (("**total, wall clock**", "wall"), ("total, s2cl's own timer (`summary.json` seconds)",
                                                             "s2cl_seconds")):
        row = [label]
        for n in names:
            s = r["scenes"][n]
            row += [f"**{s['median']['multi'][key]:.2f}**" if key == "wall" else f"{s['median']['multi'][key]:.2f}",
                    f"**{s['sum_of_singles'][key]:.2f}**" if key == "wall" else f"{s['sum_of_singles'][key]:.2f}"]
        rows.append(row)
    lines = []
    for n in names:
        s = r["scenes"][n]
        was = before["scenes"][n]["ratio"] if before and n in before["scenes"] else None
        lines.append(f"- `{n}`: {s['what']}. One run ÷ the sum of the own runs: **{s['ratio']['wall']:.2f}** wall "
                     f"clock, {s['ratio']['s2cl_seconds']:.2f} by s2cl's timer"
                     + (f" (before the sharing: {was['wall']:.2f} and {was['s2cl_seconds']:.2f})." if was else "."))
    def extra(n: str) -> float:
        return sum(r["scenes"][n]["median"]["multi"]["phases"][p] for p in ("joint table", "trade-off"))

    def without(n: str) -> float:
        s = r["scenes"][n]
        return (s["median"]["multi"]["wall"] - extra(n)) / s["sum_of_singles"]["wall"]

    return (md_table(head, rows) + "\n\n" + "\n".join(lines)
            + "\n\nThe one run does work the own runs do not: the joint table and the trade-off (margins, front, "
            f"`pareto` column, `pareto.png`; {', '.join(f'{extra(n):.2f} s in `{n}`' for n in names)}); without "
            f"them, one run ÷ the sum of the own runs is {'; '.join(f'{without(n):.2f} in `{n}`' for n in names)}. "
            "Copies 100, seed 1; medians "
            f"of {r['scenes'][names[0]]['rounds']} interleaved rounds, each run with empty kernel and program caches "
            f"(PoCL's disk cache kept, as between processes); {r['machine']['cpu']}, {r['machine']['cores']} cores, "
            f"{r['machine']['date'][:10]}; {r['load_note']}. Measured by `{r['command']}` into "
            f"`{OUTPUT.relative_to(OUTPUT.parents[2]).as_posix()}`"
            + (f"; before: the same benchmark run on s2cl {BEFORE_COMMIT} (the commit before the sharing), into "
               f"`{BEFORE.relative_to(BEFORE.parents[2]).as_posix()}`" if before else "") + ".")


BLOCKS = {"applications.cost": cost_block}
