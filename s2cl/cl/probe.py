"""What a device can build, decided by building: the widest vector width per precision that compiles
without a warning.

A driver's reported native width is a claim. The PoCL inside the pyopencl wheel (LLVM 14) on an AVX-512
CPU newer than its LLVM (AMD Zen 4) compiles for an AVX2 target yet reports 16 float lanes: ``float16``
helpers then draw clang's warning "AVX vector argument ... changes the ABI", and larger kernels crash LLVM
(a process abort). So each width from the reported one down is built as a small probe kernel — the vector
type passed to and returned from a helper, with the builtins the kernels use (``sqrt``, ``log10``,
``exp``, ``fma``) — and the first width whose build log has no warning is the device's *clean* width.

The probe runs in a child process (``python -m s2cl.cl.probe``), so an LLVM abort costs that process and
the width it was building, never the user's command; the verdict is kept in the user cache
(``devices/`` of :func:`s2cl.io.cache.cache_dir`), keyed by the device, driver, platform version and code
target, so later processes pay nothing. Where a child cannot be started or sees another device, the
probe runs in this process instead: the probe kernel is small enough that a width which cannot be
built shows as a warning before any crash can.

Two environment variables emulate machines one does not have (tests, ``tools/cpu_check.sh``):
``$S2CL_REPORTED_WIDTH`` makes every device report that native width (``16``: 16 floats and 8 doubles;
or ``float32=16,float64=8``), as a driver whose report and target disagree does; ``$S2CL_PROBE_ABORT``
(a width) makes the probe's child abort before building that width, as LLVM does, and ``$S2CL_PROBE_HANG`` (a width)
makes it hang there, as a compiler that never returns (``$S2CL_PROBE_TIMEOUT`` shortens the wait, seconds).
"""

from __future__ import annotations

import json
import logging
import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass, field
from typing import Any

from s2cl.cl.builds import pyopencl, quiet_build
from s2cl.cl.vectypes import VALID_LANES, VecTypes
from s2cl.errors import InputError, S2CLError
from s2cl.io.cache import cache_dir, digest
from s2cl.io.output import write_json

_log = logging.getLogger("s2cl.cl.runtime")

#: Bump when the probe kernel or the verdict rules change: cached verdicts of older probes are ignored.
PROBE_VERSION = 2
REPORTED_ENV = "S2CL_REPORTED_WIDTH"
ABORT_ENV = "S2CL_PROBE_ABORT"
PRECISIONS = ("float32", "float64")
HANG_ENV = "S2CL_PROBE_HANG"
TIMEOUT_ENV = "S2CL_PROBE_TIMEOUT"
#: a probe child without a verdict for this long (s) is stopped and its width counts as aborted ($S2CL_PROBE_TIMEOUT)
CHILD_TIMEOUT_S = 120.0


def probe_source(real_t: str, width: int) -> str:
    """The probe kernel for ``width`` lanes of ``real_t``: a helper taking and returning the vector type,
    with the builtins the kernels use."""
    T = VecTypes(real_t, width)
    V, R = T.V, T.R
    load = "x[i]" if width == 1 else f"vload{width}(i, x)"
    store = "x[i] = r;" if width == 1 else f"vstore{width}(r, i, x);"
    pragma = "#pragma OPENCL EXTENSION cl_khr_fp64 : enable\n" if T.double else ""
    return (f"{pragma}{V} s2cl_probe_f({V} a, {V} b) {{ return fma(sqrt(a), log10(b), exp(-a)); }}\n"
            f"__kernel void s2cl_width_probe(__global {R} *x)\n{{\n"
            f"    const size_t i = get_global_id(0);\n    const {V} a = {load};\n"
            f"    const {V} r = s2cl_probe_f(a, a + {T.vlit(1.0)});\n    {store}\n}}\n")


_DIAGNOSTIC = re.compile(r"(warning|error):\s*(?:\S+:\d+:\d+(?:\s*<Spelling=[^>]*>)?:\s*)?(.*)", re.IGNORECASE)


