"""Quicklook PNG of an image simulation's analysis: true colour, the map, its status (and its error where the
truth is known), drawn off screen (:mod:`s2cl.io.plots`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from s2cl.io.image_store import ImageStore
from s2cl.io.plots import pyplot, save_png
from s2cl.status import Status

#: bands of the true-colour panel (red, green, blue), Sentinel-2 names
TRUE_COLOUR = ("B4", "B3", "B2")
#: the true-colour stretch: each channel's percentiles (%) mapped to 0 and 1, stated on the panel
STRETCH_PERCENTILES = (2.0, 98.0)
TRUE_COLOUR_TITLE = (f"true colour ({' '.join(TRUE_COLOUR)})\nL2 reflectance, each channel stretched "
                     f"{STRETCH_PERCENTILES[0]:g}–{STRETCH_PERCENTILES[1]:g} %")
#: largest side (pixels) of a panel: a larger image is read every n-th row and column
MAX_SIDE = 600


def _decimated(store: ImageStore, name: str) -> np.ndarray:
    """Every n-th row and column of ``name`` (n: what keeps its larger side under :data:`MAX_SIDE`), float64."""
    ny, nx = store.shape(name)
    n = max(1, -(-max(ny, nx) // MAX_SIDE))
    return store.read(name, slice(0, ny, n))[:, ::n].astype(np.float64)


def true_colour(ds: Any) -> np.ndarray | None:
    """An RGB image ``(ny, nx, 3)`` in 0–1 of the corrected reflectance, each channel stretched linearly from its
    :data:`STRETCH_PERCENTILES` (2 and 98 %, over the pixels finite in all three) to 0 and 1 and clipped; NaN stays
    NaN (drawn blank); None when a true-colour band is missing."""
    names = [f"reflectance_{b}" for b in TRUE_COLOUR]
    if not all(n in ds for n in names):
        return None
    channels = [_decimated(ds, n) for n in names]
    ny = min(c.shape[0] for c in channels)
    nx = min(c.shape[1] for c in channels)
    rgb = np.stack([c[:ny, :nx] for c in channels], axis=-1)
    finite = rgb[np.isfinite(rgb).all(axis=-1)]
    if finite.size == 0:
        return None
    lo, hi = (np.percentile(finite, q, axis=0) for q in STRETCH_PERCENTILES)
    return np.clip((rgb - lo) / np.where(hi > lo, hi - lo, 1.0), 0.0, 1.0)


def write_quicklook(ds: ImageStore, path: str | Path, map_name: str = "analysis_index") -> Path:
    """Write the quicklook of the analysis in store ``ds`` (``map_name``: the variable shown as the map) to
    ``path``."""
    plt = pyplot()
    rgb = true_colour(ds)
    panels = ["rgb"] if rgb is not None else []
    panels += [map_name, "analysis_status"]
    error = map_name.replace("_map", "_error")
    if error != map_name and error in ds:
        panels.append(error)
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 4.4), layout="constrained")
    axes = np.atleast_1d(axes)
    for ax, name in zip(axes, panels, strict=True):
        ax.set_xticks([])
        ax.set_yticks([])
        if name == "rgb":
            ax.imshow(rgb, interpolation="nearest")
            ax.set_title(TRUE_COLOUR_TITLE)
            continue
        data = _decimated(ds, name)
        if name == "analysis_status":
            codes = [s.value for s in Status]
            cmap = plt.get_cmap("tab10").resampled(len(codes))
            im = ax.imshow(data, cmap=cmap, vmin=-0.5, vmax=len(codes) - 0.5, interpolation="nearest")
            bar = fig.colorbar(im, ax=ax, ticks=codes, shrink=0.8)
            bar.ax.set_yticklabels([s.name.lower() for s in Status])
            ax.set_title("status")
            continue
        finite = data[np.isfinite(data)]
        if name.endswith("_error"):
            m = float(np.percentile(np.abs(finite), 98)) if finite.size else 1.0
            im = ax.imshow(data, cmap="RdBu_r", vmin=-m, vmax=m, interpolation="nearest")
        else:
            truth = name.replace("_map", "_truth")
            if truth != name and truth in ds:  # the map on the truth's scale: outliers saturate
                values = _decimated(ds, truth)
                finite = values[np.isfinite(values)]
            lo, hi = (np.percentile(finite, [0, 100] if truth in ds else [2, 98]) if finite.size else (0.0, 1.0))
            im = ax.imshow(data, cmap="viridis", vmin=lo, vmax=hi, interpolation="nearest")
        fig.colorbar(im, ax=ax, shrink=0.8, label=ds.attrs_of(name).get("units", ""))
        ax.set_title(name.replace("_", " "))
    fig.suptitle(f"{ds.attrs.get('scene', '')}: {ds.attrs.get('analysis_kind', '')} on "
                 f"{ds.attrs.get('analysis_bands', '')} at {float(ds.attrs.get('analysis_gsd_m', 0)):g} m")
    return save_png(fig, path, dpi=100)
