"""The device's memory bounds a sweep's chunks: a device whose reported memory is made small through the seam
(``$S2CL_DEVICE_GLOBAL_MEM``, ``$S2CL_DEVICE_MAX_ALLOC``) gets chunks sized to it, with the same results as the
unconstrained run, and one too small for even one configuration is refused in one line (API and CLI); the sweep's
declared device buffers are what its kernels really allocate."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from sweep_fixtures import SMALL_SWEEP_TOML, gvmi_job, gvmi_scene
from test_bounded_runs import one_line_error, run

from s2cl.cl.device_memory import GLOBAL_ENV, MAX_ALLOC_ENV, DeviceBuffer, DeviceMemory
from s2cl.errors import InputError, ResourceError
from s2cl.io.budget import Budget

BIG = Budget(10**11, "test")  # the host never binds here: only the device does


# -- the seam ------------------------------------------------------------------------------------------------

def test_the_environment_lowers_what_the_driver_reports_never_raises_it() -> None:
    reported = DeviceMemory.of("gpu", 16 * 10**9, 4 * 10**9, environ={})
    assert (reported.global_bytes, reported.max_alloc_bytes, reported.why) == (16 * 10**9, 4 * 10**9, "")
    small = DeviceMemory.of("gpu", 16 * 10**9, 4 * 10**9, environ={GLOBAL_ENV: "2G", MAX_ALLOC_ENV: "512M"})
    assert (small.global_bytes, small.max_alloc_bytes) == (2 * 10**9, 512 * 10**6)
    assert f"${GLOBAL_ENV} 2G" in small.why and f"${MAX_ALLOC_ENV} 512M" in small.why
    assert DeviceMemory.of("gpu", 10**9, 10**8, environ={GLOBAL_ENV: "1T"}).global_bytes == 10**9
    # a global memory below the largest allocation lowers that too
    assert DeviceMemory.of("gpu", 10**9, 10**8, environ={GLOBAL_ENV: "50M"}).max_alloc_bytes == 50 * 10**6
    with pytest.raises(InputError, match=rf"\${GLOBAL_ENV}: must be a size"):
        DeviceMemory.of("gpu", 10**9, 10**8, environ={GLOBAL_ENV: "lots"})


def test_units_fitting_by_hand() -> None:
    device = DeviceMemory("gpu", 1000, 300)  # 800 bytes usable together, 300 in one buffer
    tables, out = DeviceBuffer("tables", 200.0), DeviceBuffer("out", 0.0, 50.0)
    assert device.units_fitting([tables, out]) == 6  # 300 / 50 per buffer; (800 - 200) / 50 = 12 together
    # scratch alone: (300 - 100) / 60 = 3.3; together (800 - 300) / 110 = 4.5; out alone 6
    assert device.units_fitting([tables, out, DeviceBuffer("scratch", 100.0, 60.0)]) == 3
    assert device.units_fitting([tables, out, DeviceBuffer("scratch", 100.0, 40.0)]) == 5  # (800 - 300) / 90
    assert device.units_fitting([DeviceBuffer("huge", 301.0)]) == 0
    assert device.units_fitting([tables], most=7) == 7
    with pytest.raises(ResourceError) as err:
        device.require([tables, out], 7, what="a test", key="sweep.chunk", source=None)
    line = str(err.value)
    assert "\n" not in line and line.startswith("sweep.chunk: a test needs about")
    assert "gpu offers" in line and "(out)" in line


def test_the_runtime_reports_the_device_and_honours_the_seam(rt, monkeypatch) -> None:
    monkeypatch.delenv(GLOBAL_ENV, raising=False)
    monkeypatch.delenv(MAX_ALLOC_ENV, raising=False)
    assert rt.memory.global_bytes == int(rt.device.global_mem_size) > 0
    assert rt.memory.max_alloc_bytes == int(rt.device.max_mem_alloc_size) > 0
    monkeypatch.setenv(GLOBAL_ENV, "300M")
    monkeypatch.setenv(MAX_ALLOC_ENV, "100M")
    assert (rt.global_mem_bytes, rt.max_alloc_bytes) == (300 * 10**6, 100 * 10**6)
    assert rt.memory.name == rt.name


# -- the planner sizes chunks to the device --------------------------------------------------------------------

def _pitch(pixels: int) -> int:
    """Pixels padded to the widest work-item (16 lanes): the planner's bound, whatever lanes the device takes."""
    return math.ceil(pixels / 16) * 16


