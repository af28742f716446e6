"""The suite's figures: one per group of families, one axis (panel) per family or per shared panel.

A panel function ``draw(ax, items)`` draws ``items``, a list of ``(title, result)`` of the families
on that axis; :mod:`bench.registry` says which family is drawn by which panel.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bench.common import save_figure

Items = list[tuple[str, dict[str, Any]]]


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the non-dominated points (lower time and lower error), by time."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def _marker(r: dict[str, Any]) -> dict[str, Any]:
    """Default ★, reference ■, another SRF model ×, other settings ●."""
    if r.get("model_change"):
        return {"marker": "x", "color": "0.4", "s": 30}
    if r.get("default"):
        return {"marker": "*", "color": "C3", "s": 140}
    if r.get("reference"):
        return {"marker": "s", "color": "k", "s": 36}
    return {"marker": "o", "color": "C0", "s": 22}


def pareto(ax: Any, items: Items) -> None:
    """A knob: error (its ``primary_error``, log) against time, the Pareto front of the same model."""
    from matplotlib import ticker

    ((_, fam),) = items
    rows = [r for r in fam["rows"] if not r.get("skipped") and r.get(fam["primary_error"]) is not None]
    errs = [float(r[fam["primary_error"]]) for r in rows]
    positive = [e for e in errs if e > 0]
    floor = (min(positive) / 5) if positive else 1e-6
    pts = [(1e3 * r["seconds"], max(e, floor)) for r, e in zip(rows, errs, strict=True)]
    same_model = [i for i, r in enumerate(rows) if not r.get("model_change")]
    front = [same_model[i] for i in pareto_front([pts[i] for i in same_model])]
    ax.plot([pts[i][0] for i in front], [pts[i][1] for i in front], "-", color="0.6", lw=1, zorder=1,
            label="Pareto front")
    for r, (x, y), e in zip(rows, pts, errs, strict=True):
        ax.scatter([x], [y], zorder=3, **_marker(r))
        label = r["setting"].split(" (")[0][:28] + (" (=0)" if e <= 0 else "")
        ax.annotate(label, (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
    xs = [x for x, _ in pts]
    if max(xs) / min(xs) > 8:
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(ticker.FormatStrFormatter("%g"))
        ax.xaxis.set_minor_formatter(ticker.NullFormatter())
    ax.set_yscale("log")
    ax.set_xlabel("time [ms] (median)", fontsize=8)
    ax.set_ylabel(fam["error_label"], fontsize=7)
    ax.tick_params(labelsize=7)


def loglog(ax: Any, items: Items) -> None:
    """Scaling series: time against problem size, log–log, each with its fitted slope."""
    for i, (title, s) in enumerate(items):
        ax.loglog([p["x"] for p in s["points"]], [p["seconds"] for p in s["points"]], "o-", color=f"C{i}",
                  label=f"{title} vs {s['x']} (slope {s['slope']:.2f})")
    ax.set_xlabel("pixels / configurations / bands")
    ax.set_ylabel("time [s] (median)")
    ax.legend(fontsize=7)


def memory(ax: Any, items: Items) -> None:
    """Resident-memory growth per sweep chunk, measured against s2cl's planning estimate."""
    ((_, m),) = items
    chunks = [p["chunk"] for p in m["points"]]
    ax.plot(chunks, [p["chunk_rss_mib"] for p in m["points"]], "o-", label="measured RSS growth")
    ax.plot(chunks, [p["estimate_mib"] for p in m["points"]], "--", label="s2cl's estimate")
    ax.set_xscale("log")
    ax.set_xlabel("configurations per chunk")
    ax.set_ylabel("MiB")
    ax.legend(fontsize=7)


def dask(ax: Any, items: Items) -> None:
    """Wall time of the whole sweep per run (in-process, Dask workers)."""
    ((_, d),) = items
    ax.bar([r["label"] for r in d["rows"]], [r["seconds"] for r in d["rows"]],
           color=[f"C{i}" for i in range(len(d["rows"]))])
    ax.set_ylabel("wall time [s]")


def figure(panels: Sequence[tuple[str, Any, Items]], path: Path, *, size: tuple[float, float], columns: int,
           suptitle: str | None = None) -> Path | None:
    """Draw ``panels`` (title, draw function, items) on a grid of at most ``columns`` columns, each
    axis ``size`` inches; save to ``path`` (None when there is nothing to draw)."""
    if not panels:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = min(columns, len(panels))
    rows = math.ceil(len(panels) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(size[0] * cols, size[1] * rows), squeeze=False)
    for ax, (title, draw, items) in zip(axes.flat, panels, strict=False):
        draw(ax, items)
        ax.set_title(title, fontsize=9)
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    if suptitle:
        fig.suptitle(suptitle, fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
    return path
