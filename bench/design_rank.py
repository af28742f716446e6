"""How far one sweep's ranking of designs is from another's: the numbers a band designer reads.

A sweep's results (``results.parquet`` as a DataFrame) rank the rankable configurations (those
:func:`s2cl.sweep.report.rankable` keeps, with a finite metric) by ``rms`` (µg/cm² for the IGRM
chlorophyll sweep), ties broken by configuration number as :mod:`s2cl.sweep.digest` breaks them. Two
sweeps are compared on the designs both contain, matched by their bands' centres and widths (nm), not by
configuration number, so that sweeps on different grids (``[sweep] step_nm``) compare too.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from s2cl.sweep.digest import bands_of
from s2cl.sweep.report import rankable

METRIC = "rms"
TOP = 10


def design_columns(df: pd.DataFrame) -> list[str]:
    """The columns that name a design: each band's centre and width (nm)."""
    return [f"{b}_{q}_nm" for b in bands_of(df.columns) for q in ("centre", "width")]


def ranked(df: pd.DataFrame, underdetermined: str = "exclude") -> pd.DataFrame:
    """The rankable designs, best first: design columns, ``config`` and the metric (NaN metrics dropped).

    Centres and widths are rounded to 1e-6 nm so that the same design on two grids is one key."""
    pool = rankable(df, {"underdetermined": underdetermined})
    cols = design_columns(df)
    out = pool[[*cols, "config", METRIC]].copy()
    out[cols] = out[cols].round(6)
    out = out[np.isfinite(out[METRIC].to_numpy(np.float64))]
    return out.sort_values([METRIC, "config"]).reset_index(drop=True)


def winner(r: pd.DataFrame) -> dict[str, list[float]]:
    """The best design of a ranking (``{band: [centre, width]}``, nm)."""
    row = r.iloc[0]
    return {b: [float(row[f"{b}_centre_nm"]), float(row[f"{b}_width_nm"])] for b in bands_of(r.columns)}


def compare(cheap: pd.DataFrame, ref: pd.DataFrame) -> dict[str, Any]:
    """``cheap``'s ranking against ``ref``'s (both from :func:`ranked`).

    Returns (JSON):

    - ``spearman``: Spearman rank correlation of the metric over the designs both rank (``compared``);
    - ``same_winner``: whether both rank the same design first;
    - ``winner_rank_in_reference``: 1 + the reference designs strictly better than ``cheap``'s winner
      (None when the reference does not rank that design);
    - ``regret``: the reference's metric of ``cheap``'s winner minus the reference's best (µg/cm²): what
      trusting the cheap run costs the design, judged by the reference;
    - ``max_abs_delta``: the largest |metric difference| over the common designs (µg/cm²), and
      ``max_abs_delta_top10`` over the reference's best ten of them;
    - ``top10_shared``: how many of the reference's best ten common designs are among ``cheap``'s best ten.
    """
    from scipy.stats import rankdata, spearmanr

    cols = design_columns(ref)
    both = cheap.merge(ref, on=cols, suffixes=("_cheap", "_ref"), validate="one_to_one")
    a, b = both[f"{METRIC}_cheap"].to_numpy(np.float64), both[f"{METRIC}_ref"].to_numpy(np.float64)
    if np.array_equal(rankdata(a), rankdata(b)):
        rho = 1.0  # the same order: exactly 1, not 1 − 1e-16 from the correlation's rounding
    elif len(both) > 1 and np.ptp(a) > 0 and np.ptp(b) > 0:
        rho = float(spearmanr(a, b).statistic)
    else:
        rho = float("nan")
    win = cheap.iloc[0]
    hit = ref.merge(cheap.iloc[:1][cols], on=cols)
    win_ref = float(hit[METRIC].iloc[0]) if len(hit) else float("nan")
    best_ref = float(ref[METRIC].iloc[0])
    top_cheap = set(both.nsmallest(TOP, f"{METRIC}_cheap", keep="first").index)
    top_ref = set(both.nsmallest(TOP, f"{METRIC}_ref", keep="first").index)
    top = both.loc[sorted(top_ref)]
    return {"compared": len(both), "ranked": len(cheap), "ranked_reference": len(ref), "spearman": rho,
            "one_minus_rho": 1.0 - rho, "same_winner": winner(cheap) == winner(ref),
            "winner": winner(cheap), "winner_rms": float(win[METRIC]),
            "winner_rank_in_reference": int(np.sum(ref[METRIC].to_numpy() < win_ref)) + 1 if len(hit) else None,
            "regret": win_ref - best_ref if len(hit) else None,
            "max_abs_delta": float(np.max(np.abs(a - b))) if len(both) else float("nan"),
            "max_abs_delta_top10": float(np.max(np.abs(top[f"{METRIC}_cheap"] - top[f"{METRIC}_ref"])))
            if len(top) else float("nan"),
            "top10_shared": len(top_cheap & top_ref)}
