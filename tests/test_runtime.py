"""OpenCL runtime: device choice, errors, program cache, quirks."""

from __future__ import annotations

import logging
import os
import re
import subprocess
import sys

import pytest

from s2cl.cl import devices, runtime
from s2cl.cl.builds import STRICT_ENV
from s2cl.cl.devices import LANES_ENV, choose_lanes, list_devices
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.errors import BuildError, DeviceError, InputError


def test_default_device_is_the_widest_building_pocl_cpu(rt: Runtime) -> None:
    """The default (no device named) is, of the PoCL CPU devices here that build, the first whose clean float32
    width is widest; computed from this machine's devices, not assumed (the test device may be another)."""
    infos = list_devices()
    assert infos, "no OpenCL device at all"
    pocl = [i for i in infos if "portable computing language" in i.platform.lower() and "CPU" in i.kind
            and devices.builds_at_all(i) is None]
    if not pocl:
        pytest.skip("no PoCL CPU device builds here")
    widest = max(devices.widths_of(i).clean["float32"] for i in pocl)
    assert devices.select(None)[1] == next(i for i in pocl if devices.widths_of(i).clean["float32"] == widest)


def _others(rt: Runtime) -> list[devices.DeviceInfo]:
    return [i for i in list_devices() if i != rt.info]


def _unique_part(rt: Runtime) -> str | None:
    """A part of the device's name that no other device here has in its name or platform (None: there is none)."""
    name = rt.info.name
    parts = sorted({name[a:b] for a in range(len(name)) for b in range(a + 3, len(name) + 1)},
                   key=lambda part: (len(part), part))  # a fixed order: a set's changes with the hash seed
    return next((part for part in parts if part.lower() != name.lower() and part == part.strip()
                 and not re.fullmatch(r"[\d:]+", part)  # digits are indices ("512" is platform 512), not a name
                 and not any(part.lower() in i.name.lower() or part.lower() in i.platform.lower()
                             for i in _others(rt))), None)


def test_device_by_index_and_by_name(rt: Runtime) -> None:
    """Indices always name the device; its full name does where no other device has that name; a part of its name
    does where no other device has that part (computed from the devices here, whatever they are)."""
    assert Runtime(rt.info.spec).info == rt.info
    twins = [i for i in _others(rt) if i.name.lower() == rt.info.name.lower()]
    if twins:
        with pytest.raises(DeviceError, match="ambiguous") as err:
            Runtime(rt.info.name)
        assert all(i.spec in str(err.value) for i in [rt.info, *twins])
    else:
        assert Runtime(rt.info.name.upper()).info == rt.info
    part = _unique_part(rt)
    if part is not None:
        assert Runtime(part).info == rt.info


def test_a_part_of_a_name_that_several_devices_share_is_refused(rt: Runtime) -> None:
    """On this machine: every name part that another device also has is refused, listing each match by indices."""
    shared = [i for i in _others(rt) if rt.info.platform.lower() in i.platform.lower()]
    if not shared:
        pytest.skip("no other device here shares this device's platform name")
    with pytest.raises(DeviceError, match="ambiguous") as err:
        Runtime(rt.info.platform)
    said = str(err.value)
    assert "\n" not in said
    for info in [rt.info, *shared]:
        assert f"{info.spec} {info.name}" in said


def _infos(*names: str) -> list[devices.DeviceInfo]:
    """Devices with these names, one platform per name prefix before '/': 'A/x' is device x of platform A."""
    platforms = list(dict.fromkeys(n.split("/")[0] for n in names))
    out, counts = [], dict.fromkeys(platforms, 0)
    for n in names:
        platform, name = n.split("/")
        out.append(devices.DeviceInfo(platforms.index(platform), counts[platform], platform, name, "ALL | CPU"))
        counts[platform] += 1
    return out


