"""Figures of the trade-off across applications (:mod:`s2cl.sweep.pareto`): for two applications a scatter of one
score against the other (every design faint, the front highlighted and joined, requirement lines, the sensor's own
bands marked); for three or more a parallel-coordinates figure of the front, each score relative to the sensor's
own bands' score, the sensor's own bands a distinct line. Drawn off screen (:func:`s2cl.io.plots.pyplot`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.io.plots import pyplot, save_png

#: designs drawn faintly behind the front at most (a seeded sample of the rest is not drawn; the legend says so)
MAX_POINTS = 200_000
FRONT_COLOUR, OWN_COLOUR, TARGET_COLOUR = "tab:red", "tab:blue", "tab:green"


def axis_label(application: dict[str, Any]) -> str:
    """``name: metric (units)`` of one ``summary["applications"]`` record."""
    units = application.get("units") or ""
    return f"{application['name']}: {application.get('metric', '')}" + (f" ({units})" if units else "")


def scatter_figure(scores: np.ndarray, on_front: np.ndarray, applications: Sequence[dict[str, Any]], *,
                   max_points: int = MAX_POINTS, seed: int = 0) -> Any:
    """The two-application figure: ``scores`` ``(n, 2)``, ``on_front`` ``bool[n]``, ``applications`` the two
    records (``name``, ``metric``, ``units``, ``target``, ``reference``). The front's designs are joined in order
    of the first score (a staircase line, label ``front``)."""
    plt = pyplot()
    s = np.asarray(scores, dtype=np.float64)
    on = np.asarray(on_front, dtype=bool)
    fig, ax = plt.subplots(figsize=(6.4, 5.2), layout="constrained")
    ok = np.isfinite(s).all(axis=1)
    rest = np.flatnonzero(ok & ~on)
    label = f"designs ({rest.size:,})"
    if rest.size > max_points:
        rest = np.sort(np.random.default_rng(seed).choice(rest, max_points, replace=False))
        label = f"designs ({max_points:,} of {np.count_nonzero(ok & ~on):,} drawn)"
    few = rest.size <= 10_000  # a few designs drawn plainly, many faintly
    ax.scatter(s[rest, 0], s[rest, 1], s=14 if few else 4, c="0.55" if few else "0.6", alpha=0.8 if few else 0.3,
               linewidths=0, rasterized=True, label=label)
    f = s[on][np.lexsort((s[on, 1], s[on, 0]))]
    ax.plot(f[:, 0], f[:, 1], "o-", color=FRONT_COLOUR, ms=4, lw=1.2, label=f"front ({len(f):,})", zorder=3)
    for k, line in ((0, ax.axvline), (1, ax.axhline)):
        target = applications[k].get("target")
        if target is not None:
            line(float(target), color=TARGET_COLOUR, ls="--", lw=1,
                 label=f"{applications[k]['name']} requirement {float(target):g}")
    own = [applications[k].get("reference") for k in (0, 1)]
    if all(r is not None for r in own):
        ax.plot([own[0]], [own[1]], "*", color=OWN_COLOUR, ms=14, mec="k", label="the sensor's own bands", zorder=4)
    ax.set_xlabel(axis_label(applications[0]))
    ax.set_ylabel(axis_label(applications[1]))
    ax.set_title("Designs across two applications (lower is better on both)")
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(alpha=0.3)
    return fig


def parallel_figure(front_scores: np.ndarray, applications: Sequence[dict[str, Any]]) -> Any:
    """The figure for three or more applications: one line per front design (``front_scores`` ``(f, k)``) across
    one axis per application; each score divided by the sensor's own bands' score where it is known (1: as good as
    the sensor's own bands; their line drawn distinct at 1), else by the front's best score on that axis (said on
    the axis). Requirements are marked on their axes the same way."""
    plt = pyplot()
    s = np.asarray(front_scores, dtype=np.float64).reshape(-1, len(applications))
    scale, how = relative_scales(s, applications)
    fig, ax = plt.subplots(figsize=(max(6.0, 1.8 * len(applications)), 4.8), layout="constrained")
    x = np.arange(len(applications))
    for row in s / scale:
        ax.plot(x, row, "-o", color=FRONT_COLOUR, alpha=0.35, ms=3, lw=1)
    ax.plot([], [], "-o", color=FRONT_COLOUR, label=f"front ({len(s):,} designs)")
    known = [k for k, a in enumerate(applications) if a.get("reference") is not None]
    if known:
        ax.plot(x[known], [1.0] * len(known), "-*", color=OWN_COLOUR, ms=12, mec="k", lw=2.5,
                label="the sensor's own bands", zorder=4)
    targets = [(k, float(a["target"]) / scale[k]) for k, a in enumerate(applications) if a.get("target") is not None]
    if targets:
        ax.plot([t[0] for t in targets], [t[1] for t in targets], "_", color=TARGET_COLOUR, ms=30, mew=2.5,
                ls="none", label="requirement")
    for k in x:
        ax.axvline(k, color="0.7", lw=0.8)
    # the name, then the metric and units, then the divisor: three short lines, so that neighbours do not overlap
    ax.set_xticks(x, [axis_label(a).replace(": ", ":\n", 1) + f"\n÷ {h}"
                      for a, h in zip(applications, how, strict=True)], fontsize=8)
    ax.set_ylabel("score relative to the axis's divisor (lower is better)")
    ax.set_title("The Pareto front across the applications")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.grid(axis="y", alpha=0.3)
    return fig


def relative_scales(front_scores: np.ndarray, applications: Sequence[dict[str, Any]]) -> tuple[np.ndarray, list[str]]:
    """Per application, what :func:`parallel_figure` divides its scores by and how to say it: the sensor's own
    bands' score where it is known and > 0, else the front's best (finite, > 0) score, else 1."""
    scale, how = [], []
    for k, a in enumerate(applications):
        ref = a.get("reference")
        col = front_scores[:, k][np.isfinite(front_scores[:, k]) & (front_scores[:, k] > 0)]
        if ref is not None and np.isfinite(ref) and ref > 0:
            scale.append(float(ref)), how.append(f"own bands' {float(ref):.3g}")
        elif col.size:
            scale.append(float(col.min())), how.append(f"front's best {float(col.min()):.3g}")
        else:
            scale.append(1.0), how.append("1")
    return np.asarray(scale), how


def pareto_figure(scores: np.ndarray, on_front: np.ndarray, applications: Sequence[dict[str, Any]]) -> Any:
    """The trade-off's figure: :func:`scatter_figure` for two applications, :func:`parallel_figure` of the front for
    more; None for one (no trade-off)."""
    if len(applications) < 2:
        return None
    if len(applications) == 2:
        return scatter_figure(scores, on_front, applications)
    return parallel_figure(np.asarray(scores)[np.asarray(on_front, dtype=bool)], applications)


def pareto_plot(scores: np.ndarray, on_front: np.ndarray, applications: Sequence[dict[str, Any]],
                path: str | Path) -> Path | None:
    """Write :func:`pareto_figure` to ``path`` as PNG (``pareto.png`` beside ``summary.json``, say); None (nothing
    written) for one application."""
    fig = pareto_figure(scores, on_front, applications)
    return None if fig is None else save_png(fig, path)
