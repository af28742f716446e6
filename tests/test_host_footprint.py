"""A sweep's declared host memory (:mod:`s2cl.sweep.host_footprint`, what :func:`s2cl.app.sweep_budget.sweep_resources`
plans with) against what it really allocates: a chunk run in a child process (its peak resident set, which on a PoCL
CPU device holds the device's buffers too, and numpy's allocations as ``tracemalloc`` sees them), the tables' arrays,
the numpy metrics' row block and the deviates' draw.

The margin: the declaration is an upper bound (measured ≤ declared) that is not loose (measured ≥ 0.7 × declared).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from memory_probe import env as probe_env
from sweep_fixtures import gvmi_scene

from s2cl.io.budget import Budget

ROOT = Path(__file__).resolve().parents[1]
LOWEST = 0.7  # measured / declared at least
BIG = Budget(10**11, "test")

#: in a child process: plan the sweep of gvmi_scene(copies) on a device, run one warm-up chunk, then measure chunks of
#: CHUNKS configurations one after the other (a sweep's full chunks and its last, smaller one): the growth of the
#: peak resident set (VmHWM reset) and numpy's traced peak
_CHILD = r"""
import json, sys
device, copies, host = sys.argv[1], int(sys.argv[2]), sys.argv[4] == "host"
chunks = [int(c) for c in sys.argv[3].split(",")]
from memory_probe import peak
from memory_probe import env as probe_env
from sweep_fixtures import gvmi_scene
from s2cl.app.plan import plan_sweep
from s2cl.io.budget import Budget
import s2cl.sweep.kernel as kernel
from s2cl.sweep.engine import evaluate_chunk
if host:  # the numpy metrics, as on a device without float64 or on Dask workers
    kernel.metrics_on_device = lambda rt, **kw: False
job = plan_sweep(gvmi_scene(copies), budget=Budget(10**11, "test"), device=device)
evaluate_chunk(job, 0, 2, device)
print(json.dumps({**peak(lambda: [evaluate_chunk(job, 0, chunk, device) for chunk in chunks]),
                  "pixels": job.tables.n_pixels}))
