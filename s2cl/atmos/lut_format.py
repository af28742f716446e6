"""The atmosphere LUT file: names, format version and atomic writing (shared by builder and loader).

A LUT is a NumPy ``.npz`` archive of float32 arrays plus a JSON provenance string. It stores the
factors of 6S's own formula rather than every product (see :mod:`s2cl.atmos.atmosphere`), so one file
covers all states:

================================  ============================  =========================================
key                               shape                         meaning
================================  ============================  =========================================
``wavelength_nm``                 (n_wl,)                       1 nm grid, nm
``profiles``                      (n_p,) str                    atmospheric profile names
``aot550``                        (n_aot,)                      aerosol optical thickness nodes (first 0)
``solar_zenith``                  (n_sza,)                      solar zenith nodes, deg
``water_vapour``                  (n_wv,)                       water-vapour column nodes at the reference
                                                                zenith, g/cm2
``reference``                     (3,)                          reference zenith (deg), reference ozone
                                                                (DU), view zenith (deg)
``ozone_range``                   (2,)                          allowed ozone columns, DU
``e0``                            (n_wl,)                       exo-atmospheric irradiance at 1 AU,
                                                                W m-2 um-1
``path_reflectance_scattering``   (n_p, n_sza, n_aot, n_wl)     gas-free path reflectance R (aot 0: R_R)
``t_down``                        (n_p, n_sza, n_aot, n_wl)     downward scattering transmittance
``t_up``                          (n_p, n_aot, n_wl)            upward scattering transmittance (nadir)
``spherical_albedo``              (n_p, n_aot, n_wl)            spherical albedo S
``t_water``                       (n_p, n_wv, n_wl)             two-way H2O transmittance, reference zenith
``t_ozone``                       (n_p, n_wl)                   two-way O3 transmittance, reference zenith
                                                                and reference ozone
``t_<gas>``                       (n_p, n_sza, n_wl)            two-way transmittance of oxygen,
                                                                carbon_dioxide, methane, nitrous_oxide,
                                                                carbon_monoxide
``provenance``                    () str                        JSON: 6S version, settings, date, command
================================  ============================  =========================================
"""

from __future__ import annotations

import numpy as np

from s2cl.errors import InputError
from s2cl.io.npz import declared_bytes

FORMAT_NAME = "s2cl-atmosphere-lut"
FORMAT_VERSION = 1

FIXED_GASES: tuple[str, ...] = ("oxygen", "carbon_dioxide", "methane", "nitrous_oxide", "carbon_monoxide")
"""Gases whose amount the profile fixes; stored per solar zenith node."""

SCATTERING_KEYS = ("path_reflectance_scattering", "t_down")
ALBEDO_KEYS = ("t_up", "spherical_albedo")
AXIS_KEYS = ("wavelength_nm", "profiles", "aot550", "solar_zenith", "water_vapour", "reference", "ozone_range")


def fixed_gas_key(gas: str) -> str:
    return "t_" + gas


#: most values an axis of a LUT file may hold (checked from the file's headers before it is loaded):
#: the 1 nm wavelength grid within 6S's 250-4000 nm, the profiles s2cl knows, and at most 1,000 nodes a side
AXIS_LIMITS = {"profiles": 16, "aot550": 1000, "solar_zenith": 1000, "water_vapour": 1000, "wavelength_nm": 3751,
               "reference": 3, "ozone_range": 2}
#: largest text array (profile names, provenance JSON; bytes as numpy stores them, 4 per character)
MAX_TEXT_BYTES = 4 * 2**20
#: most bytes the arrays of one LUT file may declare (the shipped LUT: 4.2 MB)
MAX_LUT_BYTES = 256 * 2**20


#: dimensions of each LUT array, by axis name
ARRAY_DIMS = {
    "path_reflectance_scattering": ("p", "sza", "aot", "wl"),
    "t_down": ("p", "sza", "aot", "wl"),
    "t_up": ("p", "aot", "wl"),
    "spherical_albedo": ("p", "aot", "wl"),
    "t_water": ("p", "wv", "wl"),
    "t_ozone": ("p", "wl"),
    "e0": ("wl",),
    **{fixed_gas_key(g): ("p", "sza", "wl") for g in FIXED_GASES},
}

#: every array a LUT file holds (other members are never loaded)
LUT_KEYS = tuple(dict.fromkeys((*AXIS_KEYS, *SCATTERING_KEYS, *ALBEDO_KEYS, *ARRAY_DIMS, "provenance")))


def check_declared(members: dict[str, tuple[tuple[int, ...], np.dtype]], source: str) -> None:
    """Refuse, before anything is loaded, a LUT whose arrays (as their headers declare them) are missing,
    not of the format's kinds, axes longer than :data:`~s2cl.atmos.lut_format.AXIS_LIMITS`, arrays of
    another shape than their axes give, or more than :data:`~s2cl.atmos.lut_format.MAX_LUT_BYTES` in all."""
    missing = [k for k in LUT_KEYS if k not in members]
    if missing:
        raise InputError(f"missing arrays: {', '.join(missing)}", source=source)
    for key, limit in AXIS_LIMITS.items():
        shape, dtype = members[key]
        if len(shape) != 1 or not 1 <= shape[0] <= limit:
            raise InputError(f"must be a list of 1 to {limit:,} values, declares shape {shape}", source=source,
                             key=key)
    for key in ("provenance", "profiles"):
        shape, dtype = members[key]
        if dtype.kind != "U" or dtype.itemsize > MAX_TEXT_BYTES:
            raise InputError(f"must be text of at most {MAX_TEXT_BYTES:,} bytes, declares {dtype}", source=source,
                             key=key)
    sizes = {d: members[k][0][0] for d, k in (("p", "profiles"), ("sza", "solar_zenith"), ("aot", "aot550"),
                                              ("wv", "water_vapour"), ("wl", "wavelength_nm"))}
    for key, dims in ARRAY_DIMS.items():
        shape, dtype = members[key]
        expected = tuple(sizes[d] for d in dims)
        if shape != expected or dtype.kind != "f" or dtype.itemsize > 8:
            raise InputError(f"expected float array of shape {expected}, got {dtype} {shape}", source=source,
                             key=key)
    total = sum(declared_bytes(*members[k]) for k in LUT_KEYS)
    if total > MAX_LUT_BYTES:
        raise InputError(f"its arrays declare {total:,} bytes (at most {MAX_LUT_BYTES:,})", source=source)
