"""The command line's own errors: usage errors, Ctrl-C, a console that
cannot show every character, a removed working folder, the environment (S2CL_LANES, PoCL's cache folder),
--scheduler and --plot: one line on stderr, exit code 2 (130 for Ctrl-C), no traceback, nothing created."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from s2cl.app.optimise import check_scheduler
from s2cl.cli.main import main
from s2cl.errors import InputError

ROOT = Path(__file__).resolve().parent.parent


def run_main(args: list[str], capsys) -> tuple[int, str, str]:
    """``s2cl ARGS`` in this process: (exit code, stdout, stderr)."""
    code = 0
    try:
        main(args)
    except SystemExit as done:
        code = done.code if isinstance(done.code, int) else 1
    out = capsys.readouterr()
    return code, out.out, out.err


def subprocess_s2cl(*args: str, cwd: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    full = {**os.environ, "PYTHONPATH": str(ROOT), **(env or {})}
    return subprocess.run([sys.executable, "-m", "s2cl", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300, env=full)


def one_line(code: int, err: str, *parts: str) -> str:
    lines = err.splitlines()
    assert code == 2, (code, err)
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    for part in parts:
        assert part in lines[0], (part, lines[0])
    return lines[0]


@pytest.mark.parametrize(("args", "parts"), [
    (["optimise", "--chunk", "0"], ("--chunk", "`s2cl optimise --help`")),
    (["optimise", "--workers", "0"], ("--workers",)),
    (["optimise", "--backend", "cuda"], ("--backend",)),
    (["simulate", "--bogus"], ("--bogus", "`s2cl simulate --help`")),
    (["simulate", "a.toml", "b.toml"], ("b.toml",)),
    (["simulate", "-o", "afile"], ("afile", "is a file")),
    (["srf", "B1", "--plot", "."], ("--plot", "is a directory")),
    (["frobnicate"], ("frobnicate", "`s2cl --help`")),
    (["optimise", "--workers", "2", "--scheduler", "tcp://h:1"], ("not both",)),
])
def test_usage_errors_are_one_line(tmp_path, monkeypatch, capsys, args: list[str], parts: tuple[str, ...]) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("")
    code, _, err = run_main(args, capsys)
    one_line(code, err, *parts)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_a_group_alone_prints_its_help(capsys) -> None:
    code, out, err = run_main(["sweep"], capsys)
    assert code == 0 and out.startswith("Usage: s2cl sweep") and err == ""


def test_ctrl_c_prints_aborted_alone(monkeypatch, capsys) -> None:
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("s2cl.scene.scene.Scene.load", interrupted)
    code, _, err = run_main(["simulate", "-q"], capsys)
    assert (code, err) == (130, "aborted\n")


def test_memory_error_is_one_line(monkeypatch, capsys) -> None:
    def exhausted(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr("s2cl.scene.scene.Scene.load", exhausted)
    code, _, err = run_main(["simulate", "-q"], capsys)
    line = one_line(code, err, "out of memory")
    assert "surface.copies" in line


@pytest.mark.parametrize("address", ["tcp://10.0.0.5:8786", "localhost:8786", "tls://sched.example.org:8786",
                                     "[::1]:8786", " tcp://host-1:1 "])
def test_scheduler_addresses_that_are_accepted(address: str) -> None:
    assert check_scheduler(address) == address.strip()


@pytest.mark.parametrize("address", ["bogus", "tcp://host", "http://h:8786", "h:70000", "h:0", "tcp://:8786",
                                     "h:8786/x", ""])
def test_scheduler_addresses_that_are_refused(address: str) -> None:
    with pytest.raises(InputError, match=r"--scheduler: .* is not a scheduler address"):
        check_scheduler(address)


def test_a_bad_scheduler_address_is_refused_before_anything_is_created(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, err = run_main(["optimise", "-q", "--scheduler", "bogus", "-o", "out"], capsys)
    one_line(code, err, "--scheduler", "'bogus'")
    assert list(tmp_path.iterdir()) == []


def test_srf_plot_never_creates_its_folder(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, err = run_main(["srf", "B1", "--platform", "none", "--plot", "nope/deeper/srf.png"], capsys)
    one_line(code, err, "nope/deeper/srf.png", "does not exist", "--plot")
    assert list(tmp_path.iterdir()) == []


def test_s2cl_lanes_is_named_when_it_is_wrong(rt, monkeypatch) -> None:
    for value in ("3", "abc", "32"):
        monkeypatch.setenv("S2CL_LANES", value)
        with pytest.raises(InputError, match=f"S2CL_LANES: must be one of .*got '{value}'"):
            rt.lanes("float32")


def test_a_console_that_cannot_show_unicode_gets_replacements(tmp_path) -> None:
    """`PYTHONIOENCODING=ascii` crashed printing λ and – after the outputs were written."""
    for args in (["sensor"], ["scenes"], ["srf", "B99"]):
        out = subprocess_s2cl(*args, cwd=tmp_path, env={"PYTHONIOENCODING": "ascii"})
        assert "Traceback" not in out.stderr and "UnicodeEncodeError" not in out.stderr, out.stderr[-500:]
        assert out.returncode == (2 if args == ["srf", "B99"] else 0), out.stderr[-500:]
    assert "B12" in subprocess_s2cl("sensor", cwd=tmp_path, env={"PYTHONIOENCODING": "ascii"}).stdout


def test_a_removed_working_folder_is_named(tmp_path) -> None:
    gone = tmp_path / "gone"
    gone.mkdir()
    script = f"cd {gone} && rmdir {gone} && exec {sys.executable} -m s2cl simulate -q"
    out = subprocess.run(["sh", "-c", script], capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    one_line(out.returncode, out.stderr, "working folder no longer exists")


def test_an_unwritable_pocl_cache_is_named_not_a_missing_platform(tmp_path) -> None:
    """With HOME or POCL_CACHE_DIR unusable PoCL lists no device; s2cl said "no OpenCL platform found"."""
    from s2cl.cl.devices import _platforms

    if not any("portable computing language" in p.name.lower() for p in _platforms()):
        pytest.skip("no PoCL platform")
    (tmp_path / "file").write_text("")
    env = {k: v for k, v in os.environ.items() if k not in ("POCL_CACHE_DIR", "XDG_CACHE_HOME", "PYOPENCL_CTX")}
    for change in ({"HOME": str(tmp_path / "file")}, {"POCL_CACHE_DIR": str(tmp_path / "file" / "pocl")}):
        out = subprocess.run([sys.executable, "-m", "s2cl", "devices"], cwd=tmp_path, capture_output=True, text=True,
                             timeout=300, env={**env, "PYTHONPATH": str(ROOT), **change})
        if out.returncode == 0:
            pytest.skip("this PoCL lists its devices without a cache folder")
        line = one_line(out.returncode, out.stderr, "POCL_CACHE_DIR", "cannot be created or written")
        assert "no OpenCL platform found" not in line


def test_an_unwritable_user_cache_is_named_before_anything_is_created(tmp_path) -> None:
    """PoCL's cache set, but HOME unusable: pyopencl failed at its first kernel call, after the output folder was
    made, with "Exception ignored ... Traceback" on stderr."""
    (tmp_path / "file").write_text("")
    env = {k: v for k, v in os.environ.items() if k not in ("XDG_CACHE_HOME", "PYOPENCL_NO_CACHE", "S2CL_CACHE")}
    env.update(HOME=str(tmp_path / "file"), POCL_CACHE_DIR=str(tmp_path / "pocl"), PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-m", "s2cl", "simulate", "-q", "-o", "out"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300, env=env)
    one_line(out.returncode, out.stderr, "cache folder", "XDG_CACHE_HOME")
    assert not (tmp_path / "out").exists()
