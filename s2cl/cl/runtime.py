"""The only module that sets up OpenCL: device choice, context, queue, program cache, builds.

Device choice, in order: the ``device`` argument (CLI ``--device``), then the
``PYOPENCL_CTX`` environment variable, then the first PoCL CPU device. A device is named
either as ``PLATFORM:DEVICE`` indices (as ``PYOPENCL_CTX`` takes them) or by a
case-insensitive substring of its platform or device name (``pocl``, ``nvidia``, ``H100``).
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
import sys
import tempfile
import threading
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.cl.vectypes import VALID_LANES
from s2cl.errors import BuildError, DeviceError, InputError, token

_log = logging.getLogger(__name__)

#: ``S2CL_BUILD_WARNINGS=error`` turns a kernel build with compiler warnings into a :class:`BuildError`
#: (the test suite sets it); otherwise build logs are DEBUG records and never reach the terminal.
STRICT_ENV = "S2CL_BUILD_WARNINGS"

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
    listing = "; ".join(str(i) for i in infos)
    if spec is None:
        chosen = _first_working(infos)
    else:
        chosen = _match(spec, infos)
        if chosen is None:
            origin = " ($PYOPENCL_CTX)" if spec == _env_spec() else ""
            raise DeviceError(f"no OpenCL device matches {token(spec, 40)}{origin}; available: {listing} "
                              "(give PLATFORM:DEVICE indices or part of a name)")
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
    _, log, err = _quiet_build(lambda: cl.Program(cl.Context([device]), _PROBE).build(), device)
    return None if err is None else log


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
        _log.debug("skipping OpenCL device %s: it cannot compile a probe kernel: %s", info, log)
        errors = [line.strip() for line in log.splitlines() if "error" in line.lower()]
        logs.append(f"{info}: {errors[0] if errors else log.strip()[:200]}")
    text = " ".join(logs)
    hint = NEWER_POCL_HINT if "unknown target CPU" in text else INSTALL_HINT
    raise DeviceError("no OpenCL device could compile a kernel (" + "; ".join(logs) + "): " + hint)


_INDICES = re.compile(r"(\d+)(?::(\d*))?")


def _match(spec: str, infos: list[DeviceInfo]) -> DeviceInfo | None:
    """The device named by ``spec``: ``P``, ``P:`` or ``P:D`` indices, or part of a device or platform
    name. Anything else made of digits and colons (``0:0:0``) or empty matches nothing."""
    spec = spec.strip()
    if not spec:
        return None
    indices = _INDICES.fullmatch(spec)
    if indices:
        pi, di = int(indices.group(1)), int(indices.group(2) or 0)
        return next((i for i in infos if i.platform_index == pi and i.device_index == di), None)
    if re.fullmatch(r"[\d:]+", spec):
        return None
    needle = spec.lower()
    return next((i for i in infos if needle in i.name.lower() or needle in i.platform.lower()), None)


LANES_ENV = "S2CL_LANES"


def choose_lanes(*, native: int, device_type: str, requested: int | None = None) -> tuple[int, str | None]:
    """Pixels per work-item (explicit ``floatN`` lanes) of a vectorised kernel, and why it differs
    from ``requested`` (``None`` when it does not).

    :param native: the device's native vector width for the precision
        (``native_vector_width_float`` or ``_double``: PoCL reports 16 floats with AVX-512, 8 with AVX2).
    :param device_type: the device's type string (``"CPU"``, ``"ALL | GPU"``...).
    :param requested: an explicit lane count (``lanes=`` or ``$S2CL_LANES``); ``None``: the default.

    PoCL on CPUs does not vectorise across work-items when a kernel holds a loop or a builtin call
    (``shared/notes/pocl-performance.md``), so each work-item takes one native vector of pixels.
    A vector wider than the native one is not faster (bench/results/lanes-*.json) and, on an x86 CPU
    without AVX-512, every helper that takes or returns it draws clang's warning "AVX vector argument
    ... changes the ABI": on CPUs the runtime caps lanes at the native width. GPUs vectorise across
    work-items in hardware: one pixel per work-item by default, any width on request.
    """
    native = max(1, int(native))
    cpu = "CPU" in device_type.upper()
    default = native if cpu else 1
    if requested is None:
        return default, None
    requested = int(requested)
    if requested not in VALID_LANES:
        raise InputError(f"must be one of {VALID_LANES}, got {requested}", key="lanes")
    if cpu and requested > native:
        return native, (f"{requested} lanes exceed this CPU device's native vector width ({native}): "
                        f"using {native}")
    return requested, None


class Runtime:
    """One OpenCL device with its context, queue and program cache."""

    def __init__(self, device_spec: str | None = None):
        cl = _cl()
        self.device, self.info = _select(device_spec)
        self.context = cl.Context([self.device])
        self.queue = cl.CommandQueue(self.context)
        self._programs: dict[tuple[str, tuple[str, ...]], Any] = {}
        _log.debug("OpenCL device %s (%s); native vector width float %d, double %d; lanes float32 %d, float64 %d",
                   self.info.spec, self.name, self.native_lanes("float32"), self.native_lanes("float64"),
                   self.lanes("float32"), self.lanes("float64"))

    @cached_property
    def has_fp64(self) -> bool:
        """Whether the device supports double precision."""
        return "cl_khr_fp64" in self.device.extensions

    def native_lanes(self, real_t: str = "float32") -> int:
        """The device's native vector width for ``real_t`` (elements)."""
        if real_t == "float64":
            return int(self.device.native_vector_width_double)
        return int(self.device.native_vector_width_float)

    def lanes(self, real_t: str = "float32", requested: int | None = None) -> int:
        """Pixels per work-item for the vectorised kernels in ``real_t``: ``requested``, else
        ``$S2CL_LANES``, else the device's default (:func:`choose_lanes`); a width the device
        cannot use cleanly is replaced, with a DEBUG record saying so."""
        if requested is None:
            env = os.environ.get(LANES_ENV, "").strip()
            if env:
                if not env.isdigit():
                    raise InputError(f"must be one of {VALID_LANES}, got {env!r}", key=LANES_ENV)
                requested = int(env)
        lanes, why = choose_lanes(native=self.native_lanes(real_t), device_type=self.info.kind, requested=requested)
        if why:
            _log.debug("%s, %s: %s", self.name, real_t, why)
        return lanes

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
        """Build ``source`` (cached on source + options); :class:`BuildError` on failure.

        The compiler's output never reaches the terminal: the build log goes to the ``s2cl.cl.runtime``
        logger at DEBUG (``s2cl -v`` shows it) and into the error when a build fails, or when it warns
        and ``$S2CL_BUILD_WARNINGS`` is ``error``.
        """
        cl = _cl()
        from s2cl.cl.templates import include_options

        opts = tuple(include_options()) + tuple(options)
        key = (source, opts)
        program = self._programs.get(key)
        if program is not None:
            return program

        def fail(err: Exception | None, log: str, reason: str | None = None) -> BuildError:
            return BuildError(template=template, device=self.name, options=list(opts), log=log,
                              source_path=save_source(source, template), reason=reason)

        # pyopencl's binary cache would hand back programs without their log; PoCL's own kernel
        # cache keeps the log, so building through it stays fast and the log is always there.
        program, log, err = _quiet_build(lambda: cl.Program(self.context, source).build(
            options=list(opts), cache_dir=False), self.device)
        if err is not None:
            raise fail(err, log) from err
        if log:
            _log.debug("build log of %s on %s (options: %s):\n%s", template, self.name, " ".join(opts), log)
            if os.environ.get(STRICT_ENV, "").lower() == "error" and "warning" in log.lower():
                raise fail(None, log, f"compiler warnings (${STRICT_ENV}=error)")
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


