"""User spectral-library files onto a grid: CSV (:func:`load_csv_library`) and ENVI ``.sli``/``.hdr``
(:func:`load_envi_library`), with wavelength units (nm or um), plausibility checks (reflectance 0-1, or
TOA radiance in W m-2 sr-1 um-1) and per-spectrum parameters (:mod:`s2cl.libraries.params`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError, ResourceError, key_token, token
from s2cl.grid import SpectralGrid, check_wavelengths
from s2cl.io.budget import BASELINE_BYTES, Allocation, Budget, largest_fitting
from s2cl.io.envi import envi_layout, read_envi_header
from s2cl.io.inputs import input_file, parse_number
from s2cl.io.tables import CsvStream, open_csv
from s2cl.libraries.library import FINITE_BLOCK, Quantity, SpectralLibrary, resample_to_grid
from s2cl.libraries.params import CsvParameters, envi_parameters

#: Largest wavelength gap (nm) in a user file that linear interpolation may bridge; a wider gap
#: inside the grid (e.g. deleted water-vapour bands) is an error instead of invented data.
DEFAULT_MAX_GAP_NM = 25.0
#: Reflectance values outside this range suggest percent or integer scaling, not reflectance.
REFLECTANCE_RANGE = (-0.05, 2.0)
#: TOA radiance (W m-2 sr-1 um-1) outside this range suggests other units (the solar constant peaks
#: near 2000 W m-2 um-1 at 450 nm; no Earth target is brighter than that over pi).
RADIANCE_RANGE = (-1.0, 1000.0)


def wavelengths_to_nm(values: np.ndarray, unit: str | None, *, source: str, key: str) -> np.ndarray:
    """Convert a wavelength axis to nm; ``unit`` is ``"nm"``, ``"um"`` or ``None`` (detect).

    Detection: an axis whose largest value is below 100 is in µm (no optical library reaches
    100 nm), otherwise nm. ENVI spellings (``Micrometers``, ``Nanometers``…) are accepted.
    """
    w = check_wavelengths(values, source=source, key=key)
    norm = _normalise_unit(unit, source=source, key=key)
    if norm is None:
        norm = "um" if w[-1] < 100.0 else "nm"
    return w * 1000.0 if norm == "um" else w


def _normalise_unit(unit: str | None, *, source: str, key: str) -> str | None:
    """``nm``, ``um`` or ``None`` (unknown: detect) for a unit's spelling; anything else is refused."""
    if unit is None:
        return None
    u = unit.strip().lower().replace("µ", "u").replace("μ", "u")
    if u in {"", "unknown", "<unspecified>", "index"}:
        return None
    if u in {"nm", "nanometer", "nanometers", "nanometre", "nanometres"}:
        return "nm"
    if u in {"um", "micron", "microns", "micrometer", "micrometers", "micrometre", "micrometres"}:
        return "um"
    raise InputError(f"wavelength unit {token(unit)} is not nm or µm", source=source, key=key)


def _check_user_spectra(
    w_nm: np.ndarray, spectra: np.ndarray, names: list[str], grid: SpectralGrid, *, source: str, max_gap_nm: float,
    quantity: Quantity = "reflectance",
) -> None:
    """Reject non-finite values, values outside the plausible range of ``quantity``, and gaps inside the grid.

    Only the samples that interpolation onto ``grid`` uses are checked (those inside the grid
    and the one bracketing sample each side): a deleted value far outside the grid is harmless.
    """
    first = max(int(np.searchsorted(w_nm, grid.start_nm, side="right")) - 1, 0)
    last = min(int(np.searchsorted(w_nm, grid.stop_nm, side="left")), w_nm.size - 1)
    check_values(w_nm, spectra, names, slice(first, last + 1), source=source, quantity=quantity)
    check_gaps(w_nm, grid, source=source, max_gap_nm=max_gap_nm)


