"""Regenerate docs/paper.md's numbers: the paper's nine sweeps and the default scene, the
sensitivity study and Fig. 7, then docs/paper/results.json and the shipped heatmaps.

Each scene runs as ``python -m s2cl optimise SCENE -q -o OUT/SCENE`` (the command docs/paper.md
shows), its output in ``OUT/logs/SCENE.log``. Each run's marker, ``OUT/logs/SCENE.paper_runs.json``
(beside the log: s2cl writes only into folders that hold nothing but its own files), holds a
fingerprint of the s2cl sources it ran with (``s2cl/``, ``kernels/``, the scene file): a finished
run with the current fingerprint is skipped, an interrupted one resumes (the sweep keeps its
finished chunks), and one made with other sources is deleted and run again, because the sweep's
own resume check does not look at the code. Then ``bench.paper_sensitivity`` and ``bench.fig7_igrm``
run (they write their own results), and the summaries go into docs/paper/results.json and the
heatmaps into docs/paper/*.png.

    python -m bench.paper_runs                         # everything (about 11 min on 2 shared cores)
    python -m bench.paper_runs --out out/paper         # run folders elsewhere (default: s2cl-out/paper)
    python -m bench.paper_runs --scenes table4-b4,table5-b11 --no-sensitivity --no-fig7
    python -m bench.paper_runs --collect-only          # results.json and PNGs from finished runs
    python -m bench.paper_runs --tables                # print docs/paper.md's tables from results.json

``--tables`` prints Markdown built only from docs/paper/results.json and
bench/results/paper_sensitivity.json: the tables in docs/paper.md are pasted from it.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import subprocess
import sys
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from bench.common import RESULTS, ROOT, machine_info, write_json

PAPER_SCENES = ("table3-lib1-b4567", "table3-lib1-b4568", "table3-lib1-b4568a", "table3-lib2-b4567",
                "table3-lib2-b4568", "table3-lib2-b4568a", "table4-b4", "table5-b11", "table6-b12")
SCENES = (*PAPER_SCENES, "default")
DOCS = ROOT / "docs" / "paper"
RESULTS_JSON = DOCS / "results.json"
SENSITIVITY_JSON = RESULTS / "paper_sensitivity.json"
MARKER = "paper_runs.json"
#: shipped heatmaps: docs/paper name -> (scene, file in its run folder)
HEATMAPS = {
    "table3-lib1-b4567_B4.png": ("table3-lib1-b4567", "heatmap_B4.png"),
    "table3-lib2-b4567_B4.png": ("table3-lib2-b4567", "heatmap_B4.png"),
    "table3-lib1-b4568a_B8a.png": ("table3-lib1-b4568a", "heatmap_B8a.png"),
    "table4_vs_paper.png": ("table4-b4", "heatmap_B4_vs_paper.png"),
    "table5_vs_paper.png": ("table5-b11", "heatmap_B11_vs_paper.png"),
    "table6_vs_paper.png": ("table6-b12", "heatmap_B12_vs_paper.png"),
}
#: scripts run after the sweeps (module, what it writes)
STUDIES = {"sensitivity": ("bench.paper_sensitivity", "bench/results/paper_sensitivity.json, "
                           "docs/paper/table4_sensitivity.png"),
           "fig7": ("bench.fig7_igrm", "bench/results/fig7_igrm.json, bench/results/fig7_igrm.png")}


# -- running ---------------------------------------------------------------------------------------

def source_fingerprint(scene: str) -> str:
    """SHA-256 of the s2cl sources a run depends on: the imported package (``.py`` and data),
    its kernels and the scene file."""
    from s2cl.resources import code_fingerprint
    from s2cl.scene.scene import find_scene

    h = hashlib.sha256(code_fingerprint().encode())
    h.update(find_scene(scene).read_bytes())
    return h.hexdigest()


def _marker(folder: Path) -> Path:
    """The marker of the run in ``folder`` (``OUT/SCENE`` -> ``OUT/logs/SCENE.paper_runs.json``)."""
    return folder.parent / "logs" / f"{folder.name}.{MARKER}"


def _read_marker(folder: Path) -> dict[str, Any]:
    p = _marker(folder)
    return json.loads(p.read_text(encoding="utf-8")) if p.exists() else {}


def run_scene(scene: str, out: Path) -> dict[str, Any]:
    """Run (resume, or skip) ``s2cl optimise scene`` into ``out/scene``; return its marker."""
    folder, log = out / scene, out / "logs" / f"{scene}.log"
    fingerprint = source_fingerprint(scene)
    marker = _read_marker(folder)
    if marker.get("fingerprint") == fingerprint and marker.get("finished"):
        print(f"{scene}: finished with these sources, skipped", flush=True)
        return marker
    resumed = marker.get("fingerprint") == fingerprint
    if folder.exists() and not resumed:
        if not (folder / "manifest.json").exists() and any(folder.iterdir()):
            raise SystemExit(f"{folder} exists and is not an s2cl sweep folder: not touching it")
        print(f"{scene}: {folder} was made with other sources (or by hand): deleting it", flush=True)
        shutil.rmtree(folder)
    log.parent.mkdir(parents=True, exist_ok=True)
    marker = {"scene": scene, "fingerprint": fingerprint, "finished": False, "resumed": resumed}
    write_json(_marker(folder), marker)
    print(f"{scene}: {'resuming' if resumed else 'running'} (log {log})", flush=True)
    t0 = time.perf_counter()
    with log.open("a", encoding="utf-8") as f:
        rc = subprocess.run([sys.executable, "-m", "s2cl", "optimise", scene, "-q", "-o", str(folder)],
                            stdout=f, stderr=subprocess.STDOUT, check=False).returncode
    wall = time.perf_counter() - t0
    if rc != 0:
        raise SystemExit(f"{scene}: s2cl optimise exited with {rc}; see {log}")
    marker |= {"finished": True, "wall_s": round(wall, 1)}
    write_json(_marker(folder), marker)
    print(f"{scene}: done in {wall:.0f} s", flush=True)
    return marker


def run_study(name: str) -> float:
    """Run one of STUDIES as ``python -m MODULE``; return its wall time in seconds."""
    module, writes = STUDIES[name]
    print(f"{module}: running (writes {writes})", flush=True)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", module], check=True, cwd=ROOT)
    return time.perf_counter() - t0


# -- collecting ------------------------------------------------------------------------------------

def b5_b6_apart(folder: Path) -> dict[str, Any] | None:
    """Among the ranked configurations of a Table 3 sweep, those whose B5 and B6 FWHM intervals do
    not overlap (|c6 - c5| >= (w5 + w6) / 2): how many, and the best of them."""
    from s2cl.sweep.report import load, rankable

    df, meta = load(folder)
    return best_apart(rankable(df, meta))


def best_apart(df: Any) -> dict[str, Any] | None:
    """:func:`b5_b6_apart` on a results table (pandas, one row per configuration, ``rms``); None
    when B5 or B6 is not in it."""
    if "B5_centre_nm" not in df or "B6_centre_nm" not in df:
        return None
    gap = (df["B6_centre_nm"] - df["B5_centre_nm"]).abs() >= (df["B5_width_nm"] + df["B6_width_nm"]) / 2
    apart = df[gap.to_numpy()]
    if apart.empty:
        return {"configurations": 0}
    best = apart.loc[apart["rms"].idxmin()]
    bands = [c[:-10] for c in df.columns if c.endswith("_centre_nm")]
    return {"configurations": len(apart), "rms": float(best["rms"]), "robust_rms": float(best["robust_rms"]),
            "bands": {b: [float(best[f"{b}_centre_nm"]), float(best[f"{b}_width_nm"])] for b in bands}}


def scene_entry(folder: Path) -> dict[str, Any]:
    """docs/paper/results.json's entry of one run: its summary.json without the top list, the
    run's wall time and, for Table 3, the best design with B5 and B6 apart."""
    summary = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    entry = {k: v for k, v in summary.items() if k != "top"}
    marker = _read_marker(folder)
    entry["wall_s"] = marker.get("wall_s")
    entry["resumed"] = marker.get("resumed")
    if summary["scene"].startswith("table3-") or summary["scene"] == "default":
        entry["b5_b6_apart"] = b5_b6_apart(folder)
    return entry


