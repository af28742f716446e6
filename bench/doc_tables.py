"""The Markdown of each generated block of the documentation (:mod:`bench.doc_blocks` rewrites the pages):
name → a function of committed results files only. Every block says which file it reads and which
command writes that file."""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Sequence
from functools import cache
from pathlib import Path
from typing import Any

from bench.bench_applications import BLOCKS as APPLICATIONS_BLOCKS
from bench.common import RESULTS, ROOT
from bench.doc_scorecard import BLOCKS as SCORECARD_BLOCKS
from bench.mission_report import BLOCKS as MISSION_BLOCKS
from bench.search_front import BLOCKS as SEARCH_FRONT_BLOCKS

DOCS = ROOT / "docs"
STUDIES = ("cirrus", "water-vapour", "aerosol", "ozone", "methane")
STUDY_JSON = {**{s: DOCS / "studies" / s / f"{s}.json" for s in STUDIES},
              "stability": DOCS / "stability" / "stability.json",
              "cellulose": DOCS / "cellulose" / "cellulose.json",
              "water-vapour-1020": DOCS / "water-vapour-1020" / "water-vapour-1020.json"}
SWEEP_JSON = RESULTS / "sweep.json"
CHUNKS_JSON = RESULTS / "sweep-chunks-amd-epyc-2c-2026-11-24.json"
THROUGHPUT_JSON = RESULTS / "sweep-throughput-amd-epyc-2c-2026-11-24.json"
SWEEP_PROFILE_JSON = RESULTS / "sweep-profile-amd-epyc-2c-2026-11-27.json"
FIG7_JSON = RESULTS / "fig7_igrm.json"
IGRM_ACCURACY_JSON = RESULTS / "igrm-accuracy-amd-epyc-2c-2026-11-24.json"
ATMOSPHERE_JSON = RESULTS / "atmosphere.json"
LUT_BUILD_JSON = RESULTS / "lut_build.json"
LUT_ACCURACY_JSON = RESULTS / "lut_accuracy.json"
RESIDUALS_JSON = RESULTS / "correction_residuals.json"
BENCH_PAGE_JSON = RESULTS / "amd-epyc-2c-2026-11-24.json"  # the full `python -m bench` run docs/bench.md shows
INSTRUMENT_JSON = DOCS / "studies" / "instrument" / "instrument.json"
STAGE_COSTS_JSON = RESULTS / "stage-costs.json"
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
    chunk_rate = o["evaluations"] / o["evaluate_chunk_s"]
    opencl_s = o["evaluate_chunk_s"] / o["configurations"] * r["configurations"]
    rows = [(f"fused kernel ({o['precision']}, {o['lanes']} lanes), {o['configurations']:,} configurations",
             f"{o['kernel_evaluations_per_s'] / 1e6:.3g} M", ""),
            ("+ per-configuration metrics in numpy on the host (Dask workers, devices without float64)",
             f"{o['with_metrics_evaluations_per_s'] / 1e6:.3g} M", ""),
            ("`evaluate_chunk` as a sweep runs it: + metrics on the device, rows", f"{chunk_rate / 1e6:.3g} M",
             f"{opencl_s:.0f} s"),
            (f"numpy twin ({n['what']}), {len(n['sample_configurations'])} configurations, extrapolated",
             f"{n['evaluations_per_s'] / 1e6:.3g} M", f"{w['numpy_s']:,.0f} s"),
            ("**ratio**", f"**{r['ratio_kernel']:.0f}×** (kernel)", f"**{w['numpy_s'] / opencl_s:.0f}×**")]
    v = r["validation"]
    return (md_table(("", "evaluations/s", f"whole {r['scene']}, extrapolated"), rows)
            + f"\n\nChecked first ({v['criterion']}): the same status for {100 * v['same_status_fraction']:.2f} % of "
            f"the pixels, |Δλp| median {v['index_abs_diff']['p50']:.1g} nm, 99th percentile "
            f"{v['index_abs_diff']['p99']:.1g} nm, per-configuration RMS within {v['rms_rel_diff_max']:.1g} "
            f"(relative). From `{_rel(THROUGHPUT_JSON)}` (written by `python -m bench.bench_sweep --skip-dask --output "
            f"{_rel(THROUGHPUT_JSON)}`; {_machine(r)}).")


