"""Band spectral response functions (SRFs): the paper's super-Gaussian model and tabulated responses.

Model (Segl et al. 2012, eq. 1)::

    R(λ) = X0 + Xs · exp(-|2(λ - λc) / (α Δλ)|^Xe),  X0 = 0.0001, Xs = 0.8999, α = 1.06299, Xe = 6

At λ - λc = ±Δλ/2 the exponential term is 0.5 (α makes Δλ the FWHM), and R peaks at 0.9.

**Support cut-off.** The constant floor X0 never reaches zero: integrated over 400–2500 nm it adds
2101 nm × 1e-4 = 0.21 nm of equivalent width, about 1 % of a 20 nm band's weight taken from the
whole spectrum. s2cl therefore evaluates the model only on ``|λ - λc| <= support × FWHM``
(``support = 1.0`` by default). The super-Gaussian term falls below the floor at
``|λ - λc| = 0.768 FWHM`` (where Xs·exp(-x^6) = X0), so the default support keeps the whole
shape plus a floor of ±0.23 FWHM on each side, and the floor contributes ≤ 0.03 % of the weight.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from s2cl.errors import DependencyError, InputError, token
from s2cl.grid import SpectralGrid, check_wavelengths
from s2cl.io.inputs import parse_number
from s2cl.io.tables import read_csv_table
from s2cl.sensor.names import check_band_name

X0 = 0.0001
XS = 0.8999
ALPHA = 1.06299
XE = 6.0
DEFAULT_SUPPORT = 1.0
#: largest response a tabulated SRF may hold (relative units: 0-1, or percent; more is not an SRF)
MAX_RESPONSE = 1000.0
#: negative responses down to this fraction of a band's peak are measurement noise: clipped to 0 with a warning
NEGATIVE_NOISE_FRACTION = 0.01

_log = logging.getLogger(__name__)


def super_gaussian(wavelengths_nm: np.ndarray, centre_nm: float, fwhm_nm: float) -> np.ndarray:
    """The paper's eq. (1) response (peak 0.9, floor 1e-4), float64, no cut-off."""
    x = np.abs(2.0 * (np.asarray(wavelengths_nm, dtype=np.float64) - centre_nm) / (ALPHA * fwhm_nm))
    return X0 + XS * np.exp(-(x**XE))


@dataclass(frozen=True, eq=False)
class TabulatedResponse:
    """A measured or user-given response on its own wavelength axis (nm), relative units."""

    wavelengths_nm: np.ndarray
    response: np.ndarray
    origin: str = ""

    def on(self, wavelengths_nm: np.ndarray) -> np.ndarray:
        """Linear interpolation onto ``wavelengths_nm``; zero outside the tabulated range."""
        return np.interp(wavelengths_nm, self.wavelengths_nm, self.response, left=0.0, right=0.0)

    def key(self) -> tuple:
        return (self.origin, self.wavelengths_nm.tobytes(), self.response.tobytes())


@dataclass(frozen=True, eq=False)
class BandWeights:
    """Normalised resampling weights of one band on a grid: ``L_k = Σ_j w[j] · L[start + j]``.

    :param start: first grid index of the support.
    :param weights: float64, sums to 1.
    """

    start: int
    weights: np.ndarray

    @property
    def stop(self) -> int:
        return self.start + int(self.weights.size)

    def apply(self, spectra: np.ndarray) -> np.ndarray:
        """The band value of ``spectra`` ``(..., n_wavelengths)`` on the grid: Σ w·spectrum over the
        support (float64); the resampling kernel computes the same on the device."""
        return np.asarray(spectra, dtype=np.float64)[..., self.start : self.stop] @ self.weights


