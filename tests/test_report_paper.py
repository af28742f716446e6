"""The paper's values beside s2cl's: matching scenes to Tables 3-6, grids, ranks, the side-by-side plot."""

from __future__ import annotations

import numpy as np
import pandas as pd

from s2cl.sweep.report import heatmap_vs_paper, paper_comparison, paper_results, summarise


def _grid_frame(table: str, band: str, values: np.ndarray, others: dict[str, tuple[float, float]]) -> pd.DataFrame:
    paper = paper_results()[table]
    rows = []
    for i, c in enumerate(paper["centres"]):
        for j, w in enumerate(paper["widths"]):
            row = {f"{band}_centre_nm": float(c), f"{band}_width_nm": float(w), "rms": values[i, j],
                   "robust_rms": values[i, j], "failed_fraction": 0.0, "bound_fraction": 0.0}
            for b, (bc, bw) in others.items():
                row[f"{b}_centre_nm"], row[f"{b}_width_nm"] = bc, bw
            rows.append(row)
    df = pd.DataFrame(rows)
    df.insert(0, "config", np.arange(len(df)))
    return df


def test_table4_grid_beside_the_paper(tmp_path) -> None:
    paper = np.asarray(paper_results()["table4"]["rms"])
    ours = paper * 0.5 + 1.0  # same order of cells, other values
    df = _grid_frame("table4", "B4", ours, {"B5": (710, 20), "B6": (735, 30), "B7": (785, 30)})
    summary = summarise(df, {"scene": "table4-b4"})
    cmp = paper_comparison(df, summary)
    assert cmp is not None and cmp["table"] == "table4" and cmp["band"] == "B4"
    assert np.allclose(np.array(cmp["s2cl"], dtype=float), ours) and cmp["paper"] == paper.tolist()
    assert cmp["paper_best"]["bands"] == [680.0, 30.0] and cmp["paper_best"]["value"] == 4.7
    assert cmp["s2cl_best"]["bands"] == [680.0, 30.0] and cmp["cells"] == 70
    assert abs(cmp["rank_correlation"] - 1.0) < 1e-12
    png = heatmap_vs_paper(cmp, tmp_path / "vs.png")
    assert png.stat().st_size > 1000


def test_partial_grid_leaves_missing_cells_empty() -> None:
    paper = np.asarray(paper_results()["table6"]["omission_error"])
    df = _grid_frame("table6", "B12", paper, {"B11": (1610, 90)})
    df = df[df["B12_width_nm"] == 50.0]
    df = df.assign(omission_error_pct=df["rms"]).drop(columns=["rms", "robust_rms", "bound_fraction"])
    cmp = paper_comparison(df, summarise(df, {"scene": "table6-b12"}))
    assert cmp is not None and cmp["metric"] == "omission_error_pct" and cmp["cells"] == 8
    j = cmp["widths_nm"].index(50.0)
    assert all(row[k] is None for row in cmp["s2cl"] for k in range(len(row)) if k != j)
    assert cmp["s2cl_best"]["bands"] == [2190.0, 50.0]


def test_table3_rank_of_the_papers_best() -> None:
    bands = ["B4", "B5", "B6", "B8"]
    shapes = [[[675, 30], [710, 20], [735, 30], [832.5, 115]], [[665, 30], [705, 15], [740, 15], [832.5, 115]],
              [[680, 30], [715, 20], [735, 30], [832.5, 115]]]
    rows = []
    for k, (shape, rms) in enumerate(zip(shapes, (6.0, 7.0, 5.0), strict=True)):
        row = {"config": k, "rms": rms, "robust_rms": rms, "failed_fraction": 0.0, "bound_fraction": 0.01}
        for b, (c, w) in zip(bands, shape, strict=True):
            row[f"{b}_centre_nm"], row[f"{b}_width_nm"] = float(c), float(w)
        rows.append(row)
    df = pd.DataFrame(rows)
    reference = {**{f"{b}_centre_nm": c for b, (c, _) in zip(bands, shapes[1], strict=True)},
                 **{f"{b}_width_nm": w for b, (_, w) in zip(bands, shapes[1], strict=True)}, "rms": 7.0}
    cmp = paper_comparison(df, summarise(df, {"scene": "table3-lib1-b4568"}, reference))
    assert cmp is not None and cmp["table"] == "table3" and cmp["library"] == "Lib1"
    assert cmp["paper"]["rms_esa"] == 18.8 and cmp["paper"]["best"]["B8"] == [832, 115]
    assert cmp["s2cl"]["rms_esa"] == 7.0 and cmp["s2cl"]["rms_best"] == 5.0
    assert cmp["paper_best_in_s2cl"]["rms"] == 6.0 and cmp["paper_best_in_s2cl"]["rank"] == 2


def test_other_scenes_have_no_paper_values() -> None:
    df = _grid_frame("table4", "B4", np.ones((10, 7)), {})
    assert paper_comparison(df, summarise(df, {"scene": "my-scene"})) is None
    # a scene named after a table but sweeping other bands is not compared
    assert paper_comparison(df, summarise(df, {"scene": "table3-lib1-b4567"})) is None
