"""The committed corpus of hostile scenes (``tests/data/bad_inputs/``) through ``s2cl simulate`` and
``s2cl sweep count`` in subprocesses: exit code 2, one ``error:`` line naming the file and key (each
case's first line says ``# expect: TEXT``), no traceback, no output folder, nothing written anywhere
(the working folder is compared before and after, and each run gets an empty ``$TMPDIR``).

A fresh ``python -m s2cl`` costs about a second of imports, 180 of them three minutes on two cores.
So each run is a child process forked from this test process after s2cl is imported, running the
CLI's entry point ``s2cl.cli.main.main`` with its own working folder, ``$TMPDIR``, stdout and stderr
files, and exit code; two children run at a time. One case in ten also runs as a real
``python -m s2cl`` and must give the same exit code and stderr line.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

CORPUS = Path(__file__).resolve().parent / "data" / "bad_inputs"
CASES = sorted(CORPUS.glob("*.toml"))
COMMANDS = ("simulate", "sweep count")
PARALLEL = 2


def expectation(case: Path) -> str:
    first = case.read_bytes().split(b"\n", 1)[0].decode()
    assert first.startswith("# expect: "), case.name
    return first[len("# expect: "):]


def _tree(root: Path) -> dict[str, int]:
    return {str(p.relative_to(root)): p.stat().st_size for p in root.rglob("*") if not p.is_symlink()}


def _child(args: list[str], cwd: Path, tmpdir: Path, out: Path, err: Path) -> None:
    """In the forked child: run the CLI with its own folder, $TMPDIR and output files; never return."""
    import io
    import tempfile
    import traceback

    code = 1
    try:
        os.chdir(cwd)
        os.environ["TMPDIR"] = str(tmpdir)
        tempfile.tempdir = None
        for fd, path in ((1, out), (2, err)):
            f = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
            os.dup2(f, fd)
            os.close(f)
        sys.stdout = io.TextIOWrapper(io.FileIO(1, "w", closefd=False), write_through=True)
        sys.stderr = io.TextIOWrapper(io.FileIO(2, "w", closefd=False), write_through=True)
        from s2cl.cli.main import main

        main(args)
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    except BaseException:
        traceback.print_exc()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def run_forked(jobs: list[tuple[list[str], Path, Path, Path]]) -> list[subprocess.CompletedProcess]:
    """Run each (args, working folder, $TMPDIR, log stem) as a forked child, ``PARALLEL`` at a time."""
    import s2cl.cli.main  # noqa: F401  (imported once, here, before any fork)

    sys.stdout.flush()
    sys.stderr.flush()
    running: dict[int, int] = {}
    codes: dict[int, int] = {}
    for i, (args, cwd, tmpdir, stem) in enumerate(jobs):
        while len(running) >= PARALLEL:
            pid, status = os.waitpid(-1, 0)
            codes[running.pop(pid)] = os.waitstatus_to_exitcode(status)
        pid = os.fork()
        if pid == 0:
            _child(args, cwd, tmpdir, stem.with_suffix(".out"), stem.with_suffix(".err"))
        running[pid] = i
    while running:
        pid, status = os.waitpid(-1, 0)
        codes[running.pop(pid)] = os.waitstatus_to_exitcode(status)
    return [subprocess.CompletedProcess(args, codes[i], stem.with_suffix(".out").read_text(),
                                        stem.with_suffix(".err").read_text())
            for i, (args, _, _, stem) in enumerate(jobs)]


@pytest.fixture(scope="module")
def corpus_run(tmp_path_factory) -> tuple[Path, dict[str, int], dict]:
    """Every case through both commands: (working folder, its files before, outcomes), where outcomes
    maps (case, command) to (completed process, files left in its $TMPDIR)."""
    work = tmp_path_factory.mktemp("bad_inputs")
    shutil.copytree(CORPUS, work, dirs_exist_ok=True)
    before = _tree(work)
    scratch = tmp_path_factory.mktemp("runs")
    keys, jobs = [], []
    for i, (case, command) in enumerate((c, m) for c in CASES for m in COMMANDS):
        tmpdir = scratch / f"tmp{i}"
        tmpdir.mkdir()
        keys.append((case.name, command, tmpdir))
        jobs.append(([*command.split(), case.name], work, tmpdir, scratch / f"log{i}"))
    done = run_forked(jobs)
    outcomes = {(name, cmd): (out, [str(p) for p in tmp.rglob("*")]) for (name, cmd, tmp), out in zip(keys, done,
                                                                                                       strict=True)}
    return work, before, outcomes


def test_the_corpus_is_large_enough() -> None:
    assert len(CASES) >= 120


def test_each_case_names_its_own_folder() -> None:
    """The check that no output folder was created looks for s2cl-out/NAME, NAME the case's name after its
    number: every case whose scene name is a valid folder name uses that name."""
    import tomllib

    from s2cl.scene.schema import SCENE_NAME

    for case in CASES:
        try:
            name = tomllib.loads(case.read_text(encoding="utf-8"))["scene"]["name"]
        except (tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError, KeyError, TypeError):
            continue  # not TOML (or nested too deeply), or no name: no folder of its own can be created
        if isinstance(name, str) and SCENE_NAME.fullmatch(name):
            assert name == case.stem.split("-", 1)[1], case.name


def test_no_case_wrote_anything(corpus_run) -> None:
    work, before, _ = corpus_run
    after = _tree(work)
    assert after == before, sorted(set(after) ^ set(before))[:10]


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("case", CASES, ids=[c.stem for c in CASES])
def test_bad_input_is_one_line_and_leaves_nothing(corpus_run, case: Path, command: str) -> None:
    work, _, outcomes = corpus_run
    out, left = outcomes[(case.name, command)]
    assert out.returncode == 2, (out.returncode, out.stdout[-300:], out.stderr[-1000:])
    lines = out.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), out.stderr[-1000:]
    assert "Traceback" not in out.stderr
    line = lines[0]
    assert expectation(case) in line, line
    assert case.name in line or "files/" in line or "missing.csv" in line, line  # names the file at fault
    assert not (work / "s2cl-out" / case.stem.split("-", 1)[1]).exists(), "an output folder was created"
    assert left == [], "temporary files were left"


@pytest.mark.parametrize("case", CASES[::10], ids=[c.stem for c in CASES[::10]])
def test_a_real_process_says_the_same(corpus_run, case: Path) -> None:
    work, _, outcomes = corpus_run
    real = subprocess.run([sys.executable, "-m", "s2cl", "simulate", case.name], cwd=work, capture_output=True,
                          text=True, timeout=300)
    forked, _ = outcomes[(case.name, "simulate")]
    assert (real.returncode, real.stderr) == (forked.returncode, forked.stderr)
