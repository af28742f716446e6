"""Methane in B11 (paper Sec. 3.4): how much CH₄ absorption changes the band signal.

For each B11 variant of the [sweep] section: the band-effective two-way CH₄ transmittance
(weighted by SRF × ground term, i.e. by the ground-reflected signal), and the relative reflectance
error of a correction that ignores methane (terms with CH₄ removed) for flat targets ρ in [study]
``reflectance``. Methane is 6S's own (a fixed mixing ratio in its code); the paper assumed 2 ppmv.
"""

from __future__ import annotations

import numpy as np

from s2cl.studies.common import KeyFigure, StudyResult, StudySetup, apply, inverse

PAPER_MAX_PCT = 0.5  # "smaller than 0.5 %"
BAND = "B11"
#: what the study needs: bands in [sweep], non-empty [study] lists (checked by s2cl.studies.run_study)
NEEDS_BANDS, NEEDS_KEYS = (BAND,), ("reflectance",)


def run(setup: StudySetup) -> StudyResult:
    st = setup.study
    space = setup.space()
    variants = space.per_band[space.bands.index(BAND)]
    terms = setup.terms(setup.truth())
    t_ch4 = terms.t_methane
    wl = setup.scene.grid.wavelengths
    radiance = {rho: terms.toa_radiance(np.full(wl.size, rho)) for rho in st.reflectance}
    # correction without methane: Lp and G with the CH4 column removed (both divided by T_CH4); S as the band's
    free = terms.with_gas_column("methane", 0.0)
    lp_free, g_free = free.path_radiance, free.ground_term
    rows, trans, errs = [], [], []
    for c, w in variants:
        wt = setup.weights(BAND, c, w)
        signal = apply(wt, terms.ground_term)
        t_band = float(apply(wt, terms.ground_term * t_ch4) / signal)
        lp, g = apply(wt, lp_free), apply(wt, g_free)
        s = apply(wt, terms.ground_term * terms.spherical_albedo) / signal
        e = [100.0 * (inverse(lp, g, s, apply(wt, L)) / rho - 1.0) for rho, L in radiance.items()]
        trans.append(t_band)
        errs.append(e)
        rows.append([f"{c:g}", f"{w:g}", f"{t_band:.5f}", f"{100 * (1 - t_band):.3f}",
                     *(f"{x:+.3f}" for x in e)])
    absorb = 100 * (1 - np.array(trans))
    nominal = setup.nominal(space)
    figures = [KeyFigure(f"B11 {variants[nominal, 0]:g}/{variants[nominal, 1]:g} methane absorption",
                         round(float(absorb[nominal]), 3), PAPER_MAX_PCT, "%", "paper: < 0.5 %"),
               KeyFigure("largest over the B11 variants", round(float(absorb.max()), 3), PAPER_MAX_PCT, "%")]
    sel = (wl >= 1450) & (wl <= 1800)   # the figure's spectrum
    data = {"variants": variants.tolist(), "band_transmittance": trans,
            "reflectance": list(st.reflectance), "reflectance_error_pct": errs,
            "wavelength_nm": wl[sel].tolist(), "methane_transmittance": t_ch4[sel].tolist()}

    return StudyResult(
        title="Methane in B11: band transmittance and reflectance error if ignored",
        columns=["centre nm", "width nm", "T CH4", "absorption %",
                 *(f"err ρ={r:g} %" for r in st.reflectance)],
        rows=rows, key_figures=figures, data=data,
        notes=["6S's methane as is (its code fixes the mixing ratio); the paper assumed 2 ppmv (MODTRAN4)."])
