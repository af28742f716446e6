"""Sensor and Band: spectral response, radiometry (Lmin, Lref, Lmax, SNR), GSD and bits.

The built-in sensor is the paper's Table 1 (Sentinel-2 MSI, MRD/SRD preliminary band set), read
from the data file ``s2cl/data/sentinel2_mrd_table1.csv``; radiances in W m⁻² sr⁻¹ µm⁻¹.
"""

from __future__ import annotations

import importlib.resources
import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from s2cl.errors import InputError, token
from s2cl.grid import SpectralGrid
from s2cl.io.inputs import parse_number
from s2cl.io.tables import read_csv_table
from s2cl.sensor.names import check_band_name
from s2cl.sensor.noise_model import NoiseModel, fit_noise_model
from s2cl.sensor.srf import DEFAULT_SUPPORT, BandWeights, TabulatedResponse, band_weights

SENSOR_COLUMNS = ("band", "centre_nm", "fwhm_nm", "lmin", "lref", "lmax", "snr_lmin", "snr_lref", "snr_lmax", "gsd_m")
MAX_BITS = 16


@dataclass(frozen=True, eq=False)
class Band:
    """One spectral band.

    :param centre_nm, fwhm_nm: SRF centre and full width at half maximum (nm).
    :param lmin, lref, lmax: radiance levels, W m⁻² sr⁻¹ µm⁻¹ (quantisation spans [lmin, lmax]).
    :param snr_points: the given (radiance, SNR) pairs.
    :param gsd_m: ground sampling distance (m).
    :param fwhm_ref_nm: the width the SNR values refer to (noise scales with √(w_ref/w)).
    :param tabulated: a measured/tabulated SRF, or None for the paper's model (eq. 1).
    :param extra: the band's values in a sensor table's optional numeric columns (name, value), such as a per-band
        coefficient a stage of the forward chain reads (:mod:`s2cl.forward.stages`).
    :param own_response: at its own centre and width the band keeps its tabulated SRF in a sweep's tables
        (:meth:`with_shape`): the scorecard's sensors with measured SRFs (:mod:`s2cl.sensor.catalogue`). Off, as
        for every band a scene's sensor reads, a sweep uses the model SRF for every variant and the reference row.
    """

    name: str
    centre_nm: float
    fwhm_nm: float
    lmin: float
    lref: float
    lmax: float
    snr_points: tuple[tuple[float, float], ...]
    gsd_m: float
    fwhm_ref_nm: float = 0.0
    tabulated: TabulatedResponse | None = field(default=None, repr=False)
    extra: tuple[tuple[str, float], ...] = ()
    own_response: bool = False

    def __post_init__(self) -> None:
        if self.fwhm_ref_nm == 0.0:
            object.__setattr__(self, "fwhm_ref_nm", self.fwhm_nm)

    def validate(self, source: str | None = None) -> None:
        """:raises InputError: naming the band, key and allowed range."""
        check_band_name(self.name, source=source, key="band")

        def bad(key: str, msg: str) -> InputError:
            return InputError(msg, source=source, key=f"{self.name}.{key}")

        for key in ("centre_nm", "fwhm_nm", "lmin", "lref", "lmax", "gsd_m"):
            if not math.isfinite(getattr(self, key)):
                raise bad(key, f"must be finite, got {getattr(self, key)}")
        if self.fwhm_nm <= 0:
            raise bad("fwhm_nm", f"must be > 0 nm, got {self.fwhm_nm}")
        if self.lmin < 0:
            raise bad("lmin", f"must be >= 0, got {self.lmin}")
        if self.lmin >= self.lmax:
            raise bad("lmin", f"Lmin ({self.lmin}) must be < Lmax ({self.lmax})")
        if self.gsd_m <= 0:
            raise bad("gsd_m", f"must be > 0 m, got {self.gsd_m}")
        if not self.snr_points:
            raise bad("snr", "needs at least one SNR value")
        for level, snr in self.snr_points:
            if not (math.isfinite(level) and level > 0 and math.isfinite(snr) and snr > 0):
                raise bad("snr", f"SNR point (L={level}, SNR={snr}) needs finite L > 0 and SNR > 0")

    @cached_property
    def noise(self) -> NoiseModel:
        """Shot-noise model fitted to this band's SNR points (see :mod:`s2cl.sensor.noise_model`); measured in-flight
        coefficients where the sensor table gives them (optional columns ``noise_alpha``, ``noise_beta``, as
        Sentinel-2 L1C products carry them: σ² = α² + β·L at the band's own width, W m⁻² sr⁻¹ µm⁻¹)."""
        extra = dict(self.extra)
        alpha, beta = extra.get("noise_alpha"), extra.get("noise_beta")
        if alpha is not None and beta is not None and math.isfinite(alpha) and math.isfinite(beta) and beta >= 0:
            return NoiseModel(alpha * alpha, beta, self.fwhm_ref_nm or self.fwhm_nm)
        return fit_noise_model(list(self.snr_points), self.fwhm_ref_nm, band=self.name)

    def noise_coefficients(self) -> tuple[float, float]:
        """(a, b) of σ² = a + b·L at this band's width."""
        return self.noise.coefficients(self.fwhm_nm)

    def weights(self, grid: SpectralGrid, support: float = DEFAULT_SUPPORT, source: str | None = None) -> BandWeights:
        """Normalised resampling weights on ``grid``."""
        return band_weights(
            grid,
            name=self.name,
            centre_nm=self.centre_nm,
            fwhm_nm=self.fwhm_nm,
            tabulated=self.tabulated,
            support=support,
            source=source,
        )

    def with_shape(self, centre_nm: float, fwhm_nm: float) -> Band:
        """This band moved to ``centre_nm`` with width ``fwhm_nm`` (model SRF; noise rescaled); a band with
        ``own_response`` left at its own centre and width keeps its tabulated SRF."""
        if self.own_response and float(centre_nm) == self.centre_nm and float(fwhm_nm) == self.fwhm_nm:
            return self
        return replace(self, centre_nm=float(centre_nm), fwhm_nm=float(fwhm_nm), tabulated=None, own_response=False)

    def stand_in(self, name: str, centre_nm: float | None = None, fwhm_nm: float | None = None,
                 gsd_m: float | None = None) -> Band:
        """A new band ``name`` with this band's radiometry (Lmin, Lref, Lmax, its SNR points and the width they refer
        to, so that a width w gets the SNR scaled by √(w / this band's width), as every swept variant does) and the
        model SRF (eq. 1) at ``centre_nm`` and ``fwhm_nm`` (default: this band's), GSD ``gsd_m`` (default: this
        band's). The one rule for a band whose own radiometry s2cl does not have: a band addition's added band
        (``[sweep.add] like``) and the scorecard's sensors without an SNR table (:mod:`s2cl.sensor.catalogue`)."""
        band = replace(self, name=name, tabulated=None, own_response=False,
                       gsd_m=self.gsd_m if gsd_m is None else float(gsd_m))
        return band.with_shape(self.centre_nm if centre_nm is None else centre_nm,
                               self.fwhm_nm if fwhm_nm is None else fwhm_nm)


