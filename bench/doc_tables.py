"""The Markdown of each generated block of the documentation (:mod:`bench.doc_blocks` rewrites the pages):
name → a function of committed results files only. Every block says which file it reads and which
command writes that file."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from functools import cache
from pathlib import Path
from typing import Any

from bench.common import RESULTS, ROOT

DOCS = ROOT / "docs"
STUDIES = ("cirrus", "water-vapour", "aerosol", "ozone", "methane")
STUDY_JSON = {**{s: DOCS / "studies" / s / f"{s}.json" for s in STUDIES},
              "stability": DOCS / "stability" / "stability.json",
              "cellulose": DOCS / "cellulose" / "cellulose.json",
              "water-vapour-1020": DOCS / "water-vapour-1020" / "water-vapour-1020.json"}
SWEEP_JSON = RESULTS / "sweep.json"
CHUNKS_JSON = RESULTS / "sweep-chunks-amd-epyc-2c-2026-11-24.json"
THROUGHPUT_JSON = RESULTS / "sweep-throughput-amd-epyc-2c-2026-11-24.json"
FIG7_JSON = RESULTS / "fig7_igrm.json"
IGRM_ACCURACY_JSON = RESULTS / "igrm-accuracy-amd-epyc-2c-2026-11-24.json"
ATMOSPHERE_JSON = RESULTS / "atmosphere.json"
BENCH_PAGE_JSON = RESULTS / "amd-epyc-2c-2026-11-24.json"  # the full `python -m bench` run docs/bench.md shows
Result = dict[str, Any]


@cache
def _load(path: Path) -> Result:
    return json.loads(path.read_text(encoding="utf-8"))


def _rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def md_table(columns: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A Markdown table; cells as given (str) or formatted with :func:`cell`."""
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def cell(v: Any) -> str:
    """A table cell: numbers to 3 significant digits (thousands separated), None as '–'."""
    if v is None:
        return "–"
    if isinstance(v, bool) or not isinstance(v, int | float):
        return str(v).replace("|", "\\|")
    if isinstance(v, int) or (abs(v) >= 1000 and float(v).is_integer()):
        return f"{v:,.0f}"
    return f"{v:,.3g}" if abs(v) < 1e5 else f"{v:,.0f}"


def _machine(r: Result) -> str:
    m = r.get("machine", {})
    return f"{m.get('cpu', '?')}, {m.get('cores', '?')} cores, {str(m.get('date', '?'))[:10]}"


# -- s2cl study NAME --------------------------------------------------------------------------------

def study_command(name: str) -> str:
    return f"s2cl study {name} -o {_rel(STUDY_JSON[name].parent)}"


def study_table(name: str) -> str:
    """The table ``s2cl study NAME`` prints, from its NAME.json."""
    r = _load(STUDY_JSON[name])
    t = r["table"]
    notes = "".join(f"\n- {n}" for n in r.get("notes", []))
    return (f"{r['title']} (`{_rel(STUDY_JSON[name])}`, written by `{study_command(name)}`).\n\n"
            + md_table(t["columns"], t["rows"]) + ("\n" + notes if notes else ""))


def study_key_figures(name: str) -> str:
    """The study's key figures beside the paper's (None: the paper gives none)."""
    r = _load(STUDY_JSON[name])
    if not r["key_figures"]:
        return f"Segl et al. (2012) give no figure to set beside this study's (`{_rel(STUDY_JSON[name])}`)."
    rows = [(k["quantity"].strip(), k["s2cl"], k["paper"], k["unit"], k.get("note") or "") for k in r["key_figures"]]
    return (f"Key figures, s2cl beside Segl et al. (2012) (`{_rel(STUDY_JSON[name])}`):\n\n"
            + md_table(("quantity", "s2cl", "paper", "unit", "note"), rows))


# -- docs/paper.md ------------------------------------------------------------------------------------

def paper_tables() -> dict[str, str]:
    """The tables of ``python -m bench.paper_runs --tables``, by block name."""
    from bench import paper_runs as p

    data = _load(p.RESULTS_JSON)
    scenes = data["scenes"]
    out = {"paper.table3": p.table3_markdown(scenes), "paper.fit-accounting": p.robustness_markdown(scenes),
           "paper.coincident": p.coincident_markdown(scenes, data.get("default"))}
    for scene, width, key in (("table4-b4", 30.0, "paper.table4"), ("table5-b11", 100.0, "paper.table5"),
                              ("table6-b12", 50.0, "paper.table6")):
        e = scenes[scene]
        text = p.grid_markdown(e, width) + "\n\n" + p.grid_facts(e)
        if scene == "table6-b12":  # broad bands; narrow bands at the Al-OH feature
            text += "\n" + p.cells_range(e, (2100, 2300), (140, 180)) + "\n" + p.cells_range(e, (2200, 2210), (30, 60))
        out[key] = text
    variants, subsets, swir = p.sensitivity_markdown(_load(p.SENSITIVITY_JSON)).split("\n\n")
    out |= {"paper.sensitivity": variants, "paper.subsets": subsets, "paper.swir": swir}
    return out


