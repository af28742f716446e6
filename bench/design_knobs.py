"""Design-level accuracy against time: does the ranking of band designs survive a cheaper sweep?

Each knob that can make ``s2cl optimise`` cheaper is moved alone from the default scene (Lib1, 120
PROSAIL canopies × 100 noisy copies, IGRM chlorophyll, B4 B5 B6 B8 moved over the Table 2 ranges on a 5 nm
grid: 3,312 configurations), the whole sweep is run through the Python API (:func:`s2cl.app.plan.plan_sweep`
and :func:`s2cl.sweep.engine.run_sweep`, into a temporary folder), and its ranking of the designs by Cab RMS
(µg/cm², rankable designs only) is compared with the knob's reference run (:mod:`bench.design_rank`):
Spearman ρ, whether the winner changes, the reference's rank of the cheap run's winner, the regret and
max |ΔRMS|. Knobs: the sweep step (against a 2.5 nm reference, on the designs both grids hold), the library
density (every n-th spectrum, through the API: no scene key selects a subset), noise copies, precision
(against float64), IGRM iterations and the atmosphere LUT's nodes and interpolation.

Time: wall time of ``plan_sweep`` + ``run_sweep`` (tables, kernel, metrics, Parquet), median of ``--repeat``
runs (default 3; ``--quick`` 2) timed in interleaved rounds so that drift in the machine's load hits every
setting alike; each setting is planned and its first chunk run once, untimed, first (kernels compiled and
loaded, as in any run after the first). The sweep kernel is validated against the float64 numpy evaluator
before anything is timed (:func:`bench.sweep_check.validate_sweep`). Nothing here asserts a timing.

    python -m bench.design_knobs             # full (4-10 min on 2 cores; 2.5 nm step: 117,425 designs):
                                             # bench/results/design-knobs.{json,md,png},
                                             # docs/bench/design-knobs.png and its section of docs/bench.md
    python -m bench.design_knobs --quick     # tiny (300 pixels, 5 nm step reference; seconds)
    python -m bench.design_knobs --report bench/results/design-knobs.json   # re-render Markdown, plot, docs
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import json
import shutil
import statistics
import tempfile
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import RESULTS, check, load_average, load_note, machine_info
from bench.design_rank import compare, ranked

SCENE = "default"
STEP_DEFAULT = 5.0  # the default scene's [sweep] step_nm


@dataclass(frozen=True)
class Run:
    """One sweep: the scene's ``{"section.key[.key]": value}`` overrides, every ``every``-th library spectrum,
    and whether the atmosphere is the shipped LUT with every other node dropped (``thin_lut``)."""

    overrides: tuple[tuple[str, Any], ...] = ()
    every: int = 1
    thin_lut: bool = False

    @property
    def name(self) -> str:
        parts = [f"{k}={v}" for k, v in self.overrides] + ([f"library every {self.every}"] if self.every > 1 else [])
        return ", ".join(parts + (["thinned LUT"] if self.thin_lut else [])) or "default scene"


DEFAULT = Run()


@dataclass(frozen=True)
class Row:
    """A knob's setting: its label, its run and whether it is the shipped setting."""

    setting: str
    run: Run
    default: bool = False


@dataclass(frozen=True)
class Knob:
    key: str
    title: str
    reference: Row
    rows: tuple[Row, ...]
    note: str = ""


@dataclass(frozen=True)
class Sizes:
    """What every run shares (``base`` overrides, library stride ``every``) and the knobs' values."""

    quick: bool
    base: tuple[tuple[str, Any], ...]
    every: int
    steps: tuple[float, ...]  # the first is the step knob's reference
    copies: tuple[int, int, int]  # the reference (the base's copies) and two cheaper settings
    repeat: int


FULL = Sizes(False, (), 1, (2.5, 5.0, 10.0), (100, 30, 10), 3)
QUICK = Sizes(True, (("surface.copies", 10),), 4, (5.0, 10.0), (10, 5, 2), 2)


def _nth(k: int) -> str:
    return {2: "2nd", 3: "3rd"}.get(k, f"{k}th")


