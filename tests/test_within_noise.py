"""Within noise of #1 (s2cl.sweep.within_noise): the per-spectrum statistics give the sweep's own scores, the
bootstrap equals resampling the pixels directly in numpy, and the verdicts have known answers — a design that
differs from the best only in its noise draws is within noise, a far worse one is not — on every analysis
family and through ``s2cl optimise``."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from sweep_fixtures import SMALL_SWEEP_TOML, numpy_evaluator

from s2cl.reference.sweep import NumpyEvaluator
from s2cl.retrieve.metric import metric_scored_by
from s2cl.retrieve.metrics import classification_metrics, regression_metrics
from s2cl.retrieve.spectrum_stats import (
    classification_score,
    classification_stats,
    regression_score,
    regression_stats,
)
from s2cl.status import Status
from s2cl.sweep.engine import SweepJob
from s2cl.sweep.within_noise import (
    kept_within_noise,
    mark_top,
    paired_bootstrap,
    resample_indices,
    spectrum_stats,
    within_column,
    within_noise,
    within_pairs,
)

REGRESS = (int(Status.OK), int(Status.STALLED), int(Status.ITERATION_LIMIT))


def _regression_case(rng: np.random.Generator, n_spectra: int = 40, copies: int = 5,
                     noise: tuple[float, ...] = (0.5, 0.5, 2.0)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Index ``(designs, pixels)`` of a curved relation to the target plus per-spectrum model error (common to
    the designs) and per-pixel noise of each design's standard deviation; statuses; the target per pixel."""
    y = np.repeat(rng.uniform(5, 80, n_spectra), copies)
    model = np.repeat(rng.normal(0, 1.0, n_spectra), copies)
    base = 700 + 0.4 * y - 0.002 * y**2 + model
    index = np.stack([base + rng.normal(0, s, y.size) for s in noise])
    status = np.zeros(index.shape, np.uint8)
    return index, status, y


def test_regression_statistics_give_the_sweeps_rms() -> None:
    """Summed over all spectra, the statistics give regression_metrics' RMS (the number the sweep ranks by),
    with pixels left out of the regression, a non-finite index, a constant index and a design without pixels."""
    rng = np.random.default_rng(1)
    index, status, y = _regression_case(rng, noise=(0.5, 3.0, 0.5, 0.5, 0.5))
    status[0, ::7] = Status.DEGENERATE
    status[1, ::5] = Status.STALLED
    index[2, ::11] = np.nan
    index[3] = 712.5  # constant: the RMS about the mean
    status[4] = Status.INVALID  # nothing to regress: NaN
    want = regression_metrics(index, status, np.zeros(index.shape, np.uint8), y, regress=REGRESS)["rms"]
    got = regression_score(regression_stats(index, status, y, 5, REGRESS).sum(axis=1))
    np.testing.assert_allclose(got[:4], want[:4], rtol=1e-10)
    assert np.isnan(got[4]) and np.isnan(want[4])
    assert got[3] == pytest.approx(np.std(y), rel=1e-10)