def collect(out: Path, scenes: Iterable[str], docs: Path = DOCS) -> Path:
    """Write ``docs``/results.json from the run folders (keeping entries of scenes not run now)
    and copy the heatmaps into ``docs``; return the JSON's path."""
    results_json = docs / RESULTS_JSON.name
    old = json.loads(results_json.read_text(encoding="utf-8")) if results_json.exists() else {}
    data: dict[str, Any] = {
        "note": "summary.json of `s2cl optimise SCENE` for the paper's nine scenes (`scenes`) and the default "
                "scene (`default`), without their `top` lists, written by `python -m bench.paper_runs`; "
                "wall_s: that run's wall time; b5_b6_apart: the best ranked Table 3 design whose B5 and B6 "
                "FWHM intervals do not overlap. Full results under the run folders are not shipped.",
        "machine": machine_info(),
        "scenes": dict(old.get("scenes", {})),
        "default": old.get("default"),
    }
    for scene in scenes:
        folder = out / scene
        if not _read_marker(folder).get("finished"):
            raise SystemExit(f"{scene}: no finished run in {folder}; run without --collect-only")
        entry = scene_entry(folder)
        if scene == "default":
            data["default"] = entry
        else:
            data["scenes"][scene] = entry
    data["scenes"] = {s: data["scenes"][s] for s in PAPER_SCENES if s in data["scenes"]}
    for name, (scene, file) in HEATMAPS.items():
        if scene in scenes:
            shutil.copyfile(out / scene / file, docs / name)
            print(f"copied {docs / name}")
    return write_json(results_json, data)