def _paper(name: str) -> Callable[[], str]:
    from bench import paper_runs as p

    source = (f"\n\nFrom `{_rel(p.RESULTS_JSON)}` (written by `python -m bench.paper_runs`)"
              if name not in ("paper.sensitivity", "paper.subsets", "paper.swir")
              else f"\n\nFrom `{_rel(p.SENSITIVITY_JSON)}` (written by `python -m bench.paper_sensitivity`)")
    return lambda: paper_tables()[name] + source + "."


def fig7() -> str:
    """Fig. 7: the hyperspectral IGRM, s2cl beside the paper."""
    r = _load(FIG7_JSON)
    rows = [("paper, Lib1", "red edge", r["paper"]["r2"], r["paper"]["rms_ug_cm2"])]
    for label, part in ((f"s2cl {r['library']} ({r['n_spectra']} spectra)", r),
                        (f"PROSAIL, {r['prosail_default_soil']['soil']} ({r['prosail_default_soil']['n_spectra']} "
                         "spectra)", r["prosail_default_soil"])):
        rows += [(label, "{}–{} nm".format(*w["window_nm"]), f"{w['r2']:.3f}", f"{w['rms_ug_cm2']:.2f}")
                 for w in part["windows"]]
    return (md_table(("spectra", "window", "R²", "RMS µg/cm²"), rows)
            + f"\n\nFrom `{_rel(FIG7_JSON)}` (written by `python -m bench.fig7_igrm`).")


def igrm_accuracy() -> str:
    """Share of the sweep's float32 IGRM fits within a distance of a tight float64 fit of the same pixels."""
    r = _load(IGRM_ACCURACY_JSON)
    rows = []
    for lib, v in r["libraries"].items():
        for cls in ("all_fitted", "converged", "stalled", "iteration_limit"):
            c = v[cls]
            share = "100 %" if cls == "all_fitted" else f"{100 * c['share_of_fitted']:.3g} %"
            rows.append((f"{lib} (`{v['scene']}`, {v['pixels']:,} pixels)", cls.replace("_", " "), share,
                         *(f"{100 * c[f'within_{d}_nm']:.5g} %" for d in ("0.001", "0.01", "0.05"))))
        rows.append((lib, "no converged float64 fit (left out)", f"{v['float64_not_converged']:,} pixels", "", "", ""))
    return (md_table(("library", "fits", "share of fitted", "within 1e-3 nm", "within 0.01 nm", "within 0.05 nm"),
                     rows)
            + f"\n\nFrom `{_rel(IGRM_ACCURACY_JSON)}` (written by `python -m bench.igrm_accuracy`; {_machine(r)}).")


def table3_timings() -> str:
    """Wall time and peak memory of each Table 3 sweep, one ``s2cl optimise`` process each."""
    r = _load(SWEEP_JSON)
    t = r["table3"]
    rows = [(s, f"{v['wall_s']:.1f} s", f"{v['peak_rss_mb']:,.0f} MB") for s, v in t["runs"].items()]
    rows.append((f"**all six ({t['configurations']:,} configurations)**",
                 f"**{t['wall_s']:.1f} s ({t['wall_s'] / 60:.1f} min)**", f"**{t['peak_rss_mb']:,.0f} MB**"))
    return (md_table(("scene", "wall", "peak RSS"), rows)
            + f"\n\nTarget: {t['target_s']} s for the six. {t['how']}; {t.get('note', '')}. From `{_rel(SWEEP_JSON)}` "
            f"(written by `python -m bench.bench_sweep --table3-run --skip-dask`; {_machine(r)}).")


def throughput() -> str:
    """The fused sweep kernel against the numpy twin, evaluations per second."""
    r = _load(THROUGHPUT_JSON)
    o, n, w = r["opencl"], r["numpy"], r["whole_sweep_extrapolated"]
    rows = [(f"fused kernel ({o['precision']}, {o['lanes']} lanes), {o['configurations']:,} configurations",
             f"{o['kernel_evaluations_per_s'] / 1e6:.3g} M", ""),
            ("+ per-configuration metrics on the device", f"{o['with_metrics_evaluations_per_s'] / 1e6:.3g} M",
             f"{w['opencl_s']:.0f} s"),
            (f"numpy twin ({n['what']}), {len(n['sample_configurations'])} configurations, extrapolated",
             f"{n['evaluations_per_s'] / 1e6:.3g} M", f"{w['numpy_s']:,.0f} s"),
            ("**ratio**", f"**{r['ratio_kernel']:.0f}×** (kernel)", f"**{w['ratio']:.0f}×**")]
    v = r["validation"]
    return (md_table(("", "evaluations/s", f"whole {r['scene']}, extrapolated"), rows)
            + f"\n\nChecked first ({v['criterion']}): the same status for {100 * v['same_status_fraction']:.2f} % of "
            f"the pixels, |Δλp| median {v['index_abs_diff']['p50']:.1g} nm, 99th percentile "
            f"{v['index_abs_diff']['p99']:.1g} nm, per-configuration RMS within {v['rms_rel_diff_max']:.1g} "
            f"(relative). From `{_rel(THROUGHPUT_JSON)}` (written by `python -m bench.bench_sweep --skip-dask --output "
            f"{_rel(THROUGHPUT_JSON)}`; {_machine(r)}).")


