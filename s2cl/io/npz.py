"""What a ``.npz`` archive declares, read before any array is loaded: each member's shape and dtype from
its ``.npy`` header (a few hundred bytes), so that a file that declares more than its format allows, or
more memory than the run may use (a "zip bomb": a small file that decompresses to gigabytes), is refused
before :func:`numpy.load` allocates it."""

from __future__ import annotations

import math
import zipfile
from pathlib import Path

import numpy as np

from s2cl.errors import InputError

#: longest ``.npy`` header read (bytes; numpy's own default limit)
MAX_HEADER_BYTES = 10_000


def npz_members(path: str | Path, what: str = ".npz archive of arrays") -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """Member name (without ``.npy``) → (shape, dtype) as each member's header declares them.

    :raises InputError: not a zip archive, a member that is not a ``.npy`` array, or an array of Python
        objects (which :func:`numpy.load` would unpickle).
    """
    out: dict[str, tuple[tuple[int, ...], np.dtype]] = {}
    try:
        with zipfile.ZipFile(path) as zf:
            for info in zf.infolist():
                name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
                with zf.open(info) as f:
                    version = np.lib.format.read_magic(f)
                    if version == (1, 0):
                        shape, _, dtype = np.lib.format.read_array_header_1_0(f, max_header_size=MAX_HEADER_BYTES)
                    elif version == (2, 0):
                        shape, _, dtype = np.lib.format.read_array_header_2_0(f, max_header_size=MAX_HEADER_BYTES)
                    else:
                        raise ValueError(f"npy format version {version}")
                if dtype.hasobject:
                    raise InputError("holds an array of Python objects, which s2cl does not read", source=path,
                                     key=name)
                out[name] = (tuple(int(n) for n in shape), dtype)
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, SyntaxError) as err:
        if isinstance(err, InputError):
            raise
        raise InputError(f"not a readable {what} (corrupt or not .npz: {type(err).__name__})", source=path) from None
    return out


def declared_bytes(shape: tuple[int, ...], dtype: np.dtype) -> int:
    """Bytes an array of ``shape`` and ``dtype`` takes once loaded."""
    return math.prod(shape) * dtype.itemsize