def knobs(sizes: Sizes) -> list[Knob]:
    """The knobs, each moved alone from the default scene (``sizes`` applied to every run)."""

    def step(s: float) -> Row:
        return Row(f"{s:g} nm", DEFAULT if s == STEP_DEFAULT else Run((("sweep.step_nm", s),)), s == STEP_DEFAULT)

    ref_copies, *fewer = sizes.copies
    return [
        Knob("step", "Sweep step ([sweep] step_nm)", step(sizes.steps[0]), tuple(step(s) for s in sizes.steps[1:]),
             "Compared on the designs both grids hold (every design of the coarser grid lies on the finer one). A "
             "design's noise draws do not depend on the grid it is swept in (common random numbers), so on those "
             "designs the RMS is the same and ρ = 1, ΔRMS = 0 by construction: a coarser step changes which "
             "designs exist, i.e. the winner and its regret."),
        Knob("library", "Library density (every n-th spectrum)", Row("every spectrum", DEFAULT, True),
             tuple(Row(f"every {_nth(k)} spectrum", Run(every=k)) for k in (2, 4)),
             "A subset of Lib1 through the Python API (no scene key selects one; from the CLI, a CSV library of "
             "the subset does the same). The RMS is over fewer canopies, so ΔRMS includes that sampling."),
        Knob("copies", "Noise copies per spectrum ([surface] copies)", Row(f"{ref_copies} copies", DEFAULT, True),
             tuple(Row(f"{c} copies", Run((("surface.copies", c),))) for c in fewer),
             "Fewer noise draws behind each design's RMS."),
        Knob("precision", "Precision ([compute] precision)", Row("float64", Run((("compute.precision", "float64"),))),
             (Row("float32", DEFAULT, True),)),
        Knob("igrm", "IGRM iterations ([analysis] igrm = { max_iter = N })", Row("max_iter 50", DEFAULT, True),
             tuple(Row(f"max_iter {m}", Run((("analysis.igrm.max_iter", m),))) for m in (20, 10))),
        Knob("lut", "Atmosphere LUT nodes and interpolation ([atmosphere] lut, interpolation)",
             Row("every node, linear", DEFAULT, True),
             (Row("every other node, linear", Run(thin_lut=True)),
              Row("every other node, nearest", Run((("atmosphere.interpolation", "nearest"),), thin_lut=True))),
             "Every other node of each axis of the shipped LUT dropped, the paper's atmosphere's nodes among them "
             "(as in bench/knobs.py's LUT knob). The LUT is interpolated once per scene on the host, so it "
             "cannot make a sweep cheaper: its times differ only by the machine's noise."),
    ]


# -- running sweeps ----------------------------------------------------------------------------------

def _set(data: dict[str, Any], dotted: str, value: Any) -> None:
    *path, key = dotted.split(".")
    for part in path:
        data = data.setdefault(part, {})
    data[key] = value


@dataclass
class Planner:
    """Scenes and sweep jobs of runs: the default scene with the base and the run's overrides."""

    sizes: Sizes
    lut_path: Path | None = None

    def __post_init__(self) -> None:
        from s2cl.scene.scene import find_scene

        self.scene_path = find_scene(SCENE)
        self.toml = tomllib.loads(self.scene_path.read_text("utf-8"))

    def scene(self, run: Run) -> Any:
        from s2cl.scene.scene import Scene

        data = copy.deepcopy(self.toml)
        for k, v in (*self.sizes.base, *run.overrides):
            _set(data, k, v)
        if run.thin_lut:
            check(self.lut_path is not None, "no thinned LUT written")
            _set(data, "atmosphere.lut", str(self.lut_path))
        return Scene.from_dict(data, path=self.scene_path)

    def job(self, run: Run) -> Any:
        from s2cl.app.checks import check_sweep
        from s2cl.app.plan import plan_sweep

        scene = self.scene(run)
        checked = check_sweep(scene)
        every = self.sizes.every * run.every
        if every > 1:
            assert checked.library is not None
            checked = dataclasses.replace(checked, library=checked.library.subset(range(0, checked.library.size,
                                                                                         every)))
        return plan_sweep(scene, checked=checked)


