"""Machines this one is not: the device-dependent tests, and the README's main job, in child processes under
OpenCL set-ups emulated on this machine (docs/devices.md lists them and where each runs).

- two CPU devices of one name, and two named apart, on each PoCL driver (``$POCL_DEVICES``);
- only the wheel's PoCL (``$OCL_ICD_VENDORS`` an empty folder hides the system's drivers);
- only the distribution's PoCL (``$OCL_ICD_VENDORS`` its ``.icd`` file: the wheel's loader then reads no other);
- a compiler that aborts at the width the device reports (``$S2CL_REPORTED_WIDTH=16``, ``$S2CL_PROBE_ABORT=16``);
- an AVX2 target under valgrind, where valgrind is installed (valgrind hides AVX-512 from CPUID).

Each child must exit 0: a test that fails, or a process that ends on a signal after its tests passed (the wheel's
PoCL aborted at exit with "still have references to IRs"), fails here with the set-up and its drivers named.
A set-up this machine cannot make (no such driver, or none that builds) is skipped with the reason.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from s2cl.cl.probe import ABORT_ENV, REPORTED_ENV

pytestmark = pytest.mark.machines

REPO = Path(__file__).resolve().parent.parent
VENDORS = Path("/etc/OpenCL/vendors")
AVX2_ONLY = ("haswell", "znver1", "znver2", "znver3", "skylake", "broadwell", "alderlake")
#: the tests that depend on the device, as each set-up runs them (paths, then a -k expression or None)
NAMES = (["tests/test_runtime.py"], None)
WIDTHS = (["tests/test_runtime.py", "tests/test_widths.py", "tests/test_vecmath.py"],
          "not test_vecmath or lanes16 or lanes8")


def _env(tmp_path: Path, **changes: str) -> dict[str, str]:
    """This process's environment for a child: a fresh s2cl cache (every width probed anew; PoCL's kernel cache,
    $POCL_CACHE_DIR, is kept), no device chosen by the parent, ``changes`` applied."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYOPENCL_CTX", "S2CL_TEST_DEVICES", "S2CL_LANES",
                                                             REPORTED_ENV, ABORT_ENV)}
    return env | {"S2CL_CACHE": str(tmp_path / "cache"), "PYTHONPATH": str(REPO)} | changes


def _how(proc: subprocess.CompletedProcess) -> str:
    if proc.returncode < 0:
        return f"ended on signal {-proc.returncode} ({signal.Signals(-proc.returncode).name})"
    return f"exit status {proc.returncode}"


def _devices(env: dict[str, str]) -> list[dict]:
    """``s2cl devices --json`` as the set-up sees it (it must not end on a signal either)."""
    out = subprocess.run([sys.executable, "-m", "s2cl", "devices", "--json"], capture_output=True, text=True,
                         env=env, timeout=600, cwd=REPO)
    assert out.returncode in (0, 2), f"s2cl devices: {_how(out)}: {out.stderr[-1500:]}"
    return json.loads(out.stdout or "[]")


def _drivers(rows: list[dict]) -> str:
    return "; ".join(sorted({f"{r['platform']} {r['driver']} ({r['target'] or '?'})" for r in rows})) or "none"


def _pytest(env: dict[str, str], tests: tuple[list[str], str | None], rows: list[dict], what: str) -> None:
    paths, keyword = tests
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "not slow and not machines", *paths]
    out = subprocess.run(cmd + (["-k", keyword] if keyword else []), capture_output=True, text=True, env=env,
                         timeout=600, cwd=REPO)
    tail = (out.stdout[-3000:] + "\n" + out.stderr[-1500:]).strip()
    assert out.returncode == 0, f"{what}, drivers {_drivers(rows)}: pytest {_how(out)}\n{tail}"
    assert "references to IRs" not in out.stderr, f"{what}: {out.stderr[-500:]}"


