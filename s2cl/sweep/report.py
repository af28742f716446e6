"""What a sweep found: best configurations, the reference (e.g. ESA) configuration, centre × width
tables and heatmaps, and JSON for the record.

Every function here takes a :class:`~s2cl.sweep.digest.Digest` (the results reduced in one streaming pass:
``s2cl optimise`` and ``sweep report`` never hold all configurations) or a DataFrame of results (reduced
the same way, as one batch)."""

from __future__ import annotations

import functools
import importlib.resources
import json
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError, token
from s2cl.io.output import write_json
from s2cl.io.plots import pyplot, save_png
from s2cl.sweep.digest import Digest, bands_of, metric_of, rankable_rows

__all__ = ["Digest", "bands_of", "metric_of"]


def open_results(path: str | Path) -> tuple[Path, dict[str, str]]:
    """The results file (``path``, or ``results.parquet`` in folder ``path``) and its metadata, checked from
    its schema and footer only (nothing is read into memory: :meth:`Digest.of_file` streams it).

    :raises InputError: no results in a folder (a sweep that did not finish says how to resume it), a
        file that is not Parquet, or a Parquet file that s2cl did not write (metadata and columns).
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = Path(path)
    if p.is_dir():
        p = _results_in(p)
    if not p.is_file():
        raise InputError("is not a regular file", source=p)
    try:
        with pq.ParquetFile(p) as f:
            schema, rows = f.schema_arrow, f.metadata.num_rows
            if f.metadata.num_row_groups:
                f.metadata.row_group(f.metadata.num_row_groups - 1)
    except (pa.ArrowException, OSError, ValueError) as err:
        raise InputError(f"not a readable Parquet file ({type(err).__name__}); a damaged results.parquet is "
                         "rebuilt by running the sweep again (finished chunks are kept)", source=p) from None
    meta = {k.decode(errors="replace"): v.decode(errors="replace") for k, v in (schema.metadata or {}).items()
            if not k.startswith(b"pandas")}
    _check_results(list(schema.names), rows, meta, p)
    return p, meta


def load(path: str | Path) -> tuple[Any, dict[str, str]]:
    """Results as a pandas DataFrame (every configuration in memory: for small sweeps and the benchmarks)
    and the file's metadata; checked as :func:`open_results` does."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    p, meta = open_results(path)
    try:
        return pq.read_table(p).to_pandas(), meta
    except (pa.ArrowException, OSError, ValueError) as err:
        raise InputError(f"not a readable Parquet file ({type(err).__name__})", source=p) from None


def _results_in(folder: Path) -> Path:
    results = folder / "results.parquet"
    if results.exists():
        return results
    if (folder / "manifest.json").exists() or (folder / "chunks").is_dir():
        raise InputError("the sweep in this folder did not finish (no results.parquet yet); run the same `s2cl "
                         "sweep run SCENE -o FOLDER` again to resume it", source=folder)
    raise InputError("no results.parquet here: not a sweep's output folder", source=folder)


def _check_results(columns: list[str], rows: int, meta: dict[str, str], source: Path) -> None:
    """A results table s2cl wrote: its metadata, the config column, a metric, band centre/width pairs."""
    missing = [k for k in ("fingerprint", "scene", "analysis") if k not in meta]
    if missing:
        raise InputError(f"not an s2cl sweep result (no {', '.join(missing)} in its metadata)", source=source)
    bands = bands_of(columns)
    needed = ["config", metric_of(columns, meta), *(f"{b}_width_nm" for b in bands)]
    lacking = [c for c in needed if c not in columns]
    if lacking or not bands:
        raise InputError(f"not an s2cl sweep result (columns missing: {', '.join(lacking) or 'band centres'})",
                         source=source)
    if rows == 0:
        raise InputError("holds no configurations", source=source)


def check_band(columns: list[str], band: str, source: str | Path) -> str:
    """``band`` as the results spell it; :class:`InputError` (key ``--band``) when it is not swept."""
    bands = bands_of(columns)
    for b in bands:
        if b.lower() == band.lower():
            return b
    raise InputError(f"{token(band)} is not a band of these results; bands: {', '.join(bands)}", source=source,
                     key="--band")


def reference_of(summary: dict[str, Any]) -> dict[str, Any] | None:
    """The reference row (the sensor's own bands) of a previous ``summary.json``, in the row form
    :func:`summarise` takes; None when there is none."""
    ref = summary.get("reference")
    if not isinstance(ref, dict) or not isinstance(ref.get("bands"), dict):
        return None
    row = {k: v for k, v in ref.items() if k not in ("bands", "configurations_better")}
    try:
        for b, (c, w) in ref["bands"].items():
            row |= {f"{b}_centre_nm": c, f"{b}_width_nm": w}
    except (TypeError, ValueError):  # not what s2cl writes: no reference
        return None
    return row


