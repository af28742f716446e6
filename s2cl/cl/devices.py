"""OpenCL devices: listing, choosing one, and how many pixels a vectorised kernel gives each work-item there.

Device choice, in order: the ``device`` argument (CLI ``--device``), then the ``PYOPENCL_CTX``
environment variable, then the first PoCL CPU device that compiles a probe kernel. A device is named
either as ``PLATFORM:DEVICE`` indices (as ``PYOPENCL_CTX`` takes them) or by a case-insensitive part of
its platform or device name (``nvidia``, ``H100``). A part of a name must name one device: where it
matches several (two PoCL drivers both list ``pthread-…`` devices; ``POCL_DEVICES="pthread pthread"``
lists two of one name) it is refused with the matches and their indices, as git refuses an ambiguous
short hash, unless it is one device's full name exactly.
"""

from __future__ import annotations

import logging
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from s2cl.cl.builds import pyopencl
from s2cl.cl.probe import ABORT_ENV, REPORTED_ENV, Widths, measure
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
            raise DeviceError(f"no OpenCL device matches {token(spec, 40)}{_origin(spec)}; available: {listing} "
                              "(give PLATFORM:DEVICE indices or part of a name)")
    return device_of(chosen), chosen


NEWER_POCL_HINT = (
    "the PoCL in the pyopencl wheel (LLVM 14) does not know this CPU model (e.g. AMD Zen 5) and cannot "
    "compile for it; install your distribution's PoCL, which picks its code target from the CPU's features: "
    "`apt-get install pocl-opencl-icd` (Debian/Ubuntu; `bash tools/setup.sh` does it), then run again"
)

def device_of(info: DeviceInfo) -> Any:
    """The pyopencl device ``info`` lists."""
    return _platforms()[info.platform_index].get_devices()[info.device_index]


_WIDTHS: dict[tuple[DeviceInfo, str, str], Widths] = {}


def widths_of(info: DeviceInfo) -> Widths:
    """``info``'s vector widths, reported and clean (:func:`s2cl.cl.probe.measure`; once per process)."""
    key = (info, os.environ.get(REPORTED_ENV, ""), os.environ.get(ABORT_ENV, ""))
    if key not in _WIDTHS:
        _WIDTHS[key] = measure(device_of(info), info.platform_index, info.device_index)
    return _WIDTHS[key]


def builds_at_all(info: DeviceInfo) -> str | None:
    """None when ``info``'s device builds the float32 probe cleanly at some width, else what its compiler said."""
    widths = widths_of(info)
    if widths.clean["float32"]:
        return None
    said = [c.detail for c in widths.checks if c.real_t == "float32" and c.detail]
    return said[-1] if said else "no width builds"


def _first_working(infos: list[DeviceInfo]) -> DeviceInfo:
    """The default device: of the PoCL CPU devices, the one whose clean float32 width is widest (ties: the
    order listed), else the first other device that builds.

    Some machines carry two PoCL platforms (the wheel's and the distribution's). The wheel's cannot
    compile at all on CPUs its LLVM does not know (AMD Zen 5), and on some it knows only in part (AMD
    Zen 4: an AVX2 target) it builds narrower vectors than the distribution's: each candidate's widths
    are probed (:mod:`s2cl.cl.probe`; cached in the user cache after the first time).
    """
    pocl = [i for i in infos if "portable computing language" in i.platform.lower() and "CPU" in i.kind]
    logs: list[str] = []

    def builds(info: DeviceInfo) -> bool:
        said = builds_at_all(info)
        if said is not None:
            _log.debug("skipping OpenCL device %s: it cannot compile a probe kernel: %s", info, said)
            logs.append(f"{info}: {said}")
        return said is None

    cpus = [i for i in pocl if builds(i)]  # other devices are probed only when no PoCL CPU device builds
    if cpus:
        return max(cpus, key=lambda i: (widths_of(i).clean["float32"], -cpus.index(i)))
    other = next((i for i in infos if i not in pocl and builds(i)), None)
    if other is not None:
        return other
    text = " ".join(logs)
    hint = NEWER_POCL_HINT if "unknown target CPU" in text else INSTALL_HINT
    raise DeviceError("no OpenCL device could compile a kernel (" + "; ".join(logs) + "): " + hint)


_INDICES = re.compile(r"(\d+)(?::(\d*))?")


def _match(spec: str, infos: list[DeviceInfo]) -> DeviceInfo | None:
    """The device named by ``spec``: ``P``, ``P:`` or ``P:D`` indices; one device's full name (any case); or
    part of a device or platform name that only one device has (:class:`DeviceError` listing the matches
    where several have it). Anything else made of digits and colons (``0:0:0``) or empty matches nothing."""
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
    exact = [i for i in infos if i.name.lower() == needle]
    if len(exact) == 1:
        return exact[0]
    matches = [i for i in infos if needle in i.name.lower() or needle in i.platform.lower()]
    if len(matches) > 1:
        raise DeviceError(f"OpenCL device {token(spec, 40)}{_origin(spec)} is ambiguous: it matches "
                          + "; ".join(str(i) for i in matches)
                          + " (give PLATFORM:DEVICE indices, e.g. " + matches[0].spec + ", or a full device name "
                          "that only one device has)")
    return matches[0] if matches else None


def _origin(spec: str) -> str:
    """`` ($PYOPENCL_CTX)`` when ``spec`` came from that variable, else ''."""
    return " ($PYOPENCL_CTX)" if spec == env_spec() else ""


LANES_ENV = "S2CL_LANES"


def choose_lanes(*, clean: int, device_type: str, requested: int | None = None) -> tuple[int, str | None]:
    """Pixels per work-item (explicit ``floatN`` lanes) of a vectorised kernel, and why it differs
    from ``requested`` (``None`` when it does not).

    :param clean: the widest width that builds without a warning for the precision on this device
        (:mod:`s2cl.cl.probe`: on CPUs the reported native width or one of its halves; not the report itself,
        which can name a width the code target lacks).
    :param device_type: the device's type string (``"CPU"``, ``"ALL | GPU"``...).
    :param requested: an explicit lane count (``lanes=`` or ``$S2CL_LANES``); ``None``: the default.

    PoCL on CPUs does not vectorise across work-items when a kernel holds a loop or a builtin call, so each
    work-item takes one native vector of pixels: the clean width. A wider vector is not faster
    (``python -m bench.bench_lanes``) and, where the target lacks it, draws clang's warning "AVX vector
    argument ... changes the ABI" or crashes LLVM: a request above the clean width steps down to it.
    GPUs vectorise across work-items in hardware: one pixel per work-item by default, any clean width on request.
    """
    clean = max(1, int(clean))
    default = clean if "CPU" in device_type.upper() else 1
    if requested is None:
        return default, None
    requested = int(requested)
    if requested not in VALID_LANES:
        raise InputError(f"must be one of {VALID_LANES}, got {requested}", key="lanes")
    if requested > clean:
        return clean, (f"{requested} lanes do not build cleanly on this device (widest clean width {clean}): "
                       f"using {clean}")
    return requested, None


def env_spec() -> str | None:
    """The device named by ``$PYOPENCL_CTX``, if any."""
    return os.environ.get("PYOPENCL_CTX") or None