# -- Markdown from results.json --------------------------------------------------------------------

def _bands(bands: dict[str, list[float]]) -> str:
    return " ".join(f"{c:g}/{w:g}" for c, w in bands.values())


def _pct(x: float | None, digits: int = 1) -> str:
    return "–" if x is None else f"{100 * x:.{digits}f} %"


def _ordinal(n: int) -> str:
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n:,}{suffix}"


def _lib_bands(scene: str) -> tuple[str, str]:
    """``"table3-lib1-b4568a"`` -> ``("Lib1", "4 5 6 8a")``."""
    lib, bands = scene.split("-")[1:]
    return lib.capitalize(), " ".join(_split_bands(bands[1:]))


def _split_bands(digits: str) -> list[str]:
    """``"4568a"`` -> ``["4", "5", "6", "8a"]``."""
    out: list[str] = []
    for ch in digits:
        if ch.isalpha() and out:
            out[-1] += ch
        else:
            out.append(ch)
    return out


def table3_markdown(scenes: dict[str, Any]) -> str:
    head = ("| lib | bands | configs | ranked | RMS ESA paper | RMS ESA s2cl | RMS best paper | RMS best s2cl "
            "| best paper | best s2cl | paper's best in s2cl (RMS, rank) |\n|" + "---|" * 11)
    rows = [head]
    for name, e in scenes.items():
        if not name.startswith("table3-"):
            continue
        p, lib, bands = e["paper"], *_lib_bands(name)
        q = p.get("paper_best_in_s2cl")
        where = f"{q['rms']:.2f}, {_ordinal(q['rank'])}" if q else "–"
        rows.append(f"| {lib} | {bands} | {e['configurations']:,} | {e['ranked']:,} | {p['paper']['rms_esa']} "
                    f"| {p['s2cl']['rms_esa']:.2f} | {p['paper']['rms_best']} | {p['s2cl']['rms_best']:.2f} "
                    f"| {_bands(p['paper']['best'])} | {_bands(p['s2cl']['best'])} | {where} |")
    return "\n".join(rows)


