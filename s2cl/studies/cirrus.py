"""B10 cirrus band (paper Sec. 3.3, Fig. 4): TOA radiance over a flat ρ = 0.3 target near 1375 nm.

At 1 nm and for bands of 10, 20 and 30 nm (centres every 3 nm, the [sweep] grid), for each water
vapour column in [study] ``water_vapour``. A good cirrus band sees no ground: the lower its
clear-sky radiance, the better. Key figure: the change of the 30 nm band radiance when its centre
moves from 1375 to 1380 nm (paper, MODTRAN4: −15 % at WV 0.4 cm and −34 % at WV 1 cm).
Radiances W m⁻² sr⁻¹ µm⁻¹.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..grid import SpectralGrid
from ..plots import pyplot, save_png
from ..srf import BandWeights
from .common import KeyFigure, StudyResult, StudySetup, apply

PAPER_CHANGE_PCT = {0.4: -15.0, 1.0: -34.0}  # Segl et al. 2012, Sec. 3.3: 1380/30 vs 1375/30
BAND = "B10"


def gaussian_weights(grid: SpectralGrid, centre_nm: float, fwhm_nm: float) -> BandWeights:
    """A Gaussian SRF of FWHM ``fwhm_nm`` on ``|λ − λc| ≤ 1.5·FWHM`` (the paper's Fig. 4 bands are
    Gaussian; s2cl's model SRF is the flat-topped eq. 1)."""
    wl = grid.wavelengths
    sel = np.flatnonzero(np.abs(wl - centre_nm) <= 1.5 * fwhm_nm)
    r = np.exp(-4 * np.log(2) * ((wl[sel] - centre_nm) / fwhm_nm) ** 2)
    return BandWeights(start=int(sel[0]), weights=r / r.sum())


def run(setup: StudySetup) -> StudyResult:
    """TOA radiance spectra and band radiances of the [sweep] B10 variants."""
    st = setup.study
    rho = float(st.reflectance[0])
    space = setup.space()
    variants = space.per_band[space.bands.index(BAND)]  # (n, 2): centre, width
    wl = setup.scene.grid.wavelengths
    window = (wl >= variants[:, 0].min() - 10) & (wl <= variants[:, 0].max() + 10)
    weights = [setup.weights(BAND, c, w) for c, w in variants]
    w_ref, w_alt = setup.weights(BAND, 1375.0, 30.0), setup.weights(BAND, 1380.0, 30.0)
    gaussians = [gaussian_weights(setup.scene.grid, c, 30.0) for c in (1375.0, 1380.0)]
    i1375 = int(np.argmin(np.abs(wl - 1375.0)))
    widths = sorted(set(variants[:, 1].tolist()))
    spectra, bands, ref, alt, gauss = {}, {}, {}, {}, {}
    for wv in st.water_vapour:
        L = setup.terms(setup.truth(water_vapour=wv)).toa_radiance(np.full(wl.size, rho))
        spectra[wv] = L
        bands[wv] = np.array([apply(wt, L) for wt in weights])
        ref[wv] = float(apply(w_ref, L))
        alt[wv] = float(apply(w_alt, L))
        g = [float(apply(wt, L)) for wt in gaussians]
        gauss[wv] = 100.0 * (g[1] / g[0] - 1.0)
    rows, figures = [], []
    for wv in st.water_vapour:
        change = 100.0 * (alt[wv] / ref[wv] - 1.0)
        best = {w: variants[variants[:, 1] == w][np.argmin(bands[wv][variants[:, 1] == w]), 0] for w in widths}
        rows.append([f"{wv:g}", f"{spectra[wv][i1375]:.3f}", f"{ref[wv]:.3f}", f"{alt[wv]:.3f}",
                     f"{change:+.1f}", f"{gauss[wv]:+.1f}",
                     f"{PAPER_CHANGE_PCT[wv]:+.0f}" if wv in PAPER_CHANGE_PCT else "–",
                     ", ".join(f"{best[w]:g}/{w:g}" for w in widths)])
        figures.append(KeyFigure(f"B10 1380/30 vs 1375/30 band radiance, WV {wv:g} g/cm2", round(change, 2),
                                 PAPER_CHANGE_PCT.get(wv), "%", f"Gaussian SRF: {gauss[wv]:+.1f} %"))
    data = {
        "reflectance": rho,
        "state": vars(setup.truth()),
        "band_1375_30": ref, "band_1380_30": alt, "change_pct_gaussian_srf": gauss,
        "variants": variants.tolist(),
        "band_radiance": {str(k): v.tolist() for k, v in bands.items()},
        "wavelength_nm": wl[window].tolist(),
        "toa_radiance_1nm": {str(k): v[window].tolist() for k, v in spectra.items()},
    }

    def plot(path: Path) -> Path:
        return _plot(path, wl[window], {k: v[window] for k, v in spectra.items()}, variants, bands, ref, alt)

    return StudyResult(
        title=f"B10 cirrus: TOA radiance over ρ = {rho:g} (W m⁻² sr⁻¹ µm⁻¹)",
        columns=["WV g/cm²", "L 1375 nm (1 nm)", "L 1375/30", "L 1380/30", "change %", "Gaussian SRF %", "paper %",
                 "darkest centre/width"],
        rows=rows, key_figures=figures, data=data, plot=plot,
        notes=["6S gas absorption is on a 2.5 nm grid in 10 cm⁻¹ intervals (aliased near 1375 nm); "
               "the paper used MODTRAN4 with rural aerosol."])


def _plot(path: Path, wl: np.ndarray, spectra: dict, variants: np.ndarray, bands: dict, ref: dict,
          alt: dict) -> Path:
    plt = pyplot()
    n = len(spectra)
    fig, axes = plt.subplots(1, n + 1, figsize=(4.2 * (n + 1), 4), dpi=110)
    markers = {10.0: "D", 20.0: "^", 30.0: "s"}
    for ax, (wv, L) in zip(axes[:n], spectra.items(), strict=True):
        ax.plot(wl, L, "-", color="0.3", lw=0.8, label="1 nm")
        for w in sorted(set(variants[:, 1].tolist())):
            sel = variants[:, 1] == w
            ax.plot(variants[sel, 0], bands[wv][sel], "-", marker=markers.get(w, "o"), ms=3, lw=0.8,
                    label=f"{w:g} nm")
        ax.set_title(f"s2cl (6S): WV {wv:g} g/cm²", fontsize=9)
        ax.set_xlabel("centre wavelength (nm)")
        ax.set_ylabel("TOA radiance (W m⁻² sr⁻¹ µm⁻¹)")
        ax.set_xlim(wl[0], wl[-1])
        ax.legend(fontsize=7)
    ax = axes[n]
    wvs = list(spectra)
    x = np.arange(len(wvs))
    s2 = [100 * (alt[w] / ref[w] - 1) for w in wvs]
    paper = [PAPER_CHANGE_PCT.get(w, np.nan) for w in wvs]
    ax.bar(x - 0.2, s2, 0.4, label="s2cl (6S)")
    ax.bar(x + 0.2, paper, 0.4, label="paper (MODTRAN4, Fig. 4)")
    ax.set_xticks(x, [f"{w:g}" for w in wvs])
    ax.set_xlabel("water vapour (g/cm²)")
    ax.set_ylabel("1380/30 vs 1375/30 band radiance (%)")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_title("paper vs s2cl", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return save_png(fig, path)
