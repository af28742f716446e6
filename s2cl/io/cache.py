"""The user cache directory and atomic writes of ``.npz`` data files.

The cache lives in ``$S2CL_CACHE`` when that variable is set, else in the platform's user cache folder
(:func:`platformdirs.user_cache_dir`: ``$XDG_CACHE_HOME/s2cl`` or ``~/.cache/s2cl`` on Linux,
``~/Library/Caches/s2cl`` on macOS, ``%LOCALAPPDATA%\\s2cl\\Cache`` on Windows).
Files are written to a temporary name in the target directory and moved into place with
:func:`os.replace`, so a reader never sees a half-written file and a killed writer leaves
at most a stray ``*.tmp`` file behind.
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import platformdirs

from s2cl.errors import InputError
from s2cl.io.output import atomic_path

CACHE_ENV = "S2CL_CACHE"


def cache_dir(*parts: str) -> Path:
    """The cache directory (``$S2CL_CACHE`` or the platform's user cache folder) joined with ``parts``, created."""
    root = os.environ.get(CACHE_ENV)
    base = Path(root).expanduser() if root else Path(platformdirs.user_cache_dir("s2cl", appauthor=False))
    path = base.joinpath(*parts)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(
            f"cannot create the cache directory ({err.strerror}); set {CACHE_ENV} to a writable directory",
            source=path,
        ) from err
    return path


def digest(obj: Any) -> str:
    """SHA-256 hex digest of a JSON-serialisable object (keys sorted): a stable cache key."""
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"), default=_json_default)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return hashlib.sha256(np.ascontiguousarray(value).tobytes()).hexdigest()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot hash {type(value).__name__}")


def write_npz_atomic(path: str | Path, arrays: dict[str, np.ndarray], *, compress: bool = True) -> Path:
    """Write ``arrays`` to ``path`` (``.npz``, readable by :func:`numpy.load`) atomically.

    The zip members carry a fixed timestamp, so equal arrays give byte-identical files
    (regenerated data files do not show up as changed in version control).
    """
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with atomic_path(path) as tmp, open(tmp, "wb") as handle, zipfile.ZipFile(handle, "w", compression=method) as zf:
        for name, value in arrays.items():
            info = zipfile.ZipInfo(name + ".npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = method
            with zf.open(info, "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)
    return Path(path)