def band_weights(
    grid: SpectralGrid,
    *,
    name: str,
    centre_nm: float,
    fwhm_nm: float,
    tabulated: TabulatedResponse | None = None,
    support: float = DEFAULT_SUPPORT,
    source: str | None = None,
) -> BandWeights:
    """Resampling weights for one band on ``grid``.

    The model SRF is evaluated on ``|λ - λc| <= support · FWHM``; a tabulated SRF where its
    interpolated response is > 0. The support must lie inside the grid.

    :raises InputError: FWHM <= 0, support <= 0, or support outside the grid.
    """
    if not np.isfinite(fwhm_nm) or fwhm_nm <= 0:
        raise InputError(f"FWHM must be > 0 nm, got {fwhm_nm}", source=source, key=f"{name}.fwhm_nm")
    if not np.isfinite(centre_nm):
        raise InputError(f"centre must be finite, got {centre_nm}", source=source, key=f"{name}.centre_nm")
    wl = grid.wavelengths
    if tabulated is None:
        if not support > 0:
            raise InputError(f"SRF support must be > 0 (× FWHM), got {support}", source=source, key="sensor.support")
        lo, hi = centre_nm - support * fwhm_nm, centre_nm + support * fwhm_nm
        _check_inside(grid, lo, hi, name, source)
        mask = (wl >= lo - 1e-9) & (wl <= hi + 1e-9)
        response = np.where(mask, super_gaussian(wl, centre_nm, fwhm_nm), 0.0)
    else:
        response = tabulated.on(wl)
        lo, hi = float(tabulated.wavelengths_nm[0]), float(tabulated.wavelengths_nm[-1])
        nz = np.flatnonzero(tabulated.response > 0)
        if nz.size:
            lo, hi = float(tabulated.wavelengths_nm[nz[0]]), float(tabulated.wavelengths_nm[nz[-1]])
        _check_inside(grid, lo, hi, name, source)
    nonzero = np.flatnonzero(response > 0)
    if nonzero.size == 0:
        raise InputError(
            f"SRF has no grid sample inside its support (centre {centre_nm} nm, FWHM {fwhm_nm} nm, grid step "
            f"{grid.step_nm} nm); use a finer grid or a wider band",
            source=source,
            key=name,
        )
    start, stop = int(nonzero[0]), int(nonzero[-1]) + 1
    w = response[start:stop]
    return BandWeights(start=start, weights=w / w.sum())


def point_weights(grid: SpectralGrid, centre_nm: float, name: str = "", source: str | None = None) -> BandWeights:
    """An ideal monochromatic band at ``centre_nm``: linear interpolation between the two nearest
    grid samples (used when a scene switches resampling off)."""
    _check_inside(grid, centre_nm, centre_nm, name, source)
    x = (centre_nm - grid.start_nm) / grid.step_nm
    i = min(int(np.floor(x)), grid.size - 2)
    f = x - i
    if f < 1e-12:
        return BandWeights(start=i, weights=np.array([1.0]))
    return BandWeights(start=i, weights=np.array([1.0 - f, f]))


def _check_inside(grid: SpectralGrid, lo: float, hi: float, name: str, source: str | None) -> None:
    if not grid.covers(lo, hi):
        raise InputError(
            f"SRF support {lo:g}–{hi:g} nm lies outside the spectral grid {grid.describe()}; "
            "move or narrow the band, reduce sensor.support, or widen the grid",
            source=source,
            key=name,
        )


def load_srf_csv(path: str, band_names: list[str] | None = None) -> dict[str, TabulatedResponse]:
    """Tabulated SRFs from a CSV: a ``wavelength_nm`` column then one column per band.

    Lines starting with ``#`` are comments. Responses must be finite and within 0-:data:`MAX_RESPONSE`
    (small negative noise is clipped, :func:`clip_response_noise`);
    band names follow :data:`s2cl.sensor.names.BAND_NAME`; numbers are ASCII decimal notation.
    """
    header, rows = read_csv_table(path)
    if not header or header[0].strip().lower() not in ("wavelength_nm", "wavelength"):
        raise InputError("first column must be 'wavelength_nm'", source=path, key="header")
    names = [check_band_name(n.strip(), source=path, key="header") for n in header[1:]]
    data = np.empty((len(rows), len(header)))
    for r, (line_no, row) in enumerate(rows):
        for c, cell in enumerate(row):
            try:
                data[r, c] = parse_number(cell.strip())
            except ValueError as err:
                raise InputError(f"line {line_no}: {token(cell.strip())} is not a number", source=path,
                                 key=header[0].strip() if c == 0 else names[c - 1]) from err
    if data.shape[0] < 2:
        raise InputError("needs at least two rows of responses", source=path)
    wl = check_wavelengths(data[:, 0], source=path, key="wavelength_nm")
    out = {}
    for j, name in enumerate(names, start=1):
        if band_names is not None and name not in band_names:
            continue
        r = clip_response_noise(wl, data[:, j], source=path, key=name)
        if not np.any(r > 0):
            raise InputError("response is zero everywhere", source=path, key=name)
        out[name] = TabulatedResponse(wl, r, origin=f"{path}:{name}")
    return out


