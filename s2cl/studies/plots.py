"""The studies' figures, drawn from a study's JSON ``data`` alone (what :func:`s2cl.studies.run_study`
writes into ``NAME.json``), so that :func:`replot` redraws ``NAME.png`` from a saved JSON without
re-running the study. The study modules compute; only this module and the ``*_plots.py`` modules it
registers draw (matplotlib, Agg).

Every ``plot_NAME(data, path)`` takes the data dict as saved (keys that were numbers are strings after
the JSON round trip; in-memory dicts with float keys work too) and writes a PNG to ``path``.
Radiances W m⁻² sr⁻¹ µm⁻¹, wavelengths nm, errors and changes in %.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError
from s2cl.io.plots import pyplot, save_png
from s2cl.studies.aerosol import PAPER_DOMINANT_ABOVE
from s2cl.studies.cellulose_plots import plot_cellulose
from s2cl.studies.cirrus_report import PAPER_CHANGE_PCT
from s2cl.studies.cirrus_spikes import SINGLE_SPIKE_NM
from s2cl.studies.methane import PAPER_MAX_PCT
from s2cl.studies.ozone import PAPER_MAX_B3_PCT, case_key
from s2cl.studies.water_vapour_plots import plot_water_vapour, plot_water_vapour_1020

Data = dict[str, Any]


def _by_wv(d: dict) -> dict[float, Any]:
    """``d`` keyed by water column as a float (JSON turns the keys into strings)."""
    return {float(k): v for k, v in d.items()}


def plot_cirrus(data: Data, path: Path) -> Path:
    """B10 (paper Fig. 4 beside s2cl's): one panel per water column (1 nm spectrum, without spikes, band
    radiances per width) and a bar chart of the 1380/30 vs 1375/30 change beside the paper's."""
    plt = pyplot()
    wl = np.asarray(data["wavelength_nm"], dtype=np.float64)
    spectra = {wv: np.asarray(v) for wv, v in _by_wv(data["toa_radiance_1nm"]).items()}
    despiked = {wv: np.asarray(v) for wv, v in _by_wv(data["toa_radiance_1nm_spikes_removed"]).items()}
    bands = {wv: np.asarray(v) for wv, v in _by_wv(data["band_radiance"]).items()}
    variants = np.asarray(data["variants"], dtype=np.float64)
    nodes = np.asarray(data["spikes"]["nodes_nm"], dtype=np.float64)
    change = {srf: {case: _by_wv(v) for case, v in cases.items()} for srf, cases in data["change_pct"].items()}
    n = len(spectra)
    fig, axes = plt.subplots(1, n + 1, figsize=(4.2 * (n + 1), 4), dpi=110)
    for ax, (wv, L) in zip(axes[:n], spectra.items(), strict=True):
        _cirrus_spectrum(ax, wl, L, despiked[wv], variants, bands[wv], nodes)
        ax.set_title(f"s2cl (6S): WV {wv:g} g/cm²", fontsize=9)
    _cirrus_change(axes[n], list(spectra), change)
    fig.tight_layout()
    return save_png(fig, path)


def _cirrus_spectrum(ax: Any, wl: np.ndarray, L: np.ndarray, despiked: np.ndarray, variants: np.ndarray,
                     bands: np.ndarray, nodes: np.ndarray) -> None:
    """One water column: the 1 nm radiance, the same without 6S's spikes (between the spike nodes), and the
    band radiance per width."""
    markers = {10.0: "D", 20.0: "^", 30.0: "s"}
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


def _cirrus_change(ax: Any, wvs: list[float], change: dict) -> None:
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


