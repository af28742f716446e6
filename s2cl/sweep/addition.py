"""Band-addition sweeps: a fixed base band set plus one added band that moves (``[sweep.add]``), each candidate
scored by its gain over the base set alone, on the same pixels and noise.

- The base set is scored by the same analysis on the base bands alone (:func:`check_base`: a base the analysis
  cannot run, e.g. an IGRM on fewer than four bands, is refused before any work, in one line; so are the
  two-band indices, which either leave the added band out or the base set without an index).
- The base score is a fixed-band sweep of the base bands (:func:`s2cl.app.plan.fixed_row`): the same library,
  atmosphere, and noise deviates, because the base bands keep their noise streams and the added band draws its
  own (:func:`s2cl.sweep.space.with_added_band`).
- ``gain = base score − candidate score``: RMS for regressions, mean omission error (percentage points) for SAM;
  positive is better. ``results.parquet`` carries it as column ``gain``; every candidate keeps its own failure
  accounting (statuses, fractions, ``underdetermined``), and ``summary.json`` the base row's.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError
from s2cl.io.plots import pyplot, save_png
from s2cl.libraries.library import SpectralLibrary
from s2cl.retrieve.analysis import AnalysisSettings, analysis_targets
from s2cl.retrieve.design import check_design
from s2cl.retrieve.family import family_of, registry
from s2cl.retrieve.metric import metric_in
from s2cl.scene.schema import AddSpec
from s2cl.sensor.names import safe_file_part
from s2cl.sensor.variants import SweepSpace
from s2cl.sweep.report import draw_grid
from s2cl.sweep.space import ADD_KEY

#: results.parquet metadata key of an addition sweep (JSON: added band, its radiometry's band, base score)
META_KEY = "addition"


@dataclass(frozen=True)
class AdditionBase:
    """The base set of an addition sweep: its fixed bands (the sweep's space without the added band) and the
    analysis that scores them alone."""

    space: SweepSpace
    analysis: AnalysisSettings
    added: str
    like: str


def score_column(analysis: AnalysisSettings) -> str:
    """The results column a gain is taken on: ``rms`` for regressions, ``omission_error_pct`` for SAM."""
    return analysis.family.score_column


def check_base(add: AddSpec | None, analysis_spec: Any, space: SweepSpace, library: SpectralLibrary | None
               ) -> AdditionBase | None:
    """The base set of an addition sweep (``add``: its [sweep.add] section; ``space``: base bands then the added
    band, as :func:`s2cl.sweep.space.sweep_space` orders them), checked to be scorable alone by the scene's analysis
    (``analysis_spec``: its [analysis] section); None without [sweep.add].

    :raises InputError: (key ``sweep.add``) the analysis cannot run on the base bands alone.
    """
    if add is None:
        return None
    base = SweepSpace(space.ranges[:-1])
    names = base.bands
    kind = analysis_spec.kind if analysis_spec is not None else None
    if kind is not None and not family_of(kind).uses_every_band:
        # such a family (an index, a formula) reads the bands it names: it either leaves the added band out (every
        # candidate scores the base: no gain to measure) or names it (then the base set alone has no value)
        users = ", ".join(k for k, f in registry().items() if f.uses_every_band)
        raise InputError(f"a band addition needs an analysis that uses every band ({users}); {kind} reads the bands "
                         "it names, so the added band would either not enter it or leave the base set without one",
                         key=ADD_KEY)
    what = f"the base set {', '.join(names)} alone cannot be scored by {kind}, so no gain"
    try:
        analysis = AnalysisSettings.from_spec(analysis_spec, names)
        shape = base.shapes(0, 1)[0]
        check_design(analysis, names, shape[:, 0], shape[:, 1])
        if library is not None:
            analysis_targets(library, analysis, analysis_spec.classes)
    except InputError as err:
        raise InputError(f"{what}: {err.detail}", key=ADD_KEY) from None
    return AdditionBase(base, analysis, add.name, add.like)


def check_base_score(row: dict[str, Any], analysis: AnalysisSettings) -> float:
    """The base row's score, refused (key ``sweep.add``) when it is not a finite number (every pixel failed)."""
    column = score_column(analysis)
    value = row.get(column)
    if value is None or not np.isfinite(value):
        raise InputError(f"the base set's {column} is not finite (failed_fraction {row.get('failed_fraction')}): "
                         "no gain can be measured against it", key=ADD_KEY)
    return float(value)


def base_reference(row: dict[str, Any], added: str) -> dict[str, Any]:
    """The base row as the reference row of a ranking: the added band has no centre and width (None)."""
    return {**row, f"{added}_centre_nm": None, f"{added}_width_nm": None}


def meta_of(base: AdditionBase, score: float) -> dict[str, Any]:
    """What results.parquet's metadata records of an addition sweep."""
    return {"band": base.added, "like": base.like, "base_bands": base.space.bands,
            "metric": score_column(base.analysis), "base_score": score, "parameter": base.analysis.parameter}


def addition_of(meta: dict[str, str]) -> dict[str, Any] | None:
    """The addition record of a results file's metadata (:func:`meta_of`), or None for any other sweep."""
    text = meta.get(META_KEY)
    if not text:
        return None
    try:
        record = json.loads(text)
    except ValueError:
        return None
    return record if isinstance(record, dict) and "band" in record else None


def gain_table(digest: Any, record: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centres, widths, gain) of the added band: ``gain[i, j]`` at centre ``i`` and width ``j`` (NaN where that
    pair is no candidate or not ranked). Every candidate is one configuration (the base is fixed), so its
    gain is exactly base score − its score."""
    pairs = digest.pairs[record["band"]]
    pairs.merge()
    c, w = pairs.keys.real, pairs.keys.imag
    centres, ci = np.unique(c, return_inverse=True)
    widths, wi = np.unique(w, return_inverse=True)
    gain = np.full((centres.size, widths.size), np.nan)
    gain[ci.ravel(), wi.ravel()] = record["base_score"] - pairs.best
    return centres, widths, gain


def summarise_addition(digest: Any, summary: dict[str, Any], record: dict[str, Any]) -> dict[str, Any]:
    """The addition's part of ``summary.json``: base bands and score, the best added band and its gain."""
    gain = gain_table(digest, record)[2]
    out: dict[str, Any] = {**record, "gain_definition": f"base {record['metric']} - candidate {record['metric']}",
                           "candidates": int(np.isfinite(gain).sum()),
                           "candidates_better": int(np.sum(gain > 0))}
    best = summary.get("best")
    if best is not None:
        c, w = best["bands"][record["band"]]
        out["best"] = {"centre_nm": c, "width_nm": w, record["metric"]: best[record["metric"]],
                       "gain": record["base_score"] - best[record["metric"]]}
    return out


def gain_plots(digest: Any, record: dict[str, Any], folder: Path) -> list[Path]:
    """``gain_<band>.png``: gain against centre, one line per width; ``heatmap_gain_<band>.png``: centre × width."""
    band, metric = record["band"], record["metric"]
    centres, widths, gain = gain_table(digest, record)
    unit = metric_in([metric]).gain_unit(record.get("parameter"))
    base = f"base {'+'.join(record['base_bands'])} alone: {metric} {record['base_score']:.3g}"
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=120)
    for j, w in enumerate(widths):
        ax.plot(centres, gain[:, j], marker="o", ms=3, lw=1.2, label=f"{w:g} nm")
    ax.axhline(0.0, color="grey", lw=0.8)
    ax.set_xlabel(f"{band} centre (nm)")
    ax.set_ylabel(f"gain in {metric} ({unit})")
    ax.set_title(f"{band} added to the base set ({base})", fontsize=8)
    ax.legend(title=f"{band} FWHM", fontsize=7, title_fontsize=7, ncol=2)
    fig.tight_layout()
    paths = [save_png(fig, folder / f"gain_{safe_file_part(band)}.png")]
    fig, ax = plt.subplots(figsize=(1.6 + 0.62 * len(widths), 1.2 + 0.42 * len(centres)), dpi=120)
    im = draw_grid(ax, centres, widths, gain, band, fontsize=8, best="max")
    fig.colorbar(im, ax=ax, label=f"gain ({unit})")
    ax.set_title(f"{band}: gain over the base set ({base}; red: best)", fontsize=8)
    fig.tight_layout()
    paths.append(save_png(fig, folder / f"heatmap_gain_{safe_file_part(band)}.png"))
    return paths