def band_addition(part: str) -> str:
    """``python -m bench.band_addition --tables``: the Mg-OH/carbonate band (``mgoh``) or the yellow band."""
    from bench import band_addition as b

    results = _load(b.RESULTS_JSON)
    text = b.tables(results)
    first_yellow = "\n\n" + next(iter(results["yellow"])) + " ("
    mgoh, yellow = text.split(first_yellow, 1)
    body = mgoh if part == "mgoh" else first_yellow.strip("\n") + yellow
    return body + f"\n\nFrom `{_rel(b.RESULTS_JSON)}` (written by `python -m bench.band_addition`)."


def soils(k: int) -> str:
    """``python -m bench.soil_backgrounds [-k K]``: table4-b4 over each background set, B4 at FWHM 30 nm."""
    from bench import soil_backgrounds as sb

    path = sb.result_path(k)
    r = _load(path)
    paper = r["paper"]
    cells = ("660/30", "665/30", "675/30", "680/30")
    rows = [("Lib1", "**paper** (goethite/hematite, MODTRAN4)", *(paper[c] for c in cells),
             f"{(paper['660/30'] + paper['665/30']) / (paper['675/30'] + paper['680/30']):.2f}", "", "")]
    for key, v in r["runs"].items():
        lib, name = key.split("/", 1)
        w = v["worst_background"]
        rows.append((lib.capitalize(), name, *(f"{v[c]:.2f}" for c in cells), f"{v['ratio_660_665_to_675_680']:.2f}",
                     "{:g}/{:g}: {:.2f}".format(*v["best"], v["rms_best"]),
                     f"{w['background'].removeprefix('earthlib:')}: {w['ratio_660_665_to_675_680']:.2f}"))
    table = md_table(("library", "background set", *cells, "(660+665)/(675+680)", "best B4: RMS",
                      "worst single soil: ratio"), rows)
    sets = "".join(f"\n- {name}: {', '.join(b.removeprefix('earthlib:') for b in v['backgrounds'])} ({v['rule']})"
                   for name, v in r["sets"].items()) if k == 3 else ""
    return (f"{k} soils per set; chlorophyll RMS in µg/cm².\n\n{table}\n{sets}\n\nFrom `{_rel(path)}` (written by "
            f"`python -m bench.soil_backgrounds{'' if k == 3 else f' -k {k}'}`; {_machine(r)}).")


def cases(path: Path, command: str) -> str:
    """A benchmark's cases (``bench/results/igrm.json``, ``sam.json``): each case's contenders, their rate, s2cl's
    ratio over them and, where measured, the share at the float64 optimum, mean iterations and lane use."""
    r = _load(path)
    extra = (("frac_at_float64_optimum", "at float64 optimum", lambda v: f"{100 * v:.4f} %"),
             ("mean_iterations", "mean iterations", lambda v: f"{v:.2f}"),
             ("lane_use", "lane use", lambda v: f"{100 * v:.0f} %"))
    out = []
    for case in r["cases"]:
        cols = [e for e in extra if any(e[0] in row for row in case["rows"])]
        rows = [(row["method"] + (" *(baseline)*" if row.get("baseline") else ""), f"{row['per_s']:.3g}",
                 f"{row['ratio_s2cl_over_this']:.3g}",
                 *(f(row[k]) if row.get(k) is not None else "–" for k, _, f in cols)) for row in case["rows"]]
        out.append(f"**{case['title']}** ({case['n']:,} items)\n\n"
                   + md_table(("method", case["unit"], "s2cl ÷ this", *(t for _, t, _ in cols)), rows))
        if "float32_vs_float64" in case:
            d = case["float32_vs_float64"]
            q = ", ".join(f"{k} {v:.2g} nm" for k, v in d["lp"].items())
            out.append(f"float32 against float64, |Δλp| over pixels both fitted: {q}; the same status for "
                       f"{100 * d['status_agreement']:.4f} %.")
        if "agreement_with_spy" in case:
            out.append(f"Same argmin as SPy: {100 * case['agreement_with_spy']:.3f} %.")
    return "\n\n".join(out) + f"\n\nFrom `{_rel(path)}` (written by `{command}`; {_machine(r)})."