def sweep_profile() -> str:
    """``python -m bench.sweep_profile``: iterations and lane use of the sweep's fits against the standalone fit's
    population, and where the fused kernel's time goes on the timed block."""
    r = _load(SWEEP_PROFILE_JSON)
    its, sec, rate, f, cm = r["iterations"], r["seconds"], r["rates_per_s"], r["findings"], r["cost_model"]
    names = {"sweep_sample": "sweep, random configurations", "timed_block": "sweep, the block bench_sweep times",
             "reference_design": "sweep, the sensor's own band set",
             "standalone_population": "standalone fit, bench_igrm's population"}
    rows = [(f"{names[k]} ({v['fits']:,} fits)", f"{v['mean']:.2f}", f"{v['quantiles']['p90']:.0f}",
             f"{v['quantiles']['max']:.0f}", f"{v['paid_iterations']:.2f}", f"{100 * v['lane_use']:.0f} %")
            for k, v in its.items()]
    table1 = md_table(("fits", "mean iterations", "90th pct", "max", "paid (group maximum)", "lane use"), rows)
    b = r["block"]
    e = b["evaluations"]
    timed = [("fused kernel (gather, noise, quantise, calibrate, correct, sort, fit, store)", "fused"),
             ("the same without its fit (`no_fit`)", "fused_no_fit"),
             ("the same with the fit stopped after one iteration (`max_iter` 1)", "fused_one_iteration"),
             ("the fit alone from the stored reflectances (`fit_only`)", "fused_fit_only"),
             ("standalone IGRM kernel on the same reflectances, a launch per configuration", "standalone_same_pixels"),
             ("as many launches of one lane group (their cost)", "standalone_empty_launches"),
             ("metrics as the sweep calls them (kernel, fetch, rows the host recomputes)", "metrics"),
             ("metrics kernel alone, work-groups named (`Runtime.local_size`)", "metrics_kernel"),
             ("metrics kernel alone, work-groups left to the driver", "metrics_kernel_driver_groups"),
             ("`evaluate_chunk` (kernel, metrics, rows)", "evaluate_chunk"),
             ("`evaluate_chunk`, the metrics' work-groups left to the driver", "evaluate_chunk_driver_groups"),
             ("standalone IGRM kernel, bench_igrm's population", "standalone_population")]
    table2 = md_table(("on the block", "seconds (median)", "evaluations or fits per s"),
                      [(w, f"{sec[k]:.3g}", f"{rate[k] / 1e6:.3g} M" if k in rate else "") for w, k in timed])
    same = r["same_pixels"]
    order, refill = its["sweep_sample"]["pixel_order"], r["refill_model"]
    return (f"{r['scene']}: {r['configurations']:,} configurations × {r['pixels']:,} pixels, {r['precision']}, "
            f"{r['lanes']} lanes. The {r['lanes']} pixels of a work-item iterate in lock-step until the slowest "
            f"stops, so each fit pays its group's maximum; lane use = mean ÷ paid iterations.\n\n{table1}\n\n"
            f"The timed block: {b['configurations']:,} configurations from number {b['first']:,} "
            f"({e:,} evaluations), in interleaved rounds.\n\n{table2}\n\n"
            f"On the same pixels the fused kernel takes {f['fused_over_standalone_same_pixels']:.2f}× the standalone "
            f"fit's time (its launch cost removed) and {f['fused_over_fit_only']:.2f}× the fit alone; the fits agree "
            f"bit for bit on all three paths (same status for {100 * same['fit_only_same_status_fraction']:.2f} % "
            f"and {100 * same['standalone_same_status_fraction']:.2f} % of the pixels, largest |Δλp| "
            f"{same['standalone_lp_abs_diff_max_nm']:.2g} nm). Of the kernel's time, the stages outside the fit "
            f"take {100 * f['outside_fit_share']:.1f} %, the fixed work of each lane group (initial guess, verdict) "
            f"{100 * f['fixed_work_share']:.1f} % and the paid iterations the rest "
            f"({cm['per_lane_group_iteration_ns']:,.0f} ns per lane-group iteration; fixed work "
            f"{cm['fixed_in_iterations']:.1f} iterations' worth); the metrics take "
            f"{100 * f['metrics_share_of_chunk']:.1f} % of a chunk. Left to the driver, the metrics kernel's "
            f"work-groups make one group of all the configurations, which one PoCL thread runs alone: "
            f"{f['metrics_kernel_driver_over_named_groups']:.2f}× the time of named groups, "
            f"{f['evaluate_chunk_driver_over_named_groups']:.2f}× for the whole chunk. The standalone fit runs "
            f"{f['population_over_fused']:.2f}× the fused rate on its own population because each of its fits "
            f"pays {f['paid_iterations_ratio']:.2f}× fewer iterations ({f['iterations_ratio']:.2f}× fewer, at "
            f"{f['lane_use_ratio']:.2f}× the lane use); at the block's costs per iteration and per group the model "
            f"predicts {cm['standalone_population_predicted_s']:.3g} s for it, measured "
            f"{cm['standalone_population_measured_s']:.3g} s. Over the whole sweep the lane use is "
            f"{100 * f['sweep_sample_lane_use']:.0f} %: lanes refilled the moment their fit stops, at no cost, would "
            f"make the kernel at most {f['perfect_lane_use_speedup_bound']:.2f}× faster. Grouping the pixels by their "
            f"mean iterations in other designs gives {100 * order['sorted_by_other_designs']:.0f} % (their own order "
            f"{100 * order['natural']:.0f} %, by each design's own iterations, known only after the fit, "
            f"{100 * order['sorted_by_own_iterations']:.0f} %; {order['rows']} sampled designs). Refilling the lanes "
            f"once k of them are free, each refill paying a lane group's fixed work, would take "
            + ", ".join(f"{refill[f'free_{k}']:.2f}× (k = {k})" for k in (4, 8, 12) if f"free_{k}" in refill)
            + f" today's time (a model on {refill['rows']} sampled designs' iteration counts, without the cost of "
            f"moving pixels in and out of lanes).\n\n"
            f"From `{_rel(SWEEP_PROFILE_JSON)}` (written by `python -m bench.sweep_profile`; {_machine(r)}; "
            f"{r['load_note']}).")


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


# -- docs/atmos.md ------------------------------------------------------------------------------------

def _pct(v: float, digits: int = 2) -> str:
    return f"{100 * v:.{digits}g} %"


def _accuracy_source() -> str:
    r = _load(LUT_ACCURACY_JSON)
    return (f"From `{_rel(LUT_ACCURACY_JSON)}` (written by `python -m bench.lut_accuracy`; {r['sixs']}; "
            f"{_machine(r)}).")


