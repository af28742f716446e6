"""How far the spatial filters of a band group reach on the input grid: the one rule that the NODATA footprint
(:mod:`s2cl.forward.nodata`), the halo a block of rows is read with (:func:`s2cl.forward.cube.simulate_cube`) and
the memory rule of ``s2cl simulate`` (:func:`s2cl.app.simulate_scene.cube_block_rows`) all take.

The filter before the box average is each band's one PSF and co-registration shift (``[effects]`` psf and
coregistration: a finite filter along each axis, :func:`s2cl.forward.instrument.fir_radius`). No input pixel beyond
its reach enters an output pixel, so a block read with the row reach gives the whole image's rows, and a valid pixel
outside a no-data pixel's reach is the pixel of the cube without the hole, bit for bit.
"""

from __future__ import annotations

from s2cl.errors import InputError
from s2cl.forward.instrument import FWHM_TO_SIGMA, Instrument
from s2cl.sensor.sensor import Sensor

__all__ = ["FWHM_TO_SIGMA", "BandGroups", "band_groups", "cube_halo", "gsd_factor"]

#: the bands by GSD, finest first: ``(factor, band indices)``, ``factor`` the cube's pixels per band pixel
BandGroups = list[tuple[int, list[int]]]


def gsd_factor(gsd: float, gsd_in: float, names: list[str]) -> int:
    """Input pixels per band pixel of the bands ``names`` of ``gsd`` m over a cube of ``gsd_in`` m: an
    :class:`InputError` naming ``surface.gsd_m`` when it is not a whole number."""
    ratio = gsd / gsd_in
    factor = round(ratio)
    if factor < 1 or abs(ratio - factor) > 1e-6:
        raise InputError(f"band GSD {gsd:g} m is not a whole multiple of the cube's GSD {gsd_in:g} m "
                         f"(bands {', '.join(names)})", key="surface.gsd_m")
    return factor


def band_groups(sensor: Sensor, gsd_in: float | None) -> BandGroups:
    """The sensor's bands by GSD over a cube of ``gsd_in`` m, finest first: ``(factor, band indices)``, ``factor``
    the cube's pixels per band pixel (an :class:`InputError` when a band's GSD is not a whole multiple of the
    cube's, or the cube has none)."""
    bands = sensor.bands
    if gsd_in is None:
        raise InputError("an image cube needs surface.gsd_m", key="surface.gsd_m")
    out = []
    for gsd in sorted({b.gsd_m for b in bands}):
        ids = [k for k, b in enumerate(bands) if b.gsd_m == gsd]
        out.append((gsd_factor(gsd, gsd_in, [bands[k].name for k in ids]), ids))
    return out


def cube_halo(instrument: Instrument, groups: BandGroups) -> int:
    """Input rows a block of rows is read with on each side (the longest row reach of the instrument's spatial
    filters, :meth:`~s2cl.forward.instrument.Instrument.reach`, over the band ``groups``), so that its output rows
    equal those of the whole image: the block reader of :func:`s2cl.forward.cube.simulate_cube` and the memory rule
    of ``s2cl simulate`` both take it from here."""
    return max(instrument.reach(ids, factor)[0] for factor, ids in groups)
