"""Why s2cl's Table 4 differs from the paper's: the B4 sweep (table4-b4, 70 configurations) under
changed fit settings, noise, correction and library, and under fit *definitions* the paper may have
used, each measured on the same simulated pixels.

Variants run through the sweep engine (OpenCL, float32) with one scene key changed:

- ``default``: the built-in scene as shipped;
- ``no-noise``: effects.noise = false (quantisation kept);
- ``wide-bounds``: IGRM l0 600–760 nm, s 2–200 nm, rmin ≥ −1 (practically unbounded);
- ``grid-init``: IGRM initial guess by variable projection over an (l0, s) grid;
- ``soft-l1``: robust loss;
- ``aot-error``: the correction assumes 15 km visibility, the atmosphere has 23 km;
- ``lib2``: the sparse-canopy library (paper: Lib2).

Variants that change the fit's definition run in float64 numpy on the *same* corrected band
reflectances (noise, quantisation, calibration, correction as in the sweep):

- ``l0-at-B4``: l0 fixed at B4's centre, rmin, rmax, s fitted (exact least squares: a fine s grid,
  rmin and rmax linear for each s);
- ``l0-rmin-from-B4``: l0 = B4 centre and rmin = B4's reflectance, rmax and s fitted.

``noise-x3`` and ``noise-x10`` multiply every band's noise σ (the reach of another noise model).
Tables 5 and 6 run with noise off, and Table 6 with the 8 full-range minerals and an AOT error.

Writes bench/results/paper_sensitivity.json and docs/paper/table4_sensitivity.png. Run from the
repository root:

    python -m bench.paper_sensitivity
    python -m bench.paper_sensitivity --plot-only   # redraw the figure from the JSON
"""

from __future__ import annotations

import copy
import json
import sys
import time
import tomllib
from dataclasses import replace
from typing import Any

import numpy as np

from bench.common import RESULTS, ROOT, machine_info, save_figure, write_json
from s2cl.app.plan import plan_sweep
from s2cl.reference.sweep import band_reflectance, variant_indices
from s2cl.retrieve.metrics import regression_metrics
from s2cl.scene.library import scene_library
from s2cl.scene.scene import Scene, find_scene
from s2cl.sweep.engine import SweepJob, evaluate_chunk

RESULT = RESULTS / "paper_sensitivity.json"
FIGURE = ROOT / "docs" / "paper" / "table4_sensitivity.png"
SCENE = "table4-b4"
S_GRID_NM = np.arange(2.0, 200.01, 0.25)
WIDE = {"l0_min_nm": 600.0, "l0_max_nm": 760.0, "s_min_nm": 2.0, "s_max_nm": 200.0, "rmin_min": -1.0}
SCENE_VARIANTS: dict[str, dict[str, Any]] = {
    "default": {},
    "no-noise": {"effects": {"noise": False}},
    "wide-bounds": {"analysis": {"igrm": WIDE}},
    "grid-init": {"analysis": {"igrm": {"init": "grid"}}},
    "soft-l1": {"analysis": {"igrm": {"loss": "soft_l1"}}},
    "aot-error": {"correction": {"visibility_km": 15.0}},
    "lib2": {"surface": {"library": "builtin:lib2"}},
}
FIT_VARIANTS = ("l0-at-B4", "l0-rmin-from-B4")
NOISE_SCALES = (3.0, 10.0)  # the sensor noise σ of every band multiplied (a different noise model's reach)
#: SWIR tables: (scene, moving band, metric) and one-key changes
SWIR = {"table5-b11": ("B11", "rms"), "table6-b12": ("B12", "omission_error_pct")}
SWIR_VARIANTS: dict[str, dict[str, Any]] = {
    "default": {},
    "no-noise": {"effects": {"noise": False}},
}
SAM_VARIANTS: dict[str, dict[str, Any]] = {
    # only the 8 minerals measured over all of 400-2500 nm (3 Al-OH, 5 Mg-OH/C-O) instead of 24
    "minerals-8": {"surface": {"library": "builtin:minerals"}},
    "aot-error": {"correction": {"visibility_km": 15.0}},
}
COLUMNS = ("rms", "robust_rms", "rms_unbounded", "bound_fraction", "failed_fraction", "iteration_limit_fraction")