def plot_aerosol(data: Data, path: Path) -> Path:
    """DDV: AOT550 relative RMS against the correlation-factor error beside the calibration case, and per
    B1 variant as the blue band."""
    plt = pyplot()
    eps = np.asarray(data["factor_errors"], dtype=np.float64)
    gain = data["calibration_gain"]
    b1_rms = data["rel_rms_pct_b1"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), dpi=110)
    ax = axes[0]
    ax.plot(100 * eps, data["rel_rms_pct_vs_factor_error"], "o-", label="s2cl: correlation-factor error")
    ax.axhline(data["rel_rms_pct_calibration"], color="tab:orange", ls="--", label=f"s2cl: calibration gain {gain:g}")
    ax.axvline(100 * PAPER_DOMINANT_ABOVE, color="tab:red", ls=":", label="paper: dominates above 10 %")
    ax.set_xlabel("correlation-factor error (%)")
    ax.set_ylabel("AOT550 relative RMS (%)")
    ax.set_title("DDV aerosol retrieval (blue B2, red B4, B12)", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[1]
    x = np.arange(len(b1_rms))
    ax.bar(x, b1_rms, 0.6)
    ax.set_xticks(x, [f"{c:g}/{w:g}" for c, w in data["b1_variants"]], fontsize=7, rotation=45)
    ax.set_ylabel("AOT550 relative RMS (%)")
    ax.set_title("B1 as blue band: centre/width (paper: not critical)", fontsize=9)
    fig.tight_layout()
    return save_png(fig, path)


def plot_ozone(data: Data, path: Path) -> Path:
    """Ozone (paper Fig. 5 beside s2cl's): the 1 nm reflectance error of each case with B1–B5 shaded, and
    the band errors beside the paper's ±6 %."""
    plt = pyplot()
    wl = np.asarray(data["wavelength_nm"], dtype=np.float64)
    assumed = data["assumed_ozone_du"]
    cases = [(o3, rho) for o3, rho in data["cases"]]
    darkest = min(rho for _, rho in cases)
    bands = data["bands"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), dpi=110)
    ax = axes[0]
    for c, w in data["shapes"]:
        ax.axvspan(c - w / 2, c + w / 2, color="0.9")
    for o3, rho in cases:
        ax.plot(wl, np.asarray(data["spectral_error_pct"][case_key(o3, rho)]), color="k" if rho == darkest else "0.6",
                lw=0.9, ls="-" if o3 < assumed else "--", label=f"{o3:g} DU, ρ={rho:g}")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("relative reflectance error (%)")
    ax.set_title(f"s2cl (6S), 1 nm, corrected with {assumed:g} DU (shaded: B1–B5)", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[1]
    x = np.arange(len(bands))
    for i, (o3, rho) in enumerate(cases):
        ax.bar(x + (i - len(cases) / 2 + 0.5) * 0.18, data["band_error_pct"][case_key(o3, rho)], 0.18,
               label=f"{o3:g} DU, ρ={rho:g}")
    ax.axhline(PAPER_MAX_B3_PCT, color="tab:red", ls=":", lw=1, label="paper: ±6 % (B3)")
    ax.axhline(-PAPER_MAX_B3_PCT, color="tab:red", ls=":", lw=1)
    ax.set_xticks(x, bands)
    ax.set_ylabel("band reflectance error (%)")
    ax.set_title("band errors, s2cl vs the paper's figure", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return save_png(fig, path)


def plot_methane(data: Data, path: Path) -> Path:
    """B11: the two-way CH₄ absorption spectrum with the variants shaded, and each variant's band absorption
    beside the paper's bound."""
    plt = pyplot()
    variants = data["variants"]
    absorb = 100 * (1 - np.asarray(data["band_transmittance"], dtype=np.float64))
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), dpi=110)
    ax = axes[0]
    t_ch4 = np.asarray(data["methane_transmittance"], dtype=np.float64)
    ax.plot(np.asarray(data["wavelength_nm"], dtype=np.float64), 100 * (1 - t_ch4), "k-", lw=0.8)
    for c, w in variants:
        ax.axvspan(c - w / 2, c + w / 2, color="0.85", alpha=0.3)
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("two-way CH₄ absorption (%)")
    ax.set_title("s2cl (6S's methane)", fontsize=9)
    ax = axes[1]
    x = np.arange(len(variants))
    ax.bar(x, absorb, 0.6, label="s2cl band absorption")
    ax.axhline(PAPER_MAX_PCT, color="tab:red", ls=":", label="paper: < 0.5 %")
    ax.set_xticks(x, [f"{c:g}/{w:g}" for c, w in variants], fontsize=7, rotation=45)
    ax.set_ylabel("%")
    ax.set_title("B11 variants vs the paper's bound", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return save_png(fig, path)


#: the stability figure's middle row shows the shifts within ± this many nm (where the requirements lie)
STABILITY_ZOOM_NM = 2.0


def plot_stability(data: Data, path: Path) -> Path:
    """Spectral stability: per application (columns), the error of each band's drift relative to the nominal
    error, against the centre shift (all, and within ±2 nm) and the width factor; noisy (solid) and noise-free
    (dashed); the requirement level (nominal + growth) as a red line."""
    plt = pyplot()
    apps = data["applications"]
    level = 1.0 + float(data["growth"])
    xs = {"shift": np.asarray(data["shifts_nm"], dtype=np.float64),
          "width": np.asarray(data["width_factors"], dtype=np.float64)}
    panels: list[tuple[str, float | None]] = [("shift", None)] if xs["shift"].size > 1 else []
    if np.abs(xs["shift"]).max() > STABILITY_ZOOM_NM and (np.abs(xs["shift"]) <= STABILITY_ZOOM_NM).sum() > 2:
        panels.append(("shift", STABILITY_ZOOM_NM))
    panels += [("width", None)] if xs["width"].size > 1 else []
    fig, axes = plt.subplots(len(panels), len(apps), figsize=(4.6 * len(apps), 3.4 * len(panels)), dpi=110,
                             squeeze=False)
    for col, app in enumerate(apps):
        for row, (kind, zoom) in enumerate(panels):
            ax = axes[row, col]
            keep = np.abs(xs[kind]) <= zoom if zoom else np.ones(xs[kind].size, dtype=bool)
            top = level
            for j, band in enumerate(app["bands"]):
                for key, nominal, style in (("error", app["nominal_error"], "-"),
                                            ("error_no_noise", app["nominal_error_no_noise"], "--")):
                    ratio = _ratio(app[key][kind][band], nominal)[keep]
                    if np.isfinite(ratio).any():
                        top = max(top, float(np.nanmax(ratio)))
                        ax.plot(xs[kind][keep], ratio, style, color=f"C{j}", lw=1.2 if style == "-" else 0.8,
                                label=band if style == "-" else None)
            ax.axhline(level, color="tab:red", lw=0.9, ls=":", label=f"+{100 * (level - 1):g} %")
            if top > 3:   # a log axis for curves that grow several-fold, with plain tick labels
                ax.set_yscale("log")
                ax.yaxis.set_major_formatter(_plain)
                ax.yaxis.set_minor_formatter(_plain_125)
            where = f", |δ| ≤ {zoom:g} nm" if zoom else ""
            ax.set_xlabel(f"centre shift δ (nm){where}" if kind == "shift" else "width factor")
            ax.set_ylabel("error / nominal error")
            ax.set_title(f"{app['label']}: {app['metric']}\nnominal {app['nominal_error']:.3g} {app['unit']} "
                         "(dashed: no noise)", fontsize=8)
            ax.legend(fontsize=7)
    fig.tight_layout()
    return save_png(fig, path)


def _plain(value: float, _pos: int | None = None) -> str:
    """Tick label of a log axis as a plain number (1, 10), not 10⁰."""
    return f"{value:g}"


def _plain_125(value: float, _pos: int | None = None) -> str:
    """Minor tick label of a log axis: plain 2 and 5 multiples (0.5, 2, 20), none for the others."""
    mantissa = value / 10 ** np.floor(np.log10(value)) if value > 0 else 0
    return f"{value:g}" if round(mantissa, 6) in (2.0, 5.0) else ""


def _ratio(values: list, nominal: float | None) -> np.ndarray:
    """``values / nominal``, NaN where either is not a positive number (JSON nulls included)."""
    v = np.array([np.nan if x is None else x for x in values], dtype=np.float64)
    if nominal is None or not nominal > 0:
        return np.full(v.shape, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(v > 0, v / nominal, np.nan)


def plot_instrument(data: Data, path: Path) -> Path:
    """Instrument effects: per band, each effect's RMS difference alone against the ideal instrument (bars, log
    axis), and the ideal product's noise and quantisation floor against the truth (black line)."""
    plt = pyplot()
    bands = list(data["bands"])
    rows = data["rows"]
    effects = [r for r in rows if r["instrument"] != "ideal"]
    fig, ax = plt.subplots(figsize=(max(6.0, 0.55 * len(bands) + 2), 4.0), dpi=110)
    x = np.arange(len(bands), dtype=np.float64)
    width = 0.8 / max(1, len(effects))
    for j, r in enumerate(effects):
        values = np.array([r["rms_effect"][b] for b in bands], dtype=np.float64)
        ax.bar(x - 0.4 + (j + 0.5) * width, np.where(values > 0, values, np.nan), width, color=f"C{j}",
               label=r["instrument"])
    floor = np.array([rows[0]["rms_vs_truth"][b] for b in bands], dtype=np.float64)
    ax.plot(x, floor, "k_", ms=14, mew=2, label="ideal: noise + quantisation")
    ax.set_yscale("log")
    ax.set_xticks(x, bands)
    ax.set_ylabel(f"RMS difference ({data['product']})")
    ax.set_title(f"each effect alone vs the ideal instrument, {data['pixels']:,} pixels", fontsize=9)
    ax.legend(fontsize=7, ncol=len(effects) + 1, loc="upper center", bbox_to_anchor=(0.5, -0.08))
    fig.tight_layout()
    return save_png(fig, path)


PLOTS: dict[str, Callable[[Data, Path], Path]] = {
    "cirrus": plot_cirrus,
    "water-vapour": plot_water_vapour,
    "water-vapour-1020": plot_water_vapour_1020,
    "aerosol": plot_aerosol,
    "ozone": plot_ozone,
    "methane": plot_methane,
    "stability": plot_stability,
    "cellulose": plot_cellulose,
    "instrument": plot_instrument,
}
"""Study kind (the ``study`` key of ``NAME.json``) → its figure."""


def plot_study(kind: str, data: Data, path: str | Path) -> Path:
    """Draw study ``kind``'s figure from its ``data`` to ``path`` (PNG, written atomically)."""
    if kind not in PLOTS:
        raise InputError(f"no figure for study {kind!r}; studies: {', '.join(PLOTS)}")
    return PLOTS[kind](data, Path(path))


def replot(json_path: str | Path, png_path: str | Path) -> Path:
    """Redraw a study's figure from its saved ``NAME.json`` (:func:`s2cl.studies.run_study`) to ``png_path``."""
    src = Path(json_path)
    try:
        saved = json.loads(src.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise InputError(f"cannot read a study JSON: {err}", source=src) from None
    if not isinstance(saved, dict) or "study" not in saved or "data" not in saved:
        raise InputError("not a study JSON (no 'study' and 'data' keys)", source=src)
    try:
        return plot_study(saved["study"], saved["data"], png_path)
    except InputError as err:
        raise InputError(err.detail, source=src, key="study") from None
    except KeyError as err:   # a JSON written before the figure needed that key
        raise InputError(f"the data lack {err.args[0]!r} (written by an older s2cl?)", source=src,
                         key="data") from None