def robustness_markdown(scenes: dict[str, Any]) -> str:
    """Fit accounting of the best and the ESA configuration of each IGRM sweep."""
    rows = ["| sweep | design | RMS | robust RMS | converged | stalled | iteration limit | on a bound | failed "
            "| log10 cond. |", "|" + "---|" * 10]
    for name, e in scenes.items():
        if e["metric"] != "rms" or not name.startswith(("table3-", "table4-")):
            continue
        for label, d in (("best", e["best"]), ("ESA", e["reference"])):
            rows.append(f"| {name} | {label} {_bands(d['bands'])} | {d['rms']:.2f} | {d['robust_rms']:.2f} "
                        f"| {_pct(d['converged_fraction'], 2)} | {_pct(d['stalled_fraction'], 2)} "
                        f"| {_pct(d['iteration_limit_fraction'], 2)} | {_pct(d['bound_fraction'], 2)} "
                        f"| {_pct(d['failed_fraction'], 2)} | {d['log10_condition_median']:.2f} |")
    return "\n".join(rows)


def coincident_markdown(scenes: dict[str, Any], default: dict[str, Any] | None) -> str:
    """Per sweep that moves B5 and B6: how many designs put them on one centre (other coincident
    pairs named), how many are ranked, and the best ranked design with B5 and B6 FWHM apart."""
    rows = ["| sweep | configs | B5 = B6 (not ranked) | ranked | B5, B6 FWHM apart | best of those | RMS |",
            "|" + "---|" * 7]
    items = [*scenes.items(), *((("default", default),) if default else ())]
    for name, e in items:
        a = e.get("b5_b6_apart")
        if a is None:
            continue
        pairs = (e.get("underdetermined") or {}).get("coincident_centres", {})
        coincident = f"{pairs.get('B5=B6', 0):,}" + "".join(f"; {k}: {v:,}" for k, v in pairs.items() if k != "B5=B6")
        apart = (f"| {a['configurations']:,} | {_bands(a['bands'])} | {a['rms']:.2f} |" if a["configurations"]
                 else "| 0 | – | – |")
        rows.append(f"| {name} | {e['configurations']:,} | {coincident} | {e['ranked']:,} {apart}")
    return "\n".join(rows)


def grid_markdown(e: dict[str, Any], width: float) -> str:
    """One width's column of a Table 4-6 grid, s2cl and the paper, as two rows."""
    p = e["paper"]
    j = p["widths_nm"].index(width)
    head = f"| {p['band']} centre | " + " | ".join(f"{c:g}" for c in p["centres_nm"]) + " |"
    rows = [head, "|" + "---|" * (len(p["centres_nm"]) + 1)]
    for label, grid, fmt in (("s2cl", p["s2cl"], ".2f"), ("paper", p["paper"], ".1f")):
        vals = [r[j] for r in grid]
        best = min(v for v in vals if v is not None)
        cells = ["–" if v is None else (f"**{v:{fmt}}**" if v == best else f"{v:{fmt}}") for v in vals]
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    for label, grid in (("s2cl spread over widths", p["s2cl"]), ("paper spread over widths", p["paper"])):
        spread = [max(v for v in r if v is not None) - min(v for v in r if v is not None) for r in grid]
        rows.append(f"| {label} | " + " | ".join(f"{v:.2f}" for v in spread) + " |")
    return "\n".join(rows)


