"""Sweep engine: chunks, Parquet output, resume after SIGKILL, refusing to mix, Dask equality."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from sweep_fixtures import gvmi_job, gvmi_scene, numpy_evaluator

from s2cl.errors import InputError, ResourceError
from s2cl.reference.sweep import evaluate
from s2cl.sweep.engine import RESULTS, run_sweep

HERE = Path(__file__).resolve().parent


def _table(path: Path):
    return pq.read_table(path)


def test_sweep_writes_rows_and_metadata(tmp_path) -> None:
    job = gvmi_job()
    path = run_sweep(job, evaluator=numpy_evaluator(job), out=tmp_path / "out")
    table = _table(path)
    assert table.num_rows == job.n_configs
    assert table.column("config").to_pylist() == list(range(job.n_configs))
    meta = table.schema.metadata
    assert meta[b"scene"] == b"gvmi-test" and meta[b"fingerprint"].decode() == job.fingerprint()
    for col in ("B11_centre_nm", "B11_width_nm", "rms", "r2", "robust_rms", "rms_unbounded", "failed_fraction",
                "bound_fraction"):
        assert col in table.column_names
    rms = table.column("rms").to_numpy()
    assert np.all(np.isfinite(rms)) and np.all(rms > 0)


def test_sweep_metrics_match_direct_evaluation(tmp_path) -> None:
    job = gvmi_job()
    table = _table(run_sweep(job, evaluator=numpy_evaluator(job), out=tmp_path / "out"))
    from s2cl.retrieve.metrics import regression_metrics

    raw = evaluate(job.tables, job.analysis, 0, job.n_configs)
    m = regression_metrics(raw.index, raw.status, raw.bounds, job.tables.target)
    # summation order follows the chunk's shape, so only the last bits may differ
    assert np.allclose(table.column("rms").to_numpy(), m["rms"], rtol=1e-12, atol=0)


def test_resume_computes_only_missing_chunks(tmp_path) -> None:
    job = gvmi_job()
    out = tmp_path / "out"
    first = _table(run_sweep(job, evaluator=numpy_evaluator(job), out=out))
    chunks = sorted((out / "chunks").glob("*.parquet"))
    chunks[1].unlink()
    chunks[3].unlink()
    done: list[int] = []
    seen: list[tuple[int, int]] = []
    again = _table(run_sweep(job, evaluator=numpy_evaluator(job), out=out, progress=done.append,
                             on_start=lambda todo, skip: seen.append((todo, skip))))
    assert sum(done) == seen[0][0] == 10 and seen[0][1] == job.n_configs - 10
    assert again.equals(first)


def test_folder_with_another_sweep_is_refused(tmp_path) -> None:
    out = tmp_path / "out"
    run_sweep(gvmi_job(), evaluator=numpy_evaluator(gvmi_job()), out=out)
    other = gvmi_job(b11_max_width=100.0)
    with pytest.raises(InputError, match="different sweep") as err:
        run_sweep(other, evaluator=numpy_evaluator(other), out=out)
    assert "--overwrite" in str(err.value)
    replaced = run_sweep(other, evaluator=numpy_evaluator(other), out=out, overwrite=True)
    assert _table(replaced).num_rows == other.n_configs


def test_chunks_of_other_code_are_never_resumed(tmp_path, monkeypatch) -> None:
    """A resumed sweep keys its chunks by the sources and kernels too: after a code change (here the
    code fingerprint, as a changed file would give), the folder is refused until --overwrite."""
    import s2cl.sweep.engine as engine

    out, job = tmp_path / "out", gvmi_job()
    run_sweep(job, evaluator=numpy_evaluator(job), out=out)
    assert json.loads((out / "manifest.json").read_text())["code"] == engine.code_fingerprint()
    monkeypatch.setattr(engine, "code_fingerprint", lambda: "0" * 64)
    with pytest.raises(InputError, match="other s2cl code") as err:
        run_sweep(job, evaluator=numpy_evaluator(job), out=out)
    assert "--overwrite" in str(err.value)
    redone = run_sweep(job, evaluator=numpy_evaluator(job), out=out, overwrite=True)
    assert _table(redone).num_rows == job.n_configs
    assert json.loads((out / "manifest.json").read_text())["code"] == "0" * 64


DRIVER = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, {tests!r})
    from sweep_fixtures import gvmi_job, numpy_evaluator
    import s2cl.sweep.engine as sweep
    real = sweep.evaluate_chunk
    def slow(*args, **kwargs):
        time.sleep(0.05)
        return real(*args, **kwargs)
    sweep.evaluate_chunk = slow
    sweep.run_sweep(gvmi_job(chunk=1), evaluator=numpy_evaluator(gvmi_job(chunk=1)), out={out!r})
""")


