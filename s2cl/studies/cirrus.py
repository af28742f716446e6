"""B10 cirrus band (paper Sec. 3.3, Fig. 4): TOA radiance over a flat ρ = 0.3 target near 1375 nm.

At 1 nm and for bands of 10, 20 and 30 nm (centres every 3 nm, the [sweep] grid), for each water
vapour column in [study] ``water_vapour``. A good cirrus band sees no ground: the lower its
clear-sky radiance, the better. Key figure: the change of the 30 nm band radiance when its centre
moves from 1375 to 1380 nm (paper, MODTRAN4: −15 % at WV 0.4 cm and −34 % at WV 1 cm).
Radiances W m⁻² sr⁻¹ µm⁻¹.

**6S's transmittance spikes.** 6S computes H₂O absorption on its own 2.5 nm grid (0.25 µm +
k·2.5 nm) with a 10 cm⁻¹ band model; near 1.38 µm single samples stand far above both neighbours.
The study measures what they do to the key figure by removing them and recomputing the radiance:

- the LUT stores the 2.5 nm samples linearly interpolated to 1 nm, so :func:`sixs_samples`
  recovers them from the 1 nm water transmittance (exactly at LUT nodes);
- a sample is an **isolated spike** (:func:`isolated_spikes`) when its transmittance exceeds both
  neighbours' and its optical depth τ = −ln T is below ``1 − SPIKE_DIP`` = 2/3 of the mean of its
  neighbours' optical depths, i.e. ``T_k > (T_k−1 · T_k+1)^(1/3)``. Only samples in
  :data:`SPIKE_REGION_NM` (1360–1410 nm) are tested;
- a spike is replaced by the geometric mean of its neighbours (linear in ln T), and the test is
  repeated until no sample qualifies, so a shoulder left beside a removed spike is tested again
  (:func:`remove_spikes`);
- ground term and aerosol path radiance scale with the new water transmittance, the Rayleigh path
  does not (6S puts water vapour above the aerosol) (:func:`despiked_terms`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from s2cl.atmos.atmosphere import AtmosphereState, AtmosphericTerms
from s2cl.errors import InputError
from s2cl.grid import SpectralGrid
from s2cl.io.plots import pyplot, save_png
from s2cl.sensor.srf import BandWeights
from s2cl.studies.common import KeyFigure, StudyResult, StudySetup, apply

PAPER_CHANGE_PCT = {0.4: -15.0, 1.0: -34.0}  # Segl et al. 2012, Sec. 3.3: 1380/30 vs 1375/30
BAND = "B10"
SIXS_STEP_NM = 2.5
"""6S's gas-absorption sampling step (its samples lie at 250 nm + k·2.5 nm)."""
SPIKE_REGION_NM = (1360.0, 1410.0)
"""6S samples tested for isolated spikes, nm (their outer neighbours 1357.5 and 1412.5 nm are not)."""
SPIKE_DIP = 1.0 / 3.0
"""A spike's optical depth is below ``1 − SPIKE_DIP`` of its neighbours' mean optical depth."""
SINGLE_SPIKE_NM = 1397.5
"""The sample the earlier explanation blamed alone; the study also removes just this one."""
SPIKE_RULE = (f"a 6S sample in {SPIKE_REGION_NM[0]:g}-{SPIKE_REGION_NM[1]:g} nm whose water transmittance exceeds "
              f"both neighbours' and whose optical depth is below {1 - SPIKE_DIP:.3g} of their mean; replaced by "
              "the neighbours' geometric mean, repeated until none is left")
RANGE_EDGES_NM = (1355.0, 1395.0)
"""Where :func:`change_by_range` splits the change: short-wave wing, band core, long-wave wing."""
CASES = {"as_6s": "as 6S gives them", "single_removed": f"{SINGLE_SPIKE_NM:g} nm removed",
         "spikes_removed": "spikes removed"}
"""Water transmittance as 6S gives it, with only :data:`SINGLE_SPIKE_NM` removed, with every isolated spike
removed: JSON key -> table label."""


