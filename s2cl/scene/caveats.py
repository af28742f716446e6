"""Scene settings that would run but give numbers not to be trusted: refused, or warned about.

Each check looks only at the resolved scene (no data), so every command runs it before any work.
A warning is a :class:`Caveat` (scene key + sentence); commands log it through the ``s2cl`` logger
(printed on stderr) and record it under ``"warnings"`` in the JSON they write.

- **Spectral grid against band width** (``grid.step_nm``): a band is integrated over the grid's
  samples; a step above half its FWHM leaves one or two samples inside the band and its radiance
  is wrong by tens of percent (an error); fewer than :data:`SAMPLES_PER_FWHM` samples per FWHM
  moves band radiance by about a noise level (a warning; the 1 nm default resolves every band).
- **Tabulated SRFs in a sweep** (``sensor.srf``): a measured or tabulated SRF describes the band at
  its own centre and width only; every swept variant, and the reference row with it (so that the
  ranking compares like with like), uses the model SRF (Segl et al. 2012 eq. 1).
- **A stage's own caveats**: each stage of the chain may declare its own (:mod:`s2cl.forward.stages`), such as
  quantisation noise above the sensor noise.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

from s2cl.errors import InputError

#: grid samples per band FWHM below which a warning is given (bench: 5 nm grid, 15 nm band = 1.4 NER)
SAMPLES_PER_FWHM = 5
_log = logging.getLogger("s2cl")


@dataclass(frozen=True)
class Caveat:
    """A warning about a scene setting: the key to change and what it does to the results."""

    key: str
    message: str

    def __str__(self) -> str:
        return f"{self.key}: {self.message}"


def srf_caveats(scene: Any, swept: list[str]) -> list[Caveat]:
    """Warn when swept bands have a tabulated SRF, which a sweep replaces by the model SRF."""
    tabulated = [b for b in swept if scene.sensor.band(b).tabulated is not None
                 and not scene.sensor.band(b).own_response]
    if not tabulated:
        return []
    return [Caveat("sensor.srf", f"the sweep uses the model SRF (Segl et al. 2012 eq. 1) for every variant of "
                                 f"{', '.join(tabulated)}, and for the reference row: the tabulated SRF describes "
                                 "only the band's own centre and width")]


def grid_caveats(scene: Any, widths: dict[str, float]) -> list[Caveat]:
    """Check the grid step against the narrowest width (nm) of each band in ``widths``.

    :raises InputError: a band is narrower than two grid steps (it cannot be resolved).
    """
    if not scene.effects.resample or not widths:
        return []
    step = scene.grid.step_nm
    band, narrowest = min(widths.items(), key=lambda kv: kv[1])
    if step > narrowest / 2:
        raise InputError(f"{step:g} nm cannot resolve band {band} ({narrowest:g} nm wide): the step must be at most "
                         f"half the narrowest band width, here {narrowest / 2:g} nm (1 nm resolves every band)",
                         source=scene.source, key="grid.step_nm")
    coarse = [b for b, w in widths.items() if step > w / SAMPLES_PER_FWHM]
    if not coarse:
        return []
    return [Caveat("grid.step_nm", f"{step:g} nm samples band(s) {', '.join(coarse)} with fewer than "
                                   f"{SAMPLES_PER_FWHM} points per FWHM: band radiances may be off by about the "
                                   "noise or more (1 nm resolves every band)")]


def report(caveats: list[Caveat]) -> list[str]:
    """Log each caveat as a WARNING (the CLI prints it) and return them as strings for the JSON record."""
    for c in caveats:
        _log.warning("%s", c)
    return [str(c) for c in caveats]