@pytest.mark.parametrize(("names", "spec", "chosen"), [
    (("pocl31/pthread-skylake-avx512-EPYC", "pocl30/pthread-EPYC"), "skylake", "0:0"),  # one match
    (("pocl31/pthread-skylake-avx512-EPYC", "pocl30/pthread-EPYC"), "PTHREAD-epyc", "1:0"),  # a full name, any case
    (("pocl31/pthread-skylake-avx512-EPYC", "pocl30/pthread-EPYC"), "pthread", None),  # two drivers: ambiguous
    (("pocl/pthread-EPYC", "pocl/pthread-EPYC"), "pthread-EPYC", None),  # POCL_DEVICES="pthread pthread"
    (("pocl/pthread-EPYC", "pocl/basic-EPYC"), "basic", "0:1"),  # POCL_DEVICES="pthread basic"
    (("pocl/pthread-EPYC", "pocl/basic-EPYC"), "epyc", None),
    (("pocl/pthread-EPYC", "pocl/basic-EPYC"), "pocl", None),  # a platform name shared by both
    (("pocl/pthread-EPYC", "NVIDIA CUDA/NVIDIA H100"), "nvidia", "1:0"),  # device and platform of one device
    (("pocl/pthread-EPYC", "pocl/basic-EPYC"), "1:0", None),  # no such indices: nothing matches
])
def test_a_name_must_name_one_device(monkeypatch, names, spec, chosen) -> None:
    """The rule by hand, on listed devices: one match, or one device's full name; else refused with every match."""
    infos = _infos(*names)
    if chosen is None and ":" not in spec:
        with pytest.raises(DeviceError, match="ambiguous") as err:
            devices._match(spec, infos)
        hits = [i for i in infos if spec.lower() in i.name.lower() or spec.lower() in i.platform.lower()]
        assert len(hits) > 1 and all(str(i) in str(err.value) for i in hits)
    else:
        got = devices._match(spec, infos)
        assert (got.spec if got else None) == chosen


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
    monkeypatch.setattr(devices, "_platforms", lambda: [])
    with pytest.raises(DeviceError) as err:
        Runtime()
    assert "pyopencl[pocl]" in str(err.value)