def lut_build_times() -> str:
    """``python -m bench.bench_lut_build``: the separable build against brute force (extrapolated)."""
    r = _load(LUT_BUILD_JSON)
    sl, sh, per = r["slice"], r["shipped_lut"], r["brute_force_seconds_per_run"]

    def brute(s: float) -> str:
        return f"{s / 3600:.2g} h" if s < 2 * 86400 else f"{s / 86400:,.0f} days"

    rows = [(f"slice: {sl['axes']}", f"{sl['separable_seconds']:.0f} s ({sl['separable_sixs_runs']:,} runs)",
             brute(sl["brute_force_seconds_extrapolated"]), f"{sl['ratio_brute_over_separable']:,.0f}×"),
            ("shipped LUT (axes below)", f"{sh['separable_seconds']:.0f} s = {sh['separable_seconds'] / 60:.1f} min "
             f"({sh['separable_sixs_runs']:,} runs, {sh['separable_workers']} workers)",
             brute(sh["brute_force_seconds_extrapolated"]), f"{sh['ratio_brute_over_separable']:,.0f}×")]
    machine = (_machine(r) if "cpu" in r["machine"] else f"{r['machine'].get('cpus', '?')} cores, CPU and load not "
               "recorded by that run")
    where = f"{machine}, {r['workers']} workers, {r['sixs']}" + (f"; {r['load_note']}" if "load_note" in r else "")
    return (md_table(("LUT", "separable build", "brute force (extrapolated)", "ratio"), rows)
            + f"\n\nBrute force: {r['brute_force_definition']}: {per['aerosol']:.3g} s per run with aerosol and "
            f"{per['aerosol_free']:.2g} s without. The shipped LUT's build time is the one its provenance records "
            f"(`lut.provenance['build']`). Checked first: the shipped LUT against direct 6S runs, largest relative "
            f"error {r['correctness_max_rel_error_vs_6s']:.1g}. From `{_rel(LUT_BUILD_JSON)}` (written by "
            f"`python -m bench.bench_lut_build`; {where}).")


def lut_nodes() -> str:
    """The LUT formula against 6S at node states: the standard state's table, the others' largest error."""
    r = _load(LUT_ACCURACY_JSON)
    std = r["nodes"]["standard"]["linear"]["relative_error"]
    rows = [(f"{wl:g}", *(f"{100 * e:+.4f} %" for e in errs), f"{100 * max(map(abs, errs)):.4f} %")
            for wl, errs in zip(r["wavelengths_nm"], std, strict=True)]
    off = [label for label, v in r["nodes"].items() if not v["on_nodes"]]
    if off:
        raise ValueError(f"{_rel(LUT_ACCURACY_JSON)}: node states {off} are not on the LUT's nodes")
    others = [f"{label} ({_pct(v['linear']['max_abs'], 2)})" for label, v in r["nodes"].items() if label != "standard"]
    return (md_table(("wavelength (nm)", *(f"ρ = {rho:g}" for rho in r["reflectances"]), "max abs"), rows)
            + f"\n\nLargest |relative error| at the other node states (330 DU, SZA 40°), over the same wavelengths "
            f"and reflectances: {'; '.join(others)}. " + _accuracy_source())


def lut_off_node() -> str:
    """Largest |relative error| over the paper's wavelengths and three reflectances, states between nodes."""
    r = _load(LUT_ACCURACY_JSON)
    rows = []
    for group, states in r["off_node"].items():
        if group == "all off node":
            rows += [(label, _pct(v["linear"]["max_abs"]), _pct(v["nearest"]["max_abs"]))
                     for label, v in states.items()]
            continue
        values = " / ".join(re.search(r"[\d.]+", label)[0] for label in states)  # type: ignore[index]
        linear = " / ".join(f"{100 * v['linear']['max_abs']:.2g}" for v in states.values()) + " %"
        worst = max(states, key=lambda k: states[k]["nearest"]["max_abs"])
        w = states[worst]["nearest"]
        exact = " (no nodes: Beer's law)" if all(v["on_nodes"] for v in states.values()) else ""
        rows.append((f"{group}{exact}: {values}", linear,
                     f"{_pct(w['max_abs'])} ({worst}, {w['worst_wavelength_nm']:g} nm)"))
    return (md_table(("off-node state (one parameter moved from the standard state)", "max error, linear",
                      "max error, nearest"), rows) + "\n\n" + _accuracy_source())


def lut_backscatter() -> str:
    """6S's path reflectance at 1610 nm for zeniths near backscatter, beside the LUT's linear interpolation."""
    r = _load(LUT_ACCURACY_JSON)["sza_backscatter"]
    rows = [(f"{z:g}", f"{a:.5f}", f"{b:.5f}") for z, a, b in zip(r["solar_zenith_deg"], r["sixs_path_reflectance"],
                                                                 r["lut_linear_path_reflectance"], strict=True)]
    nodes = ", ".join(f"{z:g}" for z in r["lut_solar_zenith_nodes"])
    return (f"Path reflectance (TOA reflectance over a black target) at {r['wavelength_nm']:g} nm, {r['state']}; "
            f"the LUT's zenith nodes are {nodes}°:\n\n"
            + md_table(("solar zenith (deg)", "6S", "LUT, linear"), rows) + "\n\n" + _accuracy_source())


def visibility_check() -> str:
    """The stored visibility → AOT550 table against 6S's own conversion."""
    r = _load(LUT_ACCURACY_JSON)["visibility"]
    v = r["visibility_km"]
    return (f"Against 6S's own conversion at {len(v)} visibilities from {v[0]:g} to {v[-1]:g} km, the table's AOT550 "
            f"differs by at most {r['max_abs_difference']:.2g} (6S prints 5 decimals). " + _accuracy_source())


def water_vapour_ranges() -> str:
    """The water-vapour range of the shipped LUT at a few zeniths (``lut.water_vapour_range``)."""
    from s2cl.atmos.atmosphere import AtmosphereLUT

    lut = AtmosphereLUT.load()
    ranges = ", ".join("{:.3g}–{:.3g} g/cm² at {:g}°".format(*lut.water_vapour_range(z), z) for z in (0.0, 40.0, 60.0))
    wv = lut.axes.water_vapour
    return (f"The water-vapour axis has {wv.size} nodes, {wv[0]:.3g}–{wv[-1]:.3g} g/cm² at the reference zenith of "
            f"40°; the range a state may use depends on the zenith: {ranges} (`lut.water_vapour_range(sza)`, read "
            "from the shipped `s2cl/data/atmosphere_lut.npz`).")


