"""Check a LUT against direct 6S runs: relative error of L = Lp + G rho / (1 - S rho).

For each wavelength and reflectance, 6S is run for the state itself (its profile with H2O and O3
scaled, continental aerosol at the AOT, the solar zenith) and its apparent reflectance, converted
to radiance at 1 AU, is compared with the LUT formula. At LUT nodes this measures the formula and
the separable build; between nodes it adds the interpolation error.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import click
import numpy as np

from s2cl.atmos.atmosphere import AtmosphereLUT
from s2cl.atmos.sixs import SixSInput, on_sixs_grid, run_many
from s2cl.atmos.sixs_profiles import get_profile
from s2cl.atmos.state import AtmosphereState
from s2cl.grid import SpectralGrid

PAPER_WAVELENGTHS_NM: tuple[float, ...] = (550.0, 665.0, 865.0, 945.0, 1375.0, 1610.0, 2190.0)
PAPER_REFLECTANCES: tuple[float, ...] = (0.05, 0.3, 0.6)


@dataclass(frozen=True)
class ValidationRow:
    """One comparison: radiances in W m-2 sr-1 um-1 at 1 AU."""

    wavelength_nm: float
    reflectance: float
    radiance_sixs: float
    radiance_lut: float

    @property
    def relative_error(self) -> float:
        return self.radiance_lut / self.radiance_sixs - 1.0


def sixs_input_for(state: AtmosphereState, wavelength_nm: float, reflectance: float, lut: AtmosphereLUT) -> SixSInput:
    """The direct 6S run that corresponds to ``state`` (same date convention as ``lut``)."""
    profile = get_profile(state.profile)
    settings = lut.provenance.get("settings", {})
    return SixSInput(
        wavelength_um=wavelength_nm / 1000.0,
        reflectance=reflectance,
        profile=state.profile,
        water_scale=state.water_vapour / profile.water_column,
        ozone_scale=state.ozone / profile.ozone_column,
        aerosol="continental" if state.aot550 > 0 else "none",
        aot550=state.aot550,
        solar_zenith=state.solar_zenith,
        month=int(settings.get("month", 4)),
        day=int(settings.get("day", 5)),
    )


def validate(
    lut: AtmosphereLUT,
    state: AtmosphereState,
    wavelengths_nm: Sequence[float] = PAPER_WAVELENGTHS_NM,
    reflectances: Sequence[float] = PAPER_REFLECTANCES,
    *,
    method: str = "linear",
    workers: int = 1,
) -> list[ValidationRow]:
    """Compare the LUT formula with direct 6S runs for ``state``.

    :param wavelengths_nm: wavelengths on 6S's 2.5 nm grid, inside the LUT.
    :returns: one row per (wavelength, reflectance).
    """
    for wl in wavelengths_nm:
        if not (on_sixs_grid(wl / 1000.0) and float(wl).is_integer()):
            raise ValueError(f"{wl} nm is not on both 6S's 2.5 nm grid and the LUT's 1 nm grid")
    ax = lut.axes.wavelength_nm
    terms = lut.terms(state, SpectralGrid(ax[0], ax[-1], 1.0), method=method)  # type: ignore[arg-type]
    pairs = [(wl, rho) for wl in wavelengths_nm for rho in reflectances]
    outputs = run_many([sixs_input_for(state, wl, rho, lut) for wl, rho in pairs], workers=workers)
    rows = []
    mu_s = math.cos(math.radians(state.solar_zenith))
    for (wl, rho), out in zip(pairs, outputs, strict=True):
        i = int(np.argmin(np.abs(terms.wavelength_nm - wl)))
        e0 = out.solar_irradiance / out.earth_sun_factor
        l_sixs = out.apparent_reflectance * mu_s * e0 / math.pi
        l_lut = float(terms.toa_radiance(np.full(terms.wavelength_nm.size, rho))[i])
        rows.append(ValidationRow(wl, rho, l_sixs, l_lut))
    return rows


def format_table(rows: Sequence[ValidationRow]) -> str:
    """Markdown table: relative error (%) per wavelength (rows) and reflectance (columns)."""
    wls = sorted({r.wavelength_nm for r in rows})
    rhos = sorted({r.reflectance for r in rows})
    err = {(r.wavelength_nm, r.reflectance): r.relative_error for r in rows}
    lines = [
        "| wavelength (nm) | " + " | ".join(f"rho = {rho:g}" for rho in rhos) + " | max abs |",
        "|---|" + "---|" * (len(rhos) + 1),
    ]
    for wl in wls:
        values = [err[(wl, rho)] for rho in rhos]
        lines.append(
            f"| {wl:g} | "
            + " | ".join(f"{100 * v:+.4f} %" for v in values)
            + f" | {100 * max(map(abs, values)):.4f} % |"
        )
    return "\n".join(lines)


@click.command(name="validate-lut")
@click.option("--lut", "lut_path", type=click.Path(dir_okay=False), default=None, help="LUT file [default: shipped].")
@click.option("--profile", default="midlatitude_summer", show_default=True)
@click.option("--water-vapour", type=float, default=1.5, show_default=True, help="g/cm2")
@click.option("--aot", type=float, default=None, help="AOT550 [default: visibility 23 km].")
@click.option("--ozone", type=float, default=330.0, show_default=True, help="DU")
@click.option("--sza", type=float, default=40.0, show_default=True, help="Solar zenith, deg.")
@click.option("--method", type=click.Choice(["linear", "nearest"]), default="linear", show_default=True)
@click.option("-j", "--workers", type=click.IntRange(1, 64), default=2, show_default=True)
def main(
    lut_path: str | None,
    profile: str,
    water_vapour: float,
    aot: float | None,
    ozone: float,
    sza: float,
    method: str,
    workers: int,
) -> None:
    """Relative error of the LUT formula against direct 6S runs at the paper's wavelengths."""
    state = AtmosphereState(profile=profile, water_vapour=water_vapour, ozone=ozone, solar_zenith=sza)
    if aot is not None:
        state = state.replace(aot550=aot)
    lut = AtmosphereLUT.load(lut_path)
    rows = validate(lut, state, method=method, workers=workers)
    click.echo(f"{state}\n")
    click.echo(format_table(rows))


if __name__ == "__main__":
    main()