def shapes(row: Any, bands: list[str]) -> dict[str, list[float]]:
    return {b: [float(row[f"{b}_centre_nm"]), float(row[f"{b}_width_nm"])] for b in bands}


def rankable(df: Any, meta: dict[str, str]) -> Any:
    """The configurations a ranking may use (:func:`s2cl.sweep.digest.rankable_rows`)."""
    return rankable_rows(df, meta)


def digest_of(data: Any, meta: dict[str, str], **kwargs: Any) -> Digest:
    """``data`` as a :class:`Digest`: itself, or a DataFrame of results reduced (as one batch)."""
    return data if isinstance(data, Digest) else Digest.of_frame(data, meta, **kwargs)


def summarise(data: Any, meta: dict[str, str], reference: dict[str, Any] | None = None, top: int = 10
              ) -> dict[str, Any]:
    """Best configurations and the reference, with every robustness and fit-accounting column; ranks only
    :func:`rankable` configurations. ``data``: a :class:`Digest` (made with the same ``reference``) or a
    DataFrame of results."""
    d = digest_of(data, meta, reference=reference, top_n=top)
    metric, bands = d.metric, d.bands
    # a design's own values; the ``pareto`` column a multi-application sweep's trade-off adds is the summary's
    # ``pareto`` record's, not a ranking entry's
    keep = [c for c in d.columns if not c.endswith(("_centre_nm", "_width_nm")) and c != "pareto"]

    def entry(row: Any) -> dict[str, Any]:
        return {"bands": shapes(row, bands), **{k: _plain(row[k]) for k in keep}}

    ranked = d.top if d.top is not None else []
    out: dict[str, Any] = {"scene": meta.get("scene", ""), "configurations": d.configurations, "ranked": d.ranked,
                           "metric": metric, "bands": bands,
                           "underdetermined": {"count": d.flagged, "ranking": meta.get("underdetermined", "exclude"),
                                               "coincident_centres": dict(d.coincident)}}
    if "regress" in meta:
        out["regress"] = json.loads(meta["regress"])
    if d.ranked:
        out["best"] = entry(ranked.iloc[0])
        out["top"] = [entry(r) for _, r in ranked.head(top).iterrows()]
    else:
        out["top"] = []
    if reference is not None:
        out["reference"] = {"bands": {b: [reference[f"{b}_centre_nm"], reference[f"{b}_width_nm"]] for b in bands},
                            **{k: _plain(reference[k]) for k in keep if k in reference}}
        out["reference"]["configurations_better"] = int(d.better)
    return out


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    return value


