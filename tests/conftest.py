"""Shared fixtures: the OpenCL runtime (PoCL CPU unless PYOPENCL_CTX says otherwise)."""

from __future__ import annotations

import pytest

from s2cl.runtime import Runtime, get_runtime


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