def _tables_bytes(job, fp64: bool) -> int:
    """What the sweep kernel uploads (float32; written here from the tables, not from the declarations), and the
    metrics kernel's float64 target where the metrics run on the device."""
    t = job.tables
    arrays = [np.concatenate(t.radiance), np.concatenate(t.centre)]
    arrays += [np.concatenate(t.values[n]) for n in t.per_row()]
    z = t.n_slots * _pitch(t.n_pixels) * 4
    return sum(a.size * 4 for a in arrays) + z + (8 * t.n_pixels if fp64 else 0)


def _per_config(pixels: int, fp64: bool) -> tuple[int, int]:
    """Device bytes per configuration in all and in its largest buffer: the float32 index and three uchar outputs
    per padded pixel; where the metrics run on the device, their 16 float64 columns and float64 scratch per pixel."""
    outputs = (4 + 1 + 1 + 1) * _pitch(pixels)
    if not fp64:
        return outputs, 4 * _pitch(pixels)
    return outputs + 16 * 8 + 8 * pixels, 8 * pixels


def test_a_small_device_sizes_the_chunks_and_the_results_stay_identical(rt, monkeypatch, tmp_path) -> None:
    from s2cl.app.plan import plan_sweep
    from s2cl.sweep.engine import run_sweep

    monkeypatch.delenv(GLOBAL_ENV, raising=False)
    monkeypatch.delenv(MAX_ALLOC_ENV, raising=False)
    scene, spec = gvmi_scene(), rt.info.spec
    free = plan_sweep(scene, budget=BIG, device=spec)
    n, pixels = free.n_configs, free.tables.n_pixels
    assert (n, pixels) == (641, 4920) and free.chunk == n  # unconstrained: one chunk
    total, largest = _per_config(pixels, rt.has_fp64)

    monkeypatch.setenv(MAX_ALLOC_ENV, str(largest * 40 + 100))  # the largest buffer: 40 configurations
    by_alloc = plan_sweep(scene, budget=BIG, device=spec)
    assert by_alloc.chunk == 40 and len(by_alloc.chunks()) == math.ceil(641 / 40) == 17
    monkeypatch.delenv(MAX_ALLOC_ENV)

    usable = _tables_bytes(free, rt.has_fp64) + 30.5 * total  # all buffers together: 30 configurations
    monkeypatch.setenv(GLOBAL_ENV, str(math.ceil(usable / 0.8)))
    by_global = plan_sweep(scene, budget=BIG, device=spec)
    assert by_global.chunk == 30 and len(by_global.chunks()) == 22

    results = [run_sweep(job, tmp_path / name, device=spec).read_bytes()
               for name, job in (("free", free), ("small", by_global))]
    assert [len(list((tmp_path / name / "chunks").iterdir())) for name in ("free", "small")] == [1, 22]
    assert results[0] == results[1]


def test_a_device_too_small_for_one_configuration_is_refused_in_one_line(rt, monkeypatch) -> None:
    from s2cl.app.plan import plan_sweep

    monkeypatch.setenv(GLOBAL_ENV, "200K")
    with pytest.raises(ResourceError) as err:
        plan_sweep(gvmi_scene(), budget=BIG, device=rt.info.spec)
    line = str(err.value)
    assert "\n" not in line and "of device memory" in line and rt.name in line and f"${GLOBAL_ENV} 200K" in line
    assert err.value.key in ("surface.copies", "sweep.step_nm")
    monkeypatch.setenv(GLOBAL_ENV, "100G")  # a chunk asked for that the device's largest buffer cannot hold
    monkeypatch.setenv(MAX_ALLOC_ENV, "1M")
    # 10⁶ bytes / the scratch's or the index's bytes per configuration
    most = 10**6 // _per_config(4920, rt.has_fp64)[1]
    with pytest.raises(ResourceError, match=rf"--chunk: .* in chunks of 600 needs .* device memory.*at most {most} "):
        plan_sweep(gvmi_scene(), budget=BIG, device=rt.info.spec, chunk=600)


