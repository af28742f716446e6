"""Shared fixtures: the OpenCL runtime (PoCL CPU unless PYOPENCL_CTX says otherwise), precisions and
the lane widths every vectorised kernel is tested at.

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

#: Pixels per work-item forced in the kernel tests, whatever this CPU's own width: an AVX-512
#: machine runs the AVX2 widths (8) and the others; on an AVX2 machine 16 falls back to 8
#: (s2cl.cl.devices.choose_lanes), which the same tests then check.
FORCED_LANES = (1, 4, 8, 16)


@pytest.fixture(scope="session")
def rt() -> Runtime:
    """The process-wide OpenCL runtime."""
    return get_runtime()


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
