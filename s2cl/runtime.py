"""The only module that sets up OpenCL: device choice, context, queue, program cache, builds.

Device choice, in order: the ``device`` argument (CLI ``--device``), then the
``PYOPENCL_CTX`` environment variable, then the first PoCL CPU device. A device is named
either as ``PLATFORM:DEVICE`` indices (as ``PYOPENCL_CTX`` takes them) or by a
case-insensitive substring of its platform or device name (``pocl``, ``nvidia``, ``H100``).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from .errors import BuildError, DeviceError

INSTALL_HINT = (
    'install an OpenCL platform: `pip install "pyopencl[pocl]"` brings the PoCL CPU driver; '
    "for a GPU install its vendor's OpenCL ICD (e.g. the NVIDIA driver, ROCm, or intel-opencl-icd)"
)


@dataclass(frozen=True)
class DeviceInfo:
    """One OpenCL device as listed to the user."""

    platform_index: int
    device_index: int
    platform: str
    name: str
    kind: str

    @property
    def spec(self) -> str:
        return f"{self.platform_index}:{self.device_index}"

    def __str__(self) -> str:
        return f"{self.spec} {self.name} [{self.kind}] ({self.platform})"


def _cl():
    import pyopencl as cl

    return cl


def _platforms() -> list[Any]:
    cl = _cl()
    try:
        return list(cl.get_platforms())
    except cl.Error:  # pyopencl raises LogicError/RuntimeError when no ICD is found
        return []


def list_devices() -> list[DeviceInfo]:
    """All OpenCL devices on this machine."""
    cl = _cl()
    out = []
    for pi, platform in enumerate(_platforms()):
        try:
            devices = platform.get_devices()
        except cl.Error:
            continue
        for di, device in enumerate(devices):
            kind = cl.device_type.to_string(device.type)
            out.append(DeviceInfo(pi, di, platform.name.strip(), device.name.strip(), kind))
    return out


def _select(spec: str | None) -> tuple[Any, DeviceInfo]:
    infos = list_devices()
    if not infos:
        raise DeviceError("no OpenCL platform found: " + INSTALL_HINT)
    listing = "\n  ".join(str(i) for i in infos)
    if spec is None:
        chosen = _first_working(infos)
    else:
        chosen = _match(spec, infos)
        if chosen is None:
            raise DeviceError(f"no OpenCL device matches {spec!r}; available:\n  {listing}")
    device = _platforms()[chosen.platform_index].get_devices()[chosen.device_index]
    return device, chosen


NEWER_POCL_HINT = (
    "the PoCL in the pyopencl wheel (LLVM 14) does not know this CPU model (e.g. AMD Zen 5) and cannot "
    "compile for it; install your distribution's PoCL, which picks its code target from the CPU's features: "
    "`apt-get install pocl-opencl-icd` (Debian/Ubuntu; `bash tools/setup.sh` does it), then run again"
)

_PROBE = "__kernel void s2cl_probe(__global float *a) { a[get_global_id(0)] *= 2.0f; }"


def _builds(info: DeviceInfo) -> str | None:
    """None when ``info``'s device compiles a trivial kernel, else the build log."""
    cl = _cl()
    device = _platforms()[info.platform_index].get_devices()[info.device_index]
    try:
        cl.Program(cl.Context([device]), _PROBE).build()
    except cl.Error as exc:
        return str(exc)
    return None


def _first_working(infos: list[DeviceInfo]) -> DeviceInfo:
    """The default device: the first PoCL CPU device that compiles (else any device that does).

    Some machines carry two PoCL platforms (the wheel's and the distribution's); the wheel's cannot
    compile on CPUs that its LLVM does not know, so each candidate is probed with a trivial build
    (cached by PoCL after the first time, ~0.05 s).
    """
    pocl = [i for i in infos if "portable computing language" in i.platform.lower() and "CPU" in i.kind]
    logs = []
    for info in pocl + [i for i in infos if i not in pocl]:
        log = _builds(info)
        if log is None:
            return info
        errors = [line.strip() for line in log.splitlines() if "error" in line.lower()]
        logs.append(f"{info}: {errors[0] if errors else log.strip()[:200]}")
    text = " ".join(logs)
    hint = NEWER_POCL_HINT if "unknown target CPU" in text else INSTALL_HINT
    raise DeviceError("no OpenCL device could compile a kernel (" + "; ".join(logs) + "): " + hint)


def _match(spec: str, infos: list[DeviceInfo]) -> DeviceInfo | None:
    spec = spec.strip()
    parts = spec.split(":")
    if all(p.isdigit() for p in parts if p) and parts[0]:
        pi = int(parts[0])
        di = int(parts[1]) if len(parts) > 1 and parts[1] else 0
        return next((i for i in infos if i.platform_index == pi and i.device_index == di), None)
    needle = spec.lower()
    return next((i for i in infos if needle in i.name.lower() or needle in i.platform.lower()), None)


def preferred_lanes(platform: str, device_type: str) -> int:
    """Pixels per work-item (explicit ``floatN`` lanes) for the kernels that support it.

    PoCL on CPUs does not vectorise across work-items when a kernel body holds a loop or a
    builtin call (``shared/notes/pocl-performance.md``), so s2cl gives each work-item 8 pixels
    as explicit vectors there. GPUs vectorise across work-items in hardware: one pixel each.
    Kept in one place and unit-tested with fake attributes.
    """
    if "GPU" in device_type.upper():
        return 1
    if "portable computing language" in platform.lower() or "CPU" in device_type.upper():
        return 8
    return 1