def profile_columns() -> str:
    """The water and ozone columns s2cl integrates from 6S's two mid-latitude profiles."""
    from s2cl.atmos.sixs_profiles import PROFILES, get_profile

    cols = "; ".join(f"{name.replace('_', ' ')}: {get_profile(name).water_column:.3g} g/cm² and "
                     f"{get_profile(name).ozone_column:.0f} DU" for name in PROFILES)
    return (f"s2cl defines a profile's columns by hydrostatic integration of its table "
            f"(`s2cl/data/sixs_profiles.csv`, `s2cl.atmos.sixs_profiles.get_profile(name).water_column` and "
            f"`.ozone_column`): {cols}.")


def lut_limits() -> str:
    """6S's measured limits: gas aliasing on its 2.5 nm grid, grid snapping, the Rayleigh-path floor."""
    r = _load(LUT_ACCURACY_JSON)
    g, s, f = r["gas_aliasing"], r["grid_snapping"], r["rayleigh_floor"]
    jumps = ", ".join(f"{b['max_jump']:.2f} in the {name} band ({b['between_nm'][0]:g}–{b['between_nm'][1]:g} nm)"
                      for name, b in g["bands"].items())
    interp = " and ".join(f"{wl} nm by {100 * p['relative_difference']:+.0f} %"
                          for wl, p in g["neighbour_interpolation"].items())
    nan = ", ".join(f"{w:g}" for w in s["non_finite_nm"][:3])
    floor = ", ".join(f"{p:.5f} at {w:g}" for w, p in zip(f["water_vapour_g_cm2"], f["sixs_path_reflectance"],
                                                          strict=True))
    return (f"- **2.5 nm gas grid, aliasing.** 6S's gas band model works in 10 cm⁻¹ intervals sampled at 2.5 nm. "
            f"Adjacent samples of the two-way gas transmittance jump by up to {jumps}, for the {g['state']}; linear "
            f"interpolation to 1 nm cannot resolve such lines: 6S itself differs from the linear interpolation of its "
            f"neighbours 2.5 nm either side at {interp}. In the SWIR one 10 cm⁻¹ interval covers several samples. "
            "Narrow-band results at 760, 940 and 1375 nm (the B10 cirrus study) inherit this; a MODTRAN-class code "
            "resolves it better.\n"
            f"- **Wavelengths must be on 6S's grid.** 6S snaps any other wavelength to its grid: of {s['requests']:,} "
            f"one-nm requests (400–2500 nm, {s['on_grid']} of them on the grid) only {s['distinct_results']:,} give "
            f"distinct results, and {s['non_finite']} come back non-finite"
            + (f" (for example {nan} nm)" if nan else "") + ", silently through Py6S. The builder only asks for grid "
            "wavelengths and refuses non-finite output.\n"
            f"- **Water vapour lies above the aerosol** in 6S, and the Rayleigh path gets no H₂O absorption. This "
            f"leaves a path-reflectance floor at {f['wavelength_nm']:g} nm at any water column ({floor} g/cm², "
            f"{f['state']}), which matters for the B10 cirrus study.\n\n" + _accuracy_source())


def user_water_and_ozone() -> str:
    """6S's ``UserWaterAndOzone`` profile against the LUT's scaled profile: path reflectance."""
    r = _load(LUT_ACCURACY_JSON)["user_water_and_ozone"]
    wls = sorted({row["wavelength_nm"] for row in r["rows"]})
    wvs = sorted({row["water_vapour_g_cm2"] for row in r["rows"]})
    return (f"6S's `UserWaterAndOzone` option would rescale the US-62 shape instead, which moves the path reflectance "
            f"at {' and '.join(f'{w:g}' for w in wls)} nm by {100 * r['min_abs_relative_difference']:.0f}–"
            f"{100 * r['max_abs_relative_difference']:.0f} % (water columns {', '.join(f'{w:g}' for w in wvs)} g/cm², "
            f"otherwise the paper's standard atmosphere). " + _accuracy_source())


def sixs_versions() -> str:
    """6SV2.1 against 6SV1.1: path reflectance at the paper's wavelengths."""
    r = _load(LUT_ACCURACY_JSON)["version_2_1"]
    rows = [(f"{row['wavelength_nm']:g}", f"{row['v1_1']:.5f}", f"{row['v2_1']:.5f}",
             f"{100 * row['relative_difference']:+.2f} %") for row in r["rows"]]
    return (f"Path reflectance (TOA reflectance over a black target), {r['state'].split(';')[0]}:\n\n"
            + md_table(("wavelength (nm)", "6SV1.1", "6SV2.1", "V2.1 − V1.1"), rows) + "\n\n" + _accuracy_source())


def correction_residuals() -> str:
    """``s2cl residuals``: the largest |corrected − true| band reflectance per library (× 10⁻⁴)."""
    r = _load(RESIDUALS_JSON)
    rows = [(f"`{lib}`", *(f"{1e4 * x:.2f}" for x in v["max_abs"])) for lib, v in r["libraries"].items()]
    return (md_table(("library", *r["bands"]), rows)
            + f"\n\nIn units of 10⁻⁴ reflectance; {r['sensor']}, float64 oracles. From `{_rel(RESIDUALS_JSON)}` "
            f"(written by `python -m bench.correction_residuals`, the numbers `{r['command']}` prints).")


def srf_floor() -> str:
    """The SRF model's constant floor, computed from :mod:`s2cl.sensor.srf`'s constants on the default grid."""
    import numpy as np

    from s2cl.grid import DEFAULT_GRID
    from s2cl.sensor.srf import ALPHA, X0, XE, XS, super_gaussian

    wl = DEFAULT_GRID.wavelengths
    floor = X0 * wl.size * DEFAULT_GRID.step_nm
    band = float(np.sum(super_gaussian(wl, 1500.0, 20.0) - X0) * DEFAULT_GRID.step_nm)
    cross = ALPHA / 2 * np.log(XS / X0) ** (1 / XE)
    return (f"Integrated over {wl[0]:g}–{wl[-1]:g} nm the floor would add X0 × {wl.size:,} nm = {floor:.2g} nm of "
            f"equivalent width, {100 * floor / band:.1g} % of a 20 nm band's weight drawn from the whole spectrum. "
            f"The super-Gaussian falls below the floor at ±{cross:.3f} FWHM (where Xs·exp(−|2x/α|^Xe) = X0). "
            "Computed from the constants of `s2cl/sensor/srf.py` on the default grid.")


