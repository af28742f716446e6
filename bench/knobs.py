"""What accuracy costs in time: one knob at a time from the default scene, each row timed and
scored against a reference (see bench/chain.py for the chain and the all-accurate reference).

Every knob returns ``{"reference", "primary_error", "error_label", "rows"}`` (its name, title and
columns are declared in :mod:`bench.registry`); a row holds ``setting``, ``default`` (the shipped
setting), ``seconds`` (median), ``speedup`` (reference seconds / seconds) and the errors against
the knob's reference.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.chain import (
    BANDS,
    REFERENCE_FIT,
    REFERENCE_FIT_REAL,
    ChainRun,
    Context,
    analysis_bands,
    compare,
    default_run,
    knob_row,
    noise_sigma,
    oracle_band_radiance,
    reference_run,
    run_chain,
    slice_reflectance,
    time_runs,
    validated,
)
from bench.common import check, interleaved_medians
from s2cl import SpectralLibrary
from s2cl.app.chain_parts import scene_simulator
from s2cl.atmos.atmosphere import ARRAY_DIMS as LUT_DIMS
from s2cl.cl.runtime import get_runtime
from s2cl.reference.forward import resample
from s2cl.retrieve.igrm import IgrmFitter
from s2cl.retrieve.igrm_settings import IgrmSettings, kernel_config
from s2cl.retrieve.quantify import score_igrm, score_retrieval
from s2cl.scene.library import scene_library
from s2cl.scene.terms import scene_atmosphere, scene_lut, true_state

KnobResult = dict[str, Any]
RADIANCE_ERROR = ("err_radiance_ner_max", "max band-radiance error / NER")


def _result(reference: str, rows: list[dict[str, Any]], primary: tuple[str, str], **extra: Any) -> KnobResult:
    """A knob's result: what its rows are scored against, its rows and its primary error (the
    Pareto plot's y axis: row key and label)."""
    return {"reference": reference, "primary_error": primary[0], "error_label": primary[1], "rows": rows, **extra}


