"""Regenerate docs/band-addition.md's numbers and figures (the bands Sect. 5 of the paper recommends).

1. ``python -m s2cl optimise add-2300-mgoh -q -o OUT/add-2300-mgoh``: the band-addition sweep of a 2.28-2.35 um
   band added to B11 1610/90 + B12 2190/180 (SAM Al-OH vs Mg-OH/C-O); its gain curve and heatmap are copied to
   docs/band-addition/.
2. ``python -m s2cl optimise yellow-620-cab -q -o OUT/yellow-620-cab`` and the same scene over Lib2 (sparse
   canopies, Cab 5-25): Cab at low contents from ND(B8a, visible band 540-720 nm); the RMS against the visible
   band's centre is plotted to docs/band-addition/yellow-620.png.
3. B3 560/35, B4 665/30 and B5 705/15 with their own radiometry (Table 1) in the same index, through the
   ordinary sweep API (one fixed configuration each), beside the swept band at 620 nm.

Everything lands in docs/band-addition/results.json (with the machine); ``--tables`` prints the Markdown tables
of docs/band-addition.md from it.

    python -m bench.band_addition                 # about 30 s on 2 shared cores
    python -m bench.band_addition --tables
"""

from __future__ import annotations

import argparse
import copy
import json
import shutil
import subprocess
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

from bench.common import ROOT, machine_info, write_json

DOCS = ROOT / "docs" / "band-addition"
RESULTS_JSON = DOCS / "results.json"
YELLOW = ("yellow-620-cab", "lib1"), ("yellow-620-cab-lib2", "lib2")
S2_VISIBLE = {"B3": (560.0, 35.0), "B4": (665.0, 30.0), "B5": (705.0, 15.0)}


def _optimise(scene: str, out: Path) -> dict[str, Any]:
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "s2cl", "optimise", scene, "-q", "-o", str(out), "--overwrite"]
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    summary = json.loads((out / "summary.json").read_text())
    summary["wall_s"] = time.perf_counter() - t0
    return summary


def _yellow_scene_dict(library: str) -> dict[str, Any]:
    data = tomllib.loads((ROOT / "scenes" / "yellow-620-cab.toml").read_text(encoding="utf-8"))
    data["surface"]["library"] = f"builtin:{library}"
    data["scene"]["name"] = "yellow-620-cab" if library == "lib1" else f"yellow-620-cab-{library}"
    return data


def _own_radiometry(library: str) -> dict[str, dict[str, float]]:
    """B3, B4, B5 at their Table 1 shapes and radiometry in the yellow scene's index (one fixed design each)."""
    from s2cl.app.plan import plan_sweep
    from s2cl.scene.scene import Scene
    from s2cl.sweep.engine import evaluate_chunk

    out = {}
    for band, (c, w) in S2_VISIBLE.items():
        d = copy.deepcopy(_yellow_scene_dict(library))
        d["analysis"]["red"] = band
        d["sweep"] = {"bands": ["B8a", band], "ranges": {"B8a": {"centre": 865.0, "width": 20.0},
                                                         band: {"centre": c, "width": w}}}
        row = evaluate_chunk(plan_sweep(Scene.from_dict(d, base_dir=ROOT / "scenes")), 0, 1)
        out[band] = {"centre_nm": c, "width_nm": w, **{k: float(row[k][0]) for k in
                                                        ("rms", "robust_rms", "r2", "failed_fraction")}}
    return out


def _grid(folder: Path, band: str, value: str) -> dict[str, Any]:
    """One moving band's centre × width table of column ``value`` from a finished sweep."""
    import pandas as pd

    df = pd.read_parquet(folder / "results.parquet")
    t = df.pivot(index=f"{band}_centre_nm", columns=f"{band}_width_nm", values=value)
    return {"centres_nm": [float(c) for c in t.index], "widths_nm": [float(w) for w in t.columns],
            value: [[float(v) for v in row] for row in t.to_numpy()]}


def _yellow_plot(results: dict[str, Any], path: Path) -> None:
    from s2cl.io.plots import pyplot, save_png

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), dpi=120)
    for ax, (name, lib) in zip(axes, YELLOW, strict=True):
        r = results["yellow"][lib]
        curve = r["curve"]
        for j, w in enumerate(curve["widths_nm"]):
            ax.plot(curve["centres_nm"], [row[j] for row in curve["rms"]], marker="o", ms=2.5, lw=1,
                    label=f"{w:g} nm")
        for band, own in r["own_radiometry"].items():
            ax.plot([own["centre_nm"]], [own["rms"]], marker="*", ms=11, color="black", ls="none")
            ax.annotate(f"{band} {own['centre_nm']:g}/{own['width_nm']:g}", (own["centre_nm"], own["rms"]),
                        textcoords="offset points", xytext=(4, 6), fontsize=7)
        ax.axvline(620, color="goldenrod", lw=1, ls="--")
        ax.set_xlabel("visible band centre (nm)")
        ax.set_ylabel("Cab RMS (µg/cm²)")
        ax.set_title(f"{name}: ND(B8a, visible) → Cab 5–25 ({lib})", fontsize=8)
    axes[0].legend(title="visible FWHM (B4 radiometry)", fontsize=7, title_fontsize=7)
    fig.tight_layout()
    save_png(fig, path)


