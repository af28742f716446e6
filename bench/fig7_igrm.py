"""Paper Fig. 7 check: chlorophyll a+b against the IGRM inflection point lp, hyperspectral.

s2cl's Lib1 (``builtin:lib1``: PROSAIL, Cab 5-100 ug/cm2 step 5, LAI 3 and 4, over the three
measured iron-bearing backgrounds; 120 spectra) at 1 nm over the red edge, IGRM fitted on every
1-nm band of the window, second-order polynomial of Cab on lp over all spectra. The paper reports
R2 = 0.98 and RMS = 3.8 ug/cm2 on its Lib1 (goethite/hematite backgrounds). Writes
bench/results/fig7_igrm.json and bench/results/fig7_igrm.png.

    python -m bench.fig7_igrm
"""

from __future__ import annotations

import numpy as np

from bench.common import RESULTS, save_figure, write_json
from s2cl.cl.runtime import get_runtime
from s2cl.grid import DEFAULT_GRID
from s2cl.libraries.registry import load_library
from s2cl.retrieve.igrm import IgrmFitter
from s2cl.retrieve.quantify import score_igrm

WINDOWS_NM = ((650, 800), (670, 780))
PAPER = {"r2": 0.98, "rms_ug_cm2": 3.8}


def default_soil_canopies() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lib1's canopies (Cab 5-100, LAI 3 and 4) over prosail's own soil (rsoil 1, psoil 0.5: the
    mean of its dry and wet soil spectra) instead of the iron-bearing backgrounds: 40 spectra."""
    import prosail

    from s2cl.libraries.vegetation import LIB1, simulate

    soil = prosail.spectral_lib.soil
    background = 0.5 * soil.rsoil1 + 0.5 * soil.rsoil2
    pairs = [(cab, lai) for lai in LIB1.lai for cab in LIB1.cab]
    spectra = np.array([simulate(LIB1, cab=c, lai=a, ewt=LIB1.ewt[0], background=background) for c, a in pairs])
    return np.array([c for c, _ in pairs]), np.array([a for _, a in pairs]), spectra


def fit_windows(spectra: np.ndarray, cab: np.ndarray) -> tuple[list[dict], list[tuple]]:
    """Hyperspectral IGRM over each window of WINDOWS_NM and the Cab ~ lp regression."""
    rows, fits = [], []
    for lo, hi in WINDOWS_NM:
        wl = np.arange(lo, hi + 1.0)
        y = spectra[:, lo - 400:hi - 400 + 1].T
        r = IgrmFitter(get_runtime(), len(wl), real_t="float64").fit(y, wl)
        score = score_igrm(r, cab)
        fits.append((lo, hi, r, score))
        rows.append({"window_nm": [lo, hi], "n_bands": int(wl.size), "r2": score.r2, "rms_ug_cm2": score.rms,
                     "median_abs_error": score.median_abs_error, "lp_range_nm": [float(r.lp.min()),
                     float(r.lp.max())], "l0_range_nm": [float(r.l0.min()), float(r.l0.max())],
                     "s_range_nm": [float(r.s.min()), float(r.s.max())], "status_counts": r.counts()})
        print(f"  {lo}-{hi} nm ({wl.size} bands): {score.summary('ug/cm2')}  [paper: R2 0.98, RMS 3.8]")
    return rows, fits


def main() -> None:
    lib = load_library("builtin:lib1", DEFAULT_GRID)
    cab, lai = np.asarray(lib.params["cab"]), np.asarray(lib.params["lai"])
    print("builtin:lib1")
    windows, fits = fit_windows(lib.spectra, cab)
    out = {"benchmark": "fig7_igrm", "library": "builtin:lib1", "paper": PAPER, "n_spectra": int(cab.size),
           "windows": windows}
    print("Lib1 canopies over prosail's default soil")
    soil_cab, _, soil_spectra = default_soil_canopies()
    out["prosail_default_soil"] = {"n_spectra": int(soil_cab.size), "soil": "prosail rsoil1/rsoil2, rsoil 1, psoil 0.5",
                                   "windows": fit_windows(soil_spectra, soil_cab)[0]}
    write_json("fig7_igrm.json", out)
    _plot(fits, cab, lai)


def _plot(fits, cab: np.ndarray, lai: np.ndarray) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lo, hi, r, score = fits[0]
    fig, ax = plt.subplots(figsize=(5, 4), dpi=120)
    for value, marker in ((3.0, "o"), (4.0, "s")):
        m = lai == value
        ax.scatter(r.lp[m], cab[m], marker=marker, s=18, label=f"LAI {value:g}")
    x = np.linspace(r.lp.min(), r.lp.max(), 200)
    ax.plot(x, score.fit.predict(x), "k-", lw=1, label="2nd-order fit")
    ax.set_xlabel("IGRM inflection point lp [nm]")
    ax.set_ylabel("chlorophyll a+b [ug/cm2]")
    ax.set_title(f"IGRM {lo}-{hi} nm: R2 {score.r2:.3f}, RMS {score.rms:.2f} (paper 0.98, 3.8)", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, RESULTS / "fig7_igrm.png", dpi=120)
    print("wrote", RESULTS / "fig7_igrm.png")


if __name__ == "__main__":
    main()
