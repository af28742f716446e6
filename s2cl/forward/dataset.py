"""Simulation results as xarray Datasets: band metadata as attributes, CF-1.10 conventions (units,
``standard_name`` where the CF standard-name table has one, flag attributes)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from s2cl.errors import InputError
from s2cl.forward.stages import ALL_OUTPUTS, RADIANCE_UNITS
from s2cl.sensor.sensor import Band

if TYPE_CHECKING:
    import xarray as xr

#: global attribute of every NetCDF file s2cl writes
CONVENTIONS = {"Conventions": "CF-1.10"}
#: CF standard names (CF standard-name table, version 84) of the variables that have one
_RADIANCE = "toa_outgoing_radiance_per_unit_wavelength"
STANDARD_NAMES = {"band_radiance": _RADIANCE, "radiance": _RADIANCE, "noisy": _RADIANCE, "calibrated": _RADIANCE,
                  "reflectance": "surface_bidirectional_reflectance",
                  "centre_nm": "sensor_band_central_radiation_wavelength"}


def band_attrs(band: Band, bits: int) -> dict[str, Any]:
    """Attributes describing one band (for per-band variables)."""
    a, b = band.noise_coefficients()
    return {
        "band": band.name, "centre_nm": band.centre_nm, "fwhm_nm": band.fwhm_nm, "gsd_m": band.gsd_m,
        "lmin": band.lmin, "lref": band.lref, "lmax": band.lmax, "bits": bits,
        "noise_variance_a": a, "noise_variance_b": b,
        "srf": band.tabulated.origin if band.tabulated is not None else "model (Segl et al. 2012 eq. 1)",
    }


def band_table(bands: tuple[Band, ...] | list[Band]) -> dict[str, Any]:
    """Per-band coordinates along the ``band`` dimension."""
    return {
        "band": [b.name for b in bands],
        "centre_nm": ("band", np.array([b.centre_nm for b in bands])),
        "fwhm_nm": ("band", np.array([b.fwhm_nm for b in bands])),
        "gsd_m": ("band", np.array([b.gsd_m for b in bands])),
        "lmin": ("band", np.array([b.lmin for b in bands])),
        "lmax": ("band", np.array([b.lmax for b in bands])),
    }


def image_layout(n_spectra: int, copies: int, layout: str) -> np.ndarray:
    """Map of image pixels to library pixel index ``s · copies + c`` (−1 where no pixel).

    ``rows``: one image row per spectrum, ``copies`` columns. ``blocks``: each spectrum a square
    tile of side √copies (copies must be a square number), tiles in a near-square grid.
    """
    if layout == "rows":
        return np.arange(n_spectra * copies).reshape(n_spectra, copies)
    side = math.isqrt(copies)
    if side * side != copies:
        raise InputError(f"layout 'blocks' needs a square number of copies, got {copies}", key="surface.copies")
    ncols = math.ceil(math.sqrt(n_spectra))
    nrows = math.ceil(n_spectra / ncols)
    out = np.full((nrows * side, ncols * side), -1, dtype=np.int64)
    for s in range(n_spectra):
        r, c = divmod(s, ncols)
        out[r * side : (r + 1) * side, c * side : (c + 1) * side] = s * copies + np.arange(copies).reshape(side, side)
    return out


#: per-pixel image variables of a simulation, the outputs of the chain's stages (:mod:`s2cl.forward.stages`):
#: (name, units, long name)
PIXEL_VARIABLES = tuple(dict.fromkeys((o.name, o.units, o.long_name) for o in ALL_OUTPUTS))
PIXEL_SPECTRUM_ATTRS = {"long_name": "library spectrum of each pixel (-1: none)"}


def library_dataset(sim: Any, layout: str = "rows") -> xr.Dataset:
    """Dataset with ``band_radiance (band, spectrum)`` and per-pixel images ``(band, y, x)``."""

    lib = sim.library
    index = image_layout(lib.size, sim.copies, layout)
    valid = index >= 0
    flat = np.where(valid, index, 0)
    ds = header_dataset(sim.sensor, lib, sim.band_radiance, sim.copies, layout, sim.attrs, sim.clipped,
                        sim.stage_values)
    ds["pixel_spectrum"] = (("y", "x"), np.where(valid, index // sim.copies, -1), PIXEL_SPECTRUM_ATTRS)
    for name, units, long_name in PIXEL_VARIABLES:
        arr = getattr(sim, name)
        if arr is None:
            continue
        pixels = arr.reshape(arr.shape[0], -1)[:, flat]
        fill = 0 if arr.dtype.kind in "ui" else np.nan
        pixels = np.where(valid[None], pixels, np.asarray(fill, dtype=pixels.dtype))
        ds[name] = (("band", "y", "x"), pixels, pixel_attrs(name, units, long_name))
    return ds


def pixel_attrs(name: str, units: str, long_name: str) -> dict[str, Any]:
    """CF attributes of a per-pixel variable: units, long name, standard name where CF has one;
    ``flags`` gets CF flag attributes (:class:`s2cl.status.PixelFlag`)."""
    if name == "flags":
        return {"long_name": long_name, "flag_masks": np.array([1, 2, 4], np.uint8),
                "flag_meanings": "below_lmin above_lmax_saturated no_data_nan_radiance"}
    attrs = {"units": units, "long_name": long_name}
    if name in STANDARD_NAMES:
        attrs["standard_name"] = STANDARD_NAMES[name]
    return attrs


def header_dataset(sensor: Any, lib: Any, band_radiance: np.ndarray, copies: int, layout: str,
                   attrs: dict[str, Any], clipped: np.ndarray | None,
                   stage_values: dict[str, list[Any]] | None = None) -> xr.Dataset:
    """Everything of a library simulation's dataset but the per-pixel images: band and spectrum
    tables, noise-free band radiance, clipping counts, attributes; ``stage_values``: what the chain's stages did
    to each band (their attributes, :func:`s2cl.forward.stages.band_attrs`), as coordinates along ``band``."""
    import xarray as xr  # ~0.35 s with pandas: only in-memory results need it, not s2cl simulate's streamed run

    coords = band_table(sensor.bands)
    for key, values in (stage_values or {}).items():
        coords[key] = ("band", np.asarray(values))
    coords["spectrum_name"] = ("spectrum", np.array(lib.names, dtype=object))
    coords["spectrum_group"] = ("spectrum", np.array(lib.groups, dtype=object))
    for key, values in lib.params.items():
        coords[f"param_{key}"] = ("spectrum", np.asarray(values))
    data: dict[str, Any] = {
        "band_radiance": (("band", "spectrum"), band_radiance,
                          pixel_attrs("band_radiance", RADIANCE_UNITS, "noise-free band radiance")),
    }
    if clipped is not None:
        data["clipped"] = (("limit", "band"), clipped, {"long_name": "pixels below Lmin / above Lmax"})
        coords["limit"] = ["below_lmin", "above_lmax"]
    ds = xr.Dataset(data, coords=coords)
    ds["centre_nm"].attrs.update(units="nm", standard_name=STANDARD_NAMES["centre_nm"])
    ds.attrs.update(CONVENTIONS)
    ds.attrs.update({k: str(v) for k, v in attrs.items()})
    ds.attrs.update(sensor=sensor.name, bits=sensor.bits, copies=copies, layout=layout,
                    library_source=lib.source, quantity=lib.quantity)
    return ds