def lut_errors() -> str:
    """The messages the shipped LUT gives for three bad inputs, produced by calling it."""
    from s2cl.atmos.atmosphere import AtmosphereLUT
    from s2cl.atmos.state import AtmosphereState
    from s2cl.errors import InputError
    from s2cl.grid import SpectralGrid

    lut = AtmosphereLUT.load()
    lines = []
    bad = ((AtmosphereState(aot550=1.2), None), (AtmosphereState(water_vapour=6.0, solar_zenith=60.0), None),
           (AtmosphereState(), SpectralGrid(350.0, 2500.0, 1.0)))
    for state, grid in bad:
        try:
            lut.terms(state, grid) if grid is not None else lut.terms(state)
        except InputError as err:
            lines.append(f"- key `{err.key}`: `{err.detail}`")
        else:
            raise AssertionError(f"{state} on {grid} was accepted")
    return "\n".join(lines)


def stability_noise_free() -> str:
    """The noise-free nominal error of each stability application, from the study's JSON."""
    path = STUDY_JSON["stability"]
    apps = _load(path)["data"]["applications"]
    errors = "; ".join(f"{a['label']}: {a['nominal_error_no_noise']:.3g} {a['unit']} ({a['metric']})" for a in apps)
    return f"Noise-free nominal errors: {errors}. From `{_rel(path)}` (written by `{study_command('stability')}`)."


def soil_fe_band_depth() -> str:
    """The spread of ``fe_band_depth`` over the shipped soils, computed from the committed earthlib file."""
    import numpy as np

    from s2cl.libraries.earthlib_spectra import soil_indices

    d = soil_indices()["fe_band_depth"]
    return (f"Over the {d.size:,} soils `fe_band_depth` runs from {d.min():.2g} to {d.max():.3g} (median "
            f"{np.median(d):.2g}, 95th percentile {np.percentile(d, 95):.2g}); computed by "
            "`s2cl.libraries.earthlib_spectra.soil_indices()` from the shipped `s2cl/data/earthlib_soils_npv.npz`.")


def cellulose_co2() -> str:
    """CO₂'s two-way transmittance near 2 µm in the shipped LUT (paper standard atmosphere), and its share of the
    2030/20 shoulder band (model SRF, eq. 1, cut at ±1 FWHM)."""
    import numpy as np

    from s2cl.atmos.atmosphere import AtmosphereLUT
    from s2cl.atmos.state import AtmosphereState
    from s2cl.sensor.srf import DEFAULT_SUPPORT, super_gaussian

    t = AtmosphereLUT.load().terms(AtmosphereState.paper_standard())
    wl, co2 = t.wavelength_nm, t.transmittance["carbon_dioxide"]

    def at(w: float) -> str:
        return f"{float(co2[np.argmin(np.abs(wl - w))]):.2f} at {w:g} nm"

    def span(lo: float, hi: float) -> np.ndarray:
        return co2[(wl >= lo) & (wl <= hi)]

    srf = super_gaussian(wl, 2030.0, 20.0) * (np.abs(wl - 2030.0) <= DEFAULT_SUPPORT * 20.0)
    share = 1.0 - float(np.sum(srf * co2) / np.sum(srf))
    return (f"Near 2 µm the LUT shows the 2.0 µm CO₂ band (two-way transmittance {at(2005)} and {at(2020)}) and the "
            f"2.06 µm band ({at(2055)} and {at(2070)}); between 2080 and 2100 nm it lies between "
            f"{span(2080, 2100).min():.2f} and {span(2080, 2100).max():.2f}, and from 2110 to 2250 nm it is at least "
            f"{span(2110, 2250).min():.3f}. In the 2030/20 shoulder band CO₂ absorbs {100 * share:.0f} % of the "
            "SRF-weighted transmittance, the same for every design. Read from the shipped LUT "
            "(`transmittance[\"carbon_dioxide\"]`, paper standard atmosphere: MLS, SZA 40°).")


def igrm_hyperspectral() -> str:
    """Where the hyperspectral IGRM puts l0, s and lp for PROSAIL canopies (the basis of the fit's default bounds)."""
    r = _load(FIG7_JSON)

    def rng(w: Result, key: str) -> str:
        return "{:.0f}–{:.0f} nm".format(*w[key])

    parts = [f"{w['window_nm'][0]}–{w['window_nm'][1]} nm: l0 {rng(w, 'l0_range_nm')}, s {rng(w, 's_range_nm')}, "
             f"lp {rng(w, 'lp_range_nm')}" for w in r["windows"]]
    return (f"Hyperspectral IGRM fits (float64, every 1 nm band of the window) of `{r['library']}` ({r['n_spectra']} "
            f"PROSAIL canopies, Cab 5–100 µg/cm², LAI 3 and 4): {'; '.join(parts)}. From `{_rel(FIG7_JSON)}` "
            "(written by `python -m bench.fig7_igrm`).")


def band_addition_machine() -> str:
    """Where ``python -m bench.band_addition`` ran, from its results file."""
    from bench import band_addition as b

    r = _load(b.RESULTS_JSON)
    load = r["machine"].get("load_average")
    return (f"Measured on {_machine(r)}" + (f" (1-minute load average {load[0]:.1f} at the start)" if load else "")
            + f"; from `{_rel(b.RESULTS_JSON)}`.")


