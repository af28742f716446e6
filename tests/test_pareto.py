"""The trade-off across applications (s2cl.sweep.pareto, pareto_plots, cli.pareto_table): the front against a
brute-force dominance test written here, hand-made fronts, requirements and the relative sum by hand, the noise
margin against within_noise's own intervals, the results file's ``pareto`` column, the figures' data and the
console table.

The realistic results file is a real sweep's (the gvmi test sweep of tests/sweep_fixtures.py, scored by the
float64 numpy twin through the engine) with a SYNTHETIC second application column added here: a multi-application
sweep is another helper's work; this tests the trade-off on the columns it will write."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from sweep_fixtures import gvmi_job, numpy_evaluator

from s2cl.sweep import pareto
from s2cl.sweep.pareto import (
    PARETO,
    add_pareto_column,
    best_configs,
    front,
    meets,
    noise_margin,
    pareto_record,
    relative_sum,
)

# -- brute force: every pair, as the rule is written ------------------------------------------------------------------


def brute_front(scores: np.ndarray, margins: np.ndarray) -> np.ndarray:
    """O(n²) pairs in plain Python: an application no design can score is left out; a design that cannot be
    scored on an application left in is off the front; else b is off when some a has a_k ≤ b_k everywhere and
    b_k − a_k > m_k somewhere."""
    n, k = scores.shape
    apps = [j for j in range(k) if any(np.isfinite(scores[i, j]) for i in range(n))]
    ok = [all(np.isfinite(scores[i, j]) for j in apps) for i in range(n)]
    out = []
    for b in range(n):
        beaten = not ok[b]
        for a in range(n):
            if beaten:
                break
            if a != b and ok[a]:
                no_worse = all(scores[a, j] <= scores[b, j] for j in apps)
                better = any(scores[b, j] - scores[a, j] > margins[j] for j in apps)
                beaten = no_worse and better
        out.append(not beaten)
    return np.array(out, dtype=bool)


def _random_case(rng: np.random.Generator, n: int, k: int, *, grid: bool) -> tuple[np.ndarray, np.ndarray]:
    """Scores (ties on an integer grid, or continuous), some NaN, sometimes a whole application NaN; margins 0 or
    not."""
    s = rng.integers(0, 6, (n, k)).astype(float) if grid else rng.random((n, k))
    s[rng.random((n, k)) < 0.08] = np.nan
    if rng.random() < 0.1:
        s[:, rng.integers(k)] = np.nan
    m = rng.choice([0.0, 0.0, 0.5, 1.0, 2.0], k) * (1.0 if grid else 0.1)
    return s, m


@pytest.mark.parametrize("grid", [True, False], ids=["ties", "continuous"])
def test_the_front_equals_brute_force_on_random_scores(grid: bool) -> None:
    rng = np.random.default_rng(35)
    for _ in range(120):
        s, m = _random_case(rng, int(rng.integers(1, 60)), int(rng.integers(1, 5)), grid=grid)
        np.testing.assert_array_equal(front(s, m), brute_front(s, m), err_msg=f"{s}\n{m}")


def test_the_blocks_and_the_screen_do_not_change_the_front(monkeypatch: pytest.MonkeyPatch) -> None:
    """Tiny blocks and screen: every path of the block-wise search runs on small inputs."""
    monkeypatch.setattr(pareto, "BLOCK", 7)
    monkeypatch.setattr(pareto, "FRONT_BLOCK", 3)
    monkeypatch.setattr(pareto, "SCREEN", 11)
    rng = np.random.default_rng(2)
    for _ in range(80):
        s, m = _random_case(rng, int(rng.integers(1, 90)), int(rng.integers(2, 6)), grid=bool(rng.integers(2)))
        np.testing.assert_array_equal(front(s, m), brute_front(s, m))


def test_a_larger_front_equals_the_pairwise_test() -> None:
    """3,000 designs × 3 applications, correlated, with margins: all pairs at once in numpy."""
    rng = np.random.default_rng(5)
    base = rng.random((3000, 1))
    s = 0.7 * base + 0.3 * rng.random((3000, 3))
    m = np.array([0.0, 0.01, 0.03])
    le = (s[:, None, :] <= s[None, :, :]).all(axis=2)
    gt = ((s[None, :, :] - s[:, None, :]) > m).any(axis=2)
    np.testing.assert_array_equal(front(s, m), ~(le & gt).any(axis=0))


# -- hand-made fronts -------------------------------------------------------------------------------------------------


def test_a_two_application_staircase() -> None:
    stairs = [(1, 5), (2, 4), (3, 3), (4, 2), (5, 1)]
    behind = [(3, 4), (5, 5), (2, 5), (4.5, 2.5)]
    s = np.array(stairs + behind, dtype=float)
    assert front(s).tolist() == [True] * 5 + [False] * 4


def test_exact_ties_are_both_on_or_both_off() -> None:
    s = np.array([[1, 2], [1, 2], [2, 3], [2, 3]], dtype=float)
    assert front(s).tolist() == [True, True, False, False]
    assert front(s, [5.0, 5.0]).tolist() == [True] * 4  # within the margin of [1, 2] everywhere


def test_a_design_within_the_margin_everywhere_stays_on_the_front() -> None:
    s = np.array([[1.00, 1.00], [1.05, 1.02], [1.30, 1.00]])
    assert front(s, [0.1, 0.1]).tolist() == [True, True, False]  # 1.30 − 1.00 > 0.1 on the first
    assert front(s, [0.0, 0.0]).tolist() == [True, False, False]
    # a margin of 0 on the second: 1.02 − 1.00 tells [1.05, 1.02] apart; 1.30 is within 0.5 and ties on the second
    assert front(s, [0.5, 0.0]).tolist() == [True, False, True]


def test_designs_that_cannot_be_scored_are_never_on_the_front() -> None:
    s = np.array([[0.1, np.nan], [1.0, 1.0], [2.0, 0.5], [np.nan, np.nan], [3.0, np.inf]])
    assert front(s).tolist() == [False, True, True, False, False]
    # every design NaN on the second application: it takes no part, the first alone decides (margin 0.5)
    s = np.array([[1.0, np.nan], [1.4, np.nan], [2.0, np.nan], [np.nan, np.nan]])
    assert front(s, [0.5, 0.0]).tolist() == [True, True, False, False]
    # no design can be scored on both: no front
    assert not front(np.array([[1.0, np.nan], [np.nan, 1.0]])).any()
    assert front(np.full((3, 2), np.nan)).tolist() == [True] * 3  # nothing told apart


def test_bad_margins_are_refused_in_one_line() -> None:
    with pytest.raises(ValueError, match=r"margins: need 2 finite values ≥ 0"):
        front(np.ones((3, 2)), [0.1, -1.0])
    with pytest.raises(ValueError, match=r"margins: need 2"):
        front(np.ones((3, 2)), [0.1])


def test_meets_and_the_relative_sum_by_hand() -> None:
    s = np.array([[4.0, 10.0], [6.0, 8.0], [5.0, np.nan], [np.nan, 12.0]])
    assert meets(s, [5.0, None]).tolist() == [True, False, True, False]
    assert meets(s, [None, 10.0]).tolist() == [True, True, False, False]
    assert meets(s, [None, None]).all()
    rel = relative_sum(s, [5.0, 10.0])
    np.testing.assert_allclose(rel[:2], [4 / 5 + 10 / 10, 6 / 5 + 8 / 10])
    assert np.isnan(rel[2:]).all()
    with pytest.raises(ValueError, match="reference: need a finite score > 0"):
        relative_sum(s, [5.0, 0.0])


def test_best_configs_are_distinct_best_first() -> None:
    configs = np.array([7, 3, 7, 1, 9, 3, 4])
    scores = np.array([0.5, 0.2, 0.1, np.nan, 0.3, 0.9, 0.2])
    assert best_configs(configs, scores, top=3).tolist() == [7, 3, 4]  # 7 by its 0.1, ties by config
    assert best_configs(configs, scores, top=10).tolist() == [7, 3, 4, 9]


# -- the record -------------------------------------------------------------------------------------------------------

APPS = [{"name": "chl", "kind": "igrm", "parameter": "cab", "metric": "rms", "units": "µg/cm²", "column": "chl_rms",
         "target": 3.0, "reference": 4.0},
        {"name": "water", "kind": "gvmi", "parameter": "ewt", "metric": "rms", "units": "g/cm²",
         "column": "water_rms", "target": None, "reference": 0.02}]


def _frame() -> pd.DataFrame:
    return pd.DataFrame({"config": [10, 11, 12, 13, 14], "B5_centre_nm": [700.0, 705, 710, 715, 720],
                         "B5_width_nm": [15.0] * 5, "chl_rms": [2.0, 2.9, 3.5, 5.0, np.nan],
                         "water_rms": [0.030, 0.0200, 0.010, 0.030, 0.001]})


def test_the_record_by_hand() -> None:
    rec = pareto_record(_frame(), APPS, [0.2, 0.0])
    # 13 is dominated by 10, 14 cannot be scored for chl; in order of relative sum: 12 (3.5/4 + 0.01/0.02 = 1.375),
    # 11 (0.725 + 1 = 1.725), 10 (0.5 + 1.5 = 2.0)
    assert rec["front"]["configs"] == [12, 11, 10]
    assert rec["front"]["count"] == 3 and rec["designs"] == 5
    first = rec["front"]["designs"][0]
    assert first["bands"] == {"B5": [710.0, 15.0]} and first["scores"] == {"chl": 3.5, "water": 0.01}
    assert first["relative_sum"] == pytest.approx(3.5 / 4 + 0.5)
    # within noise of the front's best: chl best 2.0, margin 0.2; water best 0.010, margin 0
    flags = {d["config"]: d["within_noise"] for d in rec["front"]["designs"]}
    assert flags == {11: {"chl": False, "water": False}, 10: {"chl": True, "water": False},
                     12: {"chl": False, "water": True}}
    assert rec["meeting"]["count"] == 2 and [d["config"] for d in rec["meeting"]["best"]] == [11, 10]
    assert [d["config"] for d in rec["relative_sum"]["top"]] == [12, 11, 10, 13]  # 14: NaN, not ranked
    assert rec["margins"]["chl"]["margin"] == 0.2 and "sensor's own bands" in rec["relative_sum"]["meaning"]


def test_the_record_without_a_reference_orders_by_the_first_application() -> None:
    apps = [APPS[0], {**APPS[1], "reference": None}]
    rec = pareto_record(_frame(), apps, [0.0, 0.0])
    assert rec["front"]["order"] == "chl score" and rec["front"]["configs"] == [10, 11, 12]
    assert rec["relative_sum"]["top"] == [] and rec["relative_sum"]["missing"] == ["water"]


def test_the_record_of_no_rankable_design_is_empty() -> None:
    rec = pareto_record(_frame().assign(full_fidelity=False), APPS, [0.0, 0.0], meta={})
    assert rec["front"] == {"count": 0, "configs": [], "order": "relative sum", "designs": []}
    assert rec["meeting"]["count"] == 0 and rec["relative_sum"]["top"] == []


def test_the_record_ranks_only_rankable_rows() -> None:
    df = _frame().assign(full_fidelity=[True, False, True, True, True])
    rec = pareto_record(df, APPS, [0.0, 0.0], meta={"underdetermined": "exclude"})
    assert 11 not in rec["front"]["configs"] and rec["designs"] == 4


# -- the noise margin -------------------------------------------------------------------------------------------------


def test_the_margin_is_the_median_reach_of_within_noises_intervals() -> None:
    """Against ``within_noise`` itself (the sweep's test of #1, on the same designs, replicates and seed): the
    median over the competitors of the difference minus the lower end of its interval."""
    from s2cl.sweep.engine import evaluate_chunk
    from s2cl.sweep.within_noise import within_noise

    job = gvmi_job(copies=6)
    rows = pd.DataFrame(evaluate_chunk(job, 0, job.n_configs, evaluator=numpy_evaluator(job)))
    top = rows.sort_values(["rms", "config"]).head(8).reset_index(drop=True)
    wn = within_noise(job, top, "rms", evaluator_of=numpy_evaluator, replicates=300)
    want = np.median([max(d["difference"] - d["interval"][0], 0.0) for d in wn["designs"][1:]
                      if d["interval"] != [0.0, 0.0]])
    configs = best_configs(rows["config"].to_numpy(), rows["rms"].to_numpy(), top=8)
    assert configs.tolist() == top["config"].tolist()
    got = noise_margin(job, configs, "rms", evaluator_of=numpy_evaluator, replicates=300)
    assert got["margin"] == pytest.approx(want, rel=1e-9) and got["margin"] > 0
    assert got["candidates"] == 8 and got["spectra"] == job.tables.n_spectra
    assert noise_margin(job, configs[:1], "rms")["margin"] == 0.0  # nothing to compare
    assert noise_margin(job, configs, "no_such_metric")["method"].startswith("none")


# -- the results file -------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def results_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real sweep's results.parquet (engine, numpy twin) with a synthetic second application's column."""
    from s2cl.sweep.engine import run_sweep

    folder = tmp_path_factory.mktemp("sweep")
    job = gvmi_job(chunk=7, copies=4)
    path = run_sweep(job, folder, evaluator=numpy_evaluator(job))
    table = pq.read_table(path)
    rms = table.column("rms").to_numpy()
    other = np.linspace(1.0, 0.0, len(rms)) * rms.max() + 0.1 * rms  # synthetic: worse where rms is better
    table = table.append_column("other_rms", pa.array(other)).replace_schema_metadata(table.schema.metadata)
    pq.write_table(table, path, row_group_size=5)  # several row groups
    return path


def test_the_pareto_column_round_trip(results_file: Path) -> None:
    before = pq.read_table(results_file)
    groups = [g.num_rows for g in (pq.ParquetFile(results_file).metadata.row_group(i)
                                   for i in range(pq.ParquetFile(results_file).metadata.num_row_groups))]
    apps = [{"name": "water", "metric": "rms", "units": "g/cm²", "column": "rms", "target": None, "reference": None},
            {"name": "other", "metric": "rms", "units": "", "column": "other_rms", "target": None, "reference": None}]
    df = before.to_pandas()
    rec = pareto_record(df, apps, [0.0, 0.0])
    configs = rec["front"]["configs"]
    assert 0 < len(configs) < len(df)
    for _ in range(2):  # a second time replaces the column
        add_pareto_column(results_file, configs)
        after = pq.read_table(results_file)
        assert after.column_names == [*before.column_names, PARETO]
        assert after.drop_columns([PARETO]).equals(before)
        assert after.schema.metadata == before.schema.metadata
        assert after.column(PARETO).to_pylist() == df["config"].isin(configs).tolist()
    f = pq.ParquetFile(results_file)
    assert [f.metadata.row_group(i).num_rows for i in range(f.metadata.num_row_groups)] == groups
    assert not list(results_file.parent.glob(".results.parquet.*"))  # no temporary file left
    from s2cl.sweep.report import load, summarise

    data, meta = load(results_file)  # still a sweep's results: it reads and ranks
    assert summarise(data, meta)["best"]["config"] == int(df.sort_values(["rms", "config"])["config"].iloc[0])


def test_read_scores_reads_what_the_record_needs(results_file: Path) -> None:
    apps = [{"name": "other", "column": "other_rms"}]
    df, meta = pareto.read_scores(results_file, apps)
    assert {"config", "other_rms", "B11_centre_nm", "B11_width_nm"} <= set(df.columns) and "r2" not in df.columns
    assert meta["analysis"] == "gvmi"


# -- figures ----------------------------------------------------------------------------------------------------------


def _line(ax, label: str):
    return next(line for line in ax.get_lines() if line.get_label() == label)


def test_the_two_application_figure_draws_the_front_and_the_own_bands(tmp_path: Path) -> None:
    from s2cl.sweep.pareto_plots import pareto_figure, pareto_plot

    s = _frame()[["chl_rms", "water_rms"]].to_numpy()
    on = front(s, [0.2, 0.0])
    fig = pareto_figure(s, on, APPS)
    ax = fig.axes[0]
    drawn = _line(ax, "front (3)").get_xydata()
    np.testing.assert_array_equal(drawn, [[2.0, 0.03], [2.9, 0.02], [3.5, 0.01]])  # joined by the first score
    np.testing.assert_array_equal(_line(ax, "the sensor's own bands").get_xydata(), [[4.0, 0.02]])
    assert _line(ax, "chl requirement 3").get_xdata()[0] == 3.0
    assert ax.get_xlabel() == "chl: rms (µg/cm²)" and ax.get_ylabel() == "water: rms (g/cm²)"
    faint = ax.collections[0].get_offsets()
    assert len(faint) == 1 and tuple(faint[0]) == (5.0, 0.03)  # 13 (14 cannot be scored: not drawn)
    path = pareto_plot(s, on, APPS, tmp_path / "pareto.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert pareto_plot(s[:, :1], on, APPS[:1], tmp_path / "one.png") is None and not (tmp_path / "one.png").exists()


def test_the_parallel_figure_draws_the_front_relative_to_the_own_bands(tmp_path: Path) -> None:
    from s2cl.sweep.pareto_plots import pareto_figure, pareto_plot

    apps = [*APPS, {"name": "minerals", "metric": "omission_error_pct", "units": "%", "column": "m",
                    "target": 20.0, "reference": None}]
    s = np.array([[2.0, 0.03, 10.0], [3.0, 0.01, 30.0], [4.0, 0.04, 40.0]])
    on = front(s)
    assert on.tolist() == [True, True, False]
    ax = pareto_figure(s, on, apps).axes[0]
    lines = [line.get_ydata() for line in ax.get_lines() if line.get_color() == "tab:red" and len(line.get_xdata())]
    # each score over its divisor: the own bands' 4 and 0.02, the front's best 10 for minerals
    np.testing.assert_allclose(lines, [[0.5, 1.5, 1.0], [0.75, 0.5, 3.0]])
    np.testing.assert_array_equal(_line(ax, "the sensor's own bands").get_xydata(), [[0, 1.0], [1, 1.0]])
    np.testing.assert_array_equal(_line(ax, "requirement").get_xydata(), [[0, 0.75], [2, 2.0]])
    assert "minerals:\nomission_error_pct (%)\n÷ front's best 10" in [t.get_text() for t in ax.get_xticklabels()]
    assert pareto_plot(s, on, apps, tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"


# -- the console ------------------------------------------------------------------------------------------------------


def test_the_console_table_lists_the_own_bands_then_the_front(capsys: pytest.CaptureFixture[str]) -> None:
    from s2cl.cli.pareto_table import front_headings, front_rows, print_pareto

    summary = {"scene": "two", "bands": ["B5"], "reference": {"bands": {"B5": [705.0, 15.0]}},
               "pareto": pareto_record(_frame(), APPS, [0.2, 0.0])}
    assert front_headings(summary) == ["", "B5 λ/Δλ", "chl_rms", "water_rms", "meets", "relative sum"]
    assert front_rows(summary) == [["own bands", "705/15", "4", "0.02", "no", "2"],
                                   ["#1", "710/15", "3.5", "0.01 ≈", "no", "1.38"],
                                   ["#2", "705/15", "2.9", "0.02", "yes", "1.73"],
                                   ["#3", "700/15", "2 ≈", "0.03", "yes", "2"]]
    print_pareto(summary)
    out = capsys.readouterr().out
    assert "Pareto front over 2 applications" in out and "2 designs meet every requirement (chl ≤ 3)" in out


# -- the margins of several applications, and everything in one call ----------------------------------------------


def test_noise_margins_map_joint_designs_onto_each_applications_own() -> None:
    """A joint space twice the application's (joint c is the application's c // 2, scored alike): the margin is the
    application's own, measured on its distinct designs."""
    from s2cl.sweep.engine import evaluate_chunk

    job = gvmi_job(copies=6)
    rows = pd.DataFrame(evaluate_chunk(job, 0, job.n_configs, evaluator=numpy_evaluator(job)))
    own = noise_margin(job, best_configs(rows["config"].to_numpy(), rows["rms"].to_numpy(), 6), "rms",
                       evaluator_of=numpy_evaluator, replicates=200)
    joint = pd.DataFrame({"config": np.arange(2 * len(rows)), "app_rms": np.repeat(rows["rms"].to_numpy(), 2)})
    app = {"name": "app", "metric": "rms", "column": "app_rms"}
    margins, records = pareto.noise_margins(joint, [app], [job], [lambda c: c // 2], top=6,
                                            evaluator_of=numpy_evaluator, replicates=200)
    assert margins.tolist() == [own["margin"]] and records[0]["candidates"] == 6


def test_trade_off_writes_the_record_the_column_and_the_figure(results_file: Path) -> None:
    from s2cl.sweep.trade_off import FIGURE, trade_off

    job = gvmi_job(chunk=7, copies=4)
    apps = [{"name": "water", "metric": "rms", "units": "g/cm²", "column": "rms", "target": None, "reference": 30.0},
            {"name": "other", "metric": "rms", "units": "", "column": "other_rms", "target": 40.0,
             "reference": 50.0}]
    record, written = trade_off(results_file, apps, [job, job], [None, None], evaluator_of=numpy_evaluator)
    assert written == [results_file, results_file.parent / FIGURE] and written[1].read_bytes()[:4] == b"\x89PNG"
    df = pq.read_table(results_file).to_pandas()
    assert sorted(df.loc[df[PARETO], "config"]) == sorted(record["front"]["configs"])
    want = front(df[["rms", "other_rms"]].to_numpy(), [record["margins"][n]["margin"] for n in ("water", "other")])
    assert df.loc[want, "config"].tolist() == sorted(record["front"]["configs"])
    assert record["margins"]["water"]["margin"] > 0 and record["margins"]["water"]["candidates"] == 20
