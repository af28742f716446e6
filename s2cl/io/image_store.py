"""Where an image simulation's 2-D variables go, a block of rows at a time: in memory (an :class:`xarray.Dataset`
at the end) or straight into an open NetCDF-4 file (h5netcdf), so an image larger than memory is written row block
by row block. Both take the same calls; a variable is created whole-sized, then filled and read by rows."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


class MemoryStore:
    """Variables held as numpy arrays; :meth:`dataset` makes the :class:`xarray.Dataset`."""

    def __init__(self) -> None:
        self.attrs: dict[str, Any] = {}
        self.vars: dict[str, tuple[tuple[str, ...], np.ndarray, dict[str, Any]]] = {}
        self.coords: dict[str, tuple[np.ndarray, dict[str, Any]]] = {}
        self.scalars: dict[str, dict[str, Any]] = {}
        #: the CF grid-mapping variable of each row dimension (``y_10m`` → ``crs_10m``): the variables created on it
        #: name it in their ``grid_mapping`` attribute
        self.grid_mappings: dict[str, str] = {}

    def dimension(self, name: str, values: np.ndarray, attrs: dict[str, Any]) -> None:
        """A dimension with its coordinate values."""
        self.coords[name] = (np.asarray(values), dict(attrs))

    def scalar(self, name: str, attrs: dict[str, Any]) -> None:
        """A variable without data that holds attributes (a CF grid mapping)."""
        self.scalars[name] = dict(attrs)

    def create(self, name: str, dims: tuple[str, str], dtype: Any, attrs: dict[str, Any], fill: Any = 0) -> None:
        shape = tuple(self.coords[d][0].size for d in dims)
        self.vars[name] = (dims, np.full(shape, fill, dtype=dtype), _mapped(self, dims, attrs))

    def write(self, name: str, rows: slice, data: np.ndarray) -> None:
        self.vars[name][1][rows] = data

    def read(self, name: str, rows: slice) -> np.ndarray:
        return self.vars[name][1][rows]

    def update_attrs(self, name: str, attrs: dict[str, Any]) -> None:
        self.vars[name][2].update(attrs)

    def __contains__(self, name: str) -> bool:
        return name in self.vars

    def names(self) -> list[str]:
        return list(self.vars)

    def dims(self, name: str) -> tuple[str, ...]:
        return self.vars[name][0]

    def shape(self, name: str) -> tuple[int, ...]:
        return self.vars[name][1].shape

    def attrs_of(self, name: str) -> dict[str, Any]:
        return self.vars[name][2]

    def dataset(self) -> Any:
        import xarray as xr

        ds = xr.Dataset(attrs=dict(self.attrs))
        for dim, (values, attrs) in self.coords.items():
            ds.coords[dim] = (dim, values, attrs)
        for name, attrs in self.scalars.items():
            ds.coords[name] = ((), np.int32(0), attrs)
        for name, (dims, data, attrs) in self.vars.items():
            ds[name] = (dims, data, attrs)
        return ds


class NetcdfStore:
    """The same calls on an h5netcdf file open for writing at ``path`` (``mode`` "w": created; "a": one already
    begun, added to); global attributes are written on close."""

    def __init__(self, path: str | Path, mode: str = "w") -> None:
        import h5netcdf

        self.file = h5netcdf.File(path, mode)
        self.attrs: dict[str, Any] = {}
        self.grid_mappings: dict[str, str] = {}

    def dimension(self, name: str, values: np.ndarray, attrs: dict[str, Any]) -> None:
        values = np.asarray(values)
        self.file.dimensions[name] = values.size
        v = self.file.create_variable(name, (name,), values.dtype)
        v[...] = values
        v.attrs.update(attrs)

    def scalar(self, name: str, attrs: dict[str, Any]) -> None:
        """A variable without data that holds attributes (a CF grid mapping)."""
        v = self.file.create_variable(name, (), np.int32)
        v[...] = 0
        v.attrs.update(attrs)

    def create(self, name: str, dims: tuple[str, str], dtype: Any, attrs: dict[str, Any], fill: Any = 0) -> None:
        dtype = np.dtype(dtype)
        fillvalue = np.nan if dtype.kind == "f" else None
        v = self.file.create_variable(name, dims, dtype, fillvalue=fillvalue)
        v.attrs.update(_mapped(self, dims, attrs))

    def write(self, name: str, rows: slice, data: np.ndarray) -> None:
        self.file.variables[name][rows, :] = data

    def read(self, name: str, rows: slice) -> np.ndarray:
        return np.asarray(self.file.variables[name][rows, :])

    def update_attrs(self, name: str, attrs: dict[str, Any]) -> None:
        self.file.variables[name].attrs.update(attrs)

    def __contains__(self, name: str) -> bool:
        return name in self.file.variables

    def names(self) -> list[str]:
        return [n for n, v in self.file.variables.items() if len(v.dimensions) == 2]

    def dims(self, name: str) -> tuple[str, ...]:
        return tuple(self.file.variables[name].dimensions)

    def shape(self, name: str) -> tuple[int, ...]:
        return tuple(self.file.variables[name].shape)

    def attrs_of(self, name: str) -> dict[str, Any]:
        return dict(self.file.variables[name].attrs)

    def close(self) -> None:
        self.file.attrs.update({k: v for k, v in self.attrs.items() if v is not None})
        self.file.close()


ImageStore = MemoryStore | NetcdfStore


def _mapped(store: MemoryStore | NetcdfStore, dims: tuple[str, ...], attrs: dict[str, Any]) -> dict[str, Any]:
    """``attrs`` with the CF ``grid_mapping`` of the grid ``dims`` lies on, where it has one."""
    mapping = store.grid_mappings.get(dims[0]) if dims else None
    return {**attrs, "grid_mapping": mapping} if mapping else dict(attrs)