def bench_page() -> str:
    """docs/bench.md as ``python -m bench`` writes it from :data:`BENCH_PAGE_JSON` (its figures are not redrawn)."""
    from bench import report

    figures = {g.key: f"bench/{g.figure.suffix}.png" for g in report.GROUPS if g.figure}
    return report.markdown(_load(BENCH_PAGE_JSON), figures, docs=True)


# -- docs/instrument.md -----------------------------------------------------------------------------

def instrument_costs() -> str:
    """``s2cl study instrument``: each instrument effect alone against the ideal instrument."""
    r = _load(INSTRUMENT_JSON)["data"]
    ideal = r["rows"][0]["seconds"]
    key = (r.get("analysis") or {}).get("score")
    rows = []
    for row in r["rows"]:
        worst = max(row["rms_effect"], key=row["rms_effect"].get)
        rows.append((row["instrument"], row["rms_effect_mean"],
                     "–" if row["instrument"] == "ideal" else f"{worst} {cell(row['rms_effect'][worst])}",
                     row["rms_vs_truth_mean"], row["score"].get(key) if key else None, row["seconds"],
                     f"{row['seconds'] / ideal:.2f}×"))
    spatial = r["spatial_step_seconds"]
    runs = {row["instrument"]: row["seconds"] for row in r["rows"]}
    share = ", ".join(f"{e} {spatial[e]:.3g} s of its {runs[e]:.3g} s run ({100 * spatial[e] / runs[e]:.0f} %)"
                      for e in spatial)
    m = r["machine"]
    loads = m["load_average_1min"]
    busy = max(loads) > 1.25 * m["cores"]
    load = (f"1-minute load average {loads[0]:.1f} before and {loads[1]:.1f} after the run: "
            + ("other jobs shared the machine, so the times are upper bounds; read ratios" if busy
               else "the machine was otherwise quiet"))
    a = r.get("analysis")
    what = (f"; the map: {a['kind']} on {' '.join(a['bands'])}, {a['parameter']} against the cube's truth (µg/cm² "
            "for cab)" if a else "")
    return (md_table(("instrument", "effect alone: RMS Δρ, mean of bands", "worst band", "product vs truth: RMS Δρ",
                      "map RMS vs truth", "s per run", "× ideal"), rows)
            + f"\n\n`{r['cube']}`, {r['pixels']:,} pixels at {r['input_gsd_m']:g} m, {r['product']} (L2 band "
            f"reflectance) of the {len(r['bands'])} bands, seed {r['seed']}{what}. The spatial step alone (every "
            f"band's PSF and shift): {share}; resampling every pixel, as a cube read from a file needs (the "
            f"generated cube resamples its distinct spectra only): {r['resample_every_pixel_seconds']:.3g} s "
            f"(timed on 8,192 pixels, scaled). From `{_rel(INSTRUMENT_JSON)}` (written by `s2cl study instrument -o "
            f"{_rel(INSTRUMENT_JSON.parent)}`; {m['device']}, {m['cores']} cores, {m['date']}; {load}).")


def product_example() -> str:
    """The worked example of docs/images.md: the scene, the command, what it printed and wrote (read back)."""
    from bench.bench_product import EXAMPLE_JSON

    r = _load(EXAMPLE_JSON)
    rows = [(f"`{f['file']}`", " ".join(f["bands"]), f"{f['size'][0]} × {f['size'][1]}", f"{f['pixel_m']:g} m",
             f"({f['corner'][0]:.10g}, {f['corner'][1]:.10g})", f["crs"], f["dtype"], f["nodata"] or "none")
            for f in r["files"]]
    warnings = "\n".join(r["warnings"])
    return (f"```toml\n{r['scene'].strip()}\n```\n\n```console\n$ {r['command']}\n{warnings}\n{r['stdout']}\n```\n\n"
            + md_table(("file", "bands", "pixels", "pixel", "upper-left corner", "CRS", "type", "no data"), rows)
            + f"\n\n`simulation.nc`'s `georeference`: {r['georeference']}. The product: {r['size']} × {r['size']} "
            "pixels of `builtin:fields` parcels on EnMAP's 224 bands, written in the shipped layout. From "
            f"`{_rel(EXAMPLE_JSON)}` (written, with the quicklook below, by "
            "`python -m bench.bench_product --example`).")


def _product_spread(r: Result) -> str:
    """How a product result's repeated runs spread: their own ratios, the ratio with the fastest (a) and (b), and
    reading alone against the run's own reading."""
    s = r["samples"]
    fastest = r["end_to_end_s"] / (min(s["read_alone_s"]) + min(s["kernel_alone_s"]))
    own = r["steps_s"].get("read the product (GeoTIFF rows, scale, no data)")
    return (f"; each time is the median of {r['repeats']} runs in turn, whose own ratios were "
            + ", ".join(f"{x:.2f}" for x in r["ratios"]) + f"; with the fastest (a) and (b) of the runs, "
            f"{fastest:.2f}×. Reading alone took {min(s['read_alone_s']):.2f}–{max(s['read_alone_s']):.2f} s across "
            "the runs" + (f", the run's own reading {own:.2f} s" if own is not None else ""))


