"""The sweep's per-configuration metrics on the device (kernels/metrics.cl.mako) against their float64
numpy twin (s2cl/retrieve/metrics.py): within 1e-10 relative (1e-12 absolute near 0), counts exact,
NaN where numpy has NaN, on real sweep chunks and on synthetic hard rows (constant index, no valid
pixel, one or two valid pixels, NaN and inf indices, every pixel on a bound, ties in the median)."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.app.plan import plan_sweep
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.scene.scene import Scene
from s2cl.status import Status
from s2cl.sweep.metrics_kernel import MetricsKernel, host_metrics
from s2cl.sweep.raw import RawChunk

TOL = 1e-10


def _agree(host: dict, dev: dict) -> None:
    assert list(dev) == list(host)
    for key in host:
        a, b = np.asarray(host[key]), np.asarray(dev[key])
        assert a.shape == b.shape and a.dtype.kind == b.dtype.kind, key
        if a.dtype.kind == "f":
            np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=key)
            ok = ~np.isnan(a)
            np.testing.assert_allclose(b[ok], a[ok], rtol=TOL, atol=1e-12, err_msg=key)
        else:
            np.testing.assert_array_equal(b, a, err_msg=key)


@pytest.fixture
def fp64(rt):
    if not MetricsKernel.available(rt):
        pytest.skip("device has no cl_khr_fp64: the host computes the metrics")
    return rt


@pytest.mark.parametrize("scene", ["table5-b11", "table6-b12", "ndvi-lai"])
def test_device_metrics_equal_numpy_on_sweeps(fp64, scene) -> None:
    job = plan_sweep(Scene.load(scene))
    from s2cl.sweep.kernel import SweepKernel

    k = SweepKernel(job.tables, job.analysis, fp64, precision=job.precision)
    stop = min(job.n_configs, 40)
    _agree(host_metrics(job.analysis, k(0, stop), job.tables.target, len(job.tables.class_names)), k.metrics(0, stop))


def test_device_metrics_equal_numpy_on_an_igrm_sweep(fp64) -> None:
    """The default scene's first configurations: IGRM statuses, bounds and condition codes of real fits."""
    from s2cl.sweep.kernel import SweepKernel

    job = plan_sweep(Scene.load("default"))
    k = SweepKernel(job.tables, job.analysis, fp64)
    _agree(host_metrics(job.analysis, k(0, 24), job.tables.target, 0), k.metrics(0, 24))


def _synthetic(rt, T, rows: dict[str, np.ndarray], target: np.ndarray, analysis: AnalysisSettings,
               n_classes: int = 0) -> tuple[dict, dict]:
    n, m = rows["index"].shape
    pitch = m + 3  # rows padded, as the sweep kernel pads them
    pad = {k: np.zeros((n, pitch), dtype=v.dtype) for k, v in rows.items()}
    for k, v in rows.items():
        pad[k][:, :m] = v
    buffers = {k: rt.to_device(np.ascontiguousarray(v.astype(T.dtype) if k == "index" else v)) for k, v in pad.items()}
    kernel = MetricsKernel(rt, T, analysis, target, pitch, n_classes)
    raw = RawChunk(0, n, rows["index"], rows["status"], rows["bounds"], rows["condition"])
    dev = kernel(buffers, n, lambda sel: RawChunk(0, n, *(rows[k][sel] for k in ("index", "status", "bounds",
                                                                                    "condition"))))
    return host_metrics(analysis, raw, target, n_classes), dev


def test_hard_rows_regression(fp64) -> None:
    rng = np.random.default_rng(3)
    m = 61
    target = rng.uniform(10, 90, m)
    index = 700 + 0.3 * (target - 50) + rng.normal(0, 1, (9, m))
    status = np.full((9, m), Status.OK, np.uint8)
    bounds = np.zeros((9, m), np.uint8)
    condition = rng.integers(0, 240, (9, m)).astype(np.uint8)
    index[1] = 712.5                                   # constant index
    status[2] = Status.INVALID                         # no valid pixel
    status[3, 1:] = Status.DEGENERATE                  # one valid pixel (host)
    status[4, 2:] = Status.DEGENERATE                  # two valid pixels (host)
    index[5, ::7] = np.nan                             # NaN and inf leave the regression
    index[5, 3] = np.inf
    bounds[6] = 1                                      # every pixel on a bound: unbounded refit has none
    bounds[7, ::2] = 4                                 # half on a bound
    status[7, 1::5] = Status.STALLED
    status[7, 2::5] = Status.ITERATION_LIMIT
    index[8, : m // 2] = np.round(index[8, : m // 2])  # ties
    rows = {"index": index, "status": status, "bounds": bounds, "condition": condition}
    for real_t in ("float32", "float64"):
        host, dev = _synthetic(fp64, fp64.types(real_t, 1), {**rows, "index": index.astype(real_t)}, target,
                               AnalysisSettings("igrm", "cab"))
        _agree(host, dev)
    assert np.isnan(dev["rms"][2]) and dev["n_valid"][2] == 0 and dev["constant_index"][1]
    assert np.isnan(dev["rms_unbounded"][6])


def test_hard_rows_classification(fp64) -> None:
    rng = np.random.default_rng(5)
    m, n_classes = 50, 3
    truth = rng.integers(0, n_classes, m).astype(np.float64)
    index = rng.integers(0, n_classes + 1, (4, m)).astype(np.float64)
    status = np.where(index == n_classes, Status.UNCLASSIFIED, Status.OK).astype(np.uint8)
    status[1, ::4] = Status.INVALID
    status[2] = Status.DEGENERATE                      # nothing classified
    truth[truth == 2] = 1                              # a class without pixels: omission NaN for it
    zeros = np.zeros((4, m), np.uint8)
    host, dev = _synthetic(fp64, fp64.types("float32", 1), {"index": index, "status": status, "bounds": zeros,
                                                            "condition": zeros}, truth,
                           AnalysisSettings("sam"), n_classes)
    _agree(host, dev)