def check_values(w_nm: np.ndarray, spectra: np.ndarray, names: list[str], used: slice, *, source: str,
                 quantity: Quantity) -> None:
    """Reject non-finite values and values outside the plausible range of ``quantity`` in the columns ``used``
    of ``spectra`` (n, w_nm.size); the error names the spectrum and the wavelength (nm)."""
    lo, hi = REFLECTANCE_RANGE if quantity == "reflectance" else RADIANCE_RANGE
    w = w_nm[used]
    for i in range(spectra.shape[0]):
        row = spectra[i, used]  # one row at a time: no copy of the whole library
        bad = ~np.isfinite(row)
        if bad.any():
            j = int(np.flatnonzero(bad)[0])
            raise InputError(
                f"holds a non-finite value ({row[j]}) at {w[j]:g} nm; spectra must be finite",
                source=source,
                key=key_token(names[i]),
            )
        if row.min() < lo or row.max() > hi:
            j = int(np.argmax((row < lo) | (row > hi)))
            raise InputError(f"value {row[j]:g} at {w[j]:g} nm {_out_of_range(quantity, lo, hi)}", source=source,
                             key=key_token(names[i]))


def check_gaps(w_nm: np.ndarray, grid: SpectralGrid, *, source: str, max_gap_nm: float) -> None:
    """Reject a wavelength gap wider than ``max_gap_nm`` inside ``grid`` (s2cl does not invent data there)."""
    inside = (w_nm[1:] > grid.start_nm) & (w_nm[:-1] < grid.stop_nm)
    gaps = np.diff(w_nm)
    wide = inside & (gaps > max_gap_nm)
    if wide.any():
        j = int(np.flatnonzero(wide)[0])
        raise InputError(
            f"has no data between {w_nm[j]:g} and {w_nm[j + 1]:g} nm ({gaps[j]:g} nm gap > {max_gap_nm:g} nm) "
            f"inside the grid {grid.describe()}; s2cl does not invent data across such gaps "
            "(choose a grid outside the gap or raise max_gap_nm)",
            source=source,
            key="wavelength",
        )


def _out_of_range(quantity: Quantity, lo: float, hi: float) -> str:
    """Why a value is implausible, and what to do about it in scene terms."""
    if quantity == "reflectance":
        return (f"is outside the reflectance range {lo:g}–{hi:g}: rescale percent or integer-scaled data to 0–1 in "
                "the file; if it holds TOA radiance (W m-2 sr-1 um-1) set surface.quantity = \"radiance\"")
    return (f"is outside the TOA radiance range {lo:g}–{hi:g} W m-2 sr-1 um-1: convert the file to those units; "
            "if it holds surface reflectance set surface.quantity = \"reflectance\" (with effects.atmosphere)")


def _user_library(
    w_nm: np.ndarray, spectra: np.ndarray, names: list[str], grid: SpectralGrid, *, source: str, max_gap_nm: float,
    quantity: Quantity = "reflectance", params: dict[str, np.ndarray] | None = None,
) -> SpectralLibrary:
    """A user file's spectra, checked and resampled onto ``grid`` (group ``user``), with their ``params``."""
    _check_user_spectra(w_nm, spectra, names, grid, source=source, max_gap_nm=max_gap_nm, quantity=quantity)
    resampled = resample_to_grid(w_nm, spectra, grid, source=source)
    return SpectralLibrary(
        grid=grid,
        spectra=resampled,
        names=names,
        quantity=quantity,
        groups=["user" for _ in names],
        params=params or {},
        source=str(source),
    )


