"""How close the sweep's float32 IGRM fits come to the float64 optimum, per library, at the defaults.

For sampled configurations of a sweep scene, the fused sweep kernel runs twice on the same pixels
and noise draws: float32 with the scene's IGRM settings (what a sweep reports), and float64 with a
tight fit (tol 1e-10, 1000 iterations) as the optimum. Reported per library: the fraction of fitted
pixels whose lp lies within 1e-3 nm (the accuracy the docs quote), 0.01 nm and 0.05 nm of that
optimum, the worst difference, and the same split by the float32 fit's status: CONVERGED fits are
the ones whose Gauss-Newton step says they sit at the optimum; STALLED and ITERATION_LIMIT fits are
not (kernels/common/igrm_lm.mako). Pixels whose float64 fit is not CONVERGED are left out (no
optimum to compare with) and counted. Writes bench/results/igrm-accuracy-<machine>-<date>.json.

    python -m bench.igrm_accuracy                 # Lib1 (default) and Lib2 (table3-lib2-b4568), 24 configurations each
    python -m bench.igrm_accuracy --configs 8     # quicker
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from typing import Any

import numpy as np

from bench.common import load_average, load_note, machine_info, write_result
from s2cl.app.plan import plan_sweep
from s2cl.cl.runtime import get_runtime
from s2cl.scene.scene import Scene
from s2cl.status import Status
from s2cl.sweep.kernel import SweepKernel

SCENES = {"Lib1": "default", "Lib2": "table3-lib2-b4568"}
TIGHT = {"tol": 1e-10, "max_iter": 1000, "residual_floor": 1e-12}
TOLERANCES_NM = (1e-3, 1e-2, 5e-2)


def _fractions(err: np.ndarray) -> dict[str, float]:
    out = {f"within_{t:g}_nm": float(np.mean(err <= t)) if err.size else float("nan") for t in TOLERANCES_NM}
    out["max_nm"] = float(err.max()) if err.size else float("nan")
    out["pixels"] = int(err.size)
    return out


def measure(scene: str, n_configs: int, seed: int = 0) -> dict[str, Any]:
    """Float32 against float64-optimum lp on ``n_configs`` configurations of ``scene``."""
    job = plan_sweep(Scene.load(scene))
    t = job.tables
    tight = replace(job.analysis, igrm=tuple(sorted({**dict(job.analysis.igrm), **TIGHT}.items())))
    k32 = SweepKernel(t, job.analysis, get_runtime(), precision="float32")
    k64 = SweepKernel(t, tight, get_runtime(), precision="float64")
    configs = np.sort(np.random.default_rng(seed).choice(t.n_configs, size=min(n_configs, t.n_configs),
                                                         replace=False))
    errs, status32, ok64 = [], [], []
    for c in configs:
        a, b = k32(int(c), int(c) + 1), k64(int(c), int(c) + 1)
        errs.append(np.abs(a.index[0] - b.index[0]))
        status32.append(a.status[0])
        ok64.append(b.status[0] == Status.OK)
    err, st, ok = np.concatenate(errs), np.concatenate(status32), np.concatenate(ok64)
    fitted = np.isin(st, (Status.OK, Status.STALLED, Status.ITERATION_LIMIT)) & ok
    out: dict[str, Any] = {"scene": scene, "configurations": configs.tolist(), "pixels": int(err.size),
                           "float64_not_converged": int((~ok).sum()), "all_fitted": _fractions(err[fitted])}
    for name, code in (("converged", Status.OK), ("stalled", Status.STALLED),
                       ("iteration_limit", Status.ITERATION_LIMIT)):
        sel = fitted & (st == code)
        out[name] = {"share_of_fitted": float(sel.sum() / max(fitted.sum(), 1)), **_fractions(err[sel])}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--configs", type=int, default=24, help="configurations sampled per library")
    args = ap.parse_args()
    start = load_average()

    result: dict[str, Any] = {"benchmark": "igrm_accuracy", "machine": machine_info(get_runtime()),
                              "reference": {"precision": "float64", **TIGHT}, "libraries": {}}
    for lib, scene in SCENES.items():
        r = measure(scene, args.configs)
        result["libraries"][lib] = r
        a, c = r["all_fitted"], r["converged"]
        print(f"{lib} ({scene}): {a['pixels']:,} fitted pixels: within 1e-3 nm {a['within_0.001_nm']:.2%}, "
              f"0.05 nm {a['within_0.05_nm']:.2%}, worst {a['max_nm']:.3g} nm; CONVERGED {c['share_of_fitted']:.2%} "
              f"of them, {c['within_0.001_nm']:.3%} within 1e-3 nm; stalled {r['stalled']['share_of_fitted']:.2%}, "
              f"iteration limit {r['iteration_limit']['share_of_fitted']:.2%}", flush=True)
    result["load_note"] = load_note(start, load_average())
    print("wrote", write_result("igrm-accuracy", result))


if __name__ == "__main__":
    main()
