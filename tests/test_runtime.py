"""OpenCL runtime: device choice, errors, program cache, quirks."""

from __future__ import annotations

import pytest

from s2cl import runtime
from s2cl.errors import BuildError, DeviceError
from s2cl.runtime import Runtime, get_runtime, list_devices, preferred_lanes


def test_default_device_is_pocl_cpu(rt: Runtime) -> None:
    assert list_devices(), "no OpenCL device at all"
    if any("portable computing language" in d.platform.lower() for d in list_devices()):
        assert "portable computing language" in rt.info.platform.lower()
        assert "CPU" in rt.info.kind


def test_device_by_index_and_by_name(rt: Runtime) -> None:
    by_index = Runtime(rt.info.spec)
    assert by_index.info == rt.info
    by_name = Runtime(rt.info.name.split()[0][:6])
    assert by_name.info.name == rt.info.name


def test_unknown_device_lists_available(rt: Runtime) -> None:
    with pytest.raises(DeviceError) as err:
        Runtime("no-such-device-xyz")
    assert "no-such-device-xyz" in str(err.value)
    assert rt.info.name in str(err.value)
    with pytest.raises(DeviceError):
        Runtime("7:3")


def test_pyopencl_ctx_is_honoured(monkeypatch, rt: Runtime) -> None:
    monkeypatch.setattr(runtime, "_RUNTIMES", {})
    monkeypatch.setenv("PYOPENCL_CTX", "no-such-device-xyz")
    with pytest.raises(DeviceError):
        get_runtime()
    monkeypatch.setenv("PYOPENCL_CTX", rt.info.spec)
    assert get_runtime().info == rt.info


def test_no_platform_says_how_to_install(monkeypatch) -> None:
    monkeypatch.setattr(runtime, "_platforms", lambda: [])
    with pytest.raises(DeviceError) as err:
        Runtime()
    assert "pyopencl[pocl]" in str(err.value)


def test_build_error_carries_device_options_log_and_source(rt: Runtime) -> None:
    source = "__kernel void broken(__global float *x) { x[0] = undefined_name; }\n"
    with pytest.raises(BuildError) as err:
        rt.build(source, template="broken.cl.mako", options=["-DS2_TEST_OPTION"])
    e = err.value
    assert e.device == rt.name
    assert "-DS2_TEST_OPTION" in e.options
    assert "undefined_name" in e.log
    assert e.source_path.read_text() == source
    assert str(e.source_path) in str(e)


def test_program_cache_keys_on_source_and_options(rt: Runtime) -> None:
    source = "__kernel void k(__global float *x) { x[get_global_id(0)] = 1.0f; }\n"
    a = rt.build(source, template="t")
    assert rt.build(source, template="t") is a
    assert rt.build(source, template="t", options=["-DX=1"]) is not a


@pytest.mark.parametrize(
    ("platform", "kind", "lanes"),
    [("Portable Computing Language", "ALL | CPU", 8), ("NVIDIA CUDA", "ALL | GPU", 1),
     ("Intel(R) OpenCL", "CPU", 8), ("AMD Accelerated Parallel Processing", "GPU", 1), ("Other", "ACCELERATOR", 1)],
)
def test_lane_quirk(platform: str, kind: str, lanes: int) -> None:
    assert preferred_lanes(platform, kind) == lanes


def test_default_device_compiles(rt: Runtime) -> None:
    """The default device is one that builds kernels (a PoCL that cannot is skipped, see below)."""
    assert runtime._builds(rt.info) is None


def test_default_skips_a_device_that_cannot_compile(monkeypatch) -> None:
    infos = list_devices()
    broken = infos[0]
    real = runtime._builds
    monkeypatch.setattr(runtime, "_builds", lambda info: "error: unknown target CPU 'generic'"
                        if info == broken else real(info))
    if any(real(i) is None for i in infos[1:]):  # another device that really compiles is chosen instead
        assert runtime._first_working(infos) != broken
    with pytest.raises(DeviceError) as err:
        runtime._first_working([broken])
    assert "unknown target CPU" in str(err.value)
    assert "pocl-opencl-icd" in str(err.value)