def test_build_error_carries_device_options_log_and_source(rt: Runtime, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("S2CL_CACHE", str(tmp_path))  # the failing source is kept in the user cache, not in /tmp
    source = "__kernel void broken(__global float *x) { x[0] = undefined_name; }\n"
    with pytest.raises(BuildError) as err:
        rt.build(source, template="broken.cl.mako", options=["-DS2_TEST_OPTION"])
    e = err.value
    assert e.device == rt.name
    assert "-DS2_TEST_OPTION" in e.options
    assert "undefined_name" in e.log
    assert e.source_path.read_text() == source and e.source_path.parent == tmp_path / "failed-builds"
    assert str(e.source_path) in str(e)


def test_program_cache_keys_on_source_and_options(rt: Runtime) -> None:
    source = "__kernel void k(__global float *x) { x[get_global_id(0)] = 1.0f; }\n"
    a = rt.build(source, template="t")
    assert rt.build(source, template="t") is a
    assert rt.build(source, template="t", options=["-DX=1"]) is not a


@pytest.mark.parametrize(
    ("clean", "kind", "requested", "lanes", "replaced"),
    [(16, "ALL | CPU", None, 16, False),   # PoCL, AVX-512, float32
     (8, "ALL | CPU", None, 8, False),     # PoCL, AVX2 (or AVX-512 float64)
     (4, "CPU", None, 4, False),           # AVX2 float64
     (8, "ALL | CPU", 16, 8, True),        # float16 on AVX2 warns "changes the ABI": capped
     (8, "ALL | CPU", 4, 4, False),        # narrower than native: as asked
     (16, "ALL | GPU", None, 1, False),    # GPUs vectorise across work-items
     (16, "GPU", 16, 16, False),           # ... and take any clean width on request
     (4, "GPU", 16, 4, True),              # ... but not one their compiler warns on
     (4, "ACCELERATOR", None, 1, False)],
)
def test_lane_choice_from_device_attributes(clean, kind, requested, lanes, replaced) -> None:
    got, why = choose_lanes(clean=clean, device_type=kind, requested=requested)
    assert got == lanes
    assert (why is not None) == replaced


def test_lane_choice_refuses_widths_opencl_lacks() -> None:
    with pytest.raises(InputError, match="lanes: must be one of"):
        choose_lanes(clean=8, device_type="CPU", requested=3)


def test_runtime_caps_lanes_on_a_narrower_cpu(rt: Runtime, monkeypatch, caplog) -> None:
    """An AVX2 device (8 floats, 4 doubles build clean), whatever this machine is: forced 16 lanes fall back,
    with a DEBUG record and no failure; the kernels then build at that width."""
    if "CPU" not in rt.info.kind:
        pytest.skip("CPU-device rule")
    from s2cl.cl.probe import Widths

    avx2 = Widths({"float32": 16, "float64": 8}, {"float32": 8, "float64": 4})
    monkeypatch.setattr(Runtime, "widths", property(lambda self: avx2))
    caplog.set_level(logging.DEBUG, logger="s2cl")
    assert rt.lanes("float32") == 8 and rt.lanes("float64") == 4
    assert rt.lanes("float32", 16) == 8
    said = "16 lanes do not build cleanly on this device (widest clean width 8)"
    assert any(said in r.message for r in caplog.records)
    from s2cl.retrieve.igrm import IgrmFitter

    assert IgrmFitter(rt, 4, lanes=16).types.lanes == 8


def test_lanes_from_environment(rt: Runtime, monkeypatch) -> None:
    monkeypatch.setenv(LANES_ENV, "4")
    assert rt.lanes("float32") == 4
    assert rt.lanes("float32", 1) == 1  # an explicit argument wins
    monkeypatch.setenv(LANES_ENV, "six")
    with pytest.raises(InputError, match=LANES_ENV):
        rt.lanes("float32")


WARNING_SOURCE = ("float f(float a) { if (a > 0.0f) return a; }\n"
                  "__kernel void k(__global float *x) { x[0] = f(x[0]); }\n")


def test_build_log_is_debug_not_terminal(tmp_path) -> None:
    """A kernel that compiles with a warning, in a fresh process with PoCL's kernel cache off (PoCL's
    clang then prints "1 warning generated." straight to file descriptor 2, as PoCL 3.0 does on every
    build): nothing reaches stdout or stderr; the log is a DEBUG record of ``s2cl.cl.runtime``."""
    script = tmp_path / "build.py"
    script.write_text(
        "import logging, sys\n"
        "logging.basicConfig(stream=sys.stdout, level=logging.DEBUG, format='%(name)s|%(message)s')\n"
        "from s2cl.cl.runtime import get_runtime\n"
        f"get_runtime().build({WARNING_SOURCE!r}, template='warns.cl')\n")
    env = {k: v for k, v in os.environ.items() if k != STRICT_ENV} | {"POCL_KERNEL_CACHE": "0"}
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stderr == ""
    logged = [line for line in out.stdout.splitlines() if line.startswith("s2cl.cl.runtime|")]
    assert any("warns.cl" in line for line in logged) and "does not return a value" in out.stdout


def test_strict_builds_refuse_warnings(rt: Runtime, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(STRICT_ENV, "error")
    monkeypatch.setenv("S2CL_CACHE", str(tmp_path))
    with pytest.raises(BuildError) as err:
        rt.build(WARNING_SOURCE + "/* strict */\n", template="warns.cl")  # (PoCL's cache keeps the log)
    assert err.value.reason and STRICT_ENV in err.value.reason
    assert "does not return a value" in err.value.log


def test_default_device_compiles(rt: Runtime) -> None:
    """The device under test builds kernels (a PoCL that cannot is skipped, see below)."""
    assert devices.builds_at_all(rt.info) is None


def test_default_skips_a_device_that_cannot_compile(monkeypatch) -> None:
    infos = list_devices()
    broken = infos[0]
    real = devices.builds_at_all
    monkeypatch.setattr(devices, "builds_at_all", lambda info: "error: unknown target CPU 'generic'"
                        if info == broken else real(info))
    if any(real(i) is None for i in infos[1:]):  # another device that really compiles is chosen instead
        assert devices._first_working(infos) != broken
    with pytest.raises(DeviceError) as err:
        devices._first_working([broken])
    assert "unknown target CPU" in str(err.value)
    assert "pocl-opencl-icd" in str(err.value)


def test_compiled_kernels_persist_in_the_user_cache(tmp_path) -> None:
    """A fresh process puts PoCL's compiled kernels in s2cl's cache folder ($S2CL_CACHE/pocl); a
    $POCL_CACHE_DIR the user set wins."""
    script = tmp_path / "build.py"
    script.write_text(
        "import os\n"
        "from s2cl.cl.runtime import get_runtime\n"
        "get_runtime().build('__kernel void k(__global float *a) { a[0] = 1.0f; } /* cache test */', "
        "template='cached.cl')\n"
        "print(os.environ['POCL_CACHE_DIR'])\n")
    env = {k: v for k, v in os.environ.items() if k != "POCL_CACHE_DIR"} | {"S2CL_CACHE": str(tmp_path / "c")}
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == str(tmp_path / "c" / "pocl")
    if "Portable Computing Language" in get_runtime().info.platform:
        assert any((tmp_path / "c" / "pocl").rglob("*")), "PoCL wrote nothing into its cache folder"
    mine = tmp_path / "mine"
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         env=env | {"POCL_CACHE_DIR": str(mine)}, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == str(mine)
