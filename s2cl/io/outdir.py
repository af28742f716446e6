"""Output folders: checked before anything is computed, claimed by one run at a time, tidied.

A command that writes into a folder first calls :func:`check_output_dir` (nothing is created: a
folder that cannot be written, on a read-only or virtual filesystem such as ``/proc``, or below
a file, is a one-line :class:`~s2cl.errors.OutputError` before any work). When the work starts it
holds :func:`claim` for the folder: an advisory lock (``.s2cl.lock``) that a second run into the same
folder cannot take, so two runs never compute or write the same files; it also removes the temporary
files (``.NAME.XXXX.tmp``, see :mod:`s2cl.io.output`) that a killed run left behind. The lock file
exists only while a run holds it (only a killed run leaves it, and the next run takes it over). A run
that fails before it has written a result removes the folder it created.
"""

from __future__ import annotations

import errno
import logging
import os
from collections.abc import Callable, Iterator
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
    files found there. A second claim on the same folder (another process) fails at once. When the
    body fails, its temporary files are removed, and when the folder was created here and holds no result yet,
    the folder is removed.

    :raises OutputError: the folder cannot be created, or another run holds it.
    """
    out = Path(path)
    created = _missing_parts(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create the folder ({os.strerror(err.errno or 0)})", path=out) from err
    try:
        release = _lock(out / LOCK_NAME)
    except BaseException:
        _remove_empty(created)
        raise
    try:
        remove_stale_temps(out)
        yield out
    except BaseException:
        # an atomic write interrupted between creating its temporary file and guarding it (a signal handled
        # there: SIGTERM on a loaded machine) leaves the file; under the lock, every temporary here is this run's
        remove_stale_temps(out)
        if created and _holds_no_result(out):
            _remove_unfinished(out)
        release()
        _remove_empty(created)
        raise
    release()


def _missing_parts(out: Path) -> list[Path]:
    """The folders of ``out`` (deepest first) that do not exist yet and a claim would create."""
    missing = []
    p = Path(os.path.abspath(out))
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    return missing


_UNFINISHED = ("manifest.json", "chunks", LOCK_NAME)


def _holds_no_result(out: Path) -> bool:
    """Only what a run writes before its first result: the lock, a sweep's manifest, an empty ``chunks/``."""
    return all(p.name in _UNFINISHED and not (p.is_dir() and any(p.iterdir())) for p in out.iterdir())


def _remove_unfinished(out: Path) -> None:
    """Remove a failed run's manifest and empty ``chunks/`` (the caller holds the lock)."""
    (out / "manifest.json").unlink(missing_ok=True)
    try:
        (out / "chunks").rmdir()
    except OSError:
        pass


def _remove_empty(created: list[Path]) -> None:
    """Remove the folders a claim created, deepest first, as long as they are empty (another run's files stay)."""
    for p in created:
        try:
            p.rmdir()
        except FileNotFoundError:
            continue
        except OSError:
            return


def _lock(path: Path) -> Callable[[], None]:
    """Take the advisory lock ``path`` (created, held, and removed on release); returns the release.

    POSIX: ``flock`` on the file, then a check that the locked file is still the one at ``path`` (a run
    that released the lock removed it; one that locked the removed file retries on the new one), so
    removing the file on release never lets two runs hold the folder. Elsewhere: :mod:`filelock`.
    """
    busy = ("another s2cl run is writing into this folder (it holds .s2cl.lock); wait for it to finish or "
            "choose another --output")
    try:
        import fcntl
    except ImportError:  # Windows
        from filelock import FileLock, Timeout

        lock = FileLock(path, timeout=0)
        try:
            lock.acquire()
        except Timeout:
            raise OutputError(busy, path=path.parent) from None
        except OSError as err:
            raise OutputError(f"cannot lock the folder ({os.strerror(err.errno or 0)})", path=path.parent) from err
        return lock.release
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as err:
            raise OutputError(f"cannot lock the folder ({os.strerror(err.errno or 0)})", path=path.parent) from err
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            os.close(fd)
            if err.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                raise OutputError(busy, path=path.parent) from None
            raise OutputError(f"cannot lock the folder ({os.strerror(err.errno or 0)})", path=path.parent) from err
        held = os.fstat(fd)
        try:
            now = os.stat(path)
        except FileNotFoundError:
            now = None
        if now is not None and (now.st_ino, now.st_dev) == (held.st_ino, held.st_dev):
            break
        os.close(fd)  # the holder before us removed it: lock the file now at ``path``

    def release() -> None:
        try:
            os.unlink(path)  # while still holding it: nobody can lock this file and believe it current
        except OSError:
            pass
        os.close(fd)

    return release


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