def load_csv_library(
    path: str | Path,
    grid: SpectralGrid,
    *,
    wavelength_unit: str | None = None,
    scale: float = 1.0,
    max_gap_nm: float = DEFAULT_MAX_GAP_NM,
    quantity: Quantity = "reflectance",
    budget: Budget | None = None,
) -> SpectralLibrary:
    """Read a CSV spectral library and interpolate it linearly onto ``grid``.

    Layout: a header row, then one row per wavelength. The first column is the wavelength,
    named ``wavelength_nm`` or ``wavelength_um`` (unit from the name) or ``wavelength``
    (unit from ``wavelength_unit``, else detected: values below 100 are µm). Every other
    column is one spectrum, named by its header. Lines starting with ``#`` are comments;
    commas or semicolons separate fields. Rows between the header and the first wavelength row whose
    first cell is ``param:NAME`` give a parameter of every spectrum (``param:cab,45.2,30.1``: one finite
    value per spectrum column; :mod:`s2cl.libraries.params`).

    :param scale: multiplies every value (``0.01`` for percent).
    :param max_gap_nm: widest wavelength gap inside the grid that interpolation may bridge.
    :param quantity: what the values are: surface reflectance (0–1) or TOA radiance (W m⁻² sr⁻¹ µm⁻¹).
    :param budget: memory the reading may take (default :meth:`Budget.of`): the file's values (rows ×
        columns from its header and row count) and the spectra on ``grid`` are sized before any value is
        parsed, and a file that would not fit is a one-line :class:`~s2cl.errors.ResourceError`.
    :raises InputError: missing/malformed file, bad wavelengths, NaN/inf, values that are not
        reflectance, data not covering the grid, or a bad parameter row; the message names file and column
        (``param:NAME`` for a parameter row) and the line.
    """
    source = str(path)
    stream = open_csv(path, min_rows=2, what="spectral library file", rows_are="wavelength rows")
    header = stream.header
    first = header[0].strip().lower()
    if first in {"wavelength_nm", "wavelength_um", "wavelength_µm"}:
        declared = "nm" if first.endswith("nm") else "um"
        if wavelength_unit is not None and _normalise_unit(wavelength_unit, source=source, key=header[0]) != declared:
            raise InputError(f"column name says {declared} but wavelength_unit={token(wavelength_unit)}",
                             source=source)
        unit: str | None = declared
    elif first == "wavelength":
        unit = wavelength_unit
    else:
        raise InputError("first column must be named wavelength_nm, wavelength_um or wavelength (is this a "
                         "spectral library?)", source=source)
    names = [h.strip() for h in header[1:]]
    if not names:
        raise InputError("holds a wavelength column but no spectrum column", source=source)
    if len(set(names)) != len(names) or any(not n for n in names):
        raise InputError("spectrum column names must be non-empty and unique", source=source)
    require_library_memory(budget, len(names), stream.rows * len(header) * 8.0, grid, source=source)
    values, params = _csv_values(stream, header, source=source)
    w_nm = wavelengths_to_nm(values[0], unit, source=source, key=header[0])
    spectra = values[1:]  # (spectra, rows): a view, no copy
    if float(scale) != 1.0:
        spectra *= float(scale)
    return _user_library(w_nm, spectra, names, grid, source=source, max_gap_nm=max_gap_nm, quantity=quantity,
                         params=params)


def library_read_footprint(n_spectra: int, read_bytes: float, grid: SpectralGrid) -> list[Allocation]:
    """What reading a library file allocates at its peak: the file's values as read (``read_bytes``, the reader's
    own count), its spectra put on ``grid`` (float64, :func:`s2cl.libraries.library.resample_to_grid`; bytes per
    spectrum) and the library's finiteness test of a block of at most :data:`~s2cl.libraries.library.FINITE_BLOCK` of
    the ``n_spectra`` (bool; the range checks go a row at a time)."""
    return [Allocation("values as read", float(read_bytes)),
            Allocation("spectra on the grid (float64)", 0.0, float(np.dtype(np.float64).itemsize * grid.size)),
            Allocation("finiteness test (bool)", float(np.dtype(np.bool_).itemsize * min(n_spectra, FINITE_BLOCK)
                                                       * grid.size))]


def require_library_memory(budget: Budget | None, n_spectra: int, read_bytes: float, grid: SpectralGrid, *,
                           source: str) -> None:
    """Refuse (one line naming the file, before it is read) a library whose reading would exceed ``budget``:
    :func:`library_read_footprint` beside :data:`~s2cl.io.budget.BASELINE_BYTES`."""
    budget = budget or Budget.of()
    parts = library_read_footprint(n_spectra, read_bytes, grid)
    need = BASELINE_BYTES + sum(a.bytes(n_spectra) for a in parts)
    per_spectrum = sum(a.per_unit for a in parts) + read_bytes / max(n_spectra, 1)
    most = largest_fitting(budget.memory_bytes, BASELINE_BYTES + parts[-1].fixed, per_spectrum)
    budget.require(need, what=f"reading its {n_spectra:,} spectra onto the grid {grid.describe()}", key=None,
                   source=source, fits=f"at most {min(most, n_spectra):,} spectra fit on this grid; use fewer "
                   "spectra or a coarser grid (grid.step_nm)")