def first_diagnostic(log: str) -> str:
    """The first warning or error of a build log, without its file position, address space and parenthetical
    asides (``AVX vector argument of type 'float16' without 'avx512f' enabled changes the ABI``), at most
    120 characters."""
    text = " ".join(log.split())
    for line in log.splitlines():
        match = _DIAGNOSTIC.search(line)
        if match:
            text = match.group(2).strip()
            if match.group(1).lower() == "error":
                text = "error: " + text
            break
    text = re.sub(r"\s*\([^()]*\)", "", text.replace("__private ", ""))
    return text[:119] + "…" if len(text) > 120 else text


def build_verdict(device: Any, real_t: str, width: int) -> tuple[str, str]:
    """Build the probe for (``real_t``, ``width``) on ``device``: ("clean" | "warns" | "fails", detail)."""
    cl = pyopencl()
    context = cl.Context([device])
    _, log, err = quiet_build(lambda: cl.Program(context, probe_source(real_t, width)).build(cache_dir=False), device)
    if err is not None:
        return "fails", first_diagnostic(log) or str(err)
    if "warning" in log.lower():
        return "warns", first_diagnostic(log)
    return "clean", ""


@dataclass(frozen=True)
class WidthCheck:
    """One probe build: precision, width, verdict (clean, warns, fails, aborted) and the compiler's words."""

    real_t: str
    width: int
    verdict: str
    detail: str = ""


@dataclass(frozen=True)
class Widths:
    """A device's vector widths per precision: as reported, and the widest that builds clean (0: none)."""

    reported: dict[str, int]
    clean: dict[str, int]
    checks: tuple[WidthCheck, ...] = field(default=())
    where: str = "child"

    def why(self, real_t: str) -> str:
        """One line: what was reported and what each probed width did (``reported 16; 16 warns "…"; 8
        builds clean``)."""
        parts = [f"reported {self.reported.get(real_t, 0)}"]
        for c in self.checks:
            if c.real_t != real_t:
                continue
            if c.verdict == "clean":
                parts.append(f"{c.width} builds clean")
            else:
                parts.append(f"{c.width} {c.verdict}" + (f' "{c.detail}"' if c.detail else ""))
        if len(parts) == 1:
            parts.append("not probed (no cl_khr_fp64)" if real_t == "float64" else "not probed")
        return "; ".join(parts)

    def to_json(self) -> dict[str, Any]:
        return {"reported": self.reported, "clean": self.clean, "where": self.where,
                "checks": [[c.real_t, c.width, c.verdict, c.detail] for c in self.checks]}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Widths:
        return cls(reported={k: int(v) for k, v in data["reported"].items()},
                   clean={k: int(v) for k, v in data["clean"].items()},
                   checks=tuple(WidthCheck(r, int(w), v, d) for r, w, v, d in data["checks"]),
                   where=str(data.get("where", "child")))