def test_sigkill_and_resume_gives_identical_output(tmp_path) -> None:
    job = gvmi_job(chunk=1)
    reference = _table(run_sweep(job, evaluator=numpy_evaluator(job), out=tmp_path / "reference")).to_pandas()
    out = tmp_path / "killed"
    script = DRIVER.format(tests=str(HERE), out=str(out))
    proc = subprocess.Popen([sys.executable, "-c", script], env={**os.environ, "PYTHONUNBUFFERED": "1"})
    deadline = time.time() + 120
    while time.time() < deadline and len(list((out / "chunks").glob("*.parquet"))) < 5:
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    partial = len(list((out / "chunks").glob("*.parquet")))
    assert 5 <= partial < len(reference), "the sweep should have been killed part-way"
    assert not (out / RESULTS).exists()
    done: list[int] = []
    resumed = _table(run_sweep(job, evaluator=numpy_evaluator(job), out=out, progress=done.append)).to_pandas()
    assert sum(done) == len(reference) - partial
    assert resumed.equals(reference)


@pytest.mark.slow
def test_dask_two_workers_equal_single_process(tmp_path) -> None:
    pytest.importorskip("dask.distributed")
    job = gvmi_job(chunk=4)
    single = (tmp_path / "single" / RESULTS)
    run_sweep(job, evaluator=numpy_evaluator(job), out=tmp_path / "single")
    run_sweep(job, evaluator=numpy_evaluator(job), out=tmp_path / "dask", workers=2)
    assert _table(tmp_path / "dask" / RESULTS).equals(_table(single))
    assert (tmp_path / "dask" / RESULTS).read_bytes() == single.read_bytes()


@pytest.mark.slow
def test_dask_workers_run_the_kernel_on_the_named_device(rt, tmp_path) -> None:
    """The OpenCL kernel on two Dask workers, each building its own context on the device the run names,
    gives the single-process result bit for bit."""
    pytest.importorskip("dask.distributed")
    job = gvmi_job(chunk=6, copies=6)
    run_sweep(job, tmp_path / "single", device=rt.info.spec)
    run_sweep(job, tmp_path / "dask", workers=2, device=rt.info.spec)
    assert (tmp_path / "dask" / RESULTS).read_bytes() == (tmp_path / "single" / RESULTS).read_bytes()


def test_the_disk_is_checked_before_the_tables_are_built(tmp_path, monkeypatch) -> None:
    """The results' disk is refused before anything is built (the chunk's memory: tests/test_host_footprint.py)."""
    import shutil as _shutil

    import s2cl.io.budget as budget
    from s2cl.app.checks import check_sweep
    from s2cl.app.sweep_budget import require_sweep_disk

    checked = check_sweep(gvmi_scene())
    usage = _shutil.disk_usage(tmp_path)
    monkeypatch.setattr(budget.shutil, "disk_usage", lambda p: usage._replace(free=10))
    with pytest.raises(ResourceError, match="MB of disk"):
        require_sweep_disk(checked, tmp_path / "b")
    assert not (tmp_path / "b").exists()


@pytest.mark.parametrize(
    ("sweep_section", "message"),
    [({"bands": ["B4", "B13"], "preset": "table2"}, "no band 'B13'"),
     ({"bands": ["B11"]}, "no range for band B11"),
     ({"bands": ["B4"], "ranges": {"B4": {"left": 630, "right": 640, "min_width": 30, "max_width": 50}}},
      "admits no variant"),
     ({"bands": ["B4"], "ranges": {"B4": {"left": 630, "min_width": 30}}}, "missing right, max_width"),
     ({"bands": ["B4"], "ranges": {"B4": {"centre": 665, "width": 30}, "B5": {"centre": 705, "width": 15}}},
      "not swept")],
)
def test_bad_sweep_sections(sweep_section: dict, message: str) -> None:
    from s2cl.scene.scene import Scene
    from s2cl.sweep.space import sweep_space

    scene = Scene.from_dict({"scene": {"name": "t"}, "surface": {"library": "x.csv"}, "sweep": sweep_section})
    with pytest.raises(InputError, match=message) as err:
        sweep_space(scene.spec.sweep, scene.sensor, scene.grid, scene.run.support)
    assert "sweep" in str(err.value)