"""


def _measure(device: str, copies: int, chunks: str, where: str) -> dict[str, float]:
    env = probe_env()
    out = subprocess.run([sys.executable, "-c", _CHILD, device, str(copies), chunks, where], capture_output=True,
                         text=True, env=env, cwd=ROOT, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="needs Linux's /proc peak resident set")
@pytest.mark.parametrize("where", ["device", "host"])
def test_a_chunk_allocates_what_its_host_footprint_declares(rt, where: str) -> None:
    """A chunk of 640 configurations × 24,600 pixels and then one of 600 (a sweep's last), the metrics on the device
    (where it has float64) or in numpy: the resident set within the declared chunk of 640 (device buffers included
    on a CPU device: the memory pool does not keep the first chunk's while the second runs), numpy's part within the
    declared host arrays."""
    from s2cl.app.checks import check_sweep
    from s2cl.app.sweep_budget import host_footprint

    if where == "device" and not rt.has_fp64:
        pytest.skip("the metrics kernel needs float64")
    copies, chunk = 100, 640
    measured = _measure(rt.info.spec, copies, f"{chunk},{chunk - 40}", where)
    checked = check_sweep(gvmi_scene(copies))
    fp = host_footprint(checked, host_metrics=where == "host", device_memory=rt.host_memory,
                        device_metrics=where == "device")
    declared = sum(a.bytes(chunk) for a in fp.chunk)
    device_names = {"index", "status", "bounds", "condition", "out", "scratch"}
    numpy_part = sum(a.bytes(chunk) for a in fp.chunk if a.name not in device_names)
    report = (f"{where} metrics on {rt.name}: resident {measured['rss'] / 1e6:.1f} MB against {declared / 1e6:.1f} MB "
              f"declared; numpy {measured['traced'] / 1e6:.1f} MB against {numpy_part / 1e6:.1f} MB")
    assert measured["pixels"] == 24600
    assert measured["rss"] <= declared, report
    assert measured["traced"] <= numpy_part, report
    if rt.host_memory:  # the device's buffers are in the resident set
        assert measured["rss"] >= LOWEST * declared, report
    if where == "host":  # the numpy path allocates what it declares; the device path only its marked rows (few)
        assert measured["traced"] >= LOWEST * numpy_part, report


def test_the_tables_hold_what_their_footprint_declares(rt) -> None:
    """The sweep tables' arrays, summed from the built tables, equal their declared float64 copies."""
    from s2cl.app.checks import check_sweep
    from s2cl.app.plan import plan_sweep
    from s2cl.app.sweep_budget import _sizes
    from s2cl.sweep.host_footprint import held_bytes, table_arrays

    scene = gvmi_scene(7)
    job = plan_sweep(scene, budget=BIG, device=rt.info.spec)
    t = job.tables
    arrays = [*t.radiance, *t.centre, *t.width, *t.references, t.z, t.target]
    arrays += [a for name in t.per_row() for a in t.values[name]]
    sizes, stages, metric, _ = _sizes(check_sweep(scene))
    assert held_bytes(table_arrays(stages, sizes, metric)) == sum(np.asarray(a).nbytes for a in arrays)


def _traced_peak(f, *args, **kwargs) -> int:
    """numpy's peak allocation while ``f(*args, **kwargs)`` runs (bytes)."""
    tracemalloc.start()
    try:
        f(*args, **kwargs)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("pixels", [6000, 40000])
def test_the_numpy_metrics_hold_one_row_block_whatever_the_chunk(pixels: int) -> None:
    """The numpy metrics' peak over 32 and 96 configurations (inputs made beforehand) within one declared row block
    (:func:`s2cl.retrieve.metrics.block_work_bytes`), and at least 0.7 of it."""
    from s2cl.retrieve.metrics import block_work_bytes, classification_metrics, regression_metrics

    rng = np.random.default_rng(3)
    small = np.full((2, 8), 720.0, np.float32), np.zeros((2, 8), np.uint8)  # modules imported on first use (numpy.ma)
    regression_metrics(small[0], small[1], small[1], np.zeros(8), condition=small[1])  # load before the measurement
    classification_metrics(small[0] * 0, small[1], np.zeros(8, int), 5)
    for n in (32, 96):
        index = rng.normal(720.0, 5.0, (n, pixels)).astype(np.float32)
        status = rng.choice(np.array([0, 0, 0, 1, 2, 3], np.uint8), (n, pixels))
        bounds = (rng.random((n, pixels)) < 0.05).astype(np.uint8)
        condition = rng.integers(0, 240, (n, pixels)).astype(np.uint8)
        target = rng.normal(40.0, 10.0, pixels)
        peak = _traced_peak(regression_metrics, index, status, bounds, target, condition=condition)
        declared = block_work_bytes(pixels, classifies=False)
        assert LOWEST * declared <= peak <= declared, (n, peak, declared)
        classes = rng.integers(0, 5, (n, pixels)).astype(np.float32)
        truth = rng.integers(0, 5, pixels)
        peak = _traced_peak(classification_metrics, classes, status, truth, 5)
        declared = block_work_bytes(pixels, classifies=True)
        assert LOWEST * declared <= peak <= declared, (n, peak, declared)


def test_the_deviates_draw_holds_what_it_declares() -> None:
    from s2cl.forward.noise import sensor_noise, sensor_noise_bytes

    for n, bands in ((50_000, 1), (200_000, 4)):
        peak = _traced_peak(sensor_noise, 7, np.arange(n, dtype=np.uint64), list(range(bands)))
        declared = sensor_noise_bytes(n, bands)
        assert LOWEST * declared <= peak <= declared, (n, bands, peak, declared)


def test_the_device_buffers_count_in_the_host_memory_only_where_the_device_works_in_it() -> None:
    """A GPU's buffers are its own memory: the host's chunk is then the metric rows and the results alone; on a CPU
    device the chunk's buffers (float32 index, three status bytes per padded pixel, float64 scratch per pixel) are
    the host's, rounded up by the memory pool (at most 1/16)."""
    from s2cl.app.checks import check_sweep
    from s2cl.app.sweep_budget import host_footprint

    checked = check_sweep(gvmi_scene(20))  # 4,920 pixels, padded to 4,928 for 16 lanes
    gpu = host_footprint(checked, host_metrics=False, device_memory=False, device_metrics=True).chunk
    assert {a.name for a in gpu} == {"metric rows", "marked rows", "results"}
    cpu = {a.name: a.per_unit for a in host_footprint(checked, host_metrics=False, device_memory=True,
                                                      device_metrics=True).chunk}
    assert cpu["index"] == 4 * 4928 * 17 / 16 and cpu["status"] == cpu["bounds"] == cpu["condition"] == 4928 * 17 / 16
    assert cpu["scratch"] == 8 * 4920 * 17 / 16
    # 16 metric columns as float64, fetched and copied; 2 + 2 + 24 result columns as float64, twice
    assert cpu["metric rows"] == 2 * 8 * 16 and cpu["results"] == 2 * 8 * 28


_DIGEST_CHILD = r"""
import json, sys
import pandas, pyarrow.parquet
from memory_probe import peak
from s2cl.sweep.digest import Digest
Digest.of_file(sys.argv[2], {"analysis": "igrm"})  # the modules a digest loads, before the measurement
held = []
figures = peak(lambda: held.append(Digest.of_file(sys.argv[1], {"analysis": "igrm"})), traced=False)
print(json.dumps({"rss": figures["rss"], "variants": held[0].variants("B4") + held[0].variants("B5")}))
"""


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="needs Linux's /proc peak resident set")
@pytest.mark.parametrize("rows", [200_000, 800_000])
def test_the_report_digest_holds_what_it_declares_whatever_the_rows(tmp_path: Path, rows: int) -> None:
    """The digest of a results file (26 columns, two swept bands of 2,000 pairs each) streamed in a child process:
    its resident set within the declared batch and pairs (:mod:`s2cl.sweep.digest`), at least 0.7 of it, the same for
    four times the rows."""
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    from s2cl.sweep.digest import BATCH_BYTES_PER_COLUMN, BATCH_ROWS, BYTES_PER_VARIANT

    rng = np.random.default_rng(2)
    centre, width = rng.integers(0, 100, rows) + 500.0, rng.integers(0, 20, rows) + 10.0
    df = pd.DataFrame({"config": np.arange(rows), "B4_centre_nm": centre, "B4_width_nm": width,
                       "B5_centre_nm": centre[::-1].copy(), "B5_width_nm": width[::-1].copy(), "rms": rng.random(rows),
                       **{f"m{k}": rng.random(rows) for k in range(20)}})
    path, small = tmp_path / "results.parquet", tmp_path / "small.parquet"
    pq.write_table(pa.Table.from_pandas(df, preserve_index=False), path, row_group_size=BATCH_ROWS)
    pq.write_table(pa.Table.from_pandas(df.head(10), preserve_index=False), small)
    env = probe_env()
    out = subprocess.run([sys.executable, "-c", _DIGEST_CHILD, str(path), str(small)], capture_output=True, text=True,
                         env=env, cwd=ROOT, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    measured = json.loads(out.stdout.strip().splitlines()[-1])
    declared = BATCH_BYTES_PER_COLUMN * len(df.columns) + BYTES_PER_VARIANT * measured["variants"]
    assert measured["variants"] == 4000
    assert LOWEST * declared <= measured["rss"] <= declared, (measured, declared)


def test_a_sweep_refused_for_its_copies_names_the_most_that_fit(tmp_path: Path) -> None:
    """The default scene at 10,000 copies under 1.5 GB is refused naming ``surface.copies`` and N copies: the same scene
    at N copies is accepted and at N + 1 refused (the footprint is not a straight line in the copies: past some count
    the chunk's part outgrows the report's, which a line through 0 and 1 copies missed by about 30×)."""
    import re

    from s2cl.app.checks import check_sweep
    from s2cl.app.sweep_budget import sweep_resources
    from s2cl.errors import ResourceError
    from s2cl.scene.scene import Scene

    text = (ROOT / "scenes" / "default.toml").read_text()
    assert "copies = 100 " in text

    def plan(copies: int) -> None:
        path = tmp_path / f"c{copies}.toml"
        path.write_text(text.replace("copies = 100 ", f"copies = {copies} ", 1))
        sweep_resources(check_sweep(Scene.load(str(path))), budget=Budget(1.5e9, "test"))

    with pytest.raises(ResourceError) as err:
        plan(10_000)
    assert "surface.copies" in str(err.value) and "\n" not in str(err.value)
    most = int(re.search(r"at most ([\d,]+) copies fit", str(err.value)).group(1).replace(",", ""))
    assert 0 < most < 10_000
    plan(most)
    with pytest.raises(ResourceError):
        plan(most + 1)
