"""The scene file's [grid] section (and an application's own ``grid``): the spectral grid everything is simulated
on; re-exported by :mod:`s2cl.scene.schema`."""

from __future__ import annotations

from pydantic import Field

from s2cl.scene.section import Section


class GridSpec(Section):
    start_nm: float = Field(400.0, ge=200, le=3000, description="first wavelength of the simulation grid, nm")
    stop_nm: float = Field(2500.0, ge=200, le=3000, description="last wavelength of the simulation grid, nm")
    step_nm: float = Field(1.0, gt=0, le=50, description="grid spacing, nm (at most half the narrowest band's FWHM; "
                           "warned above a fifth)")