def test_the_cli_refuses_a_device_too_small_in_one_line(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(SMALL_SWEEP_TOML.format(copies=2))
    out = run("sweep", "count", "-q", str(path), cwd=tmp_path, env={GLOBAL_ENV: "20K"})
    line = one_line_error(out, "s.toml: ", "of device memory", f"${GLOBAL_ENV} 20K", "16 kB (80% of 20 kB)")
    assert "s.toml: surface.copies: " in line or "s.toml: sweep.step_nm: " in line
    out = run("optimise", "-q", str(path), "-o", "out", cwd=tmp_path, env={GLOBAL_ENV: "20K"})
    assert one_line_error(out, "of device memory").split("needs")[0] == line.split("needs")[0]
    assert not (tmp_path / "out").exists()


# -- the declared buffers are what the kernels allocate ----------------------------------------------------------

def test_the_declared_device_buffers_are_what_the_sweep_allocates(rt, monkeypatch) -> None:
    """Every buffer the sweep and metrics kernels request (recorded where the runtime creates them) against
    :func:`s2cl.sweep.device_footprint.sweep_device_buffers` at the kernel's own lanes: the same total within 64
    bytes (an empty SAM reference table still takes one element), the same largest buffer."""
    from s2cl.forward.stages import stage
    from s2cl.retrieve.metric import REGRESSION
    from s2cl.sweep.device_footprint import SweepSizes, sweep_device_buffers
    from s2cl.sweep.kernel import SweepKernel

    sizes: list[int] = []
    to_device, alloc = rt.to_device, rt.alloc

    def record_upload(array, **kw):
        sizes.append(max(np.asarray(array).nbytes, 1))
        return to_device(array, **kw)

    def record_alloc(nbytes):
        sizes.append(int(nbytes))
        return alloc(nbytes)

    monkeypatch.setattr(rt, "to_device", record_upload)
    monkeypatch.setattr(rt, "alloc", record_alloc)
    job = gvmi_job(copies=7)
    t = job.tables
    kernel = SweepKernel(t, job.analysis, rt)
    n = 13
    kernel.metrics(0, n)
    declared = sweep_device_buffers([stage(s) for s in t.stages], SweepSizes(
        variants=sum(t.counts), spectra=t.n_spectra, copies=t.copies, slots=t.n_slots, lanes=kernel.T.lanes),
        real_bytes=kernel.T.dtype.itemsize, device_metrics=rt.has_fp64, metric=REGRESSION)
    expected = sum(b.bytes(n) for b in declared)
    assert expected <= sum(sizes) <= expected + 64, (sizes, declared)
    assert max(sizes) == max(b.bytes(n) for b in declared)


# -- the forward engines' launches are sized to the device too --------------------------------------------------

def test_a_small_device_sizes_the_resampling_and_sensing_launches(rt, monkeypatch) -> None:
    from s2cl.forward.resample import ResamplePlan, Resampler
    from s2cl.forward.sense import Radiometry, Sensing
    from s2cl.grid import DEFAULT_GRID
    from s2cl.scene.effects import EffectSet
    from s2cl.sensor.sensor import Sensor

    monkeypatch.delenv(GLOBAL_ENV, raising=False)
    monkeypatch.delenv(MAX_ALLOC_ENV, raising=False)
    bands = Sensor.sentinel2().bands
    plan = ResamplePlan(tuple(b.name for b in bands), tuple(b.weights(DEFAULT_GRID) for b in bands),
                        DEFAULT_GRID.size)
    spectra = np.random.default_rng(1).uniform(0, 300, (3001, DEFAULT_GRID.size)).astype(np.float32)
    radiometry = Radiometry.of(bands, 12)
    radiance = np.random.default_rng(2).uniform(0, 200, (13, 3001))
    free = Resampler(rt, plan)(spectra), Sensing(rt, radiometry, EffectSet())(radiance, seed=3)
    assert Resampler(rt, plan).default_chunk() > 3001

    # the largest buffer per spectrum is its float32 input: the grid's wavelengths; per pixel of sensing a float32
    # band image (13 bands: the radiance in, the noisy and calibrated images out)
    monkeypatch.setenv(MAX_ALLOC_ENV, str(4 * DEFAULT_GRID.size * 700 + 10))
    resampler = Resampler(rt, plan)
    assert resampler.default_chunk() == 700
    assert np.array_equal(resampler(spectra), free[0])
    monkeypatch.setenv(MAX_ALLOC_ENV, str(4 * 13 * 500 + 10))
    sensing = Sensing(rt, radiometry, EffectSet())
    assert sensing.default_chunk() == 500
    small = sensing(radiance, seed=3)
    assert free[1].outputs.keys() == small.outputs.keys()
    for name, image in free[1].outputs.items():
        assert np.array_equal(image, small.outputs[name]), name
    monkeypatch.setenv(MAX_ALLOC_ENV, "10")
    with pytest.raises(ResourceError, match=r"^grid.step_nm: resampling .* of device memory"):
        Resampler(rt, plan).default_chunk()


def test_simulate_refuses_a_device_too_small_in_one_line_before_any_work(tmp_path: Path) -> None:
    out = run("simulate", "-q", "default", "-o", "out", cwd=tmp_path, env={GLOBAL_ENV: "20K"})
    one_line_error(out, "default.toml: grid.step_nm: resampling ", "of device memory", f"${GLOBAL_ENV} 20K")
    assert not (tmp_path / "out").exists()


def test_the_declared_forward_buffers_are_what_resampling_and_sensing_allocate(rt, monkeypatch) -> None:
    """The resampling and sensing launches' buffers (recorded where the runtime creates them, the resampler's
    weights and atmosphere included) against their declarations for one launch of ``n`` pixels: the same bytes."""
    from s2cl.forward.resample import ResamplePlan, Resampler
    from s2cl.forward.sense import Radiometry, Sensing
    from s2cl.grid import DEFAULT_GRID
    from s2cl.scene.effects import EffectSet
    from s2cl.sensor.sensor import Sensor

    sizes: list[int] = []
    to_device, output, empty = rt.to_device, rt.output, rt.empty

    def record_upload(array, **kw):
        sizes.append(np.asarray(array).nbytes)
        return to_device(array, **kw)

    def record_output(shape, dtype):
        sizes.append(int(np.prod(shape)) * np.dtype(dtype).itemsize)
        return output(shape, dtype)

    def record_empty(nbytes):
        sizes.append(int(nbytes))
        return empty(nbytes)

    monkeypatch.setattr(rt, "to_device", record_upload)
    monkeypatch.setattr(rt, "output", record_output)
    monkeypatch.setattr(rt, "empty", record_empty)
    bands, n, grid = Sensor.sentinel2().bands, 997, DEFAULT_GRID
    plan = ResamplePlan(tuple(b.name for b in bands), tuple(b.weights(grid) for b in bands), grid.size)

    class Terms:
        path_radiance = ground_term = spherical_albedo = np.full(grid.size, 0.1)

    resampler = Resampler(rt, plan, atmosphere=Terms())
    resampler(np.full((n, grid.size), 0.2, np.float32))
    declared = sum(b.bytes(n) for b in resampler.device_buffers())
    assert sum(sizes) == declared, (sizes, resampler.device_buffers())
    sizes.clear()
    sensing = Sensing(rt, Radiometry.of(bands, 12), EffectSet())
    sensing(np.full((13, n), 50.0), seed=1)
    assert sum(sizes) == sum(b.bytes(n) for b in sensing.device_buffers()), (sizes, sensing.device_buffers())