def grid_facts(e: dict[str, Any]) -> str:
    """Best cells, the paper's best in s2cl, ESA, rank correlation and the range of one grid table."""
    import numpy as np

    p = e["paper"]
    s = np.array([[np.nan if v is None else v for v in r] for r in p["s2cl"]], dtype=float)
    pb, sb = p["paper_best"], p["s2cl_best"]
    return (f"- s2cl best {sb['bands'][0]:g}/{sb['bands'][1]:g}: {sb['value']:.2f} (paper there: {sb['paper_value']})\n"
            f"- paper best {pb['bands'][0]:g}/{pb['bands'][1]:g}: {pb['value']} (s2cl there: {pb['s2cl_value']:.2f}, "
            f"{100 * (pb['s2cl_value'] / sb['value'] - 1):+.1f} % on s2cl's best)\n"
            f"- ESA {_bands(e['reference']['bands'])}: {e['reference'][e['metric']]:.2f}; "
            f"{e['reference']['configurations_better']} of {e['ranked']} cells better\n"
            f"- s2cl range {np.nanmin(s):.2f}-{np.nanmax(s):.2f}; "
            f"paper range {np.min(p['paper'])}-{np.max(p['paper'])}\n"
            f"- rank correlation of the {p['cells']} cells: {p['rank_correlation']:.2f}")


def cells_range(e: dict[str, Any], centres: tuple[float, float], widths: tuple[float, float]) -> str:
    """Range of s2cl's and the paper's cells with centre and width in the closed intervals given."""
    import numpy as np

    p = e["paper"]
    c, w = np.asarray(p["centres_nm"]), np.asarray(p["widths_nm"])
    m = np.ix_((c >= centres[0]) & (c <= centres[1]), (w >= widths[0]) & (w <= widths[1]))
    s = np.array([[np.nan if v is None else v for v in r] for r in p["s2cl"]], dtype=float)[m]
    q = np.asarray(p["paper"], dtype=float)[m]
    return (f"- centres {centres[0]:g}-{centres[1]:g}, widths {widths[0]:g}-{widths[1]:g}: s2cl "
            f"{np.nanmin(s):.1f}-{np.nanmax(s):.1f}, paper {q.min():.1f}-{q.max():.1f}")


#: bench.paper_sensitivity's variants as docs/paper.md names them, in its order
SENSITIVITY_LABELS = {
    "default": "s2cl default", "no-noise": "no noise", "noise-x3": "noise σ × 3", "noise-x10": "noise σ × 10",
    "wide-bounds": "IGRM bounds wide (l0 600–760, s 2–200, rmin ≥ −1)", "grid-init": "IGRM grid initial guess",
    "soft-l1": "IGRM soft-L1 loss", "aot-error": "correction assumes 15 km visibility (truth 23 km)",
    "l0-at-B4": "l0 fixed at B4's centre (rmin, rmax, s fitted)",
    "l0-rmin-from-B4": "l0 = B4 centre, rmin = B4 reflectance",
    "lib2": "Lib2 instead of Lib1",
}


def _rms(v: float) -> str:
    return f"{v:.2f}" if v < 10 else f"{v:.1f}"


