"""A scene's [sweep] section as a :class:`~s2cl.sensor.variants.SweepSpace`: each band's range from its keys,
checked against the sensor and the grid; with [sweep.add] (a band-addition sweep) the fixed base bands and
then the one added band, a band the sensor does not have (:func:`added_band`).

Engine functions: they take the [sweep] section, the sensor and the grid, and their errors name the key only
(the application layer adds the scene's file: :func:`s2cl.errors.errors_in`)."""

from __future__ import annotations

from dataclasses import replace

from s2cl.errors import InputError
from s2cl.grid import SpectralGrid
from s2cl.retrieve.design import same_band
from s2cl.scene.schema import AddSpec, RangeSpec, SweepSpec
from s2cl.sensor.names import check_band_name
from s2cl.sensor.sensor import Band, Sensor
from s2cl.sensor.variants import TABLE2, BandGrid, BandRange, SweepSpace

ADD_KEY = "sweep.add"


def sweep_space(spec: SweepSpec | None, sensor: Sensor, grid: SpectralGrid, support: float) -> SweepSpace:
    """The [sweep] section ``spec`` as a :class:`SweepSpace` (bands checked against ``sensor``, every variant's SRF,
    centre ± ``support`` × width, inside ``grid``); with [sweep.add], the fixed base bands then the added band
    (:mod:`s2cl.sweep.addition`)."""
    if spec is None:
        raise InputError("the scene has no [sweep] section", key="sweep")
    ranges: list[BandRange | BandGrid] = []
    if spec.add is not None:
        added_band(spec.add, sensor)  # its name and radiometry first: a name that is a sensor band is refused as such
    if spec.add is not None and spec.add.name.lower() in (b.lower() for b in spec.bands):
        raise InputError(f"{spec.add.name} is the added band ([sweep.add]); sweep.bands lists the fixed base bands "
                         "only", key="sweep.bands")
    for name in spec.bands:
        band = _sensor_band(sensor, name, "sweep.bands")
        r = spec.ranges.get(name) or spec.ranges.get(band.name)
        if r is None:
            if spec.add is not None:  # an addition sweep's base band without a range: the sensor's own
                ranges.append(BandRange.fixed(band.name, band.centre_nm, band.fwhm_nm))
                continue
            if spec.preset == "table2" and band.name in TABLE2:
                ranges.append(BandRange(band.name, *map(float, TABLE2[band.name]), step_nm=spec.step_nm))
                continue
            raise InputError(f"no range for band {name}: give [sweep.ranges.{name}] or preset = 'table2'",
                             key=f"sweep.ranges.{name}")
        ranges.append(band_range(band.name, r, f"sweep.ranges.{name}", spec.step_nm))
    unknown = set(spec.ranges) - set(spec.bands)
    if unknown:
        raise InputError(f"ranges for bands not swept: {', '.join(sorted(unknown))}"
                         + ("; the added band's range goes in [sweep.add]" if spec.add is not None else ""),
                         key="sweep.ranges")
    if spec.add is not None:
        ranges.append(_added_range(spec, sensor, ranges))
    space = SweepSpace(tuple(ranges)).validate()
    _check_on_grid(space, grid, support, spec.add)
    return space


def band_range(name: str, r: RangeSpec, key: str, step_nm: float = 5.0) -> BandRange | BandGrid:
    """One band's range from its scene keys (``r``: a window with widths, stepped by ``step_nm``, a centre × width
    grid or a fixed band); errors name ``key``."""
    window = [v is not None for v in (r.left, r.right, r.min_width, r.max_width)]
    if r.centres is not None or r.widths is not None:
        if r.centres is None or r.widths is None or any(window) or r.centre is not None or r.width is not None:
            raise InputError("a grid band gives centres and widths only", key=key)
        return BandGrid(name, tuple(r.centres), tuple(r.widths))
    if r.centre is not None or r.width is not None:
        if r.centre is None or r.width is None or any(window):
            raise InputError("a fixed band gives centre and width only", key=key)
        return BandRange.fixed(name, r.centre, r.width)
    missing = [k for k in ("left", "right", "min_width", "max_width") if getattr(r, k) is None]
    if missing:
        raise InputError(f"missing {', '.join(missing)} (or give centres and widths for a grid, or centre and "
                         "width for a fixed band)", key=key)
    assert r.left is not None and r.right is not None and r.min_width is not None and r.max_width is not None
    return BandRange(name, r.left, r.right, r.min_width, r.max_width, step_nm=step_nm)