_STDERR_LOCK = threading.Lock()


@contextmanager
def _stderr_captured() -> Iterator[Callable[[], str]]:
    """Redirect file descriptor 2 into a temporary file for the duration; yields a function that
    returns what was written. PoCL's clang prints "N warnings generated." straight to fd 2."""
    with _STDERR_LOCK, tempfile.TemporaryFile() as tmp:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(tmp.fileno(), 2)
        try:
            yield lambda: (tmp.seek(0), tmp.read().decode("utf-8", "replace"))[1]
        finally:
            os.dup2(saved, 2)
            os.close(saved)


def _quiet_build(build: Callable[[], Any], device: Any) -> tuple[Any, str, Exception | None]:
    """Run ``build`` with the compiler's output captured: (program or None, log, error or None).

    The log is the device's build log, plus whatever the compiler wrote to stderr when the log is
    empty; pyopencl's ``CompilerWarning`` (which only says that a log exists) is not shown.
    """
    cl = _cl()
    program, err = None, None
    with _stderr_captured() as printed, warnings.catch_warnings():
        warnings.simplefilter("ignore", cl.CompilerWarning)
        try:
            program = build()
        except cl.Error as exc:
            err = exc
        stderr_text = printed()
    if err is not None:
        return None, str(err).strip() or stderr_text.strip(), err
    try:
        log = program.get_build_info(device, cl.program_build_info.LOG) or ""
    except cl.Error:  # some drivers cannot report it
        log = ""
    return program, (log.strip() or stderr_text.strip()), None


def save_source(source: str, template: str) -> Path:
    """Write a rendered source to a temporary file (kept) and return its path."""
    digest = hashlib.sha1(source.encode()).hexdigest()[:12]
    stem = Path(template).name.replace(".cl.mako", "").replace(".cl", "")
    path = Path(tempfile.gettempdir()) / f"s2cl-{stem}-{digest}.cl"
    path.write_text(source, encoding="utf-8")
    return path


_RUNTIMES: dict[str | None, Runtime] = {}


def _env_spec() -> str | None:
    return os.environ.get("PYOPENCL_CTX") or None


def get_runtime(device: str | None = None) -> Runtime:
    """The process-wide :class:`Runtime` for ``device`` (see module doc for the order)."""
    spec = device if device is not None else _env_spec()
    runtime = _RUNTIMES.get(spec)
    if runtime is None:
        runtime = _RUNTIMES[spec] = Runtime(spec)
    return runtime