def product_throughput() -> str:
    """``python -m bench.bench_product``: a product-sized scene end to end against reading it and the kernel."""
    path = sorted(RESULTS.glob("product-*.json"))[-1]
    r = _load(path)
    m = r["machine"]
    steps = sorted(r["steps_s"].items(), key=lambda kv: -kv[1])
    total = r["end_to_end_s"]
    rows = [("end to end (`s2cl simulate`)", total, r["pixels_per_s"]["end_to_end"], "1"),
            ("(a) reading the product alone", r["read_alone_s"], r["pixels_per_s"]["read_alone"],
             f"{r['read_alone_s'] / total:.2f}"),
            ("(b) resampling kernel alone", r["kernel_alone_s"], r["pixels_per_s"]["kernel_alone"],
             f"{r['kernel_alone_s'] / total:.2f}")]
    if "gridding_alone_s" in r:  # a result of the path that put pixels on the grid on the host
        rows.append(("putting the pixels on the grid alone", r["gridding_alone_s"], r["pixels"] / r["gridding_alone_s"],
                     f"{r['gridding_alone_s'] / total:.2f}"))
    where = md_table(("step of the end-to-end run (self time)", "s", "share"),
                     [(name, sec, f"{100 * sec / total:.0f} %") for name, sec in steps]
                     + [("the rest (scene, checks, kernel builds, JSON)", r["other_s"],
                         f"{100 * r['other_s'] / total:.0f} %")])
    loads = (m["load_average"][0], r["load_average_after"][0])
    busy = loads[0] > 0.5 * m["cores"]  # before the runs (after them, the load is mostly the benchmark's own)
    return (md_table(("run", "s", "pixels/s", "share of end to end"), rows)
            + f"\n\nEnd to end is **{r['ratio_to_read_plus_kernel']:.1f}×** (a) + (b) (the goal was within 2×)"
            + (_product_spread(r) if r.get("repeats", 1) > 1 else "") + ". "
            f"Peak memory (max RSS of the run's process): **{r['max_rss_bytes'] / 1e9:.2f} GB** under "
            f"`--max-memory {r['max_memory']}`, in blocks of {r['block_rows']} input rows.\n\n" + where
            + f"\n\nThe product: {r['size']} × {r['size']} pixels × {r['bands']} bands, {r['dtype']} "
            f"({r['product_bytes'] / 1e6:,.0f} MB), to all 13 bands and an IGRM map. From `{_rel(path)}` (written by "
            f"`python -m bench.bench_product --size {r['size']} --max-memory {r['max_memory']}`; "
            f"{m.get('opencl_device', 'device')}, {m['cores']} cores, {m['date']}; 1-minute load average "
            f"{loads[0]:.1f} before and {loads[1]:.1f} after: "
            + ("other jobs shared the machine, so the times are upper bounds" if busy else "the machine was otherwise "
               "quiet") + ").")


def search_joint(joint: str) -> str:
    """The six-band search and its local checks with the joint step ``joint`` (``python -m bench.search_wide
    --scene ...``)."""
    from bench.search_wide import JOINT_SCENE, joint_section, results_path

    return joint_section(_load(results_path(JOINT_SCENE, joint)))


def search_joint_one_start() -> str:
    """The six-band search as it was before restarts and recombination (one coarse start; the results file kept
    from that run, ``python -m bench.search_wide --scene ... --joint split`` at commit b8362b4)."""
    from bench.search_wide import JOINT_SCENE, ONE_START, joint_section, results_path

    path = results_path(JOINT_SCENE, "split").with_name(ONE_START)
    return joint_section(_load(path), path)


# -- docs/devices.md --------------------------------------------------------------------------------

def machines() -> str:
    """``python -m bench.machines``: which emulated set-ups of tests/test_machines.py ran here, and how."""
    from bench.machines import RESULTS_JSON

    path = RESULTS / RESULTS_JSON
    r = _load(path)
    rows = [(c["test"].removeprefix("test_").replace("_", " "), c["outcome"], c["seconds"], c["why"] or "–")
            for c in r["cases"]]
    m = r["machine"]
    return (md_table(("set-up (test)", "outcome", "s", "why skipped or failed"), rows)
            + f"\n\nOn {r['cpu']}, {m['cores']} cores, {m['date'][:10]}, with the OpenCL devices "
            + "; ".join(f"`{d}`" for d in r["drivers"]) + f"; {r['seconds']:.0f} s in all (1-minute load average "
            f"{m['load_average_before'][0]:.1f} before, {m['load_average_after'][0]:.1f} after). From "
            f"`{_rel(path)}` (written by `{r['command']}`).")


def _load_note(r: Result) -> str:
    loads = [r["load_average_start"][0], r["load_average_end"][0]]
    cores = r["machine"]["cores"]
    busy = max(loads) > 1.25 * cores
    return (f"1-minute load average {loads[0]:.1f} before and {loads[1]:.1f} after, on {cores} cores: "
            + ("other jobs shared the machine, so read the ratios, not the seconds" if busy
               else "the machine was otherwise quiet"))


def _secs(t: float) -> str:
    return f"{t:.3g} s" if t >= 1 else f"{t * 1e3:.3g} ms"


def stage_costs() -> str:
    """``python -m bench.stage_costs``: each new per-pixel stage's time in the sense and sweep kernels."""
    r = _load(STAGE_COSTS_JSON)
    f, w = r["forward"], r["sweep"]
    rows = []
    it = w.get("iterations", {})
    for name in r["stages"]:
        settings = ", ".join(f"{k} {v}" for k, v in r["stages"][name].items())
        rows.append((f"{name} ({settings})",
                     *(f"{_secs(t[name])} against {_secs(t['none'])} ({t[name] / t['none']:.2f}×)"
                       for t in (f["sense"], w["no_fit"], w["kernel"])),
                     f"{it[name]:.3g} against {it['none']:.3g}" if it else "–"))
    return (md_table(("stage alone", f"sense kernel, {f['bands']} bands × {f['pixels']:,} pixels",
                      "sweep kernel without the fit (no_fit build: the stages' own cost)",
                      f"whole sweep kernel, {w['configurations']:,} configurations × {w['pixels']:,} pixels",
                      "IGRM iterations per fit (mean)"), rows)
            + "\n\nThe build without the fit measures the stages themselves; the whole kernel's time is the fit's "
            "(its iterations, which a stage may move by changing the reflectance it fits, and the machine's load). "
            f"Medians of interleaved rounds against the chain without the stage, `{r['scene']}`'s sweep "
            f"(noise, quantisation, calibration, correction, IGRM), {r['machine']['opencl_device']}, "
            f"{r['machine']['lanes']['float32']} float32 lanes; {_machine(r)}; {_load_note(r)}. Measured by "
            f"`python -m bench.stage_costs` into `{_rel(STAGE_COSTS_JSON)}`.")