def _csv_values(stream: CsvStream, header: list[str], *, source: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The wavelength rows as numbers, float64 ``(n_columns, n_rows)`` (a column per row of the file: the
    spectra are rows of the result; empty cells become NaN), and the parameters of the ``param:NAME`` rows
    before them. Read one line at a time."""
    out = np.empty((len(header), stream.rows))
    params = CsvParameters(header, source)
    r = 0
    for line_no, row in stream:
        if params.take(line_no, row):
            continue
        if len(row) != len(header):
            raise InputError(f"line {line_no} has {len(row)} fields, the header has {len(header)}", source=source)
        for c, cell in enumerate(row):
            text = cell.strip()
            try:
                out[c, r] = parse_number(text) if text else np.nan
            except ValueError as err:
                raise InputError(f"line {line_no}: {token(text)} is not a number", source=source,
                                 key=key_token(header[c])) from err
        r += 1
    if r < 2:
        raise InputError("needs a header row and at least 2 wavelength rows (after its param: rows)", source=source)
    return out[:, :r], params.params


def load_envi_library(
    path: str | Path,
    grid: SpectralGrid,
    *,
    wavelength_unit: str | None = None,
    max_gap_nm: float = DEFAULT_MAX_GAP_NM,
    quantity: Quantity = "reflectance",
    budget: Budget | None = None,
) -> SpectralLibrary:
    """Read an ENVI spectral library (``.sli`` + ``.hdr``, through SPy) onto ``grid``.

    ``path`` may name the header (``lib.hdr`` or ``lib.sli.hdr``) or the data file
    (``lib.sli``). Wavelength units come from the header's ``wavelength units`` (else
    ``wavelength_unit``, else detected); a ``reflectance scale factor`` is divided out,
    values equal to ``data ignore value`` count as missing (an error where the grid needs
    them), and bands flagged bad in ``bbl`` are dropped (the gap check then applies). Header fields
    ``s2cl parameter NAME = {v1, v2, ...}`` give a parameter of every spectrum (one finite value per line;
    :mod:`s2cl.libraries.params`). The memory of reading it (from the header: lines × samples × data type)
    is checked against ``budget`` first.
    """
    hdr, data = _envi_paths(Path(path))
    meta, lib, params = _open_envi(hdr, data, grid, budget)
    centers = lib.bands.centers
    if not centers:
        raise InputError("header has no 'wavelength' list", source=hdr, key="wavelength")
    unit = meta.get("wavelength units") or wavelength_unit
    w_nm = wavelengths_to_nm(np.asarray(centers, dtype=np.float64), unit, source=str(hdr), key="wavelength")
    names = [str(n).strip() for n in lib.names]
    spectra = np.asarray(lib.spectra, dtype=np.float64)  # SPy's array in the file's type is let go with ``lib``
    del lib
    spectra = _envi_values(meta, spectra, hdr)
    if "bbl" in meta:
        good = _good_bands(meta, w_nm.size, hdr)
        w_nm, spectra = w_nm[good], spectra[:, good]
    return _user_library(w_nm, spectra, names, grid, source=str(data), max_gap_nm=max_gap_nm, quantity=quantity,
                         params=params)


def _open_envi(hdr: Path, data: Path, grid: SpectralGrid, budget: Budget | None
               ) -> tuple[dict, Any, dict[str, np.ndarray]]:
    """The header's metadata (lower-cased keys), SPy's library and the header's parameters, once the header's
    layout, parameters and the data file's size are checked (:mod:`s2cl.io.envi`: errors name the header key)
    and the memory of reading it onto ``grid`` is within ``budget``."""
    from spectral.io import envi
    from spectral.utilities.errors import SpyException

    # lower-cased keys; SPy's lib.metadata drops 'data ignore value'
    meta = read_envi_header(hdr, "ENVI spectral library")
    if str(meta.get("file type", "")).strip().lower() != "envi spectral library":
        raise InputError("header 'file type' is not 'ENVI Spectral Library'", source=hdr, key="file type")
    layout = envi_layout(meta, hdr, data, max_bytes=MAX_ENVI_BYTES)
    if layout.bands != 1:
        raise InputError(f"an ENVI spectral library has bands = 1 (spectra are lines, wavelengths samples), got "
                         f"{layout.bands}", source=hdr, key="bands")
    for key, want, what in (("wavelength", layout.samples, "samples"), ("spectra names", layout.lines, "lines")):
        if key in meta and len(meta[key]) != want:
            raise InputError(f"lists {len(meta[key])} values for {what} = {want}", source=hdr, key=key)
    params = envi_parameters(hdr, meta, layout.lines)
    try:
        # SPy's array in the file's type, float64 spectra, a float64 copy without the bad bands (bbl)
        values = layout.samples * layout.lines * layout.bands
        read = values * (layout.item_bytes + 8.0 + (8.0 if "bbl" in meta else 0.0))
        require_library_memory(budget, layout.lines, read, grid, source=str(hdr))
        lib = envi.open(str(hdr), str(data))
    except ResourceError:  # the memory check: its own message
        raise
    except (SpyException, OSError, ValueError, TypeError, KeyError, IndexError, UnicodeDecodeError) as err:
        raise InputError(f"not a readable ENVI spectral library ({type(err).__name__})", source=hdr) from err
    if not hasattr(lib, "names"):
        raise InputError("header 'file type' is not 'ENVI Spectral Library'", source=hdr, key="file type")
    return meta, lib, params


def _envi_values(meta: dict, spectra: np.ndarray, hdr: Path) -> np.ndarray:
    """The spectra with ``data ignore value`` as NaN and the ``reflectance scale factor`` divided out."""
    factor = _header_float(meta, "reflectance scale factor", 1.0, hdr)
    if factor <= 0 or not np.isfinite(factor):
        raise InputError(f"must be > 0, got {factor}", source=hdr, key="reflectance scale factor")
    ignore = _header_float(meta, "data ignore value", np.nan, hdr) if "data ignore value" in meta else None
    for a in range(0, spectra.shape[0], 1024):  # in place, a block of rows at a time: no full-size temporaries
        block = spectra[a : a + 1024]
        if ignore is not None:
            # missing data become NaN: an error where the grid needs them (float32 files: compare to 1e-6)
            block[np.isclose(block, ignore, rtol=1e-6, atol=0.0)] = np.nan
        block /= factor
    return spectra


def _good_bands(meta: dict, n_bands: int, hdr: Path) -> np.ndarray:
    """The header's bad-band list ``bbl`` as a mask of the good bands, bool (n_bands,)."""
    try:
        good = np.asarray([float(b) != 0.0 for b in meta["bbl"]])
    except (TypeError, ValueError) as err:
        raise InputError("must list numbers (1 good, 0 bad)", source=hdr, key="bbl") from err
    if good.size != n_bands:
        raise InputError(f"{good.size} entries for {n_bands} bands", source=hdr, key="bbl")
    if good.sum() < 2:
        raise InputError(f"flags {n_bands - int(good.sum())} of {n_bands} bands bad; a library needs at least two "
                         "good bands (1 good, 0 bad)", source=hdr, key="bbl")
    return good


