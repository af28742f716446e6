"""``simulation.nc``, the one writer of ``s2cl simulate``'s NetCDF file for a library scene and an image cube alike.

The file is written under a temporary name and renamed when complete (:func:`s2cl.io.output.atomic_path`), HDF5's
failures become one line (:func:`s2cl.io.output.hdf5_errors`), and everything goes through one open h5netcdf handle,
a :class:`s2cl.io.image_store.NetcdfStore`: a library scene's small tables first (``header``, an xarray Dataset: band
and spectrum tables, noise-free band radiance), then the images, block by block, into the open store; the global
attributes last, on close: the header's and what the caller puts in ``store.attrs`` (the run's,
:func:`s2cl.forward.run_attrs.run_attrs`, and an image's own)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from s2cl.io.image_store import NetcdfStore
from s2cl.io.output import atomic_path, hdf5_errors

SIMULATION_NC = "simulation.nc"


@contextmanager
def simulation_file(path: str | Path, header: Any | None = None) -> Iterator[NetcdfStore]:
    """Write ``path`` atomically: ``header`` (an xarray Dataset, its global attributes kept for the end) first, then
    whatever the caller writes into the yielded store; the store's attributes are written and the file closed and
    renamed onto ``path`` when the block ends (removed on an error)."""
    with atomic_path(path) as tmp, hdf5_errors(path):
        attrs: dict[str, Any] = {}
        if header is not None:
            attrs = dict(header.attrs)
            header = header.copy(deep=False)
            header.attrs = {}
            header.to_netcdf(tmp, engine="h5netcdf")
        store = NetcdfStore(tmp, mode="a" if header is not None else "w")
        store.attrs.update(attrs)
        try:
            yield store
        finally:
            store.close()