@dataclass(frozen=True, eq=False)
class Sensor:
    """A band set with a radiometric resolution of ``bits`` bits."""

    name: str
    bands: tuple[Band, ...]
    bits: int = 12
    source: str = ""

    def __post_init__(self) -> None:
        if not self.bands:
            raise InputError("sensor has no bands", source=self.source or None)
        names = [b.name for b in self.bands]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise InputError(f"duplicate band names: {', '.join(dupes)}", source=self.source or None, key="band")
        if not (isinstance(self.bits, int) and 1 <= self.bits <= MAX_BITS):
            raise InputError(f"bits must be an integer in 1–{MAX_BITS}, got {self.bits!r}",
                             source=self.source or None, key="bits")
        for b in self.bands:
            b.validate(self.source or None)

    @property
    def band_names(self) -> list[str]:
        return [b.name for b in self.bands]

    @property
    def size(self) -> int:
        return len(self.bands)

    def band(self, name: str) -> Band:
        for b in self.bands:
            if b.name.lower() == name.lower():
                return b
        raise InputError(f"sensor {self.name} has no band {name!r}; bands: {', '.join(self.band_names)}", key=name)

    def select(self, names: list[str]) -> Sensor:
        """The sensor restricted to ``names`` (in that order)."""
        return replace(self, bands=tuple(self.band(n) for n in names))

    def with_bits(self, bits: int) -> Sensor:
        return replace(self, bits=bits)

    def replace_band(self, band: Band) -> Sensor:
        return replace(self, bands=tuple(band if b.name == band.name else b for b in self.bands))

    def array(self, attr: str) -> np.ndarray:
        """One attribute of every band as a float64 array (e.g. ``"lmin"``)."""
        return np.array([float(getattr(b, attr)) for b in self.bands])

    @classmethod
    def sentinel2(cls) -> Sensor:
        """The paper's Table 1: Sentinel-2 MSI preliminary band set, 12 bits."""
        ref = importlib.resources.files("s2cl") / "data" / "sentinel2_mrd_table1.csv"
        with importlib.resources.as_file(ref) as path:
            sensor = cls.from_csv(path, name="Sentinel-2 MSI (MRD, Segl et al. 2012 Table 1)")
        return replace(sensor, source="s2cl/data/sentinel2_mrd_table1.csv")

    @classmethod
    def from_csv(cls, path: str | Path, *, name: str | None = None, bits: int = 12) -> Sensor:
        """A sensor from a CSV with the columns of ``s2cl/data/sentinel2_mrd_table1.csv``.

        Empty SNR cells mean "not given". Missing columns, non-numbers or bad ranges raise
        :class:`InputError` naming file, band and column.
        """
        header, rows = read_csv_table(path)
        missing = [c for c in SENSOR_COLUMNS if c not in header]
        if missing:
            raise InputError(f"missing columns: {', '.join(missing)} (expected {', '.join(SENSOR_COLUMNS)})",
                             source=path)
        col = {c: header.index(c) for c in SENSOR_COLUMNS}
        extra = _numeric_columns(header, rows, set(SENSOR_COLUMNS))
        bands = []
        for line_no, row in rows:
            band_name = check_band_name(row[col["band"]].strip(), source=path, key="band", where=f"line {line_no}")

            def number(key: str, *, optional: bool = False, _row=row, _band=band_name) -> float | None:
                text = _row[col[key]].strip()
                if not text:
                    if optional:
                        return None
                    raise InputError("value is empty", source=path, key=f"{_band}.{key}")
                try:
                    return parse_number(text)
                except ValueError as err:
                    raise InputError(f"not a number: {token(text)}", source=path, key=f"{_band}.{key}") from err

            levels = {k: number(k) for k in ("lmin", "lref", "lmax")}
            snrs = {k: number("snr_" + k, optional=True) for k in ("lmin", "lref", "lmax")}
            for k, snr in snrs.items():
                if snr is not None and not (math.isfinite(snr) and snr > 0):
                    raise InputError(f"must be a finite number > 0 (or empty: not given), got {snr}", source=path,
                                     key=f"{band_name}.snr_{k}")
            points = tuple((levels[k], s) for k, s in snrs.items() if s is not None)
            bands.append(
                Band(
                    name=band_name,
                    centre_nm=number("centre_nm"),
                    fwhm_nm=number("fwhm_nm"),
                    lmin=levels["lmin"],
                    lref=levels["lref"],
                    lmax=levels["lmax"],
                    snr_points=points,
                    gsd_m=number("gsd_m"),
                    extra=tuple((c, parse_number(row[i].strip())) for c, i in extra.items() if row[i].strip()),
                )
            )
        return cls(name=name or Path(path).stem, bands=tuple(bands), bits=bits, source=str(path))


def _numeric_columns(header: list[str], rows: list[tuple[int, list[str]]], known: set[str]) -> dict[str, int]:
    """The optional columns of a sensor table whose every filled cell is a number (others are ignored)."""
    out = {}
    for i, name in enumerate(header):
        if name in known or not name.strip():
            continue
        try:
            [parse_number(r[i].strip()) for _, r in rows if i < len(r) and r[i].strip()]
        except ValueError:
            continue
        out[name.strip()] = i
    return out
