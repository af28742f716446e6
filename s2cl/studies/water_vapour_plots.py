"""Plots of the water-vapour studies (two-channel APDA and the three-channel 1020 nm window): RMS by
band design, per target, against the paper's range."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from s2cl.io.plots import pyplot, save_png
from s2cl.studies.water_vapour import PAPER_RMS_PCT

Data = dict[str, Any]


def plot_water_vapour(data: Data, path: Path) -> Path:
    """B9/B8a: relative RMS over the B9 variants (nominal B8a), the table's configurations beside the paper's
    5–10 %, and winter scenes with the winter and the summer LUT."""
    plt = pyplot()
    shapes = np.asarray(data["configurations"], dtype=np.float64)   # (n, 2 bands, centre/width)
    k = int(data["nominal_configuration"])
    rms = data["rel_rms_pct"]
    classes = list(rms)
    winter = data["winter"]

    def label(j: int) -> list[str]:
        return [f"{shapes[j, 0, 0]:g}/{shapes[j, 0, 1]:g}", f"{shapes[j, 1, 0]:g}/{shapes[j, 1, 1]:g}"]

    fig, axes = plt.subplots(1, 3, figsize=(14, 4), dpi=110)
    ax = axes[0]
    sel = [j for j in range(len(shapes)) if np.allclose(shapes[j, 1], shapes[k, 1])]
    cs = sorted({shapes[j, 0, 0] for j in sel})
    ws = sorted({shapes[j, 0, 1] for j in sel})
    grid = np.full((len(ws), len(cs)), np.nan)
    for j in sel:
        grid[ws.index(shapes[j, 0, 1]), cs.index(shapes[j, 0, 0])] = rms["all"][j]
    im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis",
                   extent=(cs[0] - 2.5, cs[-1] + 2.5, ws[0] - 5, ws[-1] + 5))
    fig.colorbar(im, ax=ax, label="relative RMS of WV (%)")
    ax.set_xlabel("B9 centre (nm)")
    ax.set_ylabel("B9 width (nm)")
    ax.set_title(f"s2cl: B9 variants, B8a {shapes[k, 1, 0]:g}/{shapes[k, 1, 1]:g}", fontsize=9)
    ax = axes[1]
    tags = [(tag, int(j)) for tag, j in data["table_configurations"] if not tag.startswith("best")]
    x = np.arange(len(tags))
    for n_c, c in enumerate(classes):
        ax.bar(x + (n_c - len(classes) / 2 + 0.5) * 0.2, [rms[c][j] for _, j in tags], 0.2, label=c)
    ax.axhspan(*PAPER_RMS_PCT, color="tab:red", alpha=0.15, label="paper: 5–10 %")
    ax.set_xticks(x, ["\n".join(label(j)) for _, j in tags], fontsize=7)
    ax.set_ylabel("relative RMS (%)")
    ax.set_title("B9/B8a configurations (s2cl vs paper)", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[2]
    x = np.arange(len(classes))
    ax.bar(x - 0.2, [winter["winter_lut"][c] for c in classes], 0.4, label="winter scene, winter LUT")
    ax.bar(x + 0.2, [winter["summer_lut"][c] for c in classes], 0.4, label="winter scene, summer LUT")
    ax.set_xticks(x, classes)
    ax.set_ylabel("relative RMS (%)")
    ax.set_title(f"profile mismatch: s2cl {winter['relative_increase_pct']['all']:+.1f} % (all), paper +6 %",
                 fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return save_png(fig, path)


def plot_water_vapour_1020(data: Data, path: Path) -> Path:
    """Three- vs two-channel water vapour (nominal B9/B8a): per target class the three-channel relative RMS over
    the second window's centre × width (two-channel value in the title); the two retrievals with and without
    noise; winter scenes with the winter and the summer LUT; the surface continuum error at B9."""
    plt = pyplot()
    k = int(data["nominal_configuration"])
    win = data["window"]
    var = np.asarray(win["variants"], dtype=np.float64)
    head, best = int(win["headline"]), int(win["best"])
    two, three = data["two_channel"], data["three_channel"]
    classes = list(two["rel_rms_pct"])
    name = win["name"]
    ncol = max(len(classes), 3)
    fig, axes = plt.subplots(2, ncol, figsize=(4.2 * ncol, 7.6), dpi=110, squeeze=False)
    cs, ws = sorted(set(var[:, 0].tolist())), sorted(set(var[:, 1].tolist()))
    dc = (cs[1] - cs[0]) / 2 if len(cs) > 1 else 5.0
    dw = (ws[1] - ws[0]) / 2 if len(ws) > 1 else 5.0
    for ax, c in zip(axes[0], classes, strict=False):
        grid = np.full((len(ws), len(cs)), np.nan)
        for j, (cc, ww) in enumerate(var):
            grid[ws.index(ww), cs.index(cc)] = three["rel_rms_pct"][c][k][j]
        im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis",
                       extent=(cs[0] - dc, cs[-1] + dc, ws[0] - dw, ws[-1] + dw))
        fig.colorbar(im, ax=ax, label="relative RMS of WV (%)")
        ax.plot(*var[head], "wo", mfc="none", ms=9)
        ax.set_xlabel(f"{name} centre (nm)")
        ax.set_ylabel(f"{name} width (nm)")
        ax.set_title(f"{c}: three-channel; two-channel {two['rel_rms_pct'][c][k]:.2f} %", fontsize=9)
    for ax in axes[0][len(classes):]:
        ax.axis("off")
    ax = axes[1][0]
    x = np.arange(len(classes))
    def per_class(d: dict, j: int | None) -> list[float]:
        return [d[c][k] if j is None else d[c][k][j] for c in classes]

    cases = [(label, per_class(three["rel_rms_pct"] if j is not None else two["rel_rms_pct"], j),
              per_class(three["rel_rms_pct_no_noise"] if j is not None else two["rel_rms_pct_no_noise"], j))
             for label, j in (("two-channel", None), (f"{name} {var[head, 0]:g}/{var[head, 1]:g}", head),
                              (f"{name} {var[best, 0]:g}/{var[best, 1]:g} (best)", best))]
    width = 0.8 / len(cases)
    for i, (label, noisy, quiet) in enumerate(cases):
        pos = x + (i - (len(cases) - 1) / 2) * width
        ax.bar(pos, noisy, width, color=f"C{i}", label=label)
        ax.bar(pos, quiet, width, color="none", edgecolor="k", hatch="//", lw=0.6)
    ax.axhspan(*PAPER_RMS_PCT, color="tab:red", alpha=0.12, label="paper (two-channel): 5–10 %")
    ax.set_xticks(x, classes)
    ax.set_ylabel("relative RMS of WV (%)")
    ax.set_title("two- vs three-channel, same pixels (hatched: without noise)", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[1][1]
    winter = data["winter"]
    tags = {"two": "two-channel", "three": f"{name} {var[head, 0]:g}/{var[head, 1]:g}",
            "three_best": f"{name} {var[best, 0]:g}/{var[best, 1]:g}"}
    bars = [(f"{tags[tag]}, {lut.split('_')[1]} LUT", winter[tag][lut]) for tag in winter
            for lut in ("midlatitude_winter", "midlatitude_summer")]
    width = 0.8 / len(bars)
    for i, (label, vals) in enumerate(bars):
        ax.bar(x + (i - (len(bars) - 1) / 2) * width, [vals[c] for c in classes], width, label=label)
    ax.set_xticks(x, classes)
    ax.set_ylabel("relative RMS of WV (%)")
    ax.set_title("winter scenes (MLW truth)", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[1][2]
    surf = data["continuum_error_pct"]
    names = list(surf["two"])
    xs = np.arange(len(names))
    ax.bar(xs - 0.2, [surf["two"][c] for c in names], 0.4, label="ρ(B8a) (two-channel)")
    ax.bar(xs + 0.2, [surf["three"][c] for c in names], 0.4, label=f"linear B8a–{name} (three-channel)")
    ax.set_xticks(xs, names)
    ax.set_ylabel("mean |ρ_continuum − ρ(B9)| / ρ(B9) (%)")
    ax.set_title(f"surface continuum error at B9 ({name} {var[head, 0]:g}/{var[head, 1]:g})", fontsize=9)
    ax.set_ylim(0, 1.3 * max([*surf["two"].values(), *surf["three"].values(), 1e-9]))
    ax.legend(fontsize=7, loc="upper left")
    for ax in axes[1][3:]:
        ax.axis("off")
    fig.tight_layout()
    return save_png(fig, path)