def _merge(base: dict[str, Any], change: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in change.items():
        out[k] = _merge(out.get(k, {}), v) if isinstance(v, dict) else v
    return out


def scene_variant(change: dict[str, Any], scene: str = SCENE) -> Scene:
    path = find_scene(scene)
    data = _merge(tomllib.loads(path.read_text(encoding="utf-8")), change)
    return Scene.from_dict(data, path=path)


def fixed_l0_fit(rhos: np.ndarray, centres: np.ndarray, rmin_from_b4: bool) -> np.ndarray:
    """λp = l0 + s of the least-squares IGRM with l0 at the first band's centre, per pixel.

    ``rhos`` (n_slots, n_pixels), ``centres`` (n_slots,). For each s on S_GRID_NM the model is
    linear in (rmax, rmin) (or in rmax alone when rmin is the first band's value), so the
    minimum over the grid is the least-squares fit to 0.25 nm in s."""
    d2 = (centres - centres[0]) ** 2
    e = np.exp(-d2[None, :] / (2.0 * S_GRID_NM[:, None] ** 2))  # (n_s, n_slots)
    y = rhos.T  # (n_px, n_slots)
    if rmin_from_b4:
        a = 1.0 - e  # ρ − rmin·e = rmax·(1 − e)
        rmin = y[:, :1]
        yy = y[:, None, :] - rmin[:, :, None] * e[None, :, :]  # (n_px, n_s, n_slots)
        rmax = (yy * a[None]).sum(-1) / np.maximum((a * a).sum(-1), 1e-300)[None]
        cost = ((yy - rmax[..., None] * a[None]) ** 2).sum(-1)
    else:
        # columns (1 − e, e) for (rmax, rmin): 2×2 normal equations per s
        a, b = 1.0 - e, e
        saa, sab, sbb = (a * a).sum(-1), (a * b).sum(-1), (b * b).sum(-1)
        det = saa * sbb - sab**2
        ya, yb = y @ a.T, y @ b.T  # (n_px, n_s)
        rmax = (sbb * ya - sab * yb) / det
        rmin = (saa * yb - sab * ya) / det
        fit = rmax[..., None] * a[None] + rmin[..., None] * b[None]
        cost = ((y[:, None, :] - fit) ** 2).sum(-1)
    return centres[0] + S_GRID_NM[np.argmin(cost, axis=1)]


def fit_variant(job: SweepJob, name: str) -> dict[str, np.ndarray]:
    t = job.tables
    rhos, centres = band_reflectance(t, 0, t.n_configs)
    index = np.empty((t.n_configs, t.n_pixels))
    for i in range(t.n_configs):
        y = np.stack([r[i] for r in rhos])
        for a in range(0, t.n_pixels, 2000):  # pixel blocks keep the (pixels, s grid, bands) arrays small
            index[i, a:a + 2000] = fixed_l0_fit(y[:, a:a + 2000], centres[i], name == "l0-rmin-from-B4")
    zeros = np.zeros(index.shape, np.uint8)
    rows = regression_metrics(index, zeros, zeros, t.target)
    idx = variant_indices(t, 0, t.n_configs)
    rows["B4_centre_nm"], rows["B4_width_nm"] = t.centre[0][idx[:, 0]], t.width[0][idx[:, 0]]
    return rows


def variant_entry(name: str, change: dict[str, Any], rows: dict[str, np.ndarray], seconds: float,
                  columns: tuple[str, ...] = COLUMNS) -> dict[str, Any]:
    """One Table 4 variant's result: its rows summarised, and each of ``columns`` as a B4 centre ×
    width grid (s2cl.sweep.report.centre_width_grid; one configuration per pair here); printed."""
    import pandas as pd

    from s2cl.sweep.report import centre_width_grid

    entry = {"change": change, **summarise(rows), "seconds": seconds}
    df = pd.DataFrame(rows)
    for col in columns:
        centres, widths, values = centre_width_grid(df, "B4", col)
        entry[col] = np.round(values, 4).tolist()
    entry["centres_nm"], entry["widths_nm"] = centres.tolist(), widths.tolist()
    print(f"{name:16s} best {entry['best']} rms {entry['rms_best']:.2f}; 660/30 {entry['rms_660_30']:.2f}, "
          f"665/30 {entry['rms_665_30']:.2f}, 680/30 {entry['rms_680_30']:.2f}", flush=True)
    return entry


def per_subset(scene: Scene, job: SweepJob, index: np.ndarray, status: np.ndarray, by: str) -> dict[str, Any]:
    """RMS of the fit per background (``by="groups"``) or per library parameter value (e.g. ``"lai"``),
    each subset's pixels regressed alone."""
    lib = scene_library(scene)
    labels = np.asarray(lib.groups if by == "groups" else [f"{by} {v:g}" for v in lib.params[by]])
    labels = labels[np.arange(job.tables.n_pixels) // job.tables.copies]
    out = {}
    for g in sorted(set(labels)):
        m = labels == g
        out[g] = regression_metrics(index[:, m], status[:, m], np.zeros_like(status[:, m]), job.tables.target[m])["rms"]
    return out


def subset_rms(scene: Scene, job: SweepJob, by: tuple[str, ...],
               centres: tuple[float, ...] = (660.0, 665.0, 675.0, 680.0)) -> dict[str, dict[str, dict[str, float]]]:
    """RMS per subset (:func:`per_subset`, each of ``by``) at B4 ``centres`` with FWHM 30 nm:
    ``{by: {"660/30": {subset: rms}}}``."""
    from s2cl.sweep.engine import kernel_evaluator

    raw = kernel_evaluator(job)(0, job.n_configs)
    idx = variant_indices(job.tables, 0, job.n_configs)
    c, w = job.tables.centre[0][idx[:, 0]], job.tables.width[0][idx[:, 0]]
    out = {}
    for key in by:
        per = per_subset(scene, job, raw.index, raw.status, key)
        out[key] = {f"{centre:g}/30": {g: float(v[(c == centre) & (w == 30)][0]) for g, v in per.items()}
                    for centre in centres}
    return out


def summarise(rows: dict[str, np.ndarray]) -> dict[str, Any]:
    c, w, rms = (np.asarray(rows[k], dtype=np.float64) for k in ("B4_centre_nm", "B4_width_nm", "rms"))
    best = int(np.nanargmin(rms))

    def at(centre: float, width: float = 30.0) -> float:
        return float(rms[(c == centre) & (w == width)][0])

    return {"best": [float(c[best]), float(w[best])], "rms_best": float(rms[best]), "rms_660_30": at(660),
            "rms_665_30": at(665), "rms_680_30": at(680), "rms_705_30": at(705),
            "ratio_665_to_best": at(665) / float(rms[best])}


def main() -> None:
    out: dict[str, Any] = {"benchmark": "paper_sensitivity", "scene": SCENE, "machine": machine_info(),
                           "note": "Table 4 (B4 centre x width, B5-B7 at the paper's best Lib1 bands) under "
                                   "changed settings; each variant changes one thing", "variants": {}}
    jobs: dict[str, tuple[Scene, SweepJob]] = {}
    for name, change in SCENE_VARIANTS.items():
        t0 = time.perf_counter()
        scene = scene_variant(change)
        job = plan_sweep(scene)
        rows = evaluate_chunk(job, 0, job.n_configs)
        out["variants"][name] = variant_entry(name, change, rows, time.perf_counter() - t0)
        if name in ("default", "lib2"):
            jobs[name] = (scene, job)
    scene, job = jobs["default"]
    for name in FIT_VARIANTS:
        t0 = time.perf_counter()
        rows = fit_variant(job, name)
        out["variants"][name] = variant_entry(name, {"fit": name}, rows, time.perf_counter() - t0,
                                              ("rms", "robust_rms"))
    for k in NOISE_SCALES:
        t0 = time.perf_counter()
        tables = replace(job.tables, values={**job.tables.values,
                                             "sigma": tuple(sig * k for sig in job.tables.values["sigma"])})
        rows = evaluate_chunk(replace(job, tables=tables), 0, job.n_configs)
        out["variants"][f"noise-x{k:g}"] = variant_entry(f"noise-x{k:g}", {"sigma_scale": k}, rows,
                                                         time.perf_counter() - t0)
    # RMS of the shipped fit per background and per LAI (each subset regressed alone), Lib1 and Lib2
    for lib_name, (scene, job) in jobs.items():
        for key, per in subset_rms(scene, job, ("groups", "lai")).items():
            out[f"per_{'background' if key == 'groups' else key}_{lib_name}"] = per
    out["swir"] = swir()
    print("wrote", write_json(RESULT, out))
    plot(out)


def swir() -> dict[str, Any]:
    """Tables 5 and 6 under one-key changes: the best cell, its value, and the value at the paper's best."""
    import pandas as pd

    from s2cl.sweep.report import centre_width_grid

    out: dict[str, Any] = {}
    for scene_name, (band, metric) in SWIR.items():
        variants = dict(SWIR_VARIANTS, **(SAM_VARIANTS if metric == "omission_error_pct" else {}))
        for name, change in variants.items():
            job = plan_sweep(scene_variant(change, scene_name))
            df = pd.DataFrame(evaluate_chunk(job, 0, job.n_configs))
            centres, widths, values = centre_width_grid(df, band, metric)
            i, j = np.unravel_index(np.nanargmin(values), values.shape)
            paper_best = (2190.0, 50.0) if band == "B12" else (1600.0, 100.0)
            pi, pj = int(np.flatnonzero(centres == paper_best[0])[0]), int(np.flatnonzero(widths == paper_best[1])[0])
            entry = {"change": change, "metric": metric, "best": [float(centres[i]), float(widths[j])],
                     "best_value": float(values[i, j]), "at_paper_best": float(values[pi, pj]),
                     "range": [float(np.nanmin(values)), float(np.nanmax(values))],
                     "centres_nm": centres.tolist(), "widths_nm": widths.tolist(),
                     "values": np.round(values, 3).tolist()}
            out[f"{scene_name}/{name}"] = entry
            print(f"{scene_name}/{name}: best {entry['best']} {entry['best_value']:.2f}, at paper best "
                  f"{entry['at_paper_best']:.2f}, range {entry['range'][0]:.1f}-{entry['range'][1]:.1f}", flush=True)
    return out


def plot(out: dict[str, Any]) -> None:
    """Table 4's B4 sensitivity at FWHM 30 nm: the paper's RMS and every s2cl variant's."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from s2cl.sweep.report import paper_results

    paper = paper_results()["table4"]
    j = paper["widths"].index(30)
    fig, ax = plt.subplots(figsize=(8.4, 4.2), dpi=100)
    colours = [*plt.get_cmap("tab10").colors, "navy", "darkgoldenrod", "crimson"]
    ax.plot(paper["centres"], [r[j] for r in paper["rms"]], "k-o", lw=2, label="paper (MODTRAN4, goethite/hematite)")
    for k, (name, e) in enumerate(out["variants"].items()):
        jj = e["widths_nm"].index(30.0)
        style = "--" if name in FIT_VARIANTS else "-"
        ax.plot(e["centres_nm"], [r[jj] for r in e["rms"]], style, marker=".", color=colours[k % len(colours)],
                label=f"s2cl {name}")
    ax.set_xlabel("B4 centre (nm), FWHM 30 nm; B5-B7 at 710/20, 735/30, 785/30")
    ax.set_ylabel("chlorophyll RMS (ug/cm2)")
    ax.set_yscale("log")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title("Table 4: B4 sensitivity, s2cl variants vs paper", fontsize=9)
    fig.tight_layout()
    print("wrote", save_figure(fig, FIGURE, dpi=100))
    plt.close(fig)


if __name__ == "__main__":
    if sys.argv[1:] == ["--plot-only"]:  # redraw from the JSON
        plot(json.loads(RESULT.read_text(encoding="utf-8")))
    else:
        main()