def reported_widths(device: Any) -> dict[str, int]:
    """The device's native widths as reported, or as ``$S2CL_REPORTED_WIDTH`` makes it report them."""
    reported = {"float32": int(device.native_vector_width_float),
                "float64": int(device.native_vector_width_double)}
    text = os.environ.get(REPORTED_ENV, "").strip()
    if not text:
        return reported

    try:
        if "=" in text:
            forced = {k.strip(): int(v) for k, v in (part.split("=", 1) for part in text.split(","))}
        else:
            forced = {"float32": int(text), "float64": max(1, int(text) // 2)}
    except ValueError:
        forced = {"": 0}
    if not set(forced) <= set(PRECISIONS) or not all(v in VALID_LANES for v in forced.values()):
        raise InputError(f"must be a width of {VALID_LANES} or 'float32=W,float64=W', got {text!r}", key=REPORTED_ENV)
    return reported | forced


def plan(reported: dict[str, int], *, cpu: bool, fp64: bool) -> dict[str, list[int]]:
    """Widths to try per precision, widest first: on CPUs the reported width and its halves; elsewhere
    (GPUs vectorise across work-items, and take a width only on request) every width from 16 down."""
    out = {}
    for real_t in PRECISIONS:
        if real_t == "float64" and not fp64:
            continue
        top = max(1, reported[real_t]) if cpu else max(VALID_LANES)
        out[real_t] = [w for w in sorted(VALID_LANES, reverse=True) if w <= top]
    return out


def describe(device: Any) -> dict[str, str]:
    """What identifies a device's compiler: names and versions (PoCL's device version names its LLVM target)."""
    platform = device.platform
    return {"platform": platform.name.strip(), "platform_version": platform.version.strip(),
            "device": device.name.strip(), "device_version": device.version.strip(),
            "driver": device.driver_version.strip(), "vendor": device.vendor.strip()}


def target(device: Any) -> str:
    """The code target a PoCL CPU device compiles for (``znver3``, ``skylake-avx512``), else ''."""
    match = re.search(r"HSTR:\s*(\S+)\s*$", device.version.strip())
    if not match:
        return ""
    # <device type>-<arch>-<vendor>-<os>-<environment>-<cpu>: pthread-x86_64-pc-linux-gnu-skylake-avx512
    parts = match.group(1).split("-")
    return "-".join(parts[5:]) if len(parts) > 5 else parts[-1]


def measure(device: Any, platform_index: int, device_index: int) -> Widths:
    """The device's :class:`Widths`, from the user cache or a fresh probe (kept there)."""
    cpu = "CPU" in pyopencl().device_type.to_string(device.type).upper()
    reported = reported_widths(device)
    todo = plan(reported, cpu=cpu, fp64="cl_khr_fp64" in device.extensions)
    key = {"probe": PROBE_VERSION, **describe(device), "reported": reported, "plan": todo,
           "abort": os.environ.get(ABORT_ENV, ""), "hang": os.environ.get(HANG_ENV, "")}
    cached = _read_cache(key)
    if cached is not None:
        return cached
    checks, where = _probe_in_child(key, platform_index, device_index, todo)
    if checks is None:
        checks, where = _probe_here(device, todo), "in process"
    clean = {r: next((c.width for c in checks if c.real_t == r and c.verdict == "clean"), 0) for r in PRECISIONS}
    widths = Widths(reported=reported, clean=clean, checks=tuple(checks), where=where)
    for real_t in todo:
        _log.debug("%s, %s: %d lanes (%s)", key["device"], real_t, clean[real_t], widths.why(real_t))
    _write_cache(key, widths)
    return widths


def _probe_here(device: Any, todo: dict[str, list[int]]) -> list[WidthCheck]:
    """Probe in this process, each precision widest first up to its first clean width."""
    checks = []
    for real_t, widths in todo.items():
        for width in widths:
            checks.append(WidthCheck(real_t, width, *build_verdict(device, real_t, width)))
            if checks[-1].verdict == "clean":
                break
    return checks


def _probe_in_child(key: dict[str, Any], platform_index: int, device_index: int,
                    todo: dict[str, list[int]]) -> tuple[list[WidthCheck] | None, str]:
    """Probe in child processes; a child that dies or hangs (an LLVM abort, a compiler that never returns) marks the
    width it was building ``aborted`` and the next child goes on below it. None when no child can probe this
    device (it cannot start, fails before building anything, or sees another device)."""
    checks: list[WidthCheck] = []
    remaining = {r: list(ws) for r, ws in todo.items()}
    while any(remaining.values()):
        job = {"platform": platform_index, "device": device_index, "expect": {k: key[k] for k in (
            "platform", "platform_version", "device", "device_version", "driver")}, "plan": remaining}
        try:
            proc = subprocess.run([sys.executable, "-m", "s2cl.cl.probe", json.dumps(job)], capture_output=True,
                                  text=True, timeout=_timeout(), env=os.environ.copy())
            stdout, rc, stderr = proc.stdout, proc.returncode, proc.stderr
            how = f"signal {-rc}" if rc < 0 else f"exit status {rc}"
        except subprocess.TimeoutExpired as err:
            out = err.stdout or ""
            stdout, rc, stderr = out.decode(errors="replace") if isinstance(out, bytes) else out, None, ""
            how = f"no verdict in {_timeout():g} s"
        except (OSError, subprocess.SubprocessError) as err:
            _log.debug("width probe child could not run (%s): probing in process", err)
            return None, ""
        started: tuple[str, int] | None = None
        gained = 0
        for line in stdout.splitlines():
            if line.startswith("start "):
                _, r, w = line.split()
                started = (r, int(w))
            elif line.startswith("{"):
                c = json.loads(line)
                checks.append(WidthCheck(c["real_t"], c["width"], c["verdict"], c["detail"]))
                started, gained = None, gained + 1
            elif line.startswith("mismatch"):
                _log.debug("width probe child sees another device (%s): probing in process", line)
                return None, ""
        if rc == 0:
            break
        if started is None and not gained:
            _log.debug("width probe child failed (%s) before building: probing in process: %s", how,
                       stderr.strip()[-300:])
            return None, ""
        if started is not None:  # it died or hung building this width; else it died after its last verdict
            checks.append(WidthCheck(started[0], started[1], "aborted", f"the compiler killed the probe ({how})"
                                     if rc is not None else f"the compiler gave {how}"))
        done = {c.real_t for c in checks if c.verdict == "clean"}
        tried = {(c.real_t, c.width) for c in checks}
        cut = started or ("", 0)
        remaining = {r: [w for w in ws if (r, w) not in tried and (r != cut[0] or w < cut[1])]
                     for r, ws in remaining.items() if r not in done}
    return checks, "child"


def _timeout() -> float:
    try:
        return max(1.0, float(os.environ.get(TIMEOUT_ENV, CHILD_TIMEOUT_S)))
    except ValueError:
        return CHILD_TIMEOUT_S


def _cache_path(key: dict[str, Any]) -> Any:
    return cache_dir("devices") / f"widths-{digest(key)[:24]}.json"


def _read_cache(key: dict[str, Any]) -> Widths | None:
    try:
        path = _cache_path(key)
        if path.is_file():
            data = json.loads(path.read_text(encoding="utf-8"))
            if data.get("key") == key:
                return Widths.from_json(data["widths"])
    except (OSError, ValueError, KeyError, TypeError, S2CLError):
        pass
    return None


def _write_cache(key: dict[str, Any], widths: Widths) -> None:
    try:
        write_json(_cache_path(key), {"key": key, "widths": widths.to_json()})
    except (OSError, S2CLError) as err:
        _log.debug("width probe verdict not cached: %s", err)


def _child(job: dict[str, Any]) -> int:
    """The child's side: find the device, check it is the one the parent meant, build each width of the
    plan widest first, stopping a precision at its first clean width; one line per build."""
    cl = pyopencl()
    device = cl.get_platforms()[job["platform"]].get_devices()[job["device"]]
    seen = {k: v for k, v in describe(device).items() if k in job["expect"]}
    if seen != job["expect"]:
        print(f"mismatch {json.dumps(seen)}", flush=True)
        return 0
    abort_at, hang_at = os.environ.get(ABORT_ENV, "").strip(), os.environ.get(HANG_ENV, "").strip()
    for real_t, widths in job["plan"].items():
        for width in widths:
            print(f"start {real_t} {width}", flush=True)
            if abort_at == str(width):
                os.abort()
            if hang_at == str(width):
                time.sleep(3600)
            verdict, detail = build_verdict(device, real_t, width)
            print(json.dumps({"real_t": real_t, "width": width, "verdict": verdict, "detail": detail}), flush=True)
            if verdict == "clean":
                break
    return 0


if __name__ == "__main__":
    sys.exit(_child(json.loads(sys.argv[1])))
