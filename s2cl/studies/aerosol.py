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

import numpy as np

from s2cl.atmos.correction import BandAtmosphere, toa
from s2cl.studies.common import (
    KeyFigure,
    StudyResult,
    StudySetup,
    apply,
    band_terms,
    crossing,
    equal_error,
    inverse,
    noisy,
    rel_rms,
)

# "if the error in this correlation factor is greater than 10 %, it will be the dominating error source"
PAPER_DOMINANT_ABOVE = 0.10
STANDARD_BLUE_RED = 0.5       # rho(480 nm) = 0.5 rho(red)
RED, SWIR, BLUE, B1 = "B4", "B12", "B2", "B1"
#: what the study needs: bands in [sweep], non-empty [study] lists (checked by s2cl.studies.run_study)
NEEDS_BANDS, NEEDS_KEYS = (RED, SWIR, BLUE, B1), ("aot550", "factor_errors", "targets")
# rows of the study's band arrays: red, 2.2 µm, the blue band B2, then the B1 variants
I_RED, I_SWIR, I_BLUE, I_B1 = 0, 1, 2, 3


def aot_axis(setup: StudySetup, n: int = 51) -> np.ndarray:
    """Retrieval nodes of AOT550, spanning the LUT's aot550 axis."""
    a = setup.lut.axes.aot550
    return np.linspace(float(a[0]), float(a[-1]), n)


def retrieve(L: dict[str, np.ndarray], t: dict[str, dict[str, np.ndarray]], c_rs: np.ndarray, c_br: np.ndarray,
             axis: np.ndarray) -> np.ndarray:
    """DDV AOT550 from band radiances ``L[band] (n, …)`` (keys blue, red, swir) with band terms
    ``t[band][term] (n_axis,)`` (terms lp, g, s) and factors ``c_rs, c_br (n,)``."""
    def model(band: str, rho: np.ndarray) -> np.ndarray:
        return toa(rho, t[band]["lp"], t[band]["g"], t[band]["s"])

    shape = (-1,) + (1,) * (L["red"].ndim - 1) + (1,)
    lr, lb, ls = (L[b][..., None] for b in ("red", "blue", "swir"))
    rho_r = c_rs.reshape(shape) * inverse(**t["swir"], radiance=ls)
    rho_b = c_br.reshape(shape) * rho_r
    f = (lr - model("red", rho_r)) / lr + (lb - model("blue", rho_b)) / lb
    return crossing(axis, f)


