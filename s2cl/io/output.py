"""Atomic writes: a file appears complete or not at all (temp file in the same folder + rename)."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from s2cl.errors import OutputError


def _umask() -> int:
    """The process's file-creation mask: from /proc (Linux) where it can be read without changing
    it, else by setting and restoring it (a brief window in which other threads see 0o022). psutil,
    which gives free memory portably (:mod:`s2cl.io.budget`), has no umask; Python reads it only by
    changing it, hence /proc first."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(path: str | Path):
    """Yield a temporary path beside ``path``; on success it is renamed onto ``path``, on error removed."""
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as err:
        raise OutputError(f"cannot write here ({_reason(err)})", path=target) from err
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs get the usual permissions
        os.replace(tmp, target)
    except OSError as err:  # a full disk, a folder removed under us: one line, no temp file left
        Path(tmp).unlink(missing_ok=True)
        raise OutputError(f"cannot write ({_reason(err)})", path=target) from err
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _reason(err: OSError) -> str:
    """The system's short reason for ``err`` (libraries such as h5py pack whole reports into theirs)."""
    return os.strerror(err.errno) if err.errno else type(err).__name__


def write_atomic(path: str | Path, writer: Callable[[Path], Any]) -> Path:
    """Call ``writer(tmp_path)`` and move the result onto ``path`` atomically."""
    with atomic_path(path) as tmp:
        writer(tmp)
    return Path(path)


def write_json(path: str | Path, data: Any) -> Path:
    """Pretty JSON, written atomically. JSON has no NaN or infinity: a non-finite number is written as
    ``null`` (Python's ``json`` would write ``NaN``, which other JSON readers refuse)."""
    text = json.dumps(json_safe(data), indent=2, allow_nan=False) + "\n"
    return write_atomic(path, lambda p: p.write_text(text))


def json_safe(value: Any) -> Any:
    """``value`` with numpy scalars and arrays as Python numbers and lists, paths as strings, tuples as lists
    and every non-finite float (NaN, ±inf) as None."""
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, bool | int | str) or value is None:
        return value
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else None
    return json_safe(_jsonable(value))


def write_text(path: str | Path, text: str) -> Path:
    return write_atomic(path, lambda p: p.write_text(text, encoding="utf-8"))


def write_netcdf(path: str | Path, dataset: Any) -> Path:
    """An xarray Dataset as NetCDF-4 (h5netcdf engine), written atomically. The disk must hold it
    before writing starts: HDF5 can crash the process when the disk fills during a write."""
    require_free(path, 1.02 * dataset.nbytes + 2e6)
    with atomic_path(path) as tmp, hdf5_errors(path):
        dataset.to_netcdf(tmp, engine="h5netcdf")
    return Path(path)


def require_free(path: str | Path, nbytes: float) -> None:
    """:class:`OutputError` when the filesystem that will hold ``path`` has less than ``nbytes`` free."""
    folder = Path(os.path.abspath(path)).parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    free = shutil.disk_usage(folder).free
    if nbytes > free:
        raise OutputError(f"needs about {nbytes / 1e6:,.0f} MB of disk, {free / 1e6:,.0f} MB are free", path=path)


@contextmanager
def hdf5_errors(path: str | Path):
    """Turn HDF5's write failures (h5py raises RuntimeError or OSError carrying a whole report) into a
    one-line :class:`OutputError`."""
    try:
        yield
    except (OSError, RuntimeError) as err:
        if isinstance(err, OSError) and err.errno:
            reason = os.strerror(err.errno)
        else:
            code = re.search(r"errno = (\d+)", str(err))
            reason = os.strerror(int(code.group(1))) if code else f"HDF5 {type(err).__name__}"
        raise OutputError(f"cannot write ({reason})", path=path) from None


def _jsonable(value: Any) -> Any:
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
