"""Opening an HDF5 product file (EMIT's NetCDF-4, PRISMA's HDF-EOS5): one line naming the file where it is not."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from s2cl.errors import InputError


def open_hdf5(p: Path) -> Any:
    """``p`` opened read-only with h5py (imported here: an optional dependency of these readers only)."""
    import h5py

    try:
        return h5py.File(p, "r")
    except OSError as err:
        raise InputError(f"cannot read as HDF5 ({type(err).__name__})", source=p) from None
