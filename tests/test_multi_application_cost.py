"""What a multi-application sweep shares between its applications (issue 35, item 8), checked by counting calls:
each band's tables are built once per library (two applications on Lib1 reading the same swept bands resample them
once), each application's sweep kernel is built once (in the checks; its run and its designs' scores reuse it), and
no design is scored per pixel twice for one application (the joint ranking repeats the first application's designs;
its within-noise set and its margin's designs overlap). The numbers stay each application's own: its tables equal
those its single-application scene builds alone, bit for bit."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import s2cl.sweep.designs as designs
import s2cl.sweep.engine as engine
import s2cl.sweep.tables as tables
import s2cl.sweep.within_noise as within_noise
from s2cl.app.applications import application_bands, application_sweep_scene
from s2cl.app.optimise import optimise, prepare
from s2cl.app.plan import plan_sweep
from s2cl.scene.applications import scene_applications
from s2cl.scene.scene import Scene
from s2cl.sweep.raw import RawChunk

# chlorophyll (IGRM, B4-B7) and MTCI (B4, B5, B6) on Lib1 both read the swept B5 and B6 and the fixed B4; leaf water
# (GVMI, B8/B11) is on its own library. The sensor's own B5 (705/15), B6 (740/15) and B11 (1610/90) are in the
# ranges, so no reference needs tables of its own.
SCENE = """
[scene]
name = "shared"
[surface]
library = "builtin:lib1"
quantity = "reflectance"
copies = 2
[effects]
atmosphere = true
correct = true
seed = 5
[[application]]
name = "chlorophyll"
[application.analysis]
kind = "igrm"
parameter = "cab"
bands = ["B4", "B5", "B6", "B7"]
[[application]]
name = "mtci"
[application.analysis]
kind = "formula"
expression = "(B6 - B5) / (B5 - B4)"
parameter = "cab"
[[application]]
name = "leaf_water"
library = "builtin:leaf-water"
analysis = { kind = "gvmi", parameter = "ewt", nir = "B8", swir = "B11" }
[sweep]
bands = ["B5", "B6", "B11"]
within_noise_top = 8
[sweep.ranges]
B5 = { centres = [700, 705], widths = [15, 20] }
B6 = { centres = [740, 745], widths = [15] }
B11 = { centres = [1610, 1640], widths = [90] }
"""


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    path = tmp_path / "shared.toml"
    path.write_text(SCENE, encoding="utf-8")
    return path


def _prepare(scene: Path, out: Path):  # type: ignore[no-untyped-def]
    return prepare(scene, out, workers=None, scheduler=None, overwrite=False, chunk=None, device=None,
                   max_memory=None).applications


def test_each_band_is_resampled_once_per_library(scene: Path, tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    built: list[str] = []
    real = tables._band_tables

    def spy(variants, band, *args, **kwargs):  # type: ignore[no-untyped-def]
        built.append(band.name)
        return real(variants, band, *args, **kwargs)

    monkeypatch.setattr(tables, "_band_tables", spy)
    multi = _prepare(scene, tmp_path / "out")
    # chlorophyll builds B4-B7; MTCI's B4, B5 and B6 are the same variants on the same library: taken, not built;
    # leaf water's B8 and B11 are on another library (without sharing: 4 + 3 + 2 = 9 builds)
    assert built == ["B4", "B5", "B6", "B7", "B8", "B11"]
    chl, mtci, _ = multi.apps
    assert chl.job.tables.radiance[1] is mtci.job.tables.radiance[1]  # B5's resampled radiance, one array


def test_shared_tables_equal_each_application_s_own_bit_for_bit(scene: Path, tmp_path: Path) -> None:
    """Each application's tables (radiance, stages' values, noise deviates, targets: all in the fingerprint) equal
    the tables its own single-application scene builds alone."""
    multi = _prepare(scene, tmp_path / "out")
    sc = Scene.load(str(scene))
    for app, prepared in zip(scene_applications(sc), multi.apps, strict=True):
        alone = plan_sweep(application_sweep_scene(sc, app, application_bands(sc, app)))
        assert alone.tables.fingerprint() == prepared.job.tables.fingerprint(), app.name
        for a, b in zip(alone.tables.radiance, prepared.job.tables.radiance, strict=True):
            assert a.tobytes() == b.tobytes()


def test_each_kernel_is_built_once_and_no_design_is_scored_twice(scene: Path, tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    sweeps: Counter[str] = Counter()
    batches: Counter[str] = Counter()
    scored: dict[str, list[int]] = {}
    real_sweep, real_batch, real_pixels = engine.SweepKernel, designs.SweepKernel, within_noise.design_pixels

    def sweep_kernel(t, *args, **kwargs):  # type: ignore[no-untyped-def]
        sweeps[t.fingerprint()] += 1
        return real_sweep(t, *args, **kwargs)

    def batch_kernel(t, *args, **kwargs):  # type: ignore[no-untyped-def]
        batches[t.n_spectra] += 1  # Lib1 (both of its applications) or the leaf-water library
        return real_batch(t, *args, **kwargs)

    def pixels(job, configs, **kwargs) -> RawChunk:  # type: ignore[no-untyped-def]
        scored.setdefault(job.fingerprint(), []).extend(int(c) for c in configs)
        return real_pixels(job, configs, **kwargs)

    monkeypatch.setattr(engine, "SweepKernel", sweep_kernel)
    monkeypatch.setattr(designs, "SweepKernel", batch_kernel)
    monkeypatch.setattr(within_noise, "design_pixels", pixels)
    monkeypatch.setattr(engine, "_EVALUATORS", {})
    monkeypatch.setattr(designs, "_KERNELS", {})
    monkeypatch.setattr(within_noise, "_STATS", {})
    result = optimise(scene, tmp_path / "out")
    # the sweep kernel of each application once: in the checks, then its run (before: again for every application
    # but the last, whose kernel alone was kept)
    assert sorted(sweeps.values()) == [1, 1, 1]
    # one batch kernel per application: its reference row, its within-noise set and its margin's designs share it
    assert sum(batches.values()) == 3
    # the first application's within-noise set (the joint ranking's best 8: 4 of its own designs, each twice, with
    # B11 at either variant) and every application's margin designs: each design per pixel once per application
    assert len(scored) == 3
    for configs in scored.values():
        assert len(configs) == len(set(configs))
    wn = result.summary["within_noise"]
    assert wn["candidates"] == 8 and len({d["application_config"] for d in wn["designs"]}) == 4


def test_design_stats_of_repeated_designs_are_those_of_each_alone(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Repeated and earlier-scored designs are scored once; their statistics equal each design's scored by itself."""
    monkeypatch.setattr(within_noise, "_STATS", {})
    sc = Scene.load(str(_write(tmp_path)))
    job = plan_sweep(sc)
    metric = within_noise.metric_scored_by("rms")
    configs = np.array([3, 1, 3, 0, 1, 3])
    got = within_noise.design_stats(job, configs, metric)
    for i, c in enumerate(configs):
        alone = within_noise.spectrum_stats(metric, designs.design_pixels(job, np.array([c])), job)
        assert got[i].tobytes() == alone[0].tobytes()
    again = within_noise.design_stats(job, np.array([0, 2]), metric)  # 0 from before, 2 new
    assert again[0].tobytes() == got[3].tobytes()


