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
#: the figure's resolution (dots per inch) and each panel's image box (inches, square; an image keeps its aspect in it)
DPI = 100
PANEL_IN = 3.4
#: room (inches) around the boxes: the panels' titles and the figure's above (0.1 below), a margin each side (more where
#: the title is wider than the box), a colorbar's bar and the gap before it; a text gets :data:`LABEL_IN` per character
#: (10-point text): the colorbar's tick labels, the title's longest line
TOP_IN, MARGIN_IN, BAR_IN, GAP_IN, LABEL_IN = 0.9, 0.15, 0.17, 0.12, 0.09
#: largest side (pixels) of a panel's image: a larger image is read every n-th row and column (finer would not show)
MAX_SIDE = round(PANEL_IN * DPI)
#: zlib level of the PNG (1 fastest … 9 smallest): 3 writes a quicklook in about half the time of the default 6, for a
#: file a few percent larger
PNG_COMPRESS_LEVEL = 3


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
    ``path``: the true colour, the map (on its truth's scale where the truth is known), the status and the error
    where there is one, side by side, each value panel with its colorbar; laid out by hand (:func:`_layout`: no
    layout engine to run at every draw)."""
    plt = pyplot()
    rgb = true_colour(ds)
    panels = ["rgb"] if rgb is not None else []
    panels += [map_name, "analysis_status"]
    error = map_name.replace("_map", "_error")
    if error != map_name and error in ds:
        panels.append(error)
    status_names = [s.name.lower() for s in Status]
    titles = {"rgb": TRUE_COLOUR_TITLE, "analysis_status": "status"}
    titles.update({name: name.replace("_", " ") for name in panels if name not in titles})
    bars = {"rgb": 0, "analysis_status": max(map(len, status_names))}  # characters of the colorbar's tick labels
    fig, boxes = _layout(plt, [bars.get(name, 6) for name in panels],
                         [max(map(len, titles[name].splitlines())) for name in panels])
    for (ax, cax), name in zip(boxes, panels, strict=True):
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(titles[name])
        if name == "rgb":
            ax.imshow(rgb, interpolation="nearest")
            continue
        data = _decimated(ds, name)
        if name == "analysis_status":
            codes = [s.value for s in Status]
            cmap = plt.get_cmap("tab10").resampled(len(codes))
            im = ax.imshow(data, cmap=cmap, vmin=-0.5, vmax=len(codes) - 0.5, interpolation="nearest")
            bar = fig.colorbar(im, cax=cax, ticks=codes)
            bar.ax.set_yticklabels(status_names)
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
        fig.colorbar(im, cax=cax, label=ds.attrs_of(name).get("units", ""))
    fig.suptitle(f"{ds.attrs.get('scene', '')}: {ds.attrs.get('analysis_kind', '')} on "
                 f"{ds.attrs.get('analysis_bands', '')} at {float(ds.attrs.get('analysis_gsd_m', 0)):g} m",
                 y=1 - 0.12 / (PANEL_IN + TOP_IN + 0.1))
    return save_png(fig, path, dpi=DPI, compress_level=PNG_COMPRESS_LEVEL)


def _layout(plt: Any, bars: list[int], titles: list[int]) -> tuple[Any, list[tuple[Any, Any]]]:
    """A figure of panels side by side, each a square image box of :data:`PANEL_IN` inches under a title whose longest
    line has ``titles[i]`` characters and, where ``bars[i]`` is not 0, a colorbar beside the box (80 % of its height)
    with room for tick labels of ``bars[i]`` characters; the figure and each panel's (image axes, colorbar axes or
    None)."""
    sides = [max(MARGIN_IN, (LABEL_IN * n - PANEL_IN) / 2 + 0.1) for n in titles]
    widths = [PANEL_IN + (GAP_IN + BAR_IN + 0.25 + LABEL_IN * n if n else 0.0) + 2 * side
              for n, side in zip(bars, sides, strict=True)]
    w, h = sum(widths), PANEL_IN + TOP_IN + 0.1
    fig = plt.figure(figsize=(w, h))
    boxes, x = [], 0.0
    for width, n, side in zip(widths, bars, sides, strict=True):
        ax = fig.add_axes(((x + side) / w, 0.1 / h, PANEL_IN / w, PANEL_IN / h))
        cax = None
        if n:
            left = x + side + PANEL_IN + GAP_IN
            cax = fig.add_axes((left / w, (0.1 + 0.1 * PANEL_IN) / h, BAR_IN / w, 0.8 * PANEL_IN / h))
        boxes.append((ax, cax))
        x += width
    return fig, boxes