def _classification_case(rng: np.random.Generator, n_spectra: int = 45, copies: int = 4, n_classes: int = 3,
                         error: tuple[float, ...] = (0.2, 0.2, 0.6)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predicted classes of designs misclassifying each pixel with probability ``error`` (some unclassified);
    per-spectrum difficulty common to the designs."""
    truth = np.repeat(np.arange(n_spectra) % n_classes, copies)
    hard = np.repeat(rng.uniform(0.5, 1.5, n_spectra), copies)
    pred, status = [], []
    for e in error:
        wrong = rng.random(truth.size) < np.clip(e * hard, 0, 1)
        p = np.where(wrong, (truth + rng.integers(1, n_classes, truth.size)) % n_classes, truth)
        s = np.where(wrong & (rng.random(truth.size) < 0.2), Status.UNCLASSIFIED, Status.OK).astype(np.uint8)
        pred.append(np.where(s == Status.OK, p, n_classes).astype(np.float64))
        status.append(s)
    return np.stack(pred), np.stack(status), truth


def test_classification_statistics_give_the_sweeps_omission_error() -> None:
    rng = np.random.default_rng(2)
    pred, status, truth = _classification_case(rng)
    want = classification_metrics(pred.astype(np.int64), status, truth, 3)["omission_error_pct"]
    got = classification_score(classification_stats(pred, status, truth, 4, 3).sum(axis=1))
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_the_bootstrap_equals_resampling_the_pixels_directly() -> None:
    """Each replicate computed from scratch: the drawn spectra's pixels gathered and the regression refitted by
    regression_metrics; its difference to the best, the percentile interval and the share as good."""
    rng = np.random.default_rng(3)
    copies, n_spectra, replicates = 5, 40, 300
    index, status, y = _regression_case(rng, n_spectra, copies)
    boot = paired_bootstrap(regression_stats(index, status, y, copies, REGRESS), regression_score, 0,
                            replicates=replicates, seed=11)
    draws = resample_indices(n_spectra, replicates, 11)
    diff = np.empty((replicates, 3))
    for r, spectra in enumerate(draws):
        pixels = (spectra[:, None] * copies + np.arange(copies)).ravel()
        rms = regression_metrics(index[:, pixels], status[:, pixels], np.zeros((3, pixels.size), np.uint8), y[pixels],
                                 regress=REGRESS)["rms"]
        diff[r] = rms - rms[0]
    low, high = np.quantile(diff, [0.025, 0.975], axis=0)
    np.testing.assert_allclose(boot.low, low, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(boot.high, high, rtol=1e-8, atol=1e-10)
    np.testing.assert_array_equal(boot.as_good[1:], np.mean(diff[:, 1:] <= 0, axis=0))
    np.testing.assert_array_equal(boot.within, low <= 0)


def test_the_stratified_bootstrap_equals_resampling_each_class_directly() -> None:
    rng = np.random.default_rng(4)
    copies, n_spectra, replicates = 4, 45, 300
    pred, status, truth = _classification_case(rng, n_spectra, copies)
    strata = truth[::copies]
    boot = paired_bootstrap(classification_stats(pred, status, truth, copies, 3), classification_score, 1,
                            replicates=replicates, seed=12, strata=strata)
    draws = resample_indices(n_spectra, replicates, 12, strata)
    assert all((strata[d] == strata).all() for d in draws)  # each class keeps its spectra and its size
    diff = np.empty((replicates, 3))
    for r, spectra in enumerate(draws):
        pixels = (spectra[:, None] * copies + np.arange(copies)).ravel()
        om = classification_metrics(pred[:, pixels].astype(np.int64), status[:, pixels], truth[pixels],
                                    3)["omission_error_pct"]
        diff[r] = om - om[1]
    low, high = np.quantile(diff, [0.025, 0.975], axis=0)
    np.testing.assert_allclose(boot.low, low, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(boot.high, high, rtol=1e-10, atol=1e-10)


def test_known_answers_noise_draws_alone_are_within_noise_a_far_worse_design_is_not() -> None:
    """Two designs alike but for their noise draws, in 200 independent libraries: the 95 % test tells them apart
    in about 5 % of them (at most 10 %: over three binomial standard deviations); a design with four times the
    noise is told apart in every one."""
    rng = np.random.default_rng(5)
    trials, apart, far = 200, 0, 0
    for t in range(trials):
        index, status, y = _regression_case(rng, n_spectra=80, copies=4)
        stats = regression_stats(index, status, y, 4, REGRESS)
        best = int(np.argmin(regression_score(stats[:2].sum(axis=1))))  # the luckier of the two alike designs
        boot = paired_bootstrap(stats, regression_score, best, replicates=400, seed=t)
        apart += not boot.within[1 - best]
        far += not boot.within[2]
    assert apart / trials <= 0.10
    assert far == trials


def test_same_seed_same_set() -> None:
    rng = np.random.default_rng(6)
    index, status, y = _regression_case(rng)
    stats = regression_stats(index, status, y, 5, REGRESS)
    a, b = (paired_bootstrap(stats, regression_score, 0, replicates=200, seed=9) for _ in range(2))
    np.testing.assert_array_equal(a.low, b.low)
    np.testing.assert_array_equal(a.within, b.within)


# -- every analysis family, on a real sweep's tables (the float64 numpy twin: no device needed) --------------

ESA = {"B4": (665, 30), "B5": (705, 15), "B6": (740, 15), "B7": (783, 20), "B8a": (865, 20), "B11": (1610, 90),
       "B12": (2190, 180)}
FAMILY_CASES = {
    "igrm": ({"library": "builtin:lib1", "copies": 4}, ["B4", "B5", "B6", "B7"], {"kind": "igrm", "parameter": "cab"},
             "B4", {"centres": [665, 680], "widths": [20, 30]}),
    "gvmi": ({"library": "builtin:leaf-water", "copies": 4}, ["B8a", "B11"],
             {"kind": "gvmi", "parameter": "ewt", "nir": "B8a", "swir": "B11"}, "B11",
             {"centres": [1610, 1650], "widths": [50, 90]}),
    "sam": ({"library": "builtin:minerals-swir", "copies": 6}, ["B11", "B12"], {"kind": "sam"}, "B12",
            {"centres": [2190, 2210], "widths": [60, 180]}),
    # the converged fits only (analysis.regress): a fifth of the pixels stop at max_iter = 5 and are left out
    "igrm-converged": ({"library": "builtin:lib1", "copies": 4}, ["B4", "B5", "B6", "B7"],
                       {"kind": "igrm", "parameter": "cab", "igrm": {"max_iter": 5}, "regress": ["converged"]}, "B4",
                       {"centres": [665, 680], "widths": [20, 30]}),
    "formula": ({"library": "builtin:lib1", "copies": 4}, ["B4", "B5", "B6", "B7"],
                {"kind": "formula", "expression": "705 + 35 * ((B4 + B7) / 2 - B5) / (B6 - B5)", "parameter": "cab"},
                "B5", {"centres": [700, 710], "widths": [10, 15]}),
}


def _family_job(kind: str):
    from s2cl.app.plan import plan_sweep
    from s2cl.scene.scene import Scene

    surface, bands, analysis, moving, grid = FAMILY_CASES[kind]
    ranges = {b: ({"centre": ESA[b][0], "width": ESA[b][1]} if b != moving else grid) for b in bands}
    scene = Scene.from_dict({
        "scene": {"name": f"within-noise-{kind}"}, "surface": {**surface, "quantity": "reflectance"},
        "sensor": {"bands": bands},
        "effects": {"atmosphere": True, "correct": True, "seed": 3},
        "sweep": {"bands": bands, "ranges": ranges}, "analysis": analysis,
        **({"grid": {"start_nm": 1500, "stop_nm": 2500}} if kind == "sam" else {})})
    return plan_sweep(scene)


@pytest.mark.parametrize("kind", list(FAMILY_CASES))
def test_every_family_known_answers(kind: str) -> None:
    """On a real sweep's tables: the re-scored differences equal the sweep's own metrics' differences; the best
    design with other noise draws (fresh deviates for every pixel) is within noise of it; the best design with
    twenty times the noise is not."""
    from s2cl.sweep.engine import evaluate_chunk
    from s2cl.sweep.report import metric_of

    job = _family_job(kind)
    ev = NumpyEvaluator(job.tables, job.analysis)
    rows = pd.DataFrame(evaluate_chunk(job, 0, job.n_configs, evaluator=ev))
    metric = metric_of(list(rows.columns))
    top = rows.sort_values([metric, "config"]).reset_index(drop=True)
    out = within_noise(job, top, metric, evaluator_of=numpy_evaluator, replicates=500)
    assert out is not None and out["designs"][0]["within"] and out["candidates"] == job.n_configs
    np.testing.assert_allclose([d["difference"] for d in out["designs"]], top[metric] - top[metric][0],
                               rtol=1e-9, atol=1e-9)

    best = int(top["config"][0])
    scored = metric_scored_by(metric)
    assert scored is job.analysis.family.metric
    t = job.tables
    other_noise = replace(t, z=np.random.default_rng(8).standard_normal(t.z.shape))
    noisier = replace(t, values={**t.values, "sigma": tuple(20.0 * s for s in t.values["sigma"])})
    stats = np.concatenate([spectrum_stats(scored, NumpyEvaluator(tables, job.analysis)(best, best + 1), job)
                            for tables in (t, other_noise, noisier)])
    strata = np.asarray(t.target)[:: t.copies] if scored.stratified else None
    boot = paired_bootstrap(stats, scored.score, 0, replicates=1000, strata=strata)
    assert boot.within[1], (kind, boot.low, boot.high)
    assert not boot.within[2], (kind, boot.low, boot.high)
    assert boot.difference[2] > 0


def test_optimise_reports_the_within_noise_set(tmp_path) -> None:
    """Through `s2cl optimise` on the device: summary.json's set (the best in it, reproducible), the printed
    column and note, the results table's column, the hatched heatmap; `sweep report` keeps the set."""
    import s2cl

    scene = tmp_path / "small.toml"
    scene.write_text(SMALL_SWEEP_TOML.format(copies=5))
    result = s2cl.optimise(scene, tmp_path / "api")
    wn = result.summary["within_noise"]
    assert wn["metric"] == "rms" and wn["candidates"] == 6 and wn["designs"][0]["config"] == result.best["config"]
    assert wn["complete"]  # every ranked design was tested
    assert wn["configs"][0] == result.best["config"] and result.best["within_noise"] is True
    assert [d["rms"] for d in wn["designs"]] == [e["rms"] for e in result.summary["top"]]
    np.testing.assert_allclose([d["difference"] for d in wn["designs"]],
                               [e["rms"] - result.best["rms"] for e in result.summary["top"]], rtol=1e-6, atol=1e-9)
    assert list(result.ranking["within_noise"]) == [d["within"] for d in wn["designs"]]
    # the sensor's own bands, tested on the same pixels: its re-scored RMS is the reference row's
    assert wn["reference"]["score"] == pytest.approx(result.reference["rms"], rel=1e-6)
    assert result.reference["within_noise"] is wn["reference"]["within"]
    assert wn["reference"]["difference"] == pytest.approx(result.reference["rms"] - result.best["rms"], rel=1e-5)
    table = result.table()
    assert table.set_index("config")["within_noise"].to_dict() == {d["config"]: d["within"] for d in wn["designs"]}
    assert (tmp_path / "api" / "heatmap_B4.png").exists()

    cli = subprocess.run([sys.executable, "-m", "s2cl", "optimise", str(scene), "-o", str(tmp_path / "cli")],
                         capture_output=True, text=True, timeout=600)
    assert cli.returncode == 0, cli.stderr
    assert "within noise of #1" in cli.stdout and f"within noise of #1: {wn['count']} of the 6 best" in cli.stdout
    printed = json.loads((tmp_path / "cli" / "summary.json").read_text(encoding="utf-8"))
    same = ("configs", "designs", "count", "seed", "replicates")
    assert {k: printed["within_noise"][k] for k in same} == json.loads(json.dumps({k: wn[k] for k in same}))  # seeded

    again = subprocess.run([sys.executable, "-m", "s2cl", "sweep", "report", str(tmp_path / "cli")],
                           capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert json.loads((tmp_path / "cli" / "summary.json").read_text(encoding="utf-8"))["within_noise"] == \
        printed["within_noise"]


def test_heatmap_hatches_the_within_noise_cells(tmp_path) -> None:
    """The cells of the designs within noise are the ones binned_cells marks (others, and pairs that are no
    variant, are not)."""
    from s2cl.sweep.report import Digest

    df = pd.DataFrame({"config": np.arange(6), "B4_centre_nm": np.repeat([665.0, 675.0, 685.0], 2),
                       "B4_width_nm": np.tile([20.0, 30.0], 3), "rms": np.arange(6.0)})
    d = Digest.of_frame(df, {"underdetermined": "keep"})
    mask = d.binned_cells("B4", [(675.0, 30.0), (685.0, 20.0), (999.0, 20.0)])
    np.testing.assert_array_equal(mask, [[False, False], [False, True], [True, False]])
    from s2cl.sweep.report import heatmap

    assert heatmap(d, "B4", tmp_path / "h.png", hatch=[(675.0, 30.0)]).exists()


# -- what within_noise() passes to its parts: its output against a twin that resamples the sweep's spectra -------

def _twin_within_noise(job: SweepJob, configs: list[int], replicates: int, seed: int,
                       level: float = 0.95) -> dict[str, np.ndarray]:
    """The within-noise test of ``configs`` (the first is #1) written from the definition: every design's pixels
    from the numpy twin; per replicate the drawn library spectra, each with all of its noisy copies, gathered and
    the sweep's metric recomputed from scratch (regression_metrics or classification_metrics); SAM draws within
    each class (the class of each spectrum read off its copies' targets)."""
    t = job.tables
    raws = [NumpyEvaluator(t, job.analysis)(c, c + 1) for c in configs]
    index = np.concatenate([r.index for r in raws])
    status = np.concatenate([r.status for r in raws])
    bounds = np.concatenate([r.bounds for r in raws])
    per_spectrum = np.asarray(t.target).reshape(t.n_spectra, t.copies)  # pixel p is a copy of spectrum p // copies
    classify = bool(t.class_names)
    if classify:
        assert (per_spectrum == per_spectrum[:, :1]).all()  # every copy of a spectrum has its class

    def metric(pixels: np.ndarray) -> np.ndarray:
        if classify:
            pred = np.where(status[:, pixels] == Status.OK, index[:, pixels], 0).astype(np.int64)
            return classification_metrics(pred, status[:, pixels], t.target[pixels].astype(np.int64),
                                          len(t.class_names))["omission_error_pct"]
        return regression_metrics(index[:, pixels], status[:, pixels], bounds[:, pixels], t.target[pixels],
                                  regress=tuple(int(r) for r in job.analysis.regress))["rms"]

    score = metric(np.arange(t.n_pixels))
    draws = resample_indices(t.n_spectra, replicates, seed, per_spectrum[:, 0] if classify else None)
    diff = np.empty((replicates, len(configs)))
    for r, spectra in enumerate(draws):
        m = metric((spectra[:, None] * t.copies + np.arange(t.copies)).ravel())
        diff[r] = m - m[0]
    low, high = np.quantile(diff, [(1 - level) / 2, (1 + level) / 2], axis=0)
    within = low <= 0
    within[0] = True
    return {"score": score, "difference": score - score[0], "low": low, "high": high,
            "as_good": np.mean(diff <= 0, axis=0), "within": within}


@pytest.mark.parametrize("kind", list(FAMILY_CASES))
def test_within_noise_resamples_the_sweeps_library_spectra(kind: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """within_noise() on a real sweep's tables against the twin above: the statistics of each spectrum over all
    of its copies (not per pixel), SAM's classes per spectrum, the candidates' and the reference's intervals,
    shares and verdicts (a reference that is #1 itself: a difference of 0 in every replicate), the count, and
    ``complete`` — False exactly when the last candidate tested is within noise and the sweep ranked more designs
    than were tested. The bootstrap in blocks of two designs (the default block splits only more candidates than
    these)."""
    from s2cl.sweep import within_noise as module
    from s2cl.sweep.engine import evaluate_chunk
    from s2cl.sweep.report import metric_of

    monkeypatch.setattr(module, "DESIGN_BLOCK", 2)
    job = _family_job(kind)
    t = job.tables
    ev = NumpyEvaluator(t, job.analysis)
    rows = pd.DataFrame(evaluate_chunk(job, 0, job.n_configs, evaluator=ev))
    metric = metric_of(list(rows.columns))
    top = rows.sort_values([metric, "config"]).reset_index(drop=True)
    order = top["config"].tolist()
    references = order[1], order[0]  # the sensor's own bands may be one of the sweep's designs: #2, or #1 itself
    replicates, seed, level = 300, 17, 0.9
    twin = _twin_within_noise(job, [*order, *references], replicates, seed, level)
    assert twin["within"][1]  # #2 is within noise of #1 in every family
    completes = set()
    for n in range(2, len(order) + 1):
        for r, reference in enumerate(references, start=len(order)):
            out = within_noise(job, top.head(n), metric, evaluator_of=numpy_evaluator,
                               reference=ev(reference, reference + 1),
                               ranked=len(order), replicates=replicates, seed=seed, level=level)
            assert out is not None and out["candidates"] == n
            assert (out["spectra"], out["copies"], out["seed"], out["replicates"], out["level"]) == (
                t.n_spectra, t.copies, seed, replicates, level)
            assert out["resampled"] == "library spectra" + (" within each class" if t.class_names else "")
            designs = out["designs"]
            assert [d["config"] for d in designs] == order[:n]
            assert [d["rank"] for d in designs] == list(range(1, n + 1))
            ref = out["reference"]
            got = np.array([[*d["interval"], d["difference"], d["as_good"]] for d in designs]
                           + [[*ref["interval"], ref["difference"], ref["as_good"]]])
            want = np.stack([twin["low"], twin["high"], twin["difference"], twin["as_good"]], axis=1)[[*range(n), r]]
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
            assert ref["score"] == pytest.approx(twin["score"][r], rel=1e-9)
            within = [bool(w) for w in twin["within"][:n]]
            assert [d["within"] for d in designs] == within and ref["within"] == bool(twin["within"][r])
            assert out["count"] == sum(within)
            assert out["configs"] == [c for c, w in zip(order[:n], within, strict=True) if w]
            assert out["complete"] == (not within[-1] or n == len(order))
            completes.add(out["complete"])
    assert completes == {True, False}  # an incomplete set (the last tested within, more ranked) is among the cases


def test_a_design_alike_to_the_best_is_within_noise_and_as_good() -> None:
    """A candidate whose every pixel equals the best's differs from it by exactly 0 in every replicate: its interval
    is [0, 0], which reaches zero (within noise), and it is as good as the best in every replicate (the rounding of
    two matrix products once made it as good in 50-90 % of them); a design with four times the noise is in none."""
    rng = np.random.default_rng(7)
    index, status, y = _regression_case(rng, n_spectra=30, copies=3, noise=(0.5, 2.0))
    index, status = np.stack([index[0], index[0], index[1]]), status[[0, 0, 1]]
    stats = regression_stats(index, status, y, 3, REGRESS)
    boot = paired_bootstrap(stats, regression_score, 0, replicates=200, seed=3)
    assert boot.low[1] == 0.0 and boot.high[1] == 0.0 and boot.difference[1] == 0.0
    assert boot.within[1] and boot.as_good[1] == 1.0
    assert not boot.within[2] and boot.as_good[2] == 0.0


def _summary(best: int = 5) -> dict[str, Any]:
    """A summary.json whose within-noise test covered configurations 5, 2 and 9 (5 and 9 within noise) of a
    ranking 5, 2, 9, 4; the reference within noise."""
    designs = [{"config": c, "within": w, "bands": {"B4": [c * 10.0, 20.0], "B5": [705.0, 15.0]}}
               for c, w in ((5, True), (2, False), (9, True))]
    return {"best": {"config": best}, "top": [{"config": c} for c in (best, 2, 9, 4)], "reference": {"rms": 1.0},
            "within_noise": {"designs": designs, "reference": {"within": True}}}


def test_mark_top_marks_the_tested_designs_and_leaves_the_others_unknown() -> None:
    summary = _summary()
    mark_top(summary)
    assert [e["within_noise"] for e in summary["top"]] == [True, False, True, None]  # 4: not tested
    assert summary["reference"]["within_noise"] is True
    untested = {**_summary(), "within_noise": None}
    mark_top(untested)
    assert [e["within_noise"] for e in untested["top"]] == [None] * 4 and untested["reference"]["within_noise"] is None


def test_within_pairs_and_column_are_the_designs_within_noise() -> None:
    summary = _summary()
    assert within_pairs(summary, "B4") == [(50.0, 20.0), (90.0, 20.0)]  # 2 was tested and is not within
    assert within_pairs(summary, "B8") == [] and within_pairs({}, "B4") == []
    column = within_column(summary, np.array([2, 4, 5, 9]))
    assert [None if pd.isna(v) else bool(v) for v in column] == [False, None, True, True]  # 4: not tested


def test_a_report_keeps_the_within_noise_set_only_of_the_same_best() -> None:
    kept = _summary()
    same = {"best": {"config": 5}, "top": [{"config": 5}, {"config": 9}]}
    kept_within_noise(same, kept)
    assert same["within_noise"] is kept["within_noise"] and [e["within_noise"] for e in same["top"]] == [True, True]
    other = {"best": {"config": 4}, "top": [{"config": 4}, {"config": 5}]}
    kept_within_noise(other, kept)  # ranked again with another #1: the old set is not its set
    assert "within_noise" not in other and [e["within_noise"] for e in other["top"]] == [None, None]


@pytest.mark.parametrize("candidates", [3, 0])
def test_optimise_tests_the_scenes_within_noise_top(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    candidates: int) -> None:
    """`s2cl optimise` with ``within_noise_top = 3`` of 6 ranked designs: within_noise() is given the 3 best rows,
    the count of designs the sweep ranked (6: the set is complete only if the third is told apart) and the
    sensor's own bands' pixels; the designs it did not test are marked neither within nor outside. With
    ``within_noise_top = 0`` nothing is tested and nothing marked."""
    import s2cl
    from s2cl.sweep import within_noise as module

    seen: list[dict[str, Any]] = []
    real = module.within_noise

    def spy(job: SweepJob, top: pd.DataFrame, metric: str, **kwargs: Any) -> dict[str, Any] | None:
        seen.append({"top": top["config"].tolist(), "metric": metric, **kwargs})
        return real(job, top, metric, **kwargs)

    monkeypatch.setattr("s2cl.app.optimise.within_noise", spy)  # where optimise() looks it up
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL_SWEEP_TOML.format(copies=4).replace("[sweep.ranges]",
                                                               f"within_noise_top = {candidates}\n[sweep.ranges]"))
    result = s2cl.optimise(scene, tmp_path / "out")
    if not candidates:
        assert seen == [] and "within_noise" not in result.summary
        assert all("within_noise" not in e for e in [*result.summary["top"], result.summary["reference"]])
        return
    results = pd.read_parquet(tmp_path / "out" / "results.parquet")
    best3 = results.sort_values(["rms", "config"])["config"].head(3).tolist()
    (call,) = seen
    assert call["top"] == best3 and call["metric"] == "rms" and call["ranked"] == len(results) == 6
    assert call["reference"].index.shape == (1, 120 * 4)  # one design, every pixel: Lib1's 120 spectra × 4 copies
    wn = result.summary["within_noise"]
    assert wn["candidates"] == 3 and [d["config"] for d in wn["designs"]] == best3
    assert wn["complete"] == (not wn["designs"][-1]["within"])
    assert [e["within_noise"] for e in result.summary["top"]][3:] == [None, None, None]


def test_the_candidates_are_scored_in_batches_of_their_own_tables(monkeypatch: pytest.MonkeyPatch) -> None:
    """The candidates go to the design evaluator (s2cl.sweep.designs) as one list, scored in batches of their own
    tables (config_tables; every candidate once, in ranking order), one launch per batch: batches of two give the
    result of one batch of all, and the twin's per-design scores (the sweep's own tables, one design at a time)."""
    from s2cl.sweep import design_tables, designs
    from s2cl.sweep.engine import evaluate_chunk
    from s2cl.sweep.report import metric_of

    job = _family_job("gvmi")
    rows = pd.DataFrame(evaluate_chunk(job, 0, job.n_configs, evaluator=NumpyEvaluator(job.tables, job.analysis)))
    metric = metric_of(list(rows.columns))
    top = rows.sort_values([metric, "config"]).reset_index(drop=True)
    batches: list[list[int]] = []
    real = design_tables.config_tables

    def spy(tables: Any, configs: np.ndarray, rows: int | None = None) -> Any:
        batches.append(np.asarray(configs).tolist())
        return real(tables, configs, rows)

    monkeypatch.setattr(designs, "config_tables", spy)
    out = {}
    for size in (2, 128):
        monkeypatch.setattr(designs, "DESIGN_BATCH", size)
        out[size] = {key: v for key, v in within_noise(job, top, metric, evaluator_of=numpy_evaluator,
                                                       replicates=200).items() if key != "seconds"}
    order = top["config"].tolist()
    assert batches == [order[i:i + 2] for i in range(0, len(order), 2)] + [order]
    assert out[2] == out[128]
    np.testing.assert_allclose([d["difference"] for d in out[2]["designs"]], top[metric] - top[metric][0],
                               rtol=1e-9, atol=1e-9)


def test_the_printed_note_says_when_more_designs_may_be_within_noise(capsys: pytest.CaptureFixture[str]) -> None:
    """`s2cl optimise` prints the count, and when the set is not complete (the last design tested is within noise
    and more were ranked), that more may be."""
    from s2cl.cli.ranking import _print_within_noise

    wn = {"complete": True, "count": 2, "candidates": 3, "metric": "rms", "spectra": 120,
          "resampled": "library spectra", "replicates": 2000, "level": 0.95}
    _print_within_noise(wn)
    _print_within_noise({**wn, "complete": False, "count": 3})
    complete, incomplete = capsys.readouterr().out.splitlines()
    assert complete.startswith("within noise of #1: 2 of the 3 best designs — a paired bootstrap of the rms")
    assert incomplete.startswith("within noise of #1: 3 of the 3 best designs (the last one tested too: more may be")


def test_configuration_numbers_beyond_float_precision_come_back_exact(monkeypatch: pytest.MonkeyPatch) -> None:
    """A space of more than 2⁵³ designs (the six-band search: 3.8·10¹⁸) numbers its designs beyond what a float
    holds: the within-noise record gives each candidate's configuration number exactly as the ranking's (a row of
    a frame of numbers only, read through pandas, is a float). The designs are scored as their number modulo the
    small job's count."""
    from s2cl.sweep import within_noise as module

    job = _family_job("igrm")
    ev = NumpyEvaluator(job.tables, job.analysis)
    rows = pd.DataFrame(evaluate_chunk_rows(job, ev))
    shape = [c for c in rows.columns if c.endswith(("_centre_nm", "_width_nm"))]
    top = rows.sort_values(["rms", "config"]).reset_index(drop=True)[["config", *shape, "rms"]]  # numbers only
    big = 2**60 + 1 + top["config"].to_numpy(np.int64)  # ≡ config (mod 4) and far beyond 2⁵³
    assert job.n_configs == 4 and all(float(b) != b for b in big.tolist())
    real = module.design_stats
    monkeypatch.setattr(module, "design_stats", lambda j, configs, metric, **kw: real(j, configs % 4, metric, **kw))
    out = within_noise(job, top.assign(config=big), "rms", evaluator_of=numpy_evaluator, replicates=100)
    assert out is not None and [d["config"] for d in out["designs"]] == big.tolist()
    assert set(out["configs"]) <= set(big.tolist())


def evaluate_chunk_rows(job: SweepJob, ev: NumpyEvaluator) -> dict[str, Any]:
    from s2cl.sweep.engine import evaluate_chunk

    return evaluate_chunk(job, 0, job.n_configs, evaluator=ev)
