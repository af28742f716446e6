"""Output folders: checked before anything is computed, claimed by one run at a time, tidied.

A command that writes into a folder first calls :func:`check_output_dir` (nothing is created: a
folder that cannot be written, on a read-only or virtual filesystem such as ``/proc``, or below
a file, is a one-line :class:`~s2cl.errors.OutputError` before any work). When the work starts it
holds :func:`claim` for the folder: an advisory lock (``.s2cl.lock``, the ``filelock`` package)
that a second run into the same folder cannot take, so two runs never compute or write the same
files; it also removes the temporary files (``.NAME.XXXX.tmp``, see :mod:`s2cl.io.output`) that a
killed run left behind.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from s2cl.errors import OutputError

LOCK_NAME = ".s2cl.lock"
_log = logging.getLogger(__name__)


def _existing_ancestor(path: Path) -> Path:
    """The deepest folder of ``path`` (or ``path`` itself) that exists."""
    p = Path(os.path.abspath(path))
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def check_output_dir(path: str | Path, *, where: str = "", writes: tuple[str, ...] = ()) -> Path:
    """Check that ``path`` is, or can become, a writable folder that s2cl may write into; create nothing.

    s2cl writes only into a new folder, an empty one, or one of its own output folders (one that holds
    ``.s2cl.lock`` or a file s2cl writes: :data:`OUTPUT_NAMES`, or ``writes``); never into the filesystem's
    root, a system folder (:data:`SYSTEM_FOLDERS`) or the home folder itself, where its files would land
    beside the user's.

    :param where: how the user chose the folder (``--output``, ``output.directory in s.toml``),
        appended to the message so the user knows what to change.
    :param writes: further names of files the command writes (a study's ``NAME.json``), which mark
        the folder as an s2cl output folder too.
    :raises OutputError: naming the folder and what is wrong.
    """
    out = Path(path)
    hint = f" (set by {where})" if where else ""
    if out.exists() and not out.is_dir():
        raise OutputError(f"exists and is not a folder{hint}", path=out)
    base = _existing_ancestor(out)
    if not base.is_dir():
        raise OutputError(f"cannot be created: {base} is not a folder{hint}", path=out)
    _check_filesystem(base, out, hint)
    for folder in (base, out / "chunks"):
        if folder.is_dir() and not os.access(folder, os.W_OK | os.X_OK):
            raise OutputError(f"{folder} is not writable{hint}", path=out)
    _check_not_foreign(out, hint, writes)
    return out


def _check_filesystem(base: Path, out: Path, hint: str) -> None:
    """Refuse a folder on a virtual (``/proc``) or read-only filesystem (POSIX; ``base`` exists)."""
    if not hasattr(os, "statvfs"):
        return
    try:
        fs = os.statvfs(base)
    except OSError as err:
        raise OutputError(f"cannot be checked ({os.strerror(err.errno or 0)}){hint}", path=out) from err
    if fs.f_blocks == 0:
        raise OutputError(f"is on a virtual filesystem (such as /proc) that holds no files{hint}", path=out)
    if fs.f_flag & os.ST_RDONLY:
        raise OutputError(f"is on a read-only filesystem{hint}", path=out)


#: files and folders s2cl writes into an output folder (besides a study's NAME.json / NAME.png)
OUTPUT_NAMES = (LOCK_NAME, "simulation.nc", "simulation.json", "results.parquet", "summary.json", "manifest.json",
                "chunks")
#: folders no run may write into (nor the filesystem's root, nor the home folder itself)
SYSTEM_FOLDERS = ("/bin", "/boot", "/dev", "/etc", "/lib", "/lib32", "/lib64", "/opt", "/proc", "/root", "/run",
                  "/sbin", "/srv", "/sys", "/tmp", "/usr", "/var", "/home", "/Users", "/System", "/Library",
                  "/Applications", "/private", "C:\\Windows")


def _check_not_foreign(out: Path, hint: str, writes: tuple[str, ...]) -> None:
    """Refuse the root, a system folder, the home folder, and an existing folder that holds files but none
    of s2cl's (its files would be mixed with, or replace, the user's)."""
    real = Path(os.path.realpath(out))
    home = Path(os.path.expanduser("~"))
    if real == Path(real.anchor) or str(real) in SYSTEM_FOLDERS or (home != Path(home.anchor) and real == home):
        raise OutputError(f"is the filesystem's root, a system folder or the home folder: s2cl writes into a "
                          f"folder of its own (e.g. s2cl-out/NAME){hint}", path=out)
    if not out.is_dir():
        return
    try:
        entries = [e.name for e in os.scandir(out)]
    except OSError as err:
        raise OutputError(f"cannot be listed ({os.strerror(err.errno or 0)}){hint}", path=out) from err
    ours = set(OUTPUT_NAMES) | set(writes)
    if entries and not any(e in ours or e.startswith("heatmap_") for e in entries):
        raise OutputError(f"holds files that s2cl did not write (such as {sorted(entries)[0]!r}): s2cl writes into a "
                          f"new or empty folder, or one of its own output folders; choose another folder{hint}",
                          path=out)


def check_output_file(path: str | Path, *, where: str = "") -> Path:
    """Check that file ``path`` can be written into its folder, which must exist (nothing is created)."""
    out = Path(path)
    hint = f" (set by {where})" if where else ""
    folder = out.parent
    if out.is_dir():
        raise OutputError(f"is a folder, not a file{hint}", path=out)
    if not folder.is_dir():
        raise OutputError(f"cannot be written: its folder {folder} does not exist (s2cl does not create it){hint}",
                          path=out)
    _check_filesystem(folder, out, hint)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"cannot be written: {folder} is not writable{hint}", path=out)
    return out


@contextmanager
def claim(path: str | Path) -> Iterator[Path]:
    """Create folder ``path`` and hold its advisory lock for the duration; remove stale temporary
    files found there. A second claim on the same folder (another process) fails at once.

    :raises OutputError: the folder cannot be created, or another run holds it.
    """
    from filelock import FileLock, Timeout

    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create the folder ({os.strerror(err.errno or 0)})", path=out) from err
    lock = FileLock(out / LOCK_NAME, timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise OutputError("another s2cl run is writing into this folder (it holds .s2cl.lock); wait for it to "
                          "finish or choose another --output", path=out) from None
    except OSError as err:
        raise OutputError(f"cannot lock the folder ({os.strerror(err.errno or 0)})", path=out) from err
    try:
        remove_stale_temps(out)
        yield out
    finally:
        lock.release()


def remove_stale_temps(folder: Path) -> list[Path]:
    """Delete the temporary files of atomic writes (``.NAME.XXXX.tmp``) in ``folder`` and its
    ``chunks/``: only a run that was killed leaves them, and the caller holds the folder's lock."""
    removed = []
    for where in (folder, folder / "chunks"):
        if not where.is_dir():
            continue
        for tmp in where.glob(".*.tmp"):
            if tmp.is_file() and not tmp.is_symlink():
                tmp.unlink(missing_ok=True)
                removed.append(tmp)
    if removed:
        _log.info("removed %d temporary file(s) left by an interrupted run in %s", len(removed), folder)
    return removed
