"""OpenCL devices: listing, choosing one, and how many pixels a vectorised kernel gives each work-item there.

Device choice, in order: the ``device`` argument (CLI ``--device``), then the ``PYOPENCL_CTX``
environment variable, then the first PoCL CPU device that compiles a probe kernel. A device is named
either as ``PLATFORM:DEVICE`` indices (as ``PYOPENCL_CTX`` takes them) or by a case-insensitive
substring of its platform or device name (``pocl``, ``nvidia``, ``H100``).
"""

from __future__ import annotations

import logging
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from s2cl.cl.builds import pyopencl, quiet_build
from s2cl.cl.vectypes import VALID_LANES
from s2cl.errors import DeviceError, InputError, token

_log = logging.getLogger("s2cl.cl.runtime")

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


def _platforms() -> list[Any]:
    cl = pyopencl()
    try:
        return list(cl.get_platforms())
    except cl.Error:  # pyopencl raises LogicError/RuntimeError when no ICD is found
        return []


def _unusable(folder: Path) -> bool:
    """Whether ``folder`` cannot be created or written (its deepest existing part is not a writable folder)."""
    base = folder
    while not base.exists() and base != base.parent:
        base = base.parent
    return not (base.is_dir() and os.access(base, os.W_OK | os.X_OK))


_CACHE_HINT = ("set POCL_CACHE_DIR (PoCL's kernels), XDG_CACHE_HOME (pyopencl's) and S2CL_CACHE (s2cl's) to writable "
               "folders, e.g. XDG_CACHE_HOME=/tmp/cache POCL_CACHE_DIR=/tmp/cache/pocl")


def _pocl_cache_problem() -> str | None:
    """Why PoCL lists no device when its kernel cache folder cannot be made (a read-only or missing $HOME,
    $POCL_CACHE_DIR below a file): PoCL then hides its devices, which looks like no OpenCL at all. None when
    there is no PoCL platform or its cache folder is fine."""
    if not any("portable computing language" in p.name.lower() for p in _platforms()):
        return None
    if os.environ.get("POCL_CACHE_DIR"):
        folder, named = Path(os.environ["POCL_CACHE_DIR"]), "$POCL_CACHE_DIR"
    else:
        xdg = os.environ.get("XDG_CACHE_HOME")
        folder = Path(xdg) / "pocl" if xdg else Path(os.path.expanduser("~")) / ".cache" / "pocl"
        named = "$XDG_CACHE_HOME" if xdg else "$HOME"
    if not _unusable(folder):
        return None
    return (f"PoCL found no OpenCL device because its kernel cache folder {folder} (from {named}) cannot be "
            f"created or written; {_CACHE_HINT}")


def pyopencl_cache_problem() -> str | None:
    """Why pyopencl would fail at its first kernel call (it writes its caches below the user cache folder,
    ``$XDG_CACHE_HOME`` or ``~/.cache``, and ends with an OSError and a traceback when that cannot be made);
    None when it can, or when ``$PYOPENCL_NO_CACHE`` switches its caches off."""
    if os.environ.get("PYOPENCL_NO_CACHE"):
        return None
    import platformdirs

    for name in ("pyopencl", "pytools"):
        folder = Path(platformdirs.user_cache_dir(name, name))
        if _unusable(folder):
            return f"pyopencl's cache folder {folder} cannot be created or written; {_CACHE_HINT}"
    return None


def list_devices() -> list[DeviceInfo]:
    """All OpenCL devices on this machine."""
    cl = pyopencl()
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


def select(spec: str | None) -> tuple[Any, DeviceInfo]:
    infos = list_devices()
    if not infos:
        cache = _pocl_cache_problem()
        if cache:
            raise DeviceError(cache)
        raise DeviceError("no OpenCL platform found: " + INSTALL_HINT)
    listing = "; ".join(str(i) for i in infos)
    if spec is None:
        chosen = _first_working(infos)
    else:
        chosen = _match(spec, infos)
        if chosen is None:
            origin = " ($PYOPENCL_CTX)" if spec == env_spec() else ""
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
    cl = pyopencl()
    device = _platforms()[info.platform_index].get_devices()[info.device_index]
    _, log, err = quiet_build(lambda: cl.Program(cl.Context([device]), _PROBE).build(), device)
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


def env_spec() -> str | None:
    """The device named by ``$PYOPENCL_CTX``, if any."""
    return os.environ.get("PYOPENCL_CTX") or None