def gaussian_weights(grid: SpectralGrid, centre_nm: float, fwhm_nm: float) -> BandWeights:
    """A Gaussian SRF of FWHM ``fwhm_nm`` on ``|λ − λc| ≤ 1.5·FWHM`` (the paper's Fig. 4 bands are
    Gaussian; s2cl's model SRF is the flat-topped eq. 1)."""
    wl = grid.wavelengths
    sel = np.flatnonzero(np.abs(wl - centre_nm) <= 1.5 * fwhm_nm)
    r = np.exp(-4 * np.log(2) * ((wl[sel] - centre_nm) / fwhm_nm) ** 2)
    return BandWeights(start=int(sel[0]), weights=r / r.sum())


# ---------------------------------------------------------------- spikes of 6S's 2.5 nm samples


def spike_nodes(region_nm: tuple[float, float] = SPIKE_REGION_NM) -> np.ndarray:
    """6S's sample wavelengths (nm) from one step below ``region_nm`` to one step above it."""
    lo, hi = region_nm
    n = round((hi - lo) / SIXS_STEP_NM) + 2
    return lo - SIXS_STEP_NM + SIXS_STEP_NM * np.arange(n + 1)


def spike_dips(t: np.ndarray) -> np.ndarray:
    """Optical-depth dip ``1 − τ_k / mean(τ_k−1, τ_k+1)`` (τ = −ln t) of each interior sample of a
    transmittance ``t (n,)``; NaN where the sample does not exceed both neighbours. Shape ``(n − 2,)``."""
    t = np.clip(np.asarray(t, dtype=np.float64), 1e-30, 1.0)
    tau = -np.log(t)
    mean = 0.5 * (tau[:-2] + tau[2:])
    peak = (t[1:-1] > t[:-2]) & (t[1:-1] > t[2:])   # a peak's neighbours have τ > 0
    return np.where(peak, 1.0 - tau[1:-1] / np.where(peak, mean, 1.0), np.nan)


def isolated_spikes(t: np.ndarray, dip: float = SPIKE_DIP) -> np.ndarray:
    """Indices of the isolated spikes of a sampled transmittance ``t (n,)``: interior samples above
    both neighbours whose optical-depth dip (:func:`spike_dips`) exceeds ``dip``."""
    d = spike_dips(t)
    return np.flatnonzero(np.nan_to_num(d, nan=-1.0) > dip) + 1


def replace_samples(t: np.ndarray, idx: Sequence[int]) -> np.ndarray:
    """Copy of ``t`` with each sample ``idx`` replaced by the geometric mean of its neighbours (linear
    in ln t); the samples ``idx`` must be interior and not adjacent."""
    out = np.array(t, dtype=np.float64)
    k = np.asarray(idx, dtype=int)
    out[k] = np.sqrt(out[k - 1] * out[k + 1])
    return out


def remove_spikes(t: np.ndarray, dip: float = SPIKE_DIP,
                  keep: Sequence[int] = ()) -> tuple[np.ndarray, list[list[int]]]:
    """Remove isolated spikes (:func:`isolated_spikes`) until none is left.

    Each pass replaces all spikes found (never adjacent: a spike's neighbours are below it) by
    :func:`replace_samples`; the next pass tests the result again.

    :param t: transmittance samples ``(n,)``, 0 < t ≤ 1.
    :param keep: indices never removed (to measure what one spike does).
    :returns: the new samples and the indices removed in each pass.
    """
    out = np.array(t, dtype=np.float64)
    passes: list[list[int]] = []
    for _ in range(out.size):
        k = [int(i) for i in isolated_spikes(out, dip) if i not in keep]
        if not k:
            break
        out = replace_samples(out, k)
        passes.append(k)
    return out, passes


