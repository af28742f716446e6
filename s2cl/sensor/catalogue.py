"""The sensors a scorecard compares (``s2cl scorecard --sensor NAME``), each with where its numbers come from.

- ``sentinel2``: the paper's Table 1 (``s2cl/data/sentinel2_mrd_table1.csv``), model SRFs (eq. 1): the built-in
  sensor of every scene.
- ``S2A``, ``S2B``: Table 1's bands with ESA's measured SRFs of Sentinel-2A / 2B, as Py6S ships them; without Py6S
  the sensor is unavailable (n/a with the reason), not an error.
- ``OLI`` (Landsat 8): the published band edges (``s2cl/data/landsat_oli_bands.csv``, USGS) with NASA's measured
  SRFs as Py6S ships them; without Py6S, eq. 1 at the published centres and widths (said so).
- ``OLI-2`` (Landsat 9): the same published edges, eq. 1 (no package here ships OLI-2's measured SRFs).
- ``landsat-next``: the 21 VSWIR bands of NASA's Landsat Next band table (``s2cl/data/landsat_next_vswir.csv``),
  eq. 1 at its centres and widths, its GSDs.

**Radiometry stand-in.** s2cl has SNR tables for Sentinel-2 only. Every other sensor's band takes the radiometry of
the Table 1 band nearest its centre (Lmin, Lref, Lmax, SNR points), its SNR scaled by √(width / that band's width):
the rule of a band addition's ``like`` band (:meth:`s2cl.sensor.sensor.Band.stand_in`). It is a stand-in, not the
sensor's own noise, and every card says so.
"""

from __future__ import annotations

import importlib.resources
import math
from dataclasses import dataclass, field, replace

from s2cl.errors import DependencyError, InputError, token
from s2cl.io.inputs import parse_number
from s2cl.io.tables import read_csv_table
from s2cl.sensor.roles import nearest_band
from s2cl.sensor.sensor import Sensor
from s2cl.sensor.srf import OLI_PY6S_BANDS, measured_oli_srf, measured_sentinel2_srf

STAND_IN = ("stand-in: each band takes the radiometry (Lmin, Lref, Lmax, SNR) of the Sentinel-2 Table 1 band nearest "
            "its centre, SNR scaled by sqrt(width / that band's width) (the [sweep.add] 'like' rule)")
TABLE1 = "Sentinel-2 Table 1 (Segl et al. 2012; s2cl/data/sentinel2_mrd_table1.csv)"
MODEL_SRF = "model (eq. 1) at the table's centres and widths"
_LANDSAT_NEXT = ("NASA Landsat Science, Landsat Next bands (landsat.gsfc.nasa.gov/satellites/landsat-next/bands): "
                 "the 21 VSWIR bands; s2cl/data/landsat_next_vswir.csv")
_OLI = ("USGS, band designations of the Landsat satellites (Landsat 8-9 OLI/OLI-2 band edges); "
        "s2cl/data/landsat_oli_bands.csv")


@dataclass(frozen=True)
class CatalogueSensor:
    """A sensor to score: ``sensor`` (None when ``unavailable`` says why), its ``title``, where its bands come from
    (``source``), its SRFs (``srf``) and radiometry (``radiometry``) in words; ``labels``: band → its name on the
    mission's table (``Red Edge 1``); ``by_name``: its bands are named as the scene's (roles map by name first,
    :func:`s2cl.sensor.roles.map_roles`)."""

    name: str
    title: str
    source: str
    srf: str
    radiometry: str
    sensor: Sensor | None
    unavailable: str | None = None
    labels: dict[str, str] = field(default_factory=dict)
    by_name: bool = False

    def card(self) -> dict[str, object]:
        """What the scorecard writes about the sensor (``scorecard.json``'s ``sensors``)."""
        out: dict[str, object] = {"name": self.name, "title": self.title, "source": self.source, "srf": self.srf,
                                  "radiometry": self.radiometry, "unavailable": self.unavailable}
        if self.sensor is not None:
            out["bands"] = [{"band": b.name, "label": self.labels.get(b.name, ""), "centre_nm": b.centre_nm,
                             "width_nm": b.fwhm_nm, "gsd_m": b.gsd_m,
                             "srf": b.tabulated.origin if b.tabulated is not None else "model (eq. 1)"}
                            for b in self.sensor.bands]
        return out


#: the catalogue's names (the first of each line) and the other names it answers to (any case)
NAMES: dict[str, tuple[str, ...]] = {
    "sentinel2": ("s2", "table1"),
    "S2A": ("sentinel-2a",),
    "S2B": ("sentinel-2b",),
    "OLI": ("landsat8", "landsat-8", "L8"),
    "OLI-2": ("OLI2", "landsat9", "landsat-9", "L9"),
    "landsat-next": ("LN", "landsatnext"),
}


