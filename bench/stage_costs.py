"""What the forward chain's per-band calibration error and inter-band crosstalk (s2cl/forward/stages.py) cost and
change: each stage's time on the forward chain (the sense kernel of a library simulation) and inside the fused
sweep kernel, against the chain without it; and the Table 3 Lib1 B4567 winner (IGRM Cab) and its RMS with each on.

- **Cost**: the sense kernel on 13 bands × the default scene's 120 spectra × 1,000 copies, and the sweep kernel on the
  block of configurations ``bench.bench_sweep`` times (whole, and its ``no_fit`` profile build: the stages without
  the fit), each stage alone against the chain without it, in interleaved rounds (medians); and the fit's mean
  iterations there, which a stage moves by changing the reflectance (the whole kernel's time follows them).
- **Winner**: the exhaustive sweep of ``table3-lib1-b4567`` without a new stage, with a 5 % calibration uncertainty
  drawn once per band, and with 0.2 % crosstalk among the design's bands; then, by the halving search (which finds
  the sweep's winner, docs/search.md, and is checked against the exhaustive rows here), a calibration error of 1, 3
  and 5 % on each band in turn and 1 % crosstalk: the best design, its RMS, and whether it moved.

Nothing here asserts a timing; the machine may be shared (load averages recorded). Run from the repository root:

    python -m bench.stage_costs             # about 15 minutes on 2 cores
    python -m bench.stage_costs --quick     # costs on a smaller block; winners by the search alone
    python -m bench.stage_costs --costs-only   # the costs again (the results file's winners kept)

Writes bench/results/stage-costs.json; its figures reach docs/sensor.md through ``python -m bench.doc_blocks
stages.costs stages.table3``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.bench_sweep import KERNEL_BLOCK
from bench.common import RESULTS, interleaved_medians, load_average, machine_info, write_json
from s2cl.app.chain_parts import scene_simulator
from s2cl.app.optimise import optimise
from s2cl.app.plan import plan_sweep
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.scene.library import scene_library
from s2cl.scene.scene import Scene
from s2cl.scene.terms import scene_atmosphere
from s2cl.sweep.kernel import SweepKernel

OUTPUT = RESULTS / "stage-costs.json"
SCENE = "table3-lib1-b4567"
#: each new stage as it is costed and as it is on in the exhaustive sweep
STAGES: dict[str, dict[str, Any]] = {"calibration_error": {"uncertainty": 0.05}, "crosstalk": {"coefficient": 0.002}}
LEVELS = (0.01, 0.03, 0.05)


def with_effects(name: str, effects: dict[str, Any], search: bool = False) -> Scene:
    """The built-in scene ``name`` with those [effects] keys (and the halving search)."""
    base = Scene.load(name)
    data = base.spec.model_dump(exclude_none=True)
    data["effects"] = {**data["effects"], **effects}
    if search:
        data["sweep"]["search"] = "halving"
    data.get("output", {}).pop("precision", None)
    return Scene.from_dict(data, path=base.path, base_dir=base.base_dir)


def sweep_costs(rt: Runtime, configs: int, rounds: int) -> dict[str, Any]:
    """Seconds of the sweep kernel on ``configs`` configurations from a third of the way in, without a new stage and
    with each alone: the whole kernel and its ``no_fit`` build."""
    jobs = {"none": plan_sweep(Scene.load(SCENE)),
            **{n: plan_sweep(with_effects(SCENE, {n: s})) for n, s in STAGES.items()}}
    t = jobs["none"].tables
    lo = t.n_configs // 3
    hi = min(lo + configs, t.n_configs)
    out: dict[str, Any] = {"configurations": hi - lo, "pixels": t.n_pixels}
    for build, profile in (("kernel", frozenset()), ("no_fit", frozenset({"no_fit"}))):
        kernels = {n: SweepKernel(j.tables, j.analysis, rt, precision=j.precision, profile=profile)
                   for n, j in jobs.items()}
        times = interleaved_medians([lambda k=k: k(lo, hi) for k in kernels.values()], repeat=rounds, warmup=1)
        out[build] = dict(zip(kernels, times, strict=True))
    # the whole kernel's time follows the fit's iterations, which a stage moves by changing the reflectance
    out["iterations"] = {}
    for n, j in jobs.items():
        raw = SweepKernel(j.tables, j.analysis, rt, precision=j.precision, profile=frozenset({"iterations"}))(lo, hi)
        out["iterations"][n] = float(np.mean(raw.condition))
    return out


def forward_costs(rt: Runtime, copies: int, rounds: int) -> dict[str, Any]:
    """Seconds of the sense kernel (noise → … → correction, library simulation) on the default scene's band radiance
    × ``copies``, without a new stage and with each alone."""
    scenes = {"none": Scene.load("default"), **{n: with_effects("default", {n: s}) for n, s in STAGES.items()}}
    lib = scene_library(scenes["none"])
    sims = {n: scene_simulator(rt, s, atmosphere=scene_atmosphere(s)) for n, s in scenes.items()}
    radiance = np.repeat(sims["none"].band_radiance(lib.spectra), copies, axis=1)
    times = interleaved_medians([lambda s=s: s.sense(radiance, seed=1) for s in sims.values()], repeat=rounds,
                                warmup=1)
    return {"bands": int(radiance.shape[0]), "pixels": int(radiance.shape[1]), "sense": dict(zip(sims, times,
                                                                                                 strict=True))}


def winner(label: str, effects: dict[str, Any], search: bool, folder: Path) -> dict[str, Any]:
    """The best design of the scene with ``effects``, its RMS and how it was found."""
    t0 = time.perf_counter()
    how = "search" if search else "sweep"
    result = optimise(with_effects(SCENE, effects, search), folder / f"{label}-{how}".replace(" ", "_"))
    best = result.best or {}
    return {"label": label, "effects": effects, "how": how,
            "bands": best.get("bands"), "rms": best.get("rms"), "seconds": time.perf_counter() - t0}


def winners(quick: bool) -> list[dict[str, Any]]:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for label, effects in (("none", {}), ("calibration uncertainty 5 %", {"calibration_error": {
                "uncertainty": 0.05}}), ("crosstalk 0.2 %", {"crosstalk": {"coefficient": 0.002}})):
            if not quick:
                rows.append(winner(label, effects, False, folder))
            rows.append(winner(label, effects, True, folder))
        for band in ("B4", "B5", "B6", "B7"):
            for level in LEVELS:
                rows.append(winner(f"{band} +{level:.0%}", {"calibration_error": {"bands": {band: level}}}, True,
                                   folder))
        rows.append(winner("crosstalk 1 %", {"crosstalk": {"coefficient": 0.01}}, True, folder))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="a smaller block; winners by the search alone")
    ap.add_argument("--output", type=Path, default=OUTPUT)
    ap.add_argument("--costs-only", action="store_true", help="measure the costs again, keep the output's winners")
    args = ap.parse_args()
    rt = get_runtime()
    result: dict[str, Any] = {"benchmark": "stage-costs", "machine": machine_info(rt), "scene": SCENE,
                              "stages": STAGES, "load_average_start": load_average()}
    if args.costs_only:
        result = {**json.loads(args.output.read_text()), **result}
    result["forward"] = forward_costs(rt, 10 if args.quick else 1000, 3 if args.quick else 7)
    print("forward:", result["forward"], flush=True)
    result["sweep"] = sweep_costs(rt, KERNEL_BLOCK // 6 if args.quick else KERNEL_BLOCK, 3 if args.quick else 7)
    print("sweep:", result["sweep"], flush=True)
    if not args.costs_only:
        result["winners"] = winners(args.quick)
        for row in result["winners"]:
            print(row, flush=True)
    result["load_average_end"] = load_average()
    print("wrote", write_json(args.output.resolve(), result))


if __name__ == "__main__":
    main()