def sixs_samples(wl: np.ndarray, values: np.ndarray, nodes: np.ndarray) -> tuple[np.ndarray, float]:
    """Samples at 6S's wavelengths ``nodes`` (nm) of a curve given on grid ``wl`` (nm) as their linear
    interpolation (how the LUT stores 6S's gas transmittance): least squares over the grid points
    from ``nodes[0]`` to ``nodes[-1]``.

    :returns: the samples ``(n_nodes,)`` and the largest absolute residual on the grid (0 up to
        rounding at LUT nodes; off-node states mix two such curves in ln T, a few 1e-4 at most).
    :raises InputError: if the grid does not resolve the nodes (too coarse).
    """
    sel = (wl >= nodes[0] - 1e-9) & (wl <= nodes[-1] + 1e-9)
    m = np.stack([np.interp(wl[sel], nodes, e) for e in np.eye(nodes.size)], axis=1)
    if np.linalg.matrix_rank(m) < nodes.size:
        raise InputError(f"the grid does not resolve 6S's {SIXS_STEP_NM:g} nm samples in "
                         f"{nodes[0]:g}–{nodes[-1]:g} nm (needs about 1 nm steps)", key="grid")
    samples = np.linalg.lstsq(m, values[sel], rcond=None)[0]
    return samples, float(np.abs(m @ samples - values[sel]).max())


def despiked_terms(terms: AtmosphericTerms, rayleigh: AtmosphericTerms, nodes: np.ndarray,
                   t_water_nodes: np.ndarray) -> AtmosphericTerms:
    """``terms`` with the water transmittance from ``nodes[0]`` to ``nodes[-1]`` (nm) replaced by the
    linear interpolation of ``t_water_nodes``.

    Ground term, ``t_gas`` and the aerosol part of the path radiance scale with the water
    transmittance; the Rayleigh part does not (6S: water vapour above the aerosol).

    :param rayleigh: terms of the same state at AOT550 = 0 (path radiance = the Rayleigh part).
    """
    wl = terms.wavelength_nm
    sel = (wl >= nodes[0] - 1e-9) & (wl <= nodes[-1] + 1e-9)
    t_new = np.array(terms.t_water, dtype=np.float64)
    t_new[sel] = np.interp(wl[sel], nodes, t_water_nodes)
    r = np.divide(t_new, terms.t_water, out=np.ones_like(t_new), where=terms.t_water > 0)
    lp, rho = rayleigh.path_radiance, rayleigh.path_reflectance
    return dataclasses.replace(
        terms,
        path_radiance=lp + r * (terms.path_radiance - lp),
        path_reflectance=rho + r * (terms.path_reflectance - rho),
        ground_term=terms.ground_term * r,
        t_gas=terms.t_gas * r,
        transmittance={**terms.transmittance, "water": t_new},
    )


@dataclasses.dataclass
class _Spikes:
    """One water-vapour state: 6S's samples, what the rule removed, and the TOA radiance per case."""

    nodes: np.ndarray
    t_6s: np.ndarray
    t_removed: np.ndarray
    passes: list[list[int]]
    residual: float
    radiance: dict[str, np.ndarray]        # CASES -> (n_wl,)
    per_spike: dict[str, dict[str, np.ndarray]]   # "alone"/"all_but" -> "1390" -> (n_wl,)

    def removed_nm(self) -> list[float]:
        return sorted(float(self.nodes[k]) for p in self.passes for k in p)

    def to_json(self) -> dict:
        """Removed samples, the dips (:func:`spike_dips`) of 6S's peaks, of each removed sample when it
        was removed, and the largest dip left (the margin below :data:`SPIKE_DIP`)."""
        t, at_removal = self.t_6s, {}
        for p in self.passes:
            d = spike_dips(t)
            at_removal.update({f"{self.nodes[k]:g}": round(float(d[k - 1]), 4) for k in p})
            t = replace_samples(t, p)
        return {
            "removed_nm": self.removed_nm(),
            "passes_nm": [[float(self.nodes[k]) for k in p] for p in self.passes],
            "optical_depth_dip": _peaks(self.nodes, self.t_6s),
            "dip_at_removal": at_removal,
            "largest_dip_left": max(_peaks(self.nodes, self.t_removed).values(), default=None),
            "t_water_6s": self.t_6s.tolist(),
            "t_water_spikes_removed": self.t_removed.tolist(),
            "recovery_residual": self.residual,
        }