def run(out: Path) -> dict[str, Any]:
    results: dict[str, Any] = {"machine": machine_info(), "commands": {}}
    mg = _optimise("add-2300-mgoh", out / "add-2300-mgoh")
    results["commands"]["add-2300-mgoh"] = "python -m s2cl optimise add-2300-mgoh"
    results["mgoh"] = {k: mg[k] for k in ("addition", "reference", "top", "seconds", "wall_s")}
    results["mgoh"]["gain"] = _grid(out / "add-2300-mgoh", "N2300", "gain")
    results["mgoh"]["omission"] = _grid(out / "add-2300-mgoh", "N2300", "omission_error_pct")
    t6 = _optimise("table6-b12", out / "table6-b12")  # moving B12 instead of adding a band: the comparison
    results["table6_best"] = {k: t6["best"][k] for k in ("bands", "omission_error_pct")}
    DOCS.mkdir(parents=True, exist_ok=True)
    for name in ("gain_N2300.png", "heatmap_gain_N2300.png"):
        shutil.copyfile(out / "add-2300-mgoh" / name, DOCS / f"add-2300-mgoh_{name}")
    results["yellow"] = {}
    for name, lib in YELLOW:
        scene = "yellow-620-cab"
        if lib != "lib1":  # the same scene over Lib2: a scene file beside the run folder
            scene_path = out / f"{name}.toml"
            text = (ROOT / "scenes" / "yellow-620-cab.toml").read_text(encoding="utf-8")
            text = text.replace('"builtin:lib1"', f'"builtin:{lib}"').replace('name = "yellow-620-cab"',
                                                                              f'name = "{name}"')
            scene_path.write_text(text, encoding="utf-8")
            scene = str(scene_path)
        summary = _optimise(scene, out / name)
        results["commands"][name] = f"python -m s2cl optimise {'yellow-620-cab' if lib == 'lib1' else name}"
        results["yellow"][lib] = {"best": summary["best"], "seconds": summary["seconds"],
                                  "curve": _grid(out / name, "B4", "rms"), "own_radiometry": _own_radiometry(lib)}
    _yellow_plot(results, DOCS / "yellow-620.png")
    write_json(RESULTS_JSON, results)
    return results


def _markdown(grid: dict[str, Any], value: str, label: str, digits: int, rows: Any = None) -> list[str]:
    out = [f"| {label} centre ↓ FWHM → | " + " | ".join(f"{w:g}" for w in grid["widths_nm"]) + " |",
           "|---|" + "---|" * len(grid["widths_nm"])]
    for c, row in zip(grid["centres_nm"], grid[value], strict=True):
        if rows is None or c in rows:
            out.append(f"| {c:g} | " + " | ".join(f"{v:.{digits}f}" for v in row) + " |")
    return out


def _moved_b12(best: dict[str, Any]) -> str:
    """Table 6's best design (B12 moved instead of a band added) as ``B12 c/w: omission %``."""
    c, w = best["bands"]["B12"]
    return f"table6-b12's best B12 {c:g}/{w:g}: omission {best['omission_error_pct']:.2f} %"


def tables(results: dict[str, Any]) -> str:
    """docs/band-addition.md's tables from results.json."""
    mg = results["mgoh"]
    add = mg["addition"]
    lines = [f"base {'+'.join(add['base_bands'])}: omission {add['base_score']:.2f} %; best added "
             f"{add['best']['centre_nm']:g}/{add['best']['width_nm']:g}: {add['best']['omission_error_pct']:.2f} % "
             f"(gain {add['best']['gain']:.2f}); B12 moved instead: {_moved_b12(results['table6_best'])}", "",
             "gain (points):", *_markdown(mg["gain"], "gain", "N2300", 1), "",
             "omission (%):", *_markdown(mg["omission"], "omission_error_pct", "N2300", 1)]
    for lib, r in results["yellow"].items():
        lines += ["", f"{lib} (Cab RMS, µg/cm²):",
                  *_markdown(r["curve"], "rms", "visible", 2, rows=(550, 560, 570, 580, 600, 620, 640, 665, 705, 710))]
        lines.append("own radiometry: " + ", ".join(f"{b} {o['centre_nm']:g}/{o['width_nm']:g} RMS {o['rms']:.2f} "
                                                    f"(R² {o['r2']:.3f})" for b, o in r["own_radiometry"].items()))
        best = r["best"]
        lines.append(f"best visible band: {best['bands']['B4']} RMS {best['rms']:.2f}")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "s2cl-out" / "band-addition")
    ap.add_argument("--tables", action="store_true", help="print the Markdown tables from results.json")
    args = ap.parse_args()
    if args.tables:
        print(tables(json.loads(RESULTS_JSON.read_text())))
        return
    results = run(args.out)
    print(tables(results))


if __name__ == "__main__":
    main()
