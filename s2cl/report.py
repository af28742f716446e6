"""What a sweep found: best configurations, the reference (e.g. ESA) configuration, centre × width
tables and heatmaps, and JSON for the record."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from .output import atomic_path, write_json

LOWER_IS_BETTER = {"rms": True, "robust_rms": True, "omission_error_pct": True}


def metric_of(columns: list[str]) -> str:
    """The ranking metric of a results table."""
    return "omission_error_pct" if "omission_error_pct" in columns else "rms"


def load(path: str | Path) -> tuple[Any, dict[str, str]]:
    """Results as a pandas DataFrame and the file's metadata."""
    import pyarrow.parquet as pq

    p = Path(path)
    if p.is_dir():
        p = p / "results.parquet"
    table = pq.read_table(p)
    meta = {k.decode(): v.decode() for k, v in (table.schema.metadata or {}).items() if not k.startswith(b"pandas")}
    return table.to_pandas(), meta


def bands_of(df: Any) -> list[str]:
    return [c[: -len("_centre_nm")] for c in df.columns if c.endswith("_centre_nm")]


def shapes(row: Any, bands: list[str]) -> dict[str, list[float]]:
    return {b: [float(row[f"{b}_centre_nm"]), float(row[f"{b}_width_nm"])] for b in bands}


def summarise(df: Any, meta: dict[str, str], reference: dict[str, Any] | None = None, top: int = 10
              ) -> dict[str, Any]:
    """Best configurations and the reference, with every robustness column."""
    metric = metric_of(list(df.columns))
    bands = bands_of(df)
    ranked = df.sort_values([metric, "config"], na_position="last")
    keep = [c for c in df.columns if not c.endswith(("_centre_nm", "_width_nm"))]

    def entry(row: Any) -> dict[str, Any]:
        return {"bands": shapes(row, bands), **{k: _plain(row[k]) for k in keep}}

    out: dict[str, Any] = {"scene": meta.get("scene", ""), "configurations": len(df), "metric": metric,
                           "bands": bands, "best": entry(ranked.iloc[0]),
                           "top": [entry(r) for _, r in ranked.head(top).iterrows()]}
    if reference is not None:
        out["reference"] = {"bands": {b: [reference[f"{b}_centre_nm"], reference[f"{b}_width_nm"]] for b in bands},
                            **{k: _plain(reference[k]) for k in keep if k in reference}}
        better = np.sum(df[metric].to_numpy() < reference[metric])
        out["reference"]["configurations_better"] = int(better)
    return out


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    return value


def centre_width_grid(df: Any, band: str, metric: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centres, widths, best metric over the other bands) for one band: ``values[i, j]`` at centre ``i``
    and width ``j`` (NaN where that pair is not a variant)."""
    c, w = df[f"{band}_centre_nm"].to_numpy(), df[f"{band}_width_nm"].to_numpy()
    centres, widths = np.unique(c), np.unique(w)
    values = np.full((centres.size, widths.size), np.nan)
    ci, wi = np.searchsorted(centres, c), np.searchsorted(widths, w)
    m = df[metric].to_numpy(dtype=np.float64)
    order = np.argsort(-np.nan_to_num(m, nan=np.inf))  # fill worst first so the best value wins
    values[ci[order], wi[order]] = m[order]
    return centres, widths, values


def heatmap(df: Any, band: str, path: str | Path, *, metric: str | None = None, title: str = "",
            unit: str = "") -> Path:
    """Centre × width heatmap of ``band`` (best over the other bands), the best pair marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metric = metric or metric_of(list(df.columns))
    centres, widths, values = centre_width_grid(df, band, metric)
    fig, ax = plt.subplots(figsize=(1.0 + 0.62 * widths.size, 1.2 + 0.42 * centres.size), dpi=120)
    im = ax.imshow(values, origin="lower", aspect="auto", cmap="viridis_r")
    ax.set_xticks(range(widths.size), [f"{w:g}" for w in widths])
    ax.set_yticks(range(centres.size), [f"{c:g}" for c in centres])
    ax.set_xlabel(f"{band} FWHM (nm)")
    ax.set_ylabel(f"{band} centre (nm)")
    if values.size <= 150:
        finite = values[np.isfinite(values)]
        mid = np.median(finite) if finite.size else 0
        spread = np.ptp(finite) if finite.size else 0.0
        digits = 1 if spread >= 2 else (2 if spread >= 0.2 else 3)
        for i in range(centres.size):
            for j in range(widths.size):
                if np.isfinite(values[i, j]):
                    ax.text(j, i, f"{values[i, j]:.{digits}f}", ha="center", va="center", fontsize=7,
                            color="white" if values[i, j] > mid else "black")
    if np.isfinite(values).any():
        i, j = np.unravel_index(np.nanargmin(values), values.shape)
        ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, ec="red", lw=2))
    fig.colorbar(im, ax=ax, label=f"{metric} {unit}".strip())
    ax.set_title(title or f"{band}: {metric} (best over the other bands; red: best)", fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return Path(path)


def write_summary(path: str | Path, summary: dict[str, Any]) -> Path:
    return write_json(path, summary)


def read_summary(path: str | Path) -> dict[str, Any]:
    return json.loads(Path(path).read_text())