def _peaks(nodes: np.ndarray, t: np.ndarray) -> dict[str, float]:
    """Dip of every sample above both neighbours, keyed by its wavelength (nm)."""
    return {f"{nodes[k + 1]:g}": round(float(d), 4) for k, d in enumerate(spike_dips(t)) if np.isfinite(d)}


def _spikes(setup: StudySetup, state: AtmosphereState, rho: float) -> _Spikes:
    terms = setup.terms(state)
    rayleigh = setup.terms(state.replace(aot550=0.0))
    nodes = spike_nodes()
    try:
        t6s, residual = sixs_samples(terms.wavelength_nm, terms.t_water, nodes)
    except InputError as err:
        raise InputError(err.detail, source=setup.source, key="grid") from None
    surface = np.full(terms.wavelength_nm.size, rho)

    def radiance(t_nodes: np.ndarray) -> np.ndarray:
        return despiked_terms(terms, rayleigh, nodes, t_nodes).toa_radiance(surface)

    removed, passes = remove_spikes(t6s)
    single = int(np.argmin(np.abs(nodes - SINGLE_SPIKE_NM)))
    cases = dict(zip(CASES, (terms.toa_radiance(surface), radiance(replace_samples(t6s, [single])),
                             radiance(removed)), strict=True))
    first = passes[0] if passes else []
    per_spike = {
        "alone": {f"{nodes[k]:g}": radiance(replace_samples(t6s, [k])) for k in first},
        "all_but": {f"{nodes[k]:g}": radiance(remove_spikes(t6s, keep=[k])[0]) for k in first},
    }
    return _Spikes(nodes, t6s, removed, passes, residual, cases, per_spike)


# ---------------------------------------------------------------- the study


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


def run(setup: StudySetup) -> StudyResult:
    """TOA radiance spectra and band radiances of the [sweep] B10 variants, with 6S's spikes and without."""
    st = setup.study
    rho = float(st.reflectance[0])
    space = setup.space()
    variants = space.per_band[space.bands.index(BAND)]  # (n, 2): centre, width
    wl = setup.scene.grid.wavelengths
    window = (wl >= variants[:, 0].min() - 10) & (wl <= variants[:, 0].max() + 10)
    weights = [setup.weights(BAND, c, w) for c, w in variants]
    srfs = {"eq1": [setup.weights(BAND, c, 30.0) for c in (1375.0, 1380.0)],
            "gaussian": [gaussian_weights(setup.scene.grid, c, 30.0) for c in (1375.0, 1380.0)]}
    spikes = {wv: _spikes(setup, setup.truth(water_vapour=wv), rho) for wv in st.water_vapour}
    bands = {case: {wv: np.array([apply(w, s.radiance[case]) for w in weights]) for wv, s in spikes.items()}
             for case in CASES}
    change = {srf: {case: {wv: _change(pair, s.radiance[case]) for wv, s in spikes.items()} for case in CASES}
              for srf, pair in srfs.items()}
    rows = [_row(wv, case, s, srfs, change, variants, bands[case][wv], wl)
            for wv, s in spikes.items() for case in CASES]
    data = {
        "reflectance": rho,
        "state": vars(setup.truth()),
        "band_1375_30": {wv: float(apply(srfs["eq1"][0], s.radiance["as_6s"])) for wv, s in spikes.items()},
        "band_1380_30": {wv: float(apply(srfs["eq1"][1], s.radiance["as_6s"])) for wv, s in spikes.items()},
        "change_pct_gaussian_srf": change["gaussian"]["as_6s"],
        "change_pct": change,
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
        "variants": variants.tolist(),
        "band_radiance": {str(k): v.tolist() for k, v in bands["as_6s"].items()},
        "band_radiance_spikes_removed": {str(k): v.tolist() for k, v in bands["spikes_removed"].items()},
        "wavelength_nm": wl[window].tolist(),
        "toa_radiance_1nm": {str(k): s.radiance["as_6s"][window].tolist() for k, s in spikes.items()},
        "toa_radiance_1nm_spikes_removed": {str(k): s.radiance["spikes_removed"][window].tolist()
                                            for k, s in spikes.items()},
    }

    def plot(path: Path) -> Path:
        return _plot(path, wl[window], {k: s.radiance["as_6s"][window] for k, s in spikes.items()},
                     {k: s.radiance["spikes_removed"][window] for k, s in spikes.items()}, variants,
                     bands["as_6s"], change)

    removed = {wv: s.removed_nm() for wv, s in spikes.items()}
    return StudyResult(
        title=f"B10 cirrus: TOA radiance over ρ = {rho:g} (W m⁻² sr⁻¹ µm⁻¹); change = 1380/30 vs 1375/30",
        columns=["WV g/cm²", "6S H₂O samples", "L 1375 nm (1 nm)", "L 1375/30", "L 1380/30", "change %",
                 "Gaussian SRF %", "paper %", "darkest centre/width"],
        rows=rows, key_figures=_key_figures(st.water_vapour, change), data=data, plot=plot,
        notes=["6S gas absorption is on a 2.5 nm grid in 10 cm⁻¹ intervals (aliased near 1375 nm); "
               "the paper used MODTRAN4 with rural aerosol.",
               f"spikes removed: {_removed_text(removed)}; rule: {SPIKE_RULE}."])


