"""Table 4's open question: does B4 at 660–665 nm degrade (paper: 27.2 and 19.9 ug/cm2 at FWHM 30 nm) when
Lib1/Lib2 lie over measured iron-rich soils instead of s2cl's USGS stand-in backgrounds?

Soils are chosen from ``builtin:earthlib-soils`` (4,168 measured ICRAF-ISRIC soils) by an objective index
computed on the measured spectra (:mod:`s2cl.libraries.earthlib_spectra`): the ``k`` largest Fe3+ crystal-field
band depths near 900 nm, the ``k`` largest redness indices, and as a low-iron control the ``k`` smallest band
depths. For each set, Lib1 and Lib2 are rebuilt with PROSAIL (the shipped libraries' Cab/LAI design and
constants, :data:`s2cl.libraries.vegetation.LIB1` / ``LIB2``, the soils as backgrounds) and the ``table4-b4``
sweep (B4 centre 660–705 x FWHM 15–50 nm, B5–B7 fixed, IGRM chlorophyll, 100 copies, atmosphere, noise,
correction) is run with each, with ``[grid] stop_nm = 2450`` (earthlib is measured to 2450 nm) for every
set, the USGS stand-ins included.

Writes bench/results/soil_backgrounds.json and docs/soils/table4_soils.png. From the repository root:

    python -m bench.soil_backgrounds            # k = 3 soils per set
    python -m bench.soil_backgrounds --plot-only
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from typing import Any

import numpy as np

from bench.common import RESULTS, ROOT, machine_info, save_figure, write_json
from bench.paper_sensitivity import scene_variant, subset_rms, variant_entry
from s2cl.app.plan import plan_sweep
from s2cl.grid import SpectralGrid
from s2cl.libraries import earthlib_spectra as el
from s2cl.libraries.vegetation import DEFAULT_BACKGROUNDS, EARTHLIB_PREFIX, LIB1, LIB2, library_file
from s2cl.sweep.engine import evaluate_chunk

RESULT = RESULTS / "soil_backgrounds.json"  # k = 3; another k writes soil_backgrounds-k<K>.json
FIGURE = ROOT / "docs" / "soils" / "table4_soils.png"
GRID_STOP_NM = el.MEASURED_RANGE_NM[1]
LIBRARIES = {"lib1": LIB1, "lib2": LIB2}
CENTRES = (660.0, 665.0, 675.0, 680.0)


def select_soils(k: int) -> dict[str, dict[str, Any]]:
    """The background sets: USGS stand-ins and three earthlib selections of ``k`` soils each, with their indices."""
    lib = el.soil_library(SpectralGrid(400.0, 1000.0, 10.0))
    names, site = lib.names, lib.params["site"]
    depth, red = lib.params["fe_band_depth"], lib.params["redness_index"]

    def first_k(order: np.ndarray) -> list[int]:
        """The first ``k`` of ``order`` from distinct sites (a soil without a site counts as its own)."""
        out: list[int] = []
        seen: set[float] = set()
        for i in order:
            if site[i] == 0 or site[i] not in seen:
                out.append(int(i))
                seen.add(float(site[i]))
            if len(out) == k:
                break
        return out

    order = {
        "fe-depth-top": first_k(np.argsort(-depth, kind="stable")),
        "redness-top": first_k(np.argsort(-red, kind="stable")),
        "fe-depth-bottom": first_k(np.argsort(depth, kind="stable")),
    }
    per_site = "one soil per site (profile)"
    rules = {
        "fe-depth-top": f"the {k} largest Fe3+ band depths (continuum 760-1000 nm), {per_site}",
        "redness-top": f"the {k} largest redness indices R^2/(B G^3), {per_site}",
        "fe-depth-bottom": f"low-iron control: the {k} smallest Fe3+ band depths, {per_site}",
    }
    sets: dict[str, dict[str, Any]] = {"usgs-stand-ins": {
        "rule": "s2cl's shipped backgrounds: USGS jarosite-coated muscovite, siderite, chlorite",
        "backgrounds": list(DEFAULT_BACKGROUNDS)}}
    for key, rows in order.items():
        sets[key] = {"rule": rules[key], "backgrounds": [EARTHLIB_PREFIX + names[i] for i in rows],
                     "fe_band_depth": [round(float(depth[i]), 4) for i in rows],
                     "redness_index": [round(float(red[i]), 1) for i in rows],
                     "site": [int(site[i]) for i in rows]}
    return sets


def result_path(k: int):
    """Where a run with ``k`` soils per set writes (the figure is drawn from ``k`` = 3)."""
    return RESULT if k == 3 else RESULTS / f"soil_backgrounds-k{k}.json"


def centre_means(entry: dict[str, Any]) -> dict[str, float]:
    """RMS at FWHM 30 nm and the mean over all widths, at each of :data:`CENTRES`."""
    centres, widths, rms = entry["centres_nm"], entry["widths_nm"], np.asarray(entry["rms"], dtype=np.float64)
    j = widths.index(30.0)
    out = {}
    for c in CENTRES:
        i = centres.index(c)
        out[f"{c:g}/30"] = float(rms[i, j])
        out[f"{c:g}/all"] = float(np.mean(rms[i]))
    out["ratio_660_665_to_675_680"] = (out["660/30"] + out["665/30"]) / (out["675/30"] + out["680/30"])
    return out


def main(k: int) -> None:
    sets = select_soils(k)
    out: dict[str, Any] = {
        "benchmark": "soil_backgrounds", "scene": "table4-b4", "machine": machine_info(), "k": k,
        "note": "table4-b4 with Lib1/Lib2 rebuilt over each background set (same Cab/LAI design and PROSAIL "
                f"constants as the shipped libraries); grid 400-{GRID_STOP_NM:g} nm for every set",
        "paper": {"660/30": 27.2, "665/30": 19.9, "675/30": 5.4, "680/30": 4.7, "library": "lib1"},
        "sets": sets, "runs": {}}
    for set_name, entry in sets.items():
        for lib_name, base in LIBRARIES.items():
            t0 = time.perf_counter()
            spec = replace(base, name=f"{lib_name}-{set_name}", backgrounds=tuple(entry["backgrounds"]))
            change = {"surface": {"library": str(library_file(spec))}, "grid": {"stop_nm": GRID_STOP_NM}}
            scene = scene_variant(change)
            job = plan_sweep(scene)
            rows = evaluate_chunk(job, 0, job.n_configs)
            run = variant_entry(f"{lib_name} {set_name}", {"library": f"{lib_name} over {set_name}",
                                                          "grid.stop_nm": GRID_STOP_NM}, rows, 0.0)
            run.update(centre_means(run))
            run["per_background"] = per = subset_rms(scene, job, ("groups",), CENTRES)["groups"]
            ratios = {g: (per["660/30"][g] + per["665/30"][g]) / (per["675/30"][g] + per["680/30"][g])
                      for g in per["660/30"]}
            worst = max(ratios, key=ratios.__getitem__)
            run["worst_background"] = {"background": worst, "ratio_660_665_to_675_680": ratios[worst],
                                       **{c: per[c][worst] for c in per}}
            run["seconds"] = time.perf_counter() - t0
            out["runs"][f"{lib_name}/{set_name}"] = run
    print("wrote", write_json(result_path(k), out))
    if k == 3:
        plot(out)


def plot(out: dict[str, Any]) -> None:
    """Left: the backgrounds (400-1000 nm); middle/right: Lib1/Lib2 RMS against B4 centre at FWHM 30 nm."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from s2cl.libraries.vegetation import _background_spectra
    from s2cl.sweep.report import paper_results

    fig, axes = plt.subplots(1, 3, figsize=(13.5, 4.2), dpi=100)
    colours = {"usgs-stand-ins": "tab:grey", "fe-depth-top": "tab:red", "redness-top": "tab:orange",
               "fe-depth-bottom": "tab:blue"}
    w = np.arange(400.0, 2501.0)
    keep = w <= 1000.0
    for set_name, entry in out["sets"].items():
        spectra = _background_spectra(tuple(entry["backgrounds"]))
        for n, key in enumerate(entry["backgrounds"]):
            axes[0].plot(w[keep], spectra[key][keep], color=colours[set_name], lw=1,
                         label=set_name if n == 0 else None)
    axes[0].axvspan(652.5, 680.0, color="k", alpha=0.08, lw=0)
    axes[0].set(xlabel="wavelength (nm)", ylabel="background reflectance", title="backgrounds (shaded: B4 660/665)")
    axes[0].legend(fontsize=7)
    paper = paper_results()["table4"]
    j = paper["widths"].index(30)
    for ax, lib_name in zip(axes[1:], LIBRARIES, strict=True):
        if lib_name == "lib1":
            ax.plot(paper["centres"], [r[j] for r in paper["rms"]], "k-o", lw=2, label="paper Lib1 (goethite/hematite)")
        for set_name in out["sets"]:
            run = out["runs"][f"{lib_name}/{set_name}"]
            jj = run["widths_nm"].index(30.0)
            ax.plot(run["centres_nm"], [r[jj] for r in run["rms"]], "-", marker=".", color=colours[set_name],
                    label=f"s2cl {set_name}")
        ax.set(xlabel="B4 centre (nm), FWHM 30 nm", ylabel="chlorophyll RMS (ug/cm2)", yscale="log",
               title=f"table4-b4 with {lib_name} over each background set")
        ax.legend(fontsize=7)
    fig.tight_layout()
    print("wrote", save_figure(fig, FIGURE, dpi=100))
    plt.close(fig)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", type=int, default=3, help="soils per selected set (default 3, as Lib1 has 3)")
    parser.add_argument("--plot-only", action="store_true", help="redraw the figure from the JSON")
    args = parser.parse_args()
    if args.plot_only:
        plot(json.loads(RESULT.read_text(encoding="utf-8")))
    else:
        main(args.k)