def _with_reference(ref: ChainRun, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [knob_row("reference (float64, 1 nm, ±3 FWHM, converged)", ref, ref, extra={"reference": True}), *rows]


# -- computational knobs: the same physics, computed more or less exactly ------------------------

def knob_grid(ctx: Context) -> KnobResult:
    """Spectral grid step: library, atmosphere and SRFs on a 1, 2, 5 or 10 nm grid."""
    ref = reference_run(ctx)
    runs = {step: default_run(ctx) if step == 1 else run_chain(ctx, f"{step} nm", {"grid.step_nm": float(step)})
            for step in (1, 2, 5, 10)}
    time_runs(ctx, ref, *runs.values())
    rows = [knob_row(f"{step} nm", run, ref, default=step == 1) for step, run in runs.items()]
    return _result("all-accurate chain", _with_reference(ref, rows), RADIANCE_ERROR)


def knob_precision(ctx: Context) -> KnobResult:
    """float32 vs float64 in the kernels (forward chain and IGRM fit), default fit settings."""
    ref = reference_run(ctx)
    f32 = default_run(ctx)
    f64_32 = run_chain(ctx, "f64/f32", {"compute.precision": "float64"})
    f64 = run_chain(ctx, "f64/f64", {"compute.precision": "float64"}, fit_real="float64")
    time_runs(ctx, ref, f32, f64_32, f64)
    rows = []
    for label, run, default in (("float32 kernels + float32 fit", f32, True),
                                ("float64 kernels + float32 fit", f64_32, False),
                                ("float64 kernels + float64 fit", f64, False)):
        same = compare(run, f64)  # the precision alone: against float64 at the same settings
        rows.append(knob_row(label, run, ref, default=default,
                             extra={"precision_radiance_rel_max": same["err_radiance_rel_max"],
                                    "precision_radiance_ner_max": same["err_radiance_ner_max"],
                                    "precision_lp_rms_nm": same["err_lp_rms_nm"]}))
    return _result("all-accurate chain", _with_reference(ref, rows),
                   ("err_lp_rms_nm", "RMS lp error vs reference [nm]"),
                   note="precision_* columns in the JSON: the same settings in float64 as the reference, i.e. what "
                        "the precision alone changes")


def knob_srf(ctx: Context) -> KnobResult:
    """SRF support cut-off (± 1, 1.5, 2 FWHM of the eq. 1 model) and the measured S2A responses."""
    ref = reference_run(ctx)
    runs: list[tuple[str, ChainRun, dict[str, Any]]] = []
    for support in (1.0, 1.5, 2.0):
        run = default_run(ctx) if support == 1.0 else run_chain(ctx, f"±{support:g}", {"sensor.support": support})
        runs.append((f"model SRF ±{support:g} FWHM", run, {"default": support == 1.0}))
    skipped = []
    try:
        run = run_chain(ctx, "measured", {"sensor.srf": "measured-S2A"})
        runs.append(("measured S2A SRF (Py6S; a different sensor model, not a cut)", run,
                     {"extra": {"model_change": True}}))
    except Exception as err:  # Py6S missing: the row says so instead of failing the suite
        skipped.append({"setting": f"measured S2A SRF: unavailable ({type(err).__name__}: {err})", "skipped": True})
    time_runs(ctx, ref, *(r for _, r, _ in runs))
    rows = [knob_row(label, run, ref, **kw) for label, run, kw in runs] + skipped
    return _result("all-accurate chain",
                   _with_reference(ref, rows), RADIANCE_ERROR)


def _fit_rows(ctx: Context, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fit-knob input: the slice's reflectance for accuracy, tiled to ``n`` pixels for time."""
    refl, centres, target = slice_reflectance(ctx)
    return refl, centres, target, np.ascontiguousarray(np.resize(refl, (refl.shape[0], n)))


def knob_lm(ctx: Context, population: int) -> KnobResult:
    """IGRM fit: iteration limit and tolerance, incl. the closed-form initial guess alone."""
    from s2cl.reference.igrm import _normalise, initial_guess

    refl, centres, target, pixels = _fit_rows(ctx, population)
    ref_fit = IgrmFitter(get_runtime(), len(BANDS), REFERENCE_FIT, real_t=REFERENCE_FIT_REAL)
    ref = ref_fit.fit(refl.astype(np.float64), centres)
    ref_score = score_igrm(ref, target)
    check(ref.fitted().mean() > 0.99, "reference fits fail on the slice")
    pixels64 = pixels.astype(np.float64)

    def row(setting: str, lp: np.ndarray, fitted: np.ndarray, rms: float, *, default: bool = False, **extra: Any
            ) -> dict[str, Any]:
        """Accuracy of one setting; ``seconds``, ``pixels_per_s`` and ``speedup`` are added once timed."""
        both = fitted & ref.fitted()
        d = lp[both].astype(np.float64) - ref.lp[both]
        return {"setting": setting, "err_lp_rms_nm": float(np.sqrt(np.mean(d**2))),
                "frac_at_optimum": float(np.mean(np.abs(d) <= 0.05) * both.mean()), "rms_cab": rms,
                "err_rms_cab": abs(rms - ref_score.rms), "default": default, **extra}

    timers: list[Any] = [lambda: ref_fit.fit(pixels64, centres)]
    rows = [row("reference: float64, tol 1e-10, max_iter 255", ref.lp, ref.fitted(), ref_score.rms, reference=True)]
    # the closed-form (data) initial guess alone, in float32 numpy: what zero iterations give
    c = kernel_config(IgrmSettings(), len(BANDS), "float32")
    x = _normalise(centres, c, np.float32)

    def guess(y: np.ndarray) -> np.ndarray:
        _, _, p2, p3, _ = initial_guess(y, x, c)
        return (p2 + p3) * np.float32(c.xw) + np.float32(c.xc)

    lp0 = guess(refl)
    fitted0 = np.ones(lp0.shape, bool)
    rms0 = score_retrieval(lp0.astype(np.float64), target).rms
    rows.append(row("initial guess only (numpy, no LM step)", lp0, fitted0, rms0))
    timers.append(lambda: guess(pixels))
    settings = [(f"max_iter {m}", IgrmSettings(max_iter=m)) for m in (1, 2, 3, 5, 10, 20, 50, 255)]
    settings += [(f"tol {t:g}", IgrmSettings(tol=t)) for t in (1e-2, 1e-3, 1e-4, 1e-7)]
    settings += [("grid initial guess (6×6)", IgrmSettings(init="grid"))]
    for label, st in settings:
        fitter = IgrmFitter(get_runtime(), len(BANDS), st)
        r = fitter.fit(refl, centres)
        timers.append(lambda f=fitter: f.fit(pixels, centres))
        default = st == IgrmSettings()
        rows.append(row(label + (" (default: tol 1e-5)" if default else ""), r.lp, r.fitted(),
                        score_igrm(r, target).rms, default=default, mean_iterations=float(r.iterations.mean()),
                        frac_iteration_limit=float(np.mean(r.status == 1))))
    for r, sec in zip(rows, interleaved_medians(timers, ctx.repeat, warmup=1), strict=True):
        r["seconds"], r["pixels_per_s"] = sec, pixels.shape[1] / sec
    for r in rows:
        r["speedup"] = rows[0]["seconds"] / r["seconds"]
    return _result("float64 fit, tol 1e-10, 255 iterations, same input", rows,
                   ("err_lp_rms_nm", "RMS lp error vs converged fit [nm]"),
                   timed=f"Time: fitting {pixels.shape[1]:,} pixels (the slice's reflectance tiled); accuracy "
                         "on the slice itself")


#: LUT axis (its array in the .npz) -> the dimension's name in s2cl.atmos.atmosphere's array layout
LUT_AXIS_DIM = {"aot550": "aot", "solar_zenith": "sza", "water_vapour": "wv"}


def _thin(arrays: dict[str, np.ndarray], axis: str, state_node: int) -> dict[str, np.ndarray]:
    """Drop every other node of ``axis`` (endpoints kept), choosing the phase that drops ``state_node``,
    from the axis and from every LUT array along that dimension."""
    n = arrays[axis].size
    keep = sorted({0, n - 1, *range(1 - state_node % 2, n, 2)} - {state_node})
    out = dict(arrays)
    out[axis] = arrays[axis][keep]
    dim = LUT_AXIS_DIM[axis]
    for key, dims in LUT_DIMS.items():
        if dim in dims:
            out[key] = np.take(arrays[key], keep, axis=dims.index(dim))
    return out


def knob_lut(ctx: Context) -> KnobResult:
    """Atmosphere LUT: linear vs nearest interpolation, and every other node of an axis dropped.

    The paper's standard atmosphere (AOT 0.2347, SZA 40°, 1.5 g/cm² H2O) lies on nodes of the
    shipped LUT, so the full LUT gives its exact terms; thinning drops exactly those nodes, so
    interpolation has to bridge the widest gap it would meet."""
    from s2cl.atmos.atmosphere import AtmosphereLUT, default_lut_path

    validated(ctx)
    scene = ctx.scene()
    lut, state = scene_lut(scene), true_state(scene)
    ax = lut.axes
    nodes = {"aot550": int(np.argmin(np.abs(ax.aot550 - state.aot550))),
             "solar_zenith": int(np.argmin(np.abs(ax.solar_zenith - state.solar_zenith))),
             "water_vapour": int(np.argmin(np.abs(ax.water_vapour - state.water_vapour)))}
    check(abs(ax.aot550[nodes["aot550"]] - state.aot550) < 1e-5 and state.solar_zenith == ax.reference_zenith
          and abs(ax.water_vapour[nodes["water_vapour"]] - state.water_vapour) < 1e-6,
          "the paper's state is expected on LUT nodes")
    with np.load(default_lut_path(), allow_pickle=False) as npz:
        full = {k: np.asarray(npz[k]) for k in npz.files}
    lib = ctx.library_slice(scene)
    base = default_run(ctx, timed=False)  # only its accuracy (and its SRF weights) are used here

    def radiance(terms: Any) -> np.ndarray:
        return oracle_band_radiance(lib.spectra, terms, base.weights)

    exact = radiance(lut.terms(state, scene.grid, "linear"))
    sigma = noise_sigma(scene, exact)
    timers: list[Any] = []
    variants: list[tuple[str, tuple[str, ...]]] = [("every node", ()), ("every other AOT node", ("aot550",)),
                                                   ("every other SZA node", ("solar_zenith",)),
                                                   ("every other H2O node", ("water_vapour",)),
                                                   ("every other node of all three", tuple(nodes))]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, axes in variants:
            arrays = full
            for a in axes:
                arrays = _thin(arrays, a, nodes[a])
            path = Path(tmp) / f"lut-{len(rows)}.npz"
            np.savez(path, **arrays)  # a private temporary folder: no atomic write needed
            thin = AtmosphereLUT.load(path)
            for method in ("linear", "nearest"):
                terms = thin.terms(state, scene.grid, method)
                timers.append(lambda t=thin, m=method: t.terms(state, scene.grid, m))
                err = np.abs(radiance(terms) - exact)
                run = run_chain(ctx, label, {"atmosphere.lut": str(path), "atmosphere.interpolation": method},
                                timed=False)
                d = run.fit.lp.astype(np.float64) - base.fit.lp
                rows.append({"setting": f"{label}, {method}", "default": not axes and method == "linear",
                             "nodes": int(np.prod([arrays[k].size for k in nodes])),
                             "err_radiance_rel_max": float(np.max(err / exact)),
                             "err_radiance_ner_max": float(np.max(err / sigma)),
                             "err_lp_rms_nm": float(np.sqrt(np.mean(d**2))), "rms_cab": run.score.rms,
                             "err_rms_cab": abs(run.score.rms - base.score.rms)})
        for r, sec in zip(rows, interleaved_medians(timers, ctx.repeat, warmup=1), strict=True):
            r["seconds"] = sec
    t_ref = rows[0]["seconds"]  # every node, linear: the shipped setting and, on nodes, exact
    for r in rows:
        r["speedup"] = t_ref / r["seconds"]
    return _result("exact LUT nodes (shipped LUT)", rows,
                   RADIANCE_ERROR, timed="Time: the LUT terms for one state on the 1 nm grid (host, once per scene)",
                   note="lp and Cab errors: the whole chain (simulation and correction) on the thinned LUT, against "
                        "the default chain")


# -- physics knobs: what an effect or a sample size changes --------------------------------------

def knob_copies(ctx: Context, seeds: int) -> KnobResult:
    """Noise copies per spectrum: the confidence interval of the chlorophyll RMS each buys."""

    validated(ctx)
    seed_list = range(1, seeds + 1)
    rows = []
    for copies in (10, 100, 1000):
        scene = ctx.scene(**{"surface.copies": copies})
        lib = scene_library(scene)  # the whole Lib1 (120 spectra), as the default scene runs it
        sim = scene_simulator(get_runtime(), scene, atmosphere=scene_atmosphere(scene))
        fitter = IgrmFitter(get_runtime(), len(BANDS))
        slots, centres, target = analysis_bands(scene, lib, copies)
        rms, times = [], []
        for seed in seed_list:
            t0 = time.perf_counter()
            res = sim.run_library(lib, copies=copies, seed=seed)
            check(res.reflectance is not None, "the default scene does not correct to reflectance")
            r = fitter.fit(res.reflectance[slots].reshape(len(slots), -1), centres)
            times.append(time.perf_counter() - t0)
            rms.append(score_igrm(r, target).rms)
        sd = statistics.stdev(rms)
        rows.append({"setting": f"{copies} copies", "default": copies == 100, "seconds": statistics.median(times),
                     "rms_cab": statistics.mean(rms), "rms_cab_sd": sd, "ci95_halfwidth": 1.96 * sd,
                     "seeds": len(rms), "pixels": lib.size * copies})
    ref = rows[-1]["seconds"]
    for r in rows:
        r["speedup"] = ref / r["seconds"]
    return _result(f"spread over {seeds} noise seeds (vs 1000 copies)",
                   rows, ("ci95_halfwidth", "95 % half-width of the Cab RMS [ug/cm2]"),
                   timed="Whole Lib1 (120 spectra); time: one seed, simulate the library with its copies and fit "
                         "(compiled chain)")


def knob_bits(ctx: Context) -> KnobResult:
    """Quantisation bits, against the same noisy chain without quantisation."""
    ref = run_chain(ctx, "float", {"effects.quantise": False, "effects.calibrate": False})
    runs = {bits: default_run(ctx) if bits == 12 else run_chain(ctx, f"{bits}", {"effects.bits": bits})
            for bits in (8, 10, 12, 14, 16)}
    time_runs(ctx, ref, *runs.values())
    rows = [knob_row("no quantisation (reference)", ref, ref, extra={"reference": True})]
    rows += [knob_row(f"{bits} bits", run, ref, default=bits == 12) for bits, run in runs.items()]
    return _result("noisy chain without quantisation", rows,
                   ("err_lp_rms_nm", "RMS lp change vs unquantised [nm]"))


def knob_atmosphere(ctx: Context) -> KnobResult:
    """Atmosphere effect on (6S LUT, band-effective correction) vs off (TOA radiance ρ·E0·cos θs/π,
    no path radiance, no transmittance losses; reflectance = radiance / band-effective E0·cos θs/π)."""
    on = default_run(ctx)
    scene = ctx.scene()
    terms = scene_atmosphere(scene)
    check(terms is not None, "the default scene has no atmosphere")
    scale = terms.e0 * terms.mu_s / np.pi
    lib = scene_library(scene)
    radiance_lib = SpectralLibrary(lib.grid, lib.spectra * scale, lib.names, quantity="radiance", groups=lib.groups,
                                   params=dict(lib.params), source="Lib1 × E0·cos θs/π (no atmosphere)")
    divisor = resample(scale[None, :], on.weights)[:, 0]  # band-effective E0·cos θs/π, the chain's SRFs
    off = run_chain(ctx, "off", {"effects.atmosphere": False, "effects.correct": False,
                                 "surface.quantity": "radiance"}, library=radiance_lib, divisor=divisor)
    time_runs(ctx, on, off)
    rows = [knob_row("atmosphere on (6S LUT + correction)", on, on, default=True, extra={"reference": True}),
            knob_row("atmosphere off (exo-atmospheric sun, no correction)", off, on)]
    return _result("atmosphere on", rows,
                   ("err_rms_cab", "Cab RMS change (abs) [ug/cm2]"))