def _row(wv: float, case: str, s: _Spikes, srfs: dict, change: dict, variants: np.ndarray, bands: np.ndarray,
         wl: np.ndarray) -> list[str]:
    """One table row: a water column and one of :data:`CASES`."""
    widths = sorted(set(variants[:, 1].tolist()))
    best = {w: variants[variants[:, 1] == w][np.argmin(bands[variants[:, 1] == w]), 0] for w in widths}
    paper = PAPER_CHANGE_PCT.get(wv)
    L = s.radiance[case]
    return [f"{wv:g}", CASES[case], f"{L[int(np.argmin(np.abs(wl - 1375.0)))]:.3f}",
            f"{float(apply(srfs['eq1'][0], L)):.3f}", f"{float(apply(srfs['eq1'][1], L)):.3f}",
            f"{change['eq1'][case][wv]:+.1f}", f"{change['gaussian'][case][wv]:+.1f}",
            f"{paper:+.0f}" if paper is not None else "–", ", ".join(f"{best[w]:g}/{w:g}" for w in widths)]


def _key_figures(water_vapour: Sequence[float], change: dict) -> list[KeyFigure]:
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


def _per_spike(spikes: dict[float, _Spikes], srfs: dict) -> dict:
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


def _removed_text(removed: dict[float, list[float]]) -> str:
    """The removed samples, once if every water column lost the same ones."""
    lists = {tuple(v) for v in removed.values()}
    if len(lists) == 1:
        return "6S samples at " + ", ".join(f"{x:g}" for x in next(iter(lists))) + " nm"
    return "; ".join(f"WV {wv:g}: " + ", ".join(f"{x:g}" for x in v) + " nm" for wv, v in removed.items())


def _plot(path: Path, wl: np.ndarray, spectra: dict, despiked: dict, variants: np.ndarray, bands: dict,
          change: dict) -> Path:
    plt = pyplot()
    n = len(spectra)
    fig, axes = plt.subplots(1, n + 1, figsize=(4.2 * (n + 1), 4), dpi=110)
    markers = {10.0: "D", 20.0: "^", 30.0: "s"}
    nodes = spike_nodes()
    span = (wl >= nodes[0]) & (wl <= nodes[-1])
    for ax, (wv, L) in zip(axes[:n], spectra.items(), strict=True):
        ax.plot(wl, L, "-", color="0.3", lw=0.8, label="1 nm")
        ax.plot(wl[span], despiked[wv][span], "--", color="C3", lw=0.8, label="1 nm, 6S spikes removed")
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
    fig.tight_layout()
    return save_png(fig, path)
