"""Search instead of sweep: design tables (common random numbers, exact at every copy), the lattice, successive
halving against the exhaustive answer, refinement to a local optimum, resume and Dask."""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from sweep_fixtures import gvmi_job, numpy_evaluator

from s2cl.reference.sweep import evaluate
from s2cl.retrieve.metrics import regression_metrics
from s2cl.sweep.design_tables import copy_pixels, design_tables
from s2cl.sweep.engine import RESULTS, run_sweep
from s2cl.sweep.kernel import SweepKernel
from s2cl.sweep.lattice import Lattice
from s2cl.sweep.raw import variant_indices
from s2cl.sweep.search import SearchSettings, run_search


def _job(copies: int = 20, **search):
    job = gvmi_job(chunk=8, copies=copies, b11_max_width=150.0)
    return replace(job, search=SearchSettings(**search).record())


def test_schedule_multiplies_copies_by_the_inverse_of_keep() -> None:
    assert SearchSettings(keep=0.25).schedule(100) == [1, 4, 16, 64, 100]
    assert SearchSettings(keep=0.5).schedule(5) == [1, 2, 4, 5]
    assert SearchSettings().schedule(1) == [1]


def test_design_tables_score_each_design_as_the_sweep_does_on_every_copy_subset() -> None:
    """Common random numbers: a design on copies 0…k-1 sees exactly the pixels (and deviates) the exhaustive
    sweep gives those copies, whichever designs share its batch and in whichever order."""
    job = _job()
    t = job.tables
    full = evaluate(t, job.analysis, 0, t.n_configs)
    configs = np.array([11, 3, 27, 3, 0])
    designs = variant_indices(t, 0, t.n_configs)[configs]
    for copies in (1, 6, t.copies):
        sub = design_tables(t, designs, copies, rows=7)
        got = evaluate(sub, job.analysis, 0, len(configs))
        pix = copy_pixels(t, copies)
        assert np.array_equal(got.index, full.index[configs][:, pix])
        assert np.array_equal(got.status, full.status[configs][:, pix])
    again = evaluate(design_tables(t, designs[::-1], 6), job.analysis, 0, len(configs))
    assert np.array_equal(again.index[::-1], evaluate(design_tables(t, designs, 6), job.analysis, 0, 5).index)


def test_design_kernel_equals_the_sweep_kernel_on_every_pixel(rt) -> None:
    """At all copies a design list scored by the fused kernel is bit for bit the exhaustive sweep's score."""
    job = _job(copies=9)
    t = job.tables
    configs = np.array([5, 30, 2, 17])
    whole = SweepKernel(t, job.analysis, rt)
    want = whole.metrics(0, t.n_configs)
    kernel = SweepKernel(design_tables(t, variant_indices(t, 0, t.n_configs)[configs], t.copies, rows=5),
                         job.analysis, rt)
    got = kernel.metrics(0, 4)
    for k in ("rms", "r2", "n_valid", "failed_fraction"):
        assert np.array_equal(got[k], want[k][configs]), k
    kernel.load(design_tables(t, variant_indices(t, 0, t.n_configs)[configs[::-1]], t.copies, rows=5))
    assert np.array_equal(kernel.metrics(0, 4)["rms"], want["rms"][configs[::-1]])
    with pytest.raises(ValueError, match="another shape"):
        kernel.load(design_tables(t, variant_indices(t, 0, 3), 2, rows=5))