def _write(tmp_path: Path) -> Path:
    text = SCENE.split("[[application]]")[0] + """
[analysis]
kind = "igrm"
parameter = "cab"
bands = ["B4", "B5", "B6", "B7"]
[sweep]
bands = ["B4", "B5", "B6", "B7"]
[sweep.ranges]
B4 = { centre = 665, width = 30 }
B7 = { centre = 783, width = 20 }
B5 = { centres = [700, 705], widths = [15] }
B6 = { centres = [740, 745], widths = [15] }
"""
    path = tmp_path / "one.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("in_memory", [True, False])
def test_lookup_columns_in_memory_or_mapped_from_disk(tmp_path: Path, monkeypatch, in_memory: bool) -> None:  # type: ignore[no-untyped-def]
    """An application's columns by configuration number, whether held in memory (small) or memory-mapped from disk:
    the same values and types, rows written in any order."""
    import pandas as pd

    import s2cl.sweep.joint as joint

    monkeypatch.setattr(joint, "IN_MEMORY_BYTES", 2**40 if in_memory else 0)
    order = np.array([4, 0, 3, 1, 2])
    table = pd.DataFrame({"config": order, "rms": order * 1.5, "underdetermined": order % 2 == 1})
    path = tmp_path / "results.parquet"
    table.to_parquet(path)
    got = joint.lookup_columns(path, 5, ["rms", "underdetermined"], tmp_path / "lookup")
    assert got["rms"].tolist() == [0.0, 1.5, 3.0, 4.5, 6.0] and got["rms"].dtype == np.float64
    assert got["underdetermined"].tolist() == [False, True, False, True, False]
    assert (tmp_path / "lookup").exists() is not in_memory