def known_sensors() -> list[str]:
    """The catalogue's sensor names, in order."""
    return list(NAMES)


def canonical_name(name: str) -> str | None:
    """The catalogue's name for ``name`` (any case, or one of its other names), or None."""
    for main, others in NAMES.items():
        if name.lower() in (n.lower() for n in (main, *others)):
            return main
    return None


def catalogue_sensor(name: str) -> CatalogueSensor:
    """The catalogue's sensor ``name`` (:data:`NAMES`).

    :raises InputError: (key ``--sensor``) an unknown name, listing the known ones.
    """
    main = canonical_name(name)
    if main is None:
        raise InputError(f"unknown sensor {token(name)}; known: {', '.join(known_sensors())}, a sensor table "
                         "(FILE.csv) or results:FOLDER (a finished sweep's best design)", key="--sensor")
    if main == "sentinel2":
        return CatalogueSensor(main, "Sentinel-2 MSI (Table 1, model SRFs)", TABLE1, MODEL_SRF, TABLE1,
                               Sensor.sentinel2(), by_name=True)
    if main in ("S2A", "S2B"):
        return _measured_sentinel2(main)
    if main == "OLI":
        return _oli()
    if main == "OLI-2":
        return _table_sensor(main, "Landsat 9 OLI-2", "landsat_oli_bands.csv", _OLI,
                             MODEL_SRF + " (no package here ships OLI-2's measured SRFs)")
    return _table_sensor(main, "Landsat Next (LandIS, VSWIR)", "landsat_next_vswir.csv", _LANDSAT_NEXT, MODEL_SRF)


def _measured_sentinel2(platform: str) -> CatalogueSensor:
    """Table 1's bands with the measured SRFs of ``platform`` (``S2A``, ``S2B``), each kept at its own shape."""
    table1 = Sensor.sentinel2()
    title = f"Sentinel-2{platform[-1]} MSI (measured SRFs)"
    srf = f"measured: ESA's {platform} MSI responses as Py6S ships them"
    try:
        bands = tuple(replace(b, tabulated=measured_sentinel2_srf(platform, b.name), own_response=True)
                      for b in table1.bands)
    except DependencyError as err:
        return CatalogueSensor(platform, title, TABLE1, srf, TABLE1, None, unavailable=str(err))
    return CatalogueSensor(platform, title, TABLE1, srf, TABLE1, replace(table1, name=title, bands=bands),
                           by_name=True)


def _oli() -> CatalogueSensor:
    """Landsat 8 OLI: the published table, NASA's measured SRFs from Py6S where it is installed, else eq. 1."""
    base = _table_sensor("OLI", "Landsat 8 OLI", "landsat_oli_bands.csv", _OLI, "")
    assert base.sensor is not None
    try:
        bands = tuple(replace(b, tabulated=measured_oli_srf(b.name), own_response=True)
                      if b.name in OLI_PY6S_BANDS else b for b in base.sensor.bands)
    except DependencyError:
        return replace(base, srf=MODEL_SRF + " (Py6S, which ships OLI's measured SRFs, is not installed)")
    return replace(base, sensor=replace(base.sensor, bands=bands),
                   srf="measured: NASA's OLI band-average responses as Py6S ships them (centres and widths: the "
                       "published table, for the role mapping)")


def _table_sensor(name: str, title: str, file: str, source: str, srf: str) -> CatalogueSensor:
    """A sensor from a catalogue table (band, label, gsd_m, centre_nm, width_nm) with the stand-in radiometry."""
    bands, labels = [], {}
    table1 = Sensor.sentinel2()
    for row in _read_table(file):
        like = table1.band(nearest_band(table1, row["centre_nm"], math.inf))  # the stand-in's source
        bands.append(like.stand_in(row["band"], row["centre_nm"], row["width_nm"], row["gsd_m"]))
        labels[row["band"]] = row["label"]
    sensor = Sensor(name=title, bands=tuple(bands), source=f"s2cl/data/{file}")
    return CatalogueSensor(name, title, source, srf, STAND_IN, sensor, labels=labels)


def _read_table(file: str) -> list[dict[str, str | float]]:
    """The rows of catalogue table ``s2cl/data/<file>``: band and label as text, the rest as numbers."""
    ref = importlib.resources.files("s2cl") / "data" / file
    with importlib.resources.as_file(ref) as path:
        header, rows = read_csv_table(path)
    out = []
    for _, row in rows:
        record: dict[str, str | float] = dict(zip(header, (c.strip() for c in row), strict=True))
        for key in ("gsd_m", "centre_nm", "width_nm"):
            record[key] = parse_number(str(record[key]))
        out.append(record)
    return out