def test_lattice_neighbourhoods_stay_in_the_space() -> None:
    job = _job()
    lat = Lattice(job)
    everything = variant_indices(job.tables, 0, job.n_configs)
    assert np.array_equal(lat.configs(everything), np.arange(job.n_configs))
    inner = everything[job.n_configs // 2]
    joint = lat.joint(inner, 1)
    assert 1 < len(joint) <= 3 ** 4 and np.any((joint == inner).all(axis=1))
    box = lat.band_box(inner, 1, 2)
    assert np.all(box[:, 0] == inner[0]) and len(box) <= 25
    grid, stride = lat.coarse(10, np.random.default_rng(0))
    assert stride > 1 and 1 <= len(grid) <= 10


def test_joint_moves_split_centres_and_widths_above_max_joint(monkeypatch) -> None:
    """Above MAX_JOINT designs the joint move shifts all centres together and all widths together (2 · 3 ** bands)
    and every two bands in centre and width at once; below it, every band in both at once (3 ** (2 · bands))."""
    job = _job()
    lat = Lattice(job)
    inner = variant_indices(job.tables, job.n_configs // 2, job.n_configs // 2 + 1)[0]
    n = len(lat.slots)
    ci = np.array([sl.ci[v] for sl, v in zip(lat.slots, inner, strict=True)])
    wi = np.array([sl.wi[v] for sl, v in zip(lat.slots, inner, strict=True)])

    def shifts(designs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dc = np.stack([lat.slots[k].ci[designs[:, k]] - ci[k] for k in range(n)], axis=1)
        dw = np.stack([lat.slots[k].wi[designs[:, k]] - wi[k] for k in range(n)], axis=1)
        return dc, dw

    both = lat.joint_moves(inner, 1)
    dc, dw = shifts(both)
    assert ((dc != 0).any(axis=1) & (dw != 0).any(axis=1)).any()
    monkeypatch.setattr("s2cl.sweep.lattice.MAX_JOINT", 3 ** (2 * n) - 1)
    split = lat.joint_moves(inner, 1)
    centres, widths, pairs = (lat.joint(inner, 1, "centres"), lat.joint(inner, 1, "widths"), lat.pairs(inner, 1))
    dc, dw = shifts(np.concatenate([centres, widths]))
    assert not ((dc != 0).any(axis=1) & (dw != 0).any(axis=1)).any()
    assert len(centres) <= 3 ** n and (np.abs(dc).sum(axis=1) > 0).any() and (np.abs(dw).sum(axis=1) > 0).any()
    dc, dw = shifts(pairs)
    assert ((dc != 0) | (dw != 0)).sum(axis=1).max() <= 2 and len(pairs) <= 3 ** 4 * n * (n - 1) // 2
    assert {tuple(r) for r in np.concatenate([centres, widths, pairs])} == {tuple(r) for r in split}
    box = lat.neighbourhood(inner, 1)
    assert {tuple(r) for r in split} <= {tuple(r) for r in box}


def test_refined_search_with_split_joint_moves_ends_on_a_local_optimum(tmp_path, monkeypatch) -> None:
    """With the joint neighbourhood split (as for six bands and more) the refined search still ends on a design
    that no design of its (split) neighbourhood beats on every pixel."""
    monkeypatch.setattr("s2cl.sweep.lattice.MAX_JOINT", 10)
    monkeypatch.setattr("s2cl.sweep.search.MAX_JOINT", 10)
    job = _job(copies=6, start=100, finalists=4, radius=2)
    exhaustive = _scores_of_sweep(job, tmp_path / "sweep")
    _, record = run_search(job, tmp_path / "a", evaluator_of=numpy_evaluator)
    assert any(s["stage"].startswith("refine") for s in record["stages"])
    lat = Lattice(job)
    best = variant_indices(job.tables, record["best_config"], record["best_config"] + 1)[0]
    around = lat.configs(lat.neighbourhood(best, 2))
    assert exhaustive.loc[around, "rms"].min() == exhaustive.loc[record["best_config"], "rms"]


def _scores(out) -> pd.DataFrame:
    return pd.read_parquet(out / RESULTS)


def test_halving_finds_the_exhaustive_winner_with_fewer_pixel_evaluations(tmp_path) -> None:
    job = _job(finalists=4)
    exhaustive = _scores_of_sweep(job, tmp_path / "sweep")
    path, record = run_search(job, tmp_path / "search", evaluator_of=numpy_evaluator)
    df = pd.read_parquet(path)
    full = df[df["full_fidelity"]]
    assert record["best_config"] == int(exhaustive["rms"].idxmin())
    assert record["pixel_evaluations"] < 0.6 * record["exhaustive_pixel_evaluations"]
    rungs = record["stages"][0]["rungs"]
    assert [r["copies"] for r in rungs] == [1, 4, 16, 20] and rungs[0]["designs"] == job.n_configs
    assert len(full) == rungs[-1]["designs"] and (full["copies"] == job.tables.copies).all()
    assert np.array_equal(full["rms"].to_numpy(), exhaustive.loc[full["config"], "rms"].to_numpy())
    assert df["config"].is_unique and len(df) == job.n_configs
    assert record["evaluations"] >= len(df)


def _scores_of_sweep(job, out) -> pd.DataFrame:
    plain = replace(job, search=None)
    return pd.read_parquet(run_sweep(plain, out, evaluator=numpy_evaluator(plain))).set_index("config")


def test_refined_search_ends_on_a_local_optimum_and_repeats_from_its_seed(tmp_path) -> None:
    """A space above search_start starts from a coarse sub-grid and refines; no design of the final
    neighbourhood scores better on every pixel, and the same seed gives the same file."""
    job = _job(copies=6, start=100, finalists=4, radius=2)
    exhaustive = _scores_of_sweep(job, tmp_path / "sweep")
    path, record = run_search(job, tmp_path / "a", evaluator_of=numpy_evaluator)
    assert record["stages"][0]["stage"].startswith("start 1 of 4: sub-grid")
    lat = Lattice(job)
    best = variant_indices(job.tables, record["best_config"], record["best_config"] + 1)[0]
    around = lat.configs(lat.neighbourhood(best, 2))
    assert exhaustive.loc[around, "rms"].min() == exhaustive.loc[record["best_config"], "rms"]
    _, again = run_search(job, tmp_path / "b", evaluator_of=numpy_evaluator)
    assert again["best_config"] == record["best_config"] and again["evaluations"] == record["evaluations"]
    assert pd.read_parquet(tmp_path / "b" / RESULTS).equals(pd.read_parquet(path))


def test_search_resumes_from_its_chunk_files(tmp_path) -> None:
    job = _job(finalists=4)
    out = tmp_path / "out"
    path, record = run_search(job, out, evaluator_of=numpy_evaluator)
    first = pd.read_parquet(path)
    chunks = sorted((out / "chunks").glob("*.parquet"))
    assert len(chunks) >= 3
    for c in chunks[1:]:
        c.unlink()
    (out / RESULTS).unlink()
    calls: list[int] = []

    def counting(j):
        calls.append(j.n_configs)
        return numpy_evaluator(j)

    path, again = run_search(job, out, evaluator_of=counting)
    assert pd.read_parquet(path).equals(first)
    assert len(calls) == len(chunks) - 1 and again["evaluations"] == record["evaluations"]


@pytest.mark.slow
def test_search_on_dask_equals_single_process(tmp_path) -> None:
    pytest.importorskip("dask.distributed")
    job = _job(finalists=4)
    single, _ = run_search(job, tmp_path / "single", evaluator_of=numpy_evaluator)
    on_dask, _ = run_search(job, tmp_path / "dask", evaluator_of=numpy_evaluator, workers=2)
    assert pd.read_parquet(on_dask).equals(pd.read_parquet(single))


def test_metrics_of_a_copy_subset_are_the_metrics_of_those_pixels() -> None:
    job = _job()
    t = job.tables
    sub = design_tables(t, variant_indices(t, 4, 5), 3)
    raw = evaluate(sub, job.analysis, 0, 1)
    full = evaluate(t, job.analysis, 4, 5)
    pix = copy_pixels(t, 3)
    m = regression_metrics(full.index[:, pix], full.status[:, pix], full.bounds[:, pix], t.target[pix])
    assert regression_metrics(raw.index, raw.status, raw.bounds, sub.target)["rms"][0] == m["rms"][0]


def test_optimise_searches_a_scene_end_to_end(tmp_path) -> None:
    """`s2cl optimise` of a scene with search = "halving" on the device: the same winner and score as the sweep,
    the search's record in summary.json, the ranking from the designs scored on every pixel."""
    from sweep_fixtures import SMALL_SWEEP_TOML

    from s2cl.app.optimise import optimise
    from s2cl.scene.scene import Scene

    (tmp_path / "sweep.toml").write_text(SMALL_SWEEP_TOML.format(copies=8))
    (tmp_path / "search.toml").write_text(SMALL_SWEEP_TOML.format(copies=8).replace(
        "[sweep.ranges]", 'search = "halving"\nsearch_finalists = 2\n[sweep.ranges]'))
    swept = optimise(Scene.load(str(tmp_path / "sweep.toml")), tmp_path / "a")
    searched = optimise(Scene.load(str(tmp_path / "search.toml")), tmp_path / "b")
    record = searched.summary["search"]
    assert record["exhaustive_configurations"] == 6 and record["strategy"] == "halving"
    assert [r["copies"] for r in record["stages"][0]["rungs"]] == [1, 8]
    assert searched.best["bands"] == swept.best["bands"] and searched.best["rms"] == swept.best["rms"]
    table = searched.table()
    assert table["full_fidelity"].sum() == 2 == len(searched.summary["top"])
    assert record["pixel_evaluations"] < record["exhaustive_pixel_evaluations"]


def test_designs_beyond_the_kernels_numbers_score_through_their_own_tables(tmp_path, monkeypatch) -> None:
    """The reference row and the within-noise set come from the designs' own tables (config_tables, by which a
    design numbered beyond the kernel's 32-bit configuration numbers is scored: tests/test_designs.py), batched or
    one by one, with the same scores as through the sweep's."""
    from sweep_fixtures import SMALL_SWEEP_TOML

    from s2cl.app.optimise import optimise
    from s2cl.scene.scene import Scene
    from s2cl.sweep.design_tables import config_tables

    (tmp_path / "sweep.toml").write_text(SMALL_SWEEP_TOML.format(copies=4))
    scene = Scene.load(str(tmp_path / "sweep.toml"))
    plain = optimise(scene, tmp_path / "a").summary
    monkeypatch.setattr("s2cl.sweep.designs.DESIGN_BATCH", 1)  # every design in a batch of its own
    beyond = optimise(scene, tmp_path / "b", overwrite=True).summary
    assert beyond["reference"] == plain["reference"]

    def strip(w: dict) -> dict:
        return {k: v for k, v in w.items() if k != "seconds"}

    assert plain["within_noise"] is not None and strip(beyond["within_noise"]) == strip(plain["within_noise"])
    job = _job()
    t, configs = job.tables, np.array([17, 2, 9])
    got = evaluate(config_tables(t, configs), job.analysis, 0, len(configs))
    assert np.array_equal(got.index, evaluate(t, job.analysis, 0, t.n_configs).index[configs])


@pytest.mark.bench
def test_search_check_quick_on_table5(bench_path: None, tmp_path) -> None:
    """`python -m bench.search_check --quick --only table5-b11`: both runs, the exactness check, the row."""
    import json

    from bench.search_check import main, section

    assert main(["--quick", "--only", "table5-b11", "--out", str(tmp_path), "--no-docs"]) == 0
    data = json.loads((tmp_path / "search-check-quick-part.json").read_text())
    (row,) = data["sweeps"]
    assert row["configurations"] == 36 and row["rank"] >= 1 and row["gap"] >= 0
    assert 0 < row["pixel_evaluation_fraction"] <= 1 and row["metric"] == "rms"
    assert "table5-b11" in section(data) and len(data["load_average"]["before"]) == 3


def test_search_wide_checks_the_joint_step_at_once_or_centres_and_widths_apart(bench_path: None) -> None:
    """`python -m bench.search_wide --joint`: each band alone over ± 5 nm (11 × 11), then the ± 1 nm joint step
    as one sweep of 3²ⁿ designs (full) or two of 3ⁿ (split: centres with the widths fixed, widths with the
    centres fixed); a scene other than the default has its own results file."""
    import math

    from bench.search_wide import SCENE, check_sweeps, results_path

    best = {b: [600.0 + 40 * k, 20.0 + k] for k, b in enumerate(("B3", "B4", "B5", "B6", "B7", "B8a"))}

    def size(ranges: dict) -> int:
        return math.prod(len(r["centres"]) * len(r["widths"]) if "centres" in r else 1 for r in ranges.values())

    full, split = check_sweeps(best, "full"), check_sweeps(best, "split")
    assert [size(r) for r in full] == [121] * 6 + [3 ** 12]
    assert [size(r) for r in split] == [121] * 6 + [3 ** 6, 3 ** 6]
    assert all(r["widths"] == [best[b][1]] for b, r in split[6].items())
    assert all(r["centres"] == [best[b][0]] for b, r in split[7].items())
    assert results_path(SCENE).name == "search-wide.json"
    assert results_path("search-lib1-b3-b8a-1nm", "split").name == "search-wide-search-lib1-b3-b8a-1nm-split.json"


def test_a_design_without_a_valid_pixel_ranks_last(tmp_path: Path) -> None:
    """B11 variant 2 has no valid radiance (NaN: no pixel enters its regression, its RMS is NaN): the search's
    winner is the exhaustive sweep's best finite RMS, never the design without a score, which is left at the first
    rung."""
    job = _job(finalists=4)
    t = job.tables
    radiance = [r.copy() for r in t.radiance]
    radiance[1][2] = np.nan
    job = replace(job, tables=replace(t, radiance=tuple(radiance)))
    (nan_config,) = np.flatnonzero(variant_indices(t, 0, t.n_configs)[:, 1] == 2)
    exhaustive = _scores_of_sweep(job, tmp_path / "sweep")
    assert np.isnan(exhaustive.loc[nan_config, "rms"]) and exhaustive["rms"].notna().sum() == job.n_configs - 1
    path, record = run_search(job, tmp_path / "search", evaluator_of=numpy_evaluator)
    assert record["best_config"] == int(exhaustive["rms"].idxmin()) != nan_config
    row = pd.read_parquet(path).set_index("config").loc[nan_config]
    assert row["copies"] == 1 and np.isnan(row["rms"])


def test_refinement_moves_around_the_eight_best_of_more_finalists(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """With the default 16 finalists, each refinement stage scores the stage before it and every design one joint
    move (± step, every band at once) from each of its REFINE_AROUND = 8 best — the best by the exhaustive sweep's
    RMS, not any 8 of the 16 — with the step halved from the sub-grid's stride down to 1; the local stage scores
    the incumbent's neighbourhood at the search radius. MAX_JOINT at exactly 3 ** (2 · bands) still moves every
    band at once."""
    from s2cl.sweep import search as module

    job = _job(copies=6, start=40, radius=2, restarts=1)  # finalists: the default 16; one start
    assert SearchSettings().finalists == 16 > module.REFINE_AROUND == 8
    exhaustive = _scores_of_sweep(job, tmp_path / "sweep")["rms"]
    lat = Lattice(job)
    monkeypatch.setattr(module, "MAX_JOINT", 3 ** (2 * len(lat.slots)))
    calls: list[tuple[str, set[int], list[int]]] = []
    real_halve, real_full = module.Halving.halve, module.Halving.full

    def spy(real: Callable[..., tuple[np.ndarray, np.ndarray]]) -> Callable[..., tuple[np.ndarray, np.ndarray]]:
        def method(self: Any, pool: np.ndarray, stage: str) -> tuple[np.ndarray, np.ndarray]:
            best, scores = real(self, pool, stage)
            calls.append((stage, set(lat.configs(pool).tolist()), lat.configs(best).tolist()))
            return best, scores
        return method

    monkeypatch.setattr(module.Halving, "halve", spy(real_halve))
    monkeypatch.setattr(module.Halving, "full", spy(real_full))
    _, record = run_search(job, tmp_path / "search", evaluator_of=numpy_evaluator)
    stages = [c[0] for c in calls]
    assert stages[:3] == ["start: sub-grid every 5 steps", "refine ± 2 steps", "refine ± 1 steps"]
    lines = stages.index("each band alone over its whole range")
    assert all(s.startswith("local") for s in stages[3:lines]) and lines > 3
    designs = variant_indices(job.tables, 0, job.n_configs)
    for (_, _, before), (_, pool, _), step in zip(calls[:2], calls[1:3], (2, 1), strict=True):
        assert len(before) == len(set(before)) >= 16  # 16 distinct finalists
        eight = sorted(before, key=lambda c: (exhaustive[c], c))[:8]
        moved = {c for e in eight for c in lat.configs(lat.joint(designs[e], step)).tolist()}
        assert pool == set(before) | moved
    for (_, _, before), (_, pool, _) in itertools.pairwise(calls[2:lines]):
        incumbent = before[0]
        around = lat.neighbourhood(designs[incumbent], 2)
        assert pool == {incumbent, *lat.configs(around).tolist()}
    assert calls[lines - 1][2][0] == calls[lines - 2][2][0]
    # then every design that moves one band of the local optimum anywhere in its range: B8 is fixed, so B11's 641
    incumbent = calls[lines - 1][2][0]
    assert calls[lines][1] == set(range(job.n_configs)) and len(designs) == 641
    assert stages[lines + 1] == "refine ± 1 steps"
    final = record["best_config"]
    assert exhaustive[final] <= exhaustive[incumbent] and stages[-1].startswith(("refine", "local"))


def test_the_record_counts_what_the_chunk_files_hold(tmp_path: Path) -> None:
    """The search's evaluations and pixel-evaluations are those of its chunk files (each row a design scored on
    ``copies`` copies of every spectrum); the exhaustive count is every design on every pixel; results.parquet
    says how many pixels each design was scored on. Rung sizes: each rung keeps max(finalists, ⌈keep · n⌉), and
    designs no more than the finalists go straight to every copy."""
    job = _job(finalists=4)
    t = job.tables
    path, record = run_search(job, tmp_path / "s", evaluator_of=numpy_evaluator)
    chunks = pd.concat([pd.read_parquet(p) for p in sorted((tmp_path / "s" / "chunks").glob("*.parquet"))])
    assert record["evaluations"] == len(chunks)
    assert record["pixel_evaluations"] == int(chunks["copies"].sum()) * t.n_spectra
    assert record["exhaustive_pixel_evaluations"] == job.n_configs * t.n_spectra * t.copies == 641 * 246 * 20
    assert record["pixel_evaluation_fraction"] == record["pixel_evaluations"] / (641 * 246 * 20)
    df = pd.read_parquet(path)
    assert (df["pixels"] == df["copies"] * 246).all()
    assert df["config"].tolist() == sorted(set(chunks["config"]))  # each design once, in configuration order
    assert [(r["copies"], r["designs"]) for r in record["stages"][0]["rungs"]] == [(1, 641), (4, 161), (16, 41),
                                                                                    (20, 11)]
    _, record = run_search(_job(finalists=161), tmp_path / "161", evaluator_of=numpy_evaluator)
    assert [(r["copies"], r["designs"]) for r in record["stages"][0]["rungs"]] == [(1, 641), (20, 161)]


def test_a_scenes_search_keys_reach_the_settings() -> None:
    """Every [sweep] search key reaches its own setting (values all different, so a swap shows)."""
    from sweep_fixtures import gvmi_scene

    from s2cl.scene.scene import Scene

    raw = gvmi_scene().spec.model_dump(exclude_none=True)
    keys = {"search": "halving", "search_keep": 0.5, "search_finalists": 7, "search_start": 300, "search_radius": 3,
            "search_seed": 11, "search_restarts": 2}
    raw["sweep"].update(keys)
    settings = SearchSettings.of_spec(Scene.from_dict(raw).spec.sweep)
    assert settings is not None and settings.record() == {"strategy": "halving", "keep": 0.5, "finalists": 7,
                                                          "start": 300, "radius": 3, "seed": 11,
                                                          "restarts": 2}
    assert SearchSettings.of_spec(gvmi_scene().spec.sweep) is None  # exhaustive


@pytest.mark.parametrize("policy", ["exclude", "keep"])
def test_a_rung_ranks_nan_scores_and_left_out_designs_last(tmp_path: Path, policy: str) -> None:
    """What a rung ranks by, from a batch's rows: the metric; +inf for a NaN score, and for a design the analysis
    cannot fit when the ranking leaves those out (sweep.underdetermined = "exclude"), as digest.rankable_rows does."""
    from s2cl.sweep.search import Scorer, _local

    job = replace(_job(), underdetermined=policy)
    scorer = Scorer(job, tmp_path, _local(None, numpy_evaluator), Lattice(job))
    scorer.memo[4] = {}
    rows = {"config": np.array([3, 1, 2, 0]), "underdetermined": np.array([False, True, False, True]),
            "rms": np.array([2.0, 1.0, np.nan, np.nan]), "r2": np.array([0.5, 0.9, np.nan, np.nan])}
    scorer._remember(rows, 4)
    left_out = np.inf if policy == "exclude" else 1.0
    assert scorer.memo == {4: {3: 2.0, 1: left_out, 2: np.inf, 0: np.inf}}


def test_a_classification_search_ranks_by_omission_error(tmp_path: Path) -> None:
    """A SAM search (minerals, B12 over 5 centres × 3 widths) ranks its rungs by the mean omission error, the
    sweep's metric for classes: the exhaustive sweep's best, scored as the sweep scores it."""
    from s2cl.app.plan import plan_sweep
    from s2cl.scene.scene import Scene

    scene = Scene.from_dict({
        "scene": {"name": "search-sam"}, "sensor": {"bands": ["B11", "B12"]},
        "surface": {"library": "builtin:minerals-swir", "quantity": "reflectance", "copies": 6},
        "effects": {"atmosphere": True, "correct": True, "seed": 3}, "grid": {"start_nm": 1500, "stop_nm": 2500},
        "sweep": {"bands": ["B11", "B12"], "ranges": {"B11": {"centre": 1610, "width": 90}, "B12": {
            "centres": [2150, 2170, 2190, 2210, 2230], "widths": [60, 120, 180]}}},
        "analysis": {"kind": "sam"}})
    job = replace(plan_sweep(scene), search=SearchSettings(finalists=2).record())
    exhaustive = _scores_of_sweep(job, tmp_path / "sweep")["omission_error_pct"]
    path, record = run_search(job, tmp_path / "search", evaluator_of=numpy_evaluator)
    assert record["best_config"] == exhaustive.idxmin() and (exhaustive > exhaustive.min()).sum() == 14  # one best
    assert [(r["copies"], r["designs"]) for r in record["stages"][0]["rungs"]] == [(1, 15), (4, 4), (6, 2)]
    full = pd.read_parquet(path).query("full_fidelity").set_index("config")["omission_error_pct"]
    assert full.to_dict() == exhaustive[full.index].to_dict()


# -- restarts and recombination (spaces above search_start) ------------------------------------------------

def _grid_lattice(n_bands: int, n_c: int, n_w: int) -> Lattice:
    """A lattice of ``n_bands`` slots, each every (centre, width) of an ``n_c`` × ``n_w`` grid (no job needed)."""
    from s2cl.sweep.lattice import SlotLattice

    lat = Lattice.__new__(Lattice)
    c, w = np.meshgrid(np.arange(n_c), np.arange(n_w), indexing="ij")
    lat.slots = [SlotLattice.of(c.ravel().astype(float), w.ravel().astype(float)) for _ in range(n_bands)]
    lat.counts = np.full(n_bands, n_c * n_w, dtype=np.int64)
    lat.strides = np.array([(n_c * n_w) ** (n_bands - 1 - k) for k in range(n_bands)], dtype=np.int64)
    return lat


DEEP = 0.15  # the deep basin's width (the grid's span is 1): a couple of steps


class _Landscape:
    """A scorer twin on a grid lattice: per band a wide shallow basin and a narrow deep one (random places), a
    coupling of neighbouring bands' centres; on fewer than all copies plus noise that shrinks as 1/√copies, the same
    for a design at the same copies (common random numbers). Lower is better."""

    def __init__(self, lattice: Lattice, n_c: int, n_w: int, copies: int, seed: int):
        self.lattice, self.size, self.copies = lattice, np.array([n_c - 1, n_w - 1], dtype=float), copies
        rng = np.random.default_rng(seed)
        self.shallow, self.deep = rng.uniform(0.1, 0.9, (2, len(lattice.slots), 2))
        self.n = int(np.prod(lattice.counts))
        self.noise: dict[int, np.ndarray] = {}

    def true(self, designs: np.ndarray) -> np.ndarray:
        x = np.stack([np.stack([sl.ci[designs[:, k]], sl.wi[designs[:, k]]], -1) / self.size
                      for k, sl in enumerate(self.lattice.slots)], 1)

        def basin(at: np.ndarray, sigma: float) -> np.ndarray:
            return np.exp(-((x - at) ** 2).sum(-1) / sigma ** 2)

        return -(0.6 * basin(self.shallow, 0.3) + basin(self.deep, DEEP)).sum(1) \
            + 0.3 * np.abs(np.diff(x[..., 0], axis=1)).sum(1)

    def score(self, designs: np.ndarray, copies: int) -> np.ndarray:
        if copies == self.copies:
            return self.true(designs)
        if copies not in self.noise:
            self.noise[copies] = np.random.default_rng(copies).standard_normal(self.n)
        return self.true(designs) + 0.3 * self.noise[copies][self.lattice.configs(designs)] / np.sqrt(copies)


@pytest.mark.parametrize("split", [False, True])
def test_restarts_with_recombination_end_on_the_brute_force_optimum_from_every_seed(monkeypatch, split) -> None:
    """Three bands of 12 centres × 6 widths (373,248 designs), two basins per band: from seeds 0-4 the search with four
    starts ends on the brute-force optimum of the landscape, for three landscapes (moving every band at once, or,
    as for six bands, the joint step split)."""
    from s2cl.sweep.search import Halving

    if split:
        monkeypatch.setattr("s2cl.sweep.lattice.MAX_JOINT", 10)
        monkeypatch.setattr("s2cl.sweep.search.MAX_JOINT", 10)
    lat = _grid_lattice(3, 12, 6)
    every = np.array(list(itertools.product(range(72), repeat=3)))
    for landscape in range(3):
        land = _Landscape(lat, 12, 6, 20, landscape)
        truth = land.true(every)
        optimum = int(np.argmin(truth))
        assert (truth == truth[optimum]).sum() == 1 and lat.configs(every[optimum][None])[0] == optimum
        for seed in range(5):
            scorer = type("S", (), {"lattice": lat, "score": staticmethod(land.score)})()
            halving = Halving(SearchSettings(start=300, finalists=4, radius=2, seed=seed, restarts=4), scorer, 20)
            assert int(lat.configs(halving.run()[None])[0]) == optimum, (landscape, seed)
            assert sum(s["stage"].startswith("start") for s in halving.stages) == 4
            assert any(s["stage"].startswith("recombine") for s in halving.stages)


def test_lattice_crosses_designs_band_by_band_and_shifts_its_sub_grids() -> None:
    lat = _grid_lattice(3, 12, 6)
    designs = np.array([[1, 5, 7], [1, 9, 8], [4, 5, 70]])
    want = {(a, b, c) for a in (1, 4) for b in (5, 9) for c in (7, 8, 70)}
    got = lat.crossed(designs)
    assert len(got) == len(want) == 12 and {tuple(r) for r in got.tolist()} == want
    grid, stride, offsets = lat.coarse_offsets(300, np.random.default_rng(3))
    assert len(grid) <= 300 and stride > 1
    for shift in (0, 1, stride // 2):
        moved = lat.shifted(offsets, stride, shift)
        sub = lat.sub_grid(stride, moved)
        for k, sl in enumerate(lat.slots):
            c0, w0 = offsets[k]
            assert moved[k] == ((c0 + shift) % stride, (w0 + shift) % stride)
            assert set(sl.ci[sub[:, k]] % stride) == {(c0 + shift) % stride}
            assert set(sl.wi[sub[:, k]] % stride) == {(w0 + shift) % stride}
    assert np.array_equal(lat.sub_grid(stride, offsets), grid)


def test_the_recombination_scores_every_cross_of_the_starts_best_designs(tmp_path, monkeypatch) -> None:
    """On a real job (the numpy twin) with two starts: the recombination halves every design that takes each band
    from one of the starts' best designs, with all their finalists; every design scored on every pixel carries the
    exhaustive sweep's score bit for bit, and the search ends on a local optimum of its neighbourhood."""
    from s2cl.sweep import search as module

    job = _job(copies=6, start=100, finalists=4, radius=2, restarts=2)
    exhaustive = _scores_of_sweep(job, tmp_path / "sweep")
    lat = Lattice(job)
    calls: list[tuple[str, np.ndarray, np.ndarray]] = []
    real = module.Halving.halve

    def spy(self: Any, pool: np.ndarray, stage: str) -> tuple[np.ndarray, np.ndarray]:
        best, scores = real(self, pool, stage)
        calls.append((stage, pool, best))
        return best, scores

    monkeypatch.setattr(module.Halving, "halve", spy)
    path, record = run_search(job, tmp_path / "search", evaluator_of=numpy_evaluator)
    ends = [i for i, c in enumerate(calls) if c[0].startswith("start 2")]
    (second,) = ends
    first_best, second_best = calls[second - 1][2], calls[[c[0] for c in calls].index("recombine the best of 2 "
                                                                                       "starts band by band") - 1][2]
    (pool,) = [c[1] for c in calls if c[0].startswith("recombine")]
    crosses = {tuple(int(x) for x in (a, b)) for a in {first_best[0][0], second_best[0][0]}
               for b in {first_best[0][1], second_best[0][1]}}
    pooled = {tuple(r) for r in pool.tolist()}
    assert crosses <= pooled and {tuple(r) for r in np.concatenate([first_best, second_best]).tolist()} <= pooled
    df = pd.read_parquet(path)
    full = df[df["full_fidelity"]]
    assert np.array_equal(full["rms"].to_numpy(), exhaustive.loc[full["config"], "rms"].to_numpy())
    best = variant_indices(job.tables, record["best_config"], record["best_config"] + 1)[0]
    around = lat.configs(lat.neighbourhood(best, 2))
    assert exhaustive.loc[around, "rms"].min() == exhaustive.loc[record["best_config"], "rms"]


def test_a_killed_search_with_restarts_resumes_from_its_chunk_files(tmp_path) -> None:
    """A refined search with several starts, half its chunk files lost: run again, it computes only those and writes
    the same results."""
    job = _job(copies=6, start=100, finalists=4, radius=2, restarts=3)
    out = tmp_path / "out"
    path, record = run_search(job, out, evaluator_of=numpy_evaluator)
    first = pd.read_parquet(path)
    chunks = sorted((out / "chunks").glob("*.parquet"))
    lost = chunks[1::2]
    for c in lost:
        c.unlink()
    (out / RESULTS).unlink()
    calls: list[int] = []

    def counting(j):
        calls.append(j.n_configs)
        return numpy_evaluator(j)

    path, again = run_search(job, out, evaluator_of=counting)
    assert pd.read_parquet(path).equals(first) and len(calls) == len(lost)
    assert again["evaluations"] == record["evaluations"] and again["best_config"] == record["best_config"]


def test_search_wide_numbers_a_design_by_its_bands_and_shows_the_within_noise_cell(bench_path: None) -> None:
    """`python -m bench.search_wide --add-within-noise`: a design given as each band's (centre, width) gets its
    configuration number (the exhaustive sweep's, via variant_indices); the table's cell says the best, or yes/no with
    the interval of the difference to the best."""
    from bench.search_wide import _within, config_of

    job = _job()
    t = job.tables
    for config in (0, 123, job.n_configs - 1):
        v = variant_indices(t, config, config + 1)[0]
        bands = {b: [float(t.centre[k][v[k]]), float(t.width[k][v[k]])] for k, b in enumerate(t.bands)}
        assert config_of(job, bands) == config
    assert _within(None) == "–" and _within({"best": True}) == "the best"
    assert _within({"best": False, "within": True, "interval": [-0.02, 0.32]}) == "yes (-0.020 to +0.320)"
    assert _within({"best": False, "within": False, "interval": [0.022, 0.356]}) == "no (+0.022 to +0.356)"
