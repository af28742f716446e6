"""Shared fixtures: the OpenCL runtime, precisions and the lane widths every vectorised kernel is tested at.

The kernel tests (those taking the ``rt`` fixture) run on every OpenCL device named by ``--device SPEC``
(repeatable; ``all``: every device that builds) or ``$S2CL_TEST_DEVICES`` (comma-separated, or ``all``);
by default on ``$PYOPENCL_CTX`` where it is set, else on one device of every PoCL CPU driver that builds kernels
here (the wheel's and the distribution's, where both are installed), so one test run covers each driver. One chosen
device also becomes ``$PYOPENCL_CTX`` for the rest of the run (the CLI's subprocesses included).

Kernel builds that warn fail the tests (``S2CL_BUILD_WARNINGS=error``, inherited by the CLI runs in
subprocesses): a compiler warning on one CPU is how the AVX2 lane problem showed itself.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from s2cl.cl.builds import STRICT_ENV
from s2cl.cl.runtime import Runtime, get_runtime

os.environ.setdefault(STRICT_ENV, "error")
DEVICES_ENV = "S2CL_TEST_DEVICES"
_TEST_DEVICES: list[str] = []


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--device", action="append", default=[], metavar="SPEC",
                     help="OpenCL device for the kernel tests: PLATFORM:DEVICE or part of a name (repeat for "
                          f"several; 'all': every device that builds); default ${DEVICES_ENV}, else $PYOPENCL_CTX, "
                          "else every PoCL CPU driver that builds")


def _kernel_test_devices(asked: list[str]) -> list[str]:
    """The PLATFORM:DEVICE specs the kernel tests run on (see the module doc); a spec that matches no device,
    or names one that builds nothing, is a usage error."""
    from s2cl.cl.devices import builds_at_all, list_devices, select
    from s2cl.errors import S2CLError

    infos = list_devices()
    if not asked:
        if os.environ.get("PYOPENCL_CTX"):
            try:
                return [select(os.environ["PYOPENCL_CTX"])[1].spec]
            except S2CLError as err:
                raise pytest.UsageError(f"$PYOPENCL_CTX: {err}") from None
        pocl = [i for i in infos if "portable computing language" in i.platform.lower() and "CPU" in i.kind]
        per_driver = {}  # one device per driver: $POCL_DEVICES can list several of one driver
        for info in pocl:
            if info.platform_index not in per_driver and builds_at_all(info) is None:
                per_driver[info.platform_index] = info.spec
        return list(per_driver.values()) or [get_runtime().info.spec]
    if [a.strip().lower() for a in asked] == ["all"]:
        return [i.spec for i in infos if builds_at_all(i) is None]
    specs = []
    for spec in asked:
        try:
            info = select(spec.strip())[1]
        except S2CLError as err:
            raise pytest.UsageError(f"--device {spec}: {err}") from None
        said = builds_at_all(info)
        if said is not None:
            raise pytest.UsageError(f"--device {spec}: {info} cannot compile s2cl's kernels ({said})")
        specs.append(info.spec)
    return list(dict.fromkeys(specs))


_NO_DEVICE: list[str] = []


def pytest_configure(config: pytest.Config) -> None:
    from s2cl.errors import S2CLError

    asked = config.getoption("device") or [s for s in os.environ.get(DEVICES_ENV, "").split(",") if s.strip()]
    try:
        _TEST_DEVICES[:] = _kernel_test_devices(asked)
    except S2CLError as err:  # no device builds here: the kernel tests fail with the reason, the others run
        _NO_DEVICE[:] = [str(err)]
        return
    if len(_TEST_DEVICES) == 1:
        os.environ["PYOPENCL_CTX"] = _TEST_DEVICES[0]


def pytest_report_header(config: pytest.Config) -> str:
    from s2cl.cl.devices import select

    if _NO_DEVICE:
        return "kernel tests: no OpenCL device: " + _NO_DEVICE[0]
    return "kernel tests on: " + "; ".join(str(select(s)[1]) for s in _TEST_DEVICES)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """``-m kernel`` selects the tests that run kernels on the device under test (tools/gpu_check.sh, cpu_check.sh)."""
    for item in items:
        if "rt" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.kernel)


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "rt" in metafunc.fixturenames and len(_TEST_DEVICES) > 1:
        metafunc.parametrize("rt", _TEST_DEVICES, indirect=True, scope="session",
                             ids=[f"dev{s}" for s in _TEST_DEVICES])

#: Pixels per work-item forced in the kernel tests, whatever this CPU's own width: an AVX-512
#: machine runs the AVX2 widths (8) and the others; on an AVX2 machine 16 falls back to 8
#: (s2cl.cl.devices.choose_lanes), which the same tests then check.
FORCED_LANES = (1, 4, 8, 16)


@pytest.fixture(scope="session")
def rt(request) -> Runtime:
    """The OpenCL runtime of the device under test (one per device where several are tested)."""
    if _NO_DEVICE:
        pytest.fail(f"no OpenCL device for the kernel tests: {_NO_DEVICE[0]}", pytrace=False)
    return get_runtime(getattr(request, "param", None) or _TEST_DEVICES[0])


@pytest.fixture(params=["float32", "float64"])
def real_t(request, rt: Runtime) -> str:
    """Both precisions; float64 is skipped on devices without cl_khr_fp64."""
    if request.param == "float64" and not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    return request.param


@pytest.fixture(params=FORCED_LANES, ids=[f"lanes{n}" for n in FORCED_LANES])
def lanes(request) -> int:
    """A forced lane count (pixels per work-item) for the vectorised kernels."""
    return request.param


REPO = Path(__file__).resolve().parent.parent


@pytest.fixture
def bench_path() -> Iterator[None]:
    """The repository's ``bench/`` importable for the test (skipped where only the installed package is)."""
    if not (REPO / "bench" / "__init__.py").is_file():
        pytest.skip("bench/ is not in this checkout (installed package only)")
    sys.path.insert(0, str(REPO))
    try:
        yield
    finally:
        sys.path.remove(str(REPO))
