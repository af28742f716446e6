"""The spectral-library type (:class:`SpectralLibrary`: N spectra on a grid plus per-spectrum metadata), its
checks and resampling, and flat targets. Reading user files (CSV, ENVI): :mod:`s2cl.libraries.files`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from s2cl.errors import InputError
from s2cl.grid import SpectralGrid

Quantity = Literal["reflectance", "radiance"]
QUANTITY_UNITS = {"reflectance": "1", "radiance": "W m-2 sr-1 um-1"}


@dataclass
class SpectralLibrary:
    """Spectra on a grid, one row per spectrum.

    :param grid: the wavelength grid of the columns.
    :param spectra: float64 array ``(n_spectra, grid.size)``; reflectance (unitless) or TOA
        radiance in W m⁻² sr⁻¹ µm⁻¹ depending on ``quantity``.
    :param names: one name per spectrum.
    :param groups: one class/group label per spectrum (e.g. ``"Al-OH"``, ``"vegetation"``).
    :param params: generating parameters, each an array of length ``n_spectra``
        (e.g. ``{"cab": …, "lai": …}`` in µg/cm² and m²/m²).
    :param source: provenance (where the spectra come from, with citation).
    """

    grid: SpectralGrid
    spectra: np.ndarray
    names: list[str]
    quantity: Quantity = "reflectance"
    groups: list[str] = field(default_factory=list)
    params: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = ""

    def __post_init__(self) -> None:
        self.spectra = np.asarray(self.spectra, dtype=np.float64)
        if self.spectra.ndim != 2 or self.spectra.shape[1] != self.grid.size:
            raise InputError(
                f"spectra must have shape (n_spectra, {self.grid.size}) for grid {self.grid.describe()}, "
                f"got {self.spectra.shape}",
                source=self.source or None,
            )
        n = self.spectra.shape[0]
        if n == 0:
            raise InputError("library holds no spectra", source=self.source or None)
        if len(self.names) != n:
            raise InputError(f"{len(self.names)} names for {n} spectra", source=self.source or None)
        if not self.groups:
            self.groups = ["" for _ in range(n)]
        if len(self.groups) != n:
            raise InputError(f"{len(self.groups)} groups for {n} spectra", source=self.source or None)
        for key, values in self.params.items():
            arr = np.asarray(values)
            if arr.shape != (n,):
                raise InputError(f"parameter has shape {arr.shape}, expected ({n},)", source=self.source or None,
                                 key=key)
            self.params[key] = arr
        if self.quantity not in QUANTITY_UNITS:
            raise InputError(f"quantity must be one of {sorted(QUANTITY_UNITS)}, got {self.quantity!r}")
        check_finite(self.spectra, names=self.names, source=self.source or None)

    @property
    def size(self) -> int:
        """Number of spectra."""
        return int(self.spectra.shape[0])

    def subset(self, index: np.ndarray | list[int]) -> SpectralLibrary:
        """A new library with the spectra at ``index`` (metadata follows)."""
        idx = np.asarray(index, dtype=np.intp)
        return SpectralLibrary(
            grid=self.grid,
            spectra=self.spectra[idx],
            names=[self.names[i] for i in idx],
            quantity=self.quantity,
            groups=[self.groups[i] for i in idx],
            params={k: v[idx] for k, v in self.params.items()},
            source=self.source,
        )

    def on_grid(self, grid: SpectralGrid) -> SpectralLibrary:
        """This library linearly interpolated onto ``grid`` (which it must cover)."""
        if grid == self.grid:
            return self
        spectra = resample_to_grid(self.grid.wavelengths, self.spectra, grid, source=self.source or None)
        return SpectralLibrary(grid, spectra, list(self.names), self.quantity, list(self.groups), dict(self.params),
                               self.source)

    @staticmethod
    def concat(libraries: list[SpectralLibrary]) -> SpectralLibrary:
        """Stack libraries on the same grid and quantity; params missing in one become NaN."""
        first = libraries[0]
        for lib in libraries[1:]:
            if lib.grid != first.grid or lib.quantity != first.quantity:
                raise InputError("cannot stack libraries on different grids or of different quantities")
        keys = sorted({k for lib in libraries for k in lib.params})
        params = {
            k: np.concatenate([np.asarray(lib.params.get(k, np.full(lib.size, np.nan)), dtype=np.float64)
                               for lib in libraries])
            for k in keys
        }
        return SpectralLibrary(
            grid=first.grid,
            spectra=np.concatenate([lib.spectra for lib in libraries]),
            names=[n for lib in libraries for n in lib.names],
            quantity=first.quantity,
            groups=[g for lib in libraries for g in lib.groups],
            params=params,
            source="; ".join(dict.fromkeys(lib.source for lib in libraries if lib.source)),
        )


#: spectra :func:`check_finite` tests at a time (its bool temporaries: this many spectra's values)
FINITE_BLOCK = 4096


def check_finite(spectra: np.ndarray, *, names: list[str] | None = None, source: str | None = None) -> None:
    """Raise :class:`InputError` naming the first spectrum that holds NaN or inf (checked a block of rows at
    a time: no library-size temporaries)."""
    spectra = np.asarray(spectra)
    step = FINITE_BLOCK
    for a in range(0, max(spectra.shape[0], 1), step):
        finite = np.isfinite(spectra[a : a + step])
        if finite.all():
            continue
        row, col = (int(i) for i in np.argwhere(~finite)[0])
        row += a
        label = names[row] if names and row < len(names) else f"#{row}"
        raise InputError(
            f"spectrum {label} holds a non-finite value ({spectra[row, col]}) at column {col}; "
            "spectra must be finite (mask or drop such pixels first)",
            source=source,
        )


def check_coverage(wavelengths_nm: np.ndarray, grid: SpectralGrid, *, source: str | None = None) -> None:
    """Raise :class:`InputError` when increasing ``wavelengths_nm`` do not cover ``grid`` (1e-9 nm of slack at its
    ends): s2cl interpolates inside the data and never extrapolates."""
    w = np.asarray(wavelengths_nm, dtype=np.float64)
    lo, hi = grid.wavelengths[0], grid.wavelengths[-1]
    if w[0] > lo + 1e-9 or w[-1] < hi - 1e-9:
        raise InputError(
            f"spectra cover {w[0]:g}–{w[-1]:g} nm but the grid needs {lo:g}–{hi:g} nm; "
            "choose a grid inside the data (scene key grid.start_nm / grid.stop_nm) or supply wider spectra",
            source=source,
        )


def resample_to_grid(
    wavelengths_nm: np.ndarray, spectra: np.ndarray, grid: SpectralGrid, *, source: str | None = None
) -> np.ndarray:
    """Linear interpolation of ``spectra`` (n, len(wavelengths)) onto ``grid``; float64.

    Raises :class:`InputError` when the input does not cover the grid: s2cl never extrapolates.
    """
    w = np.asarray(wavelengths_nm, dtype=np.float64)
    check_coverage(w, grid, source=source)
    s = np.asarray(spectra, dtype=np.float64)
    out = np.empty((s.shape[0], grid.size))
    for i, row in enumerate(s):
        out[i] = np.interp(grid.wavelengths, w, row)
    return out


#: reflectances of the built-in flat targets
DEFAULT_FLAT_VALUES = (0.1, 0.2)


def flat_targets(grid: SpectralGrid, values: tuple[float, ...] | list[float] = DEFAULT_FLAT_VALUES) -> SpectralLibrary:
    """Spectrally flat (grey Lambertian) targets, one per value of ``values`` (reflectance in [0, 1]).

    :returns: library with names ``"flat 0.1"``…, group ``"flat"`` and parameter ``rho``.
    """
    vals = np.asarray(list(values), dtype=np.float64).reshape(-1)
    if vals.size == 0:
        raise InputError("needs at least one reflectance value", key="flat.values")
    bad = ~np.isfinite(vals) | (vals < 0.0) | (vals > 1.0)
    if bad.any():
        raise InputError(f"reflectance must lie in [0, 1], got {vals[bad][0]:g}", key="flat.values")
    return SpectralLibrary(
        grid=grid,
        spectra=np.repeat(vals[:, None], grid.size, axis=1),
        names=[f"flat {v:g}" for v in vals],
        groups=["flat" for _ in vals],
        params={"rho": vals},
        source="s2cl flat targets (spectrally constant reflectance)",
    )