def clip_response_noise(wavelengths_nm: np.ndarray, response: np.ndarray, *, source: str, key: str) -> np.ndarray:
    """``response`` with small negative values (measurement noise: down to
    :data:`NEGATIVE_NOISE_FRACTION` of the band's peak) set to zero, each clip logged as a warning naming the
    band and the most negative wavelength; responses that are non-finite, more negative, or above
    :data:`MAX_RESPONSE` are an :class:`InputError` naming the value and its wavelength.

    Measured tables carry such noise in the out-of-band wings (Py6S's Landsat 8 OLI B4: −0.00034 at
    625 nm); a negative weight has no physical meaning, and zero is the measured value within its noise.
    """
    r = np.asarray(response, dtype=np.float64)
    limits = f"responses must be finite, >= 0 and <= {MAX_RESPONSE:g} (relative units: 0-1, or percent)"
    bad = ~np.isfinite(r) | (r > MAX_RESPONSE)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"{limits}; got {r[i]:g} at {wavelengths_nm[i]:g} nm", source=source, key=key)
    negative = r < 0
    if not negative.any():
        return r
    peak = float(r.max())
    i = int(np.argmin(r))
    if peak <= 0 or r[i] < -NEGATIVE_NOISE_FRACTION * peak:
        raise InputError(f"{limits}; got {r[i]:g} at {wavelengths_nm[i]:g} nm, below the noise allowance of "
                         f"-{100 * NEGATIVE_NOISE_FRACTION:g} % of the peak {peak:g}", source=source, key=key)
    _log.warning("%s: %s: %d negative response value(s) down to %g at %g nm (within -%g %% of the peak %g) "
                 "set to 0", source, key, int(negative.sum()), r[i], wavelengths_nm[i],
                 100 * NEGATIVE_NOISE_FRACTION, peak)
    return np.where(negative, 0.0, r)


_S2_PY6S = {
    "B1": "01", "B2": "02", "B3": "03", "B4": "04", "B5": "05", "B6": "06", "B7": "07", "B8": "08",
    "B8a": "8A", "B9": "09", "B10": "10", "B11": "11", "B12": "12",
}


def measured_sentinel2_srf(platform: str, band: str) -> TabulatedResponse:
    """The measured Sentinel-2A or -2B MSI response of ``band`` from Py6S's built-in tables.

    Py6S ships ESA's measured responses at 2.5 nm (``PredefinedWavelengths.S2A_MSI_01``…);
    install with ``pip install "s2cl[sixs]"``. ``platform`` is ``"S2A"`` or ``"S2B"``.
    """
    platform = platform.upper()
    if platform not in ("S2A", "S2B"):
        raise InputError(f"platform must be 'S2A' or 'S2B', got {platform!r}", key="sensor.srf")
    if band not in _S2_PY6S:
        raise InputError(f"no measured Sentinel-2 response for band {band!r}; bands: {', '.join(_S2_PY6S)}", key=band)
    return py6s_response(f"{platform}_MSI_{_S2_PY6S[band]}", band, "ESA measured")


#: Landsat 8 OLI bands whose measured response Py6S ships (``PredefinedWavelengths.LANDSAT_OLI_B1``…; B8 is the
#: panchromatic band)
OLI_PY6S_BANDS = ("B1", "B2", "B3", "B4", "B5", "B6", "B7", "B9")


def measured_oli_srf(band: str) -> TabulatedResponse:
    """The measured Landsat 8 OLI response of ``band`` (``B1``…``B7``, ``B9``) from Py6S's built-in tables (NASA's
    band-average relative spectral response at 2.5 nm); install with ``pip install "s2cl[sixs]"``."""
    if band not in OLI_PY6S_BANDS:
        raise InputError(f"no measured Landsat 8 OLI response for band {band!r}; bands: {', '.join(OLI_PY6S_BANDS)}",
                         key=band)
    return py6s_response(f"LANDSAT_OLI_{band}", band, "NASA measured")


def py6s_response(table: str, band: str, what: str) -> TabulatedResponse:
    """A response Py6S ships as ``PredefinedWavelengths.<table>`` (id, start µm, stop µm, values at 2.5 nm), its
    small negative noise clipped (:func:`clip_response_noise`).

    :raises DependencyError: Py6S is not installed.
    """
    try:
        from Py6S import PredefinedWavelengths
    except ImportError as err:
        raise DependencyError(f'measured SRFs ({table}) come from Py6S: pip install "s2cl[sixs]"') from err
    _, start_um, stop_um, values = getattr(PredefinedWavelengths, table)
    values = np.asarray(values, dtype=np.float64)
    wl = 1000.0 * (start_um + 0.0025 * np.arange(values.size))
    if abs(1000.0 * stop_um - wl[-1]) >= 2.5:  # 2.5 nm steps from the start; the last within a step of the stop
        raise InputError(f"unexpected Py6S table layout for {table}", key="sensor.srf")
    origin = f"Py6S {table} ({what})"
    return TabulatedResponse(wl, clip_response_noise(wl, values, source=origin, key=band), origin=origin)
