"""Vector widths decided by building (s2cl.cl.probe): a reported width the code target cannot build steps down,
a probe the compiler kills is restarted past that width, verdicts are cached per driver, and the default device
is the one whose clean width is widest.

Expectations come from the device under test (builds of the tests' own), never from the machine these tests
were written on; tests/test_machines.py runs them under other drivers, a compiler that aborts, and an AVX2 target.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from s2cl.cl import devices, probe
from s2cl.cl.probe import ABORT_ENV, REPORTED_ENV, WidthCheck, Widths, first_diagnostic, measure
from s2cl.errors import InputError

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch) -> Path:
    """An empty user cache, so every verdict is probed anew."""
    monkeypatch.setenv("S2CL_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _measure(rt) -> Widths:
    return measure(rt.device, rt.info.platform_index, rt.info.device_index)


def _built_apart(rt, real_t: str, width: int) -> str:
    """The build log of the probe kernel at ``width`` built in a fresh process of the test's own (not the probe's
    child), or "FAILED: ..." where the build raised or the process died (as the emulated compiler of
    ``$S2CL_PROBE_ABORT`` does at its width)."""
    if os.environ.get(ABORT_ENV, "").strip() == str(width):
        return "FAILED: the emulated compiler aborts at this width"
    script = ("import sys, pyopencl as cl\n"
              "from s2cl.cl.probe import probe_source\n"
              "p, d = int(sys.argv[1]), int(sys.argv[2])\n"
              "dev = cl.get_platforms()[p].get_devices()[d]\n"
              "prg = cl.Program(cl.Context([dev]), probe_source(sys.argv[3], int(sys.argv[4])))\n"
              "try:\n    prg.build(cache_dir=False)\nexcept cl.Error as e:\n    print('FAILED:', e); sys.exit(0)\n"
              "print(prg.get_build_info(dev, cl.program_build_info.LOG))\nsys.stdout.flush()\n"
              "import os; os._exit(0)\n")  # a driver that aborts releasing the context cannot hide the log
    out = subprocess.run([sys.executable, "-c", script, str(rt.info.platform_index), str(rt.info.device_index),
                          real_t, str(width)], capture_output=True, text=True, timeout=300,
                         env=os.environ | {"POCL_KERNEL_CACHE": "0"})
    return out.stdout if out.returncode == 0 else f"FAILED: status {out.returncode}"


def _clean_apart(rt, real_t: str, width: int) -> bool:
    log = _built_apart(rt, real_t, width)
    return not log.startswith("FAILED") and "warning" not in log.lower()


def test_each_verdict_is_what_the_build_says(rt) -> None:
    """Every probed width's verdict is what a build in this process says; the default lanes are the widest
    clean width on CPUs; nothing wider than the clean width was clean."""
    w = rt.widths
    assert w.checks, "no width was probed"
    for c in w.checks:
        if c.verdict != "aborted":
            assert probe.build_verdict(rt.device, c.real_t, c.width)[0] == c.verdict, c
    for real_t in w.clean:
        clean = [c.width for c in w.checks if c.real_t == real_t and c.verdict == "clean"]
        assert clean == ([w.clean[real_t]] if w.clean[real_t] else [])
        assert all(c.width > w.clean[real_t] for c in w.checks if c.real_t == real_t and c.verdict != "clean")
    if "CPU" in rt.info.kind:
        assert rt.lanes("float32") == w.clean["float32"]


def test_a_reported_width_the_target_lacks_steps_down(rt, fresh_cache, monkeypatch) -> None:
    """The device reports 16 float lanes. Whatever its code target, the chosen width is the widest of 16, 8, ...
    that a build of the test's own, in another process, finds clean: 16 where the target has AVX-512; else 16
    warns "changes the ABI" or kills the compiler (the wheel's PoCL on Zen 4 may do either; both step down) and
    a narrower width is chosen."""
    if "CPU" not in rt.info.kind or "portable computing language" not in rt.info.platform.lower():
        pytest.skip("PoCL CPU rule")
    monkeypatch.setenv(REPORTED_ENV, "16")
    w = _measure(rt)
    assert w.reported == {"float32": 16, "float64": 8}
    first = w.checks[0]
    assert (first.real_t, first.width) == ("float32", 16)
    expected = next((n for n in (16, 8, 4, 2, 1) if _clean_apart(rt, "float32", n)), 0)
    assert w.clean["float32"] == expected
    if expected == 16:
        assert first.verdict == "clean"
    else:
        assert first.verdict in ("warns", "fails", "aborted"), first
        assert "16 " + first.verdict in w.why("float32")
        if first.verdict == "warns":
            assert first.detail == probe.first_diagnostic(_built_apart(rt, "float32", 16))
        assert f"{expected} builds clean" in w.why("float32")


def test_a_build_that_warns_never_aborts_the_process(rt, tmp_path) -> None:
    """Each width of the probe plan built in this process, warnings and all, then the process ends normally:
    the wheel's PoCL 3.0 aborted ("still have references to IRs", status 134) releasing a context whose build
    warned "changes the ABI" and came from PoCL's kernel cache (s2cl.cl.builds.keep_context_until_exit)."""
    script = tmp_path / "warn_then_exit.py"
    script.write_text(
        "import sys\n"
        "from s2cl.cl.devices import device_of, list_devices\n"
        "from s2cl.cl.probe import build_verdict\n"
        "from s2cl.cl.runtime import get_runtime\n"
        "info = next(i for i in list_devices() if i.spec == sys.argv[1])\n"
        "for width in (16, 16, 8, 8):  # the second build of a width comes from PoCL's kernel cache\n"
        "    print(width, build_verdict(device_of(info), 'float32', width)[0], flush=True)\n"
        "rt = get_runtime(sys.argv[1])\n"
        "rt.build('float f(float a) { if (a > 0.0f) return a; }\\n"
        "__kernel void k(__global float *x) { x[0] = f(x[0]); }\\n', template='warns.cl')\n"
        "print('done', flush=True)\n")
    env = {k: v for k, v in os.environ.items() if k != "S2CL_BUILD_WARNINGS"} | {
        "POCL_CACHE_DIR": str(tmp_path / "pocl")}
    out = subprocess.run([sys.executable, str(script), rt.info.spec], capture_output=True, text=True, timeout=300,
                         env=env)
    assert out.returncode == 0, f"status {out.returncode} on {rt.info}: {out.stderr[-500:]}"
    assert out.stdout.splitlines()[-1] == "done" and "references to IRs" not in out.stderr


def test_a_probe_the_compiler_kills_is_restarted_past_that_width(rt, fresh_cache, monkeypatch) -> None:
    """LLVM aborting on a width kills the probe's child, never this process; the next child goes on with the
    narrower widths."""
    if "CPU" not in rt.info.kind:
        pytest.skip("CPU plan (reported width and its halves)")
    monkeypatch.setenv(REPORTED_ENV, "16")
    monkeypatch.setenv(ABORT_ENV, "16")
    w = _measure(rt)
    assert w.where == "child"
    assert w.checks[0] == WidthCheck("float32", 16, "aborted", "the compiler killed the probe (signal 6)")
    assert w.checks[1].real_t == "float32" and w.checks[1].width == 8
    assert w.clean["float32"] == next((n for n in (8, 4, 2, 1) if _clean_apart(rt, "float32", n)), 0)
    assert "16 aborted" in w.why("float32")


def test_a_probe_the_compiler_hangs_is_stopped_and_passed(rt, fresh_cache, monkeypatch) -> None:
    """A compiler that never returns costs the probe's time limit, never the user's command: the width counts as
    aborted and the next child goes on below it."""
    if "CPU" not in rt.info.kind:
        pytest.skip("CPU plan (reported width and its halves)")
    monkeypatch.setenv(REPORTED_ENV, "16")
    monkeypatch.delenv(ABORT_ENV, raising=False)  # this test's machine hangs at 16; it does not abort there
    monkeypatch.setenv(probe.HANG_ENV, "16")
    monkeypatch.setenv(probe.TIMEOUT_ENV, "5")
    w = _measure(rt)
    assert w.where == "child"
    assert w.checks[0] == WidthCheck("float32", 16, "aborted", "the compiler gave no verdict in 5 s")
    assert w.clean["float32"] == next((n for n in (8, 4, 2, 1) if _clean_apart(rt, "float32", n)), 0)


def test_verdicts_are_cached_per_driver_and_report(rt, fresh_cache, monkeypatch) -> None:
    first = _measure(rt)
    assert len(list((fresh_cache / "devices").glob("widths-*.json"))) == 1

    def no_child(*args, **kwargs):
        raise AssertionError("probed again")

    monkeypatch.setattr(probe.subprocess, "run", no_child)
    assert _measure(rt) == first  # a later process pays nothing
    monkeypatch.setenv(REPORTED_ENV, "4")  # another report is another key
    with pytest.raises(AssertionError, match="probed again"):
        _measure(rt)


def test_the_probe_runs_in_process_where_no_child_can(rt, fresh_cache, monkeypatch) -> None:
    if os.environ.get(ABORT_ENV):
        pytest.skip(f"${ABORT_ENV} emulates a compiler that aborts: probing in this process would end it")
    child = _measure(rt)
    (fresh_cache / "devices").rename(fresh_cache / "old")

    def cannot_start(*args, **kwargs):
        raise OSError("no fork here")

    monkeypatch.setattr(probe.subprocess, "run", cannot_start)
    here = _measure(rt)
    assert here.where == "in process"
    assert here.clean == child.clean and here.reported == child.reported


@pytest.mark.parametrize("text", ["12", "float32=16,float128=2", "sixteen"])
def test_reported_width_setting_is_checked(rt, monkeypatch, text: str) -> None:
    monkeypatch.setenv(REPORTED_ENV, text)
    with pytest.raises(InputError, match=REPORTED_ENV):
        probe.reported_widths(rt.device)


def test_first_diagnostic_is_the_compilers_words_without_positions() -> None:
    log = ("/tmp/pocl/kernel.cl:1:7: warning: AVX vector argument of type 'float16' (vector of 16 'float' values) "
           "without 'avx512f' enabled changes the ABI [-Wpsabi]\nfloat16 s2cl_probe_f(float16 a)\n      ^\n"
           "1 warning generated.\n")
    assert first_diagnostic(log) == ("AVX vector argument of type 'float16' without 'avx512f' enabled changes "
                                     "the ABI [-Wpsabi]")
    assert first_diagnostic("error: unknown target CPU 'generic'") == "error: unknown target CPU 'generic'"


def test_the_default_device_builds_the_widest_clean_vectors(monkeypatch) -> None:
    """Of the PoCL CPU drivers, the one whose clean float32 width is widest (ties: listed order); a driver
    that builds nothing is passed over."""
    def info(p: int, name: str) -> devices.DeviceInfo:
        return devices.DeviceInfo(p, 0, "Portable Computing Language", name, "ALL | CPU")

    wheel, distro, broken = info(0, "wheel"), info(1, "distro"), info(2, "broken")

    def fake(clean: int) -> Widths:
        checks = (WidthCheck("float32", 16, "warns", "changes the ABI"),) if clean == 8 else ()
        return Widths({"float32": 16, "float64": 8}, {"float32": clean, "float64": clean // 2}, checks)

    table = {wheel: fake(8), distro: fake(16), broken: fake(0)}
    monkeypatch.setattr(devices, "widths_of", lambda i: table[i])
    assert devices._first_working([broken, wheel, distro]) == distro
    table[distro] = fake(8)
    assert devices._first_working([broken, wheel, distro]) == wheel


def test_devices_command_shows_each_width_and_why(rt) -> None:
    out = subprocess.run([sys.executable, "-m", "s2cl", "devices"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert f"float32: {rt.widths.clean['float32']} lanes (reported {rt.widths.reported['float32']};" in out.stdout
    data = json.loads(subprocess.run([sys.executable, "-m", "s2cl", "devices", "--json"], capture_output=True,
                                     text=True, timeout=300, check=True).stdout)
    default = [row for row in data if row["default"]]
    assert len(default) == 1 and default[0]["lanes"]["float32"] == default[0]["clean"]["float32"]