def write_thin_lut(folder: Path, planner: Planner) -> Path:
    """The shipped LUT with every other node of its AOT, SZA and H2O axes dropped, the nodes of the paper's
    atmosphere among them (:func:`bench.knobs._thin`), as ``folder/lut-thin.npz``."""
    from bench.knobs import _thin
    from s2cl.atmos.atmosphere import default_lut_path
    from s2cl.scene.terms import scene_lut, true_state

    scene = planner.scene(DEFAULT)
    ax, state = scene_lut(scene).axes, true_state(scene)
    nodes = {"aot550": int(np.argmin(np.abs(ax.aot550 - state.aot550))),
             "solar_zenith": int(np.argmin(np.abs(ax.solar_zenith - state.solar_zenith))),
             "water_vapour": int(np.argmin(np.abs(ax.water_vapour - state.water_vapour)))}
    with np.load(default_lut_path(), allow_pickle=False) as npz:
        arrays = {k: np.asarray(npz[k]) for k in npz.files}
    for axis, node in nodes.items():
        arrays = _thin(arrays, axis, node)
    path = folder / "lut-thin.npz"
    np.savez(path, **arrays)  # a private temporary folder: no atomic write needed
    return path


@dataclass
class Measured:
    """A run's timings (seconds), sizes and rankings (first and last repeat)."""

    times: list[float]
    configurations: int
    pixels: int
    spectra: int
    first: Any
    last: Any


def _sweep(planner: Planner, run: Run, folder: Path) -> tuple[float, Any, Any]:
    """One timed sweep (plan + run, the kernel rebuilt from the binary cache): seconds, ranking, job."""
    import pandas as pd

    import s2cl.sweep.engine as engine

    engine._EVALUATORS.clear()  # every timed run builds its kernel, as a new `s2cl optimise` would
    t0 = time.perf_counter()
    job = planner.job(run)
    path = engine.run_sweep(job, folder)
    seconds = time.perf_counter() - t0
    frame = ranked(pd.read_parquet(path), job.underdetermined)
    shutil.rmtree(folder)
    return seconds, frame, job


def measure(planner: Planner, runs: list[Run], repeat: int, tmp: Path) -> dict[Run, Measured]:
    """Every run ``repeat`` times in interleaved rounds, after an untimed warm-up of each: its plan and its first
    chunk (the kernels built and run once, so that no timed run pays a first compilation)."""
    from s2cl.sweep.engine import evaluate_chunk

    for run in runs:
        job = planner.job(run)
        evaluate_chunk(job, *job.chunks()[0])
    out: dict[Run, Measured] = {}
    for r in range(repeat):
        for i, run in enumerate(runs):
            seconds, frame, job = _sweep(planner, run, tmp / f"sweep-{i}-{r}")
            print(f"[design-knobs] round {r + 1}/{repeat}: {run.name}: {job.n_configs:,} configurations × "
                  f"{job.tables.n_pixels:,} pixels, {seconds:.1f} s", flush=True)
            if run in out:
                out[run].times.append(seconds)
                out[run].last = frame
            else:
                out[run] = Measured([seconds], job.n_configs, job.tables.n_pixels, job.tables.n_spectra, frame,
                                    frame)
    return out


def _timing(m: Measured) -> dict[str, Any]:
    """Times (s), sizes, and how far the last repeat's RMS are from the first's (a sweep is deterministic: 0)."""
    return {"seconds": statistics.median(m.times), "seconds_min": min(m.times), "seconds_max": max(m.times),
            "times": m.times, "configurations": m.configurations, "pixels": m.pixels, "spectra": m.spectra,
            "repeat_max_abs_delta": compare(m.last, m.first)["max_abs_delta"]}