def _check_on_grid(space: SweepSpace, grid: SpectralGrid, support: float, add: AddSpec | None) -> None:
    """Every variant's model SRF (centre ± sensor.support × width) inside the scene's grid: the one check that
    ``sweep count``, ``simulate`` and ``optimise`` share (:func:`s2cl.app.checks.check_sweep`), before any
    table is built."""
    for r in space.ranges:
        lo, hi = r.support_extent(support)
        if not grid.covers(lo, hi):
            key = ADD_KEY if add is not None and r.band == add.name else f"sweep.ranges.{r.band}"
            raise InputError(f"the variants' SRFs (centre ± {support:g} × width, sensor.support) reach {lo:g}–{hi:g} "
                             f"nm, outside the spectral grid {grid.describe()}; move or narrow the band's range, or "
                             "widen the grid", key=key)


def _sensor_band(sensor: Sensor, name: str, key: str) -> Band:
    try:
        return sensor.band(name)
    except InputError:
        raise InputError(f"sensor has no band {name!r}; bands: {', '.join(sensor.band_names)}", key=key) from None


def added_band(add: AddSpec, sensor: Sensor) -> Band:
    """The band-addition sweep's added band (``[sweep.add]``, ``add``): a new band named ``name`` with the radiometry
    of sensor band ``like`` (Lmin, Lref, Lmax, its SNR points and the width they refer to, so that a variant of
    width w gets the SNR scaled by √(w / w_like), as every swept variant does: :meth:`Band.with_shape`) and the
    model SRF (eq. 1), like every swept variant. Its nominal shape is ``like``'s (every variant replaces it)."""
    check_band_name(add.name, key=f"{ADD_KEY}.name")
    if add.name.lower() in (n.lower() for n in sensor.band_names):
        raise InputError(f"{add.name} is a band of the sensor; the added band needs a new name (e.g. 'N2300')",
                         key=f"{ADD_KEY}.name")
    like = _sensor_band(sensor, add.like, f"{ADD_KEY}.like")
    return like.stand_in(add.name)


def _added_range(spec: SweepSpec, sensor: Sensor, base: list[BandRange | BandGrid]) -> BandRange | BandGrid:
    """The added band's range, after the rules of an addition sweep: every base band fixed, and no candidate
    that is a base band itself (same centre and width)."""
    assert spec.add is not None
    band = added_band(spec.add, sensor)
    if spec.preset != "none":
        raise InputError("a band-addition sweep holds its base bands fixed; preset = 'table2' would move them",
                         key="sweep.preset")
    for r in base:
        if not r.is_fixed:
            raise InputError(f"a band-addition sweep holds its base bands fixed, but {r.band} moves: give it centre "
                             "and width, or no range (the sensor's own band)", key=f"sweep.ranges.{r.band}")
    try:
        added = band_range(band.name, spec.add, ADD_KEY, spec.step_nm)
        added.validate()
    except InputError as err:  # the range's own checks name sweep.ranges.NAME: here the keys are [sweep.add]'s
        raise InputError(err.detail, key=ADD_KEY) from None
    shapes = added.variants()
    for r in base:
        c0, _, w0, _ = r.extent()
        same = same_band(shapes[:, 0], shapes[:, 1], c0, w0)
        if same.any():
            raise InputError(f"candidate {c0:g}/{w0:g} nm of {band.name} is base band {r.band} itself; leave it out "
                             "of the added band's centres and widths", key=ADD_KEY)
    return added


def with_added_band(sensor: Sensor, spec: SweepSpec | None) -> Sensor:
    """``sensor`` with the band-addition sweep's added band appended (:func:`added_band`), so that tables, noise and
    analysis treat it as any band: its noise stream is keyed by its index, after every sensor band, so the base
    bands draw the same deviates as in a sweep without it. ``sensor`` itself without [sweep.add]."""
    if spec is None or spec.add is None:
        return sensor
    return replace(sensor, bands=(*sensor.bands, added_band(spec.add, sensor)))