def centre_width_grid(df: Any, band: str, metric: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centres, widths, best metric over the other bands) for one band of a DataFrame: ``values[i, j]`` at
    centre ``i`` and width ``j`` (NaN where that pair is not a variant). Dense: for small tables (the
    benchmarks); the heatmaps use :meth:`Digest.binned_grid`."""
    c, w = df[f"{band}_centre_nm"].to_numpy(), df[f"{band}_width_nm"].to_numpy()
    centres, widths = np.unique(c), np.unique(w)
    values = np.full((centres.size, widths.size), np.nan)
    ci, wi = np.searchsorted(centres, c), np.searchsorted(widths, w)
    np.fmin.at(values, (ci, wi), df[metric].to_numpy(dtype=np.float64))
    return centres, widths, values


def _label(value: Any) -> str:
    return value if isinstance(value, str) else f"{value:g}"


def draw_grid(ax: Any, centres: Any, widths: Any, values: np.ndarray, band: str, fontsize: float,
              digits: int | None = None, best: str = "min", hatched: np.ndarray | None = None) -> Any:
    """Centre × width table ``values`` on ``ax``: cells written where there are at most 150, the
    best (``best``: the lowest, or with ``"max"`` the highest, e.g. a gain) boxed in red; its own colour scale
    (the best end dark); the cells of ``hatched`` (a boolean mask of ``values``' shape) hatched. Returns the
    image (for a colour bar)."""
    plt = pyplot()
    cmap = "viridis_r" if best == "min" else "viridis"
    im = ax.imshow(values, origin="lower", aspect="auto", cmap=cmap, interpolation="nearest")
    ax.set_xticks(range(len(widths)), [_label(w) for w in widths], fontsize=fontsize,
                  rotation=90 if any("–" in _label(w) for w in widths) else 0)
    ax.set_yticks(range(len(centres)), [_label(c) for c in centres], fontsize=fontsize)
    ax.set_xlabel(f"{band} FWHM (nm)", fontsize=fontsize + 1)
    ax.set_ylabel(f"{band} centre (nm)", fontsize=fontsize + 1)
    finite = values[np.isfinite(values)]
    if values.size <= 150:
        mid = np.median(finite) if finite.size else 0.0
        if digits is None:
            spread = np.ptp(finite) if finite.size else 0.0
            digits = 1 if spread >= 2 else (2 if spread >= 0.2 else 3)
        for i, j in zip(*np.nonzero(np.isfinite(values)), strict=True):
            dark = values[i, j] > mid if best == "min" else values[i, j] < mid
            ax.text(j, i, f"{values[i, j]:.{digits}f}", ha="center", va="center", fontsize=fontsize - 1,
                    color="white" if dark else "black")
    if hatched is not None:
        for i, j in zip(*np.nonzero(hatched), strict=True):
            ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, ec=(0, 0, 0, 0.55), lw=0, hatch="///"))
    if finite.size:
        pick = np.nanargmin if best == "min" else np.nanargmax
        i, j = np.unravel_index(pick(values), values.shape)
        ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, ec="red", lw=2))
    return im


def heatmap(data: Any, band: str, path: str | Path, *, metric: str | None = None, title: str = "",
            unit: str = "", hatch: list[tuple[float, float]] | None = None) -> Path:
    """Centre × width heatmap of ``band`` (best over the other bands), the best cell marked, the cells holding a
    (centre, width) pair of ``hatch`` hatched (the designs within noise of #1); at most
    :data:`~s2cl.sweep.digest.HEATMAP_CENTRES` × :data:`~s2cl.sweep.digest.HEATMAP_WIDTHS` cells (consecutive
    centres or widths grouped beyond that: :meth:`Digest.binned_grid`), so the figure's size is bounded."""
    d = digest_of(data, {"underdetermined": "keep"}, metric_column=metric)
    metric = d.metric
    centres, widths, values, (gc, gw) = d.binned_grid(band)
    hatched = d.binned_cells(band, hatch) if hatch else None
    # cells shrink when there are many (at most 60 × 40: about 1,700 × 2,000 pixels)
    cell_w, cell_h = (0.62 if len(widths) <= 20 else 0.32), (0.42 if len(centres) <= 30 else 0.26)
    fig, ax = pyplot().subplots(figsize=(1.0 + cell_w * len(widths), 1.2 + cell_h * len(centres)), dpi=120)
    im = draw_grid(ax, centres, widths, values, band, fontsize=8, hatched=hatched)
    fig.colorbar(im, ax=ax, label=f"{metric} {unit}".strip())
    grouped = f"; cells group {gc} centres × {gw} widths" if gc * gw > 1 else ""
    marked = ";\nhatched: within noise of #1" if hatched is not None and hatched.any() else ""
    ax.set_title(title or f"{band}: {metric} (best over the other bands{grouped}; red: best{marked})", fontsize=9)
    fig.tight_layout()
    return save_png(fig, path)


def write_summary(path: str | Path, summary: dict[str, Any]) -> Path:
    return write_json(path, summary)


def read_summary(path: str | Path) -> dict[str, Any]:
    """A previous ``summary.json``; an unreadable one counts as none (the report rewrites it)."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


# -- the paper's values beside s2cl's (Segl et al. 2012, Tables 3-6) -------------------------------

PAPER_FILE = "segl2012_results.json"
#: scene name → (paper table, key); the built-in scenes are named after the tables they reproduce
_TABLE3 = {f"table3-{lib}-b{bands}": (lib.capitalize(), bands) for lib in ("lib1", "lib2")
           for bands in ("4567", "4568", "4568a")}
_GRIDS = {"table4-b4": ("table4", "B4", "rms"), "table5-b11": ("table5", "B11", "rms"),
          "table6-b12": ("table6", "B12", "omission_error")}


@functools.cache
def paper_results() -> dict[str, Any]:
    """The paper's printed results (s2cl/data/segl2012_results.json), read once; do not modify."""
    return json.loads((importlib.resources.files("s2cl") / "data" / PAPER_FILE).read_text(encoding="utf-8"))


def _band_key(bands: list[str]) -> str:
    return "".join(b[1:] for b in bands)


def _table3_row(name: str, bands: list[str]) -> dict[str, Any] | None:
    """The paper's Table 3 row for built-in scene ``name`` sweeping ``bands``; None for other scenes."""
    if name not in _TABLE3:
        return None
    lib, key = _TABLE3[name]
    if _band_key(bands) != key:
        return None
    return next(r for r in paper_results()["table3"] if r["library"] == lib and _band_key(r["bands"]) == key)


def paper_match(name: str, bands: list[str]) -> list[list[float]] | None:
    """The band shape whose rows a :class:`Digest` collects for the paper's Table 3 (its best design)."""
    row = _table3_row(name, bands)
    return None if row is None else row["best"]


def paper_comparison(data: Any, summary: dict[str, Any]) -> dict[str, Any] | None:
    """The paper's values for this sweep beside s2cl's, or None when the scene is not one of the
    paper's (matched by the built-in scene names ``table3-lib{1,2}-b*``, ``table4-b4``,
    ``table5-b11``, ``table6-b12`` and the swept bands). ``data``: the rankable configurations as a
    :class:`Digest` (made with :func:`paper_match`) or a DataFrame."""
    name, bands = summary.get("scene", ""), summary["bands"]
    row = _table3_row(name, bands)
    if row is not None:
        return _table3(digest_of(data, {"underdetermined": "keep"}, match=row["best"]), summary, row)
    if name in _GRIDS:
        table, band, paper_metric = _GRIDS[name]
        if band not in bands:
            return None
        return _grid_table(digest_of(data, {"underdetermined": "keep"}), summary, table, band,
                           paper_results()[table], paper_metric)
    return None


def _table3(d: Digest, summary: dict[str, Any], row: dict[str, Any]) -> dict[str, Any]:
    bands, metric = summary["bands"], summary["metric"]
    out: dict[str, Any] = {
        "table": "table3", "library": row["library"], "configurations_paper": row["configurations"],
        "paper": {"rms_esa": row["rms_esa"], "rms_best": row["rms_best"],
                  "best": dict(zip(bands, row["best"], strict=True))},
        "s2cl": {"rms_esa": summary.get("reference", {}).get(metric), "rms_best": summary["best"][metric],
                 "best": summary["best"]["bands"]},
    }
    if d.matches is not None and len(d.matches):
        r = d.matches.iloc[0]
        rank = d.count_below(float(r[metric])) + 1  # among the rankable configurations
        out["paper_best_in_s2cl"] = {k: _plain(r[k]) for k in (metric, "robust_rms", "bound_fraction",
                                                              "failed_fraction") if k in r.index}
        out["paper_best_in_s2cl"]["rank"] = rank
    return out


def _grid_table(d: Digest, summary: dict[str, Any], table: str, band: str, paper: dict[str, Any],
                paper_metric: str) -> dict[str, Any]:
    from scipy.stats import spearmanr

    metric = summary["metric"]
    pc, pw = np.asarray(paper["centres"], float), np.asarray(paper["widths"], float)
    pv = np.asarray(paper[paper_metric], float)
    ours = np.array([[d.value(band, c, w) for w in pw] for c in pc])
    pi, pj = np.unravel_index(np.argmin(pv), pv.shape)
    out: dict[str, Any] = {
        "table": table, "band": band, "metric": metric, "unit": paper.get("unit", ""),
        "centres_nm": pc.tolist(), "widths_nm": pw.tolist(),
        "paper": pv.tolist(), "s2cl": [[None if not np.isfinite(v) else float(v) for v in r] for r in ours],
        "paper_best": {"bands": [float(pc[pi]), float(pw[pj])], "value": float(pv[pi, pj]),
                       "s2cl_value": None if not np.isfinite(ours[pi, pj]) else float(ours[pi, pj])},
    }
    both = np.isfinite(ours)
    if both.any():
        si, sj = np.unravel_index(np.nanargmin(ours), ours.shape)
        out["s2cl_best"] = {"bands": [float(pc[si]), float(pw[sj])], "value": float(ours[si, sj]),
                            "paper_value": float(pv[si, sj])}
        out["cells"] = int(both.sum())
        if both.sum() >= 3:  # Spearman rank correlation (ties averaged) of the cells both have: same shape?
            rho = spearmanr(ours[both], pv[both]).statistic if np.ptp(ours[both]) and np.ptp(pv[both]) else np.nan
            out["rank_correlation"] = None if np.isnan(rho) else float(rho)
    return out


def heatmap_vs_paper(comparison: dict[str, Any], path: str | Path) -> Path:
    """s2cl's centre × width table beside the paper's (own colour scale each, best marked)."""
    pc, pw = comparison["centres_nm"], comparison["widths_nm"]
    grids = {"s2cl": np.array(comparison["s2cl"], dtype=float), "Segl et al. 2012": np.array(comparison["paper"])}
    fig, axes = pyplot().subplots(1, 2, figsize=(2.0 + 1.1 * len(pw), 1.4 + 0.38 * len(pc)), dpi=110)
    for ax, (label, v) in zip(axes, grids.items(), strict=True):
        im = draw_grid(ax, pc, pw, v, comparison["band"], fontsize=7, digits=1)
        fig.colorbar(im, ax=ax, fraction=0.05)
        ax.set_title(f"{label}: {comparison['metric']} {comparison['unit']}".strip(), fontsize=8)
    fig.tight_layout()
    return save_png(fig, path)