class Runtime:
    """One OpenCL device with its context, queue and program cache."""

    def __init__(self, device_spec: str | None = None):
        cl = _cl()
        self.device, self.info = _select(device_spec)
        self.context = cl.Context([self.device])
        self.queue = cl.CommandQueue(self.context)
        self._programs: dict[tuple[str, tuple[str, ...]], Any] = {}

    @cached_property
    def has_fp64(self) -> bool:
        """Whether the device supports double precision."""
        return "cl_khr_fp64" in self.device.extensions

    @property
    def lanes(self) -> int:
        """Pixels per work-item for vectorised kernels on this device."""
        return preferred_lanes(self.info.platform, self.info.kind)

    @property
    def name(self) -> str:
        return f"{self.info.name} ({self.info.platform})"

    @property
    def max_alloc_bytes(self) -> int:
        return int(self.device.max_mem_alloc_size)

    @property
    def global_mem_bytes(self) -> int:
        return int(self.device.global_mem_size)

    def build(self, source: str, *, template: str, options: list[str] | tuple[str, ...] = ()) -> Any:
        """Build ``source`` (cached on source + options); :class:`BuildError` on failure."""
        cl = _cl()
        from .templates import include_options

        opts = tuple(include_options()) + tuple(options)
        key = (source, opts)
        program = self._programs.get(key)
        if program is not None:
            return program
        try:
            program = cl.Program(self.context, source).build(options=list(opts))
        except cl.Error as err:
            path = save_source(source, template)
            log = str(err)
            raise BuildError(template=template, device=self.name, options=list(opts), log=log,
                             source_path=path) from err
        self._programs[key] = program
        return program

    def kernel(self, program: Any, name: str) -> Any:
        """A kernel object from ``program`` (create once, reuse)."""
        return _cl().Kernel(program, name)

    def max_work_group_size(self, kernel: Any) -> int:
        cl = _cl()
        return int(kernel.get_work_group_info(cl.kernel_work_group_info.WORK_GROUP_SIZE, self.device))

    # -- buffers ---------------------------------------------------------------------------
    @cached_property
    def host_memory(self) -> bool:
        """Whether the device works in host memory (CPU devices such as PoCL)."""
        return "CPU" in self.info.kind

    def to_device(self, array: np.ndarray, *, zero_copy: bool = False) -> Any:
        """A read-only device buffer holding ``array`` (made C-contiguous).

        ``zero_copy=True`` lets a CPU device read the host array in place (``USE_HOST_PTR``):
        copying 10⁵ spectra into fresh buffers costs ten times the resampling kernel. The caller
        must then keep the returned buffer referenced until the work that reads it has finished
        (e.g. until a blocking fetch of its results); pyopencl holds the array as long as the buffer
        lives. Other devices, and the default, copy.
        """
        cl = _cl()
        host = np.ascontiguousarray(array)
        if host.nbytes == 0:
            host = np.zeros(1, dtype=host.dtype)
        where = cl.mem_flags.USE_HOST_PTR if (zero_copy and self.host_memory) else cl.mem_flags.COPY_HOST_PTR
        return cl.Buffer(self.context, cl.mem_flags.READ_ONLY | where, hostbuf=host)

    def empty(self, nbytes: int) -> Any:
        """An uninitialised read-write device buffer of ``nbytes``."""
        cl = _cl()
        return cl.Buffer(self.context, cl.mem_flags.READ_WRITE, size=max(int(nbytes), 1))

    def zeros(self, nbytes: int) -> Any:
        cl = _cl()
        buf = self.empty(nbytes)
        cl.enqueue_fill_buffer(self.queue, buf, np.uint8(0), 0, max(int(nbytes), 1))
        return buf

    def fetch(self, buffer: Any, shape: tuple[int, ...], dtype: Any) -> np.ndarray:
        """Copy a device buffer back into a new host array (blocking)."""
        cl = _cl()
        out = np.empty(shape, dtype=dtype)
        if out.nbytes:
            cl.enqueue_copy(self.queue, out, buffer)
        return out

    def upload(self, buffer: Any, array: np.ndarray) -> None:
        """Copy a host array into an existing device buffer (blocking)."""
        _cl().enqueue_copy(self.queue, buffer, np.ascontiguousarray(array))

    def finish(self) -> None:
        self.queue.finish()


def save_source(source: str, template: str) -> Path:
    """Write a rendered source to a temporary file (kept) and return its path."""
    digest = hashlib.sha1(source.encode()).hexdigest()[:12]
    stem = Path(template).name.replace(".cl.mako", "").replace(".cl", "")
    path = Path(tempfile.gettempdir()) / f"s2cl-{stem}-{digest}.cl"
    path.write_text(source, encoding="utf-8")
    return path


_RUNTIMES: dict[str | None, Runtime] = {}


def get_runtime(device: str | None = None) -> Runtime:
    """The process-wide :class:`Runtime` for ``device`` (see module doc for the order)."""
    spec = device if device is not None else (os.environ.get("PYOPENCL_CTX") or None)
    runtime = _RUNTIMES.get(spec)
    if runtime is None:
        runtime = _RUNTIMES[spec] = Runtime(spec)
    return runtime