def sensitivity_markdown(sens: dict[str, Any]) -> str:
    """The Table 4 variants (the paper's row first), the per-subset RMS, and the SWIR variants."""
    from s2cl.sweep.report import paper_results

    paper = paper_results()["table4"]
    j, centres = paper["widths"].index(30), paper["centres"]
    at = {c: r[j] for c, r in zip(centres, paper["rms"], strict=True)}
    best = min(at, key=at.__getitem__)
    rows = ["| variant | best | RMS 660/30 | 665/30 | 680/30 | 705/30 | 665 vs best |", "|" + "---|" * 7,
            f"| paper | {best:g}/30: {at[best]:g} | {at[660]:g} | {at[665]:g} | {at[680]:g} | {at[705]:g} "
            f"| {at[665] / at[best]:.1f}× |"]
    for name in [*SENSITIVITY_LABELS, *(k for k in sens["variants"] if k not in SENSITIVITY_LABELS)]:
        v = sens["variants"][name]
        rows.append(f"| {SENSITIVITY_LABELS.get(name, name)} | {v['best'][0]:g}/{v['best'][1]:g}: "
                    f"{v['rms_best']:.2f} | {v['rms_660_30']:.2f} | {v['rms_665_30']:.2f} | {v['rms_680_30']:.2f} "
                    f"| {v['rms_705_30']:.2f} | {v['ratio_665_to_best']:.2f}× |")
    subsets = ["| subset | 660 | 665 | 675 | 680 |", "|---|---|---|---|---|"]
    for lib, key in (("Lib1", "default"), ("Lib2", "lib2")):
        for by in ("background", "lai"):
            per = sens[f"per_{by}_{key}"]
            groups = list(per["660/30"])
            label = " / ".join(groups) if by == "background" else "LAI " + " / ".join(g.split()[-1] for g in groups)
            cells = [" / ".join(_rms(per[f"{c}/30"][g]) for g in groups) for c in (660, 665, 675, 680)]
            subsets.append(f"| {lib} {label} | " + " | ".join(cells) + " |")
    swir = ["| SWIR variant | best | value | at the paper's best | range |", "|---|---|---|---|---|"]
    for name, v in sens["swir"].items():
        swir.append(f"| {name} | {v['best'][0]:g}/{v['best'][1]:g} | {v['best_value']:.2f} "
                    f"| {v['at_paper_best']:.2f} | {v['range'][0]:.2f}-{v['range'][1]:.2f} |")
    return "\n\n".join(("\n".join(rows), "\n".join(subsets), "\n".join(swir)))


def print_tables(results_json: Path = RESULTS_JSON, sensitivity_json: Path = SENSITIVITY_JSON) -> None:
    """Print docs/paper.md's tables, built from ``results_json`` and ``sensitivity_json`` only."""
    data = json.loads(results_json.read_text(encoding="utf-8"))
    scenes = data["scenes"]
    parts = [("Table 3", table3_markdown(scenes)), ("Fit accounting", robustness_markdown(scenes)),
             ("Coincident and overlapping B5/B6", coincident_markdown(scenes, data.get("default")))]
    for scene, width in (("table4-b4", 30.0), ("table5-b11", 100.0), ("table6-b12", 50.0)):
        if scene in scenes:
            e = scenes[scene]
            text = grid_markdown(e, width) + "\n\n" + grid_facts(e)
            if scene == "table6-b12":  # broad bands; narrow bands at the Al-OH feature
                text += "\n" + cells_range(e, (2100, 2300), (140, 180)) + "\n" + cells_range(e, (2200, 2210), (30, 60))
            parts.append((f"{scene} at FWHM {width:g}", text))
    if sensitivity_json.exists():
        sens = json.loads(sensitivity_json.read_text(encoding="utf-8"))
        parts.append(("bench.paper_sensitivity", sensitivity_markdown(sens)))
    for title, text in parts:
        print(f"### {title}\n\n{text}\n")


# -- command line ----------------------------------------------------------------------------------

def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m bench.paper_runs", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "s2cl-out" / "paper", help="folder of the run folders")
    ap.add_argument("--scenes", default=",".join(SCENES), help=f"comma-separated (default: {','.join(SCENES)})")
    ap.add_argument("--collect-only", action="store_true", help="no runs: results.json and PNGs from the folders")
    ap.add_argument("--no-sensitivity", action="store_true", help="skip python -m bench.paper_sensitivity")
    ap.add_argument("--no-fig7", action="store_true", help="skip python -m bench.fig7_igrm")
    ap.add_argument("--tables", action="store_true", help="only print the Markdown tables from results.json")
    args = ap.parse_args(argv)
    if args.tables:
        print_tables()
        return
    scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
    unknown = sorted(set(scenes) - set(SCENES))
    if unknown:
        ap.error(f"unknown scene(s) {', '.join(unknown)}; known: {', '.join(SCENES)}")
    t0 = time.perf_counter()
    if not args.collect_only:
        for scene in scenes:
            run_scene(scene, args.out)
        for name in STUDIES:
            if not getattr(args, f"no_{name}"):
                print(f"{name}: {run_study(name):.0f} s", flush=True)
    print("wrote", collect(args.out, scenes))
    print(f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
