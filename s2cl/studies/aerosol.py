"""Aerosol from dark dense vegetation (paper Sec. 3.1, DDV after Kaufman et al. 1997).

Truth: each DDV target of [study] ``targets`` under the [atmosphere] state with each AOT550 of
[study] ``aot550`` → band radiances of a blue band, B4 (red) and B12 (2.2 µm) → sensor noise.

Retrieval, for each node τ of an AOT550 axis (band-effective LUT terms of the assumed state):
ρ12(τ) is the corrected B12 reflectance, the red estimate is ``ρ_red = c_rs·ρ12`` and the blue one
``ρ_blue = c_br·ρ_red`` (the standard blue-to-red factor is 0.5). The retrieved τ is where the
modelled red and blue radiances meet the measured ones (zero of the summed relative residuals).

The correlation factors that are exactly right for a target are its own band-level ratios; an
assumed factor is that times (1 + ε) for each ε in [study] ``factor_errors`` (both factors off by
ε). The calibration case multiplies every measured radiance by [correction] ``calibration_gain``.
The blue band is B2 (the paper's choice) for these cases; the B1 variants of [sweep] then take the
blue role to test B1's centre/width tolerance. Error: relative RMS of AOT550 (%).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import (
    KeyFigure,
    StudyResult,
    StudySetup,
    apply,
    band_terms,
    crossing,
    forward,
    inverse,
    noisy,
    pyplot,
    rel_rms,
    save,
)

# "if the error in this correlation factor is greater than 10 %, it will be the dominating error source"
PAPER_DOMINANT_ABOVE = 0.10
PAPER_CALIBRATION = 0.05      # "radiometric calibration errors (smaller than 5 % for Sentinel-2)"
STANDARD_BLUE_RED = 0.5       # rho(480 nm) = 0.5 rho(red)


def aot_axis(setup: StudySetup, n: int = 51) -> np.ndarray:
    """Retrieval nodes of AOT550 (the LUT's range 0–1)."""
    return np.linspace(0.0, 1.0, n)


def retrieve(L: dict[str, np.ndarray], t: dict[str, dict[str, np.ndarray]], c_rs: np.ndarray, c_br: np.ndarray,
             axis: np.ndarray) -> np.ndarray:
    """DDV AOT550 from band radiances ``L[band] (n, …)`` (keys blue, red, swir) with band terms
    ``t[band][term] (n_axis,)`` and factors ``c_rs, c_br (n,)``."""
    def node(band: str, key: str) -> np.ndarray:
        return t[band][key]

    shape = (-1,) + (1,) * (L["red"].ndim - 1) + (1,)
    lr, lb, ls = (L[b][..., None] for b in ("red", "blue", "swir"))
    rho12 = inverse(node("swir", "lp"), node("swir", "g"), node("swir", "s"), ls)
    rho_r = c_rs.reshape(shape) * rho12
    rho_b = c_br.reshape(shape) * rho_r
    f = (lr - forward(node("red", "lp"), node("red", "g"), node("red", "s"), rho_r)) / lr \
        + (lb - forward(node("blue", "lp"), node("blue", "g"), node("blue", "s"), rho_b)) / lb
    return crossing(axis, f)


def equal_error(eps: np.ndarray, rms: np.ndarray, level: float, side: int) -> float:
    """|ε| (unitless) on one side (+1 or −1) of ε = 0 where the RMS curve first reaches ``level``,
    linear between the sampled errors; NaN if it never does."""
    sel = np.flatnonzero(side * eps >= 0)
    order = sel[np.argsort(np.abs(eps[sel]))]
    x, y = np.abs(eps[order]), rms[order]
    above = np.flatnonzero(y >= level)
    if not above.size or above[0] == 0:
        return float("nan") if not above.size else float(x[0])
    i = above[0]
    return float(x[i - 1] + (level - y[i - 1]) * (x[i] - x[i - 1]) / (y[i] - y[i - 1]))


def run(setup: StudySetup) -> StudyResult:
    st = setup.study
    space = setup.space()
    b1_variants = space.per_band[space.bands.index("B1")]
    fixed = {b: space.per_band[space.bands.index(b)][0] for b in ("B2", "B4", "B12")}
    targets = setup.targets()
    spectra = np.concatenate([lib.spectra for lib in targets.values()])
    names = [n for lib in targets.values() for n in lib.names]
    axis = aot_axis(setup)
    gain = setup.scene.spec.correction.calibration_gain
    roles = {"red": ("B4", *fixed["B4"]), "swir": ("B12", *fixed["B12"])}
    blues = [("B2", *fixed["B2"])] + [("B1", c, w) for c, w in b1_variants]
    all_bands = [roles["red"], roles["swir"], *blues]
    weights = [setup.weights(b, c, w) for b, c, w in all_bands]
    assumed_terms = [setup.terms(setup.assumed(aot550=a)) for a in axis]
    lut = band_terms(assumed_terms, weights)     # (n_axis, n_bands)
    truth = np.array(st.aot550)
    # true band radiances (n_bands, n_spectra, n_aot) and the band-level reflectance at the true state
    rad = np.empty((len(all_bands), spectra.shape[0], truth.size))
    rho_true = np.empty_like(rad)
    for j, a in enumerate(truth):
        tt = setup.terms(setup.truth(aot550=a))
        toa = tt.toa_radiance(spectra)
        bt = band_terms([tt], weights)
        for k, wt in enumerate(weights):
            rad[k, :, j] = apply(wt, toa)
            rho_true[k, :, j] = inverse(bt["lp"][0, k], bt["g"][0, k], bt["s"][0, k], rad[k, :, j])
    c_rs_true = rho_true[0, :, 0] / rho_true[1, :, 0]
    pixels = st.pixels
    noisy_rad = np.stack([
        noisy(setup, setup.band(b), w, rad[k].ravel(), k, pixels).reshape(*rad.shape[1:], pixels)
        for k, (b, _, w) in enumerate(all_bands)])   # (n_bands, n_spectra, n_aot, pixels)

    def terms_of(k: int) -> dict[str, np.ndarray]:
        return {key: lut[key][:, k] for key in ("lp", "g", "s")}

    def case(blue: int, eps: float, g: float, use_noise: bool = True) -> np.ndarray:
        src = noisy_rad if use_noise else rad[..., None]
        L = {"red": g * src[0], "swir": g * src[1], "blue": g * src[blue]}
        t = {"red": terms_of(0), "swir": terms_of(1), "blue": terms_of(blue)}
        c_br = rho_true[blue, :, 0] / rho_true[0, :, 0]
        return retrieve(L, t, c_rs_true * (1 + eps), c_br * (1 + eps), axis)

    def score(tau: np.ndarray) -> tuple[float, float]:
        tt = truth[None, :, None] if tau.ndim == 3 else truth[None, :]
        return 100 * rel_rms(tau, tt), 100 * float(np.mean(tau / tt - 1))

    rows, curve = [], []
    for eps in st.factor_errors:
        rms, bias = score(case(2, eps, 1.0))
        curve.append(rms)
        rows.append([f"factor error {100 * eps:+g} %", "B2 490/65", f"{rms:.2f}", f"{bias:+.2f}"])
    cal_rms, cal_bias = score(case(2, 0.0, gain))
    rows.append([f"calibration gain {gain:g}", "B2 490/65", f"{cal_rms:.2f}", f"{cal_bias:+.2f}"])
    nf_rms, nf_bias = score(case(2, 0.0, 1.0, use_noise=False))
    rows.append(["no noise, exact factors", "B2 490/65", f"{nf_rms:.2f}", f"{nf_bias:+.2f}"])
    b1_rms = []
    for i, (_, c, w) in enumerate(blues[1:]):
        rms, bias = score(case(3 + i, 0.0, 1.0))
        b1_rms.append(rms)
        rows.append(["B1 as blue band", f"B1 {c:g}/{w:g}", f"{rms:.2f}", f"{bias:+.2f}"])
    eps_arr = np.array(st.factor_errors)
    crossover = {side: equal_error(eps_arr, np.array(curve), cal_rms, side) for side in (1, -1)}
    nominal_b1 = int(np.argmin(np.abs(b1_variants[:, 0] - 443) + np.abs(b1_variants[:, 1] - 20)))
    figures = [
        *(KeyFigure(f"factor error ({'+' if side > 0 else '−'}) that gives the AOT RMS of the calibration case",
                    round(100 * x, 1), 100 * PAPER_DOMINANT_ABOVE, "%",
                    f"calibration gain {gain:g}; paper: above 10 % the factor dominates")
          for side, x in crossover.items()),
        KeyFigure(f"AOT relative RMS with calibration gain {gain:g}", round(cal_rms, 2), None, "%"),
        KeyFigure("B1 variants: spread of AOT relative RMS (max − min)", round(max(b1_rms) - min(b1_rms), 2), None,
                  "pp", f"nominal 443/20: {b1_rms[nominal_b1]:.2f} %; paper: ±5 nm, 20→30 nm not critical"),
        KeyFigure("mean true blue-to-red factor (B2/B4) of the DDV targets",
                  round(float(np.mean(rho_true[2, :, 0] / rho_true[0, :, 0])), 3), STANDARD_BLUE_RED, ""),
        KeyFigure("mean true red-to-2.2 µm factor (B4/B12)", round(float(np.mean(c_rs_true)), 3), None, "",
                  "Kaufman et al. 1997: 0.5"),
    ]
    data = {"aot550_true": truth.tolist(), "aot_axis": axis.tolist(), "targets": names, "pixels": pixels,
            "factor_errors": list(st.factor_errors), "rel_rms_pct_vs_factor_error": curve,
            "calibration_gain": gain, "rel_rms_pct_calibration": cal_rms,
            "factor_error_equal_to_calibration": {"positive": crossover[1], "negative": crossover[-1]},
            "rel_rms_pct_no_noise": nf_rms,
            "b1_variants": b1_variants.tolist(), "rel_rms_pct_b1": b1_rms,
            "factor_red_swir": c_rs_true.tolist(),
            "factor_blue_red": (rho_true[2, :, 0] / rho_true[0, :, 0]).tolist()}

    def plot(path: Path) -> Path:
        plt = pyplot()
        fig, axes = plt.subplots(1, 2, figsize=(11, 4), dpi=110)
        ax = axes[0]
        ax.plot(100 * eps_arr, curve, "o-", label="s2cl: correlation-factor error")
        ax.axhline(cal_rms, color="tab:orange", ls="--", label=f"s2cl: calibration gain {gain:g}")
        ax.axvline(100 * PAPER_DOMINANT_ABOVE, color="tab:red", ls=":", label="paper: dominates above 10 %")
        ax.set_xlabel("correlation-factor error (%)")
        ax.set_ylabel("AOT550 relative RMS (%)")
        ax.set_title("DDV aerosol retrieval (blue B2, red B4, B12)", fontsize=9)
        ax.legend(fontsize=7)
        ax = axes[1]
        x = np.arange(len(b1_rms))
        ax.bar(x, b1_rms, 0.6)
        ax.set_xticks(x, [f"{c:g}/{w:g}" for c, w in b1_variants], fontsize=7, rotation=45)
        ax.set_ylabel("AOT550 relative RMS (%)")
        ax.set_title("B1 as blue band: centre/width (paper: not critical)", fontsize=9)
        fig.tight_layout()
        return save(fig, path)

    return StudyResult(
        name="aerosol", title="Aerosol (DDV): relative RMS and bias of retrieved AOT550 (%)",
        columns=["case", "blue band", "rel. RMS %", "bias %"], rows=rows, key_figures=figures, data=data,
        plot=plot,
        notes=[f"true AOT550 {', '.join(f'{a:g}' for a in truth)}; {len(names)} DDV spectra × {pixels} noisy "
               "pixels; 6S continental aerosol (the paper does not name its DDV aerosol model)."])