def lanes() -> str:
    """``python -m bench.bench_lanes``: each kernel family's rate per vector width, and the default's."""
    path = RESULTS / "lanes-amd-epyc-2c-2026-11-24.json"
    r = _load(path)
    fams = r["families"]
    widths = sorted({int(w) for f in fams.values() for w in f["rate"]})
    rows = [(name, f["unit"], *(f"{f['rate'][str(w)]:.3g}" if str(w) in f["rate"] else "" for w in widths),
             f["best_width"], f["default_width"]) for name, f in fams.items()]
    return (md_table(("kernel", "unit", *(f"{w} lanes" for w in widths), "fastest", "default"), rows)
            + f"\n\nFrom `{_rel(path)}` (written by `python -m bench.bench_lanes`; {_machine(r)}; {r['load_note']}).")


def chunks() -> str:
    """Time per configuration of one sweep against the chunk size."""
    r = _load(CHUNKS_JSON)
    rows = [(f"{int(c):,}", f"{v['ms_per_configuration']:.3g}", f"{v['min_ms']:.3g}–{v['max_ms']:.3g}")
            for c, v in sorted(r["chunks"].items(), key=lambda kv: int(kv[0]))]
    return (md_table(("chunk (configurations)", "ms per configuration (median)", "range"), rows)
            + f"\n\n{r['scene']}, {r['pixels']:,} pixels per configuration. From `{_rel(CHUNKS_JSON)}` (written by "
            f"`python -m bench.bench_sweep --skip-dask --scene {r['scene']} --chunks "
            f"{','.join(sorted(r['chunks'], key=int))}`; {_machine(r)}).")


def atmosphere_cost() -> str:
    """The resample kernel with and without the atmosphere, and the float64 numpy oracle."""
    r = _load(ATMOSPHERE_JSON)
    p, v = r["pixels_per_second"], r["validation_max_rel_error_vs_float64"]
    rows = [("kernel, atmosphere off", f"{p['kernel_atmosphere_off'] / 1e6:.3g} M"),
            ("kernel, atmosphere on",
             f"{p['kernel_atmosphere_on'] / 1e6:.3g} M ({r['ratios']['atmosphere_cost_on_vs_off']:.2f}× the time)"),
            ("numpy float64 forward + resample (oracle)", f"{p['numpy_float64_forward_resample'] / 1e6:.3g} M")]
    return (md_table(("", "pixels/s"), rows)
            + f"\n\n{r['pixels']:,} pixels, {r['wavelengths']} wavelengths, {r['bands']} bands, {r['precision']}; "
            f"validated first on {r['validation_pixels']} pixels against float64 (max relative error "
            f"{max(v.values()):.1g}). From `{_rel(ATMOSPHERE_JSON)}` (written by `python -m bench.bench_atmosphere`; "
            f"{_machine(r)}).")


def bench_page() -> str:
    """docs/bench.md as ``python -m bench`` writes it from :data:`BENCH_PAGE_JSON` (its figures are not redrawn)."""
    from bench import report

    figures = {g.key: f"bench/{g.figure.suffix}.png" for g in report.GROUPS if g.figure}
    return report.markdown(_load(BENCH_PAGE_JSON), figures, docs=True)


BLOCKS: dict[str, Callable[[], str]] = {
    **{f"study.{s}": (lambda s=s: study_table(s)) for s in STUDY_JSON},
    **{f"study.{s}.key-figures": (lambda s=s: study_key_figures(s)) for s in STUDY_JSON},
    **{name: _paper(name) for name in ("paper.table3", "paper.fit-accounting", "paper.coincident", "paper.table4",
                                       "paper.table5", "paper.table6", "paper.sensitivity", "paper.subsets",
                                       "paper.swir")},
    "paper.fig7": fig7,
    "paper.igrm-accuracy": igrm_accuracy,
    "paper.table3-timings": table3_timings,
    "paper.throughput": throughput,
    "bench.atmosphere": atmosphere_cost,
    "bench.chunks": chunks,
    "bench.lanes": lanes,
    "bench.igrm": lambda: cases(RESULTS / "igrm.json", "python -m bench.bench_igrm"),
    "bench.sam": lambda: cases(RESULTS / "sam.json", "python -m bench.bench_sam"),
    **{f"soils.k{k}": (lambda k=k: soils(k)) for k in (3, 10, 30)},
    "band-addition.mgoh": lambda: band_addition("mgoh"),
    "band-addition.yellow": lambda: band_addition("yellow"),
}

# pages generated whole (path relative to the repository → its text)
PAGES: dict[str, Callable[[], str]] = {"docs/bench.md": bench_page}