#: largest ENVI library read (bytes of data): a library is held in memory as float64 several times
MAX_ENVI_BYTES = 256 * 2**20


def _header_float(meta: dict, key: str, default: float, hdr: Path) -> float:
    """A number from the header; ``default`` when the key is absent or empty."""
    value = meta.get(key)
    if value is None or (isinstance(value, str) and not value.strip()):
        return default
    try:
        return float(value)
    except (TypeError, ValueError) as err:
        raise InputError(f"must be a number, got {token(value)}", source=hdr, key=key) from err


def _envi_paths(path: Path) -> tuple[Path, Path]:
    """(header, data) for a path naming either file of an ENVI library; both must be regular files."""
    if path.suffix.lower() == ".hdr":
        input_file(path, what="ENVI header")
        stem = path.with_suffix("")
        candidates = [stem] if stem.suffix.lower() == ".sli" else [stem.with_suffix(".sli"), stem.with_suffix(".SLI")]
        data = next((c for c in candidates if c.exists()), None)
        if data is None:
            looked = ", ".join(c.name for c in candidates)
            raise InputError(f"ENVI library data file not found (looked for {looked})", source=path)
        return path, input_file(data, what="ENVI library data file")
    input_file(path, what="ENVI library data file (.sli)")
    candidates = [path.with_name(path.name + ".hdr"), path.with_suffix(".hdr"), path.with_suffix(".HDR")]
    hdr = next((c for c in candidates if c.exists()), None)
    if hdr is None:
        raise InputError(f"ENVI header not found (looked for {', '.join(c.name for c in candidates)})", source=path)
    return input_file(hdr, what="ENVI header"), path
