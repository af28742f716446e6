"""B10 cirrus band (paper Sec. 3.3, Fig. 4): TOA radiance over a flat ρ = 0.3 target near 1375 nm.

At 1 nm and for bands of 10, 20 and 30 nm (centres every 3 nm, the [sweep] grid), for each water
vapour column in [study] ``water_vapour``. A good cirrus band sees no ground: the lower its
clear-sky radiance, the better. Key figure: the change of the 30 nm band radiance when its centre
moves from 1375 to 1380 nm (paper, MODTRAN4: −15 % at WV 0.4 cm and −34 % at WV 1 cm).
Radiances W m⁻² sr⁻¹ µm⁻¹.

The same with 6S's isolated transmittance spikes removed: :mod:`s2cl.studies.cirrus_spikes`; the table
and key figures: :mod:`s2cl.studies.cirrus_report`; the figure (from the JSON data): :mod:`s2cl.studies.plots`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from s2cl.grid import SpectralGrid
from s2cl.sensor.srf import BandWeights
from s2cl.studies.cirrus_report import key_figures, removed_text, table_row
from s2cl.studies.cirrus_spikes import CASES, SPIKE_DIP, SPIKE_REGION_NM, SPIKE_RULE, Spikes, spike_nodes, spikes_of
from s2cl.studies.common import StudyResult, StudySetup, apply

BAND = "B10"
#: what the study needs: bands in [sweep], non-empty [study] lists (checked by s2cl.studies.run_study)
NEEDS_BANDS, NEEDS_KEYS = (BAND,), ("reflectance", "water_vapour")
RANGE_EDGES_NM = (1355.0, 1395.0)
"""Where :func:`change_by_range` splits the change: short-wave wing, band core, long-wave wing."""


def gaussian_weights(grid: SpectralGrid, centre_nm: float, fwhm_nm: float) -> BandWeights:
    """A Gaussian SRF of FWHM ``fwhm_nm`` on ``|λ − λc| ≤ 1.5·FWHM`` (the paper's Fig. 4 bands are
    Gaussian; s2cl's model SRF is the flat-topped eq. 1)."""
    wl = grid.wavelengths
    sel = np.flatnonzero(np.abs(wl - centre_nm) <= 1.5 * fwhm_nm)
    r = np.exp(-4 * np.log(2) * ((wl[sel] - centre_nm) / fwhm_nm) ** 2)
    return BandWeights(start=int(sel[0]), weights=r / r.sum())


def _change(pair: Sequence[BandWeights], spectrum: np.ndarray) -> float:
    """1380/30 vs 1375/30 band radiance change, % (``pair`` = the two bands' weights)."""
    return 100.0 * (float(apply(pair[1], spectrum)) / float(apply(pair[0], spectrum)) - 1.0)


def change_by_range(pair: Sequence[BandWeights], spectrum: np.ndarray, wl: np.ndarray,
                    edges_nm: Sequence[float] = RANGE_EDGES_NM) -> list[float]:
    """The change of :func:`_change` split by wavelength range, percentage points (they add up to it):
    ``Σ (w_1380 − w_1375)·L / L_1375/30`` over ``λ < edges[0]``, ``edges[0] ≤ λ < edges[1]``, …"""
    full = [np.zeros(wl.size) for _ in pair]
    for f, w in zip(full, pair, strict=True):
        f[w.start:w.stop] = w.weights
    part = 100.0 * (full[1] - full[0]) * spectrum / float(apply(pair[0], spectrum))
    which = np.searchsorted(np.asarray(edges_nm), wl, side="right")
    return [round(float(part[which == i].sum()), 2) for i in range(len(edges_nm) + 1)]


@dataclass
class _Bands:
    """What the study computes: the B10 variants' band radiances, the 1380/30 vs 1375/30 changes and the 1 nm
    spectra, for each water column (``wv``, g/cm2) and each of :data:`CASES`."""

    rho: float
    variants: np.ndarray                      # (n, 2): centre, width (nm)
    wl: np.ndarray                            # the scene's grid (nm)
    window: np.ndarray                        # bool (n_wl,): the spectra kept in the JSON and the figure
    srfs: dict[str, list[BandWeights]]        # "eq1"/"gaussian" -> the 1375/30 and 1380/30 bands
    spikes: dict[float, Spikes]               # wv -> 6S's samples and the radiance per case
    bands: dict[str, dict[float, np.ndarray]]  # case -> wv -> band radiance per variant (n,)
    change: dict[str, dict[str, dict[float, float]]]  # srf -> case -> wv -> change, %


def run(setup: StudySetup) -> StudyResult:
    """TOA radiance spectra and band radiances of the [sweep] B10 variants, with 6S's spikes and without."""
    b = _compute(setup)
    rows = [table_row(wv, case, s.radiance[case], b.srfs, b.change, b.variants, b.bands[case][wv], b.wl)
            for wv, s in b.spikes.items() for case in CASES]

    removed = {wv: s.removed_nm() for wv, s in b.spikes.items()}
    return StudyResult(
        title=f"B10 cirrus: TOA radiance over ρ = {b.rho:g} (W m⁻² sr⁻¹ µm⁻¹); change = 1380/30 vs 1375/30",
        columns=["WV g/cm²", "6S H₂O samples", "L 1375 nm (1 nm)", "L 1375/30", "L 1380/30", "change %",
                 "Gaussian SRF %", "paper %", "darkest centre/width"],
        rows=rows, key_figures=key_figures(setup.study.water_vapour, b.change), data=_data(setup, b),
        notes=["6S gas absorption is on a 2.5 nm grid in 10 cm⁻¹ intervals (aliased near 1375 nm); "
               "the paper used MODTRAN4 with rural aerosol.",
               f"spikes removed: {removed_text(removed)}; rule: {SPIKE_RULE}."])


def _compute(setup: StudySetup) -> _Bands:
    """Spectra per water column and case (:func:`spikes_of`), then the variants' and the pairs' band radiances."""
    st = setup.study
    rho = float(st.reflectance[0])
    space = setup.space()
    variants = space.per_band[space.bands.index(BAND)]  # (n, 2): centre, width
    wl = setup.scene.grid.wavelengths
    window = (wl >= variants[:, 0].min() - 10) & (wl <= variants[:, 0].max() + 10)
    weights = [setup.weights(BAND, c, w) for c, w in variants]
    srfs = {"eq1": [setup.weights(BAND, c, 30.0) for c in (1375.0, 1380.0)],
            "gaussian": [gaussian_weights(setup.scene.grid, c, 30.0) for c in (1375.0, 1380.0)]}
    spikes = {wv: spikes_of(setup, setup.truth(water_vapour=wv), rho) for wv in st.water_vapour}
    bands = {case: {wv: np.array([apply(w, s.radiance[case]) for w in weights]) for wv, s in spikes.items()}
             for case in CASES}
    change = {srf: {case: {wv: _change(pair, s.radiance[case]) for wv, s in spikes.items()} for case in CASES}
              for srf, pair in srfs.items()}
    return _Bands(rho, variants, wl, window, srfs, spikes, bands, change)


def _data(setup: StudySetup, b: _Bands) -> dict:
    """The study's JSON: state, band radiances, changes (by SRF, case, range and spike), spikes, spectra."""
    spikes, srfs, wl, window = b.spikes, b.srfs, b.wl, b.window
    return {
        "reflectance": b.rho,
        "state": vars(setup.truth()),
        "band_1375_30": {wv: float(apply(srfs["eq1"][0], s.radiance["as_6s"])) for wv, s in spikes.items()},
        "band_1380_30": {wv: float(apply(srfs["eq1"][1], s.radiance["as_6s"])) for wv, s in spikes.items()},
        "change_pct_gaussian_srf": b.change["gaussian"]["as_6s"],
        "change_pct": b.change,
        "change_pct_by_range": {"edges_nm": list(RANGE_EDGES_NM), **{
            srf: {case: {str(wv): change_by_range(pair, s.radiance[case], wl) for wv, s in spikes.items()}
                  for case in CASES} for srf, pair in srfs.items()}},
        "change_pct_per_spike": _per_spike(spikes, srfs),
        "srf_weight_at_removed_nm": _weights_at(srfs, sorted({x for s in spikes.values() for x in s.removed_nm()}), wl),
        "spikes": {
            "rule": SPIKE_RULE, "dip_threshold": SPIKE_DIP, "region_nm": list(SPIKE_REGION_NM),
            "nodes_nm": spike_nodes().tolist(),
            "per_water_vapour": {str(wv): s.to_json() for wv, s in spikes.items()},
        },
        "variants": b.variants.tolist(),
        "band_radiance": {str(k): v.tolist() for k, v in b.bands["as_6s"].items()},
        "band_radiance_spikes_removed": {str(k): v.tolist() for k, v in b.bands["spikes_removed"].items()},
        "wavelength_nm": wl[window].tolist(),
        "toa_radiance_1nm": {str(k): s.radiance["as_6s"][window].tolist() for k, s in spikes.items()},
        "toa_radiance_1nm_spikes_removed": {str(k): s.radiance["spikes_removed"][window].tolist()
                                            for k, s in spikes.items()},
    }


def _per_spike(spikes: dict[float, Spikes], srfs: dict) -> dict:
    """Change, %, with each first-pass spike removed alone and with all spikes but that one removed."""
    out: dict = {}
    for srf, pair in srfs.items():
        for kind in ("alone", "all_but"):
            for wv, s in spikes.items():
                for nm, L in s.per_spike[kind].items():
                    out.setdefault(srf, {}).setdefault(kind, {}).setdefault(nm, {})[str(wv)] = round(
                        _change(pair, L), 2)
    return out


def _weights_at(srfs: dict, nodes_nm: Sequence[float], wl: np.ndarray) -> dict:
    """Each 1375/30 and 1380/30 response at ``nodes_nm``, relative to its peak (linear between grid points)."""
    out: dict = {}
    for srf, pair in srfs.items():
        for centre, w in zip(("1375/30", "1380/30"), pair, strict=True):
            r = np.zeros(wl.size)
            r[w.start:w.stop] = w.weights / w.weights.max()
            out.setdefault(srf, {})[centre] = {f"{x:g}": round(float(np.interp(x, wl, r)), 3) for x in nodes_nm}
    return out
