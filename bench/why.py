"""Why the defaults: one paragraph per accuracy knob, argued from that knob's result (its rows, as
:mod:`bench.knobs` writes them), regenerated with every run's numbers. Each function returns None
when the rows it argues from are missing (a failed or older run); :mod:`bench.registry` attaches
each to its knob."""

from __future__ import annotations

from typing import Any

Result = dict[str, Any]
Row = dict[str, Any]


def row(result: Result, prefix: str) -> Row | None:
    """The first (not skipped) row whose setting starts with ``prefix``."""
    return next((r for r in result.get("rows", []) if r["setting"].startswith(prefix) and not r.get("skipped")),
                None)


def grid(result: Result) -> str | None:
    g1, g5, g10 = row(result, "1 nm"), row(result, "5 nm"), row(result, "10 nm")
    if not (g1 and g5 and g10):
        return None
    return (f"**1 nm grid.** The default's band radiance stays within {g1['err_radiance_ner_max']:.2f} NER of "
            f"the reference; 5 nm is {g1['seconds'] / g5['seconds']:.1f}× faster but errs by up to "
            f"{g5['err_radiance_ner_max']:.2f} NER (10 nm: {g10['err_radiance_ner_max']:.2f}), an error the "
            f"size of the sensor noise that the sweep is meant to resolve.")


def precision(result: Result) -> str | None:
    p32, p64 = row(result, "float32 kernels"), row(result, "float64 kernels + float64")
    if not (p32 and p64 and "precision_lp_rms_nm" in p32):
        return None
    return (f"**float32.** float64 kernels and fits take {p64['seconds'] / p32['seconds']:.2f}× the time. "
            f"Against float64 at the same settings, float32 moves the band radiance by at most "
            f"{p32['precision_radiance_ner_max']:.1e} NER ({p32['precision_radiance_rel_max']:.1e} relative) and "
            f"lp by {p32['precision_lp_rms_nm']:.1e} nm RMS; the default's distance from the reference "
            f"(lp {p32['err_lp_rms_nm']:.3f} nm) comes from the SRF cut and the fit's iteration limit, not the "
            f"precision.")


def srf(result: Result) -> str | None:
    s1, s2 = row(result, "model SRF ±1 FWHM"), row(result, "model SRF ±2")
    if not (s1 and s2):
        return None
    return (f"**SRF support ±1 FWHM.** Widening to ±2 FWHM costs {s2['seconds'] / s1['seconds']:.2f}× the time "
            f"for a radiance gain from {s1['err_radiance_ner_max']:.3f} to {s2['err_radiance_ner_max']:.3f} NER.")


def lm(result: Result) -> str | None:
    m50, m255, g0 = row(result, "max_iter 50"), row(result, "max_iter 255"), row(result, "initial guess")
    m1 = next((r for r in result.get("rows", []) if r["setting"] == "max_iter 1"), None)
    iters = [r for r in result.get("rows", []) if r["setting"].startswith("max_iter")]
    enough = next((r for r in iters if r["err_rms_cab"] < 1e-3), None)
    if not (m50 and m255 and g0 and m1 and enough):
        return None
    return (f"**LM: tol 1e-5, at most 50 iterations.** The closed-form initial guess alone (numpy: "
            f"{g0['speedup']:.0f}× faster than the converged float64 fit; the kernel's guess plus one step: "
            f"{m1['speedup']:.0f}×) misplaces lp by "
            f"{g0['err_lp_rms_nm']:.2f} nm RMS and moves the Cab RMS by {g0['err_rms_cab']:.2f} ug/cm2. From "
            f"{enough['setting']} on, the Cab RMS is within 1e-3 ug/cm2 of the converged one. The default "
            f"(50) leaves {1 - m50['frac_at_optimum']:.1%} of fits off the optimum (lp RMS error "
            f"{m50['err_lp_rms_nm']:.3f} nm; {m50.get('frac_iteration_limit', float('nan')):.1%} of fits end "
            f"flagged ITERATION_LIMIT, a fraction every sweep row reports); 255 iterations bring "
            f"{m255['frac_at_optimum']:.2%} there at {m255['seconds'] / m50['seconds']:.1f}× the fit time. The "
            f"tolerance matters far less than the iteration limit. On this band set the limit buys per-pixel lp "
            f"accuracy ({enough['err_lp_rms_nm']:.3f} → {m50['err_lp_rms_nm']:.3f} nm RMS from "
            f"{enough['setting'].split()[-1]} to 50 iterations), not Cab RMS; that other band sets need the "
            f"margin is not measured here.")


def lut(result: Result) -> str | None:
    lin, near = row(result, "every other node of all three, linear"), row(result, "every other node of all three, near")
    if not (lin and near):
        return None
    return (f"**Linear LUT interpolation.** With every other node dropped, linear interpolation errs by "
            f"{lin['err_radiance_ner_max']:.2f} NER at the worst place, nearest by "
            f"{near['err_radiance_ner_max']:.2f} NER; the terms take well under a millisecond either way "
            f"({1e3 * lin['seconds']:.2f} vs {1e3 * near['seconds']:.2f} ms), once per scene.")


def copies(result: Result) -> str | None:
    c = {r["setting"]: r for r in result.get("rows", [])}
    if not {"10 copies", "100 copies", "1000 copies"} <= c.keys():
        return None
    c10, c100, c1000 = c["10 copies"], c["100 copies"], c["1000 copies"]
    return (f"**100 copies** (the paper's): the Cab RMS is known to ±{c100['ci95_halfwidth']:.3f} ug/cm2 "
            f"(95 %), against ±{c10['ci95_halfwidth']:.3f} with 10 and ±{c1000['ci95_halfwidth']:.3f} with "
            f"1000 at {c1000['seconds'] / c100['seconds']:.1f}× the time.")


def bits(result: Result) -> str | None:
    b12 = row(result, "12 bits")
    measured = [r for r in result.get("rows", []) if r["setting"].endswith("bits")]
    if not (b12 and measured):
        return None
    lo, hi = min(r["seconds"] for r in measured), max(r["seconds"] for r in measured)
    return (f"**12 bits** (the sensor's): quantisation moves lp by {b12['err_lp_rms_nm']:.3f} nm RMS and the "
            f"Cab RMS by {b12['err_rms_cab']:.1e} ug/cm2 against a chain without DN and calibration (8 bits: "
            f"{measured[0]['err_rms_cab']:.2f}). The DN and calibration stages add "
            f"{100 * (1 / b12['speedup'] - 1):.0f} % to the chain's time here, against a spread of "
            f"{100 * (hi / lo - 1):.0f} % between 8 and 16 bits (which do the same work): this machine's noise; "
            f"neither is a time knob worth turning.")


def atmosphere(result: Result) -> str | None:
    off = row(result, "atmosphere off")
    if not off:
        return None
    saved = 100 * (1 - 1 / off["speedup"])
    cost = f"saves {saved:.0f} % of the chain's time" if saved > 5 else "saves no measurable time"
    return (f"**Atmosphere on.** Switching it off {cost} but changes the Cab RMS by {off['err_rms_cab']:.2f} "
            f"ug/cm2 and the band radiance by up to {off['err_radiance_ner_max']:.0f} NER: the atmosphere is "
            f"part of what the band study measures, not a detail.")
