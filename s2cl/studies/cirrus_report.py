"""The B10 cirrus study's table rows, key figures, notes and figure (paper Fig. 4 beside s2cl's), from the
results :func:`s2cl.studies.cirrus.run` computes. Radiances W m⁻² sr⁻¹ µm⁻¹, changes in %."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.io.plots import pyplot, save_png
from s2cl.studies.cirrus_spikes import CASES, SINGLE_SPIKE_NM, spike_nodes
from s2cl.studies.common import KeyFigure, apply

PAPER_CHANGE_PCT = {0.4: -15.0, 1.0: -34.0}  # Segl et al. 2012, Sec. 3.3: 1380/30 vs 1375/30


def table_row(wv: float, case: str, L: np.ndarray, srfs: dict, change: dict, variants: np.ndarray,
              bands: np.ndarray, wl: np.ndarray) -> list[str]:
    """One table row: a water column and one of :data:`CASES`."""
    widths = sorted(set(variants[:, 1].tolist()))
    best = {w: variants[variants[:, 1] == w][np.argmin(bands[variants[:, 1] == w]), 0] for w in widths}
    paper = PAPER_CHANGE_PCT.get(wv)
    return [f"{wv:g}", CASES[case], f"{L[int(np.argmin(np.abs(wl - 1375.0)))]:.3f}",
            f"{float(apply(srfs['eq1'][0], L)):.3f}", f"{float(apply(srfs['eq1'][1], L)):.3f}",
            f"{change['eq1'][case][wv]:+.1f}", f"{change['gaussian'][case][wv]:+.1f}",
            f"{paper:+.0f}" if paper is not None else "–", ", ".join(f"{best[w]:g}/{w:g}" for w in widths)]


def key_figures(water_vapour: Sequence[float], change: dict) -> list[KeyFigure]:
    """Per water column: the 1380/30 vs 1375/30 change beside the paper's, as 6S gives it and without spikes."""
    out = []
    for wv in water_vapour:
        c = {srf: {case: change[srf][case][wv] for case in CASES} for srf in change}
        paper = PAPER_CHANGE_PCT.get(wv)
        out.append(KeyFigure(
            f"B10 1380/30 vs 1375/30 band radiance, WV {wv:g} g/cm2", round(c["eq1"]["as_6s"], 2), paper, "%",
            f"Gaussian SRF: {c['gaussian']['as_6s']:+.1f} %; {CASES['single_removed']}: "
            f"{c['eq1']['single_removed']:+.1f} %"))
        out.append(KeyFigure(
            f"  same, 6S spikes removed, Gaussian SRF, WV {wv:g} g/cm2", round(c["gaussian"]["spikes_removed"], 2),
            paper, "%", f"eq. 1 SRF: {c['eq1']['spikes_removed']:+.1f} %"))
    return out


def removed_text(removed: dict[float, list[float]]) -> str:
    """The removed samples, once if every water column lost the same ones."""
    lists = {tuple(v) for v in removed.values()}
    if len(lists) == 1:
        return "6S samples at " + ", ".join(f"{x:g}" for x in next(iter(lists))) + " nm"
    return "; ".join(f"WV {wv:g}: " + ", ".join(f"{x:g}" for x in v) + " nm" for wv, v in removed.items())


def plot_cirrus(path: Path, wl: np.ndarray, spectra: dict, despiked: dict, variants: np.ndarray, bands: dict,
                change: dict) -> Path:
    """One panel per water column (1 nm spectrum, without spikes, band radiances per width) and a bar chart
    of the change beside the paper's; written to ``path`` (PNG)."""
    plt = pyplot()
    n = len(spectra)
    fig, axes = plt.subplots(1, n + 1, figsize=(4.2 * (n + 1), 4), dpi=110)
    for ax, (wv, L) in zip(axes[:n], spectra.items(), strict=True):
        _spectrum_panel(ax, wl, L, despiked[wv], variants, bands[wv])
        ax.set_title(f"s2cl (6S): WV {wv:g} g/cm²", fontsize=9)
    _change_panel(axes[n], list(spectra), change)
    fig.tight_layout()
    return save_png(fig, path)


def _spectrum_panel(ax: Any, wl: np.ndarray, L: np.ndarray, despiked: np.ndarray, variants: np.ndarray,
                    bands: np.ndarray) -> None:
    """One water column: the 1 nm radiance, the same without 6S's spikes, and the band radiance per width."""
    markers = {10.0: "D", 20.0: "^", 30.0: "s"}
    nodes = spike_nodes()
    span = (wl >= nodes[0]) & (wl <= nodes[-1])
    ax.plot(wl, L, "-", color="0.3", lw=0.8, label="1 nm")
    ax.plot(wl[span], despiked[span], "--", color="C3", lw=0.8, label="1 nm, 6S spikes removed")
    for w in sorted(set(variants[:, 1].tolist())):
        sel = variants[:, 1] == w
        ax.plot(variants[sel, 0], bands[sel], "-", marker=markers.get(w, "o"), ms=3, lw=0.8, label=f"{w:g} nm")
    ax.set_xlabel("centre wavelength (nm)")
    ax.set_ylabel("TOA radiance (W m⁻² sr⁻¹ µm⁻¹)")
    ax.set_xlim(wl[0], wl[-1])
    ax.legend(fontsize=7)


def _change_panel(ax: Any, wvs: list[float], change: dict) -> None:
    """The 1380/30 vs 1375/30 change per water column: s2cl's cases beside the paper's (bars)."""
    x = np.arange(len(wvs))
    series = [("s2cl (6S), eq. 1 SRF", change["eq1"]["as_6s"]),
              (f"{SINGLE_SPIKE_NM:g} nm removed", change["eq1"]["single_removed"]),
              ("spikes removed", change["eq1"]["spikes_removed"]),
              ("spikes removed, Gaussian SRF", change["gaussian"]["spikes_removed"]),
              ("paper (MODTRAN4, Fig. 4)", {w: PAPER_CHANGE_PCT.get(w, np.nan) for w in wvs})]
    width = 0.8 / len(series)
    for j, (label, values) in enumerate(series):
        ax.bar(x + (j - (len(series) - 1) / 2) * width, [values[w] for w in wvs], width, label=label)
    ax.set_xticks(x, [f"{w:g}" for w in wvs])
    ax.set_xlabel("water vapour (g/cm²)")
    ax.set_ylabel("1380/30 vs 1375/30 band radiance (%)")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_title("paper vs s2cl", fontsize=9)
    ax.legend(fontsize=6)
