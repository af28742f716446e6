"""The cellulose study's figure (:mod:`s2cl.studies.cellulose`), drawn from its JSON ``data`` alone:
the end-members and CO₂ / H₂O transmittance near 2.1 µm with the bands, the RMS of f_NPV over the 2.1 µm
band's centre × width, and the best RMS per width (noisy and noise-free) against the NDTI base."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from s2cl.io.plots import pyplot, save_png

#: Nagler et al.'s 2.1 µm band, 2091–2111 nm: its centre (nm)
NAGLER_CENTRE_NM = 2101.0
#: the heatmap's contour: the share of the band's signal CO₂ absorbs
CO2_LEVEL = 0.05


def plot_cellulose(data: dict[str, Any], path: Path) -> Path:
    plt = pyplot()
    variants = np.asarray(data["variants"], dtype=np.float64)
    rms = np.asarray(data["rms"], dtype=np.float64)
    free = np.asarray(data["rms_noise_free"], dtype=np.float64)
    best = int(data["best"])
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.3), dpi=110)
    _spectra(axes[0], data, variants[best])
    co2 = np.asarray(data["co2_signal_fraction"], dtype=np.float64) if "co2_signal_fraction" in data else None
    _heatmap(fig, axes[1], variants, rms, best, float(data["base"]["rms"]), co2)
    _per_width(axes[2], variants, rms, free, data["base"])
    fig.tight_layout()
    return save_png(fig, path)


def _spectra(ax: Any, data: dict[str, Any], best: np.ndarray) -> None:
    """Mean end-member reflectance (left axis), two-way CO₂ and H₂O transmittance (right axis), the CAI's
    shoulders (grey) and the best 2.1 µm band (green)."""
    wl = np.asarray(data["wavelength_nm"], dtype=np.float64)
    for label, spectrum in data["mean_reflectance"].items():
        ax.plot(wl, spectrum, lw=1.2, label=f"{label} (mean)")
    for c, w in data["shoulders"]:
        ax.axvspan(c - w / 2, c + w / 2, color="0.6", alpha=0.3)
    ax.axvspan(best[0] - best[1] / 2, best[0] + best[1] / 2, color="tab:green", alpha=0.25,
               label=f"best 2.1 µm band {best[0]:g}/{best[1]:g}")
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("reflectance")
    ax.set_ylim(0, max(ax.get_ylim()[1], 0.55) * 1.25)   # room for the legends above the spectra
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    tx = ax.twinx()
    tx.plot(wl, data["co2_transmittance"], color="k", lw=0.7, label="CO₂ (6S)")
    tx.plot(wl, data["water_transmittance"], color="tab:blue", lw=0.6, ls=":", label="H₂O (6S)")
    tx.set_ylim(0, 1.3)
    tx.set_ylabel("two-way transmittance")
    tx.legend(fontsize=7, loc="upper right")
    ax.set_title("end-members, gases; shoulders grey", fontsize=9)


def _on_grid(variants: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``values`` of the variants as a (width, centre) grid (NaN where a pair is not swept)."""
    centres, widths = np.unique(variants[:, 0]), np.unique(variants[:, 1])
    grid = np.full((widths.size, centres.size), np.nan)
    for (c, w), v in zip(variants, values, strict=True):
        grid[np.searchsorted(widths, w), np.searchsorted(centres, c)] = v
    return centres, widths, grid


def _heatmap(fig: Any, ax: Any, variants: np.ndarray, rms: np.ndarray, best: int, base: float,
             co2: np.ndarray | None) -> None:
    """RMS of f_NPV on the centre × width grid; the best design circled; where CO₂ takes 5 % of the signal."""
    centres, widths, grid = _on_grid(variants, rms)
    im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis",
                   extent=(centres[0] - _half(centres), centres[-1] + _half(centres),
                           widths[0] - _half(widths), widths[-1] + _half(widths)))
    if co2 is not None and centres.size > 1 and widths.size > 1:
        _, _, loss = _on_grid(variants, 1 - co2)
        if np.nanmin(loss) < CO2_LEVEL < np.nanmax(loss):
            cs = ax.contour(centres, widths, loss, levels=[CO2_LEVEL], colors="w", linewidths=0.9, linestyles="--")
            ax.clabel(cs, fmt={CO2_LEVEL: f"CO₂ takes {100 * CO2_LEVEL:g} %"}, fontsize=7)
    ax.plot(*variants[best], "o", mfc="none", mec="w", ms=10)
    fig.colorbar(im, ax=ax, label="RMS of f_NPV")
    ax.set_xlabel("2.1 µm band centre (nm)")
    ax.set_ylabel("width (nm)")
    ax.set_title(f"CAI; best {variants[best, 0]:g}/{variants[best, 1]:g}: {rms[best]:.4f} "
                 f"(NDTI base {base:.4f})", fontsize=9)


def _half(values: np.ndarray) -> float:
    return float(np.diff(values).min()) / 2 if values.size > 1 else 5.0


def _per_width(ax: Any, variants: np.ndarray, rms: np.ndarray, free: np.ndarray, base: dict[str, Any]) -> None:
    """Best RMS over centres at each width, noisy and noise-free; the same at the centre nearest Nagler's
    2.1 µm band; the NDTI base."""
    widths = np.unique(variants[:, 1])
    noisy = [rms[variants[:, 1] == w].min() for w in widths]
    clean = [free[variants[:, 1] == w].min() for w in widths]
    ax.plot(widths, noisy, "o-", color="C0", label="CAI, best centre, with noise")
    ax.plot(widths, clean, "s--", color="C0", label="CAI, best centre, no noise")
    centre = variants[np.argmin(np.abs(variants[:, 0] - NAGLER_CENTRE_NM)), 0]
    at = variants[:, 0] == centre
    order = np.argsort(variants[at, 1])
    ax.plot(variants[at, 1][order], rms[at][order], "o-", color="C1", ms=4, label=f"CAI at {centre:g} nm, with noise")
    ax.plot(variants[at, 1][order], free[at][order], "s--", color="C1", ms=4, label=f"CAI at {centre:g} nm, no noise")
    ax.axhline(base["rms"], color="tab:red", ls=":", label="NDTI (B11, B12), with noise")
    ax.axhline(base["rms_noise_free"], color="tab:red", ls="-.", lw=0.8, label="NDTI, no noise")
    ax.set_ylim(bottom=0)
    ax.set_xlabel("2.1 µm band width (nm)")
    ax.set_ylabel("RMS of f_NPV")
    ax.set_title("narrow vs wide", fontsize=9)
    ax.legend(fontsize=7)