def run(setup: StudySetup) -> StudyResult:
    st = setup.study
    space = setup.space()
    slot = {b: k for k, b in enumerate(space.bands)}
    k0 = setup.nominal(space)
    nominal = space.indices(k0, k0 + 1)[0]               # nominal variant of each sweep band
    b1_variants = space.per_band[slot[B1]]
    nominal_b1 = int(nominal[slot[B1]])
    targets = setup.targets()
    spectra = np.concatenate([lib.spectra for lib in targets.values()])
    names = [n for lib in targets.values() for n in lib.names]
    axis = aot_axis(setup)
    gain = setup.scene.run.calibration_gain
    bands = [(b, *space.per_band[slot[b]][nominal[slot[b]]]) for b in (RED, SWIR, BLUE)]
    bands += [(B1, c, w) for c, w in b1_variants]
    weights = [setup.weights(b, c, w) for b, c, w in bands]
    lut = band_terms([setup.terms(setup.assumed(aot550=a)) for a in axis], weights)   # per band, (n_axis,)
    truth = np.array(st.aot550)
    true_terms = [setup.terms(setup.truth(aot550=a)) for a in truth]
    # true band radiances (n_bands, n_spectra, n_aot)
    rad = np.empty((len(bands), spectra.shape[0], truth.size))
    for j, tt in enumerate(true_terms):
        toa = tt.toa_radiance(spectra)
        for k, wt in enumerate(weights):
            rad[k, :, j] = apply(wt, toa)
    # the exact correlation factors: the band-level reflectance ratios at the first true AOT
    rho_true = BandAtmosphere.of(true_terms[0], weights).reflectance(rad[..., 0])   # (n_bands, n_spectra)
    c_rs_true = rho_true[I_RED] / rho_true[I_SWIR]
    to_red = rho_true / rho_true[I_RED]            # blue-to-red factor of each band as the blue one
    pixels = st.pixels
    # noisy radiances (n_bands, n_spectra, n_aot, pixels), the noise keyed by the band's slot in the
    # sweep: every B1 variant sees the same deviates (common random numbers)
    noisy_rad = noisy(setup, [setup.band(b).with_shape(c, w) for b, c, w in bands], rad.reshape(len(bands), -1),
                      [slot[b] for b, _, _ in bands], pixels).reshape(*rad.shape, pixels)

    def case(blue: int, eps: float, g: float, use_noise: bool = True) -> np.ndarray:
        src = noisy_rad if use_noise else rad[..., None]
        L = {"red": g * src[I_RED], "swir": g * src[I_SWIR], "blue": g * src[blue]}
        t = {"red": lut[I_RED], "swir": lut[I_SWIR], "blue": lut[blue]}
        return retrieve(L, t, c_rs_true * (1 + eps), to_red[blue] * (1 + eps), axis)

    def score(tau: np.ndarray) -> tuple[float, float]:
        tt = truth[None, :, None]
        return 100 * rel_rms(tau, tt), 100 * float(np.mean(tau / tt - 1))

    blue_label = f"{BLUE} {bands[I_BLUE][1]:g}/{bands[I_BLUE][2]:g}"
    rows, curve = [], []
    for eps in st.factor_errors:
        rms, bias = score(case(I_BLUE, eps, 1.0))
        curve.append(rms)
        rows.append([f"factor error {100 * eps:+g} %", blue_label, f"{rms:.2f}", f"{bias:+.2f}"])
    cal_rms, cal_bias = score(case(I_BLUE, 0.0, gain))
    rows.append([f"calibration gain {gain:g}", blue_label, f"{cal_rms:.2f}", f"{cal_bias:+.2f}"])
    nf_rms, nf_bias = score(case(I_BLUE, 0.0, 1.0, use_noise=False))
    rows.append(["no noise, exact factors", blue_label, f"{nf_rms:.2f}", f"{nf_bias:+.2f}"])
    b1_rms = []
    for i, (c, w) in enumerate(b1_variants):
        rms, bias = score(case(I_B1 + i, 0.0, 1.0))
        b1_rms.append(rms)
        rows.append(["B1 as blue band", f"B1 {c:g}/{w:g}", f"{rms:.2f}", f"{bias:+.2f}"])
    eps_arr = np.array(st.factor_errors)
    crossover = {side: equal_error(eps_arr, np.array(curve), cal_rms, side) for side in (1, -1)}
    c1, w1 = b1_variants[nominal_b1]
    figures = [
        *(KeyFigure(f"factor error ({'+' if side > 0 else '−'}) that gives the AOT RMS of the calibration case",
                    round(100 * x, 1), 100 * PAPER_DOMINANT_ABOVE, "%",
                    f"calibration gain {gain:g}; paper: above 10 % the factor dominates")
          for side, x in crossover.items()),
        KeyFigure(f"AOT relative RMS with calibration gain {gain:g}", round(cal_rms, 2), None, "%"),
        KeyFigure("B1 variants: spread of AOT relative RMS (max − min)", round(max(b1_rms) - min(b1_rms), 2), None,
                  "pp", f"nominal {c1:g}/{w1:g}: {b1_rms[nominal_b1]:.2f} %; paper: ±5 nm, 20→30 nm not critical"),
        KeyFigure("mean true blue-to-red factor (B2/B4) of the DDV targets",
                  round(float(np.mean(to_red[I_BLUE])), 3), STANDARD_BLUE_RED, ""),
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
            "factor_blue_red": to_red[I_BLUE].tolist()}

    return StudyResult(
        title="Aerosol (DDV): relative RMS and bias of retrieved AOT550 (%)",
        columns=["case", "blue band", "rel. RMS %", "bias %"], rows=rows, key_figures=figures, data=data,
        notes=[f"true AOT550 {', '.join(f'{a:g}' for a in truth)}; {len(names)} DDV spectra × {pixels} noisy "
               "pixels; 6S continental aerosol (the paper does not name its DDV aerosol model)."])
