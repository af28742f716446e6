"""The one object that owns OpenCL: a device with its context, queue, program cache, memory pool and
builds. Pass a :class:`Runtime` to every engine (``IgrmFitter(rt, ...)``); :func:`get_runtime` makes
one per device spec for a process (see :mod:`s2cl.cl.devices` for how a device is chosen).
"""

from __future__ import annotations

import atexit
import gc
import logging
import os
from functools import cached_property
from typing import Any

import numpy as np

from s2cl.cl.builds import STRICT_ENV, pyopencl, quiet_build, save_source
from s2cl.cl.device_memory import DeviceMemory
from s2cl.cl.devices import LANES_ENV, builds_at_all, choose_lanes, env_spec, pyopencl_cache_problem, select, widths_of
from s2cl.cl.probe import Widths
from s2cl.cl.vectypes import VALID_LANES, VecTypes
from s2cl.errors import BuildError, DeviceError, InputError

_log = logging.getLogger(__name__)


class Runtime:
    """One OpenCL device with its context, queue and program cache."""

    def __init__(self, device_spec: str | None = None):
        cl = pyopencl()
        self.device, self.info = select(device_spec)
        cache = pyopencl_cache_problem()  # found here, before any work, not at the first kernel call
        if cache:
            raise DeviceError(cache)
        self.context = cl.Context([self.device])
        self.queue = cl.CommandQueue(self.context)
        self._programs: dict[tuple[str, tuple[str, ...]], Any] = {}
        said = builds_at_all(self.info)  # before any work: a device that builds nothing is refused here
        if said is not None:
            raise DeviceError(f"OpenCL device {self.info} cannot compile s2cl's kernels ({said}); choose another "
                              "(s2cl devices)")
        _log.debug("OpenCL device %s (%s); lanes float32 %d (%s), float64 %d (%s)", self.info.spec, self.name,
                   self.lanes("float32"), self.widths.why("float32"), self.lanes("float64"), self.widths.why("float64"))

    @cached_property
    def widths(self) -> Widths:
        """The device's vector widths per precision, as reported and as they build (:mod:`s2cl.cl.probe`)."""
        return widths_of(self.info)

    @cached_property
    def has_fp64(self) -> bool:
        """Whether the device computes in double precision: it reports ``cl_khr_fp64`` and a double probe builds
        cleanly."""
        return "cl_khr_fp64" in self.device.extensions and self.widths.clean.get("float64", 0) > 0

    def types(self, real_t: str = "float32", lanes: int | None = None, *, vector: bool = True) -> VecTypes:
        """The kernel types for ``real_t`` on this device: the one place that refuses float64 on a device
        without ``cl_khr_fp64`` (naming the device and the key), and that picks lanes (:meth:`lanes`;
        ``vector=False``: one value per work-item)."""
        if real_t not in ("float32", "float64"):
            raise InputError(f"must be 'float32' or 'float64', got {real_t!r}", key="compute.precision")
        if real_t == "float64" and not self.has_fp64:
            raise DeviceError(f"{self.name} has no float64 support (cl_khr_fp64): set compute.precision = "
                              "'float32' or choose another device (s2cl devices)")
        return VecTypes(real_t, self.lanes(real_t, lanes) if vector else 1)

    def native_lanes(self, real_t: str = "float32") -> int:
        """The device's native vector width for ``real_t`` (elements; at least 1), as it builds: on CPUs the
        widest clean width (the reported width, or a half of it where the code target lacks that:
        :mod:`s2cl.cl.probe`); on other devices the reported width, capped at the widest clean one."""
        clean = max(1, self.widths.clean.get(real_t, 0))
        if "CPU" in self.info.kind:
            return clean
        return max(1, min(self.widths.reported.get(real_t, 1), clean))

    def reported_lanes(self, real_t: str = "float32") -> int:
        """The device's native vector width for ``real_t`` as its driver reports it (a claim: see
        :meth:`native_lanes`)."""
        return self.widths.reported[real_t]

    def lanes(self, real_t: str = "float32", requested: int | None = None) -> int:
        """Pixels per work-item for the vectorised kernels in ``real_t``: ``requested``, else
        ``$S2CL_LANES``, else the device's default (:func:`choose_lanes`); a width the device
        cannot use cleanly is replaced, with a DEBUG record saying so."""
        if requested is None:
            env = os.environ.get(LANES_ENV, "").strip()
            if env:
                if not env.isdigit() or int(env) not in VALID_LANES:
                    raise InputError(f"must be one of {VALID_LANES}, got {env!r}", key=LANES_ENV)
                requested = int(env)
        clean = max(1, self.widths.clean.get(real_t, 0))
        lanes, why = choose_lanes(clean=clean, device_type=self.info.kind, requested=requested)
        if why:
            _log.debug("%s, %s: %s", self.name, real_t, why)
        return lanes

    @property
    def name(self) -> str:
        return f"{self.info.name} ({self.info.platform})"

    @property
    def memory(self) -> DeviceMemory:
        """The device's global memory and largest single buffer (bytes), as the driver reports them, lowered by
        ``$S2CL_DEVICE_GLOBAL_MEM`` / ``$S2CL_DEVICE_MAX_ALLOC`` where set (the test seam: :mod:`s2cl.cl.device_memory`;
        read at each call, so a test may set them after the runtime is made)."""
        return DeviceMemory.of(self.name, int(self.device.global_mem_size), int(self.device.max_mem_alloc_size))

    @property
    def max_alloc_bytes(self) -> int:
        """The largest single buffer (bytes; :attr:`memory`)."""
        return self.memory.max_alloc_bytes

    @property
    def global_mem_bytes(self) -> int:
        """The device's global memory (bytes; :attr:`memory`)."""
        return self.memory.global_bytes

    def build(self, source: str, *, template: str, options: list[str] | tuple[str, ...] = ()) -> Any:
        """Build ``source`` (cached on source + options); :class:`BuildError` on failure.

        The compiler's output never reaches the terminal: the build log goes to the ``s2cl.cl.runtime``
        logger at DEBUG (``s2cl -v`` shows it) and into the error when a build fails, or when it warns
        and ``$S2CL_BUILD_WARNINGS`` is ``error``.
        """
        cl = pyopencl()
        from s2cl.cl.templates import include_options  # Mako: only when a kernel is built, not to pick a device

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
        program, log, err = quiet_build(lambda: cl.Program(self.context, source).build(
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
        return pyopencl().Kernel(program, name)

    def max_work_group_size(self, kernel: Any) -> int:
        cl = pyopencl()
        return int(kernel.get_work_group_info(cl.kernel_work_group_info.WORK_GROUP_SIZE, self.device))

    def work_group(self, kernel: Any) -> int:
        """Work-items per group for the 1-D launches (resampling, sensing, IGRM, SAM, indices, the sweep's
        metrics; the 2-D sweep kernel keeps the driver's choice, which measured no worse for it): the kernel's
        preferred work-group size multiple as the device reports it (8 on PoCL CPUs), four of them on other
        devices, never above the kernel's limit. Left to itself, PoCL picks a divisor of the global size,
        which can be poor for awkward sizes: the resampling API ran 3.9 M spectra/s with PoCL's choice
        against 7.5 with named groups (``python -m bench.bench_resample``); single-item groups cost
        scheduling per item on small launches instead (``python -m bench.bench_atmosphere``, 2·10⁴ spectra:
        4.5 against 6.6 M/s in runs minutes apart)."""
        cl = pyopencl()
        info = cl.kernel_work_group_info
        multiple = int(kernel.get_work_group_info(info.PREFERRED_WORK_GROUP_SIZE_MULTIPLE, self.device))
        wanted = multiple if "CPU" in self.info.kind else 4 * multiple
        return max(1, min(wanted, self.max_work_group_size(kernel)))

    def local_size(self, kernel: Any, global_size: int) -> tuple[int] | None:
        """The work-group of a launch of ``global_size`` items that cannot be padded (no tail guard): the
        largest power of two up to :meth:`work_group` that divides it on CPUs; elsewhere
        :meth:`work_group` where it divides, else None (the driver's choice)."""
        group = self.work_group(kernel)
        if "CPU" in self.info.kind:
            while group > 1 and global_size % group:
                group //= 2
            return (group,)
        return (group,) if global_size % group == 0 else None

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
        cl = pyopencl()
        host = np.ascontiguousarray(array)
        if host.nbytes == 0:
            host = np.zeros(1, dtype=host.dtype)
        where = cl.mem_flags.USE_HOST_PTR if (zero_copy and self.host_memory) else cl.mem_flags.COPY_HOST_PTR
        return cl.Buffer(self.context, cl.mem_flags.READ_ONLY | where, hostbuf=host)

    def empty(self, nbytes: int) -> Any:
        """An uninitialised read-write device buffer of ``nbytes``."""
        cl = pyopencl()
        return cl.Buffer(self.context, cl.mem_flags.READ_WRITE, size=max(int(nbytes), 1))

    def zeros(self, nbytes: int) -> Any:
        cl = pyopencl()
        buf = self.empty(nbytes)
        cl.enqueue_fill_buffer(self.queue, buf, np.uint8(0), 0, max(int(nbytes), 1))
        return buf

    def fetch(self, buffer: Any, shape: tuple[int, ...], dtype: Any) -> np.ndarray:
        """Copy a device buffer back into a new host array (blocking)."""
        cl = pyopencl()
        out = np.empty(shape, dtype=dtype)
        if out.nbytes:
            cl.enqueue_copy(self.queue, out, buffer)
        return out

    @cached_property
    def alignment(self) -> int:
        """Bytes a host array must be aligned to for the device to use it in place (the device's
        ``MEM_BASE_ADDR_ALIGN``): PoCL stores (and loads) whole vectors with aligned instructions, and a
        misaligned in-place buffer crashed an IGRM launch; inputs that kernels read with vloadN need none."""
        return max(int(self.device.mem_base_addr_align) // 8, 16)

    def output(self, shape: tuple[int, ...], dtype: Any) -> tuple[np.ndarray, Any]:
        """A host array and a device buffer that fills it: on devices that work in host memory the kernel
        writes into the (aligned) array in place, so :meth:`result` copies nothing; elsewhere a buffer
        from :attr:`pool` that :meth:`result` copies back."""
        dtype = np.dtype(dtype)
        size = int(np.prod(shape)) * dtype.itemsize
        if not self.host_memory:
            return np.empty(shape, dtype), self.alloc(size)
        raw = np.empty(max(size, 1) + self.alignment, np.uint8)
        start = (-raw.ctypes.data) % self.alignment
        host = raw[start:start + max(size, 1)]
        cl = pyopencl()
        buffer = cl.Buffer(self.context, cl.mem_flags.READ_WRITE | cl.mem_flags.USE_HOST_PTR, hostbuf=host)
        return host[:size].view(dtype).reshape(shape), buffer

    def result(self, buffer: Any, array: np.ndarray) -> np.ndarray:
        """``array`` holding what the device wrote into ``buffer`` (from :meth:`output`; blocking)."""
        cl = pyopencl()
        if not self.host_memory:
            if array.nbytes:
                cl.enqueue_copy(self.queue, array, buffer)
            return array
        mapped, event = cl.enqueue_map_buffer(self.queue, buffer, cl.map_flags.READ, 0, (buffer.size,), np.uint8)
        event.wait()  # the kernel's writes are visible in the host array once mapped
        mapped.base.release(self.queue)
        return array

    def upload(self, buffer: Any, array: np.ndarray) -> None:
        """Copy a host array into an existing device buffer (blocking)."""
        pyopencl().enqueue_copy(self.queue, buffer, np.ascontiguousarray(array))

    @cached_property
    def pool(self) -> Any:
        """pyopencl's memory pool on this context: engines called again and again with the same sizes
        (sweep chunks, fits) get their buffers back instead of fresh ones (a fresh buffer costs ~4x an
        upload into an existing one on PoCL)."""
        tools = __import__("pyopencl.tools", fromlist=["MemoryPool"])
        return tools.MemoryPool(tools.ImmediateAllocator(self.queue))

    def free_held(self) -> None:
        """Give the buffers :attr:`pool` keeps for reuse back to the driver (on a CPU device: to the host's memory):
        when the sizes of the next launches change (a sweep's last, smaller chunk) and when an engine's launches are
        over, so that the pool never holds more than the launches that use it (:mod:`s2cl.sweep.host_footprint`)."""
        pool = self.__dict__.get("pool")
        if pool is not None:
            pool.free_held()

    def alloc(self, nbytes: int) -> Any:
        """An uninitialised device buffer of ``nbytes`` from :attr:`pool` (back to the pool when released)."""
        return self.pool.allocate(max(int(nbytes), 1))

    def upload_new(self, array: np.ndarray) -> Any:
        """``array`` (made C-contiguous) copied into a buffer from :attr:`pool`."""
        host = np.ascontiguousarray(array)
        buf = self.alloc(host.nbytes)
        if host.nbytes:
            self.upload(buf, host)
        return buf

    def finish(self) -> None:
        self.queue.finish()

    def release(self) -> None:
        """Finish the queue and drop this runtime's programs and memory pool (the context and queue go with the
        last reference to the runtime): called for every runtime at exit (:func:`release_runtimes`), so programs
        are released while the interpreter still runs, before the contexts that built them."""
        try:
            self.queue.finish()
        except pyopencl().Error:
            pass
        self._programs.clear()
        pool = self.__dict__.pop("pool", None)
        if pool is not None:
            pool.free_held()


_RUNTIMES: dict[str | None, Runtime] = {}


def get_runtime(device: str | None = None) -> Runtime:
    """The process-wide :class:`Runtime` for ``device`` (see module doc for the order)."""
    spec = device if device is not None else env_spec()
    runtime = _RUNTIMES.get(spec)
    if runtime is None:
        runtime = _RUNTIMES[spec] = Runtime(spec)
    return runtime


@atexit.register
def release_runtimes() -> None:
    """Release the process-wide runtimes' programs, pools, queues and contexts, in that order, while the
    interpreter still runs (at exit, and where a test wants a clean slate)."""
    runtimes = list(_RUNTIMES.values())
    _RUNTIMES.clear()
    for runtime in runtimes:
        runtime.release()
    del runtimes
    gc.collect()