def knob_result(knob: Knob, measured: dict[Run, Measured]) -> dict[str, Any]:
    """A knob's rows: its reference (its last repeat against its first: the identity check) and each
    setting's first repeat against the reference's first."""
    ref = measured[knob.reference.run]
    rows = [{"setting": knob.reference.setting, "run": knob.reference.run.name, "reference": True,
             "default": knob.reference.default, **_timing(ref), **compare(ref.last, ref.first)}]
    for row in knob.rows:
        m = measured[row.run]
        rows.append({"setting": row.setting, "run": row.run.name, "reference": False, "default": row.default,
                     **_timing(m), **compare(m.first, ref.first)})
    for r in rows:
        r["speedup"] = rows[0]["seconds"] / r["seconds"]
    return {"key": knob.key, "title": knob.title, "reference": knob.reference.setting, "note": knob.note,
            "rows": rows}


def run_all(sizes: Sizes) -> dict[str, Any]:
    """Validate, run every knob's sweeps and compare their rankings: the results (JSON)."""
    from bench.sweep_check import validate_sweep
    from s2cl.cl.runtime import get_runtime

    t_start = time.perf_counter()
    machine = machine_info(get_runtime())
    before = load_average()
    planner = Planner(sizes)
    all_knobs = knobs(sizes)
    with tempfile.TemporaryDirectory(prefix="s2cl-design-knobs-") as folder:
        tmp = Path(folder)
        planner.lut_path = write_thin_lut(tmp, planner)
        reference = planner.job(DEFAULT)
        validation = validate_sweep(reference)
        print(f"[design-knobs] sweep kernel validated: {validation}", flush=True)
        runs = list(dict.fromkeys(r.run for k in all_knobs for r in (k.reference, *k.rows)))
        measured = measure(planner, runs, sizes.repeat, tmp)
    after = load_average()
    return {"benchmark": "design-knobs", "quick": sizes.quick, "machine": machine,
            "load_average": {"before": before, "after": after},
            "load_note": load_note(before, after, machine["cores"]),
            "command": "python -m bench.design_knobs" + (" --quick" if sizes.quick else ""),
            "scene": SCENE, "base": {"overrides": dict(sizes.base), "library_every": sizes.every,
                                     "configurations": reference.n_configs, "pixels": reference.tables.n_pixels},
            "repeat": sizes.repeat, "metric": "rms", "metric_unit": "ug/cm2",
            "timed": "plan_sweep + run_sweep (tables, kernel, metrics, Parquet into a temporary folder) with warm "
                     "kernels (each setting planned and its first chunk run once, untimed, before), median of the "
                     "repeats timed in interleaved rounds",
            "validation": validation, "knobs": [knob_result(k, measured) for k in all_knobs],
            "seconds_total": time.perf_counter() - t_start}


def main(argv: list[str] | None = None) -> int:
    from bench import design_report

    ap = argparse.ArgumentParser(prog="python -m bench.design_knobs", description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="tiny version (300 pixels, 5 nm step reference)")
    ap.add_argument("--repeat", type=int, help="timed runs per setting (default 3, --quick 2)")
    ap.add_argument("--out", type=Path, default=RESULTS, help="results folder (default bench/results)")
    ap.add_argument("--docs", action=argparse.BooleanOptionalAction, default=None,
                    help="rewrite docs/bench/design-knobs.png and the section of docs/bench.md (default: full runs)")
    ap.add_argument("--report", type=Path, metavar="JSON", help="only re-render the Markdown, plot (and docs)")
    args = ap.parse_args(argv)
    if args.report:
        results = json.loads(args.report.read_text("utf-8"))
        out, stem = args.report.parent, args.report.stem
    else:
        sizes = QUICK if args.quick else FULL
        if args.repeat:
            sizes = dataclasses.replace(sizes, repeat=args.repeat)
        results = run_all(sizes)
        out, stem = args.out, "design-knobs" + ("-quick" if sizes.quick else "")
        out.mkdir(parents=True, exist_ok=True)
        print("[design-knobs] wrote", design_report.write_json_result(out / f"{stem}.json", results))
    docs = args.docs if args.docs is not None else not results["quick"]
    for p in design_report.write_reports(results, out, stem, docs=docs):
        print("[design-knobs] wrote", p)
    print(f"[design-knobs] total {results['seconds_total']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
