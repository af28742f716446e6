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


def check_output_dir(path: str | Path, *, where: str = "") -> Path:
    """Check that ``path`` is, or can become, a writable folder; create nothing.

    :param where: how the user chose the folder (``--output``, ``output.directory in s.toml``),
        appended to the message so the user knows what to change.
    :raises OutputError: naming the folder and what is wrong.
    """
    out = Path(path)
    hint = f" (set by {where})" if where else ""
    if out.exists() and not out.is_dir():
        raise OutputError(f"exists and is not a folder{hint}", path=out)
    base = _existing_ancestor(out)
    if not base.is_dir():
        raise OutputError(f"cannot be created: {base} is not a folder{hint}", path=out)
    if hasattr(os, "statvfs"):  # POSIX: what kind of filesystem the folder would be on
        try:
            fs = os.statvfs(base)
        except OSError as err:
            raise OutputError(f"cannot be checked ({os.strerror(err.errno or 0)}){hint}", path=out) from err
        if fs.f_blocks == 0:
            raise OutputError(f"is on a virtual filesystem (such as /proc) that holds no files{hint}", path=out)
        if fs.f_flag & os.ST_RDONLY:
            raise OutputError(f"is on a read-only filesystem{hint}", path=out)
    for folder in (base, out / "chunks"):
        if folder.is_dir() and not os.access(folder, os.W_OK | os.X_OK):
            raise OutputError(f"{folder} is not writable{hint}", path=out)
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
