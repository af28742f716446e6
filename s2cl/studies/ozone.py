"""Ozone (paper Sec. 3.4, Fig. 5): relative surface-reflectance error in B1–B5 when scenes with a
true ozone column of [study] ``ozone`` (DU) are corrected with the [correction] column (330 DU),
for flat targets ρ in [study] ``reflectance``.

Band radiance = SRF-weighted TOA radiance at the true state; correction with band-effective terms
of the assumed state (:class:`s2cl.atmos.correction.BandAtmosphere`). Error = (ρ_retrieved − ρ)/ρ in %.
"""

from __future__ import annotations

import numpy as np

from s2cl.atmos.correction import BandAtmosphere
from s2cl.studies.common import KeyFigure, StudyResult, StudySetup, apply

PAPER_MAX_B3_PCT = 6.0  # "relative errors of up to about 6 %" in B3 (Fig. 5, MODTRAN4)
#: what the study needs: bands in [sweep], non-empty [study] lists (checked by s2cl.studies.run_study)
NEEDS_BANDS, NEEDS_KEYS = (), ("ozone", "reflectance")


def case_key(o3: float, rho: float) -> str:
    """The JSON key of a case: true ozone column (DU) and reflectance."""
    return f"{o3:g}DU rho={rho:g}"


def run(setup: StudySetup) -> StudyResult:
    st = setup.study
    space = setup.space()
    shapes = space.shapes(0, 1)[0]  # the bands as given (fixed) in [sweep]
    weights = [setup.weights(b, c, w) for b, (c, w) in zip(space.bands, shapes, strict=True)]
    assumed = setup.assumed()
    t_assumed = setup.terms(assumed)
    corr = BandAtmosphere.of(t_assumed, weights)
    wl = setup.scene.grid.wavelengths
    err = {}   # (o3, rho) -> per-band %
    spec_err = {}
    for o3 in st.ozone:
        t_true = setup.terms(setup.truth(ozone=o3))
        for rho in st.reflectance:
            L = t_true.toa_radiance(np.full(wl.size, rho))
            Lb = np.array([apply(w, L) for w in weights])
            err[(o3, rho)] = 100.0 * (corr.reflectance(Lb) / rho - 1.0)
            spec_err[(o3, rho)] = 100.0 * (t_assumed.surface_reflectance(L) / rho - 1.0)
    rows = [[f"{o3:g}", f"{rho:g}", *(f"{e:+.2f}" for e in err[(o3, rho)])] for (o3, rho) in err]
    worst = max(err, key=lambda k: np.abs(err[k]).max())
    band_of_max = space.bands[int(np.abs(err[worst]).argmax())]
    figures = [KeyFigure(f"largest |error| (band {band_of_max}, {worst[0]:g} DU, ρ {worst[1]:g})",
                         round(float(np.abs(err[worst]).max()), 2), PAPER_MAX_B3_PCT, "%",
                         "paper: B3, 'up to about 6 %'")]
    if "B3" in space.bands:
        b3 = space.bands.index("B3")
        figures += [KeyFigure(f"B3 error, {o3:g} DU true, ρ {min(st.reflectance):g}",
                              round(float(err[(o3, min(st.reflectance))][b3]), 2), None, "%") for o3 in st.ozone]
    sel = (wl >= 400) & (wl <= 760)
    # the 1 nm error curves' largest |error| in the plotted range (the paper's Fig. 5 is spectral)
    spec_max = {}
    for (o3, rho), e in spec_err.items():
        i = int(np.argmax(np.abs(e[sel])))
        spec_max[case_key(o3, rho)] = {"error_pct": float(e[sel][i]), "wavelength_nm": float(wl[sel][i])}
    data = {
        "assumed_ozone_du": assumed.ozone, "bands": space.bands, "shapes": shapes.tolist(),
        "band_error_pct": {case_key(o3, rho): v.tolist() for (o3, rho), v in err.items()},
        "spectral_error_max_pct": spec_max,
        "cases": [[o3, rho] for o3, rho in err],
        "wavelength_nm": wl[sel].tolist(),   # the figure's 1 nm error curves
        "spectral_error_pct": {case_key(o3, rho): e[sel].tolist() for (o3, rho), e in spec_err.items()},
    }

    return StudyResult(
        title=f"Ozone: relative reflectance error (%), corrected with {assumed.ozone:g} DU",
        columns=["true O3 DU", "ρ", *space.bands], rows=rows, key_figures=figures, data=data,
        notes=["6S ozone: Chappuis band, Beer's law in the LUT; the paper used MODTRAN4."])