def stage_table3() -> str:
    """``python -m bench.stage_costs``: the Table 3 Lib1 B4567 winner with each new stage on."""
    r = _load(STAGE_COSTS_JSON)
    rows_in = r["winners"]
    base = next(x for x in rows_in if x["label"] == "none" and x["how"] == "sweep") if any(
        x["how"] == "sweep" for x in rows_in) else rows_in[0]

    def design(b: dict[str, list[float]]) -> str:
        return " ".join(f"{k} {c:g}/{w:g}" for k, (c, w) in b.items())

    rows = []
    for x in rows_in:
        moved = "–" if x is base else ("no" if x["bands"] == base["bands"] else "**yes**")
        rows.append((x["label"], x["how"], design(x["bands"]), x["rms"], x["rms"] - base["rms"], moved))
    sweeps = {x["label"]: x for x in rows_in if x["how"] == "sweep"}
    agree = [x["label"] for x in rows_in if x["how"] == "search" and x["label"] in sweeps
             and x["bands"] == sweeps[x["label"]]["bands"] and x["rms"] == sweeps[x["label"]]["rms"]]
    checked = (f" The halving search gave the exhaustive sweep's winner and RMS for {len(agree)} of the "
               f"{len(sweeps)} settings run both ways." if sweeps else "")
    return (md_table(("stage on", "how", "best design (centre/FWHM, nm)", "Cab RMS (µg/cm²)", "Δ RMS", "moved?"),
                     rows)
            + f"\n\n`{r['scene']}` (43,056 designs × 12,000 noisy Lib1 pixels); a calibration error on one band "
            "is that band's alone (the others exact), the uncertainty row draws every band's error once from the "
            f"scene's seed, crosstalk is among the design's four bands (one focal plane).{checked} {_machine(r)}. "
            f"Measured by `python -m bench.stage_costs` into `{_rel(STAGE_COSTS_JSON)}`.")


def cube_footprint() -> str:
    """docs/images.md: an image's declared host memory against the measured peak, per device and case
    (``bench/results/cube-footprint.json``)."""
    path = RESULTS / "cube-footprint.json"
    r = _load(path)
    mb = lambda v: f"{v / 1e6:.1f}"  # noqa: E731
    rows = []
    for d in r["devices"]:
        for case in d["cases"]:
            for run in case["runs"]:
                rows.append((d["device"].split(" (")[0], case["case"], run["block_rows"], mb(run["declared"]),
                             mb(run["rss"]), mb(run["traced"]), f"{run['rss'] / run['declared']:.2f}"))
    per_row = []
    for d in r["devices"]:
        for case in d["cases"]:
            if "per_pixel_row" in case:
                b = case["per_pixel_row"]
                per_row.append((d["device"].split(" (")[0], case["case"], f"{b['declared']:,.0f}", f"{b['rss']:,.0f}",
                                f"{b['traced']:,.0f}"))
    return (md_table(("device", "cube", "block rows", "declared MB", "resident MB", "numpy MB", "resident ÷ declared"),
                     rows)
            + "\n\nBytes per input pixel of a row read (between the two block sizes):\n\n"
            + md_table(("device", "cube", "declared", "resident", "numpy"), per_row)
            + f"\n\nFrom `{_rel(path)}` (written by `{r['command']}`; {_machine(r)}; {_load_note(r)}).")


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
    "bench.sweep-profile": sweep_profile,
    "bench.lanes": lanes,
    "bench.igrm": lambda: cases(RESULTS / "igrm.json", "python -m bench.bench_igrm"),
    "bench.sam": lambda: cases(RESULTS / "sam.json", "python -m bench.bench_sam"),
    **{f"soils.k{k}": (lambda k=k: soils(k)) for k in (3, 10, 30)},
    "band-addition.mgoh": lambda: band_addition("mgoh"),
    "band-addition.yellow": lambda: band_addition("yellow"),
    "band-addition.machine": band_addition_machine,
    "atmos.build-times": lut_build_times,
    "atmos.nodes": lut_nodes,
    "atmos.off-node": lut_off_node,
    "atmos.backscatter": lut_backscatter,
    "atmos.visibility": visibility_check,
    "atmos.water-vapour-range": water_vapour_ranges,
    "atmos.profile-columns": profile_columns,
    "atmos.limits": lut_limits,
    "atmos.user-water-and-ozone": user_water_and_ozone,
    "atmos.sixs-versions": sixs_versions,
    "atmos.residuals": correction_residuals,
    "atmos.errors": lut_errors,
    "sensor.srf-floor": srf_floor,
    "stability.noise-free": stability_noise_free,
    "soils.fe-band-depth": soil_fe_band_depth,
    "cellulose.co2": cellulose_co2,
    "retrieve.igrm-hyperspectral": igrm_hyperspectral,
    "instrument.costs": instrument_costs,
    "search.joint-b3-b8a": lambda: search_joint("split"),
    "search.joint-b3-b8a-full": lambda: search_joint("full"),
    "search.joint-b3-b8a-one-start": search_joint_one_start,
    "machines": machines,
    "images.product-example": product_example,
    "images.cube-footprint": cube_footprint,
    "images.product-throughput": product_throughput,
    "stages.costs": stage_costs,
    "stages.table3": stage_table3,
    **SCORECARD_BLOCKS,
    **MISSION_BLOCKS,
    **APPLICATIONS_BLOCKS,
    **SEARCH_FRONT_BLOCKS,
}

# pages generated whole (path relative to the repository → its text)
PAGES: dict[str, Callable[[], str]] = {"docs/bench.md": bench_page}