def _simulate(env: dict[str, str], tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    out_dir = tmp_path / f"sim{len(list(tmp_path.glob('sim*')))}"
    return subprocess.run([sys.executable, "-m", "s2cl", "simulate", "-q", "-o", str(out_dir), *args],
                          capture_output=True, text=True, env=env, timeout=600, cwd=tmp_path)


def _main_job_runs(env: dict[str, str], tmp_path: Path, rows: list[dict], what: str) -> None:
    out = _simulate(env, tmp_path)
    assert out.returncode == 0, f"{what}, drivers {_drivers(rows)}: s2cl simulate {_how(out)}: {out.stderr[-1500:]}"
    assert out.stderr == "", out.stderr[-1500:]


def _pocl(rows: list[dict]) -> list[dict]:
    return [r for r in rows if "Portable" in r["platform"] and "CPU" in r["kind"]]


def test_two_cpu_devices_of_one_name(tmp_path) -> None:
    """Each PoCL driver lists two CPU devices of one name: that name is refused in one line naming both (and
    every other match) by indices; indices work; the device tests pass."""
    env = _env(tmp_path, POCL_DEVICES="pthread pthread")
    rows = _pocl(_devices(env))
    if not any(r["builds"] for r in rows):
        pytest.skip("no PoCL CPU driver builds kernels here")
    name = next(r["name"] for r in rows if r["builds"])
    twins = [r for r in rows if r["name"] == name]
    assert len(twins) >= 2, f"$POCL_DEVICES gave no second device: {[r['name'] for r in rows]}"
    for spec in ("pthread", name):
        out = _simulate(env, tmp_path, "-d", spec)
        assert out.returncode == 2 and "Traceback" not in out.stderr, _how(out) + out.stderr[-800:]
        line = out.stderr.strip()
        assert "\n" not in line and "ambiguous" in line, line
        assert all(f"{r['spec']} {r['name']}" in line for r in (twins if spec == name else rows)), line
    out = _simulate(env, tmp_path, "-d", twins[1]["spec"])
    assert out.returncode == 0, f"-d {twins[1]['spec']}: {_how(out)}: {out.stderr[-800:]}"
    _pytest(env, NAMES, rows, "two devices of one name")


def test_two_cpu_devices_named_apart(tmp_path) -> None:
    """``pthread`` and ``basic`` devices on each driver: a full name only one device has works even where other
    names contain it; the device tests pass."""
    env = _env(tmp_path, POCL_DEVICES="pthread basic")
    rows = [r for r in _pocl(_devices(env)) if r["builds"]]
    if not rows:
        pytest.skip("no PoCL CPU driver builds kernels here")
    names = [r["name"] for r in rows]
    unique = next(r for r in rows if names.count(r["name"]) == 1)
    out = _simulate(env, tmp_path, "-d", unique["name"])
    assert out.returncode == 0, f"-d {unique['name']!r}: {_how(out)}: {out.stderr[-800:]}"
    _pytest(env, NAMES, rows, "two devices named apart")


def test_only_the_wheels_pocl(tmp_path) -> None:
    """The pyopencl wheel's PoCL alone (the system's OpenCL drivers hidden)."""
    empty = tmp_path / "no-vendors"
    empty.mkdir()
    env = _env(tmp_path, OCL_ICD_VENDORS=str(empty))
    rows = _pocl(_devices(env))
    if not rows:
        pytest.skip("the pyopencl wheel brings no PoCL here (pip install 'pyopencl[pocl]')")
    if not any(r["builds"] for r in rows):
        pytest.skip(f"the wheel's PoCL cannot compile on this CPU: {rows[0]['why_not']}")
    _pytest(env, WIDTHS, rows, "only the wheel's PoCL")
    _main_job_runs(env, tmp_path, rows, "only the wheel's PoCL")


def test_only_the_distributions_pocl(tmp_path) -> None:
    """The distribution's PoCL alone (the wheel's hidden: its ICD loader reads only the one file named)."""
    icds = sorted(VENDORS.glob("*pocl*.icd")) if VENDORS.is_dir() else []
    if not icds:
        pytest.skip("the distribution's PoCL is not installed (apt-get install pocl-opencl-icd)")
    env = _env(tmp_path, OCL_ICD_VENDORS=str(icds[0]))
    rows = _pocl(_devices(env))
    if len({r["driver"] for r in rows}) != 1:
        pytest.skip(f"this ICD loader does not read one .icd file alone: {_drivers(rows)}")
    if not any(r["builds"] for r in rows):
        pytest.skip(f"the distribution's PoCL cannot compile here: {rows[0]['why_not']}")
    _pytest(env, WIDTHS, rows, "only the distribution's PoCL")
    _main_job_runs(env, tmp_path, rows, "only the distribution's PoCL")


def test_a_compiler_that_aborts_at_the_reported_width(tmp_path) -> None:
    """Every device reports 16 float lanes and the probe's compiler aborts building 16: each driver steps down
    (``16 aborted``), the width tests and the main job pass."""
    env = _env(tmp_path, **{REPORTED_ENV: "16", ABORT_ENV: "16"})
    rows = [r for r in _pocl(_devices(env)) if r["builds"]]
    if not rows:
        pytest.skip("no PoCL CPU driver builds kernels here")
    for row in rows:
        verdicts = {(r, w): v for r, w, v, _ in row["checks"]}
        assert verdicts[("float32", 16)] == "aborted" and 0 < row["clean"]["float32"] < 16, row
    _pytest(env, (["tests/test_widths.py", "tests/test_vecmath.py"], WIDTHS[1]), rows, "a compiler aborting at 16")
    _main_job_runs(env, tmp_path, rows, "a compiler aborting at 16")


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="needs valgrind (apt-get install valgrind)")
def test_on_a_real_avx2_target_a_reported_16_steps_down_and_the_kernels_pass(tmp_path) -> None:
    """Under valgrind (an AVX2 CPU as PoCL sees it) with the device reporting 16 float lanes: every PoCL driver
    that builds there chooses 8 because 16 warns or kills the compiler (both step down), and the vector-math
    kernel tests, forced to 16 lanes, pass at the width chosen, with builds that must not warn."""
    env = _env(tmp_path, **{REPORTED_ENV: "16", "POCL_KERNEL_CACHE": "0"})
    vg = ["valgrind", "--tool=none", "-q", "--trace-children=yes", sys.executable]
    out = subprocess.run([*vg, "-m", "s2cl", "devices", "--json"], capture_output=True, text=True, env=env,
                         timeout=600)
    assert out.returncode == 0, f"{_how(out)}: {out.stderr[-2000:]}"
    rows = [r for r in json.loads(out.stdout) if r["builds"] and "Portable" in r["platform"]]
    if not rows or any(r["target"] not in AVX2_ONLY for r in rows):
        pytest.skip(f"valgrind did not give an AVX2 target: {[r['target'] for r in rows]}")
    for row in rows:
        assert row["clean"] == {"float32": 8, "float64": 4}, row
        verdicts = {(r, w): v for r, w, v, _ in row["checks"]}
        assert verdicts[("float32", 16)] in ("warns", "aborted") and verdicts[("float64", 8)] in ("warns", "aborted")
    out = subprocess.run([*vg, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--device", "all",
                          str(REPO / "tests" / "test_vecmath.py"), "-k", "lanes16 or lanes8"],
                         capture_output=True, text=True, env=env, timeout=900, cwd=REPO)
    assert out.returncode == 0, f"{_how(out)}: {out.stdout[-3000:]}"
    assert " passed" in out.stdout
