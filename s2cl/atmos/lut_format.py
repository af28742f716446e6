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

FORMAT_NAME = "s2cl-atmosphere-lut"
FORMAT_VERSION = 1

FIXED_GASES: tuple[str, ...] = ("oxygen", "carbon_dioxide", "methane", "nitrous_oxide", "carbon_monoxide")
"""Gases whose amount the profile fixes; stored per solar zenith node."""

SCATTERING_KEYS = ("path_reflectance_scattering", "t_down")
ALBEDO_KEYS = ("t_up", "spherical_albedo")
AXIS_KEYS = ("wavelength_nm", "profiles", "aot550", "solar_zenith", "water_vapour", "reference", "ozone_range")


def fixed_gas_key(gas: str) -> str:
    return "t_" + gas


