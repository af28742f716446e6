"""Pixels per work-item: each vectorised kernel at 4, 8 and 16 lanes on this machine's device.

The runtime's default is the device's native vector width (PoCL: 16 floats with AVX-512, 8 with
AVX2; :func:`s2cl.cl.devices.choose_lanes`). This script measures whether that is the right choice
here: IGRM fits (kernel alone), the fused sweep kernel of the default scene, GVMI, SAM, and the
resampler's vector-load width and its spectra per work-item (1-16, read interleaved). Every width is
first checked bit-identical to one pixel per work-item (the resampler: against its float64 oracle;
the one-lane sweep kernel itself by :func:`bench.sweep_check.validate_sweep`), then all widths are
timed in interleaved rounds (medians). Widths above the native one are capped by the runtime and not timed.
Writes bench/results/lanes-<machine>-<date>.json.

    python -m bench.bench_lanes            # ~1 minute on 2 cores
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

import numpy as np

from bench.common import check, interleaved_medians, load_average, load_note, machine_info, write_result
from s2cl.cl.runtime import Runtime, get_runtime

WIDTHS = (4, 8, 16)


Runs = tuple[dict[int, Callable[[], Any]], int, str, int]  # runs by width, items per run, unit, default


def _igrm(rt: Runtime, n: int) -> Runs:
    from bench.bench_igrm import kernel_launcher
    from s2cl.reference.igrm_cases import BANDS_4, band_centres, prosail_population
    from s2cl.retrieve.igrm import IgrmFitter

    wl = band_centres(BANDS_4)
    y = prosail_population(n, BANDS_4, noise=0.003, seed=1)[0].astype(np.float32)
    one = IgrmFitter(rt, 4, lanes=1).fit(y[:, :4096], wl)
    runs = {}
    for w in WIDTHS:
        f = IgrmFitter(rt, 4, lanes=w)
        r = f.fit(y[:, :4096], wl)
        check(bool(np.array_equal(r.lp, one.lp) and np.array_equal(r.status, one.status)),
              f"IGRM at {w} lanes differs from one lane")
        runs[w] = kernel_launcher(f, y, wl)[0]
    return runs, y.shape[1] // 16 * 16, "fits", IgrmFitter(rt, 4).types.lanes


def _sweep(rt: Runtime) -> Runs:
    from bench.sweep_check import validate_sweep
    from s2cl.app.plan import plan_sweep
    from s2cl.scene.scene import Scene
    from s2cl.sweep.kernel import SweepKernel

    job = plan_sweep(Scene.load("default"))
    lo, hi = job.n_configs // 3, job.n_configs // 3 + 48
    one_lane = SweepKernel(job.tables, job.analysis, rt, lanes=1)
    validate_sweep(job, one_lane)  # against the float64 evaluator; every width then against one lane
    one = one_lane(lo, lo + 4)
    runs = {}
    for w in WIDTHS:
        k = SweepKernel(job.tables, job.analysis, rt, lanes=w)
        got = k(lo, lo + 4)
        check(bool(np.array_equal(got.index, one.index) and np.array_equal(got.status, one.status)),
              f"sweep kernel at {w} lanes differs from one lane")
        runs[w] = (lambda k=k: k(lo, hi))
    default = SweepKernel(job.tables, job.analysis, rt).T.lanes
    return runs, (hi - lo) * job.tables.n_pixels, "configuration-pixels", default


def _gvmi_sam(rt: Runtime, n: int) -> dict[str, Runs]:
    from s2cl.retrieve.index_kernel import IndexKernel
    from s2cl.retrieve.sam import SamClassifier

    rng = np.random.default_rng(3)
    refl = rng.uniform(0.02, 0.6, (6, n)).astype(np.float32)
    refs = rng.uniform(0.05, 0.6, (12, 6))
    g1, s1 = IndexKernel(rt, "gvmi", lanes=1)(refl, 1, 2), SamClassifier(rt, refs, lanes=1).classify(refl)
    gvmi, sam = {}, {}
    for w in WIDTHS:
        g, s = IndexKernel(rt, "gvmi", lanes=w), SamClassifier(rt, refs, lanes=w)
        check(bool(np.array_equal(g(refl, 1, 2).index, g1.index)), f"GVMI at {w} lanes differs from one lane")
        check(bool(np.array_equal(s.classify(refl).reference, s1.reference)), f"SAM at {w} lanes differs")
        gvmi[w] = (lambda g=g: g(refl, 1, 2))
        sam[w] = (lambda s=s: s.classify(refl))
    return {"gvmi": (gvmi, n, "pixels", IndexKernel(rt, "gvmi").types.lanes),
            "sam": (sam, n, "pixels", SamClassifier(rt, refs).types.lanes)}


def _resample(rt: Runtime, n: int) -> Runs:
    from s2cl.forward.resample import ResamplePlan, Resampler
    from s2cl.grid import DEFAULT_GRID
    from s2cl.reference import forward as ref
    from s2cl.sensor.sensor import Sensor

    bands = Sensor.sentinel2().bands
    plan = ResamplePlan(tuple(b.name for b in bands), tuple(b.weights(DEFAULT_GRID) for b in bands), DEFAULT_GRID.size)
    spectra = np.random.default_rng(0).uniform(0.0, 100.0, (n, DEFAULT_GRID.size)).astype(np.float32)
    want = ref.resample(spectra[:1000].astype(np.float64), plan.weights)
    runs = {}
    for w in WIDTHS:
        r = Resampler(rt, plan, "float32", vector_width=w)
        err = np.max(np.abs(r(spectra[:1000]) - want) / np.abs(want).max(axis=1, keepdims=True))
        check(err < 2e-6, f"resampler at vector width {w}: max relative error {err:.3g}")
        runs[w] = (lambda r=r: r(spectra))
    return runs, n, "spectra", Resampler(rt, plan, "float32").vw


ROWS = (1, 2, 4, 8, 16)


def _resample_rows(rt: Runtime, n: int) -> Runs:
    """The resampler at its default vector width with 1-16 spectra per work-item (read interleaved)."""
    from s2cl.forward.resample import ResamplePlan, Resampler
    from s2cl.grid import DEFAULT_GRID
    from s2cl.sensor.sensor import Sensor

    plan = ResamplePlan.of(Sensor.sentinel2().bands, DEFAULT_GRID)
    spectra = np.random.default_rng(0).uniform(0.0, 100.0, (n, DEFAULT_GRID.size)).astype(np.float32)
    one = Resampler(rt, plan, "float32", rows_per_item=1)
    base = one(spectra[:1000])
    runs = {}
    for rows in ROWS:
        r = Resampler(rt, plan, "float32", rows_per_item=rows)
        check(bool(np.array_equal(r(spectra[:1000]), base)), f"{rows} rows per work-item differ from one")
        runs[rows] = (lambda r=r: r(spectra))
    return runs, n, "spectra", Resampler(rt, plan, "float32").rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    rt = get_runtime()
    native = rt.native_lanes("float32")
    widths = [w for w in WIDTHS if w <= native or "CPU" not in rt.info.kind]
    families = {"igrm": _igrm(rt, 400_000), "sweep": _sweep(rt), **_gvmi_sam(rt, 2_000_000),
                "resample (vector-load width)": _resample(rt, 100_000),
                "resample (spectra per work-item)": _resample_rows(rt, 100_000)}
    start = load_average()
    result: dict[str, Any] = {"benchmark": "lanes", "machine": machine_info(rt), "float32_native_width": native,
                              "families": {}}
    for name, (runs, items, unit, default) in families.items():
        keys = list(runs) if "per work-item" in name else widths
        secs = interleaved_medians([runs[w] for w in keys], repeat=args.repeat, warmup=1)
        rates = {w: items / s for w, s in zip(keys, secs, strict=True)}
        best = max(rates, key=rates.get)
        result["families"][name] = {"unit": f"{unit}/s", "rate": rates, "best_width": best, "default_width": default,
                                    "default_over_best": rates[default] / rates[best],
                                    "ratio_16_over_8": rates[16] / rates[8] if {8, 16} <= rates.keys() else None}
        print(f"{name:30s} " + "  ".join(f"{w:2d}: {r / 1e6:8.3f} M{unit}/s" for w, r in rates.items())
              + f"   best {best}, default {default}", flush=True)
    result["load_note"] = load_note(start, load_average())
    print(result["load_note"])
    print("wrote", write_result("lanes", result))


if __name__ == "__main__":
    main()
