"""The B10 cirrus study's table rows, key figures and notes, from the results :func:`s2cl.studies.cirrus.run`
computes (its figure: :func:`s2cl.studies.plots.plot_cirrus`). Radiances W m⁻² sr⁻¹ µm⁻¹, changes in %."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from s2cl.studies.cirrus_spikes import CASES
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
